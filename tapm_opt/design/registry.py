"""The controller kinds: each kind's options, tuned defaults, search space for tuning and build
function, stated once.

Every place that makes a controller from a specification reads this table: ``tapm simulate
--controller`` and its ``--option`` checks, study files' ``[[controllers]]``, the study parser's
dry build, :func:`tapm_opt.studies.controllers.build_controller`, the docs' controller table
(``docs/controllers.md``, checked by ``tests/test_registry.py``) and a Python user::

    from tapm_opt.design import build
    ctrl = build(system, "lmpc")                       # exactly what `tapm simulate --controller lmpc` runs
    ctrl = build(system, {"type": "mpc", "horizon": 30})

A kind is a :class:`ControllerKind`: its ``name`` (the spec's ``type``), a ``title``, the default
display ``label`` of studies, its ``options`` (a frozen dataclass whose fields carry the unit,
allowed values and meaning in their metadata, and whose defaults are the tuned study defaults),
its ``search_space`` (per tunable option: range, log or linear, integer or real; options not
listed are fixed) and ``build(system, options, context) -> Controller``.

The built-in kinds are ``pid`` (the TAPM PID modes of survey §4.2, gains by pole placement),
``mpc`` (nonlinear MPC on the CasADi model) and ``lmpc`` (linear MPC, one QP re-linearised each
step). A new kind is one module and one :func:`register` call — or, for an installed package, an
entry point in the group ``tapm_opt.controllers`` whose object is a :class:`ControllerKind` (or a
callable returning one); the registry loads the group the first time it is read.

Defaults (``docs/controllers.md``, "Tuning the MPC"): the PID as the softest restoring loop that
keeps fpso inside its safe circle in the design storm; the MPCs with a dead band at
:data:`DEAD_BAND_FRACTION` of the safe radius, a lazy and smooth thrust (``w_thrust`` 10,
``w_rate`` 5), damping (``w_velocity`` 5), fault tolerance on with the dead band tightened to
:data:`DEAD_BAND_DAMAGED_FRACTION` of itself after a reported break, within the intact thrust
budget. The fast solver paths are the defaults: the nonlinear MPC's real-time iteration with its
QP condensed for DAQP, the linear MPC's condensed QP on DAQP, with move blocking sized to the
horizon beyond :data:`AUTO_BLOCKS_FROM` steps (:func:`auto_move_blocks`). The converged SQP
(``solver = "sqp"``, ``qp_solver = "piqp"``) and the sparse linear QP (``qp_solver = "piqp"`` or
``"osqp"``) stay selectable as references.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from .._checks import is_number as _is_number
from ..models.system import CAPACITY_FRACTION
from ..errors import TapmError
from ..estimation import DEFAULT_ESTIMATOR
from ..control.pid import MODE_SETS

__all__ = ["ControllerKind", "Dimension", "BuildContext", "ControllerSpecError", "PIDOptions", "MPCOptions",
           "LMPCOptions", "register", "unregister", "kinds", "kind", "kind_names", "build", "options_from_spec",
           "auto_move_blocks", "DEAD_BAND_FRACTION", "DEAD_BAND_DAMAGED_FRACTION", "AUTO_BLOCKS_FROM",
           "ENTRY_POINT_GROUP", "MAX_PREDICTION_STEPS", "load_design", "merge_design", "DESIGN_FORMAT"]

#: Entry-point group of installed controller kinds.
ENTRY_POINT_GROUP = "tapm_opt.controllers"
#: The MPCs' dead band about the position setpoint as a fraction of the scenario's safe radius.
DEAD_BAND_FRACTION = 0.6
#: The MPCs' dead band once a line break is reported (with fault tolerance), as a fraction of the
#: dead band, within the intact thrust budget (``MPCSettings.dead_band_budget``).
DEAD_BAND_DAMAGED_FRACTION = 0.75
#: ``move_blocks = "auto"``: a move at every step up to this horizon, blocks beyond it.
AUTO_BLOCKS_FROM = 20
#: Moves of ``move_blocks = "auto"`` beyond :data:`AUTO_BLOCKS_FROM` steps.
AUTO_MOVES = 8
#: Prediction steps (horizon x substeps) an MPC may have: the problem grows with them.
MAX_PREDICTION_STEPS = 500


class ControllerSpecError(TapmError, ValueError):
    """A controller specification names an unknown kind or option, or a bad value."""


# ------------------------------------------------------------------------------------------
# the pieces of a kind
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Dimension:
    """One tunable option's search range.

    Attributes
    ----------
    low, high : float
        The range (``low <= high``) in the option's unit — or, with ``relative_to``, as a fraction
        of that scenario quantity.
    log : bool
        Sample on a log scale (``low > 0``).
    integer : bool
        Whole numbers only.
    size : int
        1 for a number; n for an option that is n numbers (e.g. the PID's surge, sway and yaw
        periods), each in the range.
    choices : tuple or None
        A categorical option's values (``low``/``high`` unused).
    relative_to : {"safe_radius"} or None
        The range is a fraction of this scenario quantity (e.g. the dead band).
    """

    low: float = 0.0
    high: float = 0.0
    log: bool = False
    integer: bool = False
    size: int = 1
    choices: tuple | None = None
    relative_to: str | None = None

    def __post_init__(self) -> None:
        if self.choices is not None:
            if not self.choices:
                raise ControllerSpecError("Dimension.choices is empty")
            return
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low <= self.high):
            raise ControllerSpecError(f"Dimension range [{self.low!r}, {self.high!r}] must be finite with low <= high")
        if self.log and self.low <= 0:
            raise ControllerSpecError(f"Dimension range [{self.low!r}, {self.high!r}] on a log scale needs low > 0")
        if self.relative_to not in (None, "safe_radius"):
            raise ControllerSpecError(f"Dimension.relative_to = {self.relative_to!r} is not one of None, 'safe_radius'")


@dataclass(frozen=True)
class BuildContext:
    """What a controller is built for besides its options: the closed loop around it.

    Attributes
    ----------
    dt_control : float
        The loop's control period [s] (a sea-state supervisor samples the estimate at it).
    estimator : {"lowpass", "passive", "ekf"}
        The loop's estimator: a supervisor's expected wave-frequency features are those of its
        ``eta_wf``. Default: the closed loop's default estimator, the EKF.
    winch : mapping or None
        The loop's winch (line-tension) control options with ``winch = "tension"`` (``{}`` for
        the defaults), else None: the PID's default command box then adds the force the winches
        can make the mooring deliver.
    where : str
        The prefix of error messages (``--option``, ``controllers[2]``).
    """

    dt_control: float = 1.0
    estimator: str = DEFAULT_ESTIMATOR
    winch: Mapping[str, Any] | None = None
    where: str = "controller"


@dataclass(frozen=True)
class ControllerKind:
    """A kind of controller (module docstring).

    Attributes
    ----------
    name : str
        The specification's ``type`` (``--controller``).
    title : str
        One line for help texts and the docs' table.
    label : str
        Default name of the kind's controllers in studies and reports.
    options : type
        A frozen dataclass: every option, its tuned default, and in each field's metadata
        ``unit``, ``doc`` and (where they are few) ``allowed`` values.
    build : callable
        ``build(system, options, context) -> Controller`` (:class:`~tapm_opt.interfaces.Controller`).
    search_space : mapping
        ``{option: Dimension}``, the options a tuner may vary; the rest are fixed.
    normalise : callable or None
        ``normalise(spec) -> spec``: numbers in the form the options take (``35`` and ``35.0`` give
        one study case id); None: the spec as given.
    """

    name: str
    title: str
    label: str
    options: type
    build: Callable[[Any, Any, BuildContext], Any]
    search_space: Mapping[str, Dimension] = field(default_factory=dict)
    normalise: Callable[[Mapping[str, Any]], dict] | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.name, str) and self.name.isidentifier()):
            raise ControllerSpecError(f"ControllerKind.name = {self.name!r} must be an identifier")
        if not (dataclasses.is_dataclass(self.options) and isinstance(self.options, type)):
            raise ControllerSpecError(f"ControllerKind {self.name!r}: options must be a dataclass type")
        names = {f.name for f in dataclasses.fields(self.options)}
        for k, d in self.search_space.items():
            if k not in names:
                raise ControllerSpecError(f"ControllerKind {self.name!r}: search_space.{k} is not an option")
            if not isinstance(d, Dimension):
                raise ControllerSpecError(f"ControllerKind {self.name!r}: search_space.{k} must be a Dimension")

    def option_names(self) -> tuple[str, ...]:
        """Every option's name, in declaration order."""
        return tuple(f.name for f in dataclasses.fields(self.options))

    def defaults(self) -> dict[str, Any]:
        """``{option: default}``."""
        return {f.name: getattr(self.options(), f.name) for f in dataclasses.fields(self.options)}

    def describe(self) -> list[dict[str, Any]]:
        """One dict per option: ``name``, ``default``, ``unit``, ``allowed``, ``doc``, and ``search``
        (its :class:`Dimension` or None when fixed)."""
        d = self.options()
        return [{"name": f.name, "default": getattr(d, f.name), "unit": f.metadata.get("unit", ""),
                 "allowed": f.metadata.get("allowed"), "doc": f.metadata.get("doc", ""),
                 "search": self.search_space.get(f.name)} for f in dataclasses.fields(self.options)]


