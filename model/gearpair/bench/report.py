"""The benchmark's result as plain-text tables and as strict JSON."""

from __future__ import annotations

import math
from statistics import median

import numpy as np

from .chost import exit_note
from .settings import (
    DEFAULT,
    FRICTION_OF,
    STIFFNESS_OF,
    TARGET_ERROR,
    TARGET_FMU_FACTOR,
    TARGET_SPEEDUP,
)


def _fmt(x, spec: str = ".3g") -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "NO"
    if isinstance(x, float):
        return format(x, spec)
    return str(x)


def table(headers: list[str], rows: list[list]) -> str:
    """Plain-text table, columns right-aligned except the first."""
    cells = [[str(h) for h in headers]] + [[str(c) for c in r] for r in rows]
    width = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = []
    for k, r in enumerate(cells):
        lines.append("  ".join(c.ljust(width[i]) if i == 0 else c.rjust(width[i])
                               for i, c in enumerate(r)).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in width))
    return "\n".join(lines)


def report(result: dict) -> str:
    """The benchmark's tables as plain text ("s/s": seconds per simulated second; "wall" and
    "CPU" are wall time and CPU time of the measuring process)."""
    out: list[str] = []
    for section in (_header, _work_precision, _equal_accuracy, _core_steps, _fmu, _c_host,
                    _fmi3_host, _wine_host, _cost, _memory_and_targets):
        out += section(result)
    return "\n".join(out)


def regimes_of(result: dict) -> list[str]:
    """The regimes of the work-precision tables of a result, in their order."""
    return [r for r, _ in result["settings"]["windows"]]


def describe(regime: str) -> str:
    """A regime's friction law and, where it is not the paper's, its stiffness law."""
    law = STIFFNESS_OF.get(regime, "potential_energy")
    return f"friction {FRICTION_OF[regime]}" + (
        f", {law} stiffness" if law != "potential_energy" else "")


def short_run_note(result: dict) -> list[str]:
    """What a run on short windows (``--quick``) measures and does not, or nothing."""
    s = result["settings"]
    if s["name"] != "quick" and s["horizon"] >= DEFAULT.horizon:
        return []
    wins = ", ".join(f"{r} {w:g} s" for r, w in s["windows"])
    return [f"NOTE ({s['name']} settings): short windows, {s['horizon']:g} s simulated per "
            f"fast-core and plain-scipy run ({wins} for scipy on the reference engine), "
            f"{s['repeats']} timed repeat(s), {len(s['fast_rtols'])} tolerances of the fast "
            "core. They test the bench's code. Their costs are mostly the start of each run "
            "(the static equilibrium, the first steps, solve_ivp's set-up), which a long "
            "run spreads out, and they hold no pair entry, exit or stick (the first, a "
            "pair exit, comes at 13.6 ms). So their ratios and target verdicts do not stand "
            "for the full run: quote `gearpair bench` (0.1 s runs).", ""]


def _header(result: dict) -> list[str]:
    """Title, machine, software, what a short run does not measure, reference and error
    definition, cross-check."""
    m, s = result["machine"], result["settings"]
    out = [f"gearpair bench ({s['name']}), {m['date']}",
           f"machine: {m['cpu']}, {m['cores']} cores ({m['usable_cores']} usable), "
           f"{m['memory_gb']} GB; load average {m['load_average']} at start, "
           f"{m.get('load_average_end')} at end",
           f"software: {m['os']}, Python {m['python']}, numpy {m['numpy']}, scipy {m['scipy']}, "
           f"numba {m['numba']}, fmpy {m['fmpy']}, pythonfmu {m['pythonfmu']}; "
           f"commit {m['commit']}",
           f"total wall time {result['wall_s']:.0f} s", ""]
    out += short_run_note(result)
    ref = result["reference"]
    win = ", ".join(f"{r} {w:g} s" for r, w in s["windows"])
    out += [f"Reference: fast core at rtol {ref['rtol']:g}, output every {ref['dt']:g} s, "
            "from the static start at 3900 N.m, 100 r/min (regimes: " + "; ".join(
                f"{r}: {describe(r)}" for r in regimes_of(result)) + "). "
            "Error = max|x - x_ref| / "
            f"max|x_ref| over the common window ({win}); the fast core and the FMU run "
            f"{s['horizon']:g} s ('whole run' error over all of it). Cost = time per "
            "simulated second of the stepping loop (engine built, FMU instantiated before).",
            ""]
    if ref["cross_check"]:
        out.append(table(
            ["cross-check", "simulated s", "DTE diff", "force diff", "DOP853 wall s/s",
             "fast wall s/s"],
            [[f"{c['regime']}: {c.get('engine', 'DOP853')} vs fast, rtol {c['rtol']:g}",
              _fmt(c["horizon_s"]),
              _fmt(c["diff_dte"], ".1e"), _fmt(c["diff_force"], ".1e"),
              _fmt(c["dop853_wall_per_sim_s"], ".0f"), _fmt(c["fast_wall_per_sim_s"])]
             for c in ref["cross_check"]]))
        out.append("")
    return out


