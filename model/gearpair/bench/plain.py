"""Rows of the plain scipy implementation a user would write (`gearpair.bench.plain_scipy`)."""

from __future__ import annotations

from . import plain_scipy
from .runs import Timing, _errors, clock, relative_error, time_limit
from .settings import FRICTION_OF, PLAIN_PREFIX, STIFFNESS_OF, Progress, Settings, _quiet
from .work_precision import _FAILED, _NO_ERRORS, _row, retime_fast


def plain_run(regime: str, method: str, rtol: float, t_end: float,
              dt: float) -> tuple[Timing, dict]:
    """One plain run from the static start at the default point, recorded every ``dt``;
    the model's construction (parameters, stiffness spline) is not timed."""
    model = plain_scipy.PlainGearPair(FRICTION_OF[regime], rtol, method,
                                      stiffness=STIFFNESS_OF[regime])
    t0 = clock()
    got = model.simulate(t_end, dt)
    return clock() - t0, {k: got[k] for k in ("time", "dte", "mesh_force")}


def plain_rows(s: Settings, refs: dict, progress: Progress = _quiet,
               fast_rows: list[dict] | None = None) -> tuple[list[dict], list[dict]]:
    """Work-precision rows (methods ``plain <scipy method>``, over ``s.horizon``) and the
    cross-check of plain DOP853 at ``ref_rtol`` against the reference over the same
    ``s.horizon``, every regime of the work-precision tables.

    Each row is the best of ``s.repeats`` runs, as the fast core's, taken in rounds that run
    every row once: a row's runs lie tens of seconds apart, so a stretch of load on a
    shared machine costs one of them, not all (the runs are deterministic: every round gives
    the same signals and errors). A run that fails in the first round is a failed row.
    ``fast_rows``: the fast core's work-precision rows, timed once already; each later round
    starts by timing them again (`work_precision.retime_fast`), so they too are the best of
    ``s.repeats`` runs spread over the same minutes."""
    jobs = [(regime, method, rtol) for regime in s.wp_regimes
            for method, rtols in s.plain_rtols for rtol in rtols]
    best: dict = {}
    failed: dict = {}
    rounds = max(1, s.repeats)
    for k in range(rounds):
        if k and fast_rows:
            retime_fast(fast_rows)
        for job in jobs:
            if job in failed:
                continue
            regime, method, rtol = job
            try:
                with time_limit(s.run_budget):
                    took, sig = plain_run(regime, method, rtol, s.horizon, s.dt)
            except Exception as exc:  # noqa: BLE001 - code as a user writes it: any failure is a row
                if job in best:  # over the budget in a later round: the earlier run stands
                    continue
                failed[job] = f"{type(exc).__name__}: {exc}"
                progress(f"plain scipy {method} {regime} rtol {rtol:g}: failed: "
                         f"{failed[job]}")
                continue
            if job in best:
                best[job] = (best[job][0].best(took), sig)
                continue
            best[job] = (took, sig)
            err = relative_error(sig["time"], sig["dte"], refs[regime], "dte")
            progress(f"plain scipy {method} {regime} rtol {rtol:g}: "
                     f"{took.wall / s.horizon:.2f} s per simulated s (round 1 of {rounds}), "
                     f"DTE error {err:.1e}")
        if rounds > 1:
            progress(f"plain scipy: round {k + 1} of {rounds} done" + (
                " (the fast core's rows timed again before it)" if k and fast_rows else ""))
    rows, checks = [], []
    for job in jobs:
        regime, method, rtol = job
        name, setting = PLAIN_PREFIX + method, f"rtol {rtol:g}"
        if job in failed:
            rows.append(_row(regime, name, setting, rtol, s.dt, s.horizon, _FAILED,
                             _NO_ERRORS, failed[job]))
        else:
            took, sig = best[job]
            rows.append(_row(regime, name, setting, rtol, s.dt, s.horizon, took,
                             _errors(sig, refs[regime], s.window(regime))))
    if s.check_horizon > 0:
        checks = [_plain_check(s, refs[r], r) for r in s.wp_regimes if r in s.check_regimes]
    return rows, checks


def _plain_check(s: Settings, ref: dict, regime: str) -> dict:
    """Plain DOP853 at the reference tolerance against the reference over the whole run of
    the work-precision rows (``s.horizon``, where equal accuracy is judged): two
    independent implementations of the model."""
    w = s.horizon
    took, sig = plain_run(regime, "DOP853", s.ref_rtol, w, s.dt)
    return {"regime": regime, "engine": PLAIN_PREFIX + "DOP853", "horizon_s": w,
            "rtol": s.ref_rtol, "dop853_wall_per_sim_s": took.wall / w,
            "fast_wall_per_sim_s": ref["wall_s"] / float(ref["time"][-1]),
            "diff_dte": relative_error(sig["time"], sig["dte"], ref, "dte"),
            "diff_force": relative_error(sig["time"], sig["mesh_force"], ref, "mesh_force")}
