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


def test_indices_are_in_the_store_beside_the_points(sobol):
    """Issue 36: the indices are a Dataset *in* the store (its group ``sensitivity``), equal
    to what the Python API returns; the points' dataset does not change and nothing is
    written next to the store."""
    from gearpair.sweep import open_dataset

    ds, store, _ = sobol
    back = sa.open_indices(store).load()
    for k in ds.data_vars:
        np.testing.assert_array_equal(back[k].values, ds[k].values, err_msg=k)
        assert back[k].attrs == ds[k].attrs, k
    assert back.attrs == ds.attrs and list(back["param"].values) == list(RANGES)
    assert list(back["distribution"].values) == ["unif:0.01:0.05", "unif:1000:4000",
                                                 "unif:100:600"]
    assert float(back["ST"].sel(output="stick_ratio", param="torque")) == \
        float(ds["ST"].sel(output="stick_ratio", param="torque"))
    points = open_dataset(store)
    assert "S1" not in points and points.sizes["point"] == N_SOBOL * 5
    assert [p.name for p in store.parent.iterdir()] == [store.name]


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
    assert sa.open_indices(store)["S1"].load().equals(first["S1"])


def test_morris_ranks_ishigami(tmp_path):
    with sa.model_hook(_ishigami):
        ds = sa.run_sensitivity(RANGES, "morris", 16, ("stick_ratio",),
                                store=tmp_path / "m.zarr", scheduler="serial", progress=False)
    mu = ds["mu_star"].sel(output="stick_ratio").values
    # known order of the Ishigami elementary effects: x2 (a sin^2) > x1 > x3
    assert list(np.argsort(-mu)) == [1, 0, 2], mu


