"""The native step: the engine's compiled step called from C at its address, timed beside the FMU.

Before GearPair.fmu had the engine in its binary, it was a pythonfmu FMU whose C layer called
the engine's compiled step (`gearpair.fast.native.step_entry`, numba's C wrapper, from
`FastEngine.native_step`) at its C address. That FMU is gone; this module runs the same call
path for the bench's C-host section (`gearpair.bench.chost.host_native`), so that the FMU's
step is compared with it in the same run, not with a number from another day.

A child process (`main`, ``python -m gearpair.bench.nativestep``) builds a `FastEngine` at the
bench's point, compiled for the CPU target of the FMU's object (`gearpair.shipped.
portable_target`, with a numba cache of its own: `child_env`), and loads the small C library
``native_step_loop.c`` (compiled by `build_loop`) with ctypes. Its function runs the master's
loop in C: per step the inputs and the step's times into the engine's step block, with
``X_FMU`` = 1 (the FMU's checks and rollback, as an FMU's doStep), the call of the compiled
step through a function pointer, the outputs from the step record. The C host
(``fmi2_bench_host -t native``) tells the child through a pipe which block to step and reads
its times and the digest of its outputs back.
"""

from __future__ import annotations

import ctypes
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

from .settings import HERE

LOOP_SOURCE = HERE / "native_step_loop.c"


def build_loop(workdir: Path) -> Path:
    """Compile ``native_step_loop.c`` into a shared library in ``workdir`` (as the C host is
    compiled there) and return its path.

    Raises
    ------
    RuntimeError
        Without gcc, or when it fails.
    """
    gcc = shutil.which("gcc")
    if gcc is None:
        raise RuntimeError("gcc not found")
    lib = Path(workdir) / "native_step_loop.so"
    proc = subprocess.run([gcc, "-O2", "-shared", "-fPIC", "-o", str(lib), str(LOOP_SOURCE)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"gcc failed on {LOOP_SOURCE.name}: {proc.stderr.strip()[-500:]}")
    return lib


def child_env(env: dict | None = None) -> dict:
    """The environment of the child: numba compiles for the CPU target of the FMU's object
    (x86-64-v2 on x86-64, no extra features, as `gearpair.aot` compiles it), into a cache
    of its own (a cache is keyed by the CPU it was compiled for, and the bench's own engine
    is compiled for this machine's CPU), without the package's shipped code, so that the
    step's machine code is made as the FMU's is and only the call path differs."""
    from ..shipped import portable_target, user_cache_dir

    target, _ = portable_target()
    child = dict(os.environ if env is None else env, NUMBA_CPU_NAME=target,
                 NUMBA_CPU_FEATURES="", GEARPAIR_SHIPPED_CODE="0", GEARPAIR_COMPILE_NOTICE="")
    base = user_cache_dir()
    if base is not None:  # kept: later runs load the compiled engine (seconds, not ~30 s)
        child["NUMBA_CACHE_DIR"] = os.path.join(base, f"bench-native-{target}")
    else:  # no disk cache: numba compiles in memory
        child.pop("NUMBA_CACHE_DIR", None)
    return child


def start(lib: Path, job: dict, fds: tuple[int, int], env: dict | None = None
          ) -> tuple[subprocess.Popen, dict]:
    """Start the child (`main`) with the pipe ends ``fds`` (it reads block numbers from the
    first, answers on the second) and wait until it has made its first step.

    ``job``: ``regime``, ``rtol``, ``torque`` (N.m), ``speed`` (rad/s), ``step`` (s), ``n``
    (steps a block), ``outputs`` (record names). Returns the process and its ready line
    (the CPU numba compiled for, the first step's code).

    Raises
    ------
    RuntimeError
        When the child ends or fails before it is ready.
    """
    args = [sys.executable, "-m", __name__, str(lib), json.dumps(job), *map(str, fds)]
    proc = subprocess.Popen(args, env=child_env(env), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, pass_fds=fds,
                            cwd=str(Path(lib).parent))
    line = proc.stdout.readline()  # the first start compiles the engine: up to a minute
    if not line.startswith("READY "):
        proc.kill()
        _, err = proc.communicate()
        raise RuntimeError(f"the native step's process failed before its first step "
                           f"(exit {proc.returncode}): {(line + err)[-1000:]}")
    return proc, json.loads(line[len("READY "):])


def main(argv: list[str]) -> int:
    """The child: the engine, its first step, then block by block as the C host says."""
    import numba
    import numpy as np

    from .. import make_engine
    from ..stepblock import STEP_RECORD, X_FMU, X_H, X_REC, X_SPEED, X_TCHK, X_TEND, X_TORQUE
    from .runs import regime_effects

    lib_path, job = argv[0], json.loads(argv[1])
    go, back = int(argv[2]), int(argv[3])
    lib = ctypes.CDLL(lib_path)
    loop = lib.native_block
    loop.restype = ctypes.c_int64
    loop.argtypes = [ctypes.c_int64, ctypes.c_int64, ctypes.c_void_p, ctypes.c_void_p,
                     ctypes.c_int64, ctypes.c_double, ctypes.c_double, ctypes.c_double,
                     ctypes.c_int64, ctypes.c_int64, ctypes.c_void_p, ctypes.c_void_p]
    eng = make_engine(None, regime_effects(job["regime"]), "fast", rtol=job["rtol"])
    torque, speed, h, n = float(job["torque"]), float(job["speed"]), float(job["step"]), \
        int(job["n"])
    # at rest at t = 0 under the inputs, as the FMU initializes (its start values of the
    # inputs are the bench's point)
    eng.reset(0.0, torque, speed)
    _, address, table = eng.native_step()
    x = eng.block
    slots = np.array([X_TEND, X_TCHK, X_H, X_TORQUE, X_SPEED, X_FMU,
                      *(X_REC + STEP_RECORD.index(k) for k in job["outputs"])], dtype=np.int64)
    digest = np.array([1469598103934665603], dtype=np.uint64)  # FNV-1a's offset basis
    times = np.zeros(2)

    def block(first: int, count: int) -> int:
        return loop(address, table, x.ctypes.data, slots.ctypes.data, len(job["outputs"]),
                    torque, speed, h, first, count, digest.ctypes.data, times.ctypes.data)

    first_code = block(-1, 1)  # the host's first step, from 0, outside the timed blocks
    digest[0] = 1469598103934665603  # the host's digest also starts after it
    print("READY " + json.dumps({"cpu_name": numba.config.CPU_NAME,
                                 "cpu_features": numba.config.CPU_FEATURES,
                                 "first_code": int(first_code)}), flush=True)
    if first_code != 0:
        return 1
    with os.fdopen(go, "rb", buffering=0) as rd, os.fdopen(back, "wb", buffering=0) as wr:
        while True:
            got = rd.read(8)
            if len(got) < 8:
                return 1
            b = int.from_bytes(got, sys.byteorder, signed=True)
            if b < 0:
                return 0
            code = block(b * n, n)
            if code != 0:
                print(f"step code {code} in block {b}", file=sys.stderr, flush=True)
                return 1
            wr.write(times.tobytes() + digest.tobytes())


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
