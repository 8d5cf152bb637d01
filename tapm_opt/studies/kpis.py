"""Key performance indicators of a closed-loop result (computed from saved results only).

:func:`case_kpis` turns one :class:`~tapm_opt.results.Result` (and the scenario it was run with)
into a flat ``{name: number}`` dict: offsets (of the centre of turret from its field-zero-point
position, ``geometry.turret_offset``), heading error, line tensions, the structural
reliability index of survey eq. (32) -- causal, as a monitor on board would compute it
(:mod:`tapm_opt.estimation.reliability`), and offline over the whole record as its cross-check --,
the riser end angles and their indices ([G] §2.2) when the result carries them, the DNV-OS-E301
(October 2008) line-strength check, thrust energy and a fuel proxy, and the controller's
solve-time statistics. :func:`kpi_table` writes one row per case as CSV and Markdown. Every
definition and assumption is in ``docs/kpis.md``; every KPI's unit, better direction and column
order in :mod:`tapm_opt.studies.kpi_catalogue` (:func:`kpi_unit` and :func:`kpi_order` are its).

:func:`basic_kpis` (used by ``tapm simulate``) is the historical subset of :func:`case_kpis`.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ..control.setpoint_opt import DELTA_S_DEFAULT
from ..errors import TapmError
from ..estimation.reliability import LP_WINDOW_DEFAULT, SIGMA_WINDOW_DEFAULT, causal_reliability, gumbel_k
from ..geometry import ssa, turret_offset
from ..results import Result
from ..standards import DNV_CAPACITY_FACTOR, DNV_E301_2008_FACTORS  # noqa: F401  (re-exported)
from ..models.fatigue import line_curves
from .verification import characteristic_tension, miner_damage, utilisation
from .kpi_catalogue import kpi as _catalogue_kpi
from .kpi_catalogue import kpi_order, kpi_unit, per_line_kpis

__all__ = [
    "KpiError", "case_kpis", "basic_kpis", "kpi_table", "kpi_unit", "kpi_order",
    "gumbel_k", "low_pass", "reliability_index", "ReliabilityTrace",
    "DNV_E301_2008_FACTORS", "DNV_CAPACITY_FACTOR", "SFC_DEFAULT", "LP_WINDOW_DEFAULT", "SIGMA_WINDOW_DEFAULT",
    "DELTA_S_DEFAULT", "RISER_ENDS", "IndexRun", "causal_runs", "break_times", "break_tensions",
    "buoy_loss_times",
]


class KpiError(TapmError, ValueError):
    """A result cannot be evaluated: a needed channel is missing, values are not finite, or an
    option is out of range."""


# DNV-OS-E301 factors (DNV_E301_2008_FACTORS, DNV_CAPACITY_FACTOR, DNV_CLASS1_COMMON_FACTOR): one
# definition in tapm_opt.standards, shared with the capability envelopes.
#: Specific fuel consumption of the fuel proxy [kg/kWh] (diesel-electric, ~200 g/kWh).
SFC_DEFAULT = 0.2
# LP_WINDOW_DEFAULT (100 s): width of the moving average that defines the low-frequency tension,
# centred offline, trailing in the causal index; SIGMA_WINDOW_DEFAULT (600 s): trailing window of
# the causal index's wave-frequency sigma and up-crossing count (both from estimation.reliability).
# DELTA_S_DEFAULT, the lower threshold of the reliability index, is the setpoint layers' one
# (tapm_opt.control.setpoint_opt; [R] §3: 2 for lines and riser), imported above.

# The plant's break events: "line <id> broke" (a prescribed break) and "line <id> broke: overload,
# tension <T> MN = <p> % MBS >= strength <S> MN" (tension and strength to 3 significant digits).
_BREAK_RE = re.compile(r"line\s+(\S+)\s+broke(?::\s*(?P<detail>.*))?", re.DOTALL)
_BUOY_RE = re.compile(r"line\s+(\S+)\s+lost its buoy at joint\s+(\d+)")
_BREAK_TENSION_RE = re.compile(r"\btension\s+(?P<T>[0-9][0-9.]*(?:[eE][-+]?[0-9]+)?)\s*MN\b")
_BREAK_STRENGTH_RE = re.compile(r"\bstrength\s+(?P<S>[0-9][0-9.]*(?:[eE][-+]?[0-9]+)?)\s*MN\b")

# Units, directions and the column order of the KPIs: tapm_opt.studies.kpi_catalogue (one table).
#: The per-line quantities, in column order (T_max, T_mean, util_max, ...).
_LINE_QUANTITIES: tuple[str, ...] = tuple(e.base for e in per_line_kpis())
_DIAG_KEYS = ("solver_time_median", "solver_time_p95", "solver_time_max", "solver_failures", "solver_fallbacks",
              "allocation_fallbacks")
_LABEL_ORDER = ("scenario", "sea_state", "controller", "condition", "seed")
#: The riser ends: (KPI name part, angle-magnitude channel [rad], Riser field of the mean critical angle).
RISER_ENDS: tuple[tuple[str, str, str], ...] = (
    ("top", "riser_top_angle", "critical_top_angle"),
    ("bottom", "riser_bottom_angle", "critical_bottom_angle"),
)


# -- building blocks ---------------------------------------------------------------------------

def _cumint(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Cumulative trapezoid integral of x over t, starting at 0."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t))])


def _int_at(t: np.ndarray, x: np.ndarray, C: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Exact integral from t[0] to tau of the piecewise-linear interpolant of x."""
    j = np.clip(np.searchsorted(t, tau, side="right") - 1, 0, len(t) - 2)
    h = t[j + 1] - t[j]
    s = np.clip(tau - t[j], 0.0, h)
    slope = np.divide(x[j + 1] - x[j], h, out=np.zeros_like(h), where=h > 0)
    return C[j] + x[j] * s + 0.5 * slope * s * s


def _tmean(t: np.ndarray, x: np.ndarray) -> float:
    """Time-weighted (trapezoid) mean; the plain mean for a single sample or zero duration."""
    d = float(t[-1] - t[0]) if len(t) else 0.0
    if len(t) < 2 or d <= 0:
        return float(np.mean(x))
    return float(np.trapezoid(x, t) / d)


