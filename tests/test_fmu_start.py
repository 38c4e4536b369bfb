"""The FMU's first start: the engine is compiled into the FMU's binary, so a first start in a
fresh process with empty user caches compiles nothing, starts no Python of its own and
imports none of the bundled package into a Python host; its outputs are bit-identical to the
Python API's. The manifest checks of `jitcache` (shipped compiled code for the Python
package) are tested in-process without compiling.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")
pytest.importorskip("numba")

pytestmark = pytest.mark.fmu

_CHILD = textwrap.dedent(r"""
    import json, os, sys
    import fmpy
    from fmpy.fmi2 import (FMU2Slave, calloc, fmi2CallbackAllocateMemoryTYPE,
                           fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                           fmi2CallbackLoggerTYPE, free)

    unzip, out = sys.argv[1:3]
    md = fmpy.read_model_description(os.path.join(unzip, "modelDescription.xml"))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    said = []

    def log(env, name, status, category, message):
        said.append([int(status), message.decode()])

    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(log)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="start")
    s.instantiate(callbacks=cb, loggingOn=True)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    names = ["dte", "mesh_force", "friction_force", "stick_fraction", "mesh_force_max"]
    rows = []
    for i in range(20):
        s.setReal([vr["torque"], vr["speed"]], [3900.0, 100 * 3.141592653589793 / 30])
        s.doStep(i * 1e-3, 1e-3)
        rows.append([x.hex() for x in s.getReal([vr[n] for n in names])])
    loaded = sorted(m for m in sys.modules
                    if m.partition(".")[0] in ("numba", "scipy", "gearpair", "_gearpair_fmu"))
    with open(out, "w") as fh:
        json.dump({"said": said, "loaded": loaded, "rows": rows}, fh)
    sys.stdout.flush()
    s.terminate()
    s.freeInstance()
""")


def _start(unzip: Path, tmp: Path) -> dict:
    """Run the child on an extracted FMU with empty user caches; return its report."""
    caches = tmp / "caches"
    env = dict(os.environ, XDG_CACHE_HOME=str(caches / "xdg"),
               NUMBA_CACHE_DIR=str(caches / "numba"))
    for name in ("PYTHONPATH", "GEARPAIR_SHIPPED_CODE", "GEARPAIR_COMPILE_NOTICE"):
        env.pop(name, None)
    out = tmp / "report.json"
    proc = subprocess.run([sys.executable, "-c", _CHILD, str(unzip), str(out)], env=env,
                          cwd=str(tmp), capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0 and out.is_file(), proc.stderr[-3000:]
    report = json.loads(out.read_text())
    report["cache_files"] = sorted(p.name for p in caches.rglob("*.nbc"))
    return report


@pytest.fixture(scope="module")
def first_start(fmu_path, tmp_path_factory) -> dict:
    tmp = tmp_path_factory.mktemp("start")
    return _start(Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp / "fmu"))), tmp)


def test_fmu_ships_no_python_engine_code(fmu_path):
    """The bundled package (for the reference engine) carries no compiled numba code: the
    fast engine is in the binary."""
    import zipfile

    with zipfile.ZipFile(fmu_path) as z:
        assert not [n for n in z.namelist() if "/_compiled/" in n]


def test_first_start_compiles_and_imports_nothing(first_start):
    assert first_start["cache_files"] == []  # nothing compiled into the user cache
    assert first_start["loaded"] == [], first_start["loaded"]  # no numba, no bundled package
    assert all(status == 0 for status, _ in first_start["said"]), first_start["said"]


def test_first_start_gives_the_python_api_bits(first_start):
    from gearpair import Effects, GearParams
    from gearpair import stepblock as sb
    from gearpair.fast import FastEngine

    eng = FastEngine(GearParams(), Effects(), rtol=1e-8)
    speed = 100 * 3.141592653589793 / 30
    eng.reset(0.0, 3900.0, speed)
    names = ["dte", "mesh_force", "friction_force", "stick_fraction", "mesh_force_max"]
    rows = []
    for i in range(20):  # the step record the compiled step leaves in the engine's block
        eng.advance(i * 1e-3 + 1e-3, 3900.0, speed)  # the FMU's t + h
        rows.append([eng.block[sb.X_REC + sb.STEP_RECORD.index(n)].hex() for n in names])
    assert first_start["rows"] == rows


# -- the manifest checks, in-process (no compile) -----------------------------------------
@pytest.fixture
def jitcache():
    from gearpair import jitcache

    return jitcache


def _manifest(jitcache, folder: Path, **change) -> Path:
    from llvmlite import binding as ll

    m = {"format": jitcache.FORMAT, "key": jitcache.KEY,
         "engine_module": jitcache.ENGINE_MODULE, "versions": jitcache._versions(),
         "triple": ll.get_process_triple(), "cpu_name": "generic", "requires": [],
         "magic": [ll.get_process_triple(), "generic", ""]}
    for k, v in change.items():
        if k in m["versions"]:
            m["versions"][k] = v
        else:
            m[k] = v
    folder.mkdir(parents=True, exist_ok=True)
    (folder / jitcache.MANIFEST).write_text(json.dumps(m))
    return folder


def test_manifest_accepted_when_all_matches(jitcache, tmp_path, monkeypatch):
    monkeypatch.delenv("GEARPAIR_SHIPPED_CODE", raising=False)
    magic, why = jitcache._check_shipped(str(_manifest(jitcache, tmp_path)))
    assert why == "" and magic[1:] == ("generic", "")


@pytest.mark.parametrize("change, expect", [
    ({"numpy": "0.0.1"}, "numpy 0.0.1"),
    ({"python": "cpython-2.7"}, "python cpython-2.7"),
    ({"numba": "0.1"}, "numba 0.1"),
    ({"requires": ["sse4.2", "no-such-feature"]}, "lacks no-such-feature"),
    ({"triple": "riscv64-unknown-linux-gnu"}, "riscv64"),
    ({"key": "deadbeef"}, "other engine sources"),
    ({"format": "gearpair-compiled/0"}, "other engine sources"),
])
def test_manifest_mismatch_is_refused(jitcache, tmp_path, monkeypatch, change, expect):
    monkeypatch.delenv("GEARPAIR_SHIPPED_CODE", raising=False)
    magic, why = jitcache._check_shipped(str(_manifest(jitcache, tmp_path, **change)))
    assert magic is None and expect in why


def test_manifest_missing_damaged_or_disabled(jitcache, tmp_path, monkeypatch):
    monkeypatch.delenv("GEARPAIR_SHIPPED_CODE", raising=False)
    assert jitcache._check_shipped(str(tmp_path)) == (None, "no compiled code shipped")
    (tmp_path / jitcache.MANIFEST).write_text("{not json")
    magic, why = jitcache._check_shipped(str(tmp_path))
    assert magic is None and "unreadable manifest" in why
    good = _manifest(jitcache, tmp_path / "good")
    monkeypatch.setenv("GEARPAIR_SHIPPED_CODE", "0")
    assert jitcache._check_shipped(str(good)) == (None, "GEARPAIR_SHIPPED_CODE=0")
