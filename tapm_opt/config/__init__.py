"""Scenario files: schema, loading, validation and the built-in scenarios."""

from .loader import (
    BUILTIN_DIR,
    builtin_scenarios,
    load_scenario,
    scenario_from_dict,
    scenario_to_dict,
    validate,
)
from .schema import (
    Environment,
    Fault,
    Limits,
    Line,
    LineType,
    Meta,
    PlantSettings,
    Riser,
    Scenario,
    SeaState,
    Sensors,
    Thruster,
    Turret,
    Vessel,
)

__all__ = [
    "BUILTIN_DIR",
    "builtin_scenarios",
    "load_scenario",
    "scenario_from_dict",
    "scenario_to_dict",
    "validate",
    "Environment",
    "Fault",
    "Limits",
    "Line",
    "LineType",
    "Meta",
    "PlantSettings",
    "Riser",
    "Scenario",
    "SeaState",
    "Sensors",
    "Thruster",
    "Turret",
    "Vessel",
]
