"""What is integrated: the matrices of Eqs. (4)-(10) and the forces of one contact state.

Coordinates ``q = [x1, y1, u1, x2, y2, u2]`` (m), Eq. (5). ``u_i = rb_i theta_i`` is the
rotational vibration on the base circle around the nominal rotation (gear 1 at ``Omega1``,
gear 2 at ``Omega2 = Omega1 z1/z2`` in the opposite sense), counter-clockwise positive.
Nothing here decides *when* the state switches (see `switching`) or *how* a step is taken
(see the engines).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .effects import Effects
from .geometry import GearDataWarning, Geometry, table1_body_mismatch
from .params import GearParams
from .stiffness import MeshStiffness

X1, Y1, U1, X2, Y2, U2 = range(6)
# Eq. (3): delta = y1 - y2 + u1 + u2 = G . q
G = np.array([0.0, 1.0, 1.0, 0.0, -1.0, 1.0])
# d v_j / d q' for the paper's sliding velocity, Eq. (12): v = nominal + x1' - x2'
A_PAPER = np.array([1.0, 0.0, 0.0, -1.0, 0.0, 0.0])


@dataclass(frozen=True)
class Model:
    """A gear pair with its effects, reduced to the arrays the engines need.

    Attributes
    ----------
    p, effects, geom, stiff : the inputs and derived geometry / stiffness law
    M, C, Kb : 6x6 mass, support damping and support stiffness matrices, Eq. (5)
    minv : diagonal of M^-1
    """

    p: GearParams
    effects: Effects
    geom: Geometry
    stiff: MeshStiffness
    M: np.ndarray
    C: np.ndarray
    Kb: np.ndarray
    minv: np.ndarray
    c_diag: np.ndarray      # diagonal of C (N.s/m)
    kb_diag: np.ndarray     # diagonal of Kb (N/m)
    rb1: float              # cached scalars: the right-hand side is a hot path
    rb2: float
    ratio: float
    cm: float
    mu: float               # kinetic coefficient, GearParams.mu
    mu_static: float        # static coefficient of the stick test, Eq. (14) (mu if not given)
    stribeck_velocity: float  # v_s of the sliding coefficient (m/s); 0: no Stribeck decay

    @classmethod
    def build(cls, p: GearParams | None = None, effects: Effects | None = None) -> Model:
        """The model of gear data ``p`` with ``effects``. Raises ValueError when the
        friction coefficients do not fit together (`check_friction_coefficients`)."""
        p = p or GearParams()
        effects = effects or Effects()
        mismatch = table1_body_mismatch(p)
        if mismatch:  # the most common slip with own gear data: Table 1's bodies kept
            warnings.warn(mismatch, GearDataWarning, stacklevel=2)
        mu_static = check_friction_coefficients(p, effects)
        geom = Geometry.from_params(p)
        stiff = MeshStiffness.build(p, geom, effects.stiffness)
        mdiag = np.array([p.m1, p.m1, p.mu1, p.m2, p.m2, p.mu2])
        M = np.diag(mdiag)
        Kb = np.diag([p.kb1, p.kb1, p.kr1, p.kb2, p.kb2, p.kr2])
        C = np.diag([p.cb1, p.cb1, p.cr1, p.cb2, p.cb2, p.cr2])
        return cls(p, effects, geom, stiff, M, C, Kb, 1.0 / mdiag, np.diag(C).copy(),
                   np.diag(Kb).copy(), p.rb1, p.rb2, p.ratio, p.cm, p.mu, mu_static,
                   float(effects.stribeck_velocity or 0.0))

    @property
    def backlash(self) -> float:
        """Back-flank clearance along the line of action (m); inf without a back flank."""
        b = self.effects.backlash
        return math.inf if b is None else float(b)

    # The physical bound of the DTE (`dte_bound`): a flank compressed by more than a tenth of
    # the module (a tooth is some 1.6 modules thick at its pitch circle: far outside the
    # model's small-deflection validity) plus DTE_BOUND_STATIC static deflections under the
    # step's torque (so that a large load keeps its margin)
    DTE_BOUND_MODULE = 0.1
    DTE_BOUND_STATIC = 20.0

    def dte_bound(self) -> tuple[float, float]:
        """(c0 in m, c1 in m/(N.m)): a run stops when a flank would be compressed by more
        than c0 + c1 |torque|, i.e. DTE > c0 + c1 |T| (drive flank), or, with a back flank,
        DTE < -(b + c0 + c1 |T|) (issue 38).

        c0 is ``DTE_BOUND_MODULE`` modules; c1 is ``DTE_BOUND_STATIC`` times the static
        deflection per unit torque at the mean mesh stiffness, 1 / (rb1 km_mean). Past it
        the teeth pass through each other: an unbounded response, often a parametric
        instability of the model itself, which the engines report instead of integrating
        on. Without a back flank (the paper's model) a negative DTE has no bound: a negative
        torque parts the teeth for good, which is the model's answer, not a failure.
        """
        return (self.DTE_BOUND_MODULE * self.p.module,
                self.DTE_BOUND_STATIC / (self.rb1 * self.stiff.km_mean))

    @property
    def torsional(self) -> bool:
        """Only u1, u2 are integrated (rigid supports)."""
        return self.effects.dof == "torsional"

    @property
    def free_dofs(self) -> np.ndarray:
        """Indices of the integrated coordinates in q (all six, or u1 and u2)."""
        return np.array([U1, U2]) if self.torsional else np.arange(6)

    @property
    def minv_free(self) -> np.ndarray:
        """Diagonal of M^-1 with zeros on the coordinates that are not integrated."""
        if not self.torsional:
            return self.minv
        out = np.zeros(6)
        out[[U1, U2]] = self.minv[[U1, U2]]
        return out

    # -- Eq. (10) ----------------------------------------------------------------------------
    def load(self, torque: float) -> np.ndarray:
        """Load vector Ft = [0, 0, Tr/rb1, 0, 0, 0] (N), Eq. (10)."""
        f = np.zeros(6)
        f[U1] = torque / self.rb1
        return f

    # -- Eq. (9) -----------------------------------------------------------------------------
    def friction_directions(self, s1m: np.ndarray, s2m: np.ndarray) -> np.ndarray:
        """Rows ``w_j = [-1, 0, S1Mj/rb1, +1, 0, S2Mj/rb2]``: generalized force of a unit
        friction force of pair j (Eq. (9)); shape (n, 6)."""
        w = np.zeros((len(s1m), 6))
        w[:, X1] = -1.0
        w[:, U1] = s1m / self.rb1
        w[:, X2] = 1.0
        w[:, U2] = s2m / self.rb2
        return w

    def nominal_sliding(self, s1m: np.ndarray, s2m: np.ndarray, speed: float) -> np.ndarray:
        """Nominal sliding velocity ``Omega2 S2Mj - Omega1 S1Mj`` (m/s), Eqs. (12)-(13)."""
        return speed * (self.ratio * s2m - s1m)

    def nominal_sliding_rate(self, speed: float) -> float:
        """d/dt of the nominal sliding velocity at constant speed, -(Omega1+Omega2) rb1 Omega1
        (m/s^2): the contact point moves along the LOA at rb1 Omega1."""
        return -(1.0 + self.p.ratio) * self.p.rb1 * speed * speed

    def sliding_gradient(self, w: np.ndarray) -> np.ndarray:
        """``a_j = d v_j / d q'`` (shape (n, 6)) for the chosen sliding variant."""
        if self.effects.sliding == "full":
            return -w  # v = nominal - w . q' keeps the friction power exactly -f v
        return np.tile(A_PAPER, (w.shape[0], 1))

    def sliding_velocity(self, nominal: np.ndarray, w: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Relative sliding velocity v_j (m/s), Eq. (12) or its full variant."""
        return nominal + self.sliding_gradient(w) @ qd

    def sliding_bias(self, w: np.ndarray, qd: np.ndarray, speed: float, tie: str) -> np.ndarray:
        """The part of d v_j/dt that does not depend on q'' (m/s^2).

        ``exact`` keeps the rate of the nominal sliding velocity (and, for the full variant,
        the turning of w_j as the contact point moves); ``paper`` drops the nominal rate as
        Eq. (19) does (x2'' = x1'').
        """
        n = w.shape[0]
        c = np.zeros(n)
        if tie == "exact":
            c += self.nominal_sliding_rate(speed)
        if self.effects.sliding == "full":
            wdot = np.zeros(6)  # d w_j / dt at constant speed
            wdot[U1] = speed
            wdot[U2] = -self.p.rb1 * speed / self.p.rb2
            c -= wdot @ qd
        return c

    # -- contact at mesh travel s ------------------------------------------------------------
    def contact(self, s: float, active: np.ndarray | None = None):
        """Pairs in contact at mesh travel ``s``: indices, positions xi, arms, stiffness.

        ``active`` fixes the set (an engine holds it constant between known boundaries so
        that a pair on the boundary is not counted twice).
        """
        geo = self.geom
        if active is None:
            active = np.flatnonzero(geo.in_contact(geo.pair_positions(s)))
        per, L = geo.period_length, geo.path_length
        xi = np.mod(s + active * geo.base_pitch, per)
        # A pair held active up to a boundary may sit a rounding error past its exit, or
        # just before its entry on the far side of the wrap.
        xi = np.minimum(np.maximum(np.where(xi > 0.5 * (L + per), xi - per, xi), 0.0), L)
        s1m, s2m = self.geom.arms(xi)
        k = self.stiff.pairs(xi, len(active))
        return active, xi, s1m, s2m, k

    def static_deflection(self, torque: float, km: float) -> np.ndarray:
        """Static equilibrium q (m) under ``torque`` with mesh stiffness ``km`` and no
        friction: (Kb + km g g^T) q = Ft. Gives delta = Tr/(rb1 km) (Eqs. (4), (6)).

        A negative torque with a back flank rests on it: (Kb + km g g^T) q = Ft - km b g,
        delta = Tr/(rb1 km) - b. Without a back flank the drive-flank solution is returned
        (delta < 0: the teeth start apart). Torsional: x and y stay zero.
        """
        f = self.load(torque)
        if torque < 0.0 and math.isfinite(self.backlash):
            f = f - km * self.backlash * G
        free = self.free_dofs
        from .fast.detlinalg import solve  # not LAPACK: the same bits on every machine

        K = (self.Kb + km * np.outer(G, G))[np.ix_(free, free)]
        q = np.zeros(6)
        q[free] = solve(K, f[free])
        return q

    def contact_code(self, delta: float) -> int:
        """Contact state of deflection ``delta`` (m) at rest: 0 drive flank, 1 apart,
        2 back flank (see `switching.Mode`)."""
        if delta >= 0.0 or not self.effects.separation:
            return 0
        return 2 if delta < -self.backlash else 1


def check_friction_coefficients(p: GearParams, effects: Effects) -> float:
    """The static coefficient of ``effects`` for the gear data ``p`` (``mu`` when not given).

    Raises ValueError naming ``mu_static`` when it is below the kinetic ``mu``, when the
    friction law has no use for a static coefficient (``off``, ``nominal``), or with
    ``regularized`` and no Stribeck velocity (the only way that law sees ``mu_static``).
    """
    ms = effects.mu_static
    if ms is None or ms == p.mu:
        return float(p.mu)
    if ms < p.mu:
        raise ValueError(f"mu_static = {ms!r} is out of range; allowed [mu, 1] = [{p.mu:g}, 1] "
                         "(static friction is at least the kinetic mu), or None for mu")
    law = effects.friction
    if law in ("off", "nominal"):
        raise ValueError(f"mu_static = {ms!r} (> mu = {p.mu:g}) needs friction = 'stick_slip' "
                         f"or 'regularized': friction = {law!r} has no static friction")
    if law == "regularized" and effects.stribeck_velocity is None:
        raise ValueError(f"mu_static = {ms!r} (> mu = {p.mu:g}) with friction = 'regularized' "
                         "needs stribeck_velocity: the regularized law has no stick state and "
                         "sees mu_static only through the Stribeck curve")
    return float(ms)


def sliding_coefficient(mu: float, mu_static: float, stribeck_velocity: float, v):
    """Coefficient of sliding friction at sliding velocity ``v`` (m/s), beyond the paper.

    ``mu + (mu_static - mu) exp(-(|v|/v_s)^2)``: ``mu_static`` as ``v -> 0`` (continuous
    with the static limit of Eq. (14), so a pair leaving stick starts to slide at the force
    that broke it) and ``mu`` for ``|v| >> v_s``. ``stribeck_velocity = 0``: the constant
    ``mu`` of Eq. (11). Works on scalars and arrays.
    """
    if stribeck_velocity == 0.0:
        return mu
    r = np.asarray(v) / stribeck_velocity
    return mu + (mu_static - mu) * np.exp(-(r * r))


@dataclass
class Eval:
    """Everything the right-hand side computes at one instant (SI)."""

    qdd: np.ndarray        # accelerations (m/s^2)
    delta: float           # mesh deflection (m), Eq. (3)
    compression: float     # compressed deflection: delta (drive flank), delta + b (back
                           # flank, < 0), 0 apart (m); the mesh force is km * compression
    ddelta: float          # its rate (m/s)
    km: float              # total mesh stiffness of the pairs in contact (N/m)
    theta: float           # 1 in contact, 0 apart, Eq. (8)
    normal: np.ndarray     # elastic normal force per active pair, k_j Theta delta (N), Eq. (16)
    friction: np.ndarray   # friction force per active pair along w_j (N), Eq. (11) or static
    v: np.ndarray          # sliding velocity per active pair (m/s), Eq. (12)
    w: np.ndarray          # friction directions, Eq. (9)
    s1m: np.ndarray        # moment arms (m)
    k: np.ndarray          # per-pair stiffness (N/m)
    xi: np.ndarray         # positions from A (m)
    lam_exact: np.ndarray  # static friction of stuck pairs with the exact tie (N)

    @property
    def mesh_force(self) -> float:
        """Elastic mesh force along the line of action (N), Eq. (16); < 0 on the back flank."""
        return self.km * self.compression


def friction_law_forces(model: Model, normal, v, nominal, dirs) -> np.ndarray:
    """Sliding friction per pair (N) for the slip state, Eq. (11), by the chosen law.

    The coefficient is the kinetic ``mu``; with a Stribeck velocity the laws that see the
    sliding velocity (``regularized``, ``stick_slip``) take `sliding_coefficient` of ``v``
    instead, so the regularized law tends to the stick-slip law with the same ``mu_static``
    as ``v_eps`` shrinks below ``v_s``. ``nominal`` keeps ``mu`` (it ignores ``v``).
    """
    law, mu = model.effects.friction, model.mu
    if model.stribeck_velocity and law in ("regularized", "stick_slip"):
        mu = sliding_coefficient(mu, model.mu_static, model.stribeck_velocity, v)
    mag = mu * np.abs(normal)
    if law == "nominal":
        return mag * np.sign(nominal)
    if law == "regularized":
        return mag * np.tanh(v / model.effects.v_eps)
    if law == "stick_slip":
        return mag * dirs
    return np.zeros_like(normal)


def static_friction(model: Model, F: np.ndarray, w: np.ndarray, a: np.ndarray,
                    c: np.ndarray) -> np.ndarray:
    """Static friction lambda (N) of the stuck pairs (rows of ``w``, ``a``, ``c``).

    Solves the stick constraint d v_j/dt = c_j + a_j . q'' = 0 with
    M q'' = F + sum_j lambda_j w_j — the Lagrange-multiplier form of the stick model,
    equivalent to Eqs. (20)-(25) (tested against them). With M diagonal this is the Schur
    complement  (A M^-1 W^T) lambda = -(c + A M^-1 F).
    """
    minv = model.minv_free
    S = (a * minv) @ w.T
    return np.linalg.solve(S, -(c + (a * minv) @ F))


def evaluate(model: Model, s: float, q: np.ndarray, qd: np.ndarray, torque: float,
             speed: float, active: np.ndarray, separated: bool, dirs: np.ndarray,
             stuck: np.ndarray, back: bool = False, anchor: tuple[float, float] = (0.0, 0.0)
             ) -> Eval:
    """Accelerations and forces for one contact state, Eqs. (1)-(4) and (20)-(22).

    Parameters
    ----------
    s : mesh travel (m); q, qd : coordinates (m) and velocities (m/s)
    torque : driving torque Tr (N.m); speed : Omega1 (rad/s)
    active : indices of the tracked pairs in contact (held between known boundaries)
    separated : teeth apart (Theta = 0); always False when separation is switched off
    dirs : slip direction (+1/-1) per active pair, used by the stick-slip law
    stuck : boolean mask over active pairs held by static friction
    back : (with ``separated``) the back flanks are in contact: delta < -backlash
    anchor : (a, a') the far end of the load shaft kr2/cr2 in u2 coordinates (m, m/s): its
        deviation from the nominal rotation when a load speed drives it (0 in the paper)

    With a back flank the mesh spring and damper act on delta + b with the same stiffness law
    and no friction. Torsional: the x and y equations are not integrated (q'' = 0 there).
    """
    fx = model.effects
    _, xi, s1m, s2m, k = model.contact(s, active)
    km = float(k.sum())
    delta = q[1] - q[4] + q[2] + q[5]       # G . q, Eq. (3)
    ddelta = qd[1] - qd[4] + qd[2] + qd[5]
    theta = 0.0 if separated else 1.0
    normal = theta * k * delta
    compression = theta * delta
    if separated and back:
        theta, compression = 1.0, delta + model.backlash
    w = model.friction_directions(s1m, s2m)
    nominal = model.nominal_sliding(s1m, s2m, speed)
    a = model.sliding_gradient(w)
    v = nominal + a @ qd
    # Eq. (4) without friction: Ft - C q' - (Kb + Km) q, mesh damping only in contact
    F = -model.c_diag * qd - model.kb_diag * q - G * (km * compression + theta * model.cm * ddelta)
    F[U1] += torque / model.rb1
    F[U2] += model.p.kr2 * anchor[0] + model.p.cr2 * anchor[1]
    friction = friction_law_forces(model, normal, v, nominal, dirs) if fx.friction != "off" \
        else np.zeros_like(k)
    if fx.friction == "stick_slip":
        friction = np.where(stuck, 0.0, friction)
    F = F + friction @ w
    if model.torsional:
        F[[X1, Y1, X2, Y2]] = 0.0  # rigid supports: no motion, whatever the force
    lam_exact = np.zeros(0)
    if fx.friction == "stick_slip" and stuck.any():
        ws, as_ = w[stuck], a[stuck]
        c = model.sliding_bias(ws, qd, speed, fx.stick_tie)
        lam = static_friction(model, F, ws, as_, c)
        friction = friction.copy()
        friction[stuck] = lam
        F = F + lam @ ws
        if model.torsional:
            F[[X1, Y1, X2, Y2]] = 0.0
        lam_exact = lam if fx.stick_tie == "exact" else static_friction(
            model, F - lam @ ws, ws, as_, model.sliding_bias(ws, qd, speed, "exact"))
    qdd = model.minv_free * F
    return Eval(qdd, delta, compression, ddelta, km, theta, normal, friction, v, w, s1m, k, xi,
                lam_exact)