def _tstd(t: np.ndarray, x: np.ndarray) -> float:
    """Time-weighted (trapezoid) standard deviation."""
    m = _tmean(t, x)
    return float(math.sqrt(max(_tmean(t, (x - m) ** 2), 0.0)))


def _hold_weights(t: np.ndarray) -> np.ndarray:
    """Zero-order-hold weights: sample i stands for [t_i, t_{i+1}); the last sample weighs 0."""
    return np.diff(t, append=t[-1]) if len(t) else np.zeros(0)


def low_pass(t: Sequence[float], x: Sequence[float], window: float = LP_WINDOW_DEFAULT) -> tuple[np.ndarray, np.ndarray]:
    """Centred moving average of width ``window`` [s] of the piecewise-linear signal (t, x).

    Returns ``(mask, x_lf)``: ``mask`` marks the samples where the whole window lies inside the
    record (only there the average is defined), ``x_lf`` the average at those samples. A record
    that is too short for any full window gives ``mask`` all true and ``x_lf`` the record's
    time-weighted mean.
    """
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    if not (window > 0 and math.isfinite(window)):
        raise KpiError(f"low-pass window = {window!r} s must be a positive number")
    half = 0.5 * window
    eps = 1e-9 * max(1.0, abs(float(t[-1])) if len(t) else 1.0)
    mask = (t - half >= t[0] - eps) & (t + half <= t[-1] + eps) if len(t) else np.zeros(0, bool)
    if mask.sum() < 2:
        return np.ones(len(t), bool), np.full(len(t), _tmean(t, x) if len(t) else 0.0)
    C = _cumint(t, x)
    tc = t[mask]
    lf = (_int_at(t, x, C, np.minimum(tc + half, t[-1])) - _int_at(t, x, C, np.maximum(tc - half, t[0]))) / window
    return mask, lf


@dataclass(frozen=True)
class ReliabilityTrace:
    """The reliability index of one line over one stationary segment (see :func:`reliability_index`).

    Attributes
    ----------
    time : ndarray
        Instants where delta is evaluated [s] (full low-pass window inside the segment).
    delta : ndarray
        delta(t) = (T_b - k sigma - T_LF(t)) / sigma_b [-].
    T_LF : ndarray
        Low-frequency tension at those instants [N].
    sigma : float
        Standard deviation of the wave-frequency tension T - T_LF [N].
    n : int
        Zero up-crossings of the wave-frequency tension (the number of maxima).
    k : float
        Gumbel extreme factor for max(n, 2) maxima.
    """

    time: np.ndarray
    delta: np.ndarray
    T_LF: np.ndarray
    sigma: float
    n: int
    k: float

    def time_below(self, delta_s: float) -> float:
        """Time [s] with delta < delta_s (zero-order hold)."""
        return float(np.sum(_hold_weights(self.time)[self.delta < delta_s]))

    @property
    def span(self) -> float:
        """Evaluated duration [s]."""
        return float(self.time[-1] - self.time[0]) if len(self.time) else 0.0


def reliability_index(t: Sequence[float], T: Sequence[float], T_b: float, sigma_b: float, *,
                      window: float = LP_WINDOW_DEFAULT) -> ReliabilityTrace:
    """Offline reliability index of survey eq. (32) for a tension record of one line (the whole
    record known: the cross-check of the causal index of
    :func:`tapm_opt.estimation.reliability.causal_reliability`, KPI ``delta_min_offline``).

    T_LF is the centred moving average of width ``window`` (:func:`low_pass`), the wave-frequency
    part is T - T_LF, sigma its time-weighted standard deviation, n its zero up-crossings (the
    number of maxima of a narrow-band process), k = :func:`gumbel_k` (max(n, 2)), and
    delta(t) = (T_b - k sigma - T_LF(t)) / sigma_b at the samples where the window fits.

    Parameters
    ----------
    t, T : sequences
        Times [s] (increasing) and tensions [N] of one stationary segment.
    T_b : float
        Mean breaking strength [N] (MBS of the scenario).
    sigma_b : float
        Standard deviation of the breaking strength [N], > 0.
    """
    t = np.asarray(t, float)
    T = np.asarray(T, float)
    if not sigma_b > 0:
        raise KpiError(f"sigma_b = {sigma_b!r} N must be positive for the reliability index")
    if len(t) < 2:
        raise KpiError("the reliability index needs at least two samples")
    mask, lf = low_pass(t, T, window)
    tc = t[mask]
    w = T[mask] - lf
    sigma = _tstd(tc, w)
    wd = w - _tmean(tc, w)
    n = int(np.sum((wd[:-1] < 0) & (wd[1:] >= 0)))
    k = gumbel_k(max(n, 2))
    delta = (T_b - k * sigma - lf) / sigma_b
    return ReliabilityTrace(time=tc, delta=delta, T_LF=lf, sigma=sigma, n=n, k=k)


@dataclass(frozen=True)
class IndexRun:
    """The causal reliability index of one signal (or the lowest over several) on one segment,
    at the samples where the estimate is ready (and the signal alive).

    Attributes
    ----------
    segment : int
        0: the intact record (up to and including the first line break), 1: the damaged record.
    t : ndarray, shape (k,)
        Times [s].
    delta : ndarray, shape (k,)
        delta(t) [-] (survey eq. 32; [R] §2.2).
    ksigma : ndarray, shape (k,) or None
        The extreme allowance k sigma at those times, in the unit of the signal (N for a line, rad
        for a riser end); None for a lowest-over-signals run.
    """

    segment: int
    t: np.ndarray
    delta: np.ndarray
    ksigma: np.ndarray | None = None


