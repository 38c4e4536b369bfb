"""Stiffness of one tooth pair against contact position: the potential-energy method.

The tooth is a non-uniform cantilever clamped at its root. The strain energy stored under a
unit normal load at the contact point gives its compliances (m/N):

* bending, shear and axial compression of the involute part of the tooth (Yang & Lin 1987,
  as corrected by Tian 2004 and used by Chaari et al. 2009), integrated over the involute
  parameter ``alpha`` from ``-alpha1`` (contact point) to the root of the involute;
* when the root circle lies below the base circle (``rf < rb``), the straight part of the
  tooth between the two circles, modelled as a rectangular cantilever segment of half width
  ``rb sin(alpha2)`` (the tooth's half chord on the base circle), as in Chen & Shao (2011);
  when it lies above, only the involute above the root circle is integrated;
* the fillet-foundation (gear body) compliance of Sainsot, Velex & Duverger (2004);
* Hertzian contact, ``4 (1 - nu^2) / (pi E b)`` (independent of position).

The pair compliance is ``1/k = 1/k_h + sum_{teeth} (1/k_b + 1/k_s + 1/k_a + 1/k_f)``.

Tooth coordinates (one tooth, gear centre at the origin, x along the tooth centre line): the
involute point with parameter ``alpha`` lies at
``x = rb [cos(alpha) - (alpha2 - alpha) sin(alpha)]`` with half thickness
``h = rb [sin(alpha) + (alpha2 - alpha) cos(alpha)]``, where
``alpha2 = pi / (2 z) + inv(alpha0)`` is the half tooth angle on the base circle and
``alpha2 - alpha`` is the roll angle. ``alpha = alpha2`` is the base circle; the contact point
is ``alpha = -alpha1`` with ``alpha1 = tan(alpha_r) - alpha2`` and ``tan(alpha_r) = S_iM / rb_i``.
The normal load makes the angle ``alpha1`` with the normal to the centre line, so it bends the
tooth with ``F cos(alpha1)`` and compresses it with ``F sin(alpha1)``.

Positions ``xi`` follow `geometry`: measured along the line of action from A, the start of
contact, ``S1M = s1a + xi`` and ``S2M = s1s2 - S1M``. Gear 1's tip is at ``xi = L`` and gear 2's
tip at ``xi = 0``.

The body (fillet-foundation) term needs the bore radius, which Table 1 does not give. By
default it is inferred from Table 1's masses and inertias: the paper's ``m_i`` and ``J_i`` are
those of steel annular discs whose outer radius is the pitch radius (``J = m (r_p^2 +
r_int^2) / 2`` gives r_int = 79.2 mm and 192.0 mm, and the same discs have the listed masses
at 7850 kg/m^3 within 1 %). See `bore_radius`.
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import Geometry
from .params import (  # noqa: F401 - the law's data, declared with the gear data
    H_FI_RANGE,
    N_GAUSS,
    SAINSOT_COEFFS,
    GearParams,
)


def _inv(a: float | np.ndarray) -> float | np.ndarray:
    """Involute function ``tan(a) - a``."""
    from .fast import setupmath as smath  # here: gearpair.fast imports this module

    return smath.tan(a) - a


def _gear_data(p: GearParams, g: Geometry, gear: int) -> tuple[int, float, float, float]:
    if gear == 1:
        return p.z1, g.rb1, g.rf1, p.module * p.z1 / 2.0
    if gear == 2:
        return p.z2, g.rb2, g.rf2, p.module * p.z2 / 2.0
    raise ValueError(f"gear must be 1 or 2, got {gear!r}")


def bore_radius(p: GearParams, g: Geometry, gear: int) -> float:
    """Bore (inner) radius of gear ``gear`` used by the fillet-foundation term (m).

    Taken from the mass and inertia of the gear as an annular disc whose outer radius is the
    pitch radius ``r_p``: ``r_int^2 = 2 J / m - r_p^2`` (79.2 mm and 192.0 mm for Table 1).
    The result is clipped so that ``h_fi = rf / r_int`` stays in `H_FI_RANGE`, which also covers
    data for which the formula has no real root.

    Parameters
    ----------
    p : GearParams
        Gear data.
    g : Geometry
        Geometry derived from ``p``.
    gear : {1, 2}
        Which gear.

    Returns
    -------
    float
        Bore radius (m).
    """
    _, _, rf, rp = _gear_data(p, g, gear)
    m, J = (p.m1, p.J1) if gear == 1 else (p.m2, p.J2)
    r2 = 2.0 * J / m - rp * rp
    lo, hi = rf / H_FI_RANGE[1], rf / H_FI_RANGE[0]
    r = math.sqrt(r2) if r2 > 0.0 else lo
    return min(max(r, lo), hi)


def load_angle(p: GearParams, g: Geometry, xi: np.ndarray, gear: int) -> np.ndarray:
    """Load angle ``alpha1`` of gear ``gear`` at positions ``xi`` (rad).

    ``alpha1 = tan(alpha_r) - alpha2`` with ``tan(alpha_r) = S_iM / rb_i`` (roll angle of the
    contact point) and ``alpha2 = pi / (2 z_i) + inv(alpha0)``.

    Parameters
    ----------
    p : GearParams
        Gear data.
    g : Geometry
        Geometry derived from ``p``.
    xi : array_like
        Contact positions from A along the line of action (m).
    gear : {1, 2}
        Which gear.

    Returns
    -------
    numpy.ndarray
        Angle between the normal load and the normal to the tooth centre line (rad).
    """
    z, rb, _, _ = _gear_data(p, g, gear)
    s1m = g.s1a + np.asarray(xi, dtype=float)
    sm = s1m if gear == 1 else g.s1s2 - s1m
    alpha2 = math.pi / (2.0 * z) + float(_inv(p.pressure_angle))
    return sm / rb - alpha2


def tooth_compliances(
    p: GearParams,
    g: Geometry,
    xi: np.ndarray,
    gear: int,
    *,
    root_segment: bool = True,
    n_gauss: int = N_GAUSS,
    r_int: float | None = None,
) -> dict[str, np.ndarray]:
    """Compliances of one tooth of gear ``gear`` loaded at positions ``xi``.

    Parameters
    ----------
    p : GearParams
        Gear data (uses ``youngs_modulus``, ``poisson``, ``face_width``, ``module``,
        ``pressure_angle``, ``z1``, ``z2``; ``m_i``, ``J_i`` for the default bore).
    g : Geometry
        Geometry derived from ``p`` (base and root radii, positions on the line of action).
    xi : array_like
        Contact positions from A along the line of action (m), ``0 <= xi <= L``.
    gear : {1, 2}
        Which gear's tooth.
    root_segment : bool, optional
        If the root circle is below the base circle, add the straight tooth part between them
        as a rectangular cantilever segment (default True). No effect if ``rf >= rb``.
    n_gauss : int, optional
        Number of Gauss-Legendre points over the involute.
    r_int : float, optional
        Bore radius for the fillet-foundation term (m); default `bore_radius`.

    Returns
    -------
    dict of str to numpy.ndarray
        ``"bending"``, ``"shear"``, ``"axial"``, ``"fillet"`` compliances (m/N), each with the
        shape of ``xi``.
    """
    from .fast.setup import tooth_compliances as compiled  # one source: the set-up's

    del g  # the compiled set-up derives the same geometry from p
    xi = np.asarray(xi, dtype=float)
    if gear not in (1, 2):
        raise ValueError(f"gear must be 1 or 2, got {gear!r}")
    c = compiled(p, xi, gear, root_segment=root_segment, n_gauss=n_gauss, r_int=r_int)
    return {name: c[k].reshape(xi.shape)
            for k, name in enumerate(("bending", "shear", "axial", "fillet"))}


def hertz_compliance(p: GearParams) -> float:
    """Hertzian contact compliance of a tooth pair, ``4 (1 - nu^2) / (pi E b)`` (m/N).

    Parameters
    ----------
    p : GearParams
        Gear data (``youngs_modulus``, ``poisson``, ``face_width``).

    Returns
    -------
    float
        Contact compliance (m/N), the same at every contact position.
    """
    return 4.0 * (1.0 - p.poisson * p.poisson) / (math.pi * p.youngs_modulus * p.face_width)


def pair_stiffness_raw(
    p: GearParams,
    g: Geometry,
    xi: np.ndarray,
    *,
    root_segment: bool = True,
    n_gauss: int = N_GAUSS,
) -> np.ndarray:
    """Stiffness of one tooth pair against contact position, not scaled (N/m).

    Parameters
    ----------
    p : GearParams
        Gear data.
    g : Geometry
        Geometry derived from ``p``.
    xi : array_like
        Contact positions from A along the line of action (m), ``0 <= xi <= L``.
    root_segment : bool, optional
        Include the straight tooth part below the base circle (see `tooth_compliances`).
    n_gauss : int, optional
        Number of Gauss-Legendre points over the involute.

    Returns
    -------
    numpy.ndarray
        ``1 / (1/k_h + sum over both teeth of 1/k_b + 1/k_s + 1/k_a + 1/k_f)`` (N/m), with the
        shape of ``xi``.
    """
    xi = np.asarray(xi, dtype=float)
    total = np.full(xi.shape, hertz_compliance(p))
    for gear in (1, 2):
        c = tooth_compliances(p, g, xi, gear, root_segment=root_segment, n_gauss=n_gauss)
        total = total + c["bending"] + c["shear"] + c["axial"] + c["fillet"]
    return 1.0 / total
