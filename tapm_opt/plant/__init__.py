"""The FEM plant, the truth controllers are validated against: the vessel with its
wave-frequency motion, the lumped-mass mooring lines, thrusters, sensors and faults; and
forced-motion analysis.

    from tapm_opt.plant import Plant, run_open_loop
"""

from __future__ import annotations

from .._lazy import lazy_exports

#: Each public name and the module that defines it (imported on first use, so importing the
#: package stays cheap and free of cycles).
_EXPORTS = {
    "Plant": ".simulator",
    "ThrusterCommand": ".simulator",
    "run_open_loop": ".simulator",
    "PlantError": ".simulator",
    "SimulationDiverged": ".simulator",
    "section_channel": ".simulator",
    "forced_motion": ".forced_motion",
    "identify_mooring_damping": ".forced_motion",
    "ForcedMotionResult": ".forced_motion",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
