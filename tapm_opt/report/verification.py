"""The report's verification section: the limit-state checks of ``DIR/verification.json``
(written by the study run or ``tapm study verify DIR``, :mod:`tapm_opt.studies.verification_study`).

The section shows the settings and the T-N curves used, the warnings, the strength checks (ULS,
ALS) as utilisation per line side by side for each controller (a composite line's sections below
its fairlead section as rows of their own, labelled ``<line>/<k> <line type>``, :func:`row_label`), the turret offset and riser
angles against their limits, the fatigue damage and lives (FLS), and each controller against the
reference controller (the one named ``PID`` when the study has one, else the first) on the worst
line of every limit state. Nothing is recomputed: every number is read from the file.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Sequence

from .document import Cell, Fig, Heading, Para, Table, _fmt, json_section
from .figures import ALERT_COLOR, kpi_bar_figure, png_bytes

__all__ = ["study_verification_section", "verification_blocks", "reference_controller", "row_label"]


def row_label(row: dict) -> str:
    """How the report names the line section of a row of ``verification.json``: the line id for
    its fairlead section (``T_fairlead[<id>]``, and every row of a file written before the sections
    were checked), ``<line>/<k> <line type>`` for section k (from the anchor up, the scenario's
    order) below it (``T_section[<line>/<k>]``), e.g. ``1/1 poly240``."""
    ch = str(row.get("channel") or "")
    if not ch.startswith("T_section["):
        return str(row.get("line"))
    return f"{row.get('line')}/{row.get('section')} {row.get('line_type')}"


def _num(v: Any) -> float | None:
    """A number of the JSON file (``"inf"`` as infinity), None for anything else."""
    if isinstance(v, bool):
        return None
    if isinstance(v, (int, float)):
        return float(v)
    if v in ("inf", "-inf", "nan"):
        return float(v)
    return None


def _txt(v: Any, scale: float = 1.0) -> str:
    x = _num(v)
    if x is None:
        return "–"
    if math.isinf(x):
        return "∞"
    return _fmt(x / scale)


def reference_controller(controllers: Sequence[str]) -> str | None:
    """The controller the others are compared with: ``PID`` when present, else the first."""
    if not controllers:
        return None
    return "PID" if "PID" in controllers else controllers[0]


def _ordered(values: Sequence[str]) -> list[str]:
    return list(dict.fromkeys(values))


def _best(values: Sequence[float | None], lower: bool = True) -> set[int]:
    ok = [(v, i) for i, v in enumerate(values) if v is not None and not math.isnan(v)]
    if len(ok) < 2:
        return set()
    target = min(v for v, _ in ok) if lower else max(v for v, _ in ok)
    if all(v == target for v, _ in ok):
        return set()
    return {i for v, i in ok if v == target}


def _settings_blocks(data: dict) -> list:
    st = data.get("settings", {})
    psf = data.get("partial_safety_factors", {})
    cc = st.get("consequence_class")
    uls, als = psf.get("ULS", ["?", "?"]), psf.get("ALS", ["?", "?"])
    probs = st.get("probabilities")
    text = (f"{st.get('standard', 'DNV-OS-E301')}, consequence class {cc}: the characteristic tension "
            f"T_c = γ_mean T_mean + γ_dyn (T_mpm − T_mean) with γ = {uls[0]}/{uls[1]} in ULS and "
            f"{als[0]}/{als[1]} in ALS (October 2008 edition, transcribed from secondary sources, unchecked)"
            + (", the class-1 common factor 1.3 on T_mean + T_dyn in ULS when T_mean > 2/3 T_dyn"
               if st.get("common_factor") and cc == 1 else "")
            + "; the utilisation is T_c / (capacity factor · MBS) of the section's own line type. Each line is "
            "checked at its fairlead (T_fairlead, the rows named by the line id) and, for a composite line, at the "
            "top of every section below (T_section, rows named `<line>/<k> <line type>`, k from the anchor up). "
            f"T_mpm is the most probable maximum of a Gumbel fitted ({st.get('mpm_method')}) to the per-seed maxima "
            "of the section's tension; T_mean the mean over the seeds of each record's time-weighted mean (in ALS after "
            "the fault). ULS: conditions without a fault; ALS: conditions with one (the whole record, transient "
            "included; a line the condition breaks is left out). FLS (conditions without a fault): rainflow "
            "ranges of the section's tension, Miner's damage per record with its line type's T-N curve below, the "
            "mean over the seeds; design fatigue factor "
            + ("from the adjacent line (DNV-OS-E301's γ_F: 5, rising to 8 as the damage ratio d_F of the line and "
               "its more damaged neighbour goes from 0.8 to 1; a secondary reading, unchecked; column dff)"
               if st.get("design_fatigue_factor") == "adjacent" else _txt(st.get("design_fatigue_factor")))
            + (f", design life {_txt(st.get('design_life'))} years" if st.get("design_life") is not None else "")
            + ". Samples before t_start = " + _txt(st.get("t_start")) + " s are left out. "
            + ("Sea-state probabilities: " + ", ".join(f"{k} {_txt(v)}" for k, v in probs.items()) + "."
               if probs else "No sea-state probabilities: no annual damage or fatigue life.")
            + " Definitions and sources: `docs/verification.md`; data: `verification.csv`, `verification.json`.")
    blocks: list = [Para(text)]
    lts = data.get("line_types", {})
    if lts:
        rows = []
        for tid, c in lts.items():
            rows.append([Cell(tid, code=True), Cell(str(c.get("component"))),
                         Cell(_txt(c.get("nominal_diameter"), 1e-3)), Cell(_txt(c.get("a_D"))), Cell(_txt(c.get("m"))),
                         Cell(_txt(c.get("area"), 1e-4)), Cell(_txt(c.get("capacity_factor"))),
                         Cell(", ".join(c.get("inferred") or []) or "–")])
        blocks.append(Para("T-N curves n = a_D s^−m (s the tension range over the nominal area, MPa) and capacity "
                           "factors of the line types checked:"))
        blocks.append(Table(header=["line type", "component", "nominal d [mm]", "a_D", "m", "area [cm²]",
                                    "capacity factor", "taken by default"], rows=rows,
                            align=["l", "l", "r", "r", "r", "r", "r", "l"]))
    return blocks


def _strength_tables(rows: list[dict], excluded: list[dict], controllers: list[str]) -> list:
    blocks: list = []
    all_lines = _ordered([r["line"] for r in rows] + [e["line"] for e in excluded])   # the scenario's order
    keys = _ordered([(r["limit_state"], r["condition"], r["sea_state"]) for r in rows
                     if r.get("limit_state") in ("ULS", "ALS")])
    for ls, cond, ss in keys:
        sel = [r for r in rows if (r["limit_state"], r["condition"], r["sea_state"]) == (ls, cond, ss)]
        here = {r["line"] for r in sel} | {e["line"] for e in excluded if (e["condition"], e["sea_state"]) == (cond, ss)}
        lines = [lid for lid in all_lines if lid in here]
        by = {(r["controller"], r["line"]): r for r in sel}
        ctrls = [c for c in controllers if any(r["controller"] == c for r in sel)]
        header = ["line"]
        for c in ctrls:
            header += [f"T_mpm [MN] ({c})", f"T_c [MN] ({c})", f"utilisation ({c})"]
        table_rows = []
        for lid in lines:
            utils = [_num(by[(c, lid)].get("utilisation")) if (c, lid) in by else None for c in ctrls]
            best = _best(utils)
            cells = [Cell(lid)]
            for j, c in enumerate(ctrls):
                r = by.get((c, lid))
                if r is None:
                    cells += [Cell("excluded (broken)"), Cell(""), Cell("")]
                    continue
                u = _txt(r.get("utilisation"))
                v = r.get("verdict")
                cells += [Cell(_txt(r.get("T_mpm"), 1e6)), Cell(_txt(r.get("T_c"), 1e6)),
                          Cell(u + ("" if v == "pass" else f" {str(v).upper()}"), best=j in best)]
            table_rows.append(cells)
        n = sorted({int(r.get("n_seeds") or 0) for r in sel})
        blocks.append(Heading(3, f"{ls}: {cond}, sea state {ss}"))
        blocks.append(Para(f"Seeds per controller: {', '.join(map(str, n))}. Lowest utilisation of each line in "
                           "**bold**; FAIL: utilisation above 1 (or a line that broke from overload), N/A: fewer "
                           "than 2 seeds, no Gumbel fit.", css="note"))
        blocks.append(Table(header=header, rows=table_rows, align=["l"] + ["r"] * (len(header) - 1)))
    return blocks


def _offset_table(offsets: list[dict], controllers: list[str]) -> list:
    if not offsets:
        return []
    keys = _ordered([(o["limit_state"], o["condition"], o["sea_state"], o["quantity"]) for o in offsets])
    by = {(o["controller"], o["limit_state"], o["condition"], o["sea_state"], o["quantity"]): o for o in offsets}
    header = ["limit state", "condition", "sea state", "quantity", "limit"]
    for c in controllers:
        header += [f"MPM ({c})", f"ratio ({c})"]
    rows = []
    for ls, cond, ss, q in keys:
        any_o = next(o for o in offsets if (o["limit_state"], o["condition"], o["sea_state"], o["quantity"])
                     == (ls, cond, ss, q))
        deg = any_o.get("unit") == "rad"
        sc = math.pi / 180.0 if deg else 1.0
        unit = "°" if deg else " m"
        ratios = [_num(by[(c, ls, cond, ss, q)].get("ratio")) if (c, ls, cond, ss, q) in by else None
                  for c in controllers]
        best = _best(ratios)
        cells = [Cell(ls), Cell(cond), Cell(ss), Cell(q),
                 Cell(f"{_txt(any_o.get('limit'), sc)}{unit} ({any_o.get('limit_name')})" if any_o.get("limit")
                      else "none")]
        for j, c in enumerate(controllers):
            o = by.get((c, ls, cond, ss, q))
            if o is None:
                cells += [Cell(""), Cell("")]
                continue
            v = o.get("verdict")
            cells += [Cell(_txt(o.get("mpm"), sc) + unit if _num(o.get("mpm")) is not None else "–"),
                      Cell(_txt(o.get("ratio")) + ("" if v in ("pass", "n/a") else f" {str(v).upper()}"),
                           best=j in best)]
        rows.append(cells)
    return [Heading(3, "Turret offset and riser angles"),
            Para("The most probable maximum (same Gumbel fit) of the turret offset — the centre of turret from its "
                 "field-zero-point position, low-frequency motion — against the safe radius, and of the riser's top "
                 "and bottom angles against their mean critical angles; ratio = MPM / limit, the lowest in **bold**."),
            Table(header=header, rows=rows, align=["l", "l", "l", "l", "l"] + ["r"] * (2 * len(controllers)))]


def _fatigue_tables(rows: list[dict], controllers: list[str], probs: bool) -> list:
    fls = [r for r in rows if r.get("limit_state") == "FLS"]
    if not fls:
        return []
    blocks: list = [Heading(3, "FLS: fatigue damage and life")]
    for cond in _ordered([r["condition"] for r in fls]):
        sel = [r for r in fls if r["condition"] == cond]
        seas = _ordered([r["sea_state"] for r in sel])
        lines = _ordered([r["line"] for r in sel])
        ctrls = [c for c in controllers if any(r["controller"] == c for r in sel)]
        by = {(r["controller"], r["sea_state"], r["line"]): r for r in sel}
        header = ["line"] + [f"damage/record {ss} ({c})" for ss in seas for c in ctrls]
        if probs:
            header += [f"life [years] ({c})" for c in ctrls]
        trows = []
        for lid in lines:
            cells = [Cell(lid)]
            for ss in seas:
                d = [_num(by[(c, ss, lid)].get("damage")) if (c, ss, lid) in by else None for c in ctrls]
                best = _best(d)
                cells += [Cell(_txt(x), best=j in best) for j, x in enumerate(d)]
            if probs:
                life = [_num(by[(c, seas[0], lid)].get("life_years")) if (c, seas[0], lid) in by else None
                        for c in ctrls]
                best = _best(life, lower=False)
                for j, c in enumerate(ctrls):
                    r = by.get((c, seas[0], lid))
                    v = r.get("verdict") if r else None
                    cells.append(Cell(_txt(life[j]) + (" FAIL" if v == "fail" else ""), best=j in best))
            trows.append(cells)
        blocks.append(Para(f"Condition **{cond}**: Miner damage per record (mean over the seeds; lowest in **bold**)"
                           + (" and the fatigue life over every sea state with their probabilities and the design "
                              "fatigue factor (longest in **bold**; FAIL: shorter than the design life)"
                              if probs else "") + "."))
        blocks.append(Table(header=header, rows=trows, align=["l"] + ["r"] * (len(header) - 1)))
    return blocks


def _worst(rows: list[dict], key: str, lower_is_worse: bool = False) -> tuple[float | None, str]:
    vals = [(_num(r.get(key)), r["line"]) for r in rows if _num(r.get(key)) is not None]
    if not vals:
        return None, ""
    v, lid = (min(vals) if lower_is_worse else max(vals))
    return v, lid


def _comparison(rows: list[dict], controllers: list[str], probs: bool) -> list:
    ref = reference_controller(controllers)
    others = [c for c in controllers if c != ref]
    if ref is None or not others:
        return []
    out: list = [Heading(3, f"Controllers against {ref} on the limit states")]
    out.append(Para("For each limit state, condition and sea state: the worst line of each controller — the "
                    "highest utilisation (ULS, ALS), the largest damage per record (FLS)"
                    + (" and the shortest fatigue life (FLS over the sea states)" if probs else "")
                    + f" — and its ratio to {ref}'s (below 1: the controller loads its worst line less; for the "
                      "life, above 1 is better)."))
    keys = _ordered([(r["limit_state"], r["condition"], r["sea_state"]) for r in rows])
    header = ["limit state", "condition", "sea state", "quantity", f"{ref} (line)"]
    for c in others:
        header += [f"{c} (line)", f"{c} / {ref}"]
    trows = []

    def add(ls: str, cond: str, ss: str, quantity: str, key: str, sel: list[dict], lower_is_worse: bool) -> None:
        vals = {c: _worst([r for r in sel if r["controller"] == c], key, lower_is_worse) for c in controllers}
        rv, rl = vals[ref]
        cells = [Cell(ls), Cell(cond), Cell(ss), Cell(quantity), Cell(f"{_txt(rv)} ({rl})" if rv is not None else "–")]
        for c in others:
            v, lid = vals[c]
            ratio = (v / rv) if (v is not None and rv not in (None, 0.0) and math.isfinite(rv)) else None
            better = ratio is not None and ((ratio > 1.0) if lower_is_worse else (ratio < 1.0))
            cells += [Cell(f"{_txt(v)} ({lid})" if v is not None else "–"),
                      Cell(_txt(ratio) if ratio is not None else "–", best=better)]
        trows.append(cells)

    for ls, cond, ss in keys:
        sel = [r for r in rows if (r["limit_state"], r["condition"], r["sea_state"]) == (ls, cond, ss)]
        if ls in ("ULS", "ALS"):
            add(ls, cond, ss, "worst utilisation", "utilisation", sel, False)
        else:
            add(ls, cond, ss, "worst damage per record", "damage", sel, False)
    if probs:
        for cond in _ordered([r["condition"] for r in rows if r["limit_state"] == "FLS"]):
            sel = [r for r in rows if r["limit_state"] == "FLS" and r["condition"] == cond]
            first = {}
            for r in sel:   # one row per line and controller carries its life
                first.setdefault((r["controller"], r["line"]), r)
            add("FLS", cond, "all", "shortest life [years]", "life_years", list(first.values()), True)
    out.append(Table(header=header, rows=trows, align=["l", "l", "l", "l", "r"] + ["r"] * (2 * len(others))))
    return out


def _figures(rows: list[dict], controllers: list[str], styles: dict | None) -> list[Fig]:
    figs: list[Fig] = []
    for kind, states, key, title in (("strength", ("ULS", "ALS"), "utilisation", "Utilisation per line"),
                                     ("fatigue", ("FLS",), "damage", "Fatigue damage per record per line")):
        sel = [r for r in rows if r.get("limit_state") in states]
        if not sel:
            continue
        lines = _ordered([r["line"] for r in sel])
        panels = _ordered([(r["limit_state"], r["condition"], r["sea_state"]) for r in sel])
        values: dict[str, dict[str, list]] = {}
        titles, refs = {}, {}
        for ls, cond, ss in panels:
            k = f"{key} {ls} {cond} {ss}"
            titles[k] = f"{ls} {key}: {cond}, {ss}"
            by = {(r["controller"], r["line"]): _num(r.get(key)) for r in sel
                  if (r["limit_state"], r["condition"], r["sea_state"]) == (ls, cond, ss)}
            values[k] = {c: [by.get((c, lid)) for lid in lines] for c in controllers
                         if any(cc == c for cc, _ in by)}
            if kind == "strength":
                refs[k] = [(1.0, "utilisation 1", ALERT_COLOR)]
        bars = kpi_bar_figure(values, groups=[f"line {x}" for x in lines], controller_of={c: c for c in controllers},
                              titles=titles, directions={k: -1 for k in values}, refs=refs, styles=styles,
                              title=title)
        figs.append(Fig(name=f"verification_{kind}", png=png_bytes(bars.figure),
                        caption=(f"{title} from verification.csv, one panel per limit state, condition and sea "
                                 "state, one bar per controller in the colours of the comparison figures; n/a: no "
                                 "value (a line the condition breaks, or too few seeds)"
                                 + ("; dashed: utilisation 1, the strength check's limit." if kind == "strength"
                                    else "."))))
    return figs


def verification_blocks(data: dict, *, styles: dict | None = None) -> tuple[list, list[Fig]]:
    """The report section of one ``verification.json`` content: settings, warnings, strength
    tables and figure, offsets, fatigue tables and figure, the controllers compared. Returns
    ``(blocks, figures)``; the figures are also among the blocks."""
    rows = [dict(r, line=row_label(r)) for r in data.get("rows", []) if isinstance(r, dict)]
    offsets = [o for o in data.get("offsets", []) if isinstance(o, dict)]
    excluded = [e for e in data.get("excluded", []) if isinstance(e, dict)]
    controllers = _ordered([r["controller"] for r in rows] + [o["controller"] for o in offsets])
    probs = bool((data.get("settings") or {}).get("probabilities"))
    blocks = _settings_blocks(data)
    warnings = data.get("warnings") or []
    if warnings:
        blocks.append(Para("Warnings of the verification:", css="note"))
        blocks += [Para("- " + str(w), css="note") for w in warnings]
    if excluded:
        blocks.append(Para("Left out of the ALS checks (broken by their condition; their record after the break is "
                           "0): " + "; ".join(f"line {e['line']} ({e['controller']}, {e['condition']}, "
                                              f"{e['sea_state']})" for e in excluded) + ".", css="note"))
    if not rows:
        blocks.append(Para("No row: no finished case.", css="note"))
        return blocks, []
    figs = _figures(rows, controllers, styles)
    blocks += _comparison(rows, controllers, probs)
    blocks += _strength_tables(rows, excluded, controllers)
    blocks += [f for f in figs if f.name == "verification_strength"]
    blocks += _offset_table(offsets, controllers)
    blocks += _fatigue_tables(rows, controllers, probs)
    blocks += [f for f in figs if f.name == "verification_fatigue"]
    return blocks, figs


def study_verification_section(study_dir: str | Path, problems: list[str] | None = None, *,
                               heading: str = "8 Verification",
                               styles: dict | None = None) -> tuple[list, list[Fig]] | None:
    """The report's verification section for a study directory that holds ``verification.json``,
    or whose ``study.toml`` has a ``[verification]`` table (then a short section saying how to
    compute it); None otherwise. An unreadable file gives a short section saying so (and a line
    in ``problems``)."""
    from ..studies.store import StudyError
    from ..studies.verification_study import VERIFICATION_JSON, read_verification_table

    d = Path(study_dir)
    path = d / VERIFICATION_JSON
    head = Heading(2, heading, anchor="verification")
    if not path.is_file():
        try:
            has = read_verification_table(d) is not None
        except StudyError:
            has = False
        if not has:
            return None
        return [head, Para(f"The study has a [verification] table but no `{VERIFICATION_JSON}`: run "
                           f"`tapm study verify {d}` and write the report again.", css="note")], []
    more, figs = json_section(path, "tapm-verification/1", lambda data: verification_blocks(data, styles=styles),
                              "verification", problems)
    return [head, *more], figs
