"""The paper's claims beside this project's numbers (docs/paper_comparison.md).

For both stick ties (``exact``, ``paper``) and both sliding velocities (``paper`` Eq. (12),
``full`` with the rotational vibration), runs on one local dask cluster:

- the slip and stick modal analysis (Figs. 5-6; the tie does not enter the modes);
- a speed sweep 10-600 r/min in steps of 10 (3900 N.m, mu = 0.02), which includes the
  operating point 100 r/min;
- a friction sweep mu = 0-0.1 in steps of 0.005 and a torque sweep 500-8000 N.m in steps of
  500 N.m (100 r/min);
- the slip model (friction direction from the nominal kinematics; the tie and the sliding
  variant do not enter it) over the same speeds;
- finely sampled responses at 100 r/min (`common.response`: 800 samples per mesh period over
  64 periods) for the mesh force range, the DTE orders and the adjacent-period difference.

Sweep points use `gearpair.sweep.SweepSettings` defaults (100 discarded mesh periods and at
least 1 s, 100 kept, capped near 6 s of simulated time; rtol 1e-7). Prints a Markdown table
and writes ``OUT/comparison.json``; the sweep files are cached in ``OUT/comparison/``.

    python examples/paper/comparison.py [--out DIR] [--workers N] [--scheduler ADDRESS]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from common import DEFAULT_OUT, SLIP, STICK, response, sweep_cached

from gearpair import Effects, GearParams, Model
from gearpair.analysis import adjacent_period_difference, order_amplitudes
from gearpair.modal import modes
from gearpair.sweep import SweepSettings, local_cluster

VARIANTS = (("exact", "paper"), ("paper", "paper"), ("exact", "full"), ("paper", "full"))
SPEEDS = np.arange(10.0, 601.0, 10.0)
MUS = np.round(np.arange(0.0, 0.1001, 0.005), 4)
TORQUES = np.arange(500.0, 8001.0, 500.0)
OP_RPM = 100.0
STICK_MIN = 1e-4  # a stick ratio below this counts as "no stick"


def modal_claims() -> dict:
    """First frequencies, the translation content of slip modes 3 and 5, stick modes."""
    out = {}
    for sliding in ("paper", "full"):
        m = Model.build(GearParams(), Effects(stiffness="constant", sliding=sliding))
        fs, vs = modes(m, "slip")
        ft, vt = modes(m, "stick")
        M = np.diag(m.M)

        def share(v, idx, M=M):
            e = M * v**2  # modal kinetic energy by coordinate (same frequency in a mode)
            return float(e[idx].sum() / e.sum())

        g1, g2, rot = [0, 1], [3, 4], [2, 5]
        out[sliding] = {
            "slip_hz": [round(float(f), 3) for f in fs],
            "stick_hz": [round(float(f), 3) for f in ft],
            "slip_mode1_rotation_share": share(vs[:, 0], rot),
            "slip_mode3_gear1_translation_share": share(vs[:, 2], g1),
            "slip_mode5_gear2_translation_share": share(vs[:, 4], g2),
            "stick_max_gear1_translation_share": max(share(vt[:, i], g1)
                                                     for i in range(len(ft))),
            "stick_max_gear2_translation_share": max(share(vt[:, i], g2)
                                                     for i in range(len(ft))),
            "stick_max_relative_x": float(np.max(np.abs(vt[0] - vt[3]))),
            "mode1_shape_difference": float(np.max(np.abs(np.abs(vs[:, 0]) - np.abs(vt[:, 0])))),
            "mode2_shape_difference": float(np.max(np.abs(np.abs(vs[:, 1]) - np.abs(vt[:, 1])))),
        }
    return out


def _ranges(x: np.ndarray, on: np.ndarray) -> list[list[float]]:
    """Contiguous runs of ``on`` as [first x, last x]."""
    out, start = [], None
    for i, flag in enumerate(on):
        if flag and start is None:
            start = i
        if (not flag or i == len(on) - 1) and start is not None:
            end = i if flag else i - 1
            out.append([float(x[start]), float(x[end])])
            start = None
    return out


def _col(res, name):
    return res.column(name)


def dynamic_claims(out_dir: Path, tie: str, sliding: str, scheduler) -> dict:
    d = out_dir / "comparison"
    st = SweepSettings(stick_tie=tie, sliding=sliding)
    tag = f"{tie}_{sliding}"
    sp = sweep_cached(d, f"speed_{tag}", "speed_rpm", SPEEDS, st, scheduler)
    mu = sweep_cached(d, f"mu_{tag}", "mu", MUS, st, scheduler)
    tq = sweep_cached(d, f"torque_{tag}", "torque", TORQUES, st, scheduler)
    slip = sweep_cached(d, "speed_slip", "speed_rpm", SPEEDS, SweepSettings(friction=SLIP),
                        scheduler)
    failed = [f"{r['param']}={r['value']:g}: {r['error']}" for res in (sp, mu, tq, slip)
              for r in res.failed]
    i_op = int(np.argmin(np.abs(SPEEDS - OP_RPM)))
    op, op_slip = sp.records[i_op], slip.records[i_op]
    rk = _col(sp, "stick_ratio")
    stick = rk > STICK_MIN
    per = _col(sp, "poincare_period")
    rk_mu = _col(mu, "stick_ratio")
    rk_tq = _col(tq, "stick_ratio")
    above = MUS > 0.01
    mu_zero = MUS[rk_mu <= STICK_MIN]
    tq_on = TORQUES[rk_tq > 0.01]
    rl_all = np.concatenate([_col(r, "contact_loss_ratio") for r in (sp, mu, tq)])
    rk_all = np.concatenate([_col(r, "stick_ratio") for r in (sp, mu, tq)])
    # Mesh force range and DTE orders from the finely sampled responses (800 samples per
    # mesh period over 64 periods; the sweep's 8 samples per period miss the ringing minima).
    fine_slip = response(SLIP, False)
    fine = response(STICK, False, tie, sliding)
    o_slip = order_amplitudes(fine_slip["dte"], fine_slip["steps_per_period"], (0.5, 1.0))
    o = order_amplitudes(fine["dte"], fine["steps_per_period"], (0.5, 1.0))

    def frange(r):
        return [float(r["mesh_force"].min() / 1e3),
                float(max(r["mesh_force"].max(), r["mesh_force_max"].max()) / 1e3)]

    return {
        "variant": {"stick_tie": tie, "sliding": sliding},
        "failed_points": failed,
        "slip_mesh_force_kn": frange(fine_slip),
        "stick_mesh_force_kn": frange(fine),
        "fine_stick_ratio": float(fine["stick_fraction"].mean()),
        "fine_contact_loss_ratio": float(fine["separation_fraction"].mean()),
        "fine_half_over_mesh": o[0.5] / o[1.0],
        "fine_slip_half_over_mesh": o_slip[0.5] / o_slip[1.0],
        "fine_adjacent_diff": adjacent_period_difference(fine["dte"],
                                                         fine["steps_per_period"])[0],
        "op_stick_ratio": op["stick_ratio"],
        "op_contact_loss_ratio": op["contact_loss_ratio"],
        "op_stick_period_fraction": op["stick_period_fraction"],
        "op_poincare_period": op["poincare_period"],
        "op_adjacent_diff": op["adjacent_diff"],
        "op_half_over_mesh": op["half_order_um"] / op["mesh_order_um"],
        "op_slip_half_over_mesh": op_slip["half_order_um"] / op_slip["mesh_order_um"],
        "stick_speed_ranges_rpm": _ranges(SPEEDS, stick),
        "max_stick_speed_rpm": float(SPEEDS[stick].max()) if stick.any() else None,
        "max_stick_ratio_speed": float(rk.max()),
        "mu_zero_stick_max": float(mu_zero.max()) if mu_zero.size else None,
        "mu_stick_ratio": {f"{m:g}": float(r) for m, r in zip(MUS, rk_mu, strict=True)},
        "mu_monotonic_above_0.01": bool(np.all(np.diff(rk_mu[above]) >= -1e-3)),
        "torque_stick_ratio": {f"{t:g}": float(r) for t, r in zip(TORQUES, rk_tq, strict=True)},
        "torque_first_above_1pct": float(tq_on.min()) if tq_on.size else None,
        "torque_monotonic": bool(np.all(np.diff(rk_tq) >= -1e-3)),
        "max_contact_loss_ratio": float(np.nanmax(rl_all)),
        "points_with_stick_and_loss": int(np.sum((rk_all > STICK_MIN) & (rl_all > 0))),
        "points_with_loss": int(np.sum(rl_all > 0)),
        "points": int(rl_all.size),
        "stick_speeds_aperiodic": int(np.sum(stick & (per == 0))),
        "stick_speeds": int(stick.sum()),
        "nonstick_speeds_aperiodic": int(np.sum(~stick & (per == 0))),
        "nonstick_speeds": int((~stick).sum()),
        "stick_speeds_period2": int(np.sum(stick & (per == 2))),
        "max_half_over_mesh_speed": float(np.nanmax(_col(sp, "half_order_um")
                                                    / _col(sp, "mesh_order_um"))),
        "slip_speeds_aperiodic": int(np.sum(_col(slip, "poincare_period") == 0)),
    }


def _fmt_ranges(r):
    return ", ".join(f"{a:g}-{b:g}" for a, b in r) or "none"


def table(modal: dict, dyn: list[dict]) -> str:
    """The Markdown table of docs/paper_comparison.md (claims as rows, variants as columns)."""
    heads = [f"tie {d['variant']['stick_tie']}, sliding {d['variant']['sliding']}" for d in dyn]
    rows = []

    def row(claim, paper, fn):
        rows.append(f"| {claim} | {paper} | " + " | ".join(fn(d) for d in dyn) + " |")

    def mod(d):
        return modal[d["variant"]["sliding"]]

    row("first natural frequency, slip / stick (Hz)", "32 / about 32",
        lambda d: f"{mod(d)['slip_hz'][0]:.1f} / {mod(d)['stick_hz'][0]:.1f}")
    row("slip modes 3 and 5: pure translations of gear 1 / gear 2 (kinetic-energy share)",
        "pure", lambda d: f"{mod(d)['slip_mode3_gear1_translation_share']:.3f} / "
                          f"{mod(d)['slip_mode5_gear2_translation_share']:.3f}")
    row("stick model lacks them (largest share of gear 1 / gear 2 translation in a stick mode)",
        "no such mode", lambda d: f"{mod(d)['stick_max_gear1_translation_share']:.3f} / "
                                  f"{mod(d)['stick_max_gear2_translation_share']:.3f}")
    row("stick modes 1-2 differ from slip modes 1-2 (largest shape difference)", "very different",
        lambda d: f"{mod(d)['mode1_shape_difference']:.1e} / "
                  f"{mod(d)['mode2_shape_difference']:.1e}")
    row("slip-model mesh force at 100 r/min (kN)", "25-60",
        lambda d: "{:.1f}-{:.1f}".format(*d["slip_mesh_force_kn"]))
    row("stick-slip mesh force at 100 r/min (kN)", "0-280 (A), 0-140 (B)",
        lambda d: "{:.1f}-{:.1f}".format(*d["stick_mesh_force_kn"]))
    row("speeds with stick (r/min, 10 r/min grid)", "three ranges in 0-300 only",
        lambda d: _fmt_ranges(d["stick_speed_ranges_rpm"]))
    row("largest mu without stick (100 r/min)", "0.01",
        lambda d: f"{d['mu_zero_stick_max']:g}")
    row("stick ratio rises monotonically with mu above 0.01", "yes",
        lambda d: "yes" if d["mu_monotonic_above_0.01"] else "no")
    row("smallest torque with stick ratio > 1 % (N.m)", "about 3000",
        lambda d: f"{d['torque_first_above_1pct']:g}" if d["torque_first_above_1pct"] else "none")
    row("stick ratio at 1000 / 3000 / 4000 N.m", "about 0 / about 0 / rising",
        lambda d: " / ".join(f"{d['torque_stick_ratio'][k]:.3f}" for k in ("1000", "3000",
                                                                             "4000")))
    row("stick ratio rises monotonically with torque", "yes (above 3000)",
        lambda d: "yes" if d["torque_monotonic"] else "no")
    row("stick ratio / stick in every mesh period at 100 r/min", "> 0 / yes",
        lambda d: f"{d['op_stick_ratio']:.3f} / {d['op_stick_period_fraction']:.2f} of periods")
    row("adjacent mesh periods differ (Poincare period at 100 r/min; 0 = none <= 16)",
        "period two", lambda d: f"{int(d['op_poincare_period'])} "
                                f"(adjacent-period difference {d['fine_adjacent_diff']:.1e})")
    row("contact loss with stick (contact-loss ratio at 100 r/min; points with stick and loss)",
        "yes, up to 4 losses per period",
        lambda d: f"{d['op_contact_loss_ratio']:.3f}; {d['points_with_stick_and_loss']} of "
                  f"{d['points']}")
    row("half-order DTE component / mesh-order, stick-slip vs slip at 100 r/min",
        "much larger with stick",
        lambda d: f"{d['fine_half_over_mesh']:.1e} vs {d['fine_slip_half_over_mesh']:.1e}")
    row("largest half-order / mesh-order DTE ratio over 10-600 r/min (stick-slip)",
        "-", lambda d: f"{d['max_half_over_mesh_speed']:.1e}")
    row("chaos in the stick ranges (aperiodic / all speeds with stick; without stick)",
        "chaotic / periodic",
        lambda d: f"{d['stick_speeds_aperiodic']}/{d['stick_speeds']}; "
                  f"{d['nonstick_speeds_aperiodic']}/{d['nonstick_speeds']}")
    head = "| claim | paper | " + " | ".join(heads) + " |"
    sep = "|---|---|" + "---|" * len(heads)
    return "\n".join([head, sep, *rows])


def run(out: Path, scheduler) -> dict:
    modal = modal_claims()
    dyn = [dynamic_claims(out, tie, sl, scheduler) for tie, sl in VARIANTS]
    res = {"modal": modal, "dynamic": dyn, "table": table(modal, dyn)}
    out.mkdir(parents=True, exist_ok=True)
    (out / "comparison.json").write_text(json.dumps(res, indent=2))
    return res


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(DEFAULT_OUT))
    ap.add_argument("--scheduler", default=None)
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args(argv)
    out = Path(a.out)
    if a.scheduler:
        res = run(out, a.scheduler)
    else:
        with local_cluster(a.workers) as addr:
            res = run(out, addr)
    print(res["table"])
    for d in res["dynamic"]:
        if d["failed_points"]:
            print(f"failed points ({d['variant']}):", *d["failed_points"], sep="\n  ")


if __name__ == "__main__":
    main()
