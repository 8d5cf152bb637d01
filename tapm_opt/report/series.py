"""Series the report plots, derived from a saved result and its scenario (nothing is simulated).

* :func:`turret_track`: the turret-referenced motion. Safety is measured at the turret (survey
  §4.2.1; ``docs/nomenclature.md``): trajectories, safe and alert circles and offsets refer to the
  centre of turret's horizontal position relative to where it rests at the field zero point,
  :func:`tapm_opt.geometry.turret_offset` of the logged body-origin pose (x, y, psi).
* :func:`causal_traces`: the causal reliability index delta(t) of every line and riser end from the
  saved tensions and riser angles, evaluated as the KPIs do (:func:`causal_runs`).
* :func:`events_of`: the ``[time, text]`` events of a result.
* :func:`comparison_series`: the four curves of one case in the controller overlay figure (turret
  offset, heading, maximum line tension, total thrust power), reduced with :func:`decimate`.
* :func:`decimate`: at most ``MAX_POINTS`` points per curve, min/max per bucket so peaks survive.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from ..estimation.reliability import LP_WINDOW_DEFAULT, SIGMA_WINDOW_DEFAULT
from ..geometry import turret_offset
from ..studies.kpis import DELTA_S_DEFAULT, RISER_ENDS, IndexRun, break_times, causal_runs
from .data import ReportError

__all__ = ["MAX_POINTS", "TurretTrack", "ComparisonSeries", "IndexRun", "CausalTraces", "decimate",
           "turret_position_of", "turret_track", "break_times", "causal_runs", "causal_traces", "events_of",
           "decisions_of", "comparison_series"]

#: Most points per plotted curve (see :func:`decimate`).
MAX_POINTS = 2000


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


def events_of(result: Any) -> list:
    """The ``[time [s], text]`` entries of ``result.meta["events"]`` (empty when there are none)."""
    ev = result.meta.get("events", []) if isinstance(result.meta, dict) else []
    return list(ev) if isinstance(ev, (list, tuple)) else []


def _decision_text(role: str, e: Mapping) -> str:
    kind = str(e.get("event", "event"))
    if kind == "line break detected":
        return f"{role}: line {e.get('line')} break detected"
    if kind == "buoy loss detected":
        return f"{role}: buoy loss at joint {e.get('joint')} of line {e.get('line')} detected"
    radius = e.get("radius")
    if kind == "dead band" and isinstance(radius, (int, float)):
        return f"{role}: dead band {float(radius):.1f} m"
    text = f"{role}: {kind}"
    if "from" in e or "to" in e:
        text += f" {e.get('from')} → {e.get('to')}"
    if isinstance(radius, (int, float)):
        text += f", dead band {float(radius):.1f} m"
    return text


def decisions_of(result: Any) -> list:
    """``[time [s], text]`` of what the loop's components decided, in time order: the estimator's
    detections (``meta["estimator_log"]``) and the controller's switches (``meta["controller_log"]``:
    a supervisor's sea state and mode set or gain-table row, the MPC's dead band after a break).
    Records without a finite time are left out."""
    meta = result.meta if isinstance(result.meta, dict) else {}
    out = []
    for role in ("estimator", "controller"):
        log = meta.get(f"{role}_log")
        for e in log if isinstance(log, (list, tuple)) else []:
            t = e.get("t") if isinstance(e, Mapping) else None
            if isinstance(t, (int, float)) and math.isfinite(t):
                out.append([float(t), _decision_text(role, e)])
    return sorted(out, key=lambda x: x[0])


@dataclass(frozen=True)
class TurretTrack:
    """Turret-referenced horizontal motion of one case, as the report plots it.

    Attributes
    ----------
    t : ndarray, shape (k,)
        Time [s].
    x, y : ndarray, shape (k,)
        Turret offset north and east [m]: the centre of turret relative to its position at the
        field zero point (eta = 0), in {E}.
    offset : ndarray, shape (k,)
        Horizontal turret offset ``hypot(x, y)`` [m], the distance the safe and alert radii bound.
    x_d, y_d : ndarray, shape (k,), or None
        Setpoint turret offset [m] (channels ``x_d``, ``y_d``, which hold turret offsets like every
        position setpoint, :class:`tapm_opt.interfaces.Setpoint`); None without a setpoint.
    p_cot_B : ndarray, shape (2,)
        Centre of turret in {B} used [m].
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    offset: np.ndarray
    x_d: np.ndarray | None
    y_d: np.ndarray | None
    p_cot_B: np.ndarray


