"""The EKF's predict and correct steps (:class:`~tapm_opt.estimation.observer.EKFObserver`) as two
compiled calls.

The observer's numpy path (``EKFObserver._predict_numpy``, ``_correct_numpy``) writes each step as
some forty small numpy operations on 3- to 15-element arrays, about 1.5 µs of Python each: over a
3-hour closed loop at 1 Hz that is 0.8 s, more than the arithmetic. These kernels do the same
arithmetic in one compiled call each, in explicit loops; they are the numpy path's equations term
by term (the state and Jacobian of the discrete map, the Joseph-form update), not a reformulation,
so the two paths agree to rounding (the loops sum in another order than the BLAS:
``tests/test_ekf_kernel.py`` checks 1e-12 of each quantity's size over a closed loop). The mooring
load and its Jacobian stay with the observer (its line model, the detector's and monitor's hooks).

Notation as in ``docs/estimation.md`` (state ``x = (xi (6), eta (3), nu (3), b (3))``, EKF1–EKF6).
Without numba (a declared dependency) :func:`kernels` gives None and the observer runs its numpy path.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._jit import jit

__all__ = ["correct_py", "kernels", "predict_py", "sandwich_py"]

_TWO_PI = 2.0 * math.pi


def sandwich_py(A, P):  # pragma: no cover - compiled
    """``A P A^T`` (n, n) of square ``A`` and ``P``, as ``(A P) A^T``."""
    n = A.shape[0]
    AP = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += A[i, k] * P[k, j]
            AP[i, j] = acc
    out = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += AP[i, k] * A[j, k]
            out[i, j] = acc
    return out


_sandwich_k = sandwich_py   # the compiled one once kernels() has built it


def predict_py(x, P, Phi_w, A_nu, M_inv, G, decay, Q, dt, tm, J, tau_c, F, xn, Pn):  # pragma: no cover - compiled
    """One prediction over ``dt`` [s] (EKF3–EKF4): ``xn`` (15,) the predicted state, ``Pn`` (15, 15)
    ``F P F^T + Q``; ``F`` (15, 15) holds the transition with its WF and bias blocks set (the
    observer's ``_Phi``) and gets the LF rows written (rows 6–11, columns 6–14).

    ``tm`` (3,) the mooring load at ``eta`` [N, N, N m], ``J`` (3, 3) its Jacobian, ``tau_c`` (3,)
    the thrust in {B}; ``A_nu`` the kinetics' implicit damping, ``M_inv`` the inverse inertia,
    ``G = dt A_nu M_inv``, ``decay`` (3,) the bias decay, ``Q`` (15, 15) the process noise."""
    psi = x[8]
    c = math.cos(psi)
    s = math.sin(psi)
    b0 = x[12]
    b1 = x[13]
    # nu+ = A_nu (nu + dt M^-1 (R^T b + tau_m + tau_c))
    w = np.empty(3)
    w[0] = (c * b0 + s * b1) + tm[0] + tau_c[0]
    w[1] = (-s * b0 + c * b1) + tm[1] + tau_c[1]
    w[2] = x[14] + tm[2] + tau_c[2]
    a = np.empty(3)
    for i in range(3):
        a[i] = x[9 + i] + dt * (M_inv[i, 0] * w[0] + M_inv[i, 1] * w[1] + M_inv[i, 2] * w[2])
    nu = np.empty(3)
    for i in range(3):
        nu[i] = A_nu[i, 0] * a[0] + A_nu[i, 1] * a[1] + A_nu[i, 2] * a[2]
    n0 = nu[0]
    n1 = nu[1]
    for i in range(6):
        acc = 0.0
        for k in range(6):
            acc += Phi_w[i, k] * x[k]
        xn[i] = acc
    xn[6] = x[6] + dt * (c * n0 - s * n1)
    xn[7] = x[7] + dt * (s * n0 + c * n1)
    xn[8] = x[8] + dt * nu[2]
    for i in range(3):
        xn[9 + i] = nu[i]
        xn[12 + i] = decay[i] * x[12 + i]
    # Jacobian of the discrete map, LF rows: X = d(R^T b + tau_m)/d(eta, nu, b) without nu (3 x 9)
    X = np.zeros((3, 9))
    for i in range(3):
        for j in range(3):
            X[i, j] = J[i, j]
    X[0, 2] += -s * b0 + c * b1           # d(R^T b)/d psi
    X[1, 2] += -c * b0 - s * b1
    X[0, 6] = c
    X[0, 7] = s
    X[1, 6] = -s
    X[1, 7] = c
    X[2, 8] = 1.0
    Fnu = np.empty((3, 9))
    for i in range(3):
        for j in range(9):
            Fnu[i, j] = G[i, 0] * X[0, j] + G[i, 1] * X[1, j] + G[i, 2] * X[2, j]
        for j in range(3):
            Fnu[i, 3 + j] = A_nu[i, j]
    # Feta = dt R(psi) Fnu + I, plus d(R nu+)/d psi
    for j in range(9):
        F[6, 6 + j] = dt * c * Fnu[0, j] + (-dt * s) * Fnu[1, j]
        F[7, 6 + j] = dt * s * Fnu[0, j] + dt * c * Fnu[1, j]
        F[8, 6 + j] = dt * Fnu[2, j]
        for i in range(3):
            F[9 + i, 6 + j] = Fnu[i, j]
    F[6, 6] += 1.0
    F[7, 7] += 1.0
    F[8, 8] += 1.0
    F[6, 8] += dt * (-s * n0 - c * n1)
    F[7, 8] += dt * (c * n0 - s * n1)
    # Pn = F P F^T + Q
    FPFt = _sandwich_k(F, P)
    for i in range(15):
        for j in range(15):
            Pn[i, j] = FPFt[i, j] + Q[i, j]


def correct_py(x, P, y, r, xn, Pn, innov, S):  # pragma: no cover - compiled
    """The correction with a new position and heading (EKF5–EKF6, every component new): ``xn``,
    ``Pn`` the corrected state and covariance (Joseph form, R = diag(r)), ``innov`` (3,) the
    innovation (heading wrapped to [-pi, pi)), ``S`` (3, 3) its covariance. Returns False when S is
    singular or not finite (nothing written but ``innov`` and ``S``)."""
    for i in range(3):
        innov[i] = y[i] - x[6 + i] - x[3 + i]
    a = innov[2]
    innov[2] = a - _TWO_PI * math.floor((a + math.pi) / _TWO_PI)
    # P H^T = P[:, 3:6] + P[:, 6:9] (15 x 3); S = H P H^T + R
    PHt = np.empty((15, 3))
    for i in range(15):
        for j in range(3):
            PHt[i, j] = P[i, 3 + j] + P[i, 6 + j]
    for i in range(3):
        for j in range(3):
            S[i, j] = PHt[3 + i, j] + PHt[6 + i, j] + (r[i] if i == j else 0.0)
    # S^-1 by cofactors
    sa, sb, sc = S[0, 0], S[0, 1], S[0, 2]
    sd, se, sf = S[1, 0], S[1, 1], S[1, 2]
    sg, sh, si = S[2, 0], S[2, 1], S[2, 2]
    cA = se * si - sf * sh
    cB = -(sd * si - sf * sg)
    cC = sd * sh - se * sg
    det = sa * cA + sb * cB + sc * cC
    if det == 0.0 or not math.isfinite(det):
        return False
    Si = np.empty((3, 3))
    Si[0, 0] = cA / det
    Si[0, 1] = -(sb * si - sc * sh) / det
    Si[0, 2] = (sb * sf - sc * se) / det
    Si[1, 0] = cB / det
    Si[1, 1] = (sa * si - sc * sg) / det
    Si[1, 2] = -(sa * sf - sc * sd) / det
    Si[2, 0] = cC / det
    Si[2, 1] = -(sa * sh - sb * sg) / det
    Si[2, 2] = (sa * se - sb * sd) / det
    K = np.empty((15, 3))
    for i in range(15):
        for j in range(3):
            K[i, j] = PHt[i, 0] * Si[0, j] + PHt[i, 1] * Si[1, j] + PHt[i, 2] * Si[2, j]
    for i in range(15):
        xn[i] = x[i] + (K[i, 0] * innov[0] + K[i, 1] * innov[1] + K[i, 2] * innov[2])
    # I - K H: K H has K in columns 3:6 and again in 6:9
    IKH = np.zeros((15, 15))
    for i in range(15):
        IKH[i, i] = 1.0
        for j in range(3):
            IKH[i, 3 + j] -= K[i, j]
            IKH[i, 6 + j] -= K[i, j]
    B = _sandwich_k(IKH, P)
    for i in range(15):
        for j in range(15):
            B[i, j] += K[i, 0] * r[0] * K[j, 0] + K[i, 1] * r[1] * K[j, 1] + K[i, 2] * r[2] * K[j, 2]
    for i in range(15):
        for j in range(15):
            Pn[i, j] = 0.5 * (B[i, j] + B[j, i])
    return True


_KERNELS: Any = False   # built on first use


def kernels() -> tuple | None:
    """(predict, correct) compiled (numba compiles them on the first call, cached on disk), or None
    without numba: the observer then runs its numpy path."""
    global _KERNELS, _sandwich_k
    if _KERNELS is False:
        sw = jit(sandwich_py, fallback=None)
        if sw is None:
            _KERNELS = None
        else:
            _sandwich_k = sw   # the kernels call it compiled (numba reads the global when it compiles them)
            _KERNELS = (jit(predict_py), jit(correct_py))
    return _KERNELS