def _opt(default: Any, doc: str, unit: str = "", allowed: tuple | None = None) -> Any:
    """A dataclass field with its documentation in the metadata."""
    meta = {"doc": doc, "unit": unit, **({"allowed": allowed} if allowed is not None else {})}
    if isinstance(default, (list, dict, set)):
        raise TypeError("mutable default")
    return field(default=default, metadata=meta)


# ------------------------------------------------------------------------------------------
# PID
# ------------------------------------------------------------------------------------------



@dataclass(frozen=True)
class PIDOptions:
    """Options of the TAPM PID (``type = "pid"``; ``tapm_opt.control.pid``, survey §4.2)."""

    periods: tuple = _opt((250.0, 250.0, 150.0), "closed-loop natural periods of surge, sway and yaw for the pole "
                          "placement on the design model linearised at the field zero point", "s")
    damping: tuple = _opt((0.8, 0.8, 0.8), "relative damping of surge, sway and yaw", "-")
    integral_ratio: float = _opt(0.1, "integral pole as a fraction of the natural frequency", "-")
    modes: Any = _opt("normal_restoring", "the active control modes: a Table 3 set or a list of modes "
                      "(heading, damping, restoring, mean)", "", tuple(MODE_SETS))
    tau_limit: Any = _opt(None, "command box (X, Y, N); None: the thrusters' capacity box (plus the winches' "
                          "force with winch tension control)", "N, N, N m")
    capacity_fraction: float = _opt(CAPACITY_FRACTION, "the capacity box (tau_limit None) as a fraction of the largest X, Y "
                                    "and N the thrusters make each alone: the PID's anti-windup limit", "-")
    fault_tolerance: bool = _opt(True, "feed a line reported broken's load forward", "", (True, False))
    gain_table: Any = _opt(None, "gains.json (or its folder, or its dict): a gain-scheduled PID on that table, "
                           "supervised (periods, damping, integral_ratio, modes, tau_limit, capacity_fraction and fault_tolerance "
                           "unused)")
    supervisor: Any = _opt(False, "sea-state supervision (survey §4.5): true or a table of SeaStateSupervisor "
                           "options, e.g. {dwell = 600}")
    initial_sea_state: Any = _opt(None, "sea-state class before the supervisor's first decision")
    roll_pitch_damping: Any = _opt(False, "roll-pitch damping mode (survey §4.2.3, docs/semi.md; a scenario with "
                                   "vessel.roll_pitch): true, or a table of zeta_roll, zeta_pitch (added damping "
                                   "as a fraction of critical, default 0.3 each), Kd_roll, Kd_pitch [N m s/rad] "
                                   "(instead of zeta), Kp_roll, Kp_pitch [N m/rad] (default 0), filter_time [s] "
                                   "(default 2)")


