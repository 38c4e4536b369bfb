"""Natural frequencies and mode shapes of the slip and stick models (Figs. 5-6).

Both use the mean mesh stiffness in contact (Theta = 1). The stick model is Eq. (22) with the
matrices of Eqs. (23)-(24), built as ``Mt = P M T`` and ``Kt = P K T``: ``T`` (6x5) expresses
q through ``[x1, y1, u1, y2, u2]`` with x2 tied to x1, and the rows of ``P`` (5x6) are the
combinations of Eqs. (1)-(2) that eliminate the friction force, ``P w = 0`` (sum of the x
equations; each rotation equation plus its arm times an x equation). Mt is not symmetric
(friction acts on a lever arm), so the eigenproblem is a general one.

Every public function takes the gear data as a `GearParams` (with optional `Effects`: only
``dof`` and ``sliding`` matter here) or an already built `Model`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .effects import Effects, StiffnessSpec
from .equations import X1, X2, G, Model
from .params import GearParams

SLIP_NAMES = ("x1", "y1", "u1", "x2", "y2", "u2")


def as_model(system: GearParams | Model, effects: Effects | None = None) -> Model:
    """The `Model` whose modes are wanted: ``system`` itself if it is one, else built from the
    `GearParams` with ``effects`` (default `Effects()`) and a constant mesh stiffness, since
    only its mean enters the modes (no stiffness law is built)."""
    if isinstance(system, Model):
        if effects is not None and effects != system.effects:
            return as_model(system.p, effects)
        return system
    if not isinstance(system, GearParams):
        raise TypeError(f"expected GearParams or Model, got {type(system).__name__}")
    fx = Effects() if effects is None else effects
    return Model.build(system, replace(fx, stiffness=StiffnessSpec(kind="constant")))


def slip_matrices(model: Model, km: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Mass and stiffness of the slip model, Eqs. (4)-(7) with Theta = 1 (kg, N/m)."""
    km = model.stiff.km_mean if km is None else km
    return model.M.copy(), model.Kb + km * np.outer(G, G)


def stick_matrices(model: Model, xi: float | None = None, km: float | None = None):
    """``(Mt, Ct, Kt, P, T)`` of the stick model, Eqs. (22)-(24), for a pair stuck at ``xi``
    (m from A; default the pitch point). Ct includes mesh damping."""
    from .fast.detlinalg import matmul, null_space_row  # not BLAS: the same bits everywhere

    p, geo = model.p, model.geom
    xi = geo.xi_pitch if xi is None else xi
    s1m, s2m = geo.arms(xi)
    s1m, s2m = float(s1m), float(s2m)
    km = model.stiff.km_mean if km is None else km
    w = model.friction_directions(np.array([s1m]), np.array([s2m]))[0]
    free = model.free_dofs
    if len(free) < 6 and model.effects.sliding == "paper":
        # the torsional model has no x1, x2 for Eq. (19) to tie (as `Effects` refuses it)
        raise ValueError("the torsional model's stick state needs sliding = 'full'")
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
        # full sliding: w . q' = nominal, over the free coordinates only (torsional: rigid
        # supports leave u1, u2, so a stuck pair has one degree of freedom)
        T = np.zeros((6, len(free) - 1))
        T[free] = null_space_row(w[free])
        P = T.T
    K = model.Kb + km * np.outer(G, G)
    C = model.C + p.cm * np.outer(G, G)
    return (matmul(matmul(P, model.M), T), matmul(matmul(P, C), T), matmul(matmul(P, K), T),
            P, T)


def _normalize(shapes: np.ndarray) -> np.ndarray:
    out = shapes.copy()
    for i in range(out.shape[1]):
        k = int(np.argmax(np.abs(out[:, i])))
        out[:, i] /= out[k, i]
    return out


