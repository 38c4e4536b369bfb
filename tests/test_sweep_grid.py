"""Parameter grids stored as they finish: grids and point lists, the Zarr store
read back with xarray, resuming, refusing a store of another sweep, and a client killed at
random moments."""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

from gearpair.cli import main
from gearpair.sweep import Grid, SweepSettings, open_dataset, run_grid, run_point
from gearpair.sweep.settings import long_name, sweepable
from gearpair.sweep.store import (
    DESCRIPTION,
    NUMERIC,
    STATUS,
    Store,
    chunk_shape,
    consolidate,
    consolidated,
)

xr = pytest.importorskip("xarray")

QUICK = SweepSettings(transient_periods=10, transient_time=0.0, kept_periods=10, max_time=0.5,
                      min_periods=4)
QUICK_ARGS = ["--transient-periods", "10", "--transient-time", "0", "--kept-periods", "10",
              "--max-time", "0.5"]
# the physics of a point (not its cost or where it ran): equal bit for bit between runs
PHYSICS = [n for n in NUMERIC if n not in ("wall_s", "cpu_s", "attempts", "rtol")]
# Units as UDUNITS-2 spells them (what CF tools parse): each one checked with its
# `udunits2 -H UNIT -W ""` (Debian's udunits-bin 2.2.28), which refuses "r/min"
UDUNITS = {"1", "rpm", "N.m", "s", "kN", "um", "m", "kg", "kg.m2", "rad", "N/m", "Pa"}


def _open_quietly(path):
    """``xr.open_zarr`` as a user calls it, every warning an error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return xr.open_zarr(path)


# -- grids ---------------------------------------------------------------------------------------
def test_grid_is_the_full_factorial_in_c_order():
    g = Grid.parse(["speed_rpm=5:600:120", "torque=1000:4000:7", "mu=0.01,0.02,0.03"])
    assert g.shape == (120, 7, 3) and g.size == 2520 and g.dims == g.names
    assert g.point(0) == {"speed_rpm": 5.0, "torque": 1000.0, "mu": 0.01}
    assert g.point(1) == {"speed_rpm": 5.0, "torque": 1000.0, "mu": 0.02}  # last fastest
    assert g.point(2519) == {"speed_rpm": 600.0, "torque": 4000.0, "mu": 0.03}
    assert [i for i, _ in g.points()] == list(range(2520))
    assert Grid.from_json(json.loads(json.dumps(g.to_json()))) == g


def test_point_list_from_csv(tmp_path):
    f = tmp_path / "pts.csv"
    f.write_text("speed_rpm,mu\n100,0.01\n150,0.03\n\n200,0\n")
    g = Grid.from_csv(f)
    assert g.kind == "points" and g.shape == (3,) and g.dims == ("point",)
    assert g.point(1) == {"speed_rpm": 150.0, "mu": 0.03}
    f.write_text("speed_rpm,mu\n100\n")
    with pytest.raises(ValueError, match="line 2 has 1 values for 2 columns"):
        Grid.from_csv(f)


@pytest.mark.parametrize("argv, words", [
    (["spead_rpm=1,2"], ["cannot sweep 'spead_rpm'", "did you mean speed_rpm"]),
    (["speed_rpm=1,2", "speed_rpm=3"], ["speed_rpm is given twice"]),
    (["speed_rpm=", "mu=0.1"], ["empty grid: no values for speed_rpm"]),
    ([], ["empty grid"]),
    (["speed_rpm=0,100"], ["speed_rpm = 0.0 is out of range", "(0, "]),
    (["mu=0.01,2"], ["mu = 2.0 is out of range", "[0, 1]"]),
    (["torque=1e7", "mu=0.01"], ["torque = 10000000.0 is out of range"]),
    (["speed_rpm=100", "mu"], ["'mu': in a grid every parameter is NAME=VALUES"]),
])
def test_bad_grid_is_one_line_and_exit_2_before_any_point(argv, words, tmp_path, capsys,
                                                          no_runs):
    assert main(["sweep", *argv, "--scheduler", "serial", "--out", str(tmp_path / "g")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    assert not (tmp_path / "g.zarr").exists()  # nothing written either


def test_unwritable_or_foreign_store_is_refused(tmp_path, capsys, no_runs):
    other = tmp_path / "data"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    for extra in ([], ["--new-store"]):  # never replaced, even when a new store is asked for
        assert main(["sweep", "mu=0.01,0.02", "--scheduler", "serial", "--store", str(other),
                     "--out", str(tmp_path / "g"), *extra]) == 2
        assert "is not a gearpair sweep store" in capsys.readouterr().err
    assert (other / "keep.txt").read_text() == "mine"
    blocker = tmp_path / "file"
    blocker.write_text("a file where the store's folder would be")
    assert main(["sweep", "mu=0.01", "--scheduler", "serial", "--store",
                 str(blocker / "s.zarr"), "--out", str(tmp_path / "g")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot create its folder" in err, err
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if not os.access(ro, os.W_OK):  # (root writes anywhere)
            assert main(["sweep", "mu=0.01", "--scheduler", "serial", "--store",
                         str(ro / "s.zarr"), "--out", str(tmp_path / "g")]) == 2
            assert "cannot write" in capsys.readouterr().err
    finally:
        ro.chmod(0o700)


# -- the store -----------------------------------------------------------------------------------
def test_zarr_local_store_writes_through_a_temporary_file_and_rename(tmp_path, monkeypatch):
    """The store's crash safety rests on this (zarr 3.1's `LocalStore`): a chunk file is
    replaced whole by a rename, never rewritten in place."""
    import zarr

    a = zarr.create_array(tmp_path / "a.zarr", shape=(4,), chunks=(4,), dtype="float64")
    a[...] = 1.0
    seen = []
    real = os.replace

    def spy(src, dst):
        seen.append((str(src), str(dst)))
        return real(src, dst)

    monkeypatch.setattr(os, "replace", spy)
    a[1] = 2.0
    assert seen and all(s.endswith(".partial") and d.endswith("/c/0") for s, d in seen)
    assert list(a[...]) == [1.0, 2.0, 1.0, 1.0]


def test_a_half_made_store_of_a_killed_creation_is_cleared(tmp_path):
    """A creation killed before its rename leaves a hidden folder beside the store; the next
    creation removes it when its process is gone, and never touches a live one's."""
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    stale = tmp_path / f".h.zarr.creating-{dead}"
    live = tmp_path / f".h.zarr.creating-{os.getppid()}"
    for d in (stale, live):
        d.mkdir()
        (d / "zarr.json").write_text("{}")
    run_grid(Grid.parse(["mu=0.01"]), QUICK, tmp_path / "h.zarr", scheduler="serial",
             progress=False)
    assert not stale.exists() and live.exists()
    assert int(open_dataset(tmp_path / "h.zarr")["done"].sum()) == 1