def _positive_triple(value: Any, key: str, where: str, example: tuple) -> tuple:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    if isinstance(value, str) or arr.shape != (3,) or not np.all(np.isfinite(arr) & (arr > 0)):
        raise ControllerSpecError(f"{where}.{key} = {value!r} must be 3 positive numbers (surge, sway, yaw), "
                                  f"e.g. {key}=" + ",".join(f"{x:g}" for x in example))
    return tuple(float(x) for x in arr)


def _dp_force_limit(system: Any, winch: Mapping[str, Any] | None, where: str,
                    fraction: float = CAPACITY_FRACTION) -> np.ndarray:
    """The PID's default command box (X [N], Y [N], N [N m]): the thrusters' capacity box
    (``fraction`` of the largest X, Y and N each alone), plus in X and Y the force the winches can
    make the mooring deliver when ``winch`` is given."""
    if not (_is_number(fraction) and 0.0 < float(fraction) <= 1.0):
        raise ControllerSpecError(f"{where}.capacity_fraction = {fraction!r} must be a number in (0, 1]")
    box = np.array(system.thrusters.capacity_box(float(fraction)), dtype=float)
    if not np.all(box > 0):
        ids = ", ".join(t.id for t in system.scenario.thrusters) or "none"
        raise ControllerSpecError(
            f"{where}: scenario {system.scenario.name!r} has no thrust capacity in every direction (capacity box "
            f"X, Y, N = {', '.join(f'{b:.3g}' for b in box)}; thrusters: {ids}): a controller needs thrusters that "
            "can push in surge, sway and yaw (give the scenario [[thrusters]], or an explicit tau_limit)")
    if winch is None:
        return box
    from ..control.winch import WinchError, WinchTensionController

    try:
        r = WinchTensionController(system, winch).force_capacity()
    except WinchError as exc:
        raise ControllerSpecError(f"{where}: winch control: {exc}") from None
    return box + np.array([r, r, 0.0])


#: Added roll and pitch damping of the roll–pitch damping mode by default, as a fraction of critical.
ROLL_PITCH_ZETA = 0.3
_RPD_KEYS = ("zeta_roll", "zeta_pitch", "Kd_roll", "Kd_pitch", "Kp_roll", "Kp_pitch", "filter_time")


