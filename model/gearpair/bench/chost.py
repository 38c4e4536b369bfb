"""The FMU in a C master: per-step cost, whole processes, further instances, first start.

A small timing host of the package's own (``fmi2_bench_host.c`` beside this module, compiled
here with gcc against the FMI 2 headers that fmpy ships) runs the loop a co-simulation
master runs, ``fmi2SetReal`` of 2 inputs, ``fmi2DoStep``, ``fmi2GetReal`` of 4 outputs, on
GearPair and on the no-op FMU (the same generic FMI layer over a model that does nothing:
the layer's own cost per step) at 1e-4 s and 1e-3 s communication steps; fmpy runs the same
loop in a Python process, and the engine's own work at the same step (the same compiled
step, called from Python) is timed in this process over the same model-time windows. The
host also runs whole processes as a master does (instantiate, one step, free, exit: wall
time and peak memory, `host_process`), makes further instances in one process
(`host_instances`), and times the first start with empty caches and again with the caches
it filled (the FMU needs none: its engine is in its binary).

The host prints its result and flushes it before it frees the instance; the exit status is
reported beside the numbers. Without gcc or fmpy's headers the section is skipped with a
note.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path
from statistics import median

from .fmu import _worker, fmu_start
from .runs import NEVER, Timing, clock, regime_effects
from .settings import HOST_SOURCE, Progress, Settings, _quiet

INPUTS = ("torque", "speed")
OUTPUTS = ("dte", "mesh_force", "input_torque", "output_torque")
REGIME = "stick_slip"  # the default point of the FMU: 3900 N.m, 100 r/min, stick-slip
# where the C host steps: the instantiating thread, a worker thread, two instances in two
# threads at once, the same two one after the other (fmi2_bench_host.c)
THREAD_MODES = ("main", "worker", "pair", "serial")


def build_host(workdir: Path) -> tuple[dict | None, str | None]:
    """Compile the timing host; (host, None) or (None, why the section is skipped).

    ``host`` holds the executable and the environment variables it adds: none. The FMU's
    default engine is compiled into its binary and needs no Python, so the host runs as a
    user's would."""
    gcc = shutil.which("gcc")
    if gcc is None:
        return None, "C host rows skipped: gcc not found"
    try:
        import fmpy
    except ImportError:
        return None, "C host rows skipped: fmpy (for the FMI 2 headers) is not installed"
    headers = Path(fmpy.__file__).parent / "c-code"
    exe = Path(workdir) / "fmi2_bench_host"
    proc = subprocess.run([gcc, "-O2", "-std=c99", f"-I{headers}", "-o", str(exe),
                           str(HOST_SOURCE), "-ldl", "-lpthread"], capture_output=True,
                          text=True)
    if proc.returncode != 0:
        return None, f"C host rows skipped: gcc failed: {proc.stderr.strip()[-500:]}"
    return {"exe": str(exe), "env": {}}, None


def extract(fmu: str | Path, dest: Path) -> dict:
    """Unzip an FMU; its folder, model identifier, GUID and value references by name."""
    import fmpy

    with zipfile.ZipFile(fmu) as z:
        z.extractall(dest)
    md = fmpy.read_model_description(str(fmu))
    return {"dir": str(dest), "model": md.coSimulation.modelIdentifier, "guid": md.guid,
            "vars": {v.name: (v.valueReference, v.type) for v in md.modelVariables}}


def _host_args(host: dict, unit: dict, start: dict, step: float, n: int, blocks: int,
               threads: str, spin: int, native: tuple[int, int] | None = None) -> list[str]:
    vr = unit["vars"]
    args = [host["exe"], unit["dir"], unit["model"], unit["guid"], repr(step), str(n),
            str(blocks), ",".join(str(vr[k][0]) for k in INPUTS),
            ",".join(repr(float(start[k])) for k in INPUTS),
            ",".join(str(vr[k][0]) for k in OUTPUTS)]
    flag = {"Real": "-r", "Integer": "-i", "Boolean": "-b"}
    for name, value in start.items():
        ref, typ = vr[name]
        if name in INPUTS or typ not in flag:
            continue
        value = int(bool(value)) if typ == "Boolean" else value
        args += [flag[typ], f"{ref}={value!r}"]
    return args + ["-t", threads] + (["-c", str(spin)] if spin else []) + \
        (["-x", f"{native[0]},{native[1]}"] if native else [])


