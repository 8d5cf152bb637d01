"""Closed-loop figures of a gain design: poles, periods, damping and loop-at-a-time margins.

Margins per DOF, **loop at a time** (``docs/gains.md``): the loop of DOF i is broken at the plant
input i, the other two loops stay closed, on the coupled linearised model with all four PID modes.
With ``T_i`` the closed-loop transfer from a load added at input i to the command i,
``L_i = -T_i / (1 + T_i)``, and ``control.stability_margins`` is applied to ``L_i(s) G_lag(s)``,
``G_lag`` the thrust lag and the estimator low-pass (:func:`loop_lag`).
"""

from __future__ import annotations

import inspect
import math
from typing import Any

import control
import numpy as np

from .._io import readonly
from ..control.pid import MODES, PIDGains
from ..control.pid_design import closed_loop
from ..estimation.lowpass import LowPassEstimator

__all__ = ["ESTIMATOR_CUTOFF", "GM_INF", "loop_lag", "margins", "sorted_damp"]

#: Default cut-off [rad/s] of the position low-pass in the margin loops: the default of
#: :class:`~tapm_opt.estimation.lowpass.LowPassEstimator`, the estimate the closed loop uses.
ESTIMATOR_CUTOFF: float = float(inspect.signature(LowPassEstimator).parameters["omega_c"].default)

#: Gain margins above this are reported as inf (the phase reaches -180 deg only asymptotically
#: and a round-off crossing gives a huge finite number).
GM_INF = 1.0e6


def sorted_damp(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eigenvalues of ``A`` by magnitude (then imaginary part), their natural periods
    ``2 pi / |p|`` [s] (inf for |p| = 0) and damping ratios ``-Re(p) / |p|``."""
    sys = control.ss(A, np.zeros((A.shape[0], 1)), np.eye(A.shape[0]), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        wn, zeta, poles = control.damp(sys, doprint=False)
    order = np.lexsort((poles.imag, np.abs(poles)))
    wn, zeta, poles = wn[order], zeta[order], poles[order]
    with np.errstate(divide="ignore"):
        periods = np.where(wn > 0.0, 2.0 * np.pi / np.where(wn > 0.0, wn, 1.0), np.inf)
    return poles, periods, zeta


def loop_lag(thrust_time_constant: float, estimator_cutoff: float | None) -> Any:
    """``G_lag(s) = 1/(T_thr s + 1) * w_c^2/(s + w_c)^2``: thrust lag (T_thr [s], 0: none) and
    the critically damped position low-pass (w_c [rad/s], None: none)."""
    lag = control.tf([1.0], [1.0])
    if thrust_time_constant > 0.0:
        lag = lag * control.tf([1.0], [thrust_time_constant, 1.0])
    if estimator_cutoff is not None:
        wc = estimator_cutoff
        lag = lag * control.tf([wc**2], [1.0, 2.0 * wc, wc**2])
    return lag


def margins(plant: control.StateSpace, gains: PIDGains, lag: Any, *,
            reference_point: Any = (0.0, 0.0)) -> tuple[np.ndarray, ...]:
    """Loop-at-a-time margins (module docstring).

    Parameters
    ----------
    plant : control.StateSpace
        Linearised moored vessel, states (eta, nu), inputs tau in {B}, full state out.
    gains : PIDGains
    lag : control.TransferFunction
        :func:`loop_lag`.
    reference_point : array_like, shape (2,)
        The PID's reference point in {B} [m] (the centre of turret), as in
        :func:`~tapm_opt.control.pid_design.closed_loop`.

    Returns
    -------
    gain_margin, phase_margin, crossover, delay_margin : ndarray, shape (3,)
        Per DOF: ratio (inf: the phase never crosses -180 deg), [deg], gain-crossover
        frequency [rad/s], phase_margin / crossover [s].
    """
    cl = closed_loop(plant, gains, MODES, reference_point=reference_point)
    out = np.zeros((4, 3))
    for i in range(3):
        T = cl[3 + i, i]  # load added at input i -> command i, all loops closed
        L = -control.feedback(T, 1.0) * lag  # T = -L/(1+L)  <=>  L = -T/(1+T)
        gm, pm, _, _, wgc, _ = control.stability_margins(L)
        gm, pm, wgc = float(gm), float(pm), float(wgc)
        if gm > GM_INF:  # the phase reaches -180 deg only asymptotically (round-off crossing)
            gm = math.inf
        dm = math.radians(pm) / wgc if (math.isfinite(wgc) and wgc > 0.0) else math.inf
        out[:, i] = gm, pm, wgc, dm
    return tuple(readonly(r) for r in out)
