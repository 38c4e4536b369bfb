"""Spur gear geometry along the line of action (docs/model.md, Fig. 3).

Positions along the line of action (LOA) are measured from S1, the tangent point on gear 1's
base circle. Contact runs A -> B -> P -> D -> E: A start of contact, P the pitch point,
[B, D] the single-contact zone, E end of contact. A tooth pair is labelled by its position
``xi`` along the path of contact measured from A (0 <= xi < L, L = AE).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .params import GearParams


@dataclass(frozen=True)
class Geometry:
    """Derived geometry of a gear pair (all lengths in m).

    Attributes
    ----------
    rb1, rb2 : base radii; ra1, ra2 : tip radii; rf1, rf2 : root radii
    center_distance : a = m (z1 + z2) / 2
    s1s2 : length of the LOA between the base-circle tangent points, a sin(alpha)
    base_pitch : pb = pi m cos(alpha)
    s1a, s1b, s1p, s1d, s1e : positions of A, B, P, D, E from S1
    contact_ratio : eps = AE / pb
    n_pairs : ceil(eps), the number of tooth pairs tracked
    """

    rb1: float
    rb2: float
    ra1: float
    ra2: float
    rf1: float
    rf2: float
    center_distance: float
    s1s2: float
    base_pitch: float
    s1a: float
    s1b: float
    s1p: float
    s1d: float
    s1e: float
    contact_ratio: float
    n_pairs: int

    @classmethod
    def from_params(cls, p: GearParams) -> Geometry:
        """The geometry of gear data ``p``: the compiled set-up's (`gearpair.fast.setup`,
        the same bits on every machine). Raises ValueError when the tip circles leave the
        line of action (interference) or the contact ratio is below 1."""
        from .fast.setup import geometry_vector  # here: gearpair.fast imports this module

        return cls.from_vector(geometry_vector(p))

    @classmethod
    def from_vector(cls, geo) -> Geometry:
        """The geometry from the compiled set-up's vector (`gearpair.fast.setup.GEO_NAMES`)."""
        from .fast.setup import GEO_NAMES

        vals = dict(zip(GEO_NAMES, (float(v) for v in geo), strict=True))
        vals["n_pairs"] = int(vals["n_pairs"])
        return cls(**vals)

    @property
    def path_length(self) -> float:
        """Length AE of the path of contact (m)."""
        return self.s1e - self.s1a

    @property
    def xi_pitch(self) -> float:
        """Position of the pitch point P from A (m)."""
        return self.s1p - self.s1a

    @property
    def period_length(self) -> float:
        """Length over which the labels of the tracked pairs repeat, n_pairs * pb (m)."""
        return self.n_pairs * self.base_pitch

    def pair_positions(self, s: float) -> np.ndarray:
        """Positions ``xi_j`` (from A) of the tracked pairs at mesh travel ``s`` (m).

        ``s`` is the distance the contact points have moved along the LOA, i.e.
        ``rb1 * integral(Omega1 dt)``. Pair j sits at ``(s + j pb) mod (n_pairs pb)``; it is
        in contact while ``0 <= xi_j < L``.
        """
        j = np.arange(self.n_pairs)
        return np.mod(s + j * self.base_pitch, self.period_length)

    def in_contact(self, xi: np.ndarray) -> np.ndarray:
        """Which pairs are on the path of contact."""
        return (xi >= 0.0) & (xi < self.path_length)

    def arms(self, xi: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Friction moment arms S1Mj and S2Mj (m) of pairs at positions ``xi`` (Eq. (9))."""
        s1m = self.s1a + np.asarray(xi, dtype=float)
        return s1m, self.s1s2 - s1m

    def boundaries(self, s0: float, s1: float, extra: tuple[float, ...] = ()) -> np.ndarray:
        """Mesh travels in the open interval (s0, s1) where a pair enters or leaves contact.

        Entries happen at ``s = k pb``, exits at ``s = k pb + (L mod pb)``; ``extra`` adds
        more positions ``xi`` (e.g. the pitch point) at which every pair causes a boundary.
        Works for either direction of travel (s1 < s0).
        """
        lo, hi = min(s0, s1), max(s0, s1)
        pb = self.base_pitch
        offsets = [0.0, math.fmod(self.path_length, pb)]
        offsets += [math.fmod(x, pb) for x in extra]
        out = []
        for off in offsets:
            k0 = math.floor((lo - off) / pb)
            k1 = math.ceil((hi - off) / pb)
            for k in range(k0, k1 + 1):
                b = k * pb + off
                if lo < b < hi:
                    out.append(b)
        out = np.unique(np.array(out, dtype=float))
        return out if s1 >= s0 else out[::-1]


# -- gear bodies from the geometry ---------------------------------------------------------------
STEEL_DENSITY = 7850.0  # kg/m^3
BORE_RATIO_TABLE1 = 0.8  # Table 1's masses and inertias are steel rings of this bore ratio
BORE_RATIO_MAX = 0.99  # a thinner rim is no gear body


def body_mass_inertia(module: float, teeth: int, face_width: float,
                      bore_ratio: float = BORE_RATIO_TABLE1,
                      density: float = STEEL_DENSITY) -> tuple[float, float]:
    """Mass (kg) and polar moment of inertia (kg.m2) of a gear body as a ring.

    The body is a ring of outer radius the pitch radius ``r = module teeth / 2``, inner
    radius ``bore_ratio r`` and width ``face_width``: ``m = density pi b (r^2 - r_i^2)``,
    ``J = m (r^2 + r_i^2) / 2``. Counting the teeth up to the pitch circle stands for their
    real shape: the tooth zone between the root circle (1.25 module below the pitch circle)
    and the tip circle (1 module above) is filled about half, which holds as much steel as
    the full ring from the root to the pitch circle. Hub, web and spokes are not modelled: a
    webbed wheel is described by the bore ratio of a plain ring of equal mass (or give its
    masses directly).

    Table 1's data (module 6 mm, 33 and 80 teeth, 200 mm face width) are steel rings of bore
    ratio 0.8 within 0.7 % (17.40 kg / 0.1399 kg.m2 against 17.29 / 0.139; 102.3 / 4.831
    against 101.62 / 4.799).
    """
    if not (math.isfinite(bore_ratio) and 0.0 <= bore_ratio <= BORE_RATIO_MAX):
        raise ValueError(f"bore_ratio = {bore_ratio!r} is out of range; allowed "
                         f"[0, {BORE_RATIO_MAX:g}] (bore diameter over pitch diameter)")
    if not (math.isfinite(density) and 0.0 < density <= 1e5):
        raise ValueError(f"density = {density!r} is out of range; allowed (0, 1e+05] kg/m^3")
    r = module * teeth / 2.0
    ri = bore_ratio * r
    m = density * math.pi * face_width * (r * r - ri * ri)
    return m, 0.5 * m * (r * r + ri * ri)


def steel_body(p: GearParams, bore_ratio: float | tuple[float, float] = BORE_RATIO_TABLE1,
               density: float = STEEL_DENSITY) -> GearParams:
    """``p`` with ``m1, J1, m2, J2`` derived from its module, tooth numbers and face width.

    Each gear is a steel ring (`body_mass_inertia`); ``bore_ratio`` (bore diameter over pitch
    diameter) is one value for both gears or ``(gear 1, gear 2)``. The other fields, ``kr2``
    included, are kept: `gearpair.modal.tune_kr2` then sets the first natural frequency.
    """
    b1, b2 = (bore_ratio, bore_ratio) if not isinstance(bore_ratio, (tuple, list)) \
        else bore_ratio
    m1, j1 = body_mass_inertia(p.module, p.z1, p.face_width, float(b1), density)
    m2, j2 = body_mass_inertia(p.module, p.z2, p.face_width, float(b2), density)
    return p.replace(m1=m1, J1=j1, m2=m2, J2=j2)


class GearDataWarning(UserWarning):
    """Gear data that are valid but probably not what was meant (`table1_body_mismatch`)."""


# Table 1's geometry, for which its masses and inertias hold.
_TABLE1_GEOMETRY = ("module", "z1", "z2", "face_width")
_TABLE1_BODY = ("m1", "J1", "m2", "J2")


def table1_body_mismatch(p: GearParams) -> str | None:
    """A warning text when ``p`` keeps Table 1's masses or inertias with another geometry,
    else None (Table 1's bodies belong to module 6 mm, 33/80 teeth, 200 mm face width)."""
    d = GearParams()
    moved = [k for k in _TABLE1_GEOMETRY if getattr(p, k) != getattr(d, k)]
    kept = [k for k in _TABLE1_BODY if getattr(p, k) == getattr(d, k)]
    if not moved or not kept:
        return None
    verb = "differs" if len(moved) == 1 else "differ"
    return (f"{', '.join(kept)} are Table 1's values, but {', '.join(moved)} {verb} from "
            "Table 1's gears (module 6 mm, 33/80 teeth, 0.2 m face width): derive them from "
            "the geometry (gearpair.geometry.steel_body; scenes: [gear] bore_ratio; CLI: "
            "--bore-ratio) or give your own, and tune kr2 to your first mode "
            "(first_mode_hz, --first-mode-hz)")


# Nominal tooth-root load Ft / (b m) above which no steel spur gear carries the torque: the
# tooth-root stress of ISO 6336-3 is sigma_F0 = Ft / (b m) Y_FS, with Y_FS (form factor
# times stress correction) about 4 to 4.6 for standard unshifted 20-degree teeth, and the
# bending strength of the best case-hardened steels is sigma_FE = 2 sigma_Flim = 1050 MPa
# (ISO 6336-5, grade ME). 250 N/mm2 puts sigma_F0 at 1000-1150 MPa: the teeth would break.
# Table 1's gears at the paper's 3900 N.m carry 33 N/mm2.
UNIT_LOAD_LIMIT = 250.0  # N/mm2


def unit_load(p: GearParams, torque: float) -> float:
    """Nominal tooth-root load ``Ft / (b m)`` (N/mm2) of gear 1 driven with ``torque`` (N.m):
    ``Ft = 2 |T| / d1`` the tangential force at the pitch circle (ISO 6336), ``b`` the face
    width and ``m`` the module."""
    ft = 2.0 * abs(torque) / (p.module * p.z1)
    return ft / (p.face_width * p.module) / 1e6


def load_implausibility(p: GearParams, torque: float) -> str | None:
    """A warning text when ``torque`` (N.m, the largest magnitude a run applies) loads the
    teeth of ``p`` beyond `UNIT_LOAD_LIMIT`, else None. The model would still run: its mesh
    stiffness does not depend on load and nothing in it breaks."""
    if not math.isfinite(torque):
        return None
    u = unit_load(p, torque)
    if u <= UNIT_LOAD_LIMIT:
        return None
    ft = 2.0 * abs(torque) / (p.module * p.z1)
    return (f"torque {abs(torque):g} N.m is implausible for these teeth: nominal tooth-root "
            f"load Ft/(b m) = {u:.0f} N/mm2 (Ft = 2T/d1 = {ft / 1e3:.3g} kN, b = "
            f"{p.face_width * 1e3:g} mm, m = {p.module * 1e3:g} mm) exceeds "
            f"{UNIT_LOAD_LIMIT:g} N/mm2, where the tooth-root stress (4-4.6 x this for "
            "standard teeth, ISO 6336-3) passes the bending strength of the best "
            "case-hardened steels (1050 MPa, ISO 6336-5); the model (no tooth damage, "
            "load-independent stiffness) runs but describes no real gear: lower the torque "
            "or check module and face width")


def warn_implausible_load(p: GearParams, torque: float, stacklevel: int = 2) -> None:
    """`load_implausibility` as a `GearDataWarning` (nothing if the load is plausible)."""
    msg = load_implausibility(p, torque)
    if msg:
        warnings.warn(msg, GearDataWarning, stacklevel=stacklevel + 1)
