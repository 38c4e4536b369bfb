"""Golden trajectories of the fast engine: what `tests/test_golden.py` reproduces bit for bit.

A refactoring of the fast engine (its package layout, its records, what numba compiles and
inlines) must not change a single bit of any trajectory. This script runs `FastEngine` over

- the shipped scenes (``examples/scenes/*.toml``, shortened), through ``FastEngine.run``;
- the hard cases of ``tests/test_hard_cases.py`` (their schedules, shortened), through
  ``advance`` step by step;
- every effect combination the engine implements (friction laws, sliding velocity, stick
  tie, separation, backlash, degrees of freedom, stiffness laws, Runge-Kutta pair, the exact
  propagator or not, speed jumps, a load-speed port),

and stores per step the outputs and the step figures (plus steps taken and rejected), and at
the end the engine state and its energy terms, in ``tests/golden/fast_engine.npz``. The step
schedules are stored too, so the comparison does not depend on how they are generated.

Regenerate (only when a change of the trajectories is intended, and say why in the commit):

    .venv/bin/python tests/golden/make_golden.py
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
GOLDEN = HERE / "fast_engine.npz"

from gearpair import RPM, Effects, GearParams  # noqa: E402
from gearpair.effects import StiffnessSpec  # noqa: E402
from gearpair.engine import Outputs  # noqa: E402
from gearpair.geometry import Geometry  # noqa: E402

OUT_FIELDS = tuple(f.name for f in fields(Outputs) if f.name != "time")
GRID_FIELDS = ("stick_fraction", "separation_fraction", "mesh_force_max", "n_events",
               "back_fraction", "mesh_force_mean", "mesh_force_min")
STEP_FIELDS = GRID_FIELDS + ("n_steps", "rejected_steps")
STATE_SCALARS = ("t", "s", "torque", "speed", "t_stick", "t_sep", "t_back", "n_events_total",
                 "h", "separated", "back")
ENERGY_KEYS = ("stored", "input", "damping", "friction", "parametric")
TR = 3900.0   # N.m
W10 = 10.0    # rad/s


@dataclass(frozen=True)
class GoldenCase:
    """One run: the engine's inputs and how it is driven.

    ``steps`` rows are (t_end, torque, speed, load_speed) per communication step (load_speed
    NaN: none); ``driver`` is "advance" (one call per step) or "grid" (one `FastEngine.run`).
    """

    name: str
    steps: np.ndarray
    params: GearParams = field(default_factory=GearParams)
    effects: Effects = field(default_factory=Effects)
    options: dict = field(default_factory=dict)
    driver: str = "advance"


def uniform(h: float, t_end: float, t0: float = 0.0) -> list[float]:
    n = int(round((t_end - t0) / h))
    ends = [t0 + k * h for k in range(1, n + 1)]
    ends[-1] = t_end
    return ends


def schedule(ends, torque, speed, load_speed=None) -> np.ndarray:
    """Rows (t_end, torque, speed, load_speed), the inputs sampled at each step's start."""
    def fn(x):
        return x if callable(x) else (lambda t, v=x: v)
    fT, fW = fn(torque), fn(speed)
    fL = fn(math.nan if load_speed is None else load_speed)
    rows, t = [], 0.0
    for te in ends:
        rows.append((float(te), float(fT(t)), float(fW(t)), float(fL(t))))
        t = te
    return np.array(rows)


def _table_stiffness() -> StiffnessSpec:
    L = Geometry.from_params(GearParams()).path_length
    xi = np.linspace(0.0, L, 7)
    return StiffnessSpec("table", table=tuple(
        (float(x), 2.0e9 + 8e8 * math.sin(math.pi * x / L)) for x in xi))


