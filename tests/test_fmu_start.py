"""The FMU's first start: compiled engine code shipped inside the FMU, and the fall-back.

A child process with empty user caches (``XDG_CACHE_HOME``, ``NUMBA_CACHE_DIR``) instantiates
the built FMU through fmpy, steps it and reports the slave's log and how the bundled
package's `jitcache` obtained each compiled function. With the FMU as built, the shipped code
is loaded and nothing compiles; with a shipped manifest that does not match, the engine
compiles once, says so (status OK) and gives bit-identical outputs. The manifest checks
themselves (versions, CPU features) are tested in-process without compiling.
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
    stats = dict(sys.modules["_gearpair_fmu.jitcache"].STATS)
    with open(out, "w") as fh:
        json.dump({"said": said, "stats": stats, "rows": rows}, fh)
    sys.stdout.flush()
    os._exit(0)  # no interpreter teardown after a pythonfmu slave (docs/hosts.md)
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
def shipped_start(fmu_path, tmp_path_factory) -> dict:
    tmp = tmp_path_factory.mktemp("start_shipped")
    return _start(Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp / "fmu"))), tmp)


def test_fmu_ships_compiled_engine(fmu_path):
    import zipfile

    with zipfile.ZipFile(fmu_path) as z:
        names = z.namelist()
        manifest = json.loads(z.read("resources/gearpair/_compiled/manifest.json"))
    assert manifest["engine_module"] == "_gearpair_fmu.fast"
    assert manifest["cpu_name"] in ("x86-64-v2", "generic")
    shipped = [n for n in names if n.startswith("resources/gearpair/_compiled/")]
    assert sum(n.endswith(".nbc") for n in shipped) >= 5  # the five entry points at least
    assert manifest["files"] == len(shipped) - 1


def test_first_start_loads_shipped_code(shipped_start):
    said = [m for _, m in shipped_start["said"]]
    assert any("loaded the compiled code shipped in this FMU" in m for m in said), said
    assert not any("compiled once" in m for m in said), said
    stats = shipped_start["stats"]
    assert stats["compiled"] == 0 and stats["shipped"] >= 5, stats
    assert shipped_start["cache_files"] == []  # nothing compiled into the user cache
    assert all(status == 0 for status, _ in shipped_start["said"]), shipped_start["said"]


@pytest.mark.slow
def test_mismatched_shipped_code_compiles_once(fmu_path, shipped_start, tmp_path):
    """A shipped manifest for other engine sources: compile (about 30 s), log it with
    status OK, save into the user cache, and step bit-identically to the shipped code."""
    unzip = Path(fmpy.extract(str(fmu_path), unzipdir=str(tmp_path / "fmu")))
    manifest = unzip / "resources" / "gearpair" / "_compiled" / "manifest.json"
    m = json.loads(manifest.read_text())
    m["key"] = "0" * len(m["key"])
    manifest.write_text(json.dumps(m))
    report = _start(unzip, tmp_path)
    said = report["said"]
    msg = [m for s, m in said if "fast engine: compiled once for this machine in" in m]
    assert len(msg) == 1, said
    assert "other engine sources" in msg[0] and "later runs load it from" in msg[0]
    assert all(status == 0 for status, _ in said), said  # fmi2OK: information, no warning
    assert report["stats"]["shipped"] == 0 and report["stats"]["compiled"] >= 5
    assert report["cache_files"]  # compiled once, into the user cache
    assert report["rows"] == shipped_start["rows"]  # bit-identical outputs


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
