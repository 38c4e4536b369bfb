"""Per-step cost of GearPair.fmu (or the no-op slave) in a C master: ``step_timer.c``.

    python examples/bench_noop/c_host_steps.py FMU [FMU ...] [--step 1e-4] [--steps 2000]

For each FMU: extract it, compile ``step_timer.c`` (the system C compiler, fmpy's FMI 2
headers), and run it with the environment a pythonfmu FMU needs in a non-Python host
(``LD_PRELOAD`` of this Python's libpython, ``PYTHONPATH`` of its site-packages; see
docs/hosts.md). Each step sets the inputs ``torque`` and ``speed``, calls ``fmi2DoStep`` and
gets ``dte``, ``mesh_force``, ``friction_force`` (Real) and ``contact_state`` (Integer); the
best of ``repeats`` blocks of ``steps`` steps is reported in microseconds per step. `measure`
is the function a benchmark calls.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "step_timer.c"
INPUTS = {"torque": 3900.0, "speed": 100.0 * math.pi / 30.0}  # N.m, rad/s (100 r/min)
REAL_OUTPUTS = ("dte", "mesh_force", "friction_force")
INT_OUTPUTS = ("contact_state",)


def host_environment() -> dict[str, str]:
    """Environment for a pythonfmu FMU in a C host running this Python's packages."""
    lib = Path(sysconfig.get_config_var("LIBDIR") or "") / (
        sysconfig.get_config_var("LDLIBRARY") or "")
    if lib.suffix != ".so" or not lib.is_file():
        raise RuntimeError(f"{lib} is not a shared libpython: this Python cannot host the FMU")
    env = dict(os.environ, LD_PRELOAD=str(lib), PYTHONPATH=sysconfig.get_paths()["purelib"])
    env.pop("PYTHONHOME", None)
    return env


def compile_timer(folder: str | Path) -> Path:
    """Compile ``step_timer.c`` into ``folder``; returns the executable."""
    import fmpy

    exe = Path(folder) / "step_timer"
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise RuntimeError("no C compiler (cc or gcc) found")
    subprocess.run([cc, "-O2", "-std=c99", "-I", str(Path(fmpy.__file__).parent / "c-code"),
                    "-o", str(exe), str(SOURCE), "-ldl"], check=True)
    return exe


def measure(fmu: str | Path, step: float = 1e-4, steps: int = 2000, repeats: int = 5,
            start: dict[str, float] | None = None, exe: str | Path | None = None,
            timeout: float = 600.0) -> dict:
    """Run the C timing host on ``fmu``.

    Parameters
    ----------
    fmu : GearPair.fmu or an FMU with the same variable names (the no-op slave)
    step : communication step (s)
    steps, repeats : steps per timed block and timed blocks (after one warm-up block)
    start : Real start values by name (default: `INPUTS`); parameters allowed
    exe : a compiled ``step_timer`` (default: compile one)

    Returns
    -------
    dict: ``wall_us`` and ``cpu_us`` per step (best block), ``start_to_first_step_s``
    (instantiate to the end of the first step), ``h``, ``steps``, ``repeats``.
    """
    import fmpy

    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    values = dict(INPUTS, **(start or {}))
    with tempfile.TemporaryDirectory(prefix="gearpair_c_host_") as tmp:
        unzip = fmpy.extract(str(fmu), unzipdir=os.path.join(tmp, "fmu"))
        exe = exe or compile_timer(tmp)
        args = [str(exe), unzip, md.coSimulation.modelIdentifier, md.guid, repr(step),
                str(steps), str(repeats)]
        for name, x in values.items():
            args += ["-r", f"{vr[name]}={float(x)!r}"]
        args += ["-u", ",".join(str(vr[n]) for n in INPUTS),
                 "-o", ",".join(str(vr[n]) for n in REAL_OUTPUTS),
                 "-n", ",".join(str(vr[n]) for n in INT_OUTPUTS)]
        proc = subprocess.run(args, env=host_environment(), cwd=tmp, capture_output=True,
                              text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"step_timer failed (exit {proc.returncode}): {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fmu", nargs="+")
    ap.add_argument("--step", type=float, default=1e-4, help="communication step (s)")
    ap.add_argument("--steps", type=int, default=2000, help="steps per timed block")
    ap.add_argument("--repeats", type=int, default=5, help="timed blocks")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="gearpair_c_host_") as tmp:
        exe = compile_timer(tmp)
        for fmu in args.fmu:
            got = measure(fmu, args.step, args.steps, args.repeats, exe=exe)
            print(json.dumps(dict(fmu=str(fmu), **got)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
