"""Figures of the study report, drawn with matplotlib's object API (no pyplot, no global state).

Plan views follow NED: y (east) on the horizontal axis, x (north) on the vertical axis, equal
scale. Case figures are turret-referenced (:mod:`tapm_opt.report.series`): trajectory, safe and
alert circles and offsets are those of the centre of turret relative to its field-zero-point
position. Long time series are reduced to at most ``MAX_POINTS`` points per curve with a min/max
envelope per bucket so peaks survive. Every function returns a :class:`matplotlib.figure.Figure`;
:func:`png_bytes` renders it with the Agg backend.
"""

from __future__ import annotations

import io
import math
from typing import Any, Mapping, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon

from ..geometry import rot2_apply, turret_position
from .series import TurretTrack, events_of, turret_position_of, turret_track

__all__ = ["MAX_POINTS", "DPI", "decimate", "png_bytes", "layout_figure", "motion_figure", "tension_figure",
           "thruster_figure"]

MAX_POINTS = 2000
DPI = 100
SAFE_COLOR = "tab:green"
ALERT_COLOR = "tab:red"
EVENT_COLOR = "tab:purple"


# -- helpers -----------------------------------------------------------------------------------

def decimate(t: np.ndarray, y: np.ndarray, n: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """At most ``n`` points of (t, y): the minimum and maximum of each of n/2 consecutive buckets,
    in time order (peaks and troughs are kept, unlike plain striding)."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    N = len(t)
    if N <= n:
        return t, y
    m = max((n - 2) // 2, 1)  # two points per bucket plus both ends
    k = math.ceil(N / m)
    pad = m * k - N
    yp = np.concatenate([y, np.full(pad, y[-1])]) if pad else y
    Y = yp.reshape(m, k)
    base = np.arange(m) * k
    with np.errstate(invalid="ignore"):
        imin = base + np.nanargmin(np.where(np.isnan(Y), np.inf, Y), axis=1)
        imax = base + np.nanargmax(np.where(np.isnan(Y), -np.inf, Y), axis=1)
    idx = np.unique(np.clip(np.concatenate([imin, imax, [0, N - 1]]), 0, N - 1))
    return t[idx], y[idx]


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


def tension_figure(result: Any, scenario: Any | None, *, title: str,
                   delta: Mapping[str, Sequence[tuple[np.ndarray, np.ndarray]]] | None = None,
                   delta_s: float | None = None) -> Figure | None:
    """Fairlead tension per line with the allowed tension (tension_utilisation x MBS) and the MBS;
    below it the reliability index delta(t) per line when ``delta`` is given."""
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
    with_delta = bool(delta)
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
        for j, lid in enumerate(ids):
            for k, (tt, dd) in enumerate(delta.get(lid, ())):
                tdd, ddd = decimate(tt, dd)
                axd.plot(tdd, ddd, **sty[j], lw=0.8, label=f"line {lid}" if k == 0 else None)
        if delta_s is not None:
            axd.axhline(delta_s, color=ALERT_COLOR, ls="--", lw=1.5, label=f"threshold δ_s = {delta_s:g}")
        axd.set_ylabel("reliability index δ [-]")
        axd.set_title("Reliability index per line (higher is safer)")
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
