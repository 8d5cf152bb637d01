"""Line-break (and buoy-loss) detection from the tension cells.

Two detectors, both fed by the estimators (``update(t, tensions, eta)``, latched, ``events``):

* :class:`TensionDropDetector` is the simplest detector a vessel with tension cells has: a line
  whose measured fairlead tension stays below ``fraction`` of its pretension (the design model's
  tension at the field zero point) for ``hold`` seconds is declared broken, and stays so. It needs
  no model of the vessel's motion: the fairlead tension of an intact catenary line cannot fall
  below the weight of the line hanging between the fairlead and the seabed (on fpso the slack side
  keeps at least 75 % of its pretension quasi-statically anywhere on the alert circle), while a
  broken line reads its cell's noise about zero.
* :class:`TensionResidualDetector` is the model-based statistical test of the survey's family (a)
  (§4.2.4, "residuals of the measured line tensions against the line model"): per line, the
  residual between the measured fairlead tension and the quasi-static catenary's at the
  estimator's low-frequency pose, standardised by a robust running estimate of its intact mean and
  standard deviation, and a one-sided CUSUM (Page) test for a downward shift of a design fraction
  of the predicted tension. It reacts to any loss of more than half that shift (a quarter of the
  line's tension by default), so also to a break below the fairlead, where the cell keeps reading
  the weight of the hanging line.

Detected breaks reach the setpoint layer and the controllers through ``Estimate.broken_lines``. On a
mooring of composite lines the residual detector also tests the loss of each buoy (its known shift
of its line's static tension, on the residual no pose error explains); a buoy found lost reaches
them through ``Estimate.lost_points``.

References
----------
E. S. Page, Continuous inspection schemes, Biometrika 41 (1954) 100-115.
G. Lorden, Procedures for reacting to a change in distribution, Ann. Math. Statist. 42 (1971)
1897-1908 (the CUSUM's mean time between false alarms is at least e^h).
G. V. Moustakides, Optimal stopping times for detecting changes in distributions, Ann. Statist.
14 (1986) 1379-1387 (the CUSUM is optimal for a known shift).
M. Basseville, I. V. Nikiforov, Detection of Abrupt Changes: Theory and Application, Prentice
Hall, 1993, §2.2 (CUSUM), §2.4 (GLR), §5.2 (mean delay).
P. J. Huber, Robust Statistics, Wiley, 1981 (the clipped running estimates).
Z. Ren et al., A survey on modeling and control of thruster-assisted position mooring systems,
§4.2.4 (fault detection and isolation of line breaks), §4.4 (loss of a buoyancy element).
E. Y. Chow, A. S. Willsky, Analytical redundancy and the design of robust failure detection
systems, IEEE Trans. Automat. Contr. 29 (1984) 603-614 (parity relations).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import TapmError
from ..models.characteristics import tension_source

__all__ = ["TensionDropDetector", "TensionResidualDetector", "DetectionError", "FALSE_ALARM_TIME_DEFAULT",
           "BUOY_CONFIRMATION_TIME"]


class DetectionError(TapmError, ValueError):
    """Bad detector settings or measurements."""


class TensionDropDetector:
    """Declares a line broken when its measured tension stays below ``fraction`` x pretension.

    Parameters
    ----------
    model : MooringModel
        The intact design model (its line ids and its tensions at eta = 0).
    fraction : float
        Threshold as a fraction of each line's pretension, in (0, 1) [-].
    hold : float
        Time the tension must stay below the threshold [s], >= 0.
    """

    def __init__(self, model: Any, *, fraction: float = 0.2, hold: float = 5.0):
        if not (isinstance(fraction, (int, float)) and 0 < fraction < 1):
            raise DetectionError(f"fraction = {fraction!r} must be a number in (0, 1)")
        if not (isinstance(hold, (int, float)) and math.isfinite(hold) and hold >= 0):
            raise DetectionError(f"hold = {hold!r} s must be a number >= 0")
        self.line_ids = tuple(model.line_ids)
        self.threshold = fraction * np.asarray(model.tensions(np.zeros(3)), float)
        self.fraction, self.hold = float(fraction), float(hold)
        self.reset()

    def reset(self) -> None:
        self._since = np.full(len(self.line_ids), np.nan)   # time each line fell below, NaN if above
        self.broken: frozenset[str] = frozenset()
        self.events: list[dict] = []

    def update(self, t: float, tensions: Any, eta: Any = None) -> frozenset[str]:
        """Feed the measured fairlead tensions (n,) [N] at time ``t`` [s]; returns the lines known
        broken so far. ``eta`` (the estimator's LF pose) is not used: this test needs no model of
        the motion."""
        T = np.asarray(tensions, float)
        if T.shape != self._since.shape:
            raise DetectionError(f"tensions has shape {T.shape}, expected ({len(self.line_ids)},) for lines "
                                 f"{list(self.line_ids)}")
        if not np.all(np.isfinite(T)):
            i = int(np.flatnonzero(~np.isfinite(T))[0])
            raise DetectionError(f"tensions[{i}] (line {self.line_ids[i]!r}) = {float(T[i])!r} N must be finite")
        low = T < self.threshold
        self._since = np.where(low, np.where(np.isnan(self._since), t, self._since), np.nan)
        new = [lid for lid, s in zip(self.line_ids, self._since)
               if not math.isnan(s) and t - s >= self.hold and lid not in self.broken]
        if new:
            self.broken = self.broken | frozenset(new)
            self.events += [{"t": float(t), "line": lid, "event": "line break detected"} for lid in new]
        return self.broken


# ------------------------------------------------------------------------------------------
# model-based test: tension residuals against the line model, CUSUM
# ------------------------------------------------------------------------------------------

#: Default design mean time between false alarms of a whole :class:`TensionResidualDetector`
#: (all its lines together) [s]: one year.
FALSE_ALARM_TIME_DEFAULT = 365.25 * 86400.0
#: Default time a buoy loss must last before :class:`TensionResidualDetector` declares it [s]
#: (``buoy_min_samples`` = this x ``rate``, rounded up): the loss shifts the static part of the
#: line's tension by a fraction of what a break does, so its hypothesis is confirmed over longer
#: than a wave group's tension swings (docs/estimation.md, "Buoy loss").
BUOY_CONFIRMATION_TIME = 30.0
#: Pose steps (x [m], y [m], psi [rad]) of the finite differences of the predicted tensions that
#: span the residuals a pose error explains (the buoy-loss test's parity space).
_POSE_STEPS = (0.5, 0.5, 0.005)
#: Default time a break must last before :class:`TensionResidualDetector` declares it [s]
#: (``min_samples`` = this x ``rate``, rounded up). An intact line's wave-frequency tension dips
#: below the test's reference level (a quarter of its tension) for up to 10 consecutive seconds
#: in fpso's extreme sea (Hs 15 m, Tp 16 s; 3 h with heading chasing, PID and linear MPC behind the
#: EKF), where the hull's heave and pitch slacken a line at its fairlead (six-degree-of-freedom
#: wave motion); with 8 samples, the earlier default, they raised 6-8 false alarms in each 3 h run
#: there, and the storm's dips (6 s) came within two samples of the threshold. 16 s, about the
#: extreme sea's peak period, leaves 6 samples of margin there and keeps every break's delay
#: well inside 30 s (docs/estimation.md).
BREAK_CONFIRMATION_TIME = 16.0


def _huber_beta(c: float) -> float:
    """E[min(z^2, c^2)] for z ~ N(0, 1): the consistency factor of a variance estimated from
    deviations clipped at c standard deviations."""
    phi = math.exp(-0.5 * c * c) / math.sqrt(2.0 * math.pi)
    tail = 0.5 * math.erfc(c / math.sqrt(2.0))
    return (1.0 - 2.0 * tail) - 2.0 * c * phi + 2.0 * c * c * tail


def _hermite(T0, T1, k0, k1, t):
    """Cubic Hermite interpolant through (0, T0, slope k0) and (1, T1, slope k1) at t in [0, 1]
    (slopes per unit of t)."""
    d = T1 - T0
    return T0 + t * (k0 + t * ((3.0 * d - 2.0 * k0 - k1) + t * (k0 + k1 - 2.0 * d)))


def _predict_py(eta, par, geo, tab, out):  # pragma: no cover - compiled by numba
    """Tabulated fairlead tensions of the lines of ``geo`` at pose ``eta`` into ``out`` (n,).

    ``par`` = (x_cot, y_cot, turret angle, free turret 1/0); ``geo`` (n, 8) = anchor x, y, fairlead
    in {T} x, y, table start distance [m], table spacing [m], first node of the line's table in
    ``tab``, number of intervals; ``tab`` (m, 2) = TF [N], dTF/dXF [N/m] at the nodes. Same
    geometry as ``MooringModel.spans`` (eq. 5). Returns 0, or 1 when a line's distance lies outside
    its table (``out`` undefined).
    """
    x, y, psi = eta[0], eta[1], eta[2]
    c, s = math.cos(psi), math.sin(psi)
    cx = c * par[0] - s * par[1]
    cy = s * par[0] + c * par[1]
    ang = par[2] if par[3] != 0.0 else psi + par[2]
    ct, st = math.cos(ang), math.sin(ang)
    for i in range(geo.shape[0]):
        fx = x + cx + (ct * geo[i, 2] - st * geo[i, 3])
        fy = y + cy + (st * geo[i, 2] + ct * geo[i, 3])
        h = geo[i, 5]
        u = (math.hypot(fx - geo[i, 0], fy - geo[i, 1]) - geo[i, 4]) / h
        nint = int(geo[i, 7])
        if not (u >= 0.0 and u <= nint):
            return 1
        a = int(u)
        if a >= nint:
            a = nint - 1
        k = int(geo[i, 6]) + a
        t = u - a
        T0 = tab[k, 0]
        d = tab[k + 1, 0] - T0
        k0 = tab[k, 1] * h
        k1 = tab[k + 1, 1] * h
        out[i] = T0 + t * (k0 + t * ((3.0 * d - 2.0 * k0 - k1) + t * (k0 + k1 - 2.0 * d)))
    return 0


def _cusum_py(T, Tp, idx, st, cfg, busy):  # pragma: no cover - compiled by numba
    """One sample of :class:`TensionResidualDetector`'s test, in place.

    ``T`` (n,) measured tensions [N] of every line; ``Tp`` (m,) predicted tensions of the lines
    still tested, whose rows in ``st`` are ``idx`` (m,); ``st`` (n, 8) per line: statistic g, bias
    b [N], scale s [N], scale floor [N], run sum of -z, run length, peak g, deepest drop;
    ``cfg`` = (shift, largest step, weight of the running estimates, clip, Huber factor, adapt
    1/0, threshold); ``busy`` (n,): 1 where another statistic of the line (a point-loss
    hypothesis, :func:`_points_py`) is building an alarm, which freezes the line's running
    estimates too. Returns the row of the line isolated at this sample, or -1.
    """
    shift, step_max, a, clip, beta, adapt, thr = cfg[0], cfg[1], cfg[2], cfg[3], cfg[4], cfg[5], cfg[6]
    best = -1
    best_shift = -math.inf
    for q in range(idx.shape[0]):
        i = idx[q]
        tp = Tp[q]
        dev = T[i] - tp - st[i, 1]
        s = st[i, 2]
        D = shift * tp if tp > 0.0 else 0.0
        d = D / s
        z = dev / s
        llr = d * (-z - 0.5 * d)
        if llr > step_max:
            llr = step_max
        g_old = st[i, 0]
        g = g_old + llr
        if g < 0.0:
            g = 0.0
        st[i, 0] = g
        if g > st[i, 6]:
            st[i, 6] = g
        if D > 0.0 and -dev / D > st[i, 7]:
            st[i, 7] = -dev / D
        if g > 0.0:
            if g_old > 0.0:
                st[i, 4] -= z
                st[i, 5] += 1.0
            else:
                st[i, 4] = -z
                st[i, 5] = 1.0
        else:
            st[i, 4] = 0.0
            st[i, 5] = 0.0
            if adapt != 0.0 and busy[i] == 0.0:  # the running estimates move only while no alarm is building
                lim = clip * s
                dc = dev if dev < lim else lim
                if dc < -lim:
                    dc = -lim
                st[i, 1] += a * dc
                v = (1.0 - a) * s * s + a * min(dev * dev, lim * lim) / beta
                st[i, 2] = max(math.sqrt(v), st[i, 3])
        if g >= thr * (1.0 - 1e-12) and st[i, 4] / st[i, 5] > best_shift:
            best = i
            best_shift = st[i, 4] / st[i, 5]
    return best


def _points_py(z, d, rows, sp, busy, cfg):  # pragma: no cover - compiled by numba
    """One sample of the buoy-loss hypotheses of :class:`TensionResidualDetector`, in place,
    before :func:`_cusum_py` (whose running estimates of the lines they freeze).

    Hypothesis q is about the line of row ``rows[q]``; ``z[q]`` is that line's standardised
    parity residual and ``d[q]`` the shift of it the hypothesis predicts (signed, in standard
    deviations; 0 where the hypothesis is not tested at this sample); ``sp`` (k, 6) per
    hypothesis: statistic g, run sum of sign(d) z, run length, peak g, largest fraction of d
    reached, unused; ``busy`` (n,) is set to 1 on the lines with a statistic above zero; ``cfg`` =
    (largest step, threshold). Returns the hypothesis isolated at this sample (the largest mean
    sign(d) z over its run among those at the threshold), or -1.
    """
    step_max, thr = cfg[0], cfg[1]
    best = -1
    best_shift = -math.inf
    for q in range(rows.shape[0]):
        dq = d[q]
        zq = z[q]
        llr = dq * (zq - 0.5 * dq)
        if llr > step_max:
            llr = step_max
        g_old = sp[q, 0]
        g = g_old + llr
        if g < 0.0:
            g = 0.0
        sp[q, 0] = g
        if g > sp[q, 3]:
            sp[q, 3] = g
        sz = zq if dq >= 0.0 else -zq
        if dq != 0.0 and zq / dq > sp[q, 4]:
            sp[q, 4] = zq / dq
        if g > 0.0:
            busy[rows[q]] = 1.0
            if g_old > 0.0:
                sp[q, 1] += sz
                sp[q, 2] += 1.0
            else:
                sp[q, 1] = sz
                sp[q, 2] = 1.0
        else:
            sp[q, 1] = 0.0
            sp[q, 2] = 0.0
        if g >= thr * (1.0 - 1e-12) and sp[q, 1] / sp[q, 2] > best_shift:
            best = q
            best_shift = sp[q, 1] / sp[q, 2]
    return best


_KERNELS = None


def _kernels():
    """(predict, cusum, points): :func:`_predict_py`, :func:`_cusum_py` and :func:`_points_py`
    compiled by numba (cached on disk when possible), or the Python functions themselves without
    numba. Compiled on first use."""
    global _KERNELS
    if _KERNELS is None:
        from .._jit import jit

        _KERNELS = (jit(_predict_py), jit(_cusum_py), jit(_points_py))
    return _KERNELS


#: The tension tables built in this process, by line, tolerance, range and scale (a table is a
#: function of these alone): the detectors of many runs on one scenario (a tuning study's trials)
#: build each once. At most :data:`_PROCESS_TABLES_MAX`, the oldest dropped first.
_PROCESS_TABLES: dict = {}
_PROCESS_TABLES_MAX = 64


class _TensionTable:
    """Fairlead tensions ``TF`` [N] of a model's lines at a pose, from tabulated characteristics.

    The same elastic catenary as :meth:`MooringModel.tensions
    <tapm_opt.models.mooring.MooringModel.tensions>` (:func:`tapm_opt.models.catenary.solve`),
    tabulated once per distinct line configuration (ZF, L, EA, w, CB, h_A) as ``TF`` against the
    horizontal anchor–fairlead distance ``XF``: a cubic Hermite interpolant through the exact
    ``TF`` and ``dTF/dXF = (HF dHF/dXF + VF dVF/dXF) / TF`` on a uniform grid, halved until it
    matches the catenary within ``rtol * max(TF, T_ref)`` at a quarter, half and three quarters of
    every interval (``T_ref``: the largest pretension of the configuration's lines). The grid covers
    every distance a line takes with the body origin up to ``max_offset`` [m] from the field zero
    point at any heading (default 30 % of the deepest seabed below the fairleads, as
    :class:`~tapm_opt.models.characteristics.TabulatedMooringLoad`); beyond, the exact
    ``model.tensions`` answers (:attr:`exact_calls` counts those). The geometry is the model's
    (eq. 5, the same operations as ``model.spans``), evaluated by a compiled kernel. ``tables`` is a
    cache of configuration tables shared between models (the reduced models of a detector reuse
    the intact model's tables: their distances lie within them).
    """

    def __init__(self, model: Any, *, max_offset: float | None = None, rtol: float = 1e-6,
                 tables: dict | None = None):
        self.model = model
        self.exact_calls = 0
        tables = {} if tables is None else tables
        eta0 = np.zeros(3)
        _, _, XF0 = model.spans(eta0)
        T0 = np.asarray(model.tensions(eta0), float)
        if max_offset is None:
            max_offset = 0.3 * float(np.max(model.ZF + model.h_A))
        reach = (float(max_offset) + 2.0 * float(np.hypot(*model.p_cot_B))
                 + 2.0 * np.hypot(model.p_T[:, 0], model.p_T[:, 1]))
        keys = [model.line_key(i) for i in range(model.n_lines)]
        n = len(keys)
        geo = np.zeros((n, 8))
        geo[:, 0:2] = model.anchors
        geo[:, 2:4] = model.p_T
        parts, start = [], 0
        for key in dict.fromkeys(keys):
            mine = np.array([k == key for k in keys])
            tkey = (key, rtol)
            if tkey not in tables:
                a = max(float(np.min(XF0[mine] - reach[mine])), 0.0)
                b = float(np.max(XF0[mine] + reach[mine]))
                ZF, L, EA, w = key[:4]
                if not math.isfinite(EA):
                    b = min(b, math.sqrt(max(L * L - ZF * ZF, 0.0)) * (1.0 - 1e-9))
                T_ref = float(np.max(T0[mine])) or w * L or 1.0
                pkey = (key, rtol, a, b, T_ref)
                tab = _PROCESS_TABLES.get(pkey)
                if tab is None:
                    i0 = int(np.argmax(mine))
                    src = model.line_solver(i0)
                    if model.composite and model.composite[i0] is not None:
                        # a composite line's TF(XF) has kinks where a joint meets the seabed, which a
                        # uniform grid resolves only with many nodes: read those from the adaptive
                        # table of the load evaluator (node pairs at every regime change, 1e-9)
                        src = tension_source(src, a, b, T_ref)
                    tab = self._table(src, a, b, rtol, T_ref)
                    for arr in tab[2:]:
                        arr.flags.writeable = False
                    if len(_PROCESS_TABLES) >= _PROCESS_TABLES_MAX:
                        _PROCESS_TABLES.pop(next(iter(_PROCESS_TABLES)))
                    _PROCESS_TABLES[pkey] = tab
                tables[tkey] = tab
            x0, dx, T, K = tables[tkey]
            geo[mine, 4:8] = (x0, dx, start, T.size - 1)
            parts.append(np.column_stack([T, K]))
            start += T.size
        self._geo = np.ascontiguousarray(geo)
        self._tab = np.ascontiguousarray(np.concatenate(parts))
        self._par = np.array([model.p_cot_B[0], model.p_cot_B[1], model.turret_angle,
                              1.0 if model.turret_mode == "free" else 0.0])
        self._k = _kernels()[0]
        self._out = np.empty(n)

    @staticmethod
    def _table(solve, a: float, b: float, rtol: float, T_ref: float, max_nodes: int = 1 << 18):
        """(x0 [m], dx [m], TF nodes [N], dTF/dXF nodes [N/m]) of a uniform grid over [a, b] fine
        enough (class docstring); a table that reaches ``max_nodes`` is kept as it is."""
        def tf(x):
            s = solve(x)
            return s.TF, s.dTF_dXF

        if not b > a:
            b = a + 1.0
        m = 256
        while True:
            X = np.linspace(a, b, m + 1)
            dx = (b - a) / m
            T, K = tf(X)
            worst = 0.0
            for q in (0.25, 0.5, 0.75):
                Tq, _ = tf(X[:-1] + q * dx)
                est = _hermite(T[:-1], T[1:], K[:-1] * dx, K[1:] * dx, q)
                worst = max(worst, float(np.max(np.abs(est - Tq) / (rtol * np.maximum(Tq, T_ref)))))
            if worst <= 1.0 or 2 * m + 1 > max_nodes:
                return a, dx, T, K
            m *= 2

    def __call__(self, eta: np.ndarray) -> np.ndarray:
        """``TF`` (n,) [N] at the pose ``eta`` (a float64 (3,) array of finite numbers, checked
        by the caller); the array is reused by the next call."""
        if self._k(eta, self._par, self._geo, self._tab, self._out) != 0:
            self.exact_calls += 1
            self._out[:] = self.model.tensions(eta)
        return self._out


class TensionResidualDetector:
    """Line-break detection and isolation by a CUSUM test of the tension residuals (survey §4.2.4,
    family (a); module references).

    Residual of line i at each new tension sample k (the cells sample and hold at ``rate``)::

        r_i = T_meas,i - T_model,i(eta_hat)

    with ``T_model`` the quasi-static catenary's fairlead tension of the line at the estimator's
    latest low-frequency pose ``eta_hat`` (body origin, {E}; from a tabulated characteristic of
    :meth:`MooringModel.tensions <tapm_opt.models.mooring.MooringModel.tensions>`, within 1e-6 of the
    line's tension or pretension). While the line is intact ``r_i`` is the cell noise
    (``noise_rel`` x MBS), the wave-frequency dynamic tension, the error of the low-pass pose (it
    lags the LF motion by ~13 s) and the mean difference between the dynamic line and the
    quasi-static catenary (current drag on the line); on fpso in the design storm its mean is
    within +-36 kN and its standard deviation 36-88 kN per line (3.3 MN pretension). A broken line
    reads its cell's noise about zero (a break at the fairlead) or the weight of the hanging line
    (a break further down; on fpso ``w x 982 m`` = 1.3 MN), so the residual falls by 50-100 % of
    ``T_model``.

    Standardisation: ``z_i = (r_i - b_i) / s_i`` with ``b_i``, ``s_i`` robust running estimates of
    the intact residual's mean and standard deviation (``adapt=True``): exponentially weighted
    (time constant ``tau``) means of the residual and of its squared deviation, each deviation
    clipped at ``clip`` x ``s_i`` (Huber; the squared one divided by E[min(z^2, clip^2)] so that
    ``s_i`` is unbiased for Gaussian residuals), started at ``b_i = 0`` and the design value
    ``s_i = sqrt((noise_rel MBS_i)^2 + (dynamic_rel T0_i)^2)`` (``T0_i``: pretension at the field
    zero point), never below the cell noise ``noise_rel MBS_i``. The estimates of a line are frozen
    while its test statistic is above zero (an alarm building), so a break is not learnt as the new
    normal. ``adapt=False``: ``b_i = 0`` and ``s_i`` the design value throughout.

    Test: Page's one-sided CUSUM of the log-likelihood ratio of "the mean residual fell by
    ``Delta_i = shift x T_model,i``" against "zero mean", Gaussian with standard deviation
    ``s_i``::

        l_i = d_i (-z_i - d_i / 2),   d_i = Delta_i / s_i
        g_i <- max(0, g_i + min(l_i, h / min_samples)),   alarm when g_i >= h

    ``l_i`` is positive only when the residual is more than ``Delta_i / 2`` below its mean, so an
    intact line whose residual stays above ``-Delta_i / 2`` (a quarter of its tension by default)
    never accumulates, whatever ``s_i``; every loss larger than that is detected. Each sample adds
    at most ``h / min_samples`` (which only lowers the statistic, so the false-alarm bound below
    still holds): at least ``min_samples`` samples must confirm a break, and a single spike of a
    cell cannot declare one.

    Threshold: ``h = ln(n_lines x false_alarm_time x rate)``. For independent residuals that follow
    the intact model, the CUSUM's mean number of samples between false alarms is at least ``e^h``
    (Lorden 1971), so the whole detector's mean time between false alarms is at least
    ``false_alarm_time`` [s] (default one year: h = 19.75 for fpso's 12 lines at 1 Hz, about 3000
    times the 3 h of a storm). The real residual is not independent (wave groups,
    the LF pose error) nor exactly Gaussian; what protects against that is the reference level
    ``Delta_i / 2``, below the intact residuals of fpso's calm and normal seas, and the
    confirmation over ``min_samples`` samples, longer than an intact line's wave-frequency dips
    below the reference in its storm (up to 6 s) and extreme sea (up to 10 s) with the hull's heave,
    roll and pitch at the fairleads (:attr:`worst_drop` reports how deep they went;
    docs/estimation.md gives the figures). Expected delay of a loss of ``D_i >= Delta_i / 2``:
    about ``h / min(d_i (D_i / s_i - d_i / 2), h / min_samples)`` samples (Basseville & Nikiforov §5.2),
    i.e. ``min_samples`` samples for a break on fpso in any of its sea states.

    Why CUSUM and not a GLR: the post-break level is known within a factor of two (zero or the
    hanging weight), so the test for the smallest shift of interest is the optimal one
    (Lorden; Moustakides 1986) and detects larger shifts faster; it is recursive (two numbers per
    line per sample) where the GLR maximises over a window of change times and shift sizes.

    Isolation: the line whose statistic crosses ``h``; when several cross at the same sample, the
    one with the largest normalised shift, the mean of ``-z_i`` since its statistic last left zero
    (the maximum-likelihood shift in units of ``s_i``); the others are declared at the next samples
    if they are still above ``h``. Latched: a detected line stays broken until :meth:`reset`, leaves
    the test, and the predictions of the remaining lines come from ``model.without(broken)``.

    Buoy loss (``buoys=True``, on a model with composite lines): one more hypothesis per buoy of
    the model (:attr:`MooringModel.buoys <tapm_opt.models.mooring.MooringModel.buoys>`), "the buoy
    at joint j of line i came off". Its predicted shift of line i's residual is known at every pose,
    ``D = T_i without the buoy (eta_hat) - T_model,i(eta_hat)`` (the quasi-static line with that
    point's weight 0, tabulated as the model's lines are); it raises the static tension where the
    buoy held up the line below the fairlead (fpso as chain-wire-chain, a 353 kN buoy 100 m below
    the fairlead: +320 kN, 13 %; at the bottom joint: +50 kN at rest, -6 to +250 kN over the
    storm's offsets), where a break drops it to the hanging weight or zero. The shift is small
    against a pose error's: in the storm the intact residuals' slow part is one pattern over the
    lines (90 % of its variance), the tensions' response to an error of ``eta_hat``. So the
    hypotheses test the *parity residual*: the standardised residuals ``(r_i - b_i) / s_i`` of the
    lines still tested less their least-squares fit by the columns of ``J = dT_model/d eta / s``
    (finite differences of the table), the part no pose error explains (Chow & Willsky 1984).
    A shift of line i alone keeps ``sqrt(1 - P_ii)`` of itself there (``P`` the projector on J's
    columns; about 0.87 with 12 lines), so with ``z_q`` line i's parity residual over that factor
    and ``d_q = sqrt(1 - P_ii) D / s_i``::

        l_q = d_q (z_q - d_q / 2),   g_q <- max(0, g_q + min(l_q, h / buoy_min_samples))

    the CUSUM of the known signed shift (l_q grows only while the residual is past half the
    predicted shift in its direction). Where ``|d_q| < buoy_shift_min`` (a shift below half the
    residual's scale at this pose by default) the sample is no evidence either way (``l_q = 0``):
    such a shift cannot be told from the model's error. ``buoy_min_samples`` (``BUOY_CONFIRMATION_TIME``
    = 30 s x ``rate``) samples at least confirm a loss: the static part of the tension is tested,
    not its wave-frequency swings. The threshold counts every statistic: ``h = ln((n_lines +
    n_buoys) x false_alarm_time x rate)``. While a hypothesis' statistic is above zero its line's
    running estimates are frozen, as for a break.

    Isolation of a buoy loss: the hypothesis whose statistic crosses ``h`` (the largest mean of
    ``sign(d_q) z_q`` over its run when several do). When a break test and a buoy hypothesis cross
    at the same sample: on different lines the larger normalised shift, as between lines; on the
    same line the one the residual fits better (the distance of the run's mean residual from the
    predicted ``D / s_i`` of the buoy against its distance past ``-Delta_i / s_i`` for the break;
    a tie goes to the break). A buoy found lost is latched in :attr:`lost_points`, logged
    ``{"t", "line", "joint", "event": "buoy loss detected", "statistic"}``, and its line is
    predicted from ``model.damaged(broken, lost_points)`` from then on (its other buoys' hypotheses
    start again against that); a line found broken drops its buoys' hypotheses.

    Before the estimator's first pose (``eta`` None) there is no test: :meth:`update` only checks
    the measurement and returns the lines already known broken.

    Parameters
    ----------
    model : MooringModel
        The intact design model (its lines, tensions at a pose, MBS).
    shift : float
        Design shift ``Delta_i / T_model,i`` of a break, in (0, 1] [-] (default 0.5: the smallest
        loss of a break anywhere along an fpso line, 60 % at pretension, with margin).
    false_alarm_time : float
        Design mean time between false alarms of the whole detector [s], > 0 (sets ``h``).
    rate : float
        Tension-cell sampling rate [Hz], > 0: the statistics advance at most once per ``1 / rate``
        (a held sample is not counted twice when the control step is shorter).
    min_samples : int or None
        Samples a break must last at least, >= 1 (None: ``BREAK_CONFIRMATION_TIME`` x ``rate``,
        rounded up: 16 at 1 Hz).
    noise_rel : float
        Tension-cell noise, standard deviation as a fraction of each line's MBS, > 0 (the
        scenario's ``sensors.tension_std_rel``, default 0.002).
    dynamic_rel : float
        Design standard deviation of the rest of the intact residual (dynamic tension, pose error)
        as a fraction of each line's pretension, >= 0: the start of ``s_i`` (and all of it with
        ``adapt=False``).
    adapt : bool
        Estimate ``b_i`` and ``s_i`` on-line (above), or keep ``b_i = 0`` and the design value.
    tau : float
        Time constant of the running estimates [s], > 0.
    clip : float
        Clipping of the deviations in the running estimates, in standard deviations, > 0.
    buoys : bool
        Test a buoy-loss hypothesis for every buoy of the model (above); False: breaks only.
    buoy_min_samples : int or None
        Samples a buoy loss must last at least, >= 1 (None: ``BUOY_CONFIRMATION_TIME`` x ``rate``,
        rounded up: 30 at 1 Hz).
    buoy_shift_min : float
        Smallest predicted shift of a buoy loss tested, in standard deviations of the parity
        residual, >= 0 (default 0.5).

    Attributes
    ----------
    line_ids : tuple of str
    buoys : tuple of (str, int)
        The buoy-loss hypotheses, (line id, joint).
    threshold : float
        ``h`` [-] (log-likelihood units).
    broken : frozenset of str
        Lines detected broken.
    lost_points : frozenset of (str, int)
        Buoys detected lost, (line id, joint).
    buoy_statistics : dict
        Per buoy hypothesis its statistic, peak and largest fraction of the predicted shift reached.
    events : list of dict
        ``{"t" [s], "line", "event": "line break detected", "statistic": g_i at the alarm}`` and
        ``{"t", "line", "joint", "event": "buoy loss detected", "statistic"}``.
    statistic, bias, sigma : ndarray (n,)
        ``g_i`` [-], ``b_i`` [N], ``s_i`` [N] of every line of ``model`` (the values at its
        detection for a broken line).
    peak : ndarray (n,)
        Largest ``g_i`` so far [-].
    worst_drop : ndarray (n,)
        Largest ``-(r_i - b_i) / Delta_i`` so far [-]: the deepest residual of the line relative
        to the design shift; above 0.5 the statistic grows (NaN before the first test).
    samples : int
        Tension samples tested so far.
    """

    def __init__(self, model: Any, *, shift: float = 0.5, false_alarm_time: float = FALSE_ALARM_TIME_DEFAULT,
                 rate: float = 1.0, min_samples: int | None = None, noise_rel: float = 0.002,
                 dynamic_rel: float = 0.02, adapt: bool = True, tau: float = 600.0, clip: float = 3.0,
                 buoys: bool = True, buoy_min_samples: int | None = None, buoy_shift_min: float = 0.5):
        def num(name, v, lo, hi=math.inf, *, lo_ok=False, unit=""):
            ok = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and \
                math.isfinite(v) and (v >= lo if lo_ok else v > lo) and v <= hi
            if not ok:
                rng = f"{'>=' if lo_ok else '>'} {lo:g}" + ("" if hi == math.inf else f" and <= {hi:g}")
                raise DetectionError(f"{name} = {v!r}{unit} must be a finite number {rng}")
            return float(v)

        self.shift = num("shift", shift, 0.0, 1.0)
        self.false_alarm_time = num("false_alarm_time", false_alarm_time, 0.0, unit=" s")
        self.rate = num("rate", rate, 0.0, unit=" Hz")
        if min_samples is None:
            min_samples = max(1, math.ceil(BREAK_CONFIRMATION_TIME * self.rate - 1e-9))
        if not (isinstance(min_samples, (int, np.integer)) and not isinstance(min_samples, bool) and min_samples >= 1):
            raise DetectionError(f"min_samples = {min_samples!r} must be an integer >= 1 or None")
        self.min_samples = int(min_samples)
        self.noise_rel = num("noise_rel", noise_rel, 0.0, 1.0)
        self.dynamic_rel = num("dynamic_rel", dynamic_rel, 0.0, 1.0, lo_ok=True)
        if not isinstance(adapt, (bool, np.bool_)):
            raise DetectionError(f"adapt = {adapt!r} must be True or False")
        self.adapt = bool(adapt)
        self.tau = num("tau", tau, 0.0, unit=" s")
        self.clip = num("clip", clip, 0.0)
        if not isinstance(buoys, (bool, np.bool_)):
            raise DetectionError(f"buoys = {buoys!r} must be True or False")
        if buoy_min_samples is None:
            buoy_min_samples = max(1, math.ceil(BUOY_CONFIRMATION_TIME * self.rate - 1e-9))
        if not (isinstance(buoy_min_samples, (int, np.integer)) and not isinstance(buoy_min_samples, bool)
                and buoy_min_samples >= 1):
            raise DetectionError(f"buoy_min_samples = {buoy_min_samples!r} must be an integer >= 1 or None")
        self.buoy_min_samples = int(buoy_min_samples)
        self.buoy_shift_min = num("buoy_shift_min", buoy_shift_min, 0.0, lo_ok=True)
        self.model = model
        self.line_ids = tuple(model.line_ids)
        #: The buoy-loss hypotheses tested, (line id, joint): every buoy of the model (``buoys``).
        self.buoys: tuple[tuple[str, int], ...] = tuple(getattr(model, "buoys", ())) if buoys else ()
        n = len(self.line_ids)
        n_stat = n + len(self.buoys)
        h = math.log(n_stat * self.false_alarm_time * self.rate)
        if not h > 0:
            raise DetectionError(f"false_alarm_time = {false_alarm_time!r} s gives the threshold h = ln(n_tests x "
                                 f"false_alarm_time x rate) = {h:.3g} <= 0: it must exceed one sample per test")
        self.threshold = h
        self._cfg = np.array([self.shift, h / self.min_samples, min(1.0 / (self.rate * self.tau), 1.0), self.clip,
                              _huber_beta(self.clip), 1.0 if self.adapt else 0.0, h])
        self._cfg_points = np.array([h / self.buoy_min_samples, h])
        self._tables: dict = {}
        self._intact_table = _TensionTable(model, tables=self._tables)
        _, self._cusum, self._points = _kernels()
        T0 = np.asarray(model.tensions(np.zeros(3)), float)
        #: Smallest scale s_i [N]: the cell noise noise_rel x MBS_i.
        self.sigma_floor = self.noise_rel * np.asarray(model.MBS, float)
        #: Start (design) value of s_i [N].
        self.sigma_design = np.hypot(self.sigma_floor, self.dynamic_rel * T0)
        self.reset()
        # compile the kernels (or load them from the disk cache) now, not in the first control step
        held = T0.copy()
        held.setflags(write=False)   # the sensors hand on read-only arrays (a second specialisation)
        none = np.zeros(0, np.intp)
        for T in (T0, held):
            self._cusum(T, T0, none, self._st.copy(), self._cfg, self._busy)
            if self.buoys:
                self._points(np.zeros(0), np.zeros(0), none, np.zeros((0, 6)), self._busy, self._cfg_points)
        self._intact_table(np.zeros(3))

    def reset(self) -> None:
        """Back to the intact model, no line broken and no buoy lost, statistics and running
        estimates at their start values."""
        n = len(self.line_ids)
        self.broken: frozenset[str] = frozenset()
        #: Buoys detected lost, (line id, joint).
        self.lost_points: frozenset[tuple[str, int]] = frozenset()
        self.events: list[dict] = []
        st = np.zeros((n, 8))
        st[:, 2] = self.sigma_design
        st[:, 3] = self.sigma_floor
        st[:, 7] = -np.inf
        self._st = st
        self.samples = 0
        self._active = np.arange(n, dtype=np.intp)
        self._predict = self._intact_table
        self._busy = np.zeros(n)
        self._hyp = list(self.buoys)
        sp = np.zeros((len(self._hyp), 6))
        sp[:, 4] = -np.inf
        self._sp = sp
        self._hyp_stats: dict[tuple[str, int], np.ndarray] = {}   # final statistics of the hypotheses left
        self._hyp_tables()
        self._t_prev = -math.inf
        self._t_next = -math.inf

    def _hyp_tables(self) -> None:
        """The tension tables of the buoy-loss hypotheses still tested: per hypothesis, its line alone
        in the present model (:attr:`active_model`) with that buoy also gone; and where each line
        is (row in the statistics, position among the predicted tensions)."""
        model = self._predict.model
        tabs = []
        for lid, j in self._hyp:
            others = [x for x in model.line_ids if x != lid]
            tabs.append(_TensionTable(model.with_point_lost(lid, j).without(others), tables=self._tables))
        self._htab = tabs
        self._hrow = np.array([self.line_ids.index(lid) for lid, _ in self._hyp], dtype=np.intp)
        self._hpos = np.array([model.line_ids.index(lid) for lid, _ in self._hyp], dtype=np.intp)
        self._hD = np.zeros(len(self._hyp))
        self._hd = np.zeros(len(self._hyp))
        self._hnv = np.ones(len(self._hyp))

    def _drop_hypotheses(self, keep) -> None:
        """Keep the hypotheses where ``keep`` (bool per hypothesis) holds; the others' final
        statistics go to :attr:`buoy_statistics`."""
        for q, h in enumerate(self._hyp):
            if not keep[q]:
                self._hyp_stats[h] = self._sp[q].copy()
        self._hyp = [h for h, k in zip(self._hyp, keep) if k]
        self._sp = self._sp[np.asarray(keep, dtype=bool)] if len(keep) else self._sp

    # -- state ----------------------------------------------------------------------------
    @property
    def statistic(self) -> np.ndarray:
        """CUSUM statistic g_i (n,) [-] of every line (its value at detection for a broken one)."""
        return self._st[:, 0].copy()

    @property
    def bias(self) -> np.ndarray:
        """Running mean b_i (n,) of the intact residual [N]."""
        return self._st[:, 1].copy()

    @property
    def sigma(self) -> np.ndarray:
        """Running standard deviation s_i (n,) of the intact residual [N]."""
        return self._st[:, 2].copy()

    @property
    def peak(self) -> np.ndarray:
        """Largest g_i (n,) so far [-]."""
        return self._st[:, 6].copy()

    @property
    def worst_drop(self) -> np.ndarray:
        """Largest ``-(r_i - b_i) / Delta_i`` (n,) so far [-] (NaN before the first test): the
        deepest residual of the line relative to the design shift; above 0.5 the statistic grows."""
        w = self._st[:, 7].copy()
        w[np.isneginf(w)] = np.nan
        return w

    @property
    def buoy_statistics(self) -> dict[tuple[str, int], dict[str, float]]:
        """Per buoy-loss hypothesis (line id, joint): its CUSUM statistic ``g`` [-] (its value at
        detection for a buoy found lost, or when its line was found broken), ``peak`` (largest g so
        far) and ``worst`` (largest residual as a fraction of the predicted shift D so far; above
        0.5 the statistic grows; NaN before the first test)."""
        out = {}
        rows = {**self._hyp_stats, **{h: self._sp[q] for q, h in enumerate(self._hyp)}}
        for h in self.buoys:
            r = rows[h]
            out[h] = {"g": float(r[0]), "peak": float(r[3]), "worst": float(r[4]) if np.isfinite(r[4]) else math.nan}
        return out

    @property
    def active_model(self) -> Any:
        """The line model the predictions come from: ``model.damaged(broken, lost_points)``."""
        return self._predict.model

    def predicted(self, eta: Any) -> np.ndarray:
        """Fairlead tensions [N] of the lines still tested (:attr:`active_model`'s order) at pose
        ``eta`` (3,) = (x [m], y [m], psi [rad]), from the tabulated line model."""
        return self._predict(self._check_eta(eta)).copy()

    @staticmethod
    def _check_eta(eta: Any) -> np.ndarray:
        e = np.array(eta, dtype=float)
        if e.shape != (3,) or not (math.isfinite(e[0]) and math.isfinite(e[1]) and math.isfinite(e[2])):
            raise DetectionError(f"eta = {np.ravel(e).tolist()} must be 3 finite numbers (x [m], y [m], psi [rad])")
        return e

    # -- test -------------------------------------------------------------------------------
    def update(self, t: float, tensions: Any, eta: Any = None) -> frozenset[str]:
        """Feed the measured fairlead tensions (n,) [N] of every line of ``model`` at time ``t``
        [s] and the estimator's latest LF pose ``eta`` (3,) = (x [m], y [m], psi [rad]) in {E}
        (None: no test yet); returns the lines known broken so far."""
        if not (isinstance(t, (int, float, np.integer, np.floating)) and math.isfinite(t)):
            raise DetectionError(f"t = {t!r} s must be a finite number")
        if t < self._t_prev:
            raise DetectionError(f"t = {t!r} s is before the previous update {self._t_prev!r} s")
        T = np.asarray(tensions, dtype=float)
        if T.shape != (len(self.line_ids),):
            raise DetectionError(f"tensions has shape {T.shape}, expected ({len(self.line_ids)},) for lines "
                                 f"{list(self.line_ids)}")
        if not math.isfinite(float(T.sum())) and not np.all(np.isfinite(T)):   # (the sum first: faster)
            i = int(np.flatnonzero(~np.isfinite(T))[0])
            raise DetectionError(f"tensions[{i}] (line {self.line_ids[i]!r}) = {float(T[i])!r} N must be finite")
        self._t_prev = t
        if eta is None:
            return self.broken
        e = self._check_eta(eta)
        if t < self._t_next or not self._active.size:  # the cells hold the sample already tested
            return self.broken
        self._t_next = t + (1.0 - 1e-6) / self.rate
        self.samples += 1
        if not T.flags.c_contiguous:
            T = np.ascontiguousarray(T)
        q = -1
        if self._hyp:
            q = self._test_buoys(T, e)
        Tp = self._predict(e)
        j = int(self._cusum(T, Tp, self._active, self._st, self._cfg, self._busy))
        if q >= 0 and (j < 0 or self._buoy_first(j, q, Tp)):
            self._declare_buoy(t, q)
        elif j >= 0:
            lid = self.line_ids[j]
            self.broken = self.broken | {lid}
            self.events.append({"t": float(t), "line": lid, "event": "line break detected",
                                "statistic": float(self._st[j, 0])})
            self._active = self._active[self._active != j]
            if self._hyp:
                self._drop_hypotheses([h[0] != lid for h in self._hyp])
            if self._active.size:
                self._predict = _TensionTable(self.model.damaged(self.broken, self.lost_points), tables=self._tables)
                self._hyp_tables()
        return self.broken

    def _test_buoys(self, T: np.ndarray, e: np.ndarray) -> int:
        """One sample of the buoy-loss hypotheses (class docstring, "Buoy loss"): the parity
        residual of the lines still tested, each hypothesis' predicted shift of it, and their
        statistics (:func:`_points_py`); returns the hypothesis isolated at this sample or -1."""
        act, st = self._active, self._st
        s = st[act, 2]
        J = np.empty((act.size, 3))
        for k, h in enumerate(_POSE_STEPS):   # the tensions' sensitivity to the pose (a pose error)
            e2 = e.copy()
            e2[k] += h
            J[:, k] = self._predict(e2)
        Tp = self._predict(e).copy()
        J = (J - Tp[:, None]) / (np.asarray(_POSE_STEPS)[None, :] * s[:, None])
        r = (T[act] - Tp - st[act, 1]) / s
        Qb = np.linalg.qr(J)[0] if act.size > 3 else np.eye(act.size)
        rp = r - Qb @ (Qb.T @ r)                             # the part no pose error explains
        keep = np.maximum(1.0 - np.einsum("ij,ij->i", Qb, Qb), 0.0)   # diagonal of I - P
        pos = self._hpos
        nv = np.sqrt(keep[pos])
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(nv > 1e-3, rp[pos] / nv, 0.0)
        D = self._hD
        for k, tab in enumerate(self._htab):
            D[k] = tab(e)[0]
        D -= Tp[pos]
        d = D / s[pos] * nv
        d[np.abs(d) < self.buoy_shift_min] = 0.0              # not testable at this pose
        self._hd, self._hnv = d, nv
        self._busy[:] = 0.0
        return int(self._points(z, d, self._hrow, self._sp, self._busy, self._cfg_points))

    def _buoy_first(self, j: int, q: int, Tp: np.ndarray) -> bool:
        """Line ``j``'s break test and buoy-loss hypothesis ``q`` both reach the threshold at this
        sample: whether the buoy loss is declared first. On different lines: the larger normalised
        shift, as between lines (the other is declared at the next sample if still above). On the
        same line: the hypothesis the residual fits better, the distance of its mean over the run
        (in units of s_i) from the hypothesis' level: ``D / s_i`` for the buoy loss, anything at
        or below ``-shift T_model / s_i`` for the break (a tie goes to the break)."""
        st, sp = self._st, self._sp
        if self._hrow[q] != j:
            return sp[q, 1] / sp[q, 2] > st[j, 4] / st[j, 5]
        s = st[j, 2]
        tp = float(Tp[int(np.flatnonzero(self._active == j)[0])])
        mean_break = -st[j, 4] / st[j, 5]                       # mean z over the break test's run
        d_break = max(mean_break + self.shift * tp / s, 0.0)   # one-sided: a break may lose more
        sgn = 1.0 if self._hd[q] >= 0 else -1.0                 # the buoy's, in the same units
        d_buoy = abs(sgn * sp[q, 1] / sp[q, 2] - self._hd[q]) / max(float(self._hnv[q]), 1e-3)
        return d_buoy < d_break

    def _declare_buoy(self, t: float, q: int) -> None:
        """Hypothesis ``q``'s buoy is lost: latched, its line predicted without it from now on, the
        line's other hypotheses restarted against the new model."""
        lid, joint = self._hyp[q]
        self.lost_points = self.lost_points | {(lid, joint)}
        self.events.append({"t": float(t), "line": lid, "joint": int(joint), "event": "buoy loss detected",
                            "statistic": float(self._sp[q, 0])})
        self._drop_hypotheses([k != q for k in range(len(self._hyp))])
        for k, h in enumerate(self._hyp):   # the line's other buoys: their shifts from the new model
            if h[0] == lid:
                self._sp[k, :4] = 0.0
        i = self.line_ids.index(lid)
        self._st[i, 0] = self._st[i, 4] = self._st[i, 5] = 0.0
        self._predict = _TensionTable(self.model.damaged(self.broken, self.lost_points), tables=self._tables)
        self._hyp_tables()
