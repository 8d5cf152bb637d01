"""Design: the controller-kind registry (:func:`build` makes the controller ``tapm simulate``
runs, with its tuned defaults and search space), the supervised PID, capability envelopes, PID and LQR gain tables per sea state and mooring
condition, and the static optimal setpoints.

    from tapm_opt.design import capability, gain_table
"""

from __future__ import annotations

from .._lazy import lazy_exports

#: Each public name and the module that defines it (imported on first use, so importing the
#: package stays cheap and free of cycles).
_EXPORTS = {
    "build": ".registry",
    "kinds": ".registry",
    "kind": ".registry",
    "register": ".registry",
    "ControllerKind": ".registry",
    "ControllerSpecError": ".registry",
    "Dimension": ".registry",
    "BuildContext": ".registry",
    "supervised_pid": ".supervisor",
    "sea_state_supervisor": ".supervisor",
    "capability": ".capability",
    "CapabilityOptions": ".capability",
    "CapabilityResult": ".capability",
    "gain_table": ".tables",
    "weathervane_heading": ".tables",
    "sea_state_class": ".tables",
    "LQRWeights": ".tables",
    "static_setpoint": ".setpoint",
    "reliability_map": ".setpoint",
    "StaticSetpoint": ".setpoint",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
