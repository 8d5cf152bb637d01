"""The report's KPI tables: the side-by-side tables (controllers compared on otherwise equal
cases, the better value marked), the full KPI table and the per-line table.

Units, the "better" convention and the column order come from the KPI catalogue
(:mod:`tapm_opt.studies.kpi_catalogue`): lower is better for a KPI the catalogue says to
minimise, higher for one it says to maximise; the others (``duration``, ``mode_switches``,
``thrust_to_command_ratio``, ...) and any name not in the catalogue are never marked.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

from ..studies.kpi_catalogue import kpi_order, kpi_sign, kpi_unit, per_line_kpis
from .data import CaseInfo, StudyData
from .document import Cell, Table, _fmt, _fmt_text

__all__ = ["kpi_direction", "side_by_side_tables", "condition_groups", "ConditionGroup", "HEADLINE_KPIS",
           "headline_kpis"]

# -- the "better" convention -------------------------------------------------------------------

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
    """-1 if a lower value of KPI ``name`` is better, +1 if higher is better, 0 if neutral or not
    a catalogue KPI (:func:`tapm_opt.studies.kpi_catalogue.kpi_sign`).

    Per-line KPIs (``T_max[3]``) follow their quantity (``T_max``)."""
    return kpi_sign(name)


def _kpi_unit(name: str) -> str:
    return kpi_unit(name)


def _kpi_order(names: Iterable[str]) -> list[str]:
    return kpi_order(names)


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
            if k == "fatigue_damage_max" and len(members) >= 2:
                rows.append(_life_ratio_row(vals, cols[0]))
        out.append((g.description,
                    Table(header=["KPI", "unit", "better", *cols], rows=rows,
                          align=["l", "l", "l", *["r"] * len(cols)], css="sbs")))
    return out


def _life_ratio_row(damage: Sequence[Any], first: str) -> list[Cell]:
    """The worst line's fatigue life of each case over the first column's, in the same sea: the
    ratio of their ``fatigue_damage_max`` (life is inversely proportional to Miner's damage per
    record, ``docs/kpis.md``); the longest marked."""
    num = [float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None for v in damage]
    d0 = num[0]
    ratio = [d0 / v if d0 is not None and v is not None and v > 0 and math.isfinite(d0 / v) else None for v in num]
    present = [r for r in ratio if r is not None]
    top = max(present) if len(present) >= 2 and max(present) != min(present) else None
    return ([Cell(f"worst line's fatigue life / {first}'s"), Cell("-"), Cell("higher")]
            + [Cell("" if r is None else f"{r:.3g}", best=top is not None and r == top) for r in ratio])


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
    qs = [q for q in (e.base for e in per_line_kpis()) if any(f"{q}[{lid}]" in kpis for lid in line_ids)]
    if not qs:
        return None
    rows = [[Cell(lid)] + [Cell(_fmt(kpis.get(f"{q}[{lid}]"))) for q in qs] for lid in line_ids]
    head = [f"{q} [{_kpi_unit(q)}]" if _kpi_unit(q) else q for q in qs]
    return Table(header=["line", *head], rows=rows, align=["l", *["r"] * len(qs)])
