"""The report's KPI tables: the "better" convention, units and order of the KPIs, the side-by-side
tables (controllers compared on otherwise equal cases), the full KPI table and the per-line table.

"Better": lower is better for offsets, time outside the circles, heading error, tensions,
utilisation, the time below delta_s, DNV ratios and failing lines, riser end angles, energy, power,
fuel, solve times and failure/fallback counts; higher is better for the reliability indices
(``delta_min``, ``delta_min_offline``, ``riser_delta_min``, ``riser_delta_top_min``,
``riser_delta_bottom_min``) and the number of lines that pass a DNV check. Neutral (never marked):
``duration``, ``lines_broken`` and any KPI not named here.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

from .data import CaseInfo, StudyData
from .document import Cell, Table, _fmt, _fmt_text

__all__ = ["kpi_direction", "side_by_side_tables", "condition_groups", "ConditionGroup", "HEADLINE_KPIS",
           "headline_kpis"]

# -- the "better" convention -------------------------------------------------------------------

_LOWER = {
    "offset_max", "offset_mean", "offset_std", "time_outside_safe", "time_outside_alert", "heading_error_max",
    "T_max", "T_mean", "util_max", "utilisation_max", "delta_frac_below", "dnv_uls_max", "dnv_als_max",
    "dnv_uls", "dnv_als", "dnv_uls_fail", "dnv_als_fail", "thrust_energy", "thrust_power_mean", "fuel",
    "solver_time_median", "solver_time_p95", "solver_time_max", "solver_failures", "solver_fallbacks",
    "allocation_fallbacks", "controller_time_median", "controller_time_max",
    "riser_top_angle_max_deg", "riser_bottom_angle_max_deg", "riser_delta_frac_below",
}
_HIGHER = {"delta_min", "delta_min_offline", "riser_delta_min", "riser_delta_top_min", "riser_delta_bottom_min",
           "dnv_uls_pass", "dnv_als_pass"}
_PER_LINE = re.compile(r"^(.*)\[(.*)\]$")

#: The headline KPIs charted per condition (name, what it is), in chart order; ``util_max`` is
#: also found under its older name ``utilisation_max``.
HEADLINE_KPIS: tuple[tuple[str, str], ...] = (
    ("offset_max", "max turret offset"),
    ("time_outside_safe", "time outside the safe circle"),
    ("util_max", "max tension utilisation T/MBS"),
    ("delta_min", "min reliability index δ"),
    ("riser_delta_min", "min riser reliability index δ"),
    ("thrust_energy", "thrust energy"),
)
_ALIASES = {"util_max": ("utilisation_max",)}


def headline_kpis(cases: Sequence[CaseInfo]) -> list[tuple[str, str]]:
    """The (KPI name as in kpis.json, title) of :data:`HEADLINE_KPIS` that at least one case has."""
    have = {k for c in cases if c.kpis for k in c.kpis}
    out = []
    for name, title in HEADLINE_KPIS:
        for n in (name, *_ALIASES.get(name, ())):
            if n in have:
                out.append((n, title))
                break
    return out


def kpi_direction(name: str) -> int:
    """-1 if a lower value of KPI ``name`` is better, +1 if higher is better, 0 if neutral.

    Per-line KPIs (``T_max[3]``) follow their quantity (``T_max``)."""
    m = _PER_LINE.match(name)
    base = m.group(1) if m else name
    if base in _LOWER:
        return -1
    if base in _HIGHER:
        return 1
    return 0


# -- optional helpers from the KPI module (the report works without them) ----------------------

_FALLBACK_UNITS = {
    "duration": "s", "offset_max": "m", "offset_mean": "m", "offset_std": "m", "time_outside_safe": "s",
    "time_outside_alert": "s", "heading_error_max": "deg", "T_max": "N", "T_mean": "N", "util_max": "-",
    "utilisation_max": "-", "delta_min": "-", "delta_frac_below": "-", "dnv_uls_max": "-", "dnv_als_max": "-",
    "dnv_uls": "-", "dnv_als": "-", "dnv_uls_pass": "lines", "dnv_uls_fail": "lines", "dnv_als_pass": "lines",
    "dnv_als_fail": "lines", "lines_broken": "lines", "thrust_energy": "J", "thrust_power_mean": "W", "fuel": "kg",
    "solver_time_median": "s", "solver_time_p95": "s", "solver_time_max": "s", "solver_failures": "-",
    "solver_fallbacks": "-", "allocation_fallbacks": "-", "delta_min_offline": "-",
    "riser_top_angle_max_deg": "deg", "riser_bottom_angle_max_deg": "deg", "riser_delta_min": "-",
    "riser_delta_top_min": "-", "riser_delta_bottom_min": "-", "riser_delta_frac_below": "-",
}


def _kpi_unit(name: str) -> str:
    try:
        from ..studies.kpis import kpi_unit

        u = kpi_unit(name)
        if u:
            return u
    except ImportError:
        pass
    m = _PER_LINE.match(name)
    return _FALLBACK_UNITS.get(m.group(1) if m else name, "")


def _kpi_order(names: Iterable[str]) -> list[str]:
    names = list(dict.fromkeys(names))
    try:
        from ..studies.kpis import kpi_order

        return list(kpi_order(names))
    except ImportError:
        agg = list(_FALLBACK_UNITS)
        return sorted(names, key=lambda n: (0, agg.index(n), n) if n in agg else (1, 0, n))


# -- tables ----------------------------------------------------------------------------------

_LABEL_ORDER = ("scenario", "sea_state", "controller", "condition", "seed")


def _label_keys(cases: Sequence[CaseInfo]) -> list[str]:
    keys = [k for k in _LABEL_ORDER if any(k in c.labels for c in cases)]
    for c in cases:
        for k in c.labels:
            if k not in keys:
                keys.append(k)
    return keys


def _group_key(c: CaseInfo, keys: Sequence[str]) -> tuple:
    return tuple((k, json.dumps(c.labels.get(k), sort_keys=True, default=str)) for k in keys if k != "controller")


def _describe_group(c: CaseInfo, keys: Sequence[str]) -> str:
    parts = [f"{k.replace('_', ' ')} {c.labels[k]}" for k in keys if k != "controller" and k in c.labels]
    return " · ".join(parts) or "all cases"


@dataclass
class ConditionGroup:
    """Cases that share every label except the controller (same scenario, sea state, condition, seed).

    ``columns[i]`` names ``members[i]`` in tables, legends and bar charts: the controller, with the
    case name added when the group has that controller more than once. ``short`` names the group
    by the labels that differ between the groups of the study (one group: its ``condition`` label,
    or all labels without one).
    """

    key: tuple
    description: str
    short: str
    members: list[CaseInfo]
    columns: list[str]


def condition_groups(cases: Sequence[CaseInfo], *, require_kpis: bool = False) -> list[ConditionGroup]:
    """The finished cases (with KPIs when ``require_kpis``) grouped by all labels except
    ``controller``, in study order."""
    done = [c for c in cases if c.status == "finished" and (c.kpis or not require_kpis)]
    keys = _label_keys(done)
    groups: dict[tuple, list[CaseInfo]] = {}
    for c in done:
        groups.setdefault(_group_key(c, keys), []).append(c)
    varying = [k for k in keys if k != "controller"
               and len({json.dumps(m[0].labels.get(k), sort_keys=True, default=str) for m in groups.values()}) > 1]
    out = []
    for key, members in groups.items():
        names = [m.controller for m in members]
        cols = [n if names.count(n) == 1 else f"{n} ({m.name})" for n, m in zip(names, members)]
        desc = _describe_group(members[0], keys)
        short = " · ".join(str(members[0].labels[k]) for k in varying if k in members[0].labels)
        if not short:  # one group: its condition label, else every label
            short = str(members[0].labels["condition"]) if "condition" in members[0].labels else desc
        out.append(ConditionGroup(key=key, description=desc, short=short, members=members, columns=cols))
    return out


def side_by_side_tables(cases: Sequence[CaseInfo]) -> list[tuple[str, Table]]:
    """One table per group of finished cases that share every label except the controller:
    aggregate KPIs (no per-line ones) as rows, one column per controller, the better value marked."""
    out = []
    for g in condition_groups(cases, require_kpis=True):
        members, cols = g.members, g.columns
        kpis = _kpi_order(k for m in members for k in m.kpis if not _PER_LINE.match(k))
        rows = []
        for k in kpis:
            vals = [m.kpis.get(k) for m in members]
            best = _best_flags(k, vals)
            unit = _kpi_unit(k)
            d = kpi_direction(k)
            rows.append([Cell(k, code=True), Cell(unit), Cell({-1: "lower", 1: "higher", 0: "–"}[d])]
                        + [Cell(_fmt(v), best=b) for v, b in zip(vals, best)])
        out.append((g.description,
                    Table(header=["KPI", "unit", "better", *cols], rows=rows,
                          align=["l", "l", "l", *["r"] * len(cols)], css="sbs")))
    return out


def _best_flags(name: str, vals: Sequence[Any]) -> list[bool]:
    """Mark the best value(s) when the KPI has a direction, at least two cases have it and they
    are not all equal."""
    d = kpi_direction(name)
    num = [float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None for v in vals]
    present = [v for v in num if v is not None and math.isfinite(v)]
    if d == 0 or len(present) < 2 or max(present) == min(present):
        return [False] * len(vals)
    target = min(present) if d < 0 else max(present)
    return [v is not None and v == target for v in num]


def _full_kpi_table(study: StudyData) -> tuple[Table | None, str]:
    """The whole KPI table (kpis.csv), transposed: one row per column of the CSV, one column per case."""
    note = ""
    if study.kpi_csv is not None:
        header, rows = study.kpi_csv
        note = ("From `kpis.csv` (one column per case; values rounded to 4 significant digits, "
                "full precision in the CSV).")
    else:
        done = [c for c in study.cases if c.status == "finished" and c.kpis]
        if not done:
            return None, "No KPI table: `kpis.csv` is missing and no case has `kpis.json`."
        keys = _label_keys(done)
        kn = _kpi_order(k for c in done for k in c.kpis)
        header = ["id", "name", *keys, *kn]
        rows = [[c.id, c.name, *(str(c.labels.get(k, "")) for k in keys), *(repr(c.kpis[k]) if k in c.kpis else ""
                                                                           for k in kn)] for c in done]
        note = "`kpis.csv` is missing: the table is built from the cases' `kpis.json`."
    if not rows:
        return None, "`kpis.csv` has no rows."
    try:
        name_col = header.index("name")
    except ValueError:
        name_col = 0
    cols = [r[name_col] if name_col < len(r) else "" for r in rows]
    t_rows = []
    for j, h in enumerate(header):
        if j == name_col:
            continue
        unit = _kpi_unit(h) if j > name_col else ""
        label = f"{h} [{unit}]" if unit and h not in ("id", *_LABEL_ORDER) else h
        t_rows.append([Cell(label, code=True)] + [Cell(_fmt_text(r[j]) if j < len(r) else "") for r in rows])
    return Table(header=["column", *cols], rows=t_rows, align=["l", *["r"] * len(cols)], css="full"), note


def _csv_table(header: list[str], rows: list[list[str]]) -> Table:
    return Table(header=list(header), rows=[[Cell(_fmt_text(x)) for x in r] for r in rows],
                 align=["l"] * len(header))


def _line_table(kpis: dict, line_ids: Sequence[str]) -> Table | None:
    qs = [q for q in ("T_max", "T_mean", "util_max", "delta_min", "delta_frac_below", "delta_min_offline", "dnv_uls",
                      "dnv_als")
          if any(f"{q}[{lid}]" in kpis for lid in line_ids)]
    if not qs:
        return None
    rows = [[Cell(lid)] + [Cell(_fmt(kpis.get(f"{q}[{lid}]"))) for q in qs] for lid in line_ids]
    head = [f"{q} [{_kpi_unit(q)}]" if _kpi_unit(q) else q for q in qs]
    return Table(header=["line", *head], rows=rows, align=["l", *["r"] * len(qs)])
