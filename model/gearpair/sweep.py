"""Parameter sweeps on dask: stick and contact-loss ratios and Poincare sections of the DTE.

One sweep point is one run of the fast engine at one value of one parameter (the speed, the
torque or any `GearParams` field) with everything else held. Each point returns

- the stick ratio ``r_k = t_k / t_t`` and contact-loss ratio ``r_l = t_l / t_t`` (Eqs. (26)-(27);
  Figs. 15, 17, 18) over the kept mesh periods, from the engine's located switching instants;
- the Poincare section of the DTE (Eq. (3)): one sample per mesh period
  ``T_m = 2 pi / (z1 Omega1)`` over the kept periods, at a fixed phase of the period
  (``section_phase``; Fig. 16), with the period of the response in mesh periods (1, 2, ...;
  0 none found up to ``max_period``) and the number of distinct values;
- the mesh force over the whole trajectory of the kept periods: its time mean from the
  engine's integral over every integrator step (`StepSummary.mesh_force_mean`), its least and
  peak values from the engine's dense samples inside every step; the back-flank contact ratio
  (with backlash: contact under a negative torque, not contact loss);
- DTE statistics at the ``steps_per_period`` samples per period, named ``_sampled`` (a mean
  over samples at fixed phases of the mesh period is not the time mean), adjacent-period
  differences, the half-order amplitude of the DTE (Fig. 14), and the cost of the point (wall
  and CPU time, worker).

Durations are counted in mesh periods: ``transient_periods`` are discarded (at least
``transient_time`` seconds: the slowest mode, 32 Hz at damping ratio 0.02, decays with a time
constant of 0.25 s) and ``kept_periods`` are kept. At low speed a mesh period is long, so the
simulated time is capped at about ``max_time`` seconds by cutting both counts, never below
``min_periods`` each; the counts used are in the output.

Points run in parallel on dask.distributed: a `LocalCluster` of worker processes by default
(one thread each: the engine is single-threaded compiled code), or an existing cluster by its
scheduler address. A point that raises is caught inside the task and returned as an error
record; it is retried (``retries`` times, each with a ten times tighter ``rtol``) and, if it
still fails, kept in the output with ``status = failed`` and the error. A worker that dies is
treated the same way. A point whose value the parameter validation refuses, or that lies
outside the model's validity (a negative torque without backlash: the teeth part for good),
is not run and not retried: ``status = invalid`` with the reason. Nothing is dropped.

``gearpair sweep PARAM VALUES`` is the command line (`add_parser`, `main`).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import socket
import sys
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from . import analysis
from .effects import Effects, StiffnessSpec
from .params import RPM, RTOL_MIN, GearParams

# Inputs that are not GearParams fields, with their units.
INPUTS = {"speed_rpm": "r/min", "torque": "N.m"}

# The per-point columns of the CSV, in order.
COLUMNS = (
    "index", "param", "value", "status", "error", "attempts", "rtol",
    "speed_rpm", "torque_nm", "mu", "friction", "stick_tie", "sliding",
    "mesh_period_s", "transient_periods", "kept_periods", "section_phase", "t_end_s",
    "stick_ratio", "contact_loss_ratio", "back_contact_ratio", "stick_period_fraction",
    "loss_period_fraction", "dte_mean_um_sampled", "dte_min_um_sampled", "dte_max_um_sampled",
    "mesh_force_min_kn", "mesh_force_mean_kn", "mesh_force_max_kn",
    "poincare_period", "poincare_distinct", "adjacent_diff", "alternate_diff",
    "half_order_um", "mesh_order_um", "events_per_period", "wall_s", "cpu_s", "worker",
)


def sweepable() -> dict[str, str]:
    """Names that can be swept, with their units: the inputs and every `GearParams` field."""
    out = dict(INPUTS)
    for f in fields(GearParams):
        out[f.name] = f.metadata.get("unit", "")
    return out


@dataclass(frozen=True)
class SweepSettings:
    """Everything a sweep point needs besides the swept value (picklable, sent to workers).

    Attributes
    ----------
    torque : N.m, driving torque when not swept
    speed_rpm : r/min, speed of gear 1 when not swept
    params : `GearParams` fields changed from Table 1, as ``((name, value), ...)``
    friction, stick_tie, sliding, stiffness, separation : the `Effects` (``friction =
        "nominal"`` is the traditional slip model, ``"stick_slip"`` the paper's model)
    rtol : relative tolerance of the fast engine
    steps_per_period : engine steps per mesh period (the DTE and mesh force statistics and
        the spectrum use these samples; the ratios do not depend on them)
    transient_periods, transient_time : mesh periods discarded, and at least this time (s)
    kept_periods : mesh periods kept (made even, so half orders fall on a spectral bin)
    max_time : s, soft cap of the simulated time per point (see module docstring)
    min_periods : floor of the discarded and kept period counts under the cap
    tol : tolerance of the Poincare periodicity test, relative to the mean |DTE|
    max_period : longest period (in mesh periods) the test looks for
    section_phase : phase of the Poincare section in the mesh period (0: a pair enters
        contact); the sample nearest it is used. The default lies just before the leaving
        pair exits (phase 0.75 for Table 1's gears), where the ringing of the 3-4 kHz mesh
        modes excited at the entry has decayed most: a section inside the ringing turns small
        changes of the speed into large jumps of the sample and makes a periodic response
        look scattered in a bifurcation diagram.
    """

    torque: float = 3900.0
    speed_rpm: float = 100.0
    params: tuple[tuple[str, float], ...] = ()
    friction: str = "stick_slip"
    stick_tie: str = "exact"
    sliding: str = "paper"
    stiffness: str = "potential_energy"
    separation: bool = True
    rtol: float = 1e-7
    steps_per_period: int = 8
    transient_periods: int = 100
    transient_time: float = 1.0
    kept_periods: int = 100
    max_time: float = 6.0
    min_periods: int = 16
    tol: float = 1e-3
    max_period: int = 16
    section_phase: float = 0.7

    def __post_init__(self) -> None:
        names = {f.name for f in fields(GearParams)}
        for k, _ in self.params:
            if k not in names:
                raise ValueError(f"unknown gear parameter {k!r}; choose from "
                                 + ", ".join(sorted(names)))
        if self.steps_per_period < 2 or self.kept_periods < 4 or self.min_periods < 4:
            raise ValueError("need steps_per_period >= 2, kept_periods >= 4, min_periods >= 4")
        if not (self.max_time > 0 and self.transient_time >= 0 and self.tol > 0):
            raise ValueError("need max_time > 0, transient_time >= 0 and tol > 0")

    def replace(self, **changes: Any) -> SweepSettings:
        return replace(self, **changes)

    def inputs(self, name: str, value: float) -> tuple[GearParams, Effects, float, float]:
        """Gear data, effects, torque (N.m) and speed (rad/s) of the point ``name = value``
        (raises ``ValueError`` for an unknown name or an invalid value)."""
        if name not in sweepable():
            raise ValueError(f"cannot sweep {name!r}; choose one of " + ", ".join(sweepable()))
        over = dict(self.params)
        torque, rpm = self.torque, self.speed_rpm
        if name == "torque":
            torque = float(value)
        elif name == "speed_rpm":
            rpm = float(value)
        else:
            over[name] = value
        params = GearParams(**over)
        effects = Effects(stiffness=StiffnessSpec(kind=self.stiffness), separation=self.separation,
                          friction=self.friction, sliding=self.sliding, stick_tie=self.stick_tie)
        return params, effects, torque, rpm * RPM

    def periods(self, mesh_period: float) -> tuple[int, int]:
        """Discarded and kept mesh periods for a mesh period (s), with the cap applied."""
        tm = mesh_period
        n_t = max(self.transient_periods, math.ceil(self.transient_time / tm - 1e-9))
        n_k = self.kept_periods
        if (n_t + n_k) * tm > self.max_time:
            n_k = min(n_k, max(self.min_periods, int(0.5 * self.max_time / tm)))
            n_t = min(n_t, max(self.min_periods, int((self.max_time - n_k * tm) / tm)))
        return n_t, n_k + n_k % 2


def _boundary_phases(params: GearParams) -> list[float]:
    """Phases (fractions of a mesh period, from the reset) of the engine's known segment
    boundaries: a pair entering (0) or leaving contact, and a pair at the pitch point (a
    boundary of the nominal law, avoided for every law so all models share one grid)."""
    from .geometry import Geometry

    g = Geometry.from_params(params)
    pb = g.base_pitch
    return [0.0, math.fmod(g.path_length, pb) / pb, math.fmod(g.xi_pitch, pb) / pb]


def _blank(index: int, name: str, value: Any, settings: SweepSettings) -> dict[str, Any]:
    rec: dict[str, Any] = {c: math.nan for c in COLUMNS}
    rec.update(index=int(index), param=name, value=value, status="failed", error="",
               attempts=1, rtol=settings.rtol, friction=settings.friction,
               stick_tie=settings.stick_tie, sliding=settings.sliding,
               worker=f"{socket.gethostname()}:{os.getpid()}", poincare=[])
    return rec


def record_periods(params: GearParams, effects: Effects, torque: float, speed: float,
                   n_transient: int, n_kept: int, steps_per_period: int = 8,
                   rtol: float = 1e-7, outputs=("dte", "mesh_force"),
                   transient_steps: int | None = None) -> dict[str, Any]:
    """Run the fast engine for ``n_transient + n_kept`` mesh periods and record the kept ones.

    The engine starts from static equilibrium under ``torque`` (N.m) at ``speed`` (rad/s) and
    steps ``steps_per_period`` (n) times per mesh period ``T_m`` at the instants
    ``(i + offset) T_m / n``, with ``offset`` in (0, 1) chosen away from the instants where a
    pair enters or leaves contact (`gearpair.analysis.section_offset`; a step ending on one of
    them up to rounding made the fast engine fail before commit 9a2d47c). Sample ``k n + j``
    of the kept record is at phase ``(j + offset) / n`` of kept period ``k`` (phase 0: a pair
    enters contact).
    ``transient_steps`` (default n) is the number of steps per period over the transient: a
    fine record (figures) need not step the transient finely. The step ends only change the
    integration at the level of the tolerance.

    Returns
    -------
    dict with ``time`` (s), the engine ``outputs`` named (SI) at the end of each kept step,
    the per-step `StepSummary` figures ``stick_fraction``, ``separation_fraction``,
    ``back_fraction``, ``mesh_force_mean``, ``mesh_force_min``, ``mesh_force_max`` (N) and
    ``n_events``, and ``mesh_period`` (s), ``offset``, ``steps_per_period``.
    """
    from . import make_engine

    tm = analysis.mesh_period(params.z1, speed)
    n = int(steps_per_period)
    off = analysis.section_offset(_boundary_phases(params), n)
    eng = make_engine(params, effects, "fast", rtol=rtol)
    eng.reset(0.0, torque, speed, static=True)
    m = n_kept * n
    first = n_transient * n  # index of the first kept step
    figures = ("stick_fraction", "separation_fraction", "back_fraction", "mesh_force_mean",
               "mesh_force_min", "mesh_force_max", "n_events")
    rec = {k: np.empty(m) for k in (*outputs, "time", *figures)}
    h = tm / n
    nt = n if transient_steps is None else int(transient_steps)
    if nt < 1 or n % nt:
        # the coarse step ends must lie on the fine grid, which avoids the boundaries
        raise ValueError(f"transient_steps = {nt} must divide steps_per_period = {n}")
    if nt != n and n_transient > 0:
        for i in range(n_transient * nt):
            eng.advance((i + 1) * tm / nt - (1.0 - off) * h, torque, speed)
        start = first
    else:
        start = 0
    for i in range(start, first + m):
        summ = eng.advance((i + off) * h, torque, speed)
        if i >= first:  # step i covers ((i - 1 + off) h, (i + off) h]
            k = i - first
            out = eng.outputs()
            rec["time"][k] = out.time
            for name in outputs:
                rec[name][k] = getattr(out, name)
            for f in figures:
                rec[f][k] = getattr(summ, f)
    rec.update(mesh_period=tm, offset=off, steps_per_period=n)
    return rec


def run_point(index: int, name: str, value: float, settings: SweepSettings,
              rtol: float | None = None, attempt: int = 1) -> dict[str, Any]:
    """Run one sweep point; never raises (an error becomes ``status = failed``).

    Records the kept periods with `record_periods`; the Poincare sample of a period is the
    sample nearest ``settings.section_phase`` (its phase is in the ``section_phase``
    column). The ratios are time means of the engine's exact per-step stick and
    separation fractions over the kept periods (Eqs. (26)-(27)): every kept step has the same
    length, so they are plain means.

    Returns the record: the `COLUMNS` plus ``poincare`` (list of DTE samples, m).
    """
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    rec = _blank(index, name, value, settings)
    rec["attempts"] = int(attempt)
    rtol = settings.rtol if rtol is None else float(rtol)
    rec["rtol"] = rtol
    try:
        params, effects, torque, speed = settings.inputs(name, value)
        tm = analysis.mesh_period(params.z1, speed)  # refuses a standstill point
        reason = outside_validity(effects, torque)
    except ValueError as exc:  # the value is refused: a tighter rtol cannot change that
        params, reason = None, f"ValueError: {exc}"
    if reason is not None:
        rec.update(status="invalid", error=reason)
        if params is not None:
            rec.update(speed_rpm=speed / RPM, torque_nm=torque, mu=params.mu)
        rec["wall_s"] = time.perf_counter() - t_wall
        rec["cpu_s"] = time.process_time() - t_cpu
        return rec
    try:
        rec.update(speed_rpm=speed / RPM, torque_nm=torque, mu=params.mu)
        n_t, n_k = settings.periods(tm)
        n = settings.steps_per_period
        r = record_periods(params, effects, torque, speed, n_t, n_k, n, rtol)
        dte, force, stick, sep = (r["dte"], r["mesh_force"], r["stick_fraction"],
                                  r["separation_fraction"])
        if not np.all(np.isfinite(dte)):
            raise ArithmeticError("the DTE is not finite")
        ph = (np.arange(n) + r["offset"]) / n
        j0 = int(np.argmin(np.abs(np.mod(ph - settings.section_phase + 0.5, 1.0) - 0.5)))
        sec = analysis.poincare_every(dte, n, offset=j0)
        tol = settings.tol * (float(np.mean(np.abs(dte))) or 1.0)
        d1, d2 = analysis.adjacent_period_difference(dte, n)
        orders = analysis.order_amplitudes(dte, n, (0.5, 1.0))
        st_per = analysis.per_period(stick, n).sum(axis=1)
        se_per = analysis.per_period(sep, n).sum(axis=1)
        rec.update(
            status="ok", mesh_period_s=tm, transient_periods=n_t, kept_periods=n_k,
            section_phase=float(ph[j0]),
            t_end_s=float(r["time"][-1]),
            stick_ratio=float(stick.mean()), contact_loss_ratio=float(sep.mean()),
            back_contact_ratio=float(r["back_fraction"].mean()),
            stick_period_fraction=float(np.mean(st_per > 0)),
            loss_period_fraction=float(np.mean(se_per > 0)),
            dte_mean_um_sampled=float(dte.mean() * 1e6),
            dte_min_um_sampled=float(dte.min() * 1e6),
            dte_max_um_sampled=float(dte.max() * 1e6),
            # every kept step has the same length: the time mean is the mean of the steps'
            mesh_force_min_kn=float(min(r["mesh_force_min"].min(), force.min()) * 1e-3),
            mesh_force_mean_kn=float(r["mesh_force_mean"].mean() * 1e-3),
            mesh_force_max_kn=float(max(r["mesh_force_max"].max(), force.max()) * 1e-3),
            poincare_period=analysis.periodicity(sec, tol, settings.max_period),
            poincare_distinct=int(analysis.distinct_values(sec, tol).size),
            adjacent_diff=d1, alternate_diff=d2,
            half_order_um=orders[0.5] * 1e6, mesh_order_um=orders[1.0] * 1e6,
            events_per_period=float(r["n_events"].sum() / n_k),
            poincare=[float(x) for x in sec],
        )
    except Exception as exc:  # noqa: BLE001 - every failure becomes a reported record
        rec["status"] = "failed"
        rec["error"] = f"{type(exc).__name__}: {exc}"
    # wall time over CPU time shows how much a worker waited for a shared core
    rec["wall_s"] = time.perf_counter() - t_wall
    rec["cpu_s"] = time.process_time() - t_cpu
    return rec


def outside_validity(effects: Effects, torque: float) -> str | None:
    """Why a run lies outside the model's validity, or None.

    Without backlash (the paper's model) a negative torque parts the teeth for good: nothing
    holds gear 1, which spins up freely, and the DTE grows without bound (a point's DTE
    statistics would be metres). `Effects.backlash` gives the back flanks that take it.
    """
    if torque < 0.0 and effects.backlash is None:
        return (f"torque = {torque:g} N.m < 0 without backlash: the teeth part for good and "
                "gear 1 spins up freely, outside the model (set a backlash for the back "
                "flanks to take a negative torque)")
    return None


# -- the sweep --------------------------------------------------------------------------------
@dataclass
class SweepResult:
    """All points of a sweep (sorted by index, failed ones included) and its cost.

    Attributes
    ----------
    name : swept parameter; values : its values; settings : the held settings
    records : one dict per point (`COLUMNS` plus ``poincare``)
    elapsed_s : wall time of the computation (submission to last result), s
    startup_s : wall time to start or reach the cluster and warm the compiled code, s
    workers : number of worker threads used; scheduler : ``local``, ``serial`` or an address
    """

    name: str
    values: list[float]
    settings: SweepSettings
    records: list[dict[str, Any]]
    elapsed_s: float = 0.0
    startup_s: float = 0.0
    workers: int = 1
    scheduler: str = "serial"
    retried: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def failed(self) -> list[dict[str, Any]]:
        """Points that did not run to the end (``status = failed``)."""
        return [r for r in self.records if r["status"] == "failed"]

    @property
    def invalid(self) -> list[dict[str, Any]]:
        """Points refused by the validation or outside the model (``status = invalid``)."""
        return [r for r in self.records if r["status"] == "invalid"]

    @property
    def throughput(self) -> float:
        """Points per second of wall time over the computation (startup excluded)."""
        return len(self.records) / self.elapsed_s if self.elapsed_s > 0 else math.nan

    def column(self, name: str) -> np.ndarray:
        """A numeric column over all points (NaN for failed points)."""
        return np.array([float(r[name]) for r in self.records])

    def summary(self) -> dict[str, Any]:
        busy = float(sum(r["wall_s"] for r in self.records))
        cpu = float(np.nansum([r.get("cpu_s", math.nan) for r in self.records]))
        return {
            "param": self.name, "unit": sweepable().get(self.name, ""),
            "points": len(self.records),
            "ok": sum(r["status"] == "ok" for r in self.records),
            "failed": [{"index": r["index"], "value": r["value"], "error": r["error"]}
                       for r in self.failed],
            "invalid": [{"index": r["index"], "value": r["value"], "error": r["error"]}
                        for r in self.invalid],
            "retried": self.retried, "scheduler": self.scheduler, "workers": self.workers,
            "startup_s": round(self.startup_s, 3), "elapsed_s": round(self.elapsed_s, 3),
            "total_s": round(self.startup_s + self.elapsed_s, 3),
            "throughput_points_per_s": round(self.throughput, 4),
            "point_busy_s": round(busy, 3), "point_cpu_s": round(cpu, 3),
            "efficiency": round(busy / (self.workers * self.elapsed_s), 3)
            if self.elapsed_s > 0 else None,
            "cpu_share": round(cpu / busy, 3) if busy > 0 else None,
            "settings": asdict(self.settings), **self.extra,
        }

    def report(self) -> str:
        """One line with the counts and the throughput."""
        s = self.summary()
        line = (f"sweep {self.name}: {s['points']} points ({s['ok']} ok, {len(s['failed'])} "
                f"failed, {len(s['invalid'])} invalid, {s['retried']} retried) in "
                f"{s['elapsed_s']:.1f} s on {self.workers} "
                f"worker(s) [{self.scheduler}]: {s['throughput_points_per_s']:.3f} points/s; "
                f"startup {s['startup_s']:.1f} s; efficiency {s['efficiency']}; the points got "
                f"{s['cpu_share']} of a core while running")
        for f in s["failed"]:
            line += f"\n  FAILED point {f['index']} ({self.name} = {f['value']}): {f['error']}"
        for f in s["invalid"]:
            line += f"\n  INVALID point {f['index']} ({self.name} = {f['value']}): {f['error']}"
        return line

    def to_csv(self, path: str | Path) -> Path:
        """One row per point, the `COLUMNS` (failed points included, with their error)."""
        path = Path(path)
        with path.open("w", newline="") as fh:
            wr = csv.writer(fh)
            wr.writerow(COLUMNS)
            for r in self.records:
                wr.writerow([_fmt(r.get(c, math.nan)) for c in COLUMNS])
        return path

    def poincare_to_csv(self, path: str | Path) -> Path:
        """The bifurcation data: ``index, value, k, dte_um`` for every Poincare sample."""
        path = Path(path)
        with path.open("w", newline="") as fh:
            wr = csv.writer(fh)
            wr.writerow(("index", "value", "k", "dte_um"))
            for r in self.records:
                for k, x in enumerate(r["poincare"]):
                    wr.writerow((r["index"], _fmt(r["value"]), k, f"{x * 1e6:.9g}"))
        return path

    def write(self, prefix: str | Path, plot: bool = True) -> dict[str, str]:
        """Write ``PREFIX.csv``, ``PREFIX_poincare.csv``, ``PREFIX.json`` (summary) and,
        with ``plot``, ``PREFIX.png``; returns the paths."""
        prefix = Path(prefix)
        prefix.parent.mkdir(parents=True, exist_ok=True)
        out = {"csv": str(self.to_csv(prefix.with_suffix(".csv"))),
               "poincare": str(self.poincare_to_csv(Path(f"{prefix}_poincare.csv")))}
        js = prefix.with_suffix(".json")
        js.write_text(json.dumps(self.summary(), indent=2, default=str))
        out["json"] = str(js)
        if plot:
            out["png"] = str(plot_sweep(self, prefix.with_suffix(".png")))
        return out


def read_result(prefix: str | Path) -> SweepResult:
    """A `SweepResult` back from the files `SweepResult.write` made (``PREFIX.csv``,
    ``PREFIX_poincare.csv``, ``PREFIX.json``)."""
    prefix = Path(prefix)
    summ = json.loads(prefix.with_suffix(".json").read_text())
    recs = read_csv(prefix.with_suffix(".csv"))
    samples: dict[int, list[float]] = {int(r["index"]): [] for r in recs}
    with Path(f"{prefix}_poincare.csv").open(newline="") as fh:
        for row in csv.DictReader(fh):
            samples[int(row["index"])].append(float(row["dte_um"]) * 1e-6)
    for r in recs:
        r["index"] = int(r["index"])
        r["poincare"] = samples[r["index"]]
    st = dict(summ["settings"])
    st["params"] = tuple(tuple(x) for x in st.get("params", ()))
    return SweepResult(summ["param"], [float(r["value"]) for r in recs], SweepSettings(**st),
                       recs, summ["elapsed_s"], summ["startup_s"], summ["workers"],
                       summ["scheduler"], summ["retried"])


def _fmt(x: Any) -> str:
    if isinstance(x, float):
        return "" if math.isnan(x) else f"{x:.10g}"
    return str(x)


def read_csv(path: str | Path) -> list[dict[str, Any]]:
    """Read a sweep CSV back (numbers as float, empty cells as NaN)."""
    with Path(path).open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    out = []
    for r in rows:
        d: dict[str, Any] = {}
        for k, v in r.items():
            if k in ("param", "status", "error", "friction", "stick_tie", "sliding", "worker"):
                d[k] = v
            else:
                d[k] = float(v) if v != "" else math.nan
        out.append(d)
    return out


def read_poincare_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read ``PREFIX_poincare.csv``: (values, dte_um) arrays, one entry per sample."""
    data = np.genfromtxt(path, delimiter=",", names=True)
    return np.atleast_1d(data["value"]), np.atleast_1d(data["dte_um"])


class Progress:
    """A progress bar on a stream: redrawn in place on a terminal, else a line every 5 %."""

    def __init__(self, total: int, label: str, stream=None, enabled: bool = True) -> None:
        self.total, self.label, self.done, self.failed = total, label, 0, 0
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        self.t0 = time.perf_counter()
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._next = 0

    def start(self) -> None:
        """Start the clock (after the cluster is up, so the rate is the computation's)."""
        self.t0 = time.perf_counter()

    def update(self, ok: bool, retrying: bool = False) -> None:
        if not retrying:
            self.done += 1
            self.failed += 0 if ok else 1
        if not self.enabled:
            return
        if not self.tty and self.done < self._next and self.done < self.total:
            return
        self._next = self.done + max(1, self.total // 20)
        dt = time.perf_counter() - self.t0
        rate = self.done / dt if dt > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else math.nan
        n = 30
        bar = "#" * int(n * self.done / max(self.total, 1))
        msg = (f"{self.label} [{bar:<{n}s}] {self.done}/{self.total} {rate:.2f} points/s "
               f"ETA {eta:5.0f} s failed {self.failed}")
        self.stream.write(("\r" + msg) if self.tty else (msg + "\n"))
        if self.tty and self.done >= self.total:
            self.stream.write("\n")
        self.stream.flush()


def _warm() -> None:
    """Load (or compile once, ~25 s) the fast engine's kernels in this process, so that local
    workers find them in the on-disk cache instead of compiling in parallel."""
    from . import make_engine

    eng = make_engine(GearParams(), Effects(), "fast", rtol=1e-6)
    eng.reset(0.0, 3900.0, 100 * RPM)
    eng.advance(1e-4, 3900.0, 100 * RPM)


def run_sweep(name: str, values, settings: SweepSettings | None = None, *,
              scheduler: str | None = None, workers: int | None = None, retries: int = 1,
              progress: bool = True, stream=None) -> SweepResult:
    """Run ``run_point`` for every value of ``name`` and gather the records.

    Parameters
    ----------
    name : parameter to sweep (`sweepable`): ``speed_rpm`` (r/min), ``torque`` (N.m) or a
        `GearParams` field (SI, e.g. ``mu``)
    values : the values (any order; the output keeps it)
    settings : held inputs, effects and durations
    scheduler : None for a new local cluster of ``workers`` processes; ``"serial"`` to run in
        this process (no dask); otherwise the address of a running dask.distributed scheduler
        (e.g. ``tcp://10.0.0.5:8786``)
    workers : local worker processes (default: the CPU count)
    retries : how many times a failed point is run again (each with ``rtol / 10``)
    progress : draw a progress bar on ``stream`` (stderr by default)
    """
    settings = settings or SweepSettings()
    if name not in sweepable():
        raise ValueError(f"cannot sweep {name!r}; choose one of " + ", ".join(sweepable()))
    values = [float(v) for v in values]
    if not values:
        raise ValueError("no values to sweep")
    if retries < 0:
        raise ValueError(f"retries = {retries!r} must be >= 0")
    bar = Progress(len(values), f"sweep {name}", stream, progress)
    t0 = time.perf_counter()
    if scheduler == "serial":
        _warm()
        startup = time.perf_counter() - t0
        t1 = time.perf_counter()
        bar.start()
        records, retried = [], 0
        for i, v in enumerate(values):
            rec = run_point(i, name, v, settings)
            for a in range(2, retries + 2):
                if rec["status"] != "failed":  # ok, or invalid: a tighter rtol cannot help
                    break
                bar.update(False, retrying=True)
                retried += 1
                rec = run_point(i, name, v, settings, _tighter(settings.rtol, a), a)
            records.append(rec)
            bar.update(rec["status"] != "failed")
        return SweepResult(name, values, settings, records, time.perf_counter() - t1, startup,
                           1, "serial", retried)
    return _run_dask(name, values, settings, scheduler, workers, retries, bar, t0)


def _tighter(rtol: float, attempt: int) -> float:
    return max(rtol / 10.0 ** (attempt - 1), RTOL_MIN)


def _local_cluster(workers: int | None):
    import logging

    try:
        from dask.distributed import LocalCluster
    except ImportError as exc:  # pragma: no cover - the extra is missing
        raise ImportError("sweeps need dask.distributed: pip install 'gearpair[sweep]'") from exc
    _warm()  # compile once here, before the workers start
    n = int(workers or os.cpu_count() or 1)
    # No dashboard; the scheduler's HTTP server (health checks) on a free port, so that a
    # second cluster on the machine does not warn about port 8787.
    return LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                        dashboard_address=None, silence_logs=logging.ERROR,
                        scheduler_kwargs={"dashboard_address": ":0"})


@contextmanager
def local_cluster(workers: int | None = None):
    """A local cluster of ``workers`` single-threaded processes for several sweeps; yields
    its scheduler address (pass it as ``scheduler``). Call it under
    ``if __name__ == "__main__":`` in scripts (worker processes are spawned)."""
    cluster = _local_cluster(workers)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


def _run_dask(name, values, settings, scheduler, workers, retries, bar, t0) -> SweepResult:
    from dask.distributed import Client, as_completed

    cluster = None
    if scheduler:
        client = Client(scheduler)
        label = scheduler
    else:
        cluster = _local_cluster(workers)
        client = Client(cluster)
        label = "local"
    try:
        client.wait_for_workers(1, timeout=120)
        info = client.scheduler_info(n_workers=-1) if _accepts_n_workers(client) \
            else client.scheduler_info()
        nthreads = sum(int(w.get("nthreads", 1)) for w in info["workers"].values()) or 1
        # Load the compiled kernels on every worker before the clock starts.
        client.run(_warm)
        startup = time.perf_counter() - t0
        t1 = time.perf_counter()
        bar.start()
        futs, first = {}, []
        for i, v in enumerate(values):
            f = client.submit(run_point, i, name, v, settings, None, 1, pure=False)
            futs[f.key] = (i, v, 1)
            first.append(f)
        ac = as_completed(first)
        del first
        records: dict[int, dict] = {}
        retried = 0
        for fut in ac:
            i, v, attempt = futs.pop(fut.key)
            try:
                rec = fut.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker or a cancelled task
                rec = _blank(i, name, v, settings)
                rec["attempts"] = attempt
                rec["error"] = f"{type(exc).__name__}: {exc}"
            fut.release()
            if rec["status"] == "failed" and attempt <= retries:
                retried += 1
                bar.update(False, retrying=True)
                g = client.submit(run_point, i, name, v, settings,
                                  _tighter(settings.rtol, attempt + 1), attempt + 1, pure=False)
                futs[g.key] = (i, v, attempt + 1)
                ac.add(g)
                continue
            records[i] = rec
            bar.update(rec["status"] != "failed")
        elapsed = time.perf_counter() - t1
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    recs = [records[i] for i in range(len(values))]
    return SweepResult(name, values, settings, recs, elapsed, startup, nthreads, label, retried)


def _accepts_n_workers(client) -> bool:
    import inspect

    return "n_workers" in inspect.signature(client.scheduler_info).parameters


# -- output -----------------------------------------------------------------------------------
def _axis_label(name: str) -> str:
    unit = sweepable().get(name, "")
    return f"{name} ({unit})" if unit and unit != "1" else name


def sweep_title(name: str, s: SweepSettings) -> str:
    """Figure title: what is swept and the operating point held (speed, torque, mu, the
    changed gear data) with the effects."""
    over = dict(s.params)
    held = [f"{s.speed_rpm:g} r/min" if name != "speed_rpm" else None,
            f"{s.torque:g} N.m" if name != "torque" else None,
            f"mu {over.get('mu', GearParams().mu):g}" if name != "mu" else None]
    held += [f"{k} {v:g}" for k, v in over.items() if k not in ("mu", name)]
    eff = f"friction {s.friction}, stiffness {s.stiffness}, sliding {s.sliding}, tie {s.stick_tie}"
    if not s.separation:
        eff += ", no separation"
    return (f"sweep of {name} at {', '.join(h for h in held if h)}\n{eff}; "
            f"rtol {s.rtol:g}")


def plot_sweep(result: SweepResult, path: str | Path, title: str | None = None) -> Path:
    """Ratios against the swept value (Figs. 15, 17, 18) over the Poincare section of the DTE
    (Fig. 16); failed points are red crosses on the axis, invalid ones (refused values,
    outside the model) grey ones; neither takes part in the axis scaling."""
    from matplotlib.figure import Figure

    x = np.array(result.values)
    ok = np.array([r["status"] == "ok" for r in result.records])
    fig = Figure(figsize=(7.0, 6.5), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.plot(x[ok], result.column("stick_ratio")[ok], "o-", ms=3, label="stick ratio $r_k$")
    ax1.plot(x[ok], result.column("contact_loss_ratio")[ok], "s-", ms=3,
             label="contact-loss ratio $r_l$")
    bad = np.array([r["status"] == "failed" for r in result.records])
    inval = np.array([r["status"] == "invalid" for r in result.records])
    if bad.any():
        ax1.plot(x[bad], np.zeros(bad.sum()), "rx", ms=8, label="failed point")
    if inval.any():
        ax1.plot(x[inval], np.zeros(inval.sum()), "x", color="0.5", ms=8,
                 label="invalid (outside the model)")
    ax1.set_ylabel("ratio (Eqs. 26-27)")
    ax1.legend(loc="best", fontsize=8)
    ax1.grid(alpha=0.3)
    for r, v in zip(result.records, x, strict=True):
        if r["poincare"] and r["status"] == "ok":
            p = np.asarray(r["poincare"]) * 1e6
            ax2.plot(np.full(p.size, v), p, ",", color="k", alpha=0.6)
            ax2.plot([v], [p[0]], ".", ms=1.5, color="k")
    ax2.set_xlabel(_axis_label(result.name))
    ax2.set_ylabel("DTE, one sample per mesh period (um)")
    ax2.grid(alpha=0.3)
    s = result.settings
    fig.suptitle(title or sweep_title(result.name, s), fontsize=10)
    fig.savefig(path, dpi=120)
    return Path(path)


# -- command line -----------------------------------------------------------------------------
def parse_values(text: str) -> list[float]:
    """``"a,b,c"`` or ``"start:stop:num"`` (num evenly spaced values, both ends included)."""
    text = text.strip()
    if ":" in text:
        parts = text.split(":")
        if len(parts) != 3:
            raise ValueError(f"values {text!r}: use start:stop:num")
        try:
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
        except ValueError:
            raise ValueError(f"values {text!r}: use start:stop:num with numbers start, stop "
                             "and a whole number num, e.g. 2:600:300") from None
        if n < 1:
            raise ValueError(f"values {text!r}: num must be >= 1")
        return [float(v) for v in np.linspace(a, b, n)]
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"values {text!r}: numbers separated by commas expected") from None


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``gearpair sweep`` on an argparse subparsers object."""
    d = SweepSettings()
    s = sub.add_parser(
        "sweep", help="stick/contact-loss ratios and bifurcation data over a parameter (dask)",
        description="Sweep one parameter; writes PREFIX.csv, PREFIX_poincare.csv, PREFIX.json "
                    "and PREFIX.png. Example: gearpair sweep speed_rpm 5:600:300 --out speed")
    from .effects import FRICTION_LAWS, SLIDING_VARIANTS, STICK_TIES, STIFFNESS_KINDS
    from .params import RTOL_MAX

    s.add_argument("param", help="what to sweep: speed_rpm (r/min), torque (N.m) or a "
                   "GearParams field in SI units (e.g. mu, kb1, module)")
    s.add_argument("values", help="a,b,c or start:stop:num (num evenly spaced values, both "
                   "ends included), in the unit of PARAM")
    s.add_argument("--out", default="sweep", metavar="PREFIX", help="output prefix: writes "
                   "PREFIX.csv, PREFIX_poincare.csv, PREFIX.json, PREFIX.png (its folder is "
                   "created; checked for writing before the run); default sweep")
    s.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running dask scheduler (tcp://host:port); 'serial' runs "
                   "in this process; default: a local cluster of --workers processes")
    s.add_argument("--workers", type=int, default=None, metavar="N",
                   help="local worker processes; default: the number of CPU cores")
    s.add_argument("--retries", type=int, default=1, metavar="N",
                   help="reruns of a failed point, each with a ten times tighter rtol; "
                   "default 1")
    s.add_argument("--torque", type=float, default=d.torque, metavar="NM",
                   help=f"driving torque on gear 1 when not swept (N.m); default {d.torque:g}")
    s.add_argument("--speed-rpm", type=float, default=d.speed_rpm, metavar="RPM",
                   help=f"speed of gear 1 when not swept (r/min); default {d.speed_rpm:g}")
    s.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="change a GearParams field (SI), e.g. --set mu=0.03; repeatable; "
                   "default: Table 1")
    s.add_argument("--friction", default=d.friction, choices=FRICTION_LAWS,
                   help="friction law: stick_slip (the paper's model), nominal (the slip "
                   f"model), regularized or off; default {d.friction}")
    s.add_argument("--stick-tie", default=d.stick_tie, choices=STICK_TIES,
                   help=f"how stuck teeth move together: exact (v = 0) or paper (Eq. 19); "
                   f"default {d.stick_tie}")
    s.add_argument("--sliding", default=d.sliding, choices=SLIDING_VARIANTS,
                   help=f"sliding velocity: paper (Eq. 12) or full; default {d.sliding}")
    s.add_argument("--stiffness", default=d.stiffness,
                   choices=[k for k in STIFFNESS_KINDS if k != "table"],
                   help=f"mesh stiffness law; default {d.stiffness}")
    s.add_argument("--no-separation", action="store_true",
                   help="teeth never separate (a linear mesh spring); default: they do")
    s.add_argument("--rtol", type=float, default=d.rtol,
                   help=f"relative tolerance of the fast engine, [{RTOL_MIN:g}, "
                   f"{RTOL_MAX:g}]; default {d.rtol:g}")
    s.add_argument("--steps-per-period", type=int, default=d.steps_per_period, metavar="N",
                   help="engine steps (samples) per mesh period for the DTE and mesh force "
                   f"statistics; default {d.steps_per_period}")
    s.add_argument("--transient-periods", type=int, default=d.transient_periods, metavar="N",
                   help=f"mesh periods discarded before the kept ones; default "
                   f"{d.transient_periods}")
    s.add_argument("--transient-time", type=float, default=d.transient_time, metavar="S",
                   help=f"discard at least this many seconds (s); default {d.transient_time:g}")
    s.add_argument("--kept-periods", type=int, default=d.kept_periods, metavar="N",
                   help=f"mesh periods kept for ratios and the Poincare section; default "
                   f"{d.kept_periods}")
    s.add_argument("--max-time", type=float, default=d.max_time, metavar="S",
                   help="soft cap of simulated seconds per point (s; both period counts are "
                   f"cut, never below {d.min_periods}); default {d.max_time:g}")
    s.add_argument("--no-plot", action="store_true", help="do not draw PREFIX.png; default: "
                   "draw it (needs matplotlib)")
    s.add_argument("--quiet", action="store_true", help="no progress line on stderr")
    return s


def settings_from_args(args) -> SweepSettings:
    over = []
    for item in args.set:
        k, sep, v = item.partition("=")
        if not sep:
            raise ValueError(f"--set {item!r}: use NAME=VALUE")
        over.append((k.strip(), float(v)))
    return SweepSettings(
        torque=args.torque, speed_rpm=args.speed_rpm, params=tuple(over),
        friction=args.friction, stick_tie=args.stick_tie, sliding=args.sliding,
        stiffness=args.stiffness, separation=not args.no_separation, rtol=args.rtol,
        steps_per_period=args.steps_per_period, transient_periods=args.transient_periods,
        transient_time=args.transient_time, kept_periods=args.kept_periods,
        max_time=args.max_time)


def main(args) -> int:
    """``gearpair sweep``: run, write the files, report the throughput; exit status 1 when a
    point failed or was invalid (it is in the CSV with its error)."""
    settings = settings_from_args(args)
    # Check names and the held values here, so a typo fails before a cluster starts.
    settings.inputs("speed_rpm", settings.speed_rpm)
    values = parse_values(args.values)
    # the heaviest tooth load of the sweep, once, before the run (a GearDataWarning line)
    from .geometry import unit_load, warn_implausible_load

    points = []
    for v in values:
        try:
            points.append(settings.inputs(args.param, v))
        except ValueError:  # refused at its run: an `invalid` record, not an error here
            pass
    if points:
        p, _, torque, _ = max(points, key=lambda pt: unit_load(pt[0], pt[2]))
        warn_implausible_load(p, torque)
    # every output file before the run, not after it (`SweepResult.write` names them)
    from .writable import check_writable

    prefix = Path(args.out)
    names = [prefix.with_suffix(".csv"), Path(f"{prefix}_poincare.csv"),
             prefix.with_suffix(".json")] + ([] if args.no_plot else [prefix.with_suffix(".png")])
    for name in names:
        check_writable("--out", name, shown=args.out)
    res = run_sweep(args.param, values, settings, scheduler=args.scheduler,
                    workers=args.workers, retries=args.retries, progress=not args.quiet)
    files = res.write(args.out, plot=not args.no_plot)
    print(res.report(), file=sys.stderr)
    print(json.dumps({"files": files, **{k: v for k, v in res.summary().items()
                                         if k != "settings"}}, indent=2, default=str))
    return 1 if res.failed or res.invalid else 0
