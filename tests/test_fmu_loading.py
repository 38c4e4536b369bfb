"""How the FMU finds its resources and, for the reference engine (engine = 1, the only one that
runs in Python), its Python: resource-location forms, the default engine without any Python,
the interpreter recorded at build time, the GEARPAIR_PYTHON override, missing packages, and
calls that arrive after the host's interpreter has finalized.

The non-Python hosts here run with an empty environment (`env -i`), as a master started
from a launcher would: the FMU must find everything from what it carries.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")

from test_hosts import compile_c_host  # noqa: E402

pytestmark = pytest.mark.fmu

ROOT = Path(__file__).resolve().parents[1]

_URI_HOST = """
import sys
sys.path.insert(0, {tests!r})
import fmpy
from fmpy.fmi2 import fmi2Warning
from fmu_slave import LoggingSlave
md = fmpy.read_model_description({fmu!r})
g = LoggingSlave(md, {unzip!r}, resource_location={uri!r})
g.fmu.setupExperiment(startTime=0.0)
g.fmu.enterInitializationMode(); g.fmu.exitInitializationMode()
g.fmu.doStep(0.0, 1e-4)
force = g.fmu.getReal([g.vr["mesh_force"]])[0]
g.fmu.terminate(); g.fmu.freeInstance()
bad = [m for st, m in g.messages if st >= fmi2Warning]
print("WARN" if bad else "OK", force > 0, bad)
"""


@pytest.mark.parametrize("form", ["file:///{p}", "file:////{p}", "file:/{p}",
                                  "file://localhost/{p}", "file:///{q}"])
def test_every_resource_location_form_reads_the_same_folder(fmu_path, tmp_path, form):
    """file:///abs, file:////abs (OMSimulator), file:/abs, file://localhost/abs and a
    percent-encoded path all name the extracted resources folder: the instance runs its own
    bundled package and logs no warning (the foreign-package warning is for another copy)."""
    unzip = tmp_path / "x y"  # a space: percent-encoded in the URI form {q}
    fmpy.extract(str(fmu_path), unzipdir=str(unzip))
    res = str(unzip / "resources").lstrip("/")
    uri = form.format(p=res, q=res.replace(" ", "%20"))
    code = _URI_HOST.format(tests=str(ROOT / "tests"), fmu=str(fmu_path), unzip=str(unzip),
                            uri=uri)
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.startswith("OK True"), (uri, r.stdout, r.stderr[-2000:])


def test_a_remote_resource_location_is_refused_with_a_message(md, fmu_path, tmp_path):
    """A URI naming another host cannot be read: fmi2Instantiate returns NULL after one
    error message that names the location."""
    sys.path.insert(0, str(ROOT / "tests"))
    from fmu_slave import LoggingSlave

    unzip = fmpy.extract(str(fmu_path), unzipdir=str(tmp_path / "u"))
    with pytest.raises(RuntimeError) as exc:
        LoggingSlave(md, unzip, resource_location="file://elsewhere/tmp/resources")
    assert "file://elsewhere/tmp/resources is not a local file URI" in str(exc.value)


def textblock(s: str) -> str:
    return textwrap.dedent(s).strip() + "\n"


def clean_env(**extra: str) -> dict[str, str]:
    """The environment of a master started with `env -i PATH=/usr/bin:/bin HOME=$HOME`."""
    env = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}
    env.update(extra)
    return env


# -- a C master with an empty environment --------------------------------------------------
@pytest.fixture(scope="module")
def c_run(fmu_path, tmp_path_factory):
    """run(env, unzip=None, reference=True) -> CompletedProcess: the C host example, 3 steps,
    loggingOn, on an extraction of the FMU (a fresh one per module unless given), with the
    reference engine (engine = 1: Python) unless ``reference`` is false."""
    base = tmp_path_factory.mktemp("c_loading")
    exe = compile_c_host(ROOT / "examples" / "hosts" / "fmi2_host.c", base / "fmi2_host")
    unzip = Path(fmpy.extract(str(fmu_path), unzipdir=str(base / "unzip")))
    md = fmpy.read_model_description(str(fmu_path))
    vr = {v.name: v.valueReference for v in md.modelVariables}

    def run(env, where: Path | None = None, reference: bool = True):
        engine = ["-i", f"{vr['engine']}=1"] if reference else []
        return subprocess.run([str(exe), str(where or unzip), "GearPair", md.guid, "1e-4", "3",
                               "-o", str(vr["mesh_force"]), "-l", "1", *engine],
                              env=env, capture_output=True, text=True, timeout=300)
    run.unzip = unzip
    return run


def _venv(where: Path, packages_from: Path | None) -> Path:
    """A venv of the Python running the tests, without pip; its packages are those of the
    folder ``packages_from`` (through a .pth file), or none."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(where)], check=True)
    site = next((where / "lib").glob("python3*/site-packages"))
    if packages_from is not None:
        (site / "_linked.pth").write_text(str(packages_from) + "\n")
    return where / "bin" / "python"


