"""How the FMU finds its resources and its Python: resource-location forms, the interpreter
recorded at build time, the GEARPAIR_PYTHON override, missing packages, and calls that
arrive after the host's interpreter has finalized.

The non-Python hosts here run with an empty environment (`env -i`), as a master started
from a launcher would: the FMU must find everything from what it carries.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

fmpy = pytest.importorskip("fmpy")

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