def test_store_opens_with_xarray_without_a_warning_also_after_a_resume(tmp_path):
    """Issue 36: consolidated metadata from the creation on, and kept up to date by every
    run (the runs' attributes): a plain ``xr.open_zarr`` warns of nothing."""
    import zarr

    g = Grid.parse(["speed_rpm=100,150", "torque=2000,3900"])
    store = tmp_path / "c.zarr"
    seen = []

    def stop_after_one(rec):
        seen.append(rec)
        raise KeyboardInterrupt  # Ctrl-C after the first point

    run = run_grid(g, QUICK, store, scheduler="serial", progress=False,
                   on_record=stop_after_one)
    assert run.interrupted and consolidated(store)
    assert int(_open_quietly(store)["done"].sum()) == 1
    run_grid(g, QUICK, store, scheduler="serial", progress=False)  # resumed
    ds = _open_quietly(store)
    assert int(ds["done"].sum()) == 4 and len(ds.attrs["runs"]) == 2
    assert ds["stick_ratio"].attrs["long_name"].startswith("stick ratio")
    # the consolidated metadata is what the arrays' own zarr.json files say, for every array
    inline = json.loads((store / "zarr.json").read_text())["consolidated_metadata"]["metadata"]
    names = sorted(name for name, _ in zarr.open_group(store, mode="r",
                                                       use_consolidated=False).arrays())
    assert sorted(inline) == names and len(names) > len(NUMERIC)
    for name in names:
        assert inline[name] == json.loads((store / name / "zarr.json").read_text()), name
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        open_dataset(store).load()
    # a store written before it had consolidated metadata: read without a warning, and
    # consolidated by its next run
    meta = store / "zarr.json"
    doc = json.loads(meta.read_text())
    del doc["consolidated_metadata"]
    meta.write_text(json.dumps(doc))
    assert not consolidated(store)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        open_dataset(store).load()
    assert run_grid(g, QUICK, store, scheduler="serial", progress=False).ran == 0
    assert consolidated(store) and len(_open_quietly(store).attrs["runs"]) == 3
    consolidate(store)  # again: no warning of zarr's own passed on
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        consolidate(store)


