"""Study report: one self-contained HTML file and a Markdown version, from saved results only.

:func:`write_report` reads a study directory (see :mod:`tapm_opt.report.data` and
``docs/report.md``), draws the figures, builds the tables and writes ``report.html`` (figures
inline as base64 PNG, CSS inline, no external resource) and ``report.md`` (figures as PNG files in
``report_files/`` next to it, linked relatively). Nothing is simulated: the report uses the saved
``result.npz``, ``kpis.json``, ``kpis.csv`` and gain tables.

"Better" in the side-by-side KPI tables: lower is better for offsets, time outside the circles,
heading error, tensions, utilisation, DNV ratios and failing lines, energy, power, fuel, solve
times and failure/fallback counts; higher is better for the reliability index ``delta_min`` and
the number of lines that pass a DNV check. Neutral (never marked): ``duration``,
``lines_broken`` and any KPI not named here.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from .._io import atomic_write_bytes, atomic_write_text
from ..studies.kpis import format_number
from .data import CaseInfo, ReportError, StudyData, read_study
from . import figures as figs

__all__ = ["write_report", "ReportError", "kpi_direction", "side_by_side_tables", "BEST_MARK"]

BEST_MARK = "✓"

# -- the "better" convention -------------------------------------------------------------------

_LOWER = {
    "offset_max", "offset_mean", "offset_std", "time_outside_safe", "time_outside_alert", "heading_error_max",
    "T_max", "T_mean", "util_max", "utilisation_max", "delta_frac_below", "dnv_uls_max", "dnv_als_max",
    "dnv_uls", "dnv_als", "dnv_uls_fail", "dnv_als_fail", "thrust_energy", "thrust_power_mean", "fuel",
    "solver_time_median", "solver_time_p95", "solver_time_max", "solver_failures", "solver_fallbacks",
    "allocation_fallbacks", "controller_time_median", "controller_time_max",
}
_HIGHER = {"delta_min", "dnv_uls_pass", "dnv_als_pass"}
_PER_LINE = re.compile(r"^(.*)\[(.*)\]$")


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
    "solver_fallbacks": "-", "allocation_fallbacks": "-",
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


def _reliability(result: Any, scenario: Any) -> tuple[dict[str, list], float] | None:
    """delta(t) per line from the saved tensions with the KPI module's reliability index (default
    window), split at the first line break like the KPIs; None when unavailable."""
    try:
        from ..studies.kpis import DELTA_S_DEFAULT, LP_WINDOW_DEFAULT, reliability_index
    except ImportError:
        return None
    if scenario is None:
        return None
    t = result.time
    breaks: dict[str, float] = {}
    for ev in figs._events_of(result):
        try:
            m = re.fullmatch(r"line\s+(\S+)\s+broke", str(ev[1]).strip())
            if m:
                breaks[m.group(1)] = min(float(ev[0]), breaks.get(m.group(1), math.inf))
        except (TypeError, ValueError, IndexError):
            continue
    t_b1 = min(breaks.values(), default=math.inf)
    eps = 1e-9 * max(1.0, abs(float(t[-1])))
    mbs = scenario.line_arrays["MBS"]
    mbs_std = scenario.line_arrays["MBS_std"]
    out: dict[str, list] = {}
    for j, ln in enumerate(scenario.lines):
        ch = f"T_fairlead[{ln.id}]"
        if ch not in result or not mbs_std[j] > 0:
            continue
        T = result[ch]
        alive = t <= breaks.get(ln.id, math.inf) + eps
        intact = alive & (t <= t_b1 + eps)
        damaged = alive & ~intact
        segs = []
        for seg in (intact, damaged):
            if seg.sum() >= 2:
                try:
                    tr = reliability_index(t[seg], T[seg], float(mbs[j]), float(mbs_std[j]), window=LP_WINDOW_DEFAULT)
                except Exception:  # noqa: BLE001 - a figure must not stop the report
                    continue
                segs.append((np.asarray(tr.time), np.asarray(tr.delta)))
        if segs:
            out[ln.id] = segs
    return (out, float(DELTA_S_DEFAULT)) if out else None


# -- document model: blocks rendered to HTML and Markdown --------------------------------------

@dataclass
class Cell:
    text: str
    best: bool = False
    code: bool = False


@dataclass
class Table:
    header: list[str]
    rows: list[list[Cell]]
    align: list[str] = field(default_factory=list)  # "l" or "r" per column
    css: str = ""


@dataclass
class Fig:
    name: str
    png: bytes
    caption: str


@dataclass
class Heading:
    level: int
    text: str
    anchor: str = ""


@dataclass
class Para:
    text: str  # plain text; inline markup: **bold** only
    css: str = ""


@dataclass
class Pre:
    text: str


@dataclass
class Details:
    summary: str
    text: str


@dataclass
class RawMarkdown:
    """Markdown from a file of the study (gain tables): copied into report.md, converted for HTML."""

    text: str


def _fmt(v: Any) -> str:
    """The KPI tables' number format (one definition: :func:`tapm_opt.studies.kpis.format_number`)."""
    return format_number(v)


