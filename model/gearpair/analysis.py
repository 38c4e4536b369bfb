"""Signal analysis for the paper's figures: Poincare sections, periodicity, DTE spectra.

Pure numpy, no model imports: every function takes plain arrays (SI) so it can be tested on
synthetic signals. The section of Fig. 16 samples the dynamic transmission error (DTE, Eq. (3))
once per mesh period ``T_m = 2 pi / (z1 Omega1)`` after a transient; the spectra of Fig. 14
are in orders of the mesh frequency ``f_m = 1 / T_m``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["mesh_period", "poincare_every", "poincare_interp", "distinct_values", "periodicity",
           "per_period", "adjacent_period_difference", "amplitude_spectrum", "order_amplitudes",
           "section_offset"]


def mesh_period(z1: int | float, speed: float) -> float:
    """Mesh period ``T_m = 2 pi / (z1 Omega1)`` (s) of a pinion with ``z1`` teeth turning at
    ``speed`` (rad/s); raises ``ValueError`` unless the speed is positive."""
    if not (math.isfinite(speed) and speed > 0.0):
        raise ValueError(f"speed = {speed!r} rad/s: a mesh period needs a positive speed")
    return 2.0 * math.pi / (float(z1) * speed)


def poincare_every(x: np.ndarray, samples_per_period: int, skip_periods: int = 0,
                   offset: int = 0) -> np.ndarray:
    """Poincare section of a signal sampled ``samples_per_period`` times per period.

    Returns ``x[(skip_periods + k) * n + offset]`` for every whole period ``k`` after the first
    ``skip_periods`` (the transient). ``x[0]`` is taken to be at phase 0 of period 0.
    """
    n = int(samples_per_period)
    if n < 1 or not 0 <= offset < n:
        raise ValueError(f"need samples_per_period >= 1 and 0 <= offset < it, got {n}, {offset}")
    x = np.asarray(x, dtype=float)
    return x[skip_periods * n + offset::n].copy()


def poincare_interp(t: np.ndarray, x: np.ndarray, period: float, t_from: float,
                    phase: float = 0.0) -> np.ndarray:
    """Poincare section of a signal on any time grid: ``x`` linearly interpolated at
    ``t_from + phase * period + k period`` (s) for every such instant inside ``t``.

    Use it when the grid is fine compared with the DTE's fastest motion; the sweep samples the
    engine exactly at the section instead (`gearpair.sweep`).
    """
    t = np.asarray(t, dtype=float)
    if not (period > 0.0):
        raise ValueError(f"period = {period!r} s must be positive")
    t0 = t_from + phase * period
    k = np.arange(0, int(np.floor((t[-1] - t0) / period + 1e-9)) + 1)
    ts = t0 + k * period
    ts = ts[(ts >= t[0]) & (ts <= t[-1])]
    return np.interp(ts, t, np.asarray(x, dtype=float))


def distinct_values(samples: np.ndarray, tol: float) -> np.ndarray:
    """Cluster centres of 1-D samples: sorted samples split where a gap exceeds ``tol``.

    A period-n orbit gives n values; a chaotic or quasi-periodic one as many as samples
    (unless ``tol`` is coarse)."""
    s = np.sort(np.asarray(samples, dtype=float))
    if s.size == 0:
        return s
    cuts = np.flatnonzero(np.diff(s) > tol) + 1
    return np.array([c.mean() for c in np.split(s, cuts)])


def periodicity(samples: np.ndarray, tol: float, max_period: int = 16) -> int:
    """Smallest p <= ``max_period`` with ``|x[k+p] - x[k]| <= tol`` for every k, else 0.

    Applied to Poincare samples (one per mesh period) it is the period of the response in
    mesh periods: 1 periodic with the mesh, 2 period-two ("adjacent mesh periods differ, every
    other one is the same", Sec. 3.2), 0 no period found (chaotic, quasi-periodic, or still
    settling). Needs at least ``2 p`` samples to call a period p.
    """
    x = np.asarray(samples, dtype=float)
    for p in range(1, max_period + 1):
        if x.size < 2 * p:
            break
        if np.max(np.abs(x[p:] - x[:-p])) <= tol:
            return p
    return 0


def per_period(x: np.ndarray, samples_per_period: int) -> np.ndarray:
    """The whole periods of ``x`` as rows: shape (n_periods, samples_per_period)."""
    n = int(samples_per_period)
    x = np.asarray(x, dtype=float)
    m = x.size // n
    return x[:m * n].reshape(m, n)


def adjacent_period_difference(x: np.ndarray, samples_per_period: int) -> tuple[float, float]:
    """How much adjacent mesh periods differ, against every other one (Sec. 3.2, Fig. 11).

    Returns ``(d1, d2)``: the largest RMS difference between period k and k+1, and between k
    and k+2, both divided by the RMS of the fluctuation ``x - mean(x)``. A period-one response
    gives ``d1 ~ d2 ~ 0``; a period-two response ``d1 >> d2 ~ 0``; a chaotic one both large.
    """
    rows = per_period(x, samples_per_period)
    if rows.shape[0] < 3:
        raise ValueError("need at least 3 whole periods")
    scale = float(np.sqrt(np.mean((rows - rows.mean()) ** 2)))
    if scale == 0.0:
        return 0.0, 0.0
    d1 = np.sqrt(np.mean((rows[1:] - rows[:-1]) ** 2, axis=1)).max() / scale
    d2 = np.sqrt(np.mean((rows[2:] - rows[:-2]) ** 2, axis=1)).max() / scale
    return float(d1), float(d2)


def amplitude_spectrum(x: np.ndarray, dt: float, window: str = "rect",
                       detrend: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Single-sided amplitude spectrum of a uniformly sampled signal.

    Parameters
    ----------
    x : samples (any unit; the amplitude has the same unit)
    dt : sample interval (s)
    window : ``"rect"`` (exact amplitudes for components on the frequency grid, e.g. mesh
        orders of a record of a whole, even number of mesh periods) or ``"hann"``
        (amplitude-corrected for components between bins)
    detrend : remove the mean first

    Returns
    -------
    f : frequencies (Hz), ``k / (N dt)``
    a : amplitude of the sinusoid at each frequency (same unit as ``x``)
    """
    x = np.asarray(x, dtype=float)
    if detrend:
        x = x - x.mean()
    n = x.size
    if window == "hann":
        w = np.hanning(n)
    elif window == "rect":
        w = np.ones(n)
    else:
        raise ValueError(f"window = {window!r}; choose rect or hann")
    spec = np.fft.rfft(x * w)
    a = np.abs(spec) * 2.0 / w.sum()
    a[0] /= 2.0
    if n % 2 == 0:
        a[-1] /= 2.0
    return np.fft.rfftfreq(n, dt), a