def test_an_output_the_same_at_every_point_has_no_indices(tmp_path):
    """A constant output (e.g. no contact loss anywhere) has no variance to share out: NaN
    and a note, not SALib's zeros that would read as 'no parameter matters'."""
    with sa.model_hook(lambda p: {**_ishigami(p), "contact_loss_ratio": 0.0}):
        ds = sa.run_sensitivity(RANGES, "sobol", 8, ("stick_ratio", "contact_loss_ratio"),
                                store=tmp_path / "c.zarr", scheduler="serial",
                                progress=False, second_order=True)
    assert np.all(np.isnan(ds["ST"].sel(output="contact_loss_ratio").values))
    assert np.all(np.isnan(ds["S2"].sel(output="contact_loss_ratio").values))
    assert np.all(np.isfinite(ds["ST"].sel(output="stick_ratio").values))
    assert ds.attrs["constant_outputs"].startswith("contact_loss_ratio = 0 at every point")


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
    for group in (None, "sensitivity"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            ds = xr.open_zarr(tmp_path / "s.zarr", group=group)
        for name, var in ds.variables.items():
            said = var.attrs.get("long_name", "")
            assert said.strip() and said != name, (group, name)
            assert var.attrs.get("units", "1") in ("1", "rpm", "N.m", "s", "kN", "um", "m")
    if method == "sobol":
        assert ds["S1"].attrs["units"] == "1" and "95 %" in ds["ST_conf"].attrs["long_name"]


@pytest.mark.parametrize("specs, words", [
    (["mu=0.05:0.01", "torque=1:2"], ("mu", "LO must be < HI")),
    (["mu=0.01", "torque=1:2"], ("mu", "LO:HI")),
    (["nope=0:1", "torque=1:2"], ("nope",)),
    (["mu=0.01:0.05"], ("two",)),
    (["mu=gauss:0.03:0.005", "torque=1:2"], ("mu=gauss", "unknown distribution", "truncnorm")),
    (["mu=norm:0.03", "torque=1:2"], ("mu=norm:0.03", "mu=norm:MEAN:SD", "2 numbers")),
    (["mu=norm:0.03:0", "torque=1:2"], ("mu=norm:0.03:0", "SD must be > 0")),
    (["mu=norm:0.03:x", "torque=1:2"], ("mu=norm", "MEAN:SD")),
    (["torque=1:2", "mu=triang:0.01:0.05:1.5"], ("mu=triang", "PEAK", "fraction")),
    (["torque=1:2", "mu=truncnorm:0.05:0.01:0.03:0.01"], ("mu=truncnorm", "LO must be < HI")),
    (["torque=1:2", "mu=lognorm:-4:-1"], ("mu=lognorm", "LN_SD must be > 0")),
    (["torque=1:2", "mu=logunif:0:0.05"], ("mu=logunif", "LO must be > 0")),
    (["torque=1:2", "mu=weibull:2"], ("mu=weibull", "SHAPE:SCALE[:LOC]")),
])
def test_bad_ranges(specs, words):
    with pytest.raises(ValueError) as err:
        sa.parse_ranges(specs)
    for w in words:
        assert w in str(err.value), (w, str(err.value))


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


# -- distributions other than uniform --------------------------------------------------------

DISTS = {  # spec -> (mean, standard deviation) from the distribution's own formulas
    "unif:1:3": (2.0, 2 / math.sqrt(12)),
    "norm:0.03:0.005": (0.03, 0.005),
    "lognorm:-3.5:0.2": (math.exp(-3.5 + 0.02), math.exp(-3.5 + 0.02) * math.sqrt(
        math.exp(0.04) - 1)),
    "triang:1000:4000:0.25": ((1000 + 4000 + 1750) / 3, math.sqrt(
        (1000**2 + 4000**2 + 1750**2 - 1000 * 4000 - 1000 * 1750 - 4000 * 1750) / 18)),
    "logunif:1e6:1e8": ((1e8 - 1e6) / math.log(100), None),
}


@pytest.mark.parametrize("spec", list(DISTS) + ["truncnorm:0:1:0.2:0.5", "weibull:2:3",
                                                "weibull:2:3:1"])
def test_sample_has_the_distribution(spec):
    """Every column of a Sobol sample is drawn from its distribution: mean and standard
    deviation as the distribution's (closed forms, and scipy's for the others), and a
    Kolmogorov-Smirnov distance that a sample of that size gives."""
    from scipy import stats

    d = sa.Dist.parse("torque", spec)
    x = sa.sample({"torque": d, "mu": (0.01, 0.05)}, "sobol", 1024)
    col = x[:, 0]
    mean, sd = DISTS.get(spec, (d.frozen().mean(), d.frozen().std()))
    sd = d.frozen().std() if sd is None else sd
    assert d.frozen().mean() == pytest.approx(mean, rel=1e-9)
    assert col.mean() == pytest.approx(mean, rel=0.01, abs=0.01 * sd)
    assert col.std() == pytest.approx(sd, rel=0.02)
    assert stats.kstest(col, d.frozen().cdf).statistic < 0.01
    np.testing.assert_array_equal(x[:, 1] >= 0.01, True)  # the uniform column unchanged
    assert sa.Dist.parse("torque", d.spec) == d  # its text reads back as itself


def test_morris_takes_uniform_ranges_only():
    with pytest.raises(ValueError, match=r"Morris takes uniform ranges only.*mu=norm:0.03"):
        sa.sample({"mu": "norm:0.03:0.005", "torque": (1000, 4000)}, "morris", 4)
    with pytest.raises(ValueError, match="Morris"):
        sa.run_sensitivity(["mu=norm:0.03:0.005", "torque=1000:4000"], "morris", 4,
                           store="/nonexistent/never.zarr", scheduler="serial")


def test_a_distribution_that_leaves_the_range_is_refused_naming_it(tmp_path):
    """A normal distribution reaches any value: mu = norm:0.01:0.01 samples negative
    friction coefficients, refused before any point runs, with the way out."""
    with pytest.raises(ValueError) as err:
        sa.run_sensitivity(["mu=norm:0.01:0.01", "torque=1000:4000"], "sobol", 64,
                           store=tmp_path / "s.zarr", scheduler="serial", progress=False)
    said = str(err.value)
    assert said.startswith("mu=norm:0.01:0.01: the sample reaches mu = -") and \
        "truncnorm" in said, said
    assert not (tmp_path / "s.zarr").exists()


def _moment(d, power, lo, hi):
    """E[x^power] of x = -pi + 2 pi (v - lo) / (hi - lo) with v from the Dist ``d``."""
    return d.frozen().expect(lambda v: (-math.pi + 2 * math.pi * (v - lo) / (hi - lo)) ** power)


def test_ishigami_with_a_non_uniform_input_has_its_exact_indices(tmp_path):
    """Ishigami with x3 from a truncated normal distribution (speed_rpm =
    truncnorm:100:600:350:150, i.e. x3 on [-pi, pi] with mean 0 and standard deviation
    0.6 pi before the cut). With x1, x2 uniform the exact variances are V1 = (1 + b m4)^2 / 2,
    V2 = a^2 / 8, V3 = 0 and V13 = b^2 (m8 - m4^2) / 2 for any x3, m_k = E[x3^k] (the
    formulas give the known indices for a uniform x3): S1 = (0.2170, 0.5955, 0), ST =
    (0.4045, 0.5955, 0.1875), against (0.3139, 0.4424, 0) and (0.5576, 0.4424, 0.2437)."""

    def exact(d3):
        m4, m8 = (_moment(d3, k, 100.0, 600.0) for k in (4, 8))
        v1, v2, v13 = (1 + B * m4) ** 2 / 2, A**2 / 8, B**2 * (m8 - m4**2) / 2
        v = v1 + v2 + v13
        return np.array([v1, v2, 0]) / v, np.array([v1 + v13, v2, v13]) / v

    s1, st = exact(sa.Dist.parse("speed_rpm", "100:600"))
    assert s1 == pytest.approx(S1_EXACT, abs=1e-4) and st == pytest.approx(ST_EXACT, abs=1e-4)
    d3 = sa.Dist.parse("speed_rpm", "truncnorm:100:600:350:150")
    s1, st = exact(d3)
    assert s1 == pytest.approx([0.2170, 0.5955, 0.0], abs=1e-4)
    assert st == pytest.approx([0.4045, 0.5955, 0.1875], abs=1e-4)
    ranges = {"mu": (0.01, 0.05), "torque": (1000.0, 4000.0), "speed_rpm": d3}
    with sa.model_hook(_ishigami):
        ds = sa.run_sensitivity(ranges, "sobol", N_SOBOL, ("stick_ratio",),
                                store=tmp_path / "n.zarr", scheduler="serial", progress=False)
    got = {k: ds[k].sel(output="stick_ratio").values for k in ("S1", "ST", "S1_conf",
                                                               "ST_conf")}
    assert np.all(np.abs(got["S1"] - s1) <= got["S1_conf"]), (got["S1"], s1, got["S1_conf"])
    assert np.all(np.abs(got["ST"] - st) <= got["ST_conf"]), (got["ST"], st, got["ST_conf"])
    assert list(sa.open_indices(tmp_path / "n.zarr")["distribution"].values)[2] == \
        "truncnorm:100:600:350:150"


def test_a_parameter_the_model_cannot_depend_on_has_total_index_zero(tmp_path):
    """Issue 36 item 2, on the gear model: with the rectangular stiffness law, Poisson's
    ratio (which shapes only the potential-energy law) cannot change any figure, so its
    total index is 0 within its interval, while the speed's is not; Poisson's ratio from a
    truncated normal distribution runs the non-uniform path through the real model."""
    from gearpair.sweep import SweepSettings

    quick = SweepSettings(transient_periods=10, transient_time=0.0, kept_periods=10,
                          max_time=0.5, min_periods=4, stiffness="rectangular")
    ds = sa.run_sensitivity(["speed_rpm=50:300", "poisson=truncnorm:0.2:0.4:0.3:0.05"],
                            "sobol", 8, ("stick_ratio", "mesh_force_max_kn"), quick,
                            store=tmp_path / "p.zarr", scheduler="serial", progress=False)
    st = ds["ST"].sel(param="poisson").values
    assert np.all(np.abs(st) <= ds["ST_conf"].sel(param="poisson").values + 1e-12), st
    assert np.all(ds["ST"].sel(param="speed_rpm").values > 0.5), ds["ST"].values


def test_cli_takes_the_sweep_settings_and_distributions(tmp_path, capsys):
    """``gearpair sensitivity`` holds what ``gearpair sweep`` holds (effects, durations,
    --set), records it in the store, and reads a distribution."""
    import json

    from gearpair.cli import main
    from gearpair.sweep import Store

    store = tmp_path / "c.zarr"
    argv = ["sensitivity", "mu=0.01:0.05", "torque=1000:4000",
            "speed_rpm=truncnorm:100:600:350:150", "-n", "8", "--outputs", "stick_ratio",
            "--store", str(store), "--scheduler", "serial", "--stiffness", "rectangular",
            "--backlash", "5e-05", "--kept-periods", "20", "--set", "kb1=5e7", "--json"]
    with sa.model_hook(_ishigami):
        assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["param"] == ["mu", "torque", "speed_rpm"] and len(out["ST"][0]) == 3
    st = Store.open(store).settings
    assert (st.stiffness, st.backlash, st.kept_periods, st.params) == \
        ("rectangular", 5e-05, 20, (("kb1", 5e7),))
    assert list(sa.open_indices(store)["distribution"].values)[2] == \
        "truncnorm:100:600:350:150"
