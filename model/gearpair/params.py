"""Gear pair data: Table 1 of Xun, Dai & Wang (2023) and the choices the paper leaves open.

Every field is SI. ``GearParams`` validates itself on construction and raises
``ValueError`` naming the field and its allowed range, so a bad value never reaches the
integrator (nor the FMU, which checks through the same function).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

RPM = 2.0 * math.pi / 60.0  # rad/s per r/min

# The integrator tolerance every entry point accepts (engines, command line, scenes, FMU).
# Below 1e-12 the step control works at the rounding level of the 18-wide state (scipy's
# solvers silently raise an rtol below 100 eps = 2.2e-14 anyway); above 1e-3 the energy
# balance (checked to 50 rtol of its scale) and the event location stop meaning anything.
RTOL_MIN, RTOL_MAX = 1e-12, 1e-3
RTOL_META = {"unit": "1", "min": RTOL_MIN, "max": RTOL_MAX, "lo_open": False}
# The inputs every entry point accepts (engines, FMU, scenes): |torque| in N.m, |speed| and
# |load_speed| in rad/s. Far beyond any gear of this size (the load warning,
# `geometry.load_implausibility`, speaks long before); they keep non-physical numbers out.
TORQUE_MAX, SPEED_MAX = 1e6, 2e4

# -- the stiffness laws' data (`gearpair.stiffness`, `gearpair.potential_energy`), read by the
# compiled set-up (`gearpair.fast.setup`) -------------------------------------------------
N_TABLE = 401  # grid points along the path of a table law (linear between them)
N_SPLINE = 41  # knots of the cubic spline of the potential-energy law
#: Sainsot, Velex & Duverger (2004), Table 1: rows L*, M*, P*, Q*; columns A..F of
#: ``X* = A / theta_f^2 + B h_fi^2 + C h_fi / theta_f + D / theta_f + E h_fi + F``.
SAINSOT_COEFFS = np.array(
    [
        [-5.574e-5, -1.9986e-3, -2.3015e-4, 4.7702e-3, 0.0271, 6.8045],
        [60.111e-5, 28.100e-3, -83.431e-4, -9.9256e-3, 0.1624, 0.9086],
        [-50.952e-5, 185.50e-3, 0.0538e-4, 53.300e-3, 0.2895, 0.9236],
        [-6.2042e-5, 9.0889e-3, -4.0964e-4, 7.8297e-3, -0.1472, 0.6904],
    ]
)

#: Range allowed for h_fi = rf / r_int when the bore is inferred from the masses and inertias.
H_FI_RANGE = (1.1, 3.3)

#: Default number of Gauss-Legendre points over the involute (converged to < 1e-8 relative).
N_GAUSS = 32


def _meta(unit: str, lo: float | None, hi: float | None, doc: str, *, lo_open: bool = False):
    return {"unit": unit, "min": lo, "max": hi, "lo_open": lo_open, "doc": doc}


@dataclass(frozen=True)
class GearParams:
    """Physical data of the gear pair (Table 1 defaults).

    Parameters carry their unit and allowed range in ``dataclasses.fields(...)[i].metadata``;
    `describe()` lists them. Derived quantities (damping coefficients, equivalent mass) are
    properties so they can never go stale.
    """

    m1: float = field(default=17.29, metadata=_meta("kg", 0, 1e5, "mass of gear 1", lo_open=True))
    m2: float = field(default=101.62, metadata=_meta("kg", 0, 1e5, "mass of gear 2", lo_open=True))
    J1: float = field(
        default=0.139, metadata=_meta("kg.m2", 0, 1e4, "moment of inertia of gear 1", lo_open=True)
    )
    J2: float = field(
        default=4.799, metadata=_meta("kg.m2", 0, 1e4, "moment of inertia of gear 2", lo_open=True)
    )
    z1: int = field(default=33, metadata=_meta("1", 12, 400, "tooth number of gear 1 (pinion)"))
    z2: int = field(default=80, metadata=_meta("1", 12, 400, "tooth number of gear 2 (wheel)"))
    module: float = field(default=6e-3, metadata=_meta("m", 0, 0.1, "module", lo_open=True))
    face_width: float = field(
        default=0.2, metadata=_meta("m", 0, 2.0, "face width", lo_open=True)
    )
    pressure_angle: float = field(
        default=math.radians(20.0),
        metadata=_meta("rad", math.radians(10), math.radians(35), "pressure angle"),
    )
    addendum_coef: float = field(
        default=1.0, metadata=_meta("1", 0.5, 1.5, "addendum coefficient ha*")
    )
    dedendum_coef: float = field(
        default=1.25, metadata=_meta("1", 1.0, 1.6, "dedendum coefficient hf* (root circle)")
    )
    kb1: float = field(
        default=4.06e7, metadata=_meta("N/m", 0, 1e14, "translational support stiffness, gear 1",
                                       lo_open=True)
    )
    kb2: float = field(
        default=4.11e10, metadata=_meta("N/m", 0, 1e14, "translational support stiffness, gear 2",
                                        lo_open=True)
    )
    kr2: float = field(
        # Not in Table 1: chosen so that the slip model's first mode is 32 Hz with the mean
        # mesh stiffness (paper, Sec. 3.1); `kr2_for_first_mode` recomputes it for other data.
        default=4.4745e6,
        metadata=_meta("N/m", 0, 1e14, "rotational stiffness of gear 2 on its base circle "
                       "(kr2 * rb2^2 is the load shaft stiffness in N.m/rad)", lo_open=True),
    )
    kr1: float = field(
        # Beyond the paper: 0 keeps its torque-driven gear 1. A driveline connects gear 1 to
        # the motor through this input shaft and takes its torque as the reaction.
        default=0.0,
        metadata=_meta("N/m", 0, 1e14, "input shaft stiffness of gear 1 on its base circle "
                       "(kr1 * rb1^2 in N.m/rad); 0: gear 1 driven by the torque input only"),
    )
    damping_ratio: float = field(
        default=0.02, metadata=_meta("1", 0, 1, "damping ratio applied to every spring")
    )
    mu: float = field(
        default=0.02, metadata=_meta("1", 0, 1, "coefficient of friction between the teeth")
    )
    km_mean: float = field(
        default=4.05e9, metadata=_meta("N/m", 0, 1e13, "time mean of the mesh stiffness",
                                       lo_open=True)
    )
    youngs_modulus: float = field(
        default=2.06e11, metadata=_meta("Pa", 0, 1e13, "Young's modulus (stiffness shape only)",
                                        lo_open=True)
    )
    poisson: float = field(
        default=0.3, metadata=_meta("1", 0, 0.5, "Poisson's ratio (stiffness shape only)")
    )

    def __post_init__(self) -> None:
        for f in fields(self):
            check_range(f.name, getattr(self, f.name), f.metadata)
        for name in ("z1", "z2"):
            if int(getattr(self, name)) != getattr(self, name):
                raise ValueError(
                    f"{name} must be a whole number of teeth, got {getattr(self, name)}")

    # -- derived quantities (Eq. (5) and docs/model.md "Choices") --------------------------------
    @property
    def rb1(self) -> float:
        """Base radius of gear 1 (m)."""
        from .fast.setupmath import cos  # the same bits on every machine

        return self.module * self.z1 * cos(self.pressure_angle) / 2.0

    @property
    def rb2(self) -> float:
        """Base radius of gear 2 (m)."""
        from .fast.setupmath import cos

        return self.module * self.z2 * cos(self.pressure_angle) / 2.0

    @property
    def ratio(self) -> float:
        """Speed ratio Omega2/Omega1 = z1/z2."""
        return self.z1 / self.z2

    @property
    def mu1(self) -> float:
        """Rotational inertia of gear 1 as a mass on its base circle, J1/rb1^2 (kg)."""
        return self.J1 / (self.rb1 * self.rb1)

    @property
    def mu2(self) -> float:
        """Rotational inertia of gear 2 as a mass on its base circle, J2/rb2^2 (kg)."""
        return self.J2 / (self.rb2 * self.rb2)

    @property
    def m_equiv(self) -> float:
        """Equivalent mass of the two rotational masses (kg)."""
        return self.mu1 * self.mu2 / (self.mu1 + self.mu2)

    @property
    def cb1(self) -> float:
        """Support damping of gear 1, 2 zeta sqrt(kb1 m1) (N.s/m)."""
        return 2.0 * self.damping_ratio * math.sqrt(self.kb1 * self.m1)

    @property
    def cb2(self) -> float:
        """Support damping of gear 2, 2 zeta sqrt(kb2 m2) (N.s/m)."""
        return 2.0 * self.damping_ratio * math.sqrt(self.kb2 * self.m2)

    @property
    def cr2(self) -> float:
        """Rotational damping of gear 2 on its base circle, 2 zeta sqrt(kr2 J2/rb2^2) (N.s/m)."""
        return 2.0 * self.damping_ratio * math.sqrt(self.kr2 * self.mu2)

    @property
    def cr1(self) -> float:
        """Input shaft damping of gear 1 on its base circle, 2 zeta sqrt(kr1 J1/rb1^2)
        (N.s/m)."""
        return 2.0 * self.damping_ratio * math.sqrt(self.kr1 * self.mu1)

    @property
    def cm(self) -> float:
        """Mesh damping, 2 zeta sqrt(km_mean m_e) (N.s/m); acts only while teeth touch."""
        return 2.0 * self.damping_ratio * math.sqrt(self.km_mean * self.m_equiv)

    def replace(self, **changes: Any) -> GearParams:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)

    @classmethod
    def describe(cls) -> list[dict[str, Any]]:
        """Name, default, unit, range and description of every field (for the FMU and docs)."""
        out = []
        for f in fields(cls):
            out.append({"name": f.name, "default": f.default, **f.metadata})
        return out


def unit_name(unit: str) -> str:
    """A unit as a message prints it: ``"1"`` (the FMI spelling of dimensionless) as nothing,
    every other unit as written."""
    return "" if unit in ("1", "") else unit


def check_rtol(rtol: Any, name: str = "rtol") -> float:
    """``rtol`` as a float, or ``ValueError`` naming the one allowed range
    [`RTOL_MIN`, `RTOL_MAX`]."""
    check_range(name, rtol, RTOL_META)
    return float(rtol)


def check_range(name: str, value: Any, meta: dict) -> None:
    """Raise ``ValueError`` unless ``value`` is a finite number inside the field's range."""
    lo, hi, lo_open = meta.get("min"), meta.get("max"), meta.get("lo_open", False)
    unit = meta.get("unit", "")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    left = "(" if lo_open else "["
    allowed = f"{left}{lo:g}, {hi:g}] {unit_name(unit)}".rstrip()
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}; allowed {allowed}")
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise ValueError(f"{name} = {value!r} is out of range; allowed {allowed}")
    if hi is not None and x > hi:
        raise ValueError(f"{name} = {value!r} is out of range; allowed {allowed}")


@dataclass(frozen=True)
class OperatingPoint:
    """Default operating inputs (the paper does not state them; docs/model.md "Choices").

    The slip model's mesh force spans 25-60 kN in Fig. 10, so the mean mesh force is near
    42 kN, i.e. a torque near 3.9 kN.m; stick occurs below 300 r/min (Fig. 15).
    """

    torque: float = field(
        default=3900.0, metadata=_meta("N.m", -TORQUE_MAX, TORQUE_MAX, "driving torque on gear 1")
    )
    speed: float = field(
        default=100.0 * RPM, metadata=_meta("rad/s", -SPEED_MAX, SPEED_MAX, "speed of gear 1")
    )

    def __post_init__(self) -> None:
        for f in fields(self):
            check_range(f.name, getattr(self, f.name), f.metadata)