def causal_runs(t: np.ndarray, X: np.ndarray, r_t: np.ndarray, sigma_t: np.ndarray,
                segments: Sequence[np.ndarray], alive: np.ndarray, *, names: Sequence[str],
                lp_window: float = LP_WINDOW_DEFAULT, sigma_window: float = SIGMA_WINDOW_DEFAULT,
                ) -> tuple[list[list[IndexRun]], list[IndexRun]]:
    """The causal index of the columns of ``X`` (N, m), restarted on each segment, exactly as the
    KPIs evaluate it (:func:`case_kpis`): one
    :func:`~tapm_opt.estimation.reliability.causal_reliability` per segment (boolean masks over
    ``t``), a column's values kept where the estimate is ready and the column's ``alive`` (m, N)
    holds; with ``k sigma`` and the lowest index over the columns at each instant (for the report).

    Returns
    -------
    (per_column, lowest)
        ``per_column[j]``: the :class:`IndexRun` of column j on each segment where it has values;
        ``lowest``: per segment, the minimum over the alive columns at each ready instant.
    """
    per: list[list[IndexRun]] = [[] for _ in range(X.shape[1])]
    lowest: list[IndexRun] = []
    for s, seg in enumerate(segments):
        if seg.sum() < 2:
            continue
        ts = t[seg]
        rec = causal_reliability(ts, X[seg], r_t, sigma_t, names=names, lp_window=lp_window,
                                 sigma_window=sigma_window)
        ok = rec.ready[None, :] & alive[:, seg]           # (m, n)
        ks = np.asarray(rec.k) * np.asarray(rec.sigma)     # (n, m)
        for j in range(X.shape[1]):
            if ok[j].any():
                per[j].append(IndexRun(segment=s, t=ts[ok[j]], delta=np.asarray(rec.delta[ok[j], j]),
                                       ksigma=ks[ok[j], j]))
        anyok = ok.any(axis=0)
        if anyok.any():
            d = np.where(ok.T, np.asarray(rec.delta), np.inf)[anyok]
            lowest.append(IndexRun(segment=s, t=ts[anyok], delta=d.min(axis=1)))
    return per, lowest


def _run_stats(runs: Sequence[IndexRun], delta_s: float) -> tuple[float, float]:
    """(min delta, fraction of the evaluated time with delta < delta_s) of a column's runs."""
    d_min = float(min(r.delta.min() for r in runs))
    span = sum(float(r.t[-1] - r.t[0]) for r in runs)
    if span > 0:
        frac = sum(float(np.sum(_hold_weights(r.t)[r.delta < delta_s])) for r in runs) / span
    else:
        frac = float(any(bool(np.any(r.delta < delta_s)) for r in runs))
    return d_min, frac


def _dnv_ratio(t: np.ndarray, T: np.ndarray, mbs: float, limit_state: str, consequence_class: int,
               common_factor: bool, peak: float = -math.inf) -> float:
    """LHS / S_C of the line check on the record (t, T); ``peak`` [N]: a maximum the samples
    missed (the tension of the line's break)."""
    t_mean = _tmean(t, T)
    # the time-weighted mean of a constant record can exceed its maximum by a rounding
    t_dyn = max(max(float(T.max()), peak) - t_mean, 0.0)
    lhs = characteristic_tension(t_mean, t_dyn, consequence_class, limit_state, common_factor=common_factor)
    return utilisation(lhs, mbs)


# -- case KPIs ---------------------------------------------------------------------------------

def _channel(result: Result, name: str, what: str, mask: np.ndarray) -> np.ndarray:
    if name not in result:
        raise KpiError(f"result has no channel {name!r} (needed for {what}); channels are {', '.join(result.channels)}")
    x = result[name][mask]
    if not np.all(np.isfinite(x)):
        i = int(np.flatnonzero(~np.isfinite(x))[0])
        raise KpiError(f"channel {name!r} is not finite at t = {float(result.time[mask][i]):g} s")
    return x


def _break_events(result: Any, line_ids: Sequence[str] | None) -> list[tuple[float, str, str]]:
    """``(time, line id, detail)`` of the line-break events of a result, in log order (``detail``:
    the text after ``"broke:"``, empty for a prescribed break)."""
    out = []
    for ev in result.meta.get("events", []) or []:
        try:
            te, text = float(ev[0]), str(ev[1])
        except (TypeError, ValueError, IndexError):
            raise KpiError(f"result.meta['events'] entry {ev!r} is not [time, text]") from None
        m = _BREAK_RE.fullmatch(text.strip())
        if not m:
            continue
        lid = m.group(1)
        if line_ids is not None and lid not in line_ids:
            raise KpiError(f"event {text!r} at t = {te:g} s names a line without a channel 'T_fairlead[{lid}]'")
        out.append((te, lid, m.group("detail") or ""))
    return out


def break_times(result: Any, line_ids: Sequence[str] | None = None) -> dict[str, float]:
    """``{line id: time [s]}`` of the ``"line <id> broke"`` events of a result (the first per
    line), prescribed breaks and overload breaks (``"line <id> broke: overload, ..."``) alike; with
    ``line_ids``, an event naming another line is an error."""
    out: dict[str, float] = {}
    for te, lid, _ in _break_events(result, line_ids):
        out[lid] = min(te, out.get(lid, math.inf))
    return out


def buoy_loss_times(result: Any) -> dict[tuple[str, int], float]:
    """``{(line id, joint): time [s]}`` of the plant's ``"line <id> lost its buoy at joint <j>"``
    events of a result (the first per buoy)."""
    out: dict[tuple[str, int], float] = {}
    for ev in result.meta.get("events", []) or []:
        try:
            te, text = float(ev[0]), str(ev[1])
        except (TypeError, ValueError, IndexError):
            raise KpiError(f"result.meta['events'] entry {ev!r} is not [time, text]") from None
        m = _BUOY_RE.fullmatch(text.strip())
        if m:
            key = (m.group(1), int(m.group(2)))
            out[key] = min(te, out.get(key, math.inf))
    return out


def break_tensions(result: Any, line_ids: Sequence[str] | None = None,
                   strength: Mapping[str, float] | None = None) -> dict[str, float]:
    """``{line id: tension [N]}`` at the overload break of each line that broke from overload.

    The plant checks the tension at every step and logs the break with the tension that broke
    the line (``"line <id> broke: overload, tension <T> MN = ... >= strength <S> MN"``), which the
    logged samples, taken at ``dt_log``, usually miss: the break's peak falls between them. The
    event's figures are rounded to 3 significant digits, so the tension returned is the larger
    of ``<T>``, ``<S>`` and ``strength[line]`` when given (the plant breaks a line only when its
    tension has reached its strength). A prescribed break (no tension in its event) gives none.
    """
    first = break_times(result, line_ids)
    out: dict[str, float] = {}
    for te, lid, detail in _break_events(result, line_ids):
        if te != first[lid] or lid in out:
            continue
        mt = _BREAK_TENSION_RE.search(detail)
        if not mt:
            continue
        ms = _BREAK_STRENGTH_RE.search(detail)
        vals = [float(mt.group("T")) * 1e6, float(ms.group("S")) * 1e6 if ms else 0.0]
        if strength is not None and lid in strength:
            vals.append(float(strength[lid]))
        if all(math.isfinite(v) for v in vals):
            out[lid] = max(vals)
    return out


