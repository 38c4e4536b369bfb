"""One sweep point: the fast engine over the discarded and kept mesh periods, and the record
of ratios, Poincare section, mesh-force statistics and cost it returns (never raises)."""

from __future__ import annotations

import math
import os
import socket
import time
from typing import Any

import numpy as np

from .. import analysis
from ..effects import Effects
from ..engine import RunFailure
from ..params import RPM, GearParams
from .settings import SweepSettings, _boundary_phases, outside_validity

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
    from .. import make_engine

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


def run_point(index: int, name: str | tuple[str, ...], value: float | tuple[float, ...],
              settings: SweepSettings, rtol: float | None = None,
              attempt: int = 1) -> dict[str, Any]:
    """Run one sweep point; never raises (an error becomes ``status = failed``).

    ``name = value`` is the swept parameter and its value, or for a point of a grid the
    tuples of the names and the values.

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
        point = dict(zip(name, value, strict=True)) if isinstance(name, tuple) \
            else {name: value}
        params, effects, torque, speed = settings.inputs_at(point)
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
    except RunFailure as exc:  # missed event or unbounded response: not a value to draw,
        rec["status"] = "invalid"  # and a tighter rtol is not what it needs (issue 38)
        rec["error"] = f"RunFailure: {exc}"
    except Exception as exc:  # noqa: BLE001 - every failure becomes a reported record
        rec["status"] = "failed"
        rec["error"] = f"{type(exc).__name__}: {exc}"
    # wall time over CPU time shows how much a worker waited for a shared core
    rec["wall_s"] = time.perf_counter() - t_wall
    rec["cpu_s"] = time.process_time() - t_cpu
    return rec


def _warm() -> None:
    """Load (or compile once, ~25 s) the fast engine's kernels in this process, so that local
    workers find them in the on-disk cache instead of compiling in parallel."""
    from .. import make_engine

    eng = make_engine(GearParams(), Effects(), "fast", rtol=1e-6)
    eng.reset(0.0, 3900.0, 100 * RPM)
    eng.advance(1e-4, 3900.0, 100 * RPM)


