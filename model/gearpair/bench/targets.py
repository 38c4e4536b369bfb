"""The targets of the issues: measured value, met or not, short by how much."""

from __future__ import annotations

from .settings import (
    CEILING_AT_TARGET,
    FLOOR_AT_TARGET_US,
    TARGET_ERROR,
    TARGET_FIRST_START_S,
    TARGET_FMI3_STEP,
    TARGET_FMU_FACTOR,
    TARGET_INSTANCE_MB,
    TARGET_INSTANCE_S,
    TARGET_LADDER,
    TARGET_LAYER_US,
    TARGET_MEMORY_MB,
    TARGET_NATIVE_RATIO,
    TARGET_PAIR,
    TARGET_PROCESS_MB,
    TARGET_PROCESS_S,
    TARGET_SPEEDUP,
    TARGET_STEP_US,
    TARGET_STICK_SLIP,
    TARGET_WORKER,
)
from .work_precision import accurate_rtol


def _target(what: str, wall, cpu, limit: float, fmt: str, higher_is_better: bool = False,
            error: str | None = None) -> dict:
    """A target row: measured value in wall and CPU time, met or not, short by how much."""
    if error or wall is None:
        return {"target": what, "measured": f"run failed: {error}", "measured_cpu": None,
                "met": None, "met_cpu": None, "short_by": None}

    def ok(x):
        return None if x is None else (x >= limit if higher_is_better else x <= limit)

    factor = (limit / wall) if higher_is_better else (wall / limit)
    return {"target": what, "measured": format(wall, fmt),
            "measured_cpu": None if cpu is None else format(cpu, fmt),
            "met": ok(wall), "met_cpu": ok(cpu),
            "short_by": None if ok(wall) else f"factor {factor:.2f}"}


def targets(result: dict) -> list[dict]:
    """Each target: the measured value in wall time (the target's measure) and in CPU
    time (steadier on a shared machine), whether it is met and by what factor it is not."""
    out = []
    for kind, whose in (("", "scipy on the reference engine"),
                        ("_plain", "plain scipy")):
        for e in result["equal_accuracy"]:
            what = (f"fast core >= {TARGET_SPEEDUP:g} x the fastest scipy method ({whose}) at "
                    f"DTE error <= {TARGET_ERROR:g} ({e['regime']}; x)")
            out.append(_target(what, e["ratio" + kind], e["ratio" + kind + "_cpu"],
                               TARGET_SPEEDUP, ".0f", True,
                               None if e["ratio" + kind] else "not reached by a method"))
    for st in (result.get("fmu") or {}).get("steps", []):
        what = (f"FMU at 1e-3 s <= {TARGET_FMU_FACTOR:g} x core + floor ({st['regime']}, "
                f"rtol {st['rtol']:g}; FMU / allowed)")
        if st["error"]:
            out.append(_target(what, None, None, 1.0, ".2f", error=st["error"]))
            continue
        out.append(_target(what, st["fmu_per_sim_s"] / st["allowed_per_sim_s"],
                           st["fmu_per_sim_s_cpu"] / st["allowed_per_sim_s_cpu"], 1.0, ".2f"))
    out += _host_targets(result.get("c_host"))
    out += _fmi3_targets(result.get("fmi3_host"))
    acc = accurate_rtol(result["work_precision"], "stick_slip")
    for c in result["core_steps"]:
        if c["regime"] != "stick_slip":
            continue
        tag = ", the loosest with DTE error <= 1e-6" if c["rtol"] == acc else ""
        what = (f"stick-slip: 1 simulated s in <= {TARGET_STICK_SLIP:g} s, fast core at "
                f"1e-3 s steps, rtol {c['rtol']:g}{tag} (s)")
        out.append(_target(what, c["wall_per_sim_s"], c["cpu_per_sim_s"], TARGET_STICK_SLIP,
                           ".3f", error=c["error"]))
    mem = result.get("memory")
    if mem:
        out.append(_target(f"{mem['t_end']:g} s recorded every {mem['dt']:g} s: peak RSS <= "
                           f"{TARGET_MEMORY_MB:g} MB (MB)", mem["peak_rss_mb"], None,
                           TARGET_MEMORY_MB, ".0f"))
    cost = result.get("cost")
    if cost:
        for run, what in (("step_1e-3", "1e-3 s steps"), ("out_1e-4", "output every 1e-4 s")):
            w, c = cost["checks"]["wall_" + run], cost["checks"]["cpu_" + run]
            row = _target(f"effect ladder, {what}: stick-slip / torsional constant stiffness "
                          f">= {TARGET_LADDER:g} (x)", w["stick_slip_over_torsional_constant"],
                          c["stick_slip_over_torsional_constant"], TARGET_LADDER, ".1f", True,
                          None if w["stick_slip_over_torsional_constant"] else "a rung failed")
            out.append(row)
            out.append({"target": f"effect ladder, {what}: each added effect costs more",
                        "measured": str(w["increasing"]), "measured_cpu": str(c["increasing"]),
                        "met": w["increasing"], "met_cpu": c["increasing"], "short_by": None})
    return out