def run_host(host: dict, unit: dict, start: dict, step: float, n: int, blocks: int,
             env: dict | None = None, timeout: float = 600.0, threads: str = "main",
             spin: int = 0, native: tuple[int, int] | None = None) -> dict:
    """One host process: its RESULT line as a dict, with ``exit_status``; ``threads`` the
    host's thread mode (main, worker, pair, serial: `THREAD_MODES`; instances: set-up only,
    `host_instances`; interleaved, with ``spin`` multiply-adds of the machine ceiling's
    arithmetic per round: `host_threads`; or native, with ``native`` the host's ends of the
    pipes to the native step's process: `host_native`).

    Raises RuntimeError when the host printed no result (it failed before its loop)."""
    args = _host_args(host, unit, start, step, n, blocks, threads, spin, native)
    child = dict(os.environ if env is None else env, **host["env"])
    child.pop("PYTHONHOME", None)
    proc = subprocess.run(args, capture_output=True, text=True, env=child, timeout=timeout,
                          pass_fds=native or ())
    return parse(proc.stdout, proc.stderr, proc.returncode)


def parse(stdout: str, stderr: str, status: int) -> dict:
    """A timing host's RESULT line (`fmi2_bench_host.c`, `fmi3_bench_host.c`) as a dict,
    with ``exit_status``.

    Raises
    ------
    RuntimeError
        No RESULT line, or one that reports a failure.
    """
    lines = [ln for ln in stdout.splitlines() if ln.startswith("RESULT ")]
    if not lines:
        raise RuntimeError(f"the C host printed no result (exit {status}): "
                           f"{(stderr or stdout)[-1000:]}")
    out = json.loads(lines[-1][len("RESULT "):])
    if not out.get("ok"):
        raise RuntimeError(f"the C host: {out.get('error')}: {stderr[-1000:]}")
    out["exit_status"] = status
    return out


def engine_step_cost(rtol: float, step: float, n: int, repeats: int = 1,
                     blocks: int = 1) -> list[Timing]:
    """Time per step of the fast engine at the FMU's default point, stepped ``step`` at a
    time, through the calls the FMU's doStep makes: ``advance_values`` and
    ``output_values`` (plain numbers; ``advance`` + ``outputs`` would add the dataclasses
    the FMU never builds).

    The same model-time windows as the C host's: one first step, then ``blocks`` blocks of
    ``n`` steps one after the other; per block the best of ``repeats`` runs from the start
    (the cost of a step depends on where in the stick-slip cycle it falls)."""
    from .. import make_engine
    from ..params import OperatingPoint

    op = OperatingPoint()
    best = [NEVER] * max(1, blocks)
    for _ in range(max(1, repeats)):
        eng = make_engine(None, regime_effects(REGIME), "fast", rtol=rtol)
        advance, outputs = eng.advance_values, eng.output_values
        torque, speed = float(op.torque), float(op.speed)
        eng.reset(0.0, torque, speed)
        advance(step, torque, speed, None)
        outputs()
        for b in range(len(best)):
            t0 = clock()
            for i in range(b * n + 2, (b + 1) * n + 2):  # the host's grid, i * step
                advance(i * step, torque, speed, None)
                outputs()
            took = clock() - t0
            best[b] = best[b].best(Timing(took.wall / n, took.cpu / n))
    return best