def _roll_pitch_damping(system: Any, value: Any, where: str) -> Any:
    """The PID's :class:`~tapm_opt.control.pid.RollPitchDamping` from the option
    ``roll_pitch_damping`` (false, true or a table; see :class:`PIDOptions`): K_d = 2 zeta sqrt(C I)
    of the vessel's roll–pitch model unless K_d is given (docs/semi.md eq. RP6)."""
    from ..control.pid import ControlError, RollPitchDamping

    key = f"{where}.roll_pitch_damping"
    if value is False:
        return None
    if value is not True and not isinstance(value, Mapping):
        raise ControllerSpecError(f"{key} = {value!r} must be true, false or a table of {', '.join(_RPD_KEYS)}")
    rp = system.vessel.roll_pitch
    if rp is None:
        raise ControllerSpecError(f"{key}: scenario {system.scenario.name!r} has no low-frequency roll and pitch "
                                  "(give its vessel a [vessel.roll_pitch] table)")
    opts = dict(value) if isinstance(value, Mapping) else {}
    unknown = sorted(set(opts) - set(_RPD_KEYS))
    if unknown:
        raise ControllerSpecError(f"{key}: unknown option(s) {unknown}; options are {', '.join(_RPD_KEYS)}")
    for k, v in opts.items():
        if isinstance(v, bool) or not _is_number(v) or not math.isfinite(float(v)) or float(v) < 0:
            raise ControllerSpecError(f"{key}.{k} = {v!r} must be a number >= 0")
    kd = {}
    for axis, crit in zip(("roll", "pitch"), rp.critical_damping):
        if f"Kd_{axis}" in opts and f"zeta_{axis}" in opts:
            raise ControllerSpecError(f"{key}: give Kd_{axis} or zeta_{axis}, not both")
        kd[axis] = float(opts[f"Kd_{axis}"]) if f"Kd_{axis}" in opts else \
            float(opts.get(f"zeta_{axis}", ROLL_PITCH_ZETA)) * crit
    try:
        return RollPitchDamping(lever=rp.thruster_lever, Kd_roll=kd["roll"], Kd_pitch=kd["pitch"],
                                Kp_roll=float(opts.get("Kp_roll", 0.0)), Kp_pitch=float(opts.get("Kp_pitch", 0.0)),
                                filter_time=float(opts.get("filter_time", 2.0)))
    except ControlError as exc:
        raise ControllerSpecError(f"{where}: {exc}") from None


def _build_pid(system: Any, o: PIDOptions, ctx: BuildContext) -> Any:
    from ..control.pid import TAPMPID
    from ..control.pid_design import design_from_scenario

    where = ctx.where
    if isinstance(o.modes, str) and o.modes not in tuple(MODE_SETS):
        raise ControllerSpecError(f"{where}.modes = {o.modes!r} is not one of {', '.join(tuple(MODE_SETS))}")
    periods = _positive_triple(o.periods, "periods", where, PIDOptions.periods)
    damping = _positive_triple(o.damping, "damping", where, PIDOptions.damping)
    if not isinstance(o.fault_tolerance, bool):
        raise ControllerSpecError(f"{where}.fault_tolerance = {o.fault_tolerance!r} must be true or false")
    sup, table = o.supervisor, o.gain_table
    if not isinstance(sup, (bool, Mapping)):
        raise ControllerSpecError(f"{where}.supervisor = {sup!r} must be true, false or a table of supervisor options")
    if table is not None and not isinstance(table, (str, Mapping)):
        raise ControllerSpecError(f"{where}.gain_table = {table!r} must be the path of gains.json")
    if o.roll_pitch_damping is not False and (sup is not False or table is not None):
        raise ControllerSpecError(f"{where}.roll_pitch_damping is not available with a supervisor or a gain_table "
                                  "(the supervised PID does not read the motion reference unit)")
    if sup is False and table is None and o.initial_sea_state is not None:
        raise ControllerSpecError(f"{where}.initial_sea_state needs supervisor = true or a gain_table")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # clamped gains are reported in the design
        design = design_from_scenario(system, periods=periods, damping=damping,
                                      integral_ratio=float(o.integral_ratio))
    if o.tau_limit is not None:
        try:
            tau_limit = np.broadcast_to(np.asarray(o.tau_limit, dtype=float), (3,))
        except (TypeError, ValueError):
            raise ControllerSpecError(f"{where}.tau_limit = {o.tau_limit!r} must be a number or 3 numbers "
                                      "(X [N], Y [N], N [N m])") from None
    else:
        tau_limit = _dp_force_limit(system, ctx.winch, where, o.capacity_fraction)
    ctrl = TAPMPID.from_design(design, modes=o.modes if isinstance(o.modes, str) else tuple(o.modes),
                               tau_limit=tau_limit, reference_point=system.p_cot_B, thrusters=system.thrusters,
                               line_model=system.lines, fault_tolerance=o.fault_tolerance,
                               roll_pitch=_roll_pitch_damping(system, o.roll_pitch_damping, where))
    ctrl.design = design
    if sup is False and table is None:
        return ctrl
    from .supervisor import supervised_pid

    opts = dict(sup) if isinstance(sup, Mapping) else {}
    opts.setdefault("dt", float(ctx.dt_control))
    if ctx.estimator != "lowpass":
        opts.setdefault("estimator_cutoff", None)
    if table is not None:
        return supervised_pid(system, gain_table=table, initial_sea_state=o.initial_sea_state, **opts)
    return supervised_pid(system, pid=ctrl, initial_sea_state=o.initial_sea_state, **opts)


def _normalise_pid(spec: Mapping[str, Any]) -> dict:
    out: dict = {}
    for k, v in spec.items():
        if k in ("periods", "damping", "tau_limit") and isinstance(v, list):
            v = [float(x) if _is_number(x) else x for x in v]
        elif k in ("integral_ratio", "capacity_fraction") and _is_number(v):
            v = float(v)
        out[k] = v
    return out


PID_SEARCH_SPACE = {
    "periods": Dimension(60.0, 600.0, log=True, size=3),
    "damping": Dimension(0.4, 1.5, size=3),
    "integral_ratio": Dimension(0.0, 0.5),
    "capacity_fraction": Dimension(0.4, 1.0),
    "modes": Dimension(choices=("normal", "normal_restoring", "extreme", "extreme_restoring")),
}


