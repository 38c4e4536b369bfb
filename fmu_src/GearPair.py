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
import io
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

STATE_FORMAT = "gearpair-fmu-state/1"
BUNDLE = "_gearpair_fmu"  # import name of the bundled package (never ``gearpair``)
RPM = 2.0 * math.pi / 60.0  # rad/s per r/min

# The slave's own choice (not an effect; the effects' choices, codes and ranges come from
# `gearpair.effects.OPTIONS`): the integrator, coded as its index in `gearpair.ENGINES`.
ENGINE_DOC = ("integrator: numba-compiled (fast; falls back to reference without numba) or "
              "the scipy yardstick (reference)")
# The parameters after GearParams' and the outputs added later, in registration order (value
# references follow it): the effects' FMU parameters (`gearpair.effects.OPTIONS`, "fmu") and the
# slave's own. Append, never reorder: a new effect's parameter goes at the end.
LATER_VARIABLES = ("stiffness_model", "separation", "friction_law", "v_eps", "sliding",
                   "stick_tie", "engine", "backlash", "dof", "load_speed_input", "rtol",
                   "mu_static", "stribeck_velocity", "back_fraction", "mesh_force_mean",
                   "mesh_force_min")

# Display units chosen for parameters by their unit.
_PARAM_DISPLAY_UNIT = {"rad": "deg", "m": "mm"}

# Outputs: name, type, unit, display unit, min, max, description. Their values come from the
# engine's Outputs (instantaneous, at the end of the step) and StepSummary (over the step).
OUTPUTS: tuple[tuple[str, str, str | None, str | None, float | None, float | None, str], ...] = (
    ("dte", "Real", "m", "um", None, None,
     "dynamic transmission error: mesh deflection along the line of action, Eq. (3)"),
    ("mesh_force", "Real", "N", "kN", None, None,
     "elastic mesh force km*Theta(delta)*delta, Eq. (16)"),
    ("friction_force", "Real", "N", None, None, None,
     "total tangential tooth force (sliding or static friction), sum over the pairs"),
    ("contact_state", "Integer", None, None, 0, 3,
     "contact state at the end of the step: 0 separated, 1 slip, 2 stick (any pair stuck), "
     "3 back flanks in contact (backlash > 0)"),
    ("output_torque", "Real", "N.m", None, None, None,
     "torque delivered to the gear 2 shaft"),
    ("input_torque_reaction", "Real", "N.m", None, None, None,
     "torque the mesh exerts back on gear 1 about its axis"),
    ("input_torque", "Real", "N.m", None, None, None,
     "torque the input side delivers into gear 1 (torque input plus input shaft kr1): the "
     "load a driving motor feels"),
    ("gear1_speed", "Real", "rad/s", "rpm", None, None,
     "absolute speed of gear 1 (nominal + vibration)"),
    ("gear2_speed", "Real", "rad/s", "rpm", None, None,
     "absolute speed of gear 2 (nominal + vibration)"),
    ("sliding_velocity", "Real", "m/s", None, None, None,
     "relative sliding velocity of the tooth pair nearest the pitch point"),
    ("stick_fraction", "Real", "1", None, 0.0, 1.0,
     "fraction of the last communication step spent in stick (from located switches)"),
    ("separation_fraction", "Real", "1", None, 0.0, 1.0,
     "fraction of the last communication step with the teeth apart"),
    ("mesh_force_max", "Real", "N", "kN", None, None,
     "greatest elastic mesh force in the last communication step"),
    ("n_events", "Integer", None, None, 0, None,
     "number of state switches located in the last communication step"),
)
# Step figures added later: registered after every other variable (`interface`), so the value
# references of the earlier ones stay as they were; their values are the last three step
# figures in `StepSummary`'s order (`_values_of`, `FastEngine.advance_values`).
APPENDED_OUTPUTS: tuple[tuple[str, str, str | None, str | None, float | None, float | None,
                              str], ...] = (
    ("back_fraction", "Real", "1", None, 0.0, 1.0,
     "fraction of the last communication step with the back flanks in contact (backlash > 0: "
     "contact under a negative torque, not contact loss)"),
    ("mesh_force_mean", "Real", "N", "kN", None, None,
     "time mean of the elastic mesh force over the last communication step (from the "
     "engine's integral over its steps)"),
    ("mesh_force_min", "Real", "N", "kN", None, None,
     "least elastic mesh force in the last communication step"),
)
def _resources_folder(resources: str | None) -> str | None:
    """The resources folder as a normal absolute path.

    The FMU's C layer hands pythonfmu ``file://`` + an absolute path, which pythonfmu turns
    into that path; a path with leading ``//`` (a ``file:////abs`` location given to
    pythonfmu directly) or a leftover ``file:`` URI names the same folder.
    """
    if not resources:
        return resources
    path = resources
    if path[:5].lower() == "file:":
        from urllib.parse import unquote, urlsplit

        parts = urlsplit(path)
        if parts.netloc not in ("", "localhost"):
            return path
        path = unquote(parts.path)
    if path.startswith("//"):
        path = "/" + path.lstrip("/")
    return os.path.abspath(path)