def _fmt_text(s: str) -> str:
    """A CSV cell: numbers formatted like :func:`_fmt`, text unchanged."""
    try:
        f = float(s)
    except (TypeError, ValueError):
        return s
    if re.fullmatch(r"[+-]?\d+", s.strip()):
        return str(int(s))
    return _fmt(f)


# Markdown rendering

def _md_escape(s: str) -> str:
    return s.replace("\\", "\\\\").replace("|", "\\|").replace("\n", " ")


def _md_cell(c: Cell) -> str:
    s = _md_escape(c.text)
    if c.code and s:
        s = f"`{s}`"
    if c.best and s:
        s = f"**{s}** {BEST_MARK}"
    return s


def _md_table(t: Table) -> str:
    al = t.align or ["l"] * len(t.header)
    lines = ["| " + " | ".join(_md_escape(h) for h in t.header) + " |",
             "|" + "|".join("---:" if a == "r" else "---" for a in al) + "|"]
    for r in t.rows:
        lines.append("| " + " | ".join(_md_cell(c) for c in r) + " |")
    return "\n".join(lines)


def _render_md(blocks: Sequence[Any], fig_dir_rel: str) -> str:
    out: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            out.append("#" * b.level + " " + b.text)
        elif isinstance(b, Para):
            out.append(b.text)
        elif isinstance(b, Pre):
            fence = "```"
            while fence in b.text:
                fence += "`"
            out.append(f"{fence}\n{b.text.rstrip()}\n{fence}")
        elif isinstance(b, Details):
            fence = "```"
            while fence in b.text:
                fence += "`"
            out.append(f"{b.summary}:\n\n{fence}\n{b.text.rstrip()}\n{fence}")
        elif isinstance(b, Table):
            out.append(_md_table(b))
        elif isinstance(b, Fig):
            out.append(f"![{_md_escape(b.caption)}]({fig_dir_rel}/{b.name}.png)\n\n*{b.caption}*")
        elif isinstance(b, RawMarkdown):
            out.append(_demote_md_headings(b.text.strip(), 2))
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _demote_md_headings(text: str, by: int) -> str:
    return "\n".join(("#" * by + ln) if re.match(r"^#{1,6}\s", ln) else ln for ln in text.splitlines())


# HTML rendering

_CSS = """
body{font-family:-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:0 auto;max-width:1400px;
padding:1em 2em;color:#222;line-height:1.4}
h1{border-bottom:2px solid #333;padding-bottom:.2em}h2{border-bottom:1px solid #bbb;margin-top:2em}
table{border-collapse:collapse;margin:.6em 0 1.2em 0;font-size:.85em}
th,td{border:1px solid #ccc;padding:.25em .6em;vertical-align:top}th{background:#f0f0f0;text-align:left}
td.r{text-align:right;font-variant-numeric:tabular-nums}td.best{background:#e3f4e3;font-weight:bold}
.wide{overflow-x:auto;max-width:100%}
pre{background:#f7f7f7;border:1px solid #ddd;padding:.6em;overflow-x:auto;font-size:.85em}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #eee}figcaption{font-size:.85em;color:#555}
p.note{color:#555;font-size:.9em}p.error{color:#a00}code{background:#f3f3f3;padding:0 .2em}
nav ul{columns:2}
"""


