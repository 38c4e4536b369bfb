"""Global sensitivity analysis (Sobol with Saltelli sampling, Morris) on the sweep machinery.

The SALib sample is a `Grid` of ``kind = "points"`` and runs through `run_grid` into a sweep
`Store`: a killed study resumes with the same call (the sample is fixed by ``seed``), a lost
worker loses nothing and ``scheduler`` runs it on a dask cluster. The indices are computed
from the stored figures of the points (any numeric sweep column, e.g. ``stick_ratio``) and
returned as an ``xarray.Dataset``, also written next to the store
(``<store>.sensitivity.zarr``).

Uniform distributions only for now: every range is ``lo:hi`` in the parameter's own unit.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from .grid import Grid, _check_name
from .point import COLUMNS, _blank
from .settings import SweepSettings

METHODS = ("sobol", "morris")
DEFAULT_OUTPUTS = ("stick_ratio", "contact_loss_ratio")
# figures a point records that are not inputs, bookkeeping or cost: the allowed outputs
_NOT_OUTPUTS = {"index", "param", "value", "status", "error", "attempts", "rtol", "friction",
                "stick_tie", "sliding", "worker", "wall_s", "cpu_s", "speed_rpm", "torque_nm",
                "mu"}
OUTPUTS = tuple(c for c in COLUMNS if c not in _NOT_OUTPUTS)
HOOK_FLUSH_S = 0.5  # a serial run under `model_hook` stores its points this often (s)


def parse_ranges(specs: list[str]) -> dict[str, tuple[float, float]]:
    """``["mu=0.01:0.05", "torque=1000:4000"]`` as ``{name: (lo, hi)}``.

    Parameters
    ----------
    specs : ``NAME=LO:HI`` with NAME a sweepable parameter (``speed_rpm`` in r/min,
        ``torque`` in N.m, or a `GearParams` field in SI units)

    Raises ``ValueError`` naming the parameter for a bad spec or ``lo >= hi``.
    """
    out: dict[str, tuple[float, float]] = {}
    for s in specs:
        name, sep, text = s.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ValueError(f"{s!r}: use NAME=LO:HI, e.g. mu=0.01:0.05")
        _check_name(name)
        if name in out:
            raise ValueError(f"parameter {name} is given twice")
        parts = text.split(":")
        try:
            lo, hi = (float(p) for p in parts) if len(parts) == 2 else (math.nan, math.nan)
        except ValueError:
            lo = hi = math.nan
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise ValueError(f"{name}={text}: use {name}=LO:HI with two numbers")
        if not lo < hi:
            raise ValueError(f"{name}={text}: LO must be < HI")
        out[name] = (lo, hi)
    if len(out) < 2:
        raise ValueError("give at least two parameters NAME=LO:HI")
    return out


def _problem(ranges: Mapping[str, tuple[float, float]]) -> dict[str, Any]:
    return {"num_vars": len(ranges), "names": list(ranges),
            "bounds": [list(map(float, b)) for b in ranges.values()]}


def sample(ranges: Mapping[str, tuple[float, float]], method: str = "sobol", n: int = 256, *,
           second_order: bool = False, levels: int = 4, seed: int = 1) -> np.ndarray:
    """The SALib sample (rows: points, columns: parameters in the order of ``ranges``).

    ``n`` is the base sample size: Sobol runs ``n (D + 2)`` points (``n (2D + 2)`` with
    ``second_order``; a power of two keeps the Sobol sequence balanced), Morris ``n (D + 1)``
    (``n`` trajectories of ``levels`` levels). The same arguments give the same sample,
    which is what makes a study resumable.
    """
    if method not in METHODS:
        raise ValueError(f"method {method!r}: choose one of {', '.join(METHODS)}")
    if not isinstance(n, int | np.integer) or n < 2:
        raise ValueError(f"n = {n!r}: the base sample size must be a whole number >= 2")
    problem = _problem(ranges)
    if method == "sobol":
        if n & (n - 1):
            raise ValueError(f"n = {n}: Sobol needs a power of two (e.g. 256, 1024)")
        from SALib.sample import sobol as s_sobol

        return s_sobol.sample(problem, n, calc_second_order=second_order, scramble=True,
                              seed=seed)
    from SALib.sample import morris as s_morris

    return s_morris.sample(problem, n, num_levels=levels, seed=seed)


@contextmanager
def model_hook(func: Callable[[dict[str, float]], Mapping[str, float]]):
    """Replace the gear model of every point by ``func`` (tests: known answers).

    ``func({name: value})`` returns ``{output: value}``; the record keeps the machinery's
    other columns. Serial runs only: the hook patches this process, not dask workers. Its
    points take microseconds, so while it is on a serial run hands them to the store in
    batches (at most every `HOOK_FLUSH_S` seconds) rather than one by one.
    """
    from . import run as run_mod

    def fake(index, name, value, settings, rtol=None, attempt=1):
        rec = _blank(index, name, value, settings)
        point = dict(zip(name, value, strict=True)) if isinstance(name, tuple) \
            else {name: value}
        rec.update(func(point))
        rec["status"] = "ok"
        return rec

    saved = run_mod.run_point, run_mod._warm, run_mod.SERIAL_FLUSH_S
    run_mod.run_point, run_mod._warm = fake, lambda: None
    run_mod.SERIAL_FLUSH_S = HOOK_FLUSH_S
    try:
        yield
    finally:
        run_mod.run_point, run_mod._warm, run_mod.SERIAL_FLUSH_S = saved


def run_sensitivity(ranges: Mapping[str, tuple[float, float]] | list[str],
                    method: str = "sobol", n: int = 256,
                    outputs: tuple[str, ...] | list[str] = DEFAULT_OUTPUTS,
                    settings: SweepSettings | None = None,
                    store: str | Path = "sensitivity.zarr", *, second_order: bool = False,
                    levels: int = 4, seed: int = 1, conf_level: float = 0.95,
                    scheduler: str | None = None, workers: int | None = None,
                    new_store: bool = False, progress: bool = True, stream=None):
    """Sobol or Morris indices of ``outputs`` over ``ranges``, through a sweep store.

    Parameters
    ----------
    ranges : ``{name: (lo, hi)}`` or specs ``["mu=0.01:0.05", ...]`` (`parse_ranges`);
        uniform over each range, in the parameter's unit (r/min, N.m, SI)
    method : ``"sobol"`` (Saltelli sampling) or ``"morris"``
    n : base sample size (see `sample`)
    outputs : stored figures of a point (`OUTPUTS`), e.g. ``stick_ratio`` (-)
    settings : held inputs, effects and durations (`SweepSettings`)
    store : the Zarr store of the points (resumed when it holds this sample)
    second_order : Sobol second-order indices ``S2`` too
    levels : Morris grid levels; seed : the sample's seed
    conf_level : level of the confidence intervals (bootstrap)
    scheduler, workers, new_store, progress, stream : as in `run_grid`

    Returns
    -------
    xarray.Dataset
        dims ``output`` x ``param``: Sobol ``S1``, ``S1_conf``, ``ST``, ``ST_conf`` (half
        widths of the intervals; ``S2``, ``S2_conf`` over ``param`` x ``param2`` when
        asked), Morris ``mu_star``, ``mu_star_conf``, ``sigma``; attrs: method, n, points.
        Also written to ``<store>.sensitivity.zarr``.
    """
    from .store import STATUS, open_dataset
    from .study import run_grid

    if not isinstance(ranges, Mapping):
        ranges = parse_ranges(list(ranges))
    outputs = tuple(outputs)
    for o in outputs:
        if o not in OUTPUTS:
            raise ValueError(f"output {o!r}: choose from {', '.join(OUTPUTS)}")
    if not outputs:
        raise ValueError("give at least one output")
    if not 0 < conf_level < 1:
        raise ValueError(f"conf_level = {conf_level!r}: must be in (0, 1)")
    x = sample(ranges, method, n, second_order=second_order, levels=levels, seed=seed)
    names = tuple(ranges)
    grid = Grid(names, tuple(tuple(float(v) for v in x[:, j]) for j in range(len(names))),
                "points")
    run_grid(grid, settings, store, scheduler=scheduler, workers=workers, new_store=new_store,
             progress=progress, stream=stream)
    ds = open_dataset(store)
    status = np.asarray(ds["status"].values)
    bad = int(np.count_nonzero(status != STATUS.index("ok")))
    if bad:
        raise ValueError(f"{bad} of {grid.size} points are not ok in {store} (failed, "
                         "invalid or not run): the indices need every point; narrow the "
                         "ranges or run the same command again")
    return _analyse(ranges, method, x, {o: np.asarray(ds[o].values, float) for o in outputs},
                    n, second_order, conf_level, seed, store)


def _analyse(ranges, method, x, ys, n, second_order, conf_level, seed, store):
    import xarray as xr

    problem = _problem(ranges)
    names = list(ranges)
    outs = list(ys)
    res = []
    for o in outs:
        y = ys[o]
        if not np.all(np.isfinite(y)):
            raise ValueError(f"output {o}: {np.count_nonzero(~np.isfinite(y))} points have no "
                             "value; choose another output")
        if method == "sobol":
            from SALib.analyze import sobol as a_sobol

            res.append(a_sobol.analyze(problem, y, calc_second_order=second_order,
                                       conf_level=conf_level, seed=seed))
        else:
            from SALib.analyze import morris as a_morris

            res.append(a_morris.analyze(problem, x, y, conf_level=conf_level, seed=seed))
    keys = ("S1", "S1_conf", "ST", "ST_conf") if method == "sobol" \
        else ("mu_star", "mu_star_conf", "sigma")
    data = {k: (("output", "param"), np.array([np.asarray(r[k], float) for r in res]))
            for k in keys}
    if method == "sobol" and second_order:
        for k in ("S2", "S2_conf"):
            data[k] = (("output", "param", "param2"),
                       np.array([np.asarray(r[k], float) for r in res]))
    ds = xr.Dataset(data, coords={"output": outs, "param": names,
                                  **({"param2": names} if "S2" in data else {})})
    _describe(ds, conf_level)
    ds.attrs.update(method=method, n=int(n), points=int(x.shape[0]),
                    conf_level=float(conf_level), seed=int(seed), store=str(store),
                    ranges=str({k: list(v) for k, v in ranges.items()}))
    # Zarr v2: v3 has no spec for the string coordinates nor consolidated metadata (warnings)
    ds.to_zarr(sensitivity_path(store), mode="w", zarr_format=2, consolidated=True)
    return ds


# what each index is (its ``long_name``); the Sobol indices are fractions of the variance
# (units "1"), Morris's are in the unit of the output, which differs along ``output``
_SAID = {"S1": "first-order Sobol index", "ST": "total Sobol index",
         "S2": "second-order Sobol index (param with param2)",
         "mu_star": "Morris mu*: mean absolute elementary effect (output unit)",
         "sigma": "Morris sigma: standard deviation of the elementary effects (output unit)"}


def _describe(ds, conf_level: float) -> None:
    """Give the indices and coordinates of ``ds`` long names (and units where they have one)."""
    for k in list(ds.data_vars):
        base = k.removesuffix("_conf")
        said = _SAID[base] if k == base else \
            f"half width of the {100 * conf_level:g} % confidence interval of {base}"
        ds[k].attrs["long_name"] = said
        if base.startswith("S"):
            ds[k].attrs["units"] = "1"
    ds["output"].attrs["long_name"] = "figure of a sweep point (a variable of the store)"
    ds["param"].attrs["long_name"] = "parameter varied"
    if "param2" in ds.coords:
        ds["param2"].attrs["long_name"] = "second parameter of a second-order index"


def sensitivity_path(store: str | Path) -> Path:
    """Where the indices of the points in ``store`` are written."""
    p = Path(store)
    return p.with_name(p.name.removesuffix(".zarr") + ".sensitivity.zarr")


def plot_indices(ds, path: str | Path) -> Path:
    """Bar chart of the indices with their confidence intervals, one panel per output."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = ("S1", "ST") if "S1" in ds else ("mu_star",)
    outs = list(ds["output"].values)
    fig, axes = plt.subplots(len(outs), 1, figsize=(7, 2.6 * len(outs)), squeeze=False)
    names = list(ds["param"].values)
    xs = np.arange(len(names))
    w = 0.8 / len(keys)
    for ax, o in zip(axes[:, 0], outs, strict=True):
        for k, key in enumerate(keys):
            ax.bar(xs + (k - (len(keys) - 1) / 2) * w, ds[key].sel(output=o).values, w,
                   yerr=ds[f"{key}_conf"].sel(output=o).values, capsize=3, label=key)
        ax.set_xticks(xs, names)
        ax.set_title(f"{o} ({ds.attrs['method']}, n = {ds.attrs['n']})")
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
