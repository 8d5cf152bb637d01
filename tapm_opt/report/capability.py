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
  that holds ``capability/capability.json``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from matplotlib.figure import Figure

from .._io import atomic_write_bytes
from .document import Cell, Fig, Heading, Para, Table, json_section
from .figures import png_bytes

__all__ = ["CAPABILITY_DIR", "capability_figure", "cases_figure", "capability_files", "write_capability",
           "capability_blocks", "study_capability_section", "LIMIT_COLORS"]

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


def capability_figure(data: dict, *, title: str | None = None) -> Figure:
    """Every reported case's limiting wind speed [m/s] against the direction the environment comes
    from (north up, clockwise), with the Beaufort rows as circles and the design sector shaded."""
    st = data["settings"]
    table = st["table"]
    vmax = float(table[-1]["wind_speed"]) * 1.05
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
    vmax = float(st["table"][-1]["wind_speed"]) * 1.05
    ncol = min(columns, len(cases))
    nrow = int(math.ceil(len(cases) / ncol))
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


def write_capability(result: Any, out_dir: str | Path) -> list[Path]:
    """Write :func:`capability_files` into ``out_dir`` (created): every file is built before the
    first is written, and each is written atomically. Returns the paths."""
    files = capability_files(result)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, blob in files.items():
        p = out / name
        atomic_write_bytes(p, blob)
        paths.append(p)
    return paths


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
        + " and the thrust allocation delivering the rest. Directions: where the environment comes from, "
          "clockwise from north." + (f" Source: `{source}`." if source else "")))
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


def study_capability_section(study_dir: str | Path, problems: list[str] | None = None,
                             *, heading: str = "8 Capability") -> tuple[list, list[Fig]] | None:
    """The report's capability section for a study directory that holds
    ``capability/capability.json`` (``tapm capability SCENARIO --out DIR/capability``); None when it
    holds none. An unreadable file gives a short section saying so (and a line in ``problems``)."""
    path = Path(study_dir) / CAPABILITY_DIR / "capability.json"
    if not path.is_file():
        return None
    more, figs = json_section(path, "tapm-capability/1",
                              lambda data: capability_blocks(data, source=f"{CAPABILITY_DIR}/capability.json"),
                              "capability", problems)
    return [Heading(2, heading, anchor="capability"), *more], figs