def _inline_html(text: str) -> str:
    s = html.escape(text)
    s = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", s)
    s = re.sub(r"`([^`]+)`", r"<code>\1</code>", s)
    return s


def _html_table(t: Table) -> str:
    al = t.align or ["l"] * len(t.header)
    h = "".join(f"<th>{html.escape(x)}</th>" for x in t.header)
    body = []
    for r in t.rows:
        tds = []
        for a, c in zip(al, r):
            cls = " ".join(x for x in ("r" if a == "r" else "", "best" if c.best else "") if x)
            txt = html.escape(c.text)
            if c.code and txt:
                txt = f"<code>{txt}</code>"
            if c.best and txt:
                txt = f"<strong>{txt}</strong> {BEST_MARK}"
            tds.append(f'<td class="{cls}">{txt}</td>' if cls else f"<td>{txt}</td>")
        body.append("<tr>" + "".join(tds) + "</tr>")
    cls = f' class="{t.css}"' if t.css else ""
    return f'<div class="wide"><table{cls}><thead><tr>{h}</tr></thead><tbody>{"".join(body)}</tbody></table></div>'


def _md_to_html(text: str) -> str:
    """Minimal Markdown (headings, pipe tables, paragraphs, fenced code) to HTML for the gain tables."""
    out: list[str] = []
    lines = text.splitlines()
    i = 0
    para: list[str] = []

    def flush() -> None:
        if para:
            out.append(f"<p>{_inline_html(' '.join(para))}</p>")
            para.clear()

    while i < len(lines):
        ln = lines[i]
        if ln.strip().startswith("```"):
            flush()
            j = i + 1
            while j < len(lines) and not lines[j].strip().startswith("```"):
                j += 1
            out.append(f"<pre>{html.escape(chr(10).join(lines[i + 1:j]))}</pre>")
            i = j + 1
            continue
        m = re.match(r"^(#{1,6})\s+(.*)$", ln)
        if m:
            flush()
            lvl = min(len(m.group(1)) + 2, 6)
            out.append(f"<h{lvl}>{_inline_html(m.group(2))}</h{lvl}>")
            i += 1
            continue
        if ln.strip().startswith("|"):
            flush()
            rows = []
            while i < len(lines) and lines[i].strip().startswith("|"):
                rows.append(_split_md_row(lines[i]))
                i += 1
            header, body, align = rows[0], [], []
            for r in rows[1:]:
                if all(re.fullmatch(r":?-{1,}:?", c.strip()) for c in r if c.strip()) and not align:
                    align = ["r" if c.strip().endswith(":") else "l" for c in r]
                    continue
                body.append(r)
            tab = Table(header=[_unmd(h) for h in header],
                        rows=[[Cell(_unmd(c), best=_is_bold(c)) for c in r] for r in body],
                        align=align or ["l"] * len(header))
            out.append(_html_table(tab))
            continue
        if not ln.strip():
            flush()
        else:
            para.append(ln.strip())
        i += 1
    flush()
    return "\n".join(out)


def _split_md_row(line: str) -> list[str]:
    s = line.strip()
    if s.startswith("|"):
        s = s[1:]
    if s.endswith("|") and not s.endswith("\\|"):
        s = s[:-1]
    cells, cur, esc = [], [], False
    for ch in s:
        if esc:
            cur.append(ch)
            esc = False
        elif ch == "\\":
            esc = True
        elif ch == "|":
            cells.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    cells.append("".join(cur).strip())
    return cells


def _is_bold(c: str) -> bool:
    return c.strip().startswith("**")


def _unmd(c: str) -> str:
    return c.replace("**", "").replace("`", "").strip()


