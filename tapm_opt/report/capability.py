"""Capability envelopes: polar plots, the output files of ``tapm capability`` and the report section.

Everything here works from the ``capability.json`` dictionary
(:meth:`tapm_opt.design.capability.CapabilityResult.as_json`), so the report draws the same figures
from a saved study as the command does from a fresh computation:

* :func:`capability_figure` — every reported case's limiting wind speed against the environment
  direction on one polar plot (north up, clockwise, the direction the environment comes from;
  circles at the Beaufort table's wind speeds);
* :func:`cases_figure` — one small polar plot per case with the binding constraint of each
  direction as the marker colour;
* :func:`write_capability` — ``capability.csv``, ``capability.json``, ``capability.png`` and
  ``capability_cases.png``, all built first and then written atomically (a failure writes
  nothing);
* :func:`capability_blocks` / :func:`study_capability_section` — the report's capability section
  (the numbers A-D, the settings, a per-case table and the two figures), for a study directory
  that holds ``capability/capability.json``, and the Level 3 results next to it
  (``capability/capability_level3_<controller>.json``: one table and one figure per controller,
  :func:`level3_blocks`);
* :func:`level3_figure`, :func:`level3_files`, :func:`write_level3` — the time-domain (Level 3)
  capability of one controller against its two Level 1 references
  (:mod:`tapm_opt.studies.capability_level3`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from .._io import atomic_write_bytes
from .document import Cell, Fig, Heading, Para, Table, json_section
from .figures import png_bytes

__all__ = ["CAPABILITY_DIR", "LIMIT_COLORS", "capability_blocks", "capability_figure", "capability_files",
           "cases_figure", "level3_blocks", "level3_figure", "level3_files", "study_capability_section",
           "write_capability", "write_level3"]

#: Folder of a study directory the report reads the capability from.
CAPABILITY_DIR = "capability"
#: Marker colour of each binding constraint in :func:`cases_figure`.
LIMIT_COLORS = {"table": "tab:green", "thrust": "tab:blue", "offset": "tab:orange", "tension": "tab:red",
                "riser top": "tab:purple", "riser bottom": "tab:brown"}
_CASE_COLORS = {"mooring": "black", "intact": "tab:blue"}


def _limit_kind(limit: str) -> str:
    return "tension" if limit.startswith("tension") else limit


def _closed(deg: Sequence[float], vals: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Angles [rad] and values sorted by direction and closed (the first point repeated) when the
    directions go round the whole circle."""
    d = np.mod(np.asarray(deg, float), 360.0)
    v = np.asarray([np.nan if x is None else x for x in vals], float)
    o = np.argsort(d)
    d, v = d[o], v[o]
    if len(d) > 2 and (d[0] + 360.0 - d[-1]) <= 1.5 * np.median(np.diff(d)):
        d, v = np.r_[d, d[0] + 360.0], np.r_[v, v[0]]
    return np.radians(d), v


def _polar(ax: Any, table: Sequence[dict], vmax: float) -> None:
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(-1)
    rows = [r for r in table if r["wind_speed"] > 0]
    ax.set_rlim(0.0, vmax)
    ax.set_rticks([r["wind_speed"] for r in rows if r["wind_speed"] <= vmax + 1e-9])
    ax.set_yticklabels([f"BF{r['number']}" if r["number"] % 2 == 0 else "" for r in rows
                        if r["wind_speed"] <= vmax + 1e-9], fontsize=6)
    ax.tick_params(axis="x", labelsize=7)
    ax.grid(True, alpha=0.4)


def _line_style(k: int, n: int) -> dict:
    import matplotlib

    cmap = matplotlib.colormaps["tab20"]
    return {"color": cmap(k % 20), "lw": 0.9, "ls": "-" if k < 20 else "--"}


def _vmax(table: Sequence[dict], values: Sequence[Any]) -> float:
    """Radius of a polar plot: the first table row above the largest value plotted (the table's top
    when none is above), plus 5 %."""
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    top = max(v, default=0.0)
    rows = [float(r["wind_speed"]) for r in table]
    above = [w for w in rows if w > top + 1e-9]
    return 1.05 * (min(above) if above else rows[-1])