def host_measurements(s: Settings, fmu: Path, noop: Path, workdir: str | Path,
                      progress: Progress = _quiet) -> dict:
    """Per-step cost in the C host and in fmpy (GearPair, no-op, engine) at each of
    ``s.host_steps``, and the C host's first start with empty and with warm caches."""
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    rtol = s.fmu_rtols[-1]
    out: dict = {"note": None, "regime": REGIME, "rtol": rtol, "inputs": list(INPUTS),
                 "outputs": list(OUTPUTS), "n": s.host_n, "blocks": s.host_blocks,
                 "steps": [], "startup": None}
    host, note = build_host(workdir)
    if host is None:
        out["note"] = note
        return out
    units = {k: extract(f, workdir / k) for k, f in (("gearpair", fmu), ("noop", noop))}
    starts = {k: fmu_start(f, REGIME, rtol) for k, f in (("gearpair", fmu), ("noop", noop))}
    fmpy_loops = _fmpy_loops(s, fmu, noop, starts, progress)
    for h in s.host_steps:
        row = {"step": h, "error": None, "exit_status": {}}
        try:
            blocks = {}
            for key in ("gearpair", "noop"):
                progress(f"C host: {key} at {h:g} s steps")
                got = run_host(host, units[key], starts[key], h, s.host_n, s.host_blocks)
                blocks[key] = got
                row[f"c_{key}_us"] = 1e6 * min(got["block_wall_s"]) / s.host_n
                row[f"c_{key}_cpu_us"] = 1e6 * min(got["block_cpu_s"]) / s.host_n
                row["exit_status"][key] = got["exit_status"]
                for clk, i in (("", 0), ("_cpu", 1)):
                    ans = fmpy_loops[key].get(repr(h))
                    row[f"fmpy_{key}{clk}_us"] = None if not isinstance(ans, list) \
                        else 1e6 * ans[i]
            took = engine_step_cost(rtol, h, s.host_n, s.repeats, s.host_blocks)
            # the engine in the model-time window of GearPair's best block (each clock's)
            for clk, key, i in (("", "block_wall_s", 0), ("_cpu", "block_cpu_s", 1)):
                times = blocks["gearpair"][key]
                b = times.index(min(times))
                row[f"engine{clk}_us"] = 1e6 * took[b][i]
                row[f"engine{clk}_block"] = b
            row["c_per_sim_s"] = row["c_gearpair_us"] * 1e-6 / h
        except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
            row["error"] = f"{type(exc).__name__}: {exc}"
        out["steps"].append(row)
    out["threads"] = host_threads(host, units["gearpair"], starts["gearpair"],
                                  s.host_steps[0], s.host_n, s.host_rounds, s.round_spin,
                                  progress)
    out["native"] = host_native(host, units["gearpair"], starts["gearpair"], rtol,
                                s.host_steps[0], s.host_n, s.host_rounds, workdir, progress)
    progress("C host: whole processes and further instances")
    out["process"] = host_process(host, units["gearpair"], starts["gearpair"])
    out["instances"] = host_instances(host, units["gearpair"], starts["gearpair"])
    if s.startup:
        out["startup"] = host_startup(host, units["gearpair"], starts["gearpair"], progress)
    return out


def host_threads(host: dict, unit: dict, start: dict, step: float, n: int, rounds: int,
                 spin: int, progress: Progress = _quiet) -> dict:
    """GearPair stepped from every thread mode of the C host, interleaved (the host's
    ``-t interleaved``): each round runs a block of ``n`` steps of each mode back to back,
    so that every ratio compares times measured a fraction of a second apart in the same
    stretch of model time. A machine whose speed drifts over seconds (a shared or
    throttled virtual machine) otherwise makes runs of one mode after another compare
    speeds, not modes. Per round:

    - ``main_us``: per step in the thread that instantiated the instance;
    - ``worker_us``: per step of another instance in a thread of its own, as a master's
      thread pool steps it (main and worker on one CPU, the one the main thread is on: the
      vCPUs of a virtual machine can differ in speed at the same moment);
    - ``serial_us`` / ``pair_us`` / ``procs_us``: per step and instance of two instances,
      one after the other in the main thread / at once in two threads / at once in two
      processes (the host and a forked copy of it, which share nothing), from the first
      start to the last end of the block;
    - ``floor_us``: the floor of a ``step``: an instance stepping the same model time at
      10 ``step`` (the engine's bulk cost; the C layer's own cost, well under 1 % of it
      there, included), per ``step`` of model time (``floor_median_us``: the median);
    - ``gain``: serial over pair, the pair's throughput gain;
    - ``ceilings``: serial over the two processes, what this machine gives two instances
      that share nothing: the ceiling of ``gain``. Its cores may deliver less than 2 for
      this work where they are hyperthreads of one or share a core with other guests,
      while a chain of dependent arithmetic, which leaves most of a core idle, still
      scales by 2 (``spin_ceilings``: ``spin`` multiply-adds twice one after the other
      over twice at once in two threads);

    and the medians of the per-round ratios: ``worker_over_main``, ``step_over_floor``
    (main over floor), ``pair_speedup`` (the pair's throughput over one after the other),
    ``ceiling``, ``spin_ceiling`` and ``pair_over_ceiling`` (gain over ceiling: the pair in
    threads over the two processes). ``identical``: every instance stepping at ``step``, in
    either process, gave the same outputs (the host's digest of every output of every
    step)."""
    out: dict = {"step": step, "n": n, "rounds": rounds, "error": None}
    try:
        progress(f"C host: GearPair at {step:g} s steps, every thread mode, {rounds} rounds")
        got = run_host(host, unit, start, step, n, rounds, threads="interleaved", spin=spin)
        r = got["rounds"]
        # per step (and instance: serial and pair blocks hold two instances' n steps)
        per = {f"{k}_us": [1e6 * v / (n * (2 if k in ("serial", "pair", "procs") else 1))
                           for v in r[f"{k}_s"]]
               for k in ("main", "worker", "serial", "pair", "procs", "floor")}
        gain = _ratios(r["serial_s"], r["pair_s"])
        ceiling = _ratios(r["serial_s"], r["procs_s"])
        spin = _ratios(r["spin_serial_s"], r["spin_pair_s"])
        # the floor's instance (the last) steps a grid of its own
        digests = [i["digest"] for i in got["instances"]][:-1] + [r["twin_digest"]]
        out.update(per, gain=gain, ceilings=ceiling, spin_ceilings=spin, digests=digests,
                   exit_status=got["exit_status"])
        out["worker_over_main"] = median(_ratios(r["worker_s"], r["main_s"]))
        out["step_over_floor"] = median(_ratios(r["main_s"], r["floor_s"]))
        out["floor_median_us"] = median(per["floor_us"])
        out["pair_speedup"] = median(gain)
        out["ceiling"] = median(ceiling)
        out["spin_ceiling"] = median(spin)
        out["pair_over_ceiling"] = median(_ratios(gain, ceiling))
        out["identical"] = len(set(digests)) == 1
    except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
        out["error"] = f"{type(exc).__name__}: {exc}"
    return out