def _host_targets(ch: dict | None) -> list[dict]:
    """The C host at a 1e-4 s step (GearPair per step, the C layer's own cost), by thread,
    and the first start with empty caches."""
    if not ch or ch["note"]:
        return []
    out = []
    for r in ch["steps"]:
        if r["step"] != 1e-4:
            continue
        what = (f"C host at 1e-4 s: GearPair per step (native step, {ch['regime']}, rtol "
                f"{ch['rtol']:g}) <= {TARGET_STEP_US:g} us (us)")
        out.append(_target(what, r.get("c_gearpair_us"), r.get("c_gearpair_cpu_us"),
                           TARGET_STEP_US, ".2f", error=r["error"]))
        what = (f"C host at 1e-4 s: the FMI layer's own cost per step (the same layer over a "
                f"model that does nothing) <= {TARGET_LAYER_US:g} us (us)")
        out.append(_target(what, r.get("c_noop_us"), r.get("c_noop_cpu_us"),
                           TARGET_LAYER_US, ".2f", error=r["error"]))
    pr = ch.get("process")
    if pr:
        what = (f"C host: a whole process (instantiate, one 1e-4 s step, free, exit; empty "
                f"environment) <= {TARGET_PROCESS_S:g} s (s)")
        out.append(_target(what, pr["wall_s"], None, TARGET_PROCESS_S, ".3f",
                           error=pr["error"]))
        what = f"C host: a whole process, peak memory <= {TARGET_PROCESS_MB:g} MB (MB)"
        out.append(_target(what, pr["peak_mb"], None, TARGET_PROCESS_MB, ".1f",
                           error=pr["error"]))
    inst = ch.get("instances")
    if inst:
        what = (f"C host: each further instance, fmi2Instantiate to the end of "
                f"fmi2ExitInitializationMode <= {TARGET_INSTANCE_S * 1e3:g} ms (ms)")
        out.append(_target(what, None if inst["error"] else 1e3 * inst["further_s"], None,
                           TARGET_INSTANCE_S * 1e3, ".2f", error=inst["error"]))
        what = f"C host: each further instance adds <= {TARGET_INSTANCE_MB:g} MB (MB)"
        out.append(_target(what, None if inst["error"] else inst["further_mb"], None,
                           TARGET_INSTANCE_MB, ".3f", error=inst["error"]))
    th = ch.get("threads")
    if th:
        err = th["error"]
        scaled = TARGET_STEP_US / FLOOR_AT_TARGET_US
        what = (f"C host at 1e-4 s: GearPair per step / the floor of a 1e-4 s step (the "
                f"same model time at 1e-3 s steps), median of the interleaved rounds <= "
                f"{scaled:.2f} (the {TARGET_STEP_US:g} us target over the "
                f"{FLOOR_AT_TARGET_US:g} us floor of the machine it was set on; x)")
        out.append(_target(what, th.get("step_over_floor"), None, scaled, ".2f", error=err))
        what = (f"C host: per step from a worker thread / from the instantiating thread <= "
                f"{TARGET_WORKER:g} (x)")
        out.append(_target(what, th.get("worker_over_main"), None, TARGET_WORKER, ".2f",
                           error=err))
        what = (f"C host: two instances in two threads, throughput / one after the other >= "
                f"{TARGET_PAIR:g} (x)")
        out.append(_target(what, th.get("pair_speedup"), None, TARGET_PAIR, ".2f", True,
                           error=err))
        scaled = TARGET_PAIR / CEILING_AT_TARGET
        what = (f"C host: two instances in two threads, throughput gain / the machine's "
                f"ceiling for two instances (two in two processes, in the same rounds) >= "
                f"{scaled:.2f} (the {TARGET_PAIR:g} x target on two free cores; x)")
        out.append(_target(what, th.get("pair_over_ceiling"), None, scaled, ".2f", True,
                           error=err))
        if not err:
            out.append({"target": "C host: every thread mode and instance gives the same "
                        "outputs (digest of every output of every step)",
                        "measured": str(th["identical"]), "measured_cpu": None,
                        "met": th["identical"], "met_cpu": None, "short_by": None})
    out += _native_targets(ch.get("native"))
    st = ch.get("startup")
    if st:
        what = (f"first start of the FMU with empty caches (C host) <= "
                f"{TARGET_FIRST_START_S:g} s (s)")
        out.append(_target(what, None if st["error"] else st["empty"]["total_s"], None,
                           TARGET_FIRST_START_S, ".1f", error=st["error"]))
    return out


