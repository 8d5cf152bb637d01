"""Study files: parsing, validation and expansion into cases.

The file format is documented in :mod:`tapm_opt.studies.study`. :func:`load_study` reads a file,
:func:`study_from_dict` takes it parsed, :func:`expand_cases` checks everything (every problem is
collected with its field path, then :class:`~tapm_opt.studies.store.StudyError` lists them all) and
turns the product of sea states, controllers, conditions and seeds, plus the listed cases, into
:class:`Case` objects whose inputs need nothing but themselves to run.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from .._io import toml_key, toml_value
from ..config import Fault, builtin_scenarios, load_scenario, scenario_from_dict, scenario_to_dict
from .._checks import fmt as _fmt  # the scenario loader's value checks too
from ..config.loader import BUILTIN_DIR
from ..config.schema import (SENSOR_FAULT_FIELDS, SENSOR_FAULT_KINDS, FaultTargetError, buoy_of_fault,
                             sensor_fault_issues)
from ..config.loader import fem_size_issues, log_size_issues
from ..errors import ScenarioError
from . import store
from ._checks import Checker
from ..design.registry import kind as _controller_kind, kind_names as _controller_kinds
from .controllers import ControllerSpecError, build_controller
from .store import StudyError

__all__ = ["Case", "Study", "load_study", "study_from_dict", "expand_cases"]


@dataclass(frozen=True)
class Case:
    """One closed-loop run of a study.

    Attributes
    ----------
    id : str
        :func:`tapm_opt.studies.store.case_id` of ``inputs`` (12 hex digits).
    name : str
        Display name, e.g. ``"storm, PID, intact, seed 1"``.
    labels : dict
        ``{"scenario": str, "sea_state": str, "controller": str, "condition": str, "seed": int}``.
    inputs : dict
        ``{"scenario", "scenario_name", "sea_state", "controller", "seed", "duration", "segments",
        "closed_loop"}`` — JSON-ready; the argument of
        :func:`~tapm_opt.studies.jobs.run_case`. Do not mutate.
    """

    id: str
    name: str
    labels: dict
    inputs: dict


@dataclass(frozen=True)
class Study:
    """A validated study: its cases and where it came from.

    Attributes
    ----------
    name, description : str
    path : Path or None
        The study file (None for a study built from a dictionary).
    cases : tuple of Case
        In file order: the product (sea states, then controllers, then conditions, then seeds
        varying fastest), then the listed cases.
    text : str
        The study file's text as loaded (copied to ``DIR/study.toml``).
    capability : dict or None
        The study's ``[capability]`` table (options of
        :class:`~tapm_opt.design.capability.CapabilityOptions`, or with ``level = 3`` of
        :func:`~tapm_opt.studies.capability_level3.study_level3_options`, checked): the capability
        envelopes of its scenario are computed into ``DIR/capability`` and shown in the report;
        None: none.
    scenario : dict or None
        The study's scenario (as loaded, without the cases' faults), for the capability envelopes.
    verification : dict or None
        The study's ``[verification]`` table (checked,
        :func:`~tapm_opt.studies.verification_study.check_verification`): the limit-state checks
        written into ``DIR/verification.csv`` after the run and shown in the report; None: none.
    """

    name: str
    description: str
    path: Path | None
    cases: tuple[Case, ...]
    text: str = field(default="", repr=False)
    capability: dict | None = None
    scenario: dict | None = field(default=None, repr=False)
    verification: dict | None = field(default=None, repr=False)

    def case(self, key: str) -> Case:
        """The case with this id or name."""
        for c in self.cases:
            if key in (c.id, c.name):
                return c
        raise KeyError(f"no case {key!r} in study {self.name!r}")


# -- parsing and validation --------------------------------------------------------------------

_STUDY_KEYS = {"name", "description", "scenario", "duration", "segments", "break_on_overload", "dt_control",
               "dt_log", "heading",
               "setpoint", "setpoint_options", "true_state", "seeds", "mode", "estimator", "detector", "winch",
               "winch_options", "current", "redundancy"}
_TOP_KEYS = {"study", "sea_states", "controllers", "conditions", "cases", "capability", "tuning", "verification"}
_CONDITION_KEYS = {"name", "line_break", "thruster_failure", "buoy_loss", *SENSOR_FAULT_KINDS}
_FAULT_KEYS = {"line_break": {"line", "time", "time_fraction"}, "thruster_failure": {"thruster", "time", "time_fraction"},
               "buoy_loss": {"line", "joint", "point", "time", "time_fraction"}}
#: A sensor fault's study keys (file keys: ``direction_deg``, ``heading_rate_deg_s``) and their
#: Fault fields, units and the conversion to SI.
_SENSOR_KEYS = {"line": ("line", "", None), "end_time": ("end_time", "s", None), "speed": ("speed", "m/s", None),
                "direction_deg": ("direction", "deg", math.radians), "rate": ("rate", "N/s", None),
                "rate_rel": ("rate_rel", "1/s", None), "heading_rate_deg_s": ("heading_rate", "deg/s", math.radians),
                "factor": ("factor", "", None), "gyro": ("gyro", "", None)}
for _k in SENSOR_FAULT_KINDS:
    _need, _may = SENSOR_FAULT_FIELDS[_k]
    _FAULT_KEYS[_k] = {"time", "time_fraction", "end_time"} | {
        key for key, (fld, _u, _c) in _SENSOR_KEYS.items() if fld in _need or fld in _may}
_CASE_KEYS = {"name", "sea_state", "controller", "condition", "seed", "duration"}


@dataclass(frozen=True)
class _FaultSpec:
    kind: str           # "line_break" | "thruster_failure" | "buoy_loss"
    target: str         # line or thruster id
    time: float | None
    fraction: float | None
    path: str
    joint: int | None = None    # buoy_loss: the buoy's joint (resolved from point when that is given)
    point: str | None = None    # buoy_loss: the point type id given instead of joint
    params: tuple = ()          # a sensor fault's other Fault fields, (name, SI value) pairs

    def at(self, duration: float) -> float:
        return float(self.time) if self.time is not None else float(self.fraction) * duration

    def fault(self, duration: float) -> Fault:
        """The scenario's :class:`Fault` of this spec in a run of ``duration`` [s]."""
        if self.kind == "buoy_loss":
            return Fault(kind="buoy_loss", time=self.at(duration), line=self.target, joint=self.joint)
        if self.kind in SENSOR_FAULT_KINDS:
            return Fault(kind=self.kind, time=self.at(duration), **dict(self.params))
        return Fault(kind=self.kind, time=self.at(duration),
                     **{"line" if self.kind == "line_break" else "thruster": self.target})


