"""Study files: many closed-loop cases from one TOML file, run in parallel, resumable.

A study compares controllers across sea states, mooring conditions (intact, a line broken at some
time, a thruster failed) and seeds. Every case is one :func:`run_case` — scenario with the
condition's faults, FEM plant, controller, :func:`~tapm_opt.studies.closed_loop.run_closed_loop`,
KPIs — and :func:`run_study` writes each to its own folder (layout: :mod:`tapm_opt.studies.store`).

Study file
----------
::

    [study]
    name = "mpc_vs_pid"              # required
    description = "..."              # optional
    scenario = "fpso"                # required: built-in name, or a path relative to this file
    duration = 3600.0                # required: simulated time of each case [s], > 0
    segments = 10                    # optional: FEM segments per line (default: each line's own)
    dt_control = 1.0                 # control / allocation / plant period [s] (default 1)
    dt_log = 1.0                     # logging period [s], a multiple of dt_control (default 1)
    heading = "chasing"              # "chasing" (bow into the weather, default) or "fixed"
    setpoint = "fixed"               # "fixed" (default) or "chasing" (survey eq. 38)
    true_state = false               # hand the controller the true state (default false)
    seeds = [1]                      # seeds of waves, wind and sensor noise (default [1])
    mode = "product"                 # "product" (default): every sea state x controller x condition
                                     # x seed, plus the [[cases]] below; "list": only the [[cases]]

    [[sea_states]]                   # optional; default: the scenario's first sea state
    id = "storm"                     # a sea state of the scenario ...
    [[sea_states]]
    id = "storm_12m"                 # ... or a new one: every SeaState field of the scenario schema
    Hs = 12.0                        # (Hs, Tp, gamma, wave_direction_deg, wind_speed, ...), checked
    Tp = 14.0                        # as in a scenario file

    [[controllers]]                  # at least one
    name = "PID"                     # display name, unique (default: PID, MPC for lmpc, NMPC for mpc)
    type = "pid"                     # "pid", "mpc" (nonlinear MPC) or "lmpc" (linear MPC)
    periods = [250.0, 250.0, 150.0]  # any option of tapm_opt.studies.controllers.build_controller

    [[conditions]]                   # optional; default: one condition "intact"
    name = "line 1 broken at 1800 s" # display name (default: made from the faults, or "intact")
    line_break = { line = "1", time = 1800.0 }              # a table or a list of tables
    thruster_failure = { thruster = "A3", time_fraction = 0.25 }
                                     # time [s] or time_fraction (of the case's duration), one of them

    [[cases]]                        # optional: extra (mode "product") or the only (mode "list") cases
    controller = "PID"               # controller name (default: the only controller)
    sea_state = "storm"              # sea-state id (default: the first of [[sea_states]])
    condition = "intact"             # condition name (default: the first condition)
    seed = 7                         # default: the first of study.seeds
    duration = 600.0                 # optional: overrides study.duration for this case
    name = "..."                     # optional: display name of the case

Everything is checked when the file is loaded — unknown keys (with a suggestion), types, ranges,
the scenario (its own errors are passed on under ``study.scenario``), sea-state ids, controller
types, options and values (each controller is built once, which takes about a second for a
nonlinear MPC), line and thruster ids, fault times within the run — and :class:`StudyError` lists
every problem with its field path, e.g. ``controllers[1].type = 'lqr' is not one of pid, mpc,
lmpc``. Nothing is written for an invalid study.

Cases
-----
A :class:`Case` holds ``id``, ``name``, ``labels`` (``scenario``, ``sea_state``, ``controller``,
``condition``, ``seed``) and ``inputs``: everything needed to run it, with no reference to the study
file — the full scenario dictionary (:func:`~tapm_opt.config.scenario_to_dict`) with the
condition's faults added and *only the case's sea state* among its sea states (so adding a sea state
to a study does not change the ids of the other cases), the sea-state id, the controller
specification (without the display name), the seed, the duration, the FEM segments and the
closed-loop settings. The id is the hash of the inputs (:func:`~tapm_opt.studies.store.case_id`),
so two cases with the same inputs are the same case: a study that defines one twice under different
names is an error.

Running
-------
:func:`run_study` runs the cases that are not finished yet in ``out_dir`` on local processes (or a
Dask cluster); each worker writes its case's files itself, atomically, so a run killed at any point
(even ``kill -9``) loses no finished case, and running the same study into the same folder again
resumes it. A case that raises writes ``error.json`` and the others go on.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import difflib
import json
import math
import multiprocessing
import os
import time
import tomllib
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

from .._io import atomic_write_text
from ..config import Fault, builtin_scenarios, load_scenario, scenario_from_dict, scenario_to_dict
from ..config.loader import BUILTIN_DIR, _fmt, _is_number  # the scenario loader's value checks
from ..errors import ScenarioError
from . import store
from .controllers import CONTROLLER_TYPES, PID_DEFAULTS, ControllerSpecError, build_controller
from .store import StudyError, StudyIssue

__all__ = [
    "Case",
    "Study",
    "StudySummary",
    "StudyError",
    "StudyIssue",
    "load_study",
    "study_from_dict",
    "expand_cases",
    "run_case",
    "run_study",
    "compute_kpis",
]


# ---------------------------------------------------------------------------------------------
# data
# ---------------------------------------------------------------------------------------------


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
        "closed_loop"}`` — JSON-ready; the argument of :func:`run_case`. Do not mutate.
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
    """

    name: str
    description: str
    path: Path | None
    cases: tuple[Case, ...]
    text: str = field(default="", repr=False)

    def case(self, key: str) -> Case:
        """The case with this id or name."""
        for c in self.cases:
            if key in (c.id, c.name):
                return c
        raise KeyError(f"no case {key!r} in study {self.name!r}")


