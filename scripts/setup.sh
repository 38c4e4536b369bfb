#!/usr/bin/env bash
# Create .venv (if missing) and install gearpair with its FMU, test and plot extras.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
# System libraries of the optional co-simulation hosts: ecospy's engine links libtbb.so.12.
if command -v apt-get >/dev/null 2>&1 && command -v dpkg >/dev/null 2>&1 \
        && ! dpkg -s libtbb12 >/dev/null 2>&1; then
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo -n"
    { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq libtbb12; } >/dev/null 2>&1 \
        || echo "setup.sh: could not install libtbb12; the ecospy host tests will be skipped" >&2
fi
# OMSimulator (optional co-simulation master, tests/test_omsimulator.py), when present at
# $OMSIMULATOR_HOME or ../shared/tools/omsimulator: its binaries link ICU 72 (libicu72).
OMS_HOME=${OMSIMULATOR_HOME:-../shared/tools/omsimulator}
if [ -x "$OMS_HOME/bin/OMSimulator" ] && command -v apt-get >/dev/null 2>&1 \
        && command -v dpkg >/dev/null 2>&1 && ! dpkg -s libicu72 >/dev/null 2>&1; then
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo -n"
    { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq libicu72; } >/dev/null 2>&1 \
        || echo "setup.sh: could not install libicu72; the OMSimulator tests will be skipped" >&2
fi
# A C compiler: build_fmu.py compiles the FMU's binary (fmu_src/c) and the host tests build
# C hosts. Installed like libtbb12 when missing and apt-get is usable.
if ! command -v "${CC:-gcc}" >/dev/null 2>&1 && ! command -v cc >/dev/null 2>&1; then
    if command -v apt-get >/dev/null 2>&1; then
        SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo -n"
        { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq gcc libc6-dev; } >/dev/null 2>&1 || true
    fi
    command -v "${CC:-gcc}" >/dev/null 2>&1 || command -v cc >/dev/null 2>&1 || {
        echo "setup.sh: no C compiler found: building GearPair.fmu needs one for its binary;" \
             "install gcc (Debian/Ubuntu: apt-get install gcc) or set CC" >&2
        exit 1
    }
fi
# Windows: build_fmu.py cross-compiles GearPair.fmu's win64 binary with mingw-w64, and
# tests/test_win64.py runs it under Wine (Debian's gcc-mingw-w64-x86-64 and wine64, x86-64
# machines only). Without them the FMU holds linux64 only and those tests are skipped.
if [ "$(uname -m)" = x86_64 ] && command -v apt-get >/dev/null 2>&1 \
        && { ! command -v x86_64-w64-mingw32-gcc >/dev/null 2>&1 \
             || ! command -v wine >/dev/null 2>&1; }; then
    SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo -n"
    { $SUDO apt-get update -qq \
        && $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gcc-mingw-w64-x86-64 \
            wine64; } \
        >/dev/null 2>&1 \
        || echo "setup.sh: could not install gcc-mingw-w64-x86-64 and wine64; GearPair.fmu" \
                "gets no win64 binary and the Wine tests will be skipped" >&2
fi
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip 2>&1 | grep -v "^WARNING: Location" || true
.venv/bin/python -m pip install -q -e '.[dev]' 2>&1 | grep -v "^WARNING: Location" || true
.venv/bin/python -c "import gearpair, pythonfmu, fmpy" 
