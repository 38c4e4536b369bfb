"""GearPair.fmu's Windows binary (#34): ``binaries/win64/GearPair.dll``, which build_fmu.py
cross-compiles with mingw-w64 from the same C layer and the engine's object emitted for
Windows from the same numba module, run here under Wine.

- The DLL needs only Windows' own DLLs (``objdump -p``) and exports the fmi2 functions the
  Linux binary exports.
- C hosts cross-compiled for Windows run it under Wine, and the same hosts built for Linux
  run the linux64 binary: ``tests/hosts/fmi2_scenes.c`` runs every scene (the default
  stick-slip, each friction law, a changed geometry, each stiffness model, backlash, the
  torsional model), FMU states (get, set, serialize, deserialize into a fresh instance),
  two instances in turn and in two threads, refused values, in one process per platform
  (Wine starts slowly); ``examples/hosts/fmi2_host.c`` and the fuzzer ``tests/fuzz`` run as
  they do on Linux. Each prints the outputs with all their bits and the FMU's log messages:
  the text of the two platforms is the same, so the outputs are bit for bit the linux64
  binary's (which equal the Python API's: test_fmu_no_python.py, test_fmu_step_path.py).
- The reference engine (engine = 1), which needs Python, ends in a clear error at
  fmi2ExitInitializationMode in the win64 binary, and the process exits cleanly.
- Without mingw-w64 the build writes binaries/linux64 only and says so.

Skips, with the reason: no mingw-w64 (then the FMU has no win64 binary), no Wine, no
objdump of mingw-w64. ``scripts/setup.sh`` installs them from Debian's packages
(gcc-mingw-w64-x86-64, wine64). Wine's prefix is kept in the user cache (made once: about
12 s and 0.7 GB; GEARPAIR_WINEPREFIX names another), and its wineserver ends by itself
3 s after the last program.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import struct
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")

from test_hosts import compile_c_host  # noqa: E402

from gearpair.bench import wine as bench_wine  # noqa: E402

pytestmark = pytest.mark.fmu

ROOT = Path(__file__).resolve().parents[1]
HOSTS = ROOT / "examples" / "hosts"
SCENES_C = ROOT / "tests" / "hosts" / "fmi2_scenes.c"
FUZZ_C = ROOT / "tests" / "fuzz" / "fmi2_fuzz.c"
MINGW = bench_wine.MINGW
INSTALL = "apt-get install gcc-mingw-w64-x86-64 wine64 (scripts/setup.sh does)"

N, H = 200, 1e-4
# scene -> start values by name (`run` in fmi2_scenes.c)
SCENES = {
    "stick_slip": {},
    "friction_off": {"friction_law": 0},
    "friction_nominal": {"friction_law": 1},
    "friction_regularized": {"friction_law": 2, "v_eps": 0.05},
    "geometry": {"module": 0.004, "z1": 25, "z2": 61},
    "stiffness_constant": {"stiffness_model": 1},
    "stiffness_rectangular_exact": {"stiffness_model": 2, "friction_law": 0},
    "backlash": {"backlash": 5e-5, "friction_law": 2},
    "torsional": {"dof": 1, "sliding": 1},
    "torque_reversal": {"torque": -1500.0, "mu": 0.08},
}
# refusal -> (values set first, values refused; `refuse` in fmi2_scenes.c) and the statuses
# it prints: the set in initialization mode, fmi2ExitInitializationMode, then (when that
# passed) the set in step mode
REFUSALS = {
    "out_of_range": ({}, {"mu": -1.0}, (3, 3)),
    "not_finite": ({}, {"torque": float("nan")}, (3, 3)),
    "combination": ({}, {"dof": 1, "sliding": 0}, (0, 3)),
    "fixed_after_init": ({}, {"rtol": 1e-6}, (0, 0, 3)),
}
REFERENCE = "reference_engine"  # engine = 1: win64 only (on Linux it runs, in Python)
# resource locations of the extracted FMU's folder ({} as Z:/...), each tried in win64
LOCATIONS = ("file:/{}/resources", "file://localhost/{}/resources", "{}\\resources",
             "file:///{}/re%73ources")


# -- the FMU and the tools ---------------------------------------------------------------------
@pytest.fixture(scope="module")
def unzipped(fmu_path, tmp_path_factory) -> Path:
    """The FMU extracted; skips when it has no win64 binary."""
    with zipfile.ZipFile(fmu_path) as z:
        if "binaries/win64/GearPair.dll" not in z.namelist():
            pytest.skip(f"the FMU has no binaries/win64: build_fmu.py found no mingw-w64 "
                        f"({MINGW}); {INSTALL}")
    return Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp_path_factory.mktemp("unzip"))))


def _mingw() -> str:
    cc = shutil.which(MINGW)
    if cc is None:
        pytest.skip(f"no {MINGW}; {INSTALL}")
    return cc


def compile_win64_host(source: Path, exe: Path) -> Path:
    """A C host for Windows x86-64 (mingw-w64), against fmpy's FMI 2 headers and
    examples/hosts/fmu_dl.h; C99 printf, as glibc's."""
    include = Path(fmpy.__file__).parent / "c-code"
    subprocess.run([_mingw(), "-O2", "-std=c99", "-Wall", "-Wextra", "-Werror",
                    "-D__USE_MINGW_ANSI_STDIO=1", f"-I{include}", f"-I{HOSTS}", "-o", str(exe),
                    str(source)], check=True)
    return exe