@dataclass(frozen=True)
class StudySummary:
    """What :func:`run_study` did.

    Attributes
    ----------
    out_dir : Path
    finished : tuple of str
        Ids of the cases run to completion now.
    failed : tuple of str
        Ids of the cases that raised (each has ``error.json``).
    skipped : tuple of str
        Ids of the cases already finished before (not run again).
    wall_time : float
        Wall-clock time of :func:`run_study` [s].
    errors : dict
        ``{id: "Type: message"}`` of the failed cases.
    """

    out_dir: Path
    finished: tuple[str, ...]
    failed: tuple[str, ...]
    skipped: tuple[str, ...]
    wall_time: float
    errors: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """True when no case failed."""
        return not self.failed

    def __str__(self) -> str:
        return (f"{len(self.finished)} finished, {len(self.failed)} failed, {len(self.skipped)} already done "
                f"in {self.wall_time:.1f} s -> {self.out_dir}")


# ---------------------------------------------------------------------------------------------
# parsing and validation
# ---------------------------------------------------------------------------------------------

_STUDY_KEYS = {"name", "description", "scenario", "duration", "segments", "dt_control", "dt_log", "heading",
               "setpoint", "true_state", "seeds", "mode"}
_TOP_KEYS = {"study", "sea_states", "controllers", "conditions", "cases"}
_CONDITION_KEYS = {"name", "line_break", "thruster_failure"}
_FAULT_KEYS = {"line_break": {"line", "time", "time_fraction"}, "thruster_failure": {"thruster", "time", "time_fraction"}}
_CASE_KEYS = {"name", "sea_state", "controller", "condition", "seed", "duration"}
_NAMES = {"pid": "PID", "mpc": "NMPC", "lmpc": "MPC"}



