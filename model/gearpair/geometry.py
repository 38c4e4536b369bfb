"""Spur gear geometry along the line of action (MODEL.md "Geometry", Fig. 3).

Positions along the line of action (LOA) are measured from S1, the tangent point on gear 1's
base circle. Contact runs A -> B -> P -> D -> E: A start of contact, P the pitch point,
[B, D] the single-contact zone, E end of contact. A tooth pair is labelled by its position
``xi`` along the path of contact measured from A (0 <= xi < L, L = AE).
"""

from __future__ import annotations

import math
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
        m, a0 = p.module, p.pressure_angle
        rb1, rb2 = p.rb1, p.rb2
        ra1 = m * p.z1 / 2 + p.addendum_coef * m
        ra2 = m * p.z2 / 2 + p.addendum_coef * m
        rf1 = m * p.z1 / 2 - p.dedendum_coef * m
        rf2 = m * p.z2 / 2 - p.dedendum_coef * m
        a = m * (p.z1 + p.z2) / 2
        s1s2 = a * math.sin(a0)
        pb = math.pi * m * math.cos(a0)
        s1a = s1s2 - math.sqrt(ra2**2 - rb2**2)
        s1e = math.sqrt(ra1**2 - rb1**2)
        s1p = rb1 * math.tan(a0)
        if s1a < 0 or s1e > s1s2:
            raise ValueError(
                "addendum_coef too large: the path of contact leaves the line of action "
                "(interference); allowed: tip circles that keep A and E between S1 and S2"
            )
        eps = (s1e - s1a) / pb
        if eps < 1.0:
            raise ValueError(
                f"contact ratio {eps:.3f} is below 1 (allowed >= 1): the gears cannot mesh "
                "continuously; raise addendum_coef or the tooth numbers"
            )
        return cls(
            rb1=rb1, rb2=rb2, ra1=ra1, ra2=ra2, rf1=rf1, rf2=rf2, center_distance=a,
            s1s2=s1s2, base_pitch=pb, s1a=s1a, s1b=s1e - pb, s1p=s1p, s1d=s1a + pb, s1e=s1e,
            contact_ratio=eps, n_pairs=math.ceil(eps),
        )

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
