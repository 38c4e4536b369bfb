"""Plot the driveline start-up: speeds, torques, DTE, contact state and master agreement.

    python examples/driveline/plot.py [--out docs/driveline_startup.png] [--stop-time 3]

Builds the example into ``build/driveline`` (unless ``--ssp`` is given), runs it in every
available master (fmpy, libcosimpy, ecospy) with the same communication step, writes the
agreement table next to the SSP and the figure to ``--out``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import driveline_system as ds  # noqa: E402

STICK_RANGE_RPM = 300.0  # r/min of gear 1: stick occurs below this (Fig. 15 of the paper)


def block_mean(t: np.ndarray, x: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """Means of ``x`` over consecutive windows of ``width`` seconds (steps of equal size)."""
    n = max(1, round(width / float(t[1] - t[0])))
    m = len(x) // n * n
    return t[:m].reshape(-1, n)[:, -1], x[:m].reshape(-1, n).mean(axis=1)


def plot(results: dict[str, dict[str, np.ndarray]], params: dict[str, dict],
         out: str | Path, reference: str = "fmpy") -> Path:
    """Write the start-up figure for ``{master: results}`` to ``out`` (PNG); return the path.

    ``params`` are the SSP's parameters (`driveline_system.read_parameters`), used for the
    steady speeds the characteristic predicts before and after the load step.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ref = results[reference]
    t = ref["time"]
    r = ds.mesh_ratio(params)
    rpm = 1.0 / ds.RPM
    fig, ax = plt.subplots(5, 1, figsize=(10, 13), sharex=True,
                           gridspec_kw={"height_ratios": [3, 3, 3, 2, 2]})

    a = ax[0]
    a.axhspan(0.0, STICK_RANGE_RPM, color="0.92", label="stick possible (< 300 r/min)")
    for m, res in results.items():
        style = "-" if m == reference else (0, (4, 4))
        a.plot(res["time"], res["Motor.speed"] * rpm, ls=style, lw=1.0, label=f"motor ({m})")
    a.plot(t, ref["Load.speed"] / r * rpm, lw=1.0, label="load x z2/z1")
    ld = params["Load"]
    before = ds.steady_state(params)["motor_speed"] * rpm
    after = ds.steady_state(params, ld["T_step"])["motor_speed"] * rpm
    a.hlines(before, t[0], min(ld["t_step"], t[-1]), colors="k", linestyles=":",
             label="steady speed of the characteristic")
    if ld["t_step"] < t[-1]:
        a.hlines(after, ld["t_step"], t[-1], colors="k", linestyles=":")
    a.set_ylabel("speed of gear 1 (r/min)")
    a.legend(loc="lower right", fontsize=8)

    a = ax[1]
    a.plot(t, ref["GearPair.input_torque"] * 1e-3, lw=0.6, label="GearPair.input_torque (motor)")
    a.plot(t, ref["Motor.torque"] * 1e-3, lw=1.0, label="Motor.torque (characteristic)")
    a.plot(t, ref["GearPair.output_torque"] * r * 1e-3, lw=0.6,
           label="GearPair.output_torque x z1/z2 (load)")
    a.plot(t, ref["Load.resisting_torque"] * r * 1e-3, lw=1.0,
           label="Load.resisting_torque x z1/z2")
    a.set_ylabel("torque at gear 1 (kN.m)")
    a.legend(loc="upper right", fontsize=8)

    a = ax[2]
    a.plot(t, ref["GearPair.dte"] * 1e6, lw=0.3, color="0.6", label="DTE")
    tb, dte = block_mean(t, ref["GearPair.dte"], 0.01)
    a.plot(tb, dte * 1e6, lw=1.2, label="10 ms mean")
    a.set_ylabel("DTE (um)")
    a.legend(loc="upper right", fontsize=8)

    a = ax[3]
    tb, stick = block_mean(t, ref["GearPair.stick_fraction"], 0.01)
    _, sep = block_mean(t, ref["GearPair.separation_fraction"], 0.01)
    # The state at each step end as shading along the time axis (not a curve on the fraction
    # scale, where a constant "slip" would read as a threshold).
    state = ref["GearPair.contact_state"]
    band = a.get_xaxis_transform()
    a.fill_between(t, 0.0, 1.0, where=state == 2, step="post", transform=band, lw=0,
                   color="tab:blue", alpha=0.35, label="stuck at the step end")
    if np.any(state == 0):
        a.fill_between(t, 0.0, 1.0, where=state == 0, step="post", transform=band, lw=0,
                       color="tab:orange", alpha=0.35, label="apart at the step end")
    a.plot(tb, stick, lw=1.2, color="tab:blue", label="stick fraction (10 ms mean)")
    a.plot(tb, sep, lw=1.2, color="tab:orange", label="separation fraction (10 ms mean)")
    a.set_ylabel("fraction of time")
    a.set_ylim(-0.05, 1.05)
    a.legend(loc="upper right", fontsize=8)

    # Agreement on a log axis: exact zeros have no logarithm, so they sit on a marked floor
    # line, and a signal equal at every step says so in its label instead of vanishing.
    a = ax[4]
    floor = 1e-17
    a.axhline(floor, color="0.5", lw=0.8, ls=":")
    a.text(t[-1], floor * 3, "difference exactly 0 ", ha="right", va="bottom", fontsize=7,
           color="0.4")
    for m, res in results.items():
        if m == reference:
            continue
        for sig in ("Motor.speed", "GearPair.output_torque", "GearPair.dte"):
            scale = float(np.max(np.abs(ref[sig])))
            diff = np.abs(res[sig] - ref[sig]) / scale
            zero = diff == 0.0
            if zero.all():
                label = f"{m}: {sig} (identical at every step)"
            elif zero.any():
                label = f"{m}: {sig} ({zero.sum()} of {zero.size} steps identical)"
            else:
                label = f"{m}: {sig}"
            a.semilogy(t, np.where(zero, floor, diff), lw=0.6, label=label)
    a.set_ylabel(f"|master - {reference}| / max")
    a.set_xlabel("time (s)")
    a.set_ylim(floor / 10, 1e3)  # room above the data for the legend
    a.legend(loc="upper left", fontsize=7, ncol=2)

    h = float(t[1] - t[0])
    mo, gp = params["Motor"], params.get("GearPair", {})
    laws = {0: "no friction", 1: "nominal friction", 2: "regularized friction",
            3: "stick-slip"}
    fig.suptitle(f"Driveline start-up: Motor - GearPair - Load, Jacobi, {h:g} s steps "
                 f"({', '.join(results)})\nmotor {mo['T_stall']:g} N.m at stall, no load at "
                 f"{mo['w_noload'] * rpm:g} r/min; load {ld['T_load']:g} N.m + "
                 f"{ld['T_step']:g} N.m at {ld['t_step']:g} s;\nGearPair mu "
                 f"{gp.get('mu', 0.02):g}, {laws.get(int(gp.get('friction_law', 3)), '')}, "
                 f"kr1 {gp.get('kr1', 0):g} N/m")
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ssp", default=None, help="an SSP to run (default: build one)")
    ap.add_argument("--stop-time", type=float, default=ds.PLOT_STOP_TIME, help="s")
    ap.add_argument("--step", type=float, default=1e-4, help="communication step, s")
    ap.add_argument("--out", default=str(ROOT / "docs" / "driveline_startup.png"))
    ap.add_argument("--build-dir", default=str(ROOT / "build" / "driveline"))
    a = ap.parse_args(argv)
    compare = ds.sibling("compare")
    ssp = a.ssp or ds.sibling("build").build(a.build_dir, stop_time=a.stop_time, step=a.step)
    results = compare.run_all(ssp, a.stop_time, a.step)
    table = compare.write_table(results, Path(ssp).parent / "agreement.md")
    print(table.read_text())
    print(f"wrote {plot(results, ds.read_parameters(ssp), a.out)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