@dataclass(frozen=True)
class _Condition:
    name: str | None
    faults: tuple[_FaultSpec, ...]
    path: str

    def label(self, duration: float) -> str:
        if self.name is not None:
            return self.name
        if not self.faults:
            return "intact"
        parts = []
        for f in self.faults:
            if f.kind in SENSOR_FAULT_KINDS:
                on = f" {f.target}" if f.target else ""
                parts.append(f"{f.kind.replace('_', ' ')}{on} at {f.at(duration):g} s")
                continue
            if f.kind == "buoy_loss":
                parts.append(f"line {f.target} buoy at joint {f.joint} lost at {f.at(duration):g} s")
                continue
            verb = "broken" if f.kind == "line_break" else "failed"
            what = "line" if f.kind == "line_break" else "thruster"
            parts.append(f"{what} {f.target} {verb} at {f.at(duration):g} s")
        return ", ".join(parts)


def _resolve_scenario(value: str, base_dir: Path) -> str | Path:
    """A built-in name as is; anything else as a path relative to the study file's folder."""
    p = Path(value)
    if not p.suffix and "/" not in value and "\\" not in value and (BUILTIN_DIR / f"{value}.toml").is_file():
        return value
    return p if p.is_absolute() else (base_dir / p)


def _normalise_spec(kind: str, opts: dict) -> dict:
    """Numbers in the form the controller takes them (``35`` and ``35.0`` give one case id): the
    kind's own ``normalise`` (:mod:`tapm_opt.design.registry`)."""
    k = _controller_kind(kind)
    return {"type": kind, **(k.normalise(opts) if k.normalise is not None else dict(opts))}


@dataclass
class _Parsed:
    """The sections of a study file after checking (None where a value was bad)."""

    sc: Any = None
    name: str | None = None
    description: str = ""
    duration: float | None = None
    segments: int | None = None
    break_on_overload: str | None = None
    closed_loop: dict = field(default_factory=dict)
    mode: str | None = "product"
    seeds: list = field(default_factory=list)
    sea_states: list = field(default_factory=list)    # [(id, SeaState or None)]
    controllers: list = field(default_factory=list)   # [(display name, normalised spec or None)]
    controller_loop: list = field(default_factory=list)  # [closed-loop overrides of each controller]
    conditions: list = field(default_factory=list)    # [_Condition]
    listed: list = field(default_factory=list)        # [(path, i_ss, i_ctrl, i_cond, seed, duration or None, name)]
    base_dir: Path = Path(".")                        # the study file's folder (relative paths)


def _parse_study_table(ck: Checker, data: Mapping, base_dir: Path, out: _Parsed) -> None:
    if "study" not in data:
        ck.err("study", "missing required section [study] (name, scenario, duration, ...)")
    st = (ck.table(data["study"], "study") if "study" in data else None) or {}
    ck.keys(st, _STUDY_KEYS, "study")
    for key in ("name", "scenario", "duration"):
        if key not in st:
            ck.err(f"study.{key}", "missing required field")
    out.name = ck.text(st["name"], "study.name") if "name" in st else None
    out.description = st.get("description", "")
    if not isinstance(out.description, str):
        ck.err("study.description", f"must be text, got {type(out.description).__name__}")
        out.description = ""
    if "duration" in st:
        out.duration = ck.number(st["duration"], "study.duration", unit="s", positive=True)
    if "segments" in st:
        out.segments = ck.integer(st["segments"], "study.segments", at_least=2)
    if "break_on_overload" in st:
        out.break_on_overload = ck.choice(st["break_on_overload"], ("mbs", "sampled", "never"),
                                          "study.break_on_overload")
    dt_control = ck.number(st.get("dt_control", 1.0), "study.dt_control", unit="s", positive=True)
    if dt_control is not None and dt_control < 0.01:
        ck.err("study.dt_control",
               f"= {dt_control:g} s must be >= 0.01 s (100 Hz, faster than any position-control loop)")
        dt_control = None
    dt_log = ck.number(st.get("dt_log", 1.0), "study.dt_log", unit="s", positive=True)
    if dt_control is not None and dt_log is not None:
        ratio = dt_log / dt_control
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            ck.err("study.dt_log", f"= {dt_log:g} s must be a whole multiple of dt_control = {dt_control:g} s")
    out.closed_loop = {
        "dt_control": dt_control, "dt_log": dt_log,
        **_setpoint_fields(ck, st, "study", {"setpoint": "fixed"}),
        "heading": ck.choice(st.get("heading", "chasing"), ("chasing", "fixed"), "study.heading"),
        "true_state": ck.boolean(st.get("true_state", False), "study.true_state"),
        **_ESTIMATION_DEFAULTS, **_estimation_fields(ck, st, "study"), **_winch_fields(ck, st, "study")}
    out.mode = ck.choice(st.get("mode", "product"), ("product", "list"), "study.mode")
    seeds = st.get("seeds", [1])
    if not isinstance(seeds, list) or not seeds:
        ck.err("study.seeds", f"must be a non-empty list of whole numbers, got {_fmt(seeds)}")
        seeds = []
    if len(seeds) > MAX_CASES:   # each seed is at least one case: refused before each is checked
        ck.err("study.seeds", f"has {len(seeds)} seeds; a study holds at most {MAX_CASES} cases, each seed at least "
               "one: give fewer seeds, or split the study into several (each with its own --out)")
        seeds = []
    seen: set[int] = set()
    for i, s in enumerate(seeds):
        v = ck.integer(s, f"study.seeds[{i}]", at_least=0)
        if v is not None and v in seen:
            ck.err(f"study.seeds[{i}]", f"= {v} is given twice")
        elif v is not None:
            out.seeds.append(v)
            seen.add(v)
    scen = ck.text(st["scenario"], "study.scenario") if "scenario" in st else None
    if scen is not None:
        try:
            out.sc = load_scenario(_resolve_scenario(scen, base_dir))
        except ScenarioError as exc:
            msg = str(exc)
            if "no built-in scenario or file" in msg:
                msg = (f"= {scen!r}: no built-in scenario or file of that name (relative paths are taken from "
                       f"{base_dir}); built-in scenarios: {', '.join(builtin_scenarios())}")
            ck.err("study.scenario", msg)
    if out.sc is not None and out.segments is not None:  # FEM memory and cost, before any case starts
        for iss in fem_size_issues(out.sc, out.segments, where="study.segments"):
            ck.err(iss.path, iss.message)