# ------------------------------------------------------------------------------------------
# MPC (nonlinear and linear)
# ------------------------------------------------------------------------------------------

#: Units of the MPC settings that have one (the rest are dimensionless weights or choices).
_MPC_UNITS = {"dt": "s", "dead_band": "m", "dead_band_damaged": "m", "safe_radius": "m", "r_ref": "m",
              "psi_ref": "rad", "nu_ref": "m/s", "r_rate_ref": "rad/s", "max_time": "s",
              "load_time_constant": "s", "tension_utilisation": "-", "capacity_fraction": "-", "period": "s",
              "horizon": "steps", "move_blocks": "steps"}


def auto_move_blocks(horizon: int) -> tuple[int, ...] | None:
    """Move blocking sized to the horizon (``move_blocks = "auto"``).

    A move at every step up to :data:`AUTO_BLOCKS_FROM` steps (None); beyond, :data:`AUTO_MOVES`
    blocks whose ends grow quadratically, ``round(N (k / M)^2)`` for k = 1..M, each at least one
    step longer than the one before ends — short blocks where the plan acts now, long ones at the
    end of the horizon (e.g. N = 50: ``(1, 2, 4, 5, 8, 8, 10, 12)``). The condensed QP's work grows
    with the moves squared, so a long horizon costs about what N = 20 does unblocked
    (``docs/controllers.md``, "Move blocking").
    """
    n = int(horizon)
    if n <= AUTO_BLOCKS_FROM:
        return None
    m = AUTO_MOVES
    ends: list[int] = []
    for k in range(1, m + 1):
        e = max(int(round(n * (k / m) ** 2)), (ends[-1] + 1) if ends else 1)
        ends.append(min(e, n - (m - k)))
    ends[-1] = n
    return tuple(int(b) for b in np.diff([0, *ends]))


def _mpc_options_class(name: str, doc: str, overrides: Mapping[str, Any], extra: list[tuple]) -> type:
    """A frozen options dataclass: every ``MPCSettings`` field with the study's ``overrides`` of
    its defaults, plus ``extra`` fields (name, type, field)."""
    from ..control.mpc_problem import MPCSettings

    doc_lines = _settings_docs(MPCSettings.__doc__ or "")
    specs = []
    for f in dataclasses.fields(MPCSettings):
        default = overrides.get(f.name, f.default)
        allowed = tuple(getattr(f.type, "__args__", ())) or None
        if isinstance(f.type, str) and f.type.startswith("Literal["):
            allowed = tuple(x.strip().strip("'\"") for x in f.type[len("Literal["):-1].split(","))
        meta = {"doc": doc_lines.get(f.name, ""), "unit": _MPC_UNITS.get(f.name, "-" if f.name.startswith("w_") else ""),
                **({"allowed": allowed} if allowed else {})}
        specs.append((f.name, Any, field(default=default, metadata=meta)))
    cls = dataclasses.make_dataclass(name, specs + extra, frozen=True)
    cls.__doc__ = doc
    cls.__module__ = __name__
    return cls


def _settings_docs(doc: str) -> dict[str, str]:
    """``{attribute: its description's first sentence}`` from a numpydoc ``Attributes`` section
    (headers indented 4 spaces, ``name[, name] : type``; descriptions indented 8)."""
    out: dict[str, str] = {}
    names: list[str] = []
    body: list[str] = []

    def flush() -> None:
        text = " ".join(body)
        first = re.split(r"(?<!e\.g)(?<!eq)(?<!i\.e)(?<!cf)\.\s+(?=[A-Z(])", text)[0].rstrip(".")
        for n in names:
            out[n] = first

    for ln in doc.splitlines():
        if ln.startswith("    ") and not ln.startswith("     ") and " : " in ln:
            flush()
            names, body = [n.strip() for n in ln.split(" : ")[0].split(",")], []
        elif ln.startswith("        ") and names:
            body.append(ln.strip())
    flush()
    return out


#: The tuned study defaults that differ from ``MPCSettings``' (None: worked out at build, see
#: :func:`_mpc_settings`).
_MPC_OVERRIDES = {"w_thrust": 10.0, "w_rate": 5.0, "w_velocity": 5.0, "fault_tolerance": None,
                  "dead_band": None, "dead_band_damaged": None, "dead_band_budget": None}

_MPC_EXTRA_COMMON = [
    ("period", Any, field(default=None, metadata={"doc": "re-solve period (None: the prediction step dt)",
                                                  "unit": "s"})),
]

MPCOptions = _mpc_options_class(
    "MPCOptions", "Options of the nonlinear MPC (``type = \"mpc\"``, :class:`~tapm_opt.control.mpc.NonlinearMPC`): "
    "every MPCSettings field with the tuned study defaults (dead_band None: DEAD_BAND_FRACTION of the safe "
    "radius; dead_band_damaged None: DEAD_BAND_DAMAGED_FRACTION of the dead band with fault tolerance), the "
    "re-solve period and the QP solver.",
    {**_MPC_OVERRIDES, "solver": "rti", "move_blocks": "auto"},
    _MPC_EXTRA_COMMON + [("qp_solver", Any, field(default=None, metadata={
        "doc": "QP solver: daqp (the real-time iteration's QP condensed) or piqp (inside the NLP solver); None: "
               "daqp with solver = rti, else piqp", "unit": "", "allowed": ("daqp", "piqp", None)}))])