def capability_figure(data: dict, *, title: str | None = None) -> Figure:
    """Every reported case's limiting wind speed [m/s] against the direction the environment comes
    from (north up, clockwise), with the Beaufort rows as circles and the design sector shaded."""
    st = data["settings"]
    table = st["table"]
    vmax = _vmax(table, [v for c in data["cases"] for v in c["wind_speed"]])
    fig = Figure(figsize=(8.0, 6.6))
    ax = fig.add_axes([0.05, 0.08, 0.62, 0.8], projection="polar")
    _polar(ax, table, vmax)
    dd = math.radians(float(data["design_direction_deg"]))
    half = math.radians(float(st.get("design_sector_deg", 30.0)))
    ax.fill_between(np.linspace(dd - half, dd + half, 30), 0.0, vmax, color="tab:gray", alpha=0.12, lw=0,
                    label=f"design sector ±{math.degrees(half):g}°")
    dirs = data["directions_deg"]
    others = [c for c in data["cases"] if c["kind"] in ("line", "thruster")]
    for k, c in enumerate(others):
        th, v = _closed(dirs, c["wind_speed"])
        style = _line_style(k, len(others))
        if c["kind"] == "thruster":
            style.update(color="tab:red", lw=1.6, ls="--")
        ax.plot(th, v, label=c["name"] + (" (worst thruster)" if c["kind"] == "thruster" else ""), **style)
    for c in data["cases"]:   # intact below the failure cases (they coincide where both reach the table's top)
        if c["kind"] in ("mooring", "intact"):
            th, v = _closed(dirs, c["wind_speed"])
            ax.plot(th, v, color=_CASE_COLORS[c["kind"]], lw=3.0 if c["kind"] == "intact" else 2.2,
                    ls="-" if c["kind"] == "intact" else ":", alpha=0.6 if c["kind"] == "intact" else 1.0,
                    label="thrusters + mooring intact" if c["kind"] == "intact" else "mooring alone",
                    zorder=1 if c["kind"] == "intact" else 5)
    n = data["numbers"]

    def fmt(x: Any) -> str:
        return "–" if x is None else str(x)

    heading = st["heading"] + (f" {st['fixed_heading_deg']:g}°" if st["heading"] == "fixed" else "")
    ax.set_title(title or (f"{data['scenario']}: TAPM capability, Level {st['level']}, heading {heading}\n"
                           f"A {fmt(n['A'])}  B {fmt(n['B'])}  C {fmt(n['C'])}  D {fmt(n['D'])}"
                           f"  (mooring alone {fmt(n['mooring_A'])} / {fmt(n['mooring_B'])})"), fontsize=9)
    ax.legend(loc="upper left", bbox_to_anchor=(1.08, 1.02), fontsize=6.5, frameon=False)
    fig.text(0.02, 0.015, "Limiting wind speed [m/s] (radius; circles: Beaufort rows) against the direction the "
                          "environment comes from (clockwise from north), dynamic allowance "
                          f"{st['dynamic_allowance']:g}.", fontsize=6.5)
    return fig


def cases_figure(data: dict, *, columns: int = 6) -> Figure:
    """One small polar plot per reported case: the limiting wind speed with each direction's
    binding constraint as the marker colour (:data:`LIMIT_COLORS`)."""
    cases = data["cases"]
    st = data["settings"]
    vmax = _vmax(st["table"], [v for c in cases for v in c["wind_speed"]])
    ncol = min(columns, len(cases))
    nrow = math.ceil(len(cases) / ncol)
    fig = Figure(figsize=(2.0 * ncol, 2.15 * nrow + 0.5))
    dirs = data["directions_deg"]
    for k, c in enumerate(cases):
        ax = fig.add_subplot(nrow, ncol, k + 1, projection="polar")
        _polar(ax, st["table"], vmax)
        ax.set_xticklabels([])
        ax.set_yticklabels([])
        th, v = _closed(dirs, c["wind_speed"])
        ax.plot(th, v, color="0.4", lw=0.8)
        cols = [LIMIT_COLORS.get(_limit_kind(lim), "k") for lim in c["limit"]]
        wv = [np.nan if x is None else x for x in c["wind_speed"]]
        ax.scatter(np.radians(dirs), wv, c=cols, s=7, zorder=3)
        ax.set_title(c["name"], fontsize=7, pad=2)
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], marker="o", ls="", color=col, label=name) for name, col in LIMIT_COLORS.items()]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=7, frameon=False)
    fig.subplots_adjust(left=0.02, right=0.98, top=0.95, bottom=0.1, wspace=0.25, hspace=0.35)
    return fig


