"""Where the GearPair FMU is, and whether it still holds the physics of this package.

The package never looks for a repository: the FMU is the path a caller passes
(``--fmu PATH``, ``Scene.run(fmu_path=...)``), else the file ``GEARPAIR_FMU`` names, else
``dist/GearPair.fmu`` of the current folder (where ``python build_fmu.py`` puts it). Without
one, `find_fmu` says how to build or pass it.

An FMU is *stale* when it would not run this package's physics:

- its bundled copy of ``gearpair`` (``resources/gearpair/**.py`` in the FMU) differs from
  this package's own files, fast-engine sub-package included; or
- a file of its build record changed since the build. ``build_fmu.py`` writes the record
  beside the FMU (``GearPair.fmu.build.json``): the builder, the slave and its C layer with
  their content hashes, and the FMU's own hash. A file of the record that no longer exists
  (the FMU moved to another machine) is not judged.

A stale FMU found by default is rebuilt with the builder the record names, bundling this
package (as before a run on stale physics); without one, the run goes on with a warning.
An FMU the caller passes is never rebuilt: a stale one gets the warning.

Processes that find one stale FMU at once (parallel runs, sweep workers, test workers)
rebuild it once: the rebuild holds a lock on ``.GearPair.fmu.lock`` beside the FMU, and
whoever waited for it looks at the FMU again, finds it rebuilt and runs it. The builder
writes the FMU under another name and renames it into place, so a run that reads it during a
rebuild gets the old file or the new one whole.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import json
import os
import sys
import warnings
import zipfile
from pathlib import Path

try:
    import fcntl
except ImportError:  # not POSIX (the FMU's binary is Linux-only): no lock
    fcntl = None

from .errors import SceneError, SceneWarning

ENV = "GEARPAIR_FMU"  # environment variable naming the FMU
FMU_NAME = "GearPair.fmu"
RECORD_SUFFIX = ".build.json"  # GearPair.fmu -> GearPair.fmu.build.json
_BUNDLED = "resources/gearpair/"  # the package's copy in the FMU
PACKAGE = Path(__file__).resolve().parents[1]  # this gearpair package (not a repository)


def file_hash(path: str | Path) -> str:
    """SHA-256 of a file's bytes (hex), as the build record holds them."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def record_path(fmu: str | Path) -> Path:
    """The build record beside ``fmu``."""
    fmu = Path(fmu)
    return fmu.with_name(fmu.name + RECORD_SUFFIX)


def read_record(fmu: str | Path) -> dict | None:
    """The build record of ``fmu``, or ``None`` when there is none or it describes another
    file (the FMU was replaced after the build)."""
    path = record_path(fmu)
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("fmu_sha256") != file_hash(fmu):
        return None
    return record


def _package_files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*.py"))
            if "__pycache__" not in p.parts}


def stale_reason(fmu: str | Path, package: str | Path | None = None) -> str | None:
    """Why ``fmu`` would not run the physics of ``package`` (default: this package), in one
    line, or ``None``."""
    package = Path(package) if package is not None else PACKAGE
    with zipfile.ZipFile(fmu) as z:
        bundled = {n[len(_BUNDLED):]: z.read(n) for n in z.namelist()
                   if n.startswith(_BUNDLED) and n.endswith(".py")
                   and not n.startswith(_BUNDLED + "_compiled/")}
    if bundled:  # an FMU without the package (another slave) is not judged by it
        own = _package_files(package)
        differ = sorted(k for k in own.keys() | bundled.keys() if own.get(k) != bundled.get(k))
        if differ:
            more = f" (and {len(differ) - 1} more)" if len(differ) > 1 else ""
            return (f"its copy of gearpair/{differ[0]}{more} differs from "
                    f"{package / differ[0]}")
    record = read_record(fmu) or {}
    for path, digest in sorted(record.get("sources", {}).items()):
        if Path(path).is_file() and file_hash(path) != digest:
            return f"{path} changed after the build"
    return None


def _not_found(where: str) -> SceneError:
    return SceneError(
        f"no {FMU_NAME} {where}: build it with 'python build_fmu.py' in the gearpair "
        f"repository (it writes dist/{FMU_NAME}; run from that folder or set {ENV} to the "
        "file), or pass its path (--fmu PATH, Scene.run(fmu_path=...))")


@contextlib.contextmanager
def _rebuild_lock(fmu: Path):
    """Hold the lock that serializes rebuilds of ``fmu`` among processes (and threads): an
    exclusive `fcntl.flock` on ``.<name>.lock`` beside it, released when the holder ends."""
    if fcntl is None:
        yield
        return
    with open(fmu.with_name(f".{fmu.name}.lock"), "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _rebuild(fmu: Path, builder: Path) -> None:
    spec = importlib.util.spec_from_file_location("_gearpair_build_fmu", builder)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.build(fmu.parent, package=PACKAGE)


def _where(fmu_path: str | Path | None) -> tuple[Path, str]:
    if fmu_path is not None:
        return Path(fmu_path), f"at {fmu_path}"
    if os.environ.get(ENV):
        return Path(os.environ[ENV]), f"at {os.environ[ENV]} (${ENV})"
    fmu = Path.cwd() / "dist" / FMU_NAME
    return fmu, f"in {fmu.parent} (no {ENV} set)"


def _checked(fmu_path: str | Path | None) -> tuple[Path, str | None, Path | None]:
    """(the FMU, its `stale_reason`, the builder that would rebuild it or None): one look
    at the FMU's contents, shared by `locate_fmu` and `find_fmu`."""
    fmu, where = _where(fmu_path)
    if not fmu.is_file():
        raise _not_found(where)
    reason = stale_reason(fmu)
    builder = (read_record(fmu) or {}).get("builder") if reason else None
    usable = fmu_path is None and builder and Path(builder).is_file()
    return fmu, reason, Path(builder) if usable else None


def locate_fmu(fmu_path: str | Path | None = None) -> tuple[Path, str | None]:
    """The FMU `find_fmu` would run and, when it would rebuild it first, why (its
    `stale_reason`), without rebuilding or warning: e.g. to start the compile of its
    engine beside other work, or to check the FMU before a long run.

    Raises
    ------
    SceneError
        No FMU there, with how to build or pass one.
    """
    fmu, reason, builder = _checked(fmu_path)
    return fmu, reason if builder else None


def find_fmu(fmu_path: str | Path | None = None, rebuild_stale: bool = True) -> Path:
    """The FMU to run: ``fmu_path``, else ``$GEARPAIR_FMU``, else ``./dist/GearPair.fmu``.

    A stale FMU (`stale_reason`) found by default is rebuilt with the builder of its build
    record when ``rebuild_stale`` and the builder exists; otherwise, and for a passed FMU, a
    `SceneWarning` says why it is stale and the run uses it.

    Raises
    ------
    SceneError
        No FMU there, with how to build or pass one.
    """
    fmu, reason, builder = _checked(fmu_path)
    if reason and builder and rebuild_stale:
        with _rebuild_lock(fmu):
            # another process may have rebuilt it while this one waited for the lock
            fmu, reason, builder = _checked(fmu_path)
            if reason and builder:
                print(f"gearpair: rebuilding stale {fmu}: {reason}", file=sys.stderr,
                      flush=True)
                _rebuild(fmu, builder)
                reason = stale_reason(fmu)
    if reason is None:
        return fmu
    warnings.warn(SceneWarning(f"{fmu} is stale ({reason}): it runs other physics than this "
                               "gearpair; rebuild it with 'python build_fmu.py'"), stacklevel=2)
    return fmu
