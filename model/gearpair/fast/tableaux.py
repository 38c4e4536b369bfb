"""Explicit Runge-Kutta pairs as data: one tableau shape serves both methods.

Dormand & Prince 5(4) (7 stages, first same as last, continuous extension of order 4 by
Hairer, Norsett & Wanner) and Dormand & Prince 8(5,3) (DOP853: 13 stages, 3 more for its
order-7 continuous extension). DOP853's coefficients are read from scipy, which integrates
with the same method, so the two can be compared number for number. A method is a row index
(``M_DP5``, ``M_DOP853``) into the arrays below; the compiled step reads them as globals.
"""

from __future__ import annotations

import numpy as np

M_DP5, M_DOP853 = 0, 1
METHOD_CODE = {"dp5": M_DP5, "dop853": M_DOP853}
RK_NK = 16  # stage rows of Work.stages
RK_NS = np.array([7, 13])  # stages of a step, the last at the new point (FSAL)
RK_NX = np.array([7, 16])  # stages including the extra ones of the continuous extension
RK_ND = np.array([1, 4])  # rows of D in the continuous extension
RK_Q = np.array([5.0, 8.0])  # the error estimate is O(h^q): step factor err^(-1/q)
RK_A = np.zeros((2, RK_NK, RK_NK))
RK_C = np.zeros((2, RK_NK))
RK_E = np.zeros((2, RK_NK))  # error weights (b - b_hat); DOP853: its 5th-order estimate
RK_E3 = np.zeros((2, RK_NK))  # DOP853's 3rd-order estimate (zero for DP5)
RK_D = np.zeros((2, 4, RK_NK))
RK_C[0, :7] = [0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0]
RK_A[0, 1, :1] = [1 / 5]
RK_A[0, 2, :2] = [3 / 40, 9 / 40]
RK_A[0, 3, :3] = [44 / 45, -56 / 15, 32 / 9]
RK_A[0, 4, :4] = [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]
RK_A[0, 5, :5] = [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]
RK_A[0, 6, :6] = [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]
RK_E[0, :7] = [71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40]
RK_D[0, 0, :7] = [-12715105075 / 11282082432, 0.0, 87487479700 / 32700410799,
                  -10690763975 / 1880347072, 701980252875 / 199316789632,
                  -1453857185 / 822651844, 69997945 / 29380423]


def _load_dop853() -> None:
    from scipy.integrate._ivp import dop853_coefficients as d8

    RK_A[1] = d8.A
    RK_A[1, 12, :12] = d8.B  # the FSAL stage is evaluated at the new point
    RK_C[1] = d8.C
    RK_C[1, 11:13] = 1.0
    RK_E[1, :13] = d8.E5
    RK_E3[1, :13] = d8.E3
    RK_D[1] = d8.D


_load_dop853()
