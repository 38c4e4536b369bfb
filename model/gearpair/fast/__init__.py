"""The fast engine: the reference engine's physics and switching rules, compiled with numba.

`FastEngine` implements the `Engine` contract with the same model (`equations.evaluate`), the
same switching rules (`switching`: Eq. (14) stick test, the paper-tie rule, slip directions
settled at entry and re-contact, the velocity projection at stick entry) and the same way of
taking a step as `reference.ReferenceEngine`. One module per concern, as the reference:

- `layout`: the records the compiled functions take (`ModelData`, `HybridState`, `Work`,
  `Piece`, `Step`) and the index names of their flat arrays (no numba);
- `contact`: contact-state evaluation, event functions and the right-hand side;
- `switching`: slip directions, the Eq. (14) stick test, releases, separation, speed jumps;
- `tableaux` and `rk`: the Runge-Kutta pairs as data (DOP853 by default, Dormand-Prince 5(4)
  with ``method="dp5"``), one step with its error control;
- `events`: dense output, sampling of each step for falls through zero, Illinois refinement;
- `lti`: the exact propagator ``expm(A h)`` for constant-coefficient pieces;
- `loop`: pieces, segments between known boundaries, `advance`, outputs, the grid recorder;
- `setup`: the model's set-up compiled (geometry, stiffness law, constants, flags, step
  bound), the records' source for the Python API and the FMU;
- `engine`: `FastEngine`, the `Engine` contract over the compiled functions.

Everything on the hot path is ``numba.njit`` on named tuples of flat float64/int64 arrays:
no Python objects, no allocation in the right-hand side (the work buffers are allocated once
per engine). Only this package and `gearpair.jitcache` (numba's on-disk cache, keyed by the
content of this package's files) import numba; the rest of `gearpair` works without it.
"""

from __future__ import annotations

from .. import jitcache  # noqa: F401  (first: sets NUMBA_CACHE_DIR before numba loads)
from ..jitcache import CACHE, CACHE_DIR
from .engine import FastEngine, FastOptions
from .layout import (
    FR_NOMINAL,
    FR_OFF,
    FR_REG,
    FR_STICK,
    I_LTI,
    I_METHOD,
    N_Q,
    N_Y,
    Y_A,
    Y_AD,
    HybridState,
    ModelData,
    Piece,
    Work,
)
from .tableaux import M_DOP853, M_DP5

__all__ = [
    "CACHE", "CACHE_DIR", "FR_NOMINAL", "FR_OFF", "FR_REG", "FR_STICK", "I_LTI", "I_METHOD",
    "M_DOP853", "M_DP5", "N_Q", "N_Y", "Y_A", "Y_AD", "FastEngine", "FastOptions",
    "HybridState", "ModelData", "Piece", "Work",
]
