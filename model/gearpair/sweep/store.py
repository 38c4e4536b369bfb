"""The sweep's store: a Zarr (v3) folder that xarray opens as a labelled N-D dataset, written
point by point as the points finish.

Layout (``xarray.open_zarr(path)``): one dimension per swept parameter (a factorial grid) or
one dimension ``point`` (a list of points, the parameters as coordinates along it); per point
the variables `NUMERIC` (ratios, mesh-force and DTE statistics, period, cost ...), ``status``
(0 not run, 1 ok, 2 failed, 3 invalid; CF ``flag_values``/``flag_meanings``), ``error``,
``worker``, and ``done`` (1 once the point's record is complete); the Poincare section as
``poincare`` over an extra dimension ``section`` padded with NaN, its length in
``poincare_count`` (CF's "incomplete multidimensional array" form of ragged data). The
group's attributes hold the layout version, the grid, the settings and the engine version.
Every variable and coordinate has a ``long_name`` that says what it is and, where it has one,
``units`` in a UDUNITS spelling (``rpm``, ``N.m``, ``kN``, ``um``, ``1`` ...; `DESCRIPTION`),
so CF tools and xarray's plots label them.

Consolidated metadata (zarr-python's, in the root ``zarr.json``): ``xarray.open_zarr`` reads
the whole layout from that one file instead of warning and opening every array's. The points
only ever change chunks, never metadata, so it is written when the metadata changes: once
at creation (before the store is renamed into place) and after every run (`Store.add_run`,
which changes the group's attributes), so a store without it gets it on its next run.

Crash safety: only this process (the client) writes, one batch of finished points at a time
(`Store.write_many`). A chunk holds up to `CHUNK_POINTS` neighbouring points (one file per
point would make a 1,000-point store 37,000 files); writing points makes zarr read their
chunk, merge them in and write the whole chunk again, and zarr's `LocalStore` (zarr 3.1)
writes every file to a temporary name and renames it over the old one (`os.replace`, atomic
on POSIX; checked by a test): a chunk file is the old one or the new one, never a mix.
``done`` is written after the points' other variables, so a point killed between the two
reads as not done and runs again. The store's
metadata is written once, into a temporary folder renamed into place; after that only the
root ``zarr.json`` (attributes, consolidated metadata) changes, replaced whole through a
temporary file and a rename like a chunk. A killed client therefore loses only the points in
flight, and the store always opens.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import math
import os
import shutil
import time
import warnings
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

import numpy as np

from .grid import Grid
from .point import COLUMNS
from .settings import INPUTS, SweepSettings, long_name, sweepable

CHUNK_POINTS = 64  # most points in one chunk of a variable
FORMAT = 1  # layout version of the store; a different one is refused
STATUS = ("not_run", "ok", "failed", "invalid")
# per-point record fields kept as text or as the settings (in the attributes), not numbers
_TEXT = ("error", "worker")
_NOT_NUMERIC = ("index", "param", "value", "status", "friction", "stick_tie", "sliding",
                *_TEXT)
NUMERIC = tuple(c for c in COLUMNS if c not in _NOT_NUMERIC)
_INT = ("attempts", "transient_periods", "kept_periods", "poincare_period",
        "poincare_distinct")
# Units (UDUNITS spellings, as CF asks: "1" is dimensionless, "rpm" revolutions per minute,
# "um" micrometres) and long names (what the variable is, in words) of the numeric variables.
# Every `NUMERIC` name needs one (a new column without one fails the store's tests).
DESCRIPTION = {
    "attempts": ("1", "runs of the point (the first and the retries with a tighter rtol)"),
    "rtol": ("1", "relative tolerance of the fast engine"),
    "speed_rpm": (INPUTS["speed_rpm"], "speed of gear 1"),
    "torque_nm": (INPUTS["torque"], "driving torque on gear 1"),
    "mu": ("1", "coefficient of friction between the teeth"),
    "mesh_period_s": ("s", "mesh period"),
    "transient_periods": ("1", "mesh periods discarded as transient"),
    "kept_periods": ("1", "mesh periods kept (recorded)"),
    "section_phase": ("1", "phase of the Poincare section in the mesh period (0: a pair "
                           "enters contact)"),
    "t_end_s": ("s", "simulated time at the end of the record"),
    "stick_ratio": ("1", "stick ratio: fraction of the kept time in stick (Eq. 26)"),
    "contact_loss_ratio": ("1", "contact-loss ratio: fraction of the kept time with the "
                                "teeth apart (Eq. 27)"),
    "back_contact_ratio": ("1", "fraction of the kept time in contact on the back flank"),
    "stick_period_fraction": ("1", "fraction of the kept mesh periods with some stick"),
    "loss_period_fraction": ("1", "fraction of the kept mesh periods with some contact loss"),
    "dte_mean_um_sampled": ("um", "mean dynamic transmission error (DTE) over the samples"),
    "dte_min_um_sampled": ("um", "least dynamic transmission error (DTE) of the samples"),
    "dte_max_um_sampled": ("um", "greatest dynamic transmission error (DTE) of the samples"),
    "mesh_force_min_kn": ("kN", "least mesh force"),
    "mesh_force_mean_kn": ("kN", "mean mesh force"),
    "mesh_force_max_kn": ("kN", "greatest mesh force"),
    "poincare_period": ("1", "period of the Poincare section in mesh periods (0: none "
                             "found, -1: no record)"),
    "poincare_distinct": ("1", "distinct values of the Poincare section"),
    "adjacent_diff": ("1", "largest RMS difference of the DTE between adjacent mesh periods, "
                           "over the RMS of its fluctuation"),
    "alternate_diff": ("1", "largest RMS difference of the DTE between mesh periods two "
                            "apart, over the RMS of its fluctuation"),
    "half_order_um": ("um", "DTE amplitude at half the mesh frequency"),
    "mesh_order_um": ("um", "DTE amplitude at the mesh frequency"),
    "events_per_period": ("1", "state switches located by the engine per kept mesh period"),
    "wall_s": ("s", "wall time of the point"),
    "cpu_s": ("s", "CPU time of the point"),
}
UNITS = {name: unit for name, (unit, _) in DESCRIPTION.items()}

# the modules whose code decides a point's numbers (beside the fast engine's own files)
_PHYSICS = ("params.py", "effects.py", "geometry.py", "stiffness.py", "potential_energy.py",
            "equations.py", "switching.py", "analysis.py", "sweep/point.py",
            "sweep/settings.py")


class _Lock:
    """An exclusive ``flock`` on the store's folder, held until `close`."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    __del__ = close


