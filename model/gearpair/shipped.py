"""Compiled code of the fast engine shipped with a copy of the package (the FMU's).

A first compile of the engine takes about 30 s on a 2-core machine. `ship` compiles it once
at build time, in a child process, for a portable CPU (`portable_target`), and puts numba's
cache files with a manifest (engine key, Python/numba/llvmlite/numpy versions, CPU target and
the host CPU features it needs) into ``<package>/_compiled``. `gearpair.jitcache` consults
them before the user cache when the manifest matches the running interpreter and CPU, and
otherwise compiles into the user cache as before. This module does not import numba (the
builder calls it).
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

SHIPPED_FOLDER = "_compiled"
MANIFEST = "manifest.json"
FORMAT = "gearpair-compiled/1"

# Portable CPU targets (numba's NUMBA_CPU_NAME, with no extra features) and the host CPU
# features (LLVM names) their code needs. Per step (CPU time, interleaved runs on an AMD EPYC
# build machine) against code compiled for that machine: x86-64-v2 (SSE4.2, POPCNT: every
# x86-64 CPU since about 2009) 6-7 % slower, x86-64-v3 (AVX2, FMA: not in many low-power CPUs
# and virtual machines) 3-5 %, plain x86-64 (SSE2) 16-20 %; results bit-identical in all
# (no fused multiply-add without fastmath). Other machines get their architecture's
# generic target.
TARGETS: dict[str, tuple[str, tuple[str, ...]]] = {
    "x86_64": ("x86-64-v2", ("cx16", "sahf", "popcnt", "sse3", "ssse3", "sse4.1", "sse4.2")),
    "amd64": ("x86-64-v2", ("cx16", "sahf", "popcnt", "sse3", "ssse3", "sse4.1", "sse4.2")),
}


def portable_target() -> tuple[str, tuple[str, ...]]:
    """(CPU name, host features it needs) of the shipped code for this architecture."""
    return TARGETS.get(platform.machine().lower(), ("generic", ()))


def user_cache_dir() -> str | None:
    """A writable directory for numba's cache (NUMBA_CACHE_DIR or a per-user one), or None."""
    path = os.environ.get("NUMBA_CACHE_DIR")
    if not path:
        home = os.path.expanduser("~")
        if sys.platform.startswith("win"):
            base = os.environ.get("LOCALAPPDATA") or os.path.join(home, "AppData", "Local")
        elif sys.platform == "darwin":
            base = os.path.join(home, "Library", "Caches")
        else:
            base = os.environ.get("XDG_CACHE_HOME") or os.path.join(home, ".cache")
        path = os.path.join(base, "gearpair", "numba")
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except Exception:  # noqa: BLE001 - any failure means: no disk cache
        return None
    return path


# The child: import the package copy under its import name, compile every entry point of
# the engine (`jitcache.load_engine`), then copy numba's files and write the manifest.
_CHILD = r"""
import importlib, importlib.util, json, os, sys
folder, name, out = sys.argv[1:4]
spec = importlib.util.spec_from_file_location(
    name, os.path.join(folder, "__init__.py"), submodule_search_locations=[folder])
pkg = importlib.util.module_from_spec(spec)
sys.modules[name] = pkg
spec.loader.exec_module(pkg)
jitcache = importlib.import_module(name + ".jitcache")
shipped = importlib.import_module(name + ".shipped")
with open(out, "w") as fh:
    json.dump(shipped._write(jitcache, jitcache.load_engine()), fh)
"""


def ship(package: str | Path, import_name: str, timeout: float = 1800.0) -> dict | None:
    """Compile the engine of the package copy in ``package`` (imported as ``import_name``,
    the name it will run under: numba's cached code names its module) for
    `portable_target` and write ``<package>/_compiled``. Returns the manifest, or None
    without numba (nothing to ship; the package then runs its reference engine).

    The compile (about 45 s of CPU time) is kept in ``<user cache>/portable-<target>``, so
    building again with unchanged engine sources copies it in a few seconds.
    """
    import importlib.util

    if importlib.util.find_spec("numba") is None:
        return None
    package = Path(package).resolve()
    target, _ = portable_target()
    base = user_cache_dir() or tempfile.mkdtemp(prefix="gearpair_ship_")
    env = dict(os.environ, NUMBA_CPU_NAME=target, NUMBA_CPU_FEATURES="",
               NUMBA_CACHE_DIR=os.path.join(base, f"portable-{target}"),
               GEARPAIR_SHIPPED_CODE="0", GEARPAIR_COMPILE_NOTICE="")
    with tempfile.TemporaryDirectory(prefix="gearpair_ship_") as tmp:
        out = os.path.join(tmp, "manifest.json")
        proc = subprocess.run([sys.executable, "-c", _CHILD, str(package), import_name, out],
                              env=env, cwd=tmp, capture_output=True, text=True,
                              timeout=timeout)
        if proc.returncode != 0 or not os.path.isfile(out):
            raise RuntimeError(f"compiling the engine to ship failed (exit {proc.returncode}): "
                               f"{(proc.stderr or proc.stdout)[-2000:]}")
        with open(out, encoding="utf-8") as fh:
            return json.load(fh)


def _write(jitcache, report: dict) -> dict:
    """In the child: copy the engine's cache files next to the package, with the manifest."""
    import llvmlite
    import numba
    import numpy
    from llvmlite import binding as ll
    from numba.core.registry import cpu_target

    if report["source"] == "memory" or not jitcache.CACHE_PATH:
        raise RuntimeError("no disk cache to ship from: " + str(report))
    target, requires = portable_target()
    magic = list(cpu_target.target_context.codegen().magic_tuple())
    if magic[1] != target or magic[2] != "":
        raise RuntimeError(f"compiled for {magic[1:]}, not the portable target {target}")
    dest = os.path.join(os.path.dirname(os.path.abspath(jitcache.__file__)), SHIPPED_FOLDER)
    shutil.rmtree(dest, ignore_errors=True)
    os.makedirs(dest)
    names = sorted(n for n in os.listdir(jitcache.CACHE_PATH) if n.endswith((".nbi", ".nbc")))
    for n in names:
        shutil.copy2(os.path.join(jitcache.CACHE_PATH, n), os.path.join(dest, n))
    manifest = {
        "format": FORMAT, "key": jitcache.KEY, "engine_module": jitcache.ENGINE_MODULE,
        "versions": {"python": jitcache.python_tag(), "numba": numba.__version__,
                     "llvmlite": llvmlite.__version__, "numpy": numpy.__version__},
        "triple": ll.get_process_triple(), "cpu_name": target, "requires": list(requires),
        "magic": magic, "files": len(names), "compiled": report,
    }
    with open(os.path.join(dest, MANIFEST), "w", encoding="utf-8") as fh:
        json.dump(manifest, fh, indent=1)
    return manifest
