"""Sobol and Morris through the sweep machinery, checked on the Ishigami function."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("SALib")

from gearpair.sweep import sensitivity as sa  # noqa: E402

# Three sweepable parameters stand for the Ishigami inputs: each range maps linearly onto
# [-pi, pi], which leaves the indices of uniform inputs unchanged.
RANGES = {"mu": (0.01, 0.05), "torque": (1000.0, 4000.0), "speed_rpm": (100.0, 600.0)}
A, B = 7.0, 0.1
S1_EXACT = (0.3139, 0.4424, 0.0)
ST_EXACT = (0.5576, 0.4424, 0.2437)
N_SOBOL = 128  # base sample: 640 points (~20 s serial through the store, run once for the
#                file); intervals ~ +-0.15


def _ishigami(point):
    x = [-math.pi + 2 * math.pi * (point[k] - lo) / (hi - lo) for k, (lo, hi) in RANGES.items()]
    y = math.sin(x[0]) + A * math.sin(x[1]) ** 2 + B * x[2] ** 4 * math.sin(x[0])
    return {"stick_ratio": y}


@pytest.fixture(scope="module")
def sobol(tmp_path_factory):
    """The Sobol indices of the Ishigami function at ``N_SOBOL`` and their points' store."""
    store = tmp_path_factory.mktemp("sobol") / "s.zarr"
    calls = []

    def f(point):
        calls.append(1)
        return _ishigami(point)

    with sa.model_hook(f):
        ds = sa.run_sensitivity(RANGES, "sobol", N_SOBOL, ("stick_ratio",), store=store,
                                scheduler="serial", progress=False)
    return ds, store, len(calls)


def test_sobol_ishigami_within_intervals(sobol):
    ds, store, _ = sobol
    s1 = ds["S1"].sel(output="stick_ratio").values
    st = ds["ST"].sel(output="stick_ratio").values
    s1c = ds["S1_conf"].sel(output="stick_ratio").values
    stc = ds["ST_conf"].sel(output="stick_ratio").values
    assert ds.attrs["points"] == N_SOBOL * 5
    assert np.all(np.abs(s1 - S1_EXACT) <= s1c), (s1, s1c)
    assert np.all(np.abs(st - ST_EXACT) <= stc), (st, stc)
    assert np.all(s1c < 0.25) and np.all(stc < 0.25)  # intervals narrow enough to mean something
    assert sa.sensitivity_path(store).exists()


def test_resume_runs_nothing_again(sobol):
    """The first run ran every point once; the same run again on its store runs none."""
    first, store, ran = sobol
    calls = []

    def f(point):
        calls.append(1)
        return _ishigami(point)

    with sa.model_hook(f):
        ds = sa.run_sensitivity(RANGES, "sobol", N_SOBOL, ("stick_ratio",), store=store,
                                scheduler="serial", progress=False)
    assert ran == N_SOBOL * 5 and calls == []
    assert ds.attrs["points"] == N_SOBOL * 5
    assert ds["S1"].equals(first["S1"]) and ds["ST_conf"].equals(first["ST_conf"])


def test_morris_ranks_ishigami(tmp_path):
    with sa.model_hook(_ishigami):
        ds = sa.run_sensitivity(RANGES, "morris", 16, ("stick_ratio",),
                                store=tmp_path / "m.zarr", scheduler="serial", progress=False)
    mu = ds["mu_star"].sel(output="stick_ratio").values
    # known order of the Ishigami elementary effects: x2 (a sin^2) > x1 > x3
    assert list(np.argsort(-mu)) == [1, 0, 2], mu


def test_chart(sobol, tmp_path):
    out = sa.plot_indices(sobol[0], tmp_path / "s.png")
    assert out.stat().st_size > 1000


@pytest.mark.parametrize("method, n", [("sobol", 8), ("morris", 4)])
def test_stores_open_without_a_warning_and_say_what_they_hold(method, n, tmp_path):
    """Issue 36: the points' store and the indices' store open with a plain
    ``xr.open_zarr``, no warning, every variable with a long name in words."""
    import warnings

    xr = pytest.importorskip("xarray")
    with sa.model_hook(_ishigami):
        sa.run_sensitivity(RANGES, method, n, ("stick_ratio",), store=tmp_path / "s.zarr",
                           scheduler="serial", progress=False, second_order=method == "sobol")
    for path in (tmp_path / "s.zarr", sa.sensitivity_path(tmp_path / "s.zarr")):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            ds = xr.open_zarr(path)
        for name, var in ds.variables.items():
            said = var.attrs.get("long_name", "")
            assert said.strip() and said != name, (path.name, name)
            assert var.attrs.get("units", "1") in ("1", "rpm", "N.m", "s", "kN", "um", "m")
    if method == "sobol":
        assert ds["S1"].attrs["units"] == "1" and "95 %" in ds["ST_conf"].attrs["long_name"]


@pytest.mark.parametrize("specs, word", [
    (["mu=0.05:0.01", "torque=1:2"], "mu"),
    (["mu=0.01", "torque=1:2"], "mu"),
    (["nope=0:1", "torque=1:2"], "nope"),
    (["mu=0.01:0.05"], "two"),
])
def test_bad_ranges(specs, word):
    with pytest.raises(ValueError, match=word):
        sa.parse_ranges(specs)


def test_bad_method_and_n():
    with pytest.raises(ValueError, match="method"):
        sa.sample(RANGES, "fast", 8)
    with pytest.raises(ValueError, match="power of two"):
        sa.sample(RANGES, "sobol", 100)


def test_out_of_range_parameter_refused_before_running(tmp_path):
    with pytest.raises(ValueError, match="mu"):
        sa.run_sensitivity({"mu": (-1.0, 0.05), "torque": (1000.0, 4000.0)}, "sobol", 8,
                           store=tmp_path / "s.zarr", scheduler="serial", progress=False)
    with pytest.raises(ValueError, match="output"):
        sa.run_sensitivity(RANGES, "sobol", 8, ("nope",), store=tmp_path / "t.zarr",
                           scheduler="serial", progress=False)