class _Checker:
    """Collects every problem with its field path."""

    def __init__(self) -> None:
        self.issues: list[StudyIssue] = []

    def err(self, path: str, msg: str) -> None:
        self.issues.append(StudyIssue(path, msg))

    def keys(self, data: Mapping, allowed: set[str], path: str) -> None:
        for k in data:
            if k not in allowed:
                hint = difflib.get_close_matches(str(k), sorted(allowed), n=1, cutoff=0.6)
                self.err(f"{path}.{k}" if path else str(k),
                         "unknown key" + (f"; did you mean '{hint[0]}'?" if hint else
                                          f"; allowed keys: {', '.join(sorted(allowed))}"))

    def table(self, v: Any, path: str) -> dict | None:
        if not isinstance(v, dict):
            self.err(path, f"must be a table, got {type(v).__name__} {_fmt(v)}")
            return None
        return v

    def tables(self, v: Any, path: str) -> list[dict]:
        """A list of tables ([[path]]); a single table is accepted as a list of one."""
        if isinstance(v, dict):
            return [v]
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            self.err(path, f"must be a list of tables ([[{path}]]), got {type(v).__name__} {_fmt(v)}")
            return []
        return v

    def text(self, v: Any, path: str, *, id_like: bool = False) -> str | None:
        if id_like and isinstance(v, int) and not isinstance(v, bool):
            return str(v)
        if not isinstance(v, str) or not v.strip():
            self.err(path, f"must be non-empty text, got {type(v).__name__} {_fmt(v)}")
            return None
        return v

    def number(self, v: Any, path: str, *, unit: str = "", positive: bool = False, nonneg: bool = False,
               at_most: float | None = None) -> float | None:
        u = f" [{unit}]" if unit else ""
        if not _is_number(v):
            self.err(path, f"must be a number{u}, got {type(v).__name__} {_fmt(v)}")
            return None
        x = float(v)
        if not math.isfinite(x):
            self.err(path, f"= {_fmt(x)} must be a finite number")
            return None
        su = f" {unit}" if unit else ""
        if positive and x <= 0:
            self.err(path, f"= {_fmt(x)}{su} must be > 0")
            return None
        if nonneg and x < 0:
            self.err(path, f"= {_fmt(x)}{su} must be >= 0")
            return None
        if at_most is not None and x > at_most:
            self.err(path, f"= {_fmt(x)}{su} must be <= {_fmt(at_most)}")
            return None
        return x

    def integer(self, v: Any, path: str, *, at_least: int | None = None) -> int | None:
        if not (isinstance(v, int) and not isinstance(v, bool)):
            self.err(path, f"must be a whole number, got {type(v).__name__} {_fmt(v)}")
            return None
        if at_least is not None and v < at_least:
            self.err(path, f"= {v} must be >= {at_least}")
            return None
        return int(v)

    def choice(self, v: Any, allowed: Sequence[str], path: str) -> str | None:
        if v not in allowed:
            hint = difflib.get_close_matches(str(v), list(allowed), n=1)
            self.err(path, f"= {_fmt(v)} is not one of {', '.join(allowed)}"
                     + (f" (did you mean {hint[0]!r}?)" if hint else ""))
            return None
        return v

    def boolean(self, v: Any, path: str) -> bool | None:
        if not isinstance(v, bool):
            self.err(path, f"must be true or false, got {_fmt(v)}")
            return None
        return v

    def unique(self, names: list[tuple[int, str | None]], path: str, key: str) -> None:
        seen: dict[str, int] = {}
        for i, n in names:
            if n is None:
                continue
            if n in seen:
                self.err(f"{path}[{i}].{key}", f"= {n!r} is also used by {path}[{seen[n]}] ({key}s must be unique)")
            else:
                seen[n] = i


@dataclass(frozen=True)
class _FaultSpec:
    kind: str           # "line_break" | "thruster_failure"
    target: str         # line or thruster id
    time: float | None
    fraction: float | None
    path: str

    def at(self, duration: float) -> float:
        return float(self.time) if self.time is not None else float(self.fraction) * duration


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
    """Numbers in the form the controller takes them (``35`` and ``35.0`` give one case id)."""
    from ..control.mpc import MPCSettings

    out: dict = {"type": kind}
    if kind == "pid":
        for k, v in opts.items():
            if k in ("periods", "damping", "tau_limit") and isinstance(v, list):
                v = [float(x) if _is_number(x) else x for x in v]
            elif k == "integral_ratio" and _is_number(v):
                v = float(v)
            out[k] = v
        return out
    floats = {f.name for f in dataclasses.fields(MPCSettings) if "float" in str(f.type)} | {"period"}
    for k, v in opts.items():
        out[k] = float(v) if (k in floats and _is_number(v)) else v
    return out


@dataclass
class _Parsed:
    """The sections of a study file after checking (None where a value was bad)."""

    sc: Any = None
    name: str | None = None
    description: str = ""
    duration: float | None = None
    segments: int | None = None
    closed_loop: dict = field(default_factory=dict)
    mode: str | None = "product"
    seeds: list = field(default_factory=list)
    sea_states: list = field(default_factory=list)    # [(id, SeaState or None)]
    controllers: list = field(default_factory=list)   # [(display name, normalised spec or None)]
    conditions: list = field(default_factory=list)    # [_Condition]
    listed: list = field(default_factory=list)        # [(path, i_ss, i_ctrl, i_cond, seed, duration or None, name)]


def _parse_study_table(ck: _Checker, data: Mapping, base_dir: Path, out: _Parsed) -> None:
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
    dt_control = ck.number(st.get("dt_control", 1.0), "study.dt_control", unit="s", positive=True)
    dt_log = ck.number(st.get("dt_log", 1.0), "study.dt_log", unit="s", positive=True)
    if dt_control is not None and dt_log is not None:
        ratio = dt_log / dt_control
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            ck.err("study.dt_log", f"= {dt_log:g} s must be a whole multiple of dt_control = {dt_control:g} s")
    out.closed_loop = {
        "dt_control": dt_control, "dt_log": dt_log,
        "setpoint": ck.choice(st.get("setpoint", "fixed"), ("fixed", "chasing"), "study.setpoint"),
        "heading": ck.choice(st.get("heading", "chasing"), ("chasing", "fixed"), "study.heading"),
        "true_state": ck.boolean(st.get("true_state", False), "study.true_state")}
    out.mode = ck.choice(st.get("mode", "product"), ("product", "list"), "study.mode")
    seeds = st.get("seeds", [1])
    if not isinstance(seeds, list) or not seeds:
        ck.err("study.seeds", f"must be a non-empty list of whole numbers, got {_fmt(seeds)}")
        seeds = []
    for i, s in enumerate(seeds):
        v = ck.integer(s, f"study.seeds[{i}]", at_least=0)
        if v is not None and v in out.seeds:
            ck.err(f"study.seeds[{i}]", f"= {v} is given twice")
        elif v is not None:
            out.seeds.append(v)
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


