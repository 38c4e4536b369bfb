"""Work-precision: the reference, the rows of every method, equal accuracy, step costs."""

from __future__ import annotations

import math
import time

from .runs import (
    NEVER,
    Timing,
    _errors,
    _record_calls,
    clock,
    engine_run,
    regime_effects,
    relative_error,
    time_limit,
)
from .settings import (
    PLAIN_PREFIX,
    REGIMES,
    SCIPY_MAX_EVENTS,
    SCIPY_METHODS,
    TARGET_ERROR,
    Progress,
    Settings,
    _quiet,
)


def references(s: Settings, progress: Progress = _quiet) -> tuple[dict, list[dict]]:
    """Tight reference per regime (fast core at ``ref_rtol`` over the longest horizon) and
    its cross-check against scipy DOP853 at the same tolerance over ``check_horizon``.

    Returns ``(refs, checks)``: refs maps a regime to ``time``, ``dte``, ``mesh_force`` arrays
    and ``dt``; checks are rows (regime, horizon, wall times, DTE and force differences).
    """
    refs, checks = {}, []
    t_ref = max([s.horizon, *dict(s.windows).values()])
    for regime in dict.fromkeys((*REGIMES, *s.wp_regimes)):
        took, sig = engine_run(regime, "fast", t_ref, s.dt, rtol=s.ref_rtol)
        refs[regime] = {**sig, "dt": s.dt, "wall_s": took.wall}
        progress(f"reference {regime}: fast core rtol {s.ref_rtol:g}, {t_ref:g} s simulated "
                 f"in {took.wall:.2f} s")
    if s.check_horizon > 0:
        for regime in (r for r in s.check_regimes if r in refs):
            took, sig = engine_run(regime, "reference", s.check_horizon, s.dt,
                                   rtol=s.ref_rtol, method="DOP853")
            wall = took.wall
            ref = refs[regime]
            checks.append({
                "regime": regime, "engine": "reference DOP853", "horizon_s": s.check_horizon,
                "rtol": s.ref_rtol,
                "dop853_wall_per_sim_s": wall / s.check_horizon,
                "fast_wall_per_sim_s": ref["wall_s"] / t_ref,
                "diff_dte": relative_error(sig["time"], sig["dte"], ref, "dte"),
                "diff_force": relative_error(sig["time"], sig["mesh_force"], ref, "mesh_force"),
            })
            progress(f"cross-check {regime}: DOP853 rtol {s.ref_rtol:g} differs by "
                     f"{checks[-1]['diff_dte']:.1e} (DTE) in {wall:.1f} s")
    return refs, checks


_NO_ERRORS = dict.fromkeys(("err_dte", "err_force", "err_dte_horizon", "err_force_horizon"),
                           math.nan)



def _row(regime, method, setting, rtol, step, horizon, took: Timing, errs,
         error=None) -> dict:
    return {"regime": regime, "method": method, "setting": setting, "rtol": rtol,
            "step": step, "horizon_s": horizon, "wall_s": took.wall, "cpu_s": took.cpu,
            "wall_per_sim_s": took.wall / horizon, "cpu_per_sim_s": took.cpu / horizon,
            **errs, "error": error}


_FAILED = Timing(math.nan, math.nan)


def engine_rows(s: Settings, refs: dict, progress: Progress = _quiet) -> list[dict]:
    """Work-precision rows of the fast core and of the scipy methods, every regime of the
    work-precision tables."""
    rows = []
    for regime in s.wp_regimes:
        w = s.window(regime)
        for step in s.fast_steps:
            for rtol in s.fast_rtols:
                rows.append(_engine_row(regime, "fast", rtol, s.horizon, s, refs[regime],
                                        step))
        for alt in s.fast_alt_methods:
            for rtol in s.fast_rtols:
                rows.append(_engine_row(regime, f"fast {alt}", rtol, s.horizon, s,
                                        refs[regime]))
        progress(f"fast core {regime}: {len(s.fast_rtols)} tolerances")
        for method, rtols in s.scipy_rtols:
            for rtol in rtols:
                r = _engine_row(regime, method, rtol, w, s, refs[regime])
                rows.append(r)
                progress(f"scipy {method} {regime} rtol {rtol:g}: " + (
                    f"failed: {r['error']}" if r["error"] else
                    f"{r['wall_per_sim_s']:.0f} s per simulated s, DTE error "
                    f"{r['err_dte']:.1e}"))
    return rows


