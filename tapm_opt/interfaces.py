"""The seams of the control loop: what flows between plant, estimator, setpoint layer, controller
and allocation, and the small protocols each component implements.

::

    plant.measure() -> Measurement -> Estimator -> Estimate -> SetpointLayer -> Setpoint
                    -> Controller -> tau_cmd -> allocation -> ThrusterCommand -> plant.step

The closed-loop runner (:func:`tapm_opt.studies.closed_loop.run_closed_loop`) knows only these
protocols and the :class:`Measurement`; it never reads a component's or the plant's internals.
A third-party component needs nothing but the methods below (``typing.Protocol``: no base class
to inherit). Data objects are frozen; their arrays are read-only float copies.

Position convention: every position in a :class:`Setpoint` and every safety measure refers to the
centre of turret, as an offset from where it rests at the field zero point
(:func:`tapm_opt.geometry.turret_offset`); ``Estimate.eta`` is the body origin's pose.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ._io import readonly

__all__ = ["Measurement", "Truth", "Estimate", "Setpoint", "ThrusterCommand", "ControllerStep",
           "Controller", "ThrusterController", "FaultAware", "AttitudeAware", "Logged", "Estimator", "SetpointLayer",
           "WinchController"]


@dataclass(frozen=True, kw_only=True)
class Truth:
    """The plant's true low-frequency state, for validation estimators only (a real vessel has
    none). ``eta`` (3,) [m, m, rad] in {E}; ``nu`` (3,) [m/s, m/s, rad/s] in {B}; ``tau_env`` (3,)
    the slowly varying wind and wave-drift load in {B} [N, N, N m]."""

    eta: np.ndarray
    nu: np.ndarray
    tau_env: np.ndarray

    def __post_init__(self) -> None:
        for name in ("eta", "nu", "tau_env"):
            object.__setattr__(self, name, readonly(getattr(self, name)))


@dataclass(frozen=True, kw_only=True)
class Measurement:
    """What the vessel's sensors and thruster feedback report at time ``t``; arrays are read-only.

    Attributes
    ----------
    t : float
        Time of the request [s].
    position : ndarray, shape (2,)
        Measured (x, y) of the body origin in {E} [m] (held since ``t_position``); (nan, nan)
        when the GNSS has no fix (``position_valid`` False).
    heading : float
        Measured heading [rad] in [-pi, pi) (held since ``t_heading``).
    tensions : ndarray, shape (n_lines,)
        Measured fairlead tensions [N] (held since ``t_tensions``).
    t_position, t_heading, t_tensions : float
        Times [s] at which each held value was sampled.
    thruster_f, thruster_alpha : ndarray, shape (n_thrusters,) or None
        Thruster feedback: delivered thrust [N] and azimuth [rad] of each thruster.
    thruster_failed : ndarray of bool, shape (n_thrusters,) or None
        Thruster feedback: True where a thruster reports a failure.
    tau_thr : ndarray, shape (3,) or None
        Generalised thrust the thrusters deliver in {B} [N, N, N m], from the feedback.
    truth : Truth or None
        The plant's true LF state (validation only; see :class:`Truth`).
    riser_angles : ndarray, shape (4,) or None
        Measured riser angles (top_x, top_y, bottom_x, bottom_y) [rad] in {E}: the horizontal
        components of the riser's inclination from the vertical at the hang-off and at the
        wellhead, dw/ds with s up from the wellhead (:mod:`tapm_opt.models.riser`); held since
        ``t_riser_angles``. None without a riser.
    t_riser_angles : float or None
        Time [s] at which the held riser angles were sampled (None without a riser).
    attitude : ndarray, shape (4,) or None
        Motion reference unit of a vessel with low-frequency roll and pitch
        (``vessel.roll_pitch``): measured (roll [rad], pitch [rad], roll rate [rad/s], pitch rate
        [rad/s]), held since ``t_attitude``; None without it.
    t_attitude : float or None
        Time [s] at which the held attitude was sampled (None without it).
    position_valid : bool
        False when the GNSS reports no fix (a dropout): ``position`` is then (nan, nan) and every
        consumer must do without it (the estimators hold their prediction, or a redundant
        reference takes over: :mod:`tapm_opt.estimation.redundancy`). True otherwise.
    heading2 : float or None
        The second gyro-compass's heading [rad] in [-pi, pi), sampled with ``heading`` (held since
        ``t_heading``); None when the source has one gyro.
    """

    t: float
    position: np.ndarray
    heading: float
    tensions: np.ndarray
    t_position: float
    t_heading: float
    t_tensions: float
    thruster_f: np.ndarray | None = None
    thruster_alpha: np.ndarray | None = None
    thruster_failed: np.ndarray | None = None
    tau_thr: np.ndarray | None = None
    truth: Truth | None = None
    riser_angles: np.ndarray | None = None
    t_riser_angles: float | None = None
    attitude: np.ndarray | None = None
    t_attitude: float | None = None
    position_valid: bool = True
    heading2: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "position_valid", bool(self.position_valid))
        for name in ("position", "tensions", "thruster_f", "thruster_alpha", "tau_thr", "riser_angles", "attitude"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, readonly(v))
        if self.thruster_failed is not None:
            object.__setattr__(self, "thruster_failed", readonly(self.thruster_failed, dtype=bool))


@dataclass(frozen=True, eq=False)
class Estimate:
    """State estimate handed to setpoint layers and controllers.

    Parameters
    ----------
    t : float
        Time of the estimate [s].
    eta : ndarray, shape (3,)
        Low-frequency position and heading of the body origin in {E} (x [m], y [m], psi [rad]).
    nu : ndarray, shape (3,)
        Low-frequency velocity in {B} (u [m/s], v [m/s], r [rad/s]).
    tau_env : ndarray, shape (3,)
        Estimated slowly varying environmental load in {B} (X [N], Y [N], N [N m]); zeros if
        unknown.
    tensions : ndarray, shape (n_lines,), optional
        Measured fairlead tensions [N], if available.
    riser_angles : ndarray, shape (4,), optional
        Measured riser angles (top_x, top_y, bottom_x, bottom_y) [rad] in {E}, as
        :attr:`Measurement.riser_angles`; None without a riser.
    broken_lines : frozenset of str
        Ids of the lines the estimator's line-break detector reports broken (empty: none known,
        or no detector). Faults reach the setpoint layer and the controller only this way.
    lost_points : frozenset of (str, int)
        Buoys the detector reports lost from composite lines, (line id, joint index from the
        anchor up) (empty: none known). The line system after the faults is
        ``model.damaged(broken_lines, lost_points)``.
    reliability : ReliabilityState or None
        The estimator's on-line reliability statistics of the measured tensions and riser angles
        (:class:`tapm_opt.estimation.reliability.ReliabilityState`: ``x_lf``, ``sigma``, ``k``,
        ``delta`` per signal, ``names``, ``ready``), None without a monitor.
    eta_wf : ndarray, shape (3,), optional
        The estimator's wave-frequency motion of the body origin in {E} (x [m], y [m], psi [rad]):
        the part of the measured pose it filtered out of ``eta``; None when it does not say (e.g.
        the plant's truth). A sea-state supervisor reads its amplitude and period.
    """

    t: float
    eta: np.ndarray
    nu: np.ndarray
    tau_env: np.ndarray
    tensions: np.ndarray | None = None
    riser_angles: np.ndarray | None = None
    broken_lines: frozenset = frozenset()
    reliability: Any = None
    eta_wf: np.ndarray | None = None
    lost_points: frozenset = frozenset()

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", float(self.t))
        bl = self.broken_lines
        object.__setattr__(self, "broken_lines", frozenset([bl] if isinstance(bl, str) else (str(b) for b in bl)))
        object.__setattr__(self, "lost_points", frozenset((str(lid), int(j)) for lid, j in self.lost_points))
        for name in ("eta", "nu", "tau_env"):
            object.__setattr__(self, name, readonly(getattr(self, name)))
        for name in ("tensions", "riser_angles", "eta_wf"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, readonly(getattr(self, name)))


@dataclass(frozen=True, eq=False)
class Setpoint:
    """Desired motion handed to controllers.

    Parameters
    ----------
    eta_d : ndarray, shape (3,)
        Desired turret offset (x [m], y [m]: the centre of turret relative to its field-zero-point
        position, in {E}) and heading psi [rad].
    nu_d : ndarray, shape (3,)
        Desired velocity in {B} (u [m/s], v [m/s], r [rad/s]); zeros by default.
    """

    eta_d: np.ndarray
    nu_d: np.ndarray = field(default_factory=lambda: readonly(np.zeros(3)))

    def __post_init__(self) -> None:
        for name in ("eta_d", "nu_d"):
            object.__setattr__(self, name, readonly(getattr(self, name)))


@dataclass(frozen=True)
class ThrusterCommand:
    """Commanded thrust ``f`` [N] and azimuth ``alpha`` [rad] of each thruster, shape (n,)
    (``alpha`` None: keep the azimuths)."""

    f: np.ndarray
    alpha: np.ndarray | None = None


@dataclass(frozen=True)
class ControllerStep:
    """Diagnostics of one controller update.

    Attributes
    ----------
    t : float
        Time of the update [s].
    success : bool
        False when the controller could not compute its law (e.g. a failed solve).
    status : str
        Solver or controller status text.
    solve_time : float or None
        Wall time of the optimisation [s]; None for a controller that solves nothing.
    iterations : int
        Solver iterations (0 if none).
    fallback : bool
        True when a fallback command was applied.
    active : tuple of str
        Names of the constraints or limits active in this update (e.g. ``"safe_circle"``,
        ``"thrust_capacity"``, ``"saturated"``); counted by the runner.
    """

    t: float
    success: bool = True
    status: str = "ok"
    solve_time: float | None = None
    iterations: int = 0
    fallback: bool = False
    active: tuple[str, ...] = ()


def _trusted(cls: type, **fields: Any) -> Any:
    """A frozen data object of ``cls`` (:class:`Measurement`, :class:`Estimate`, :class:`Setpoint`,
    :class:`Truth`) from fields that are already what its constructor would make of them: every
    array a new read-only float64 (bool for ``thruster_failed``) held by nobody else, ``t`` a
    float, ``broken_lines`` a frozenset of str, ``lost_points`` a frozenset of (str, int). For the
    loop's own components on their hot path; the constructor's copies and conversions are skipped,
    the object is the same."""
    obj = object.__new__(cls)
    d = obj.__dict__
    d.update(_DEFAULTS[cls])
    d.update(fields)
    return obj


_DEFAULTS: dict[type, dict[str, Any]] = {
    Measurement: {"thruster_f": None, "thruster_alpha": None, "thruster_failed": None, "tau_thr": None,
                  "truth": None, "riser_angles": None, "t_riser_angles": None, "attitude": None,
                  "t_attitude": None, "position_valid": True, "heading2": None},
    Estimate: {"tensions": None, "riser_angles": None, "broken_lines": frozenset(), "reliability": None,
               "eta_wf": None, "lost_points": frozenset()},
    Setpoint: {},
    Truth: {},
}


def _frozen(a: np.ndarray) -> np.ndarray:
    """``a`` (a new float64 or bool array nobody else holds) made read-only in place."""
    a.flags.writeable = False
    return a


@runtime_checkable
class Controller(Protocol):
    """A motion controller: generalised thrust from the estimate and the setpoint."""

    #: Update period [s] (None: the runner's control period).
    period: float | None

    def update(self, t: float, estimate: Estimate, setpoint: Setpoint) -> np.ndarray:
        """Commanded generalised thrust ``tau_cmd`` (3,) in {B} [N, N, N m]."""
        ...

    def reset(self) -> None:
        ...

    def last_step(self) -> ControllerStep | None:
        """Diagnostics of the latest :meth:`update` (None before the first)."""
        ...


@runtime_checkable
class ThrusterController(Controller, Protocol):
    """A controller that can also allocate: when ``owns_allocation`` is True the runner applies its
    thruster command as it is, without the thrust allocation."""

    #: True when :meth:`thruster_command` is to be applied instead of allocating ``tau_cmd``.
    owns_allocation: bool

    def thruster_command(self) -> ThrusterCommand:
        """Thruster forces and azimuths of the latest update."""
        ...


@runtime_checkable
class FaultAware(Protocol):
    """A component that is told which thrusters the feedback reports as failed."""

    def set_failed_thrusters(self, failed: frozenset[str]) -> None:
        ...


@runtime_checkable
class AttitudeAware(Protocol):
    """A component that reads the motion reference unit of a vessel with low-frequency roll and
    pitch (:attr:`Measurement.attitude`), e.g. the PID's roll–pitch damping mode."""

    def set_attitude(self, t: float, attitude: np.ndarray) -> None:
        ...


@runtime_checkable
class Logged(Protocol):
    """A component that keeps a log of what it decided (e.g. a setpoint layer's re-optimisations);
    the runner stores it in the result's metadata under ``"<role>_log"``."""

    def log(self) -> list[dict]:
        """JSON-ready records, oldest first."""
        ...


@runtime_checkable
class Estimator(Protocol):
    """A state estimator: an :class:`Estimate` from each :class:`Measurement`."""

    def update(self, t: float, measurement: Measurement) -> Estimate:
        ...

    def reset(self) -> None:
        ...


@runtime_checkable
class SetpointLayer(Protocol):
    """A setpoint generator: the :class:`Setpoint` for the current estimate."""

    def update(self, t: float, estimate: Estimate) -> Setpoint:
        ...

    def reset(self) -> None:
        ...


@runtime_checkable
class WinchController(Protocol):
    """A line-tension (winch) controller ([AF] = seed line-tension-control-fem, §III): winch
    speeds that drive the mooring's horizontal force toward the DP command; the thrusters then
    supply the DP command minus :meth:`mooring_load` (``tau_thr = tau_c - tau_m``)."""

    def update(self, t: float, estimate: Estimate, tau_cmd: np.ndarray) -> np.ndarray:
        """Winch speed of each line (n_lines,) [m/s], + pays out, from the estimate (pose,
        measured tensions) and the DP controller's ``tau_cmd`` (3,) in {B} [N, N, N m]."""
        ...

    def mooring_load(self) -> np.ndarray:
        """The measured mooring load ``tau_m`` (3,) in {B} [N, N, N m] of the latest update."""
        ...

    def reset(self) -> None:
        ...