def effect_cases() -> list[GoldenCase]:
    """Every effect combination that matters, near the paper's stick-slip point."""
    base = schedule(uniform(1e-3, 0.025), TR, W10)
    reversal = schedule(uniform(5e-4, 0.03), lambda t: TR * math.cos(2 * math.pi * 40 * t),
                        31.4)
    jump = schedule(uniform(1e-3, 0.02), TR, lambda t: W10 if t < 0.0095 else 12.0)
    load = schedule(uniform(1e-3, 0.02), TR, W10, lambda t: W10 * 33 / 80 * (1 + 2 * t))
    E, cases = Effects, []

    def add(name, eff, steps=base, **options):
        cases.append(GoldenCase("effects/" + name, steps, effects=eff, options=options))

    for fr in ("off", "nominal", "regularized", "stick_slip"):
        add(f"friction_{fr}", E(friction=fr))
        add(f"friction_{fr}_full_sliding", E(friction=fr, sliding="full"))
        add(f"friction_{fr}_torsional", E(friction=fr, sliding="full", dof="torsional"))
        add(f"friction_{fr}_no_separation", E(friction=fr, separation=False))
        add(f"friction_{fr}_backlash", E(friction=fr, backlash=1e-4), reversal)
        add(f"friction_{fr}_dp5", E(friction=fr), method="dp5")
    add("paper_tie", E(stick_tie="paper"))
    add("paper_tie_full_sliding", E(stick_tie="paper", sliding="full"))
    add("regularized_v_eps", E(friction="regularized", v_eps=1e-3))
    for kind in ("constant", "rectangular"):
        for lti in (True, False):
            for fr in ("off", "stick_slip"):
                add(f"{kind}_{fr}_lti_{lti}", E(stiffness=kind, friction=fr), exact_lti=lti)
        add(f"{kind}_off_backlash_torsional",
            E(stiffness=kind, friction="off", backlash=1e-4, dof="torsional"), reversal)
        add(f"{kind}_off_dp5", E(stiffness=kind, friction="off"), method="dp5",
            exact_lti=False)
    add("table_regularized", E(stiffness=_table_stiffness(), friction="regularized"))
    add("table_stick_slip_no_separation", E(stiffness=_table_stiffness(), separation=False))
    add("potential_energy_no_scaling",
        E(stiffness=StiffnessSpec("potential_energy", scale_to_mean=False)))
    add("stick_slip_speed_jump", E(), jump)
    add("stick_slip_full_speed_jump", E(sliding="full"), jump)
    add("stick_slip_load_speed", E(), load)
    add("exact_load_speed", E(stiffness="rectangular", friction="off"), load)
    add("stick_slip_rtol_1e-6", E(), rtol=1e-6)
    add("stick_slip_options", E(), n_samples=3, t_tol=1e-12, max_step=2e-5)
    add("nominal_sample_spacing", E(friction="nominal"), sample_spacing=1e-5)
    return cases


def hard_cases() -> list[GoldenCase]:
    """The schedules of tests/test_hard_cases.py (shortened to at most 60 steps)."""
    p = GearParams()
    u1 = uniform(1e-3, 0.06)
    ramp = uniform(1e-3, 0.06)

    def ramp_speed(t):
        return W10 - 17.0 * min(t, 0.04) / 0.04

    def steps_ladder():
        from fractions import Fraction
        t, out = Fraction(0), []
        for n, h in ((10, "1e-6"), (9, "1e-5"), (9, "1e-4"), (9, "1e-3"), (3, "1e-2"),
                     (1, "1e-1")):
            for _ in range(n):
                t += Fraction(h)
                out.append(float(t))
        return out

    def varying():
        rng = np.random.default_rng(7)
        ends, t = [1e-6, 1e-6 + 0.1], 1e-6 + 0.1
        while t < 0.2:
            h = float(10.0 ** rng.uniform(-6.0, -1.0))
            t = min(t + h, 0.2)
            if 0.2 - t < 1e-6:
                t = 0.2
            ends.append(t)
        return ends[:60]

    exact_c = Effects(friction="off", stiffness="constant")
    exact_r = Effects(friction="off", stiffness="rectangular")
    step_ends = [0.01, 0.02, 0.03, *uniform(1e-3, 0.06, 0.03)]
    spec = [
        ("stiff_support_kb2_x100", schedule(u1, TR, W10), p.replace(kb2=4.11e12), Effects()),
        ("standstill", schedule(uniform(1e-3, 0.03), TR, 0.0), p, Effects()),
        ("standstill_full_sliding", schedule(uniform(1e-3, 0.03), TR, 0.0), p,
         Effects(sliding="full")),
        ("speed_ramp_through_zero", schedule(ramp, TR, ramp_speed), p, Effects()),
        ("reverse_speed", schedule(u1, TR, -W10), p, Effects()),
        ("zero_torque", schedule(uniform(1e-3, 0.03), 0.0, W10), p, Effects()),
        ("zero_torque_backlash", schedule(uniform(1e-3, 0.03), 0.0, W10), p,
         Effects(backlash=1e-4)),
        ("negative_torque", schedule(uniform(1e-3, 0.03), -TR, W10), p, Effects()),
        ("negative_torque_backlash", schedule(u1, -TR, W10), p, Effects(backlash=1e-4)),
        ("torque_step_0_to_10kNm",
         schedule(step_ends, lambda t: 1e4 if t >= 0.02 - 1e-12 else 0.0, W10), p, Effects()),
        ("mu_0", schedule(u1, TR, W10), p.replace(mu=0.0), Effects()),
        ("mu_0.3", schedule(u1, TR, W10), p.replace(mu=0.3), Effects()),
        ("low_speed_1rpm", schedule(uniform(1e-2, 0.5), TR, 1.0 * RPM), p, Effects()),
        ("high_speed_6000rpm", schedule(uniform(1e-3, 0.01), TR, 628.0), p, Effects()),
        ("high_speed_6000rpm_paper_tie", schedule(uniform(1e-3, 0.01), TR, 628.0), p,
         Effects(stick_tie="paper")),
        ("chatter_paper_tie_600rpm", schedule(uniform(1e-3, 0.03), TR, 62.8), p,
         Effects(stick_tie="paper")),
        ("contact_loss_reimpact", schedule(uniform(5e-4, 0.02), 1000.0, 250.0), p, Effects()),
        ("comm_steps_1e-6_to_0.1", schedule(steps_ladder(), TR, W10), p, Effects()),
        ("comm_steps_varying", schedule(varying(), TR, W10), p, Effects()),
        ("exact_comm_steps_varying", schedule(varying(), TR, W10), p, exact_c),
        ("exact_contact_loss_reimpact", schedule(uniform(5e-4, 0.02), 1000.0, 250.0), p,
         exact_r),
        # mesh resonance with impacts on both flanks: a last-bit difference grows through
        # the impacts, so this is where machines that round differently part first (#32)
        ("resonance_backlash_5000rpm", schedule(uniform(1e-4, 0.02), 1000.0, 5000.0 * RPM), p,
         Effects(friction="nominal", stiffness="rectangular", backlash=5e-5)),
        ("exact_reversals_backlash",
         schedule(u1, lambda t: TR * math.cos(2.0 * math.pi * 20.0 * t), W10), p,
         replace(exact_r, backlash=1e-4)),
    ]
    return [GoldenCase("hard/" + n, s, pp, fx) for n, s, pp, fx in spec]