def _detection(result: Result, breaks: dict[str, float],
               losses: dict[tuple[str, int], float] | None = None) -> dict[str, Any]:
    """Line-break and buoy-loss detection KPIs from the estimator's log (``meta["estimator_log"]``:
    events ``{"t", "line", "event": "line break detected"}`` and ``{"t", "line", "joint", "event":
    "buoy loss detected"}``), against the breaks and buoy losses the plant reported:
    ``break_detected_at`` [s] — the first detection of a line that broke, after its break (absent
    when no break was detected); ``detection_delay`` [s] — that time less the break's;
    ``break_isolated_line`` — the id of the first line detected after the first break (``""``
    when none was) and ``break_isolated`` — 1 when that line is one that broke, else 0 (both
    absent without a break); the same for buoy losses (``buoy_loss_detected_at``,
    ``buoy_loss_detection_delay``, ``buoy_loss_isolated``: 1 when the first fault detected after
    the first loss, break or buoy loss, is a buoy lost by then; absent without a buoy loss);
    ``false_alarms`` — detections of a break or a buoy loss that had not happened by then (a
    buoy loss detected as a break counts). All absent when the run had no detector (no log)."""
    log = result.meta.get("estimator_log")
    if log is None:
        return {}
    losses = losses or {}
    det = sorted((float(e["t"]), str(e["line"])) for e in log if e.get("event") == "line break detected")
    lost = sorted((float(e["t"]), (str(e["line"]), int(e["joint"]))) for e in log
                  if e.get("event") == "buoy loss detected")
    true = [(t, lid) for t, lid in det if lid in breaks and t >= breaks[lid]]
    wrong_lost = sum(1 for t, b in lost if not (b in losses and t >= losses[b]))
    out: dict[str, Any] = {"false_alarms": sum(1 for t, lid in det if not (lid in breaks and t >= breaks[lid]))
                           + wrong_lost}
    if losses:
        t_l = min(losses.values())
        first = sorted([(t, 0, b in losses and t >= losses[b]) for t, b in lost if t >= t_l]
                       + [(t, 1, False) for t, lid in det if t >= t_l])
        out["buoy_loss_isolated"] = float(bool(first) and first[0][2])
        hit = [(t, b) for t, b in lost if b in losses and t >= losses[b]]
        if hit:
            out["buoy_loss_detected_at"] = hit[0][0]
            out["buoy_loss_detection_delay"] = hit[0][0] - losses[hit[0][1]]
    if breaks:
        t_b = min(breaks.values())
        after = [(t, lid) for t, lid in det if t >= t_b]
        out["break_isolated"] = float(bool(after) and after[0][1] in breaks)
        out["break_isolated_line"] = after[0][1] if after else ""
        if true:
            out["break_detected_at"] = true[0][0]
            out["detection_delay"] = true[0][0] - breaks[true[0][1]]
    return out


def _current_estimation(result: Result, scenario: Any, t_start: float) -> dict[str, float]:
    """Current-profile estimation KPIs from the estimator's log (``"current estimate"`` events of
    :class:`~tapm_opt.estimation.current_profile.CurrentEstimating`) against the plant's current
    at each estimate's time (``Environment.current_surface``: the turning and developing current of
    the case's sea state; the seabed factor of its profile, :func:`~tapm_opt.estimation.current_profile.
    profile_shape`): RMS over the estimates at or after ``t_start`` of the speed error
    ``current_speed_error`` [m/s], the direction error ``current_direction_error`` [deg] (wrapped to
    +-180 deg) and the seabed-factor error ``current_seabed_factor_error`` [-]. All absent without
    estimates (the run took the current as known)."""
    log = result.meta.get("estimator_log") or []
    est = [e for e in log if e.get("event") == "current estimate" and float(e["t"]) >= t_start - 1e-9]
    if not est:
        return {}
    from ..estimation.current_profile import profile_shape
    from ..plant.environment import Environment

    sid = result.meta.get("sea_state")
    try:
        ss = scenario.sea_state(sid)
    except (KeyError, ValueError, TapmError):
        raise KpiError(f"the record's sea_state = {sid!r} is not a sea state of scenario {scenario.name!r}: "
                       "its current is the truth of the current KPIs") from None
    env = Environment(scenario, ss)
    f_b = profile_shape(ss, scenario.environment.water_depth)[1]
    eV, eb, ef = [], [], []
    for e in est:
        u = env.current_surface(float(e["t"]))
        eV.append(float(e["speed"]) - math.hypot(u[0], u[1]))
        eb.append(float(ssa(float(e["direction"]) - math.atan2(u[1], u[0]))))
        ef.append(float(e["seabed_factor"]) - f_b)
    rms = lambda x: math.sqrt(float(np.mean(np.square(x))))  # noqa: E731
    return {"current_speed_error": rms(eV), "current_direction_error": math.degrees(rms(eb)),
            "current_seabed_factor_error": rms(ef)}


def _sensor_target(kind: str, fault: Any) -> tuple:
    """The sensor a fault or a detection names: ("gnss",), ("cell", line id) or ("gyro", 1 | 2)."""
    if kind.startswith("gnss"):
        return ("gnss",)
    if kind.startswith("cell"):
        return ("cell", str(fault.get("line") if isinstance(fault, Mapping) else fault.line))
    g = fault.get("gyro") if isinstance(fault, Mapping) else fault.gyro
    return ("gyro", int(g or 1))


