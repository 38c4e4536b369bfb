"""Natural frequencies and mode shapes of the slip and stick models (Figs. 5-6).

Both use the mean mesh stiffness in contact (Theta = 1). The stick model is Eq. (22) with the
matrices of Eqs. (23)-(24), built as ``Mt = P M T`` and ``Kt = P K T``: ``T`` (6x5) expresses
q through ``[x1, y1, u1, y2, u2]`` with x2 tied to x1, and the rows of ``P`` (5x6) are the
combinations of Eqs. (1)-(2) that eliminate the friction force, ``P w = 0`` (sum of the x
equations; each rotation equation plus its arm times an x equation). Mt is not symmetric
(friction acts on a lever arm), so the eigenproblem is a general one.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import eig, eigh, null_space

from .equations import X1, X2, G, Model

SLIP_NAMES = ("x1", "y1", "u1", "x2", "y2", "u2")


def slip_matrices(model: Model, km: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Mass and stiffness of the slip model, Eqs. (4)-(7) with Theta = 1 (kg, N/m)."""
    km = model.stiff.km_mean if km is None else km
    return model.M.copy(), model.Kb + km * np.outer(G, G)


def stick_matrices(model: Model, xi: float | None = None, km: float | None = None):
    """``(Mt, Ct, Kt, P, T)`` of the stick model, Eqs. (22)-(24), for a pair stuck at ``xi``
    (m from A; default the pitch point). Ct includes mesh damping."""
    p, geo = model.p, model.geom
    xi = geo.xi_pitch if xi is None else xi
    s1m, s2m = geo.arms(xi)
    s1m, s2m = float(s1m), float(s2m)
    km = model.stiff.km_mean if km is None else km
    w = model.friction_directions(np.array([s1m]), np.array([s2m]))[0]
    if model.effects.sliding == "paper":
        T = np.zeros((6, 5))
        T[X1, 0] = T[X2, 0] = 1.0  # x2 moves with x1, Eq. (19)
        T[1, 1] = T[2, 2] = T[4, 3] = T[5, 4] = 1.0
        P = np.zeros((5, 6))
        P[0, X1] = P[0, X2] = 1.0
        P[1, 1] = 1.0
        P[2, 2], P[2, X1] = 1.0, s1m / p.rb1
        P[3, 4] = 1.0
        P[4, 5], P[4, X2] = 1.0, -s2m / p.rb2
    else:
        T = null_space(w[None, :])           # full sliding: w . q' = nominal
        P = null_space(w[None, :]).T
    K = model.Kb + km * np.outer(G, G)
    C = model.C + p.cm * np.outer(G, G)
    return P @ model.M @ T, P @ C @ T, P @ K @ T, P, T


def _normalize(shapes: np.ndarray) -> np.ndarray:
    out = shapes.copy()
    for i in range(out.shape[1]):
        k = int(np.argmax(np.abs(out[:, i])))
        out[:, i] /= out[k, i]
    return out


def modes(model: Model, which: str = "slip", xi: float | None = None):
    """Natural frequencies (Hz, ascending) and mode shapes in q = [x1..u2] (columns,
    largest component 1) of the ``slip`` (6) or ``stick`` (5) model."""
    if which == "slip":
        M, K = slip_matrices(model)
        free = model.free_dofs  # torsional: the (u1, u2) block, shapes padded with zeros
        lam, v = eigh(K[np.ix_(free, free)], M[np.ix_(free, free)])
        vec = np.zeros((6, len(free)))
        vec[free] = v
    elif which == "stick":
        Mt, _, Kt, _, T = stick_matrices(model, xi)
        lam, vec = eig(Kt, Mt)
        if np.max(np.abs(lam.imag)) > 1e-9 * np.max(np.abs(lam.real)):
            raise ArithmeticError("stick model has complex eigenvalues")
        lam, vec = lam.real, T @ vec.real
        order = np.argsort(lam)
        lam, vec = lam[order], vec[:, order]
    else:
        raise ValueError(f"which = {which!r}; choose slip or stick")
    freqs = np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi)
    return freqs, _normalize(vec)


def natural_frequencies(model: Model, which: str = "slip") -> np.ndarray:
    """Natural frequencies (Hz) of the slip or stick model."""
    return modes(model, which)[0]


def kr2_for_first_mode(model: Model, f_hz: float = 32.0) -> float:
    """The rotational stiffness kr2 (N/m on the base circle) that puts the slip model's first
    natural frequency at ``f_hz`` (the paper's 32 Hz 'rigid' mode)."""
    from scipy.optimize import brentq

    from .effects import Effects

    def f1(log_kr2):
        p = model.p.replace(kr2=float(np.exp(log_kr2)))
        # Only the mean mesh stiffness enters the modes: skip building the stiffness law.
        return natural_frequencies(Model.build(p, Effects(stiffness="constant")), "slip")[0] - f_hz

    return float(np.exp(brentq(f1, np.log(1e2), np.log(1e12), xtol=1e-12)))
