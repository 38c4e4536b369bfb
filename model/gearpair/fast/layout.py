"""The records the compiled functions take, and the index names of their flat arrays.

The compiled code passes four records instead of loose arrays (numba-typed named tuples,
built by `FastEngine` once; a compiled entry point receives them as plain tuples, which
numba types faster on every call, and names them at once):

- `ModelData`: the model's constants and stiffness tables (never written while stepping);
- `HybridState`: the continuous and discrete engine state (`FastEngine.get_state`);
- `Work`: work buffers, allocated once per engine (no allocation on the hot path);
- `Piece`: what holds over one piece of integration (start, inputs, pair set, contact).

Scalars that travel together in one float or int array keep index names below (``P_RB1``
is the base radius of gear 1 in ``ModelData.par``), so the arithmetic reads as before.
This module imports no numba: the layout is plain data.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# -- ModelData.par: float constants ---------------------------------------------------------
P_MINV, P_C, P_KB = 0, 6, 12  # 6 each: inverse masses, support damping, support stiffness
(P_RB1, P_RB2, P_RATIO, P_CM, P_MU, P_VEPS, P_S1A, P_S1S2, P_PB, P_L, P_PER, P_XIP, P_KMEAN,
 P_RTOL, P_MAXSTEP, P_TTOL, P_DX, P_INVDX, P_SPACING, P_IRB1, P_IRB2, P_IPER,
 P_BACK, P_MUS, P_VS, P_DB0, P_DB1) = range(18, 45)
N_MP = 45  # P_MUS: static coefficient mu_static; P_VS: Stribeck velocity (0: none)
# P_DB0, P_DB1: the physical bound of |DTE|, P_DB0 + P_DB1 |torque| (m; `Model.dte_bound`)
# -- ModelData.flag: int flags ----------------------------------------------------------------
(I_NP, I_KIND, I_VARY, I_SEP, I_FRIC, I_SLIDE, I_TIE, I_NSAMP, I_MAXEV, I_NTAB, I_BACK,
 I_TORS, I_LTI, I_METHOD, I_NIX) = range(15)
I_IX = 15  # flag[I_IX:I_IX + flag[I_NIX]]: the components of y the Runge-Kutta steps integrate
# The names each effect (`gearpair.effects.Effects` field) fills in the records
# (`engine.model_constants`, `engine.model_flags`): the compiled code reads the effect
# through these and nothing else (docs/architecture.md "What an effect touches" is checked
# against the modules that read them)
EFFECT_RECORDS = {"stiffness": ("I_KIND", "I_VARY"), "separation": ("I_SEP",),
                  "friction": ("I_FRIC",), "v_eps": ("P_VEPS",), "sliding": ("I_SLIDE",),
                  "stick_tie": ("I_TIE",), "backlash": ("P_BACK", "I_BACK"),
                  "dof": ("I_TORS",), "mu_static": ("P_MUS",), "stribeck_velocity": ("P_VS",)}
KIND_CONSTANT, KIND_TABLE, KIND_CUBIC = 0, 1, 2  # KIND_CUBIC: k_coef holds 4 spline
#                                                  coefficients per interval
FR_OFF, FR_NOMINAL, FR_REG, FR_STICK = 0, 1, 2, 3
FRICTION_CODE = {"off": FR_OFF, "nominal": FR_NOMINAL, "regularized": FR_REG,
                 "stick_slip": FR_STICK}
# -- Work.pair: per-pair rows ---------------------------------------------------------------
W_XI, W_S1M, W_S2M, W_K, W_N, W_F, W_V, W_NOM, W_LAMEX, W_STK, W_DK = range(11)
N_PW = 11
# -- Work.scal: delta, ddelta, km, theta, F[6], qdd[6], compression (delta, delta + b on the
# back flank, 0 apart: the mesh force is km * compression)
S_DELTA, S_DDELTA, S_KM, S_THETA, S_F, S_QDD, S_COMP = 0, 1, 2, 3, 4, 10, 16
N_SC = 17
# -- HybridState.clock (continuous scalars) and HybridState.mode (discrete) -----------------
# T_SEP: no flank in contact (free flight); T_BACK: on the back flank (contact, not loss);
# T_LAST0, T_LAST1: start and end of the last step (nan before one: `FastEngine.get_state`)
T_T, T_S, T_H, T_STICK, T_SEP, T_TORQUE, T_SPEED, T_REL, T_BACK, T_LAST0, T_LAST1 = range(11)
N_ST = 11
# J_SEP: 0 drive flank, 1 apart, 2 back flank; J_REL: 1 + the pair released at time T_REL;
# J_RESUME: 1 when the last step ended early inside a segment (`loop.segment`, an FMU's early
# return at a contact event): the next one resumes that segment, its slip directions as set
J_SEP, J_NPREV, J_NEVTOT, J_REL, J_RESUME = range(5)
N_IST = 5
N_Q = 6
N_Y = 18  # q, q', 4 energy quadratures (input, damping loss, friction work, parametric),
Y_A, Y_AD = 16, 17  # load-shaft end a (m, u2 coordinates) and its rate a' (held per step)
N_MI = I_IX + N_Y
# -- Work.summary: the summary of one advance --------------------------------------------------
# O_NREJ: rejected steps; O_FINT: time integral of the mesh force over the advance (N s),
# O_FMIN: its least sample (as O_FMAX the peak); O_TFAIL, O_DFAIL, O_CFAIL, O_BFAIL: time,
# DTE, contact code (J_SEP) and DTE bound where the advance failed (O_STATUS)
(O_FMAX, O_NEV, O_NSTEPS, O_STATUS, O_TFAIL, O_NREJ, O_FINT, O_FMIN, O_DFAIL, O_CFAIL,
 O_BFAIL) = range(11)
N_OUT = 11
# STATUS_MISSED: the contact state and the geometry disagree after a step (`events.
# flank_guard`); STATUS_UNBOUNDED: the DTE left its physical bound (P_DB0, P_DB1)
STATUS_OK, STATUS_EVENTS, STATUS_STEP, STATUS_MISSED, STATUS_UNBOUNDED = 0, 1, 2, 3, 4
N_O = 10  # outputs: dte, mesh, friction, state, out torque, reaction, in torque, w1, w2, v
# a recorded row: outputs, stick and separation fractions, peak force, events, back-flank
# fraction, mean and least mesh force over the interval
N_REC = N_O + 7
# -- Work.dense rows: the continuous extension, the event values at a step's ends, and the
# mesh force at each Runge-Kutta stage of the current step
R_GSAVE, R_GEND, R_FSTG = 8, 9, 10
# -- the exact propagator: z = [q, q', a, a', torque, 1, integral of u2] ---------------------
NZ = 17
Z_A, Z_AD, Z_TQ, Z_ONE, Z_IU2 = 12, 13, 14, 15, 16
L_NSLOT = 12  # cached propagators, keyed by (contact code, total stiffness, step)
L_SCRATCH = 2 * L_NSLOT  # lti_mats[:L_NSLOT]: A of a slot; [L_NSLOT:L_SCRATCH]: expm(A h)


class ModelData(NamedTuple):
    """The model's constants and stiffness tables (read-only while stepping)."""

    par: np.ndarray        # float64[N_MP]: constants, index names P_*
    flag: np.ndarray       # int64[N_MI]: flags I_*, then the integrated components
    atol: np.ndarray       # float64[N_Y]: absolute tolerance per component of y
    xi_knots: np.ndarray   # float64: stiffness-table positions (uniform from 0 to L)
    k_coef: np.ndarray     # float64: table values, or 4 cubic coefficients per interval
    k_slope: np.ndarray    # float64: slope d k / d xi at the start of each interval