def _engine_row(regime: str, method: str, rtol: float, horizon: float, s: Settings,
                ref: dict, step: float | None = None) -> dict:
    """One work-precision row of an engine run; a failed run is a row with ``error``.

    ``step``: communication step (default the common output grid ``s.dt``); the fast core
    stepped at another one is the method ``fast (step h)``. A fast-core row is timed once
    here and again by `retime_fast` (its ``options`` say how), in the rounds of the plain
    scipy rows.
    """
    step = s.dt if step is None else step
    if method.split()[0] == "fast":
        engine, opts, repeats = "fast", {"rtol": rtol}, 1
        if method != "fast":  # another Runge-Kutta pair: "fast dp5"
            opts["method"] = method.split()[1]
        if step != s.dt:
            method = f"fast (step {step:g})"
    else:
        # a stall (switches chattering at one instant) fails fast instead of running on
        engine, repeats = "reference", 1
        opts = {"rtol": rtol, "method": method, "max_events": SCIPY_MAX_EVENTS}
    try:
        with time_limit(s.run_budget):
            took, sig = engine_run(regime, engine, horizon, step, repeats, **opts)
    except (RuntimeError, ArithmeticError, ValueError) as exc:
        return _row(regime, method, f"rtol {rtol:g}", rtol, step, horizon, _FAILED,
                    _NO_ERRORS, f"{type(exc).__name__}: {exc}")
    row = _row(regime, method, f"rtol {rtol:g}", rtol, step, horizon, took,
               _errors(sig, ref, s.window(regime)))
    if engine == "fast":
        row["options"] = opts
    return row


def retime_fast(rows: list[dict]) -> None:
    """Run every fast-core row of ``rows`` once more and keep, per clock, the shorter time
    (the runs are deterministic: the signals and errors stay). `plain.plain_rows` calls it
    before each of its rounds after the first, so both sides of the speed claim are the
    best of as many runs spread over the same minutes of a shared machine."""
    for r in rows:
        if "options" not in r or r["error"]:
            continue
        took, _ = engine_run(r["regime"], "fast", r["horizon_s"], r["step"], 1,
                             **r["options"])
        r["wall_s"], r["cpu_s"] = min(r["wall_s"], took.wall), min(r["cpu_s"], took.cpu)
        r["wall_per_sim_s"] = r["wall_s"] / r["horizon_s"]
        r["cpu_per_sim_s"] = r["cpu_s"] / r["horizon_s"]


def equal_accuracy(rows: list[dict], target: float = TARGET_ERROR) -> list[dict]:
    """Per regime of ``rows`` (in their order): each method's cheapest row (by wall time)
    with DTE error <= ``target`` over the common window and over its whole run (None: not
    reached; a method without rows in the regime has no key), and the ratios to the fast
    core of the fastest scipy method run as the reference engine (``ratio``,
    ``fastest_scipy``) and of the fastest plain scipy implementation (``ratio_plain``,
    ``fastest_plain``: `gearpair.bench.plain_scipy`, what a user would write). The keys
    ending in ``_cpu`` are the same comparison in CPU time (each method's cheapest row by
    CPU time)."""
    out = []
    for regime in dict.fromkeys(r["regime"] for r in rows):
        # the target holds over the common window and over all the method ran: a switch
        # lost after the window (e.g. a short slip between two sticks) disqualifies a row
        mine = [r for r in rows if r["regime"] == regime and r["err_dte"] <= target
                and r["err_dte_horizon"] <= target]
        methods = dict.fromkeys(r["method"] for r in rows if r["regime"] == regime)
        entry: dict = {"regime": regime, "target_error": target}
        for clock_key, suffix in (("wall_per_sim_s", ""), ("cpu_per_sim_s", "_cpu")):
            best: dict[str, dict | None] = {}
            for method in methods:
                ok = [r for r in mine if r["method"] == method]
                b = min(ok, key=lambda r, k=clock_key: r[k]) if ok else None
                best[method] = None if b is None else {
                    k: b[k] for k in ("setting", "rtol", "step", "wall_per_sim_s",
                                      "cpu_per_sim_s", "err_dte", "err_force",
                                      "err_dte_horizon", "horizon_s")}
            entry["best" + suffix] = best
            for name, is_kind in (("", lambda m: m in SCIPY_METHODS),
                                  ("_plain", lambda m: m.startswith(PLAIN_PREFIX))):
                m, ratio = _fastest(best, is_kind, clock_key)
                entry["fastest" + (name or "_scipy") + suffix] = m
                entry["ratio" + name + suffix] = ratio
        out.append(entry)
    return out