@pytest.mark.parametrize("kind", ["product", "points"])
def test_every_variable_says_what_it_is_in_udunits(kind, tmp_path):
    """Issue 36: a ``long_name`` in words (not the variable's name) on every variable and
    coordinate, and units only in UDUNITS spellings."""
    if kind == "product":
        g = Grid.parse(["speed_rpm=100", "torque=3900", "kb1=1e8"])
    else:
        f = tmp_path / "pts.csv"
        f.write_text("speed_rpm,mu,module\n100,0.01,0.006\n")
        g = Grid.from_csv(f)
    run_grid(g, QUICK, tmp_path / "u.zarr", scheduler="serial", progress=False)
    ds = _open_quietly(tmp_path / "u.zarr")
    assert set(ds.data_vars) >= {n for n in NUMERIC if n not in g.names}
    for name, var in ds.variables.items():
        said = var.attrs.get("long_name", "")
        assert said.strip() and said != name, name
        if "units" in var.attrs or name in DESCRIPTION:
            assert var.attrs["units"] in UDUNITS, (name, var.attrs["units"])
    assert ds["speed_rpm"].attrs["units"] == "rpm"
    assert ds["mesh_force_mean_kn"].attrs["long_name"] == "mean mesh force"
    assert ds["mesh_force_mean_kn"].attrs["units"] == "kN"
    # whatever may be swept, and every numeric column, has both
    assert set(NUMERIC) <= set(DESCRIPTION)
    for name, (unit, said) in DESCRIPTION.items():
        assert unit in UDUNITS and said.strip() and said != name, name
    for name, unit in sweepable().items():
        assert unit in UDUNITS and long_name(name).strip() and long_name(name) != name, name


@pytest.mark.skipif(shutil.which("udunits2") is None, reason="UDUNITS-2's udunits2 program "
                    "(Debian: udunits-bin) not installed")
def test_the_store_units_parse_in_udunits():
    units = UDUNITS | {u for u, _ in DESCRIPTION.values()} | set(sweepable().values())
    for unit in sorted(units):
        got = subprocess.run(["udunits2", "-H", unit, "-W", ""], capture_output=True,
                             text=True, timeout=30)
        assert got.returncode == 0 and "Don't recognize" not in got.stdout + got.stderr, unit
    got = subprocess.run(["udunits2", "-H", "r/min", "-W", ""], capture_output=True,
                         text=True, timeout=30)
    assert "Don't recognize" in got.stdout + got.stderr  # what the store wrote before


def test_chunks_hold_neighbouring_points():
    assert chunk_shape((120, 7, 3)) == (3, 7, 3)
    assert chunk_shape((1000,)) == (64,) and chunk_shape((5, 100)) == (1, 64)


def test_grid_store_is_a_labelled_dataset_equal_to_the_points(tmp_path):
    g = Grid.parse(["speed_rpm=100,150", "torque=-500,3900", "mu=0,0.03"])
    run = run_grid(g, QUICK, tmp_path / "s.zarr", scheduler="serial", progress=False)
    assert run.ran == 8 and run.after == {"ok": 4, "failed": 0, "invalid": 4, "not_run": 0}
    ds = open_dataset(tmp_path / "s.zarr").load()
    assert ds["stick_ratio"].dims == ("speed_rpm", "torque", "mu")
    assert list(ds["torque"].values) == [-500.0, 3900.0]
    assert ds["poincare"].dims == ("speed_rpm", "torque", "mu", "section")
    assert ds["status"].attrs["flag_meanings"].split() == list(STATUS)
    assert (ds["done"] == 1).all()
    pt = ds.sel(speed_rpm=150.0, torque=3900.0, mu=0.03)
    rec = run_point(0, ("speed_rpm", "torque", "mu"), (150.0, 3900.0, 0.03), QUICK)
    for name in PHYSICS:
        if name not in g.names:
            assert float(pt[name]) == pytest.approx(rec[name], rel=0, abs=0, nan_ok=True), name
    n = int(pt["poincare_count"])
    assert n == len(rec["poincare"]) == 10
    assert list(pt["poincare"].values[:n]) == rec["poincare"]
    bad = ds.sel(speed_rpm=100.0, torque=-500.0, mu=0.0)
    assert STATUS[int(bad["status"])] == "invalid" and "torque" in str(bad["error"].values)
    # more stick with more friction, none without
    assert float(ds["stick_ratio"].sel(speed_rpm=100, torque=3900, mu=0)) == 0.0
    assert float(ds["stick_ratio"].sel(speed_rpm=100, torque=3900, mu=0.03)) > 0.05


