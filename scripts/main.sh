#!/usr/bin/env bash
# The main job: set up, build dist/GearPair.fmu, simulate the default scene with fmpy.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python build_fmu.py
mkdir -p out
.venv/bin/fmpy simulate dist/GearPair.fmu --stop-time "${STOP_TIME:-0.5}" \
    --output-interval 1e-4 --output-file out/default_run.csv
.venv/bin/python - <<'PY'
import numpy as np
d = np.genfromtxt("out/default_run.csv", delimiter=",", names=True)
print(f"out/default_run.csv: {len(d)} rows, t = {d['time'][0]:g}..{d['time'][-1]:g} s")
print(f"  mesh force kN  min {d['mesh_force'].min()/1e3:.2f}  mean {d['mesh_force'].mean()/1e3:.2f}"
      f"  max {d['mesh_force'].max()/1e3:.2f}")
print(f"  stick fraction {d['stick_fraction'][1:].mean():.3f}   "
      f"separation fraction {d['separation_fraction'][1:].mean():.3f}")
PY
