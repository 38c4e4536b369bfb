"""Which effects a simulation includes: typed, frozen options (not dicts of flags).

An effect switched off changes which terms the engine builds, never a multiplier inside
them: e.g. ``friction="off"`` means no friction forces, no sliding-velocity events and no
stick bookkeeping at all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

FrictionLaw = Literal["off", "nominal", "regularized", "stick_slip"]
StiffnessKind = Literal["potential_energy", "constant", "rectangular", "table"]
Sliding = Literal["paper", "full"]
StickTie = Literal["exact", "paper"]
Dof = Literal["full", "torsional"]

_FRICTION = ("off", "nominal", "regularized", "stick_slip")
_STIFFNESS = ("potential_energy", "constant", "rectangular", "table")
_SLIDING = ("paper", "full")
_TIE = ("exact", "paper")
_DOF = ("full", "torsional")
BACKLASH_MAX = 1e-3  # m; a clearance beyond a millimetre is a broken gearbox, not a scene
MU_STATIC_MAX = 1.0  # as GearParams.mu
STRIBECK_MAX = 1.0  # m/s; sliding velocities of this gear stay below about 1 m/s at 600 r/min


def _one_of(name: str, value: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise ValueError(f"{name} = {value!r} is not allowed; choose one of {', '.join(allowed)}")


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

    stiffness: StiffnessSpec = field(default_factory=StiffnessSpec)
    separation: bool = True
    friction: FrictionLaw = "stick_slip"
    v_eps: float = 1e-4
    sliding: Sliding = "paper"
    stick_tie: StickTie = "exact"
    backlash: float | None = None
    dof: Dof = "full"
    mu_static: float | None = None
    stribeck_velocity: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.stiffness, str):  # convenience: Effects(stiffness="constant")
            object.__setattr__(self, "stiffness", StiffnessSpec(kind=self.stiffness))
        if not isinstance(self.stiffness, StiffnessSpec):
            raise ValueError("stiffness must be a StiffnessSpec or one of " + ", ".join(_STIFFNESS))
        _one_of("friction", self.friction, _FRICTION)
        _one_of("sliding", self.sliding, _SLIDING)
        _one_of("stick_tie", self.stick_tie, _TIE)
        if not (isinstance(self.separation, bool)):
            raise ValueError(f"separation must be true or false, got {self.separation!r}")
        if not (math.isfinite(self.v_eps) and 1e-9 <= self.v_eps <= 1.0):
            raise ValueError(f"v_eps = {self.v_eps!r} is out of range; allowed [1e-09, 1] m/s")
        _one_of("dof", self.dof, _DOF)
        if self.dof == "torsional" and self.friction == "stick_slip" and self.sliding == "paper":
            raise ValueError("dof = 'torsional' with friction = 'stick_slip' needs sliding = "
                             "'full': the paper's sliding velocity (Eq. 12) moves only with "
                             "x1 - x2, which rigid supports hold still, so no stick can form")
        if self.backlash is not None:
            b = self.backlash
            if isinstance(b, bool) or not isinstance(b, (int, float)) or not math.isfinite(b) \
                    or not 0.0 < b <= BACKLASH_MAX:
                raise ValueError(f"backlash = {b!r} is out of range; allowed (0, {BACKLASH_MAX:g}]"
                                 " m, or None for no back flank")
            if not self.separation:
                raise ValueError("backlash needs separation = true (a back flank only matters "
                                 "once the drive flanks can separate)")
        self._check_static_friction()

    def _check_static_friction(self) -> None:
        ms = self.mu_static
        if ms is not None and (isinstance(ms, bool) or not isinstance(ms, (int, float))
                               or not math.isfinite(ms) or not 0.0 <= ms <= MU_STATIC_MAX):
            raise ValueError(f"mu_static = {ms!r} is out of range; allowed [0, {MU_STATIC_MAX:g}]"
                             " (and >= mu), or None for mu_static = mu")
        vs = self.stribeck_velocity
        if vs is None:
            return
        if isinstance(vs, bool) or not isinstance(vs, (int, float)) or not math.isfinite(vs) \
                or not 0.0 <= vs <= STRIBECK_MAX:
            raise ValueError(f"stribeck_velocity = {vs!r} is out of range; allowed (0, "
                             f"{STRIBECK_MAX:g}] m/s, or 0 or None for no Stribeck decay")
        if vs == 0.0:  # 0 means off, as None: one representation, so equal effects compare equal
            object.__setattr__(self, "stribeck_velocity", None)
            return
        if self.friction not in ("stick_slip", "regularized"):
            raise ValueError(f"stribeck_velocity needs friction = 'stick_slip' or 'regularized' "
                             f"(friction = {self.friction!r} does not see the sliding velocity)")


FRICTION_LAWS = _FRICTION
STIFFNESS_KINDS = _STIFFNESS
SLIDING_VARIANTS = _SLIDING
STICK_TIES = _TIE
DOFS = _DOF
