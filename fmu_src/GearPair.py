"""FMI 2.0 co-simulation slave for the gearpair model (built with pythonfmu).

Thin plumbing over the engine contract in ``gearpair.engine``: parameters and effect switches
become FMU parameters, ``do_step`` validates the inputs and advances the engine to exactly
``currentCommunicationPoint + communicationStepSize``. The FMU's C layer (``fmu_src/c``) runs
the default fast engine itself, compiled into the FMU's binary; it runs this slave, through
pythonfmu, only for the scipy reference engine (``engine = 1``). Nothing raises out of the
slave (pythonfmu would turn any exception into fmi2Fatal). A refusal (invalid parameters or
combination at initialization, a wrong communication point, a state that cannot be
restored) is logged with status error and changes nothing; the C layer turns a call during
which the slave logged an error into fmi2Error. A step the integrator cannot complete is
logged with status discard and returns False (fmi2Discard) with the state of the step start.

The ``gearpair`` package is imported from the FMU's resources folder, where the builder
(``build_fmu.py``) puts a copy of it, under the private name ``_gearpair_fmu`` (`BUNDLE`),
and the resources folder pythonfmu puts on ``sys.path`` comes off it again: a Python host
keeps its own ``gearpair``, imported before or after the FMU. Importing this module imports
neither; `interface()` and the slave's constructor do.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import math
import operator
import os
import pickle
import sys
from typing import Any

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Initial, Fmi2Status
from pythonfmu.variables import Boolean, Integer, Real

RPM = 2.0 * math.pi / 60.0  # rad/s per r/min


def _sibling(name: str):
    """The module ``name`` of the FMU's sources beside this file (in an FMU: its resources
    folder), imported under a private name of its own folder."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), name + ".py")
    key = f"_gearpair_fmu_{name}_{abs(hash(path)):x}"
    mod = sys.modules.get(key)
    if mod is None:
        spec = importlib.util.spec_from_file_location(key, path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        sys.modules[key] = mod
    return mod


_declared = _sibling("fmu_interface")  # the one declaration of the FMU's variables
_bundle = _sibling("fmu_bundle")  # the bundled gearpair package
_state = _sibling("fmu_state")  # the FMU state as bytes
BUNDLE, STATE_FORMAT = _bundle.BUNDLE, _state.STATE_FORMAT
_resources_folder, _unlist_resources = _bundle._resources_folder, _bundle._unlist_resources
_import_gearpair, _loads_state = _bundle._import_gearpair, _state._loads_state
OUTPUTS, APPENDED_OUTPUTS = _declared.OUTPUTS, _declared.APPENDED_OUTPUTS
choices = _declared.choices


def interface(gp=None) -> list[dict[str, Any]]:
    """Every FMU variable in value-reference order (`fmu_interface.interface`), for the
    bundled package ``gp`` (default: this FMU's, else the installed one)."""
    return _declared.interface(_import_gearpair(None) if gp is None else gp)

def _combination_error(effects_mod, values: dict) -> str | None:
    """The first combination the model refuses (`gearpair.effects.RULES`), said in the FMU's
    names and codes (``values``: Effects field -> value, decoded; `say_fmu`, which also
    writes the codes in the parameters' descriptions), or None."""
    for rule in effects_mod.RULES:
        if rule.refuses(values):
            return rule.message(values, effects_mod.say_fmu)
    return None


class GearPair(Fmi2Slave):
    """Spur gear pair with time-varying mesh stiffness, tooth separation and stick-slip."""

    author = "gearpair project"
    description = ("Spur gear pair dynamics (Xun, Dai & Wang 2023): time-varying mesh "
                   "stiffness, tooth separation, tooth friction with exact stick-slip switching")
    version = "0.1.0"
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=0.5, step_size=1e-4)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        _unlist_resources(self.resources)
        self._gp = _import_gearpair(_resources_folder(self.resources))
        self._warn_foreign_package()
        self._spec = interface(self._gp)
        self._sb = importlib.import_module(self._gp.__name__ + ".stepblock")
        kinds = {row[0]: row[1] for row in OUTPUTS + APPENDED_OUTPUTS}
        # the outputs in the step record's order (`stepblock.STEP_RECORD`): name, integer
        self._record = [(n, kinds.get(n) == "Integer") for n in self._sb.STEP_RECORD]
        self._param_names = tuple(v["name"] for v in self._spec if v["causality"] == "parameter")
        self._get_params = operator.attrgetter(*self._param_names)
        for v in self._spec:
            start = v["start"]
            if v["type"] == "Integer":
                setattr(self, v["name"], int(start) if start is not None else 0)
            elif v["type"] == "Boolean":
                setattr(self, v["name"], bool(start))
            else:
                setattr(self, v["name"], float(start) if start is not None else 0.0)
            self._register(v)
        self._engine = None
        self._engine_key: tuple | None = None  # parameter values the engine was built with
        self._params_set = True  # a parameter was set since the last comparison with the key
        self._start_time = 0.0
        self._stepped = False  # at least one step done since initialization
        self._poisoned: str | None = None  # set when a failed step lost the engine state

    # -- setup -------------------------------------------------------------------------------
    def _register(self, v: dict) -> None:
        cls = {"Real": Real, "Integer": Integer, "Boolean": Boolean}[v["type"]]
        kw: dict[str, Any] = dict(causality=getattr(Fmi2Causality, v["causality"]),
                                  variability=getattr(Fmi2Variability, v["variability"]),
                                  description=v["description"])
        if v["causality"] == "parameter":
            kw["initial"] = Fmi2Initial.exact
            kw["setter"] = functools.partial(self._set_parameter, v["name"])
        self.register_variable(cls(v["name"], **kw))

    def _set_parameter(self, name: str, value) -> None:
        # a master's set: the next doStep compares the parameters with the engine's
        setattr(self, name, value)
        self._params_set = True

    def _warn_foreign_package(self) -> None:
        """Warn when the package running is not this FMU's copy (only then: the folder is
        compared as a file, whatever form of path the host's resource location gave)."""
        where = os.path.dirname(os.path.abspath(getattr(self._gp, "__file__", None) or
                                                list(self._gp.__path__)[0]))
        res = _resources_folder(self.resources)
        own = os.path.join(res, "gearpair") if res else ""
        if not os.path.isdir(own):
            return  # no bundled copy (the builder's instance): nothing to compare with
        try:
            same = os.path.samefile(own, where)
        except OSError:
            same = False
        if not same:
            self.log(f"running the gearpair package at {where} (an earlier FMU instance's copy "
                     f"or the installed one), not the copy in this FMU's resources {res}",
                     Fmi2Status.warning)

    def _param_values(self) -> tuple:
        # checked after a master set a parameter (fixed ones must not change): one C call
        return self._get_params(self)

    def _build_engine(self):
        """Validate the parameters and build the engine. Raises ValueError with a message
        naming the offending parameter."""
        return self._new_engine()

    def _new_engine(self):
        gp = self._gp
        params_mod = sys.modules[gp.__name__ + ".params"]
        effects_mod = sys.modules[gp.__name__ + ".effects"]
        values = {}
        for row in params_mod.GearParams.describe():
            values[row["name"]] = getattr(self, row["name"])
        params = params_mod.GearParams(**values)
        engine = self._decode("engine", tuple(gp.ENGINES))
        effects = self._effects(effects_mod)
        params_mod.check_rtol(self.rtol)
        if engine == "fast":
            try:
                self._load_fast_engine()
                return gp.make_engine(params, effects, engine="fast", rtol=float(self.rtol))
            except ImportError as exc:  # numba missing in this host's Python
                self.log(f"engine fast unavailable ({exc}): the reference engine "
                         "(scipy) runs instead, much slower; install numba into the "
                         f"environment of {sys.executable or 'this Python'}",
                         Fmi2Status.warning)
        return gp.make_engine(params, effects, engine=engine, rtol=float(self.rtol))

    def _decode(self, name: str, codes: tuple[str, ...]) -> str:
        """The choice an integer-coded parameter selects; ValueError naming it if out of range."""
        code = getattr(self, name)
        if isinstance(code, bool) or int(code) != code or not 0 <= int(code) < len(codes):
            listing = ", ".join(f"{i} ({c})" for i, c in enumerate(codes))
            raise ValueError(f"{name} = {code!r} is out of range; allowed {listing}")
        return codes[int(code)]

    def _effects(self, effects_mod):
        """The `Effects` the effect parameters select (`gearpair.effects.OPTIONS`): codes,
        ranges and combinations checked in the FMU's names (0 codes None)."""
        values = {}
        params_mod = sys.modules[self._gp.__name__ + ".params"]
        for name, m in effects_mod.OPTIONS.items():
            v = getattr(self, m["fmu"])
            if m["kind"] == "choice":
                values[name] = self._decode(m["fmu"], m["fmu_choices"])
            elif m["kind"] == "bool":
                values[name] = bool(v)
            else:
                params_mod.check_range(m["fmu"], v, {"unit": m["unit"], "max": m["max"],
                                                     "min": 0.0 if m["none"] else m["min"]})
                values[name] = None if m["none"] and v == 0.0 else float(v)
        msg = _combination_error(effects_mod, values)
        if msg is not None:
            raise ValueError(msg)
        # the checks with the gear data (mu_static >= mu) raise ValueError from the package
        return effects_mod.Effects(
            stiffness=effects_mod.StiffnessSpec(kind=values.pop("stiffness")), **values)

    def _load_fast_engine(self) -> None:
        """Load the fast engine's compiled code (shipped in this FMU, from the user cache, or
        compiled now) once per process, and say which and how long it took (status OK)."""
        jitcache = importlib.import_module(self._gp.__name__ + ".jitcache")
        try:
            report = jitcache.load_engine()
        except Exception as e:  # noqa: BLE001 - the engine then compiles on first use
            self.log(f"fast engine: loading its compiled code failed ({type(e).__name__}: "
                     f"{e}); it compiles on first use", Fmi2Status.warning)
            return
        if report["first"]:
            self.log(jitcache.describe(report, "this FMU"), Fmi2Status.ok)

    def _ensure_engine(self) -> str | None:
        """Build the engine if needed; return an error message or None."""
        if self._engine is not None and not self._params_set:
            return None  # nothing set since the last check (the usual doStep)
        key = self._param_values()
        if self._engine is not None:
            if key != self._engine_key:
                changed = [n for n, a, b in zip(self._param_names, key, self._engine_key,
                                                strict=True) if a != b]
                return (f"parameter(s) {', '.join(changed)} changed after initialization; "
                        "they are fixed (re-instantiate or reset the FMU to change them)")
            self._params_set = False
            return None
        try:
            engine = self._build_engine()
        except (ValueError, TypeError, ArithmeticError) as e:
            return f"invalid parameters: {e}"  # names the parameter(s)
        except Exception as e:  # noqa: BLE001 - nothing may escape the slave
            return f"engine construction failed: {type(e).__name__}: {e}"
        self._engine, self._engine_key = engine, key
        return None

    def _values_of(self, summary=None) -> tuple:
        """The step record (`stepblock.STEP_RECORD`'s order) from the engine's `Outputs` and
        a step's `StepSummary` (None: no step yet, the figures describe the instant t0)."""
        o = self._engine.outputs()
        values = (o.dte, o.mesh_force, o.friction_force, o.contact_state, o.output_torque,
                  o.input_torque_reaction, o.input_torque, o.gear1_speed, o.gear2_speed,
                  o.sliding_velocity)
        if summary is None:
            summary = self._gp.engine.StepSummary.at_instant(o)
        return values + tuple(summary)[2:]  # the figures after t_start and t_end

    def _error(self, msg: str) -> bool:
        self.log(msg, Fmi2Status.error)
        return False

    # -- FMI calls ---------------------------------------------------------------------------
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._start_time = float(start_time)
        if tolerance is not None:
            self.log(f"the master's tolerance {tolerance:g} is not used; the parameter rtol "
                     f"({self.rtol:g}) sets the integrator tolerance", Fmi2Status.ok)

    def exit_initialization_mode(self):
        # Outputs at the start time, so a master reading them before the first step sees the
        # static equilibrium. A refusal is logged with status error: the C layer returns
        # fmi2Error and keeps the instance in initialization mode, where the master may
        # correct a parameter and call fmi2ExitInitializationMode again.
        try:
            msg = self._ensure_engine()
            if msg is None:
                msg = self._check_inputs()
            if msg is None:
                self._engine.reset(t0=self._start_time, torque=float(self.torque),
                                   speed=float(self.speed), static=True)
                self._put_record(self._values_of())
                self._stepped = False
                return
        except Exception as e:  # noqa: BLE001
            msg = f"initialization failed: {type(e).__name__}: {e}"
        self.log(f"fmi2ExitInitializationMode refused: {msg}", Fmi2Status.error)

    def _check_inputs(self) -> str | None:
        try:
            self._gp.engine.check_inputs(self.torque, self.speed, self._load_speed())
        except ValueError as e:
            return f"input refused: {e}"
        return None

    def _load_speed(self) -> float | None:
        return float(self.load_speed) if self.load_speed_input else None

    def _put_record(self, record) -> None:
        """Show a step record (`stepblock.STEP_RECORD`'s order) in the output variables."""
        for (name, integer), v in zip(self._record, record, strict=True):
            if integer:
                setattr(self, name, int(v))
            elif hasattr(self, name):
                setattr(self, name, float(v))

    def do_step(self, current_time: float, step_size: float) -> bool:
        """The FMU's doStep. Checks (a refusal is logged with status error and changes
        nothing), then one step of the engine (`_advance`) from the state of the step start;
        a failure is logged with status discard (fmi2Discard) and leaves the state of the
        step start and the outputs of the last good step.
        """
        try:
            t, h = float(current_time), float(step_size)
            if self._poisoned:
                return self._error(f"step refused: {self._poisoned}")
            if not (math.isfinite(t) and math.isfinite(h)) or h <= 0.0:
                return self._error(f"step refused: communication step size must be > 0 "
                                   f"(currentCommunicationPoint = {t!r}, step size = {h!r})")
            msg = self._ensure_engine()
            if msg is not None:
                return self._error(f"step refused: {msg}")
            msg = self._check_inputs()
            if msg is not None:
                return self._error(f"step refused at t = {t:g} s: {msg}")
            eng = self._engine
            now = eng.time if self._stepped else self._start_time  # the first: startTime
            if abs(t - now) > 1e-9 * max(1.0, abs(t), h):
                return self._error(
                    f"step refused: currentCommunicationPoint = {t!r} s does not match the "
                    f"FMU's time {now!r} s (restore an FMU state to go back)")
            saved = eng.snapshot()  # the fast engine's is one copy of its state buffer
            try:
                if not self._stepped:
                    eng.reset(t0=t, torque=float(self.torque), speed=float(self.speed),
                              static=True)
                self._advance(eng, t, h)
            except Exception as e:  # noqa: BLE001
                kind = "" if isinstance(e, (ValueError, ArithmeticError)) else \
                    f"{type(e).__name__}: "
                msg = f"step from t = {t:g} s with h = {h:g} s failed: {kind}{e}"
                if not self._restore_engine(saved):
                    return self._error(msg + "; the engine state could not be restored, "
                                       "further steps are refused")
                if isinstance(e, self._gp.engine.RunFailure):
                    # a missed contact event or an unbounded response (issue 38): the
                    # result cannot be trusted and a shorter step does not change that
                    return self._error(msg + "; the state is that of the step start")
                # fmi2Discard: the state is that of the step start (lastSuccessfulTime)
                self.log(msg + "; the state is that of the step start", Fmi2Status.discard)
                return False
            self._stepped = True
            return True
        except Exception as e:  # noqa: BLE001 - never let an exception reach pythonfmu
            return self._error(f"internal error in do_step: {type(e).__name__}: {e}")

    def _advance(self, eng, t: float, h: float) -> None:
        """One step of the engine from t to t + h with the inputs; the step record into the
        outputs. Raises (ValueError, ArithmeticError, RuntimeError with
        the message of the step's failure) when the step failed or a value is not finite,
        after which the caller restores the state of the step start."""
        sb = self._sb
        load_speed = self._load_speed()
        torque, speed = float(self.torque), float(self.speed)
        summary = eng.advance(t + h, torque, speed) if load_speed is None else \
            eng.advance(t + h, torque, speed, load_speed)
        record = self._values_of(summary)
        for name, v in zip(sb.STEP_RECORD, record, strict=True):
            if not math.isfinite(v):
                raise ArithmeticError(f"output {name} is not finite")
        self._put_record(record)

    def _restore_engine(self, saved) -> bool:
        try:
            self._engine.restore(saved)
            return True
        except Exception as e:  # noqa: BLE001
            self._poisoned = f"engine state lost after a failed step ({type(e).__name__}: {e})"
            return False

    # -- FMU state ---------------------------------------------------------------------------
    def _get_fmu_state(self) -> bytes:
        """A snapshot (pickled at once, so later steps cannot alter it)."""
        state = {
            "format": STATE_FORMAT,
            "values": {v["name"]: getattr(self, v["name"]) for v in self._spec},
            "engine": None if self._engine is None else self._engine.get_state(),
            "engine_key": self._engine_key,
            "start_time": self._start_time,
            "stepped": self._stepped,
            "poisoned": self._poisoned,
        }
        return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)

    def _set_fmu_state(self, state) -> None:
        # Decode and rebuild everything first; touch self only when all succeeded. A failure
        # is logged with status error (the C layer returns fmi2Error) and leaves the current
        # state as it was.
        try:
            s = _loads_state(bytes(state), self._gp.__name__)
            values = s["values"]
            names = [v["name"] for v in self._spec]
            if set(values) != set(names):
                raise ValueError("the state is from a GearPair FMU with another interface")
            engine = self._engine
            key = s["engine_key"]
            if s["engine"] is not None:
                if engine is None or key != self._engine_key:
                    saved = {n: getattr(self, n) for n in self._param_names}
                    try:
                        for n in self._param_names:
                            setattr(self, n, values[n])
                        engine = self._build_engine()
                    finally:
                        for n, x in saved.items():
                            setattr(self, n, x)
                engine.set_state(s["engine"])
            else:
                engine, key = None, None
        except Exception as e:  # noqa: BLE001
            self.log(f"fmi2SetFMUstate refused: {type(e).__name__}: {e}; the FMU keeps its "
                     "current state", Fmi2Status.error)
            return
        for n in names:
            setattr(self, n, values[n])
        self._params_set = True
        self._engine, self._engine_key = engine, (tuple(key) if key is not None else None)
        self._start_time = s["start_time"]
        self._stepped = s["stepped"]
        self._poisoned = s["poisoned"]

    @staticmethod
    def _fmu_state_to_bytes(state) -> bytes:
        return bytes(state)

    @staticmethod
    def _fmu_state_from_bytes(state: bytes) -> bytes:
        return bytes(state)

