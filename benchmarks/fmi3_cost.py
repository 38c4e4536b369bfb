"""GearPair3.fmu's step cost against GearPair.fmu's, and what early return adds (#35 item 4).

Builds ``benchmarks/fmi3_cost.c`` (gcc, fmpy's FMI headers), extracts the two FMUs and runs
it in an empty environment: per variant the best of ``--rounds`` runs over ``--span`` s at
the communication step ``--h``, at the FMUs' default point (the paper's stick-slip scene:
3900 N.m, 100 r/min, mu 0.02, rtol 1e-8) unless ``--set NAME=VALUE`` changes a Float64.
Prints the CPU time per communication point, the fmi3DoStep calls and early returns per
simulated second, and each variant's ratio to GearPair.fmu.

    .venv/bin/python benchmarks/fmi3_cost.py [--dist dist] [--rounds 30]

Run it on a quiet machine: the variants alternate within each round, so a load change hits
them alike, but a busy machine spreads the rounds.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv=None) -> int:
    import fmpy

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dist", default="dist", help="folder of GearPair.fmu and GearPair3.fmu")
    ap.add_argument("--h", type=float, default=1e-4, help="communication step (s)")
    ap.add_argument("--span", type=float, default=1.0, help="simulated seconds per run")
    ap.add_argument("--rounds", type=int, default=30)
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a Float64 start value of both FMUs")
    a = ap.parse_args(argv)
    dist = Path(a.dist)
    fmu2, fmu3 = dist / "GearPair.fmu", dist / "GearPair3.fmu"
    for f in (fmu2, fmu3):
        if not f.is_file():
            print(f"no {f}: run build_fmu.py first", file=sys.stderr)
            return 2
    md2, md3 = fmpy.read_model_description(str(fmu2)), fmpy.read_model_description(str(fmu3))
    vr = {v.name: v.valueReference for v in md3.modelVariables}
    sets = []
    for item in a.set:
        name, value = item.split("=", 1)
        sets.append(f"{vr[name]}={float(value)!r}")
    with tempfile.TemporaryDirectory(prefix="fmi3_cost_") as tmp:
        tmp = Path(tmp)
        exe = tmp / "fmi3_cost"
        include = Path(fmpy.__file__).parent / "c-code"
        subprocess.run([shutil.which("gcc") or "cc", "-O2", "-std=c99", f"-I{include}", "-o",
                        str(exe), str(HERE / "fmi3_cost.c"), "-ldl"], check=True)
        u2 = fmpy.extract(str(fmu2), unzipdir=str(tmp / "u2"))
        u3 = fmpy.extract(str(fmu3), unzipdir=str(tmp / "u3"))
        out = subprocess.run([str(exe), u2, md2.guid, u3, md3.guid, repr(a.h), repr(a.span),
                              str(a.rounds), *sets], env={"PATH": "/usr/bin:/bin"},
                             capture_output=True, text=True, check=True).stdout
    rows = [line.split() for line in out.splitlines()]
    base = float(rows[0][1])
    print(f"h = {a.h:g} s, {a.span:g} s per run, best of {a.rounds}, load "
          f"{os.getloadavg()[0]:.1f}")
    print("| variant | us CPU per communication point | fmi3DoStep calls per s | "
          "early returns per s | / GearPair.fmu |")
    print("|---|---|---|---|---|")
    label = {"fmi2": "GearPair.fmu", "fmi3": "GearPair3.fmu",
             "fmi3_events": "GearPair3.fmu, early return + Event Mode",
             "fmi3_early": "GearPair3.fmu, early return, no Event Mode"}
    for name, us, calls, early in rows:
        print(f"| {label[name]} | {float(us):.2f} | {float(calls):.0f} | {float(early):.0f} | "
              f"{float(us) / base:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