def _site_packages() -> Path:
    import sysconfig

    return Path(sysconfig.get_paths()["purelib"])


def _packages_without(package: str, where: Path) -> Path:
    """A folder with (links to) every package of this environment but ``package``."""
    where.mkdir()
    for p in _site_packages().iterdir():
        if not p.name.lower().startswith(package) and p.suffix != ".pth":
            (where / p.name).symlink_to(p)
    return where


def _one_error(proc) -> list[str]:
    """The FMU's messages of status error (3) in the C host's stderr."""
    return [ln for ln in proc.stderr.splitlines() if ln.startswith("[host|3|")]


def _shared_python_or_skip():
    import sysconfig

    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        pytest.skip("the Python running the tests has no shared libpython: the FMU built "
                    "with it cannot run in a C host")


def test_c_master_runs_the_fast_engine_without_python(c_run):
    """`env -i PATH=/usr/bin:/bin HOME=$HOME fmi2_host ...` with the default engine: the
    compiled engine in the FMU's binary runs, no Python is looked for; exit status 0, no
    warning or error."""
    proc = c_run(clean_env(), reference=False)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert len(proc.stdout.split()) == 4
    assert "Python" not in proc.stderr, proc.stderr
    assert "[host|1|" not in proc.stderr and "[host|3|" not in proc.stderr, proc.stderr


def test_c_master_runs_the_reference_engine_in_the_python_that_built_it(c_run):
    """The same with engine = 1: the FMU loads the Python that built it, finds its packages
    and runs the scipy reference engine; exit status 0."""
    _shared_python_or_skip()
    proc = c_run(clean_env())
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert len(proc.stdout.split()) == 4
    log = proc.stderr
    assert "the Python that built this FMU" in log and sys.executable in log, log
    assert "runs the reference engine (engine = 1)" in log, log
    assert "[host|1|" not in log and "[host|3|" not in log, log  # no warning, no error


def test_gearpair_python_names_another_environment(c_run, tmp_path):
    """GEARPAIR_PYTHON=<another venv>/bin/python: that interpreter and its packages run."""
    _shared_python_or_skip()
    other = _venv(tmp_path / "other venv", _site_packages())
    proc = c_run(clean_env(GEARPAIR_PYTHON=str(other)))
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert f"GEARPAIR_PYTHON={other}" in proc.stderr and f"at {other} " in proc.stderr


