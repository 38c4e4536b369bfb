"""Figs. 8-14: velocities, mesh force, friction and DTE of the slip and stick-slip models.

Operating point 3900 N.m, 100 r/min, Table 1 (mu = 0.02); steady response after 100 mesh
periods (`common.response`). "Slip model" is the traditional model with the friction
direction taken from the nominal kinematics; "stick-slip model" is the paper's model with
the exact tie (`Effects()` defaults). Periods A and B are two adjacent mesh periods, as in
the paper's Figs. 9, 11 and 13.

    python examples/paper/time_response.py [--out DIR] [--quick]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from common import DEFAULT_OUT, MODEL_LABEL, SLIP, STICK, figure, response, save

from gearpair.analysis import amplitude_spectrum, order_amplitudes

N_SHOW = 4  # mesh periods shown in the time plots


def _window(rec: dict, periods: int = N_SHOW, start: int = 0) -> slice:
    n = rec["steps_per_period"]
    return slice(start * n, (start + periods) * n)


def _t_ms(rec: dict, w: slice) -> np.ndarray:
    return (rec["time"][w] - rec["time"][0]) * 1e3


def _velocities(rec: dict, title: str, out, name: str) -> Path:
    w = _window(rec)
    t = _t_ms(rec, w)
    v, nom = rec["sliding_velocity"][w], rec["nominal_sliding"][w]
    stuck = rec["contact_state"][w] == 2
    fig, (ax, axz) = figure(2, 1, figsize=(7.0, 6.0))
    ax.plot(t, nom, color="0.5", lw=1, label="nominal sliding velocity (Eq. (12) without x')")
    ax.plot(t, v - nom, color="C1", lw=0.8, label="vibration part $\\dot x_1 - \\dot x_2$")
    ax.plot(t, v, color="C0", lw=1, label="relative sliding velocity $v_r$")
    if stuck.any():
        ax.plot(t[stuck], v[stuck], "k.", ms=3, label="stick")
    ax.set_ylabel("velocity (m/s)")
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(alpha=0.3)
    # zoom on the reversal near the pitch point in the first period shown
    i0 = int(np.argmin(np.abs(nom[: rec["steps_per_period"]])))
    n = rec["steps_per_period"]
    z = slice(max(i0 - n // 10, 0), min(i0 + n // 10, len(t)))
    axz.plot(t[z], nom[z], color="0.5", lw=1)
    axz.plot(t[z], v[z], color="C0", lw=1)
    if stuck[z].any():
        axz.plot(t[z][stuck[z]], v[z][stuck[z]], "k.", ms=4)
    axz.axhline(0.0, color="k", lw=0.6)
    axz.set_xlabel("time in the steady window (ms)")
    axz.set_ylabel("velocity (m/s)")
    axz.set_title("near the pitch point", fontsize=9)
    axz.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    return save(fig, out, name)


def fig08_velocities_slip(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 8: sliding velocity of the pair nearest the pitch point, slip model."""
    return _velocities(response(SLIP, quick), "Fig. 8: velocities of the slip model", out,
                       "fig08_velocities_slip.png")


