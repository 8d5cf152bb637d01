"""Controllers from a plain specification (used by ``tapm simulate`` and study files).

A specification is a dict with ``type`` = ``"pid"``, ``"mpc"`` (nonlinear MPC) or ``"lmpc"`` (linear
MPC) and that controller's options; anything not given takes the defaults below, chosen the TAPM
way (survey §4.1): let the mooring do the work inside the safe region, damp the motion, keep the
heading, and restore only near the edge.

PID (``tapm_opt.control.pid``): gains by pole placement on the design model linearised at the field
zero point — ``periods`` (surge, sway, yaw) [s], ``damping`` (-), ``integral_ratio`` —, ``modes``
(a Table 3 set: ``calm``, ``normal``, ``normal_restoring``, ``extreme``, ``extreme_restoring``, or a
list of modes), ``tau_limit`` (default: the capacity box of the thrusters,
``models.system.ThrusterSet.capacity_box``, the same box the MPC uses), ``fault_tolerance``
(default true: a line the estimator reports broken has its load fed forward). Its position loop
acts on the turret offset (the reference point is the centre of turret). Sea-state supervision
(survey §4.5, ``tapm_opt.control.supervisor``): ``supervisor = true`` (or a table of
``SeaStateSupervisor.from_scenario`` options, e.g. ``{dwell = 600}``) switches this PID's mode set
with the detected sea state's class; ``gain_table`` (``gains.json`` or its folder, or the table's
JSON dict; a study file's path is relative to the study file and the table is embedded in the
case) runs a gain-scheduled PID on that table instead, supervised (the table's gains and mode
sets: ``periods``, ``damping``, ``integral_ratio``, ``modes``, ``tau_limit`` and
``fault_tolerance`` are not used); ``initial_sea_state`` is the sea state before the
supervisor's first decision.

MPC (``tapm_opt.control.mpc.MPCSettings``): every settings field; ``dead_band`` defaults to 0.6 of the
scenario's safe radius (``MPC_DEAD_BAND``), ``w_thrust``, ``w_rate`` and ``w_velocity`` to ``MPC_DEFAULTS``,
``fault_tolerance`` to true with the (default) characteristic mooring (a line reported broken
leaves the prediction), and with it ``dead_band_damaged`` [m], the dead band once a break is known,
to ``MPC_DEAD_BAND_DAMAGED`` of the dead band, tightened within the intact thrust budget
(``dead_band_budget``, ``docs/controllers.md``);
``period`` [s] is the re-solve period (default the prediction step); ``qp_solver`` is, for
``lmpc``, ``"piqp"`` (default), ``"osqp"`` or ``"daqp"`` (the QP condensed for DAQP,
``control.mpc_condensed``), for ``mpc`` ``"piqp"`` (default: inside the NLP solver) or ``"daqp"``
(with ``solver = "rti"``: each step's Gauss–Newton QP condensed for DAQP).

The defaults were tuned on the fpso design storm (``docs/controllers.md``): the PID as the
softest restoring loop that keeps the vessel inside the safe circle, the MPC with a dead band at
0.6 of the safe radius, a lazy and smooth thrust (w_thrust 10, w_rate 5), damping (w_velocity 5)
and soft heading and position weights.
"""

from __future__ import annotations

import difflib
import warnings
from dataclasses import fields
from typing import Any, Mapping

import numpy as np

from ..control.mpc import LinearMPC, MPCError, MPCSettings, NonlinearMPC
from ..control.pid import MODE_SETS, TAPMPID, ControlError
from ..control.pid_design import design_from_scenario
from ..errors import TapmError
from ..models.system import as_system

__all__ = ["build_controller", "CONTROLLER_TYPES", "ControllerSpecError"]

CONTROLLER_TYPES = ("pid", "mpc", "lmpc")
_MAX_HORIZON = 500  # prediction steps (horizon x substeps): the default is 20

PID_DEFAULTS = {"periods": (250.0, 250.0, 150.0), "damping": (0.8, 0.8, 0.8), "integral_ratio": 0.1,
                "modes": "normal_restoring", "tau_limit": None, "fault_tolerance": True,
                "gain_table": None, "supervisor": False, "initial_sea_state": None}


#: Study defaults of the MPCs that differ from MPCSettings' (tuned on the fpso design storm, intact
#: and with a line break, docs/controllers.md "Tuning the MPC"): a lazy and smooth thrust, damping.
MPC_DEFAULTS = {"w_thrust": 10.0, "w_rate": 5.0, "w_velocity": 5.0}
#: Dead band of the MPCs' turret offset as a fraction of the safe radius.
MPC_DEAD_BAND = 0.6
#: The MPCs' dead band once a line break is reported (with fault tolerance), as a fraction of the
#: dead band, within the intact thrust budget (``MPCSettings.dead_band_budget``): 0.45 of the safe
#: radius with the default dead band (docs/controllers.md "Tightening the MPC after a break").
MPC_DEAD_BAND_DAMAGED = 0.75