def test_an_environment_without_numpy_gives_one_clear_error(c_run, tmp_path):
    """A copy of the environment without numpy: fmi2ExitInitializationMode of the reference
    engine fails with one message of status error that names numpy, where it looked and the
    fix; the host exits 1 (its own status for a failed call), no crash, no traceback."""
    _shared_python_or_skip()
    pkgs = _packages_without("numpy", tmp_path / "pkgs")
    python = _venv(tmp_path / "venv", pkgs)
    proc = c_run(clean_env(GEARPAIR_PYTHON=str(python)))
    assert proc.returncode == 1, proc.stderr[-3000:]
    errors = _one_error(proc)
    assert len(errors) == 1, proc.stderr
    msg = errors[0]
    for words in ("cannot import numpy", str(python), str(pkgs), "-m pip install",
                  "GEARPAIR_PYTHON"):
        assert words in msg, (words, msg)
    assert "Traceback" not in proc.stderr and "exit_init(c) returned status 3" in proc.stderr


@pytest.mark.parametrize("bad", ["missing", "not python"])
def test_a_wrong_gearpair_python_gives_one_clear_error(c_run, tmp_path, bad):
    python = tmp_path / "python"
    if bad == "not python":
        python.write_text("#!/bin/sh\necho hello\n")
        python.chmod(0o755)
    proc = c_run(clean_env(GEARPAIR_PYTHON=str(python)))
    assert proc.returncode == 1, proc.stderr[-3000:]
    errors = _one_error(proc)
    assert len(errors) == 1 and f"GEARPAIR_PYTHON={python}" in errors[0], proc.stderr


def test_a_recorded_python_that_is_gone_gives_one_clear_error(c_run, tmp_path):
    """The FMU moved to a machine without the Python that built it: one message naming the
    library it looked for and the override."""
    where = tmp_path / "moved"
    shutil.copytree(c_run.unzip, where)
    rec = where / "resources" / "python.txt"
    rec.write_text(rec.read_text().replace("libpython=", "libpython=/nowhere"))
    proc = c_run(clean_env(), where)
    assert proc.returncode == 1, proc.stderr[-3000:]
    errors = _one_error(proc)
    assert len(errors) == 1, proc.stderr
    assert "/nowhere" in errors[0] and "GEARPAIR_PYTHON" in errors[0], errors


# -- calls after the host's interpreter has finalized -----------------------------------------
_LATE_C = r"""
#include <stdio.h>
#include <stdlib.h>
typedef int (*call_t)(void *);
typedef void (*free_t)(void *);
typedef int (*step_t)(void *, double, double, int);
static void *comp;
static call_t term;
static free_t fr;
static step_t step;
static double t_next;
/* a C master's logger (OMSimulator's is C++) */
void c_logger(void *env, const char *inst, int st, const char *cat, const char *msg, ...) {
    (void)env;
    fprintf(stderr, "[late-log %s|%d|%s] %s\n", inst, st, cat ? cat : "(null)", msg);
}
/* as OMSimulator's static destructor: after Python has finalized */
static void late(void) {
    int s = step(comp, t_next, 1e-4, 1);
    int t = term(comp);
    fr(comp);
    fprintf(stderr, "late: doStep %d terminate %d freed\n", s, t);
}
void arm(void *c, void *tm, void *f, void *st, double t) {
    comp = c, term = (call_t)tm, fr = (free_t)f, step = (step_t)st, t_next = t;
    atexit(late);
}
"""

_LATE_HOST = r"""
import ctypes, sys
import fmpy
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE,
                       fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, calloc, free)
fmu, helper, native = sys.argv[1], ctypes.CDLL(sys.argv[2]), sys.argv[3] == "native"
md = fmpy.read_model_description(fmu)
s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(fmu), modelIdentifier="GearPair",
              instanceName="late")
cb = None
if native:
    cb = fmi2CallbackFunctions()
    cb.logger = ctypes.cast(helper.c_logger, fmi2CallbackLoggerTYPE)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
s.instantiate(callbacks=cb)
vr = {v.name: v.valueReference for v in md.modelVariables}
s.setupExperiment(startTime=0.0); s.enterInitializationMode()
s.setInteger([vr["engine"]], [1])  # the reference engine: the one that runs in Python
s.exitInitializationMode()
s.doStep(0.0, 1e-4)
addr = lambda f: ctypes.cast(f, ctypes.c_void_p)
helper.arm.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_double]
helper.arm(s.component, addr(s.dll.fmi2Terminate), addr(s.dll.fmi2FreeInstance),
           addr(s.dll.fmi2DoStep), 1e-4)
print("alive", flush=True)  # the script ends with the instance alive
"""