def turret_position_of(result: Any, scenario: Any | None) -> np.ndarray:
    """Centre of turret p_cot^B [m], shape (2,), of a saved case: ``result.meta["turret_position_B"]``
    (what the run used) or else the case scenario's ``turret.position``.

    Raises
    ------
    ReportError
        Neither is available (or the saved value is not two finite numbers).
    """
    meta = result.meta if isinstance(result.meta, dict) else {}
    saved = meta.get("turret_position_B")
    if saved is not None:
        try:
            p = np.array(saved, dtype=float)
        except (TypeError, ValueError):
            p = np.empty(0)
        if p.shape != (2,) or not np.isfinite(p).all():
            raise ReportError(f"result meta turret_position_B = {saved!r} is not two finite numbers (x, y) [m]")
        return p
    if scenario is not None:
        return np.array(scenario.turret.position, dtype=float)
    raise ReportError("the turret position is unknown (no turret_position_B in the result metadata and no "
                      "scenario): turret offsets cannot be computed")


def turret_track(result: Any, p_cot_B: Any) -> TurretTrack:
    """Turret offsets of a saved result (module docstring).

    Parameters
    ----------
    result : Result
        With channels ``x``, ``y`` [m] and ``psi`` [rad] (body-origin pose in {E}); ``x_d``, ``y_d``
        [m] optional.
    p_cot_B : array_like, shape (2,)
        Centre of turret in {B} [m].

    Returns
    -------
    TurretTrack
    """
    p = np.array(p_cot_B, dtype=float)
    eta = np.column_stack([result["x"], result["y"], result["psi"]])
    x, y = turret_offset(eta, p)
    has_sp = "x_d" in result and "y_d" in result
    return TurretTrack(t=np.asarray(result.time, dtype=float), x=x, y=y, offset=np.hypot(x, y),
                       x_d=np.asarray(result["x_d"], dtype=float) if has_sp else None,
                       y_d=np.asarray(result["y_d"], dtype=float) if has_sp else None, p_cot_B=p)


@dataclass(frozen=True)
class CausalTraces:
    """The causal reliability index of one saved case, evaluated as its KPIs are (:func:`causal_traces`).

    Attributes
    ----------
    lines : dict
        ``lines[line_id]``: the :class:`IndexRun` of each segment where that line has values (lines
        with MBS_std > 0 only). Their minimum is the KPI ``delta_min[<id>]``.
    riser : dict
        ``riser["top"]``, ``riser["bottom"]``: the same for the riser end angles (scenario riser and
        channels ``riser_top_angle``, ``riser_bottom_angle`` present). Minima: ``riser_delta_<end>_min``.
    lines_min, riser_min : list of IndexRun
        Per segment, the lowest index over the alive lines (over both riser ends) at each ready
        instant; their minima are the KPIs ``delta_min`` and ``riser_delta_min``.
    segments : list of (float, float)
        First and last time [s] of each segment that has at least two samples.
    ready_from : list of float or None
        Per segment, the first time the index is ready (None: never, the segment is shorter than
        ``lp_window + sigma_window``).
    t_break : float or None
        Time of the first line break [s].
    broken : tuple of str
        Lines broken during the record (the ``"line <id> broke"`` events).
    delta_s : float
        Threshold of the index [-] (:data:`tapm_opt.studies.kpis.DELTA_S_DEFAULT`).
    """

    lines: dict[str, list[IndexRun]]
    riser: dict[str, list[IndexRun]]
    lines_min: list[IndexRun]
    riser_min: list[IndexRun]
    segments: list[tuple[float, float]]
    ready_from: list[float | None]
    t_break: float | None
    broken: tuple[str, ...]
    delta_s: float