def modes(system: GearParams | Model, which: str = "slip", xi: float | None = None,
          effects: Effects | None = None):
    """Natural frequencies (Hz, ascending) and mode shapes of the slip or stick model.

    Parameters
    ----------
    system : GearParams or Model
        The gear data (see `as_model`).
    which : {"slip", "stick"}
        ``slip``: Eqs. (4)-(7), 6 modes (2 in the torsional model); ``stick``: Eq. (22),
        5 modes, a pair stuck at ``xi`` (m from A; default the pitch point).
    effects : Effects, optional
        ``dof`` and ``sliding`` of the model (with a `GearParams`).

    Returns
    -------
    freqs : ndarray
        Natural frequencies (Hz), ascending.
    shapes : ndarray
        Mode shapes in q = [x1, y1, u1, x2, y2, u2] (m), one column per mode, largest
        component 1.
    """
    # the set-up's own eigen-solvers: LAPACK's round differently from one CPU and BLAS kernel
    # to another (`gearpair.fast.detlinalg`)
    from .fast.detlinalg import eig_real_general, eigh_generalized, matmul

    model = as_model(system, effects)
    if which == "slip":
        M, K = slip_matrices(model)
        free = model.free_dofs  # torsional: the (u1, u2) block, shapes padded with zeros
        lam, v = eigh_generalized(K[np.ix_(free, free)], M[np.ix_(free, free)])
        vec = np.zeros((6, len(free)))
        vec[free] = v
    elif which == "stick":
        Mt, _, Kt, _, T = stick_matrices(model, xi)
        lam, vec = eig_real_general(Kt, Mt)  # ascending; complex: ArithmeticError
        vec = matmul(T, vec)
    else:
        raise ValueError(f"which = {which!r}; choose slip or stick")
    freqs = np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi)
    return freqs, _normalize(vec)


def natural_frequencies(system: GearParams | Model, which: str = "slip",
                        effects: Effects | None = None) -> np.ndarray:
    """Natural frequencies (Hz, ascending) of the slip or stick model (see `modes`), e.g.
    ``natural_frequencies(GearParams(module=4e-3, z1=25, z2=60))``."""
    return modes(system, which, effects=effects)[0]


_KR2_BRACKET = (1e2, 1e12)  # N/m searched for kr2 (the field allows (0, 1e14])


def kr2_for_first_mode(system: GearParams | Model, f_hz: float = 32.0,
                       effects: Effects | None = None) -> float:
    """The rotational stiffness kr2 (N/m on gear 2's base circle) that puts the first
    (lowest) natural frequency of the slip model (Eqs. (4)-(7), mean mesh stiffness) at
    ``f_hz``.

    That mode is the paper's 32 Hz one (Fig. 5): both gears turn together against the load
    shaft kr2, with the mesh hardly deflected. Adding stiffness never lowers a natural
    frequency, so the first one rises monotonically with kr2 and the root is unique; it
    saturates where another mode (a support translation) becomes the lowest, so a target
    above that is refused with ``ValueError`` giving the reachable range.
    """
    from scipy.optimize import brentq

    from .fast.setupmath import exp, log  # the same bits on every machine

    model = as_model(system, effects)
    if not (np.isfinite(f_hz) and f_hz > 0):
        raise ValueError(f"first_mode_hz = {f_hz!r} is out of range; allowed > 0 Hz")

    def f1(log_kr2):
        p = model.p.replace(kr2=exp(log_kr2))
        return natural_frequencies(as_model(p, model.effects), "slip")[0] - f_hz

    lo, hi = (log(x) for x in _KR2_BRACKET)
    f_lo, f_hi = f1(lo) + f_hz, f1(hi) + f_hz
    if not f_lo < f_hz < f_hi:
        raise ValueError(f"first_mode_hz = {f_hz:g} is out of reach for this gear data: kr2 "
                         f"from {_KR2_BRACKET[0]:g} to {_KR2_BRACKET[1]:g} N/m gives a first "
                         f"mode from {f_lo:.4g} to {f_hi:.4g} Hz")
    return exp(brentq(f1, lo, hi, xtol=1e-12))


def tune_kr2(p: GearParams, first_mode_hz: float = 32.0,
             effects: Effects | None = None) -> GearParams:
    """``p`` with ``kr2`` set so that the slip model's first natural frequency is
    ``first_mode_hz`` (`kr2_for_first_mode`); Table 1's kr2 gives 32 Hz for Table 1's gears
    only."""
    return p.replace(kr2=kr2_for_first_mode(p, first_mode_hz, effects))


def derive_params(p: GearParams, *, bore_ratio: float | tuple[float, float] | None = None,
                  first_mode_hz: float | None = None,
                  effects: Effects | None = None) -> GearParams:
    """``p`` with the quantities Table 1 cannot give for other gears derived from the geometry.

    Parameters
    ----------
    bore_ratio : float or (float, float), optional
        Derive ``m1, J1, m2, J2`` as steel rings (`gearpair.geometry.steel_body`; bore
        diameter over pitch diameter, Table 1's bodies are 0.8). None keeps them.
    first_mode_hz : float, optional
        Then set ``kr2`` so that the slip model's first natural frequency is this (Hz;
        `kr2_for_first_mode`). None keeps it.
    effects : Effects, optional
        ``dof`` and ``sliding`` of the model the frequency refers to.
    """
    from .geometry import steel_body

    if bore_ratio is not None:
        p = steel_body(p, bore_ratio)
    if first_mode_hz is not None:
        p = tune_kr2(p, first_mode_hz, effects)
    return p
