"""TAPM PID control modes and their gains by pole placement.

The multivariable PID of [G] §2.3,

    tau = -K_i R(psi)^T int(eta - eta_d) dt - K_p R(psi)^T (eta - eta_d) - K_d (nu - nu_d),

split into the four TAPM control modes of [S] Table 2 by the projections H_psi = diag(0, 0, 1)
and H_xy = diag(1, 1, 0) (xi_dot = eta - eta_d, heading error wrapped with ``ssa``):

    1. heading PID          -H_psi K_i R^T xi - H_psi K_p R^T (eta - eta_d) - H_psi K_d (nu - nu_d)
    2. surge-sway damping   -H_xy K_d (nu - nu_d)
    3. surge-sway restoring -H_xy K_p R^T (eta - eta_d)
    4. surge-sway mean      -H_xy K_i R^T xi

The enabled modes are summed; :data:`MODE_SETS` holds the combinations of [S] Table 3. A vessel
with low-frequency roll and pitch (a semi-submersible) may add the **roll–pitch damping** mode of
[S] §4.2.3 (:class:`RollPitchDamping`, off by default): the measured roll and pitch rates (and,
optionally, angles) of its motion reference unit, low-pass filtered, make a sway and a surge force
whose moment about the centre of gravity through the thrusters' vertical lever arm ell = z_T - z_G
opposes the motion (``docs/semi.md`` eq. RP6)::

    Y_rp = (K_d,roll p + K_p,roll phi) / ell,    X_rp = -(K_d,pitch q + K_p,pitch theta) / ell

so the thrust's roll moment is -K_d,roll p - K_p,roll phi (and likewise in pitch). The
position in eta - eta_d is that of the controller's reference point — the centre of turret for a
turret-moored vessel, as a turret offset (``geometry.turret_offset``) — so a hull turning about
the turret gives no position error.
[S] writes the damping term on accelerations (nu_dot - nu_d_dot); this module follows [G] and
feeds back velocities: with K_d in N s/m a D-term on acceleration has the wrong units, and
"damping" means a load proportional to velocity.

Gains come from per-DOF pole placement on the linearised moored vessel ([S] eq. 31 about an
equilibrium): :func:`~tapm_opt.control.pid_design.design_gains`,
:func:`~tapm_opt.control.pid_design.design_from_scenario` (module ``pid_design``, which also computes
the closed-loop poles of the coupled 3-DOF model with python-control). ``[S]`` = seed survey-tapm-modeling-and-control,
``[G]`` = seed reliability-setpoint-riser-mooring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Mapping, Sequence

import numpy as np

from .._checks import vector
from .._io import readonly
from ..errors import TapmError
from ..geometry import rot_z, ssa
from ..interfaces import ControllerStep
from .estimate import Estimate, Setpoint

__all__ = [
    "ControlError",
    "GainClampWarning",
    "MODES",
    "MODE_SETS",
    "SEA_CLASSES",
    "CLASS_MODE_SETS",
    "H_PSI",
    "H_XY",
    "PIDGains",
    "RollPitchDamping",
    "TAPMPID",
]

_X, _Y, _PSI = 0, 1, 2





class ControlError(TapmError, ValueError):
    """A controller or a gain design got input it cannot use (bad shape, NaN, unknown mode)."""


class GainClampWarning(UserWarning):
    """A designed gain came out negative and was set to zero (see ``PIDDesign.clamped``)."""


#: The four TAPM control modes of [S] Table 2, in the order of the table.
MODES: tuple[str, ...] = ("heading", "damping", "restoring", "mean")

#: Mode combinations of [S] Table 3 (control actions 1, 1+2, 1+2+3, 1+2+4, 1+2+3+4).
MODE_SETS: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "calm": ("heading",),
    "normal": ("heading", "damping"),
    "normal_restoring": ("heading", "damping", "restoring"),
    "extreme": ("heading", "damping", "mean"),
    "extreme_restoring": ("heading", "damping", "restoring", "mean"),
})

#: Sea-state classes, ordered from calm to extreme.
SEA_CLASSES: tuple[str, ...] = ("calm", "normal", "extreme")
#: Control modes of each class ([S] Table 3): calm -> heading PID only (action 1); normal ->
#: heading + surge-sway damping + restoring (1+2+3); extreme -> all four (1+2+3+4). Keys of
#: :data:`MODE_SETS`; the gain tables (``design.tables``) and the sea-state supervisor use them.
CLASS_MODE_SETS: Mapping[str, str] = MappingProxyType(
    {"calm": "calm", "normal": "normal_restoring", "extreme": "extreme_restoring"})

#: Projections of [S] Table 2 onto heading and onto surge-sway.
H_PSI = readonly(np.diag([0.0, 0.0, 1.0]))
H_XY = readonly(np.diag([1.0, 1.0, 0.0]))


def _resolve_modes(modes: str | Sequence[str]) -> tuple[str, ...]:
    """Modes as a tuple in the order of :data:`MODES`; a string is a :data:`MODE_SETS` key or
    one mode name."""
    if isinstance(modes, str):
        if modes in MODE_SETS:
            return MODE_SETS[modes]
        modes = (modes,)
    try:
        given = tuple(modes)
    except TypeError:
        raise ControlError(f"modes={modes!r} must be a name in {tuple(MODE_SETS)} or a sequence "
                           f"of modes from {MODES}") from None
    unknown = [m for m in given if m not in MODES]
    if unknown:
        raise ControlError(f"unknown control mode(s) {unknown}; modes are {MODES}, combinations "
                           f"{tuple(MODE_SETS)}")
    if not given:
        raise ControlError(f"modes is empty; enable at least one of {MODES}")
    return tuple(m for m in MODES if m in given)


def _projections(modes: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(H_I, H_P, H_D): the rows of K_i, K_p, K_d in use for ``modes`` ([S] Table 2)."""
    head = H_PSI if "heading" in modes else np.zeros((3, 3))
    H_I = head + (H_XY if "mean" in modes else 0.0)
    H_P = head + (H_XY if "restoring" in modes else 0.0)
    H_D = head + (H_XY if "damping" in modes else 0.0)
    return H_I, H_P, H_D