def _parse_sea_states(ck: Checker, data: Mapping, out: _Parsed) -> None:
    sc = out.sc
    entries = ck.tables(data.get("sea_states", []), "sea_states")
    for i, e in enumerate(entries):
        p = f"sea_states[{i}]"
        if "id" not in e:
            ck.err(f"{p}.id", "missing required field (a sea-state id of the scenario, or the id of a new one)")
            continue
        sid = ck.text(e["id"], f"{p}.id", id_like=True)
        if sid is None or sc is None:
            out.sea_states.append((sid, None))
            continue
        known = [s.id for s in sc.sea_states]
        if len(e) == 1:  # a sea state of the scenario
            if sid not in known:
                hint = difflib.get_close_matches(sid, known, n=1)
                ck.err(f"{p}.id", f"= {sid!r} is not a sea state of scenario {sc.name!r} ("
                       + (f"did you mean {hint[0]!r}? " if hint else "")
                       + f"sea states: {', '.join(known)}); to define a new one give its fields (Hs, Tp, ...)")
            out.sea_states.append((sid, sc.sea_state(sid) if sid in known else None))
            continue
        if sid in known:
            ck.err(f"{p}.id", f"= {sid!r} is already a sea state of scenario {sc.name!r}: give only its id, "
                   "or choose a new id for the new sea state")
            out.sea_states.append((sid, None))
            continue
        # a new sea state: checked by the scenario loader, as part of the scenario
        d = {**scenario_to_dict(sc), "sea_states": [dict(e)], "faults": []}
        try:
            out.sea_states.append((sid, scenario_from_dict(d).sea_states[0]))
        except ScenarioError as exc:
            for iss in exc.issues:
                ck.err(iss.path.replace("sea_states[0]", p, 1) if iss.path.startswith("sea_states[0]") else p,
                       iss.message)
            out.sea_states.append((sid, None))
    ck.unique(list(enumerate(s for s, _ in out.sea_states)), "sea_states", "id")
    if "sea_states" in data and not entries and isinstance(data["sea_states"], list):
        ck.err("sea_states", "is empty: give at least one [[sea_states]] or leave it out")
    if "sea_states" not in data and sc is not None:
        if not sc.sea_states:
            ck.err("sea_states", f"scenario {sc.name!r} defines no sea state: give at least one [[sea_states]]")
        else:
            out.sea_states.append((sc.sea_states[0].id, sc.sea_states[0]))


def _setpoint_fields(ck: Checker, table: Mapping, where: str, default: dict, inherited: str | None = None) -> dict:
    """``setpoint`` and ``setpoint_options`` of a [study] or [[controllers]] table, checked;
    options with a setpoint (its own, else ``inherited``) that takes none are an error."""
    from ..control.fatigue_setpoint import FatigueOptions, FatigueSetpointError
    from ..control.setpoint_opt import METHODS, SetpointOptError, SetpointOptions
    from .closed_loop import SETPOINT_KINDS

    out = dict(default)
    if "setpoint" in table:
        out["setpoint"] = ck.choice(table["setpoint"], SETPOINT_KINDS, f"{where}.setpoint")
    if "setpoint_options" in table:
        opts = ck.table(table["setpoint_options"], f"{where}.setpoint_options")
        kind = out.get("setpoint", inherited)
        if opts is not None and kind is not None and kind not in (*METHODS, "fatigue"):
            ck.err(f"{where}.setpoint_options", f"are options of the optimal setpoints ({', '.join(METHODS)}) "
                   f"and of 'fatigue'; the setpoint here is {kind!r}")
        elif opts is not None:
            try:
                if kind == "fatigue":
                    FatigueOptions.from_mapping(opts, where=f"{where}.setpoint_options")
                else:
                    SetpointOptions.from_mapping(opts, where=f"{where}.setpoint_options")
                out["setpoint_options"] = dict(opts)
            except (SetpointOptError, FatigueSetpointError) as exc:
                ck.err("", str(exc))
    return out


#: The estimation every case's inputs name explicitly (the runner's defaults when the study names
#: none), so that a change of the runner's default changes the case ids instead of reusing results
#: computed with the old one.
def _estimation_defaults() -> dict:
    from .closed_loop import DEFAULT_ESTIMATOR

    return {"estimator": DEFAULT_ESTIMATOR, "detector": "tension"}


_ESTIMATION_DEFAULTS = _estimation_defaults()


def _estimation_fields(ck: Checker, table: Mapping, where: str) -> dict:
    """``estimator``, ``detector``, ``redundancy`` and ``current`` ("known" | "estimated": the
    layers take the sea state's current or its on-line estimate,
    :mod:`tapm_opt.estimation.current_profile`) of a [study] or [[controllers]] table, checked (only
    the ones given; the study's defaults are :data:`_ESTIMATION_DEFAULTS`, and ``current`` and
    ``redundancy`` are named only when given, so the case ids of a study without them are
    unchanged)."""
    from .closed_loop import CURRENT_MODES, DETECTOR_KINDS, ESTIMATOR_KINDS, REDUNDANCY_KINDS

    return {k: ck.choice(table[k], kinds, f"{where}.{k}")
            for k, kinds in (("estimator", ESTIMATOR_KINDS), ("detector", DETECTOR_KINDS),
                             ("redundancy", REDUNDANCY_KINDS), ("current", CURRENT_MODES)) if k in table}