LMPCOptions = _mpc_options_class(
    "LMPCOptions", "Options of the linear MPC (``type = \"lmpc\"``, :class:`~tapm_opt.control.mpc.LinearMPC`): "
    "every MPCSettings field with the tuned study defaults (as MPCOptions), the re-solve period and the QP solver.",
    {**_MPC_OVERRIDES, "move_blocks": "auto"},
    _MPC_EXTRA_COMMON + [("qp_solver", Any, field(default="daqp", metadata={
        "doc": "QP solver: daqp (condensed, dense active set), piqp or osqp (the sparse QP)", "unit": "",
        "allowed": ("daqp", "piqp", "osqp")}))])

_NOT_SETTINGS = ("period", "qp_solver")


def _mpc_settings(system: Any, o: Any, where: str) -> Any:
    from ..control.mpc_problem import MPCError, MPCSettings, RollPitchWeights

    s = {k: getattr(o, k) for k in (f.name for f in dataclasses.fields(o)) if k not in _NOT_SETTINGS}
    if s["dead_band"] is None:
        r = system.limits.safe_radius
        s["dead_band"] = DEAD_BAND_FRACTION * r if r is not None else 0.0
    if isinstance(s["move_blocks"], str):
        if s["move_blocks"] != "auto":
            raise ControllerSpecError(f"{where}.move_blocks = {s['move_blocks']!r} must be 'auto', a list of block "
                                      "lengths summing to the horizon, or none")
        s["move_blocks"] = auto_move_blocks(s["horizon"]) if isinstance(s["horizon"], int) else None
    if s["fault_tolerance"] is None:   # where it can be: the lines are parameters only with characteristics
        s["fault_tolerance"] = s["mooring"] == "characteristic"
    has_band = _is_number(s["dead_band"]) and s["dead_band"] > 0
    if s["dead_band_damaged"] is None and s["fault_tolerance"] is True and has_band:
        s["dead_band_damaged"] = DEAD_BAND_DAMAGED_FRACTION * s["dead_band"]
    if s["dead_band_budget"] is None:
        s["dead_band_budget"] = True
    elif s["dead_band_damaged"] is None:
        raise ControllerSpecError(f"{where}.dead_band_budget = {s['dead_band_budget']!r} has nothing to budget: it "
                                  "needs fault tolerance and a dead band (dead_band > 0)")
    rpd = s["roll_pitch_damping"]
    if rpd is not False and rpd is not None:
        if system.vessel.roll_pitch is None:
            raise ControllerSpecError(f"{where}.roll_pitch_damping: scenario {system.scenario.name!r} has no "
                                      "low-frequency roll and pitch (give its vessel a [vessel.roll_pitch] table)")
        if rpd is not True and not isinstance(rpd, Mapping):
            raise ControllerSpecError(f"{where}.roll_pitch_damping = {rpd!r} must be true, false or a table of "
                                      + ", ".join(f.name for f in dataclasses.fields(RollPitchWeights)))
        try:
            s["roll_pitch_damping"] = RollPitchWeights.from_option(rpd)
        except MPCError as exc:
            raise ControllerSpecError(f"{where}.{str(exc).removeprefix('MPCSettings.')}") from None
    settings = MPCSettings(**s)
    n_pred = settings.horizon * settings.substeps
    if n_pred > MAX_PREDICTION_STEPS:
        raise ControllerSpecError(
            f"{where}.horizon = {settings.horizon} (x substeps = {settings.substeps}) makes {n_pred} prediction "
            f"steps, above {MAX_PREDICTION_STEPS}: the optimisation problem grows with them (look further ahead "
            "with a larger dt)")
    for name, hi in (("polygon_sides", 256), ("max_iter", 10000), ("polytope_directions", 400)):
        if getattr(settings, name) > hi:
            raise ControllerSpecError(f"{where}.{name} = {getattr(settings, name)!r} is above {hi}")
    return settings


def _period(o: Any, where: str) -> float | None:
    if o.period is None:
        return None
    if not (_is_number(o.period) and math.isfinite(o.period) and o.period > 0):
        raise ControllerSpecError(f"{where}.period = {o.period!r} must be a positive number of seconds or none")
    return float(o.period)


def _build_mpc(system: Any, o: Any, ctx: BuildContext) -> Any:
    from ..control.mpc import NonlinearMPC

    settings = _mpc_settings(system, o, ctx.where)
    qp = o.qp_solver if o.qp_solver is not None else ("daqp" if settings.solver == "rti"
                                                      and settings.hessian == "gauss-newton" else "piqp")
    return NonlinearMPC(system, settings, period=_period(o, ctx.where), qp_solver=qp)


def _build_lmpc(system: Any, o: Any, ctx: BuildContext) -> Any:
    from ..control.mpc import LinearMPC

    return LinearMPC(system, _mpc_settings(system, o, ctx.where), period=_period(o, ctx.where),
                     qp_solver=o.qp_solver)