def _lock(path: Path) -> _Lock | None:
    """Hold the store's writer lock (``flock`` on its folder, whose inode stays while zarr
    replaces the files inside it): a second sweep writing the same store would lose points
    to the first one's chunk rewrites. The kernel drops the lock when the process ends,
    however it ends. `StoreError` if another process holds it."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock (the project is tested on Linux)
        return None
    fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise StoreError(f"store {path} is being written by another sweep; wait for it or "
                         "give another --store") from None
    return _Lock(fd)


def _remove_unfinished(path: Path) -> None:
    """Remove what a killed process left beside the store ``path``: half-made stores of a
    creation (``.NAME.creating-PID``), a replaced store not yet deleted
    (``.NAME.replaced-PID``), half-made or replaced groups (``.NAME.group-PID``,
    ``.NAME.group-old-PID``; `Store.put_dataset`), each of a process that is gone: never a
    store or a group, which are only ever renamed into place complete."""
    for kind in ("creating", "replaced", "group"):
        for tmp in path.parent.glob(f".{path.name}.{kind}-*"):
            try:
                pid = int(tmp.name.rpartition("-")[2])
                os.kill(pid, 0)
            except ValueError:
                continue
            except ProcessLookupError:
                shutil.rmtree(tmp, ignore_errors=True)
            except OSError:  # alive, another user's
                continue


def consolidate(path: str | Path) -> None:
    """Write the consolidated metadata of the store at ``path`` (every array's metadata, read
    from its own ``zarr.json``, into the root ``zarr.json``, which is replaced whole): what
    ``xarray.open_zarr`` reads first, and without which it warns on every open.

    Zarr v3 has no consolidated metadata in its specification yet; zarr-python writes its
    own form and warns that other implementations may ignore it. They then read the arrays'
    own ``zarr.json`` files, which stay as they are, so the warning is not passed on.
    """
    zarr = _zarr()
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Consolidated metadata is currently not "
                                "part in the Zarr format 3 specification")
        zarr.consolidate_metadata(str(path), zarr_format=3)


def consolidated(path: str | Path) -> bool:
    """True when the store at ``path`` holds consolidated metadata (`consolidate`)."""
    try:
        meta = json.loads((Path(path) / "zarr.json").read_text())
    except (OSError, ValueError):
        return False
    return bool((meta.get("consolidated_metadata") or {}).get("metadata"))


def _zarr():
    try:
        import xarray  # noqa: F401 - readers need it; say so before anything is written
        import zarr
    except ImportError as exc:
        raise StoreError(f"the sweep store needs zarr and xarray ({exc}): pip install -e "
                         "'.[sweep]'") from None
    return zarr


def engine_version() -> str:
    """The package version and a digest of the code that decides a point's results: the
    fast engine (`gearpair.jitcache.engine_files`, numba's version) and the physics and
    analysis modules. A store written by another is refused on resume."""
    from .. import __version__, jitcache

    here = Path(__file__).resolve().parents[1]
    h = hashlib.sha1(str(jitcache.KEY).encode())
    for name in _PHYSICS:
        try:
            h.update((here / name).read_bytes())
        except OSError:
            h.update(name.encode())
    return f"{__version__}+{h.hexdigest()[:12]}"


def _settings_json(settings: SweepSettings) -> dict[str, Any]:
    d = asdict(settings)
    d["params"] = [list(p) for p in settings.params]
    return d


def _settings_from_json(d: dict[str, Any], path: Path) -> SweepSettings:
    """The settings a store recorded. One this gearpair has not (e.g. an effect since
    renamed) is refused naming it; one the store lacks (an effect added since) takes its
    default, which the resume check then compares like any other."""
    d = dict(d)
    d["params"] = tuple(tuple(p) for p in d.get("params", ()))
    unknown = sorted(set(d) - {f.name for f in fields(SweepSettings)})
    if unknown:
        raise StoreError(f"store {path} holds another sweep: "
                         + "; ".join(f"{k} = {d[k]!r} in the store, no such setting now"
                                     for k in unknown)
                         + " (--new-store replaces it, or give another --store)")
    return SweepSettings(**d)


def kmax(settings: SweepSettings) -> int:
    """Most Poincare samples a point can have (the kept periods, made even)."""
    return settings.kept_periods + settings.kept_periods % 2


class StoreError(ValueError):
    """A store that cannot be used as asked (one line, for the command's exit status 2)."""


class Store:
    """An open sweep store (see the module docstring): create, check and resume, write points.

    Use `Store.open_or_create`; the points are written with `write`.
    """

    def __init__(self, path: Path, group, grid: Grid, settings: SweepSettings) -> None:
        self.path, self.group, self.grid, self.settings = path, group, grid, settings
        # a swept name (speed_rpm, mu) is a coordinate, not a variable
        self.numeric = tuple(n for n in NUMERIC if n not in grid.names)
        self._arrays = {name: group[name] for name in (*self.numeric, "status", *_TEXT,
                                                        "poincare", "poincare_count", "done")}

    # -- creation and checks ------------------------------------------------------------
    @classmethod
    def open_or_create(cls, path: str | Path, grid: Grid, settings: SweepSettings, *,
                       new: bool = False) -> Store:
        """Open the store at ``path`` for this sweep, or create it.

        An existing store must hold the same grid, settings and engine version (else
        `StoreError` naming the difference); ``new`` replaces it by an empty one instead
        (the user asked). A path that is not a store, a store of another layout version, or
        a folder that cannot be written: `StoreError`.
        """
        path = Path(path)
        if path.exists() and not new:
            store = cls.open(path, mode="r+")
            diff = store.differences(grid, settings)
            if diff:
                raise StoreError(f"store {path} holds another sweep: {'; '.join(diff)} "
                                 "(--new-store replaces it, or give another --store)")
            return store
        return cls._create(path, grid, settings, replace_old=path.exists())

    @classmethod
    def open(cls, path: str | Path, mode: str = "r") -> Store:
        """An existing store (``mode`` ``"r"`` or ``"r+"``); `StoreError` when it is none."""
        zarr = _zarr()

        path = Path(path)
        meta = path / "zarr.json"
        if not path.is_dir() or not meta.is_file():
            what = "is a file" if path.is_file() else "is not a gearpair sweep store"
            raise StoreError(f"store {path} {what} (no zarr.json); give a new path or a "
                             "store that a sweep wrote")
        try:
            attrs = json.loads(meta.read_text()).get("attributes", {})
        except (OSError, ValueError) as exc:
            raise StoreError(f"store {path}: cannot read zarr.json ({exc})") from None
        fmt = attrs.get("gearpair_store")
        if fmt != FORMAT:
            raise StoreError(f"store {path} was written by an incompatible version (store "
                             f"format {fmt}; this gearpair reads format {FORMAT})")
        if mode == "r+" and not os.access(path, os.W_OK):
            raise StoreError(f"store {path} is not writable")
        lock = _lock(path) if mode == "r+" else None
        group = zarr.open_group(path, mode=mode, zarr_format=3)
        grid = Grid.from_json(attrs["grid"])
        settings = _settings_from_json(attrs["settings"], path)
        store = cls(path, group, grid, settings)
        store._lock = lock  # held while this object lives (and released when the process dies)
        return store

    def differences(self, grid: Grid, settings: SweepSettings) -> list[str]:
        """What differs between this store and the sweep ``grid`` at ``settings``: the grid,
        each setting, the engine version (empty when the store can be resumed)."""
        out = []
        if grid != self.grid:
            out.append(f"grid {self.grid.describe()} in the store, {grid.describe()} now"
                       if grid.describe() != self.grid.describe()
                       else f"grid values of {', '.join(grid.names)} differ")
        for f in fields(SweepSettings):
            a, b = getattr(self.settings, f.name), getattr(settings, f.name)
            if a != b:
                out.append(f"{f.name} = {a!r} in the store, {b!r} now")
        have = self.group.attrs.get("engine_version")
        now = engine_version()
        if have != now:
            out.append(f"engine version {have} in the store, {now} now")
        return out

    @classmethod
    def _create(cls, path: Path, grid: Grid, settings: SweepSettings,
                replace_old: bool) -> Store:
        zarr = _zarr()

        path = path.absolute()
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StoreError(f"store {path}: cannot create its folder {path.parent} "
                             f"({exc.strerror or exc})") from None
        old = None
        if replace_old:  # only a store is ever replaced, never another folder or file,
            old = cls.open(path, mode="r+")  # and not one that another sweep is writing
        _remove_unfinished(path)
        tmp = path.parent / f".{path.name}.creating-{os.getpid()}"
        try:
            if tmp.exists():
                shutil.rmtree(tmp)
            group = zarr.open_group(tmp, mode="w-", zarr_format=3)
        except OSError as exc:
            raise StoreError(f"store {path}: cannot write in {path.parent} "
                             f"({exc.strerror or exc})") from None
        try:
            _layout(group, grid, settings)
            consolidate(tmp)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        if replace_old:  # the old one goes only once the new one is complete
            trash = path.parent / f".{path.name}.replaced-{os.getpid()}"
            os.rename(path, trash)
            os.rename(tmp, path)
            shutil.rmtree(trash, ignore_errors=True)
            del old
        else:
            os.rename(tmp, path)
        return cls.open(path, mode="r+")

    def close(self) -> None:
        """Release the writer lock (also released when the object goes or the process
        ends)."""
        lock, self._lock = getattr(self, "_lock", None), None
        if lock is not None:
            lock.close()

    # -- state ------------------------------------------------------------------------------
    def done(self) -> np.ndarray:
        """1 where a point's record is complete, over the grid's shape."""
        return np.asarray(self._arrays["done"][...])

    def status(self) -> np.ndarray:
        return np.asarray(self._arrays["status"][...])

    def todo(self, rerun_failed: bool = False) -> list[int]:
        """Indexes of the points to run: not done, and with ``rerun_failed`` also the failed
        and invalid ones."""
        done = self.done().ravel() == 1
        if rerun_failed:
            done &= self.status().ravel() == STATUS.index("ok")
        return [int(i) for i in np.flatnonzero(~done)]

    def counts(self) -> dict[str, int]:
        """Points done (ok, failed, invalid) and not run."""
        done = self.done().ravel() == 1
        st = self.status().ravel()
        out = {s: int(np.sum(done & (st == k))) for k, s in enumerate(STATUS) if k}
        out["not_run"] = int(np.sum(~done))
        return out

    # -- writing ----------------------------------------------------------------------------
    def write(self, rec: dict[str, Any]) -> None:
        """Store one finished point (a `run_point` record), ``done`` last."""
        self.write_many([rec])

    def write_many(self, recs: list[dict[str, Any]]) -> None:
        """Store finished points (`run_point` records) at once: each variable's chunks are
        written once for all of them, the variables side by side, ``done`` after them."""
        if not recs:
            return
        from zarr.core.sync import sync

        nd = np.unravel_index(np.array([int(r["index"]) for r in recs]), self.grid.shape)
        a = self._arrays
        values: dict[str, Any] = {}
        for name in self.numeric:
            col = [r.get(name, math.nan) for r in recs]
            if name in _INT:
                col = [-1 if x is None or (isinstance(x, float) and math.isnan(x)) else int(x)
                       for x in col]
            values[name] = np.asarray(col, dtype=a[name].dtype)
        values["status"] = np.array([STATUS.index(r["status"]) for r in recs], dtype="int8")
        for name in _TEXT:
            values[name] = np.array([str(r.get(name, "")) for r in recs], dtype=object)
        k = a["poincare"].shape[-1]
        sec = np.full((len(recs), k), np.nan)
        counts = np.zeros(len(recs), dtype="int32")
        for j, r in enumerate(recs):
            p = np.asarray(r.get("poincare", []), dtype=float)[:k]
            sec[j, : p.size] = p
            counts[j] = p.size
        values["poincare_count"] = counts
        cols = np.broadcast_to(np.arange(k), sec.shape)
        sel_sec = tuple(np.broadcast_to(i[:, None], sec.shape) for i in nd) + (cols,)

        targets = {n: (nd, v) for n, v in values.items()}
        targets["poincare"] = (sel_sec, sec.reshape(-1))  # coordinate values go flat

        async def put(names: list[str]) -> None:
            # every variable's chunks at once on zarr's event loop (its async array API):
            # a batch costs about what one point costs written variable by variable
            from zarr.core.buffer import default_buffer_prototype
            from zarr.core.indexing import CoordinateIndexer

            proto = default_buffer_prototype()
            await asyncio.gather(*(
                a[n]._async_array._set_selection(
                    CoordinateIndexer(targets[n][0], a[n].shape, a[n].metadata.chunk_grid),
                    targets[n][1], prototype=proto) for n in names))

        sync(put(list(targets)))
        targets["done"] = (nd, np.ones(len(recs), dtype="int8"))
        sync(put(["done"]))  # last: the records are complete


    def add_run(self, info: dict[str, Any]) -> None:
        """Append a run's cost (wall time, points, workers ...) to the store's ``runs``."""
        runs = list(self.group.attrs.get("runs", []))
        runs.append(info)
        self.group.attrs["runs"] = runs
        consolidate(self.path)  # the new attributes (and a store that had none gets it)

    def put_dataset(self, name: str, ds) -> None:
        """Write the ``xarray.Dataset`` ``ds`` into the store as its group ``name``
        (``xr.open_zarr(path, group=name)`` reads it), replacing a group of that name, whole
        or not at all: it is written as a Zarr store beside this one, renamed into place
        (the old group renamed away first, then deleted), and the consolidated metadata
        rewritten. A killed process leaves the old group or the new one (and what it left
        beside the store goes at the next creation or `put_dataset`)."""
        if not name.isidentifier() or name in self.group.array_keys():
            raise StoreError(f"store {self.path}: {name!r} cannot be a group's name here")
        _remove_unfinished(self.path)
        pid = os.getpid()
        tmp = self.path.parent / f".{self.path.name}.group-{pid}"
        old = self.path.parent / f".{self.path.name}.group-old-{pid}"
        for p in (tmp, old):
            shutil.rmtree(p, ignore_errors=True)
        try:
            ds.to_zarr(tmp, mode="w-", zarr_format=3, consolidated=False)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        dest = self.path / name
        if dest.exists():
            os.rename(dest, old)
        os.rename(tmp, dest)
        shutil.rmtree(old, ignore_errors=True)
        consolidate(self.path)

    # -- reading ----------------------------------------------------------------------------
    def records(self) -> list[dict[str, Any]]:
        """The stored points as `run_point` records (index order; points not done have
        ``status = not_run``)."""
        a = {k: np.asarray(v[...]).ravel() for k, v in self._arrays.items()
             if k != "poincare"}
        pc = np.asarray(self._arrays["poincare"][...]).reshape(self.grid.size, -1)
        s = self.settings
        out = []
        for i, point in self.grid.points():
            rec: dict[str, Any] = {
                "index": i, "param": ",".join(self.grid.names),
                "value": point[self.grid.names[0]] if len(point) == 1 else tuple(point.values()),
                "status": STATUS[int(a["status"][i])] if a["done"][i] else "not_run",
                "friction": s.friction, "stick_tie": s.stick_tie, "sliding": s.sliding,
                **{n: point[n] for n in NUMERIC if n in point}}
            for name in self.numeric:
                x = a[name][i]
                rec[name] = (int(x) if x >= 0 else math.nan) if name in _INT else float(x)
            for name in _TEXT:
                rec[name] = str(a[name][i])
            rec["poincare"] = [float(x) for x in pc[i, : int(a["poincare_count"][i])]]
            out.append(rec)
        return out


def chunk_shape(shape: tuple[int, ...], most: int = CHUNK_POINTS) -> tuple[int, ...]:
    """Chunks of at most ``most`` neighbouring points: whole trailing dimensions first."""
    out = [1] * len(shape)
    room = most
    for d in range(len(shape) - 1, -1, -1):
        out[d] = max(1, min(shape[d], room))
        room //= out[d]
        if room <= 1:
            break
    return tuple(out)


def _layout(group, grid: Grid, settings: SweepSettings) -> None:
    """Create every array of the store (fill values only; one chunk per point)."""
    from .. import __version__

    shape, dims = grid.shape, grid.dims
    one = chunk_shape(shape)
    units = sweepable()
    if grid.kind == "product":
        for name, vals in zip(grid.names, grid.values, strict=True):
            c = group.create_array(name, shape=(len(vals),), dtype="float64",
                                   dimension_names=(name,),
                                   attributes={"units": units[name],
                                               "long_name": long_name(name)})
            c[...] = np.asarray(vals)
        coords = ""
    else:
        for name, vals in zip(grid.names, grid.values, strict=True):
            c = group.create_array(name, shape=shape, dtype="float64", dimension_names=dims,
                                   attributes={"units": units[name],
                                               "long_name": long_name(name)})
            c[...] = np.asarray(vals)
        idx = group.create_array("point", shape=shape, dtype="int64", dimension_names=dims,
                                 attributes={"long_name": "number of the point (its index)"})
        idx[...] = np.arange(grid.size)
        coords = " ".join(grid.names)

    def arr(name, dtype, fill, extra=(), **attrs):
        if coords:
            attrs["coordinates"] = coords
        return group.create_array(name, shape=shape + tuple(n for _, n in extra),
                                  chunks=one + tuple(n for _, n in extra), dtype=dtype,
                                  fill_value=fill,
                                  dimension_names=dims + tuple(d for d, _ in extra),
                                  attributes=attrs)

    for name in NUMERIC:
        if name in grid.names:
            continue
        unit, said = DESCRIPTION[name]
        if name in _INT:
            arr(name, "int32", -1, units=unit, long_name=said, missing="-1")
        else:
            arr(name, "float64", math.nan, units=unit, long_name=said)
    arr("status", "int8", 0, long_name="outcome of the point",
        flag_values=list(range(len(STATUS))), flag_meanings=" ".join(STATUS))
    arr("error", str, "", long_name="why the point is not ok (empty when it is)")
    arr("worker", str, "", long_name="worker that ran the point (host:process id)")
    arr("poincare", "float64", math.nan, extra=(("section", kmax(settings)),), units="m",
        long_name="DTE at the Poincare section, one sample per kept mesh period (NaN pads)")
    arr("poincare_count", "int32", 0, units="1", long_name="number of Poincare samples")
    arr("done", "int8", 0, long_name="1 once the point's record is complete")
    group.attrs.update({
        "gearpair_store": FORMAT, "gearpair_version": __version__,
        "engine_version": engine_version(), "grid": grid.to_json(),
        "settings": _settings_json(settings), "created": time.strftime(
            "%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "title": f"gearpair sweep: {grid.describe()}", "runs": []})


def open_dataset(path: str | Path):
    """The store at ``path`` as an ``xarray.Dataset`` (lazy; `StoreError` if it is no sweep
    store of this layout version). Through the consolidated metadata where the store has it
    (`consolidate`), else array by array (a store written before it had any), without a
    warning either way."""
    import xarray as xr

    Store.open(path)  # the checks, one line each
    return xr.open_zarr(path, consolidated=consolidated(path), zarr_format=3,
                        mask_and_scale=False)