def causal_traces(result: Any, scenario: Any, *, lp_window: float = LP_WINDOW_DEFAULT,
                  sigma_window: float = SIGMA_WINDOW_DEFAULT) -> CausalTraces | None:
    """The causal reliability index delta(t) (survey eq. 32; [R] §2.2) of every line and riser end
    of a saved result, as the KPIs evaluate it: the record split at the first line break (the
    estimate restarts there), a broken line counted up to its break, values only where the
    estimate is ready (``lp_window + sigma_window`` = 700 s into each segment by default). The
    minima of the runs are the KPIs ``delta_min[<id>]``, ``delta_min``, ``riser_delta_top_min``,
    ``riser_delta_bottom_min`` and ``riser_delta_min`` of :func:`tapm_opt.studies.kpis.case_kpis`
    with its defaults.

    Returns
    -------
    CausalTraces or None
        None without a scenario or without a signal that has an index (a line with MBS_std > 0, a
        riser end); a record too short for the index gives empty runs.

    Raises
    ------
    TapmError
        A tension or riser channel is not finite (``ReliabilityError``).
    """
    if scenario is None or len(result.time) < 2:
        return None
    t = np.asarray(result.time, dtype=float)
    breaks = break_times(result)
    ids_all = [ln.id for ln in scenario.lines]
    breaks = {k: v for k, v in breaks.items() if k in ids_all}
    t_b1 = min(breaks.values(), default=math.inf)
    eps = 1e-9 * max(1.0, abs(float(t[-1])))
    intact_all = t <= t_b1 + eps
    segments = (intact_all, ~intact_all)
    spans = [(float(t[s][0]), float(t[s][-1])) for s in segments if s.sum() >= 2]
    mbs = scenario.line_arrays["MBS"]
    mbs_std = scenario.line_arrays["MBS_std"]
    cols = [j for j, lid in enumerate(ids_all) if f"T_fairlead[{lid}]" in result and mbs_std[j] > 0]
    lines: dict[str, list[IndexRun]] = {}
    lines_min: list[IndexRun] = []
    ready: dict[int, float] = {}
    if cols:
        ids = [ids_all[j] for j in cols]
        X = np.column_stack([np.asarray(result[f"T_fairlead[{lid}]"], dtype=float) for lid in ids])
        alive = np.stack([t <= breaks.get(lid, math.inf) + eps for lid in ids])
        per, lines_min = causal_runs(t, X, mbs[cols], mbs_std[cols], segments, alive, names=ids,
                                     lp_window=lp_window, sigma_window=sigma_window)
        lines = {lid: r for lid, r in zip(ids, per) if r}
    riser: dict[str, list[IndexRun]] = {}
    riser_min: list[IndexRun] = []
    rs = getattr(scenario, "riser", None)
    ends = [(end, ch, fld) for end, ch, fld in RISER_ENDS if ch in result]
    if rs is not None and ends:
        r_t = np.array([float(getattr(rs, fld)) for _, _, fld in ends])
        s_t = np.array([float(getattr(rs, fld + "_std")) for _, _, fld in ends])
        if np.all(np.isfinite(r_t)) and np.all(np.isfinite(s_t) & (s_t > 0)):
            X = np.column_stack([np.asarray(result[ch], dtype=float) for _, ch, _ in ends])
            per, low = causal_runs(t, X, r_t, s_t, segments, np.ones((len(ends), len(t)), bool),
                                   names=[e for e, _, _ in ends], lp_window=lp_window, sigma_window=sigma_window)
            riser = {end: r for (end, _, _), r in zip(ends, per) if r}
            if all(per):  # as the KPI: the worst end only when every end has values
                riser_min = low
    if not cols and not (rs is not None and ends):
        return None
    for run in [*lines_min, *riser_min]:
        ready[run.segment] = min(float(run.t[0]), ready.get(run.segment, math.inf))
    n_seg = sum(1 for s in segments if s.sum() >= 2)
    return CausalTraces(lines=lines, riser=riser, lines_min=lines_min, riser_min=riser_min, segments=spans,
                        ready_from=[ready.get(s) for s in range(n_seg)],
                        t_break=None if not math.isfinite(t_b1) else float(t_b1),
                        broken=tuple(sorted(breaks, key=lambda k: (breaks[k], k))), delta_s=float(DELTA_S_DEFAULT))


# -- controller overlay ------------------------------------------------------------------------

Curve = tuple[np.ndarray, np.ndarray]