def _render_html(blocks: Sequence[Any], title: str) -> str:
    body: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            aid = f' id="{html.escape(b.anchor)}"' if b.anchor else ""
            body.append(f"<h{b.level}{aid}>{html.escape(b.text)}</h{b.level}>")
        elif isinstance(b, Para):
            cls = f' class="{b.css}"' if b.css else ""
            body.append(f"<p{cls}>{_inline_html(b.text)}</p>")
        elif isinstance(b, Pre):
            body.append(f"<pre>{html.escape(b.text)}</pre>")
        elif isinstance(b, Details):
            body.append(f"<details><summary>{html.escape(b.summary)}</summary><pre>{html.escape(b.text)}</pre></details>")
        elif isinstance(b, Table):
            body.append(_html_table(b))
        elif isinstance(b, Fig):
            data = base64.b64encode(b.png).decode("ascii")
            body.append(f'<figure id="fig-{html.escape(b.name)}"><img alt="{html.escape(b.caption)}" '
                        f'src="data:image/png;base64,{data}"><figcaption>{html.escape(b.caption)}</figcaption></figure>')
        elif isinstance(b, RawMarkdown):
            body.append(_md_to_html(b.text))
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
            + "\n".join(body) + "\n</body>\n</html>\n")


# -- report content ----------------------------------------------------------------------------

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


def _status_text(c: CaseInfo) -> str:
    return {"finished": "finished", "failed": "FAILED", "incomplete": "not finished"}.get(c.status, c.status)