def _unlist_resources(resources: str | None) -> None:
    """Take the resources folder off ``sys.path`` again.

    pythonfmu's binary puts it first on ``sys.path`` to import this script and leaves it
    there, so in a Python host a later ``import gearpair`` would find the FMU's copy (and
    fail once the host deleted the folder) instead of the host's own. This module is
    imported by then and the bundled package needs no ``sys.path`` entry (`_import_gearpair`).
    Only in an extracted FMU, recognised by a ``binaries`` folder beside it (fmpy extracts
    just ``binaries`` and ``resources``): pythonfmu's builder instantiates the slave with the
    script's own folder, which it removes itself.
    """
    where = _resources_folder(resources)
    if where and os.path.isdir(os.path.join(os.path.dirname(where), "binaries")):
        sys.path[:] = [p for p in sys.path if not (p and _resources_folder(p) == where)]


def _package_alive(mod) -> bool:
    """Whether a package's folder still exists (hosts delete an FMU's extracted folder)."""
    paths = list(getattr(mod, "__path__", []))
    return any(os.path.isfile(os.path.join(p, "__init__.py")) for p in paths)


def _import_gearpair(resources: str | None):
    """The gearpair package of this FMU: the copy in ``resources`` imported as `BUNDLE`.

    Neither ``sys.path`` nor a ``gearpair`` of the host is touched, so a host that imports
    gearpair later gets its own. Instances share the bundled package while its folder exists;
    after a host deleted it, the next instance imports its own copy (live instances keep the
    module objects they hold). Without a bundled copy (this module imported outside an FMU,
    e.g. by the builder's documentation) the installed ``gearpair`` is used.
    """
    folder = os.path.join(resources, "gearpair") if resources else ""
    init = os.path.join(folder, "__init__.py")
    if not os.path.isfile(init):
        gp = importlib.import_module("gearpair")
    else:
        gp = sys.modules.get(BUNDLE)
        if gp is not None and not _package_alive(gp):
            for name in [n for n in sys.modules if n == BUNDLE or n.startswith(BUNDLE + ".")]:
                del sys.modules[name]
            gp = None
        if gp is None:
            spec = importlib.util.spec_from_file_location(
                BUNDLE, init, submodule_search_locations=[folder])
            gp = importlib.util.module_from_spec(spec)
            sys.modules[BUNDLE] = gp
            try:
                spec.loader.exec_module(gp)
            except BaseException:
                del sys.modules[BUNDLE]
                raise
    for sub in ("params", "effects", "engine"):
        importlib.import_module(f"{gp.__name__}.{sub}")
    return gp


def interface(gp=None) -> list[dict[str, Any]]:
    """Every FMU variable in registration (value reference) order, as plain dicts.

    Keys: name, type (Real/Integer/Boolean), causality, variability, unit, display_unit, min,
    max, start (None for outputs), description, lo_open, and for an integer-coded choice
    field (what it sets) and codes (the choices in code order, `choices`). The single source
    for the slave's variables, the modelDescription post-processing and the documentation
    page; parameter data come from ``GearParams.describe()``, the effects' from their
    metadata (``gearpair.effects.OPTIONS``) and the input data from ``OperatingPoint``.
    """
    if gp is None:
        gp = _import_gearpair(None)
    from dataclasses import fields

    params_mod = importlib.import_module(gp.__name__ + ".params")
    out: list[dict[str, Any]] = []

    def add(name, typ, causality, variability, unit=None, display_unit=None, lo=None,
            hi=None, start=None, description="", lo_open=False, field=None, codes=None):
        out.append(dict(name=name, type=typ, causality=causality, variability=variability,
                        unit=unit, display_unit=display_unit, min=lo, max=hi, start=start,
                        description=description, lo_open=lo_open, field=field, codes=codes))

    display_in = {"torque": None, "speed": "rpm"}
    for f in fields(params_mod.OperatingPoint):
        m = f.metadata
        add(f.name, "Real", "input", "continuous", m["unit"], display_in.get(f.name),
            m["min"], m["max"], float(f.default), m["doc"] + ", held over each step")
    add("load_speed", "Real", "input", "continuous", "rad/s", "rpm", -params_mod.SPEED_MAX,
        params_mod.SPEED_MAX, 0.0,
        "speed of the load at the far end of the load shaft kr2 (gear 2's sense), held over "
        "each step; used only when the parameter load_speed_input is true")

    for name, typ, unit, dunit, lo, hi, doc in OUTPUTS:
        add(name, typ, "output", "discrete" if typ == "Integer" else "continuous", unit, dunit,
            lo, hi, None, doc)

    for row in params_mod.GearParams.describe():
        is_int = isinstance(row["default"], int) and not isinstance(row["default"], bool)
        doc = row["doc"]
        if row.get("lo_open"):
            doc += f" (must be > {row['min']:g})"
        add(row["name"], "Integer" if is_int else "Real", "parameter", "fixed",
            None if is_int else row["unit"], _PARAM_DISPLAY_UNIT.get(row["unit"]),
            row["min"], row["max"], row["default"], doc, lo_open=bool(row.get("lo_open")))

    effects_mod = importlib.import_module(gp.__name__ + ".effects")
    defaults = effects_mod.Effects().values()
    by_fmu = {m["fmu"]: (name, m) for name, m in effects_mod.OPTIONS.items()}
    unplaced = sorted(set(by_fmu) - set(LATER_VARIABLES))
    if unplaced:
        raise RuntimeError(f"effect parameter(s) {', '.join(unplaced)} have no place in "
                           "LATER_VARIABLES (append them: value references never move)")
    appended = {row[0]: row for row in APPENDED_OUTPUTS}
    for name in LATER_VARIABLES:
        if name in by_fmu:
            field_name, m = by_fmu[name]
            add(name, **_effect_variable(m, defaults[field_name]), field=field_name)
        elif name == "engine":
            engines = tuple(gp.ENGINES)
            add(name, "Integer", "parameter", "fixed", None, None, 0, len(engines) - 1, 0,
                f"{ENGINE_DOC}: {_listing(engines)}", field="engine", codes=engines)
        elif name == "load_speed_input":
            add(name, "Boolean", "parameter", "fixed", start=False,
                description="true: the load shaft kr2/cr2 ends at a load turning at the input "
                "load_speed (a driveline; power flows both ways); false: it ends at the "
                "nominal rotation (the paper)")
        elif name == "rtol":
            add("rtol", "Real", "parameter", "fixed", "1", None, params_mod.RTOL_MIN,
                params_mod.RTOL_MAX, 1e-8, "relative tolerance of the engine's integrator")
        else:
            _, typ, unit, dunit, lo, hi, doc = appended[name]
            add(name, typ, "output", "continuous", unit, dunit, lo, hi, None, doc)
    return out