def _work_precision(result: dict) -> list[str]:
    """One work-precision table per regime."""
    out: list[str] = []
    for regime in regimes_of(result):
        rows = [r for r in result["work_precision"] if r["regime"] == regime]
        out.append(f"Work-precision, {regime} ({describe(regime)}):")
        out.append(table(
            ["method", "setting", "simulated s", "wall s/s", "CPU s/s", "DTE error",
             "force error", "DTE err whole run"],
            [[r["method"], r["setting"], _fmt(r["horizon_s"]), _fmt(r["wall_per_sim_s"]),
              _fmt(r["cpu_per_sim_s"]), _fmt(r["err_dte"], ".1e"), _fmt(r["err_force"], ".1e"),
              _fmt(r["err_dte_horizon"], ".1e")] if not r["error"] else
             [r["method"], r["setting"], _fmt(r["horizon_s"]), "failed", "-", "-", "-", "-"]
             for r in rows]))
        out += [f"  {r['method']} {r['setting']} failed: {r['error']}" for r in rows
                if r["error"]]
        out.append("")
    return out


def _equal_accuracy(result: dict) -> list[str]:
    """Cheapest setting per method at the target error, wall and CPU, and the fast core's
    lead over scipy's solvers on the reference engine and over plain scipy."""
    out: list[str] = []
    methods = list(dict.fromkeys(r["method"] for r in result["work_precision"]))
    acc = result["equal_accuracy"]
    for suffix, what in (("", "wall"), ("_cpu", "CPU")):
        key = "wall_per_sim_s" if not suffix else "cpu_per_sim_s"
        out.append(f"Equal accuracy, {what} time: cheapest setting with DTE error <= "
                   f"{TARGET_ERROR:g} over the window and over its whole run, s/s:")

        def cell(e, mm, key=key, suffix=suffix):
            if mm not in e["best" + suffix]:
                return "-"  # not run in this regime
            b = e["best" + suffix][mm]
            return "not reached" if b is None else f"{b[key]:.3g} ({b['setting']})"

        def ratio(e, kind, suffix=suffix):
            x, m = e["ratio" + kind + suffix], e["fastest" + (kind or "_scipy") + suffix]
            return "-" if x is None else f"{x:.0f} x ({m})"

        rows = [[mm, *[cell(e, mm) for e in acc]] for mm in methods]
        rows.append(["scipy on the reference engine / fast", *[ratio(e, "") for e in acc]])
        rows.append(["plain scipy / fast", *[ratio(e, "_plain") for e in acc]])
        out.append(table(["method", *[e["regime"] for e in acc]], rows))
        out.append("")
    return out + _claim(result)


