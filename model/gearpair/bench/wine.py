"""Running a Windows program under Wine for the bench: the tools, the prefix, the run.

The prefix is the one ``tests/test_win64.py`` uses (``$GEARPAIR_WINEPREFIX``, else
``~/.cache/gearpair/wine64``), made once (about 12 s and 0.7 GB) under a lock. Two pitfalls
that the tests met are handled as there: a new prefix's registry files are written only
when its wineserver exits (seconds after ``wineboot`` returns), so the boot waits with
``wineserver -w``; and a wineserver that a program starts inherits the program's output
and stays 3 s after it ends, so programs write into files, not pipes, whose reader would
wait for it.
"""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

MINGW = "x86_64-w64-mingw32-gcc"


def tools() -> tuple[dict | None, str | None]:
    """Wine and mingw-w64, or why not: ({"wine", "cc"}, None) or (None, the reason)."""
    wine = shutil.which("wine") or shutil.which("wine64")
    cc = shutil.which(MINGW)
    missing = [name for name, path in (("wine64 (or wine)", wine), (MINGW, cc)) if not path]
    if missing:
        return None, (f"no {' and no '.join(missing)} (apt-get install gcc-mingw-w64-x86-64 "
                      "wine64; scripts/setup.sh does)")
    return {"wine": wine, "cc": cc}, None


def prefix() -> Path:
    """The Wine prefix the bench and the tests share."""
    own = os.environ.get("GEARPAIR_WINEPREFIX")
    if own:
        return Path(own)
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(cache) / "gearpair" / "wine64"


def environment(where: Path) -> dict:
    """The environment of a Wine program: no display, no debug output, no .NET or Gecko
    installer prompts."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env.update(WINEPREFIX=str(where), WINEDEBUG="-all", WINEDLLOVERRIDES="mscoree,mshtml=")
    return env


def boot(wine: str, timeout: float = 600.0) -> Path:
    """The prefix, made first when it is not there (one boot at a time: a lock file beside
    it).

    Raises
    ------
    RuntimeError
        wineboot made no registry.
    """
    where = prefix()
    env = environment(where)
    where.parent.mkdir(parents=True, exist_ok=True)
    with open(where.parent / f".{where.name}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (where / "system.reg").is_file():
            with tempfile.TemporaryFile() as err:
                subprocess.run([wine, "wineboot", "--init"], env=env, stdin=subprocess.DEVNULL,
                               stdout=subprocess.DEVNULL, stderr=err, timeout=timeout)
                server = shutil.which("wineserver") or str(Path(wine).with_name("wineserver"))
                subprocess.run([server, "-w"], env=env, stdin=subprocess.DEVNULL,
                               stdout=subprocess.DEVNULL, stderr=err, timeout=timeout)
                err.seek(0)
                why = err.read().decode(errors="replace")[-2000:]
            if not (where / "system.reg").is_file():
                raise RuntimeError(f"wineboot made no Wine prefix in {where}: {why}")
    return where


def run(wine: str, program: Path, args: list[str], timeout: float = 600.0,
        input: str | None = None) -> subprocess.CompletedProcess:
    """``program`` with ``args`` (and ``input`` on its stdin) under Wine in the bench's
    prefix (`boot` first); stdout with CR LF as LF, stderr as text."""
    env = environment(prefix())
    with tempfile.TemporaryFile() as i, tempfile.TemporaryFile() as o, \
            tempfile.TemporaryFile() as e:
        i.write((input or "").encode())
        i.seek(0)
        proc = subprocess.run([wine, str(program), *args], env=env, stdin=i,
                              stdout=o, stderr=e, timeout=timeout)
        o.seek(0)
        e.seek(0)
        proc.stdout = o.read().decode(errors="replace").replace("\r\n", "\n")
        proc.stderr = e.read().decode(errors="replace")
    return proc


def winpath(p: str | Path) -> str:
    """A Linux path as Wine's programs name it (drive Z: is the root)."""
    return "Z:" + str(Path(p).resolve())