def _parse_sea_states(ck: _Checker, data: Mapping, out: _Parsed) -> None:
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


def _parse_controllers(ck: _Checker, data: Mapping, out: _Parsed) -> None:
    from ..control.mpc import MPCSettings

    if "controllers" not in data:
        ck.err("controllers", "missing: give at least one [[controllers]] (name, type, options)")
    entries = ck.tables(data.get("controllers", []), "controllers")
    if "controllers" in data and not entries and isinstance(data["controllers"], list):
        ck.err("controllers", "is empty: give at least one [[controllers]]")
    mpc_allowed = {f.name for f in dataclasses.fields(MPCSettings)} | {"period"}
    for i, e in enumerate(entries):
        p = f"controllers[{i}]"
        if "type" not in e:
            ck.err(f"{p}.type", f"missing required field ({', '.join(CONTROLLER_TYPES)})")
        kind = ck.choice(e["type"], CONTROLLER_TYPES, f"{p}.type") if "type" in e else None
        cname = ck.text(e["name"], f"{p}.name") if "name" in e else _NAMES.get(kind or "")
        opts = {k: v for k, v in e.items() if k not in ("name", "type")}
        spec = None
        if kind is not None:
            n_issues = len(ck.issues)
            ck.keys(opts, (set(PID_DEFAULTS) if kind == "pid" else mpc_allowed) | {"name", "type"}, p)
            if len(ck.issues) == n_issues:
                spec = _normalise_spec(kind, opts)
                if out.sc is not None:
                    try:
                        build_controller(out.sc, spec, where=p)   # dry build: checks every value
                    except ControllerSpecError as exc:
                        ck.err("", str(exc))
                        spec = None
        out.controllers.append((cname or f"controller {i + 1}", spec))
    ck.unique(list(enumerate(n for n, _ in out.controllers)), "controllers", "name")


def _parse_fault(ck: _Checker, f: dict, kind: str, fp: str, sc: Any) -> _FaultSpec | None:
    target_key = "line" if kind == "line_break" else "thruster"
    ck.keys(f, _FAULT_KEYS[kind], fp)
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


def _parse_conditions(ck: _Checker, data: Mapping, out: _Parsed) -> None:
    entries = ck.tables(data.get("conditions", []), "conditions")
    for i, e in enumerate(entries):
        p = f"conditions[{i}]"
        ck.keys(e, _CONDITION_KEYS, p)
        faults = []
        for kind in ("line_break", "thruster_failure"):
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


def _parse_listed(ck: _Checker, data: Mapping, out: _Parsed) -> None:
    entries = ck.tables(data.get("cases", []), "cases")
    if out.mode == "list" and not entries:
        ck.err("cases", "study.mode = 'list' needs at least one [[cases]] entry")
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


