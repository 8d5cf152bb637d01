"""Load, parse and validate scenarios.

Parsing is driven by the field metadata of :mod:`tapm_opt.config.schema`; every problem is
collected with its field path (``lines[3].length``) so a user sees all of them at once.

Size: one module on purpose — the metadata-driven parser, its cross-field rules and the
size and plausibility checks all read the same field paths and issue lists.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import tomllib
import types
import typing
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal, get_args, get_origin, get_type_hints

import numpy as np

from .._checks import fmt as _fmt, is_number as _is_number  # one definition for every layer
from ..errors import ScenarioError, ScenarioIssue
from ..geometry import fairleads_B, merge_sectors
from ..strain_table import secant_of_rows, table_problem
from .schema import (DEVELOPING_FIELDS, SENSOR_FAULT_KINDS, Fault, FaultTargetError, Scenario, buoy_of_fault,
                     sensor_fault_issues)

BUILTIN_DIR = Path(__file__).parent / "scenarios"

__all__ = [
    "load_scenario",
    "scenario_from_dict",
    "scenario_to_dict",
    "validate",
    "fem_size_issues",
    "log_size_issues",
    "builtin_scenarios",
    "BUILTIN_DIR",
]


def builtin_scenarios() -> list[str]:
    """Names of the scenarios shipped with tapm_opt."""
    return sorted(p.stem for p in BUILTIN_DIR.glob("*.toml"))


# --------------------------------------------------------------------------------------------
# generic parsing from dataclass metadata
# --------------------------------------------------------------------------------------------


class _Missing:
    pass


_MISSING = _Missing()


def file_key(f: dataclasses.Field) -> str:
    """Key of a field in the scenario file (``<name>_deg`` for angles)."""
    unit = f.metadata.get("unit", "")
    return {"deg": f"{f.name}_deg", "deg/s": f"{f.name}_deg_s"}.get(unit, f.name)


def _file_key_of_fault(name: str) -> str:
    """The file key of :class:`~tapm_opt.config.schema.Fault` field ``name`` (``direction_deg``)."""
    return file_key({f.name: f for f in dataclasses.fields(Fault)}[name])


def _unwrap_optional(tp: Any) -> tuple[Any, bool]:
    if get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(get_args(tp)) == 2:
            return args[0], True
    return tp, False


class _Parser:
    def __init__(self) -> None:
        self.issues: list[ScenarioIssue] = []

    def err(self, path: str, msg: str) -> None:
        self.issues.append(ScenarioIssue(path, msg))

    # dataclass ---------------------------------------------------------------------------
    def dataclass(self, cls: type, data: Any, path: str) -> Any:
        if not isinstance(data, dict):
            self.err(path, f"must be a table of fields, got {type(data).__name__} {_fmt(data)}")
            return None
        hints = get_type_hints(cls)
        fields = [f for f in dataclasses.fields(cls)]
        keys = {file_key(f): f for f in fields}
        for k in data:
            if k not in keys:
                hint = difflib.get_close_matches(k, list(keys), n=1, cutoff=0.6)
                for suffix in ("_deg", "_deg_s"):
                    if not hint and f"{k}{suffix}" in keys:
                        hint = [f"{k}{suffix}"]
                sugg = f"; did you mean '{hint[0]}'?" if hint else f"; allowed keys: {', '.join(sorted(keys))}"
                self.err(f"{path}.{k}" if path else k, f"unknown key{sugg}")
        kwargs: dict[str, Any] = {}
        ok = True
        for key, f in keys.items():
            fpath = f"{path}.{key}" if path else key
            if key not in data:
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                    unit = f.metadata.get("unit", "")
                    self.err(fpath, f"missing required field ({f.metadata.get('doc', '')}"
                             + (f" [{unit}]" if unit else "") + ")")
                    ok = False
                continue
            val = self.value(hints[f.name], data[key], fpath, f.metadata)
            if val is _MISSING:
                ok = False
                continue
            kwargs[f.name] = val
        if not ok:
            return None
        try:
            return cls(**kwargs)
        except (TypeError, ValueError) as exc:  # pragma: no cover - schema bug
            self.err(path, str(exc))
            return None

    # values ------------------------------------------------------------------------------
    def value(self, tp: Any, v: Any, path: str, meta: Any) -> Any:
        tp, optional = _unwrap_optional(tp)
        if v is None:
            if optional:
                return None
            self.err(path, "must not be empty")
            return _MISSING
        unit = meta.get("unit", "")
        check = meta.get("check")
        origin = get_origin(tp)
        if dataclasses.is_dataclass(tp):
            out = self.dataclass(tp, v, path)
            return _MISSING if out is None else out
        if origin is tuple and dataclasses.is_dataclass(get_args(tp)[0]):
            if not isinstance(v, list):
                self.err(path, f"must be a list of tables ([[{path}]]), got {type(v).__name__}")
                return _MISSING
            items = [self.dataclass(get_args(tp)[0], item, f"{path}[{i}]") for i, item in enumerate(v)]
            return _MISSING if any(x is None for x in items) else tuple(items)
        if origin is Literal:
            allowed = get_args(tp)
            if v not in allowed:
                hint = difflib.get_close_matches(str(v), [str(a) for a in allowed], n=1)
                sugg = f" (did you mean {hint[0]!r}?)" if hint else ""
                self.err(path, f"= {_fmt(v)} is not one of {', '.join(repr(a) for a in allowed)}{sugg}")
                return _MISSING
            return v
        if tp is str:
            if meta.get("id_like") and isinstance(v, int) and not isinstance(v, bool):
                return str(v)
            if not isinstance(v, str):
                self.err(path, f"must be text, got {type(v).__name__} {_fmt(v)}")
                return _MISSING
            return self.text(v, path, check)
        if tp is bool:
            if not isinstance(v, bool):
                self.err(path, f"must be true or false, got {_fmt(v)}")
                return _MISSING
            return v
        if tp is int:
            if not (isinstance(v, int) and not isinstance(v, bool)):
                self.err(path, f"must be a whole number, got {type(v).__name__} {_fmt(v)}")
                return _MISSING
            return self.checked(v, path, check, unit)
        if tp is float:
            return self.number(v, path, check, unit)
        if origin is tuple:
            return self.array(tp, v, path, meta)
        raise TypeError(f"unsupported schema type {tp!r} at {path}")  # pragma: no cover

    def text(self, v: str, path: str, check: Any) -> Any:
        """Free text through its length check (the message names the length, not a long value)."""
        msg = check(v) if check is not None else None
        if msg:
            self.err(path, msg)
            return _MISSING
        return v

    def number(self, v: Any, path: str, check: Any, unit: str) -> Any:
        if not _is_number(v):
            self.err(path, f"must be a number{f' [{unit}]' if unit else ''}, got {type(v).__name__} {_fmt(v)}")
            return _MISSING
        v = float(v)
        if not math.isfinite(v):
            self.err(path, f"= {_fmt(v)} must be a finite number")
            return _MISSING
        out = self.checked(v, path, check, unit)
        if out is _MISSING:
            return out
        return math.radians(v) if unit in ("deg", "deg/s") else v

    def checked(self, v: Any, path: str, check: Any, unit: str) -> Any:
        if check is not None:
            msg = check(v)
            if msg:
                u = f" {unit}" if unit and unit not in ("deg", "deg/s") else (" deg" if unit else "")
                self.err(path, f"= {_fmt(v)}{u} {msg}")
                return _MISSING
        return v

    def array(self, tp: Any, v: Any, path: str, meta: Any) -> Any:
        shape = meta.get("shape")
        unit = meta.get("unit", "")
        inner = get_args(tp)[0]
        if inner is str:
            if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
                self.err(path, "must be a list of text entries")
                return _MISSING
            texts = [self.text(s, f"{path}[{i}]", meta.get("check")) for i, s in enumerate(v)]
            return _MISSING if any(t is _MISSING for t in texts) else tuple(texts)
        if not isinstance(v, list):
            self.err(path, f"must be a list of numbers with shape {shape}, got {type(v).__name__} {_fmt(v)}")
            return _MISSING
        nested = get_origin(inner) is tuple
        if nested:
            if not all(isinstance(row, list) for row in v):
                self.err(path, f"must be a list of rows (a matrix) with shape {shape}")
                return _MISSING
            got = (len(v),) + ((len(v[0]),) if v else (0,))
            if any(len(row) != got[1] for row in v):
                self.err(path, "rows must all have the same length")
                return _MISSING
            flat = [x for row in v for x in row]
        else:
            got = (len(v),)
            flat = list(v)
        if shape is not None and any(s != -1 and s != g for s, g in zip(shape, got)) and (v or not nested):
            self.err(path, f"must have shape {tuple(shape)}, got {got}")
            return _MISSING
        if shape is not None and len(shape) == 2 and not flat and shape[0] != -1:
            self.err(path, f"must have shape {tuple(shape)}, got {got}")
            return _MISSING
        out = []
        bad = False
        for i, x in enumerate(flat):
            r = self.number(x, f"{path}[{i}]" if not nested else f"{path}[{i // got[1]}][{i % got[1]}]",
                            meta.get("check"), unit)
            bad |= r is _MISSING
            out.append(r)
        if bad:
            return _MISSING
        if nested:
            return tuple(tuple(out[i * got[1]:(i + 1) * got[1]]) for i in range(got[0]))
        return tuple(out)


# --------------------------------------------------------------------------------------------
# cross-field (physical) validation
# --------------------------------------------------------------------------------------------


def _dupes(items: Any, what: str, issues: list[ScenarioIssue]) -> None:
    ids = [getattr(x, "id") for x in items]
    for name, n in Counter(ids).items():
        if n > 1:
            idx = [i for i, x in enumerate(ids) if x == name]
            issues.append(ScenarioIssue(f"{what}[{idx[1]}].id", f"= {name!r} is used by {what}{idx} (ids must be unique)"))


def _matrix_checks(M: np.ndarray, path: str, issues: list[ScenarioIssue], *, pd: bool, psd: bool = False) -> None:
    scale = max(float(np.max(np.abs(M))), 1e-300)
    if np.max(np.abs(M - M.T)) > 1e-6 * scale:
        i, j = np.unravel_index(np.argmax(np.abs(M - M.T)), M.shape)
        issues.append(ScenarioIssue(path, f"must be symmetric: [{i}][{j}] = {M[i, j]:g} but [{j}][{i}] = {M[j, i]:g}"))
        return
    eig = np.linalg.eigvalsh(0.5 * (M + M.T))
    if pd and eig.min() <= 0:
        issues.append(ScenarioIssue(path, f"must be positive definite; smallest eigenvalue {eig.min():g}"))
    if psd and eig.min() < -1e-9 * scale:
        issues.append(ScenarioIssue(path, f"must be positive semidefinite; smallest eigenvalue {eig.min():g}"))


# Plausibility bounds (docs/scenarios.md, "Plausibility checks", gives the reason for each).

#: Strain at MBS, MBS/EA, of mooring materials: chain about 1.5 %, steel wire about 1 %, polyester
#: and HMPE ropes up to about 20 %; the bounds are generous on both sides.
STRAIN_AT_MBS_RANGE = (1.0e-4, 0.5)
#: Axial wave speed sqrt(EA / mass_per_length) [m/s]: steel about 5000, carbon fibre about 11 000.
MAX_AXIAL_WAVE_SPEED = 2.0e4
#: mass_per_length over the cross-section pi d^2 / 4 of the hydrodynamic diameter [kg/m^3]: fibre
#: ropes about 600-1000, chain on its hydrodynamic diameter about 8000, on its bar diameter 25 000.
EFFECTIVE_DENSITY_RANGE = (100.0, 5.0e4)
#: Surge and sway mass (with added mass) over the mass of water in the box length_pp x breadth x
#: draught (ships: block coefficient 0.5-0.9, added mass 0.05-1 of the mass), and the yaw radius of
#: gyration sqrt(M33/M11) over length_pp (ships: about 0.25-0.35).
VESSEL_MASS_RANGE = (0.05, 5.0)
GYRATION_RANGE = (0.05, 1.0)
#: Largest linear damping over mass, D_ii / M_ii [1/s] (hulls: decay times M/D of 10-1000 s), and
#: quadratic damping over mass, d_i / M_ii [1/m, 1/rad].
MAX_DAMPING_RATE = 1.0
MAX_QUADRATIC_DAMPING_RATE = 100.0
#: Largest mean height of the wind area above water [m]: wind_area_frontal / breadth and
#: wind_area_lateral / length_pp; also the highest CO may lie above the waterline (reference_point
#: z up to draught + this above the keel).
MAX_WINDAGE_HEIGHT = 200.0
#: Largest coefficient of variation MBS_std / MBS (measured: 0.05-0.15).
MAX_MBS_COV = 0.5
#: A line (or winch max_length) longer than this many times (horizontal + vertical span) is a typo.
MAX_LENGTH_FACTOR = 10.0
#: A riser longer than this many times (horizontal offset + water depth) is a typo (lazy-wave
#: risers are about 2 x the depth).
MAX_RISER_LENGTH_FACTOR = 3.0
#: Largest riser top tension over its submerged weight (submerged_weight x length).
MAX_RISER_TENSION_FACTOR = 10.0
#: Breaking limit of wave steepness H / L (Michell 1893), applied to Hs / (g Tp^2 / 2 pi).
MAX_STEEPNESS = 1.0 / 7.0
#: FEM nodes of all lines together, and node updates per simulated second (nodes / FEM step; the
#: compiled kernel does about 3e7 a second on one core, so the bound is a few seconds of computing
#: per simulated second; the built-in scenarios with their 20 segments need about 2e4).
MAX_FEM_NODES = 100_000
MAX_FEM_NODE_UPDATES = 1.0e8
#: Largest in-memory log of a simulation [bytes]: rows (duration / dt_log) x channels x 8 bytes.
MAX_LOG_BYTES = 2**30
#: Highest the fairleads may lie above the water line [m] (turret.fairlead_depth >= -this): chain
#: stoppers on deck stand at most about the freeboard of the largest hulls above the water.
MAX_FAIRLEAD_HEIGHT = 30.0
#: Smallest acceleration all thrusters together may give the vessel, sum(max_thrust) / M11
#: [m/s^2]: DP and thruster-assist vessels have 0.005-0.05 (the built-ins 0.03); 1e-4 is a thrust
#: given in kN instead of N.
MIN_THRUST_ACCELERATION = 1.0e-4
#: An anchor this fraction of the water depth above the seabed is raised far; when every anchor is,
#: the water depth is wrong (e.g. given in feet), not the anchors.
RAISED_ANCHOR_FRACTION = 0.5


def _metres(x: float) -> str:
    """A distance for messages: whole metres, or 3 digits when huge."""
    return f"{x:.0f}" if abs(x) < 1e7 else f"{x:.3g}"


def _scenario_lines_ok(sc: Scenario) -> bool:
    ids = {t.id for t in sc.line_types}
    pids = {p.id for p in sc.point_types}
    return bool(sc.lines) and all(s.type in ids and (s.top is None or s.top in pids)
                                  for ln in sc.lines if ln.type is not None and ln.length is not None
                                  for s in ln.parts) and all(ln.type is not None and ln.length is not None
                                                             for ln in sc.lines)


def _shared(ln: Any, n: int) -> tuple[int, ...]:
    """Segments of each section of ``ln`` when the whole line has ``n`` (a ``--segments`` override)."""
    if not ln.composite:
        return (n,)
    import dataclasses as _dc
    return _dc.replace(ln, sections=tuple(_dc.replace(s, segments=None) for s in ln.sections),
                       segments=n).section_segments()


def fem_size_issues(sc: Scenario, segments: int | None = None, *, where: str | None = None) -> list[ScenarioIssue]:
    """Memory and cost of the FEM plant of ``sc``, before anything is allocated.

    Parameters
    ----------
    sc : Scenario
    segments : int, optional
        Segments per line overriding the scenario's (e.g. ``--segments``).
    where : str, optional
        Path to name in the issue (default: ``lines[i].segments`` of the scenario, or ``segments``).

    Returns
    -------
    list of ScenarioIssue
        Empty when the segment count, the total node count (at most :data:`MAX_FEM_NODES`) and the
        estimated node updates per simulated second (at most :data:`MAX_FEM_NODE_UPDATES`) are within
        bounds. The FEM step is estimated as half the time an axial wave takes to cross the shortest
        segment, ``0.5 (L/n) / sqrt(EA/m)`` (the plant's own stable step is about 0.7 of that).
    """
    from .schema import FEM_BYTES_PER_NODE, MAX_SEGMENTS, gib

    if not _scenario_lines_ok(sc):
        return []
    n = [int(segments) if segments is not None else int(sum(ln.section_segments())) for ln in sc.lines]

    def path(i: int) -> str:
        if where is not None:
            return where
        return f"lines[{i}].segments" if segments is None else "segments"

    if segments is not None and not 2 <= segments <= MAX_SEGMENTS:
        return [ScenarioIssue(path(0), f"= {segments} must be in [2, {MAX_SEGMENTS}] (the FEM arrays would take about "
                                       f"{gib(len(n) * (segments + 1) * FEM_BYTES_PER_NODE)})")]
    if any(not 2 <= k <= MAX_SEGMENTS for k in n):
        return []  # reported by the field check
    nodes = sum(k + 1 for k in n)
    if nodes > MAX_FEM_NODES:
        i = int(np.argmax(n))
        return [ScenarioIssue(path(i), f"= {n[i]}: {len(n)} lines of up to {max(n)} segments make {nodes} FEM nodes "
                                       f"(about {gib(nodes * FEM_BYTES_PER_NODE)}), above the limit {MAX_FEM_NODES}")]
    steps = []
    for i, ln in enumerate(sc.lines):
        nk = ln.section_segments() if segments is None else _shared(ln, n[i])
        for sec, k in zip(ln.parts, nk):
            lt = sc.line_type_by_id(sec.type)
            c = math.sqrt(lt.max_EA / lt.mass_per_length)
            steps.append((0.5 * sec.length / k / c, i, c, sec.length / k))
    dt, i, c, seg = min(steps)
    rate = nodes / dt if dt > 0 else math.inf
    if not rate <= MAX_FEM_NODE_UPDATES:
        return [ScenarioIssue(path(i), (
            f"= {n[i]}: the FEM step would be about {dt:.3g} s (segments of {seg:.3g} m of line {sc.lines[i].id!r}, "
            f"axial wave speed sqrt(EA/m) = {c:.3g} m/s), {rate:.3g} node updates per simulated second for "
            f"{nodes} nodes, above the limit {MAX_FEM_NODE_UPDATES:g}: use fewer segments"))]
    return []


def log_channels(sc: Scenario) -> int:
    """Columns of a closed-loop log of ``sc``: time, vessel state and loads, 3 per line, 3 per thruster."""
    return 36 + 3 * (len(sc.lines) + len(sc.thrusters))


def log_size_issues(sc: Scenario, duration: float, dt_log: float, *, where: str = "duration",
                    dt_name: str = "dt_log", channels: int | None = None) -> list[ScenarioIssue]:
    """The in-memory log of a run of ``duration`` logged every ``dt_log`` seconds must hold at least
    two samples and fit in :data:`MAX_LOG_BYTES` (rows x channels x 8 bytes). ``where`` and
    ``dt_name`` name the options or fields of the duration and the logging interval; ``channels``
    defaults to :func:`log_channels`."""
    from .schema import gib

    if not (math.isfinite(duration) and math.isfinite(dt_log) and duration > 0 and dt_log > 0):
        return []
    if duration < dt_log * (1 - 1e-9):
        return [ScenarioIssue(where, f"= {duration:g} s is shorter than the logging interval, {dt_log:g} s "
                                     f"({dt_name}): the run would log a single sample")]
    ch = log_channels(sc) if channels is None else channels
    rows = duration / dt_log + 2
    size = rows * ch * 8.0
    if size <= MAX_LOG_BYTES:
        return []
    longest = (MAX_LOG_BYTES / (ch * 8.0) - 2) * dt_log
    return [ScenarioIssue(where, f"= {duration:g} s logged every {dt_log:g} s ({dt_name}) makes {rows:.3g} rows of "
                                 f"{ch} channels, about {gib(size)}, above {gib(MAX_LOG_BYTES)}: at most "
                                 f"{longest:.4g} s at that interval")]


def _field_issues(obj: Any, path: str, issues: list[ScenarioIssue]) -> None:
    """Each field's own type and range check on a scenario built in code (``dataclasses.replace``):
    finite numbers, the ``check=`` of :func:`schema.spec`, the values of a ``Literal``."""
    hints = get_type_hints(type(obj))
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        fpath = f"{path}.{file_key(f)}" if path else file_key(f)
        if v is None or (f.default is not dataclasses.MISSING and _same(v, f.default)):
            continue
        tp, _ = _unwrap_optional(hints[f.name])
        if dataclasses.is_dataclass(v):
            _field_issues(v, fpath, issues)
            continue
        if isinstance(v, tuple) and v and dataclasses.is_dataclass(v[0]):
            for i, x in enumerate(v):
                _field_issues(x, f"{fpath}[{i}]", issues)
            continue
        if get_origin(tp) is Literal:
            if v not in get_args(tp):
                issues.append(ScenarioIssue(fpath, f"= {_fmt(v)} is not one of {', '.join(map(repr, get_args(tp)))}"))
            continue
        unit, check = f.metadata.get("unit", ""), f.metadata.get("check")
        texts = [(fpath, v)] if isinstance(v, str) else (
            [(f"{fpath}[{i}]", x) for i, x in enumerate(v)] if isinstance(v, tuple) and v and isinstance(v[0], str)
            else [])
        for sub, x in texts:
            msg = check(x) if check is not None and isinstance(x, str) else None
            if msg:
                issues.append(ScenarioIssue(sub, msg))
        for sub, x in _numbers(v, fpath):
            if not math.isfinite(x):
                issues.append(ScenarioIssue(sub, f"= {_fmt(x)} must be a finite number"))
                continue
            xf = math.degrees(x) if unit in ("deg", "deg/s") else x
            msg = check(xf) if check is not None else None
            if msg:
                issues.append(ScenarioIssue(sub, f"= {_fmt(xf)} {msg}"))


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def _numbers(v: Any, path: str):
    if isinstance(v, tuple):
        for i, x in enumerate(v):
            yield from _numbers(x, f"{path}[{i}]")
    elif _is_number(v) or isinstance(v, (np.floating, np.integer)):
        yield path, v.item() if isinstance(v, np.generic) else v


def _plausibility(sc: Scenario, fl_x: np.ndarray, fl_y: np.ndarray, issues: list[ScenarioIssue]) -> None:
    """Bounds a valid-looking scenario must also keep to be physical (docs/scenarios.md,
    "Plausibility checks")."""
    env, v = sc.environment, sc.vessel
    g = env.gravity
    if v.draught >= env.water_depth:
        issues.append(ScenarioIssue("vessel.draught", f"= {v.draught:g} m is not less than the water depth "
                                                      f"{env.water_depth:g} m: the vessel would be aground"))
    box = env.water_density * v.length_pp * v.breadth * v.draught  # mass of the displaced box L B T
    M = v.M
    mass_ok = [not any(i.path.startswith("vessel.mass_matrix") for i in issues)] * 3  # PD, symmetric
    lo, hi = VESSEL_MASS_RANGE
    for k, dof in ((0, "surge"), (1, "sway")):
        if mass_ok[k] and not lo * box <= M[k, k] <= hi * box:
            mass_ok[k] = False
            issues.append(ScenarioIssue(f"vessel.mass_matrix[{k}][{k}]", (
                f"= {M[k, k]:g} kg is {M[k, k] / box:.3g} x the mass of water in the box length_pp x breadth x "
                f"draught ({box:.4g} kg); a hull's {dof} mass with its added mass is {lo:g}-{hi:g} x that")))
    if mass_ok[0] and mass_ok[2]:
        rg = math.sqrt(M[2, 2] / M[0, 0]) / v.length_pp
        lo, hi = GYRATION_RANGE
        if not lo <= rg <= hi:
            mass_ok[2] = False
            issues.append(ScenarioIssue("vessel.mass_matrix[2][2]", (
                f"= {M[2, 2]:g} kg m^2 gives a yaw radius of gyration sqrt(M33/M11) of {rg:.3g} x length_pp, "
                f"outside [{lo:g}, {hi:g}] (ships: about 0.25-0.35)")))
    for k, dof in enumerate(("surge", "sway", "yaw")):
        if not mass_ok[k]:
            continue
        if v.D_lin[k, k] > MAX_DAMPING_RATE * M[k, k]:
            issues.append(ScenarioIssue(f"vessel.linear_damping[{k}][{k}]", (
                f"= {v.D_lin[k, k]:g} would stop a {dof} motion within M/D = {M[k, k] / v.D_lin[k, k]:.3g} s, under "
                f"{1 / MAX_DAMPING_RATE:g} s (hulls: 10-1000 s): check the units")))
        if v.quadratic_damping[k] > MAX_QUADRATIC_DAMPING_RATE * M[k, k]:
            issues.append(ScenarioIssue(f"vessel.quadratic_damping[{k}]", (
                f"= {v.quadratic_damping[k]:g} would stop a {dof} motion within M/d = "
                f"{M[k, k] / v.quadratic_damping[k]:.3g} {'rad' if k == 2 else 'm'}, under "
                f"{1 / MAX_QUADRATIC_DAMPING_RATE:g}: check the units")))
    for key, area, side, name in (("wind_area_frontal", v.wind_area_frontal, v.breadth, "breadth"),
                                  ("wind_area_lateral", v.wind_area_lateral, v.length_pp, "length_pp")):
        if area > MAX_WINDAGE_HEIGHT * side:
            issues.append(ScenarioIssue(f"vessel.{key}", (
                f"= {area:g} m^2 is over {MAX_WINDAGE_HEIGHT:g} m x {name} ({side:g} m): a mean height above water "
                "taller than any superstructure")))
    x, y, z = v.reference_point  # NaN: not given
    if _co_outside_hull(v):
        issues.append(ScenarioIssue("vessel.reference_point", (
            f"= ({x:g}, {y:g}, {z:g}) m puts CO outside the hull: x from the aft perpendicular within "
            f"[{-v.length_pp / 2:g}, {1.5 * v.length_pp:g}] m, |y| <= breadth {v.breadth:g} m, z above the keel within "
            f"[{-v.draught:g}, {v.draught + MAX_WINDAGE_HEIGHT:g}] m (draught + {MAX_WINDAGE_HEIGHT:g} m)")))
    longest_line = max((ln.length for ln in sc.lines), default=math.inf)
    for key in ("safe_radius", "alert_radius"):
        r = getattr(sc.limits, key)
        if r is not None and r > longest_line:
            issues.append(ScenarioIssue(f"limits.{key}", f"= {r:g} m is larger than the longest line "
                                                         f"({longest_line:g} m): the vessel cannot get there moored"))

    def in_hull(path: str, x: float, y: float, what: str) -> None:
        if abs(x) > v.length_pp or abs(y) > v.breadth:
            issues.append(ScenarioIssue(path, f"= ({x:g}, {y:g}) m puts the {what} outside the hull: |x| must be <= "
                                              f"length_pp = {v.length_pp:g} m and |y| <= breadth = {v.breadth:g} m"))

    tur = sc.turret
    in_hull("turret.position", *tur.position, "turret")
    hull = fairlead_reach(v.length_pp, v.breadth)

    def radius_issue(path: str, r: float) -> None:
        if r > hull:
            issues.append(ScenarioIssue(path, (
                f"= {r:g} m puts the fairleads beyond the hull: the fairlead circle of a turret, or of a spread "
                f"mooring with its fairleads at the hull ends, has a radius of at most the hull's length "
                f"or breadth, whichever is larger (length_pp {v.length_pp:g} m, breadth {v.breadth:g} m)")))

    radius_issue("turret.fairlead_radius", tur.fairlead_radius)
    for i, th in enumerate(sc.thrusters):
        in_hull(f"thrusters[{i}].position", *th.position, "thruster")

    bad_types: set[str] = set()
    for i, t in enumerate(sc.line_types):
        p = f"line_types[{i}]"
        n0 = len(issues)
        strain = t.MBS / t.EA if t.EA_table is None else float(t.strain_table.strain_at(t.MBS))
        lo, hi = STRAIN_AT_MBS_RANGE
        c = math.sqrt(t.max_EA / t.mass_per_length)
        area = math.pi * t.diameter * t.diameter / 4.0
        rho_eff = t.mass_per_length / area if area > 0 else math.inf
        fld, what = (("EA", f"= {t.EA:g} N") if t.EA_table is None else
                     ("EA_table", f"(largest slope {t.max_EA:g} N, secant {t.EA:g} N)"))
        if not lo <= strain <= hi:
            issues.append(ScenarioIssue(f"{p}.{fld}", (
                f"{what} with MBS = {t.MBS:g} N gives a strain at MBS "
                f"({'MBS/EA' if t.EA_table is None else 'from the table'}) of {strain:.3g}, outside "
                f"[{lo:g}, {hi:g}] (chain breaks at about 1.5 %, wire 1 %, polyester and HMPE up to 20 %): "
                "check the units of EA and MBS")))
        elif c > MAX_AXIAL_WAVE_SPEED:
            issues.append(ScenarioIssue(f"{p}.{fld}", (
                f"{what} with mass_per_length = {t.mass_per_length:g} kg/m gives an axial wave speed "
                f"sqrt(EA/m) = {c:.3g} m/s, above {MAX_AXIAL_WAVE_SPEED:g} m/s (steel about 5000, carbon fibre "
                "11000): check the units of EA and mass_per_length")))
        lo, hi = EFFECTIVE_DENSITY_RANGE
        if not lo <= rho_eff <= hi:
            issues.append(ScenarioIssue(f"{p}.mass_per_length", (
                f"= {t.mass_per_length:g} kg/m on a diameter of {t.diameter:g} m is {rho_eff:.3g} kg/m^3 of its "
                f"cross-section pi d^2/4, outside [{lo:g}, {hi:g}] kg/m^3 (ropes about 600-1000, chain up to "
                "25000): check the units of mass_per_length and diameter")))
        if t.submerged_weight is not None and t.submerged_weight > t.mass_per_length * g:
            issues.append(ScenarioIssue(f"{p}.submerged_weight", (
                f"= {t.submerged_weight:g} N/m exceeds the weight in air, mass_per_length x g = "
                f"{t.mass_per_length * g:.4g} N/m (buoyancy only reduces it)")))
        if t.MBS_std > MAX_MBS_COV * t.MBS:
            issues.append(ScenarioIssue(f"{p}.MBS_std", (
                f"= {t.MBS_std:g} N is more than {MAX_MBS_COV:g} x MBS = {MAX_MBS_COV * t.MBS:g} N (measured "
                "coefficients of variation are 0.05-0.15)")))
        if t.max_strain is not None and t.max_strain > 0 and t.max_strain > strain * (1 + 1e-9):
            issues.append(ScenarioIssue(f"{p}.max_strain", (
                f"= {t.max_strain:g} exceeds the strain at MBS, "
                f"{'MBS/EA' if t.EA_table is None else 'from EA_table'} = {strain:.4g}: the line breaks first")))
        if len(issues) > n0:
            bad_types.add(t.id)

    types_ok = {t.id: t for t in sc.line_types}
    for i, ln in enumerate(sc.lines):
        p = f"lines[{i}]"
        lt = types_ok.get(ln.type)
        if lt is None or len(ln.anchor) not in (2, 3):
            continue
        r = tur.fairlead_radius if ln.fairlead_radius is None else ln.fairlead_radius
        if ln.fairlead_radius is not None:
            radius_issue(f"{p}.fairlead_radius", r)
        horiz = math.hypot(ln.anchor[0] - float(fl_x[i]), ln.anchor[1] - float(fl_y[i]))
        z_anchor = ln.anchor[2] if len(ln.anchor) == 3 else env.water_depth
        vert = abs(z_anchor - tur.fairlead_depth)
        longest = MAX_LENGTH_FACTOR * (horiz + vert)
        for key, val in (("length", ln.length), ("max_length", ln.max_length)):
            if val is not None and val > longest:
                issues.append(ScenarioIssue(f"{p}.{key}", (
                    f"= {val:g} m is over {MAX_LENGTH_FACTOR:g} x (horizontal span {_metres(horiz)} m + vertical span "
                    f"{_metres(vert)} m) = {_metres(longest)} m: far longer than the line can need")))
        if ln.min_length is not None and ln.min_length * (1.0 + lt.strain_limit) < math.hypot(horiz, vert):
            issues.append(ScenarioIssue(f"{p}.min_length", (
                f"= {ln.min_length:g} m cannot reach the anchor from the fairlead (distance "
                f"{_metres(math.hypot(horiz, vert))} m) within the line type's strain limit "
                f"{100 * lt.strain_limit:.3g} %: hauling in that far would break the line")))

    if not bad_types:
        issues.extend(fem_size_issues(sc))

    if tur.fairlead_depth < -MAX_FAIRLEAD_HEIGHT:
        issues.append(ScenarioIssue("turret.fairlead_depth", (
            f"= {tur.fairlead_depth:g} m puts the fairleads {-tur.fairlead_depth:g} m above the water line (depth is "
            f"z down, 0 at the water line); fairleads lie at most {MAX_FAIRLEAD_HEIGHT:g} m above it (chain stoppers "
            "on deck), usually below it: check the sign and units")))
    h_A = [env.water_depth - ln.anchor[2] for ln in sc.lines if len(ln.anchor) == 3]
    if sc.lines and len(h_A) == len(sc.lines) and min(h_A) > RAISED_ANCHOR_FRACTION * env.water_depth:
        z_max = max(ln.anchor[2] for ln in sc.lines)
        feet = (f"; {env.water_depth:g} is {env.water_depth * 0.3048:.6g} m in feet"
                if abs(env.water_depth * 0.3048 - z_max) <= 0.01 * z_max else "")
        issues.append(ScenarioIssue("environment.water_depth", (
            f"= {env.water_depth:g} m puts every anchor more than {RAISED_ANCHOR_FRACTION:g} x the water depth above "
            f"the seabed (the anchors' z is {min(ln.anchor[2] for ln in sc.lines):g}-{z_max:g} m, z down): check the "
            f"units of the water depth and of the anchors' z{feet}")))
    if sc.thrusters and all(th.max_thrust > 0 for th in sc.thrusters) and M[0, 0] > 0:
        total = sum(th.max_thrust for th in sc.thrusters)
        if total < MIN_THRUST_ACCELERATION * M[0, 0]:
            k = int(np.argmax([th.max_thrust for th in sc.thrusters]))
            issues.append(ScenarioIssue(f"thrusters[{k}].max_thrust", (
                f"= {sc.thrusters[k].max_thrust:g} N: all {len(sc.thrusters)} thrusters together ({total:g} N) would "
                f"accelerate the vessel's surge mass ({M[0, 0]:g} kg) by {total / M[0, 0]:.3g} m/s^2, under "
                f"{MIN_THRUST_ACCELERATION:g} (DP and thruster-assisted vessels: 0.005-0.05): thrusts are in N, "
                "not kN")))

    for i, th in enumerate(sc.thrusters):
        p = f"thrusters[{i}]"
        if th.kind != "azimuth" and th.max_reverse_thrust > th.max_thrust:
            issues.append(ScenarioIssue(f"{p}.max_reverse_thrust", (
                f"= {th.max_reverse_thrust:g} N exceeds max_thrust = {th.max_thrust:g} N: a propeller pushes no "
                "harder astern than ahead (a symmetric tunnel thruster equally); if the other direction is the "
                "stronger, turn angle_deg by 180 and swap the two")))
        for k, (a, b) in enumerate(th.forbidden_sectors):
            width = math.degrees(b - a)
            if abs(width) >= 360.0 * (1 - 1e-12):
                issues.append(ScenarioIssue(f"{p}.forbidden_sectors_deg[{k}]", (
                    f"= ({math.degrees(a):g}, {math.degrees(b):g}) spans a full turn: it forbids every direction")))
            elif a == b:
                issues.append(ScenarioIssue(f"{p}.forbidden_sectors_deg[{k}]", (
                    f"= ({math.degrees(a):g}, {math.degrees(b):g}) is empty (from = to): remove it or give its end")))

    for i, ss in enumerate(sc.sea_states):
        steep = ss.Hs / (g * ss.Tp ** 2 / (2.0 * math.pi))
        if steep > MAX_STEEPNESS:
            issues.append(ScenarioIssue(f"sea_states[{i}].Hs", (
                f"= {ss.Hs:g} m with Tp = {ss.Tp:g} s is steeper than waves can be: Hs / (g Tp^2 / 2 pi) = "
                f"{steep:.3g} > 1/7, the breaking limit; at this Tp Hs must be <= "
                f"{MAX_STEEPNESS * g * ss.Tp ** 2 / (2.0 * math.pi):.3g} m")))

    rs = sc.riser
    if rs is not None:
        in_hull("riser.hangoff", *rs.hangoff, "riser hang-off")
        horiz = math.hypot(rs.wellhead[0] - rs.hangoff[0], rs.wellhead[1] - rs.hangoff[1])
        top = hangoff_depth_limit(tur.fairlead_depth, v.draught)
        shortest = math.hypot(horiz, env.water_depth - top)
        longest = MAX_RISER_LENGTH_FACTOR * (horiz + env.water_depth)
        if rs.length * 1.01 < shortest:
            issues.append(ScenarioIssue("riser.length", (
                f"= {rs.length:g} m cannot reach the wellhead from its hang-off: the straight distance is at least "
                f"{shortest:.0f} m (horizontal {horiz:.0f} m; water depth {env.water_depth:g} m less the "
                f"hang-off depth, at most {top:g} m)")))
        elif rs.length > longest:
            issues.append(ScenarioIssue("riser.length", (
                f"= {rs.length:g} m is over {MAX_RISER_LENGTH_FACTOR:g} x (horizontal offset {horiz:.0f} m + water "
                f"depth {env.water_depth:g} m) = {longest:.0f} m")))
        if rs.wall_thickness >= 0.5 * rs.diameter:
            issues.append(ScenarioIssue("riser.wall_thickness", (
                f"= {rs.wall_thickness:g} m must be less than half of riser.diameter = {rs.diameter:g} m "
                f"({0.5 * rs.diameter:g} m): the pipe would have no bore")))
        weight = rs.submerged_weight * (env.water_depth - top)
        if rs.top_tension > MAX_RISER_TENSION_FACTOR * rs.submerged_weight * rs.length:
            issues.append(ScenarioIssue("riser.top_tension", (
                f"= {rs.top_tension:g} N is over {MAX_RISER_TENSION_FACTOR:g} x the riser's submerged weight "
                f"({rs.submerged_weight * rs.length:.4g} N; tensioners pull about 1.2-2 x): check the units")))
        if rs.top_tension < weight:
            issues.append(ScenarioIssue("riser.top_tension", (
                f"= {rs.top_tension:g} N cannot hold up the riser: its submerged weight over the water column is at "
                f"least {weight:.4g} N (submerged_weight {rs.submerged_weight:g} N/m x {env.water_depth - top:g} m)")))


def fairlead_reach(length_pp: float, breadth: float) -> float:
    """Largest fairlead radius about the centre of turret a scenario may have [m]: the hull's
    length or breadth, whichever is larger (a spread mooring's fairleads at the hull ends lie about
    length_pp / 2 out)."""
    return max(float(length_pp), float(breadth))


def hangoff_depth_limit(fairlead_depth: float, draught: float) -> float:
    """The deepest a riser's hang-off is taken to be [m]: the fairlead depth or the draught,
    whichever is larger (not above the water line). A riser must reach its wellhead from there."""
    return max(float(fairlead_depth), float(draught), 0.0)


def _axial_law_issues(sc: Scenario, issues: list[ScenarioIssue]) -> None:
    """Each line type's EA or EA_table: a valid tension-strain table (:func:`table_problem`), and
    EA absent or the table's secant at its last row; EA given when there is no table."""
    for i, t in enumerate(sc.line_types):
        p = f"line_types[{i}]"
        if t.EA_table is None:
            if t.EA is None:
                issues.append(ScenarioIssue(f"{p}.EA", (
                    "is missing: give the axial stiffness EA [N], or a tension-strain table EA_table "
                    "[[strain, tension], ...] for a nonlinear one")))
            continue
        bad = table_problem(t.EA_table)
        if bad is not None:
            k, msg = bad
            issues.append(ScenarioIssue(f"{p}.EA_table" + ("" if k is None else f"[{k}]"), msg))
            continue
        secant = secant_of_rows(t.EA_table)
        if secant is None or not math.isclose(float(t.EA), secant, rel_tol=1e-9):
            issues.append(ScenarioIssue(f"{p}.EA", (
                f"= {t.EA:g} N differs from EA_table's secant at its last row, T_n / eps_n = {secant:.10g} N: "
                "with a table EA is that secant (leave EA out)")))


def _co_outside_hull(v: Any) -> bool:
    """The body origin CO (``vessel.reference_point``; NaN: not given) outside the hull's box: x from
    the aft perpendicular beyond [-L/2, 1.5 L], |y| beyond the breadth, z above the keel beyond
    [-T, T + MAX_WINDAGE_HEIGHT]."""
    x, y, z = v.reference_point
    bad_x = abs(x - v.length_pp / 2) > v.length_pp  # False for NaN
    bad_z = math.isfinite(z) and not -v.draught <= z <= v.draught + MAX_WINDAGE_HEIGHT
    return bool(bad_x or abs(y) > v.breadth or bad_z)


def _wave_motion_issues(v: Any, issues: list[ScenarioIssue]) -> None:
    """``vessel.wave_motion``: the six-degree-of-freedom model needs the hull's block coefficient,
    GM_T and roll period, and a water-plane coefficient not below the block coefficient; a table
    (``rao_file``, ``drift_file``) must name a file of a format read, and the file must exist."""
    wm = v.wave_motion
    p = "vessel.wave_motion"
    if wm.model == "six_dof":
        for name, what in (("block_coefficient", "the block coefficient C_B [-]"),
                           ("GM_T", "the transverse metacentric height [m]"),
                           ("roll_period", "the natural roll period [s]")):
            if getattr(wm, name) is None:
                issues.append(ScenarioIssue(f"{p}.{name}", (
                    f"is missing: model = 'six_dof' needs {what} for the closed-form heave, roll and pitch "
                    "transfer functions (or model = 'horizontal')")))
    if wm.model == "six_dof" and not _co_outside_hull(v):   # (outside: the hull's own check says so)
        # the closed form's motion is at midships on the water line, the plant's about CO
        rp, L, T = v.reference_point, v.length_pp, v.draught
        for i, (where, at, tol) in enumerate((("midships", L / 2.0, 0.01 * L), ("the centre line", 0.0, 0.01 * L),
                                              ("the water line", T, 0.05 * T))):
            if math.isfinite(rp[i]) and abs(rp[i] - at) > tol:
                issues.append(ScenarioIssue("vessel.reference_point", (
                    f"= {list(rp)} puts the body origin CO {rp[i] - at:+.3g} m off {where} (from AP, CL, keel: "
                    f"{at:g} m): model = 'six_dof' turns the hull about CO with the closed form's heave, roll and "
                    f"pitch of midships on the water line; put CO there (within {tol:.3g} m) or give the RAOs at "
                    "CO as a table (model = 'table')")))
                break
    if wm.model == "table":
        f = wm.rao_file
        if f is None:
            issues.append(ScenarioIssue(f"{p}.rao_file", (
                "is missing: model = 'table' reads the hull's RAOs from a CSV table or a WAMIT .4 file")))
        elif not (f.lower().endswith(".csv") or f.lower().endswith(".4")):
            issues.append(ScenarioIssue(f"{p}.rao_file", f"= {f!r} must name a .csv table or a WAMIT .4 file"))
        elif not Path(f).is_file():
            issues.append(ScenarioIssue(f"{p}.rao_file", (
                f"= {f!r}: no such file (a relative path is read from the scenario file's folder)")))
    f = wm.drift_file
    if f is not None:
        if not f.lower().endswith((".csv", ".8", ".9")):
            issues.append(ScenarioIssue(f"{p}.drift_file", (
                f"= {f!r} must name a .csv table of mean drift coefficients or a WAMIT .8 or .9 file")))
        elif not Path(f).is_file():
            issues.append(ScenarioIssue(f"{p}.drift_file", (
                f"= {f!r}: no such file (a relative path is read from the scenario file's folder)")))
    if wm.block_coefficient is not None and wm.waterplane_coefficient is not None \
            and wm.waterplane_coefficient < wm.block_coefficient:
        issues.append(ScenarioIssue(f"{p}.waterplane_coefficient", (
            f"= {wm.waterplane_coefficient:g} is below block_coefficient = {wm.block_coefficient:g}: a hull's "
            "water-plane is at least as full as its block")))


def buoyant_line_problem(w: Sequence[float], L: Sequence[float], W: Sequence[float] = ()) -> tuple[int | None, str] | None:
    """Where buoyant sections may be: the rule, on a line's sections from the anchor up (submerged
    weights ``w`` [N/m], lengths ``L`` [m]) and its points' net weights ``W`` [N], positive down.

    A section not heavier than water (``w <= 0``: a buoyant section, distributed buoyancy modules,
    a lazy wave's arch) must lie between two weighted sections of a composite line: the section at
    the anchor weighs (it holds the line down; a buoyant section cannot rest on the seabed) and so
    does the fairlead's (the line hangs from its fairlead, pulling it down and out, the convention
    of every fairlead tension in the models), and the whole line with its points weighs in water
    (``sum w L + sum W > 0``), or it would float. Returns None when the line keeps the rule, else
    (the offending section's index, or None for the line as a whole; the reason)."""
    w, L = [float(x) for x in w], [float(x) for x in L]
    light = [k for k, x in enumerate(w) if not x > 0]
    if not light:
        return None
    if len(w) == 1:
        return 0, (f"is not heavier than water (submerged weight {w[0]:g} N/m): a line of it floats and cannot hang "
                   "from its fairlead; a buoyant type may be a middle section of a composite line, between weighted "
                   "sections (a lazy wave)")
    for k, end in ((0, "anchor"), (len(w) - 1, "fairlead")):
        if k in light:
            why = ("a buoyant section cannot rest on the seabed and would lift the anchor" if end == "anchor" else
                   "the line must hang from its fairlead, pulling it down")
            return k, (f"is not heavier than water (submerged weight {w[k]:g} N/m) and is the line's {end} section: "
                       f"{why}; a buoyant section must lie between weighted sections")
    total = sum(a * b for a, b in zip(w, L)) + sum(float(x) for x in W)
    if not total > 0:
        return None, (f"with their points weigh {total:g} N in water (the sum of w L and of the points' W): the line "
                      "would float; its buoyant sections and buoys must lift less than the rest of it weighs")
    return None


def _buoyant_line_issues(sc: Scenario, i: int, ln: Any, issues: list[ScenarioIssue]) -> bool:
    """:func:`buoyant_line_problem` of line ``i`` as an issue (True when one was added)."""
    env = sc.environment
    parts = ln.parts
    try:
        w = [sc.line_type_by_id(s.type).w(env) for s in parts]
        W = [sc.point_type(s.top).net_weight(env) for s in parts[:-1] if s.top is not None]
    except KeyError:  # an unknown type or point: said elsewhere
        return False
    got = buoyant_line_problem(w, [s.length for s in parts], W)
    if got is None:
        return False
    k, why = got
    p = f"lines[{i}]"
    if not ln.sections:
        issues.append(ScenarioIssue(f"{p}.type", f"= {ln.type!r} {why}"))
    elif k is None:
        issues.append(ScenarioIssue(f"{p}.sections", why))
    else:
        issues.append(ScenarioIssue(f"{p}.sections[{k}].type", f"= {parts[k].type!r} {why}"))
    return True


def _development_issues(ss: Any, p: str, issues: list[ScenarioIssue]) -> None:
    """A developing sea state's rows: times increasing; a row at t = 0 gives the sea state's own
    values (they are its values at t = 0)."""
    rows = ss.development
    for j, (a, b) in enumerate(zip(rows, rows[1:])):
        if not b.t > a.t:
            issues.append(ScenarioIssue(f"{p}.development[{j + 1}].t", (
                f"= {b.t:g} s must be later than the row before ({a.t:g} s): the rows are a time table")))
            return
    for j, r in enumerate(rows):
        if r.t != 0.0:
            continue
        for f in DEVELOPING_FIELDS:
            v = getattr(r, f)
            if v is not None and not math.isclose(v, getattr(ss, f), rel_tol=1e-12, abs_tol=1e-12):
                deg = f.endswith("direction")
                show = (lambda x: f"{math.degrees(x):g} deg") if deg else (lambda x: f"{x:g}")
                issues.append(ScenarioIssue(f"{p}.development[{j}].{f}{'_deg' if deg else ''}", (
                    f"= {show(v)} at t = 0 differs from the sea state's {f}{'_deg' if deg else ''} = "
                    f"{show(getattr(ss, f))}, its value at t = 0: leave it out of the row or give it there")))


def validate(sc: Scenario) -> list[ScenarioIssue]:
    """Physical and cross-field checks of a parsed scenario.

    A scenario built or changed in code (``dataclasses.replace``) is first checked field by field
    (finite numbers, each field's range) as the loader checks a file.

    Returns
    -------
    list of ScenarioIssue
        Empty when the scenario is valid.
    """
    issues: list[ScenarioIssue] = []
    _field_issues(sc, "", issues)
    if not issues:
        _axial_law_issues(sc, issues)
    if issues:
        return issues
    env = sc.environment
    v = sc.vessel
    _matrix_checks(v.M, "vessel.mass_matrix", issues, pd=True)
    if v.added_mass is not None:
        _matrix_checks(v.M_A, "vessel.added_mass", issues, pd=False, psd=True)  # added mass stores energy: >= 0
        if not issues:
            eig = np.linalg.eigvalsh(v.M - v.M_A)
            if eig.min() <= 0:
                issues.append(ScenarioIssue(
                    "vessel.added_mass",
                    f"leaves a rigid-body mass M - M_A that is not positive definite (eigenvalue {eig.min():g})"))
    _matrix_checks(v.D_lin, "vessel.linear_damping", issues, pd=False, psd=True)
    _wave_motion_issues(v, issues)

    if sc.turret.fairlead_depth >= env.water_depth:
        issues.append(ScenarioIssue(
            "turret.fairlead_depth",
            f"= {sc.turret.fairlead_depth:g} m puts the fairleads at or below the seabed "
            f"(water depth {env.water_depth:g} m)"))

    _dupes(sc.line_types, "line_types", issues)
    _dupes(sc.lines, "lines", issues)
    _dupes(sc.thrusters, "thrusters", issues)
    _dupes(sc.sea_states, "sea_states", issues)
    if not sc.lines:
        issues.append(ScenarioIssue("lines", "a scenario needs at least one mooring line"))

    type_ids = {t.id for t in sc.line_types}
    for i, t in enumerate(sc.line_types):
        p = f"line_types[{i}]"
        if (t.density is None) == (t.submerged_weight is None):
            issues.append(ScenarioIssue(p, "give exactly one of 'density' and 'submerged_weight'"))
        if t.max_strain is not None and t.max_strain <= 0:
            issues.append(ScenarioIssue(f"{p}.max_strain", f"= {t.max_strain:g} must be > 0"))

    # reach check: the line must span anchor -> fairlead at the field zero point within its strain limit
    # (at eta = 0 the fairleads in {E} are those in {B}, eq. 3)
    fl_x, fl_y = fairleads_B(sc.turret.position, sc.fairleads_T, sc.turret.angle)
    point_ids = {pt.id for pt in sc.point_types}
    _dupes(sc.point_types, "point_types", issues)
    for i, ln in enumerate(sc.lines):
        p = f"lines[{i}]"
        if ln.sections:
            bad = False
            given = [k for k, v in (("type", ln.type), ("length", ln.length)) if v is not None]
            if ln.type != ln.sections[-1].type or not math.isclose(
                    float(ln.length or 0.0), sum(s.length for s in ln.sections), rel_tol=1e-12):
                issues.append(ScenarioIssue(p, (
                    f"gives sections and {' and '.join(given)}: give either type and length (a homogeneous line) or "
                    "sections (a composite line, whose type is its fairlead section's and length their sum)")))
                bad = True
            for k, sec in enumerate(ln.sections):
                q = f"{p}.sections[{k}]"
                if sec.type not in type_ids:
                    hint = difflib.get_close_matches(sec.type, sorted(type_ids), n=1)
                    issues.append(ScenarioIssue(f"{q}.type", f"= {sec.type!r} is not a line type" + (
                        f"; did you mean {hint[0]!r}?" if hint else f"; defined: {sorted(type_ids)}")))
                    bad = True
                if sec.top is not None and k == len(ln.sections) - 1:
                    issues.append(ScenarioIssue(f"{q}.top", (
                        f"= {sec.top!r}: the last section ends at the fairlead; a point can only join two sections")))
                    bad = True
                elif sec.top is not None and sec.top not in point_ids:
                    hint = difflib.get_close_matches(sec.top, sorted(point_ids), n=1)
                    issues.append(ScenarioIssue(f"{q}.top", f"= {sec.top!r} is not a point type" + (
                        f"; did you mean {hint[0]!r}?" if hint else f"; defined: {sorted(point_ids) or 'none'}")))
                    bad = True
            if any(s.segments is None for s in ln.sections) and ln.segments < len(ln.sections):
                issues.append(ScenarioIssue(f"{p}.segments", (
                    f"= {ln.segments} is fewer than the line's {len(ln.sections)} sections (each needs one)")))
                bad = True
            if ln.winch_max_rate > 0 and ln.composite and ln.min_length is not None:
                # the winch pays out and hauls in the fairlead section: it must keep a length
                below = sum(float(s.length) for s in ln.sections[:-1])
                if not ln.min_length > below:
                    issues.append(ScenarioIssue(f"{p}.min_length", (
                        f"= {ln.min_length:g} m: the winch hauls in the fairlead section ({ln.sections[-1].length:g} m "
                        f"of {ln.sections[-1].type!r}), so the line stays longer than its other sections' "
                        f"{below:g} m; give more than that")))
                    bad = True
            if bad:
                continue
        elif ln.type is None or ln.length is None:
            missing = " and ".join(k for k, v in (("type", ln.type), ("length", ln.length)) if v is None)
            issues.append(ScenarioIssue(f"{p}.{'type' if ln.type is None else 'length'}", (
                f"is missing: a line gives type and length, or sections (missing: {missing})")))
            continue
        if ln.type not in type_ids:
            hint = difflib.get_close_matches(ln.type, sorted(type_ids), n=1)
            issues.append(ScenarioIssue(
                f"{p}.type", f"= {ln.type!r} is not a line type" + (f"; did you mean {hint[0]!r}?" if hint else
                                                                     f"; defined: {sorted(type_ids)}")))
            continue
        if len(ln.anchor) not in (2, 3):
            issues.append(ScenarioIssue(f"{p}.anchor", f"must be (x, y) or (x, y, z), got {len(ln.anchor)} numbers"))
            continue
        z_anchor = ln.anchor[2] if len(ln.anchor) == 3 else env.water_depth
        if z_anchor > env.water_depth * (1 + 1e-6):
            issues.append(ScenarioIssue(
                f"{p}.anchor[2]",
                f"= {z_anchor:g} m puts the anchor below the seabed (water depth {env.water_depth:g} m, z down)"))
            continue
        if z_anchor <= sc.turret.fairlead_depth:
            issues.append(ScenarioIssue(
                f"{p}.anchor[2]",
                f"= {z_anchor:g} m is not below the fairleads (fairlead_depth {sc.turret.fairlead_depth:g} m, z down): "
                "a lower end above the seabed must still hang below its fairlead"))
            continue
        lo, hi = ln.length_limits
        if not lo <= ln.length <= hi:
            issues.append(ScenarioIssue(
                f"{p}.length", f"= {ln.length:g} m is outside the winch limits [{lo:g}, {hi:g}] m"))
        if (ln.min_length is not None or ln.max_length is not None) and ln.winch_max_rate == 0:
            issues.append(ScenarioIssue(
                f"{p}.winch_max_rate", "= 0 m/s: length limits are given but the line has no winch (set a rate)"))
        if _buoyant_line_issues(sc, i, ln, issues):
            continue
        lt = sc.line_type(ln)
        dist = math.hypot(math.hypot(ln.anchor[0] - float(fl_x[i]), ln.anchor[1] - float(fl_y[i])),
                          min(z_anchor, env.water_depth) - sc.turret.fairlead_depth)
        reach = sum(s.length * (1.0 + sc.line_type_by_id(s.type).strain_limit) for s in ln.parts)
        if reach < dist:
            lim = "max strain" if lt.max_strain is not None else "strain at MBS"
            lim = "sections' strain limits" if ln.composite else f"line type's {lim}"
            issues.append(ScenarioIssue(
                f"{p}.length",
                f"= {ln.length:g} m cannot reach the anchor from the fairlead (distance {_metres(dist)} m) within the "
                f"{lim}" + ("" if ln.composite else f" {100 * lt.strain_limit:.3g} %")))

    for i, th in enumerate(sc.thrusters):
        p = f"thrusters[{i}]"
        if th.kind == "azimuth":
            if th.max_azimuth_rate is None:
                issues.append(ScenarioIssue(f"{p}.max_azimuth_rate_deg_s", "is required for an azimuth thruster"))
            if th.max_reverse_thrust != 0:
                issues.append(ScenarioIssue(
                    f"{p}.max_reverse_thrust",
                    f"= {th.max_reverse_thrust:g} N must be 0 for an azimuth thruster (it turns instead)"))
            try:  # the union of the sectors, overlaps counted once (shapes were checked when parsed)
                merge_sectors(th.forbidden_sectors, p)
            except ValueError:
                issues.append(ScenarioIssue(f"{p}.forbidden_sectors_deg", "forbid every direction"))
        else:
            if th.max_azimuth_rate is not None:
                issues.append(ScenarioIssue(f"{p}.max_azimuth_rate_deg_s", f"is only allowed for azimuth thrusters, not {th.kind!r}"))
            if th.forbidden_sectors:
                issues.append(ScenarioIssue(f"{p}.forbidden_sectors_deg", f"are only allowed for azimuth thrusters, not {th.kind!r}"))
        if th.max_thrust_rate * th.time_constant < 1e-3 * th.max_thrust:
            issues.append(ScenarioIssue(
                f"{p}.max_thrust_rate",
                f"= {th.max_thrust_rate:g} N/s would need {th.max_thrust / th.max_thrust_rate:.3g} s to reach max_thrust "
                f"{th.max_thrust:g} N, over 1000 time constants ({th.time_constant:g} s): check the units"))

    for i, ss in enumerate(sc.sea_states):
        p = f"sea_states[{i}]"
        prof, d, fct = ss.current_profile, ss.current_profile_depths, ss.current_profile_factors
        if prof == "uniform" and (d or fct):
            issues.append(ScenarioIssue(f"{p}.current_profile", "is 'uniform' but profile depths/factors are given"))
        if prof == "linear" and (len(fct) != 1 or d):
            issues.append(ScenarioIssue(f"{p}.current_profile_factors",
                                        "'linear' takes exactly one factor (at the seabed) and no depths"))
        if prof == "piecewise":
            if len(d) < 2 or len(d) != len(fct):
                issues.append(ScenarioIssue(f"{p}.current_profile_depths",
                                            f"'piecewise' needs >= 2 depths and as many factors (got {len(d)} and {len(fct)})"))
            elif any(b <= a for a, b in zip(d, d[1:])) or d[0] != 0:
                issues.append(ScenarioIssue(f"{p}.current_profile_depths", f"= {list(d)} must start at 0 and increase"))
            elif d[-1] > env.water_depth:
                issues.append(ScenarioIssue(f"{p}.current_profile_depths",
                                            f"last depth {d[-1]:g} m is below the seabed ({env.water_depth:g} m)"))
        _development_issues(ss, p, issues)

    line_ids = [ln.id for ln in sc.lines]
    thr_ids = [t.id for t in sc.thrusters]
    first_fault: dict[tuple[str, str], int] = {}
    for i, fault in enumerate(sc.faults):
        p = f"faults[{i}]"
        sensor = sensor_fault_issues(fault, line_ids)
        issues.extend(ScenarioIssue(f"{p}.{_file_key_of_fault(name)}", msg) for name, msg in sensor)
        if fault.kind in SENSOR_FAULT_KINDS:
            continue
        if fault.kind == "line_break":
            if fault.line is None:
                issues.append(ScenarioIssue(f"{p}.line", "is required for a line_break"))
            elif fault.line not in line_ids:
                issues.append(ScenarioIssue(f"{p}.line", f"= {fault.line!r} is not a line id; lines are {line_ids}"))
        if fault.kind == "thruster_failure":
            if fault.thruster is None:
                issues.append(ScenarioIssue(f"{p}.thruster", "is required for a thruster_failure"))
            elif fault.thruster not in thr_ids:
                issues.append(ScenarioIssue(f"{p}.thruster", f"= {fault.thruster!r} is not a thruster id; thrusters are {thr_ids}"))
        for extra in ("joint", "point"):
            if fault.kind != "buoy_loss" and getattr(fault, extra) is not None:
                issues.append(ScenarioIssue(f"{p}.{extra}", f"is only for a buoy_loss, not a {fault.kind}"))
        if fault.kind == "buoy_loss":
            try:
                li, jj = buoy_of_fault(sc, fault.line, fault.joint, fault.point)
            except FaultTargetError as exc:
                issues.append(ScenarioIssue(f"{p}.{exc.field}", str(exc)))
                continue
            key, target = "joint", (line_ids[li], jj)
            j = first_fault.setdefault(("buoy_loss", target), i)
            if j != i:
                issues.append(ScenarioIssue(f"{p}.{'point' if fault.point is not None else 'joint'}", (
                    f"takes off the buoy at joint {jj} of line {line_ids[li]!r}, which faults[{j}] already takes off "
                    f"at t = {sc.faults[j].time:g} s; a buoy comes off once (remove one of the two)")))
            continue
        key, target = ("line", fault.line) if fault.kind == "line_break" else ("thruster", fault.thruster)
        if target is None:
            continue
        j = first_fault.setdefault((fault.kind, target), i)
        if j != i:
            issues.append(ScenarioIssue(f"{p}.{key}", (
                f"= {target!r}: faults[{j}] already {'breaks' if key == 'line' else 'fails'} {key} {target!r} at "
                f"t = {sc.faults[j].time:g} s; a {key} {'breaks' if key == 'line' else 'fails'} once (remove one of "
                "the two)")))
    broken = {f.line for f in sc.faults if f.kind == "line_break"}
    if line_ids and set(line_ids) <= broken:
        last = max((i for i, f in enumerate(sc.faults) if f.kind == "line_break"), key=lambda i: sc.faults[i].time)
        issues.append(ScenarioIssue(f"faults[{last}].line", (
            f"= {sc.faults[last].line!r} breaks the last intact line: the faults break every line "
            f"({len(line_ids)} of {len(line_ids)}), and the controllers, estimators and fault detection model "
            "the vessel on its mooring, so a run with no line left cannot be simulated; keep at least one "
            "line intact")))

    lim = sc.limits
    if lim.safe_radius is not None and lim.alert_radius is not None and lim.alert_radius <= lim.safe_radius:
        issues.append(ScenarioIssue("limits.alert_radius",
                                    f"= {lim.alert_radius:g} m must exceed safe_radius = {lim.safe_radius:g} m"))
    _plausibility(sc, fl_x, fl_y, issues)
    return issues


# --------------------------------------------------------------------------------------------
# public entry points
# --------------------------------------------------------------------------------------------


def scenario_from_dict(data: dict[str, Any], *, source: str = "") -> Scenario:
    """Build and validate a :class:`Scenario` from a dictionary (e.g. parsed TOML).

    Raises
    ------
    ScenarioError
        With every problem found, each naming its field path and value.
    """
    parser = _Parser()
    sc = parser.dataclass(Scenario, data, "")
    if parser.issues or sc is None:
        raise ScenarioError(parser.issues, source=source)
    issues = validate(sc)
    if issues:
        raise ScenarioError(issues, source=source)
    return sc


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load a built-in scenario by name (``"fpso"``, ``"aamo4"``, ``"ren8"``) or a TOML file by path.

    Raises
    ------
    ScenarioError
        If there is no such scenario or file, the TOML is malformed, or the scenario is invalid.
    """
    text = str(name_or_path)
    path = Path(text)
    if not path.suffix and (BUILTIN_DIR / f"{text}.toml").is_file():
        path = BUILTIN_DIR / f"{text}.toml"
    if not text.strip():
        raise ScenarioError(f"the scenario name is empty; give a built-in name ({', '.join(builtin_scenarios())}) "
                            "or a .toml file")
    if path.is_dir():
        raise ScenarioError(f"{text!r} is a directory, not a scenario file")
    if not path.is_file():
        raise ScenarioError(
            f"no built-in scenario or file named {text!r}; built-in scenarios: {', '.join(builtin_scenarios())}")
    data = read_toml(path, ScenarioError)
    if not data:
        raise ScenarioError(f"{path.name} is empty: a scenario needs [meta], [environment], [vessel], [turret], "
                            "[[line_types]] and [[lines]]", source=str(path))
    wm = data.get("vessel", {}).get("wave_motion") if isinstance(data.get("vessel"), dict) else None
    for key in ("rao_file", "drift_file"):   # read from the scenario file's folder
        if isinstance(wm, dict) and isinstance(wm.get(key), str) and not Path(wm[key]).is_absolute():
            wm[key] = str(path.parent / wm[key])
    return scenario_from_dict(data, source=str(path) if path.parent != BUILTIN_DIR else path.stem)


def read_toml(path: Path, error: type[ScenarioError] | Any) -> dict[str, Any]:
    """Parse a TOML file; every failure (unreadable, not UTF-8, malformed, nested too deeply for the
    parser) raises ``error`` with a one-line message naming the file."""
    try:
        text = path.read_text(encoding="utf-8-sig")   # a byte-order mark (some Windows editors write one) skipped
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"cannot read {path}: {exc}", source=str(path)) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path.name} is not valid TOML: {exc}", source=str(path)) from None
    except RecursionError:
        raise error(f"{path.name} nests arrays or tables too deeply to be read as TOML", source=str(path)) from None


def scenario_to_dict(obj: Any) -> Any:
    """Inverse of parsing: a plain dict with file keys and file units (degrees), TOML-ready.

    ``scenario_from_dict(scenario_to_dict(sc)) == sc`` up to floating-point round-off of angles.
    """
    if dataclasses.is_dataclass(obj):
        out: dict[str, Any] = {}
        for f in dataclasses.fields(obj):
            val = getattr(obj, f.name)
            if val is None or _has_nan(val):  # NaN only comes from an "unknown" default: omit it
                continue
            if val == () and f.default == ():  # an empty list that is the default (sections, points)
                continue
            if f.metadata.get("unit") in ("deg", "deg/s"):
                val = _deg(val)
            out[file_key(f)] = scenario_to_dict(val)
        return out
    if isinstance(obj, tuple):
        return [scenario_to_dict(x) for x in obj]
    return obj


def _has_nan(val: Any) -> bool:
    if isinstance(val, tuple):
        return any(_has_nan(x) for x in val)
    return isinstance(val, float) and math.isnan(val)


def _deg(val: Any) -> Any:
    if isinstance(val, tuple):
        return tuple(_deg(x) for x in val)
    return math.degrees(val)
