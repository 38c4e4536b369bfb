"""How far the golden cases move under other BLAS kernels and C-library math paths.

The golden file (`make_golden.py`) was made in one environment: OpenBLAS's AVX-512 kernel
(``SkylakeX``; ``Cooperlake`` gives the same bits) and glibc's FMA paths for ``exp``, ``pow``
and ``tanh``. Until the model's setup and the engine's elementary functions stop depending on
either, another environment reproduces a case only to a spread. This script runs every golden
case in subprocesses under several environments, measures per case the largest deviation
from the golden file (each column scaled by its largest golden magnitude) and writes
``environment.json``, which `tests/test_golden.py` reads:

- ``made_in``: the environment the golden file reproduces bit for bit in;
- ``spread``: per case, the largest scaled deviation seen, and the environments measured.

Run (about 3 minutes on 2 cores)::

    .venv/bin/python tests/golden/measure_spread.py
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import make_golden  # noqa: E402

ENV_JSON = HERE / "environment.json"
MADE_IN = {"openblas": ["SkylakeX", "Cooperlake"], "libm_fma": True}
NO_FMA = "glibc.cpu.hwcaps=-AVX2,-FMA"
ENVIRONMENTS = {
    "host kernel": {},
    "Prescott": {"OPENBLAS_CORETYPE": "Prescott"},
    "Sandybridge": {"OPENBLAS_CORETYPE": "Sandybridge"},
    "Haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "Zen, libm without FMA": {"OPENBLAS_CORETYPE": "Zen", "GLIBC_TUNABLES": NO_FMA},
    "host kernel, libm without FMA": {"GLIBC_TUNABLES": NO_FMA},
}
KEYS = ("rows", "y", "state", "energy", "dirs", "stuck", "prev_active", "error")


def openblas_cores() -> list[str]:
    """The kernel each OpenBLAS loaded in this process runs (numpy's and scipy's), by
    OpenBLAS's own ``get_corename``; empty where none is found."""
    import ctypes

    import scipy.linalg  # noqa: F401  (loads scipy's OpenBLAS)

    with open("/proc/self/maps") as fh:
        libs = sorted({ln.split()[-1] for ln in fh if "openblas" in ln.lower()})
    cores = []
    for path in libs:
        lib = ctypes.CDLL(path)
        for sym in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename",
                    "openblas_get_corename64_", "openblas_get_corename"):
            fn = getattr(lib, sym, None)
            if fn is not None:
                fn.restype = ctypes.c_char_p
                cores.append(fn().decode())
                break
    return cores


def libm_fma() -> bool:
    """Whether glibc takes its FMA paths for exp, pow, tanh: the CPU has FMA and AVX2 and
    GLIBC_TUNABLES does not mask either."""
    with open("/proc/cpuinfo") as fh:
        flags = next((ln.split(":", 1)[1].split() for ln in fh if ln.startswith("flags")), [])
    tun = os.environ.get("GLIBC_TUNABLES", "")
    masked = any(f"-{f}" in tun for f in ("FMA", "AVX2"))
    return "fma" in flags and "avx2" in flags and not masked


def environment() -> dict:
    return {"openblas": openblas_cores(), "libm_fma": libm_fma()}


def is_golden_environment(made_in: dict, env: dict | None = None) -> bool:
    """Whether this process computes in the environment the golden file was made in."""
    env = environment() if env is None else env
    return (bool(env["openblas"]) and all(c in made_in["openblas"] for c in env["openblas"])
            and env["libm_fma"] == made_in["libm_fma"])


def golden() -> dict[str, np.ndarray]:
    with np.load(make_golden.GOLDEN) as f:
        return {k: f[k] for k in f.files}


def run_all(out: str) -> None:
    """Every golden case on the golden schedules, into ``out`` (npz)."""
    gold, data = golden(), {}
    for c in make_golden.all_cases():
        c = replace(c, steps=gold[f"{c.name}/steps"])
        for k, v in make_golden.run_case(c).items():
            data[f"{c.name}/{k}"] = v
    np.savez(out, **data)


def scaled_deviation(v: np.ndarray, w: np.ndarray) -> float:
    """max |v - w| over each column's largest golden magnitude (1 where that is 0 or NaN);
    NaN against NaN is no deviation, NaN against a number an infinite one."""
    if v.shape != w.shape:
        return float("inf")
    v2 = v.reshape(len(v), -1) if v.ndim else v.reshape(1, 1)
    w2 = w.reshape(len(w), -1) if w.ndim else w.reshape(1, 1)
    if not w2.size:
        return 0.0
    with np.errstate(invalid="ignore"):
        mag = np.max(np.where(np.isnan(w2), 0.0, np.abs(w2)), axis=0)
    scale = np.where(np.isfinite(mag) & (mag > 0.0), mag, 1.0)
    both_nan = np.isnan(v2) & np.isnan(w2)
    d = np.where(both_nan, 0.0, np.abs(v2 - w2))
    d = np.where(np.isnan(v2) ^ np.isnan(w2), np.inf, d)
    return float(np.max(d / scale))


def case_deviation(run: dict, gold: dict, name: str) -> float:
    return max(scaled_deviation(run[f"{name}/{k}"], gold[f"{name}/{k}"]) for k in KEYS)


def main() -> None:
    gold = golden()
    names = sorted({k.rsplit("/", 1)[0] for k in gold})
    spread = dict.fromkeys(names, 0.0)
    with tempfile.TemporaryDirectory() as tmp:
        procs = []
        for i, extra in enumerate(ENVIRONMENTS.values()):
            out = os.path.join(tmp, f"{i}.npz")
            env = {k: v for k, v in os.environ.items()
                   if k not in ("OPENBLAS_CORETYPE", "GLIBC_TUNABLES")} | extra
            procs.append((out, subprocess.Popen(
                [sys.executable, __file__, "--run", out], env=env)))
            if len(procs) % 2 == 0 or i == len(ENVIRONMENTS) - 1:
                for _, p in procs[-2:]:
                    if p.wait():
                        raise SystemExit(f"a run failed (exit {p.returncode})")
        for out, _ in procs:
            with np.load(out) as f:
                run = {k: f[k] for k in f.files}
            for n in names:
                spread[n] = max(spread[n], case_deviation(run, gold, n))
    ENV_JSON.write_text(json.dumps({
        "made_in": MADE_IN, "measured_under": list(ENVIRONMENTS),
        "spread": {n: float(f"{s:.3g}") for n, s in spread.items()}}, indent=1) + "\n")
    print(f"{ENV_JSON.name}: {sum(s > 0 for s in spread.values())} of {len(names)} cases "
          f"move, largest {max(spread.values()):.3g}", file=sys.stderr)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--run"]:
        run_all(sys.argv[2])
    else:
        main()
