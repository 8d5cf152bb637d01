"""Figures of the study report, drawn with matplotlib's object API (no pyplot, no global state).

Plan views follow NED: y (east) on the horizontal axis, x (north) on the vertical axis, equal
scale. Case figures are turret-referenced (:mod:`tapm_opt.report.series`): trajectory, safe and
alert circles and offsets are those of the centre of turret relative to its field-zero-point
position. Long time series are reduced to at most ``MAX_POINTS`` points per curve with a min/max
envelope per bucket so peaks survive. The scenario and case figures return a
:class:`matplotlib.figure.Figure`; the comparison figures return it with what they plot:
:func:`comparison_figure` (every controller of one condition overlaid, :class:`OverlayFigure`) and
:func:`kpi_bar_figure` (grouped bars of the headline KPIs, :class:`KpiBars`), coloured per controller
by :func:`controller_styles`. :func:`png_bytes` renders a figure with the Agg backend.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle

from ..geometry import rot2_apply, turret_position
from .series import (MAX_POINTS, CausalTraces, ComparisonSeries, TurretTrack, decimate, events_of,
                     turret_position_of, turret_track)

__all__ = ["MAX_POINTS", "DPI", "CONTROLLER_COLORS", "decimate", "png_bytes", "controller_styles", "layout_figure",
           "motion_figure", "tension_figure", "thruster_figure", "OverlayFigure", "comparison_figure",
           "KpiBars", "kpi_bar_figure"]

DPI = 100
SAFE_COLOR = "tab:green"
ALERT_COLOR = "tab:red"
EVENT_COLOR = "tab:purple"
#: Controller colours, in order of first appearance in the study; green, red and purple are left
#: out (safe circle, alert circle / allowed tension, events).
CONTROLLER_COLORS = ("tab:blue", "tab:orange", "tab:brown", "tab:cyan", "tab:pink", "tab:olive", "tab:gray",
                     "black", "gold", "navy")
_CONTROLLER_LS = ("-", "--", "-.", ":")
_HATCHES = ("", "//", "..", "xx")


# -- helpers -----------------------------------------------------------------------------------

def controller_styles(controllers: Sequence[str]) -> dict[str, dict]:
    """One style per distinct controller, in order of first appearance: ``{"color", "ls", "hatch"}``.

    The colours are :data:`CONTROLLER_COLORS`; past ten controllers they repeat with another line
    style (and bar hatch). The report computes this once for the whole study, so a controller has
    the same colour in every figure."""
    out: dict[str, dict] = {}
    for name in controllers:
        if name not in out:
            k = len(out)
            n = len(CONTROLLER_COLORS)
            out[name] = {"color": CONTROLLER_COLORS[k % n], "ls": _CONTROLLER_LS[(k // n) % len(_CONTROLLER_LS)],
                         "hatch": _HATCHES[(k // n) % len(_HATCHES)]}
    return out


def _stride(n: int, limit: int = MAX_POINTS) -> slice:
    return slice(None, None, max(1, math.ceil(n / limit)))


def png_bytes(fig: Figure, dpi: int = DPI) -> bytes:
    """The figure as PNG bytes (Agg backend)."""
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def _scale(values: Sequence[float], unit: str) -> tuple[float, str]:
    """(factor, label) with an SI prefix so the largest |value| is below 1000 in the label unit."""
    vmax = float(np.nanmax(np.abs(values))) if len(values) else 0.0
    for f, p in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if vmax >= f:
            return f, p + unit
    return 1.0, unit


def _circles(ax, limits: Any, *, centre: Sequence[float] = (0.0, 0.0), label: bool = True) -> None:
    """Safe and alert circles about ``centre`` = (x north, y east) [m] in the plotted frame."""
    if limits is None:
        return
    for r, c, name in ((limits.safe_radius, SAFE_COLOR, "safe"), (limits.alert_radius, ALERT_COLOR, "alert")):
        if r:
            ax.add_patch(Circle((float(centre[1]), float(centre[0])), r, fill=False, color=c, lw=1.5, ls="--",
                                label=f"{name} circle (r = {r:g} m)" if label else None))


def _ned_axes(ax, title: str, *, quantity: str = "") -> None:
    """Equal-scale plan view; ``quantity`` prefixes the axis labels (e.g. "turret offset")."""
    ax.set_aspect("equal", adjustable="box")
    q = f"{quantity} " if quantity else ""
    ax.set_xlabel(f"{q}y (east) [m]")
    ax.set_ylabel(f"{q}x (north) [m]")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)


def _events(axes: Sequence[Any], events: Sequence[Sequence[Any]]) -> None:
    """Vertical lines at the events; the text is written on the first axes only."""
    for k, ev in enumerate(events):
        try:
            te, text = float(ev[0]), str(ev[1])
        except (TypeError, ValueError, IndexError):
            continue
        for j, ax in enumerate(axes):
            ax.axvline(te, color=EVENT_COLOR, ls=":", lw=1.5, label="event" if (j == 0 and k == 0) else None)
        ax0 = axes[0]
        ax0.annotate(f" {text} (t = {te:g} s)", xy=(te, 1.0), xycoords=("data", "axes fraction"),
                     xytext=(2, -2), textcoords="offset points", va="top", ha="left", fontsize=8,
                     color=EVENT_COLOR)


def _hull(vessel: Any) -> np.ndarray | None:
    """Schematic waterline outline in {B} (x fwd, y stbd), shape (k, 2); None if unknown."""
    L = getattr(vessel, "length_pp", None)
    B = getattr(vessel, "breadth", None)
    if not (L and B and math.isfinite(L) and math.isfinite(B)):
        return None
    ref = getattr(vessel, "reference_point", None)
    x_ap = -float(ref[0]) if ref is not None and math.isfinite(float(ref[0])) else -L / 2
    x_fp = x_ap + L
    bow = min(B, 0.25 * L)
    return np.array([(x_ap, -B / 2), (x_fp - bow, -B / 2), (x_fp, 0.0), (x_fp - bow, B / 2), (x_ap, B / 2)])


def _to_E(p_B: np.ndarray, eta: Sequence[float]) -> np.ndarray:
    """Points (k, 2) given in {B} at pose ``eta`` as (x, y) in {E}: p + R2(psi) p^B (eq. 5)."""
    x, y = rot2_apply(eta[2], p_B[:, 0], p_B[:, 1])
    return np.column_stack([eta[0] + x, eta[1] + y])


# -- scenario ----------------------------------------------------------------------------------

def layout_figure(scenario: Any, *, title: str | None = None) -> Figure:
    """Plan view of the mooring at the field zero point (vessel at x = y = 0, heading 0):
    anchors, lines as straight lines anchor -> fairlead, turret, fairleads, and the safe and alert
    circles about the turret centre's rest position; left the whole pattern, right the vessel region."""
    from ..models.mooring import MooringModel

    eta0 = (0.0, 0.0, 0.0)
    mm = MooringModel.from_scenario(scenario)
    fx, fy = (np.asarray(v, float) for v in mm.fairleads(np.array(eta0)))
    anchors = np.asarray(scenario.anchors, float)
    ids = [ln.id for ln in scenario.lines]
    cot = np.array(turret_position(eta0, scenario.turret.position), dtype=float)
    limits = scenario.limits
    hull = _hull(scenario.vessel)

    fig = Figure(figsize=(13, 7.4), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1]})
    for ax, zoom in ((ax1, False), (ax2, True)):
        for j in range(len(ids)):
            ax.plot([anchors[j, 1], fy[j]], [anchors[j, 0], fx[j]], color="0.45", lw=1,
                    label="mooring line (straight, anchor → fairlead)" if j == 0 else None)
        _circles(ax, limits, centre=cot)
        if hull is not None:
            h = _to_E(hull, eta0)
            ax.add_patch(Polygon(h[:, ::-1], closed=True, fc="lightsteelblue", ec="navy", lw=1, alpha=0.6,
                                 zorder=0.5, label="hull (schematic, heading 0)"))
        ax.plot(cot[1], cot[0], "o", mfc="none", mec="k", ms=9 if zoom else 6, label="turret centre")
        ax.plot(fy, fx, ".", color="tab:orange", ms=5, label="fairleads")
        ax.plot([0], [0], "+", color="k", ms=12, mew=2, label="field zero point")
    ax1.plot(anchors[:, 1], anchors[:, 0], "^", color="k", ms=7, label="anchors")
    for j, lid in enumerate(ids):
        ax1.annotate(lid, (anchors[j, 1], anchors[j, 0]), xytext=(4, 4), textcoords="offset points", fontsize=8)
    if getattr(scenario, "thrusters", ()):
        tp = _to_E(np.asarray([t.position for t in scenario.thrusters], float), eta0)
        ax2.plot(tp[:, 1], tp[:, 0], "s", color="tab:blue", ms=5, label="thrusters")
        for t, p in zip(scenario.thrusters, tp):
            ax2.annotate(t.id, (p[1], p[0]), xytext=(0, -9), textcoords="offset points", fontsize=6.5,
                         color="tab:blue", ha="center")

    span = float(np.max(np.abs(anchors[:, :2]))) * 1.12 if len(anchors) else 100.0
    ax1.set_xlim(-span, span)
    ax1.set_ylim(-span, span)
    depth = getattr(scenario.environment, "water_depth", None)
    _ned_axes(ax1, f"Mooring pattern: {len(ids)} lines" + (f", water depth {depth:g} m" if depth else ""))
    ax1.annotate("N ↑", xy=(0.03, 0.95), xycoords="axes fraction", fontsize=11, fontweight="bold")
    ax1.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncols=3, fontsize=8)

    radii = [r for r in (limits.safe_radius, limits.alert_radius) if r]
    extent = [float(np.hypot(*cot)) + 1.15 * max(radii)] if radii else []
    if hull is not None:
        extent.append(1.1 * float(np.max(np.abs(hull))))
    extent.append(1.3 * float(np.max(np.hypot(fx, fy))))
    z = max(extent)
    ax2.set_xlim(-z, z)
    ax2.set_ylim(-z, z)
    _ned_axes(ax2, "Vessel region (field zero point, heading 0)")
    ax2.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncols=3, fontsize=8)
    fig.suptitle(title or f"Scenario {scenario.name}: mooring layout (plan view, north up)", fontsize=13)
    return fig


