"""When the contact state switches: event functions and the rules of Eq. (14).

Every event function is positive while the current discrete state is valid and crosses zero
when it must change, so an engine only watches for a fall through zero:

- teeth in contact: ``delta`` (falls through 0 -> separation, Eq. (8));
  apart: ``-delta`` (-> re-contact) and, with a back flank of clearance b, ``delta + b``
  (-> back-flank contact); on the back flank: ``-(delta + b)`` (-> apart);
- a slipping pair with direction d: ``d * v_j`` (the sliding velocity reverses -> test for
  stick by Eq. (14));
- a stuck pair: ``mu_static f_mesh - |f_static|`` (Eq. (14) violated -> slip in the
  direction of ``f_static``).

``mu_static`` (`Effects.mu_static`, equal to the kinetic ``mu`` unless given) bounds the
static friction wherever this module tests for stick; a pair that slips takes the sliding
coefficient (``mu``, or the Stribeck curve) from `equations.friction_law_forces`. With
``mu_static > mu`` a released pair therefore slides with less friction than the limit it
broke, and slip continues away from v = 0 (no chatter at the release).

With ``stick_tie="paper"`` the static friction of Eq. (20)-(21) lacks the rate of the nominal
sliding velocity. Then Eq. (14) may release a stick while the slip dynamics on both sides push
``v_j`` back to zero (the band of docs/model.md, "The paper's tie and the switching rule"),
and a literal implementation stalls. Rule used here: a pair sticks while
``min(|f_static,paper|, |f_static,exact|) <= mu_static f_mesh``;
it is released only when both exceed the limit, in the direction of the exact one. So the
paper tie can only lengthen sticks, never chatter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .equations import Eval, Model, evaluate


@dataclass
class Mode:
    """Discrete state of the contact (all arrays over the *tracked* pairs).

    Attributes
    ----------
    separated : drive flanks apart (Theta = 0)
    dirs : slip direction +1/-1 of each pair (sign of its sliding velocity)
    stuck : pair held by static friction
    back : (with ``separated``) the back flanks are in contact
    """

    separated: bool
    dirs: np.ndarray
    stuck: np.ndarray
    back: bool = False

    def copy(self) -> Mode:
        return Mode(self.separated, self.dirs.copy(), self.stuck.copy(), self.back)

    @property
    def code(self) -> int:
        """0 drive flank in contact, 1 apart, 2 back flank in contact."""
        return 0 if not self.separated else (2 if self.back else 1)


def _stuck_rank(stuck_active: np.ndarray, i: int) -> int:
    """Row of active pair ``i`` among the stuck ones (the order of the multipliers)."""
    return int(np.count_nonzero(stuck_active[:i]))


def _sign(x: float, fallback: float = 1.0) -> float:
    return 1.0 if x > 0 else (-1.0 if x < 0 else fallback)


def event_labels(model: Model, mode: Mode, active: np.ndarray) -> list[tuple[str, int]]:
    """What each event function watches: ("sep", -1) or ("pair", tracked index)."""
    labels: list[tuple[str, int]] = []
    if model.effects.separation:
        labels.append(("back" if mode.back else "sep", -1))
        if mode.separated and not mode.back and math.isfinite(model.backlash):
            labels.append(("back", -1))
    if model.effects.friction == "stick_slip" and not mode.separated:
        labels += [("pair", int(j)) for j in active]
    return labels


def event_values(model: Model, ev: Eval, mode: Mode, active: np.ndarray) -> np.ndarray:
    """Event functions at one instant, positive while the state holds (see module doc)."""
    out = []
    if model.effects.separation:
        b = model.backlash
        if mode.back:
            out.append(-(ev.delta + b))
        else:
            out.append(-ev.delta if mode.separated else ev.delta)
            if mode.separated and math.isfinite(b):
                out.append(ev.delta + b)
    if model.effects.friction == "stick_slip" and not mode.separated:
        mu = model.mu_static
        stuck = mode.stuck[active]
        lam_i = 0
        for i, j in enumerate(active):
            if stuck[i]:
                lam = abs(ev.friction[i])
                if model.effects.stick_tie == "paper":
                    lam = min(lam, abs(ev.lam_exact[lam_i]))
                lam_i += 1
                out.append(mu * abs(ev.normal[i]) - lam)
            else:
                out.append(mode.dirs[j] * ev.v[i])
    return np.array(out)


def stick_test(model: Model, s, q, qd, torque, speed, active, mode: Mode, j: int):
    """Eq. (14) for pair ``j`` at a zero of its sliding velocity.

    Returns ``(sticks, direction)``: whether static friction can hold the pair (with the rule
    for the paper tie, see module doc) and otherwise the direction it slips in, the sign of
    the exact static friction (the side to which the slip dynamics carry ``v_j``).
    """
    trial = mode.stuck.copy()
    trial[j] = True
    stuck_a = trial[active]
    ev = evaluate(model, s, q, qd, torque, speed, active, mode.separated, mode.dirs[active],
                  stuck_a, mode.back)
    i = int(np.flatnonzero(active == j)[0])
    lam = abs(ev.friction[i])
    lam_e = ev.lam_exact[_stuck_rank(stuck_a, i)]
    if model.effects.stick_tie == "paper":
        lam = min(lam, abs(lam_e))
    limit = model.mu_static * abs(ev.normal[i])
    return lam <= limit, _sign(lam_e)


def switch(model: Model, label: tuple[str, int], s, q, qd, torque, speed, active,
           mode: Mode) -> tuple[Mode, np.ndarray]:
    """Apply the state change of the event ``label`` at its located instant.

    Returns the new mode and the (possibly projected) velocities: entering stick puts
    ``v_j`` exactly to zero through x2', which Eq. (18) says the stuck surfaces share.
    """
    new = mode.copy()
    qd = qd.copy()
    kind, j = label
    if kind == "back":
        new.back = not mode.back
        return new, qd
    if kind == "sep":
        if not mode.separated:
            new.separated = True
            new.stuck[:] = False
            return new, qd
        new.separated = False
        return settle_directions(model, s, q, qd, torque, speed, active, new)
    if mode.stuck[j]:
        ev = evaluate(model, s, q, qd, torque, speed, active, mode.separated,
                      mode.dirs[active], mode.stuck[active])
        i = int(np.flatnonzero(active == j)[0])
        new.stuck[j] = False
        new.dirs[j] = _sign(ev.lam_exact[_stuck_rank(mode.stuck[active], i)])
        return new, qd
    sticks, direction = stick_test(model, s, q, qd, torque, speed, active, mode, j)
    if sticks:
        new.stuck[j] = True
        i = int(np.flatnonzero(active == j)[0])
        ev = evaluate(model, s, q, qd, torque, speed, active, mode.separated,
                      mode.dirs[active], mode.stuck[active])
        qd[3] += ev.v[i]  # d v_j / d x2' = -1 in both sliding variants
    else:
        new.dirs[j] = direction
    return new, qd


def settle_directions(model: Model, s, q, qd, torque, speed, active, mode: Mode):
    """Set the slip direction of pairs (re-)entering contact from their sliding velocity."""
    if model.effects.friction != "stick_slip" or mode.separated:
        return mode, qd
    ev = evaluate(model, s, q, qd, torque, speed, active, mode.separated, mode.dirs[active],
                  np.zeros(len(active), dtype=bool))
    for i, j in enumerate(active):
        if not mode.stuck[j]:
            mode.dirs[j] = _sign(ev.v[i], mode.dirs[j])
    return mode, qd


def speed_change(model: Model, s, q, qd, torque, speed, active, mode: Mode, h: float):
    """Rule for a speed input that changed between two steps (zero-order hold).

    The nominal sliding velocity of a stuck pair jumps with the speed, Eqs. (12)-(13). A real
    speed change is spread over the step ``h`` (s), during which static friction can deliver
    at most the impulse ``mu_static N h``. A stuck pair therefore stays stuck, with its
    sliding velocity restored to zero by a friction impulse along ``w_j``
    (``q' += M^-1 w_j lambda``), when that impulse ``m_eff |v_j|`` is within
    ``mu_static N_j h``; otherwise it slips in the
    direction of its new ``v_j``. Slipping pairs take the sign of their new ``v_j``. So a
    finely sampled speed ramp keeps its sticks and a large speed step breaks them.

    Returns the new mode and velocities.
    """
    if model.effects.friction != "stick_slip" or mode.separated:
        return mode, qd
    new = mode.copy()
    qd = qd.copy()
    minv = model.minv_free
    for i, j in enumerate(active):
        if not new.stuck[j]:
            continue
        ev = evaluate(model, s, q, qd, torque, speed, active, False, new.dirs[active],
                      np.zeros(len(active), dtype=bool))
        w = ev.w[i]
        a = model.sliding_gradient(ev.w)[i]
        v = float(ev.v[i])
        if v == 0.0:
            continue
        S = float((a * minv) @ w)
        if abs(v) <= model.mu_static * abs(ev.normal[i]) * h * abs(S):
            qd += minv * w * (-v / S)
        else:
            new.stuck[j] = False
            new.dirs[j] = _sign(v)
    return settle_directions(model, s, q, qd, torque, speed, active, new)
