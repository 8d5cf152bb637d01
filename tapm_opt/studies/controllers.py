"""Controllers from a plain specification (used by ``tapm simulate`` and study files).

A specification is a dict with ``type`` = ``"pid"``, ``"mpc"`` (nonlinear MPC) or ``"lmpc"`` (linear
MPC) and that controller's options; anything not given takes the defaults below, chosen the TAPM
way (survey §4.1): let the mooring do the work inside the safe region, damp the motion, keep the
heading, and restore only near the edge.

PID (``tapm_opt.control.pid``): gains by pole placement on the design model linearised at the field
zero point — ``periods`` (surge, sway, yaw) [s], ``damping`` (-), ``integral_ratio`` —, ``modes``
(a Table 3 set: ``calm``, ``normal``, ``normal_restoring``, ``extreme``, ``extreme_restoring``, or a
list of modes), ``tau_limit`` (default: the allocation's capacity box).

MPC (``tapm_opt.control.mpc.MPCSettings``): every settings field; ``dead_band`` defaults to 0.7 of the
scenario's safe radius; ``period`` [s] is the re-solve period (default the prediction step).

The defaults were tuned on the fpso design storm (``docs/controllers.md``): the PID as the
softest restoring loop that keeps the vessel inside the safe circle, the MPC with a dead band at
0.7 of the safe radius and soft heading and position weights.
"""

from __future__ import annotations

import difflib
import warnings
from dataclasses import fields
from typing import Any, Mapping

import numpy as np

from ..control.mpc import LinearMPC, MPCError, MPCSettings, NonlinearMPC
from ..control.pid import MODE_SETS, TAPMPID, ControlError, design_from_scenario
from ..errors import TapmError

__all__ = ["build_controller", "CONTROLLER_TYPES", "ControllerSpecError"]

CONTROLLER_TYPES = ("pid", "mpc", "lmpc")

PID_DEFAULTS = {"periods": (250.0, 250.0, 150.0), "damping": (0.8, 0.8, 0.8), "integral_ratio": 0.1,
                "modes": "normal_restoring", "tau_limit": None}


class ControllerSpecError(TapmError, ValueError):
    """A controller specification names an unknown type or option, or a bad value."""


def _unknown(keys: set[str], allowed: set[str], where: str) -> None:
    for k in sorted(keys - allowed):
        hint = difflib.get_close_matches(k, sorted(allowed), n=1)
        raise ControllerSpecError(f"{where}.{k}: unknown option" + (f"; did you mean {hint[0]!r}?" if hint else
                                                                    f"; allowed: {', '.join(sorted(allowed))}"))


def build_controller(scenario: Any, spec: Mapping[str, Any] | str, *, where: str = "controller") -> Any:
    """A controller object (``update(t, estimate, setpoint) -> tau``) from a specification.

    Raises
    ------
    ControllerSpecError
        Unknown type or option, or an invalid value (the message names ``where.option``).
    """
    if isinstance(spec, str):
        spec = {"type": spec}
    spec = dict(spec)
    kind = spec.pop("type", None)
    if kind not in CONTROLLER_TYPES:
        hint = difflib.get_close_matches(str(kind), CONTROLLER_TYPES, n=1)
        raise ControllerSpecError(f"{where}.type = {kind!r} is not one of {', '.join(CONTROLLER_TYPES)}"
                                  + (f" (did you mean {hint[0]!r}?)" if hint else ""))
    try:
        if kind == "pid":
            _unknown(set(spec), set(PID_DEFAULTS), where)
            o = {**PID_DEFAULTS, **spec}
            if isinstance(o["modes"], str) and o["modes"] not in MODE_SETS:
                raise ControllerSpecError(f"{where}.modes = {o['modes']!r} is not one of {', '.join(MODE_SETS)}")
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # clamped gains are reported in the design
                design = design_from_scenario(scenario, periods=tuple(o["periods"]), damping=tuple(o["damping"]),
                                              integral_ratio=float(o["integral_ratio"]))
            tau_limit = o["tau_limit"] if o["tau_limit"] is not None else _capacity_box(scenario)
            ctrl = TAPMPID.from_design(design, modes=o["modes"] if isinstance(o["modes"], str) else tuple(o["modes"]),
                                       tau_limit=np.asarray(tau_limit, float))
            ctrl.design = design
            return ctrl
        allowed = {f.name for f in fields(MPCSettings)} | {"period"}
        _unknown(set(spec), allowed, where)
        period = spec.pop("period", None)
        if "dead_band" not in spec and scenario.limits.safe_radius is not None:
            spec["dead_band"] = 0.7 * scenario.limits.safe_radius
        settings = MPCSettings(**spec)
        ctrl = NonlinearMPC(scenario, settings) if kind == "mpc" else LinearMPC(scenario, settings)
        ctrl.period = float(period) if period is not None else settings.dt
        return ctrl
    except (MPCError, ControlError) as exc:
        raise ControllerSpecError(f"{where}: {exc}") from None
    except TypeError as exc:
        raise ControllerSpecError(f"{where}: {exc}") from None


def _capacity_box(scenario: Any) -> np.ndarray:
    """|X|, |Y|, |N| each reachable alone with every thruster, times 0.6 (room for the others)."""
    from ..models.thrust import configuration_matrix

    th = scenario.thrusters
    if not th:
        return np.zeros(3)
    x = np.array([t.position[0] for t in th])
    y = np.array([t.position[1] for t in th])
    fmax = np.array([t.max_thrust for t in th])
    # an azimuth can point its full thrust anywhere: its best contribution to each DOF
    best = np.array([fmax.sum(), fmax.sum(), np.sum(fmax * np.hypot(x, y))])
    fixed = [i for i, t in enumerate(th) if t.kind != "azimuth"]
    if fixed:
        T = np.abs(configuration_matrix(np.array([th[i].angle for i in fixed]), x[fixed], y[fixed]))
        best = best - np.array([fmax[fixed].sum(), fmax[fixed].sum(), np.sum(fmax[fixed] * np.hypot(x[fixed], y[fixed]))])
        best = best + T @ fmax[fixed]
    return 0.6 * best