# -- per case ----------------------------------------------------------------------------------

def motion_figure(result: Any, scenario: Any | None, *, title: str, track: TurretTrack | None = None) -> Figure:
    """Turret-referenced plan-view trajectory with the safe and alert circles and the setpoint;
    turret offset and heading against time.

    ``track`` defaults to :func:`~tapm_opt.report.series.turret_track` of the result with the
    turret position of :func:`~tapm_opt.report.series.turret_position_of` (raises
    :class:`~tapm_opt.report.data.ReportError` when that is unknown).
    """
    if track is None:
        track = turret_track(result, turret_position_of(result, scenario))
    t, x, y, off = track.t, track.x, track.y, track.offset
    limits = getattr(scenario, "limits", None)
    fig = Figure(figsize=(14, 6.6), layout="constrained")
    gs = fig.add_gridspec(2, 2, width_ratios=[1, 1.75])
    axp = fig.add_subplot(gs[:, 0])
    axo = fig.add_subplot(gs[0, 1])
    axh = fig.add_subplot(gs[1, 1], sharex=axo)

    # plan view
    _circles(axp, limits)
    s = _stride(len(t))
    axp.plot(y[s], x[s], color="tab:blue", lw=0.8, label="turret centre (LF)")
    axp.plot(y[0], x[0], "o", color="tab:blue", ms=6, label=f"start (t = {t[0]:g} s)")
    axp.plot(y[-1], x[-1], "s", color="tab:blue", ms=6, label=f"end (t = {t[-1]:g} s)")
    i = int(np.argmax(off))
    axp.plot(y[i], x[i], "*", color="tab:red", ms=11, label=f"max turret offset {off[i]:.1f} m (t = {t[i]:g} s)")
    has_sp = track.x_d is not None and track.y_d is not None
    if has_sp:
        xd, yd = track.x_d, track.y_d
        if np.ptp(xd) < 1e-9 and np.ptp(yd) < 1e-9:
            axp.plot(yd[0], xd[0], "x", color="k", ms=10, mew=2, label="setpoint")
        else:
            axp.plot(yd[s], xd[s], color="k", lw=1, ls="--", label="setpoint (moving)")
    r = max([off.max()] + [v for v in (getattr(limits, "safe_radius", None), getattr(limits, "alert_radius", None))
                           if v])
    r *= 1.15
    axp.set_xlim(-r, r)
    axp.set_ylim(-r, r)
    _ned_axes(axp, "Turret trajectory (plan view, north up)", quantity="turret offset")
    axp.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncols=2, fontsize=7.5)

    # offset
    td, od = decimate(t, off)
    axo.plot(td, od, color="tab:blue", lw=0.9, label="turret offset")
    if has_sp:
        sp_off = np.hypot(track.x_d, track.y_d)
        if np.ptp(sp_off) > 1e-9 or sp_off[0] > 1e-9:
            tsd, sod = decimate(t, sp_off)
            axo.plot(tsd, sod, color="k", ls="--", lw=1, label="setpoint turret offset")
    if limits is not None:
        if limits.safe_radius:
            axo.axhline(limits.safe_radius, color=SAFE_COLOR, ls="--", lw=1.2, label=f"safe radius {limits.safe_radius:g} m")
        if limits.alert_radius:
            axo.axhline(limits.alert_radius, color=ALERT_COLOR, ls="--", lw=1.2,
                        label=f"alert radius {limits.alert_radius:g} m")
    axo.set_ylabel("turret offset [m]")
    top = max([float(off.max())] + [v for v in (getattr(limits, "safe_radius", None),
                                                getattr(limits, "alert_radius", None)) if v])
    axo.set_ylim(0, 1.3 * top)
    axo.set_title("Horizontal turret offset from its field-zero-point position")
    axo.grid(True, alpha=0.3)

    # heading
    psi = np.degrees(np.unwrap(result["psi"]))
    thd, hd = decimate(t, psi)
    axh.plot(thd, hd, color="tab:blue", lw=0.9, label="heading ψ")
    if "psi_d" in result:
        psi_d = np.degrees(np.unwrap(result["psi_d"]))
        # keep setpoint and heading on the same branch of 360 degrees
        psi_d = psi_d + 360.0 * np.round((psi[0] - psi_d[0]) / 360.0)
        tdd, pdd = decimate(t, psi_d)
        axh.plot(tdd, pdd, color="k", ls="--", lw=1, label="heading setpoint ψ_d")
    axh.set_ylabel("heading [deg]")
    axh.set_xlabel("time [s]")
    axh.set_title("Heading (from north, clockwise)")
    axh.grid(True, alpha=0.3)
    _events([axo, axh], events_of(result))
    axo.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5)
    axh.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5)
    axo.set_xlim(t[0], t[-1])
    fig.suptitle(title, fontsize=12)
    return fig