def _winch_fields(ck: Checker, table: Mapping, where: str) -> dict:
    """``winch`` and ``winch_options`` of a [study] or [[controllers]] table, checked (only the
    ones given, so a study that names neither keeps the runner's default, no winch control, and its
    case ids)."""
    from ..control.winch import WinchError, WinchSettings
    from .closed_loop import WINCH_KINDS

    out: dict = {}
    if "winch" in table:
        out["winch"] = ck.choice(table["winch"], WINCH_KINDS, f"{where}.winch")
    if "winch_options" in table:
        opts = table["winch_options"]
        if not isinstance(opts, Mapping):
            ck.err(f"{where}.winch_options", f"must be a table of options, got {_fmt(opts)}")
        else:
            try:
                WinchSettings.from_mapping(opts)
                out["winch_options"] = dict(opts)
            except WinchError as exc:
                ck.err(f"{where}.winch_options", str(exc))
    return out


def _loop(study: dict, controller: dict) -> dict:
    """The closed-loop settings of one controller's cases: the study's, with the controller's own
    setpoint in place of the study's and its options over the study's (key by key); a controller
    whose setpoint is fixed or chased takes none of the study's options, nor one whose setpoint
    takes other options (the fatigue-aware layer's against the optimal setpoints')."""
    from ..control.setpoint_opt import METHODS

    out = dict(study)
    for key in ("setpoint", "estimator", "detector", "winch", "winch_options", "current", "redundancy"):
        if key in controller:
            out[key] = controller[key]
    out.pop("setpoint_options", None)

    def family(kind: Any) -> str:   # the optimal setpoints share their options; the fatigue layer has its own
        return "fatigue" if kind == "fatigue" else "optimal" if kind in METHODS else str(kind)

    inherited = (study.get("setpoint_options") or {}) if family(study.get("setpoint")) == family(out.get("setpoint")) else {}
    opts = {**inherited, **(controller.get("setpoint_options") or {})}
    if opts and out.get("setpoint") in (*METHODS, "fatigue"):
        out["setpoint_options"] = opts
    return out


def _case_sea_states(candidates: list, ss: Any, spec: Mapping) -> list[dict]:
    """The sea states a case's scenario carries: its own only (so a case's id does not depend on
    the other sea states), or, for a sea-state supervised controller (``supervisor`` not false,
    or a ``gain_table``), the supervisor's ``candidates`` — every sea state of the scenario, in its
    order, with the study's versions in their place and the study's own appended — the same for
    every case of the controller."""
    if spec.get("supervisor", False) is False and spec.get("gain_table") is None:
        return [scenario_to_dict(ss)]
    out = [scenario_to_dict(s) for s in candidates]
    return out if any(s.id == ss.id for s in candidates) else out + [scenario_to_dict(ss)]


def _embedded_gain_table(ck: Checker, path: str, base_dir: Path, where: str) -> dict | None:
    """The gain table at ``path`` (relative to the study file) as its JSON dict, so a case carries
    it in its inputs (a worker needs no file of the client's; a changed table changes the case
    ids); None, with the issue recorded, when it cannot be read."""
    from ..control.gain_table import GainTableError, load_gain_table

    p = Path(path)
    try:
        return load_gain_table(p if p.is_absolute() else base_dir / p).to_dict()
    except GainTableError as exc:
        ck.err(where, f"= {path!r}: {exc}")
        return None


def _parse_tuning(ck: Checker, data: Mapping) -> None:
    """The ``[tuning]`` table (``tapm tune``), checked here too so a study file is checked whole."""
    if "tuning" not in data:
        return
    if not isinstance(data["tuning"], Mapping):
        ck.err("tuning", f"must be a table, got {type(data['tuning']).__name__}")
        return
    from .tuning_space import TuningError, tuning_settings

    try:
        tuning_settings(data["tuning"])
    except TuningError as exc:
        ck.err("", str(exc))


def _parse_verification(ck: Checker, data: Mapping, out: _Parsed) -> None:
    """The ``[verification]`` table (limit-state checks after the run), checked against the
    study's scenario (line types), sea states (probabilities) and duration (``t_start``)."""
    if "verification" not in data:
        return
    from .verification_study import check_verification

    sea = [s for s, _ in out.sea_states] if all(s is not None for s, _ in out.sea_states) else None
    check_verification(ck, data["verification"], out.sc, sea, duration=out.duration)


def _embedded_design(ck: Checker, path: Any, base_dir: Path, where: str) -> dict | None:
    """The controller specification of a tuned design file at ``path`` (relative to the study
    file), embedded in the cases' inputs like a gain table; None, with the issue recorded, when it
    cannot be read."""
    from ..design.registry import load_design

    if not isinstance(path, str) or not path.strip():
        ck.err(where, f"= {path!r} must be the path of a design file (tapm tune's tuned/<controller>.toml)")
        return None
    p = Path(path)
    try:
        return load_design(p if p.is_absolute() else base_dir / p, where)
    except ControllerSpecError as exc:
        ck.err("", str(exc))
        return None


def _check_tune(ck: Checker, kind: str, e: Mapping, p: str) -> None:
    """A controller's ``tune`` table (``tapm tune``: its search space narrowed or fixed)."""
    from .tuning_space import TuningError, search_space

    if not isinstance(e["tune"], Mapping):
        ck.err(f"{p}.tune", f"= {e['tune']!r} must be a table, e.g. tune = {{ w_thrust = [1.0, 100.0] }}")
        return
    try:
        search_space(kind, {}, e["tune"], where=p)
    except TuningError as exc:
        ck.err("", str(exc))