def _fastest(best: dict, is_kind, clock_key: str) -> tuple[str | None, float | None]:
    """The cheapest method of a kind among ``best`` and its cost over the fast core's."""
    kind = {m: b for m, b in best.items() if is_kind(m) and b is not None}
    fast = best.get("fast")
    m = min(kind, key=lambda k: kind[k][clock_key]) if kind else None
    return m, None if m is None or fast is None else kind[m][clock_key] / fast[clock_key]


def core_step_costs(s: Settings, rtols: dict[str, list[float]], step: float = 1e-3) -> list[dict]:
    """Fast core stepped at ``step`` over ``step_horizon``: loop time (best of ``repeats``)
    recording the grid in one compiled call (``wall_per_sim_s``) and with one Python
    `advance` + `outputs` call per step as an FMU master drives it
    (``calls_wall_per_sim_s``), and the one-off engine construction, per regime and
    tolerance."""
    from .. import make_engine

    rows = []
    for regime in REGIMES:
        for rtol in rtols[regime]:
            t0 = time.perf_counter()
            make_engine(None, regime_effects(regime), "fast", rtol=rtol)
            build = time.perf_counter() - t0
            row = {"regime": regime, "rtol": rtol, "step": step, "horizon_s": s.step_horizon,
                   "wall_per_sim_s": None, "cpu_per_sim_s": None, "build_s": build,
                   "error": None}
            try:
                took, _ = engine_run(regime, "fast", s.step_horizon, step, s.repeats,
                                     rtol=rtol)
                row["wall_per_sim_s"] = took.wall / s.step_horizon
                row["cpu_per_sim_s"] = took.cpu / s.step_horizon
                calls = NEVER
                for _ in range(max(1, s.repeats)):
                    eng = make_engine(None, regime_effects(regime), "fast", rtol=rtol)
                    calls = calls.best(_record_calls(eng, s.step_horizon, step))
                row["calls_wall_per_sim_s"] = calls.wall / s.step_horizon
                row["calls_cpu_per_sim_s"] = calls.cpu / s.step_horizon
            except (RuntimeError, ArithmeticError, ValueError) as exc:
                row["error"] = f"{type(exc).__name__}: {exc}"
            rows.append(row)
    return rows


def engine_call_cost(n: int, step: float = 1e-3, repeats: int = 1) -> Timing:
    """Time per advance+outputs call of the fast core in the regime of the FMU call-cost
    measurement (6-DOF, constant stiffness, no friction), stepped ``step`` at a time."""
    from ..effects import Effects
    from ..fast import FastEngine
    from ..params import OperatingPoint

    op = OperatingPoint()
    best = NEVER
    for _ in range(max(1, repeats)):
        eng = FastEngine(None, Effects(stiffness="constant", friction="off"))
        eng.reset(0.0, op.torque, op.speed)
        eng.advance(step, op.torque, op.speed)
        eng.outputs()
        t0 = clock()
        for i in range(2, n + 2):
            eng.advance(i * step, op.torque, op.speed)
            eng.outputs()
        took = clock() - t0
        best = best.best(Timing(took.wall / n, took.cpu / n))
    return best



def accurate_rtol(rows: list[dict], regime: str, target: float = TARGET_ERROR) -> float | None:
    """The loosest fast-core tolerance whose DTE error on the common grid is <= ``target``."""
    ok = [r["rtol"] for r in rows if r["regime"] == regime and r["method"] == "fast"
          and r["err_dte"] <= target]
    return max(ok) if ok else None


def _step_rtols(rows: list[dict], extra: tuple[float, ...]) -> dict[str, list[float]]:
    out = {}
    for regime in REGIMES:
        rt = set(extra)
        acc = accurate_rtol(rows, regime)
        if acc is not None:
            rt.add(acc)
        out[regime] = sorted(rt, reverse=True)
    return out