def tension_figure(result: Any, scenario: Any | None, *, title: str, traces: CausalTraces | None = None,
                   n_lowest: int = 4) -> Figure | None:
    """Fairlead tension per line with the allowed tension (tension_utilisation x MBS) and the MBS;
    below it, with ``traces`` (:func:`~tapm_opt.report.series.causal_traces`), the causal
    reliability index delta(t) of the ``n_lowest`` lines with the lowest minimum and of the riser
    top and bottom angles, against delta_s, grey where the index is not ready yet.

    Every delta curve carries ``gid="delta:line <id>"`` or ``"delta:riser <end>"``; the lowest line
    and riser end are always drawn, so the lowest plotted value is the KPI ``delta_min`` (and
    ``riser_delta_min``)."""
    if not any(c.startswith("T_fairlead[") for c in result.channels):
        return None
    t = result.time
    ids = result.group_names("T_fairlead")
    T = result.group("T_fairlead")
    mbs: dict[str, float] = {}
    util = None
    if scenario is not None:
        arr = scenario.line_arrays["MBS"]
        for j, ln in enumerate(scenario.lines):
            mbs[ln.id] = float(arr[j])
        util = float(scenario.limits.tension_utilisation)
    refs = list(mbs.values()) or [float(np.nanmax(T))]
    f, unit = _scale([max(refs), float(np.nanmax(T))], "N")
    with_delta = traces is not None
    fig = Figure(figsize=(13, 7.8 if with_delta else 4.8), layout="constrained")
    axes = fig.subplots(2 if with_delta else 1, 1, sharex=True, squeeze=False)[:, 0]
    ax = axes[0]
    sty = _line_styles(len(ids))
    for j, lid in enumerate(ids):
        td, Td = decimate(t, T[:, j])
        ax.plot(td, Td / f, **sty[j], lw=0.8, label=f"line {lid}")
    for k, m in enumerate(sorted(set(mbs.values()))):
        which = [lid for lid, v in mbs.items() if v == m]
        suffix = "" if len(set(mbs.values())) == 1 else f" (lines {', '.join(which)})"
        ax.axhline(m / f, color="k", lw=1.5, label=f"MBS = {m / f:.4g} {unit}{suffix}")
        if util is not None:
            ax.axhline(util * m / f, color=ALERT_COLOR, lw=1.5, ls="--",
                       label=f"allowed = {util:g}·MBS = {util * m / f:.4g} {unit}{suffix}")
    ax.set_ylim(bottom=0)
    ax.set_ylabel(f"fairlead tension [{unit}]")
    ax.set_title("Fairlead tension per line")
    ax.grid(True, alpha=0.3)
    if with_delta:
        axd = axes[1]
        lows = sorted(traces.lines, key=lambda lid: min(float(r.delta.min()) for r in traces.lines[lid]))
        lows = lows[:max(int(n_lowest), 1)]
        for lid in sorted(lows, key=lambda i: ids.index(i) if i in ids else len(ids)):
            st = sty[ids.index(lid)] if lid in ids else {"color": "0.4", "ls": "-"}
            for k, run in enumerate(traces.lines[lid]):
                tdd, ddd = decimate(run.t, run.delta)
                axd.plot(tdd, ddd, **st, lw=0.9, label=f"line {lid}" if k == 0 else None, gid=f"delta:line {lid}")
        for end, ls in (("top", "-"), ("bottom", "--")):
            for k, run in enumerate(traces.riser.get(end, ())):
                tdd, ddd = decimate(run.t, run.delta)
                axd.plot(tdd, ddd, color="k", ls=ls, lw=1.1, label=f"riser {end} angle" if k == 0 else None,
                         gid=f"delta:riser {end}")
        for k, (a, b) in enumerate(traces.segments):
            r = traces.ready_from[k] if k < len(traces.ready_from) else None
            b = b if r is None else r
            if b > a:
                axd.axvspan(a, b, color="0.85", alpha=0.6, lw=0,
                            label="index not ready (windows filling)" if k == 0 else None)
        axd.axhline(traces.delta_s, color=ALERT_COLOR, ls="--", lw=1.5, label=f"threshold δ_s = {traces.delta_s:g}")
        if not (traces.lines or traces.riser):
            _no_data(axd, "no causal index: each segment is shorter than the monitor's windows")
        n_more = len(traces.lines) - len(lows)
        axd.set_ylabel("reliability index δ [-]")
        axd.set_title("Causal reliability index (higher is safer): "
                      + (f"the {len(lows)} lowest lines" if n_more > 0 else "every line")
                      + (" and the riser ends" if traces.riser else ""))
        axd.grid(True, alpha=0.3)
        axd.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_xlim(t[0], t[-1])
    _events(list(axes), events_of(result))
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5)
    fig.suptitle(title, fontsize=12)
    return fig