def fig09_velocities_stick_slip(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 9: the same for the stick-slip model; dots mark stick (v_r = 0)."""
    return _velocities(response(STICK, quick), "Fig. 9: velocities of the stick-slip model",
                       out, "fig09_velocities_stick_slip.png")


def _periods_ab(rec: dict, key: str, scale: float, ylabel: str, title: str, out,
                name: str) -> Path:
    """Four mesh periods, then the adjacent periods A and B side by side."""
    n = rec["steps_per_period"]
    w = _window(rec)
    t = _t_ms(rec, w)
    y = rec[key][w] * scale
    state = rec["contact_state"][w]
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 5.6), layout="constrained")
    ax = fig.subplot_mosaic([["top", "top"], ["A", "B"]])
    top, axes = ax["top"], [ax["A"], ax["B"]]
    top.plot(t, y, lw=1)
    for code, style, lab in ((2, "k.", "stick"), (0, "r.", "contact loss")):
        sel = state == code
        if sel.any():
            top.plot(t[sel], y[sel], style, ms=2, label=lab)
    top.axvspan(t[0], t[n - 1], color="C2", alpha=0.08)
    top.axvspan(t[n], t[2 * n - 1], color="C3", alpha=0.08)
    top.text(t[n // 2], top.get_ylim()[1], "A", ha="center", va="top")
    top.text(t[n + n // 2], top.get_ylim()[1], "B", ha="center", va="top")
    top.set_ylabel(ylabel)
    top.grid(alpha=0.3)
    if (state != 1).any():
        top.legend(fontsize=7, loc="upper right")
    for k, (ax, lab) in enumerate(zip(axes, "AB", strict=True)):
        s = slice(k * n, (k + 1) * n)
        ax.plot(t[s], y[s], lw=1)
        for code, style in ((2, "k."), (0, "r.")):
            sel = state[s] == code
            if sel.any():
                ax.plot(t[s][sel], y[s][sel], style, ms=2)
        ax.set_title(f"mesh period {lab}", fontsize=9)
        ax.set_xlabel("time (ms)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(ylabel)
    fig.suptitle(title, fontsize=10)
    return save(fig, out, name)


def fig10_mesh_force_slip(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 10: mesh force of the slip model (the paper: 25-60 kN)."""
    rec = response(SLIP, quick)
    w = _window(rec)
    fig, ax = figure(figsize=(7.0, 3.6))
    ax.plot(_t_ms(rec, w), rec["mesh_force"][w] / 1e3, lw=1)
    f = rec["mesh_force"] / 1e3
    ax.set_title(f"Fig. 10: mesh force of the slip model: {f.min():.1f}-{f.max():.1f} kN "
                 "(paper 25-60 kN)", fontsize=10)
    ax.set_xlabel("time in the steady window (ms)")
    ax.set_ylabel("mesh force (kN)")
    ax.grid(alpha=0.3)
    return save(fig, out, "fig10_mesh_force_slip.png")


def fig11_mesh_force_stick_slip(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 11: mesh force of the stick-slip model, periods A and B."""
    return _periods_ab(response(STICK, quick), "mesh_force", 1e-3, "mesh force (kN)",
                       "Fig. 11: mesh force of the stick-slip model", out,
                       "fig11_mesh_force_stick_slip.png")


def fig12_friction_slip(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 12: total friction force of the slip model."""
    rec = response(SLIP, quick)
    w = _window(rec)
    fig, ax = figure(figsize=(7.0, 3.6))
    ax.plot(_t_ms(rec, w), rec["friction_force"][w] / 1e3, lw=1)
    ax.set_title("Fig. 12: friction of the slip model (direction from the nominal kinematics)",
                 fontsize=10)
    ax.set_xlabel("time in the steady window (ms)")
    ax.set_ylabel("friction force (kN)")
    ax.grid(alpha=0.3)
    return save(fig, out, "fig12_friction_slip.png")


def fig13_friction_stick_slip(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 13: friction (sliding or static) of the stick-slip model, periods A and B."""
    return _periods_ab(response(STICK, quick), "friction_force", 1e-3, "friction force (kN)",
                       "Fig. 13: friction of the stick-slip model (static while stuck)", out,
                       "fig13_friction_stick_slip.png")


def dte_orders(quick: bool = False) -> dict[str, dict[float, float]]:
    """DTE amplitudes (um) at mesh orders 0.5, 1, 1.5, 2, 3 of both models (Fig. 14(b))."""
    out = {}
    for fr in (SLIP, STICK):
        rec = response(fr, quick)
        out[fr] = {k: v * 1e6 for k, v in order_amplitudes(
            rec["dte"], rec["steps_per_period"], (0.5, 1.0, 1.5, 2.0, 3.0)).items()}
    return out


def fig14_dte(out: str | Path = DEFAULT_OUT, quick: bool = False) -> Path:
    """Fig. 14: DTE of both models (a) over four mesh periods, (b) amplitude spectrum in
    orders of the mesh frequency (whole, even number of periods: exact half orders)."""
    fig, (ax, axs) = figure(2, 1, figsize=(7.0, 6.0))
    for fr, c in ((SLIP, "C0"), (STICK, "C3")):
        rec = response(fr, quick)
        w = _window(rec)
        ax.plot(_t_ms(rec, w), rec["dte"][w] * 1e6, color=c, lw=1, label=MODEL_LABEL[fr])
        n = rec["steps_per_period"]
        f, a = amplitude_spectrum(rec["dte"], 1.0 / n)  # frequency in mesh orders
        sel = (f > 0) & (f <= 5.0)
        axs.plot(f[sel], a[sel] * 1e6, color=c, lw=1, marker=".", ms=3, label=MODEL_LABEL[fr])
    ax.set_xlabel("time in the steady window (ms)")
    ax.set_ylabel("DTE (um)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    axs.set_yscale("log")
    axs.set_xlabel("frequency / mesh frequency")
    axs.set_ylabel("DTE amplitude (um)")
    axs.legend(fontsize=8)
    axs.grid(alpha=0.3)
    fig.suptitle("Fig. 14: DTE of the slip and stick-slip models", fontsize=10)
    return save(fig, out, "fig14_dte.png")


FIGURES = (fig08_velocities_slip, fig09_velocities_stick_slip, fig10_mesh_force_slip,
           fig11_mesh_force_stick_slip, fig12_friction_slip, fig13_friction_stick_slip,
           fig14_dte)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    for fn in FIGURES:
        print(fn(a.out, a.quick))


if __name__ == "__main__":
    main()
