"""tapm_opt — optimisation-based control design workbench for thruster-assisted position mooring.

Public entry points::

    import tapm_opt
    sc = tapm_opt.load_scenario("fpso")          # built-in name or a TOML path
"""

from .config import Scenario, load_scenario, scenario_from_dict
from .errors import CatenaryError, ModelError, ScenarioError, TapmError

__version__ = "0.2.0"

__all__ = [
    "Scenario",
    "load_scenario",
    "scenario_from_dict",
    "CatenaryError",
    "ModelError",
    "ScenarioError",
    "TapmError",
    "__version__",
]