def _native_targets(nat: dict | None) -> list[dict]:
    """GearPair.fmu's step against the native step it replaced, measured in the same run
    (`chost.host_native`): the median of the per-round ratios at most `TARGET_NATIVE_RATIO`,
    and the same output bits."""
    if not nat:
        return []
    what = (f"C host at {nat['step']:g} s: GearPair.fmu per step / the native step (the "
            f"engine's compiled step called from C at its address, as the FMU it replaced "
            f"did), median of the interleaved rounds <= {TARGET_NATIVE_RATIO:g} (x)")
    if nat["error"]:
        return [_target(what, None, None, TARGET_NATIVE_RATIO, ".3f", error=nat["error"])]
    return [_target(what, nat["fmu_over_native"], nat["fmu_over_native_cpu"],
                    TARGET_NATIVE_RATIO, ".3f"),
            {"target": "C host: GearPair.fmu gives the native step's outputs at every step "
             "(digest of their bits)", "measured": str(nat["identical"]),
             "measured_cpu": None, "met": nat["identical"], "met_cpu": None,
             "short_by": None}]


def _fmi3_targets(fh: dict | None) -> list[dict]:
    """GearPair3.fmu without early return against GearPair.fmu in the C host (issue 35): the
    median of the per-round ratios of their cost per step within `TARGET_FMI3_STEP` of 1,
    either way (the same cost, not only no dearer), and the same output bits."""
    if not fh or fh["note"]:
        return []
    what = (f"C host at {fh['step']:g} s: GearPair3.fmu per step without early return / "
            f"GearPair.fmu per step, median of the interleaved rounds, within "
            f"{100 * TARGET_FMI3_STEP:g} % of 1 (x)")
    if fh["error"]:
        return [_target(what, None, None, 1.0, ".3f", error=fh["error"])]

    def ok(x):
        return None if x is None else abs(x - 1.0) <= TARGET_FMI3_STEP

    wall, cpu = fh["fmi3_over_fmi2"], fh.get("fmi3_over_fmi2_cpu")
    off = abs(wall - 1.0) / TARGET_FMI3_STEP
    return [{"target": what, "measured": format(wall, ".3f"),
             "measured_cpu": None if cpu is None else format(cpu, ".3f"), "met": ok(wall),
             "met_cpu": ok(cpu), "short_by": None if ok(wall) else f"factor {off:.2f}"},
            {"target": "C host: GearPair3.fmu without early return gives GearPair.fmu's "
             "outputs at every communication point (digest of their bits)",
             "measured": str(fh["identical"]), "measured_cpu": None, "met": fh["identical"],
             "met_cpu": None, "short_by": None}]
