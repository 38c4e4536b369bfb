"""Figs. 15-18: stick and contact-loss ratios against speed, friction coefficient and torque,
and bifurcation diagrams of the slip and stick-slip models against speed.

Each figure is one or two `gearpair.sweep` runs on dask (a local cluster of worker processes
unless ``scheduler`` names one; ``"serial"`` runs in this process). Full settings: the
speed sweeps take 300 speeds over 2-600 r/min (0 r/min has no mesh period), the friction
sweep mu = 0-0.1 and the torque sweep 250-8000 N.m, both at 100 r/min. The sweep files
(``speed_stick_slip.csv`` ...) are written next to the figures and reused when the values and
settings match. ``quick`` runs a few short points serially (for tests).

    python examples/paper/parametric.py [--out DIR] [--quick] [--scheduler ADDRESS]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from common import (
    DEFAULT_OUT,
    MODEL_LABEL,
    SLIP,
    STICK,
    figure,
    quick_settings,
    save,
    sweep_cached,
)

from gearpair.sweep import SweepSettings


def speed_values(quick: bool) -> np.ndarray:
    return np.array([60.0, 150.0, 450.0]) if quick else np.linspace(2.0, 600.0, 300)


def mu_values(quick: bool) -> np.ndarray:
    return np.array([0.0, 0.01, 0.03]) if quick else np.linspace(0.0, 0.1, 41)


def torque_values(quick: bool) -> np.ndarray:
    return np.array([1000.0, 3900.0, 6000.0]) if quick else np.linspace(250.0, 8000.0, 32)


def _settings(quick: bool, **kw) -> SweepSettings:
    return quick_settings(**kw) if quick else SweepSettings(**kw)


def _sched(quick: bool, scheduler):
    return "serial" if quick and scheduler is None else scheduler


def speed_sweep(friction: str, out, quick: bool = False, scheduler=None, workers=None, **kw):
    """The speed sweep of one model (cached in ``out/speed_<friction>.*``)."""
    tag = f"speed_{'slip' if friction == SLIP else 'stick_slip'}" + ("_quick" if quick else "")
    return sweep_cached(out, tag, "speed_rpm", speed_values(quick),
                        _settings(quick, friction=friction, **kw), _sched(quick, scheduler),
                        workers)


def _ratios(res, xlabel: str, title: str, out, name: str, xscale: float = 1.0) -> Path:
    x = np.array(res.values) * xscale
    ok = np.array([r["status"] == "ok" for r in res.records])
    fig, ax = figure(figsize=(7.0, 3.8))
    ax.plot(x[ok], res.column("stick_ratio")[ok], "o-", ms=3, lw=1, label="stick ratio $r_k$")
    ax.plot(x[ok], res.column("contact_loss_ratio")[ok], "s-", ms=3, lw=1,
            label="contact-loss ratio $r_l$")
    if (~ok).any():
        ax.plot(x[~ok], np.zeros((~ok).sum()), "rx", ms=8, label="failed point")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("ratio (Eqs. (26)-(27))")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return save(fig, out, name)


def fig15_ratios_speed(out: str | Path = DEFAULT_OUT, quick: bool = False, scheduler=None,
                       workers=None) -> Path:
    """Fig. 15: ratios against speed (3900 N.m, mu = 0.02)."""
    res = speed_sweep(STICK, out, quick, scheduler, workers)
    return _ratios(res, "speed of gear 1 (r/min)",
                   "Fig. 15: stick and contact-loss ratios against speed (3900 N.m, mu 0.02)",
                   out, "fig15_ratios_speed.png")


def fig16_bifurcation(out: str | Path = DEFAULT_OUT, quick: bool = False, scheduler=None,
                      workers=None) -> Path:
    """Fig. 16: DTE sampled once per mesh period against speed, (a) slip, (b) stick-slip."""
    fig, axes = figure(2, 1, figsize=(7.0, 6.5), sharex=True)
    for ax, fr, lab in ((axes[0], SLIP, "(a)"), (axes[1], STICK, "(b)")):
        res = speed_sweep(fr, out, quick, scheduler, workers)
        xs, ys = [], []
        for r, v in zip(res.records, res.values, strict=True):
            xs.append(np.full(len(r["poincare"]), v))
            ys.append(np.asarray(r["poincare"]) * 1e6)
        if xs:
            ax.scatter(np.concatenate(xs), np.concatenate(ys), s=0.5, c="k", lw=0)
        stick = res.column("stick_ratio") > 0
        for v in np.array(res.values)[stick]:
            ax.axvline(v, color="C3", alpha=0.08, lw=2)
        ax.set_ylabel("DTE (um)")
        ax.set_title(f"{lab} {MODEL_LABEL[fr]}" + (" (red: speeds with stick)" if fr == STICK
                                                     else ""), fontsize=9)
        ax.grid(alpha=0.3)
    axes[1].set_xlabel("speed of gear 1 (r/min)")
    fig.suptitle("Fig. 16: bifurcation diagrams (one DTE sample per mesh period)", fontsize=10)
    return save(fig, out, "fig16_bifurcation.png")


def fig17_ratios_mu(out: str | Path = DEFAULT_OUT, quick: bool = False, scheduler=None,
                    workers=None) -> Path:
    """Fig. 17: ratios against the friction coefficient (3900 N.m, 100 r/min)."""
    res = sweep_cached(out, "mu" + ("_quick" if quick else ""), "mu", mu_values(quick),
                       _settings(quick), _sched(quick, scheduler), workers)
    return _ratios(res, "friction coefficient mu",
                   "Fig. 17: ratios against the friction coefficient (3900 N.m, 100 r/min)",
                   out, "fig17_ratios_mu.png")


def fig18_ratios_torque(out: str | Path = DEFAULT_OUT, quick: bool = False, scheduler=None,
                        workers=None) -> Path:
    """Fig. 18: ratios against the applied torque (100 r/min, mu = 0.02)."""
    res = sweep_cached(out, "torque" + ("_quick" if quick else ""), "torque",
                       torque_values(quick), _settings(quick), _sched(quick, scheduler), workers)
    return _ratios(res, "applied torque (N.m)",
                   "Fig. 18: ratios against the applied torque (100 r/min, mu 0.02)",
                   out, "fig18_ratios_torque.png")


FIGURES = (fig15_ratios_speed, fig16_bifurcation, fig17_ratios_mu, fig18_ratios_torque)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--scheduler", default=None)
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args(argv)
    for fn in FIGURES:
        print(fn(a.out, a.quick, a.scheduler, a.workers))


if __name__ == "__main__":
    main()