def capability_files(result: Any) -> dict[str, bytes]:
    """The output files of one capability computation, built in memory: ``capability.csv``,
    ``capability.json``, ``capability.png`` (:func:`capability_figure`) and ``capability_cases.png``
    (:func:`cases_figure`)."""
    data = result.as_json()
    return {**result.data_files(),
            "capability.png": png_bytes(capability_figure(data)),
            "capability_cases.png": png_bytes(cases_figure(data))}


def _write_files(files: dict[str, bytes], out_dir: str | Path) -> list[Path]:
    """Write the built ``files`` (name: bytes) into ``out_dir`` (created), each atomically.
    Returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, blob in files.items():
        p = out / name
        atomic_write_bytes(p, blob)
        paths.append(p)
    return paths


def write_capability(result: Any, out_dir: str | Path) -> list[Path]:
    """Write :func:`capability_files` into ``out_dir`` (created): every file is built before the
    first is written, and each is written atomically. Returns the paths."""
    return _write_files(capability_files(result), out_dir)


def _fmt(x: Any) -> str:
    return "–" if x is None else str(x)


def capability_blocks(data: dict, *, fig_prefix: str = "capability", source: str = "") -> tuple[list, list[Fig]]:
    """The report section of one capability computation (the ``capability.json`` dict): the
    numbers A-D, the settings, one row per case and the two figures. Returns ``(blocks, figures)``;
    the figures are also among the blocks."""
    st = data["settings"]
    n = data["numbers"]
    blocks: list = []
    figs: list[Fig] = []
    heading = "weathervane" if st["heading"] == "weathervane" else f"fixed at {st['fixed_heading_deg']:g}°"
    spread = ("wind, waves and current collinear" if st["level"] == 1 else
              f"wind and current {st['spreads_deg'][0]:.0f}° and {st['spreads_deg'][1]:.0f}° off the waves "
              f"(sea state {st['base_sea_state']})")
    tl = st["tension_limit"]
    blocks.append(Para(
        f"DNV-ST-0111-style capability of **{data['scenario']}** (Level {st['level']}: {spread}; heading {heading}; "
        f"dynamic allowance {st['dynamic_allowance']:g} on the environmental load). An environment passes when a "
        f"quasi-static equilibrium exists with the turret inside the {st['safe_radius_m']:g} m safe circle, every "
        f"line below {tl['capacity_factor']:g}·MBS/γ (γ = {tl['gamma_ULS']:g} intact, {tl['gamma_ALS']:g} with a "
        "line broken; DNV-OS-E301 2008, quasi-static)"
        + (f", the riser's top and bottom angles below {st['riser_limits_deg'][0]:g}° and "
           f"{st['riser_limits_deg'][1]:g}°" if st.get("riser_limits_deg") else "")
        + " and the thrust allocation delivering the rest"
        + (" (thrusters with DNV-ST-0111's Level 1 losses: factor "
           f"{st['thrust_losses']['beta_misc']:g} and {len(st['thrust_losses']['pairs'])} interaction sectors)"
           if st.get("thrust_losses") else " (thrusters without thrust losses)")
        + ". Directions: where the environment comes from, clockwise from north."
        + (f" Table: {st.get('table_name', 'standard')}"
           + (" (rows above Beaufort 11 are the extension, not the standard's)"
              if st.get("table_name") == "extended" else "") + "." if st.get("table_name") else "")
        + (f" Source: `{source}`." if source else "")))
    sector = f"±{st['design_sector_deg']:g}° of {data['design_direction_deg']:g}°"
    blocks.append(Table(
        header=["number", "meaning", "Beaufort", "case"],
        rows=[[Cell("A"), Cell(f"intact, lowest within {sector}"), Cell(_fmt(n["A"])), Cell("intact")],
              [Cell("B"), Cell("intact, lowest over 360°"), Cell(_fmt(n["B"])), Cell("intact")],
              [Cell("C"), Cell(f"worst single failure, within ±{st['design_sector_deg']:g}°"), Cell(_fmt(n["C"])),
               Cell(_fmt(n.get("C_case")))],
              [Cell("D"), Cell("worst single failure, over 360°"), Cell(_fmt(n["D"])), Cell(_fmt(n.get("D_case")))],
              [Cell("–"), Cell("mooring alone (A, B)"), Cell(f"{_fmt(n['mooring_A'])}, {_fmt(n['mooring_B'])}"),
               Cell("mooring")]],
        align=["l", "l", "r", "l"]))
    rows = []
    dirs = data["directions_deg"]
    for c in data["cases"]:
        w = np.array([np.nan if v is None else v for v in c["wind_speed"]], float)
        j = int(np.nanargmin(w)) if np.isfinite(w).any() else 0
        lims: dict[str, int] = {}
        for lim in c["limit"]:
            lims[lim] = lims.get(lim, 0) + 1
        top = ", ".join(f"{k} ({v})" for k, v in sorted(lims.items(), key=lambda kv: -kv[1])[:3])
        rows.append([Cell(c["name"]), Cell(str(min(c["beaufort"]))), Cell(f"{w[j]:.1f}"), Cell(f"{dirs[j]:g}"),
                     Cell(f"{np.nanmean(w):.1f}"), Cell(top)])
    blocks.append(Table(header=["case", "lowest Beaufort", "lowest wind [m/s]", "at direction [°]",
                                "mean wind [m/s]", "binding constraints (directions)"],
                        rows=rows, align=["l", "r", "r", "r", "r", "l"]))
    wt = st.get("worst_thruster")
    f1 = Fig(name=f"{fig_prefix}", png=png_bytes(capability_figure(data)),
             caption="Limiting wind speed against the direction the environment comes from (north up, clockwise), "
                     "circles at the Beaufort rows: mooring alone (dotted black), thrusters with the mooring intact "
                     "(blue), each single line broken (thin) and the worst single thruster failure"
                     + (f" ({wt}, dashed red)" if wt else "") + "; shaded: the design sector of A and C.")
    f2 = Fig(name=f"{fig_prefix}_cases", png=png_bytes(cases_figure(data)),
             caption="Each case's envelope with the binding constraint of every direction: "
                     + ", ".join(f"{k} {v.replace('tab:', '')}" for k, v in LIMIT_COLORS.items()) + ".")
    blocks += [f1, f2]
    figs += [f1, f2]
    return blocks, figs


#: Colour of each controller's Level 3 envelope in :func:`level3_figure`.
LEVEL3_COLORS = {"pid": "tab:orange", "lmpc": "tab:green", "mpc": "tab:purple"}


def _level3_wind(data: dict) -> list:
    """The Level 3 capability as the wind speed of its row (NaN for none) per direction."""
    return [w if b >= 0 else float("nan") for b, w in zip(data["beaufort"], data["wind_speed"])]


def level3_case(data: dict) -> str:
    """The case of a ``capability_level3_*.json`` dict: ``intact``, or ``line <id>`` after that
    line's loss (its settings' ``failed_line``)."""
    fl = data["settings"].get("failed_line")
    return "intact" if fl is None else f"line {fl}"


def _level1_case(ref: dict, case: str) -> dict:
    return next(c for c in ref["cases"] if c["name"] == case)


def level3_figure(datas: Sequence[dict], *, title: str | None = None) -> Figure:
    """The Level 3 capability of one or more controllers (``capability_level3_<controller>.json``
    dicts of one scenario) as the wind speed of the capability row per direction (markers joined
    by lines), with the first one's Level 1 references: without losses, the same limits, the
    dynamic allowance 1.25 (dashed) and 1 (dotted, the bound), of the first one's case
    (:func:`level3_case`)."""
    first = datas[0]
    table = first["settings"]["table"]
    dirs = first["directions_deg"]
    case = level3_case(first)

    def reference(ref: dict) -> list:
        return _level1_case(ref, case)["wind_speed"]

    vals = [v for d in datas for v in _level3_wind(d)] + reference(first["level1_bound"])
    vmax = _vmax(table, vals)
    fig = Figure(figsize=(9.0, 6.4))
    ax = fig.add_axes([0.04, 0.1, 0.56, 0.78], projection="polar")
    _polar(ax, table, vmax)
    for key, ls, mk, label in (("level1", "--", "x", "Level 1, allowance 1.25"),
                               ("level1_bound", ":", "+", "Level 1, allowance 1")):
        th, v = _closed(dirs, reference(first[key]))
        ax.plot(th, v, color="tab:blue", lw=1.6, ls=ls, marker=mk, ms=5, label=label + "\n(no losses, same limits)")
    for d in datas:
        th, v = _closed(d["directions_deg"], _level3_wind(d))
        ctl = d["controller"]
        ax.plot(th, v, color=LEVEL3_COLORS.get(ctl, "black"), lw=2.0, marker="o", ms=4,
                label=f"Level 3, {ctl.upper()} ({d['settings']['duration_s']:g} s x {d['settings']['seeds']} seed"
                      + ("s" if d["settings"]["seeds"] > 1 else "") + ")")
    st = first["settings"]
    ax.set_title(title or f"{first['scenario']}: capability in the time domain, heading {st['heading']}"
                 + ("" if case == "intact" else f", after the loss of {case}"), fontsize=9)
    ax.legend(loc="upper left", bbox_to_anchor=(1.08, 1.02), fontsize=6.5, frameon=False)
    fig.text(0.02, 0.02, "Radius: wind speed [m/s] of the strongest table row held (circles: Beaufort rows), against "
                         "the direction the environment comes from (clockwise from north).", fontsize=6.5)
    return fig


def level3_files(result: Any) -> dict[str, bytes]:
    """The output files of one Level 3 computation, built in memory:
    ``capability_level3_<controller>.csv``, ``.json`` and ``.png`` (:func:`level3_figure`)."""
    files = result.data_files()
    data = result.as_json()
    stem = next(iter(files)).rsplit(".", 1)[0]
    return {**files, f"{stem}.png": png_bytes(level3_figure([data]))}


def write_level3(result: Any, out_dir: str | Path) -> list[Path]:
    """Write :func:`level3_files` into ``out_dir`` (created), each file atomically once all are
    built. Returns the paths."""
    return _write_files(level3_files(result), out_dir)


def _mwh(v: Any) -> str:
    return "–" if v is None else f"{v / 3.6e9:.2f}"


def level3_blocks(datas: Sequence[dict], *, fig_prefix: str = "capability_level3") -> tuple[list, list[Fig]]:
    """The report's Level 3 part: what was run, one table per controller (per direction: the Level 3
    capability, the Level 1 references, the deciding run's offset, tension and energy, what failed
    in the row above) and one figure with every controller."""
    blocks: list = []
    first = datas[0]
    st = first["settings"]
    case = level3_case(first)
    blocks.append(Para(
        "**Level 3** (time domain, the controller in the loop"
        + ("" if case == "intact" else f"; the system after the loss of {case}, from the start") +
        "): per direction the strongest table row in which "
        f"the closed loop on the FEM plant keeps the turret inside the {st['safe_radius_m']:g} m safe circle and "
        f"every fairlead tension below {st['tension_utilisation_used']:g}·MBS"
        + (", the riser within its angles" if st.get("riser_limits_deg") else "")
        + (f", the heading within {st['heading_tolerance_deg']:g}° of its setpoint" if "heading_tolerance_deg" in st
           else "")
        + f" for {st['duration_s']:g} s after a {st['warmup_s']:g} s warm-up ({st['seeds']} seed"
        + ("s" if st["seeds"] > 1 else "") + " per row; heading " + st["heading"]
        + ("; thrusters with the Level 1 losses" if st.get("losses") else "") + "). Level 1 for comparison: "
        f"without losses, the same limits, case {case}" + ("" if case == "intact" else " after the failure") +
        ", dynamic allowance 1.25 (L1) and 1 (L1 bound)."))
    for d in datas:
        b1 = _level1_case(d["level1"], level3_case(d))["beaufort"]
        b0 = _level1_case(d["level1_bound"], level3_case(d))["beaufort"]
        rows = []
        for i, e in enumerate(d["directions"]):
            dec, ab = e["decided"], e["above"]
            rows.append([Cell(f"{e['direction_deg']:g}"), Cell(str(e["beaufort"])), Cell(str(b1[i])), Cell(str(b0[i])),
                         Cell("–" if dec is None else f"{dec['offset_max_m']:.1f}"),
                         Cell("–" if dec is None else f"{dec['util_max']:.3f} ({dec['util_line']})"),
                         Cell("–" if dec is None or dec.get("heading_error_max_deg") is None
                              else f"{dec['heading_error_max_deg']:.1f}"),
                         Cell("–" if dec is None else _mwh(dec["thrust_energy_J"])),
                         Cell(e["limit"] if ab is None else f"BF {ab['beaufort']}: {ab['detail'] or ab['limit']}")])
        blocks.append(Para(f"Level 3 with **{d['controller'].upper()}** ({d['settings']['runs']} runs, "
                           f"{d['settings']['elapsed_s']:.0f} s of wall time)."))
        blocks.append(Table(header=["direction [°]", "Level 3", "L1", "L1 bound", "offset max [m]", "T/MBS max (line)",
                                    "heading error max [°]", "energy [MWh]", "row above: what failed"],
                            rows=rows, align=["r", "r", "r", "r", "r", "r", "r", "r", "l"]))
    f = Fig(name=fig_prefix, png=png_bytes(level3_figure(datas)),
            caption="Level 3 capability per controller (the wind speed of the strongest row held) against the "
                    "direction the environment comes from, with Level 1 without losses at the same limits "
                    "(dashed: allowance 1.25; dotted: allowance 1).")
    blocks.append(f)
    return blocks, [f]


def study_capability_section(study_dir: str | Path, problems: list[str] | None = None,
                             *, heading: str = "8 Capability") -> tuple[list, list[Fig]] | None:
    """The report's capability section for a study directory that holds
    ``capability/capability.json`` (``tapm capability SCENARIO --out DIR/capability``) or Level 3
    results ``capability/capability_level3_<controller>.json`` (``--level 3``); None when it holds
    neither. An unreadable file gives a short section saying so (and a line in ``problems``)."""
    import json

    d = Path(study_dir) / CAPABILITY_DIR
    path = d / "capability.json"
    lv3 = sorted(d.glob("capability_level3_*.json")) if d.is_dir() else []
    if not path.is_file() and not lv3:
        return None
    more: list = []
    figs: list[Fig] = []
    if path.is_file():
        more, figs = json_section(path, "tapm-capability/1",
                                  lambda data: capability_blocks(data, source=f"{CAPABILITY_DIR}/capability.json"),
                                  "capability", problems)
    datas = []
    for p in lv3:
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
            if data.get("format") != "tapm-capability-level3/1":
                raise ValueError(f"format = {data.get('format')!r}, expected 'tapm-capability-level3/1'")
            datas.append(data)
        except Exception as exc:  # noqa: BLE001 - a broken file must not stop the report
            if problems is not None:
                problems.append(f"capability section: {p.name} not drawn: {exc}")
            more.append(Para(f"**Capability not shown:** {p.name}: {exc}", css="error"))
    cases: dict[str, list] = {}
    for data in datas:   # one part per case (intact, after a line's loss), each with its figure
        cases.setdefault(level3_case(data), []).append(data)
    for case in sorted(cases, key=lambda c: (c != "intact", c)):
        b3, f3 = level3_blocks(cases[case], fig_prefix="capability_level3" if case == "intact"
                               else f"capability_level3_{case.replace(' ', '')}")
        more += b3
        figs += f3
    return [Heading(2, heading, anchor="capability"), *more], figs
