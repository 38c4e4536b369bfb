"""FMU measurements: the GearPair FMU that `gearpair.scenes.location.find_fmu` finds (or the
one passed) and the no-op slave made beside it, driven by fmpy in child processes."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from ..scenes import driver
from .runs import Timing, _errors, regime_effects
from .settings import NOOP_SCRIPT, REGIMES, TARGET_FMU_FACTOR, Progress, Settings, _quiet
from .work_precision import _FAILED, _NO_ERRORS, _row, engine_call_cost

# Runs in a child process that never imports the working tree's gearpair: the FMU driver's
# text (`gearpair.scenes.driver`, which imports nothing of gearpair), then this. Reads a job
# (JSON file argv[1]) and writes its answers (JSON file argv[2]).
_FMU_WORKER = driver.source() + r"""
import importlib, json, os, sys, time
job = json.load(open(sys.argv[1]))
t_imp = time.perf_counter()
import fmpy
drv = FmuDriver(job["fmu"], unzipdir=os.path.join(os.getcwd(), "extracted"))
md, unzip, var = drv.md, drv.unzip, drv.variables
out = {"import_s": time.perf_counter() - t_imp}

def instance():
    return drv.instance("bench")

set_values = drv.set_values

def simulate(r):
    try:
        return simulate1(r)
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}

def simulate1(r):
    best = None
    for _ in range(r["repeats"]):
        fmu = instance()
        marks = []
        def mark(t, recorder):
            marks.append((time.perf_counter(), time.process_time()))
            return True
        t0 = (time.perf_counter(), time.process_time())
        res = fmpy.simulate_fmu(unzip, model_description=md, fmu_instance=fmu, start_time=0.0,
                                stop_time=r["t_end"], output_interval=r["step"],
                                start_values=r["start"], output=r["outputs"],
                                step_finished=mark, validate=False)
        t1 = (time.perf_counter(), time.process_time())
        fmu.freeInstance()
        n = len(marks)
        # the loop: from the first step's end to the last's, scaled to all n steps
        got = {"steps": n}
        for i, key in enumerate(("", "_cpu")):
            total = t1[i] - t0[i]
            got["total_s" + key] = total
            got["loop_s" + key] = (marks[-1][i] - marks[0][i]) * n / (n - 1) if n > 1 \
                else total
        if r.get("core"):
            # the core as the FMU drives it, right after: same process, same minute
            got["core_s"], got["core_s_cpu"] = core_calls(r["core"])
        if best is None:
            best = got
        else:
            best = {k: min(v, got[k]) for k, v in best.items()}
    if r.get("signals"):
        best["signals"] = {k: [float(x) for x in res[k]] for k in ["time"] + r["signals"]}
    return best

def core_calls(c):
    # `gearpair.bench._record_calls` of the FMU's bundled package, which the FMU instances
    # imported as `_gearpair_fmu`: the loop an FMU master drives, without the FMU
    # (the default engine runs in the FMU's binary and imports no package: the installed
    # gearpair then, the same sources)
    name = "_gearpair_fmu" if "_gearpair_fmu" in sys.modules else "gearpair"
    gp = importlib.import_module(name)
    bench = importlib.import_module(name + ".bench")
    took = bench._record_calls(gp.make_engine(None, bench.regime_effects(c["regime"]), "fast",
                                              rtol=c["rtol"]), c["t_end"], c["step"])
    return took.wall, took.cpu

def init(start, step):
    fmu = instance()
    drv.initialize(fmu, start)
    return fmu

def calls(c):
    try:
        return calls1(c)
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}

def calls1(c):
    reals = [var[n].valueReference for n in c["outputs"] if var[n].type == "Real"]
    ints = [var[n].valueReference for n in c["outputs"] if var[n].type == "Integer"]
    vin = [var["torque"].valueReference, var["speed"].valueReference]
    u = [float(c["start"]["torque"]), float(c["start"]["speed"])]
    h, n, best = c["step"], c["n"], None
    for _ in range(c["repeats"]):
        fmu = init(c["start"], h)
        fmu.setReal(vin, u)
        fmu.doStep(0.0, h)
        t0, c0 = time.perf_counter(), time.process_time()
        for i in range(1, n + 1):
            fmu.setReal(vin, u)
            fmu.doStep(i * h, h)
            fmu.getReal(reals)
            if ints:
                fmu.getInteger(ints)
        per = [(time.perf_counter() - t0) / n, (time.process_time() - c0) / n]
        fmu.terminate()
        fmu.freeInstance()
        best = per if best is None else [min(a, b) for a, b in zip(best, per)]
    return best

