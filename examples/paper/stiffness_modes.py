"""Figs. 4-6: mesh stiffness, and the mode shapes of the slip and stick models.

Fig. 4 of the paper is a finite-element stiffness curve that is not given; this project's
default is the potential-energy law scaled to the mean 4.05e9 N/m (README "Model choices").
Figs. 5-6 use the mean mesh stiffness (Theta = 1), the stick model stuck at the pitch point
(`gearpair.modal`).

    python examples/paper/stiffness_modes.py [--out DIR]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from common import DEFAULT_OUT, figure, save

from gearpair import Effects, GearParams, Model
from gearpair.modal import SLIP_NAMES, modes


def fig04_mesh_stiffness(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 4: per-pair and total mesh stiffness over two mesh periods (N/m against the
    rotation of gear 1 in mesh periods)."""
    m = Model.build(GearParams(), Effects())
    g, k = m.geom, m.stiff
    n = 201 if quick else 1201
    s = np.linspace(0.0, 2.0 * g.base_pitch, n)  # mesh travel: one base pitch per mesh period
    total = k.total(g, s)
    fig, ax = figure(figsize=(7.0, 3.8))
    for j in range(g.n_pairs):
        xi = np.mod(s + j * g.base_pitch, g.period_length)
        on = xi < g.path_length
        kj = np.where(on, k.pairs(np.minimum(xi, g.path_length), 1), np.nan)
        ax.plot(s / g.base_pitch, kj / 1e9, "--", lw=1, label=f"tooth pair {j + 1}")
    ax.plot(s / g.base_pitch, total / 1e9, "k-", lw=1.6, label="total $k_m(t)$")
    ax.axhline(k.km_mean / 1e9, color="0.5", lw=0.8, ls=":",
               label=f"mean {k.km_mean / 1e9:.2f}e9 N/m")
    ax.set_xlabel("rotation of gear 1 (mesh periods)")
    ax.set_ylabel("mesh stiffness (1e9 N/m)")
    ax.set_title(f"Fig. 4: mesh stiffness ({k.kind}), contact ratio {g.contact_ratio:.3f}",
                 fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)
    return save(fig, out, "fig04_mesh_stiffness.png")


def _mode_figure(which: str, out, name: str, title: str) -> Path:
    m = Model.build(GearParams(), Effects(stiffness="constant"))
    f, shapes = modes(m, which)
    n = len(f)
    fig, axes = figure(2, 3, figsize=(9.0, 5.2), sharey=True)
    axes = axes.ravel()
    x = np.arange(len(SLIP_NAMES))
    for i in range(6):
        ax = axes[i]
        if i >= n:
            ax.set_axis_off()
            ax.text(0.5, 0.5, "no 6th mode:\nx2 is tied to x1", ha="center", va="center",
                    transform=ax.transAxes, fontsize=9)
            continue
        ax.bar(x, shapes[:, i], color=["C0", "C0", "C1", "C2", "C2", "C3"])
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xticks(x, SLIP_NAMES)
        ax.set_title(f"mode {i + 1}: {f[i]:.1f} Hz", fontsize=9)
        ax.set_ylim(-1.1, 1.1)
        ax.grid(alpha=0.3, axis="y")
    fig.suptitle(title, fontsize=10)
    return save(fig, out, name)


def fig05_slip_modes(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 5: natural frequencies and mode shapes of the slip model (6 DOF, Eqs. (4)-(7))."""
    return _mode_figure("slip", out, "fig05_slip_modes.png",
                        "Fig. 5: slip model, mode shapes (largest component 1)")


def fig06_stick_modes(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 6: natural frequencies and mode shapes of the stick model (5 DOF, Eqs. (22)-(24),
    stuck at the pitch point), shown in the six coordinates (x2 follows x1)."""
    return _mode_figure("stick", out, "fig06_stick_modes.png",
                        "Fig. 6: stick model at the pitch point, mode shapes")


FIGURES = (fig04_mesh_stiffness, fig05_slip_modes, fig06_stick_modes)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    for fn in FIGURES:
        print(fn(a.out, a.quick))


if __name__ == "__main__":
    main()