def test_point_list_store_has_the_parameters_as_coordinates(tmp_path):
    f = tmp_path / "pts.csv"
    f.write_text("speed_rpm,mu\n100,0.01\n150,0.03\n")
    run_grid(Grid.from_csv(f), QUICK, tmp_path / "p.zarr", scheduler="serial", progress=False)
    ds = open_dataset(tmp_path / "p.zarr")
    assert ds["stick_ratio"].dims == ("point",)
    assert list(ds["mu"].values) == [0.01, 0.03] and "mu" in ds.coords


def test_resume_runs_only_the_missing_points_and_says_so(tmp_path, capsys):
    g = Grid.parse(["speed_rpm=100,150,200", "mu=0.01,0.03"])
    store = tmp_path / "r.zarr"
    seen = []

    def stop_after_two(rec):
        seen.append(rec["index"])
        if len(seen) == 2:
            raise KeyboardInterrupt  # as Ctrl-C between two points

    run = run_grid(g, QUICK, store, scheduler="serial", progress=False,
                   on_record=stop_after_two)
    assert run.interrupted and run.after["not_run"] == 4
    again = []
    run = run_grid(g, QUICK, store, scheduler="serial", stream=sys.stderr,
                   on_record=lambda r: again.append(r["index"]))
    assert "2 done (2 ok, 0 failed, 0 invalid), 4 to run" in capsys.readouterr().err
    assert sorted(again) == [i for i in range(6) if i not in seen]
    assert run.after == {"ok": 6, "failed": 0, "invalid": 0, "not_run": 0}
    whole = run_grid(g, QUICK, tmp_path / "w.zarr", scheduler="serial", progress=False)
    assert whole.ran == 6
    a, b = open_dataset(store).load(), open_dataset(tmp_path / "w.zarr").load()
    for name in PHYSICS:
        if name in a:
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)
    np.testing.assert_array_equal(a["poincare"].values, b["poincare"].values)
    # a third run has nothing to do
    assert run_grid(g, QUICK, store, scheduler="serial", progress=False).ran == 0


def test_changed_setting_is_refused_naming_it_unless_a_new_store_is_asked(tmp_path, capsys):
    out = str(tmp_path / "c")
    argv = ["sweep", "speed_rpm=100", "torque=-100,3900", "--scheduler", "serial", "--out",
            out, "--quiet", *QUICK_ARGS]
    assert main(argv) == 1  # the negative torque is invalid
    capsys.readouterr()
    before = sorted(p.name for p in (tmp_path / "c.zarr").rglob("*"))
    assert main([*argv, "--rtol", "1e-6"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "rtol = 1e-07 in the store, 1e-06 now" in err
    assert "--new-store" in err
    assert main([*argv, "--friction", "nominal"]) == 2
    assert "friction = 'stick_slip' in the store, 'nominal' now" in capsys.readouterr().err
    assert main(["sweep", "speed_rpm=100,150", "torque=-100,3900", "--scheduler", "serial",
                 "--out", out, *QUICK_ARGS]) == 2
    assert "grid speed_rpm (1) x torque (2) = 2 points in the store" in capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "c.zarr").rglob("*")) == before  # untouched
    # the invalid point is kept (not run again) unless asked
    assert main([*argv]) == 1
    assert json.loads(capsys.readouterr().out)["ran"] == 0
    assert main([*argv, "--rerun-failed"]) == 1
    assert json.loads(capsys.readouterr().out)["ran"] == 1
    # a new store when asked: the old one replaced
    assert main([*argv, "--rtol", "1e-6", "--new-store"]) == 1
    assert json.loads(capsys.readouterr().out)["ran"] == 2
    assert Store.open(tmp_path / "c.zarr").settings.rtol == 1e-6


