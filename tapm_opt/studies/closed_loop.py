"""Closed loop: plant -> sensors -> estimate -> setpoint -> controller -> allocation -> thrusters.

The runner owns time and rates and knows the components only through the protocols of
:mod:`tapm_opt.interfaces`. Every control period ``dt_control`` it reads the plant's measurement
(sensors and thruster feedback), updates the :class:`~tapm_opt.interfaces.Estimator` (the low-pass
estimator, or the plant's truth when ``true_state=True``), the
:class:`~tapm_opt.interfaces.SetpointLayer` (fixed, or chased by the low-pass filter of survey
eq. 38 and projected into the safe circle, with the heading fixed or weather-optimal), asks the
:class:`~tapm_opt.interfaces.Controller` for a generalised thrust at its own period (held in
between), allocates it to the thrusters (unless the controller is a
:class:`~tapm_opt.interfaces.ThrusterController` that owns the allocation) and steps the plant.
Each update's :class:`~tapm_opt.interfaces.ControllerStep` (solve time, status, active constraints,
fallback) is summarised in the result's diagnostics.

Positions of setpoints are turret offsets (``geometry.turret_offset``).

Faults: a thruster failure reaches the allocator (and a :class:`~tapm_opt.interfaces.FaultAware`
controller) through the thruster feedback of the measurement; a line break reaches the setpoint
layer and the controller through the default estimator's line-break detector (the statistical
tension test, ``Estimate.broken_lines``), which also drops the line from the estimator's load
balance.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from dataclasses import dataclass, fields
from typing import Any, Literal, Mapping

import numpy as np

from ..control.allocation import ThrustAllocator
from ..control.setpoint import FixedSetpoint, HeadingChasing, SetpointChasing
from ..control.setpoint_opt import METHODS, OptimalSetpoint, SetpointOptions
from ..errors import TapmError
from ..estimation import DEFAULT_ESTIMATOR
from ..estimation.current_profile import CURRENT_MODES, CurrentEstimating, CurrentProfileEstimator, CurrentResponseModel
from ..estimation.detection import TensionDropDetector, TensionResidualDetector
from ..estimation.lowpass import LowPassEstimator, TrueStateEstimator
from ..estimation.reliability import monitor_for
from ..geometry import body_from_turret
from ..interfaces import (AttitudeAware, Controller, ControllerStep, Estimate, Estimator, FaultAware, Logged, Setpoint,
                          SetpointLayer, ThrusterCommand, ThrusterController, WinchController)
from ..models.system import System
from ..plant.simulator import Plant
from ..results import Result, ResultBuilder

__all__ = ["ClosedLoopSettings", "SetpointChasing", "run_closed_loop", "default_setpoint_layer",
           "optimal_setpoint_layer", "SETPOINT_KINDS", "ClosedLoopError", "default_estimator", "ESTIMATOR_KINDS",
           "DEFAULT_ESTIMATOR", "DETECTOR_KINDS", "REDUNDANCY_KINDS", "WINCH_KINDS", "default_winch_controller",
           "combination_issues", "CURRENT_MODES", "current_estimator", "fem_static_tensions"]


class ClosedLoopError(TapmError, ValueError):
    """Bad closed-loop settings."""




@dataclass(frozen=True, kw_only=True)
class ClosedLoopSettings:
    """Rates and options of :func:`run_closed_loop`.

    Attributes
    ----------
    duration : float
        Simulated time [s].
    dt_control : float
        Period of sensing, estimation, allocation and plant stepping [s].
    controller_period : float or None
        Period of the motion controller [s] (None: the controller's own, else ``dt_control``).
    dt_log : float
        Logging period [s] (a multiple of ``dt_control``).
    true_state : bool
        Hand the controller the true LF state and the true mean environmental load instead of the
        low-pass estimate.
    setpoint : {"fixed", "chasing", "quadratic", "reliability", "unified", "fatigue"}
        Fixed setpoint ``eta_d``; setpoint chasing (survey eq. 38) with time constant
        ``chase_time`` projected into ``chase_margin`` times the safe radius; the optimum of the
        quadratic (eq. 34), reliability (eq. 36) or unified riser + mooring cost ([R] §2.2) of
        :class:`~tapm_opt.control.setpoint_opt.OptimalSetpoint`, started at ``eta_d``; or the
        fatigue-aware chasing (survey §4.2.4) of
        :class:`~tapm_opt.control.fatigue_setpoint.FatigueAwareSetpoint` (chasing with the same
        time constant and circle).
    setpoint_options : mapping or None
        Options of the optimal setpoints (:class:`~tapm_opt.control.setpoint_opt.SetpointOptions`)
        or of the fatigue-aware layer (:class:`~tapm_opt.control.fatigue_setpoint.FatigueOptions`).
    eta_d : (3,)
        Fixed setpoint — turret offset x [m], y [m] (the centre of turret relative to its
        field-zero-point position) and heading [rad] — or the heading of the chased setpoint.
    heading : {"fixed", "chasing"}
        Heading setpoint ``eta_d[2]``, or the weather-optimal heading: the bow pointed into the
        estimated mean environmental force in {E}, ``atan2(-b_y, -b_x)``, low-pass filtered with time
        constant ``heading_chase_time`` from ``eta_d[2]``. A turret-moored vessel then weathervanes
        slowly instead of spending thrust on a yaw moment against the weather.
    estimator : {"lowpass", "passive", "ekf"}
        The loop's estimator (:func:`default_estimator`; default :data:`DEFAULT_ESTIMATOR`, the
        EKF): the low-pass filters
        (:class:`~tapm_opt.estimation.lowpass.LowPassEstimator`), the nonlinear passive observer
        or the extended Kalman filter (:mod:`tapm_opt.estimation.observer`). Ignored with
        ``true_state`` (the plant's truth) and when the runner is given an estimator.
    detector : {"tension", "drop", "bank", "none"}
        Line-break detection of the default estimator: the statistical test of the measured
        tensions against the line model's at the estimated pose
        (:class:`~tapm_opt.estimation.detection.TensionResidualDetector`), the tension-drop
        threshold (:class:`~tapm_opt.estimation.detection.TensionDropDetector`), a bank of
        observers, one per hypothesis (intact, each line broken), that needs no tension cells
        (:class:`~tapm_opt.estimation.bank.ObserverBank`, of ``estimator``'s kind), or none.
    winch : {"none", "tension"}
        Line-tension control ([AF] = seed line-tension-control-fem, §III-IV): none (the lines keep
        their lengths), or the passivity-based tension controller
        (:class:`~tapm_opt.control.winch.WinchTensionController`): the winches drive the measured
        mooring force toward the DP command ``tau_cmd`` and the thrusters get
        ``tau_cmd - tau_m`` (the measured mooring load). Needs lines with winches and
        ``detector = "none"`` (the line-break detectors compare the tensions with the lines at
        their nominal lengths, which the winches change).
    winch_options : mapping or None
        Options of the tension controller (:class:`~tapm_opt.control.winch.WinchSettings`: ``kc``,
        ``ki``, ``T_max_fraction``, ``T_min_fraction``, ``geometry``).
    current : {"known", "estimated", "estimated_tensions"}
        The current the layers take: the sea state's profile ("known", as it is at t = 0), or the
        on-line estimate from the tension cells and riser inclinometers ("estimated"), or from the
        tension cells alone ("estimated_tensions", the seabed factor held at the nominal profile's)
        (:mod:`tapm_opt.estimation.current_profile`): the estimator is wrapped in a
        :class:`~tapm_opt.estimation.current_profile.CurrentEstimating` (its estimates in the
        estimator's log, ``"current estimate"`` events) and the optimal setpoints read its surface
        current in place of the sea state's.
    redundancy : {"none", "vote"}
        Sensor redundancy of the default estimator: none, or the tension cells as a second
        position reference with the voting that finds and excludes a failed GNSS, tension cell or
        gyro-compass (:class:`~tapm_opt.estimation.redundancy.SensorVoting`).
    """

    duration: float = 3600.0
    dt_control: float = 1.0
    controller_period: float | None = None
    dt_log: float = 1.0
    true_state: bool = False
    setpoint: Literal["fixed", "chasing", "quadratic", "reliability", "unified", "fatigue"] = "fixed"
    setpoint_options: Mapping[str, Any] | None = None
    heading: Literal["fixed", "chasing"] = "fixed"
    eta_d: tuple[float, float, float] = (0.0, 0.0, 0.0)
    chase_time: float = 300.0
    chase_margin: float = 0.8
    heading_chase_time: float = 600.0
    estimator: Literal["lowpass", "passive", "ekf"] = DEFAULT_ESTIMATOR
    detector: Literal["tension", "drop", "bank", "none"] = "tension"
    winch: Literal["none", "tension"] = "none"
    winch_options: Mapping[str, Any] | None = None
    current: Literal["known", "estimated", "estimated_tensions"] = "known"
    redundancy: Literal["none", "vote"] = "none"

    def __post_init__(self) -> None:
        for name in ("duration", "dt_control", "dt_log", "chase_time", "chase_margin", "heading_chase_time"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ClosedLoopError(f"{name} = {v!r} must be a positive number")
        if self.controller_period is not None and not (math.isfinite(self.controller_period) and self.controller_period > 0):
            raise ClosedLoopError(f"controller_period = {self.controller_period!r} must be a positive number or None")
        if self.setpoint not in SETPOINT_KINDS:
            raise ClosedLoopError(f"setpoint = {self.setpoint!r} is not one of {', '.join(map(repr, SETPOINT_KINDS))}")
        if self.heading not in ("fixed", "chasing"):
            raise ClosedLoopError(f"heading = {self.heading!r} is not one of 'fixed', 'chasing'")
        for name, kinds in (("estimator", ESTIMATOR_KINDS), ("detector", DETECTOR_KINDS),
                            ("redundancy", REDUNDANCY_KINDS)):
            if getattr(self, name) not in kinds:
                raise ClosedLoopError(f"{name} = {getattr(self, name)!r} is not one of {', '.join(map(repr, kinds))}")
        if self.current not in CURRENT_MODES:
            raise ClosedLoopError(f"current = {self.current!r} is not one of {', '.join(map(repr, CURRENT_MODES))}")
        if self.winch not in WINCH_KINDS:
            raise ClosedLoopError(f"winch = {self.winch!r} is not one of {', '.join(map(repr, WINCH_KINDS))}")
        issues = combination_issues(vars(self))
        if issues:
            raise ClosedLoopError(f"{issues[0][0]} {issues[0][1]}")
        if self.winch_options is not None:
            from ..control.winch import WinchError, WinchSettings

            try:
                WinchSettings.from_mapping(self.winch_options)
            except WinchError as exc:
                raise ClosedLoopError(str(exc)) from None
        if self.setpoint_options is not None:
            if not isinstance(self.setpoint_options, Mapping):
                raise ClosedLoopError(f"setpoint_options = {self.setpoint_options!r} must be a table of options")
            if self.setpoint_options and self.setpoint not in (*METHODS, "fatigue"):
                raise ClosedLoopError(f"setpoint_options are for the optimal setpoints ({', '.join(METHODS)}) "
                                      f"and 'fatigue', not setpoint = {self.setpoint!r}")
            if self.setpoint == "fatigue":
                from ..control.fatigue_setpoint import FatigueOptions

                FatigueOptions.from_mapping(self.setpoint_options)
            else:
                SetpointOptions.from_mapping(self.setpoint_options)
        ratio = self.dt_log / self.dt_control
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ClosedLoopError(f"dt_log = {self.dt_log:g} s must be a whole multiple of dt_control = {self.dt_control:g} s")


#: Every ``ClosedLoopSettings.setpoint``.
SETPOINT_KINDS = ("fixed", "chasing", *METHODS, "fatigue")
#: Every ``ClosedLoopSettings.estimator`` and ``.detector``.
ESTIMATOR_KINDS = ("lowpass", "passive", "ekf")
DETECTOR_KINDS = ("tension", "drop", "bank", "none")
#: Every ``ClosedLoopSettings.redundancy``.
REDUNDANCY_KINDS = ("none", "vote")
#: Every ``ClosedLoopSettings.winch``.
WINCH_KINDS = ("none", "tension")


def combination_issues(settings: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The settings that do not go together, as ``(field, message)`` (the message follows the
    field name: ``"detector = 'bank' needs ..."``): the one statement of these rules, for
    :class:`ClosedLoopSettings` and for study files (``settings`` may name only some fields; the
    others take the defaults)."""
    g = {f.name: f.default for f in fields(ClosedLoopSettings)}
    g.update({k: v for k, v in settings.items() if k in g and v is not None})
    out = []
    if g["detector"] == "bank" and g["true_state"]:
        out.append(("detector", "= 'bank' needs the observers' estimates; with true_state the plant's truth "
                                "replaces them: give detector = 'tension', 'drop' or 'none'"))
    elif g["detector"] == "bank" and g["estimator"] == "lowpass":
        out.append(("detector", "= 'bank' is a bank of model-based observers: give estimator = 'passive' or "
                                "'ekf', not 'lowpass'"))
    if g["winch"] == "tension" and g["detector"] != "none":
        out.append(("winch", f"= 'tension' with detector = {g['detector']!r}: the line-break detectors compare "
                             "the tensions with the lines at their nominal lengths, which the winches change; give "
                             "detector = 'none'"))
    if g["redundancy"] == "vote" and g["true_state"]:
        out.append(("redundancy", "= 'vote' screens the sensors for the estimator; with true_state the plant's truth "
                                  "replaces them: give redundancy = 'none'"))
    if g["winch_options"] and g["winch"] != "tension":
        out.append(("winch_options", f"are for winch = 'tension', not winch = {g['winch']!r}"))
    if g["current"] != "known" and g["winch"] == "tension":
        out.append(("current", f"= {g['current']!r} reads the drag share of the tensions of the lines at their nominal "
                               "lengths, which the winches change; give winch = 'none'"))
    return out


def fem_static_tensions(scenario: Any, segments: int | None = 10) -> Any:
    """``settle(eta, current) -> (M,)``: the fairlead tensions [N] of ``scenario``'s lines as the
    plant's FEM (``segments`` per line) settled by dynamic relaxation with the vessel held at ``eta``
    under ``current`` (node depths [m] -> velocities (n, 3) in {E} [m/s]; None: still water): the
    line model with current drag of :class:`~tapm_opt.estimation.current_profile.CurrentResponseModel`
    and of :func:`tapm_opt.studies.anchor_network.current_tension_share`."""
    from ..plant.mooring_fem import MooringFEM

    def settle(eta: Any, current: Any) -> np.ndarray:
        eta = np.asarray(eta, dtype=float)
        fem = MooringFEM(scenario, segments=segments, current=current)
        fem.initialise(eta)
        fem.settle(eta, max_time=3000.0)
        return np.asarray(fem.fairlead_tension(), dtype=float).copy()

    return settle


def current_estimator(system: System, sea_state: Any, eta_ref: Any = (0.0, 0.0, 0.0), *,
                      use_riser: bool = True) -> CurrentProfileEstimator:
    """The on-line current-profile estimator of ``system`` (:mod:`tapm_opt.estimation.current_profile`):
    the response model of its lines (and riser, read when ``use_riser``) with ``sea_state``'s
    profile shape settled at ``eta_ref`` (body origin, {E}), the tension-cell and inclinometer
    noise of its sensors."""
    sc = system.scenario
    model = CurrentResponseModel(sc, fem_static_tensions(sc), sea_state, eta_ref=eta_ref)
    sens = sc.sensors
    return CurrentProfileEstimator(model,
                                   tension_noise=float(sens.tension_std_rel) * np.asarray(system.lines.MBS, float),
                                   angle_noise=float(sens.riser_angle_std), use_riser=use_riser)


def default_estimator(system: System, settings: ClosedLoopSettings, sea_state: Any = None) -> Estimator:
    """The estimator a :class:`ClosedLoopSettings` describes: ``settings.estimator`` on
    ``system.lines`` (the plant's truth with ``true_state``), with ``settings.detector``'s
    line-break detection and the reliability monitor of the measured tensions and riser angles
    (:func:`~tapm_opt.estimation.reliability.monitor_for`), inside the sensor voting with
    ``redundancy = "vote"``. ``sea_state`` gives the observers' wave-frequency model its peak
    period (None: the observers' default)."""
    est = _default_estimator(system, settings, sea_state)
    if settings.redundancy == "vote" and not settings.true_state:
        from ..estimation.redundancy import SensorVoting

        return SensorVoting(system, est)
    return est


def _default_estimator(system: System, settings: ClosedLoopSettings, sea_state: Any = None) -> Estimator:
    s = settings
    mon = monitor_for(system.scenario)
    det: Any = None
    if s.detector == "drop":
        det = TensionDropDetector(system.lines)
    elif s.detector == "tension":   # at the cells' rate, with their noise as the floor of the scale
        sens = system.scenario.sensors
        noise = {"noise_rel": float(sens.tension_std_rel)} if sens.tension_std_rel > 0 else {}
        det = TensionResidualDetector(system.lines, rate=float(sens.tension_rate), **noise)
    if s.true_state:
        return TrueStateEstimator(detector=det, monitor=mon)
    if s.detector == "bank":
        from ..estimation.bank import ObserverBank

        return ObserverBank.from_scenario(system, sea_state=sea_state, kind=s.estimator, monitor=mon)
    if s.estimator == "lowpass":
        return LowPassEstimator(system.lines, detector=det, monitor=mon)
    from ..estimation.observer import EKFObserver, PassiveObserver

    cls = PassiveObserver if s.estimator == "passive" else EKFObserver
    return cls.from_scenario(system, sea_state=sea_state, detector=det, monitor=mon)


def default_winch_controller(system: System, settings: ClosedLoopSettings) -> Any:
    """The winch controller a :class:`ClosedLoopSettings` describes: None for ``winch = "none"``,
    else the tension controller of ``winch_options`` on ``system``
    (:class:`~tapm_opt.control.winch.WinchTensionController`)."""
    if settings.winch == "none":
        return None
    from ..control.winch import WinchError, WinchTensionController

    try:
        return WinchTensionController(system, settings.winch_options)
    except WinchError as exc:
        raise ClosedLoopError(str(exc)) from None


def optimal_setpoint_layer(system: System, method: str, sea_state: Any = None, *,
                           options: Mapping[str, Any] | None = None, eta_d: Any = (0.0, 0.0, 0.0),
                           current_source: Any = None) -> OptimalSetpoint:
    """An :class:`~tapm_opt.control.setpoint_opt.OptimalSetpoint` of ``method`` on ``system``, with
    the scenario's riser under ``sea_state``'s current (the wave-frequency statistics come with the
    estimate, from the estimator's reliability monitor); ``current_source`` an estimated surface
    current read in its place (``ClosedLoopSettings.current = "estimated"``)."""
    riser = system.riser(sea_state)
    return OptimalSetpoint(system, method, riser=riser, options=options, eta_d=eta_d, current_source=current_source)


def _sea_state(system: System, sea_state_id: Any) -> Any:
    """The plant's sea state (by its id in the metadata) from the system's scenario, or None."""
    if sea_state_id is None:
        return None
    try:
        return system.scenario.sea_state(sea_state_id)
    except (KeyError, ValueError, TapmError):
        return None


def default_setpoint_layer(system: System, settings: ClosedLoopSettings, sea_state: Any = None, *,
                           current_source: Any = None) -> Any:
    """The setpoint layer a :class:`ClosedLoopSettings` describes (fixed, chasing, optimal or
    fatigue-aware, with the heading fixed or chased). ``sea_state`` gives the current the riser model of the optimal
    setpoints sees (None: still water); ``current_source`` an estimated one read in its place."""
    s = settings
    R = system.limits.safe_radius
    if s.setpoint in METHODS:
        layer: Any = optimal_setpoint_layer(system, s.setpoint, sea_state, options=s.setpoint_options,
                                            eta_d=s.eta_d, current_source=current_source)
    elif s.setpoint == "fatigue":
        from ..control.fatigue_setpoint import FatigueAwareSetpoint
        from ..models.fatigue import line_curves

        layer = FatigueAwareSetpoint(system.lines, line_curves(system.scenario), system.thrusters.max_tau(),
                                     s.chase_time, None if R is None else s.chase_margin * R, s.eta_d[2],
                                     p_cot_B=system.p_cot_B, options=s.setpoint_options)
    elif s.setpoint == "chasing":
        layer = SetpointChasing(s.chase_time, None if R is None else s.chase_margin * R, s.eta_d[2],
                                     p_cot_B=system.p_cot_B)
    else:
        layer = FixedSetpoint(s.eta_d)
    if s.heading == "chasing":
        layer = HeadingChasing(layer, s.heading_chase_time, s.eta_d[2])
    return layer


def run_closed_loop(plant: Plant, controller: Controller, settings: ClosedLoopSettings = ClosedLoopSettings(), *,
                    system: System | None = None, estimator: Estimator | None = None,
                    setpoint_layer: SetpointLayer | None = None, allocator: ThrustAllocator | None = None,
                    winch: WinchController | None = None, meta: dict | None = None) -> Result:
    """Run ``controller`` against ``plant`` and return the labelled result.

    The runner owns time, rates and logging and talks to the components only through the
    protocols of :mod:`tapm_opt.interfaces` and the plant only through ``measure()`` / ``step()``.

    Parameters
    ----------
    plant : Plant
    controller : Controller
        ``update(t, estimate, setpoint) -> tau_cmd``, ``period``, ``reset()``, ``last_step()``;
        a :class:`~tapm_opt.interfaces.ThrusterController` is applied without allocation.
    settings : ClosedLoopSettings
    system : System, optional
        The system the control side is designed on (default: the plant's ``system``, the one it was
        built from).
    estimator : Estimator, optional
        Default: :func:`default_estimator` of the settings (the low-pass estimator on
        ``system.lines`` with the statistical tension test for line breaks and the reliability
        monitor, unless the settings choose otherwise).
    setpoint_layer : SetpointLayer, optional
        Default: :func:`default_setpoint_layer` of the settings.
    allocator : ThrustAllocator, optional
        Default: built from the system's thrusters.
    winch : WinchController, optional
        Line-tension controller, called every control period after the motion controller with its
        ``tau_cmd``; its speeds go to ``plant.step`` and the thrusters are allocated
        ``tau_cmd - winch.mooring_load()`` ([AF] §III). Default: :func:`default_winch_controller`
        of the settings (none unless ``winch = "tension"``). Adds the channels
        ``tau_moor_hat[X|Y|N]`` (the measured mooring load, {B}) and ``u_winch[<line>]`` [m/s].
    """
    s = settings
    for name, obj, proto in (("controller", controller, Controller), ("estimator", estimator, Estimator),
                             ("setpoint_layer", setpoint_layer, SetpointLayer), ("winch", winch, WinchController)):
        if obj is not None and not isinstance(obj, proto):
            need = {"controller": "period, update(t, estimate, setpoint), reset() and last_step()",
                    "estimator": "update(t, measurement) and reset()",
                    "setpoint_layer": "update(t, estimate) and reset()",
                    "winch": "update(t, estimate, tau_cmd), mooring_load() and reset()"}[name]
            raise ClosedLoopError(f"{name} {type(obj).__name__} is not a {proto.__name__}: it needs {need}")
    system = system or plant.system
    alloc = allocator or ThrustAllocator(system.thrusters.specs, dt=s.dt_control)
    owns = isinstance(controller, ThrusterController) and bool(controller.owns_allocation)
    period = s.controller_period or controller.period or s.dt_control
    period = max(period, s.dt_control)
    sea_state = _sea_state(system, plant.metadata().get("sea_state"))
    chosen = {} if estimator is not None else {"estimator_kind": s.estimator, "detector": s.detector,
                                               **({"redundancy": s.redundancy} if s.redundancy != "none" else {})}
    estimator = estimator or default_estimator(system, s, sea_state)
    source = None
    if s.current != "known":
        psi0 = float(s.eta_d[2])
        eta_ref = (*body_from_turret(s.eta_d[:2], psi0, system.p_cot_B), psi0)
        estimator = CurrentEstimating(estimator, current_estimator(system, sea_state, eta_ref,
                                                                   use_riser=s.current == "estimated"))
        source = estimator.surface_current
    layer = setpoint_layer or default_setpoint_layer(system, s, sea_state, current_source=source)
    winch = winch if winch is not None else default_winch_controller(system, s)
    extra = [("tau_cmd[X]", "N"), ("tau_cmd[Y]", "N"), ("tau_cmd[N]", "N m"),
             ("x_d", "m"), ("y_d", "m"), ("psi_d", "rad"),
             ("x_hat", "m"), ("y_hat", "m"), ("psi_hat", "rad"),
             ("tau_env_hat[X]", "N"), ("tau_env_hat[Y]", "N"), ("tau_env_hat[N]", "N m"),
             ("alloc_fallback", "-"), ("alloc_slack", "-")]
    line_ids = tuple(ln.id for ln in system.scenario.lines)
    if winch is not None:
        extra += [("tau_moor_hat[X]", "N"), ("tau_moor_hat[Y]", "N"), ("tau_moor_hat[N]", "N m")]
        extra += [(f"u_winch[{i}]", "m/s") for i in line_ids]
    u_winch = np.zeros(len(line_ids))
    tau_m_hat = np.zeros(3)
    plant_channels = plant.channels()
    n_plant = len(plant_channels)
    rb = ResultBuilder(plant_channels + extra, capacity=int(s.duration / s.dt_log) + 2)
    n_steps = int(round(s.duration / s.dt_control))
    log_every = int(round(s.dt_log / s.dt_control))
    tau_cmd = np.zeros(3)
    next_ctrl = 0.0
    ids = system.thrusters.ids
    failed_known: frozenset[str] = frozenset()
    alloc_fallbacks = 0
    alloc_times: list[float] = []
    ctrl_times: list[float] = []
    steps: list[ControllerStep] = []
    t_wall0 = time.perf_counter()
    last = {"fallback": 0.0, "slack": 0.0}
    sp = Setpoint(eta_d=np.asarray(s.eta_d, float))
    est: Estimate | None = None

    attitude_aware = isinstance(controller, AttitudeAware)
    for step in range(n_steps + 1):
        m = plant.measure(truth=s.true_state)
        t = m.t
        # thruster feedback: failures reach the allocation and fault-aware controllers
        if m.thruster_failed is not None:
            failed = frozenset(tid for tid, f in zip(ids, m.thruster_failed) if f)
            if failed != failed_known:
                for tid in failed - failed_known:
                    alloc.set_failed(tid)
                if isinstance(controller, FaultAware):
                    controller.set_failed_thrusters(failed)
                failed_known = failed
        if attitude_aware and m.attitude is not None:   # the MRU reaches a controller that reads it
            controller.set_attitude(t, m.attitude)
        est = estimator.update(t, m)
        if step % log_every == 0:   # the row written in place: plant, then the runner's channels
            row = rb.next_row(t)
            row[:n_plant] = plant.sample_row()
            row[n_plant:n_plant + 3] = tau_cmd
            row[n_plant + 3:n_plant + 6] = sp.eta_d
            row[n_plant + 6:n_plant + 9] = est.eta
            row[n_plant + 9:n_plant + 12] = est.tau_env
            row[n_plant + 12] = last["fallback"]
            row[n_plant + 13] = last["slack"]
            if winch is not None:
                row[n_plant + 14:n_plant + 17] = tau_m_hat
                row[n_plant + 17:] = u_winch
        if step == n_steps:
            break
        sp = layer.update(t, est)
        # controller at its own period
        if t >= next_ctrl - 1e-9:
            w0 = time.perf_counter()
            tau_cmd = np.asarray(controller.update(t, est, sp), float)
            ctrl_times.append(time.perf_counter() - w0)
            info = controller.last_step()
            if info is not None:
                steps.append(info)
            next_ctrl += period
        # winches ([AF] §III): the mooring is driven toward tau_cmd, the thrusters get the rest
        tau_thr_cmd = tau_cmd
        if winch is not None:
            u_winch = np.asarray(winch.update(t, est, tau_cmd), float)
            tau_m_hat = np.asarray(winch.mooring_load(), float)
            tau_thr_cmd = tau_cmd - tau_m_hat
        # allocation
        if owns:
            cmd = controller.thruster_command()
            last["fallback"], last["slack"] = 0.0, 0.0
        else:
            w0 = time.perf_counter()
            ar = alloc.allocate(tau_thr_cmd)
            alloc_times.append(time.perf_counter() - w0)
            alloc_fallbacks += int(ar.fallback)
            last["fallback"] = float(ar.fallback)
            last["slack"] = float(_norm(ar.slack) / max(_norm(tau_thr_cmd), 1.0))
            cmd = ThrusterCommand(f=np.asarray(ar.f, float), alpha=np.asarray(ar.alpha, float))
        plant.step(s.dt_control, cmd, u_winch if winch is not None else None)
    wall = time.perf_counter() - t_wall0
    diag = _diagnostics(steps, ctrl_times, alloc_times, alloc_fallbacks)
    md = {**plant.metadata(), "controller": type(controller).__name__, "controller_period": period,
          "dt_control": s.dt_control, "true_state": s.true_state, "setpoint": s.setpoint,
          "setpoint_options": dict(s.setpoint_options or {}), "heading": s.heading,
          **({"current": s.current} if s.current != "known" else {}),
          "estimator": type(estimator).__name__, **chosen, "setpoint_layer": type(layer).__name__,
          **({"winch": s.winch, "winch_options": dict(s.winch_options or {}),
              "winch_controller": type(winch).__name__} if winch is not None else {}),
          "turret_position_B": [float(v) for v in system.p_cot_B],
          "wall_time": wall, "diagnostics": diag, **(meta or {})}
    for role, comp in (("setpoint", layer), ("controller", controller), ("estimator", estimator)):
        if isinstance(comp, Logged):   # an empty log says "nothing happened", so it is kept too
            md[f"{role}_log"] = list(comp.log())
    return rb.build(md)


def _norm(v: Any) -> float:
    """``np.linalg.norm`` of a vector: ``sqrt(v . v)``, as numpy computes it (the same number)."""
    v = np.asarray(v)
    if v.ndim == 1 and v.dtype == np.float64:
        return math.sqrt(float(v.dot(v)))
    return float(np.linalg.norm(v))


def _diagnostics(steps: list[ControllerStep], ctrl_times: list, alloc_times: list, alloc_fallbacks: int) -> dict:
    out: dict = {"controller_calls": len(ctrl_times),
                 "controller_time_median": float(np.median(ctrl_times)) if ctrl_times else 0.0,
                 "controller_time_max": float(np.max(ctrl_times)) if ctrl_times else 0.0,
                 "allocation_calls": len(alloc_times),
                 "allocation_time_median": float(np.median(alloc_times)) if alloc_times else 0.0,
                 "allocation_fallbacks": alloc_fallbacks}
    if steps:
        active = Counter(name for d in steps for name in d.active)
        out["active_constraints"] = dict(sorted(active.items()))
        out["controller_failures"] = int(sum(not d.success for d in steps))
        out["controller_fallbacks"] = int(sum(d.fallback for d in steps))
    solved = [d for d in steps if d.solve_time is not None]
    if solved:
        st = [d.solve_time for d in solved]
        out.update({
            "solver_time_median": float(np.median(st)), "solver_time_p95": float(np.percentile(st, 95)),
            "solver_time_max": float(np.max(st)),
            "solver_failures": int(sum(not d.success for d in solved)),
            "solver_fallbacks": int(sum(d.fallback for d in solved)),
            "solver_iterations_median": float(np.median([d.iterations for d in solved])),
            "statuses": sorted({d.status for d in solved}),
        })
    return out
