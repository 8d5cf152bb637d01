"""What a tuning run asks for, checked before anything runs: the objectives and constraints (KPIs
of the catalogue aggregated over the cases), the ``[tuning]`` settings, each controller's search
space (its kind's, narrowed or fixed by ``tune``) and the selection rule. The study-file parser
checks a study's ``[tuning]`` and ``tune`` tables with these; :mod:`tapm_opt.studies.tuning` runs
the search (``docs/tuning.md``).
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ..design.registry import Dimension, kind as controller_kind
from ..errors import TapmError
from .kpi_catalogue import UnknownKpiError, kpi as catalogue_kpi

__all__ = ["TuningError", "Objective", "Constraint", "TuningSettings", "Param", "tuning_settings", "search_space",
           "spec_from_params", "DEFAULT_OBJECTIVES", "ALWAYS_REPORTED", "CONTEXT_KPIS", "default_params", "SUMMED_KPIS", "MAX_TRIALS", "parse_rule", "GROUP_LABELS"]

#: The objectives when ``[tuning] objectives`` is not given: the turret's largest offset (worst over
#: the cases) and the thrust energy (summed over the cases), both minimised.
DEFAULT_OBJECTIVES = ("offset_max", "thrust_energy")
#: KPIs that trials.csv and front.csv always carry (aggregated as an objective would be).
ALWAYS_REPORTED = ("offset_max", "thrust_energy", "time_outside_safe")
#: KPIs trials.csv and front.csv carry as well when the cases report them (aggregated as objectives
#: would be): what the report reads to say where and why one front beats another, and what the
#: riser and the lines' reliability cost.
CONTEXT_KPIS = ("offset_mean", "util_max", "delta_min", "riser_delta_min")
#: Extensive KPIs, aggregated over the cases by their sum (the others by their worst case).
SUMMED_KPIS = frozenset({"thrust_energy", "fuel", "winch_energy", "time_outside_safe", "time_outside_alert"})
#: The case labels a tuning can be split by (``[tuning] per``).
GROUP_LABELS = ("sea_state", "condition")
#: Largest number of trials per controller a run may ask for.
MAX_TRIALS = 100_000
_AGGREGATES = ("max", "min", "sum", "mean")


class TuningError(TapmError, ValueError):
    """A tuning specification names an unknown KPI, parameter or storage, or a bad value."""


# ------------------------------------------------------------------------------------------
# objectives and constraints
# ------------------------------------------------------------------------------------------


def _catalogued(name: Any, where: str) -> Any:
    if not isinstance(name, str):
        raise TuningError(f"{where} = {name!r} must be the name of a KPI (docs/kpis.md)")
    try:
        k = catalogue_kpi(name)
    except UnknownKpiError as exc:
        raise TuningError(f"{where}: {exc}") from None
    if k.kind == "text":
        raise TuningError(f"{where} = {name!r} is a text KPI: it cannot be optimised")
    return k


def _default_aggregate(name: str, direction: str) -> str:
    if name in SUMMED_KPIS:
        return "sum"
    return "min" if direction == "maximise" else "max"


@dataclass(frozen=True)
class Objective:
    """A KPI aggregated over a controller's cases, minimised or maximised.

    Attributes
    ----------
    kpi : str
        A name of the KPI catalogue (``docs/kpis.md``).
    direction : {"minimise", "maximise"}
        The catalogue's direction (a KPI without one must be given it, ``maximise:name``).
    aggregate : {"max", "min", "sum", "mean"}
        Over the cases: the worst case by default, the sum for :data:`SUMMED_KPIS`.
    """

    kpi: str
    direction: str
    aggregate: str

    @classmethod
    def parse(cls, item: Any, where: str = "tuning.objectives") -> "Objective":
        """From ``"offset_max"``, ``"sum(thrust_energy)"``, ``"maximise:delta_min"`` or
        ``{kpi = ..., aggregate = ..., direction = ...}``."""
        direction = aggregate = None
        if isinstance(item, Mapping):
            unknown = set(item) - {"kpi", "aggregate", "direction"}
            if unknown:
                raise TuningError(f"{where}.{sorted(unknown)[0]}: unknown key (kpi, aggregate, direction)")
            name, aggregate, direction = item.get("kpi"), item.get("aggregate"), item.get("direction")
        elif isinstance(item, str):
            text = item.strip()
            m = re.fullmatch(r"(minimise|maximise|minimize|maximize)\s*:\s*(.+)", text)
            if m:
                direction, text = m.group(1).replace("z", "s"), m.group(2).strip()
            m = re.fullmatch(r"(\w+)\((\w[\w\[\]]*)\)", text)
            if m:
                aggregate, text = m.group(1), m.group(2)
            name = text
        else:
            raise TuningError(f"{where} = {item!r} must be a KPI name, e.g. \"offset_max\" or \"sum(thrust_energy)\"")
        k = _catalogued(name, where)
        if direction is None:
            direction = k.direction
        if direction not in ("minimise", "maximise"):
            raise TuningError(f"{where} = {name!r} has no better direction in the KPI catalogue: write "
                              f"\"minimise:{name}\" or \"maximise:{name}\"")
        if aggregate is None:
            aggregate = _default_aggregate(k.name if k.per is None else name, direction)
        if aggregate not in _AGGREGATES:
            raise TuningError(f"{where}: aggregate {aggregate!r} is not one of {', '.join(_AGGREGATES)}")
        return cls(kpi=name, direction=direction, aggregate=aggregate)

    def value(self, per_case: Sequence[Mapping[str, float]]) -> float:
        """The aggregate of the KPI over the cases' KPI dicts (NaN where a case lacks it)."""
        return _aggregate(self.aggregate, [_num(k.get(self.kpi)) for k in per_case])

    @property
    def label(self) -> str:
        return f"{self.aggregate}({self.kpi})"


