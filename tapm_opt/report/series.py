"""Series the report plots, derived from a saved result and its scenario (nothing is simulated).

* :func:`turret_track`: the turret-referenced motion. Safety is measured at the turret (survey
  §4.2.1; ``docs/nomenclature.md``): trajectories, safe and alert circles and offsets refer to the
  centre of turret's horizontal position relative to where it rests at the field zero point,
  :func:`tapm_opt.geometry.turret_offset` of the logged body-origin pose (x, y, psi).
* :func:`reliability_traces`: the reliability index delta(t) per line from the saved tensions.
* :func:`events_of`: the ``[time, text]`` events of a result.
* :func:`comparison_series`: the four curves of one case in the controller overlay figure (turret
  offset, heading, maximum line tension, total thrust power), reduced with :func:`decimate`.
* :func:`decimate`: at most ``MAX_POINTS`` points per curve, min/max per bucket so peaks survive.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..geometry import turret_offset
from .data import ReportError

__all__ = ["MAX_POINTS", "TurretTrack", "ComparisonSeries", "decimate", "turret_position_of", "turret_track",
           "reliability_traces", "events_of", "comparison_series"]

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


def reliability_traces(result: Any, scenario: Any) -> tuple[dict[str, list], float] | None:
    """delta(t) per line from the saved tensions with the KPI module's reliability index (survey
    eq. 32, default window), split at the first line break like the KPIs.

    Returns
    -------
    (traces, delta_s) or None
        ``traces[line_id]`` is a list of ``(t [s], delta [-])`` segments (intact record, then the
        damaged record while the line is alive); ``delta_s`` is the KPI module's threshold [-].
        None when the KPI module, the scenario or every line's breaking-strength scatter is missing.
    """
    try:
        from ..studies.kpis import DELTA_S_DEFAULT, LP_WINDOW_DEFAULT, reliability_index
    except ImportError:
        return None
    if scenario is None:
        return None
    t = result.time
    breaks: dict[str, float] = {}
    for ev in events_of(result):
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