def _claim(result: dict) -> list[str]:
    """The speed claim: per regime the fast core and the fastest plain scipy method, each at
    its cheapest setting that reaches the error bar, their errors and the ratio of costs."""
    s = result["settings"]
    out = [f"The claim: fast core against the fastest plain scipy method at equal accuracy "
           f"(each at its cheapest setting with DTE error <= {TARGET_ERROR:g} against the "
           f"reference, over the window and over its whole {s['horizon']:g} s run; target "
           f">= {TARGET_SPEEDUP:g} x):"]
    rows = []
    for e in result["equal_accuracy"]:
        fast, m = e["best"].get("fast"), e["fastest_plain"]
        plain = e["best"].get(m) if m else None

        def side(b):
            if b is None:
                return ["not reached", "-", "-"]
            return [b["setting"], _fmt(b["wall_per_sim_s"]),
                    f"{b['err_dte']:.1e} / {b['err_dte_horizon']:.1e}"]

        cpu = e["ratio_plain_cpu"]
        cpu_txt = "-" if cpu is None else f"{cpu:.0f} x" + (
            f" ({e['fastest_plain_cpu']})" if e["fastest_plain_cpu"] != m else "")
        rows.append([e["regime"], *side(fast), m or "none", *side(plain),
                     "-" if e["ratio_plain"] is None else f"{e['ratio_plain']:.0f} x", cpu_txt])
    out.append(table(["regime", "fast setting", "fast wall s/s", "fast DTE err window / run",
                      "fastest plain", "its setting", "plain wall s/s",
                      "plain DTE err window / run", "plain / fast wall", "CPU"], rows))
    out.append("")
    return out


def _core_steps(result: dict) -> list[str]:
    """The fast core at 1e-3 s steps."""
    s = result["settings"]
    out: list[str] = []
    out.append(f"Fast core at 1e-3 s steps ({s['step_horizon']:g} s simulated, best of "
               f"{s['repeats']}):")
    out.append("(grid: `simulate`, one compiled call for the whole run; per call: one "
               "`advance` + `outputs` Python call per step, as an FMU master drives it)")
    out.append(table(["regime", "rtol", "wall s/s grid", "CPU s/s grid", "wall s/s per call",
                      "CPU s/s per call", "engine build s"],
                     [[c["regime"], _fmt(c["rtol"]),
                       _fmt(c["wall_per_sim_s"]) if not c["error"] else "failed",
                       _fmt(c["cpu_per_sim_s"]), _fmt(c.get("calls_wall_per_sim_s")),
                       _fmt(c.get("calls_cpu_per_sim_s")), _fmt(c["build_s"])]
                      for c in result["core_steps"]]))
    out += [f"  {c['regime']} rtol {c['rtol']:g} failed: {c['error']}"
            for c in result["core_steps"] if c["error"]]
    out.append("")
    return out


