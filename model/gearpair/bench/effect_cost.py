"""Cost of effects: the shipped scenes and the effect ladder."""

from __future__ import annotations

from pathlib import Path

from .runs import NEVER, Timing, _best_of, _record, clock
from .settings import LADDER, TARGET_LADDER, Progress, Settings, _quiet

LADDER_RUNS = (("step_1e-3", 1e-3), ("out_1e-4", 1e-4))  # communication step of the rungs


def cost_table(s: Settings, rtol: float = 1e-8, progress: Progress = _quiet) -> dict:
    """Time per simulated second of every shipped scene and of the effect ladder (fast
    engine, best of ``repeats`` for a scene and of ``ladder_repeats`` for a rung, kernels
    already loaded), with ratios to stick-slip.

    Scenes run as shipped (their step, output interval and rtol) over their first
    ``cost_t_end`` s, construction included. Ladder rungs run at the default point with
    ``rtol``, stepped every 1e-3 s (``step_1e-3``) and recorded every 1e-4 s (``out_1e-4``),
    construction excluded. Keys ``wall_<run>`` and ``cpu_<run>`` are s per simulated s.
    ``scenes_note`` says why there are no scene rows (no folder ``s.scenes_dir``).
    """
    folder = Path(s.scenes_dir)
    note = None if folder.is_dir() else (
        f"scene rows skipped: no folder {s.scenes_dir} here (the repository's example scenes; "
        "run from a checkout or pass --scenes DIR)")
    if note:
        progress(note)
    scenes = [] if note else scene_costs(s, progress)
    best, fails = _ladder_rounds(s, rtol)
    ladder = []
    for label, kw in LADDER:
        row = _ladder_row(s, rtol, label, kw, best, fails.get(label))
        ladder.append(row)
        progress(f"ladder {label}: " + (f"failed: {row['error']}" if row["error"] else
                                        f"{row['wall_step_1e-3']:.3f} s per simulated s "
                                        "at 1e-3 s steps"))
    return {"t_end": s.cost_t_end, "rtol": rtol, "scenes": scenes, "scenes_note": note,
            "ladder": ladder, "checks": _ladder_checks(ladder)}


def scene_costs(s: Settings, progress: Progress = _quiet) -> list[dict]:
    """Every scene ``*.toml`` of the folder ``s.scenes_dir`` over its first ``cost_t_end`` s
    (best of ``repeats``, construction included): wall and CPU s per simulated s."""
    from ..scenes import load_scene

    def timed_scene(scene) -> Timing:
        t0 = clock()
        scene.run("fast")
        return clock() - t0

    scenes = []
    for path in sorted(Path(s.scenes_dir).glob("*.toml")):
        scene = load_scene(path)
        scene = scene.with_t_end(min(scene.t_end, s.cost_t_end))
        took, err = _best_of(lambda sc=scene: timed_scene(sc), s.repeats)
        fx = scene.effects
        scenes.append({"scene": scene.name, "t_end": scene.t_end, "step": scene.step,
                       "rtol": scene.solver.rtol, "dof": fx.dof,
                       "stiffness": fx.stiffness.kind, "friction": fx.friction,
                       "wall_per_sim_s": None if took is None else took.wall / scene.t_end,
                       "cpu_per_sim_s": None if took is None else took.cpu / scene.t_end,
                       "error": err})
        progress(f"scene {scene.name}: " + (f"failed: {err}" if err else
                                            f"{took.wall / scene.t_end:.3f} s per simulated s"))
    return scenes


def _ladder_rounds(s: Settings, rtol: float) -> tuple[dict, dict]:
    """Best time of every rung and run, and the error of each failed rung.

    Rungs are timed round-robin (each repeat runs every rung once; the best counts), so a
    slow phase of this shared machine hits every rung alike instead of some rungs only.
    """
    from .. import make_engine
    from ..effects import Effects

    best: dict[tuple[str, str], Timing] = {}
    fails: dict[str, str] = {}
    for _ in range(max(1, s.ladder_repeats)):
        for label, kw in LADDER:
            if label in fails:
                continue
            fx = Effects(**kw)
            for run, dt in LADDER_RUNS:
                took, err = _best_of(
                    lambda dt=dt, fx=fx: _record(make_engine(None, fx, "fast", rtol=rtol),
                                                 s.cost_t_end, dt)[0], 1)
                if err:
                    fails[label] = err
                    break
                best[label, run] = best.get((label, run), NEVER).best(took)
    return best, fails


def _ladder_row(s: Settings, rtol: float, label: str, kw: dict, best: dict,
                error: str | None) -> dict:
    """One rung: s per simulated s of each run, and (unless it failed) its solver work."""
    row = {"rung": label, **kw, "error": error}
    for run, _dt in LADDER_RUNS:
        took = None if error else best[label, run]
        row["wall_" + run] = None if took is None else took.wall / s.cost_t_end
        row["cpu_" + run] = None if took is None else took.cpu / s.cost_t_end
    if not error:
        row.update(_ladder_work(s, rtol, kw))
        row["us_per_step"] = 1e6 * row["wall_step_1e-3"] / row["steps_per_sim_s"]
    return row


def _ladder_work(s: Settings, rtol: float, kw: dict) -> dict:
    """The work, free of timing noise: solver steps (an exact-propagator piece counts one)
    and rejected attempts per simulated second at 1e-3 s steps."""
    from .. import make_engine
    from ..effects import Effects
    from ..params import OperatingPoint

    op = OperatingPoint()
    eng = make_engine(None, Effects(**kw), "fast", rtol=rtol)
    eng.reset(0.0, op.torque, op.speed)
    n = int(round(s.cost_t_end / 1e-3))
    steps = rejected = 0
    for i in range(1, n + 1):
        steps += eng.advance(i * 1e-3, op.torque, op.speed).n_steps
        rejected += eng.rejected_steps
    return {"steps_per_sim_s": steps / s.cost_t_end,
            "rejected_per_sim_s": rejected / s.cost_t_end}


def _ladder_checks(ladder: list[dict]) -> dict:
    """Ratios to the top rung (stick-slip, set on the rows) and the ladder's targets: each
    rung dearer than the one below, and the top at least `TARGET_LADDER` x the bottom."""
    top = ladder[-1]
    checks = {}
    for run, _ in LADDER_RUNS:
        for key in ("wall_" + run, "cpu_" + run):
            for row in ladder:
                row["ratio_" + key] = None if row[key] is None or top[key] is None \
                    else row[key] / top[key]
            costs = [r[key] for r in ladder]
            ok = all(c is not None for c in costs)
            x = costs[-1] / costs[0] if ok else None
            checks[key] = {
                "increasing": ok and all(b > a for a, b in zip(costs, costs[1:], strict=False)),
                "stick_slip_over_torsional_constant": x,
                "met": x is not None and x >= TARGET_LADDER,
            }
    return checks
