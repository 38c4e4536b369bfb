"""How the slave finds its gearpair package: the copy in the FMU's resources, imported under a
private name (`BUNDLE`), with the resources folder taken off ``sys.path`` again, so that a
Python host keeps its own ``gearpair``, imported before or after the FMU. Ships in the FMU's
resources beside the slave (``GearPair.py``).
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys

BUNDLE = "_gearpair_fmu"  # import name of the bundled package (never ``gearpair``)


def _resources_folder(resources: str | None) -> str | None:
    """The resources folder as a normal absolute path.

    The FMU's C layer hands pythonfmu ``file://`` + an absolute path, which pythonfmu turns
    into that path; a path with leading ``//`` (a ``file:////abs`` location given to
    pythonfmu directly) or a leftover ``file:`` URI names the same folder.
    """
    if not resources:
        return resources
    path = resources
    if path[:5].lower() == "file:":
        from urllib.parse import unquote, urlsplit

        parts = urlsplit(path)
        if parts.netloc not in ("", "localhost"):
            return path
        path = unquote(parts.path)
    if path.startswith("//"):
        path = "/" + path.lstrip("/")
    return os.path.abspath(path)


def _unlist_resources(resources: str | None) -> None:
    """Take the resources folder off ``sys.path`` again.

    pythonfmu's binary puts it first on ``sys.path`` to import this script and leaves it
    there, so in a Python host a later ``import gearpair`` would find the FMU's copy (and
    fail once the host deleted the folder) instead of the host's own. This module is
    imported by then and the bundled package needs no ``sys.path`` entry (`_import_gearpair`).
    Only in an extracted FMU, recognised by a ``binaries`` folder beside it (fmpy extracts
    just ``binaries`` and ``resources``): pythonfmu's builder instantiates the slave with the
    script's own folder, which it removes itself.
    """
    where = _resources_folder(resources)
    if where and os.path.isdir(os.path.join(os.path.dirname(where), "binaries")):
        sys.path[:] = [p for p in sys.path if not (p and _resources_folder(p) == where)]


def _package_alive(mod) -> bool:
    """Whether a package's folder still exists (hosts delete an FMU's extracted folder)."""
    paths = list(getattr(mod, "__path__", []))
    return any(os.path.isfile(os.path.join(p, "__init__.py")) for p in paths)


def _import_gearpair(resources: str | None):
    """The gearpair package of this FMU: the copy in ``resources`` imported as `BUNDLE`.

    Neither ``sys.path`` nor a ``gearpair`` of the host is touched, so a host that imports
    gearpair later gets its own. Instances share the bundled package while its folder exists;
    after a host deleted it, the next instance imports its own copy (live instances keep the
    module objects they hold). Without a bundled copy (this module imported outside an FMU,
    e.g. by the builder's documentation) the installed ``gearpair`` is used.
    """
    folder = os.path.join(resources, "gearpair") if resources else ""
    init = os.path.join(folder, "__init__.py")
    if not os.path.isfile(init):
        gp = importlib.import_module("gearpair")
    else:
        gp = sys.modules.get(BUNDLE)
        if gp is not None and not _package_alive(gp):
            for name in [n for n in sys.modules if n == BUNDLE or n.startswith(BUNDLE + ".")]:
                del sys.modules[name]
            gp = None
        if gp is None:
            spec = importlib.util.spec_from_file_location(
                BUNDLE, init, submodule_search_locations=[folder])
            gp = importlib.util.module_from_spec(spec)
            sys.modules[BUNDLE] = gp
            try:
                spec.loader.exec_module(gp)
            except BaseException:
                del sys.modules[BUNDLE]
                raise
    for sub in ("params", "effects", "engine"):
        importlib.import_module(f"{gp.__name__}.{sub}")
    return gp
