"""Mean environmental load on the moored vessel at rest, for the gain design (``docs/gains.md``).

Nothing here re-derives a load: the wind is the hull wind-load model of the plant
(:class:`~tapm_opt.models.environment.HullWindLoad`) at the mean wind speed, the drift is the
plant's Newman mean drift, the current load is the rich vessel model at rest in the current.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._io import readonly
from ..models.vessel import VesselParams, vessel_rhs
from ..plant.environment import Environment

__all__ = ["MeanLoad", "mean_environmental_load"]


@dataclass(frozen=True, kw_only=True, eq=False)
class MeanLoad:
    """Mean environmental load in {B} at one heading, each (X [N], Y [N], N [N m]).

    Attributes
    ----------
    wind, drift, current, total : ndarray, shape (3,)
    """

    wind: np.ndarray
    drift: np.ndarray
    current: np.ndarray
    total: np.ndarray


def mean_environmental_load(scenario: Any, sea_state: Any, psi: float, *,
                            seed: int = 0) -> MeanLoad:
    """Mean wind, wave-drift and current load on the vessel at rest with heading ``psi``.

    * wind: :meth:`~tapm_opt.models.environment.HullWindLoad.tau` of the plant's wind
      (``Wind.hull``, the coefficients of ``WindParams``) at the mean speed ``Wind.mean_speed``
      (no gusts) with the vessel at rest: ``-1/2 rho_a V^2 (c_x cos(gamma) A_F, c_y sin(gamma)
      A_L, c_n sin(2 gamma) A_L L_pp)``, the load of
      :meth:`~tapm_opt.plant.environment.Wind.tau_wind` without gusts;
    * drift: :meth:`~tapm_opt.plant.environment.WaveField.mean_drift` (Newman), which depends a
      little on ``seed`` through the random wave frequencies;
    * current: ``M nu_dot`` of :func:`~tapm_opt.models.vessel.vessel_rhs` (rich form) at nu = 0,
      tau = 0 in the surface current (as the plant): linear and quadratic damping and the
      Coriolis/Munk terms on nu_r = -nu_c.

    Parameters
    ----------
    scenario : Scenario
    sea_state : SeaState or str
    psi : float
        Heading [rad].
    seed : int
        Seed of :class:`~tapm_opt.plant.environment.Environment`.

    Returns
    -------
    MeanLoad
    """
    env = Environment(scenario, sea_state, seed=seed)
    psi = float(psi)
    wind = env.wind
    tau_wind = wind.hull.tau(wind.mean_speed, wind.direction, psi)
    tau_drift = np.asarray(env.waves.mean_drift(psi), dtype=float)
    params = VesselParams.from_scenario(scenario)
    _, nu_dot = vessel_rhs(np.array([0.0, 0.0, psi]), np.zeros(3), np.zeros(3),
                           np.asarray(env.current.surface[:2], dtype=float), params, form="rich")
    tau_current = params.M @ np.asarray(nu_dot, dtype=float)
    return MeanLoad(wind=readonly(tau_wind), drift=readonly(tau_drift),
                    current=readonly(tau_current),
                    total=readonly(tau_wind + tau_drift + tau_current))
