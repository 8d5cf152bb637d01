"""Closed loop: plant -> sensors -> estimate -> setpoint -> controller -> allocation -> thrusters.

The runner owns time and rates. Every control period ``dt_control`` it reads the sensors, updates
the estimate (a low-pass filter of the measurements, or the true LF state when ``true_state=True``),
the setpoint (fixed, or chased by the low-pass filter of survey eq. 38 and projected into the safe
circle), asks the controller for a generalised thrust at the controller's own period (held in
between), allocates it to the thrusters (unless the controller optimises thruster forces itself)
and steps the plant. Controller diagnostics (solve times, statuses, active constraints, fallbacks)
go into the result.

Faults: a thruster failure is reported to the allocator (and an MPC that allocates) at once; a line
break is not reported to the controller (no line-break detection yet) — the estimator's
environmental-load estimate absorbs the lost line force.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..control.allocation import ThrustAllocator
from ..control.estimate import Estimate, Setpoint
from ..errors import TapmError
from ..estimation.lowpass import LowPassEstimator
from ..geometry import rot_z
from ..models.mooring import MooringModel
from ..plant.simulator import Plant, ThrusterCommand
from ..results import Result, ResultBuilder

__all__ = ["ClosedLoopSettings", "SetpointChasing", "run_closed_loop", "ClosedLoopError"]


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
    setpoint : {"fixed", "chasing"}
        Fixed setpoint ``eta_d``, or setpoint chasing (survey eq. 38) with time constant
        ``chase_time`` projected into ``chase_margin`` times the safe radius.
    eta_d : (3,)
        Fixed setpoint, or the heading of the chased setpoint [m, m, rad].
    heading : {"fixed", "chasing"}
        Heading setpoint ``eta_d[2]``, or the weather-optimal heading: the bow pointed into the
        estimated mean environmental force in {E}, ``atan2(-b_y, -b_x)``, low-pass filtered with time
        constant ``heading_chase_time`` from ``eta_d[2]``. A turret-moored vessel then weathervanes
        slowly instead of spending thrust on a yaw moment against the weather.
    """

    duration: float = 3600.0
    dt_control: float = 1.0
    controller_period: float | None = None
    dt_log: float = 1.0
    true_state: bool = False
    setpoint: Literal["fixed", "chasing"] = "fixed"
    heading: Literal["fixed", "chasing"] = "fixed"
    eta_d: tuple[float, float, float] = (0.0, 0.0, 0.0)
    chase_time: float = 300.0
    chase_margin: float = 0.8
    heading_chase_time: float = 600.0

    def __post_init__(self) -> None:
        for name in ("duration", "dt_control", "dt_log", "chase_time", "chase_margin", "heading_chase_time"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ClosedLoopError(f"{name} = {v!r} must be a positive number")
        if self.controller_period is not None and not (math.isfinite(self.controller_period) and self.controller_period > 0):
            raise ClosedLoopError(f"controller_period = {self.controller_period!r} must be a positive number or None")
        for name in ("setpoint", "heading"):
            if getattr(self, name) not in ("fixed", "chasing"):
                raise ClosedLoopError(f"{name} = {getattr(self, name)!r} is not one of 'fixed', 'chasing'")
        ratio = self.dt_log / self.dt_control
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ClosedLoopError(f"dt_log = {self.dt_log:g} s must be a whole multiple of dt_control = {self.dt_control:g} s")


class SetpointChasing:
    """Low-pass setpoint chasing (survey eq. 38): ``p_sp' = -(p_sp - p) / T``, projected into the
    circle of radius ``R`` about the field zero point (``Pr_Safe``, Table 2)."""

    def __init__(self, T: float, R: float | None, psi_d: float):
        self.T, self.R, self.psi_d = T, R, psi_d
        self.p: np.ndarray | None = None

    def update(self, dt: float, p: np.ndarray) -> np.ndarray:
        if self.p is None:
            self.p = np.array(p[:2], float)
        else:
            a = math.exp(-dt / self.T)
            self.p = a * self.p + (1 - a) * np.asarray(p[:2], float)
        if self.R is not None:
            r = float(np.hypot(*self.p))
            if r > self.R:
                self.p = self.p * (self.R / r)
        return np.array([self.p[0], self.p[1], self.psi_d])


def run_closed_loop(plant: Plant, controller: Any, settings: ClosedLoopSettings = ClosedLoopSettings(), *,
                    allocator: ThrustAllocator | None = None, meta: dict | None = None) -> Result:
    """Run ``controller`` against ``plant`` and return the labelled result.

    Parameters
    ----------
    plant : Plant
    controller : object with ``update(t, estimate, setpoint) -> tau`` (and optionally ``period``,
        ``owns_allocation``, ``thruster_command(u)``, ``diagnostics``)
    settings : ClosedLoopSettings
    allocator : ThrustAllocator, optional
        Default: built from the plant's scenario.
    """
    s = settings
    sc = plant.scenario
    alloc = allocator or ThrustAllocator.from_scenario(sc, dt=s.dt_control)
    owns = bool(getattr(controller, "owns_allocation", False))
    period = s.controller_period or getattr(controller, "period", None) or s.dt_control
    period = max(period, s.dt_control)
    est = LowPassEstimator(MooringModel.from_scenario(sc))
    chase = SetpointChasing(s.chase_time, None if sc.limits.safe_radius is None else s.chase_margin * sc.limits.safe_radius,
                            s.eta_d[2]) if s.setpoint == "chasing" else None
    extra = [("tau_cmd[X]", "N"), ("tau_cmd[Y]", "N"), ("tau_cmd[N]", "N m"),
             ("x_d", "m"), ("y_d", "m"), ("psi_d", "rad"),
             ("x_hat", "m"), ("y_hat", "m"), ("psi_hat", "rad"),
             ("tau_env_hat[X]", "N"), ("tau_env_hat[Y]", "N"), ("tau_env_hat[N]", "N m"),
             ("alloc_fallback", "-"), ("alloc_slack", "-")]
    rb = ResultBuilder(plant.channels() + extra, capacity=int(s.duration / s.dt_log) + 2)
    n_steps = int(round(s.duration / s.dt_control))
    log_every = int(round(s.dt_log / s.dt_control))
    tau_cmd = np.zeros(3)
    tau_applied = np.zeros(3)
    next_ctrl = 0.0
    eta_d = np.asarray(s.eta_d, float)
    failed_known: set[str] = set()
    alloc_fallbacks = 0
    alloc_times = []
    ctrl_times = []
    t_wall0 = time.perf_counter()
    last = {"fallback": 0.0, "slack": 0.0}
    sp_eta = eta_d
    psi_sp = float(eta_d[2])

    def log():
        row = np.concatenate([plant.sample_row(), tau_cmd, sp_eta, est_vals[0], est_vals[2],
                              [last["fallback"], last["slack"]]])
        rb.append(plant.t, row)

    est_vals = (plant.eta.copy(), plant.nu.copy(), np.zeros(3))
    for step in range(n_steps + 1):
        t = plant.t
        # faults known to the control system: thruster failures
        for i, tid in enumerate(plant.thrusters.ids):
            if plant.thrusters.failed[i] and tid not in failed_known:
                failed_known.add(tid)
                alloc.set_failed(tid)
        # sensing and estimation
        m = plant.measure()
        if s.true_state:
            loads = plant.loads
            tau_env_true = loads["tau_wind"] + loads["tau_drift"]
            est_vals = (plant.eta.copy(), plant.nu.copy(), tau_env_true)
        else:
            est_vals = est.update(t, m.position, m.heading, tau_applied)
        if step % log_every == 0:
            log()
        if step == n_steps:
            break
        # setpoint
        sp_eta = chase.update(s.dt_control, est_vals[0]) if chase is not None else eta_d.copy()
        if s.heading == "chasing":
            # weather-optimal heading: bow into the estimated mean environmental force in {E}
            b_E = rot_z(est_vals[0][2]) @ np.asarray(est_vals[2], float)
            if math.hypot(b_E[0], b_E[1]) > 1e3:
                target = math.atan2(-b_E[1], -b_E[0])
                a = math.exp(-s.dt_control / s.heading_chase_time)
                psi_sp = psi_sp + (1 - a) * ((target - psi_sp + math.pi) % (2 * math.pi) - math.pi)
            sp_eta = np.array([sp_eta[0], sp_eta[1], psi_sp])
        # controller at its own period
        if t >= next_ctrl - 1e-9:
            e = Estimate(t=t, eta=est_vals[0], nu=est_vals[1], tau_env=est_vals[2], tensions=m.tensions)
            w0 = time.perf_counter()
            tau_cmd = np.asarray(controller.update(t, e, Setpoint(eta_d=sp_eta)), float)
            ctrl_times.append(time.perf_counter() - w0)
            next_ctrl += period
        # allocation
        if owns:
            f, alpha = controller.last_thruster_command()
            cmd = ThrusterCommand(f=f, alpha=alpha)
            last["fallback"], last["slack"] = 0.0, 0.0
        else:
            w0 = time.perf_counter()
            ar = alloc.allocate(tau_cmd)
            alloc_times.append(time.perf_counter() - w0)
            alloc_fallbacks += int(ar.fallback)
            last["fallback"] = float(ar.fallback)
            last["slack"] = float(np.linalg.norm(ar.slack) / max(np.linalg.norm(tau_cmd), 1.0))
            cmd = ThrusterCommand(f=np.asarray(ar.f, float), alpha=np.asarray(ar.alpha, float))
        tau_applied = plant.thrusters.tau()
        plant.step(s.dt_control, cmd)
    wall = time.perf_counter() - t_wall0
    diag = _diagnostics(controller, ctrl_times, alloc_times, alloc_fallbacks)
    md = {**plant.metadata(), "controller": type(controller).__name__, "controller_period": period,
          "dt_control": s.dt_control, "true_state": s.true_state, "setpoint": s.setpoint, "heading": s.heading,
          "wall_time": wall, "diagnostics": diag, **(meta or {})}
    return rb.build(md)


def _diagnostics(controller: Any, ctrl_times: list, alloc_times: list, alloc_fallbacks: int) -> dict:
    out: dict = {"controller_calls": len(ctrl_times),
                 "controller_time_median": float(np.median(ctrl_times)) if ctrl_times else 0.0,
                 "controller_time_max": float(np.max(ctrl_times)) if ctrl_times else 0.0,
                 "allocation_calls": len(alloc_times),
                 "allocation_time_median": float(np.median(alloc_times)) if alloc_times else 0.0,
                 "allocation_fallbacks": alloc_fallbacks}
    steps = getattr(controller, "diagnostics", None)
    if steps:
        st = [d.solve_time for d in steps]
        out.update({
            "solver_time_median": float(np.median(st)), "solver_time_p95": float(np.percentile(st, 95)),
            "solver_time_max": float(np.max(st)),
            "solver_failures": int(sum(not d.success for d in steps)),
            "solver_fallbacks": int(sum(d.fallback for d in steps)),
            "solver_iterations_median": float(np.median([d.iterations for d in steps])),
            "active_constraints": {k: int(sum(k in d.active for d in steps))
                                   for k in ("safe_circle", "tension", "dead_band", "thrust_capacity")},
            "statuses": sorted({d.status for d in steps}),
        })
    return out