#: Keys of an MPC's controller specification: every ``MPCSettings`` field, the re-solve period and
#: the QP solver.
MPC_SPEC_KEYS = frozenset({f.name for f in fields(MPCSettings)} | {"period", "qp_solver"})


class ControllerSpecError(TapmError, ValueError):
    """A controller specification names an unknown type or option, or a bad value."""


def _unknown(keys: set[str], allowed: set[str], where: str) -> None:
    for k in sorted(keys - allowed):
        hint = difflib.get_close_matches(k, sorted(allowed), n=1)
        raise ControllerSpecError(f"{where}.{k}: unknown option" + (f"; did you mean {hint[0]!r}?" if hint else
                                                                    f"; allowed: {', '.join(sorted(allowed))}"))


def _dp_force_limit(system: Any, winch: Mapping[str, Any] | None, where: str) -> np.ndarray:
    """The PID's default command box (X [N], Y [N], N [N m]): the thrusters' capacity box, plus
    in X and Y the force the winches can make the mooring deliver when ``winch`` (the winch
    control options) is given."""
    box = np.array(system.thrusters.capacity_box(), dtype=float)
    if winch is None:
        return box
    from ..control.winch import WinchError, WinchTensionController

    try:
        r = WinchTensionController(system, winch).force_capacity()
    except WinchError as exc:
        raise ControllerSpecError(f"{where}: winch control: {exc}") from None
    return box + np.array([r, r, 0.0])