def startup(c):
    t0 = time.perf_counter()
    fmu = instance()
    t1 = time.perf_counter()
    drv.initialize(fmu, c["start"])
    t2 = time.perf_counter()
    fmu.doStep(0.0, c["step"])
    t3 = time.perf_counter()
    return {"instantiate_s": t1 - t0, "initialize_s": t2 - t1, "first_step_s": t3 - t2,
            "total_s": t3 - t0}

if job.get("warmup"):
    simulate(job["warmup"])
if job.get("startup"):
    out["startup"] = startup(job["startup"])
out["runs"] = {key: simulate(r) for key, r in job.get("runs", {}).items()}
if job.get("calls"):
    out["call_s"] = calls(job["calls"])
if job.get("loops"):
    out["loops"] = {key: calls(c) for key, c in job["loops"].items()}
with open(sys.argv[2], "w") as fh:
    json.dump(out, fh)
sys.stdout.flush()
sys.stderr.flush()
os._exit(0)  # skip interpreter teardown after pythonfmu slaves were loaded (docs/hosts.md)
"""


def _worker(job: dict, env: dict | None = None, timeout: float = 3600.0) -> dict:
    """Run `_FMU_WORKER` on ``job`` in a child process and return its answers."""
    with tempfile.TemporaryDirectory(prefix="gearpair_bench_") as tmp:
        jf, of = Path(tmp) / "job.json", Path(tmp) / "out.json"
        jf.write_text(json.dumps(job))
        child_env = dict(os.environ if env is None else env)
        # the child must import the FMU's bundled gearpair, never the working tree's
        child_env.pop("PYTHONPATH", None)
        proc = subprocess.run([sys.executable, "-c", _FMU_WORKER, str(jf), str(of)],
                              capture_output=True, text=True, env=child_env, cwd=tmp,
                              timeout=timeout)
        if proc.returncode != 0 or not of.is_file():
            tail = (proc.stderr or proc.stdout)[-2000:]
            raise RuntimeError(f"FMU benchmark child failed (exit {proc.returncode}): {tail}")
        return json.loads(of.read_text())


def build_noop(gearpair_fmu: str | Path, outdir: str | Path) -> Path:
    """Build ``<outdir>/GearPairNoop.fmu``: the slave that does nothing
    (``gearpair/bench/GearPairNoop.py``) with the variables of ``gearpair_fmu`` (its
    ``interface.json``: every variable of that modelDescription, in value-reference order,
    so that both have the same value references), built with pythonfmu for its
    modelDescription (with GearPair's GUID); its binary is the generic FMI layer of
    ``gearpair_fmu``'s builder over a model that does nothing (`_noop_binary`: the builder
    its build record names, and a C compiler). The floor is then the cost of the same layer
    with no engine behind it.

    Raises RuntimeError when ``gearpair_fmu`` has no build record naming its builder or its
    value references are not 0, 1, 2, ... in the order of its modelDescription (the no-op
    could not match them)."""
    import shutil

    import fmpy
    from pythonfmu.builder import FmuBuilder

    outdir = Path(outdir)
    md = fmpy.read_model_description(str(gearpair_fmu))
    if [v.valueReference for v in md.modelVariables] != list(range(len(md.modelVariables))):
        raise RuntimeError(f"{gearpair_fmu}: value references not 0, 1, 2, ... in order; the "
                           "no-op slave cannot take its variables")
    iface = [{"name": v.name, "type": v.type, "causality": v.causality,
              "variability": v.variability, "description": v.description,
              "start": None if v.start is None else
              {"Real": float, "Integer": int}.get(v.type, lambda x: x in (True, "true"))(
                  v.start)}
             for v in md.modelVariables]
    src = outdir / "noop_src"
    src.mkdir(parents=True, exist_ok=True)
    shutil.copy(NOOP_SCRIPT, src / NOOP_SCRIPT.name)
    (src / "interface.json").write_text(json.dumps(iface, indent=1))
    noop = Path(FmuBuilder.build_FMU(src / NOOP_SCRIPT.name, dest=outdir / "GearPairNoop.fmu",
                                     project_files=[src / "interface.json"]))
    _run_on_the_binary_of(noop, gearpair_fmu, md)
    return noop


def _run_on_the_binary_of(noop: Path, gearpair_fmu: str | Path, md) -> None:
    """Make ``noop``'s Linux binary the generic FMI layer over a model doing nothing
    (`_noop_binary`), with ``gearpair_fmu``'s GUID; binaries for other platforms are left
    out."""
    import fmpy

    nmd = fmpy.read_model_description(str(noop))
    mine = {v.name: (v.valueReference, v.type) for v in nmd.modelVariables}
    theirs = {v.name: (v.valueReference, v.type) for v in md.modelVariables}
    if mine != theirs:
        raise RuntimeError("the no-op slave's variables differ from GearPair's")
    noop_model = nmd.coSimulation.modelIdentifier
    with zipfile.ZipFile(noop) as z:
        entries = {n: z.read(n) for n in z.namelist() if not n.startswith("binaries/")}
    xml = entries["modelDescription.xml"].decode("utf-8")
    xml, n = re.subn(r'guid="[^"]*"', f'guid="{md.guid}"', xml, count=1)
    if n != 1:
        raise RuntimeError("the no-op slave's modelDescription.xml has no guid")
    entries["modelDescription.xml"] = xml.encode("utf-8")
    entries[f"binaries/linux64/{noop_model}.so"] = _noop_binary(gearpair_fmu, xml)
    tmp = noop.with_suffix(".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in entries.items():
            z.writestr(name, data)
    tmp.replace(noop)


def _noop_binary(gearpair_fmu: str | Path, xml: str) -> bytes:
    """The generic FMI layer over a model that does nothing, compiled by the builder that
    built ``gearpair_fmu`` (its build record names it) for the variables of ``xml``."""
    import importlib.util
    import tempfile

    from ..scenes import location

    record = location.read_record(gearpair_fmu) or {}
    builder = Path(record.get("builder", ""))
    if not builder.is_file():
        raise RuntimeError(f"{gearpair_fmu} has no build record naming its builder "
                           "(build_fmu.py): the no-op floor needs its C layer's sources")
    spec = importlib.util.spec_from_file_location("_gearpair_bench_builder", builder)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    with tempfile.TemporaryDirectory(prefix="gearpair_noop_") as tmp:
        return mod.noop_binary(xml.encode("utf-8"), Path(tmp))


def fmu_start(fmu: str | Path, regime: str, rtol: float, effects=None) -> dict:
    """Start values setting an FMU with GearPair's variables up as a regime (or ``effects``)
    at the default point (3900 N.m, 100 r/min)."""
    import fmpy

    from ..params import OperatingPoint
    from ..scenes import Scene, Solver, fmu_start_values

    md = fmpy.read_model_description(str(fmu))
    variables = {v.name: v for v in md.modelVariables}
    fx = regime_effects(regime) if effects is None else effects
    start = fmu_start_values(Scene(name="bench", effects=fx, solver=Solver(rtol=rtol)),
                             variables)
    op = OperatingPoint()
    start.update(torque=op.torque, speed=op.speed)
    return start


def _output_names(fmu: str | Path) -> list[str]:
    import fmpy

    md = fmpy.read_model_description(str(fmu))
    return [v.name for v in md.modelVariables if v.causality == "output"]


def fmu_measurements(s: Settings, refs: dict, fmu: Path, noop: Path,
                     progress: Progress = _quiet) -> dict:
    """FMU work-precision rows, costs at a 1e-3 s step against the core (timed in the FMU's
    process) and the floor, and the cost of one set+doStep+get call (GearPair and no-op, in
    separate child processes).
    """
    from ..effects import Effects

    outputs = _output_names(fmu)
    first = fmu_start(fmu, "stick_slip", s.fmu_rtols[-1])
    trivial = Effects(stiffness="constant", friction="off")
    call = dict(start=fmu_start(fmu, "no_friction", s.fmu_rtols[-1], trivial), step=1e-3,
                n=s.calls, outputs=outputs, repeats=s.repeats)
    warm = dict(start=first, t_end=0.002, step=1e-3, outputs=["dte"], repeats=1)
    progress("FMU: GearPair through fmpy (child process)")
    got = _worker({"fmu": str(fmu), "warmup": warm, "runs": _fmu_runs(s, fmu, outputs),
                   "calls": call})
    progress("FMU: no-op slave through fmpy (child process)")
    nstart = fmu_start(noop, "stick_slip", s.fmu_rtols[-1])
    nrun = dict(start=nstart, t_end=s.step_horizon, step=1e-3, outputs=outputs,
                repeats=s.repeats)
    ncall = dict(call, start=fmu_start(noop, "no_friction", s.fmu_rtols[-1], trivial))
    ngot = _worker({"fmu": str(noop), "warmup": dict(nrun, t_end=0.002, repeats=1),
                    "runs": {"floor": nrun}, "calls": ncall})
    rows = _fmu_wp_rows(s, refs, got)
    floor = ngot["runs"]["floor"]
    if "error" in floor:
        raise RuntimeError(f"the no-op FMU failed: {floor['error']}")
    return {"rows": rows, "steps": _fmu_step_rows(s, got, floor),
            "calls": _call_costs(s, got, ngot)}


def _fmu_runs(s: Settings, fmu: Path, outputs: list[str]) -> dict:
    """The `simulate_fmu` jobs of GearPair: work-precision (``wp|regime|rtol|step``) and the
    1e-3 s step cost with the core timed after each repeat (``step|regime|rtol``)."""
    runs = {}
    for regime in REGIMES:
        for rtol in s.fmu_rtols:
            start = fmu_start(fmu, regime, rtol)
            for h in s.fmu_steps:
                runs[f"wp|{regime}|{rtol!r}|{h!r}"] = dict(
                    start=start, t_end=s.horizon, step=h, outputs=["dte", "mesh_force"],
                    signals=["dte", "mesh_force"], repeats=1)
            core = dict(regime=regime, rtol=rtol, t_end=s.step_horizon, step=1e-3)
            runs[f"step|{regime}|{rtol!r}"] = dict(start=start, t_end=s.step_horizon,
                                                   step=1e-3, outputs=outputs,
                                                   repeats=s.repeats, core=core)
    return runs


def _fmu_wp_rows(s: Settings, refs: dict, got: dict) -> list[dict]:
    """Work-precision rows of the FMU (method ``FMU``) from the child's answers."""
    rows = []
    for regime in REGIMES:
        for rtol in s.fmu_rtols:
            for h in s.fmu_steps:
                r = got["runs"][f"wp|{regime}|{rtol!r}|{h!r}"]
                setting = f"step {h:g}, rtol {rtol:g}"
                if "error" in r:
                    rows.append(_row(regime, "FMU", setting, rtol, h, s.horizon, _FAILED,
                                     _NO_ERRORS, r["error"]))
                    continue
                sig = {k: np.asarray(v) for k, v in r["signals"].items()}
                rows.append(_row(regime, "FMU", setting, rtol, h, s.horizon,
                                 Timing(r["loop_s"], r["loop_s_cpu"]),
                                 _errors(sig, refs[regime], s.window(regime))))
                rows[-1]["total_per_sim_s"] = r["total_s"] / s.horizon
    return rows