def _parse_controllers(ck: Checker, data: Mapping, out: _Parsed) -> None:
    from .closed_loop import combination_issues

    if "controllers" not in data:
        ck.err("controllers", "missing: give at least one [[controllers]] (name, type, options)")
    entries = ck.tables(data.get("controllers", []), "controllers")
    if "controllers" in data and not entries and isinstance(data["controllers"], list):
        ck.err("controllers", "is empty: give at least one [[controllers]]")
    for i, e in enumerate(entries):
        p = f"controllers[{i}]"
        design = _embedded_design(ck, e["design"], out.base_dir, f"{p}.design") if "design" in e else None
        if design is not None:
            if "type" in e and e["type"] != design["type"]:
                ck.err(f"{p}.type", f"= {e['type']!r}, but the design is a {design['type']!r}")
            e = {**{k: v for k, v in design.items()}, **{k: v for k, v in e.items() if k not in ("design", "type")}}
        elif "design" in e:
            e = {k: v for k, v in e.items() if k != "design"}
        if "type" not in e:
            ck.err(f"{p}.type", f"missing required field ({', '.join(_controller_kinds())}), or a design")
        kind = ck.choice(e["type"], _controller_kinds(), f"{p}.type") if "type" in e else None
        cname = ck.text(e["name"], f"{p}.name") if "name" in e else (_controller_kind(kind).label if kind else None)
        if "tune" in e and kind is not None:
            _check_tune(ck, kind, e, p)
        opts = {k: v for k, v in e.items()
                if k not in ("name", "type", "setpoint", "setpoint_options", "estimator", "detector", "winch",
                             "winch_options", "tune", "current", "redundancy")}
        loop = {**_setpoint_fields(ck, e, p, {}, inherited=out.closed_loop.get("setpoint")),
                **_estimation_fields(ck, e, p), **_winch_fields(ck, e, p)}
        merged = _loop(out.closed_loop, loop)
        for name, message in combination_issues(merged):   # the runner's rules, once
            ck.err(f"{p}.{name}", f"{message} (here or in [study])")
        spec = None
        if kind is not None:
            n_issues = len(ck.issues)
            allowed = set(_controller_kind(kind).option_names())
            ck.keys(opts, allowed | {"name", "type"}, p)
            if len(ck.issues) == n_issues:
                spec = _normalise_spec(kind, opts)
                if isinstance(spec.get("gain_table"), str):
                    spec["gain_table"] = _embedded_gain_table(ck, spec["gain_table"], out.base_dir, f"{p}.gain_table")
                if out.sc is not None and len(ck.issues) == n_issues:
                    try:
                        build_controller(out.sc, spec, where=p,   # dry build: checks every value
                                         dt_control=out.closed_loop.get("dt_control") or 1.0,
                                         estimator=merged.get("estimator") or _ESTIMATION_DEFAULTS["estimator"],
                                         winch=(merged.get("winch_options") or {})
                                         if merged.get("winch") == "tension" else None)
                    except ControllerSpecError as exc:
                        ck.err("", str(exc))
                        spec = None
        out.controllers.append((cname or f"controller {i + 1}", spec))
        out.controller_loop.append(loop)
    ck.unique(list(enumerate(n for n, _ in out.controllers)), "controllers", "name")


def _parse_fault(ck: Checker, f: dict, kind: str, fp: str, sc: Any) -> _FaultSpec | None:
    target_key = "thruster" if kind == "thruster_failure" else "line"
    ck.keys(f, _FAULT_KEYS[kind], fp)
    if kind == "buoy_loss":
        return _parse_buoy_loss(ck, f, fp, sc)
    if kind in SENSOR_FAULT_KINDS:
        return _parse_sensor_fault(ck, f, kind, fp, sc)
    target = None
    if target_key not in f:
        ck.err(f"{fp}.{target_key}", f"missing required field (the {target_key} id)")
    else:
        target = ck.text(f[target_key], f"{fp}.{target_key}", id_like=True)
        ids = None if sc is None else [x.id for x in (sc.lines if kind == "line_break" else sc.thrusters)]
        if target is not None and ids is not None and target not in ids:
            hint = difflib.get_close_matches(target, ids, n=1)
            ck.err(f"{fp}.{target_key}", f"= {target!r} is not a {target_key} of scenario {sc.name!r}"
                   + (f" (did you mean {hint[0]!r}?)" if hint else "") + f"; {target_key}s: {', '.join(ids)}")
            target = None
    t = frac = None
    if ("time" in f) == ("time_fraction" in f):
        ck.err(fp, "give exactly one of 'time' [s] and 'time_fraction' (of the case's duration)")
    elif "time" in f:
        t = ck.number(f["time"], f"{fp}.time", unit="s", nonneg=True)
    else:
        frac = ck.number(f["time_fraction"], f"{fp}.time_fraction", nonneg=True, at_most=1.0)
    if target is None or (t is None and frac is None):
        return None
    return _FaultSpec(kind, target, t, frac, fp)


def _fault_time(ck: Checker, f: dict, fp: str) -> tuple[float | None, float | None, bool]:
    """(time, time_fraction, ok) of a fault table: exactly one of them, checked."""
    if ("time" in f) == ("time_fraction" in f):
        ck.err(fp, "give exactly one of 'time' [s] and 'time_fraction' (of the case's duration)")
        return None, None, False
    if "time" in f:
        t = ck.number(f["time"], f"{fp}.time", unit="s", nonneg=True)
        return t, None, t is not None
    frac = ck.number(f["time_fraction"], f"{fp}.time_fraction", nonneg=True, at_most=1.0)
    return None, frac, frac is not None


def _parse_sensor_fault(ck: Checker, f: dict, kind: str, fp: str, sc: Any) -> _FaultSpec | None:
    """A sensor fault (:data:`~tapm_opt.config.schema.SENSOR_FAULT_KINDS`): its time and its
    fields, each checked here for type and then by the scenario's rules
    (:func:`~tapm_opt.config.schema.sensor_fault_issues`), the key named."""
    ok = True
    params: dict = {}
    for key in sorted(set(f) & set(_SENSOR_KEYS)):
        fld, unit, conv = _SENSOR_KEYS[key]
        if fld == "line":
            v = ck.text(f[key], f"{fp}.{key}", id_like=True)
        elif fld == "gyro":
            v = ck.integer(f[key], f"{fp}.{key}", at_least=1)
        else:
            v = ck.number(f[key], f"{fp}.{key}", unit=unit)
            v = conv(v) if (v is not None and conv is not None) else v
        ok &= v is not None
        params[fld] = v
    t, frac, t_ok = _fault_time(ck, f, fp)
    if not (ok and t_ok):
        return None
    probe = Fault(kind=kind, time=t if t is not None else 0.0, **params)
    keys = {fld: key for key, (fld, _u, _c) in _SENSOR_KEYS.items()}
    ids = [ln.id for ln in sc.lines] if sc is not None else ([params["line"]] if params.get("line") else [])
    bad = [(n, m) for n, m in sensor_fault_issues(probe, ids) if not (n == "end_time" and t is None)]
    for name, msg in bad:
        key = keys.get(name, name)
        if key in f and _SENSOR_KEYS.get(key, (0, 0, None))[2] is not None and msg.startswith("= "):
            msg = f"= {_fmt(f[key])} {_SENSOR_KEYS[key][1]}: " + msg.split(" ", 2)[2]   # the file's value, in its unit
        ck.err(f"{fp}.{key}", msg)
    if bad:
        return None
    return _FaultSpec(kind, str(params.get("line") or ""), t, frac, fp, params=tuple(sorted(params.items())))