def _fmu(result: dict) -> list[str]:
    """FMU at a 1e-3 s step against core and floor; one call's cost; start-up."""
    s = result["settings"]
    out: list[str] = []
    fm = result.get("fmu")
    if fm:
        if result.get("fmu_file"):
            out.append(f"FMU measured: {result['fmu_file']}")
        out.append(f"FMU through fmpy.simulate_fmu at a 1e-3 s step ({s['step_horizon']:g} s "
                   f"simulated, best of {s['repeats']}) against the core (per call) and the "
                   "no-op floor, "
                   "s/s; 'FMU total' adds the initialization (instantiation excluded):")
        for suffix, what in (("", "wall"), ("_cpu", "CPU")):
            out.append(table(
                ["regime", "rtol", f"core {what}", f"FMU {what}", "FMU total",
                 f"floor {what}", "FMU/core", "(FMU-floor)/core",
                 f"allowed {TARGET_FMU_FACTOR:g}xcore+floor", "met"],
                [[st["regime"], _fmt(st["rtol"]), _fmt(st.get("core_per_sim_s" + suffix)),
                  _fmt(st.get("fmu_per_sim_s" + suffix)),
                  _fmt(st.get("fmu_total_per_sim_s" + suffix)),
                  _fmt(st.get("floor_per_sim_s" + suffix)),
                  _fmt(st.get("fmu_over_core" + suffix), ".2f"),
                  _fmt(st.get("fmu_minus_floor_over_core" + suffix), ".2f"),
                  _fmt(st.get("allowed_per_sim_s" + suffix)), _fmt(st.get("met" + suffix))]
                 for st in fm["steps"]]))
        out += [f"  {st['regime']} failed: {st['error']}" for st in fm["steps"] if st["error"]]
        c = fm["calls"]

        def us(key):
            w, cpu = c[key + "_s"], c[key + "_cpu_s"]
            return "failed" if w is None else f"{w * 1e6:.0f} us ({cpu * 1e6:.0f} us CPU)"

        out.append(f"One setReal+doStep(1e-3 s)+getReal+getInteger call ({c['regime']}, "
                   f"{c['n']} calls): GearPair {us('gearpair')}, no-op {us('noop')}; the "
                   f"engine's own advance+outputs {us('engine')}.")
        if c["error"]:
            out.append(f"  failed: {c['error']}")
        out.append("")
    if result.get("fmu_error"):
        out += [f"FMU section failed: {result['fmu_error']}", ""]
    st = result.get("startup")
    if st:
        out.append("FMU first instantiation + initialization + first step (fresh process):")
        out.append(table(
            ["caches", "instantiate s", "initialize s", "first step s", "total s"],
            [[k, _fmt(v["instantiate_s"]), _fmt(v["initialize_s"]), _fmt(v["first_step_s"]),
              _fmt(v["total_s"])]
             for k, v in (("empty caches (shipped code)", st.get("empty")),
                          ("warm (cached)", st.get("cached")),
                          ("empty, GEARPAIR_SHIPPED_CODE=0 (compile)", st.get("compile")))
             if v]))
        out.append("")
    return out


def _c_host(result: dict) -> list[str]:
    """The FMU's per-step cost in a C host and in fmpy, and its first start in the C host."""
    ch = result.get("c_host")
    if not ch:
        return []
    if ch["note"]:
        return [ch["note"], ""]
    out = [f"FMU per step in a C host (gearpair/bench/fmi2_bench_host.c) and in fmpy, the loop "
           f"of a master: set {', '.join(ch['inputs'])}; doStep; get {', '.join(ch['outputs'])} "
           f"({ch['regime']} at the default point, rtol {ch['rtol']:g}, best of {ch['blocks']}"
           f" blocks of {ch['n']} steps), us per step; no-op: the same binary (this project's "
           "C layer over pythonfmu's library) with a slave that computes nothing, the C "
           "layer's own cost; engine: the same compiled step called from Python in this "
           "process (advance_values + output_values), over GearPair's best block:"]
    for clk, what in (("", "wall"), ("_cpu", "CPU")):
        out.append(table(
            ["step s", f"C GearPair {what}", "C no-op", "fmpy GearPair", "fmpy no-op",
             "engine (Python)", "C host s/s"],
            [[_fmt(r["step"]), *[_fmt(r.get(f"{k}{clk}_us"), ".2f") for k in (
                "c_gearpair", "c_noop", "fmpy_gearpair", "fmpy_noop", "engine")],
              _fmt(r.get("c_per_sim_s")) if not clk else "-"]
             if not r["error"] else [_fmt(r["step"]), "failed", *["-"] * 5]
             for r in ch["steps"]]))
    out += [f"  step {r['step']:g} failed: {r['error']}" for r in ch["steps"] if r["error"]]
    status = {k: v for r in ch["steps"] for k, v in r.get("exit_status", {}).items()}
    if status:
        out.append("C host exit status: " + ", ".join(
            f"{k} {exit_note(v)}" for k, v in status.items()) + " (each host prints and "
            "flushes its result before it frees the instance)")
    th = ch.get("threads")
    if th and th["error"]:
        out.append(f"C host thread modes failed: {th['error']}")
    elif th:
        out.append(f"GearPair in the C host by thread ({th['step']:g} s steps, {th['rounds']} "
                   f"rounds of {th['n']} steps a mode, run back to back; us per step; main: "
                   "the instantiating thread; worker: another thread; serial: two instances "
                   "one after the other; pair: the same two at once in two threads; "
                   "processes: two at once in two processes, this host and a forked copy; "
                   "floor: the same model time at 10 x the step, per step; pair gain and "
                   "ceiling: serial over pair and over processes; spin: two threads of "
                   "dependent arithmetic over one):")
        rows = [[m, _fmt(min(th[k]), ".2f"), _fmt(median(th[k]), ".2f"),
                 _fmt(max(th[k]), ".2f")]
                for m, k in (("main", "main_us"), ("worker", "worker_us"),
                             ("serial", "serial_us"), ("pair", "pair_us"),
                             ("processes", "procs_us"), ("floor", "floor_us"),
                             ("pair gain", "gain"), ("ceiling", "ceilings"),
                             ("spin", "spin_ceilings"))]
        out.append(table(["mode", "best", "median", "worst"], rows))
        out.append(f"medians of the per-round ratios: worker / main "
                   f"{th['worker_over_main']:.2f}; main / floor {th['step_over_floor']:.2f}; "
                   f"pair gain {th['pair_speedup']:.2f} against a ceiling of "
                   f"{th['ceiling']:.2f} for two processes, {th['pair_over_ceiling']:.2f} "
                   f"of it (spin {th['spin_ceiling']:.2f}); outputs of every instance at the "
                   "step " + ("the same" if th["identical"] else
                              "DIFFER: " + " ".join(th["digests"])))
    out += _native_rows(ch.get("native"))
    st = ch.get("startup")
    if st and st.get("error"):
        out.append(f"C host first start failed: {st['error']}")
    elif st:
        out.append("FMU first start in the C host (fresh process: instantiate, initialize, "
                   "first 1e-3 s step), caches = NUMBA_CACHE_DIR and XDG_CACHE_HOME:")
        out.append(table(
            ["caches", "instantiate s", "initialize s", "first step s", "total s", "exit"],
            [[k, _fmt(v["instantiate_s"]), _fmt(v["initialize_s"]), _fmt(v["first_step_s"]),
              _fmt(v["total_s"]), exit_note(v["exit_status"])]
             for k, v in (("empty (shipped code)", st["empty"]), ("warm", st["warm"]))]))
    out.append("")
    return out