def _fmu_step_rows(s: Settings, got: dict, floor: dict) -> list[dict]:
    """FMU at a 1e-3 s step against the core and the no-op floor, and the allowance
    ``TARGET_FMU_FACTOR x core + floor``, per regime and rtol (wall and CPU)."""
    steps = []
    horizon = s.step_horizon
    for regime in REGIMES:
        for rtol in s.fmu_rtols:
            r = got["runs"][f"step|{regime}|{rtol!r}"]
            row = {"regime": regime, "rtol": rtol, "step": 1e-3, "horizon_s": horizon,
                   "error": r.get("error")}
            steps.append(row)
            if row["error"]:
                continue
            # the core as the FMU drives it (one advance + outputs call per step), timed in
            # the FMU's process after each FMU run: a slow phase of a shared machine cannot
            # fall on one side of the ratio only
            for key in ("", "_cpu"):
                c = r["core_s" + key] / horizon
                fmu_x, floor_x = r["loop_s" + key] / horizon, floor["loop_s" + key] / horizon
                allowed = TARGET_FMU_FACTOR * c + floor_x
                row.update({
                    "core_per_sim_s" + key: c, "fmu_per_sim_s" + key: fmu_x,
                    "fmu_total_per_sim_s" + key: r["total_s" + key] / horizon,
                    "floor_per_sim_s" + key: floor_x,
                    "floor_total_per_sim_s" + key: floor["total_s" + key] / horizon,
                    "fmu_over_core" + key: fmu_x / c,
                    "fmu_minus_floor_over_core" + key: (fmu_x - floor_x) / c,
                    "allowed_per_sim_s" + key: allowed, "met" + key: fmu_x <= allowed})
    return steps