@dataclass
class ComparisonSeries:
    """The curves of one case in the controller overlay figure, each reduced to at most
    ``MAX_POINTS`` points (:func:`decimate`); a curve is None when the case cannot give it and
    ``missing`` says why (one short phrase per missing curve).

    Attributes
    ----------
    label : str
        Legend entry (the controller; the case name is added when a group has the controller twice).
    controller : str
        The controller, which sets the colour.
    t_span : (float, float)
        First and last logged time [s].
    offset : (t, offset [m]) or None
        Horizontal turret offset from its field-zero-point position (:func:`turret_track`).
    heading : (t, psi [deg]) or None
        Heading, unwrapped and started on the branch nearest 0 so controllers line up.
    util : (t, max_j T_j/MBS_j [-]) or None
        Largest fairlead tension utilisation over the lines at each time (needs the scenario's MBS).
    tension : (t, max_j T_j [N]) or None
        Largest fairlead tension over the lines at each time.
    power : (t, sum P [W]) or None
        Total thrust power (sum of the ``P[<thruster>]`` channels).
    events : list
        ``[time, text]`` events of the result.
    """

    label: str
    controller: str
    t_span: tuple[float, float]
    offset: Curve | None = None
    heading: Curve | None = None
    util: Curve | None = None
    tension: Curve | None = None
    power: Curve | None = None
    events: list = field(default_factory=list)
    missing: list[str] = field(default_factory=list)


def comparison_series(result: Any, scenario: Any | None, *, label: str, controller: str | None = None,
                      n: int = MAX_POINTS) -> ComparisonSeries:
    """The overlay curves of one saved case (:class:`ComparisonSeries`); never raises for a missing
    channel or an unknown scenario: that curve is left out and named in ``missing``."""
    t = np.asarray(result.time, dtype=float)
    cs = ComparisonSeries(label=label, controller=controller or label,
                          t_span=(float(t[0]), float(t[-1])) if len(t) else (0.0, 0.0),
                          events=events_of(result))
    chans = tuple(result.channels)

    def lacking(names: Sequence[str]) -> list[str]:
        return [c for c in names if c not in chans]

    # turret offset
    miss = lacking(("x", "y", "psi"))
    if miss:
        cs.missing.append(f"no turret offset (channel{'s' if len(miss) > 1 else ''} {', '.join(miss)} missing)")
    else:
        try:
            cs.offset = decimate(t, turret_track(result, turret_position_of(result, scenario)).offset, n)
        except ReportError as exc:
            cs.missing.append(f"no turret offset ({exc})")
    # heading
    if "psi" in chans:
        psi = np.degrees(np.unwrap(np.asarray(result["psi"], dtype=float)))
        if len(psi) and np.isfinite(psi[0]):
            psi = psi - 360.0 * np.round(psi[0] / 360.0)
        cs.heading = decimate(t, psi, n)
    else:
        cs.missing.append("no heading (channel psi missing)")
    # maximum line tension
    ids = [c[len("T_fairlead["):-1] for c in chans if c.startswith("T_fairlead[") and c.endswith("]")]
    if not ids:
        cs.missing.append("no line tension (no T_fairlead[...] channels)")
    else:
        T = np.column_stack([np.asarray(result[f"T_fairlead[{i}]"], dtype=float) for i in ids])
        with np.errstate(invalid="ignore"):
            cs.tension = decimate(t, np.nanmax(T, axis=1), n)
        mbs = {}
        if scenario is not None:
            try:
                arr = scenario.line_arrays["MBS"]
                mbs = {ln.id: float(arr[j]) for j, ln in enumerate(scenario.lines)}
            except Exception:  # noqa: BLE001 - utilisation is optional, tension in MN is drawn instead
                mbs = {}
        have = [j for j, i in enumerate(ids) if mbs.get(i, 0.0) > 0]
        if have:
            U = T[:, have] / np.array([mbs[ids[j]] for j in have])
            with np.errstate(invalid="ignore"):
                cs.util = decimate(t, np.nanmax(U, axis=1), n)
    # thrust power
    pch = [c for c in chans if c.startswith("P[") and c.endswith("]")]
    if pch:
        P = np.column_stack([np.asarray(result[c], dtype=float) for c in pch]).sum(axis=1)
        cs.power = decimate(t, P, n)
    else:
        cs.missing.append("no thrust power (no P[...] channels)")
    return cs
