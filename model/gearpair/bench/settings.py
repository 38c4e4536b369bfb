"""What the benchmark runs: regimes, targets, the effect ladder and the presets."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent  # gearpair/bench: its files ship with the package
NOOP_SCRIPT = HERE / "GearPairNoop.py"  # the do-nothing slave of the plumbing floor
HOST_SOURCE = HERE / "fmi2_bench_host.c"  # the C timing host
# the C timing host of GearPair3.fmu against GearPair.fmu (gcc), and of GearPair.fmu's win64
# binary under Wine (mingw-w64)
FMI3_HOST_SOURCE = HERE / "fmi3_bench_host.c"
# the example scenes whose cost the bench times (Settings.scenes_dir): a folder of the
# current directory, where a checkout has them
SCENES_DIR = "examples/scenes"
PLAIN_PREFIX = "plain "  # method names of its rows: "plain DOP853", ...

# the regimes of every section (work-precision, step costs, FMU, targets): the paper's
# potential-energy stiffness with three friction laws
REGIMES = ("no_friction", "sliding", "stick_slip")
# and one more of the work-precision and equal-accuracy tables only: stick-slip with the
# rectangular stiffness law, where the plain scipy code can be set against other plain codes
# of the model (issue 37 item 2)
RECTANGULAR = "stick_slip_rectangular"
WP_REGIMES = (*REGIMES, RECTANGULAR)
FRICTION_OF = {"no_friction": "off", "sliding": "nominal", "stick_slip": "stick_slip",
               RECTANGULAR: "stick_slip"}
STIFFNESS_OF = {**dict.fromkeys(REGIMES, "potential_energy"), RECTANGULAR: "rectangular"}
SCIPY_METHODS = ("RK45", "DOP853", "Radau", "LSODA")
TARGET_ERROR = 1e-6  # DTE relative error of "equal accuracy"
TARGET_SPEEDUP = 50.0  # fast core against the fastest scipy method
TARGET_FMU_FACTOR = 1.2  # FMU <= factor * core + floor at a 1e-3 s step
TARGET_STICK_SLIP = 0.1  # s of wall time per simulated second
TARGET_MEMORY_MB = 500.0
TARGET_STEP_US = 7.0  # C host, 1e-4 s step, stick-slip rtol 1e-8: GearPair per step (native)
TARGET_LAYER_US = 0.5  # C host: the C layer's own cost per step (the native no-op)
TARGET_WORKER = 1.10  # C host: a worker thread's cost per step over the instantiating one's
TARGET_PAIR = 1.8  # C host: two instances in two threads, throughput over one after the other
# The FMU without Python (issue 33): a whole C-host process that instantiates, takes one
# 1e-4 s step and frees; each further instance in one process (fmi2Instantiate to the end of
# fmi2ExitInitializationMode); the step no slower than the native step it replaced (the
# engine's compiled step called from C at its address, measured in the same run:
# `chost.host_native`), the median of the per-round ratios within the project's 3 % margin
# of per-step A/B comparisons
TARGET_PROCESS_S = 0.05
TARGET_PROCESS_MB = 20.0
TARGET_INSTANCE_S = 0.005
TARGET_INSTANCE_MB = 0.5
TARGET_NATIVE_RATIO = 1.03
# GearPair3.fmu (FMI 3.0, issue 35), without early return: its step costs GearPair.fmu's
# within this fraction (C host, 1e-4 s steps, the median of the per-round ratios)
TARGET_FMI3_STEP = 0.05
# Where the two targets above were set (an AMD EPYC machine, 2 cores, 2026-11-25): the floor
# of a 1e-4 s step there (the engine's bulk cost at 1e-3 s steps per 1e-4 s simulated) and
# what two cores give two instances there at best (two free cores: 2). A machine of another
# speed or with cores that do not run two instances at full speed is held to the same
# ratios: a step of at most TARGET_STEP_US / FLOOR_AT_TARGET_US of its floor, and a pair at
# least TARGET_PAIR / CEILING_AT_TARGET of its own ceiling (two instances in two processes).
FLOOR_AT_TARGET_US = 5.66
CEILING_AT_TARGET = 2.0
TARGET_FIRST_START_S = 5.0  # first instantiation with empty caches
TARGET_LADDER = 10.0  # torsional constant stiffness at least this much cheaper than stick-slip
SCIPY_MAX_EVENTS = 1000  # switches per communication step before a scipy run counts as stalled
LADDER = (
    ("torsional, constant stiffness", dict(dof="torsional", stiffness="constant",
                                           friction="off")),
    ("torsional, time-varying", dict(dof="torsional", stiffness="potential_energy",
                                     friction="off")),
    ("6-DOF, time-varying", dict(dof="full", stiffness="potential_energy", friction="off")),
    ("6-DOF + sliding friction", dict(dof="full", stiffness="potential_energy",
                                      friction="nominal")),
    ("6-DOF + stick-slip", dict(dof="full", stiffness="potential_energy",
                                friction="stick_slip")),
)


@dataclass(frozen=True)
class Settings:
    """What the benchmark runs (simulated times in s).

    Attributes
    ----------
    name : preset name
    horizon : simulated time of the fast-core and FMU work-precision runs
    windows : per regime of the work-precision tables (the three `REGIMES`, which every
        section runs, and `RECTANGULAR` unless left out), the simulated time of the scipy
        runs on the reference engine; errors of every method are compared over this common
        window (the stick-slip ones contain the first stick at about 0.015 s) and over the
        whole run
    dt : output grid of the engine runs and of the reference
    fast_rtols : tolerances of the fast core
    fast_steps : communication steps of the fast core: ``dt`` (the common grid, the row
        ``fast``) and coarser ones (rows ``fast (step h)``, sampled every h)
    fast_alt_methods : other Runge-Kutta pairs of the fast core than its default DOP853
        (rows ``fast dp5``, on the common grid), to show what the choice of method buys
    scipy_rtols : per scipy method, its tolerances (run as the reference engine)
    plain_rtols : per scipy method, the tolerances of the plain scipy implementation
        (`gearpair.bench.plain_scipy`, rows ``plain <method>``, over ``horizon``)
    run_budget : wall-time limit (s) of one engine run of the work-precision table; a run
        that exceeds it is reported as failed
    ref_rtol : tolerance of the reference (fast core)
    check_horizon : simulated time of the cross-check of the reference against scipy DOP853
        at ``ref_rtol`` (the reference engine's); 0 skips it. The plain scipy implementation
        is cross-checked at ``ref_rtol`` over ``horizon``, the whole run over which equal
        accuracy is judged
    check_regimes : regimes cross-checked
    fmu_steps, fmu_rtols : communication steps and ``rtol`` parameter of the FMU rows
    step_horizon : simulated time of the costs at a 1e-3 s step (core, FMU, floor)
    calls : number of set+doStep+get calls timed per FMU
    host_steps : communication steps of the C host and fmpy loops (2 inputs set, doStep,
        4 outputs got)
    host_n, host_blocks : steps per timed block and blocks (the best block counts)
    host_rounds : rounds of the C host's interleaved thread modes (`chost.host_threads`:
        the medians of the per-round ratios count; ``host_n`` steps a block, a multiple of
        10)
    round_spin : multiply-adds per thread of each round's machine-ceiling arithmetic
    repeats : timed runs of the cheap measurements (the best counts)
    cost_t_end : simulated time of each scene and ladder run
    scenes_dir : the folder of scenes (``*.toml``) whose cost is timed, relative to the
        current directory: the repository's ``examples/scenes``; without it the scene rows
        are skipped with a note
    ladder_repeats : rounds of the effect ladder (each runs every rung once; the best of
        each rung counts). A round costs about half a second, and neighbouring rungs differ
        by a few per cent, so it takes more rounds than ``repeats`` to rank them
    startup : measure the first instantiation with an empty and a warm numba cache (fmpy)
        and with empty and warm caches (C host)
    memory : measure the peak RSS of a ``memory_t_end`` run recorded every 1e-4 s
    fmu : run the FMU sections (needs pythonfmu and fmpy)
    wine : time GearPair.fmu's win64 binary under Wine in the C host (`fmi3.wine_measurements`;
        skipped with a note without Wine or mingw-w64)
    wine_runs : processes per platform (linux64, win64 under Wine), alternating, each
        ``host_rounds`` blocks of ``host_n`` steps
    """

    name: str = "default"
    horizon: float = 0.1
    windows: tuple[tuple[str, float], ...] = (("no_friction", 0.005), ("sliding", 0.005),
                                              ("stick_slip", 0.02), (RECTANGULAR, 0.02))
    dt: float = 1e-4
    fast_rtols: tuple[float, ...] = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
    fast_steps: tuple[float, ...] = (1e-4, 1e-3)
    fast_alt_methods: tuple[str, ...] = ("dp5",)
    run_budget: float = 300.0
    scipy_rtols: tuple[tuple[str, tuple[float, ...]], ...] = (
        ("RK45", (1e-5, 1e-6, 1e-7)), ("DOP853", (1e-5, 1e-6, 1e-7)),
        ("Radau", (1e-4, 1e-5)), ("LSODA", (1e-5, 1e-6)))
    plain_rtols: tuple[tuple[str, tuple[float, ...]], ...] = (
        ("RK45", (1e-5, 1e-6, 1e-7, 1e-8)), ("DOP853", (1e-5, 1e-6, 1e-7, 1e-8, 1e-9)),
        ("Radau", (1e-5, 1e-6)), ("LSODA", (1e-5, 1e-6, 1e-7, 1e-8)))
    ref_rtol: float = 1e-12
    check_horizon: float = 0.002
    check_regimes: tuple[str, ...] = WP_REGIMES
    fmu_steps: tuple[float, ...] = (1e-5, 1e-4, 1e-3)
    fmu_rtols: tuple[float, ...] = (1e-8,)
    step_horizon: float = 1.0
    calls: int = 2000
    host_steps: tuple[float, ...] = (1e-4, 1e-3)
    host_n: int = 2000
    host_blocks: int = 3
    host_rounds: int = 15
    round_spin: int = 10_000_000
    repeats: int = 3
    cost_t_end: float = 0.3
    scenes_dir: str = SCENES_DIR
    ladder_repeats: int = 9
    startup: bool = True
    memory: bool = False
    memory_t_end: float = 100.0
    fmu: bool = True
    wine: bool = True
    wine_runs: int = 3

    def window(self, regime: str) -> float:
        """Simulated time of the scipy runs (and of the common error window) of a regime."""
        return dict(self.windows)[regime]

    @property
    def wp_regimes(self) -> tuple[str, ...]:
        """The regimes of the work-precision and equal-accuracy tables (those with a
        window)."""
        return tuple(r for r, _ in self.windows)


DEFAULT = Settings()
QUICK = Settings(
    name="quick", horizon=0.004, windows=tuple((r, 0.001) for r in WP_REGIMES),
    fast_rtols=(1e-6, 1e-9),
    scipy_rtols=(("RK45", (1e-5, 1e-6)), ("DOP853", (1e-5, 1e-6)), ("Radau", (1e-5,)),
                 ("LSODA", (1e-5,))),
    plain_rtols=(("RK45", (1e-6,)), ("DOP853", (1e-6, 1e-9))),
    check_horizon=0.0005, check_regimes=("stick_slip",), step_horizon=0.02, calls=150,
    host_n=100, host_blocks=2, host_rounds=3, round_spin=2_000_000,
    repeats=1, cost_t_end=0.01, ladder_repeats=1, startup=False, run_budget=60.0,
    wine=False)
FULL = Settings(
    name="full", windows=tuple((r, 0.02) for r in WP_REGIMES),
    fast_rtols=(1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11),
    scipy_rtols=(("RK45", (1e-4, 1e-5, 1e-6, 1e-7, 1e-8)),
                 ("DOP853", (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)),
                 ("Radau", (1e-4, 1e-5, 1e-6, 1e-7)), ("LSODA", (1e-4, 1e-5, 1e-6, 1e-7))),
    check_horizon=0.02, fmu_rtols=(1e-6, 1e-8), step_horizon=2.0, calls=5000, repeats=5,
    cost_t_end=0.5, ladder_repeats=15, host_rounds=30, memory=True)
PRESETS = {"quick": QUICK, "default": DEFAULT, "full": FULL}

Progress = Callable[[str], None]


def _quiet(msg: str) -> None:
    pass

