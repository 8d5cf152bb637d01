"""Study report: one self-contained HTML file and a Markdown version, from saved results only.

:func:`write_report` reads a study directory (see :mod:`tapm_opt.report.data` and
``docs/report.md``), draws the figures, builds the tables and writes ``report.html`` (figures
inline as base64 PNG, CSS inline, no external resource) and ``report.md`` (figures as PNG files in
``report_files/`` next to it, linked relatively). Nothing is simulated: the report uses the saved
``result.npz``, ``kpis.json``, ``kpis.csv`` and gain tables.

Sections: 1 Study, 2 Scenario, 3 Controllers compared (per condition, every controller overlaid:
turret offset, heading, max line tension, thrust power; the setpoint layers and lowest causal
reliability indices; with a riser or an optimal setpoint, the reliability-safe region, tracks,
setpoints and delta(t), :mod:`tapm_opt.report.reliability`), 4 Cases, 5 KPIs (bar charts of the
headline KPIs, then the tables), 6 Gains, 7 Failed cases, then with ``verification.json`` 8
Verification (:mod:`tapm_opt.report.verification`) and with a capability computation the
capability envelopes. Each result is read once: the case
sections are built first and keep the reduced curves the comparison figures need.

The document model and its renderers are in :mod:`tapm_opt.report.document`, the KPI tables in
:mod:`tapm_opt.report.kpi_tables`, the plotted series derived from the saved results in
:mod:`tapm_opt.report.series` and the figures in :mod:`tapm_opt.report.figures`.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import re
from pathlib import Path

import numpy as np

from .._io import atomic_write_bytes, atomic_write_text
from . import figures as figs
from .data import CaseInfo, ReportError, StudyData, read_study
from .document import (BEST_MARK, Cell, Details, Fig, Heading, Para, Pre, RawMarkdown, Table, _fmt, render_html,
                       render_markdown)
from .kpi_tables import (_PER_LINE, HEADLINE_KPIS, ConditionGroup, _csv_table, _full_kpi_table, _kpi_unit,
                         _label_keys, _line_table, condition_groups, headline_kpis, kpi_direction,
                         side_by_side_tables)
from .reliability import OPTIMAL_SETPOINTS, case_reliability, plan_half_width, reliability_figure, safe_regions
from .series import causal_traces, comparison_series, decisions_of, events_of

__all__ = ["write_report", "ReportError", "kpi_direction", "side_by_side_tables", "BEST_MARK"]


#: Decisions of the estimator and controller listed per case at most (the rest are counted).
MAX_DECISIONS = 12


def _status_text(c: CaseInfo) -> str:
    return {"finished": "finished", "failed": "FAILED", "incomplete": "not finished"}.get(c.status, c.status)


def _slug(s: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]+", "-", s).strip("-") or "x"


def _case_section(c: CaseInfo, blocks: list, figures_out: list[Fig], problems: list[str],
                  overlay_out: dict | None = None, rel_out: dict | None = None) -> None:
    """The figures and tables of one finished case; with ``overlay_out``, also store
    ``overlay_out[c.id] = (ComparisonSeries, scenario limits or None)`` for the controller overlays,
    with ``rel_out``, ``rel_out[c.id] = (CaseReliability, scenario)`` for the reliability figures."""
    lab = ", ".join(f"{k} {v}" for k, v in c.labels.items())
    blocks.append(Heading(3, f"{c.name}", anchor=f"case-{c.id}"))
    blocks.append(Para(f"Case `{c.id}` · {lab}"))
    try:
        result = c.load_result()
    except Exception as exc:  # noqa: BLE001 - one unreadable case must not stop the report
        npz = c.folder / "result.npz"
        msg = f"case {c.id}: {exc}" if str(npz) in str(exc) else f"case {c.id}: cannot read {npz}: {exc}"
        problems.append(msg)
        blocks.append(Para(f"**Result not readable:** {exc}", css="error"))
        return
    scenario = None
    try:
        scenario = c.scenario()
    except Exception as exc:  # noqa: BLE001
        problems.append(f"case {c.id}: cannot rebuild the scenario from inputs['scenario']: {exc}")
    if overlay_out is not None:
        try:
            overlay_out[c.id] = (comparison_series(result, scenario, label=c.controller, controller=c.controller),
                                 scenario.limits if scenario is not None else None)
        except Exception as exc:  # noqa: BLE001 - the overlay then leaves this case out
            problems.append(f"case {c.id}: curves for the controller comparison not computed: {exc}")
    events = events_of(result)
    if events:
        blocks.append(Para("Events: " + "; ".join(f"t = {float(e[0]):g} s: {e[1]}" for e in events
                                                  if isinstance(e, (list, tuple)) and len(e) >= 2)))
    decisions = decisions_of(result)
    if decisions:
        shown = "; ".join(f"t = {t:g} s: {text}" for t, text in decisions[:MAX_DECISIONS])
        more = len(decisions) - MAX_DECISIONS
        blocks.append(Para("Decisions: " + shown + (f"; and {more} more" if more > 0 else "")))
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

    add("motion", lambda: figs.motion_figure(result, scenario, title=f"{title}: turret position and heading"),
        f"{c.name}: turret offset — the centre of turret relative to its position at the field zero point — "
        "in plan view (y east right, x north up) with the safe and alert circles and the setpoint; turret "
        "offset and heading with their setpoints over time.")
    traces = None
    try:
        traces = causal_traces(result, scenario)
    except Exception as exc:  # noqa: BLE001
        problems.append(f"case {c.id}: reliability index not drawn: {exc}")
    if rel_out is not None and (traces is not None or _setpoint_of(c, result) in OPTIMAL_SETPOINTS):
        try:
            rel_out[c.id] = (case_reliability(result, scenario, traces, label=c.controller, controller=c.controller,
                                              setpoint=_setpoint_of(c, result)), scenario)
        except Exception as exc:  # noqa: BLE001 - the condition's reliability figure then leaves this case out
            problems.append(f"case {c.id}: tracks for the reliability figure not computed: {exc}")
    cap = (f"{c.name}: fairlead tension per line with the allowed tension (tension_utilisation·MBS, dashed red) "
           "and the MBS (black)")
    if traces is not None:
        cap += ("; below, the causal reliability index δ(t) as the KPIs evaluate it (recomputed from the saved "
                "tensions and riser angles: 100 s trailing low-pass, 600 s σ window, restarted at the first line "
                "break, a broken line counted up to its break; grey where the estimate is not ready yet) of the "
                "four lowest lines" + (" and of the riser top (solid black) and bottom (dashed black) angles"
                                       if traces.riser else "")
                + f", against δ_s = {traces.delta_s:g} (dashed red). Its lowest line value is the KPI `delta_min`"
                + (", its lowest riser value `riser_delta_min`" if traces.riser else ""))
    add("lines", lambda: figs.tension_figure(result, scenario, title=f"{title}: mooring lines", traces=traces),
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


#: Most conditions in one KPI bar chart (more go to further charts).
BARS_PER_CHART = 8


def _limits_key(lim) -> tuple:
    return tuple(getattr(lim, a, None) for a in ("safe_radius", "alert_radius", "tension_utilisation"))


def _comparison_section(g: ConditionGroup, n: int, blocks: list, figures_out: list[Fig], problems: list[str],
                        overlay: dict, styles: dict) -> None:
    """Section 3, one condition: every controller overlaid (turret offset, heading, max tension, power)."""
    blocks.append(Heading(3, f"Condition {n + 1}: {g.description}", anchor=f"compare-{n + 1}"))
    blocks.append(Para("Cases: " + ", ".join(f"{col} (`{m.id}`)" for col, m in zip(g.columns, g.members)) + "."))
    if len({m.controller for m in g.members}) < 2:
        blocks.append(Para("Only one controller ran in this condition: the figure shows it alone.", css="note"))
    series, limits, left_out = [], None, []
    for col, m in zip(g.columns, g.members):
        got = overlay.get(m.id)
        if got is None:
            left_out.append(col)
            continue
        cs, lim = got
        cs.label = col
        series.append(cs)
        if limits is None and lim is not None:
            limits = lim
    if left_out:
        blocks.append(Para(f"Left out (result not readable, see the problems at the end): {', '.join(left_out)}.",
                           css="note"))
    if not series:
        blocks.append(Para("No readable result in this condition: no comparison figure.", css="note"))
        return
    try:
        ov = figs.comparison_figure(series, limits, styles=styles,
                                    title=f"Controllers compared: {g.description}")
        png = figs.png_bytes(ov.figure)
    except Exception as exc:  # noqa: BLE001 - one figure must not stop the report
        problems.append(f"comparison figure of {g.description} not drawn: {exc}")
        blocks.append(Para(f"**Comparison figure not drawn:** {exc}", css="error"))
        return
    tq = {"utilisation": "the largest fairlead tension over the lines as utilisation T/MBS (with the allowed "
                         "utilisation, dashed red)",
          "tension": "the largest fairlead tension over the lines in MN (the MBS is unknown, so no utilisation)",
          "": "line tensions (not logged)"}[ov.tension_quantity]
    radii = ("with the safe (green) and alert (red) radii" if limits is not None
             else "(safe and alert radii unknown: no scenario)")
    f = Fig(name=f"compare_{n + 1}", png=png,
            caption=f"{g.short}: every controller on shared time axes, one colour per controller as in every "
                    f"comparison figure and KPI chart. Top to bottom: horizontal turret offset in m {radii}; "
                    f"heading in degrees; {tq}; total thrust power in MW. Dotted purple lines: events.")
    figures_out.append(f)
    blocks.append(f)
    if ov.notes:
        blocks.append(Para("Not in the figure: " + "; ".join(ov.notes) + ".", css="note"))


def _setpoint_of(c: CaseInfo, result=None) -> str:
    """The setpoint layer of a case: the study's ``closed_loop`` inputs, else the result's metadata."""
    loop = c.inputs.get("closed_loop")
    sp = loop.get("setpoint") if isinstance(loop, dict) else None
    if sp is None and result is not None and isinstance(result.meta, dict):
        sp = result.meta.get("setpoint")
    return str(sp) if sp is not None else "?"


def _setpoint_text(c: CaseInfo, layer: str) -> str:
    loop = c.inputs.get("closed_loop")
    opts = loop.get("setpoint_options") if isinstance(loop, dict) else None
    if isinstance(opts, dict) and opts:
        return f"{layer}, " + ", ".join(f"{k} = {_fmt(v) if isinstance(v, (int, float)) else v}"
                                        for k, v in opts.items())
    return layer


def _reliability_section(g: ConditionGroup, n: int, blocks: list, figures_out: list[Fig], problems: list[str],
                         rel: dict, styles: dict) -> None:
    """Section 3, one condition: the lowest causal index of lines and riser per controller and the
    setpoint layer (a paragraph), then, with a riser or an optimal setpoint, the reliability figure."""
    from ..studies.kpis import DELTA_S_DEFAULT

    parts = []
    for col, m in zip(g.columns, g.members):
        got = rel.get(m.id)
        layer = got[0].setpoint if got is not None else _setpoint_of(m)
        k = m.kpis or {}
        vals = []
        for key, what in (("delta_min", "lines"), ("riser_delta_min", "riser")):
            v = k.get(key)
            if isinstance(v, (int, float)):
                vals.append(f"{what} {_fmt(v)}" + (" (below δ_s)" if v < DELTA_S_DEFAULT else ""))
            elif key == "delta_min" or (got is not None and got[0].has_riser):
                vals.append(f"{what} n/a")
        parts.append(f"**{col}** (setpoint {_setpoint_text(m, layer)}): " + ", ".join(vals))
    if parts:
        blocks.append(Para(f"Lowest causal reliability index over the run (KPIs `delta_min`, `riser_delta_min` "
                           f"from kpis.json; δ_s = {DELTA_S_DEFAULT:g}; n/a: no segment long enough for the "
                           "monitor's 700 s of windows): " + "; ".join(parts) + "."))
    members = [(col, m, rel[m.id]) for col, m in zip(g.columns, g.members) if m.id in rel]
    if not members:
        return
    want = any(got[0].has_riser for _, _, got in members) or any(got[0].setpoint in OPTIMAL_SETPOINTS
                                                                  for _, _, got in members)
    if not want:
        return
    cases = []
    for col, m, (cr, _) in members:
        cr.label = col
        cases.append(cr)
    scenario = next((sc for _, _, (_, sc) in members if sc is not None), None)
    limits = scenario.limits if scenario is not None else None
    regions, map_note = [], ""
    hw = plan_half_width(cases, limits)
    if scenario is None:
        map_note = "no safe region: the scenario could not be rebuilt"
    else:
        ss = None
        sid = g.members[0].inputs.get("sea_state")
        try:
            ss = scenario.sea_state(sid) if isinstance(sid, str) else None
        except Exception as exc:  # noqa: BLE001 - the map then sees still water
            map_note = f"sea state {sid!r} not found ({exc}): the riser's current is left out of the map"
        regions = safe_regions(cases, scenario, ss, half_width=hw)
    try:
        rf = reliability_figure(cases, regions, limits, title=f"Reliability and setpoints: {g.description}",
                                delta_s=DELTA_S_DEFAULT, styles=styles, half_width=hw)
        png = figs.png_bytes(rf.figure)
    except Exception as exc:  # noqa: BLE001 - one figure must not stop the report
        problems.append(f"reliability figure of {g.description} not drawn: {exc}")
        blocks.append(Para(f"**Reliability figure not drawn:** {exc}", css="error"))
        return
    inputs = []
    for reg in regions:
        i = reg.inputs
        tau = ("mean τ_env = (" + ", ".join(f"{v / 1e3:.0f}" for v in i.tau_env) + ") kN, kN, kN·m in {B}"
               if i.tau_env is not None else "τ_env not logged")
        ks = list(i.ksigma_lines.values())
        kstxt = (f"k·σ of the lines {min(ks) / 1e3:.0f}–{max(ks) / 1e3:.0f} kN" if ks else "no line k·σ")
        if reg.map is not None and reg.map.delta_riser is not None:
            kstxt += (f", of the riser top {np.degrees(i.ksigma_riser[0]):.2f}° and bottom "
                      f"{np.degrees(i.ksigma_riser[1]):.2f}°")
        state = i.state + (f" (lines {', '.join(i.broken)} left out; dashed teal)" if i.broken
                           else " (solid dark green, filled)")
        inputs.append(f"{state}: heading {np.degrees(i.heading):.1f}°, {tau}, {kstxt} — {i.source}"
                      + (f"; **not computed:** {reg.error}" if reg.map is None else ""))
    cap = (f"{g.short}: left, the reliability-safe region — turret offsets where every line's and the riser's "
           f"reliability index is at least δ_s = {DELTA_S_DEFAULT:g} on the design models "
           "(`design.setpoint.reliability_map`: catenary lines, quasi-static riser in the sea state's current) — "
           "with the safe (green) and alert (red) circles, each controller's turret track (thin) and setpoint "
           "trajectory x_d, y_d (dashed, its re-optimised targets ✕), in the controller colours. Right: the "
           "lowest causal reliability index over the lines and over the riser ends (the KPIs `delta_min`, "
           "`riser_delta_min` are their minima), grey where the monitor's windows are still filling, events "
           "dotted. The maps are evaluated at the condition's mean conditions, pooled over its controllers: "
           + "; ".join(inputs) + ("" if inputs else "no map") + ".")
    notes = ([map_note] if map_note else []) + rf.notes
    if notes:
        cap += " Notes: " + "; ".join(notes) + "."
    f = Fig(name=f"reliability_{n + 1}", png=png, caption=cap)
    figures_out.append(f)
    blocks.append(f)


def _kpi_charts(study: StudyData, blocks: list, figures_out: list[Fig], problems: list[str], overlay: dict,
                styles: dict) -> None:
    """Section 5: grouped bar charts of the headline KPIs, one group per condition, one bar per controller."""
    heads = headline_kpis(study.cases)
    groups = condition_groups(study.cases, require_kpis=True)
    if not heads or not groups:
        names = ", ".join(f"`{k}`" for k, _ in HEADLINE_KPIS)
        blocks.append(Para(f"No headline KPI ({names}) in any finished case: no KPI chart.", css="note"))
        return
    lims = {_limits_key(lim): lim for _, lim in overlay.values() if lim is not None}
    lim = next(iter(lims.values())) if len(lims) == 1 else None
    refs: dict[str, list] = {}
    if lim is not None:
        radii = ((lim.safe_radius, "safe", figs.SAFE_COLOR), (lim.alert_radius, "alert", figs.ALERT_COLOR))
        refs["offset_max"] = [(v, f"{nm} radius {v:g} m", c) for v, nm, c in radii if v]
        if lim.tension_utilisation:
            refs["util_max"] = refs["utilisation_max"] = [(lim.tension_utilisation,
                                                          f"allowed {lim.tension_utilisation:.3g}", figs.ALERT_COLOR)]
    try:
        from ..studies.kpis import DELTA_S_DEFAULT

        refs["delta_min"] = refs["riser_delta_min"] = [(DELTA_S_DEFAULT, f"δ_s = {DELTA_S_DEFAULT:g}",
                                                        figs.ALERT_COLOR)]
    except ImportError:
        pass
    chunks = [groups[i:i + BARS_PER_CHART] for i in range(0, len(groups), BARS_PER_CHART)]
    for n, chunk in enumerate(chunks):
        values: dict[str, dict[str, list]] = {k: {} for k, _ in heads}
        controller_of: dict[str, str] = {}
        for j, g in enumerate(chunk):
            for col, m in zip(g.columns, g.members):
                controller_of[col] = m.controller
                for k, _ in heads:
                    values[k].setdefault(col, [None] * len(chunk))[j] = m.kpis.get(k)
        which = f" ({n + 1} of {len(chunks)})" if len(chunks) > 1 else ""
        try:
            bars = figs.kpi_bar_figure(values, groups=[g.short for g in chunk], controller_of=controller_of,
                                       units={k: _kpi_unit(k) for k, _ in heads}, titles=dict(heads),
                                       directions={k: kpi_direction(k) for k, _ in heads}, refs=refs, styles=styles,
                                       title="Headline KPIs per condition" + which)
            png = figs.png_bytes(bars.figure)
        except Exception as exc:  # noqa: BLE001
            problems.append(f"KPI chart{which} not drawn: {exc}")
            blocks.append(Para(f"**KPI chart not drawn:** {exc}", css="error"))
            continue
        f = Fig(name="kpi_bars" if n == 0 else f"kpi_bars_{n + 1}", png=png,
                caption="Headline KPIs from each case's kpis.json (the numbers of the side-by-side tables below), "
                        "one group of bars per condition, one bar per controller in the colours of the comparison "
                        "figures; the value is written on each bar, n/a where a case has no such KPI. Panels: "
                        + "; ".join(f"{t} ({k}" + (f", {bars.units[k]})" if bars.units[k] not in ("", "-") else ")")
                                    for k, t in heads)
                        + (". Dashed lines: safe/alert radius, allowed utilisation, δ threshold." if refs else "."))
        figures_out.append(f)
        blocks.append(f)
    legend = "; ".join(f"{g.short} = {g.description}" for g in groups if g.short != g.description)
    if legend:
        blocks.append(Para("Conditions: " + legend + ".", css="note"))


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
    from .capability import study_capability_section
    from .verification import study_verification_section

    styles = figs.controller_styles([c.controller for c in study.cases])
    # None unless DIR/verification.json (or a [verification] table in study.toml)
    verification = study_verification_section(study.path, problems, styles=styles)
    cap_n = 8 + (verification is not None)
    # None unless DIR/capability/capability.json
    capability = study_capability_section(study.path, problems, heading=f"{cap_n} Capability")
    blocks.append(Para("Contents: 1 Study · 2 Scenario · 3 Controllers compared · 4 Cases · 5 KPIs · 6 Gains · "
                       "7 Failed cases" + (" · 8 Verification" if verification is not None else "")
                       + (f" · {cap_n} Capability" if capability is not None else "")))

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
                            "alert (red) circles about the turret centre's rest position.")
            fig_list.append(f)
            blocks.append(f)
        except Exception as exc:  # noqa: BLE001
            problems.append(f"layout figure of {sc.name} not drawn: {exc}")

    # the case sections first (each result is read once), placed after the comparison
    done = [c for c in study.cases if c.status == "finished"]
    case_blocks: list = []
    overlay: dict = {}
    rel: dict = {}
    for c in done:
        _case_section(c, case_blocks, fig_list, problems, overlay, rel)

    # 3. controllers compared
    blocks.append(Heading(2, "3 Controllers compared", anchor="compare"))
    groups = condition_groups(study.cases)
    if not groups:
        blocks.append(Para("No finished case: nothing to compare.", css="note"))
    else:
        blocks.append(Para(
            "One figure per condition (cases that share every label except the controller): every controller "
            "on shared time axes — turret offset, heading, the largest line tension and the thrust power. "
            "Colours: " + ", ".join(f"{nm} {st['color'].replace('tab:', '')}" for nm, st in styles.items())
            + ", the same in every comparison figure and KPI chart. Curves reduced to at most "
            f"{figs.MAX_POINTS} points (min/max per bucket, peaks kept). Below each, the setpoint layer and the "
            "lowest causal reliability index of every controller and, with a riser or an optimal setpoint, "
            "the reliability-safe region with the turret tracks and setpoint trajectories and δ(t) of lines "
            "and riser against δ_s."))
    for n, g in enumerate(groups):
        _comparison_section(g, n, blocks, fig_list, problems, overlay, styles)
        _reliability_section(g, n, blocks, fig_list, problems, rel, styles)

    # 4. cases
    blocks.append(Heading(2, "4 Cases", anchor="cases"))
    if not done:
        blocks.append(Para("No finished case.", css="note"))
    blocks.extend(case_blocks)

    # 5. KPIs
    blocks.append(Heading(2, "5 KPIs", anchor="kpis"))
    blocks.append(Heading(3, "KPI charts"))
    _kpi_charts(study, blocks, fig_list, problems, overlay, styles)
    blocks.append(Heading(3, "KPI tables"))
    blocks.append(Para("Controllers side by side: one table per set of cases that share every label except the "
                       f"controller. The better value of each KPI is **bold** and marked {BEST_MARK} (lower is "
                       "better for offsets, time outside the circles, heading error, tensions, utilisation, time "
                       "below δ_s, DNV ratios, riser end angles, energy, power, fuel, solve times and "
                       "failure/fallback counts; higher is better for the reliability indices δ of the lines and "
                       "the riser (causal `delta_min`, offline `delta_min_offline`, `riser_delta_*_min`) and the "
                       "number of lines passing a DNV check; `duration` and "
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

    # 6. gains
    blocks.append(Heading(2, "6 Gains", anchor="gains"))
    if study.gains_md is not None:
        blocks.append(Para("From `gains/gains.md`:", css="note"))
        blocks.append(RawMarkdown(study.gains_md))
    elif study.gains_csv is not None:
        blocks.append(Para("From `gains/gains.csv`:", css="note"))
        blocks.append(_csv_table(*study.gains_csv))
    else:
        blocks.append(Para("The study has no gain tables (`gains/`).", css="note"))

    # 7. failed
    blocks.append(Heading(2, "7 Failed cases", anchor="failed"))
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
    # 8. limit-state verification (the study's [verification], or tapm study verify DIR)
    if verification is not None:
        blocks.extend(verification[0])
        fig_list.extend(verification[1])
    # 8 or 9. capability envelopes (the study's [capability], or tapm capability SCENARIO --out DIR/capability)
    if capability is not None:
        blocks.extend(capability[0])
        fig_list.extend(capability[1])
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
    md = render_markdown(blocks, fig_rel)
    page = render_html(blocks, title)

    # everything is built: now write (figures first so the Markdown never links a missing file)
    fig_dir.mkdir(parents=True, exist_ok=True)
    names = set()
    for f in fig_list:
        atomic_write_bytes(fig_dir / f"{f.name}.png", f.png)
        names.add(f"{f.name}.png")
    for old in fig_dir.glob("*.png"):
        if old.name not in names and old.name.startswith(
                ("case_", "layout", "compare_", "kpi_bars", "reliability_", "capability", "verification_")):
            old.unlink(missing_ok=True)
    atomic_write_text(out_md, md)
    atomic_write_text(out_html, page)
    return out_html, out_md