@pytest.fixture(scope="module")
def wine():
    """A function running a Windows program under Wine: ``run(exe, *args, input=None)``
    returns the CompletedProcess with the stdout's CR LF as LF (`gearpair.bench.wine`: the
    prefix the bench shares, booted once)."""
    exe = shutil.which("wine") or shutil.which("wine64")
    if exe is None:
        pytest.skip(f"no Wine; {INSTALL}")
    bench_wine.boot(exe)

    def run(program: Path, *args: str, input: str | None = None, timeout: float = 300):
        return bench_wine.run(exe, program, list(args), timeout=timeout, input=input)

    return run


winpath = bench_wine.winpath


def _vr_types(md) -> tuple[dict, dict]:
    return ({v.name: v.valueReference for v in md.modelVariables},
            {v.name: v.type for v in md.modelVariables})


# -- the DLL itself ----------------------------------------------------------------------------
def _objdump_p(dll: Path) -> str:
    objdump = shutil.which("x86_64-w64-mingw32-objdump")
    if objdump is None:
        pytest.skip(f"no x86_64-w64-mingw32-objdump; {INSTALL}")
    return subprocess.run([objdump, "-p", str(dll)], capture_output=True, text=True,
                          check=True).stdout


def _builder():
    spec = importlib.util.spec_from_file_location("build_fmu_win64", ROOT / "build_fmu.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_dll_needs_only_windows_own_dlls(unzipped):
    dll = unzipped / "binaries" / "win64" / "GearPair.dll"
    text = _objdump_p(dll)
    dlls = re.findall(r"DLL Name: (\S+)", text)
    assert sorted(d.lower() for d in dlls) == ["kernel32.dll", "msvcrt.dll"], dlls
    assert _builder().pe_imports(dll.read_bytes()) == dlls  # the build's own check agrees
    assert "pei-x86-64" in subprocess.run(["x86_64-w64-mingw32-objdump", "-f", str(dll)],
                                         capture_output=True, text=True).stdout


def test_the_dll_exports_the_fmi2_functions_of_the_linux_binary(unzipped):
    text = _objdump_p(unzipped / "binaries" / "win64" / "GearPair.dll")
    table = text[text.index("[Ordinal/Name Pointer] Table"):]
    exported = set(re.findall(r"^\s+\[\s*\d+\]\s+(\w+)$", table, re.M))
    so = unzipped / "binaries" / "linux64" / "GearPair.so"
    nm = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True,
                        text=True, check=True).stdout
    linux = {w.split()[-1] for w in nm.splitlines() if w.split()[-1].startswith("fmi2")}
    assert exported == linux and len(exported) >= 30, exported ^ linux


# -- many scenes in one process a platform -----------------------------------------------------
def _values(values: dict, vr: dict, types: dict) -> str:
    return " ".join(f"{types[n][0]}{vr[n]}={float(x)!r}" for n, x in values.items())


def _script(md, reference: bool = False, folder: str | None = None) -> str:
    vr, types = _vr_types(md)
    reals = [v.valueReference for v in md.modelVariables
             if v.causality == "output" and v.type == "Real"]
    ints = [v.valueReference for v in md.modelVariables
            if v.causality == "output" and v.type == "Integer"]
    lines = [f"outputs {','.join(map(str, reals))} {','.join(map(str, ints))}"]
    lines += [f"run {name} {N} {H!r} {_values(v, vr, types)}" for name, v in SCENES.items()]
    lines += [f"states states {N} {H!r}",
              f"states states_backlash {N} {H!r} {_values(SCENES['backlash'], vr, types)}",
              f"pair pair {N // 2} {H!r} / {_values({'torque': 2500.0}, vr, types)}"]
    lines += [f"refuse {name} {_values(pre, vr, types)} / {_values(bad, vr, types)}"
              for name, (pre, bad, _) in REFUSALS.items()]
    if reference:  # then a new instance with the default engine, in the same process
        lines += [f"refuse {REFERENCE} / {_values({'engine': 1}, vr, types)}",
                  f"run after_reference 3 {H!r}"]
    if folder is not None:  # other forms of the resource location that Windows masters use
        for k, form in enumerate(LOCATIONS):
            lines += [f"location {form.format(folder)}", f"run location{k} 1 {H!r}"]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def scenes(unzipped, md, wine, tmp_path_factory) -> dict:
    """fmi2_scenes.c run once on each platform: {"linux", "win64"}: CompletedProcess."""
    where = tmp_path_factory.mktemp("scenes")
    native = compile_c_host(SCENES_C, where / "fmi2_scenes")
    windows = compile_win64_host(SCENES_C, where / "fmi2_scenes.exe")
    lin = subprocess.run([str(native), str(unzipped), "GearPair", md.guid],
                         input=_script(md), capture_output=True, text=True,
                         env={"PATH": "/usr/bin:/bin"}, timeout=300)
    win = wine(windows, winpath(unzipped), "GearPair", md.guid,
               input=_script(md, reference=True, folder=winpath(unzipped)))
    return {"linux": lin, "win64": win}