def test_store_of_another_engine_or_layout_version_is_refused(tmp_path, capsys):
    argv = ["sweep", "mu=0.01", "speed_rpm=100", "--scheduler", "serial", "--out",
            str(tmp_path / "v"), "--quiet", "--no-plot", *QUICK_ARGS]
    assert main(argv) == 0
    capsys.readouterr()
    meta = tmp_path / "v.zarr" / "zarr.json"
    doc = json.loads(meta.read_text())
    doc["attributes"]["engine_version"] = "0.0.1+older"
    meta.write_text(json.dumps(doc))
    assert main(argv) == 2
    assert "engine version 0.0.1+older in the store" in capsys.readouterr().err
    doc["attributes"]["gearpair_store"] = 99
    meta.write_text(json.dumps(doc))
    assert main(argv) == 2
    assert "incompatible version (store format 99" in capsys.readouterr().err


def test_maps_of_a_three_parameter_grid_one_per_value_or_the_chosen_slice(tmp_path, capsys):
    argv = ["sweep", "speed_rpm=100,150", "mu=0,0.03", "torque=3000,3900", "--scheduler",
            "serial", "--out", str(tmp_path / "m"), "--quiet", *QUICK_ARGS]
    assert main(argv) == 0
    files = json.loads(capsys.readouterr().out)["files"]
    assert sorted(os.path.basename(p) for p in files["maps"]) == [
        "m_map_torque=3000.png", "m_map_torque=3900.png"]
    assert main([*argv, "--slice", "torque=3800"]) == 0  # the nearest value
    files = json.loads(capsys.readouterr().out)["files"]
    assert [os.path.basename(p) for p in files["maps"]] == ["m_map_torque=3900.png"]
    assert os.path.getsize(files["maps"][0]) > 5000
    summary = json.loads((tmp_path / "m.json").read_text())
    assert summary["ok"] == 8 and summary["settings"]["kept_periods"] == 10


def test_one_parameter_sweep_keeps_its_files_and_stores_too(tmp_path, capsys):
    assert main(["sweep", "mu", "0,0.03", "--scheduler", "serial", "--out",
                 str(tmp_path / "o"), "--no-plot", *QUICK_ARGS]) == 0
    cap = capsys.readouterr()
    assert "0 done (0 ok, 0 failed, 0 invalid), 2 to run" in cap.err
    assert "CPU" in cap.err and "speed-up over one core" in cap.err
    assert (tmp_path / "o.csv").exists() and (tmp_path / "o_poincare.csv").exists()
    ds = open_dataset(tmp_path / "o.zarr")
    assert ds["stick_ratio"].dims == ("mu",) and int(ds["done"].sum()) == 2


def _done(store) -> int:
    """Points stored so far (0 before the store exists)."""
    import zarr

    try:
        return int(np.sum(zarr.open_array(store / "done", mode="r")[...]))
    except Exception:  # noqa: BLE001 - not created yet
        return 0