def _parse_buoy_loss(ck: Checker, f: dict, fp: str, sc: Any) -> _FaultSpec | None:
    """A ``buoy_loss`` fault: the composite line, its buoy's joint (index from the anchor up) or
    point type id, and the time; the target checked against the scenario
    (:func:`tapm_opt.config.schema.buoy_of_fault`) with the field named."""
    ok = True
    line = joint = point = None
    if "line" not in f:
        ck.err(f"{fp}.line", "missing required field (the id of the composite line that loses the buoy)")
        ok = False
    else:
        line = ck.text(f["line"], f"{fp}.line", id_like=True)
        ok &= line is not None
    if "joint" in f:
        joint = ck.integer(f["joint"], f"{fp}.joint", at_least=0)
        ok &= joint is not None
    if "point" in f:
        point = ck.text(f["point"], f"{fp}.point", id_like=True)
        ok &= point is not None
    t, frac, t_ok = _fault_time(ck, f, fp)
    if ok and sc is not None:
        try:
            joint = buoy_of_fault(sc, line, joint, point)[1]
        except FaultTargetError as exc:
            ck.err(f"{fp}.{exc.field}", str(exc))
            ok = False
    if not (ok and t_ok) or joint is None:
        return None
    return _FaultSpec("buoy_loss", line, t, frac, fp, joint, point)


def _parse_conditions(ck: Checker, data: Mapping, out: _Parsed) -> None:
    entries = ck.tables(data.get("conditions", []), "conditions")
    for i, e in enumerate(entries):
        p = f"conditions[{i}]"
        ck.keys(e, _CONDITION_KEYS, p)
        faults = []
        for kind in ("line_break", "thruster_failure", "buoy_loss", *SENSOR_FAULT_KINDS):
            if kind in e:
                many = isinstance(e[kind], list)
                for j, f in enumerate(ck.tables(e[kind], f"{p}.{kind}")):
                    fs = _parse_fault(ck, f, kind, f"{p}.{kind}[{j}]" if many else f"{p}.{kind}", out.sc)
                    if fs is not None:
                        faults.append(fs)
        out.conditions.append(_Condition(ck.text(e["name"], f"{p}.name") if "name" in e else None, tuple(faults), p))
    if "conditions" not in data:
        out.conditions.append(_Condition("intact", (), "conditions"))
    elif not entries and isinstance(data["conditions"], list):
        ck.err("conditions", "is empty: give at least one [[conditions]] or leave it out (intact)")
    ck.unique(list(enumerate(c.name for c in out.conditions)), "conditions", "name")


def _parse_listed(ck: Checker, data: Mapping, out: _Parsed) -> None:
    entries = ck.tables(data.get("cases", []), "cases")
    if out.mode == "list" and not entries:
        ck.err("cases", "study.mode = 'list' needs at least one [[cases]] entry")
    if len(entries) > MAX_CASES:   # refused before each entry is checked
        ck.err("cases", f"has {len(entries)} [[cases]] entries; a study holds at most {MAX_CASES} cases: split it "
               "into several studies (each with its own --out)")
        return
    choices = {"sea_state": ([s for s, _ in out.sea_states], "sea state id", "sea_states"),
               "controller": ([n for n, _ in out.controllers], "controller name", "controllers"),
               "condition": ([c.name for c in out.conditions], "condition name", "conditions")}
    for i, e in enumerate(entries):
        p = f"cases[{i}]"
        ck.keys(e, _CASE_KEYS, p)
        picked = []
        for key, (names, what, section) in choices.items():
            if key not in e:
                if key == "controller" and len(names) > 1:
                    ck.err(f"{p}.{key}", f"missing: the study has {len(names)} controllers ({', '.join(names)})")
                picked.append(0 if names and (key != "controller" or len(names) == 1) else None)
                continue
            v = ck.text(e[key], f"{p}.{key}", id_like=True)
            if v is not None and v not in names:
                hint = difflib.get_close_matches(v, [str(n) for n in names], n=1)
                ck.err(f"{p}.{key}", f"= {v!r} is not a {what} of [[{section}]]"
                       + (f" (did you mean {hint[0]!r}?)" if hint else "") + f"; defined: {', '.join(map(str, names))}")
            picked.append(names.index(v) if v in names else None)
        seed = ck.integer(e["seed"], f"{p}.seed", at_least=0) if "seed" in e else (out.seeds or [None])[0]
        dur = ck.number(e["duration"], f"{p}.duration", unit="s", positive=True) if "duration" in e else None
        cname = ck.text(e["name"], f"{p}.name") if "name" in e else None
        if None not in picked and seed is not None and ("duration" not in e or dur is not None):
            out.listed.append((p, *picked, seed, dur, cname))


#: Most cases one study may hold; a larger one is refused when its file is read, before any case
#: is built. Each case is a folder with its own copy of its inputs, a row of the KPI tables and a
#: section of the report: split a larger design space into several studies.
MAX_CASES = 10_000

#: Most bytes of one case's inputs as JSON (the scenario, the controller with any embedded gain
#: table, the settings: about 9 kB for fpso), which ``cases/<id>/case.json`` stores in full.
MAX_CASE_INPUT_BYTES = 16 * 2**20

#: Most bytes of the inputs of all the cases of a study together (what the ``case.json`` files
#: of a run hold together, before indentation): 1 GiB.
MAX_STUDY_INPUT_BYTES = 2**30


def _mib(n: float) -> str:
    return f"{n / 2**20:.3g} MiB" if n >= 2**20 else f"{n / 2**10:.3g} KiB"


