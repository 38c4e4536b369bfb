"""Which effects a simulation includes: typed, frozen options (not dicts of flags).

An effect switched off changes which terms the engine builds, never a multiplier inside
them: e.g. ``friction="off"`` means no friction forces, no sliding-velocity events and no
stick bookkeeping at all.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields
from typing import Any, Literal

FrictionLaw = Literal["off", "nominal", "regularized", "stick_slip"]
StiffnessKind = Literal["potential_energy", "constant", "rectangular", "table"]
Sliding = Literal["paper", "full"]
StickTie = Literal["exact", "paper"]
Dof = Literal["full", "torsional"]

# The choices of each option. The FMU's integer code of a choice is its index here (the
# stiffness table, last, has none): append, never reorder.
_FRICTION = ("off", "nominal", "regularized", "stick_slip")
_STIFFNESS = ("potential_energy", "constant", "rectangular", "table")
_SLIDING = ("paper", "full")
_TIE = ("exact", "paper")
_DOF = ("full", "torsional")
BACKLASH_MAX = 1e-3  # m; a clearance beyond a millimetre is a broken gearbox, not a scene
MU_STATIC_MAX = 1.0  # as GearParams.mu
STRIBECK_MAX = 1.0  # m/s; sliding velocities of this gear stay below about 1 m/s at 600 r/min


VARIANT = "variant"  # an option's ``off`` when no value leaves it out (e.g. the stiffness law)


def _one_of(name: str, value: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ValueError(f"{name} = {value!r} is not allowed; choose one of {', '.join(allowed)}")


def _option(doc: str, *, fmu: str, fmu_doc: str, off: Any = VARIANT, choices=None,
            fmu_choices=None, unit: str | None = None, lo: float | None = None,
            hi: float | None = None, lo_open: bool = False, none: str | None = None,
            zero_off: bool = False, display_unit: str | None = None):
    """Metadata of an `Effects` field (``dataclasses.fields(Effects)[i].metadata``), the one
    declaration that validation, the FMU's parameters, the scene keys, the command line and
    the docs' tables are made from.

    ``doc``: what it means (docs); ``off``: the value that leaves the effect out of the model
    (`VARIANT`: none, every value is a variant of the model); ``choices`` (strings), a
    boolean (no ``unit``) or a number with ``unit`` in [``lo``, ``hi``] (``lo_open``: lo
    excluded); ``none``: what None means when it is allowed (e.g. "no back flank");
    ``zero_off``: 0 means None too; ``fmu``: the FMU parameter's name, ``fmu_doc`` its
    description, ``fmu_choices`` the choices it can code (default ``choices``; the code is
    the index), ``display_unit`` its display unit. ``fmu_doc`` names another option's value
    as ``{field=value}`` (``{friction=stick_slip}``, ``{separation=true}``), which `OPTIONS`
    writes in the FMU's words with the code and its choice (`say_fmu`: ``friction_law = 3
    (stick_slip)``), so no code is typed by hand. An FMU parameter has no None: 0 codes it
    (and a value 0 means None: one representation, so equal effects compare equal).
    """
    kind = "choice" if choices else "bool" if unit is None else "number"
    return {"kind": kind, "doc": doc, "off": off, "choices": choices, "unit": unit, "min": lo,
            "max": hi, "lo_open": lo_open, "none": none, "zero_off": zero_off, "fmu": fmu,
            "fmu_doc": fmu_doc, "fmu_choices": fmu_choices or choices,
            "display_unit": display_unit}


ON = object()  # in a `Rule`: any value but the field's ``off`` (the effect is on)


@dataclass(frozen=True)
class Rule:
    """A combination of options the model refuses: ``given`` (field, value or `ON`) all hold
    and ``needs`` (field, allowed values) does not. Its message says it in any front
    door's words (`message`)."""

    given: tuple[tuple[str, Any], ...]
    needs: tuple[str, tuple[Any, ...]]
    why: str

    def refuses(self, values) -> bool:
        """Whether ``values`` (field -> value, Effects' values) break the rule."""
        for name, want in self.given:
            v = values[name]
            if (v == OPTIONS[name]["off"]) if want is ON else (v != want):
                return False
        name, allowed = self.needs
        return values[name] not in allowed

    def message(self, values, say) -> str:
        """The refusal: ``say(field, value)`` writes an assignment in the caller's words."""
        name, allowed = self.needs
        return (" with ".join(say(n, values[n]) for n, _ in self.given) + " needs "
                + " or ".join(say(name, a) for a in allowed) + ": " + self.why)