def thruster_figure(result: Any, *, title: str) -> Figure | None:
    """Thrust of every thruster and the total thruster power."""
    has_f = any(c.startswith("f[") for c in result.channels)
    has_p = any(c.startswith("P[") for c in result.channels)
    if not (has_f or has_p):
        return None
    t = result.time
    n = int(has_f) + int(has_p)
    fig = Figure(figsize=(13, 2.9 * n + 0.6), layout="constrained")
    axes = list(fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0])
    k = 0
    if has_f:
        ax = axes[k]
        k += 1
        ids = result.group_names("f")
        F = result.group("f")
        fs, unit = _scale([float(np.nanmax(np.abs(F)))], "N")
        sty = _line_styles(len(ids))
        for j, tid in enumerate(ids):
            td, fd = decimate(t, F[:, j])
            ax.plot(td, fd / fs, **sty[j], lw=0.8, label=f"thruster {tid}")
        ax.set_ylabel(f"thrust [{unit}]")
        ax.set_title("Thrust per thruster")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5)
    if has_p:
        ax = axes[k]
        P = result.group("P").sum(axis=1)
        ps, unit = _scale([float(np.nanmax(np.abs(P)))], "W")
        td, pd = decimate(t, P)
        ax.plot(td, pd / ps, color="tab:brown", lw=0.9, label="total power Σ P")
        ax.axhline(float(np.mean(P)) / ps, color="k", ls="--", lw=1, label=f"mean {np.mean(P) / ps:.3g} {unit}")
        ax.set_ylabel(f"power [{unit}]")
        ax.set_title("Total thruster power")
        ax.set_ylim(bottom=0)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5)
    axes[-1].set_xlabel("time [s]")
    axes[0].set_xlim(t[0], t[-1])
    _events(axes, events_of(result))
    fig.suptitle(title, fontsize=12)
    return fig