def test_the_processes_exit_cleanly(scenes):
    for platform, proc in scenes.items():
        assert proc.returncode == 0 and proc.stderr == "", (platform, proc.stdout[-3000:],
                                                            proc.stderr[-3000:])


def test_win64_prints_the_same_bits_and_messages_as_linux64(scenes):
    lin, win = scenes["linux"].stdout, scenes["win64"].stdout
    assert lin and win.startswith(lin), _first_difference(lin, win)


def _first_difference(a: str, b: str) -> str:
    for k, (x, y) in enumerate(zip(a.splitlines(), b.splitlines(), strict=False)):
        if x != y:
            return f"line {k}:\n  linux64: {x}\n  win64:   {y}"
    return "one is a prefix of the other"


@pytest.mark.parametrize("scene", SCENES)
def test_each_scene_runs_and_moves(scenes, scene):
    rows = [line.split()[2:] for line in scenes["win64"].stdout.splitlines()
            if line.startswith(f"{scene} ")]
    assert len(rows) == N + 1
    values = [[struct.unpack(">d", bytes.fromhex(w))[0] for w in row] for row in rows]
    assert values[-1][0] == pytest.approx(N * H)
    assert len({row[1] for row in values}) > N // 4  # the DTE changes


def test_fmu_states_replay_bit_for_bit(scenes):
    out = scenes["win64"].stdout
    for name in ("states", "states_backlash"):
        assert f"{name} replay after fmi2SetFMUstate identical" in out
        assert f"{name} replay in a fresh instance after fmi2DeSerializeFMUstate identical" in out
        assert f"{name} altered state: status 3" in out
        assert re.search(rf"^{name} state \d+ bytes, hash [0-9a-f]{{16}}$", out, re.M)


def test_two_instances_and_two_threads(scenes):
    out = scenes["win64"].stdout
    assert "pair runs differ: yes" in out
    assert "pair two instances in turn: identical" in out
    assert "pair two threads at once: identical" in out


@pytest.mark.parametrize("name", REFUSALS)
def test_refused_values(scenes, name):
    out = scenes["win64"].stdout
    statuses = tuple(int(m) for m in re.findall(
        rf"^{name} (?:set in initialization mode|fmi2ExitInitializationMode|set in step "
        rf"mode): status (\d)$", out, re.M))
    assert statuses == REFUSALS[name][2], out[-3000:]
    errors = [ln for ln in out.splitlines() if ln.startswith(f"log {name} 3 ")]
    assert errors and all("keeps" in e or "refused" in e for e in errors), errors
    if len(statuses) == 3:
        assert f"{name} outputs after the refusal: unchanged" in out


def test_the_reference_engine_says_what_to_do_instead(scenes):
    out = scenes["win64"].stdout
    assert f"{REFERENCE} fmi2ExitInitializationMode: status 3" in out
    said = [ln for ln in out.splitlines() if ln.startswith(f"log {REFERENCE} 3 ")]
    assert len(said) == 1, out[-3000:]
    for words in ("engine = 1 (reference) needs Python", "win64 binary of this FMU does not "
                  "load", "Use engine = 0", "linux64"):
        assert words in said[0], said[0]
    # the same process goes on: a new instance with the default engine runs
    assert len([ln for ln in out.splitlines() if ln.startswith("after_reference ")]) == 4


def test_resource_locations_as_windows_masters_write_them(scenes):
    out = scenes["win64"].stdout
    for k, form in enumerate(LOCATIONS):
        assert len([ln for ln in out.splitlines() if ln.startswith(f"location{k} ")]) == 2, \
            (form, out[-2000:])