def _integrated(Ki_used: np.ndarray) -> np.ndarray:
    """Which components of xi (x, y, psi) feed the output: x and y together (R^T mixes them)."""
    used_cols = np.any(Ki_used != 0.0, axis=0)
    xy = bool(used_cols[_X] or used_cols[_Y])
    return np.array([xy, xy, bool(used_cols[_PSI])])


def _gain_matrix(name: str, value: Any) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ControlError(f"{name}={value!r} is not numeric") from None
    if arr.shape == (3,):
        arr = np.diag(arr)
    if arr.shape != (3, 3):
        raise ControlError(f"{name} must have shape (3,) (diagonal) or (3, 3), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ControlError(f"{name} must be finite, got {name}={arr.tolist()}")
    if np.any(np.diag(arr) < 0.0):
        raise ControlError(f"{name} must have a non-negative diagonal ([G] §2.3), got "
                           f"diag({name})={np.diag(arr).tolist()}")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, kw_only=True, eq=False)
class PIDGains:
    """Gains of the multivariable PID ([G] §2.3), acting on {B}-frame errors.

    Each accepts a (3,) diagonal or a full (3, 3) matrix (stored as (3, 3), read-only); the
    diagonal must be non-negative.

    Parameters
    ----------
    Kp : array_like, shape (3,) or (3, 3)
        Restoring gain [N/m, N/m, N m/rad].
    Ki : array_like, shape (3,) or (3, 3)
        Integral gain [N/(m s), N/(m s), N m/(rad s)].
    Kd : array_like, shape (3,) or (3, 3)
        Damping gain [N s/m, N s/m, N m s/rad].
    """

    Kp: np.ndarray
    Ki: np.ndarray
    Kd: np.ndarray

    def __post_init__(self) -> None:
        for name in ("Kp", "Ki", "Kd"):
            object.__setattr__(self, name, _gain_matrix(name, getattr(self, name)))


