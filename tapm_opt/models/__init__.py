"""Control-design models: vessel (CasADi), elastic catenary, mooring restoring model."""

from . import catenary
from .catenary import CatenarySolution
from .characteristics import line_characteristics, offset_curves
from .mooring import LinearMooring, MooringModel
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
    "LinearMooring",
    "MooringModel",
    "VesselParams",
    "coriolis",
    "equilibrium",
    "linearise",
    "moored_function",
    "vessel_function",
    "vessel_rhs",
]