def fmu_code(name: str, value: Any) -> str:
    """An `Effects` assignment as the FMU parameter takes it (``friction_law = 3``,
    ``separation = true``, ``backlash = 0.0001``): a choice is coded by its index."""
    m = OPTIONS[name]
    if m["kind"] == "choice":
        return f"{m['fmu']} = {m['fmu_choices'].index(value)}"
    if m["kind"] == "bool":
        return f"{m['fmu']} = {'true' if value else 'false'}"
    return f"{m['fmu']} = {value:g}"


def say_fmu(name: str, value: Any) -> str:
    """An `Effects` assignment in the FMU's names and codes, with what a code chooses or the
    unit (``friction_law = 3 (stick_slip)``, ``separation = true``, ``backlash = 0.0001 m``)."""
    m = OPTIONS[name]
    if m["kind"] == "choice":
        return f"{fmu_code(name, value)} ({value})"
    unit = "" if m["kind"] == "bool" or m["unit"] == "1" else f" {m['unit']}"
    return fmu_code(name, value) + unit


def _fmu_words(text: str) -> str:
    """``text`` (an ``fmu_doc``) with each ``{field=value}`` said by `say_fmu`; a field or
    value the declaration does not have raises at import."""
    def one(ref: re.Match) -> str:
        name, raw = ref.group(1), ref.group(2)
        m = OPTIONS[name]
        value = {"true": True, "false": False}[raw] if m["kind"] == "bool" else \
            raw if m["kind"] == "choice" else float(raw)
        check_option(name, value, m)
        return say_fmu(name, value)

    return re.sub(r"\{(\w+)=([\w.+-]+)\}", one, text)


def say_effect(name: str, value: Any) -> str:
    """An `Effects` assignment as Python and the scenes write it (``friction = 'off'``)."""
    if isinstance(value, bool):
        return f"{name} = {'true' if value else 'false'}"
    return f"{name} = {value!r}"


@dataclass(frozen=True)
class StiffnessSpec:
    """Mesh stiffness law per tooth pair against contact position.

    Attributes
    ----------
    kind : {"potential_energy", "constant", "rectangular", "table"}
        ``potential_energy``: Hertz + bending + shear + axial compression + fillet foundation
        (Sainsot et al. 2004) of both teeth, scaled to the mean. ``constant``: the total mesh
        stiffness is ``km_mean`` at all times (shared between the pairs in contact).
        ``rectangular``: each pair has the same constant stiffness, so the total steps between
        single and double contact with time mean ``km_mean``. ``table``: per-pair stiffness
        from ``table`` (positions along the path of contact from its start A, m; stiffness
        N/m), linearly interpolated and scaled to the mean unless ``scale_to_mean`` is False.
        The potential-energy law is represented by a cubic spline on 41 knots (`stiffness`).
    table : tuple of (position_m, stiffness_n_per_m) pairs, optional
    scale_to_mean : bool
        Scale the law so that the time mean of the total mesh stiffness is ``km_mean``.
    """

    kind: StiffnessKind = "potential_energy"
    table: tuple[tuple[float, float], ...] | None = None
    scale_to_mean: bool = True

    def __post_init__(self) -> None:
        _one_of("stiffness", self.kind, _STIFFNESS)
        if self.kind == "table":
            if not self.table or len(self.table) < 2:
                raise ValueError(
                    "stiffness table needs at least 2 rows (position m, stiffness N/m)")
            pos = [float(r[0]) for r in self.table]
            k = [float(r[1]) for r in self.table]
            if any(not math.isfinite(v) for v in pos + k):
                raise ValueError("stiffness table has a non-finite value")
            if any(b <= a for a, b in zip(pos, pos[1:], strict=False)):
                raise ValueError("stiffness table positions must increase strictly")
            if any(v < 0 for v in k):
                raise ValueError("stiffness table values must be >= 0 N/m")