@dataclass(frozen=True, kw_only=True)
class RollPitchDamping:
    """Gains of the roll–pitch damping mode ([S] §4.2.3, ``docs/semi.md`` eq. RP6).

    Parameters
    ----------
    lever : float
        Vertical lever arm ell = z_T - z_G of the thrust below the centre of gravity [m], non-zero
        (:attr:`tapm_opt.models.vessel.RollPitchParams.thruster_lever`).
    Kd_roll, Kd_pitch : float
        Roll and pitch damping the thrust adds [N m s/rad], >= 0.
    Kp_roll, Kp_pitch : float
        Roll and pitch stiffness the thrust adds [N m/rad], >= 0 (default 0: damping only).
    filter_time : float
        Time constant of the first-order low-pass filter on the measured attitude [s], >= 0 (0: none);
        it keeps the sensor noise out of the thrust. A hull whose MRU also reads wave-frequency roll
        and pitch (``six_dof``) needs a longer one (or a notch) so that the thrusters do not chase
        them; the default 2 s lags the semi's 108 s roll by 7 deg and its 36 s pitch by 19 deg.
    """

    lever: float
    Kd_roll: float
    Kd_pitch: float
    Kp_roll: float = 0.0
    Kp_pitch: float = 0.0
    filter_time: float = 2.0

    def __post_init__(self) -> None:
        for name in ("lever", "Kd_roll", "Kd_pitch", "Kp_roll", "Kp_pitch", "filter_time"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ControlError(f"roll_pitch_damping.{name} = {v!r} must be a finite number")
            if name != "lever" and v < 0.0:
                raise ControlError(f"roll_pitch_damping.{name} = {v!r} must be >= 0")
            object.__setattr__(self, name, float(v))
        if self.lever == 0.0:
            raise ControlError("roll_pitch_damping.lever = 0 m: thrust at the centre of gravity's depth makes no roll "
                               "or pitch moment")

    def force(self, attitude: np.ndarray) -> tuple[float, float]:
        """(X, Y) [N] in {B} for the (filtered) attitude (roll, pitch, roll rate, pitch rate)."""
        phi, theta, p, q = attitude
        return (-(self.Kd_pitch * q + self.Kp_pitch * theta) / self.lever,
                (self.Kd_roll * p + self.Kp_roll * phi) / self.lever)


def _limit(name: str, value: Any, *, allow_zero: bool) -> np.ndarray | None:
    if value is None:
        return None
    try:
        arr = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy()
    except (TypeError, ValueError):
        raise ControlError(f"{name}={value!r} must be a scalar or have shape (3,) "
                           f"[N, N, N m]") from None
    bad = np.isnan(arr) | (arr < 0.0) | ((arr == 0.0) if not allow_zero else False)
    if np.any(bad):
        rule = ">= 0" if allow_zero else "> 0"
        raise ControlError(f"{name} must be {rule} (inf for no limit), got {name}={arr.tolist()}")
    arr.flags.writeable = False
    return arr


def _vec3(name: str, value: Any) -> np.ndarray:
    return vector(name, value, 3, error=ControlError, eq="=",
                  note="the controller will not command thrust from it (check the observer/sensors)")


def _vec3_in(name: str, value: Any) -> np.ndarray:
    """:func:`_vec3` of an input the controller only reads: a float64 (3,) array with finite
    entries is taken as it is (no copy; a finite sum means finite entries), anything else checked
    and converted by :func:`_vec3`."""
    if (type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (3,)
            and math.isfinite(value[0] + value[1] + value[2])):
        return value
    return _vec3(name, value)


def _clip(v: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """``np.clip(v, -limit, limit)`` for float (3,) arrays (the same numbers, without its
    dispatch)."""
    return np.minimum(np.maximum(v, -limit), limit)


class TAPMPID:
    """TAPM PID controller: the sum of the enabled modes of [S] Table 2.

    ``update(t, estimate, setpoint) -> tau`` returns the commanded generalised thrust in {B}
    (X [N], Y [N], N [N m]). Discrete time: the integral advances by the actual time since the
    previous call (backward Euler on the current error); the first call after construction or
    :meth:`reset` only initialises the clock.

    Parameters
    ----------
    gains : PIDGains
    modes : str or sequence of str
        Enabled modes from :data:`MODES`, or a :data:`MODE_SETS` name such as ``"extreme"``.
    tau_limit : float or array_like shape (3,), optional
        Saturation of the output per DOF [N, N, N m] (e.g. the thrust the allocation can deliver
        in each DOF); None for no saturation.
    integral_limit : float or array_like shape (3,), optional
        Bound on each component of the integral load K_i R^T xi in {B} [N, N, N m]. Default:
        ``tau_limit`` (if given), else unbounded. Use e.g. ``0.5 * tau_limit`` to reserve thrust
        for damping and restoring.
    anti_windup : bool
        If True (default), clamp the integral to ``integral_limit`` and stop integrating a DOF
        while its output is saturated by ``tau_limit`` and the error would drive it further into
        saturation (conditional integration). False is the plain PID (for comparison).
    env_feedforward : bool
        If True, subtract ``estimate.tau_env`` from the command (mean-load feedforward, the
        alternative to integral action of Aalbers et al. in [S] §4.2.1). Default False: in TAPM
        the mooring should carry the mean load.
    reference_point : array_like shape (2,)
        Point of the hull in {B} [m] whose position is controlled: the centre of turret for a
        turret-moored vessel (the DP reference point, [S] §4.2.1), so that the position error is
        the turret offset (``geometry.turret_offset``) minus the setpoint and the surge-sway
        damping acts on that point's velocity. Default (0, 0): the body origin.
    period : float or None
        Update period [s] for the closed-loop runner (None: the runner's control period).
    thrusters : ThrusterSet, optional
        The thrusters behind ``tau_limit``: when the thruster feedback reports failures
        (:meth:`set_failed_thrusters`), ``tau_limit`` shrinks by the ratio of the remaining
        thrusters' capacity box to the intact one (``models.system.ThrusterSet``). Without it the
        limit stays.
    line_model : MooringModel, optional
        The intact line model, for ``fault_tolerance``.
    roll_pitch : RollPitchDamping, optional
        The roll–pitch damping mode ([S] §4.2.3): its surge and sway force, from the attitude of
        the last :meth:`set_attitude` (the motion reference unit), is added to the command before
        the saturation. None (default): off.
    fault_tolerance : bool
        When the estimate reports broken lines (``Estimate.broken_lines``) or lost buoys
        (``Estimate.lost_points``), add the load the mooring no longer gives the vessel at the
        estimated pose as feed-forward, ``tau_moor,intact(eta) - tau_moor,damaged(eta)`` ([S]
        §4.2.4: "the thrusters must be used in feedforward to compensate for the lost mooring
        force"; the tabulated catenary of :meth:`MooringModel.load_evaluator`). Needs ``line_model``.

    Notes
    -----
    The integral state xi lives in {E} (xi_dot = eta - eta_d, heading error wrapped), as in
    [S] Table 2, so a mean load fixed in {E} stays compensated when the vessel turns. Only the
    components of xi that reach the output through the enabled modes are integrated (x and y
    for ``"mean"``, psi for ``"heading"``); the others are held at zero, so enabling a mode later
    starts its integral from zero.
    """

    def __init__(self, gains: PIDGains, *, modes: str | Sequence[str] = MODES,
                 tau_limit: Any = None, integral_limit: Any = None, anti_windup: bool = True,
                 env_feedforward: bool = False, reference_point: Any = (0.0, 0.0),
                 period: float | None = None, thrusters: Any = None, line_model: Any = None,
                 fault_tolerance: bool = False, roll_pitch: RollPitchDamping | None = None) -> None:
        if not isinstance(gains, PIDGains):
            raise ControlError(f"gains must be a PIDGains, got {type(gains).__name__}")
        if roll_pitch is not None and not isinstance(roll_pitch, RollPitchDamping):
            raise ControlError(f"roll_pitch must be a RollPitchDamping or None, got {type(roll_pitch).__name__}")
        self._rpd = roll_pitch
        if not isinstance(fault_tolerance, bool):
            raise ControlError(f"fault_tolerance = {fault_tolerance!r} must be true or false")
        if fault_tolerance and line_model is None:
            raise ControlError("fault_tolerance needs the intact line model (line_model)")
        self._line_model, self._ft = line_model, fault_tolerance
        self._reduced: dict[frozenset, Any] = {}
        self._gains = gains
        self._tau_limit = _limit("tau_limit", tau_limit, allow_zero=False)
        self._tau_limit_intact = self._tau_limit
        self._thrusters = thrusters
        il = _limit("integral_limit", integral_limit, allow_zero=True)
        if il is None:
            il = self._tau_limit if self._tau_limit is not None else readonly(np.full(3, np.inf))
        self._integral_limit = il
        self._integral_limited = bool(np.any(np.isfinite(il)))
        self._anti_windup = bool(anti_windup)
        self._env_ff = bool(env_feedforward)
        rp = np.asarray(reference_point, dtype=float)
        if rp.shape != (2,) or not np.all(np.isfinite(rp)):
            raise ControlError(f"reference_point={reference_point!r} must be 2 finite numbers (x, y) in {{B}} [m]")
        self._p_ref = rp
        self._p_ref_xy = (float(rp[0]), float(rp[1]))
        if period is not None and not (np.isfinite(period) and period > 0):
            raise ControlError(f"period={period!r} must be a positive number [s] or None")
        self.period = None if period is None else float(period)
        self._xi = np.zeros(3)
        self.set_modes(modes)
        self.reset()

    @classmethod
    def from_design(cls, design: Any, *, modes: str | Sequence[str] = MODES,
                    **kwargs: Any) -> TAPMPID:
        """Controller with the gains of ``design`` (a
        :class:`~tapm_opt.control.pid_design.PIDDesign`); ``kwargs`` as for the constructor."""
        if not isinstance(getattr(design, "gains", None), PIDGains):
            raise ControlError(f"design must be a PIDDesign, got {type(design).__name__}")
        return cls(design.gains, modes=modes, **kwargs)

    # -- state ---------------------------------------------------------------------------
    def reset(self) -> None:
        """Zero the integral, forget the clock and the saturation state."""
        self._xi = np.zeros(3)
        self._t_prev: float | None = None
        self._sat = np.zeros(3, dtype=bool)
        self._tau_unsat = np.zeros(3)
        self._psi = 0.0
        self._last: ControllerStep | None = None
        self._att: np.ndarray | None = None   # the filtered attitude of the roll–pitch damping mode
        self._t_att: float | None = None
        self._tau_rp = np.zeros(3)

    @property
    def roll_pitch(self) -> RollPitchDamping | None:
        """The roll–pitch damping mode's gains, or None (off)."""
        return self._rpd

    @property
    def roll_pitch_force(self) -> np.ndarray:
        """The roll–pitch damping mode's part of the last command (X [N], Y [N], 0) in {B}, before the
        saturation; zeros when off."""
        return readonly(self._tau_rp)

    def set_attitude(self, t: float, attitude: Any) -> None:
        """The motion reference unit's attitude at ``t`` [s]: (roll [rad], pitch [rad], roll rate
        [rad/s], pitch rate [rad/s]) (:attr:`tapm_opt.interfaces.Measurement.attitude`), low-pass
        filtered with ``roll_pitch.filter_time`` (exact discretisation of the first-order filter
        over the time since the previous call). Ignored when the roll–pitch mode is off."""
        if self._rpd is None:
            return
        a = np.asarray(attitude, dtype=float)
        if a.shape != (4,) or not np.isfinite(a).all():
            raise ControlError(f"attitude = {a.tolist()} must be 4 finite numbers (roll [rad], pitch [rad], "
                               "roll rate [rad/s], pitch rate [rad/s]): the controller will not command thrust from it")
        t = float(t)
        if self._att is None or self._rpd.filter_time == 0.0:
            self._att = a.copy()
        elif t > self._t_att:
            k = 1.0 - math.exp(-(t - self._t_att) / self._rpd.filter_time)
            self._att = self._att + k * (a - self._att)
        self._t_att = t

    def last_step(self) -> ControllerStep | None:
        """Diagnostics of the latest update: ``active`` holds ``"saturated"`` when ``tau_limit``
        clipped the command."""
        return self._last

    def set_failed_thrusters(self, failed: frozenset[str]) -> None:
        """Thruster feedback reports ``failed`` (the :class:`~tapm_opt.interfaces.FaultAware`
        method): scale ``tau_limit`` to what the remaining thrusters can deliver."""
        if self._thrusters is None or self._tau_limit_intact is None:
            return
        intact = np.asarray(self._thrusters.capacity_box(), float)
        left = np.asarray(self._thrusters.without(failed).capacity_box(), float) if failed else intact
        ratio = np.divide(left, intact, out=np.zeros(3), where=intact > 0)
        # a DOF the remaining thrusters cannot serve keeps a tiny limit (tau_limit must stay > 0)
        self._tau_limit = readonly(np.maximum(self._tau_limit_intact * ratio, 1e-9 * self._tau_limit_intact))

    def set_modes(self, modes: str | Sequence[str]) -> None:
        """Switch the enabled modes (e.g. from a sea-state supervisor, [S] Table 3).

        The integral of components no longer in use is zeroed; the rest is kept (bumpless).
        """
        self._modes = _resolve_modes(modes)
        H_I, H_P, H_D = _projections(self._modes)
        g = self._gains
        self._Ki = H_I @ g.Ki
        self._Kp = H_P @ g.Kp
        self._Kd = H_D @ g.Kd
        self._Ki_pinv = np.linalg.pinv(self._Ki)
        self._minus_Ki_diag = -np.diag(self._Ki)
        self._mask = _integrated(self._Ki)
        self._xi = np.where(self._mask, self._xi, 0.0)

    @property
    def gains(self) -> PIDGains:
        return self._gains

    @property
    def modes(self) -> tuple[str, ...]:
        """Enabled modes, in the order of :data:`MODES`."""
        return self._modes

    @property
    def tau_limit(self) -> np.ndarray | None:
        """Output saturation [N, N, N m], or None."""
        return self._tau_limit

    @property
    def integral_limit(self) -> np.ndarray:
        """Bound on |K_i R^T xi| per DOF [N, N, N m] (inf: none)."""
        return self._integral_limit

    @property
    def integral(self) -> np.ndarray:
        """Integral state xi in {E} (x [m s], y [m s], psi [rad s]), a read-only copy."""
        return readonly(self._xi)

    @property
    def integral_load(self) -> np.ndarray:
        """Integral part of the last command, -K_i R^T xi in {B} [N, N, N m] (projected)."""
        return readonly(-(self._Ki @ (rot_z(self._psi).T @ self._xi)))

    @property
    def saturated(self) -> np.ndarray:
        """Per DOF: was the last command clipped by ``tau_limit``? Read-only (3,) bool."""
        return readonly(self._sat, dtype=bool)

    # -- control law ---------------------------------------------------------------------
    def update(self, t: float, estimate: Estimate, setpoint: Setpoint) -> np.ndarray:
        """Command for the estimate at time ``t`` ([S] Table 2 with the enabled modes).

        Parameters
        ----------
        t : float
            Time [s]; must not decrease between calls (call :meth:`reset` to restart).
        estimate : Estimate
            ``eta`` (3,) in {E} [m, m, rad], ``nu`` (3,) in {B} [m/s, m/s, rad/s], ``tau_env``
            (3,) [N, N, N m] (used only with ``env_feedforward``).
        setpoint : Setpoint
            ``eta_d`` (3,): turret offset (x [m], y [m]) in {E} and heading [rad]; ``nu_d`` (3,)
            in {B}.

        Returns
        -------
        tau : ndarray, shape (3,)
            Commanded load in {B} (X [N], Y [N], N [N m]), saturated at ``tau_limit``.

        Raises
        ------
        ControlError
            Non-finite or wrongly shaped input, or time running backwards.
        """
        try:
            t = float(t)
        except (TypeError, ValueError):
            raise ControlError(f"t={t!r} must be a number [s]") from None
        if not np.isfinite(t):
            raise ControlError(f"t={t} must be finite [s]")
        eta = _vec3_in("estimate.eta", getattr(estimate, "eta", None))
        nu = _vec3_in("estimate.nu", getattr(estimate, "nu", None))
        eta_d = _vec3_in("setpoint.eta_d", getattr(setpoint, "eta_d", None))
        nu_d = _vec3_in("setpoint.nu_d", getattr(setpoint, "nu_d", None))
        tau_env = _vec3_in("estimate.tau_env", estimate.tau_env) if self._env_ff else None
        if self._t_prev is not None and t < self._t_prev:
            raise ControlError(f"t={t} s is earlier than the previous call at {self._t_prev} s; "
                               f"call reset() to restart the controller")

        # position error of the reference point (turret offset, geometry.turret_offset) and its
        # velocity in {B}, written out on the components (the same operations)
        psi = eta[_PSI]
        c, s = np.cos(psi), np.sin(psi)
        px, py = self._p_ref_xy
        e = np.array([(eta[_X] + (c * px - s * py) - px) - eta_d[_X],
                      (eta[_Y] + (s * px + c * py) - py) - eta_d[_Y],
                      ssa(psi - eta_d[_PSI])])
        r = nu[_PSI]
        dnu = np.array([(nu[_X] + -r * self._p_ref[1]) - nu_d[_X], (nu[_Y] + r * self._p_ref[0]) - nu_d[_Y],
                        (r + 0.0) - nu_d[_PSI]])
        Rt = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T   # rot_z(psi).T
        e_b = Rt @ e
        if self._t_prev is not None and t > self._t_prev:
            self._integrate(e_b, Rt, t - self._t_prev)
        self._t_prev = t
        self._psi = float(psi)

        tau = -(self._Ki @ (Rt @ self._xi)) - self._Kp @ e_b - self._Kd @ dnu
        if tau_env is not None:
            tau = tau - tau_env
        if self._ft and (estimate.broken_lines or estimate.lost_points):
            tau = tau + self.lost_load(eta, frozenset(estimate.broken_lines), frozenset(estimate.lost_points))
        if self._rpd is not None and self._att is not None:   # roll–pitch damping ([S] §4.2.3)
            X, Y = self._rpd.force(self._att)
            self._tau_rp = np.array([X, Y, 0.0])
            tau = tau + self._tau_rp
        self._tau_unsat = tau
        if self._tau_limit is not None:
            self._sat = np.abs(tau) > self._tau_limit
            tau = _clip(tau, self._tau_limit)
        self._last = ControllerStep(t=t, active=("saturated",) if np.any(self._sat) else ())
        return np.array(tau)

    def lost_load(self, eta: np.ndarray, broken: frozenset, lost_points: frozenset = frozenset()) -> np.ndarray:
        """The load in {B} [N, N, N m] the mooring no longer gives the vessel at pose ``eta`` (the
        fault-tolerant feed-forward): the intact model's minus the damaged model's, without the
        lines ``broken`` and the buoys ``lost_points`` ((line id, joint);
        :meth:`MooringModel.damaged <tapm_opt.models.mooring.MooringModel.damaged>`)."""
        ids = frozenset(self._line_model.line_ids)
        broken = frozenset(broken) & ids
        lost = frozenset(p for p in lost_points if p[0] in ids and p[0] not in broken)
        if not broken and not lost:
            return np.zeros(3)
        key = (broken, lost) if lost else broken
        if key not in self._reduced:
            self._reduced[key] = self._line_model.damaged(broken, lost)
        return np.asarray(self._line_model.force_fast(eta), float) - np.asarray(self._reduced[key].force_fast(eta), float)

    def _integrate(self, e_b: np.ndarray, Rt: np.ndarray, dt: float) -> None:
        """xi += (eta - eta_d) dt with conditional integration and clamping (anti-windup)."""
        step_b = np.where(self._mask, e_b * dt, 0.0)  # mask is x-y symmetric: R^T commutes
        if self._anti_windup and self._tau_limit is not None:
            # the integral's own push on DOF i has the sign of -Ki_ii e_b,i: freeze a saturated
            # DOF whose integral would push further into saturation
            push = self._minus_Ki_diag * step_b * self._tau_unsat
            step_b = np.where(self._sat & (push > 0.0), 0.0, step_b)
        xi = self._xi + Rt.T @ step_b
        if self._anti_windup and self._integral_limited:
            q = self._Ki @ (Rt @ xi)
            q_c = _clip(q, self._integral_limit)
            if (q_c != q).any():
                xi = xi + Rt.T @ (self._Ki_pinv @ (q_c - q))
        self._xi = xi
