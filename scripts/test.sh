#!/usr/bin/env bash
# Set up and run the whole test suite (CI runs exactly this).
# The tests run on every core (pytest-xdist, one worker per core, whole test files per
# worker so that a file's shared runs are computed once); GEARPAIR_TEST_WORKERS=N sets the
# number of workers, 0 runs them in this one process. Serial, as before: pytest -q.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check .
workers=${GEARPAIR_TEST_WORKERS:-$(nproc 2>/dev/null || echo 1)}
if [ "$workers" -gt 1 ]; then
    .venv/bin/python -m pytest -q -n "$workers" --dist loadfile "$@"
else
    .venv/bin/python -m pytest -q "$@"
fi