def _sensor_faults(result: Result, scenario: Any, win: np.ndarray) -> dict[str, float]:
    """Sensor-fault KPIs (docs/kpis.md, "Sensor faults"): the scenario's sensor faults
    (:data:`~tapm_opt.config.schema.SENSOR_FAULT_KINDS`) against the estimator's
    ``sensor fault detected`` events (``meta["estimator_log"]``,
    :mod:`tapm_opt.estimation.redundancy`): ``sensor_fault_detected_at`` and
    ``sensor_fault_detection_delay`` [s] of the first fault's sensor (absent when not detected),
    ``sensor_fault_isolated`` (1 when the first sensor detection after the first fault names its
    sensor), ``sensor_false_alarms`` (detections of a sensor with no fault by then: 0 in a run
    without sensor faults when the estimator votes; absent without the events' estimator); and
    the error of the estimated turret position (``x_hat, y_hat, psi_hat``) against the true one
    (``x, y, psi``) over the first fault (its time to its end or the record's),
    ``turret_error_fault_max`` and ``turret_error_fault_rms`` [m] (time-weighted)."""
    from ..config.schema import SENSOR_FAULT_KINDS

    faults = sorted((f for f in getattr(scenario, "faults", ()) if f.kind in SENSOR_FAULT_KINDS),
                    key=lambda f: f.time)
    log = result.meta.get("estimator_log")
    voting = log is not None and result.meta.get("redundancy") == "vote"
    out: dict[str, float] = {}
    det = [] if log is None else sorted(
        (float(e["t"]), _sensor_target(str(e.get("sensor")), e)) for e in log
        if isinstance(e, Mapping) and e.get("event") == "sensor fault detected")
    starts: dict[tuple, float] = {}
    for f in faults:
        starts.setdefault(_sensor_target(f.kind, f), float(f.time))
    if voting or det:
        out["sensor_false_alarms"] = sum(1 for t, tgt in det if not (tgt in starts and t >= starts[tgt] - 1e-9))
    if not faults:
        return out
    f0 = faults[0]
    t0 = float(f0.time)
    tgt0 = _sensor_target(f0.kind, f0)
    hit = [t for t, tgt in det if tgt == tgt0 and t >= t0 - 1e-9]
    if hit:
        out["sensor_fault_detected_at"] = hit[0]
        out["sensor_fault_detection_delay"] = hit[0] - t0
    if voting or det:
        after = [tgt for t, tgt in det if t >= t0 - 1e-9]
        out["sensor_fault_isolated"] = float(bool(after) and after[0] == tgt0)
    if all(c in result for c in ("x_hat", "y_hat", "psi_hat")):
        t_all = result.time
        t1 = math.inf if f0.end_time is None else float(f0.end_time)
        sel = win & (t_all >= t0 - 1e-9) & (t_all <= t1 + 1e-9)
        if sel.sum() >= 2:
            p = scenario.turret.position
            true = turret_offset(np.stack([result["x"][sel], result["y"][sel], result["psi"][sel]], -1), p)
            est = turret_offset(np.stack([result["x_hat"][sel], result["y_hat"][sel], result["psi_hat"][sel]], -1), p)
            e = np.hypot(*(np.asarray(true) - np.asarray(est)))
            if np.all(np.isfinite(e)):
                ts = t_all[sel]
                out["turret_error_fault_max"] = float(e.max())
                out["turret_error_fault_rms"] = math.sqrt(_tmean(ts, e * e))
    return out


def _mode_switches(result: Result) -> dict[str, float]:
    """``mode_switches`` — the controller's switches of mode set or gain-table row, or of the MPC's
    dead band between intact and damaged (events ``{"event": "mode switch"}`` of
    ``meta["controller_log"]``), absent when the controller keeps no log."""
    log = result.meta.get("controller_log")
    if log is None:
        return {}
    return {"mode_switches": sum(1 for e in log if isinstance(e, Mapping) and e.get("event") == "mode switch")}


def _scenario_of(system_or_scenario: Any) -> Any:
    """The scenario of a :class:`~tapm_opt.models.system.System`, or the argument itself (a
    scenario: lines, thrusters, limits, turret and riser are read from it)."""
    from ..config import Scenario

    if isinstance(system_or_scenario, Scenario):
        return system_or_scenario
    from ..models.system import System   # only for an argument that is not a scenario (CasADi)

    return system_or_scenario.scenario if isinstance(system_or_scenario, System) else system_or_scenario