@dataclass(frozen=True)
class Effects:
    """The effects a scene calls for.

    Attributes
    ----------
    stiffness : StiffnessSpec
        Mesh stiffness law (Fig. 4; docs/model.md "Choices").
    separation : bool
        Tooth separation, Eq. (8): mesh force and mesh damping vanish for delta < 0. When
        False the mesh spring also pulls (a linear model).
    friction : {"off", "nominal", "regularized", "stick_slip"}
        ``nominal``: Coulomb friction with its direction from the nominal kinematics (reverses
        exactly at the pitch point; the traditional slip model). ``regularized``:
        ``tanh(v / v_eps)``. ``stick_slip``: sign law with exact switching by Eq. (14).
    v_eps : float
        Regularization velocity of the ``regularized`` law (m/s).
    sliding : {"paper", "full"}
        Relative sliding velocity: Eq. (12) (translations only) or with the rotational
        vibration too (``Omega_i + u_i'/rb_i``), which keeps the energy balance exact.
    stick_tie : {"exact", "paper"}
        How the stuck surfaces move together: ``exact`` holds v_j = 0 (includes the rate of
        change of the nominal sliding velocity); ``paper`` is Eqs. (19)-(21) (x2'' = x1'').
    backlash : float or None
        Total clearance along the line of action (m) between the drive flanks and the back
        flanks (beyond the paper). ``None``: no back flank (the paper: for delta < 0 the
        teeth are free). A value b: back-flank contact for delta < -b with the same mesh
        stiffness law and damping, so torque reversal and coasting stay bounded. Needs
        ``separation=True``. Friction acts on the drive flanks only.
    dof : {"full", "torsional"}
        ``full``: the 6-DOF model of Eq. (5). ``torsional``: rigid supports, only u1 and u2
        are integrated (x1 = y1 = x2 = y2 = 0); friction then acts through its moments only.
    mu_static : float or None
        Static friction coefficient (beyond the paper, whose single ``mu`` is both): bounds
        the static friction in the stick test of Eq. (14), ``|f_static| <= mu_static f_mesh``,
        while ``GearParams.mu`` stays the kinetic coefficient of the sliding friction.
        ``None``: equal to ``mu`` (the paper). Allowed [0, 1]; it must be >= ``mu`` (checked
        with the gear data by `equations.Model.build`). Used by ``stick_slip``, and by
        ``regularized`` through the Stribeck curve; ``off`` and ``nominal`` have no static
        state and refuse a value other than ``mu``.
    stribeck_velocity : float or None
        Stribeck velocity v_s (m/s): the sliding coefficient falls from ``mu_static`` at
        v = 0 to ``mu`` as ``mu + (mu_static - mu) exp(-(|v|/v_s)^2)``
        (`equations.sliding_coefficient`). ``None`` or 0: off (sliding at ``mu`` whatever
        the speed). Allowed (0, 1] m/s, with ``friction`` ``stick_slip`` or ``regularized``
        (the laws that see the sliding velocity).
    """

    stiffness: StiffnessSpec = field(default_factory=StiffnessSpec, metadata=_option(
        "mesh stiffness law per tooth pair", choices=_STIFFNESS,
        fmu="stiffness_model", fmu_choices=_STIFFNESS[:3],
        fmu_doc="mesh stiffness law per tooth pair"))
    separation: bool = field(default=True, metadata=_option(
        "tooth separation, Eq. (8): no mesh force or mesh damping while the teeth are apart "
        "(`false`: the mesh spring also pulls)", off=False, fmu="separation",
        fmu_doc="tooth separation, Eq. (8): mesh force and mesh damping vanish when the teeth "
        "part (false: the mesh spring also pulls)"))
    friction: FrictionLaw = field(default="stick_slip", metadata=_option(
        "`nominal`: direction from the nominal kinematics, the traditional slip model; "
        "`regularized`: tanh(v / v_eps); `stick_slip`: sign law with exact slip/stick "
        "switching, Eq. (14)", choices=_FRICTION, off="off", fmu="friction_law",
        fmu_doc="tooth friction law"))
    v_eps: float = field(default=1e-4, metadata=_option(
        "regularization velocity of `regularized`", unit="m/s", lo=1e-9, hi=1.0, fmu="v_eps",
        fmu_doc="regularization velocity of {friction=regularized}, tanh(v/v_eps)"))
    sliding: Sliding = field(default="paper", metadata=_option(
        "sliding velocity: Eq. (12), or with the rotational vibration too", choices=_SLIDING,
        off="paper", fmu="sliding",
        fmu_doc="relative sliding velocity: Eq. (12) translations only (paper) or with the "
        "rotational vibration (full)"))
    stick_tie: StickTie = field(default="exact", metadata=_option(
        "stuck surfaces hold v = 0 exactly, or Eqs. (19)-(21)", choices=_TIE, fmu="stick_tie",
        fmu_doc="how stuck surfaces move together: v = 0 held exactly (exact) or "
        "Eqs. (19)-(21) (paper)"))
    backlash: float | None = field(default=None, metadata=_option(
        "clearance along the line of action; back-flank contact beyond it", unit="m", lo=0.0,
        hi=BACKLASH_MAX, lo_open=True, none="no back flank", off=None, fmu="backlash",
        display_unit="um",
        fmu_doc="clearance between drive and back flanks along the line of action; 0: no back "
        "flank (the paper). > 0 catches torque reversal on the back flanks (needs "
        "{separation=true})"))
    dof: Dof = field(default="full", metadata=_option(
        "`torsional`: rigid supports, only the two rotations", choices=_DOF, off="full",
        fmu="dof", fmu_doc="degrees of freedom: the 6-DOF model (full) or u1, u2 only with "
        "rigid supports (torsional; with {friction=stick_slip} it needs {sliding=full})"))
    mu_static: float | None = field(default=None, metadata=_option(
        "static friction coefficient, >= `mu`: bounds the static friction in the stick test "
        "of Eq. (14); `[gear] mu` stays the kinetic one. Above `mu` it needs `friction = "
        "\"stick_slip\"` (or `\"regularized\"` with `stribeck_velocity`; checked with the gear "
        "data, `equations.check_friction_coefficients`)", unit="1",
        lo=0.0, hi=MU_STATIC_MAX, none="mu_static = mu", off=None, fmu="mu_static",
        fmu_doc="static friction coefficient bounding the static friction in the stick test "
        "of Eq. (14) (mu stays the kinetic coefficient); 0: equal to mu (the paper); "
        "otherwise it must be >= mu, with {friction=stick_slip}, or {friction=regularized} "
        "together with stribeck_velocity"))
    stribeck_velocity: float | None = field(default=None, metadata=_option(
        "Stribeck velocity v_s: sliding coefficient mu + (mu_static - mu) exp(-(v/v_s)²), "
        "from `mu_static` at v = 0 down to `mu`", unit="m/s", lo=0.0, hi=STRIBECK_MAX,
        lo_open=True, none="no Stribeck decay", zero_off=True, off=None,
        fmu="stribeck_velocity",
        fmu_doc="Stribeck velocity v_s: the sliding coefficient is mu + (mu_static - mu) "
        "exp(-(|v|/v_s)^2); 0: off (sliding at mu); with {friction=regularized} or "
        "{friction=stick_slip}"))

    def __post_init__(self) -> None:
        if isinstance(self.stiffness, str):  # convenience: Effects(stiffness="constant")
            object.__setattr__(self, "stiffness", StiffnessSpec(kind=self.stiffness))
        if not isinstance(self.stiffness, StiffnessSpec):
            raise ValueError("stiffness must be a StiffnessSpec or one of " + ", ".join(_STIFFNESS))
        for name, meta in OPTIONS.items():
            if name != "stiffness":  # checked by StiffnessSpec
                check_option(name, getattr(self, name), meta)
        if self.stribeck_velocity == 0.0:  # 0 means off, as None: one representation
            object.__setattr__(self, "stribeck_velocity", None)
        values = self.values()
        for rule in RULES:
            if rule.refuses(values):
                raise ValueError(rule.message(values, say_effect))

    def values(self) -> dict[str, Any]:
        """Field -> value, the stiffness as its kind (what `RULES` and the FMU read)."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["stiffness"] = self.stiffness.kind
        return out


def check_option(name: str, value: Any, meta: dict) -> None:
    """Raise ``ValueError`` naming the option unless ``value`` is one its metadata allows."""
    if meta["kind"] == "choice":
        _one_of(name, value, meta["choices"])
        return
    if meta["kind"] == "bool":
        if not isinstance(value, bool):
            raise ValueError(f"{name} must be true or false, got {value!r}")
        return
    if value is None and meta["none"]:
        return
    lo, hi = meta["min"], meta["max"]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or not value <= hi or \
            not (lo < value if meta["lo_open"] else lo <= value) and \
            not (meta["zero_off"] and value == 0.0):
        raise ValueError(f"{name} = {value!r} is out of range; allowed {allowed(meta)}")


def allowed(meta: dict) -> str:
    """The allowed values of an option's metadata as a message or a table says them."""
    if meta["kind"] == "choice":
        return ", ".join(meta["choices"])
    if meta["kind"] == "bool":
        return "true, false"
    text = f"{'(' if meta['lo_open'] else '['}{meta['min']:g}, {meta['max']:g}]"
    if meta["unit"] not in ("1", None):
        text += f" {meta['unit']}"
    if meta["none"]:
        text += f", or {'0 or ' if meta['zero_off'] else ''}None for {meta['none']}"
    return text


OPTIONS: dict[str, dict] = {f.name: dict(f.metadata) for f in fields(Effects)}
for _m in OPTIONS.values():  # the FMU codes other options' values by: generated, not typed
    _m["fmu_doc"] = _fmu_words(_m["fmu_doc"])
del _m
# The combinations the model refuses, checked by `Effects` and said in the FMU's words by the
# FMU (fmu_src/GearPair.py) from the same rules.
RULES = (
    Rule((("dof", "torsional"), ("friction", "stick_slip")), ("sliding", ("full",)),
         "the paper's sliding velocity (Eq. (12)) moves only with the support deflections, "
         "which the torsional model holds still, so no stick could form"),
    Rule((("backlash", ON),), ("separation", (True,)),
         "a back flank only matters once the drive flanks can separate"),
    Rule((("stribeck_velocity", ON),), ("friction", ("stick_slip", "regularized")),
         "the other friction laws do not see the sliding velocity"),
)


FRICTION_LAWS = _FRICTION
STIFFNESS_KINDS = _STIFFNESS
SLIDING_VARIANTS = _SLIDING
STICK_TIES = _TIE
DOFS = _DOF