def scene_cases(t_end: float = 0.02) -> list[GoldenCase]:
    """The shipped scenes over their first ``t_end`` s, recorded by `FastEngine.run`."""
    from gearpair.scenes import load_scene

    out = []
    for path in sorted((ROOT / "examples" / "scenes").glob("*.toml")):
        sc = load_scene(path)
        dt = sc.step
        ends = uniform(dt, min(t_end, sc.t_end))
        grid = np.r_[0.0, ends]
        T = np.array([sc.inputs.torque(t) for t in grid[:-1]])
        W = np.array([sc.inputs.speed(t) for t in grid[:-1]])
        steps = np.column_stack([grid[1:], T, W, np.full(len(T), math.nan)])
        out.append(GoldenCase("scene/" + path.stem, steps, sc.params, sc.effects,
                              {"rtol": sc.solver.rtol}, driver="grid"))
    return out


def all_cases() -> list[GoldenCase]:
    return effect_cases() + hard_cases() + scene_cases()


def _state_arrays(engine) -> dict[str, np.ndarray]:
    st = engine.get_state()
    scal = [float(st[k]) if st[k] is not None else -1.0 for k in STATE_SCALARS]
    prev = st["prev_active"]
    e = engine.energy()
    return {"state": np.array(scal), "y": np.asarray(st["y"], float),
            "dirs": np.asarray(st["dirs"], float),
            "stuck": np.asarray(st["stuck"], float),
            "prev_active": np.array([-1.0] if prev is None else prev, float),
            "energy": np.array([e[k] for k in ENERGY_KEYS])}


def run_case(case: GoldenCase) -> dict[str, np.ndarray]:
    """The golden arrays of one case: ``steps`` (its schedule), ``rows`` (per step: the
    outputs, then STEP_FIELDS), the final state, and ``error`` (1 if a step raised)."""
    from gearpair.fast import FastEngine

    opts = {"rtol": 1e-8, **case.options}
    eng = FastEngine(case.params, case.effects, **opts)
    s = case.steps
    eng.reset(0.0, s[0, 1], s[0, 2], static=True)
    n = len(s)
    rows = np.full((n, len(OUT_FIELDS) + len(STEP_FIELDS)), np.nan)
    error = 0.0
    if case.driver == "grid":
        grid = np.r_[eng.time, s[:, 0]]
        rec = eng.run(grid, s[:, 1], s[:, 2])
        for m, k in enumerate(OUT_FIELDS + GRID_FIELDS):
            rows[:, m] = rec[k][1:]
    else:
        try:
            for i, (te, T, W, L) in enumerate(s):
                summ = eng.advance(te, T, W, None if math.isnan(L) else L)
                o = eng.outputs()
                rows[i, :len(OUT_FIELDS)] = [getattr(o, k) for k in OUT_FIELDS]
                rows[i, len(OUT_FIELDS):] = [getattr(summ, k) for k in GRID_FIELDS] + [
                    summ.n_steps, eng.rejected_steps]
        except (RuntimeError, ArithmeticError):
            error = 1.0
    return {"steps": s, "rows": rows, "error": np.array([error]), **_state_arrays(eng)}


def main() -> None:
    data = {}
    for case in all_cases():
        for k, v in run_case(case).items():
            data[f"{case.name}/{k}"] = v
        print(case.name, file=sys.stderr)
    np.savez_compressed(GOLDEN, **data)
    print(f"{GOLDEN.name}: {len(data)} arrays, {GOLDEN.stat().st_size / 1e3:.0f} kB",
          file=sys.stderr)


if __name__ == "__main__":
    main()