def _compute(result: Result, scenario: Any, *, t_start: float, lp_window: float, delta_s: float,
             consequence_class: int, sfc: float, dnv_class1_common_factor: bool,
             require_setpoint: bool = True, sigma_window: float = SIGMA_WINDOW_DEFAULT,
             reliability: bool = True) -> dict[str, float]:
    scenario = _scenario_of(scenario)
    if consequence_class not in (1, 2):
        raise KpiError(f"consequence_class = {consequence_class!r} must be 1 or 2")
    if not (sfc >= 0 and math.isfinite(sfc)):
        raise KpiError(f"sfc = {sfc!r} kg/kWh must be a non-negative number")
    if not math.isfinite(delta_s):
        raise KpiError(f"delta_s = {delta_s!r} must be finite")
    for name, v in (("lp_window", lp_window), ("sigma_window", sigma_window)):
        try:
            ok = math.isfinite(float(v)) and float(v) > 0
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise KpiError(f"{name} = {v!r} s must be a positive number")
    t_all = result.time
    if len(t_all) < 2:
        raise KpiError(f"the result has {len(t_all)} sample(s); KPIs need at least two")
    if not math.isfinite(t_start) or t_start >= t_all[-1]:
        raise KpiError(f"t_start = {t_start!r} s must be a number below the end of the record ({t_all[-1]:g} s)")
    win = t_all >= t_start - 1e-9
    if win.sum() < 2:
        raise KpiError(f"fewer than two samples after t_start = {t_start:g} s")
    t = t_all[win]
    hold = _hold_weights(t)
    out: dict[str, float] = {"duration": float(t[-1] - t[0])}

    # offsets and heading
    # turret-referenced: the centre of turret relative to its field-zero-point position
    x = _channel(result, "x", "the offset KPIs", win)
    y = _channel(result, "y", "the offset KPIs", win)
    psi_o = _channel(result, "psi", "the offset KPIs", win)
    off = np.hypot(*turret_offset(np.stack([x, y, psi_o], axis=-1), scenario.turret.position))
    lim = scenario.limits
    out["offset_max"] = float(off.max())
    out["offset_mean"] = _tmean(t, off)
    out["offset_std"] = _tstd(t, off)
    out["time_outside_safe"] = float(np.sum(hold[off > lim.safe_radius])) if lim.safe_radius else 0.0
    out["time_outside_alert"] = float(np.sum(hold[off > lim.alert_radius])) if lim.alert_radius else 0.0
    psi = _channel(result, "psi", "heading_error_max", win)
    if require_setpoint or "psi_d" in result:
        psi_d = _channel(result, "psi_d", "heading_error_max", win)
    else:
        psi_d = np.zeros_like(psi)
    err = ssa(psi - psi_d)
    out["heading_error_max"] = float(np.degrees(np.abs(err).max()))

    # lines
    line_ids = [ln.id for ln in scenario.lines]
    for lid in line_ids:
        if f"T_fairlead[{lid}]" not in result:
            raise KpiError(f"result has no channel 'T_fairlead[{lid}]' (scenario line {lid!r}); "
                           f"channels are {', '.join(result.channels)}")
    breaks = break_times(result, line_ids)
    t_b1 = min(breaks.values(), default=math.inf)
    mbs_all = scenario.line_arrays["MBS"]
    mbs_std_all = scenario.line_arrays["MBS_std"]
    # the tension of an overload break, which falls between the logged samples; in the plant's
    # 'mbs' mode a line breaks at its MBS, which bounds the event's rounded figures from below
    floor = ({lid: float(v) for lid, v in zip(line_ids, mbs_all)}
             if result.meta.get("break_on_overload") == "mbs" else None)
    peaks = break_tensions(result, line_ids, floor)
    per: dict[str, dict[str, float]] = {k: {} for k in _LINE_QUANTITIES}
    eps = 1e-9 * max(1.0, abs(float(t[-1])))
    intact_all = t <= t_b1 + eps
    segments = (intact_all, ~intact_all)
    rel_cols: list[int] = []  # lines with a reliability index (MBS_std > 0, alive after t_start)
    tensions: dict[str, np.ndarray] = {}
    alive_of: dict[str, np.ndarray] = {}
    curves = line_curves(scenario)
    for j, lid in enumerate(line_ids):
        T = _channel(result, f"T_fairlead[{lid}]", f"the tension KPIs of line {lid}", win)
        mbs, mbs_std = float(mbs_all[j]), float(mbs_std_all[j])
        alive = t <= breaks.get(lid, math.inf) + eps  # the sample at the break time is logged before it
        if alive.sum() == 0:
            continue  # broken before t_start: no per-line KPIs
        tensions[lid], alive_of[lid] = T, alive
        intact = alive & intact_all
        damaged = alive & ~intact
        ta, Ta = t[alive], T[alive]
        # the line's own break (in the window, as the line is alive there) with the tension that broke it
        peak = peaks.get(lid, -math.inf)
        t_max = max(float(Ta.max()), peak)
        per["T_max"][lid] = t_max
        per["T_mean"][lid] = _tmean(ta, Ta)
        per["util_max"][lid] = t_max / mbs
        if Ta.size >= 2:
            c = curves[lid]
            per["fatigue_damage"][lid] = miner_damage(Ta, c.a_D, c.m, c.area)
        peak_intact = peak if breaks.get(lid, math.inf) <= t_b1 + eps else -math.inf
        if intact.any():
            per["dnv_uls"][lid] = _dnv_ratio(t[intact], T[intact], mbs, "ULS", consequence_class,
                                             dnv_class1_common_factor, peak_intact)
        if damaged.any():
            per["dnv_als"][lid] = _dnv_ratio(t[damaged], T[damaged], mbs, "ALS", consequence_class,
                                             dnv_class1_common_factor, peak if peak_intact == -math.inf else -math.inf)
        if mbs_std > 0 and reliability:
            rel_cols.append(j)
            traces = [reliability_index(t[seg], T[seg], mbs, mbs_std, window=lp_window)
                      for seg in (intact, damaged) if seg.sum() >= 2]
            if traces:
                per["delta_min_offline"][lid] = float(min(tr.delta.min() for tr in traces))
    if rel_cols:
        # causal index of every line at once, restarted at the first break; a line's values count
        # while it is alive
        ids = [line_ids[j] for j in rel_cols]
        runs, _ = causal_runs(t, np.column_stack([tensions[lid] for lid in ids]), mbs_all[rel_cols],
                              mbs_std_all[rel_cols], segments, np.stack([alive_of[lid] for lid in ids]),
                              names=ids, lp_window=lp_window, sigma_window=sigma_window)
        for lid, r in zip(ids, runs):
            if r:
                per["delta_min"][lid], per["delta_frac_below"][lid] = _run_stats(r, delta_s)
    if per["T_max"]:
        out["T_max"] = max(per["T_max"].values())
        out["util_max"] = max(per["util_max"].values())
    if per["delta_min"]:
        out["delta_min"] = min(per["delta_min"].values())
        out["delta_frac_below"] = max(per["delta_frac_below"].values())
    if per["delta_min_offline"]:
        out["delta_min_offline"] = min(per["delta_min_offline"].values())
    dmg = list(per["fatigue_damage"].values())
    if dmg:
        out["fatigue_damage_max"] = max(dmg)
        mean = sum(dmg) / len(dmg)
        if mean > 0:
            out["fatigue_damage_spread"] = max(dmg) / mean
    for ls in ("uls", "als"):
        r = per[f"dnv_{ls}"]
        if r:
            out[f"dnv_{ls}_max"] = max(r.values())
        out[f"dnv_{ls}_pass"] = int(sum(v <= 1.0 for v in r.values()))
        out[f"dnv_{ls}_fail"] = int(sum(v > 1.0 for v in r.values()))
    out["lines_broken"] = len(breaks)
    losses = buoy_loss_times(result)
    if losses:
        out["buoys_lost"] = len(losses)
    out.update(_detection(result, breaks, losses))
    out.update(_sensor_faults(result, scenario, win))
    out.update(_mode_switches(result))
    out.update(_current_estimation(result, scenario, t_start))

    # riser end angles and their reliability indices ([G] §2.2)
    riser = getattr(scenario, "riser", None)
    ends = [(end, ch, fld) for end, ch, fld in RISER_ENDS if ch in result]
    ang: dict[str, np.ndarray] = {}
    for end, ch, _ in ends:
        ang[end] = _channel(result, ch, f"the riser {end} angle KPIs", win)
        out[f"riser_{end}_angle_max_deg"] = float(np.degrees(ang[end].max()))
    if riser is not None and ends and reliability:
        r_t = np.array([float(getattr(riser, fld)) for _, _, fld in ends])
        s_t = np.array([float(getattr(riser, fld + "_std")) for _, _, fld in ends])
        for (_, _, fld), v, sd in zip(ends, r_t, s_t):
            if not (math.isfinite(v) and math.isfinite(sd) and sd > 0):
                raise KpiError(f"riser.{fld} = {v!r} rad with riser.{fld}_std = {sd!r} rad: the riser reliability "
                               "index needs a finite angle and a positive standard deviation")
        runs, worst = causal_runs(t, np.column_stack([ang[end] for end, _, _ in ends]), r_t, s_t, segments,
                                  np.ones((len(ends), len(t)), bool), names=[end for end, _, _ in ends],
                                  lp_window=lp_window, sigma_window=sigma_window)
        for (end, _, _), r in zip(ends, runs):
            if r:
                out[f"riser_delta_{end}_min"] = _run_stats(r, delta_s)[0]
        if all(runs):  # the worst end at each ready instant
            out["riser_delta_min"], out["riser_delta_frac_below"] = _run_stats(worst, delta_s)

    # low-frequency roll and pitch (channels of a plant with vessel.roll_pitch; docs/semi.md)
    for axis in ("roll", "pitch"):
        if axis in result:
            a = _channel(result, axis, f"the {axis} KPIs", win)
            out[f"{axis}_std_deg"] = float(np.degrees(a.std()))
            out[f"{axis}_max_deg"] = float(np.degrees(np.abs(a).max()))

    # thrust energy and fuel
    th_ids = [th.id for th in scenario.thrusters]
    if th_ids:
        P = np.column_stack([_channel(result, f"P[{i}]", "thrust_energy", win) for i in th_ids]).sum(axis=1)
        energy = float(np.trapezoid(P, t))
    else:
        energy = 0.0
    out["thrust_energy"] = energy
    out["thrust_power_mean"] = energy / out["duration"] if out["duration"] > 0 else 0.0
    out["fuel"] = energy / 3.6e6 * sfc

    # line-tension control ([AF] = seed line-tension-control-fem, Fig. 3): the thrusters' share of
    # the DP command, and the work the winches deliver hauling in
    ratio = _thrust_to_command(result, win, t)
    if ratio is not None:
        out["thrust_to_command_ratio"] = ratio
    if any(ln.winch_max_rate > 0 for ln in scenario.lines) and all(f"L[{ln.id}]" in result for ln in scenario.lines):
        out["winch_energy"] = _winch_energy(result, scenario, win, t)

    # controller diagnostics (whole run)
    diag = result.meta.get("diagnostics", {}) or {}
    for k in _DIAG_KEYS:
        v = diag.get(k)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
            out[k] = int(v) if _catalogue_kpi(k).kind == "count" else float(v)

    for k in _LINE_QUANTITIES:
        for lid, v in per[k].items():
            out[f"{k}[{lid}]"] = v
    return out