def _count_issue(P: _Parsed, n: int) -> str:
    """What the study's case count is made of, and the limit (the count is above it)."""
    def many(k: int, what: str) -> str:
        return f"{k} {what}" + ("" if k == 1 else "s")

    parts = []
    if P.mode == "product":
        parts.append(" x ".join((many(len(P.sea_states), "sea state"), many(len(P.controllers), "controller"),
                                 many(len(P.conditions), "condition"), many(len(P.seeds), "seed"))))
    if P.listed:
        parts.append(many(len(P.listed), "listed case"))
    return (f"the study has {n} cases ({' + '.join(parts)}); at most {MAX_CASES} cases are allowed in one study: "
            "give fewer seeds, sea states, controllers or conditions, or split it into several studies (each "
            "with its own --out)")


def _inputs_size_issue(name: str, inputs: dict, size: int) -> str:
    """A case's inputs are above :data:`MAX_CASE_INPUT_BYTES`: say which part is large."""
    parts = []
    for k, v in (inputs.get("scenario") or {}).items():
        parts.append((len(store.canonical_json(v)), f"scenario.{k}"))
    for k, v in inputs.items():
        if k != "scenario":
            parts.append((len(store.canonical_json(v)), k))
    big, where = max(parts) if parts else (size, "inputs")
    return (f"case {name!r}: its inputs are {_mib(size)} of JSON, above the {_mib(MAX_CASE_INPUT_BYTES)} one case "
            f"may hold (every case stores them in full in cases/<id>/case.json); the largest part is {where}, "
            f"{_mib(big)}")


def _expand(ck: Checker, P: _Parsed) -> list[Case]:
    sc, duration = P.sc, float(P.duration)
    wanted = []
    if P.mode == "product":
        n = len(P.sea_states) * len(P.controllers) * len(P.conditions) * len(P.seeds)
        if n + len(P.listed) > MAX_CASES:   # counted, not built
            ck.err("cases", _count_issue(P, n + len(P.listed)))
            return []
        wanted = [("", a, b, c, s, duration, None) for a in range(len(P.sea_states))
                  for b in range(len(P.controllers)) for c in range(len(P.conditions)) for s in P.seeds]
    wanted += [(p, a, b, c, s, duration if d is None else d, n) for p, a, b, c, s, d, n in P.listed]
    if len(wanted) > MAX_CASES:
        ck.err("cases", _count_issue(P, len(wanted)))
        return []
    for p, dur in sorted({(p, d) for p, _, _, _, _, d, _ in wanted}):  # the size of each run's log
        for iss in log_size_issues(sc, dur, P.closed_loop["dt_log"], where=f"{p}.duration" if p else "study.duration",
                                   dt_name="study.dt_log"):
            ck.err(iss.path, iss.message)
    base = scenario_to_dict(sc)
    if P.break_on_overload is not None:
        base["plant"] = {**base.get("plant", {}), "break_on_overload": P.break_on_overload}
    # a supervisor's candidates: the scenario's sea states (the study's versions in their place),
    # then the ones the study defines
    study_ss = {sid: ss for sid, ss in P.sea_states if ss is not None}
    candidates = [study_ss.get(s.id, s) for s in sc.sea_states]
    candidates += [ss for sid, ss in study_ss.items() if sid not in {s.id for s in sc.sea_states}]
    cases: list[Case] = []
    where: dict[str, str] = {}
    total = 0
    for p, i_ss, i_ctrl, i_cond, seed, dur, cname in wanted:
        sid, ss = P.sea_states[i_ss]
        ctrl_name, spec = P.controllers[i_ctrl]
        cond = P.conditions[i_cond]
        late = [f for f in cond.faults if f.at(dur) > dur]
        for f in late:
            ck.err(f"{f.path}.time", f"= {f.at(dur):g} s is after the end of the run ({dur:g} s"
                   + (f", {p}" if p else "") + ")")
        if late:
            continue
        faults = [f.fault(dur) for f in cond.faults]
        sc_dict = {**base, "sea_states": _case_sea_states(candidates, ss, spec),
                   "faults": list(base.get("faults", [])) + [scenario_to_dict(f) for f in faults]}
        inputs = {"scenario": sc_dict, "scenario_name": sc.name, "sea_state": sid, "controller": spec,
                  "seed": int(seed), "duration": float(dur), "segments": P.segments,
                  "closed_loop": _loop(P.closed_loop, P.controller_loop[i_ctrl])}
        labels = {"scenario": sc.name, "sea_state": sid, "controller": ctrl_name, "condition": cond.label(dur),
                  "seed": int(seed)}
        name = cname or (f"{sid}, {ctrl_name}, {labels['condition']}, seed {seed}"
                         + (f", {dur:g} s" if dur != duration else ""))
        cid, size = store.case_id_and_size(inputs)
        total += size
        if size > MAX_CASE_INPUT_BYTES:
            ck.err(p or "study.scenario", _inputs_size_issue(name, inputs, size))
            return cases
        if total > MAX_STUDY_INPUT_BYTES:
            ck.err("cases", f"the inputs of the study's cases are above {_mib(MAX_STUDY_INPUT_BYTES)} of JSON "
                   f"together at its case {len(cases) + 1} of {len(wanted)} ({_mib(size)} each; every case stores "
                   "them in full in cases/<id>/case.json): give fewer cases or a smaller scenario")
            return cases
        here = p or f"sea_states[{i_ss}] x controllers[{i_ctrl}] x conditions[{i_cond}] x seed {seed}"
        if cid in where:
            if p and next(c for c in cases if c.id == cid).labels == labels:
                continue  # a listed case that the product already has
            ck.err(p or "cases", f"{here} has the same inputs as {where[cid]} (case {cid}): two names for one run; "
                   "remove one")
            continue
        where[cid] = here
        cases.append(Case(id=cid, name=name, labels=labels, inputs=inputs))
    from collections import Counter

    for n in sorted(n for n, k in Counter(c.name for c in cases).items() if k > 1):
        ck.err("cases", f"two cases are named {n!r}; give them distinct names")
    if not cases and not ck.issues:
        ck.err("cases", "the study has no case")
    return cases