def _line_styles(n: int) -> list[dict]:
    """Distinct styles for n curves: the 10 tab10 colours, then the same colours dashed, dotted."""
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    ls = ("-", "--", ":", "-.")
    return [{"color": cmap(i % 10), "ls": ls[(i // 10) % len(ls)]} for i in range(n)]


# -- controllers compared ----------------------------------------------------------------------

#: Panels of the overlay figure, top to bottom.
PANELS = ("offset", "heading", "tension", "power")


@dataclass
class OverlayFigure:
    """The controller overlay figure of one condition and what it shows.

    Attributes
    ----------
    figure : Figure
    curves : dict
        ``curves[panel][label] = (t [s], y)`` exactly as plotted, for the panels :data:`PANELS`:
        turret offset [m], heading [deg], maximum line tension (T/MBS [-] or MN, see
        ``tension_quantity``) and total thrust power [MW]. A case without that curve is absent.
    tension_quantity : str
        ``"utilisation"`` (max over the lines of T/MBS, when every case's MBS is known) or
        ``"tension"`` (max over the lines of T in MN), or ``""`` when no case has tensions.
    notes : list of str
        One line per missing curve, ``"<label>: <what is missing>"``.
    """

    figure: Figure
    curves: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]]
    tension_quantity: str
    notes: list[str] = field(default_factory=list)


def _series_styles(series: Sequence[ComparisonSeries], styles: Mapping[str, dict] | None) -> list[dict]:
    """Colour from the controller; a second case of the same controller gets another line style."""
    base = dict(styles or {})
    for name, st in controller_styles([s.controller for s in series]).items():
        base.setdefault(name, st)
    seen: dict[str, int] = {}
    out = []
    for s in series:
        st = dict(base[s.controller])
        k = seen.get(s.controller, 0)
        seen[s.controller] = k + 1
        if k:
            st["ls"] = _CONTROLLER_LS[(_CONTROLLER_LS.index(st.get("ls", "-")) + k) % len(_CONTROLLER_LS)]
        out.append(st)
    return out


def _merged_events(series: Sequence[ComparisonSeries]) -> list[list]:
    """The events of all cases once each; an event not in every case names the cases that have it."""
    seen: dict[tuple[float, str], list[str]] = {}
    for s in series:
        for ev in s.events:
            try:
                key = (round(float(ev[0]), 6), str(ev[1]))
            except (TypeError, ValueError, IndexError):
                continue
            who = seen.setdefault(key, [])
            if s.label not in who:
                who.append(s.label)
    out = []
    for (te, text), who in sorted(seen.items()):
        out.append([te, text if len(who) == len(series) else f"{text} ({', '.join(who)})"])
    return out


def _legend_row(ax, handles: Sequence[Any], labels: Sequence[str]) -> None:
    """The controller legend in a thin axes of its own above the panels (a figure legend placed
    "outside" would collide with the suptitle)."""
    ax.set_axis_off()
    if handles:
        ax.legend(handles=list(handles), labels=list(labels), loc="center", ncols=min(len(handles), 6), fontsize=9,
                  title="controller", title_fontsize=9, frameon=True)


def _no_data(ax, text: str) -> None:
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=10, color="0.4")


def comparison_figure(series: Sequence[ComparisonSeries], limits: Any | None = None, *, title: str,
                      styles: Mapping[str, dict] | None = None) -> OverlayFigure:
    """Every controller of one condition on shared time axes: turret offset with the safe and alert
    radii, heading, maximum line tension (T/MBS with the allowed utilisation, or MN) and total
    thrust power [MW]; one colour per controller (``styles`` from :func:`controller_styles`),
    the events as dotted vertical lines.

    A curve a case does not have is left out of its panel and named in ``notes``; a panel no case
    can fill says so. Raises ``ValueError`` only when ``series`` is empty.
    """
    if not series:
        raise ValueError("comparison_figure needs at least one case")
    sty = _series_styles(series, styles)
    notes = [f"{s.label}: {m}" for s in series for m in s.missing]
    with_t = [s for s in series if s.tension is not None]
    quantity = "" if not with_t else ("utilisation" if all(s.util is not None for s in with_t) else "tension")

    fig = Figure(figsize=(13, 11.2), layout="constrained")
    gs = fig.add_gridspec(5, 1, height_ratios=[0.16, 1, 1, 1, 1])
    ax_leg = fig.add_subplot(gs[0, 0])
    axes = [fig.add_subplot(gs[1, 0])]
    axes += [fig.add_subplot(gs[k, 0], sharex=axes[0]) for k in (2, 3, 4)]
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    curves: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {p: {} for p in PANELS}
    handles = []
    for s, st in zip(series, sty):
        parts = {"offset": s.offset, "heading": s.heading, "power": None, "tension": None}
        if s.power is not None:
            parts["power"] = (s.power[0], s.power[1] / 1e6)
        if quantity == "utilisation" and s.util is not None:
            parts["tension"] = s.util
        elif quantity == "tension" and s.tension is not None:
            parts["tension"] = (s.tension[0], s.tension[1] / 1e6)
        line = None
        for ax, panel in zip(axes, PANELS):
            c = parts[panel]
            if c is None:
                continue
            (ln,) = ax.plot(c[0], c[1], color=st["color"], ls=st.get("ls", "-"), lw=1.0, label=s.label,
                            gid=f"controller:{s.label}")
            curves[panel][s.label] = (np.asarray(c[0]), np.asarray(c[1]))
            line = line or ln
        if line is None:
            from matplotlib.lines import Line2D

            line = Line2D([], [], color=st["color"], ls=st.get("ls", "-"), lw=1.5, label=s.label)
        handles.append(line)

    ax_o, ax_h, ax_t, ax_p = axes
    refs: dict[int, list] = {k: [] for k in range(4)}
    top = max([float(np.nanmax(c[1])) for c in curves["offset"].values() if len(c[1])] + [0.0])
    if limits is not None:
        for r, col, name in ((getattr(limits, "safe_radius", None), SAFE_COLOR, "safe"),
                             (getattr(limits, "alert_radius", None), ALERT_COLOR, "alert")):
            if r:
                refs[0].append(ax_o.axhline(r, color=col, ls="--", lw=1.2, label=f"{name} radius {r:g} m"))
                top = max(top, float(r))
    ax_o.set_ylim(0, 1.15 * top if top > 0 else 1.0)
    ax_o.set_ylabel("turret offset [m]")
    ax_o.set_title("Horizontal turret offset from its field-zero-point position")
    ax_h.set_ylabel("heading [deg]")
    ax_h.set_title("Heading ψ (from north, clockwise)")
    if quantity == "utilisation":
        u = getattr(limits, "tension_utilisation", None) if limits is not None else None
        if u:
            refs[2].append(ax_t.axhline(u, color=ALERT_COLOR, ls="--", lw=1.2, label=f"allowed T/MBS = {u:.3g}"))
        ax_t.set_ylabel("max T/MBS [-]")
        ax_t.set_title("Largest fairlead tension over the lines, as utilisation T/MBS")
    else:
        ax_t.set_ylabel("max tension [MN]")
        ax_t.set_title("Largest fairlead tension over the lines [MN]")
    ax_t.set_ylim(bottom=0)
    ax_p.set_ylabel("thrust power [MW]")
    ax_p.set_title("Total thrust power Σ P")
    ax_p.set_ylim(bottom=0)
    ax_p.set_xlabel("time [s]")
    empty = {"offset": "turret offset not available for any case", "heading": "heading not logged for any case",
             "tension": "line tensions not logged for any case", "power": "thrust power not logged for any case"}
    for ax, panel in zip(axes, PANELS):
        ax.grid(True, alpha=0.3)
        if not curves[panel]:
            _no_data(ax, empty[panel])
    t0 = min(s.t_span[0] for s in series)
    t1 = max(s.t_span[1] for s in series)
    if t1 > t0:
        ax_o.set_xlim(t0, t1)
    events = _merged_events(series)
    _events(axes, events)
    if events:
        refs[0].append(next(ln for ln in ax_o.lines if ln.get_label() == "event"))
    for k, ax in enumerate(axes):
        if refs[k]:
            ax.legend(handles=refs[k], loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5)
    _legend_row(ax_leg, handles, [h.get_label() for h in handles])
    fig.suptitle(title, fontsize=12)
    return OverlayFigure(figure=fig, curves=curves, tension_quantity=quantity, notes=notes)


@dataclass
class KpiBars:
    """A grouped bar chart of headline KPIs and what it shows.

    ``values[kpi][label]`` holds one value per group (None where the case has no such KPI: no bar),
    as given (the ``kpis.json`` numbers); a bar's height is ``value / scale[kpi]`` in ``units[kpi]``.
    ``bars[kpi][label]`` is the list of (group index, Rectangle) actually drawn.
    """

    figure: Figure
    kpis: list[str]
    groups: list[str]
    labels: list[str]
    values: dict[str, dict[str, list]]
    scale: dict[str, float]
    units: dict[str, str]
    bars: dict[str, dict[str, list]]


_PREFIXED_UNITS = ("J", "W", "N")


def kpi_bar_figure(values: Mapping[str, Mapping[str, Sequence[Any]]], *, groups: Sequence[str],
                   controller_of: Mapping[str, str], units: Mapping[str, str] | None = None,
                   titles: Mapping[str, str] | None = None, directions: Mapping[str, int] | None = None,
                   refs: Mapping[str, Sequence[tuple[float, str, str]]] | None = None,
                   styles: Mapping[str, dict] | None = None, title: str = "") -> KpiBars:
    """One panel per KPI (``values`` order), the groups (conditions) along x, one bar per label
    (controller) in each group, coloured by ``controller_of[label]`` with ``styles``; the value is
    written on each bar, missing values are marked "n/a". ``refs[kpi]`` adds horizontal lines
    ``(value in the KPI's unit, label, colour)`` such as the safe radius."""
    import textwrap

    kpis = list(values)
    labels = list(dict.fromkeys(lab for k in kpis for lab in values[k]))
    all_st = controller_styles([controller_of.get(lab, lab) for lab in labels])
    all_st.update(styles or {})
    seen: dict[str, int] = {}
    lab_st = {}
    for lab in labels:
        ctrl = controller_of.get(lab, lab)
        st = dict(all_st.get(ctrl) or controller_styles([ctrl])[ctrl])
        k = seen.get(ctrl, 0)
        seen[ctrl] = k + 1
        if k:
            st["hatch"] = _HATCHES[(_HATCHES.index(st.get("hatch", "")) + k) % len(_HATCHES)]
        lab_st[lab] = st
    n = max(len(kpis), 1)
    ncols = 2 if n == 4 else min(n, 3)
    nrows = math.ceil(n / ncols)
    ng = len(groups)
    width_in = max(13.0, min(16.0, 3.0 + ncols * (1.0 + 0.55 * ng * max(len(labels), 1))))
    fig = Figure(figsize=(width_in, 3.8 * nrows + 1.5), layout="constrained")
    gs = fig.add_gridspec(nrows + 1, ncols, height_ratios=[0.16 * 3.6 / 2.6] + [1.0] * nrows)
    ax_leg = fig.add_subplot(gs[0, :])
    axs = [fig.add_subplot(gs[1 + i // ncols, i % ncols]) for i in range(n)]
    x = np.arange(ng, dtype=float)
    w = 0.8 / max(len(labels), 1)
    scale: dict[str, float] = {}
    unit_out: dict[str, str] = {}
    bars: dict[str, dict[str, list]] = {}
    tick = [textwrap.fill(str(g), 28) for g in groups]
    handles = {}
    for ax, k in zip(axs, kpis):
        vals = [float(v) for lab in labels for v in values[k].get(lab, ()) if _finite(v)]
        u = (units or {}).get(k, "")
        f, lab_u = _scale(vals, u) if u in _PREFIXED_UNITS else (1.0, u)
        scale[k], unit_out[k] = f, lab_u
        bars[k] = {}
        for i, lab in enumerate(labels):
            row = list(values[k].get(lab, ()))
            xs = x + (i - (len(labels) - 1) / 2) * w
            idx = [j for j in range(ng) if j < len(row) and _finite(row[j])]
            st = lab_st[lab]
            cont = ax.bar(xs[idx], [float(row[j]) / f for j in idx], width=w * 0.92, color=st["color"],
                          hatch=st.get("hatch") or None, edgecolor="white" if not st.get("hatch") else "k",
                          label=lab, gid=f"controller:{lab}")
            bars[k][lab] = list(zip(idx, cont.patches))
            handles.setdefault(lab, Rectangle((0, 0), 1, 1, facecolor=st["color"], hatch=st.get("hatch") or None,
                                              edgecolor="white" if not st.get("hatch") else "k", label=lab))
            if idx:
                ax.bar_label(cont, labels=[f"{float(row[j]) / f:.3g}" for j in idx], padding=2,
                             fontsize=7 if ng * len(labels) <= 12 else 6)
            for j in range(ng):
                if j not in idx:
                    ax.text(xs[j], 0, "n/a", ha="center", va="bottom", fontsize=7, color="0.4", rotation=90)
        ref_h = []
        for val, rl, col in (refs or {}).get(k, ()):
            if _finite(val):
                ref_h.append(ax.axhline(float(val) / f, color=col, ls="--", lw=1.2, label=rl))
        lo = ax.get_ylim()[0]
        top = max([float(v) / f for v in vals] + [float(r[0]) / f for r in (refs or {}).get(k, ()) if _finite(r[0])]
                  + [0.0])
        if top > 0:
            ax.set_ylim(min(lo, 0.0), 1.22 * top)
        elif not any(float(v) < 0 for v in vals):
            ax.set_ylim(0.0, 1.0)  # all zero (e.g. never outside the safe circle): bars on the floor
        ax.set_xticks(x, tick, fontsize=8, rotation=0 if ng <= 4 else 25, ha="center" if ng <= 4 else "right")
        ax.set_xlim(-0.6, ng - 0.4)
        d = (directions or {}).get(k, 0)
        better = {-1: "lower is better", 1: "higher is better"}.get(d, "")
        name = (titles or {}).get(k, k)
        ax.set_title(f"{name}" + (f" [{lab_u}]" if lab_u else "") + (f"\n{better}" if better else ""), fontsize=10)
        ax.set_ylabel(f"{k} [{lab_u}]" if lab_u else k, fontsize=8)
        ax.grid(True, axis="y", alpha=0.3)
        if ref_h:
            ax.legend(handles=ref_h, loc="upper right", fontsize=7)
    _legend_row(ax_leg, list(handles.values()), list(handles))
    if title:
        fig.suptitle(title, fontsize=12)
    return KpiBars(figure=fig, kpis=kpis, groups=list(groups), labels=labels,
                   values={k: {lab: list(values[k].get(lab, ())) for lab in labels} for k in kpis},
                   scale=scale, units=unit_out, bars=bars)


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool) and math.isfinite(float(v))