def host_native(host: dict, unit: dict, start: dict, rtol: float, step: float, n: int,
                rounds: int, workdir: Path, progress: Progress = _quiet) -> dict:
    """GearPair.fmu's step against the native step it replaced, in the same rounds.

    The native step (`gearpair.bench.nativestep`): the engine's compiled step called from C
    at its C address, as the C layer of the pythonfmu-based FMU called it, with ``X_FMU`` = 1
    (the FMU's checks and rollback), in a child process whose engine is compiled for the CPU
    target of the FMU's object, from the same start (the point, ``rtol``, at rest at t = 0,
    a first ``step`` outside the timed blocks). The host (``-t native``) runs ``rounds``
    rounds: its instance's block of ``n`` steps and the child's block of the same model time,
    the first of the two alternating. Both processes are held to one CPU (they never run at
    once: each waits for the other), so that the ratio compares call paths, not the vCPUs of
    a virtual machine.

    Per round (us per step): ``fmu_us``, ``native_us`` (wall) and ``fmu_cpu_us``,
    ``native_cpu_us`` (the stepping thread's CPU); ``ratios`` (``ratios_cpu``): FMU over
    native; ``fmu_over_native`` (``_cpu``): their median. ``identical``: the two gave the
    same output bits at every step (the digests); ``cpu_name``: the CPU the child's engine
    was compiled for."""
    from ..params import OperatingPoint
    from . import nativestep

    out: dict = {"step": step, "n": n, "rounds": rounds, "error": None}
    op = OperatingPoint()
    job = {"regime": REGIME, "rtol": rtol, "torque": float(start.get("torque", op.torque)),
           "speed": float(start.get("speed", op.speed)), "step": step, "n": n,
           "outputs": list(OUTPUTS)}
    go, back = os.pipe(), os.pipe()  # (read, write) each: the host writes go, reads back
    child = None
    keep = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    try:
        progress(f"C host: GearPair against the native step at {step:g} s steps, {rounds} "
                 "rounds (the first run after an engine change compiles it, about 30 s)")
        lib = nativestep.build_loop(workdir)
        if keep:  # both children inherit one CPU (this thread's affinity at their fork)
            os.sched_setaffinity(0, {max(keep)})
        child, ready = nativestep.start(lib, job, (go[0], back[1]))
        out.update(cpu_name=ready["cpu_name"], cpu_features=ready["cpu_features"])
        os.close(go[0])
        os.close(back[1])
        go, back = (-1, go[1]), (back[0], -1)
        got = run_host(host, unit, start, step, n, rounds, threads="native",
                       native=(go[1], back[0]))
        nat = got["native"]
        per = {"fmu_us": got["block_wall_s"], "fmu_cpu_us": got["block_cpu_s"],
               "native_us": nat["wall_s"], "native_cpu_us": nat["cpu_s"]}
        out.update({k: [1e6 * v / n for v in times] for k, times in per.items()})
        out["ratios"] = _ratios(got["block_wall_s"], nat["wall_s"])
        out["ratios_cpu"] = _ratios(got["block_cpu_s"], nat["cpu_s"])
        out["fmu_over_native"] = median(out["ratios"])
        out["fmu_over_native_cpu"] = median(out["ratios_cpu"])
        out["digests"] = [got["instances"][0]["digest"], nat["digest"]]
        out["identical"] = len(set(out["digests"])) == 1
        out["exit_status"] = got["exit_status"]
    except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
        out["error"] = f"{type(exc).__name__}: {exc}"
    finally:
        if keep:
            os.sched_setaffinity(0, keep)
        for fd in (*go, *back):
            if fd >= 0:
                os.close(fd)
        if child is not None:
            try:
                child.communicate(timeout=60)
            except subprocess.TimeoutExpired:
                child.kill()
                child.communicate()
    return out


