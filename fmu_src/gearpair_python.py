"""Which Python the GearPair FMU runs on, and whether it has what the FMU needs.

Only the scipy reference engine (``engine = 1``) runs in Python; the default engine is
compiled into the FMU's binary. This file ships in the FMU's resources beside ``python.txt``
and serves the FMU's C layer (``fmu_src/c/python_slave.c``) when an instance chooses the
reference engine, in three ways, with the standard library only:

- ``build_fmu.py`` writes `describe()` of the building interpreter to ``python.txt``: its
  shared libpython, its installation (home: the standard library), its executable (a venv's
  ``bin/python``, from which embedded Python finds the venv) and its package folders;
- ``python gearpair_python.py`` prints the same for another interpreter: the C layer runs
  the one named by ``GEARPAIR_PYTHON`` this way;
- `prepare` runs inside the interpreter the C layer started (or the host's, in a Python
  host) before the slave is imported: it adds the recorded package folders to ``sys.path``
  (only in an interpreter the FMU started) and checks the packages the FMU needs, so that a
  missing one is one clear message rather than a traceback from pythonfmu.
"""

from __future__ import annotations

import os
import sys
import sysconfig

NEEDED = ("numpy", "scipy", "pythonfmu")  # the reference engine cannot run without these


def libpython() -> str:
    """The shared libpython of this interpreter, or "" when it was built without one."""
    if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
        return ""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    for name in (sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")):
        if name and ".so" in name and os.path.isfile(os.path.join(libdir, name)):
            return os.path.join(libdir, name)
    return ""


def package_folders() -> list[str]:
    """The folders this interpreter imports installed packages from (site-packages of the
    environment, the user's, the system's), in ``sys.path`` order."""
    return [p for p in dict.fromkeys(sys.path)
            if p and os.path.basename(p.rstrip("/")) in ("site-packages", "dist-packages")
            and os.path.isdir(p)]


def describe() -> str:
    """``key=value`` lines, the format of ``python.txt`` (``site`` repeats)."""
    lines = [f"version={sys.version.split()[0]}", f"libpython={libpython()}",
             f"home={sys.base_prefix}", f"executable={sys.executable}"]
    lines += [f"site={p}" for p in package_folders()]
    return "\n".join(lines) + "\n"


def prepare(sites: list[str], started_here: bool, origin: str) -> tuple[str, str]:
    """Make the recorded package folders importable and check the packages.

    ``sites``: folders to add (with their ``.pth`` files) when ``started_here`` (an
    interpreter the FMU started; a host's own ``sys.path`` is left alone); ``origin``: how
    this interpreter was chosen, for the messages. Returns ``(error, note)``: ``error`` is
    "" or one message naming what is missing, where it looked and the fix; ``note`` says
    which Python and engine the FMU runs on (logged as information).
    """
    import importlib
    import importlib.util

    if started_here:
        import site

        for p in sites:
            if p and os.path.isdir(p) and p not in sys.path:
                site.addsitedir(p)
    where = f"Python {sys.version.split()[0]} at {sys.executable or sys.prefix} ({origin})"
    missing = []
    for name in NEEDED:
        try:
            importlib.import_module(name)
        except Exception as e:  # noqa: BLE001 - any failure to import is reported
            missing.append(f"{name} ({type(e).__name__}: {e})")
    if missing:
        folders = [p for p in sys.path if p and os.path.isdir(p)]
        python = sys.executable or "python"
        return (f"the FMU cannot import {', '.join(missing)} in {where}; it looked in "
                f"{os.pathsep.join(folders)}. Fix: install what is missing into that "
                f"environment ({python} -m pip install numpy scipy pythonfmu), or set "
                "GEARPAIR_PYTHON to the python executable of an environment that has them "
                "(docs/hosts.md)"), ""
    return "", f"runs the reference engine (engine = 1) on {where}"


if __name__ == "__main__":
    sys.stdout.write(describe())