# -- the example host and the fuzzer -----------------------------------------------------------
def test_the_example_host_gives_the_linux_bits(unzipped, md, wine, tmp_path):
    native = compile_c_host(HOSTS / "fmi2_host.c", tmp_path / "fmi2_host")
    windows = compile_win64_host(HOSTS / "fmi2_host.c", tmp_path / "fmi2_host.exe")
    vr, _ = _vr_types(md)
    outs = ("dte", "mesh_force", "friction_force", "stick_fraction", "mesh_force_max")
    args = ["GearPair", md.guid, "1e-4,3e-4,1e-3", "60", "-r", f"{vr['torque']}=3000",
            "-o", ",".join(str(vr[o]) for o in outs), "-n", str(vr["contact_state"]),
            "-d", "1"]  # -d 1: FreeLibrary after fmi2FreeInstance
    lin = subprocess.run([str(native), str(unzipped), *args], capture_output=True, text=True,
                         env={"PATH": "/usr/bin:/bin"}, timeout=120)
    win = wine(windows, winpath(unzipped), *args)
    assert lin.returncode == 0 and win.returncode == 0, win.stderr[-2000:]
    assert win.stderr == "" and len(win.stdout.split()) == 61
    assert win.stdout == lin.stdout, _first_difference(lin.stdout, win.stdout)


def test_fuzz_under_wine_as_on_linux(unzipped, md, wine, tmp_path):
    from test_fmu_fuzz import N_OPS, SEEDS, fuzz_spec

    native = compile_c_host(FUZZ_C, tmp_path / "fmi2_fuzz")
    windows = compile_win64_host(FUZZ_C, tmp_path / "fmi2_fuzz.exe")
    spec = tmp_path / "spec.txt"
    spec.write_text(fuzz_spec(md))
    for seed in SEEDS:
        lin = subprocess.run([str(native), str(unzipped), "GearPair", md.guid, str(spec),
                              str(seed), str(N_OPS)], capture_output=True, text=True,
                             env={"PATH": "/usr/bin:/bin"}, timeout=120)
        win = wine(windows, winpath(unzipped), "GearPair", md.guid, winpath(spec), str(seed),
                   str(N_OPS))
        assert win.returncode == 0, (seed, win.stderr[-3000:])
        summary = win.stdout.split("\n")[0]
        assert summary.startswith(f"ops {N_OPS};") and "fatal 0" in summary, win.stdout
        assert "error 0" not in summary  # the refusals were exercised
        assert win.stdout == lin.stdout, (seed, win.stdout, lin.stdout)


# -- the build where mingw-w64 is missing ------------------------------------------------------
def _without_build_details(xml: bytes) -> str:
    text = xml.decode("utf-8")
    return re.sub(r'(guid|generationDateAndTime)="[^"]*"', r'\1=""', text)


def test_without_mingw_the_build_writes_linux64_and_says_so(fmu_path, tmp_path):
    env = dict(os.environ, GEARPAIR_WIN64_CC="x86_64-w64-mingw32-gcc-not-here")
    proc = subprocess.run([sys.executable, str(ROOT / "build_fmu.py"), "--out", str(tmp_path)],
                          env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "no win64 binary: no mingw-w64 cross compiler" in proc.stderr
    assert "GearPair.fmu holds binaries/linux64 only" in proc.stderr
    with zipfile.ZipFile(tmp_path / "GearPair.fmu") as z:
        binaries = sorted(n for n in z.namelist() if n.startswith("binaries/"))
        xml = z.read("modelDescription.xml")
    assert binaries == ["binaries/linux64/GearPair.so", "binaries/linux64/GearPair_pythonfmu.so"]
    with zipfile.ZipFile(fmu_path) as z:
        assert "binaries/win64/GearPair.dll" in z.namelist() or shutil.which(MINGW) is None
        # the modelDescription does not depend on the platforms (FMI 2.0 lists none)
        assert _without_build_details(z.read("modelDescription.xml")) == \
            _without_build_details(xml)


def test_the_engine_object_for_windows_needs_only_the_c_library(fmu_path, tmp_path):
    """The build's engine object for Windows (a COFF object, from the user cache the build
    filled): the four entry points, and from outside only fmod and memset, and LLVM's stack
    probe for frames over 4 KB (___chkstk_ms), which mingw-w64's libgcc links in."""
    from gearpair import aot

    if _builder().win64_compiler() is None:
        pytest.skip(f"no {MINGW}; {INSTALL}")
    made = aot.write_engine(tmp_path, win64=True)
    obj = Path(made["object_win64"])
    assert obj.read_bytes()[:2] == b"\x64\x86"  # COFF, x86-64
    needs = set(aot.undefined_symbols(obj))
    assert set(aot.LIBC) <= needs <= set(aot.LIBC + aot.WIN64_LIBGCC), needs
    nm = subprocess.run(["x86_64-w64-mingw32-nm", "--defined-only", "-g", str(obj)],
                        capture_output=True, text=True)
    if nm.returncode == 0:
        assert sorted(w.split()[-1] for w in nm.stdout.splitlines()) == \
            sorted(c for c, _, _ in aot.ENTRIES)