def _expand(ck: _Checker, P: _Parsed) -> list[Case]:
    sc, duration = P.sc, float(P.duration)
    wanted = []
    if P.mode == "product":
        wanted = [("", a, b, c, s, duration, None) for a in range(len(P.sea_states))
                  for b in range(len(P.controllers)) for c in range(len(P.conditions)) for s in P.seeds]
    wanted += [(p, a, b, c, s, duration if d is None else d, n) for p, a, b, c, s, d, n in P.listed]
    base = scenario_to_dict(sc)
    cases: list[Case] = []
    where: dict[str, str] = {}
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
        faults = [Fault(kind=f.kind, time=f.at(dur), **{"line" if f.kind == "line_break" else "thruster": f.target})
                  for f in cond.faults]
        sc_dict = {**base, "sea_states": [scenario_to_dict(ss)],
                   "faults": list(base.get("faults", [])) + [scenario_to_dict(f) for f in faults]}
        inputs = {"scenario": sc_dict, "scenario_name": sc.name, "sea_state": sid, "controller": spec,
                  "seed": int(seed), "duration": float(dur), "segments": P.segments, "closed_loop": dict(P.closed_loop)}
        labels = {"scenario": sc.name, "sea_state": sid, "controller": ctrl_name, "condition": cond.label(dur),
                  "seed": int(seed)}
        name = cname or (f"{sid}, {ctrl_name}, {labels['condition']}, seed {seed}"
                         + (f", {dur:g} s" if dur != duration else ""))
        cid = store.case_id(inputs)
        here = p or f"sea_states[{i_ss}] x controllers[{i_ctrl}] x conditions[{i_cond}] x seed {seed}"
        if cid in where:
            if p and next(c for c in cases if c.id == cid).labels == labels:
                continue  # a listed case that the product already has
            ck.err(p or "cases", f"{here} has the same inputs as {where[cid]} (case {cid}): two names for one run; "
                   "remove one")
            continue
        where[cid] = here
        cases.append(Case(id=cid, name=name, labels=labels, inputs=inputs))
    names = [c.name for c in cases]
    for n in sorted({n for n in names if names.count(n) > 1}):
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
    ck = _Checker()
    ck.keys(data, _TOP_KEYS, "")
    parsed = _Parsed()
    _parse_study_table(ck, data, Path(base_dir), parsed)
    _parse_sea_states(ck, data, parsed)
    _parse_controllers(ck, data, parsed)
    _parse_conditions(ck, data, parsed)
    _parse_listed(ck, data, parsed)
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
    return Study(name=st["name"], description=st.get("description", ""), path=None if path is None else Path(path),
                 cases=cases, text=text or _to_toml(data))


def _toml_key(k: str) -> str:
    return k if k and all(c.isascii() and (c.isalnum() or c in "_-") for c in k) else json.dumps(k)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _to_toml(data: Mapping[str, Any]) -> str:
    """TOML text of a study dictionary (for ``DIR/study.toml`` of a study built without a file)."""
    lines = ["# written by tapm_opt from a study built in code"]
    for k, v in data.items():
        if isinstance(v, Mapping):
            lines += ["", f"[{_toml_key(k)}]", *(f"{_toml_key(a)} = {_toml_value(b)}" for a, b in v.items())]
        elif isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v):
            for item in v:
                lines += ["", f"[[{_toml_key(k)}]]", *(f"{_toml_key(a)} = {_toml_value(b)}" for a, b in item.items())]
        else:
            lines.insert(1, f"{_toml_key(k)} = {_toml_value(v)}")
    return "\n".join(lines) + "\n"