# -- a killed client ----------------------------------------------------------------------------
@pytest.mark.slow
def test_client_killed_at_random_moments_leaves_a_readable_store(tmp_path):
    """SIGKILL or SIGINT at random moments (start-up, store creation, between and inside point
    writes), 10 times: the store opens every time, finished points stay finished, and each
    completed store equals an uninterrupted run. A store that completes between kills is
    followed by a new one, so that the kills keep landing inside sweeps."""
    g = ["speed_rpm=100,130,160,190", "mu=0.01,0.02,0.03,0.04"]
    rnd = random.Random(26)
    stores, done_before, mid_sweep = [tmp_path / "k0.zarr"], 0, 0

    def cmd(store):
        return [sys.executable, "-m", "gearpair.cli", "sweep", *g, "--scheduler", "serial",
                "--out", str(tmp_path / "k"), "--store", str(store), "--quiet", "--no-plot",
                *QUICK_ARGS]

    for kill in range(30):  # 10 kills, and more until 3 of them landed inside a sweep
        if kill >= 10 and mid_sweep >= 3:
            break
        store = stores[-1]
        p = subprocess.Popen(cmd(store), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        if kill % 4 == 0:  # anywhere: start-up, store creation or the points
            time.sleep(rnd.uniform(0.2, 4.0))
        else:  # while the points run: once a random number of them is stored
            target = min(done_before + rnd.randint(1, 6), 15)
            t0 = time.monotonic()
            while p.poll() is None and time.monotonic() - t0 < 60:
                if _done(store) >= target:
                    break
                time.sleep(0.01)
            time.sleep(rnd.uniform(0.0, 0.05))
        p.send_signal(signal.SIGKILL if kill % 2 == 0 else signal.SIGINT)
        _, err = p.communicate(timeout=60)
        # killed; interrupted (130, or -SIGINT before the sweep caught it, or 1 when Python
        # itself was still starting); or already done
        early = p.returncode == 1 and "KeyboardInterrupt" in err.decode()
        assert early or p.returncode in (-signal.SIGKILL, -signal.SIGINT, 130, 0), \
            err.decode()[-2000:]
        if not store.exists():
            continue
        ds = open_dataset(store).load()  # always readable
        assert consolidated(store)  # and by xr.open_zarr without a warning
        done = int(ds["done"].sum())
        assert done >= done_before
        ok = ds["done"] == 1  # a point marked done has its whole record
        assert bool((ds["stick_ratio"].notnull() | ~ok).all())
        assert bool((ds["poincare_count"].where(ok, 10) == 10).all())
        mid_sweep += 0 < done < 16
        done_before = done
        if done == 16:
            stores.append(tmp_path / f"k{len(stores)}.zarr")
            done_before = 0
    assert mid_sweep >= 3  # the kills did land inside sweeps
    run_grid(Grid.parse(g), QUICK, tmp_path / "w.zarr", scheduler="serial", progress=False)
    whole = open_dataset(tmp_path / "w.zarr").load()
    for store in stores:
        subprocess.run(cmd(store), check=True, stdout=subprocess.DEVNULL, timeout=120)
        ds = open_dataset(store).load()
        assert int(ds["done"].sum()) == 16
        for name in PHYSICS:
            if name in ds:
                np.testing.assert_array_equal(ds[name].values, whole[name].values,
                                              err_msg=name)


def test_progress_on_a_terminal_and_quiet(tmp_path):
    """On a terminal the bar is redrawn in place with done/total, rate, time left and failed
    points; without progress nothing is written."""
    import io

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    g = Grid.parse(["mu=0.01,0.02,0.03"])
    term = Terminal()
    run_grid(g, QUICK, tmp_path / "t.zarr", scheduler="serial", stream=term)
    text = term.getvalue()
    assert text.startswith("store ") and "3 to run" in text
    assert "\rsweep [" in text and "3/3" in text and "points/s" in text and "ETA" in text
    assert "failed 0" in text and text.endswith("\n")
    quiet = Terminal()
    run_grid(g, QUICK, tmp_path / "q.zarr", scheduler="serial", stream=quiet, progress=False)
    assert quiet.getvalue() == ""


def test_recorded_effects_resume_as_settings_and_an_unknown_one_is_refused(tmp_path):
    """A store records each effect as a setting by its `Effects` name: one it lacks (an
    effect added since) takes the default and resumes; one this gearpair has not (an effect
    since renamed) is refused naming it, not a traceback."""
    from gearpair.sweep.store import StoreError

    g = Grid.parse(["mu=0.01,0.02"])
    path = tmp_path / "e.zarr"
    Store.open_or_create(path, g, QUICK.replace(friction="nominal")).close()
    meta = path / "zarr.json"
    doc = json.loads(meta.read_text())
    recorded = doc["attributes"]["settings"]
    assert recorded["friction"] == "nominal" and recorded["backlash"] is None
    del recorded["backlash"]  # as if written before backlash existed
    meta.write_text(json.dumps(doc))
    st = Store.open_or_create(path, g, QUICK.replace(friction="nominal"))
    assert st.settings.backlash is None and st.settings.effects().friction == "nominal"
    st.close()
    recorded["gear_backlash"] = 1e-4  # a setting this gearpair has not
    meta.write_text(json.dumps(doc))
    with pytest.raises(StoreError, match=r"gear_backlash = 0\.0001 in the store, no such "
                       "setting now"):
        Store.open_or_create(path, g, QUICK.replace(friction="nominal"))


def test_a_store_being_written_is_refused_to_a_second_sweep(tmp_path, capsys):
    """Two sweeps writing one store would lose points to each other's chunk rewrites: the
    second is refused while the first holds the store (the lock goes with its process)."""
    g = Grid.parse(["mu=0.01,0.02"])
    first = Store.open_or_create(tmp_path / "l.zarr", g, QUICK.replace(min_periods=16))
    argv = ["sweep", "mu=0.01,0.02", "--scheduler", "serial", "--store",
            str(tmp_path / "l.zarr"), "--out", str(tmp_path / "l"), *QUICK_ARGS]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "is being written by another sweep" in err and err.count("\n") == 1
    assert main([*argv, "--new-store"]) == 2  # not replaced under the writer either
    first.close()
    assert main(argv) == 0
