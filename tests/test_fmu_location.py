"""Where `--engine fmu` finds the FMU (a passed path, ``$GEARPAIR_FMU``, ``./dist``; never a
path into the repository), the error that says how to build or pass it, and the stale-FMU
protection: an FMU whose bundled gearpair differs from the running package, or whose slave,
C layer or builder changed after the build, is rebuilt (found by default) or warned about."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from gearpair.cli import main
from gearpair.scenes import SceneError, SceneWarning, location

ROOT = Path(__file__).resolve().parents[1]

# A stand-in for build_fmu.py: zips the package's .py files as the FMU bundles them and writes
# the build record as build_fmu.write_build_record does (here: the C layer file only).
FAKE_BUILDER = '''
import hashlib, json, time, zipfile
from pathlib import Path
HERE = Path(__file__).resolve().parent
def digest(p):
    return hashlib.sha256(Path(p).read_bytes()).hexdigest()
def build(out, package):
    if (HERE / "slow.txt").is_file():  # a build that takes this long (s)
        time.sleep(float((HERE / "slow.txt").read_text()))
    fmu = Path(out) / "GearPair.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        for p in sorted(Path(package).rglob("*.py")):
            z.writestr("resources/gearpair/" + p.relative_to(package).as_posix(), p.read_bytes())
    shim = HERE / "fmu_src" / "c" / "fmi2Functions.c"
    (HERE / "builds.txt").open("a").write("built\\n")
    fmu.with_name(fmu.name + ".build.json").write_text(json.dumps(
        {"fmu_sha256": digest(fmu), "builder": str(HERE / "build_fmu.py"),
         "sources": {str(shim): digest(shim)}}))
    return fmu
'''


@pytest.fixture()
def repo(tmp_path, monkeypatch):
    """A folder laid out like the repository (a builder, the C layer), a package standing in
    for the running one (top level and the fast sub-package), and the folder as the current
    one, with no ``$GEARPAIR_FMU``."""
    (tmp_path / "build_fmu.py").write_text(FAKE_BUILDER)
    (tmp_path / "fmu_src" / "c").mkdir(parents=True)
    (tmp_path / "fmu_src" / "c" / "fmi2Functions.c").write_text("int x;\n")
    pkg = tmp_path / "site" / "gearpair"
    (pkg / "fast").mkdir(parents=True)
    (pkg / "params.py").write_text("A = 1\n")
    (pkg / "fast" / "loop.py").write_text("B = 2\n")
    monkeypatch.setattr(location, "PACKAGE", pkg)
    monkeypatch.delenv(location.ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _build(repo: Path) -> Path:
    location._rebuild(repo / "dist" / "GearPair.fmu", repo / "build_fmu.py")
    return repo / "dist" / "GearPair.fmu"


def _builds(repo: Path) -> int:
    f = repo / "builds.txt"
    return len(f.read_text().split()) if f.is_file() else 0


def test_no_fmu_says_how_to_build_or_pass_it(repo, monkeypatch):
    with pytest.raises(SceneError, match=r"no GearPair.fmu in .*dist.*build_fmu.py.*--fmu PATH"):
        location.find_fmu()
    monkeypatch.setenv(location.ENV, str(repo / "elsewhere.fmu"))
    with pytest.raises(SceneError, match=r"elsewhere.fmu \(\$GEARPAIR_FMU\)"):
        location.find_fmu()
    with pytest.raises(SceneError, match="at nowhere.fmu"):
        location.find_fmu("nowhere.fmu")


def test_the_fmu_is_found_in_the_current_dist_or_by_the_environment(repo, monkeypatch):
    (repo / "dist").mkdir()
    fmu = _build(repo)
    assert location.find_fmu() == repo / "dist" / "GearPair.fmu"
    moved = repo / "moved.fmu"
    shutil.copy(fmu, moved)
    monkeypatch.setenv(location.ENV, str(moved))
    assert location.find_fmu() == moved
    assert location.find_fmu(fmu) == fmu  # a passed path comes first


def test_a_stale_fmu_found_by_default_is_rebuilt(repo, capsys):
    """A change in the package's sub-package (the fast engine) or top level, or in the C
    layer named by the build record, rebuilds it; nothing changed, nothing is built."""
    (repo / "dist").mkdir()
    _build(repo)
    assert _builds(repo) == 1
    location.find_fmu()
    assert _builds(repo) == 1  # nothing changed
    edits = [location.PACKAGE / "fast" / "loop.py", location.PACKAGE / "params.py",
             repo / "fmu_src" / "c" / "fmi2Functions.c"]
    for n, path in enumerate(edits, start=2):
        path.write_text(path.read_text() + "# edited\n")
        location.find_fmu()
        assert _builds(repo) == n, path
        err = capsys.readouterr().err
        assert "rebuilding stale" in err and path.name in err
    (location.PACKAGE / "fast" / "new.py").write_text("")  # a file the FMU does not bundle
    assert "gearpair/fast/new.py" in location.stale_reason(repo / "dist" / "GearPair.fmu",
                                                            location.PACKAGE)


def test_a_stale_fmu_found_twice_at_once_is_rebuilt_once(repo):
    """Two runs that find one stale FMU at the same time (parallel runs, sweep workers): one
    rebuilds it, the other waits for that rebuild and runs the rebuilt FMU, rather than both
    writing the same file. Threads stand in for processes (the lock is `flock` on a file each
    opens: the same exclusion either way)."""
    import threading
    import warnings

    (repo / "dist").mkdir()
    fmu = _build(repo)
    (location.PACKAGE / "params.py").write_text("A = 4\n")
    (repo / "slow.txt").write_text("1.0")  # the second finds it stale while it is rebuilt
    start, found, said = threading.Barrier(2), [], []

    def run():
        start.wait()
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            found.append(location.find_fmu())
        said.extend(str(x.message) for x in w if issubclass(x.category, SceneWarning))

    threads = [threading.Thread(target=run) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert found == [fmu, fmu] and said == []  # both run it, neither warned of staleness
    assert _builds(repo) == 2  # the first build and one rebuild
    assert location.stale_reason(fmu, location.PACKAGE) is None


def test_a_stale_fmu_without_its_builder_or_passed_is_run_with_a_warning(repo):
    (repo / "dist").mkdir()
    fmu = _build(repo)
    (location.PACKAGE / "params.py").write_text("A = 3\n")
    with pytest.warns(SceneWarning, match=r"stale \(its copy of gearpair/params.py differs"):
        assert location.find_fmu(fmu) == fmu  # passed: never rebuilt
    (repo / "build_fmu.py").unlink()  # the repository is gone: nothing to rebuild with
    with pytest.warns(SceneWarning, match="rebuild it with 'python build_fmu.py'"):
        assert location.find_fmu() == fmu
    assert _builds(repo) == 1


def test_a_record_of_another_fmu_is_not_used(repo):
    """The record holds the FMU's hash: after the FMU is replaced, its sources are not
    judged (the bundled package still is)."""
    (repo / "dist").mkdir()
    fmu = _build(repo)
    (repo / "fmu_src" / "c" / "fmi2Functions.c").write_text("int y;\n")
    assert "fmi2Functions.c changed" in location.stale_reason(fmu, location.PACKAGE)
    with zipfile.ZipFile(fmu, "a") as z:
        z.writestr("documentation/extra.txt", "")
    assert location.read_record(fmu) is None
    assert location.stale_reason(fmu, location.PACKAGE) is None


def test_cli_engine_fmu_without_an_fmu_is_one_line_and_exit_2(repo, capsys):
    scene = ROOT / "examples" / "scenes" / "paper_slip.toml"
    assert main(["simulate", str(scene), "--engine", "fmu", "--t-end", "0.001"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gearpair: error: no GearPair.fmu") and "\n" not in err
    assert "build_fmu.py" in err and "--fmu PATH" in err
    assert main(["simulate", str(scene), "--fmu", "x.fmu", "--t-end", "0.001"]) == 2
    assert "--engine fmu only" in capsys.readouterr().err


def test_the_package_names_no_repository_path():
    """The installed package has no repository around it: no module of scenes/ or cli/
    climbs out of the package to build_fmu.py, dist/ or fmu_src/."""
    pkg = ROOT / "model" / "gearpair"
    for path in [*(pkg / "scenes").glob("*.py"), *(pkg / "cli").glob("*.py")]:
        text = path.read_text()
        assert "parents[2]" not in text and "parents[3]" not in text, path
        assert '"build_fmu.py"' not in text and '"fmu_src"' not in text, path


@pytest.mark.fmu
def test_a_fresh_build_is_not_stale_and_records_its_sources(fmu_path):
    """build_fmu.py's FMU bundles this package byte for byte and records the builder, the
    slave and the C layer; this package finds none of them changed."""
    record = json.loads(location.record_path(fmu_path).read_text())
    assert record == location.read_record(fmu_path)
    assert Path(record["builder"]) == ROOT / "build_fmu.py"
    names = {Path(p).relative_to(ROOT).as_posix() for p in record["sources"]}
    assert {"build_fmu.py", "fmu_src/GearPair.py", "fmu_src/c/fmi2Functions.c"} <= names
    assert location.stale_reason(fmu_path) is None


@pytest.mark.fmu
def test_gearpair_finds_the_fmu_by_the_environment(fmu_path, tmp_path):
    """In a folder with no dist/, GEARPAIR_FMU is enough (a fresh interpreter: the CLI as a
    user runs it)."""
    env_code = ("import sys; from gearpair.cli import main; "
                f"sys.exit(main(['simulate', {str(ROOT / 'examples/scenes/paper_slip.toml')!r}, "
                "'--engine', 'fmu', '--t-end', '0.002', '--json']))")
    proc = subprocess.run([sys.executable, "-c", env_code], cwd=tmp_path, text=True,
                          capture_output=True, timeout=600,
                          env=dict(os.environ, GEARPAIR_FMU=str(fmu_path)))
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(proc.stdout)["engine"] == "fmu"