def _normalise_mpc(spec: Mapping[str, Any]) -> dict:
    from ..control.mpc_problem import MPCSettings

    floats = {f.name for f in dataclasses.fields(MPCSettings) if "float" in str(f.type)} | {"period"}
    return {k: float(v) if (k in floats and _is_number(v)) else v for k, v in spec.items()}


MPC_SEARCH_SPACE = {
    "horizon": Dimension(10, 50, integer=True),
    "w_thrust": Dimension(0.3, 3000.0, log=True),
    "w_rate": Dimension(0.1, 50.0, log=True),
    "w_velocity": Dimension(0.1, 50.0, log=True),
    "w_position": Dimension(0.1, 100.0, log=True),
    "w_heading": Dimension(0.1, 100.0, log=True),
    "dead_band": Dimension(0.0, 0.9, relative_to="safe_radius"),
    "load_time_constant": Dimension(0.0, 400.0),
}


# ------------------------------------------------------------------------------------------
# the table
# ------------------------------------------------------------------------------------------

_BUILTIN = (
    ControllerKind("pid", "TAPM PID control modes (survey §4.2), gains by pole placement", "PID", PIDOptions,
                   _build_pid, PID_SEARCH_SPACE, _normalise_pid),
    ControllerKind("mpc", "nonlinear MPC on the CasADi model (real-time iteration, QP condensed for DAQP)", "NMPC",
                   MPCOptions, _build_mpc, MPC_SEARCH_SPACE, _normalise_mpc),
    ControllerKind("lmpc", "linear MPC, one QP re-linearised about the present state each step (DAQP)", "MPC",
                   LMPCOptions, _build_lmpc, MPC_SEARCH_SPACE, _normalise_mpc),
)
_KINDS: dict[str, ControllerKind] = {k.name: k for k in _BUILTIN}
_plugins_loaded = False


def register(k: ControllerKind, *, replace: bool = False) -> ControllerKind:
    """Add a controller kind to the table (``replace=True`` to redefine one); returns it."""
    if not isinstance(k, ControllerKind):
        raise ControllerSpecError(f"register() takes a ControllerKind, got {type(k).__name__}")
    if k.name in _KINDS and not replace and _KINDS[k.name] is not k:
        raise ControllerSpecError(f"controller kind {k.name!r} is registered already (replace=True to redefine it)")
    _KINDS[k.name] = k
    return k


def unregister(name: str) -> None:
    """Remove a registered kind (a built-in one cannot be removed)."""
    if name in {b.name for b in _BUILTIN}:
        raise ControllerSpecError(f"controller kind {name!r} is built in and cannot be removed")
    _KINDS.pop(name, None)


def _load_plugins() -> None:
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            obj = ep.load()
            k = obj() if callable(obj) and not isinstance(obj, ControllerKind) else obj
            if k.name not in _KINDS:
                register(k)
        except Exception as exc:  # noqa: BLE001 - a broken plugin is reported, the built-ins still work
            warnings.warn(f"controller plugin {ep.name!r} ({ep.value}) could not be loaded: {exc}", stacklevel=2)


def reload_plugins() -> None:
    """Read the entry-point group again (after installing a plugin in a running process)."""
    global _plugins_loaded
    _plugins_loaded = False
    _load_plugins()


def kinds() -> Mapping[str, ControllerKind]:
    """Every registered kind by name: the built-ins, registered ones and installed plugins."""
    _load_plugins()
    return dict(_KINDS)


def kind_names() -> tuple[str, ...]:
    """The registered kinds' names."""
    return tuple(kinds())


def kind(name: Any, where: str = "controller") -> ControllerKind:
    """The kind called ``name`` (a typed error naming it, with the closest match, if unknown)."""
    ks = kinds()
    if name not in ks:
        hint = difflib.get_close_matches(str(name), list(ks), n=1)
        raise ControllerSpecError(f"{where}.type = {name!r} is not one of {', '.join(ks)}"
                                  + (f" (did you mean {hint[0]!r}?)" if hint else ""))
    return ks[name]


#: Format tag of a tuned design file (``tapm tune``'s ``tuned/<controller>.toml``).
DESIGN_FORMAT = "tapm-design/1"