def order_amplitudes(x: np.ndarray, samples_per_period: int,
                     orders=(0.5, 1.0, 1.5, 2.0, 3.0)) -> dict[float, float]:
    """Amplitudes of the mesh orders ``orders`` (multiples of the mesh frequency) of a signal
    sampled ``samples_per_period`` times per mesh period (Fig. 14(b)).

    The record is cut to an even number of whole periods, so every half order falls on a
    frequency bin and a rectangular window gives exact amplitudes. Orders at or above the
    Nyquist order ``samples_per_period / 2`` are refused.
    """
    n = int(samples_per_period)
    rows = per_period(x, n)
    m = rows.shape[0] - rows.shape[0] % 2
    if m < 2:
        raise ValueError("need at least 2 whole periods")
    _, a = amplitude_spectrum(rows[:m].ravel(), 1.0 / n, "rect")  # frequency unit: order
    out = {}
    for r in orders:
        if not 0.0 <= r < n / 2:
            raise ValueError(f"order {r} is at or above the Nyquist order {n / 2}")
        k = r * m  # bin of order r for a record of m periods
        if abs(k - round(k)) > 1e-9:
            raise ValueError(f"order {r} is not on the grid of a {m}-period record")
        out[float(r)] = float(a[int(round(k))])
    return out


def section_offset(boundary_phases, samples_per_period: int, candidates: int = 32) -> float:
    """A sub-step phase (fraction of one sub-step, in (0, 1)) that keeps every sample instant
    away from the given phases of the mesh period.

    The engines take an instant where a pair enters or leaves contact as a segment boundary;
    a requested step end that falls on one up to rounding is avoided altogether (it made the
    fast engine's step size underflow before commit 9a2d47c). Sample instants are
    ``(j + offset) T_m / n``.
    """
    n = int(samples_per_period)
    b = np.mod(np.asarray(list(boundary_phases), dtype=float), 1.0)
    best, best_d = 0.5, -1.0
    for c in (np.arange(candidates) + 0.5) / candidates:
        ph = (np.arange(n) + c) / n
        d = np.abs(ph[:, None] - b[None, :])
        d = np.minimum(d, 1.0 - d).min() if b.size else 1.0
        if d > best_d + 1e-12:
            best, best_d = float(c), float(d)
    return best