def load_study(path: str | Path) -> Study:
    """Read and validate a study file.

    Raises
    ------
    StudyError
        If the file is missing, is not valid TOML, or has any problem (all of them are listed).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise StudyError(f"no study file {path}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise StudyError(f"cannot read {path}: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise StudyError(f"{path.name} is not valid TOML: {exc}", source=str(path)) from None
    return study_from_dict(data, base_dir=path.resolve().parent, source=str(path), path=path.resolve(), text=text)


# ---------------------------------------------------------------------------------------------
# one case
# ---------------------------------------------------------------------------------------------


def compute_kpis(result: Any, scenario: Any) -> dict[str, float]:
    """KPIs of one case: ``tapm_opt.studies.kpis.case_kpis`` (``basic_kpis`` where it does not exist)."""
    from . import kpis as _kpis

    fn = getattr(_kpis, "case_kpis", None) or _kpis.basic_kpis
    return fn(result, scenario)


def run_case(inputs: Mapping[str, Any]) -> tuple[Any, dict[str, float]]:
    """Run one case from its inputs alone and compute its KPIs.

    Parameters
    ----------
    inputs : mapping
        :attr:`Case.inputs`: ``scenario`` (scenario dict, faults included), ``sea_state`` (id in it),
        ``controller`` (``build_controller`` spec), ``seed``, ``duration`` [s], ``segments`` (or None),
        ``closed_loop`` (``dt_control``, ``dt_log``, ``setpoint``, ``heading``, ``true_state``).

    Returns
    -------
    result : Result
        The closed-loop run; ``meta`` adds ``case_id``, ``controller_spec`` and ``seed``.
    kpis : dict
        :func:`compute_kpis` of the result against the case's scenario.

    Notes
    -----
    Deterministic: the same inputs give identical arrays (every random process is seeded from
    ``seed``); only wall-clock figures in ``meta`` (and KPIs taken from them) differ.
    """
    from ..plant.simulator import Plant
    from .closed_loop import ClosedLoopSettings, run_closed_loop

    cid = store.case_id(inputs)
    sc = scenario_from_dict(inputs["scenario"], source=f"case {cid}")
    spec = dict(inputs["controller"])
    ctrl = build_controller(sc, spec, where="controller")
    plant = Plant(sc, sea_state=sc.sea_state(inputs["sea_state"]), seed=int(inputs["seed"]),
                  segments=inputs.get("segments"))
    cl = dict(inputs.get("closed_loop") or {})
    settings = ClosedLoopSettings(duration=float(inputs["duration"]), **cl)
    result = run_closed_loop(plant, ctrl, settings, meta={"case_id": cid, "controller_spec": spec,
                                                          "seed": int(inputs["seed"])})
    return result, compute_kpis(result, sc)


def _run_case_job(cid: str, name: str, labels: dict, inputs: dict, cdir: str) -> dict:
    """Run one case and write its folder (runs in a worker process or on a Dask worker).

    Writes ``case.json`` (started), then ``result.npz``, ``kpis.json`` and ``case.json`` (finished)
    — or ``error.json`` if anything raises. Returns ``{"id", "status", "wall_time", "error"}``.
    """
    from .. import __version__

    d = Path(cdir)
    d.mkdir(parents=True, exist_ok=True)
    (d / store.ERROR_JSON).unlink(missing_ok=True)
    head = {"id": cid, "name": name, "labels": labels, "inputs": inputs, "tapm_opt_version": __version__}
    started = store.now_iso()
    w0 = time.perf_counter()
    try:
        store.write_json(d / store.CASE_JSON, {**head, "started": started})
        result, kpis = run_case(inputs)
        result.save(d / store.RESULT_NPZ)
        store.write_json(d / store.KPIS_JSON, kpis)
        wall = time.perf_counter() - w0
        store.write_json(d / store.CASE_JSON, {**head, "started": started, "finished": store.now_iso(),
                                               "wall_time": wall})
        return {"id": cid, "status": "finished", "wall_time": wall, "error": None}
    except Exception as exc:  # noqa: BLE001 - a failed case is recorded, the study goes on
        return _record_failure(d, cid, exc, traceback.format_exc(), time.perf_counter() - w0)


def _record_failure(d: Path, cid: str, exc: BaseException, tb: str, wall: float, message: str | None = None) -> dict:
    """Write ``error.json``; remove any result or KPIs of the case, so it cannot look finished."""
    err = {"type": type(exc).__name__, "message": str(exc) if message is None else message, "traceback": tb}
    for f in (store.RESULT_NPZ, store.KPIS_JSON):
        if (d / f).is_file():
            (d / f).unlink()
    store.write_json(d / store.ERROR_JSON, err)
    return {"id": cid, "status": "failed", "wall_time": wall, "error": f"{err['type']}: {err['message']}"}


# ---------------------------------------------------------------------------------------------
# a whole study
# ---------------------------------------------------------------------------------------------


class _Progress:
    """tqdm bar (cases done, ETA) with the number running and failed; or nothing."""

    def __init__(self, total: int, initial: int, enabled: bool, name: str):
        self.failed = 0
        self.running = 0
        self.bar = None
        if enabled:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, initial=initial, desc=name, unit="case", dynamic_ncols=True,
                            smoothing=0.0)
            self._post()

    def _post(self) -> None:
        if self.bar is not None:
            self.bar.set_postfix_str(f"running {self.running}, failed {self.failed}", refresh=True)

    def set_running(self, n: int) -> None:
        self.running = n
        self._post()

    def done(self, failed: bool, running: int) -> None:
        """One more case done (``failed`` or not); ``running`` cases still under way."""
        self.failed += int(failed)
        self.running = running
        if self.bar is not None:
            self.bar.set_postfix_str(f"running {self.running}, failed {self.failed}", refresh=False)
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run_study(study: Study, out_dir: str | Path, *, workers: int | None = None, scheduler: Any = None,
              progress: bool = True) -> StudySummary:
    """Run every case of ``study`` that is not finished in ``out_dir`` and write the tables.

    Parameters
    ----------
    study : Study
        From :func:`load_study`.
    out_dir : path
        Study run directory (layout: :mod:`tapm_opt.studies.store`); created if needed. Finished
        cases found there are skipped, so running the same study again resumes it; failed or
        interrupted cases are run again.
    workers : int, optional
        Local worker processes (default ``os.cpu_count()``, at most one per case to run); ``0`` runs
        the cases one after the other in this process (for debugging). Ignored with ``scheduler``.
    scheduler : str or dask.distributed.Client or cluster, optional
        Run the cases on a Dask cluster instead: a scheduler address (``"tcp://host:8786"``), a
        ``Client``, or a cluster object (``LocalCluster``). The workers write the case folders
        themselves, so ``out_dir`` must be on a file system they share. Needs the ``dask`` extra
        (``pip install 'tapm_opt[dask]'``).
    progress : bool
        Show a progress bar (done / running / failed, ETA) on stderr.

    Returns
    -------
    StudySummary

    Notes
    -----
    Local workers are started with ``spawn`` (a fork would copy the parent's threads and solver
    state), so a script that calls ``run_study`` must guard it with ``if __name__ == "__main__":``.
    Every case runs in ``_run_case_job``, which writes its own files atomically, so killing the run
    at any point (even ``kill -9``) keeps every case finished so far. A case that raises gets
    ``error.json`` (type, message, traceback); the other cases go on. At the end ``kpis.csv`` and
    ``kpis.md`` list every finished case and every failed one (with its error).
    """
    from .. import __version__

    t0 = time.perf_counter()
    if not isinstance(study, Study):
        raise TypeError(f"study must be a Study (from load_study), got {type(study).__name__}")
    if workers is not None and (not isinstance(workers, int) or isinstance(workers, bool) or workers < 0):
        raise StudyError(f"workers = {workers!r} must be a whole number >= 0 (0: run in this process)")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise StudyError(f"output {out} exists and is not a directory")
    client_info = _dask_client(scheduler) if scheduler is not None else None

    out.mkdir(parents=True, exist_ok=True)
    if study.text:
        atomic_write_text(out / store.STUDY_TOML, study.text)
    store.write_json(out / store.STUDY_JSON, {
        "name": study.name, "description": study.description,
        "study_file": None if study.path is None else str(study.path),
        "cases": [{"id": c.id, "name": c.name, "labels": c.labels, "inputs": c.inputs} for c in study.cases],
        "tapm_opt_version": __version__})

    skipped = [c.id for c in study.cases if store.is_finished(store.case_dir(out, c.id))]
    todo = [c for c in study.cases if c.id not in set(skipped)]
    bar = _Progress(len(study.cases), len(skipped), progress, study.name)
    outcomes: dict[str, dict] = {}
    try:
        if not todo:
            pass
        elif client_info is not None:
            _run_dask(todo, out, client_info[0], bar, outcomes)
        elif workers == 0:
            for c in todo:
                bar.set_running(1)
                outcomes[c.id] = _run_case_job(*_job_args(c, out))
                bar.done(outcomes[c.id]["status"] != "finished", 0)
        else:
            _run_local(todo, out, workers or os.cpu_count() or 1, bar, outcomes)
    finally:
        bar.close()
        if client_info is not None and client_info[1]:
            client_info[0].close()

    write_tables(study, out)
    finished = tuple(c.id for c in todo if outcomes.get(c.id, {}).get("status") == "finished")
    failed = tuple(c.id for c in todo if outcomes.get(c.id, {}).get("status") == "failed")
    errors = {cid: outcomes[cid]["error"] for cid in failed}
    return StudySummary(out_dir=out, finished=finished, failed=failed, skipped=tuple(skipped),
                        wall_time=time.perf_counter() - t0, errors=errors)


def _job_args(c: Case, out: Path) -> tuple:
    return (c.id, c.name, c.labels, c.inputs, str(store.case_dir(out, c.id)))


def _run_local(todo: list[Case], out: Path, workers: int, bar: _Progress, outcomes: dict) -> None:
    """Cases on a pool of spawned processes; a pool broken by a dying worker is replaced and the
    cases it had not started are run again."""
    ctx = multiprocessing.get_context("spawn")   # no fork of a parent holding threads or solver state
    pending = list(todo)
    while pending:
        n = min(workers, len(pending))
        marks = {c.id: _started_mark(out, c.id) for c in pending}
        retry: list[Case] = []
        with cf.ProcessPoolExecutor(max_workers=n, mp_context=ctx) as ex:
            futs = {ex.submit(_run_case_job, *_job_args(c, out)): c for c in pending}
            left = len(futs)
            bar.set_running(min(n, left))
            try:
                for fut in cf.as_completed(futs):
                    c = futs[fut]
                    try:
                        outcomes[c.id] = fut.result()
                    except cf.process.BrokenProcessPool as exc:
                        if _started_mark(out, c.id) == marks[c.id]:
                            retry.append(c)     # never started: run it in the next pool
                            continue
                        outcomes[c.id] = _parent_failure(out, c.id, exc, "the worker process running it died "
                                                         "(killed, out of memory or crashed)")
                    except Exception as exc:  # noqa: BLE001 - e.g. inputs that cannot be pickled
                        outcomes[c.id] = _parent_failure(out, c.id, exc, str(exc))
                    left -= 1
                    bar.done(outcomes[c.id]["status"] != "finished", min(n, left - len(retry)))
            except BaseException:
                ex.shutdown(wait=False, cancel_futures=True)
                raise
        if len(retry) == len(pending):   # pragma: no cover - a pool that dies before running anything
            for c in retry:
                outcomes[c.id] = _parent_failure(out, c.id, RuntimeError("worker pool died"),
                                                 "the worker pool died before the case started")
                bar.done(True, 0)
            return
        pending = retry


def _started_mark(out: Path, cid: str) -> float | None:
    p = store.case_dir(out, cid) / store.CASE_JSON
    try:
        return p.stat().st_mtime_ns
    except OSError:
        return None


def _parent_failure(out: Path, cid: str, exc: BaseException, message: str) -> dict:
    d = store.case_dir(out, cid)
    d.mkdir(parents=True, exist_ok=True)
    return _record_failure(d, cid, exc, "".join(traceback.format_exception(exc)), 0.0, message)


def _dask_client(scheduler: Any) -> tuple[Any, bool]:
    """(client, whether run_study owns it and must close it)."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise StudyError("scheduler=... runs the cases on Dask, which is not installed; install the extra: "
                         "pip install 'tapm_opt[dask]'") from None
    if isinstance(scheduler, Client):
        return scheduler, False
    if isinstance(scheduler, str) or hasattr(scheduler, "scheduler_address"):
        try:
            return Client(scheduler), True
        except (OSError, TimeoutError, ValueError) as exc:
            raise StudyError(f"cannot connect to the Dask scheduler {scheduler!r}: {exc}") from None
    raise StudyError(f"scheduler = {scheduler!r} must be a scheduler address ('tcp://host:port'), a "
                     "dask.distributed.Client or a cluster object")