def _slug(s: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", s).strip("-") or "x"


def side_by_side_tables(cases: Sequence[CaseInfo]) -> list[tuple[str, Table]]:
    """One table per group of finished cases that share every label except the controller:
    aggregate KPIs (no per-line ones) as rows, one column per controller, the better value marked."""
    done = [c for c in cases if c.status == "finished" and c.kpis]
    keys = _label_keys(done)
    groups: dict[tuple, list[CaseInfo]] = {}
    for c in done:
        groups.setdefault(_group_key(c, keys), []).append(c)
    out = []
    for members in groups.values():
        names = [m.controller for m in members]
        cols = [n if names.count(n) == 1 else f"{n} ({m.name})" for n, m in zip(names, members)]
        kpis = _kpi_order(k for m in members for k in m.kpis if not _PER_LINE.match(k))
        rows = []
        for k in kpis:
            vals = [m.kpis.get(k) for m in members]
            best = _best_flags(k, vals)
            unit = _kpi_unit(k)
            d = kpi_direction(k)
            rows.append([Cell(k, code=True), Cell(unit), Cell({-1: "lower", 1: "higher", 0: "–"}[d])]
                        + [Cell(_fmt(v), best=b) for v, b in zip(vals, best)])
        out.append((_describe_group(members[0], keys),
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
    qs = [q for q in ("T_max", "T_mean", "util_max", "delta_min", "delta_frac_below", "dnv_uls", "dnv_als")
          if any(f"{q}[{lid}]" in kpis for lid in line_ids)]
    if not qs:
        return None
    rows = [[Cell(lid)] + [Cell(_fmt(kpis.get(f"{q}[{lid}]"))) for q in qs] for lid in line_ids]
    head = [f"{q} [{_kpi_unit(q)}]" if _kpi_unit(q) else q for q in qs]
    return Table(header=["line", *head], rows=rows, align=["l", *["r"] * len(qs)])


def _case_section(c: CaseInfo, blocks: list, figures_out: list[Fig], problems: list[str]) -> None:
    lab = ", ".join(f"{k} {v}" for k, v in c.labels.items())
    blocks.append(Heading(3, f"{c.name}", anchor=f"case-{c.id}"))
    blocks.append(Para(f"Case `{c.id}` · {lab}"))
    try:
        result = c.load_result()
    except Exception as exc:  # noqa: BLE001 - one unreadable case must not stop the report
        msg = f"case {c.id}: cannot read {c.folder / 'result.npz'}: {exc}"
        problems.append(msg)
        blocks.append(Para(f"**Result not readable:** {exc}", css="error"))
        return
    scenario = None
    try:
        scenario = c.scenario()
    except Exception as exc:  # noqa: BLE001
        problems.append(f"case {c.id}: cannot rebuild the scenario from inputs['scenario']: {exc}")
    events = figs._events_of(result)
    if events:
        blocks.append(Para("Events: " + "; ".join(f"t = {float(e[0]):g} s: {e[1]}" for e in events
                                                  if isinstance(e, (list, tuple)) and len(e) >= 2)))
    title = f"{c.name} ({c.controller})"

    def add(kind: str, make, caption: str) -> None:
        try:
            fig = make()
        except Exception as exc:  # noqa: BLE001 - a missing channel drops one figure, not the report
            problems.append(f"case {c.id}: {kind} figure not drawn: {exc}")
            return
        if fig is None:
            return
        f = Fig(name=f"case_{_slug(c.id)}_{kind}", png=figs.png_bytes(fig), caption=caption)
        figures_out.append(f)
        blocks.append(f)

    add("motion", lambda: figs.motion_figure(result, scenario, title=f"{title}: position and heading"),
        f"{c.name}: LF position in plan view (y east right, x north up) with the safe and alert circles and "
        "the setpoint; offset from the field zero point and heading with its setpoint over time.")
    rel = None
    try:
        rel = _reliability(result, scenario)
    except Exception as exc:  # noqa: BLE001
        problems.append(f"case {c.id}: reliability index not drawn: {exc}")
    cap = (f"{c.name}: fairlead tension per line with the allowed tension (tension_utilisation·MBS, dashed red) "
           "and the MBS (black)")
    if rel:
        cap += ("; below, the reliability index δ(t) recomputed from the saved tensions (100 s low-pass "
                "window, whole record, split at the first line break); δ_min in the table below is from kpis.json")
    add("lines", lambda: figs.tension_figure(result, scenario, title=f"{title}: mooring lines",
                                             delta=rel[0] if rel else None, delta_s=rel[1] if rel else None),
        cap + ".")
    add("thrusters", lambda: figs.thruster_figure(result, title=f"{title}: thrusters"),
        f"{c.name}: thrust of each thruster and total thruster power.")
    if c.kpis:
        ids = [ln.id for ln in scenario.lines] if scenario is not None else \
            sorted({m.group(2) for k in c.kpis if (m := _PER_LINE.match(k))}, key=_natural)
        tab = _line_table(c.kpis, ids)
        if tab is not None:
            blocks.append(Para("Per-line KPIs (from kpis.json):"))
            blocks.append(tab)


def _natural(s: str) -> tuple:
    return tuple((0, int(p), "") if p.isdigit() else (1, 0, p) for p in re.split(r"(\d+)", s) if p)


def _build(study: StudyData, fig_dir_rel: str, kpi_csv_rel: str) -> tuple[list, list[Fig], str]:
    from .. import __version__

    blocks: list = []
    fig_list: list[Fig] = []
    problems = list(study.problems)
    for c in study.cases:
        problems.extend(c.problems)
    title = f"Study report: {study.name}"
    now = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    blocks.append(Heading(1, title))
    if study.description:
        blocks.append(Para(study.description))
    n_ok = sum(c.status == "finished" for c in study.cases)
    n_fail = sum(c.status == "failed" for c in study.cases)
    n_inc = len(study.cases) - n_ok - n_fail
    blocks.append(Para(f"Written {now} by tapm_opt {__version__} (study run with tapm_opt "
                       f"{study.study.get('tapm_opt_version', '?')}) from `{study.path}`. "
                       f"{len(study.cases)} case{'' if len(study.cases) == 1 else 's'}: {n_ok} finished, {n_fail} failed"
                       + (f", {n_inc} not finished" if n_inc else "") + ". "
                       "Everything below comes from the saved results; nothing was re-simulated."))
    blocks.append(Para("Contents: 1 Study · 2 Scenario · 3 Cases · 4 KPIs · 5 Gains · 6 Failed cases"))

    # 1. study
    blocks.append(Heading(2, "1 Study", anchor="study"))
    sf = study.study.get("study_file")
    if study.study_toml is not None:
        blocks.append(Para("Study file" + (f" ({sf})" if sf else "") + ", as run (`study.toml`):"))
        blocks.append(Pre(study.study_toml))
    else:
        blocks.append(Para("`study.toml` is missing from the study directory.", css="note"))
    keys = _label_keys(study.cases)
    rows = []
    for c in study.cases:
        wt = c.case_json.get("wall_time")
        rows.append([Cell(c.id, code=True), Cell(c.name), *(Cell(str(c.labels.get(k, ""))) for k in keys),
                     Cell(_status_text(c)), Cell(_fmt(wt) if isinstance(wt, (int, float)) else "")])
    blocks.append(Para("Cases:"))
    blocks.append(Table(header=["id", "name", *keys, "status", "wall time [s]"], rows=rows,
                        align=["l", "l", *["l"] * len(keys), "l", "r"]))

    # 2. scenario(s)
    blocks.append(Heading(2, "2 Scenario", anchor="scenario"))
    layouts: dict[str, tuple[CaseInfo, list[str]]] = {}
    for c in study.cases:
        sc = c.inputs.get("scenario")
        if not isinstance(sc, dict):
            continue
        key = json.dumps({k: v for k, v in sc.items() if k != "faults"}, sort_keys=True, default=str)
        layouts.setdefault(key, (c, []))[1].append(c.id)
    if not layouts:
        blocks.append(Para("No case carries its scenario (`inputs.scenario`): no layout plot.", css="note"))
    for n, (c, members) in enumerate(layouts.values()):
        try:
            sc = c.scenario()
        except Exception as exc:  # noqa: BLE001
            problems.append(f"scenario of case {c.id} cannot be rebuilt: {exc}")
            continue
        if len(layouts) > 1:
            blocks.append(Heading(3, f"Scenario {sc.name} (cases {', '.join(members)})"))
        lim = sc.limits
        desc = str(sc.meta.description or "").strip()
        if desc and not desc.endswith("."):
            desc += "."
        blocks.append(Para(f"**{sc.name}**: {desc} Safe radius "
                           f"{_fmt(lim.safe_radius) if lim.safe_radius else '–'} m, alert radius "
                           f"{_fmt(lim.alert_radius) if lim.alert_radius else '–'} m, allowed tension "
                           f"{lim.tension_utilisation:g}·MBS. Faults differ per case (see the case list)."))
        try:
            fig = figs.layout_figure(sc)
            f = Fig(name="layout" if n == 0 else f"layout_{n}", png=figs.png_bytes(fig),
                    caption=f"Mooring layout of {sc.name}, plan view with north up (x north vertical, y east "
                            "horizontal): lines drawn straight from anchor to fairlead with the vessel at the "
                            "field zero point (heading 0); right: the vessel region with the safe (green) and "
                            "alert (red) circles.")
            fig_list.append(f)
            blocks.append(f)
        except Exception as exc:  # noqa: BLE001
            problems.append(f"layout figure of {sc.name} not drawn: {exc}")

    # 3. cases
    blocks.append(Heading(2, "3 Cases", anchor="cases"))
    done = [c for c in study.cases if c.status == "finished"]
    if not done:
        blocks.append(Para("No finished case.", css="note"))
    for c in done:
        _case_section(c, blocks, fig_list, problems)

    # 4. KPIs
    blocks.append(Heading(2, "4 KPIs", anchor="kpis"))
    blocks.append(Para("Controllers side by side: one table per set of cases that share every label except the "
                       f"controller. The better value of each KPI is **bold** and marked {BEST_MARK} (lower is "
                       "better for offsets, time outside the circles, heading error, tensions, utilisation, DNV "
                       "ratios, energy, power, fuel, solve times and failure/fallback counts; higher is better for "
                       "the reliability index δ and the number of lines passing a DNV check; `duration` and "
                       "`lines_broken` are not compared). Values from each case's `kpis.json`, 4 significant "
                       "digits; definitions in `docs/kpis.md`."))
    sbs = side_by_side_tables(study.cases)
    if not sbs:
        blocks.append(Para("No finished case with KPIs.", css="note"))
    for desc, tab in sbs:
        blocks.append(Heading(3, f"Side by side: {desc}"))
        blocks.append(tab)
    blocks.append(Heading(3, "All KPIs"))
    tab, note = _full_kpi_table(study)
    if note:
        blocks.append(Para(note + (f" CSV: `{kpi_csv_rel}`." if study.kpi_csv is not None else ""), css="note"))
    if tab is not None:
        blocks.append(tab)

    # 5. gains
    blocks.append(Heading(2, "5 Gains", anchor="gains"))
    if study.gains_md is not None:
        blocks.append(Para("From `gains/gains.md`:", css="note"))
        blocks.append(RawMarkdown(study.gains_md))
    elif study.gains_csv is not None:
        blocks.append(Para("From `gains/gains.csv`:", css="note"))
        blocks.append(_csv_table(*study.gains_csv))
    else:
        blocks.append(Para("The study has no gain tables (`gains/`).", css="note"))

    # 6. failed
    blocks.append(Heading(2, "6 Failed cases", anchor="failed"))
    failed = [c for c in study.cases if c.status == "failed"]
    if not failed:
        blocks.append(Para("No case failed."))
    for c in failed:
        err = c.error or {}
        blocks.append(Heading(3, f"{c.name} (`{c.id}`)"))
        blocks.append(Para(", ".join(f"{k} {v}" for k, v in c.labels.items())))
        blocks.append(Para(f"**{err.get('type', 'Error')}:** {err.get('message', '(no message)')}", css="error"))
        if err.get("traceback"):
            blocks.append(Details("Traceback", str(err["traceback"])))
    incomplete = [c for c in study.cases if c.status == "incomplete"]
    if incomplete:
        blocks.append(Para("Not finished (no result and no error yet): "
                           + ", ".join(f"{c.name} (`{c.id}`)" for c in incomplete), css="note"))
    if problems:
        blocks.append(Heading(2, "Problems met while writing this report", anchor="problems"))
        for p in problems:
            blocks.append(Para("- " + p, css="error"))
    return blocks, fig_list, title


def write_report(study_dir: str | Path, *, out_html: str | Path | None = None,
                 out_md: str | Path | None = None) -> tuple[Path, Path]:
    """Write the study report as HTML and Markdown; returns ``(html_path, md_path)``.

    Parameters
    ----------
    study_dir : path
        A study output directory (``study.json``, ``cases/<id>/...``; see ``docs/report.md``).
    out_html, out_md : path, optional
        Where to write; default ``study_dir/report.html`` and ``study_dir/report.md``. The
        Markdown figures go to ``<md stem>_files/`` next to the Markdown file.

    Raises
    ------
    ReportError
        ``study_dir`` is missing or not a study directory. Nothing is written then. Problems of
        single cases (unreadable result, failed run) are reported inside the report instead.
    """
    study = read_study(study_dir)
    out_html = Path(out_html) if out_html is not None else study.path / "report.html"
    out_md = Path(out_md) if out_md is not None else study.path / "report.md"
    fig_dir = out_md.parent / f"{out_md.stem}_files"
    fig_rel = Path(os.path.relpath(fig_dir, out_md.parent)).as_posix()
    csv_rel = Path(os.path.relpath(study.path / "kpis.csv", out_md.parent)).as_posix()

    blocks, fig_list, title = _build(study, fig_rel, csv_rel)
    md = _render_md(blocks, fig_rel)
    page = _render_html(blocks, title)

    # everything is built: now write (figures first so the Markdown never links a missing file)
    fig_dir.mkdir(parents=True, exist_ok=True)
    names = set()
    for f in fig_list:
        atomic_write_bytes(fig_dir / f"{f.name}.png", f.png)
        names.add(f"{f.name}.png")
    for old in fig_dir.glob("*.png"):
        if old.name not in names and (old.name.startswith("case_") or old.name.startswith("layout")):
            old.unlink(missing_ok=True)
    atomic_write_text(out_md, md)
    atomic_write_text(out_html, page)
    return out_html, out_md


