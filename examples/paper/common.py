"""Shared settings and helpers of the paper's figures (Xun, Dai & Wang 2023).

The figure modules (`stiffness_modes`, `time_response`, `parametric`) and `comparison` import
this module; run them as scripts (``python examples/paper/make_all.py``), which puts this folder on
``sys.path``. Plots use
matplotlib's object interface (no pyplot, no backend switch), imported inside functions.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from gearpair import RPM, Effects, GearParams, Geometry
from gearpair.analysis import mesh_period
from gearpair.sweep import SweepResult, SweepSettings, read_result, record_periods, run_sweep

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_OUT = ROOT / "build" / "paper"

# The operating point of the time responses (docs/model.md "Choices": not stated in the paper).
TORQUE = 3900.0      # N.m
SPEED_RPM = 100.0    # r/min
# The traditional slip model takes the friction direction from the nominal kinematics
# (`Effects.friction = "nominal"`); the paper's slip model with sign(v) has no solution where
# stick occurs (docs/model.md "Choices").
SLIP = "nominal"
STICK = "stick_slip"
MODEL_LABEL = {SLIP: "slip model", STICK: "stick-slip model"}


def figure(nrows: int = 1, ncols: int = 1, figsize=(7.0, 4.0), **kw):
    """A matplotlib Figure (not registered with pyplot) and its axes."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout="constrained")
    return fig, fig.subplots(nrows, ncols, **kw)


def save(fig, out: str | Path, name: str) -> Path:
    """Write ``fig`` as ``out/name`` (PNG, 120 dpi) and return the path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / name
    fig.savefig(path, dpi=120)
    return path


@functools.lru_cache(maxsize=16)
def response(friction: str, quick: bool, stick_tie: str = "exact", sliding: str = "paper",
             torque: float = TORQUE, speed_rpm: float = SPEED_RPM, mu: float | None = None,
             rtol: float = 1e-8) -> dict:
    """A steady time response at the operating point, finely sampled (Figs. 8-14).

    Discards 100 mesh periods (quick: 10) stepped 8 times per period, then records 64 mesh
    periods (quick: 8) at 800 samples per period (23 us at 100 r/min: about 14 samples per
    cycle of the 3 kHz mesh modes that ring after a pair enters contact). Returns the
    `record_periods` dict plus the nominal sliding velocity ``nominal_sliding`` (m/s) of the
    pair nearest the pitch point (the pair whose relative sliding velocity the engine
    reports) and ``xi_near`` (m from A).
    """
    p = GearParams() if mu is None else GearParams(mu=mu)
    fx = Effects(friction=friction, stick_tie=stick_tie, sliding=sliding)
    speed = speed_rpm * RPM
    n_t, n_k = (10, 8) if quick else (100, 64)
    rec = record_periods(p, fx, torque, speed, n_t, n_k, 800, rtol,
                         outputs=("dte", "mesh_force", "friction_force", "contact_state",
                                  "sliding_velocity"), transient_steps=8)
    g = Geometry.from_params(p)
    s = p.rb1 * speed * rec["time"]  # mesh travel since the reset (m)
    xi = np.mod(s[:, None] + np.arange(g.n_pairs)[None, :] * g.base_pitch, g.period_length)
    xi = np.where(xi < g.path_length, xi, np.inf)  # pairs out of contact
    near = xi[np.arange(len(s)), np.argmin(np.abs(xi - g.xi_pitch), axis=1)]
    s1m = g.s1a + near
    rec["xi_near"] = near
    # Eq. (12) without vibration: Omega2 S2M - Omega1 S1M
    rec["nominal_sliding"] = speed * (p.ratio * (g.s1s2 - s1m) - s1m)
    rec["mesh_frequency"] = 1.0 / mesh_period(p.z1, speed)
    return rec


def sweep_cached(out: str | Path, tag: str, name: str, values, settings: SweepSettings,
                 scheduler: str | None = None, workers: int | None = None,
                 progress: bool = True) -> SweepResult:
    """Run a sweep, or read it back from ``out/tag.*`` when those files hold the same values
    and settings (so the figures and the comparison reuse one long run)."""
    prefix = Path(out) / tag
    values = [float(v) for v in values]
    if prefix.with_suffix(".json").exists():
        try:
            old = read_result(prefix)
            if old.settings == settings and np.allclose(old.values, values, rtol=0, atol=1e-9):
                return old
        except (KeyError, ValueError, TypeError, OSError):
            pass  # unreadable or from another version: run again
    res = run_sweep(name, values, settings, scheduler=scheduler, workers=workers,
                    progress=progress)
    res.write(prefix, plot=False)
    return res


def quick_settings(**kw) -> SweepSettings:
    """Short sweep points for tests: 10 discarded and 10 kept mesh periods, no time floor."""
    return SweepSettings(transient_periods=10, transient_time=0.0, kept_periods=10,
                         max_time=0.5, min_periods=4, **kw)