def _thrust_to_command(result: Result, win: np.ndarray, t: np.ndarray) -> float | None:
    """``∫ |tau_thr,xy| dt / ∫ |tau_c,xy| dt`` (trapezoid) of the delivered thrust and the DP
    command in {B}; None without the ``tau_cmd`` channels or with a zero command."""
    names = ("tau_cmd[X]", "tau_cmd[Y]", "tau_thr[X]", "tau_thr[Y]")
    if not all(n in result.channels for n in names):
        return None
    cx, cy, hx, hy = (_channel(result, n, "thrust_to_command_ratio", win) for n in names)
    den = float(np.trapezoid(np.hypot(cx, cy), t))
    if not den > 0:
        return None
    return float(np.trapezoid(np.hypot(hx, hy), t)) / den


def _winch_energy(result: Result, scenario: Any, win: np.ndarray, t: np.ndarray) -> float:
    """Work [J] the winches deliver hauling in, ``Σ_j ∫ max(-dL_j/dt, 0) T_j dt`` from the logged
    lengths ``L[<line>]`` and fairlead tensions (interval means); paying out costs nothing."""
    total = 0.0
    for ln in scenario.lines:
        if ln.winch_max_rate <= 0:
            continue
        L = _channel(result, f"L[{ln.id}]", "winch_energy", win)
        T = _channel(result, f"T_fairlead[{ln.id}]", "winch_energy", win)
        total += float(np.sum(np.maximum(-np.diff(L), 0.0) * 0.5 * (T[1:] + T[:-1])))
    return total


def case_kpis(result: Result, scenario: Any, *, t_start: float = 0.0, lp_window: float = LP_WINDOW_DEFAULT,
              sigma_window: float = SIGMA_WINDOW_DEFAULT, delta_s: float = DELTA_S_DEFAULT,
              consequence_class: int = 1, sfc: float = SFC_DEFAULT,
              dnv_class1_common_factor: bool = True) -> dict[str, float]:
    """All KPIs of one closed-loop run as a flat, JSON-serialisable ``{name: number}`` dict.

    Parameters
    ----------
    result : Result
        A closed-loop result (channels ``x, y, psi, psi_d, T_fairlead[<line>]`` for every scenario
        line, ``P[<thruster>]`` for every scenario thruster; ``riser_top_angle``,
        ``riser_bottom_angle`` [rad] (angle magnitudes) and ``meta["events"]``,
        ``meta["diagnostics"]`` when present).
    scenario : Scenario or System
        The scenario the result was run with (MBS, MBS_std, limits, line and thruster ids, the
        riser's critical angles), or a :class:`~tapm_opt.models.system.System` built from it
        (its ``scenario`` is read).
    t_start : float
        Samples before this time [s] are left out of every statistic (start-up transient);
        default 0. The solver statistics from ``meta["diagnostics"]`` always cover the whole run.
    lp_window : float
        Width [s] of the moving average defining the low-frequency tension and riser angle: trailing
        in the causal index, centred in the offline one (default 100).
    sigma_window : float
        Trailing window [s] of the causal index's wave-frequency sigma and up-crossing count, and its
        exposure period (default 600); the causal index is evaluated once it has filled.
    delta_s : float
        Reliability-index threshold for ``delta_frac_below`` (default 2).
    consequence_class : int
        DNV-OS-E301 consequence class, 1 (default) or 2.
    sfc : float
        Specific fuel consumption of the fuel proxy [kg/kWh] (default 0.2).
    dnv_class1_common_factor : bool
        Apply the class-1 common factor 1.3 on T_C,mean + T_C,dyn when T_C,mean > 2/3 T_C,dyn
        (DNV-OS-E301 2008, Ch. 2 Sec. 2 as transcribed; default on, as the standard requires).

    Returns
    -------
    dict
        Names, units and definitions in ``docs/kpis.md``; order of columns: :func:`kpi_order`.
        Every value is finite. Keys whose quantity does not exist for the case are left out
        (``dnv_als*`` without a line break, per-line keys of a line broken before ``t_start``,
        ``delta*`` of lines with MBS_std = 0, the causal ``delta_min``/``delta_frac_below`` of a
        line whose segments are all shorter than ``lp_window + sigma_window``, ``riser_*`` without
        the riser channels, ``riser_delta*`` without a scenario riser, solver statistics without
        an MPC).

    Raises
    ------
    KpiError
        A needed channel is missing or not finite, or an option is out of range.
    """
    return _compute(result, scenario, t_start=t_start, lp_window=lp_window, sigma_window=sigma_window,
                    delta_s=delta_s, consequence_class=consequence_class, sfc=sfc,
                    dnv_class1_common_factor=dnv_class1_common_factor)