def _ratios(a: list[float], b: list[float]) -> list[float]:
    """Round by round, a over b."""
    return [x / y for x, y in zip(a, b, strict=True)]


def _fmpy_loops(s: Settings, fmu: Path, noop: Path, starts: dict,
                progress: Progress = _quiet) -> dict:
    """The same loop through fmpy (one child process per FMU): per step [wall, CPU] (s) by
    ``repr(step)``, or an error dict."""
    got = {}
    for key, f in (("gearpair", fmu), ("noop", noop)):
        progress(f"fmpy: {key}, the C host's loop")
        loops = {repr(h): dict(start=starts[key], step=h, n=s.host_n, outputs=list(OUTPUTS),
                               repeats=s.host_blocks) for h in s.host_steps}
        try:
            got[key] = _worker({"fmu": str(f), "loops": loops})["loops"]
        except RuntimeError as exc:
            got[key] = {repr(h): {"error": str(exc)} for h in s.host_steps}
    return got


def host_startup(host: dict, unit: dict, start: dict, progress: Progress = _quiet) -> dict:
    """First start in the C host (instantiate, initialize, first 1e-3 s step) with empty
    caches, then again with the caches that run filled."""
    out: dict = {"error": None}
    with tempfile.TemporaryDirectory(prefix="gearpair_bench_cache_") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(cache) / "numba"),
                   XDG_CACHE_HOME=str(Path(cache) / "xdg"))
        try:
            for key, what in (("empty", "empty caches"), ("warm", "the caches just filled")):
                progress(f"C host: first start with {what}")
                got = run_host(host, unit, start, 1e-3, 10, 1, env=env, timeout=1800.0)
                out[key] = {k: got[k] for k in ("instantiate_s", "initialize_s",
                                                "first_step_s", "exit_status")}
                out[key]["total_s"] = sum(got[k] for k in ("instantiate_s", "initialize_s",
                                                           "first_step_s"))
        except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
            out["error"] = f"{type(exc).__name__}: {exc}"
    return out


def host_process(host: dict, unit: dict, start: dict, repeats: int = 5) -> dict:
    """A whole process as a C master runs one, with an empty environment: load the FMU,
    instantiate, initialize, one 1e-4 s step, free, exit. Its wall time (start to exit) and
    peak resident memory (the host's VmHWM after its step: a child's ``ru_maxrss`` would
    count the Python process it was forked from), the best of ``repeats``."""
    args = _host_args(host, unit, start, 1e-4, 1, 1, "main", 0)
    best: dict = {"error": None, "wall_s": None, "peak_mb": None}
    try:
        for _ in range(repeats):
            t0 = clock()[0]
            proc = subprocess.Popen(args, env={"PATH": "/usr/bin:/bin"},
                                    stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
            text = proc.stdout.read().decode()  # one short line, then the exit
            proc.wait()
            wall = clock()[0] - t0
            proc.stdout.close()
            lines = [ln for ln in text.splitlines() if ln.startswith("RESULT ")]
            if proc.returncode != 0 or not lines:
                raise RuntimeError(f"the host failed (exit {proc.returncode}): {text[-300:]}")
            peak = json.loads(lines[-1][len("RESULT "):])["peak_rss_kb"] / 1024.0
            if best["wall_s"] is None or wall < best["wall_s"]:
                best["wall_s"] = wall
            if best["peak_mb"] is None or peak < best["peak_mb"]:
                best["peak_mb"] = peak
    except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
        best["error"] = f"{type(exc).__name__}: {exc}"
    return best


def host_instances(host: dict, unit: dict, start: dict, k: int = 20) -> dict:
    """``k`` instances made one after the other in one C-host process: per further instance
    (after the first, which also loads the library) the median time from fmi2Instantiate to
    the end of fmi2ExitInitializationMode and the resident memory it adds (the growth from
    the first to the last, over k - 1)."""
    try:
        got = run_host(host, unit, start, 1e-4, 1, k, threads="instances")
    except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}
    rss = got["rss_kb"]
    return {"error": None, "k": k, "first_s": got["setup_s"][0],
            "further_s": median(got["setup_s"][1:]),
            "further_mb": (rss[-1] - rss[0]) / (k - 1) / 1024.0}


def exit_note(status: int) -> str:
    """An exit status in words (a negative one is the signal that ended the host)."""
    if status >= 0:
        return str(status)
    try:
        import signal

        return f"{signal.Signals(-status).name} at exit"
    except ValueError:
        return f"signal {-status}"

