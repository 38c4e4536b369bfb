"""Rows of the plain scipy implementation a user would write (`gearpair.bench.plain_scipy`)."""

from __future__ import annotations

from . import plain_scipy
from .runs import Timing, _errors, clock, relative_error, time_limit
from .settings import FRICTION_OF, PLAIN_PREFIX, STIFFNESS_OF, Progress, Settings, _quiet
from .work_precision import _FAILED, _NO_ERRORS, _row


def plain_run(regime: str, method: str, rtol: float, t_end: float,
              dt: float) -> tuple[Timing, dict]:
    """One plain run from the static start at the default point, recorded every ``dt``;
    the model's construction (parameters, stiffness spline) is not timed."""
    model = plain_scipy.PlainGearPair(FRICTION_OF[regime], rtol, method,
                                      stiffness=STIFFNESS_OF[regime])
    t0 = clock()
    got = model.simulate(t_end, dt)
    return clock() - t0, {k: got[k] for k in ("time", "dte", "mesh_force")}


def plain_rows(s: Settings, refs: dict, progress: Progress = _quiet
               ) -> tuple[list[dict], list[dict]]:
    """Work-precision rows (methods ``plain <scipy method>``, over ``s.horizon``) and the
    cross-check of plain DOP853 at ``ref_rtol`` against the reference over the same
    ``s.horizon``, every regime of the work-precision tables."""
    rows, checks = [], []
    for regime in s.wp_regimes:
        for method, rtols in s.plain_rtols:
            for rtol in rtols:
                rows.append(_plain_row(s, refs[regime], regime, method, rtol))
                r = rows[-1]
                progress(f"plain scipy {method} {regime} rtol {rtol:g}: " + (
                    f"failed: {r['error']}" if r["error"] else
                    f"{r['wall_per_sim_s']:.2f} s per simulated s, DTE error "
                    f"{r['err_dte']:.1e}"))
        if s.check_horizon > 0 and regime in s.check_regimes:
            checks.append(_plain_check(s, refs[regime], regime))
    return rows, checks


def _plain_row(s: Settings, ref: dict, regime: str, method: str, rtol: float) -> dict:
    name = PLAIN_PREFIX + method
    try:
        with time_limit(s.run_budget):
            took, sig = plain_run(regime, method, rtol, s.horizon, s.dt)
    except Exception as exc:  # noqa: BLE001 - code as a user writes it: any failure is a row
        return _row(regime, name, f"rtol {rtol:g}", rtol, s.dt, s.horizon, _FAILED,
                    _NO_ERRORS, f"{type(exc).__name__}: {exc}")
    return _row(regime, name, f"rtol {rtol:g}", rtol, s.dt, s.horizon, took,
                _errors(sig, ref, s.window(regime)))


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
