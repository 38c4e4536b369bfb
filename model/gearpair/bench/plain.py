"""Rows of the plain scipy implementation a user would write (``benchmarks/plain_scipy.py``).

It lives in the repository, not in the package: an installed ``gearpair`` without the
repository has no such rows, and the report says so.
"""

from __future__ import annotations

import importlib.util
import sys

from .runs import Timing, _errors, clock, relative_error, time_limit
from .settings import FRICTION_OF, PLAIN_PREFIX, PLAIN_SCRIPT, REGIMES, Progress, Settings, _quiet
from .work_precision import _FAILED, _NO_ERRORS, _row

_MODULE = "gearpair_bench_plain_scipy"


def load_plain():
    """The module ``benchmarks/plain_scipy.py``, or None without the repository."""
    if _MODULE in sys.modules:
        return sys.modules[_MODULE]
    if not PLAIN_SCRIPT.is_file():
        return None
    spec = importlib.util.spec_from_file_location(_MODULE, PLAIN_SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[_MODULE] = mod  # its dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


def plain_run(mod, regime: str, method: str, rtol: float, t_end: float,
              dt: float) -> tuple[Timing, dict]:
    """One plain run from the static start at the default point, recorded every ``dt``;
    the model's construction (parameters, stiffness spline) is not timed."""
    model = mod.PlainGearPair(FRICTION_OF[regime], rtol, method)
    t0 = clock()
    got = model.simulate(t_end, dt)
    return clock() - t0, {k: got[k] for k in ("time", "dte", "mesh_force")}


def plain_rows(s: Settings, refs: dict, progress: Progress = _quiet
               ) -> tuple[list[dict], list[dict], str | None]:
    """Work-precision rows (methods ``plain <scipy method>``, over ``s.horizon``), the
    cross-check of plain DOP853 at ``ref_rtol`` against the reference over each regime's
    window, and a note when the rows are skipped."""
    mod = load_plain()
    if mod is None:
        return [], [], (f"plain scipy rows skipped: {PLAIN_SCRIPT.name} not found (an "
                        "installed package without the repository's benchmarks/ folder)")
    rows, checks = [], []
    for regime in REGIMES:
        for method, rtols in s.plain_rtols:
            for rtol in rtols:
                rows.append(_plain_row(mod, s, refs[regime], regime, method, rtol))
                r = rows[-1]
                progress(f"plain scipy {method} {regime} rtol {rtol:g}: " + (
                    f"failed: {r['error']}" if r["error"] else
                    f"{r['wall_per_sim_s']:.2f} s per simulated s, DTE error "
                    f"{r['err_dte']:.1e}"))
        if s.check_horizon > 0 and regime in s.check_regimes:
            checks.append(_plain_check(mod, s, refs[regime], regime))
    return rows, checks, None


def _plain_row(mod, s: Settings, ref: dict, regime: str, method: str, rtol: float) -> dict:
    name = PLAIN_PREFIX + method
    try:
        with time_limit(s.run_budget):
            took, sig = plain_run(mod, regime, method, rtol, s.horizon, s.dt)
    except Exception as exc:  # noqa: BLE001 - a script beside the package: any failure is a row
        return _row(regime, name, f"rtol {rtol:g}", rtol, s.dt, s.horizon, _FAILED,
                    _NO_ERRORS, f"{type(exc).__name__}: {exc}")
    return _row(regime, name, f"rtol {rtol:g}", rtol, s.dt, s.horizon, took,
                _errors(sig, ref, s.window(regime)))


def _plain_check(mod, s: Settings, ref: dict, regime: str) -> dict:
    """Plain DOP853 at the reference tolerance over the regime's window against the
    reference: two independent implementations of the model."""
    w = s.window(regime)
    took, sig = plain_run(mod, regime, "DOP853", s.ref_rtol, w, s.dt)
    return {"regime": regime, "engine": PLAIN_PREFIX + "DOP853", "horizon_s": w,
            "rtol": s.ref_rtol, "dop853_wall_per_sim_s": took.wall / w,
            "fast_wall_per_sim_s": ref["wall_s"] / float(ref["time"][-1]),
            "diff_dte": relative_error(sig["time"], sig["dte"], ref, "dte"),
            "diff_force": relative_error(sig["time"], sig["mesh_force"], ref, "mesh_force")}
