"""Setpoint layers (:class:`~tapm_opt.interfaces.SetpointLayer`): fixed, setpoint chasing
(survey eq. 38) and weather-optimal heading chasing.

Positions are turret offsets: the centre of turret relative to where it rests at the field zero
point (``geometry.turret_offset``), the point the mooring acts on and the DP reference point of a
turret-moored vessel (survey §4.2.1). Headings are in {E} [rad].
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import TapmError
from ..estimation.lowpass import first_order_step
from ..geometry import ssa, turret_offset
from ..interfaces import Estimate, Logged, Setpoint, _frozen, _trusted

__all__ = ["FixedSetpoint", "SetpointChasing", "HeadingChasing", "SetpointError"]


class SetpointError(TapmError, ValueError):
    """Bad setpoint-layer settings."""


def _positive(name: str, v: Any) -> float:
    if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
        raise SetpointError(f"{name} = {v!r} must be a positive number")
    return float(v)


def _eta_d(v: Any) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise SetpointError(f"eta_d = {v!r} must be 3 finite numbers (x [m], y [m], psi [rad])")
    return a


class FixedSetpoint:
    """A constant setpoint ``eta_d`` = (turret offset x [m], y [m], heading [rad])."""

    def __init__(self, eta_d: Any = (0.0, 0.0, 0.0)):
        self.eta_d = _eta_d(eta_d)
        self._sp: Setpoint | None = None   # the (frozen, read-only) setpoint of the present eta_d

    def update(self, t: float, estimate: Estimate) -> Setpoint:
        sp = self._sp
        if sp is None or not np.array_equal(sp.eta_d, self.eta_d):
            sp = self._sp = Setpoint(eta_d=self.eta_d)
        return sp

    def reset(self) -> None:
        pass


class SetpointChasing:
    """Low-pass setpoint chasing (survey eq. 38): ``p_sp' = -(p_sp - p) / T`` with ``p`` the
    estimated turret offset, projected into the circle of radius ``R`` about the field zero point
    (``Pr_Safe`` of survey Table 2); the heading setpoint is ``psi_d``.

    Parameters
    ----------
    T : float
        Time constant [s].
    R : float or None
        Radius of the circle the setpoint is kept in [m] (None: no projection).
    psi_d : float
        Heading setpoint [rad].
    p_cot_B : array_like (2,)
        Centre of turret in {B} [m] (the reference point).
    """

    def __init__(self, T: float, R: float | None, psi_d: float = 0.0, p_cot_B: Any = (0.0, 0.0)):
        self.T = _positive("chase_time", T)
        self.R = None if R is None else _positive("chase radius", R)
        self.psi_d = float(psi_d)
        self.p_cot_B = np.asarray(p_cot_B, dtype=float)
        self.reset()

    def reset(self) -> None:
        self.p: np.ndarray | None = None
        self._t: float | None = None

    def update(self, t: float, estimate: Estimate) -> Setpoint:
        p = np.array(turret_offset(estimate.eta, self.p_cot_B), dtype=float)
        if self.p is None:
            self.p = p
        else:
            self.p = first_order_step(self.p, p, t - self._t, self.T)
        self._t = float(t)
        if self.R is not None:
            r = float(np.hypot(*self.p))
            if r > self.R:
                self.p = self.p * (self.R / r)
        return Setpoint(eta_d=np.array([self.p[0], self.p[1], self.psi_d]))


class HeadingChasing:
    """Weather-optimal heading on top of a position layer: the bow pointed into the estimated mean
    environmental force in {E}, ``atan2(-b_y, -b_x)``, low-pass filtered with time constant ``T``
    from ``psi_0``. A turret-moored vessel then weathervanes slowly instead of spending thrust on a
    yaw moment against the weather. Forces below ``min_force`` [N] leave the heading as it is.
    """

    def __init__(self, inner: Any, T: float, psi_0: float = 0.0, *, min_force: float = 1e3):
        self.inner = inner
        self.T = _positive("heading_chase_time", T)
        self.psi_0 = float(psi_0)
        self.min_force = float(min_force)
        self.reset()

    def log(self) -> list[dict]:
        """The inner layer's log (:class:`~tapm_opt.interfaces.Logged`), if it keeps one."""
        return self.inner.log() if isinstance(self.inner, Logged) else []

    def reset(self) -> None:
        self.inner.reset()
        self.psi = self.psi_0
        self._t: float | None = None

    def update(self, t: float, estimate: Estimate) -> Setpoint:
        sp = self.inner.update(t, estimate)
        c, s = np.cos(estimate.eta[2]), np.sin(estimate.eta[2])
        b_E = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.asarray(estimate.tau_env, float)  # rot_z
        dt = 0.0 if self._t is None else max(t - self._t, 0.0)
        self._t = float(t)
        if math.hypot(b_E[0], b_E[1]) > self.min_force and dt > 0:
            target = math.atan2(-b_E[1], -b_E[0])
            a = math.exp(-dt / self.T)
            self.psi = self.psi + (1 - a) * float(ssa(target - self.psi))
        eta_d = np.array([sp.eta_d[0], sp.eta_d[1], self.psi], dtype=float)
        if type(sp) is Setpoint and not sp.nu_d.flags.writeable:   # the inner layer's read-only nu_d, shared
            return _trusted(Setpoint, eta_d=_frozen(eta_d), nu_d=sp.nu_d)
        return Setpoint(eta_d=eta_d, nu_d=sp.nu_d)