def _listing(codes) -> str:
    return ", ".join(f"{i} {c}" for i, c in enumerate(codes))


def _effect_variable(m: dict, default) -> dict:
    """`interface` arguments of an effect's FMU parameter from its metadata
    (`gearpair.effects.OPTIONS`): a choice as its code (the index), a number with 0 for None."""
    if m["kind"] == "choice":
        codes = m["fmu_choices"]
        return dict(typ="Integer", causality="parameter", variability="fixed", lo=0,
                    hi=len(codes) - 1, start=codes.index(default),
                    description=f"{m['fmu_doc']}: {_listing(codes)}", codes=codes)
    if m["kind"] == "bool":
        return dict(typ="Boolean", causality="parameter", variability="fixed",
                    start=bool(default), description=m["fmu_doc"])
    return dict(typ="Real", causality="parameter", variability="fixed", unit=m["unit"],
                display_unit=m["display_unit"], lo=0.0 if m["none"] else m["min"],
                hi=m["max"], start=0.0 if default is None else float(default),
                description=m["fmu_doc"])


def choices(spec: list[dict]) -> dict[str, tuple[str, tuple[str, ...]]]:
    """The integer-coded parameters of ``spec`` (`interface`): FMU name -> (what it sets,
    the choices in code order)."""
    return {v["name"]: (v["field"], v["codes"]) for v in spec if v["codes"]}


def _combination_error(effects_mod, values: dict) -> str | None:
    """The first combination the model refuses (`gearpair.effects.RULES`), said in the FMU's
    names and codes (``values``: Effects field -> value, decoded; `say_fmu`, which also
    writes the codes in the parameters' descriptions), or None."""
    for rule in effects_mod.RULES:
        if rule.refuses(values):
            return rule.message(values, effects_mod.say_fmu)
    return None


class _StateUnpickler(pickle.Unpickler):
    """Unpickler for serialized FMU states: plain data, numpy arrays and gearpair classes."""

    _ALLOWED = {
        ("builtins", "set"), ("builtins", "frozenset"), ("builtins", "complex"),
        ("builtins", "slice"), ("builtins", "range"), ("builtins", "bytearray"),
        ("collections", "OrderedDict"),
        ("numpy", "dtype"), ("numpy", "ndarray"),
        ("numpy._core.numeric", "_frombuffer"), ("numpy.core.numeric", "_frombuffer"),
        ("numpy._core.multiarray", "_reconstruct"), ("numpy.core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "scalar"), ("numpy.core.multiarray", "scalar"),
    }

    def __init__(self, file, package: str) -> None:
        super().__init__(file)
        self._package = package  # name of the gearpair package the slave runs

    def find_class(self, module: str, name: str):
        if (module, name) in self._ALLOWED:
            return super().find_class(module, name)
        top, dot, rest = module.partition(".")
        if top in ("gearpair", BUNDLE):  # either import name: the package this slave runs
            module = self._package + dot + rest
        if module == "numpy.dtypes" or module.partition(".")[0] == self._package:
            obj = super().find_class(module, name)
            if isinstance(obj, type):  # classes only, never functions
                return obj
        raise pickle.UnpicklingError(f"FMU state refers to {module}.{name}, which is not allowed")


def _loads_state(data: bytes, package: str = "gearpair") -> dict:
    state = _StateUnpickler(io.BytesIO(data), package).load()
    if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
        raise ValueError("not a GearPair FMU state")
    return state


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