class HybridState(NamedTuple):
    """The engine state: views into one float buffer (a snapshot is one copy)."""

    y: np.ndarray            # float64[N_Y]: q, q', energy quadratures, a, a'
    clock: np.ndarray        # float64[N_ST]: t, s, h, times in stick / apart, inputs (T_*)
    mode: np.ndarray         # int64[N_IST]: contact code, pairs of the last segment (J_*)
    dirs: np.ndarray         # float64[n pairs]: slip direction of each tracked pair
    stuck: np.ndarray        # int64[n pairs]: 1 while a pair sticks
    prev_active: np.ndarray  # int64[n pairs]: the pair set of the last segment


class Work(NamedTuple):
    """Work buffers (allocated once per engine)."""

    active: np.ndarray      # int64[n]: pairs in contact over the current segment
    trial: np.ndarray       # int64[n]: stuck flags of the Eq. (14) stick test
    bound_offs: np.ndarray  # float64[3]: offsets of the known boundaries in a base pitch
    bound_k: np.ndarray     # int64[3]: index of the next boundary of each kind
    stages: np.ndarray      # float64[16, N_Y]: Runge-Kutta stages
    dense: np.ndarray       # float64[11, >= N_Y]: continuous extension, event values, stage
    #                         mesh forces (rows R_*)
    ytmp: np.ndarray        # float64[N_Y]
    ynew: np.ndarray        # float64[N_Y]
    g: np.ndarray           # float64[n + 2]: event values
    gprev: np.ndarray       # float64[n + 2]: event values at the last sample
    pair: np.ndarray        # float64[N_PW, n]: per-pair quantities (W_*)
    scal: np.ndarray        # float64[N_SC]: contact-state scalars (S_*)
    solve: np.ndarray       # float64[n, n + 2]: static-friction system
    lti_mats: np.ndarray    # float64[L_SCRATCH + 12, NZ, NZ]: propagators and scratch
    lti_keys: np.ndarray    # float64[L_NSLOT + 1, 4]: (code, km, h, last use) per slot
    lti_vecs: np.ndarray    # float64[6, >= NZ]: vectors of the exact propagator
    summary: np.ndarray     # float64[N_OUT]: the summary of one advance (O_*)
    outputs: np.ndarray     # float64[N_O]: the outputs at the current state


class Piece(NamedTuple):
    """What holds over one piece: its start, the held inputs, the pair set and contact."""

    t0: float      # s: start of the piece
    s0: float      # m: mesh travel at t0
    torque: float  # N.m
    speed: float   # rad/s
    nact: int      # pairs in contact (Work.active[:nact])
    cs: int        # contact code: 0 drive flank, 1 apart, 2 back flank


class Step(NamedTuple):
    """One Runge-Kutta step from t to tn = t + hh (tn exact where the step was cut)."""

    t: float        # s: start
    hh: float       # s: size
    tn: float       # s: end
    si: float       # m: mesh travel at mid-step (picks the stiffness-table interval)
    last: bool      # the step ends the piece
    at_knot: bool   # the step ends on a knot of the stiffness table


class LtiPiece(NamedTuple):
    """A piece integrated by the exact propagator: what holds over it."""

    km: float     # N/m: total mesh stiffness (constant over the piece)
    slot: int     # propagator slot of one sub-step
    nsub: int     # sub-steps (scanned for events)
    hsub: float   # s: sub-step
    quiet: bool   # no event can fall and the force stays at its static value
