"""One recipe for a case: a controller from its specification, the FEM plant in a sea state, the
closed loop, and the case's KPIs — the same steps for ``tapm simulate``, every study case and a
Python user::

    from tapm_opt.studies import ClosedLoopSettings, run_case_on
    run = run_case_on(system, "lmpc", ClosedLoopSettings(duration=600.0), sea_state="storm", seed=3, segments=10)
    run.kpis["offset_max"], run.result["x"], run.events

The system is built once at the edge (``System.from_scenario``) and handed on: the controller, the
plant and the runner share it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Mapping

from .closed_loop import ClosedLoopSettings, run_closed_loop
from .controllers import build_controller

__all__ = ["CaseRun", "run_case_on"]


@dataclass(frozen=True)
class CaseRun:
    """What one closed-loop case gives.

    Attributes
    ----------
    result : Result
        The closed-loop run (labelled channels, ``meta`` with ``diagnostics``).
    kpis : dict
        :func:`tapm_opt.studies.kpis.case_kpis` of the result (names, units and directions in
        :mod:`tapm_opt.studies.kpi_catalogue`).
    sea_state : str
        The sea state's id (``"none"`` for still water).
    events : list of dict
        The plant's events in time order (line breaks, thruster failures), as the plant logged
        them: ``time`` [s], ``kind`` and what broke or failed.
    settle_time, settle_wall_time : float
        Simulated and wall-clock time spent settling the lines before t = 0 [s].
    wall_time : float
        Wall-clock time of the whole case [s].
    """

    result: Any
    kpis: dict
    sea_state: str
    events: list
    settle_time: float
    settle_wall_time: float
    wall_time: float


def run_case_on(system: Any, controller: Mapping[str, Any] | str, settings: ClosedLoopSettings, *,
                sea_state: Any = None, seed: int = 0, segments: int | None = None, where: str = "controller",
                meta: Mapping[str, Any] | None = None) -> CaseRun:
    """Run one case on ``system`` and compute its KPIs.

    Parameters
    ----------
    system : System
        Built once (``System.from_scenario``), faults included in its scenario.
    controller : mapping or str
        A controller specification (:func:`tapm_opt.design.registry.build`).
    settings : ClosedLoopSettings
        Duration, control and log periods, setpoint, heading, estimation, winch control.
    sea_state : str, SeaState or None
        The sea state (an id of the scenario, ``"none"``, or None for the scenario's first).
    seed : int
        Seed of waves, wind and sensor noise.
    segments : int or None
        FEM segments per line (None: the plant's default).
    where : str
        Prefix of controller-specification errors.
    meta : mapping, optional
        Added to the result's ``meta`` (with ``controller_spec`` and ``seed``).
    """
    from ..plant.simulator import Plant
    from .kpis import case_kpis

    w0 = time.perf_counter()
    spec = {"type": controller} if isinstance(controller, str) else dict(controller)
    ctrl = build_controller(system, spec, where=where, dt_control=settings.dt_control, estimator=settings.estimator,
                            winch=(settings.winch_options or {}) if settings.winch == "tension" else None)
    plant = Plant(system, sea_state=sea_state, seed=int(seed), segments=segments)
    result = run_closed_loop(plant, ctrl, settings, system=system,
                             meta={**dict(meta or {}), "controller_spec": spec, "seed": int(seed)})
    kpis = case_kpis(result, system)
    return CaseRun(result=result, kpis=kpis, sea_state=plant.sea_state.id if plant.sea_state else "none",
                   events=list(plant.events), settle_time=float(plant.settle_info.time),
                   settle_wall_time=float(plant.settle_info.wall_time), wall_time=time.perf_counter() - w0)