def _native_rows(nat: dict | None) -> list[str]:
    """GearPair.fmu's step against the native step it replaced, round by round."""
    if not nat:
        return []
    if nat["error"]:
        return [f"GearPair.fmu against the native step failed: {nat['error']}"]
    out = [f"GearPair.fmu in the C host against the native step it replaced (the engine's "
           f"compiled step, compiled for {nat['cpu_name']} as the FMU's, called from C at its "
           f"address with the FMU's checks and rollback, in a process of its own; "
           f"{nat['step']:g} s steps, {nat['rounds']} rounds of {nat['n']} steps of each, the "
           "same model time, the first of the two alternating, both on one CPU; us per step, "
           "wall and the stepping thread's CPU):"]
    rows = [[what, *[_fmt(f(nat[k]), fmt) for k in keys for f in (min, median)]]
            for what, keys, fmt in (("GearPair.fmu", ("fmu_us", "fmu_cpu_us"), ".2f"),
                                    ("native step", ("native_us", "native_cpu_us"), ".2f"),
                                    ("FMU / native", ("ratios", "ratios_cpu"), ".3f"))]
    out.append(table(["step", "best", "median", "CPU best", "CPU median"], rows))
    out.append(f"median of the per-round ratios GearPair.fmu / native: "
               f"{nat['fmu_over_native']:.3f} (CPU {nat['fmu_over_native_cpu']:.3f}); "
               "outputs at every step " + ("the same" if nat["identical"] else
                                           "DIFFER: " + " ".join(nat["digests"])))
    return out


_VARIANT_NAMES = {"fmi2": "GearPair.fmu (FMI 2)", "fmi3": "GearPair3.fmu, no early return",
                  "fmi3_events": "GearPair3.fmu, early return + Event Mode",
                  "fmi3_early": "GearPair3.fmu, early return, no Event Mode"}