def expand_cases(data: Mapping[str, Any], *, base_dir: str | Path = ".", source: str = "") -> tuple[Case, ...]:
    """Validate a parsed study file and expand it into its cases.

    Parameters
    ----------
    data : mapping
        The study file as parsed TOML (see the module docstring).
    base_dir : path
        Folder that relative scenario paths are taken from (the study file's folder).
    source : str
        Name of the study in error messages.

    Returns
    -------
    tuple of Case
        The product (sea states, controllers, conditions, seeds; the last varying fastest) unless
        ``mode = "list"``, then the listed cases that are not in it already.

    Raises
    ------
    StudyError
        With every problem found, each naming its field path.
    """
    if not isinstance(data, Mapping):
        raise StudyError(f"a study must be a table of sections, got {type(data).__name__}", source=source)
    ck = Checker()
    ck.keys(data, _TOP_KEYS, "")
    parsed = _Parsed(base_dir=Path(base_dir))
    _parse_study_table(ck, data, Path(base_dir), parsed)
    _parse_sea_states(ck, data, parsed)
    _parse_controllers(ck, data, parsed)
    _parse_conditions(ck, data, parsed)
    _parse_listed(ck, data, parsed)
    _parse_tuning(ck, data)
    _parse_verification(ck, data, parsed)
    if not ck.issues:
        cases = _expand(ck, parsed)
    if ck.issues:
        raise StudyError(list(dict.fromkeys(ck.issues)), source=source)
    return tuple(cases)


def study_from_dict(data: Mapping[str, Any], *, base_dir: str | Path = ".", source: str = "",
                    path: str | Path | None = None, text: str = "") -> Study:
    """A validated :class:`Study` from a parsed study file (see :func:`expand_cases`)."""
    cases = expand_cases(data, base_dir=base_dir, source=source)
    st = data["study"]
    cap = _capability_table(data, base_dir, source)
    sc_dict = None
    if cap is not None:   # the study's scenario as loaded: every sea state, no fault
        sc_dict = {**scenario_to_dict(load_scenario(_resolve_scenario(st["scenario"], Path(base_dir)))), "faults": []}
    ver = dict(data["verification"]) if "verification" in data else None
    return Study(name=st["name"], description=st.get("description", ""), path=None if path is None else Path(path),
                 cases=cases, text=text or _to_toml(data), capability=cap, scenario=sc_dict, verification=ver)


def _capability_table(data: Mapping[str, Any], base_dir: str | Path, source: str) -> dict | None:
    """The ``[capability]`` table, its options checked by building them (None without one)."""
    if "capability" not in data:
        return None
    from ..design.capability import (
        CONDITIONS,
        STUDY_OPTIONS,
        CapabilityError,
        CapabilityOptions,
        case_names,
        resolve_options,
    )

    tab = data["capability"]
    if not isinstance(tab, Mapping):
        raise StudyError(f"capability must be a table of options ({', '.join(STUDY_OPTIONS)}), got {tab!r}",
                         source=source)
    lv3 = []
    if tab.get("level") == 3:   # time domain, the controllers in the loop (studies.capability_level3)
        from .capability_level3 import check_failed_line, study_level3_options

        try:
            lv3 = study_level3_options(tab)
        except (CapabilityError, TypeError, ValueError) as exc:
            raise StudyError(f"capability.{exc}", source=source) from None
    else:
        bad = sorted(set(tab) - set(STUDY_OPTIONS))
        if bad:
            raise StudyError(f"capability.{bad[0]}: unknown option; allowed: {', '.join(STUDY_OPTIONS)} "
                             "(level = 3: more)", source=source)
        try:
            CapabilityOptions(**dict(tab))
        except (CapabilityError, TypeError, ValueError) as exc:
            raise StudyError(f"capability: {exc}", source=source) from None
    one_line = tab.get("condition", "all") not in CONDITIONS and tab.get("level") != 3
    vane = tab.get("heading") == "weathervane"   # refused with a locked turret
    if "sea_state" in tab or one_line or "failed_line" in tab or vane:   # of the study's scenario
        sc = load_scenario(_resolve_scenario(data["study"]["scenario"], Path(base_dir)))
        if vane:
            try:
                if lv3:
                    lv3[0].resolved(sc)
                else:
                    resolve_options(sc, CapabilityOptions(**dict(tab)))
            except CapabilityError as exc:
                raise StudyError(f"capability.{exc}", source=source) from None
        ids = [ss.id for ss in sc.sea_states]
        if "sea_state" in tab and tab["sea_state"] not in ids:
            raise StudyError(f"capability.sea_state = {tab['sea_state']!r} is not a sea state of the scenario "
                             f"({', '.join(ids)})", source=source)
        try:   # condition = "line <id>", failed_line: a line of the scenario
            if one_line:
                case_names(sc, tab["condition"])
            for opt in lv3[:1]:
                check_failed_line(sc, opt)
        except CapabilityError as exc:
            raise StudyError(f"capability.{exc}", source=source) from None
    return dict(tab)


# -- TOML text of a study built in code -------------------------------------------------------


def _to_toml(data: Mapping[str, Any]) -> str:
    """TOML text of a study dictionary (for ``DIR/study.toml`` of a study built without a file)."""
    lines = ["# written by tapm_opt from a study built in code"]
    for k, v in data.items():
        if isinstance(v, Mapping):
            lines += ["", f"[{toml_key(k)}]", *(f"{toml_key(a)} = {toml_value(b)}" for a, b in v.items())]
        elif isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v):
            for item in v:
                lines += ["", f"[[{toml_key(k)}]]", *(f"{toml_key(a)} = {toml_value(b)}" for a, b in item.items())]
        else:
            lines.insert(1, f"{toml_key(k)} = {toml_value(v)}")
    return "\n".join(lines) + "\n"


# -- reading a study file ----------------------------------------------------------------------


def load_study(path: str | Path) -> Study:
    """Read and validate a study file.

    Raises
    ------
    StudyError
        If the file is missing, is not valid TOML, or has any problem (all of them are listed).
    """
    path = Path(path)
    data, text = store.read_study_file(path)
    return study_from_dict(data, base_dir=path.resolve().parent, source=str(path), path=path.resolve(), text=text)
