"""Controllers and their layers: the TAPM PID modes, linear and nonlinear MPC, QP thrust
allocation, setpoint layers, the sea-state supervisor, gain scheduling and winch (line-tension)
control. A controller from a specification, as ``tapm simulate`` builds it, comes from the
controller-kind registry (:mod:`tapm_opt.design.registry`)::

    from tapm_opt.design import build
    ctrl = build(system, "lmpc")
"""

from __future__ import annotations

from .._lazy import lazy_exports

#: Each public name and the module that defines it (imported on first use, so importing the
#: package stays cheap and free of cycles).
_EXPORTS = {
    "TAPMPID": ".pid",
    "MODE_SETS": ".pid",
    "design_from_scenario": ".pid_design",
    "design_gains": ".pid_design",
    "LinearMPC": ".mpc",
    "NonlinearMPC": ".mpc",
    "MPCSettings": ".mpc_problem",
    "ThrustAllocator": ".allocation",
    "FixedSetpoint": ".setpoint",
    "HeadingChasing": ".setpoint",
    "SetpointChasing": ".setpoint",
    "OptimalSetpoint": ".setpoint_opt",
    "SetpointOptions": ".setpoint_opt",
    "SeaStateSupervisor": ".supervisor",
    "GainScheduledPID": ".scheduled",
    "WinchTensionController": ".winch",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
