"""Control-design models: vessel (CasADi), elastic catenary, mooring restoring model, current
profile, quasi-static riser."""

from . import catenary
from .catenary import CatenarySolution
from .characteristics import line_characteristics, offset_curves
from .environment import CurrentProfile, HullWindLoad
from .mooring import LinearMooring, MooringModel
from .riser import RiserModel
from .statics import EquilibriumError
from .system import System, ThrusterSet
from .vessel import (
    VesselParams,
    coriolis,
    equilibrium,
    linearise,
    moored_function,
    vessel_function,
    vessel_rhs,
)

__all__ = [
    "catenary",
    "CatenarySolution",
    "line_characteristics",
    "offset_curves",
    "CurrentProfile",
    "HullWindLoad",
    "EquilibriumError",
    "System",
    "ThrusterSet",
    "LinearMooring",
    "MooringModel",
    "RiserModel",
    "VesselParams",
    "coriolis",
    "equilibrium",
    "linearise",
    "moored_function",
    "vessel_function",
    "vessel_rhs",
]
