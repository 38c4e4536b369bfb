"""GearPair3.fmu's step against GearPair.fmu's, what early return adds, and GearPair.fmu's
step in a win64 process under Wine (issue 35 item 4, issue 34 item 6).

A timing host of the package's own, ``fmi3_bench_host.c`` beside this module (compiled here
with gcc, and with mingw-w64 for Windows, against the FMI 2 and FMI 3 headers that fmpy
ships), runs the C host section's loop (set torque and speed, doStep, get dte, mesh_force,
input_torque, output_torque: `chost.INPUTS`, `chost.OUTPUTS`) at its point: the default
values of the FMUs, the paper's stick-slip scene (``examples/scenes/paper_stick_slip.toml``:
3900 N.m, 100 r/min, mu 0.02, rtol 1e-8), on 1e-4 s communication steps.

- `fmi3_measurements`: one process loads both FMUs' Linux binaries and steps four instances
  round by round over the same stretch of model time, back to back (``fmi2``: GearPair.fmu;
  ``fmi3``: GearPair3.fmu without early return; ``fmi3_events``: with early return and a
  master that handles each one in Event Mode; ``fmi3_early``: early return without Event
  Mode). The ratio GearPair3.fmu / GearPair.fmu per step counts as the median of the
  per-round ratios, as the C host's thread ratios do; the early-return variants report
  their fmi3DoStep calls, early returns and Event Mode entries per simulated second and
  their cost per simulated second against the run without early return.
- `wine_measurements`: the same host, built for Windows, steps GearPair.fmu's win64 DLL
  under Wine, and built for Linux its linux64 binary, in processes that alternate; per
  step the best and the median block of each. Information, not a target: Wine is not
  Windows.

Both are skipped with a note where a tool is missing (gcc, fmpy's headers, GearPair3.fmu of
the same build; Wine, mingw-w64, a win64 binary).
"""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path
from statistics import median

from . import wine as _wine
from .chost import INPUTS, OUTPUTS, REGIME, extract, parse
from .fmu import fmu_start
from .settings import FMI3_HOST_SOURCE, Progress, Settings, _quiet

VARIANTS = ("fmi2", "fmi3", "fmi3_events", "fmi3_early")
FMU3_NAME = "GearPair3.fmu"  # build_fmu.py writes it beside GearPair.fmu
# start-value flags of the host by the FMI 3 type of the variable
_FLAG3 = {"Float64": "-r", "Int32": "-i", "Enumeration": "-e", "Boolean": "-b"}
_ERRORS = (RuntimeError, OSError, ValueError, KeyError, subprocess.SubprocessError)


def fmu3_beside(fmu: str | Path) -> tuple[Path | None, str | None]:
    """GearPair3.fmu of the same build as ``fmu`` (beside it; its instantiation token is
    GearPair.fmu's GUID): (path, None), or (None, why not)."""
    import fmpy

    fmu3 = Path(fmu).with_name(FMU3_NAME)
    if not fmu3.is_file():
        return None, f"no {fmu3} beside {Path(fmu).name} (python build_fmu.py writes both)"
    token = fmpy.read_model_description(str(fmu3)).guid
    guid = fmpy.read_model_description(str(fmu)).guid
    if token != guid:
        return None, (f"{fmu3} is of another build than {fmu} (instantiation token {token}, "
                      f"GUID {guid}): rebuild both with python build_fmu.py")
    return fmu3, None