@pytest.mark.parametrize("logger", ["native", "ctypes"])
def test_calls_after_the_python_host_finalized_are_answered_by_the_c_layer(fmu_path, tmp_path,
                                                                           logger):
    """OMSimulator's Python API path: a Python host ends with an instance of the reference
    engine (Python) alive, and its
    exit handler (after the interpreter finalized) calls fmi2DoStep, fmi2Terminate and
    fmi2FreeInstance. The C layer answers without entering Python: fmi2Error for the step
    (one message, with a category, through a C logger; fmpy's logger, which calls into
    Python, is not called: the message goes to stderr), fmi2OK for fmi2Terminate; the
    process exits with status 0."""
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        pytest.skip("no C compiler")
    (tmp_path / "late.c").write_text(_LATE_C)
    helper = tmp_path / "late.so"
    subprocess.run([gcc, "-shared", "-fPIC", "-o", str(helper), str(tmp_path / "late.c")],
                   check=True)
    r = subprocess.run([sys.executable, "-c", _LATE_HOST, str(fmu_path), str(helper), logger],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split() == ["alive"]
    assert "late: doStep 3 terminate 0 freed" in r.stderr, r.stderr[-3000:]
    said = [ln for ln in r.stderr.splitlines() if ln.startswith("[late-log")]
    if logger == "native":
        assert len(said) == 1 and "[late-log late|3|logStatusError] fmi2DoStep: the host's " \
            "Python interpreter has finalized" in said[0], r.stderr[-3000:]
    else:
        assert not said
        assert "GearPair FMU instance late: fmi2DoStep: the host's Python interpreter has " \
            "finalized" in r.stderr, r.stderr[-3000:]


_PY_HOST_NO_SCIPY = """
import fmpy
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
fmu = {fmu!r}
md = fmpy.read_model_description(fmu)
said = []
cb = fmi2CallbackFunctions()
cb.logger = fmi2CallbackLoggerTYPE(
    lambda env, inst, status, cat, msg: said.append((status, cat, msg.decode())))
s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(fmu), modelIdentifier="GearPair")
s.instantiate(callbacks=cb, loggingOn=False)
s.setupExperiment(startTime=0.0); s.enterInitializationMode()
s.setInteger([md.modelVariables[[v.name for v in md.modelVariables].index("engine")]
              .valueReference], [1])
try:
    s.exitInitializationMode()
except Exception:
    print("refused")
for status, cat, msg in said:
    print(status, cat.decode(), msg)
"""


def test_a_python_host_without_scipy_gets_one_clear_error(fmu_path, tmp_path):
    """A Python host keeps its own interpreter; when it lacks a package the reference engine
    needs (here scipy), its fmi2ExitInitializationMode fails after one error message (with a
    category, also with loggingOn false) naming it, the interpreter and the fix; no
    traceback."""
    python = _venv(tmp_path / "venv", _packages_without("scipy", tmp_path / "pkgs"))
    r = subprocess.run([str(python), "-c", _PY_HOST_NO_SCIPY.format(fmu=str(fmu_path))],
                       cwd=tmp_path, env=clean_env(), capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    lines = r.stdout.splitlines()
    assert lines[0] == "refused" and len(lines) == 2, r.stdout
    assert lines[1].startswith("3 logStatusError engine = 1 (reference) needs Python: the "
                               "FMU cannot import scipy"), lines[1]
    assert "the host's own Python" in lines[1] and "-m pip install" in lines[1]
    assert "Traceback" not in r.stderr, r.stderr[-3000:]
