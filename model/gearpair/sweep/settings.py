"""What a sweep holds fixed and what it may vary: `SweepSettings`, the sweepable names and
the model's validity."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

from ..effects import OPTIONS, Effects, StiffnessSpec
from ..params import RPM, GearParams, OperatingPoint, check_range

# Inputs that are not GearParams fields, with their units. Units are UDUNITS spellings (what
# CF tools read; the store writes them): "rpm" for revolutions per minute, not "r/min".
INPUTS = {"speed_rpm": "rpm", "torque": "N.m"}
# What a sweepable name is, said in words (the store's ``long_name``): the inputs, and the
# `GearParams` fields whose ``doc`` would only repeat the name
_SAID = {"speed_rpm": "speed of gear 1", "torque": "driving torque on gear 1",
         "module": "module of the teeth (pitch diameter over tooth number)"}
_FX = Effects().values()  # the effects' defaults (the stiffness as its kind)
_HELD_TYPE = {"choice": "str", "bool": "bool", "number": "float"}


def _holding_effects(cls: type) -> type:
    """Give ``cls`` (a class about to become a dataclass) one field per `Effects` field, after
    its ``params``: the effect's default (the stiffness as its kind) and a type from its
    metadata (`gearpair.effects.OPTIONS`). The effects are declared once, in
    `gearpair.effects`: a new effect is a setting of every sweep with no edit here, and its
    value is read, stored and compared like any other setting (the store's resume check
    names it)."""
    own = dict(cls.__dict__.get("__annotations__", {}))
    clash = set(own) & set(OPTIONS)
    if clash or "params" not in own:
        raise TypeError(f"{cls.__name__}: effect fields {sorted(clash)} declared by hand, or "
                        "no params field to place the effects after")
    annotations = {}
    for name, typ in own.items():
        annotations[name] = typ
        if name == "params":
            for effect, m in OPTIONS.items():
                annotations[effect] = _HELD_TYPE[m["kind"]] + (" | None" if m["none"] else "")
                setattr(cls, effect, _FX[effect])
    cls.__annotations__ = annotations
    return cls


def sweepable() -> dict[str, str]:
    """Names that can be swept, with their units: the inputs and every `GearParams` field."""
    out = dict(INPUTS)
    for f in fields(GearParams):
        out[f.name] = f.metadata.get("unit", "")
    return out


def long_name(name: str) -> str:
    """What the sweepable ``name`` is, in words (``"speed of gear 1"``, ``"mass of gear
    1"``): the ``doc`` of a `GearParams` field."""
    if name in _SAID:
        return _SAID[name]
    for f in fields(GearParams):
        if f.name == name:
            return f.metadata.get("doc") or name
    raise KeyError(name)


@dataclass(frozen=True)
@_holding_effects
class SweepSettings:
    """Everything a sweep point needs besides the swept value (picklable, sent to workers).

    Attributes
    ----------
    torque : N.m, driving torque when not swept
    speed_rpm : r/min (UDUNITS ``rpm``), speed of gear 1 when not swept
    params : `GearParams` fields changed from Table 1, as ``((name, value), ...)``
    (one field per `Effects` field, added from `gearpair.effects.OPTIONS`) : the effects of
        every point, with the `Effects` defaults (the stiffness as its kind; ``friction =
        "nominal"`` is the traditional slip model, ``"stick_slip"`` the paper's model);
        `effects` makes them one `Effects`
    rtol : relative tolerance of the fast engine
    steps_per_period : engine steps per mesh period (the DTE and mesh force statistics and
        the spectrum use these samples; the ratios do not depend on them)
    transient_periods, transient_time : mesh periods discarded, and at least this time (s)
    kept_periods : mesh periods kept (made even, so half orders fall on a spectral bin)
    max_time : s, soft cap of the simulated time per point (see module docstring)
    min_periods : floor of the discarded and kept period counts under the cap
    tol : tolerance of the Poincare periodicity test, relative to the mean |DTE|
    max_period : longest period (in mesh periods) the test looks for
    section_phase : phase of the Poincare section in the mesh period (0: a pair enters
        contact); the sample nearest it is used. The default lies just before the leaving
        pair exits (phase 0.75 for Table 1's gears), where the ringing of the 3-4 kHz mesh
        modes excited at the entry has decayed most: a section inside the ringing turns small
        changes of the speed into large jumps of the sample and makes a periodic response
        look scattered in a bifurcation diagram.
    """

    torque: float = 3900.0
    speed_rpm: float = 100.0
    params: tuple[tuple[str, float], ...] = ()
    # here: one field per effect (`_holding_effects`)
    rtol: float = 1e-7
    steps_per_period: int = 8
    transient_periods: int = 100
    transient_time: float = 1.0
    kept_periods: int = 100
    max_time: float = 6.0
    min_periods: int = 16
    tol: float = 1e-3
    max_period: int = 16
    section_phase: float = 0.7

    def __post_init__(self) -> None:
        names = {f.name for f in fields(GearParams)}
        for k, _ in self.params:
            if k not in names:
                raise ValueError(f"unknown gear parameter {k!r}; choose from "
                                 + ", ".join(sorted(names)))
        if self.steps_per_period < 2 or self.kept_periods < 4 or self.min_periods < 4:
            raise ValueError("need steps_per_period >= 2, kept_periods >= 4, min_periods >= 4")
        if not (self.max_time > 0 and self.transient_time >= 0 and self.tol > 0):
            raise ValueError("need max_time > 0, transient_time >= 0 and tol > 0")

    def replace(self, **changes: Any) -> SweepSettings:
        return replace(self, **changes)

    def effects(self) -> Effects:
        """The `Effects` of every point (raises ``ValueError`` for a refused combination)."""
        kw = {name: getattr(self, name) for name in OPTIONS}
        kw["stiffness"] = StiffnessSpec(kind=self.stiffness)
        return Effects(**kw)

    def inputs(self, name: str, value: float) -> tuple[GearParams, Effects, float, float]:
        """Gear data, effects, torque (N.m) and speed (rad/s) of the point ``name = value``
        (raises ``ValueError`` for an unknown name or an invalid value)."""
        return self.inputs_at({name: value})

    def inputs_at(self, point: Mapping[str, float]) -> tuple[GearParams, Effects, float, float]:
        """`inputs` of a point of several parameters, ``{name: value}``."""
        over = dict(self.params)
        torque, rpm = self.torque, self.speed_rpm
        for name, value in point.items():
            if name not in sweepable():
                raise ValueError(f"cannot sweep {name!r}; choose one of "
                                 + ", ".join(sweepable()))
            if name == "torque":
                torque = float(value)
            elif name == "speed_rpm":
                rpm = float(value)
            else:
                over[name] = value
        params = GearParams(**over)
        return params, self.effects(), torque, rpm * RPM

    def check_point(self, point: Mapping[str, float]) -> None:
        """Raise ``ValueError`` naming the parameter and its range when a value of the point
        is outside its range (a zero or negative speed included: it has no mesh period)."""
        params, _, torque, speed = self.inputs_at(point)
        shown = {"torque": "torque", "speed": "speed_rpm"}
        for f in fields(OperatingPoint):
            x = torque if f.name == "torque" else speed
            meta = dict(f.metadata)
            if f.name == "speed":  # the sweep's unit (r/min); zero has no mesh period
                meta.update(unit="r/min", min=0.0, lo_open=True, max=meta["max"] / RPM)
                x /= RPM
            check_range(shown[f.name], x, meta)

    def periods(self, mesh_period: float) -> tuple[int, int]:
        """Discarded and kept mesh periods for a mesh period (s), with the cap applied."""
        tm = mesh_period
        n_t = max(self.transient_periods, math.ceil(self.transient_time / tm - 1e-9))
        n_k = self.kept_periods
        if (n_t + n_k) * tm > self.max_time:
            n_k = min(n_k, max(self.min_periods, int(0.5 * self.max_time / tm)))
            n_t = min(n_t, max(self.min_periods, int((self.max_time - n_k * tm) / tm)))
        return n_t, n_k + n_k % 2


def _boundary_phases(params: GearParams) -> list[float]:
    """Phases (fractions of a mesh period, from the reset) of the engine's known segment
    boundaries: a pair entering (0) or leaving contact, and a pair at the pitch point (a
    boundary of the nominal law, avoided for every law so all models share one grid)."""
    from ..geometry import Geometry

    g = Geometry.from_params(params)
    pb = g.base_pitch
    return [0.0, math.fmod(g.path_length, pb) / pb, math.fmod(g.xi_pitch, pb) / pb]


def outside_validity(effects: Effects, torque: float) -> str | None:
    """Why a run lies outside the model's validity, or None.

    Without backlash (the paper's model) a negative torque parts the teeth for good: nothing
    holds gear 1, which spins up freely, and the DTE grows without bound (a point's DTE
    statistics would be metres). `Effects.backlash` gives the back flanks that take it.
    """
    if torque < 0.0 and effects.backlash is None:
        return (f"torque = {torque:g} N.m < 0 without backlash: the teeth part for good and "
                "gear 1 spins up freely, outside the model (set a backlash for the back "
                "flanks to take a negative torque)")
    return None