def compile_host(cc: str, exe: Path, win64: bool = False) -> Path:
    """``fmi3_bench_host.c`` compiled with ``cc`` (gcc; or mingw-w64 with ``win64``: C99
    printf, as glibc's) into ``exe``.

    Raises
    ------
    RuntimeError
        The compiler failed (its message).
    """
    import fmpy

    headers = Path(fmpy.__file__).parent / "c-code"
    args = [cc, "-O2", "-std=c99", f"-I{headers}", "-o", str(exe), str(FMI3_HOST_SOURCE)]
    args += ["-D__USE_MINGW_ANSI_STDIO=1"] if win64 else ["-ldl"]
    proc = subprocess.run(args, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{Path(cc).name} failed: {proc.stderr.strip()[-500:]}")
    return exe


def extract3(fmu3: str | Path, dest: Path) -> dict:
    """Unzip GearPair3.fmu; its folder, instantiation token and value references (and FMI 3
    types) by name."""
    import fmpy

    with zipfile.ZipFile(fmu3) as z:
        z.extractall(dest)
    md = fmpy.read_model_description(str(fmu3))
    return {"dir": str(dest), "guid": md.guid,
            "vars": {v.name: (v.valueReference, v.type) for v in md.modelVariables}}


def host_args(variants: tuple[str, ...], step: float, n: int, rounds: int, start: dict,
              unit2: dict | None, unit3: dict | None, path=str) -> list[str]:
    """The host's arguments: variants, grid, the loop's value references and inputs, the
    extracted FMUs (their folders as ``path`` names them: `wine.winpath` under Wine) and the
    start values other than the inputs, typed by GearPair3.fmu's declaration where it is
    given (GearPair.fmu's otherwise; both FMUs have the same value references).

    Raises
    ------
    ValueError
        The two FMUs give a variable different value references.
    """
    vr2 = unit2["vars"] if unit2 else {}
    vr3 = unit3["vars"] if unit3 else {}
    vr = vr3 or vr2
    for name in vr2.keys() & vr3.keys():
        if vr2[name][0] != vr3[name][0]:
            raise ValueError(f"{name}: value reference {vr2[name][0]} in GearPair.fmu, "
                             f"{vr3[name][0]} in GearPair3.fmu")
    args = [",".join(variants), repr(step), str(n), str(rounds),
            ",".join(str(vr[k][0]) for k in INPUTS),
            ",".join(repr(float(start[k])) for k in INPUTS),
            ",".join(str(vr[k][0]) for k in OUTPUTS)]
    if unit2:
        args += ["-2", path(unit2["dir"]), unit2["guid"]]
    if unit3:
        args += ["-3", path(unit3["dir"]), unit3["guid"]]
    flag2 = {"Real": "-r", "Integer": "-i", "Enumeration": "-e", "Boolean": "-b"}
    for name, value in start.items():
        if name in INPUTS:
            continue
        ref, typ = vr[name]
        flag = _FLAG3.get(typ) if vr3 else flag2.get(typ)
        if flag is None:
            continue
        value = int(bool(value)) if flag == "-b" else value
        args += [flag, f"{ref}={value!r}"]
    return args


def _ratios(a: list[float], b: list[float]) -> list[float]:
    """Round by round, a over b."""
    return [x / y for x, y in zip(a, b, strict=True)]


def summarize(got: dict) -> dict:
    """Per variant its cost and counts, and the ratios that count, from the host's result.

    Per variant: ``wall_us`` / ``cpu_us`` per communication point, round by round;
    ``wall_mean_us`` (over all rounds), ``wall_best_us`` (and ``cpu_``); ``per_sim_s`` /
    ``per_sim_s_cpu`` (s of the loop per simulated s, over all rounds); ``calls_per_s``,
    ``early_per_s``, ``events_per_s`` (per simulated s); ``digest``. The means, not the
    medians, of the rounds: a shared virtual machine's speed drifts from round to round
    (7 to 15 us per point within a minute under load 3), the variants of a round alike,
    so a variant's median round is whichever side of a jump it falls on, while its mean
    has every round. Ratios (medians of the per-round ratios, which compare times taken
    tens of milliseconds apart; and of the best rounds): ``fmi3_over_fmi2`` (and ``_cpu``,
    ``_best``); per early-return variant ``<v>_over_fmi3`` (and ``_cpu``) and
    ``<v>_extra_us`` (and ``_cpu``), the extra cost per early return (us: that median ratio
    minus 1 times fmi3's mean cost per simulated s, per early return; noise makes it
    negative where the extra cost is below what the clocks resolve);
    ``identical``: the outputs at every communication point have the same bits in fmi2 and
    fmi3 (``identical_early``: in the early-return variants too)."""
    n, h, rounds = got["n"], got["h"], got["rounds"]
    sim = n * h * rounds
    out: dict = {"simulated_s": sim, "variants": {}}
    for name, v in got["variants"].items():
        wall = [1e6 * x / n for x in v["wall_s"]]
        cpu = [1e6 * x / n for x in v["cpu_s"]]
        out["variants"][name] = {
            "wall_us": wall, "cpu_us": cpu, "wall_mean_us": sum(wall) / rounds,
            "wall_best_us": min(wall), "cpu_mean_us": sum(cpu) / rounds, "cpu_best_us": min(cpu),
            "per_sim_s": sum(v["wall_s"]) / sim, "per_sim_s_cpu": sum(v["cpu_s"]) / sim,
            "calls_per_s": v["calls"] / sim, "early_per_s": v["early"] / sim,
            "events_per_s": v["events"] / sim, "digest": v["digest"]}
    var = got["variants"]
    if "fmi2" in var and "fmi3" in var:
        a, b = var["fmi3"], var["fmi2"]
        out["fmi3_over_fmi2"] = median(_ratios(a["wall_s"], b["wall_s"]))
        out["fmi3_over_fmi2_cpu"] = median(_ratios(a["cpu_s"], b["cpu_s"]))
        out["fmi3_over_fmi2_best"] = min(a["wall_s"]) / min(b["wall_s"])
        out["identical"] = a["digest"] == b["digest"]
        out["identical_early"] = all(v["digest"] == b["digest"] for v in var.values())
    for name in ("fmi3_events", "fmi3_early"):
        if name in var and "fmi3" in var:
            e, base = var[name], var["fmi3"]
            ratio = median(_ratios(e["wall_s"], base["wall_s"]))
            out[f"{name}_over_fmi3"] = ratio
            out[f"{name}_over_fmi3_cpu"] = cpu = median(_ratios(e["cpu_s"], base["cpu_s"]))
            early = out["variants"][name]["early_per_s"]
            for key, r in (("", ratio), ("_cpu", cpu)):
                per_s = out["variants"]["fmi3"]["per_sim_s" + key]
                out[f"{name}_extra_us{key}"] = 1e6 * (r - 1.0) * per_s / early if early \
                    else None
    return out


def fmi3_measurements(s: Settings, fmu: Path, workdir: str | Path,
                      progress: Progress = _quiet) -> dict:
    """GearPair3.fmu against GearPair.fmu in the C host at its first step of
    ``s.host_steps`` (1e-4 s), ``s.host_rounds`` rounds of ``s.host_n`` communication
    points (`summarize`), or a note saying why not."""
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    rtol, step = s.fmu_rtols[-1], s.host_steps[0]
    out: dict = {"note": None, "error": None, "regime": REGIME, "rtol": rtol, "step": step,
                 "n": s.host_n, "rounds": s.host_rounds, "inputs": list(INPUTS),
                 "outputs": list(OUTPUTS)}
    gcc = shutil.which("gcc")
    if gcc is None:
        out["note"] = "GearPair3.fmu rows skipped: gcc not found"
        return out
    fmu3, why = fmu3_beside(fmu)
    if fmu3 is None:
        out["note"] = f"GearPair3.fmu rows skipped: {why}"
        return out
    out["fmu3_file"] = str(fmu3)
    try:
        exe = compile_host(gcc, workdir / "fmi3_bench_host")
        unit2, unit3 = extract(fmu, workdir / "u2"), extract3(fmu3, workdir / "u3")
        start = fmu_start(fmu, REGIME, rtol)
        progress(f"C host: GearPair3.fmu against GearPair.fmu, with and without early return "
                 f"({s.host_rounds} rounds of {s.host_n} steps of {step:g} s)")
        args = host_args(VARIANTS, step, s.host_n, s.host_rounds, start, unit2, unit3)
        proc = subprocess.run([str(exe), *args], capture_output=True, text=True,
                              env={"PATH": "/usr/bin:/bin"}, timeout=1800)
        got = parse(proc.stdout, proc.stderr, proc.returncode)
        out.update(summarize(got), exit_status=got["exit_status"])
    except _ERRORS as exc:
        out["error"] = f"{type(exc).__name__}: {exc}"
    return out


def wine_measurements(s: Settings, fmu: Path, workdir: str | Path,
                      progress: Progress = _quiet) -> dict:
    """GearPair.fmu per step in the host built for Windows, on the win64 DLL under Wine, and
    built for Linux, on the linux64 binary: ``s.wine_runs`` processes of each, alternating,
    each ``s.host_rounds`` blocks of ``s.host_n`` steps of 1e-4 s; or a note saying why
    not.

    ``linux_us`` / ``win64_us``: wall time per step of every block; ``*_best_us``,
    ``*_median_us``; ``*_cpu_us``: the CPU time of all blocks per step (Wine's thread clock
    ticks in 10 ms, so only the sum means anything); ``win64_over_linux``: median over
    median; ``identical``: the same output bits on both platforms."""
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    rtol, step = s.fmu_rtols[-1], s.host_steps[0]
    out: dict = {"note": None, "error": None, "regime": REGIME, "rtol": rtol, "step": step,
                 "n": s.host_n, "rounds": s.host_rounds, "runs": s.wine_runs}
    if not s.wine:
        out["note"] = (f"win64 under Wine: not measured with the {s.name} settings (the "
                       "default run measures it)")
        return out
    have, why = _wine.tools()
    gcc = shutil.which("gcc")
    if have is None or gcc is None:
        out["note"] = f"win64 under Wine skipped: {why or 'gcc not found'}"
        return out
    with zipfile.ZipFile(fmu) as z:
        if "binaries/win64/GearPair.dll" not in z.namelist():
            out["note"] = (f"win64 under Wine skipped: {Path(fmu).name} has no win64 binary "
                           "(build_fmu.py found no mingw-w64)")
            return out
    try:
        native = compile_host(gcc, workdir / "fmi3_bench_host")
        windows = compile_host(have["cc"], workdir / "fmi3_bench_host.exe", win64=True)
        unit = extract(fmu, workdir / "u2")
        start = fmu_start(fmu, REGIME, rtol)
        progress(f"Wine: its prefix {_wine.prefix()} (made once: about 12 s)")
        _wine.boot(have["wine"])
        blocks: dict = {"linux": [], "win64": []}
        cpu: dict = {"linux": 0.0, "win64": 0.0}
        digests = set()
        for r in range(s.wine_runs):
            progress(f"C host: GearPair.fmu on linux64 and on win64 under Wine, run {r + 1} "
                     f"of {s.wine_runs}")
            for platform in ("linux", "win64"):
                path = _wine.winpath if platform == "win64" else str
                args = host_args(("fmi2",), step, s.host_n, s.host_rounds, start, unit, None,
                                 path=path)
                if platform == "win64":
                    proc = _wine.run(have["wine"], windows, args)
                else:
                    proc = subprocess.run([str(native), *args], capture_output=True, text=True,
                                          env={"PATH": "/usr/bin:/bin"}, timeout=1800)
                got = parse(proc.stdout, proc.stderr, proc.returncode)["variants"]["fmi2"]
                blocks[platform] += [1e6 * x / s.host_n for x in got["wall_s"]]
                cpu[platform] += sum(got["cpu_s"])
                digests.add(got["digest"])
        steps = s.wine_runs * s.host_rounds * s.host_n
        for platform, times in blocks.items():
            out[f"{platform}_us"] = times
            out[f"{platform}_best_us"] = min(times)
            out[f"{platform}_median_us"] = median(times)
            out[f"{platform}_cpu_us"] = 1e6 * cpu[platform] / steps
        out["win64_over_linux"] = out["win64_median_us"] / out["linux_median_us"]
        out["identical"] = len(digests) == 1
    except _ERRORS as exc:
        out["error"] = f"{type(exc).__name__}: {exc}"
    return out