def basic_kpis(result: Result, scenario: Any) -> dict[str, float]:
    """Offsets, heading error, tensions, thrust energy and solver statistics of one run
    (``scenario``: the Scenario or a System built from it, as in :func:`case_kpis`).

    The historical subset of :func:`case_kpis` (whole record): ``duration``, ``offset_max``/
    ``offset_mean``/``offset_std`` [m], ``time_outside_safe``/``time_outside_alert`` [s],
    ``heading_error_max`` [deg] (against ``psi_d`` when logged, else against 0), ``T_max`` [N],
    ``utilisation_max`` (= ``util_max``, T/MBS), ``thrust_energy`` [J], and the solver statistics
    when the result carries them.
    """
    k = _compute(result, scenario, t_start=float(result.time[0]) if len(result.time) else 0.0,
                 lp_window=LP_WINDOW_DEFAULT, delta_s=DELTA_S_DEFAULT, consequence_class=1, sfc=SFC_DEFAULT,
                 dnv_class1_common_factor=False, require_setpoint=False, reliability=False)
    keep = ("duration", "offset_max", "offset_mean", "offset_std", "time_outside_safe", "time_outside_alert",
            "heading_error_max", "T_max")
    out = {n: k[n] for n in keep if n in k}
    if "util_max" in k:
        out["utilisation_max"] = k["util_max"]
    out["thrust_energy"] = k["thrust_energy"]
    for n in ("solver_time_median", "solver_time_max", "solver_failures", "solver_fallbacks", "allocation_fallbacks"):
        if n in k:
            out[n] = float(k[n])
    return out


# -- tables ------------------------------------------------------------------------------------

def _row_parts(row: Mapping[str, Any]) -> tuple[Any, Any, dict, dict]:
    labels = dict(row.get("labels") or {})
    if "kpis" in row:
        kpis = dict(row.get("kpis") or {})
    else:
        kpis = {k: v for k, v in row.items() if k not in ("id", "name", "labels")}
    return row.get("id", ""), row.get("name", ""), labels, kpis


def _scalar_text(v: Any, float_text: Any, other_text: Any = str) -> str:
    """Text of a KPI value: empty for missing, booleans and integers as such, floats through
    ``float_text``, anything else through ``other_text``."""
    if v is None or (isinstance(v, str) and v == ""):
        return ""
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return float_text(float(v))
    return other_text(v)


def _table_float(f: float) -> str:
    if not math.isfinite(f):
        return str(f)
    if f == 0:
        return "0"
    if f.is_integer() and abs(f) < 1e6:
        return str(int(f))
    a = abs(f)
    return f"{f:.3e}" if (a >= 1e6 or a < 1e-3) else f"{f:.4g}"


def format_number(v: Any) -> str:
    """A KPI value for tables: 4 significant digits, integers as integers, empty for missing."""
    return _scalar_text(v, _table_float, lambda x: str(x).replace("|", "\\|").replace("\n", " "))


def _csv_value(v: Any) -> str:
    """A KPI value for CSV: floats at full precision (``repr``)."""
    return _scalar_text(v, repr)


def kpi_table(rows: Sequence[Mapping[str, Any]]) -> tuple[str, str]:
    """CSV text and Markdown text of one row per case.

    Each row is ``{"id", "name", "labels": {...}, "kpis": {...}}`` (or a flat dict: every key
    other than id, name and labels is a KPI). Columns: ``id``, ``name``, the labels (scenario,
    sea_state, controller, condition, seed, then any other label in order of appearance), then
    the union of the KPI names in :func:`kpi_order`. A KPI a case lacks is an empty cell. The
    CSV holds full precision (``repr``); the Markdown rounds to 4 significant digits and adds
    the unit to each KPI header.
    """
    parts = [_row_parts(r) for r in rows]
    label_cols = [c for c in _LABEL_ORDER if any(c in p[2] for p in parts)]
    for p in parts:
        for c in p[2]:
            if c not in label_cols:
                label_cols.append(c)
    kpi_cols = kpi_order(k for p in parts for k in p[3])
    header = ["id", "name", *label_cols, *kpi_cols]

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for rid, name, labels, kpis in parts:
        w.writerow([_csv_value(rid), _csv_value(name), *(_csv_value(labels.get(c)) for c in label_cols),
                    *(_csv_value(kpis.get(c)) for c in kpi_cols)])

    md_head = ["id", "name", *label_cols, *(f"{c} [{kpi_unit(c)}]" if kpi_unit(c) else c for c in kpi_cols)]
    lines = ["| " + " | ".join(md_head) + " |",
             "|" + "|".join(["---"] * (2 + len(label_cols)) + ["---:"] * len(kpi_cols)) + "|"]
    for rid, name, labels, kpis in parts:
        cells = [format_number(rid), format_number(name), *(format_number(labels.get(c)) for c in label_cols),
                 *(format_number(kpis.get(c)) for c in kpi_cols)]
        lines.append("| " + " | ".join(cells) + " |")
    return buf.getvalue(), "\n".join(lines) + "\n"