def _fmi3_host(result: dict) -> list[str]:
    """GearPair3.fmu against GearPair.fmu in the C host, with and without early return."""
    fh = result.get("fmi3_host")
    if not fh:
        return []
    if fh["note"]:
        return [fh["note"], ""]
    if fh["error"]:
        return [f"GearPair3.fmu rows failed: {fh['error']}", ""]
    out = [f"GearPair3.fmu (FMI 3.0) against GearPair.fmu in a C host "
           f"(gearpair/bench/fmi3_bench_host.c), the loop of a master: set "
           f"{', '.join(fh['inputs'])}; doStep; get {', '.join(fh['outputs'])} ({fh['regime']} "
           f"at the default point, the paper's stick-slip scene, rtol {fh['rtol']:g}, "
           f"{fh['step']:g} s communication steps; {fh['rounds']} rounds of {fh['n']} points, "
           "every variant over the same model time in each round, back to back; us per "
           "communication point, an early return's extra set + doStep + get included, the "
           "best round and the mean of all; s/s: s per simulated s over all rounds; ratio: "
           "the median of the per-round ratios to the run without early return):"]
    base = "fmi3"
    rows = []
    for name, v in fh["variants"].items():
        ratio = 1.0 if name == base else fh.get(f"{name}_over_{base}")
        if name == "fmi2":
            ratio = 1.0 / fh["fmi3_over_fmi2"]
        rows.append([_VARIANT_NAMES.get(name, name), _fmt(v["wall_best_us"], ".2f"),
                     _fmt(v["wall_mean_us"], ".2f"), _fmt(v["cpu_mean_us"], ".2f"),
                     _fmt(v["calls_per_s"], ".0f"), _fmt(v["early_per_s"], ".0f"),
                     _fmt(v["events_per_s"], ".0f"), _fmt(v["per_sim_s"], ".4f"),
                     _fmt(v["per_sim_s_cpu"], ".4f"), _fmt(ratio, ".3f")])
    out.append(table(["variant", "wall best", "wall mean", "CPU mean", "doStep/s",
                      "early returns/s", "Event Mode/s", "wall s/s", "CPU s/s",
                      "/ no early return"], rows))
    same = "the same" if fh["identical"] else "DIFFERENT"
    out.append(f"GearPair3.fmu / GearPair.fmu per step without early return: "
               f"{fh['fmi3_over_fmi2']:.3f} (median of the per-round ratios; CPU "
               f"{fh['fmi3_over_fmi2_cpu']:.3f}; best rounds {fh['fmi3_over_fmi2_best']:.3f});"
               f" outputs at every communication point {same} bits"
               + (", with early return too" if fh["identical_early"] else "") + ".")
    ev = fh["variants"].get("fmi3_events")
    if ev:
        extra, extra_cpu = fh.get("fmi3_events_extra_us"), fh.get("fmi3_events_extra_us_cpu")
        out.append(f"With early return (a master that handles each one in Event Mode): "
                   f"{ev['early_per_s']:.0f} early returns, i.e. extra doStep calls, per "
                   f"simulated s; the run costs {fh['fmi3_events_over_fmi3']:.3f} x the run "
                   f"without (CPU {fh['fmi3_events_over_fmi3_cpu']:.3f} x)"
                   + ("" if extra is None else f", {extra:.1f} us per early return (CPU "
                      f"{extra_cpu:.1f} us)") + ".")
    out.append("")
    return out


