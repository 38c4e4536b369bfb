"""The `gearpair` command line: help, version and the bare command, output options checked
before a run starts, CSV files that go back in as inputs, and figure titles."""

from __future__ import annotations

import argparse
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from gearpair.cli import build_parser, main
from gearpair.cli.simulate import plot_title
from gearpair.scenes import load_scene

ROOT = Path(__file__).resolve().parents[1]


# -- help, version -------------------------------------------------------------------------
def _subparsers(ap: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    act = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    return dict(act.choices)


def test_every_option_of_every_command_has_help_with_choices_and_default():
    subs = _subparsers(build_parser())
    assert set(subs) == {"modes", "simulate", "sweep", "sensitivity", "bench"}
    for name, sp in subs.items():
        for act in sp._actions:
            if isinstance(act, argparse._HelpAction):
                continue
            where = f"gearpair {name} {'/'.join(act.option_strings) or act.dest}"
            assert act.help and len(act.help) > 10, where
            if act.option_strings and act.type in (float, int) and name != "bench":
                assert "default" in act.help, where  # every number says its default
            if act.option_strings and act.choices is None and act.type is None \
                    and act.nargs == 0:
                continue  # a flag
    sim = subs["simulate"].format_help()
    for text in ("{off,nominal,regularized,stick_slip}", "(N.m)", "(r/min)", "default 3900",
                 "[1e-12, 0.001]"):
        assert text in sim, text
    sweep = subs["sweep"].format_help()
    assert "{stick_slip" not in sweep and "{off,nominal,regularized,stick_slip}" in sweep
    assert "default 1e-07" in sweep


def test_version_and_bare_command(capsys):
    from gearpair import __version__

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"gearpair {__version__}"
    assert main([]) == 2
    out = capsys.readouterr().out
    assert out.startswith("usage: gearpair") and "simulate" in out and "modes" in out


# -- output options checked before the run -------------------------------------------------
UNWRITABLE = Path("/proc")

needs_proc = pytest.mark.skipif(not UNWRITABLE.is_dir(), reason="needs Linux /proc")


def _one_line_error(capsys, *words):
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err
    return err


@needs_proc
@pytest.mark.parametrize("argv, flag", [
    (["simulate", "--out", str(UNWRITABLE / "run.csv")], "--out"),
    (["simulate", "--plot", str(UNWRITABLE / "run.png")], "--plot"),
    (["sweep", "mu", "0.01,0.02", "--scheduler", "serial", "--out", str(UNWRITABLE / "sw")],
     "--out"),
    (["bench", "--quick", "--plot", str(UNWRITABLE / "wp.png")], "--plot"),
])
def test_unwritable_output_folder_is_refused_before_the_run(argv, flag, no_runs, capsys):
    assert main(argv) == 2
    _one_line_error(capsys, f"gearpair: error: {flag} {UNWRITABLE}", "cannot write")


def test_sweep_prefix_whose_file_is_a_folder_is_refused_before_the_run(tmp_path, no_runs,
                                                                       capsys):
    (tmp_path / "speed.json").mkdir()  # PREFIX.json cannot be written
    assert main(["sweep", "mu", "0.01", "--scheduler", "serial", "--out",
                 str(tmp_path / "speed")]) == 2
    _one_line_error(capsys, f"--out {tmp_path / 'speed'}", "speed.json, which it would "
                    "write, is a folder")
    # --no-plot: PREFIX.png is not written, so a folder of that name is no obstacle
    (tmp_path / "other.png").mkdir()
    with pytest.raises(AssertionError, match="run started"):
        main(["sweep", "mu", "0.01", "--scheduler", "serial", "--no-plot", "--out",
              str(tmp_path / "other")])


def test_bench_plot_format_is_checked_before_the_run(tmp_path, no_runs, capsys):
    assert main(["bench", "--quick", "--plot", str(tmp_path / "wp.xyz")]) == 2
    _one_line_error(capsys, "--plot", "unknown figure format 'xyz'")


def test_sweep_load_check_leaves_points_outside_the_model_to_the_run(no_runs, tmp_path,
                                                                     capsys):
    """A point outside the model (a negative torque without backlash) is an `invalid` record
    of the run, not an error of the load check before it; a value outside its parameter's
    range (mu = -1) is refused before any point runs, one line, exit status 2."""
    with pytest.raises(AssertionError, match="run started"):
        main(["sweep", "--scheduler", "serial", "--out", str(tmp_path / "t"), "torque", "--",
              "-1000,3900"])
    capsys.readouterr()
    assert main(["sweep", "--scheduler", "serial", "--out", str(tmp_path / "m"), "mu", "--",
                 "-1,0.02"]) == 2
    _one_line_error(capsys, "mu = -1.0", "out of range")


# -- CSV files and figures -----------------------------------------------------------------
def test_csv_written_by_gearpair_goes_back_in(tmp_path, capsys):
    out = tmp_path / "run.csv"
    assert main(["simulate", "--engine", "fast", "--t-end", "0.003", "--speed-rpm", "150",
                 "--torque", "3000", "--out", str(out)]) == 0
    capsys.readouterr()
    header = out.read_text().splitlines()[0].split(",")
    assert header[0] == "time" and all(re.fullmatch(r"[a-z0-9_]+", h) for h in header)
    for name in ("torque", "speed", "load_speed"):  # every input of the FMU
        assert name in header
    # a scene reads its torque and speed back, without a word about the output columns
    # (they are gearpair's own output names, not misspelt inputs)
    scene = tmp_path / "again.toml"
    scene.write_text(f'[inputs.csv]\nfile = "{out.name}"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sc = load_scene(scene)
    assert capsys.readouterr().err == ""
    assert sc.inputs.torque(0.001) == pytest.approx(3000.0)
    assert sc.inputs.speed(0.001) == pytest.approx(150 * 2 * np.pi / 60)
    # fmpy reads the same names (its reader keeps them as they are)
    fmpy_util = pytest.importorskip("fmpy.util")
    sig = fmpy_util.read_csv(str(out))
    assert {"time", "torque", "speed", "load_speed"} <= set(sig.dtype.names)
    assert sig["load_speed"][1] == pytest.approx(sig["speed"][1] * 33 / 80)


def test_plot_title_gives_the_operating_point():
    sc = load_scene(ROOT / "examples/scenes/paper_stick_slip.toml")
    title = plot_title(sc, "fast")
    for text in ("paper_stick_slip", "100 r/min", "3900 N.m", f"mu {sc.params.mu:g}",
                 "friction stick_slip", "fast engine"):
        assert text in title, text
    ramp = load_scene(ROOT / "examples/scenes/torque_reversal_backlash.toml")
    title = plot_title(ramp, "reference")
    assert "3900->-3900 N.m ramp" in title and "backlash 100 um" in title


def test_sweep_title_gives_the_operating_point():
    from gearpair.sweep import SweepSettings, sweep_title

    title = sweep_title("speed_rpm", SweepSettings(torque=3000.0, params=(("mu", 0.03),),
                                                   friction="nominal"))
    assert "sweep of speed_rpm" in title and "3000 N.m" in title and "mu 0.03" in title
    assert "friction nominal" in title and "r/min" not in title  # the swept one is the axis
    assert "100 r/min" in sweep_title("torque", SweepSettings())