@dataclass(frozen=True)
class Constraint:
    """``aggregate(kpi) <= bound`` or ``>= bound`` over a controller's cases."""

    kpi: str
    op: str
    bound: float
    aggregate: str

    @classmethod
    def parse(cls, item: Any, where: str = "tuning.constraints") -> "Constraint":
        """From ``"time_outside_safe <= 0"``, ``"riser_delta_min >= 2"`` or ``"sum(x) <= 1e9"``
        (the aggregate: the worst case for the bound by default — the largest value under ``<=``,
        the smallest under ``>=``)."""
        if not isinstance(item, str):
            raise TuningError(f"{where} = {item!r} must read like \"time_outside_safe <= 0\"")
        m = re.fullmatch(r"\s*(?:(\w+)\()?\s*([\w\[\]]+)\s*\)?\s*(<=|>=)\s*([-+0-9.eE]+)\s*", item)
        if not m:
            raise TuningError(f"{where} = {item!r} must read like \"time_outside_safe <= 0\" (a KPI, <= or >=, "
                              "a number)")
        aggregate, name, op, num = m.groups()
        _catalogued(name, where)
        try:
            bound = float(num)
        except ValueError:
            bound = math.nan
        if not math.isfinite(bound):
            raise TuningError(f"{where} = {item!r}: the bound {num!r} is not a finite number")
        if aggregate is None:
            aggregate = "max" if op == "<=" else "min"
        if aggregate not in _AGGREGATES:
            raise TuningError(f"{where}: aggregate {aggregate!r} is not one of {', '.join(_AGGREGATES)}")
        return cls(kpi=name, op=op, bound=bound, aggregate=aggregate)

    def value(self, per_case: Sequence[Mapping[str, float]]) -> float:
        return _aggregate(self.aggregate, [_num(k.get(self.kpi)) for k in per_case])

    def violation(self, value: float) -> float:
        """How far ``value`` is outside the bound (<= 0: met; NaN counts as not met)."""
        if not math.isfinite(value):
            return math.inf
        return value - self.bound if self.op == "<=" else self.bound - value

    @property
    def text(self) -> str:
        return f"{self.kpi} {self.op} {self.bound:g}"


