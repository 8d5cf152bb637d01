"""Reliability and setpoints of one condition: the reliability-safe region, the setpoint
trajectories and the causal index delta(t) of every controller (section 3 of the report).

* :func:`case_reliability` keeps, from one saved case, what the condition figure needs once its
  result is released: the turret track and the setpoint (turret offsets, as drawn), the
  re-optimised targets of ``meta["setpoint_log"]``, the causal index
  (:func:`~tapm_opt.report.series.causal_traces`, evaluated as the KPIs are) and the conditions
  over each segment's ready part (heading, estimated environmental load, ``k sigma`` of every line
  and riser end).
* :func:`map_inputs` pools those conditions over the cases of a condition, :func:`safe_regions`
  evaluates :func:`tapm_opt.design.setpoint.reliability_map` with them (intact, and after the
  break with the broken lines left out), never raising for a map that cannot be computed.
* :func:`reliability_figure` draws the plan view (safe region, circles, tracks, setpoints) and
  delta(t) of the lines and the riser against delta_s, one colour per controller.

The inputs of the map (what :func:`map_inputs` pools, over the cases of the condition):

* heading: the circular mean of ``psi``;
* ``tau_env``: the mean of ``tau_env_hat[X|Y|N]`` (in {B}; it sets the map's thrust measure only,
  not the indices);
* ``k sigma`` of every line and riser end: the **median over the ready part** of the causal
  monitor's ``k * sigma`` (steadier than its last value, which one wave group can move).

Each is taken over the ready part of the segment (from ``lp_window + sigma_window`` after its
start to its end, the part the KPIs evaluate), or over the whole segment when it never becomes
ready (then ``k sigma`` = 0, the quasi-static indices, and the caption says so). After a break,
the damaged segment's values are used when it has a ready part, else the intact ones.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from ..errors import TapmError
from .series import CausalTraces, decimate, events_of, turret_position_of, turret_track

__all__ = ["OPTIMAL_SETPOINTS", "SegmentConditions", "CaseReliability", "MapInputs", "SafeRegion",
           "ReliabilityFigure", "case_reliability", "map_inputs", "safe_regions", "reliability_figure",
           "MAP_POINTS"]

#: The optimal setpoint layers (``setpoint`` of a study); a condition with one of them, or with a
#: scenario riser, gets the reliability figure.
OPTIMAL_SETPOINTS = ("quadratic", "reliability", "unified")
#: Grid points per axis of the reliability map.
MAP_POINTS = 41
SAFE_REGION_COLOR = "tab:green"
#: Colour of the contour min delta = delta_s: intact (solid), after the break (dashed); apart from
#: the safe circle's green and the controller colours.
CONTOUR_COLORS = {"intact": "darkgreen", "after the break": "teal"}
_TAU = ("tau_env_hat[X]", "tau_env_hat[Y]", "tau_env_hat[N]")
_RISER_CHANNELS = ("riser_top_angle", "riser_bottom_angle")
_STATES = ("intact", "after the break")


def _stride(n: int, limit: int) -> slice:
    return slice(None, None, max(1, math.ceil(n / limit)))


@dataclass(frozen=True)
class SegmentConditions:
    """The conditions of one case over one segment (its ready part when it has one).

    Attributes
    ----------
    segment : int
        0 intact, 1 after the first line break.
    window : (float, float)
        First and last time [s] the sums cover.
    ready : bool
        The window is the ready part of the segment (else the whole segment, never ready).
    n : int
        Samples in the window.
    sin_psi, cos_psi : float
        Sums of sin(psi) and cos(psi) over the window (for the circular mean).
    tau_sum : ndarray, shape (3,), or None
        Sum of ``tau_env_hat`` [N, N, N m] in {B}; None without those channels.
    ksigma : dict
        ``ksigma[name]``: the monitor's ``k sigma`` at the ready samples (line id [N], ``"top"``,
        ``"bottom"`` [rad]); empty when the segment is never ready.
    """

    segment: int
    window: tuple[float, float]
    ready: bool
    n: int
    sin_psi: float
    cos_psi: float
    tau_sum: np.ndarray | None
    ksigma: dict[str, np.ndarray]


@dataclass
class CaseReliability:
    """What the condition figure needs from one case (:func:`case_reliability`).

    Attributes
    ----------
    label, controller : str
        Legend entry (column of the condition) and the controller (sets the colour).
    setpoint : str
        The setpoint layer (``fixed``, ``chasing``, ``quadratic``, ``reliability``, ``unified``).
    t, x, y : ndarray
        Time [s] and turret offset north, east [m] (every ``stride``-th sample: what is drawn).
    x_d, y_d : ndarray or None
        The setpoint turret offset (channels ``x_d``, ``y_d``) at the same samples.
    targets : ndarray, shape (k, 2)
        The re-optimised targets [x, y] [m] of ``meta["setpoint_log"]`` (empty for other layers).
    traces : CausalTraces or None
    conditions : list of SegmentConditions
    events : list
        ``[time, text]`` events.
    has_riser : bool
        The case's scenario has a riser and its result the riser angle channels (every closed-loop
        run of such a scenario logs them).
    """

    label: str
    controller: str
    setpoint: str
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    x_d: np.ndarray | None
    y_d: np.ndarray | None
    targets: np.ndarray
    traces: CausalTraces | None
    conditions: list[SegmentConditions]
    events: list
    has_riser: bool
    stride: int = 1


def case_reliability(result: Any, scenario: Any, traces: CausalTraces | None, *, label: str, controller: str,
                     setpoint: str, max_points: int = 4000) -> CaseReliability:
    """The :class:`CaseReliability` of one saved case (module docstring).

    Raises
    ------
    ReportError
        The turret position is unknown (no ``turret_position_B`` and no scenario).
    """
    tr = turret_track(result, turret_position_of(result, scenario))
    s = _stride(len(tr.t), max_points)
    meta = result.meta if isinstance(result.meta, dict) else {}
    tg = []
    for entry in meta.get("setpoint_log", []) or []:
        try:
            p = np.asarray(entry["target"], dtype=float)
        except (TypeError, KeyError, ValueError):
            continue
        if p.shape == (2,) and np.all(np.isfinite(p)):
            tg.append(p)
    t = np.asarray(result.time, dtype=float)
    conds: list[SegmentConditions] = []
    if traces is not None and len(t) >= 2:
        eps = 1e-9 * max(1.0, abs(float(t[-1])))
        tb = traces.t_break if traces.t_break is not None else math.inf
        masks = (t <= tb + eps, t > tb + eps)
        psi = np.asarray(result["psi"], dtype=float) if "psi" in result else None
        tau = np.column_stack([np.asarray(result[c], dtype=float) for c in _TAU]) if all(c in result for c in _TAU) \
            else None
        signals = {**traces.lines, **traces.riser}
        for k, seg in enumerate(masks):
            if seg.sum() < 2 or psi is None:
                continue
            t_r = traces.ready_from[k] if k < len(traces.ready_from) else None
            win = seg & (t >= t_r - eps) if t_r is not None else seg
            ks = {name: np.concatenate([r.ksigma for r in runs if r.segment == k and r.ksigma is not None])
                  for name, runs in signals.items() if any(r.segment == k for r in runs)}
            tw = t[win]
            conds.append(SegmentConditions(
                segment=k, window=(float(tw[0]), float(tw[-1])), ready=t_r is not None, n=int(win.sum()),
                sin_psi=float(np.sin(psi[win]).sum()), cos_psi=float(np.cos(psi[win]).sum()),
                tau_sum=None if tau is None else tau[win].sum(axis=0), ksigma=ks))
    return CaseReliability(
        label=label, controller=controller, setpoint=setpoint, t=tr.t[s], x=tr.x[s], y=tr.y[s],
        x_d=None if tr.x_d is None else tr.x_d[s], y_d=None if tr.y_d is None else tr.y_d[s],
        targets=np.array(tg, dtype=float).reshape(-1, 2), traces=traces, conditions=conds,
        events=events_of(result),
        has_riser=getattr(scenario, "riser", None) is not None and all(ch in result for ch in _RISER_CHANNELS),
        stride=int(s.step or 1))


# -- the safe region ---------------------------------------------------------------------------

@dataclass(frozen=True)
class MapInputs:
    """The conditions a reliability map is evaluated at (:func:`map_inputs`).

    Attributes
    ----------
    state : str
        ``"intact"`` or ``"after the break"``.
    broken : tuple of str
        Lines left out of the map.
    heading : float
        [rad].
    tau_env : ndarray, shape (3,), or None
        Mean estimated environmental load in {B} [N, N, N m] (None: not logged).
    ksigma_lines : dict
        ``k sigma`` per line id [N].
    ksigma_riser : ndarray, shape (2,)
        ``k sigma`` of the riser top and bottom angles [rad].
    source : str
        Where ``k sigma`` comes from, for the caption.
    cases : int
        Cases pooled.
    """

    state: str
    broken: tuple[str, ...]
    heading: float
    tau_env: np.ndarray | None
    ksigma_lines: dict[str, float]
    ksigma_riser: np.ndarray
    source: str
    cases: int


def _pooled(cases: Sequence[CaseReliability], segment: int) -> list[SegmentConditions]:
    return [sc for c in cases for sc in c.conditions if sc.segment == segment]


def _median_ksigma(conds: Sequence[SegmentConditions]) -> dict[str, float]:
    names = list(dict.fromkeys(n for sc in conds for n in sc.ksigma))
    out = {}
    for n in names:
        v = np.concatenate([sc.ksigma[n] for sc in conds if n in sc.ksigma])
        if v.size:
            out[n] = float(np.median(v))
    return out


def map_inputs(cases: Sequence[CaseReliability], segment: int, *, broken: Sequence[str] = ()) -> MapInputs | None:
    """Pool the conditions of segment ``segment`` (0 intact, 1 after the break) over ``cases``
    (module docstring); None when no case has that segment."""
    conds = _pooled(cases, segment)
    if not conds:
        return None
    psi = math.atan2(sum(sc.sin_psi for sc in conds), sum(sc.cos_psi for sc in conds))
    with_tau = [sc for sc in conds if sc.tau_sum is not None]
    tau = (np.sum([sc.tau_sum for sc in with_tau], axis=0) / sum(sc.n for sc in with_tau)) if with_tau else None
    ready = [sc for sc in conds if sc.ready]
    ks = _median_ksigma(ready)
    n_cases = len(conds)  # one per case and segment
    if ks:
        src = (f"median of the causal monitor's k·σ over the ready part of the {_STATES[segment]} record "
               f"({min(sc.window[0] for sc in ready):g}–{max(sc.window[1] for sc in ready):g} s) of {len(ready)} case"
               f"{'s' if len(ready) != 1 else ''}")
    elif segment == 1:
        ks = _median_ksigma([sc for sc in _pooled(cases, 0) if sc.ready])
        src = ("the intact record's k·σ (median over its ready part): the record after the break is shorter "
               "than the monitor's windows" if ks else
               "k·σ = 0 (quasi-static indices): no record is long enough for the causal monitor")
    else:
        src = "k·σ = 0 (quasi-static indices): the record is shorter than the causal monitor's windows"
    broken = tuple(broken)
    lines = {n: v for n, v in ks.items() if n not in ("top", "bottom") and n not in broken}
    riser = np.array([ks.get("top", 0.0), ks.get("bottom", 0.0)])
    return MapInputs(state=_STATES[segment], broken=broken, heading=float(psi), tau_env=tau, ksigma_lines=lines,
                     ksigma_riser=riser, source=src, cases=n_cases)


@dataclass
class SafeRegion:
    """One evaluated reliability map: its inputs, the map (None when it could not be computed,
    ``error`` then says why) and the seconds it took."""

    inputs: MapInputs
    map: Any | None
    error: str = ""
    seconds: float = 0.0


def _broken_lines(cases: Sequence[CaseReliability]) -> tuple[str, ...]:
    out: list[str] = []
    for c in cases:
        for lid in (c.traces.broken if c.traces is not None else ()):
            if lid not in out:
                out.append(lid)
    return tuple(out)


def safe_regions(cases: Sequence[CaseReliability], scenario: Any, sea_state: Any, *,
                 half_width: float | None = None, n: int = MAP_POINTS) -> list[SafeRegion]:
    """The reliability maps of a condition: intact and, when a line breaks in some case, after the
    break with the broken lines left out (module docstring for the inputs). A map that cannot be
    computed is returned with its ``error`` instead of raising."""
    from ..design.setpoint import reliability_map

    out = []
    broken = _broken_lines(cases)
    for seg, brk in ((0, ()), (1, broken)):
        if seg == 1 and not broken:
            break
        inp = map_inputs(cases, seg, broken=brk)
        if inp is None:
            continue
        w0 = time.perf_counter()
        try:
            m = reliability_map(scenario, sea_state, broken=inp.broken, heading=inp.heading, tau_env=inp.tau_env,
                                ksigma_lines=inp.ksigma_lines, ksigma_riser=inp.ksigma_riser,
                                half_width=half_width, n=n)
            out.append(SafeRegion(inputs=inp, map=m, seconds=time.perf_counter() - w0))
        except TapmError as exc:
            out.append(SafeRegion(inputs=inp, map=None, error=f"{type(exc).__name__}: {exc}",
                                  seconds=time.perf_counter() - w0))
        except Exception as exc:  # noqa: BLE001 - a map that cannot be computed must not stop the report
            out.append(SafeRegion(inputs=inp, map=None, error=f"{type(exc).__name__}: {exc}",
                                  seconds=time.perf_counter() - w0))
    return out


def plan_half_width(cases: Sequence[CaseReliability], limits: Any | None) -> float:
    """Half-width [m] of the plan view and the map grid: 1.25 x the alert (else safe) radius, widened
    to 1.1 x the largest turret or setpoint offset of the cases, rounded up to 5 m."""
    r = [1.25 * float(v) for v in (getattr(limits, "alert_radius", None) or getattr(limits, "safe_radius", None),)
         if v]
    for c in cases:
        r.append(1.1 * float(np.max(np.hypot(c.x, c.y))) if len(c.x) else 0.0)
        if c.x_d is not None and len(c.x_d):
            r.append(1.1 * float(np.max(np.hypot(c.x_d, c.y_d))))
    hw = max(r + [10.0])
    return 5.0 * math.ceil(hw / 5.0)


# -- the figure --------------------------------------------------------------------------------

@dataclass
class ReliabilityFigure:
    """The reliability figure of one condition and what it shows.

    Attributes
    ----------
    figure : Figure
    regions : list of SafeRegion
    filled : QuadContourSet or None
        The intact safe region (``delta_min >= delta_s``, filled) as drawn.
    contours : dict
        ``contours[state]``: the line ``delta_min = delta_s`` as drawn (``"intact"`` solid,
        ``"after the break"`` dashed).
    tracks, setpoints : dict
        ``[label] = (east, north)`` arrays [m] of the turret track and the setpoint as plotted
        (horizontal, vertical).
    delta_lines, delta_riser : dict
        ``[label]``: list of ``(t, delta)`` segments as plotted: the lowest causal index over the
        lines, over the riser ends.
    notes : list of str
    """

    figure: Figure
    regions: list[SafeRegion]
    filled: Any = None
    contours: dict[str, Any] = field(default_factory=dict)
    tracks: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    setpoints: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    delta_lines: dict[str, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)
    delta_riser: dict[str, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def reliability_figure(cases: Sequence[CaseReliability], regions: Sequence[SafeRegion], limits: Any | None, *,
                       title: str, delta_s: float, styles: Mapping[str, dict] | None = None,
                       half_width: float | None = None) -> ReliabilityFigure:
    """Left: plan view of turret offsets (north up) with the reliability-safe region of each map
    (filled and solid: intact; dashed: after the break), the safe and alert circles, and every
    controller's turret track (thin) and setpoint (dashed, targets ✕). Right: the lowest causal
    index over the lines and, when any case has a riser, over the riser ends, against ``delta_s``;
    grey where the index is not ready yet; events dotted. One colour per controller (``styles``)."""
    from . import figures as figs

    if not cases:
        raise ValueError("reliability_figure needs at least one case")
    sty = figs._series_styles(cases, styles)
    with_riser = any(c.traces is not None and c.traces.riser_min for c in cases) or any(c.has_riser for c in cases)
    fig = Figure(figsize=(14, 7.2), layout="constrained")
    gs = fig.add_gridspec(2 if with_riser else 1, 2, width_ratios=[1, 1.35])
    axp = fig.add_subplot(gs[:, 0])
    axd = fig.add_subplot(gs[0, 1])
    axr = fig.add_subplot(gs[1, 1], sharex=axd) if with_riser else None
    out = ReliabilityFigure(figure=fig, regions=list(regions))

    # plan view: the safe regions
    hw = half_width or plan_half_width(cases, limits)
    handles: list[Any] = []
    for reg in regions:
        m = reg.map
        if m is None:
            out.notes.append(f"{reg.inputs.state} safe region not computed ({reg.error})")
            continue
        X, Y = np.meshgrid(m.x, m.y)
        D = np.ma.masked_invalid(np.asarray(m.delta_min, dtype=float))
        intact = reg.inputs.state == "intact"
        if D.count() == 0 or not (float(D.min()) <= m.delta_s <= float(D.max())):
            where = "everywhere" if D.count() and float(D.min()) > m.delta_s else "nowhere"
            out.notes.append(f"{reg.inputs.state}: min δ ≥ δ_s {where} on the map (no contour)")
            if intact and where == "everywhere":
                out.filled = axp.contourf(Y, X, D, levels=[float(D.min()) - 1.0, float(D.max()) + 1.0],
                                          colors=[SAFE_REGION_COLOR], alpha=0.13)
            continue
        if intact:
            out.filled = axp.contourf(Y, X, D, levels=[m.delta_s, max(float(D.max()), m.delta_s) + 1.0],
                                      colors=[SAFE_REGION_COLOR], alpha=0.13)
            handles.append(Patch(fc=SAFE_REGION_COLOR, alpha=0.25,
                                 label=f"reliability-safe (min δ ≥ {m.delta_s:g})"))
        ls = "-" if intact else "--"
        col = CONTOUR_COLORS.get(reg.inputs.state, "darkgreen")
        out.contours[reg.inputs.state] = axp.contour(Y, X, D, levels=[m.delta_s], colors=[col],
                                                     linestyles=[ls], linewidths=2.0)
        brk = f", line{'s' if len(reg.inputs.broken) > 1 else ''} {', '.join(reg.inputs.broken)} left out" \
            if reg.inputs.broken else ""
        handles.append(Line2D([], [], color=col, ls=ls, lw=2.0, label=f"min δ = δ_s, {reg.inputs.state}{brk}"))
    figs._circles(axp, limits)
    for c, st in zip(cases, sty):
        col = st["color"]
        axp.plot(c.y, c.x, color=col, lw=0.7, alpha=0.8, gid=f"track:{c.label}")
        out.tracks[c.label] = (np.asarray(c.y), np.asarray(c.x))
        if c.x_d is not None and c.y_d is not None:
            out.setpoints[c.label] = (np.asarray(c.y_d), np.asarray(c.x_d))
            if np.ptp(c.x_d) < 1e-9 and np.ptp(c.y_d) < 1e-9:
                axp.plot(c.y_d[:1], c.x_d[:1], "X", color=col, ms=10, mec="k", mew=0.8, gid=f"setpoint:{c.label}")
            else:
                axp.plot(c.y_d, c.x_d, color=col, lw=2.0, ls="--", gid=f"setpoint:{c.label}")
                axp.plot(c.y_d[-1:], c.x_d[-1:], "D", color=col, ms=6, mec="k", mew=0.8)
        if len(c.targets):
            axp.plot(c.targets[:, 1], c.targets[:, 0], "x", color=col, ms=5, mew=1.2, ls="none",
                     gid=f"targets:{c.label}")
        handles.append(Line2D([], [], color=col, lw=1.6, label=f"{c.label} (setpoint {c.setpoint})"))
    axp.plot([0], [0], "+", color="k", ms=12, mew=2)
    handles += [Line2D([], [], color="0.3", lw=0.7, label="turret track (thin)"),
                Line2D([], [], color="0.3", lw=2.0, ls="--", label="setpoint x_d, y_d (dashed; ◆ end, X fixed)"),
                Line2D([], [], color="0.3", marker="x", ls="none", label="re-optimised targets"),
                Line2D([], [], color="k", marker="+", ls="none", ms=10, mew=2, label="field zero point")]
    for r, col, name in ((getattr(limits, "safe_radius", None), figs.SAFE_COLOR, "safe"),
                         (getattr(limits, "alert_radius", None), figs.ALERT_COLOR, "alert")):
        if r:
            handles.append(Line2D([], [], color=col, ls="--", lw=1.5, label=f"{name} circle (r = {r:g} m)"))
    axp.set_xlim(-hw, hw)
    axp.set_ylim(-hw, hw)
    figs._ned_axes(axp, "Reliability-safe region, turret tracks and setpoints", quantity="turret offset")
    axp.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncols=2, fontsize=7.5)

    # delta(t)
    spans: set[tuple[float, float]] = set()
    for c in cases:
        tr = c.traces
        if tr is None:
            continue
        for k, (t0, t1) in enumerate(tr.segments):
            r = tr.ready_from[k] if k < len(tr.ready_from) else None
            spans.add((round(t0, 6), round(t1 if r is None else r, 6)))
    drawn_any = {"lines": False, "riser": False}
    for ax, key, store in ((axd, "lines", out.delta_lines), (axr, "riser", out.delta_riser)):
        if ax is None:
            continue
        vals = []
        for c, st in zip(cases, sty):
            runs = [] if c.traces is None else (c.traces.lines_min if key == "lines" else c.traces.riser_min)
            for k, run in enumerate(runs):
                td, dd = decimate(run.t, run.delta)
                ax.plot(td, dd, color=st["color"], ls=st.get("ls", "-"), lw=1.0, gid=f"controller:{c.label}",
                        label=c.label if k == 0 else None)
                store.setdefault(c.label, []).append((td, dd))
                vals.append(dd)
            if not runs:
                out.notes.append(f"{c.label}: no causal {'line' if key == 'lines' else 'riser'} index "
                                 "(record shorter than the monitor's windows, or no such signal)")
        for i, (a, b) in enumerate(sorted(spans)):
            if b > a:
                ax.axvspan(a, b, color="0.85", alpha=0.6, lw=0,
                           label="index not ready (windows filling)" if i == 0 else None)
        ax.axhline(delta_s, color=figs.ALERT_COLOR, ls="--", lw=1.5, label=f"δ_s = {delta_s:g}")
        if vals:
            drawn_any[key] = True
            lo = min(float(np.nanmin(v)) for v in vals)
            hi = max(float(np.nanmax(v)) for v in vals)
            pad = 0.08 * max(hi - min(lo, delta_s), 1.0)
            ax.set_ylim(min(lo, delta_s) - pad, max(hi, delta_s) + pad)
        else:
            figs._no_data(ax, "no causal index (record shorter than the monitor's windows)")
        ax.set_ylabel("min δ [-]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5)
    axd.set_title("Lowest causal reliability index over the lines (higher is safer)")
    if axr is not None:
        axr.set_title("Lowest causal reliability index of the riser top and bottom angles")
        axr.set_xlabel("time [s]")
        axd.tick_params(labelbottom=False)
    else:
        axd.set_xlabel("time [s]")
    t0 = min((float(c.t[0]) for c in cases if len(c.t)), default=0.0)
    t1 = max((float(c.t[-1]) for c in cases if len(c.t)), default=1.0)
    if t1 > t0:
        axd.set_xlim(t0, t1)
    events = figs._merged_events(cases)
    figs._events([ax for ax in (axd, axr) if ax is not None], events)
    fig.suptitle(title, fontsize=12)
    return out
