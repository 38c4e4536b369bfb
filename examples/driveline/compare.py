"""Run the driveline SSP in fmpy, libcosimpy and ecospy and tabulate how far they agree.

    python examples/driveline/compare.py [--ssp build/driveline/driveline.ssp] [--quick]

All three are fixed-step Jacobi masters: with the same communication step they compute the
same thing, and any difference comes from their time grids (fmpy and ecos accumulate
``t += h``, libcosim counts integer nanoseconds) and from initialization. The table gives
the largest difference from fmpy over the run, relative to the signal's largest magnitude.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import driveline_system as ds  # noqa: E402

MASTERS = ("fmpy", "libcosim", "ecospy")
COMPARED = ("Motor.speed", "GearPair.output_torque", "GearPair.dte", "GearPair.input_torque",
            "Load.speed", "GearPair.contact_state")
_MODULES = {"fmpy": "fmpy", "libcosim": "libcosimpy", "ecospy": "ecospy"}


def unavailable(master: str) -> str | None:
    """Why ``master`` cannot run here (module missing, native library not loading), or None."""
    try:
        __import__(_MODULES[master])
    except ImportError as e:
        return f"{_MODULES[master]} is not installed ({e}; its wheels are x86_64 only)"
    except OSError as e:  # ecospy imports but its libtbb.so.12 is missing
        return (f"{_MODULES[master]} cannot load its native library ({e}; ecospy needs the "
                "Debian package libtbb12)")
    return None


def share_gearpair() -> None:
    """Import ``gearpair`` (with its numba engine) in this process before any FMU does.

    Python hosts run every GearPair instance in their own interpreter, and the instances
    share the ``gearpair`` package first imported. When a host deletes the folder that
    package came from (fmpy does after each run), the next GearPair instance imports its own
    copy again, and numba then recompiles the engine (about 30 s of CPU per run) instead of
    loading it from its cache. Importing the package once from a folder that stays avoids
    that; the FMUs then log that they use it. Does nothing when ``gearpair`` is not installed.
    """
    try:
        import gearpair.fast  # noqa: F401
    except ImportError:
        pass


def run_all(ssp: str | Path, stop_time: float, step: float,
            masters: tuple[str, ...] = MASTERS) -> dict[str, dict[str, np.ndarray]]:
    """Run the SSP in each available master; ``{master: results}`` (see run_fmpy.run)."""
    share_gearpair()
    out = {}
    for m in masters:
        reason = unavailable(m)
        if reason:
            print(f"skipping {m}: {reason}", file=sys.stderr)
            continue
        t0 = time.perf_counter()
        out[m] = ds.sibling(f"run_{m}").run(ssp, stop_time, step)
        print(f"{m}: {len(out[m]['time'])} steps in {time.perf_counter() - t0:.1f} s",
              file=sys.stderr)
    return out


def agreement(results: dict[str, dict[str, np.ndarray]], reference: str = "fmpy",
              signals: tuple[str, ...] = COMPARED) -> list[dict]:
    """Largest difference of every other master from ``reference``, per signal.

    Rows: master, signal, ``max_abs`` (SI units), ``scale`` (largest magnitude of the
    reference signal) and ``rel = max_abs / scale``; plus ``time`` for the time grids (s).
    """
    ref = results[reference]
    rows = []
    for m, res in results.items():
        if m == reference:
            continue
        if res["time"].shape != ref["time"].shape:
            raise ValueError(f"{m} made {len(res['time'])} steps, {reference} "
                             f"{len(ref['time'])}")
        for sig in ("time",) + tuple(signals):
            diff = float(np.max(np.abs(res[sig] - ref[sig])))
            scale = float(np.max(np.abs(ref[sig])))
            rows.append({"master": m, "signal": sig, "max_abs": diff, "scale": scale,
                         "rel": diff / scale if scale > 0 else 0.0})
    return rows


def write_table(results: dict[str, dict[str, np.ndarray]], out: str | Path,
                reference: str = "fmpy") -> Path:
    """Write the agreement table (Markdown) to ``out``; return its path."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    ref = results[reference]
    h = float(ref["time"][0])
    lines = [f"Agreement with {reference}: {len(ref['time'])} steps of {h:g} s "
             f"(to {ref['time'][-1]:g} s).", "",
             "| master | signal | max abs difference | scale | relative |",
             "| --- | --- | --- | --- | --- |"]
    for r in agreement(results, reference):
        lines.append(f"| {r['master']} | {r['signal']} | {r['max_abs']:.3g} | "
                     f"{r['scale']:.4g} | {r['rel']:.2e} |")
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ssp", default=None, help="an SSP to run (default: build one)")
    ap.add_argument("--quick", action="store_true",
                    help="the 0.35 s test variant (built into build/driveline/quick)")
    ap.add_argument("--stop-time", type=float, default=None, help="s")
    ap.add_argument("--step", type=float, default=1e-4, help="communication step, s")
    ap.add_argument("--out", default=None, help="table (default: agreement.md by the SSP)")
    a = ap.parse_args(argv)
    stop = a.stop_time or (ds.QUICK_STOP_TIME if a.quick else ds.PLOT_STOP_TIME)
    folder = ROOT / "build" / "driveline" / ("quick" if a.quick else "")
    ssp = Path(a.ssp) if a.ssp else ds.sibling("build").build(
        folder, overrides=ds.QUICK if a.quick else None, stop_time=stop, step=a.step)
    path = write_table(run_all(ssp, stop, a.step), a.out or ssp.parent / "agreement.md")
    print(path.read_text(), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
