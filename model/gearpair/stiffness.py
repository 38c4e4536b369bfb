"""Mesh stiffness per tooth pair against contact position (Fig. 4; docs/model.md "Choices").

All laws are reduced once, at model build, to a table of per-pair stiffness against the
position ``xi`` along the path of contact (from A), scaled so that the time mean of the total
mesh stiffness is ``km_mean``. The right-hand side then only interpolates:

* the potential-energy law, which is smooth, by a cubic spline on `N_SPLINE` knots (within
  6e-7 of the law for Table 1, where straight lines between 401 points were within 2.8e-6).
  An integrator must end its steps on knots, where the interpolant's derivatives jump, so
  ten times fewer knots are ten times fewer forced step ends;
* a user ``table`` linearly, resampled to `N_TABLE` points: its kinks are the data's.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .effects import StiffnessSpec
from .geometry import Geometry
from .params import N_SPLINE, N_TABLE, GearParams  # noqa: F401


@dataclass(frozen=True)
class MeshStiffness:
    """Per-pair mesh stiffness ``k(xi)`` (N/m) on ``0 <= xi <= L``.

    Attributes
    ----------
    kind : the law it came from
    xi : grid positions from A (m), uniform
    k : per-pair stiffness on the grid (N/m); for ``constant`` unused
    km_mean : time mean of the total (N/m)
    cubic : for a spline, its coefficients per interval, shape (len(xi) - 1, 4): on
        ``xi[i] <= x <= xi[i + 1]``, ``k = c0 + c1 d + c2 d^2 + c3 d^3`` with
        ``d = x - xi[i]`` (N/m, N/m^2, N/m^3, N/m^4); None: linear between the points
    """

    kind: str
    xi: np.ndarray
    k: np.ndarray
    km_mean: float
    cubic: np.ndarray | None = None

    @classmethod
    def build(cls, p: GearParams, g: Geometry, spec: StiffnessSpec) -> MeshStiffness:
        """The law ``spec`` for gear data ``p`` (geometry ``g``). Every law but a table
        comes from the compiled set-up (`gearpair.fast.setup`: the potential-energy
        compliances on `N_SPLINE` knots, the not-a-knot spline and its exact mean); a table
        is resampled here and its arrays handed to the set-up as they are."""
        if spec.kind == "table":
            return cls._table(p, g, spec)
        from .fast.setup import run_setup  # here: gearpair.fast imports this module

        return cls.from_model_data(spec.kind, run_setup(p, stiffness=spec).md)

    @classmethod
    def from_model_data(cls, kind: str, md) -> MeshStiffness:
        """The law of the compiled set-up's `ModelData` (its tables and mean)."""
        from .fast.layout import I_KIND, KIND_CUBIC, P_KMEAN

        mean = float(md.par[P_KMEAN])
        if md.flag[I_KIND] != KIND_CUBIC:
            return cls(kind, md.xi_knots.copy(), md.k_coef.copy(), mean)
        xi, cubic = md.xi_knots.copy(), md.k_coef.reshape(-1, 4).copy()
        h = xi[1] - xi[0]
        c0, c1, c2, c3 = cubic[-1]
        return cls(kind, xi, np.r_[cubic[:, 0], ((c3 * h + c2) * h + c1) * h + c0], mean, cubic)

    @classmethod
    def _table(cls, p: GearParams, g: Geometry, spec: StiffnessSpec) -> MeshStiffness:
        from .fast.setupmath import trapezoid  # summed in a fixed order

        L = g.path_length
        tab = np.asarray(spec.table, dtype=float)
        xi = np.linspace(0.0, L, N_TABLE)
        k = np.interp(xi, tab[:, 0], tab[:, 1])
        if spec.scale_to_mean:
            # Time mean of the total is (1/pb) * integral_0^L k dxi: over n_pairs base
            # pitches each of the n_pairs tracked pairs sweeps the path once.
            mean = trapezoid(k, xi) / g.base_pitch
            k = k * (p.km_mean / mean)
        mean = float(trapezoid(k, xi) / g.base_pitch)
        return cls(spec.kind, xi, k, mean)

    def pairs(self, xi: np.ndarray, n_in_contact: int) -> np.ndarray:
        """Stiffness (N/m) of pairs at positions ``xi`` (all in contact)."""
        if self.kind == "constant":
            return np.full(np.shape(xi), self.km_mean / max(n_in_contact, 1))
        if self.cubic is not None:
            c, d = self._interval(xi)
            return ((c[..., 3] * d + c[..., 2]) * d + c[..., 1]) * d + c[..., 0]
        return np.interp(xi, self.xi, self.k)

    def _interval(self, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Spline coefficients of the interval holding each ``xi`` and the offset into it."""
        xi = np.asarray(xi, dtype=float)
        h = self.xi[1] - self.xi[0]
        i = np.clip(np.floor(xi / h).astype(int), 0, len(self.xi) - 2)
        return self.cubic[i], xi - self.xi[i]

    def slope(self, xi: np.ndarray, n_in_contact: int) -> np.ndarray:
        """d k / d xi (N/m^2) of pairs at ``xi`` (for the energy balance's parametric term)."""
        if self.kind in ("constant", "rectangular"):
            return np.zeros(np.shape(xi))
        if self.cubic is not None:
            c, d = self._interval(xi)
            return (3.0 * c[..., 3] * d + 2.0 * c[..., 2]) * d + c[..., 1]
        dk = np.diff(self.k) / np.diff(self.xi)
        idx = np.clip(np.searchsorted(self.xi, xi, side="right") - 1, 0, len(dk) - 1)
        return dk[idx]

    def total(self, g: Geometry, s: np.ndarray) -> np.ndarray:
        """Total mesh stiffness km (N/m) at mesh travels ``s`` (m), for plots (Fig. 4)."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        out = np.zeros_like(s)
        for i, si in enumerate(s):
            xi = g.pair_positions(si)
            on = g.in_contact(xi)
            out[i] = self.pairs(xi[on], int(on.sum())).sum()
        return out


def read_table(path: str | Path, p: GearParams | None = None) -> tuple[tuple[float, float], ...]:
    """Read a per-pair stiffness table from CSV.

    Columns: ``position_m,stiffness_n_per_m`` (position along the path of contact from its
    start A), or ``angle_rad,stiffness_n_per_m`` (rotation of gear 1 from the start of contact,
    converted with ``xi = rb1 * angle``, which needs ``p``). A header row is required.
    """
    path = Path(path)
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    if len(rows) < 3:
        raise ValueError(f"stiffness table {path}: needs a header and at least 2 rows")
    head = [h.strip().lower() for h in rows[0]]
    if len(head) < 2 or head[1] not in ("stiffness_n_per_m", "stiffness"):
        raise ValueError(
            f"stiffness table {path}: header must be 'position_m,stiffness_n_per_m' or "
            f"'angle_rad,stiffness_n_per_m', got {','.join(rows[0])}"
        )
    scale = 1.0
    if head[0] == "angle_rad":
        if p is None:
            raise ValueError("stiffness table in angle needs the gear parameters (rb1)")
        scale = p.rb1
    elif head[0] != "position_m":
        raise ValueError(f"stiffness table {path}: first column must be position_m or angle_rad")
    out = []
    for i, r in enumerate(rows[1:], start=2):
        try:
            a, b = float(r[0]), float(r[1])
        except (ValueError, IndexError):
            raise ValueError(f"stiffness table {path}, line {i}: two numbers expected") from None
        if not (math.isfinite(a) and math.isfinite(b)):
            raise ValueError(f"stiffness table {path}, line {i}: non-finite value")
        out.append((a * scale, b))
    return tuple(out)