def _call_costs(s: Settings, got: dict, ngot: dict) -> dict:
    """One set+doStep+get call through fmpy on GearPair and on the no-op slave, and the
    engine's own advance+outputs in this process (s per call, wall and CPU)."""
    calls = {"n": s.calls, "step": 1e-3, "regime": "6-DOF, constant stiffness, no friction",
             "error": None}
    for key, ans in (("gearpair", got["call_s"]), ("noop", ngot["call_s"])):
        if isinstance(ans, dict):
            calls["error"], ans = ans["error"], [None, None]
        calls[key + "_s"], calls[key + "_cpu_s"] = ans
    try:
        took = engine_call_cost(s.calls, repeats=s.repeats)
        calls["engine_s"], calls["engine_cpu_s"] = took.wall, took.cpu
    except (RuntimeError, ArithmeticError) as exc:
        calls["engine_s"] = calls["engine_cpu_s"] = None
        calls["error"] = f"{type(exc).__name__}: {exc}"
    return calls


def fmu_startup(fmu: Path, progress: Progress = _quiet, compile_row: bool = False) -> dict:
    """Instantiate + initialize + first 1e-3 s step in a fresh process with empty caches
    (``NUMBA_CACHE_DIR`` and ``XDG_CACHE_HOME`` new folders: the FMU loads the compiled code
    it ships, if it fits this machine) and again with the caches it left (``empty`` and
    ``cached``); with ``compile_row`` also with empty caches and ``GEARPAIR_SHIPPED_CODE=0``
    (``compile``: the kernels compile, as on a machine the shipped code does not fit)."""
    start = fmu_start(fmu, "stick_slip", 1e-8)
    job = {"fmu": str(fmu), "startup": {"start": start, "step": 1e-3}}
    out = {"compile": None}
    with tempfile.TemporaryDirectory(prefix="gearpair_bench_numba_") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(cache) / "numba"),
                   XDG_CACHE_HOME=str(Path(cache) / "xdg"))
        progress("FMU start-up with empty caches (loads the shipped code)")
        out["empty"] = _worker(job, env)["startup"]
        progress("FMU start-up with the caches just filled")
        out["cached"] = _worker(job, env)["startup"]
    if compile_row:
        with tempfile.TemporaryDirectory(prefix="gearpair_bench_numba_") as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(cache) / "numba"),
                       XDG_CACHE_HOME=str(Path(cache) / "xdg"), GEARPAIR_SHIPPED_CODE="0")
            progress("FMU start-up with empty caches and GEARPAIR_SHIPPED_CODE=0 (compiles)")
            out["compile"] = _worker(job, env)["startup"]
    warm = out["cached"]["total_s"]
    out["ratio"] = out["empty"]["total_s"] / warm if warm > 0 else None
    return out