def load_design(path: Any, where: str = "design") -> dict:
    """The controller specification of a design file (``tapm tune``'s ``tuned/<controller>.toml``:
    its ``[design.controller]`` table, ``type`` and options).

    Raises
    ------
    ControllerSpecError
        The file cannot be read, is not TOML, or is not a design file (the message names it).
    """
    import tomllib
    from pathlib import Path

    p = Path(str(path))
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8-sig"))
    except OSError as exc:
        raise ControllerSpecError(f"{where} = {str(path)!r}: cannot read the design file: "
                                  f"{exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ControllerSpecError(f"{where} = {str(path)!r} is not valid TOML: {exc}") from None
    d = data.get("design")
    if not isinstance(d, Mapping) or d.get("format") != DESIGN_FORMAT or not isinstance(d.get("controller"), Mapping):
        raise ControllerSpecError(f"{where} = {str(path)!r} is not a design file ([design] with format = "
                                  f"{DESIGN_FORMAT!r} and a [design.controller] table, as tapm tune writes)")
    spec = dict(d["controller"])
    if "type" not in spec:
        raise ControllerSpecError(f"{where} = {str(path)!r}: [design.controller] has no type")
    return spec


def merge_design(spec: Mapping[str, Any], design: Mapping[str, Any], where: str = "controller") -> dict:
    """``spec`` on top of a design's specification: the design's kind and options, ``spec``'s own
    options overriding them; a ``type`` in ``spec`` must be the design's."""
    spec = dict(spec)
    spec.pop("design", None)
    if spec.get("type") not in (None, design["type"]):
        raise ControllerSpecError(f"{where}.type = {spec['type']!r}, but the design is a {design['type']!r}")
    return {**dict(design), **{k: v for k, v in spec.items() if k != "type"}}


def options_from_spec(spec: Mapping[str, Any] | str, where: str = "controller") -> tuple[ControllerKind, Any]:
    """The kind and its options instance from ``{"type": ..., option: value}`` (or just the type),
    or ``{"design": path, ...}`` (a tuned design file, :func:`load_design`, its options overridden
    by the others given).

    Unknown options are a :class:`ControllerSpecError` naming ``where.option`` with the closest
    match; values are checked when the controller is built.
    """
    if isinstance(spec, str):
        spec = {"type": spec}
    if not isinstance(spec, Mapping):
        raise ControllerSpecError(f"{where} = {spec!r} must be a kind name or a table with a type")
    spec = dict(spec)
    if "design" in spec:
        spec = merge_design(spec, load_design(spec["design"], f"{where}.design"), where)
    k = kind(spec.pop("type", None), where)
    allowed = k.option_names()
    for key in sorted(set(spec) - set(allowed), key=str):
        hint = difflib.get_close_matches(str(key), allowed, n=1)
        raise ControllerSpecError(f"{where}.{key}: unknown option of {k.name}"
                                  + (f"; did you mean {hint[0]!r}?" if hint else f"; allowed: {', '.join(allowed)}"))
    if k.normalise is not None:
        spec = k.normalise(spec)
    return k, k.options(**spec)


def build(system: Any, spec: Mapping[str, Any] | str, *, where: str = "controller", dt_control: float = 1.0,
          estimator: str | None = None, winch: Mapping[str, Any] | None = None) -> Any:
    """A :class:`~tapm_opt.interfaces.Controller` from a specification — the controller ``tapm
    simulate`` and study files build.

    Parameters
    ----------
    system : System or Scenario
        What the controller is designed on (a scenario is built into its System).
    spec : mapping or str
        ``{"type": kind, option: value, ...}`` or just the kind; unspecified options take the
        kind's defaults (``kind(name).defaults()``).
    where, dt_control, estimator, winch
        :class:`BuildContext` (``estimator`` None: the EKF, the closed loop's default).

    Raises
    ------
    ControllerSpecError
        Unknown kind or option, or an invalid value (the message names ``where.option``).
    """
    from ..models.system import as_system

    k, opts = options_from_spec(spec, where)
    ctx = BuildContext(dt_control=float(dt_control), estimator=estimator or DEFAULT_ESTIMATOR, winch=winch, where=where)
    try:
        return k.build(as_system(system), opts, ctx)
    except ControllerSpecError:
        raise
    except TapmError as exc:
        raise ControllerSpecError(f"{where}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise ControllerSpecError(f"{where}: {exc}") from None


# ------------------------------------------------------------------------------------------
# the docs' table
# ------------------------------------------------------------------------------------------


def _text(v: Any) -> str:
    if isinstance(v, float) and not v.is_integer():
        return f"{v:.4g}"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, tuple):
        return ", ".join(_text(x) for x in v)
    return "none" if v is None else str(v).lower() if isinstance(v, bool) else str(v)


def _search_text(d: Dimension | None) -> str:
    if d is None:
        return "fixed"
    if d.choices is not None:
        return "one of " + ", ".join(str(c) for c in d.choices)
    scale = "log" if d.log else "linear"
    rel = f" × {d.relative_to.replace('_', ' ')}" if d.relative_to else ""
    size = f", {d.size} values" if d.size > 1 else ""
    kind_ = "integer" if d.integer else "real"
    return f"[{d.low:g}, {d.high:g}]{rel}, {scale}, {kind_}{size}"


def markdown_table(names: tuple[str, ...] | None = None) -> str:
    """The docs' table of controller kinds and their options (``docs/controllers.md``, checked by
    ``tests/test_registry.py``; ``python -m tapm_opt.design.registry`` prints it)."""
    rows = ["| kind | option | default | unit | tuning search space | meaning |", "|---|---|---|---|---|---|"]
    for n in names or tuple(k.name for k in _BUILTIN):
        k = _KINDS[n]
        first = True
        for d in k.describe():
            doc = d["doc"].replace("|", "\\|").replace("\n", " ")
            if d["allowed"]:
                doc += " (" + ", ".join(_text(a) for a in d["allowed"]) + ")"
            rows.append(f"| {f'`{k.name}` ({k.label})' if first else ''} | `{d['name']}` | {_text(d['default'])} | "
                        f"{d['unit']} | {_search_text(d['search'])} | {doc} |")
            first = False
    return "\n".join(rows) + "\n"


if __name__ == "__main__":  # pragma: no cover
    print(markdown_table(), end="")
