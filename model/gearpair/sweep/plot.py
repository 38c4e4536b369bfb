"""Figures of a sweep."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..params import GearParams
from .settings import SweepSettings, sweepable

if TYPE_CHECKING:  # an annotation only: result.py imports this module to draw
    from .result import SweepResult


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


