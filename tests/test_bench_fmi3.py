"""The bench's GearPair3.fmu and Wine rows (`gearpair.bench.fmi3`) apart from the quick run:
where they are skipped and why, a short Wine run, and the ratios they report.

No timing is asserted (the machine is shared): structure, counts and the same output bits.
"""

from __future__ import annotations

import importlib.util
import shutil
import zipfile
from dataclasses import replace

import pytest

from gearpair import bench
from gearpair.bench import fmi3
from gearpair.bench import wine as bench_wine

pytestmark = pytest.mark.skipif(
    any(importlib.util.find_spec(m) is None for m in ("pythonfmu", "fmpy")),
    reason="pythonfmu/fmpy missing")


def test_summarize_takes_medians_of_the_per_round_ratios():
    got = {"n": 10, "h": 1e-4, "rounds": 3, "variants": {
        "fmi2": {"wall_s": [1e-4, 2e-4, 1e-4], "cpu_s": [1e-4, 1e-4, 1e-4], "calls": 30,
                 "early": 0, "events": 0, "digest": "a"},
        "fmi3": {"wall_s": [1.1e-4, 2e-4, 0.9e-4], "cpu_s": [1e-4, 1e-4, 1e-4], "calls": 30,
                 "early": 0, "events": 0, "digest": "a"},
        "fmi3_events": {"wall_s": [1.1e-4, 2.4e-4, 1.08e-4], "cpu_s": [1e-4, 1e-4, 1e-4],
                        "calls": 36, "early": 6, "events": 6, "digest": "b"}}}
    out = fmi3.summarize(got)
    assert out["simulated_s"] == pytest.approx(3e-3)
    assert out["fmi3_over_fmi2"] == pytest.approx(1.0)  # rounds: 1.1, 1.0, 0.9
    assert out["fmi3_over_fmi2_best"] == pytest.approx(0.9)
    assert out["identical"] and not out["identical_early"]
    assert out["fmi3_events_over_fmi3"] == pytest.approx(1.2)  # rounds: 1.0, 1.2, 1.2
    v = out["variants"]["fmi3_events"]
    assert v["early_per_s"] == pytest.approx(2000.0) and v["calls_per_s"] == 12000.0
    assert v["wall_mean_us"] == pytest.approx((11.0 + 24.0 + 10.8) / 3)
    assert v["per_sim_s"] == pytest.approx(4.58e-4 / 3e-3)
    # 0.2 x fmi3's 4e-4 s per 3e-3 s simulated, per early return (2000 a simulated s)
    assert out["fmi3_events_extra_us"] == pytest.approx(1e6 * 0.2 * (4 / 30) / 2000.0)
    assert out["fmi3_events_extra_us_cpu"] == pytest.approx(0.0)


def test_fmi3_rows_skipped_with_a_note_without_gearpair3(fmu_path, tmp_path):
    alone = tmp_path / "GearPair.fmu"
    shutil.copy(fmu_path, alone)
    out = fmi3.fmi3_measurements(bench.QUICK, alone, tmp_path / "work")
    assert out["note"].startswith("GearPair3.fmu rows skipped: no ") and "build_fmu.py" in \
        out["note"]
    # a GearPair3.fmu of another build (another instantiation token) is not measured
    other = tmp_path / "GearPair3.fmu"
    with zipfile.ZipFile(fmu_path.with_name("GearPair3.fmu")) as z, \
            zipfile.ZipFile(other, "w") as w:
        for item in z.infolist():
            data = z.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'instantiationToken="', b'instantiationToken="x')
            w.writestr(item, data)
    out = fmi3.fmi3_measurements(bench.QUICK, alone, tmp_path / "work")
    assert "of another build" in out["note"], out
    # a skipped section has no target row, and the report prints its note
    from importlib import import_module

    from gearpair.bench.targets import _fmi3_targets

    assert _fmi3_targets(out) == []
    assert import_module("gearpair.bench.report")._fmi3_host({"fmi3_host": out}) == \
        [out["note"], ""]


def test_wine_rows_skipped_with_one_line_without_the_tools(fmu_path, tmp_path, monkeypatch):
    monkeypatch.setattr(bench_wine.shutil, "which", lambda name: None)
    out = fmi3.wine_measurements(replace(bench.DEFAULT, wine_runs=1), fmu_path, tmp_path)
    assert out["note"].startswith("win64 under Wine skipped: no wine64 (or wine) and no "
                                  "x86_64-w64-mingw32-gcc"), out
    from importlib import import_module

    lines = import_module("gearpair.bench.report")._wine_host({"wine_host": out})
    assert lines == [out["note"], ""]


def test_wine_rows_on_a_short_run(fmu_path, tmp_path):
    """The host built for Windows steps the win64 DLL under Wine and gives the linux64
    binary's output bits; its per-step cost is reported beside the linux64 one."""
    have, why = bench_wine.tools()
    if have is None:
        pytest.skip(why)
    with zipfile.ZipFile(fmu_path) as z:
        if "binaries/win64/GearPair.dll" not in z.namelist():
            pytest.skip("the FMU has no win64 binary")
    s = replace(bench.QUICK, wine=True, wine_runs=1, host_n=100, host_rounds=2)
    out = fmi3.wine_measurements(s, fmu_path, tmp_path)
    assert out["note"] is None and out["error"] is None, out
    assert out["identical"], out
    for platform in ("linux", "win64"):
        assert len(out[f"{platform}_us"]) == 2 and min(out[f"{platform}_us"]) > 0
        assert out[f"{platform}_best_us"] <= out[f"{platform}_median_us"]
    assert out["win64_over_linux"] == pytest.approx(out["win64_median_us"] /
                                                    out["linux_median_us"])