def _wine_host(result: dict) -> list[str]:
    """GearPair.fmu's win64 DLL under Wine against its linux64 binary (information)."""
    wh = result.get("wine_host")
    if not wh:
        return []
    if wh["note"]:
        return [wh["note"], ""]
    if wh["error"]:
        return [f"win64 under Wine failed: {wh['error']}", ""]
    return [f"GearPair.fmu per step, win64 DLL under Wine against the linux64 binary "
            f"(information, no target: Wine is not Windows): the host above built with "
            f"mingw-w64 and with gcc, {wh['runs']} processes of each, alternating, "
            f"{wh['rounds']} blocks of {wh['n']} steps of {wh['step']:g} s each, "
            f"{wh['regime']} at the default point, rtol {wh['rtol']:g}; us per step:",
            table(["platform", "wall best", "wall median", "CPU (all blocks)"],
                  [[name, _fmt(wh[f"{key}_best_us"], ".2f"),
                    _fmt(wh[f"{key}_median_us"], ".2f"), _fmt(wh[f"{key}_cpu_us"], ".2f")]
                   for name, key in (("linux64", "linux"), ("win64 under Wine", "win64"))]),
            f"win64 / linux64 (medians): {wh['win64_over_linux']:.3f}; outputs "
            + ("the same bits on both" if wh["identical"] else "DIFFER between them")
            + " (Wine's thread CPU clock ticks in 10 ms: only the sum over the blocks "
            "counts)", ""]


def _cost(result: dict) -> list[str]:
    """Cost of the shipped scenes and the effect ladder."""
    out: list[str] = []
    cost = result.get("cost")
    if cost and cost.get("scenes_note"):
        out += [cost["scenes_note"], ""]
    elif cost:
        out.append(f"Cost of the shipped scenes (fast engine, first {cost['t_end']:g} s, "
                   "their own step and rtol):")
        out.append(table(["scene", "simulated s", "step s", "dof", "stiffness", "friction",
                          "wall s/s", "CPU s/s"],
                         [[r["scene"], _fmt(r["t_end"]), _fmt(r["step"]), r["dof"],
                           r["stiffness"], r["friction"],
                           "failed" if r["error"] else _fmt(r["wall_per_sim_s"]),
                           _fmt(r["cpu_per_sim_s"])] for r in cost["scenes"]]))
        out += [f"  {r['scene']} failed: {r['error']}" for r in cost["scenes"] if r["error"]]
        out.append("")
    if cost:
        out.append(f"Effect ladder (fast engine, rtol {cost['rtol']:g}, 3900 N.m, 100 r/min, "
                   f"{cost['t_end']:g} s simulated), s/s and ratio to stick-slip:")
        heads, cols = ["rung"], []
        for run, what in (("step_1e-3", "1e-3 s steps"), ("out_1e-4", "output 1e-4 s")):
            for clk in ("wall", "cpu"):
                heads += [f"{clk} {what}", "ratio"]
                cols += [f"{clk}_{run}"]
        heads += ["steps/s", "rejected/s", "us/step"]
        out.append(table(heads, [[r["rung"], *[x for k in cols for x in (
            _fmt(r[k]), _fmt(r["ratio_" + k], ".2f"))], _fmt(r.get("steps_per_sim_s"), ".3g"),
            _fmt(r.get("rejected_per_sim_s"), ".3g"), _fmt(r.get("us_per_step"))]
            for r in cost["ladder"]]))
        out += [f"  {r['rung']} failed: {r['error']}" for r in cost["ladder"] if r["error"]]
        out.append("")
    return out


def _memory_and_targets(result: dict) -> list[str]:
    """Memory line and the targets table."""
    out: list[str] = []
    mem = result.get("memory")
    if mem:
        out.append(f"Memory: {mem['t_end']:g} s simulated, recorded every {mem['dt']:g} s "
                   f"({mem['samples']} samples, {mem['trajectory_mb']:.0f} MB of arrays): peak "
                   f"RSS {mem['peak_rss_mb']:.0f} MB (after imports {mem['baseline_rss_mb']:.0f}"
                   f" MB), {mem['wall_s']:.0f} s of wall time.")
        out.append("")
    out += short_run_note(result)
    out.append("Targets (measured in wall time, the target's measure, and in CPU time):")
    out.append(table(["target", "wall", "met", "CPU", "met (CPU)", "short by (wall)"],
                     [[t["target"], _fmt(t["measured"]), _fmt(t["met"]),
                       _fmt(t["measured_cpu"]), _fmt(t["met_cpu"]), _fmt(t["short_by"])]
                      for t in result["targets"]]))
    return out



def jsonable(x):
    """``x`` with numpy scalars as Python numbers and NaN/inf as None (strict JSON)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    return x