def build_controller(system: Any, spec: Mapping[str, Any] | str, *, where: str = "controller",
                     dt_control: float = 1.0, estimator: str | None = None,
                     winch: Mapping[str, Any] | None = None) -> Any:
    """A :class:`~tapm_opt.interfaces.Controller` from a specification.

    Parameters
    ----------
    system : System or Scenario
        The system the controller is designed on (a scenario is built into its System).
    spec : mapping or str
        ``{"type": ..., option: value, ...}`` (module docstring) or just the type.
    dt_control : float
        The loop's control period [s]: a sea-state supervisor samples the estimate at it.
    estimator : {"lowpass", "passive", "ekf"}, optional
        The loop's estimator (default :data:`~tapm_opt.studies.closed_loop.DEFAULT_ESTIMATOR`):
        a supervisor's expected wave-frequency features are those of its
        ``eta_wf`` (the low-pass estimator's measured-minus-filtered pose, or an observer's wave
        state: the WF motion itself, ``estimator_cutoff=None``).
    winch : mapping or None
        The loop's winch (line-tension) control options (``ClosedLoopSettings.winch_options``,
        ``{}`` for the defaults) when ``winch = "tension"``, else None. With winch control the
        mooring carries the DP command ([AF] §III), so a PID without an explicit ``tau_limit`` may
        command the thrust capacity plus the force the winches can make the mooring deliver
        (:meth:`~tapm_opt.control.winch.WinchTensionController.force_capacity`, added to X and Y).

    Raises
    ------
    ControllerSpecError
        Unknown type or option, or an invalid value (the message names ``where.option``).
    """
    if estimator is None:
        from .closed_loop import DEFAULT_ESTIMATOR as estimator
    if isinstance(spec, str):
        spec = {"type": spec}
    spec = dict(spec)
    kind = spec.pop("type", None)
    if kind not in CONTROLLER_TYPES:
        hint = difflib.get_close_matches(str(kind), CONTROLLER_TYPES, n=1)
        raise ControllerSpecError(f"{where}.type = {kind!r} is not one of {', '.join(CONTROLLER_TYPES)}"
                                  + (f" (did you mean {hint[0]!r}?)" if hint else ""))
    system = as_system(system)
    try:
        if kind == "pid":
            _unknown(set(spec), set(PID_DEFAULTS), where)
            o = {**PID_DEFAULTS, **spec}
            if isinstance(o["modes"], str) and o["modes"] not in MODE_SETS:
                raise ControllerSpecError(f"{where}.modes = {o['modes']!r} is not one of {', '.join(MODE_SETS)}")
            for key in ("periods", "damping"):
                v = o[key]
                try:
                    arr = np.asarray(v, dtype=float)
                except (TypeError, ValueError):
                    arr = np.zeros(0)
                if isinstance(v, str) or arr.shape != (3,) or not np.all(np.isfinite(arr) & (arr > 0)):
                    raise ControllerSpecError(f"{where}.{key} = {v!r} must be 3 positive numbers (surge, sway, yaw), "
                                              f"e.g. {key}=" + ",".join(f"{x:g}" for x in PID_DEFAULTS[key]))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # clamped gains are reported in the design
                design = design_from_scenario(system, periods=tuple(o["periods"]), damping=tuple(o["damping"]),
                                              integral_ratio=float(o["integral_ratio"]))
            tau_limit = o["tau_limit"] if o["tau_limit"] is not None else _dp_force_limit(system, winch, where)
            try:
                tau_limit = np.broadcast_to(np.asarray(tau_limit, dtype=float), (3,))
            except (TypeError, ValueError):
                raise ControllerSpecError(f"{where}.tau_limit = {o['tau_limit']!r} must be a number or 3 numbers "
                                          f"(X [N], Y [N], N [N m])") from None
            if not isinstance(o["fault_tolerance"], bool):
                raise ControllerSpecError(f"{where}.fault_tolerance = {o['fault_tolerance']!r} must be true or false")
            ctrl = TAPMPID.from_design(design, modes=o["modes"] if isinstance(o["modes"], str) else tuple(o["modes"]),
                                       tau_limit=tau_limit, reference_point=system.p_cot_B,
                                       thrusters=system.thrusters, line_model=system.lines,
                                       fault_tolerance=o["fault_tolerance"])
            ctrl.design = design
            sup, table = o["supervisor"], o["gain_table"]
            if not isinstance(sup, (bool, Mapping)):
                raise ControllerSpecError(f"{where}.supervisor = {sup!r} must be true, false or a table of "
                                          f"supervisor options")
            if table is not None and not isinstance(table, (str, Mapping)):
                raise ControllerSpecError(f"{where}.gain_table = {table!r} must be the path of gains.json")
            if sup is False and table is None:
                if o["initial_sea_state"] is not None:
                    raise ControllerSpecError(f"{where}.initial_sea_state needs supervisor = true or a gain_table")
                return ctrl
            from ..control.supervisor import supervised_pid

            opts = dict(sup) if isinstance(sup, Mapping) else {}
            opts.setdefault("dt", float(dt_control))
            if estimator != "lowpass":
                opts.setdefault("estimator_cutoff", None)
            if table is not None:
                return supervised_pid(system, gain_table=table, initial_sea_state=o["initial_sea_state"], **opts)
            return supervised_pid(system, pid=ctrl, initial_sea_state=o["initial_sea_state"], **opts)
        _unknown(set(spec), set(MPC_SPEC_KEYS), where)
        period = spec.pop("period", None)
        qp_solver = spec.pop("qp_solver", "piqp")
        if "dead_band" not in spec and system.limits.safe_radius is not None:
            spec["dead_band"] = MPC_DEAD_BAND * system.limits.safe_radius
        ft = {"fault_tolerance": spec.get("mooring", "characteristic") == "characteristic"}  # where it can be
        if (spec.get("fault_tolerance", ft["fault_tolerance"]) is True and "dead_band_damaged" not in spec
                and isinstance(spec.get("dead_band"), (int, float)) and spec["dead_band"] > 0):
            spec["dead_band_damaged"] = MPC_DEAD_BAND_DAMAGED * spec["dead_band"]
        if "dead_band_budget" in spec and spec.get("dead_band_damaged") is None:
            raise ControllerSpecError(f"{where}.dead_band_budget = {spec['dead_band_budget']!r} has nothing to budget: "
                                      "it needs fault tolerance and a dead band (dead_band > 0)")
        settings = MPCSettings(**{**MPC_DEFAULTS, **ft, **spec})
        n_pred = settings.horizon * settings.substeps
        if n_pred > _MAX_HORIZON:
            raise ControllerSpecError(
                f"{where}.horizon = {settings.horizon} (x substeps = {settings.substeps}) makes {n_pred} prediction "
                f"steps, above {_MAX_HORIZON}: the optimisation problem grows with them (look further ahead with a "
                "larger dt)")
        for name, hi in (("polygon_sides", 256), ("max_iter", 10000), ("polytope_directions", 400)):
            if getattr(settings, name) > hi:
                raise ControllerSpecError(f"{where}.{name} = {getattr(settings, name)!r} is above {hi}")
        if kind == "mpc":
            return NonlinearMPC(system, settings, period=None if period is None else float(period), qp_solver=qp_solver)
        return LinearMPC(system, settings, period=None if period is None else float(period), qp_solver=qp_solver)
    except ControllerSpecError:
        raise
    except (MPCError, ControlError) as exc:
        raise ControllerSpecError(f"{where}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise ControllerSpecError(f"{where}: {exc}") from None
