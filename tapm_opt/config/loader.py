"""Load, parse and validate scenarios.

Parsing is driven by the field metadata of :mod:`tapm_opt.config.schema`; every problem is
collected with its field path (``lines[3].length``) so a user sees all of them at once.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import tomllib
import types
import typing
from collections import Counter
from pathlib import Path
from typing import Any, Literal, get_args, get_origin, get_type_hints

import numpy as np

from ..errors import ScenarioError, ScenarioIssue
from ..geometry import fairleads_B, merge_sectors
from . import schema
from .schema import Scenario

BUILTIN_DIR = Path(__file__).parent / "scenarios"

__all__ = [
    "load_scenario",
    "scenario_from_dict",
    "scenario_to_dict",
    "validate",
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


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, str):
        return repr(v)
    return str(v)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


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
            return v
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
            return tuple(v)
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


def validate(sc: Scenario) -> list[ScenarioIssue]:
    """Physical and cross-field checks of a parsed scenario.

    Returns
    -------
    list of ScenarioIssue
        Empty when the scenario is valid.
    """
    issues: list[ScenarioIssue] = []
    env = sc.environment
    v = sc.vessel
    _matrix_checks(v.M, "vessel.mass_matrix", issues, pd=True)
    if v.added_mass is not None:
        _matrix_checks(v.M_A, "vessel.added_mass", issues, pd=False)
        if not issues:
            eig = np.linalg.eigvalsh(v.M - v.M_A)
            if eig.min() <= 0:
                issues.append(ScenarioIssue(
                    "vessel.added_mass",
                    f"leaves a rigid-body mass M - M_A that is not positive definite (eigenvalue {eig.min():g})"))
    _matrix_checks(v.D_lin, "vessel.linear_damping", issues, pd=False, psd=True)

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
        elif t.density is not None and t.density <= env.water_density:
            issues.append(ScenarioIssue(
                f"{p}.density",
                f"= {t.density:g} kg/m^3 is not heavier than water ({env.water_density:g} kg/m^3); "
                "buoyant lines are not supported by the catenary model"))
        if t.max_strain is not None and t.max_strain <= 0:
            issues.append(ScenarioIssue(f"{p}.max_strain", f"= {t.max_strain:g} must be > 0"))

    # reach check: the line must span anchor -> fairlead at the field zero point within its strain limit
    # (at eta = 0 the fairleads in {E} are those in {B}, eq. 3)
    fl_x, fl_y = fairleads_B(sc.turret.position, sc.fairleads_T, sc.turret.angle)
    for i, ln in enumerate(sc.lines):
        p = f"lines[{i}]"
        if ln.type not in type_ids:
            hint = difflib.get_close_matches(ln.type, sorted(type_ids), n=1)
            issues.append(ScenarioIssue(
                f"{p}.type", f"= {ln.type!r} is not a line type" + (f"; did you mean {hint[0]!r}?" if hint else
                                                                     f"; defined: {sorted(type_ids)}")))
            continue
        if len(ln.anchor) not in (2, 3):
            issues.append(ScenarioIssue(f"{p}.anchor", f"must be (x, y) or (x, y, z), got {len(ln.anchor)} numbers"))
            continue
        if len(ln.anchor) == 3 and abs(ln.anchor[2] - env.water_depth) > 1e-6 * env.water_depth:
            where = "above" if ln.anchor[2] < env.water_depth else "below"
            issues.append(ScenarioIssue(
                f"{p}.anchor[2]",
                f"= {ln.anchor[2]:g} m puts the anchor {where} the seabed (water depth {env.water_depth:g} m, z down)"))
            continue
        lo, hi = ln.length_limits
        if not lo <= ln.length <= hi:
            issues.append(ScenarioIssue(
                f"{p}.length", f"= {ln.length:g} m is outside the winch limits [{lo:g}, {hi:g}] m"))
        if (ln.min_length is not None or ln.max_length is not None) and ln.winch_max_rate == 0:
            issues.append(ScenarioIssue(
                f"{p}.winch_max_rate", "= 0 m/s: length limits are given but the line has no winch (set a rate)"))
        lt = sc.line_type(ln)
        dist = math.hypot(math.hypot(ln.anchor[0] - float(fl_x[i]), ln.anchor[1] - float(fl_y[i])),
                          env.water_depth - sc.turret.fairlead_depth)
        reach = ln.length * (1.0 + lt.strain_limit)
        if reach < dist:
            lim = "max strain" if lt.max_strain is not None else "strain at MBS"
            issues.append(ScenarioIssue(
                f"{p}.length",
                f"= {ln.length:g} m cannot reach the anchor from the fairlead (distance {dist:.0f} m) within the "
                f"line type's {lim} {100 * lt.strain_limit:.3g} %"))

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

    line_ids = [ln.id for ln in sc.lines]
    thr_ids = [t.id for t in sc.thrusters]
    for i, fault in enumerate(sc.faults):
        p = f"faults[{i}]"
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

    lim = sc.limits
    if lim.safe_radius is not None and lim.alert_radius is not None and lim.alert_radius <= lim.safe_radius:
        issues.append(ScenarioIssue("limits.alert_radius",
                                    f"= {lim.alert_radius:g} m must exceed safe_radius = {lim.safe_radius:g} m"))
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
    if not path.is_file():
        raise ScenarioError(
            f"no built-in scenario or file named {text!r}; built-in scenarios: {', '.join(builtin_scenarios())}")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path.name} is not valid TOML: {exc}", source=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"cannot read {path}: {exc}", source=str(path)) from None
    return scenario_from_dict(data, source=str(path) if path.parent != BUILTIN_DIR else path.stem)


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