def _run_dask(todo: list[Case], out: Path, client: Any, bar: _Progress, outcomes: dict) -> None:
    from dask.distributed import as_completed

    futs = {}
    for c in todo:
        f = client.submit(_run_case_job, *_job_args(c, out), key=f"tapm-case-{c.id}-{os.urandom(4).hex()}",
                          pure=False)
        futs[f] = c
    left = len(futs)
    bar.set_running(left)
    try:
        for fut in as_completed(list(futs)):
            c = futs[fut]
            try:
                outcomes[c.id] = fut.result()
            except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker
                outcomes[c.id] = _parent_failure(out, c.id, exc, f"Dask could not run the case: {exc}")
            left -= 1
            bar.done(outcomes[c.id]["status"] != "finished", left)
    except BaseException:
        client.cancel(list(futs))
        raise


def write_tables(study: Study, out_dir: str | Path) -> tuple[Path, Path]:
    """Write ``kpis.csv`` and ``kpis.md``: one row per finished or failed case of ``study`` (in study
    order); a failed case has an ``error`` entry instead of KPIs."""
    from . import kpis as _kpis

    out = Path(out_dir)
    rows = []
    for r in store.load_study_results(out):
        if r.id not in {c.id for c in study.cases}:
            continue
        if r.status == "finished":
            rows.append({"id": r.id, "name": r.name, "labels": r.labels, "kpis": r.kpis})
        elif r.status == "failed":
            err = r.error or {}
            rows.append({"id": r.id, "name": r.name, "labels": r.labels,
                         "kpis": {"error": f"{err.get('type', 'Error')}: {err.get('message', '')}".strip()}})
    table: Callable | None = getattr(_kpis, "kpi_table", None)
    csv_text, md_text = table(rows) if table is not None else _kpi_table(rows)
    return atomic_write_text(out / store.KPIS_CSV, csv_text), atomic_write_text(out / store.KPIS_MD, md_text)


_LABELS = ("scenario", "sea_state", "controller", "condition", "seed")


def _kpi_table(rows: list[dict]) -> tuple[str, str]:
    """CSV and Markdown of the rows (used until ``kpis.kpi_table`` exists)."""
    import csv
    import io

    kpi_cols = list(dict.fromkeys(k for r in rows for k in r["kpis"] if k != "error"))
    if any("error" in r["kpis"] for r in rows):
        kpi_cols.append("error")
    header = ["id", "name", *_LABELS, *kpi_cols]

    def cell(v: Any, md: bool) -> str:
        if v is None:
            return ""
        if isinstance(v, float):
            return f"{v:.4g}" if md else repr(v)
        return str(v).replace("|", "\\|").replace("\n", " ") if md else str(v)

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    md = ["| " + " | ".join(header) + " |", "|" + "|".join(["---"] * len(header)) + "|"]
    for r in rows:
        vals = [r["id"], r["name"], *(r["labels"].get(k) for k in _LABELS), *(r["kpis"].get(k) for k in kpi_cols)]
        w.writerow([cell(v, False) for v in vals])
        md.append("| " + " | ".join(cell(v, True) for v in vals) + " |")
    return buf.getvalue(), "\n".join(md) + "\n"