def _num(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _aggregate(how: str, values: Sequence[float]) -> float:
    a = np.asarray(values, dtype=float)
    if a.size == 0 or not np.all(np.isfinite(a)):
        return math.nan
    return float({"max": np.max, "min": np.min, "sum": np.sum, "mean": np.mean}[how](a))


@dataclass(frozen=True)
class TuningSettings:
    """The ``[tuning]`` table of a study file.

    Attributes
    ----------
    objectives : tuple of Objective
        Default :data:`DEFAULT_OBJECTIVES`.
    constraints : tuple of Constraint
    trials : int
        Finished trials per controller (``--trials`` overrides).
    sampler : {"tpe", "nsga2"}
        optuna's multi-objective TPE (default: it learns from few trials, which is what a
        closed-loop case costs) or NSGA-II (populations of ``population`` trials).
    population : int or None
        NSGA-II's population (default ``min(50, max(8, trials // 4))``).
    seed : int
        The sampler's seed: one worker reproduces a run exactly; several interleave their trials
        as they finish.
    select : str or tuple of str
        ``"knee"`` (default: the front point nearest the ideal point, each objective scaled to
        [0, 1] over the front) or a rule ``"min KPI with KPI <= v [and KPI >= v ...]"``; a list of
        them is tried in order, the first that a front design meets choosing (e.g. ``["min
        thrust_energy with time_outside_safe <= 0", "knee"]``: the cheapest design inside the safe
        circle all the time, else the knee).
    verify_seeds : tuple of int
        Seeds the search never used, on which the selected designs are run again.
    start_from_defaults : bool
        The first trial of a new run is the kind's registry default design (where it lies in the
        search space), so each front is at least as good as the hand-picked default (default true).
    per : tuple of {"sea_state", "condition"}
        Tune each controller separately for each sea state, each mooring condition, or each of
        both (default: once over all the cases): a design per group, e.g. the PID's gains per sea
        state and mooring condition for a gain table (``tapm gains --designs``).
    """

    objectives: tuple[Objective, ...] = ()
    constraints: tuple[Constraint, ...] = ()
    trials: int = 30
    sampler: str = "tpe"
    population: int | None = None
    seed: int = 0
    select: str | tuple[str, ...] = "knee"
    verify_seeds: tuple[int, ...] = ()
    per: tuple[str, ...] = ()
    start_from_defaults: bool = True

    def __post_init__(self) -> None:
        per = (self.per,) if isinstance(self.per, str) else tuple(self.per)
        if not all(p in GROUP_LABELS for p in per) or len(set(per)) != len(per):
            raise TuningError(f"tuning.per = {self.per!r} must be a list of {', '.join(GROUP_LABELS)} (each once)")
        object.__setattr__(self, "per", per)
        if not self.objectives:
            object.__setattr__(self, "objectives", tuple(Objective.parse(o) for o in DEFAULT_OBJECTIVES))
        names = [o.kpi for o in self.objectives]
        if len(set(names)) != len(names):
            raise TuningError(f"tuning.objectives = {names}: a KPI is named twice")
        if not (isinstance(self.trials, int) and not isinstance(self.trials, bool) and 1 <= self.trials <= MAX_TRIALS):
            raise TuningError(f"tuning.trials = {self.trials!r} must be a whole number from 1 to {MAX_TRIALS}")
        if self.sampler not in ("tpe", "nsga2"):
            raise TuningError(f"tuning.sampler = {self.sampler!r} is not one of tpe, nsga2")
        if self.population is not None and not (isinstance(self.population, int) and self.population >= 2):
            raise TuningError(f"tuning.population = {self.population!r} must be a whole number >= 2")
        if not (isinstance(self.seed, int) and not isinstance(self.seed, bool) and self.seed >= 0):
            raise TuningError(f"tuning.seed = {self.seed!r} must be a whole number >= 0")
        if isinstance(self.select, (list, tuple)):
            if not self.select:
                raise TuningError("tuning.select = [] must name at least one rule")
            object.__setattr__(self, "select", tuple(self.select))
        for rule in self.rules():
            parse_rule(rule, [o.kpi for o in self.objectives])
        for s in self.verify_seeds:
            if not (isinstance(s, int) and not isinstance(s, bool) and s >= 0):
                raise TuningError(f"tuning.verify_seeds: {s!r} must be a whole number >= 0")
        if not isinstance(self.start_from_defaults, bool):
            raise TuningError(f"tuning.start_from_defaults = {self.start_from_defaults!r} must be true or false")

    def rules(self) -> tuple[str, ...]:
        """The selection rules, in the order they are tried."""
        return self.select if isinstance(self.select, tuple) else (self.select,)

    def reported(self) -> list[tuple[str, Any]]:
        """``(column, Objective or Constraint)`` of every KPI written per trial: the objectives, the
        constraints, then :data:`ALWAYS_REPORTED` not among them (aggregated as objectives)."""
        cols: list[tuple[str, Any]] = [(o.kpi, o) for o in self.objectives]
        for c in self.constraints:
            if c.kpi not in dict(cols):
                cols.append((c.kpi, c))
        for name in ALWAYS_REPORTED:
            if name not in dict(cols):
                cols.append((name, Objective.parse(name)))
        for rule in self.rules():   # the KPIs a selection rule reads
            parsed = parse_rule(rule, [o.kpi for o in self.objectives])
            for name in ((parsed[1], *(c.kpi for c in parsed[2])) if parsed else ()):
                if name not in dict(cols):
                    cols.append((name, Objective.parse(name)))
        for name in CONTEXT_KPIS:
            if name not in dict(cols):
                cols.append((name, Objective.parse(name)))
        return cols


def tuning_settings(table: Mapping[str, Any] | None, where: str = "tuning") -> TuningSettings:
    """:class:`TuningSettings` from a study file's ``[tuning]`` table (every error names its key)."""
    table = dict(table or {})
    allowed = {f.name for f in dataclasses.fields(TuningSettings)}
    for k in table:
        if k not in allowed:
            import difflib

            hint = difflib.get_close_matches(k, sorted(allowed), n=1)
            raise TuningError(f"{where}.{k}: unknown key" + (f"; did you mean {hint[0]!r}?" if hint else
                                                              f"; allowed: {', '.join(sorted(allowed))}"))
    objs = table.pop("objectives", None)
    cons = table.pop("constraints", None)
    if objs is not None and (not isinstance(objs, list) or not objs):
        raise TuningError(f"{where}.objectives = {objs!r} must be a non-empty list of KPI names")
    if cons is not None and not isinstance(cons, list):
        raise TuningError(f"{where}.constraints = {cons!r} must be a list like [\"time_outside_safe <= 0\"]")
    per = table.pop("per", ())
    if not isinstance(per, (list, tuple, str)):
        raise TuningError(f"{where}.per = {per!r} must be a list of {', '.join(GROUP_LABELS)}")
    vs = table.pop("verify_seeds", ())
    if not isinstance(vs, (list, tuple)):
        raise TuningError(f"{where}.verify_seeds = {vs!r} must be a list of whole numbers")
    return TuningSettings(
        objectives=tuple(Objective.parse(o, f"{where}.objectives[{i}]") for i, o in enumerate(objs or ())),
        constraints=tuple(Constraint.parse(c, f"{where}.constraints[{i}]") for i, c in enumerate(cons or ())),
        verify_seeds=tuple(vs), per=(per,) if isinstance(per, str) else tuple(per), **table)


# ------------------------------------------------------------------------------------------
# the search space
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Param:
    """One sampled number of a trial: option ``option`` (component ``index`` of a vector option)."""

    name: str
    option: str
    index: int | None
    dim: Dimension


def search_space(kind_name: str, base_spec: Mapping[str, Any], tune: Mapping[str, Any] | None = None,
                 where: str = "controller") -> tuple[list[Param], dict[str, Any]]:
    """The parameters to sample and the options fixed by ``tune``.

    Starts from the kind's search space (:mod:`tapm_opt.design.registry`); an option the
    controller's specification sets is fixed at that value. ``tune`` narrows or fixes: ``option =
    [low, high]`` a narrower range (in the dimension's units: for ``dead_band`` a fraction of the
    safe radius), ``option = value`` fixed, ``option = ["a", "b"]`` fewer choices.

    Returns
    -------
    params : list of Param
        One per sampled number (``periods`` is three: ``periods[0]`` ...).
    fixed : dict
        ``{option: value}`` fixed by ``tune`` (in the dimension's units, see :func:`spec_from_params`).
    """
    k = controller_kind(kind_name, where)
    space = dict(k.search_space)
    options = set(k.option_names())
    fixed: dict[str, Any] = {}
    for name, v in dict(tune or {}).items():
        p = f"{where}.tune.{name}"
        if name not in options:
            import difflib

            hint = difflib.get_close_matches(name, sorted(options), n=1)
            raise TuningError(f"{p}: {name!r} is not an option of {k.name}" + (f"; did you mean {hint[0]!r}?"
                                                                                 if hint else ""))
        d = space.get(name)
        if isinstance(v, list) and d is not None and d.choices is None:
            if len(v) != 2 or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
                raise TuningError(f"{p} = {v!r} must be a range [low, high] or one value")
            lo, hi = float(v[0]), float(v[1])
            if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
                raise TuningError(f"{p} = {v!r} is an empty or inverted range: give [low, high] with low <= high")
            if d.log and lo <= 0:
                raise TuningError(f"{p} = {v!r}: {name} is searched on a log scale, so low must be > 0")
            space[name] = dataclasses.replace(d, low=lo, high=hi)
        elif isinstance(v, list) and d is not None and d.choices is not None:
            bad = [x for x in v if x not in d.choices]
            if not v or bad:
                raise TuningError(f"{p} = {v!r}: choices must be among {', '.join(map(str, d.choices))}")
            space[name] = dataclasses.replace(d, choices=tuple(v))
        elif isinstance(v, list) and d is None:
            raise TuningError(f"{p} = {v!r}: {name} has no search space in {k.name} (docs/controllers.md); fix it "
                              "with one value")
        else:
            fixed[name] = v
            space.pop(name, None)
    for name in list(space):
        if name in base_spec and name not in (tune or {}):
            space.pop(name)   # the study sets it: fixed there
    params: list[Param] = []
    for name, d in space.items():
        if d.size == 1:
            params.append(Param(name, name, None, d))
        else:
            params += [Param(f"{name}[{i}]", name, i, d) for i in range(d.size)]
    return params, fixed


def default_params(kind_name: str, params: Sequence[Param], safe_radius: float | None) -> dict[str, Any] | None:
    """The registry default design of ``kind_name`` as the values of ``params`` (in the search
    space's units: a dead band as a fraction of the safe radius), or None when a default is not in
    the space (a range ``tune`` narrowed past it, an option without a default value)."""
    from ..design.registry import DEAD_BAND_FRACTION

    opts = controller_kind(kind_name).options()
    out: dict[str, Any] = {}
    for p in params:
        v = getattr(opts, p.option, None)
        d = p.dim
        if v is None and p.option == "dead_band":
            v = DEAD_BAND_FRACTION            # the registry's automatic dead band, relative already
        elif v is not None and d.relative_to == "safe_radius" and not isinstance(v, str):
            if not safe_radius or p.index is not None:
                return None
            v = float(v) / float(safe_radius)
        if v is not None and p.index is not None:
            try:
                v = v[p.index]
            except (TypeError, IndexError):
                return None
        if d.choices is not None:
            if v not in d.choices:
                return None
        else:
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not (d.low - 1e-12 <= v <= d.high + 1e-12):
                return None
            v = int(round(v)) if d.integer else float(v)
        out[p.name] = v
    return out


def _scaled(d: Dimension | None, v: Any, safe_radius: float | None) -> Any:
    if d is not None and d.relative_to == "safe_radius" and isinstance(v, (int, float)):
        if safe_radius is None:
            raise TuningError(f"a value relative to the safe radius ({v!r}) needs a scenario with a safe radius")
        return float(v) * float(safe_radius)
    return v


def spec_from_params(base_spec: Mapping[str, Any], params: Sequence[Param], values: Mapping[str, Any],
                     fixed: Mapping[str, Any] | None = None, *, safe_radius: float | None = None) -> dict:
    """The controller specification of a trial: ``base_spec`` with the fixed and sampled options
    (vector options assembled from their components, relative ones scaled by ``safe_radius``)."""
    spec = dict(base_spec)
    kind_name = spec["type"]
    space = controller_kind(kind_name).search_space
    for name, v in dict(fixed or {}).items():
        d = space.get(name)
        if d is not None and d.size > 1 and isinstance(v, (int, float)) and not isinstance(v, bool):
            v = [float(v)] * d.size   # one value for every component (e.g. the PID's three dampings)
        spec[name] = _scaled(d, v, safe_radius)
    vectors: dict[str, dict[int, Any]] = {}
    for p in params:
        v = values[p.name]
        if p.dim.integer and p.dim.choices is None:
            v = int(round(v))
        if p.index is None:
            spec[p.option] = _scaled(p.dim, v, safe_radius)
        else:
            vectors.setdefault(p.option, {})[p.index] = float(v)
    for name, comp in vectors.items():
        spec[name] = [comp[i] for i in sorted(comp)]
    return spec


_RULE = re.compile(r"\s*(min|max)\s+([\w\[\]]+)(?:\s+with\s+(.+))?\s*$")


def parse_rule(rule: Any, objectives: Sequence[str]) -> tuple | None:
    if rule == "knee":
        return None
    if not isinstance(rule, str):
        raise TuningError(f"tuning.select = {rule!r} must be \"knee\" or a rule like \"min thrust_energy with "
                          "offset_max <= 45\"")
    m = _RULE.fullmatch(rule)
    if not m:
        raise TuningError(f"tuning.select = {rule!r} must be \"knee\" or read like \"min thrust_energy with "
                          "offset_max <= 45\"")
    how, target, conds = m.groups()
    _catalogued(target, "tuning.select")
    cs = []
    for part in (conds.split(" and ") if conds else []):
        c = Constraint.parse(part.strip(), "tuning.select")
        cs.append(c)
    return how, target, cs
