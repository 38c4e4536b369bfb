"""Global sensitivity analysis (Sobol with Saltelli sampling, Morris) on the sweep machinery.

The SALib sample is a `Grid` of ``kind = "points"`` and runs through `run_grid` into a sweep
`Store`: a killed study resumes with the same call (the sample is fixed by ``seed``), a lost
worker loses nothing and ``scheduler`` runs it on a dask cluster. The indices are computed
from the stored figures of the points (any numeric sweep column, e.g. ``stick_ratio``),
returned as an ``xarray.Dataset`` and written into the same store as its group
``sensitivity`` (`GROUP`; `open_indices`), beside the points.

Each parameter has a distribution (`Dist`), in SALib's names and bounds conventions: uniform
``lo:hi`` by default, or ``norm:MEAN:SD``, ``lognorm:LN_MEAN:LN_SD``, ``triang:LO:HI:PEAK``,
``truncnorm:LO:HI:MEAN:SD``, ``logunif:LO:HI``, ``weibull:SHAPE:SCALE[:LOC]`` (Sobol only;
Morris's elementary effects are steps on a uniform grid).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .grid import Grid, _check_name
from .point import COLUMNS, _blank
from .settings import SweepSettings

METHODS = ("sobol", "morris")
DEFAULT_OUTPUTS = ("stick_ratio", "contact_loss_ratio")
GROUP = "sensitivity"  # the store's group that holds the indices
# figures a point records that are not inputs, bookkeeping or cost: the allowed outputs
_NOT_OUTPUTS = {"index", "param", "value", "status", "error", "attempts", "rtol", "friction",
                "stick_tie", "sliding", "worker", "wall_s", "cpu_s", "speed_rpm", "torque_nm",
                "mu"}
OUTPUTS = tuple(c for c in COLUMNS if c not in _NOT_OUTPUTS)
HOOK_FLUSH_S = 0.5  # a serial run under `model_hook` stores its points this often (s)

# SALib's distributions (SALib.util._nonuniform_scale_samples): the numbers of each, in the
# order of its "bounds"; weibull's location may be left out (0)
DISTS = {
    "unif": ("LO", "HI"),
    "logunif": ("LO", "HI"),
    "triang": ("LO", "HI", "PEAK"),
    "norm": ("MEAN", "SD"),
    "truncnorm": ("LO", "HI", "MEAN", "SD"),
    "lognorm": ("LN_MEAN", "LN_SD"),
    "weibull": ("SHAPE", "SCALE", "LOC"),
}
_SPECS = ("LO:HI (uniform), " + ", ".join(f"{k}:{':'.join(v)}" for k, v in DISTS.items()
                                            if k != "unif")).replace(":LOC", "[:LOC]")


@dataclass(frozen=True)
class Dist:
    """A parameter's distribution in SALib's conventions (``problem["dists"]``, ``bounds``).

    Attributes
    ----------
    kind : ``unif`` (``LO, HI``), ``logunif`` (``LO, HI``, both > 0), ``triang`` (``LO, HI,
        PEAK``; PEAK is where the mode lies as a fraction of the width, in [0, 1)), ``norm``
        (``MEAN, SD``), ``truncnorm`` (``LO, HI, MEAN, SD``: the normal distribution cut to
        [LO, HI]), ``lognorm`` (``LN_MEAN, LN_SD``: the mean and standard deviation of the
        natural log of the value), ``weibull`` (``SHAPE, SCALE[, LOC]``)
    args : the numbers, in the parameter's unit (r/min, N.m, SI) except PEAK, LN_SD and
        SHAPE (dimensionless) and LN_MEAN (log of the unit)
    """

    kind: str
    args: tuple[float, ...]

    @classmethod
    def parse(cls, name: str, text: str) -> Dist:
        """``"0.01:0.05"`` (uniform) or ``"norm:0.03:0.005"`` for parameter ``name``;
        ``ValueError`` naming the parameter for a bad spec."""
        parts = [p.strip() for p in text.split(":")]
        kind = "unif" if parts and _is_number(parts[0]) else parts[0].lower()
        if kind not in DISTS:
            raise ValueError(f"{name}={text}: unknown distribution {parts[0]!r}; use "
                             f"{name}={_SPECS}")
        nums = parts if kind == "unif" and _is_number(parts[0]) else parts[1:]
        try:
            args = tuple(float(p) for p in nums)
        except ValueError:
            args = ()
        return cls.make(name, kind, args, text)

    @classmethod
    def make(cls, name: str, kind: str, args, text: str | None = None) -> Dist:
        """The distribution ``kind`` with ``args`` for ``name``, checked (`ValueError` naming
        the parameter, its spec and what is wrong)."""
        args = tuple(float(a) for a in args)
        d = cls(kind, args)
        said = f"{name}={text if text is not None else d.spec}"
        want = DISTS.get(kind)
        if want is None:
            raise ValueError(f"{said}: unknown distribution {kind!r}; use {name}={_SPECS}")
        usage = f"{name}={'LO:HI' if kind == 'unif' else kind + ':' + ':'.join(want)}"
        if kind == "weibull":
            usage = usage.replace(":LOC", "[:LOC]")
        least = len(want) - (kind == "weibull")
        if not least <= len(args) <= len(want) or not all(map(math.isfinite, args)):
            raise ValueError(f"{said}: use {usage} with {least} numbers"
                             + (" (LOC optional)" if kind == "weibull" else ""))
        why = d._wrong()
        if why:
            raise ValueError(f"{said}: {why} ({usage})")
        return d

    def _wrong(self) -> str | None:
        a, k = self.args, self.kind
        if k in ("unif", "logunif", "triang", "truncnorm") and not a[0] < a[1]:
            return "LO must be < HI"
        if k == "logunif" and a[0] <= 0:
            return "LO must be > 0"
        if k == "triang" and not 0 <= a[2] < 1:
            return "PEAK is the mode's place as a fraction of the width: 0 <= PEAK < 1"
        if k in ("norm", "lognorm") and a[1] <= 0:
            return f"{DISTS[k][1]} must be > 0"
        if k == "truncnorm" and a[3] <= 0:
            return "SD must be > 0"
        if k == "weibull" and (a[0] <= 0 or a[1] <= 0):
            return "SHAPE and SCALE must be > 0"
        return None

    @property
    def spec(self) -> str:
        """The text form: ``0.01:0.05`` for uniform, else ``norm:0.03:0.005``."""
        nums = ":".join(f"{a:g}" for a in self.args)
        return f"unif:{nums}" if self.kind == "unif" else f"{self.kind}:{nums}"

    @property
    def bounds(self) -> list[float]:
        """SALib's ``bounds`` entry (triang's start given: the three-number form)."""
        return list(self.args)

    def frozen(self):
        """The same distribution as a frozen ``scipy.stats`` one (its moments, support)."""
        from scipy import stats

        a, k = self.args, self.kind
        if k == "unif":
            return stats.uniform(loc=a[0], scale=a[1] - a[0])
        if k == "logunif":
            return stats.loguniform(a[0], a[1])
        if k == "triang":
            return stats.triang(a[2], loc=a[0], scale=a[1] - a[0])
        if k == "norm":
            return stats.norm(loc=a[0], scale=a[1])
        if k == "truncnorm":
            return stats.truncnorm((a[0] - a[2]) / a[3], (a[1] - a[2]) / a[3], loc=a[2],
                                   scale=a[3])
        if k == "lognorm":
            return stats.lognorm(a[1], scale=math.exp(a[0]))
        return stats.weibull_min(a[0], scale=a[1], loc=a[2] if len(a) > 2 else 0.0)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def as_dists(ranges) -> dict[str, Dist]:
    """``{name: Dist}`` from specs ``["mu=0.01:0.05", "torque=norm:2500:400"]`` or a mapping
    of names to a `Dist`, a ``(lo, hi)`` pair (uniform) or a spec's text (``"norm:0.03:0.005"``).

    ``ValueError`` naming the parameter for an unknown name, a bad spec, a parameter given
    twice, or fewer than two parameters.
    """
    if not isinstance(ranges, Mapping):
        return parse_ranges(list(ranges))
    out: dict[str, Dist] = {}
    for name, d in ranges.items():
        _check_name(name)
        if isinstance(d, str):
            d = Dist.parse(name, d)
        elif not isinstance(d, Dist):
            try:
                lo, hi = (float(x) for x in d)
            except (TypeError, ValueError):
                raise ValueError(f"{name}: give (LO, HI), a Dist or a spec such as "
                                 f"'norm:0.03:0.005', not {d!r}") from None
            d = Dist.make(name, "unif", (lo, hi), f"{lo:g}:{hi:g}")
        out[name] = d
    if len(out) < 2:
        raise ValueError("give at least two parameters NAME=LO:HI (or NAME=DIST:...)")
    return out


def parse_ranges(specs: list[str]) -> dict[str, Dist]:
    """``["mu=0.01:0.05", "torque=norm:2500:400"]`` as ``{name: Dist}``.

    Parameters
    ----------
    specs : ``NAME=LO:HI`` (uniform) or ``NAME=DIST:A:B...`` (`Dist`, SALib's conventions),
        NAME a sweepable parameter (``speed_rpm`` in r/min, ``torque`` in N.m, or a
        `GearParams` field in SI units)

    Raises ``ValueError`` naming the parameter for a bad spec (an unknown distribution, the
    wrong count of numbers, ``lo >= hi``, a standard deviation <= 0 ...).
    """
    out: dict[str, Dist] = {}
    for s in specs:
        name, sep, text = s.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ValueError(f"{s!r}: use NAME=LO:HI, e.g. mu=0.01:0.05, or NAME=DIST:..., "
                             "e.g. mu=norm:0.03:0.005")
        _check_name(name)
        if name in out:
            raise ValueError(f"parameter {name} is given twice")
        out[name] = Dist.parse(name, text)
    if len(out) < 2:
        raise ValueError("give at least two parameters NAME=LO:HI (or NAME=DIST:...)")
    return out


def _problem(dists: Mapping[str, Dist]) -> dict[str, Any]:
    p: dict[str, Any] = {"num_vars": len(dists), "names": list(dists),
                         "bounds": [d.bounds for d in dists.values()]}
    if any(d.kind != "unif" for d in dists.values()):
        p["dists"] = [d.kind for d in dists.values()]
    return p


def sample(ranges, method: str = "sobol", n: int = 256, *, second_order: bool = False,
           levels: int = 4, seed: int = 1) -> np.ndarray:
    """The SALib sample (rows: points, columns: parameters in the order of ``ranges``).

    ``ranges`` as `as_dists` takes them. ``n`` is the base sample size: Sobol runs
    ``n (D + 2)`` points (``n (2D + 2)`` with ``second_order``; a power of two keeps the
    Sobol sequence balanced), Morris ``n (D + 1)`` (``n`` trajectories of ``levels``
    levels; uniform ranges only). The same arguments give the same sample, which is what
    makes a study resumable.
    """
    if method not in METHODS:
        raise ValueError(f"method {method!r}: choose one of {', '.join(METHODS)}")
    dists = as_dists(ranges)
    if not isinstance(n, int | np.integer) or n < 2:
        raise ValueError(f"n = {n!r}: the base sample size must be a whole number >= 2")
    problem = _problem(dists)
    if method == "sobol":
        if n & (n - 1):
            raise ValueError(f"n = {n}: Sobol needs a power of two (e.g. 256, 1024)")
        from SALib.sample import sobol as s_sobol

        return s_sobol.sample(problem, n, calc_second_order=second_order, scramble=True,
                              seed=seed)
    other = [f"{k}={d.spec}" for k, d in dists.items() if d.kind != "unif"]
    if other:
        raise ValueError(f"Morris takes uniform ranges only (its elementary effects are steps "
                         f"on a uniform grid of levels): {', '.join(other)}; give NAME=LO:HI, "
                         "or use --method sobol for other distributions")
    from SALib.sample import morris as s_morris

    return s_morris.sample(problem, n, num_levels=levels, seed=seed)


def check_sample(dists: Mapping[str, Dist], x: np.ndarray, settings: SweepSettings) -> None:
    """``ValueError`` naming the parameter and its distribution when the sample ``x`` of it
    leaves the parameter's range (a normal distribution reaches any value: ``mu =
    norm:0.01:0.01`` gives negative friction coefficients), before any point runs."""
    for j, (name, d) in enumerate(dists.items()):
        for v in (float(np.min(x[:, j])), float(np.max(x[:, j]))):
            try:
                settings.check_point({name: v})
            except ValueError as exc:
                raise ValueError(
                    f"{name}={d.spec}: the sample reaches {name} = {v:g}, outside the "
                    f"parameter's range ({exc}); narrow the distribution or cut it to the "
                    f"range with truncnorm:LO:HI:MEAN:SD") from None


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


def run_sensitivity(ranges, method: str = "sobol", n: int = 256,
                    outputs: tuple[str, ...] | list[str] = DEFAULT_OUTPUTS,
                    settings: SweepSettings | None = None,
                    store: str | Path = "sensitivity.zarr", *, second_order: bool = False,
                    levels: int = 4, seed: int = 1, conf_level: float = 0.95,
                    scheduler: str | None = None, workers: int | None = None,
                    new_store: bool = False, progress: bool = True, stream=None):
    """Sobol or Morris indices of ``outputs`` over ``ranges``, through a sweep store.

    Parameters
    ----------
    ranges : the parameters and their distributions: specs ``["mu=0.01:0.05",
        "torque=norm:2500:400", ...]`` (`parse_ranges`) or a mapping ``{name: (lo, hi)}``
        (uniform), ``{name: Dist}`` or ``{name: "norm:2500:400"}`` (`as_dists`), in the
        parameter's unit (r/min, N.m, SI); Morris: uniform only
    method : ``"sobol"`` (Saltelli sampling) or ``"morris"``
    n : base sample size (see `sample`)
    outputs : stored figures of a point (`OUTPUTS`), e.g. ``stick_ratio`` (-)
    settings : held inputs, effects and durations (`SweepSettings`)
    store : the Zarr store of the points (resumed when it holds this sample)
    second_order : Sobol second-order indices ``S2`` too
    levels : Morris grid levels; seed : the sample's seed
    conf_level : level of the confidence intervals (bootstrap)
    scheduler, workers, new_store, progress, stream : as in `run_grid`

    Every value of the sample is checked against its parameter's range before any point
    runs (`check_sample`).

    Returns
    -------
    xarray.Dataset
        dims ``output`` x ``param``: Sobol ``S1``, ``S1_conf``, ``ST``, ``ST_conf`` (half
        widths of the intervals; ``S2``, ``S2_conf`` over ``param`` x ``param2`` when
        asked), Morris ``mu_star``, ``mu_star_conf``, ``sigma``; ``distribution`` (param):
        each parameter's `Dist` as text; attrs: method, n, points, conf_level, seed, and
        ``constant_outputs`` naming an output that is the same at every point (its indices
        are NaN: there is no variance to share out, e.g. a contact-loss ratio 0). The
        same Dataset is written into the store as its group ``sensitivity``
        (`open_indices`; ``xr.open_zarr(store, group="sensitivity")``), replacing the
        indices an earlier call wrote there.
    """
    from .store import STATUS, Store
    from .study import run_grid

    dists = as_dists(ranges)
    outputs = tuple(outputs)
    for o in outputs:
        if o not in OUTPUTS:
            raise ValueError(f"output {o!r}: choose from {', '.join(OUTPUTS)}")
    if not outputs:
        raise ValueError("give at least one output")
    if not 0 < conf_level < 1:
        raise ValueError(f"conf_level = {conf_level!r}: must be in (0, 1)")
    settings = settings or SweepSettings()
    x = sample(dists, method, n, second_order=second_order, levels=levels, seed=seed)
    check_sample(dists, x, settings)
    names = tuple(dists)
    grid = Grid(names, tuple(tuple(float(v) for v in x[:, j]) for j in range(len(names))),
                "points")
    st = Store.open_or_create(store, grid, settings, new=new_store)
    try:  # the store stays locked for this study until its indices are in
        run_grid(grid, settings, st, scheduler=scheduler, workers=workers, progress=progress,
                 stream=stream)
        status = st.status()
        bad = int(np.count_nonzero((st.done() != 1) | (status != STATUS.index("ok"))))
        if bad:
            raise ValueError(f"{bad} of {grid.size} points are not ok in {store} (failed, "
                             "invalid or not run): the indices need every point; narrow the "
                             "ranges or run the same command again")
        ys = {o: np.asarray(st.group[o][...], float).ravel() for o in outputs}
        ds = _analyse(dists, method, x, ys, n, second_order, conf_level, seed, store)
        st.put_dataset(GROUP, ds)
    finally:
        st.close()
    return ds


def open_indices(store: str | Path):
    """The indices a `run_sensitivity` wrote into ``store`` (its group ``sensitivity``), as
    an ``xarray.Dataset``; `StoreError` when the store holds none."""
    import xarray as xr

    from .store import Store, StoreError, consolidated

    Store.open(store)  # the store's checks, one line each
    if not (Path(store) / GROUP / "zarr.json").is_file():
        raise StoreError(f"store {store} holds no sensitivity indices (gearpair sensitivity "
                         "writes them)")
    return xr.open_zarr(store, group=GROUP, consolidated=consolidated(store), zarr_format=3)


def _analyse(dists, method, x, ys, n, second_order, conf_level, seed, store):
    import xarray as xr

    problem = _problem(dists)
    names = list(dists)
    outs = list(ys)
    res = []
    constant = []
    for o in outs:
        y = ys[o]
        if not np.all(np.isfinite(y)):
            raise ValueError(f"output {o}: {np.count_nonzero(~np.isfinite(y))} points have no "
                             "value; choose another output")
        if np.all(y == y[0]):  # no variance to share out (SALib would say 0 for all)
            constant.append(f"{o} = {y[0]:g}")
            nan = np.full(len(names), np.nan)
            res.append({"S1": nan, "S1_conf": nan, "ST": nan, "ST_conf": nan,
                        "S2": np.full((len(names),) * 2, np.nan),
                        "S2_conf": np.full((len(names),) * 2, np.nan),
                        "mu_star": nan, "mu_star_conf": nan, "sigma": nan})
            continue
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
    # text as Python strings (object arrays): Zarr v3 stores them as its variable-length
    # "string" type; numpy's fixed-width "<U" has no v3 specification (zarr warns)
    text = lambda items: np.array(list(items), dtype=object)  # noqa: E731
    data["distribution"] = (("param",), text(d.spec for d in dists.values()))
    ds = xr.Dataset(data, coords={"output": text(outs), "param": text(names),
                                  **({"param2": text(names)} if "S2" in data else {})})
    _describe(ds, conf_level)
    if constant:
        ds.attrs["constant_outputs"] = ", ".join(constant) + " at every point: no variance, " \
            "no indices (NaN)"
    ds.attrs.update(method=method, n=int(n), points=int(x.shape[0]),
                    conf_level=float(conf_level), seed=int(seed), store=str(store),
                    title=f"gearpair sensitivity: {method} indices of "
                          f"{', '.join(outs)} over {', '.join(names)}")
    return ds


# what each index is (its ``long_name``); the Sobol indices are fractions of the variance
# (units "1"), Morris's are in the unit of the output, which differs along ``output``
_SAID = {"S1": "first-order Sobol index", "ST": "total Sobol index",
         "S2": "second-order Sobol index (param with param2)",
         "mu_star": "Morris mu*: mean absolute elementary effect (output unit)",
         "sigma": "Morris sigma: standard deviation of the elementary effects (output unit)",
         "distribution": "distribution of the parameter in SALib's terms (unif:LO:HI, "
                         "norm:MEAN:SD, ...)"}


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
