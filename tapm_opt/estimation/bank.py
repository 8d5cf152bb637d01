"""Line-break detection and isolation without tension cells: a bank of observers, one per mooring
hypothesis, and a supervisor that decides between them from their position/heading innovations.

Hypotheses: ``H0`` — the intact line system — and ``H_k`` — line ``k`` broken, one per line of the
model (or per line of ``lines``). Each is a full DP observer of the same kind
(:class:`~tapm_opt.estimation.observer.EKFObserver` or
:class:`~tapm_opt.estimation.observer.PassiveObserver`, same settings) whose mooring term is
``tau_m`` of ``intact_model.without({k})``; every update feeds every observer the same measurement.
A hypothesis whose model matches the plant predicts the measured pose best; the bank needs no
tension measurement (Ren, Skjetne & Hassani 2015: "a bank of observers, one per mooring mode";
survey §4.2.4, §4.5).

Decision (``method``):

``"probability"`` (default) — dynamic hypothesis testing, multiple-model adaptive estimation
(Magill 1965; Hassani et al. 2018): at every new position sample the posterior probability of each
hypothesis is updated with the likelihood of its observer's a-priori innovation ``v_i`` (x [m], y [m],
psi [rad]; the components sampled since the previous correction)::

    log p_i <- log p_i - 1/2 (v_i^T S_i^-1 v_i + log det S_i),   then normalised (Bayes' rule)

``S_i`` is the EKF's own innovation covariance ``H P^- H^T + R``; the passive observer has none, so
it uses the fixed ``innovation_cov`` ``S_0 = diag(gnss_std^2 + wf_x^2, gnss_std^2 + wf_y^2,
heading_std^2 + wf_psi^2)`` (sensor noise plus the expected WF motion, the EKF's ``wf_std`` of the
sea state; the same for every hypothesis). Each probability is floored at ``p_min`` after every
update (then renormalised), so that a hypothesis improbable for a long intact run can take over in
a bounded time: at most ``log(1/p_min)`` nats of evidence are needed. The log-likelihood of one
sample is clipped at ``-max_nats`` (a GNSS outlier cannot decide alone). Line ``k`` is declared
broken when ``p_k >= threshold`` continuously for ``hold`` seconds.

``"residual"`` — the supervisor of Ren et al. (2015): monitoring signals
``J_i(t) = int_0^t exp(-forgetting (t - s)) v_i(s)^T S_0^-1 v_i(s) ds`` (discretised at the position
samples, ``J_i <- exp(-forgetting dt) J_i + dt v_i^T S_0^-1 v_i``); the active hypothesis (first
``H0``) is replaced by ``argmin_i J_i`` when ``J_min < (1 - hysteresis) J_active`` has held with the
same candidate for ``dwell`` seconds (hysteresis and dwell time against chattering).

Before a decision, and during ``warmup`` seconds after the first update (no evidence is counted
then: the observers' start-up transients), the bank's estimate is ``H0``'s — the intact observer's,
not a mixture — so the controllers see the intact estimate until the bank decides. On a decision
for ``H_k`` the bank latches: ``Estimate.broken_lines = {k}`` from then on, one event ``{"t", "line",
"event": "line break detected", "probability" | "residual", ...}`` in :meth:`log` (the format of the
tension detectors, which :func:`tapm_opt.studies.kpis._detection` reads from
``result.meta["estimator_log"]``), and the estimate is ``H_k``'s observer's — already converged on the
reduced model. Only that observer is updated from then on: the bank isolates one break. A second
break needs the bank rebuilt on the reduced model (``ObserverBank(observer on
model.without({k}))``); it is not done on-line here.

Why the hypotheses have a slower bias than the estimating observer: each observer estimates a
slowly varying bias ``b`` (the environmental load). In an observer with the intact model's fast
bias every hypothesis absorbs the *mean* of the lost line's pull alike: before the break ``H_k``'s
bias holds ``tau_env + tau_k``, after it ``H0``'s must become ``tau_env - tau_k``, and right after the
break both predict the same wrong load; only the lost line's stiffness times the LF motion (17 kN/m
x 4 m on fpso's most loaded line in the storm, against a 2.5 MN pull) separates them, and the fast
bias absorbs that too (measured: no line detected). So the bank keeps two sets of observers: the
estimating observer ``observer`` (the loop's ``H0``, default settings), whose estimate the
controllers see, and the hypotheses ``H0', H_1 ... H_n``, copies of ``hypothesis_observer`` — the same
observer with a bias ``bias_scale`` times as agile (``from_scenario``: EKF ``bias_std`` x 0.1;
passive ``omega_b`` x 0.1) — whose innovations are the evidence. A slow bias cannot absorb a
line's pull within the minutes that the evidence needs; it also tracks the storm's slowly varying
drift load worse, the price of the test (the limits: the docs). After a decision for ``H_k`` the
estimate comes from a copy of the estimating observer on the reduced model with ``H_k``'s state
(its bias did not absorb the lost pull) and the estimating observer's covariance and bias
dynamics. With ``hypothesis_observer=None`` (``bias_scale=1``) the hypotheses are copies of
``observer`` and ``H0`` is ``observer`` itself.

The reliability ``monitor`` is fed the measured tensions and riser angles as the other estimators
do, if the measurement has them; the bank itself never reads tensions.

Cost: every hypothesis is a full observer, so an update costs ``n_lines + 2`` observer updates
before a decision (14 on fpso with a separate hypothesis bank) and one after it.

References
----------
D. T. Magill, Optimal adaptive estimation of sampled stochastic processes, IEEE Trans. Automat.
Contr. 10 (1965) 434-439.
Z. Ren, R. Skjetne, V. Hassani, Supervisory control of line breakage for thruster-assisted position
mooring system, IFAC-PapersOnLine 48-16 (2015) 235-240 (MCMC 2015).
V. Hassani, A. M. Pascoal, A. J. Sorensen, Detection of mooring line failures using dynamic
hypothesis testing, Ocean Engineering 159 (2018) 496-503.
J. P. Hespanha, D. Liberzon, A. S. Morse, Hysteresis-based switching algorithms for supervisory
control of uncertain systems, Automatica 39 (2003) 263-272 (the monitoring signals' forgetting
factor and hysteresis).
Z. Ren et al., A survey on modeling and control of thruster-assisted position mooring systems,
§4.2.4, §4.5.
"""

from __future__ import annotations

import copy
import math
from dataclasses import replace
from typing import Any, Iterable

import numpy as np

from ..interfaces import Estimate, Measurement
from .lowpass import EstimationError, _WithDetectorAndMonitor
from .observer import EKFObserver, PassiveObserver, _number, _vec3

__all__ = ["ObserverBank", "KINDS", "METHODS", "EstimationError"]

#: ``ObserverBank.from_scenario(kind=...)``: the observer of every hypothesis.
KINDS = {"passive": PassiveObserver, "ekf": EKFObserver}
#: ``ObserverBank(method=...)``: the decision logic.
METHODS = ("probability", "residual")

_LOG_2PI = math.log(2.0 * math.pi)


def _innovation_cov_default(gnss_std: float = 0.5, heading_std: float = math.radians(0.1),
                            wf_std: Any = (0.5, 0.5, 0.005)) -> np.ndarray:
    """``diag(gnss_std^2 + wf_x^2, gnss_std^2 + wf_y^2, heading_std^2 + wf_psi^2)`` (3, 3) [m^2,
    m^2, rad^2]: the fixed innovation covariance (sensor noise plus the expected WF motion)."""
    wf = np.asarray(wf_std, float)
    return np.diag([gnss_std ** 2 + wf[0] ** 2, gnss_std ** 2 + wf[1] ** 2, heading_std ** 2 + wf[2] ** 2])


class ObserverBank(_WithDetectorAndMonitor):
    """A bank of observers, one per hypothesis (intact; each line broken), and the supervisor that
    detects and isolates a line break from their innovations (module docstring). An
    :class:`~tapm_opt.interfaces.Estimator` and :class:`~tapm_opt.interfaces.Logged`.

    Parameters
    ----------
    observer : EKFObserver or PassiveObserver
        The intact hypothesis' observer (``H0``), without a detector or monitor of its own; every
        ``H_k`` is a copy of it with ``intact_model = observer.intact_model.without({k})``. It is
        reset. Its estimate is the bank's until a decision.
    hypothesis_observer : observer of the same kind, optional
        Template of the hypotheses' observers (the evidence), on the same intact model, e.g. with a
        slower bias (module docstring); default: ``observer`` itself.
    lines : iterable of str, optional
        The lines to hypothesise broken (ids of the model); default every line.
    method : {"probability", "residual"}
        Decision logic; default ``"probability"``.
    threshold : float
        ``"probability"``: the posterior probability [-] in (0.5, 1) at which a line is declared
        broken; default 0.99.
    hold : float
        ``"probability"``: how long [s] the probability must stay at or above ``threshold``,
        >= 0; default 20 s.
    p_min : float
        ``"probability"``: floor [-] of every hypothesis' probability, in (0, 0.01]; default 1e-6.
    max_nats : float
        ``"probability"``: bound [-] of one sample's negative log-likelihood (outlier clip), > 0;
        default 50.
    forgetting : float
        ``"residual"``: forgetting factor ``lambda`` [1/s] of the monitoring signals, > 0; default
        1/120 s.
    hysteresis : float
        ``"residual"``: relative hysteresis ``h`` [-] in (0, 1); default 0.3.
    dwell : float
        ``"residual"``: how long [s] the switching condition must hold, >= 0; default 30 s.
    warmup : float
        Time [s] after the first update during which no evidence is counted, >= 0; default 120 s.
    use_heading : bool
        Count the heading innovation in the evidence; default True.
    innovation_cov : (3, 3) or (3,), optional
        The fixed innovation covariance ``S_0`` [m^2, m^2, rad^2] (a diagonal as 3 numbers): the
        passive observer's likelihood and the residual method's weight. Default
        ``diag(gnss_std^2 + wf_std^2)`` per component, from the observer's settings for the EKF
        and from the EKF's defaults (0.5 m, 0.1 deg, WF 0.5 m, 0.5 m, 0.005 rad) for the passive
        observer (``from_scenario``: the scenario's sensors and sea state).
    monitor : ReliabilityMonitor, optional
        On-line reliability statistics of the measured tensions and riser angles, handed on as
        ``Estimate.reliability``.

    Attributes
    ----------
    hypotheses : tuple of str
        ``"intact"`` then the line ids, the order of ``observers``, ``probabilities``, ``residuals``.
    observers : list
        The observer of each hypothesis (the evidence).
    main : observer
        The estimating observer (``H0`` of the loop).
    probabilities : ndarray (n_h,)
        Posterior probability of each hypothesis [-] (``"probability"``; uniform over the
        hypotheses' prior ``(1 - n p_min, p_min, ...)`` at the start).
    residuals : ndarray (n_h,)
        Monitoring signals ``J_i`` [s] (``"residual"``; zeros at the start).
    active : int
        Index of the hypothesis whose estimate the bank reports (0 until a decision).
    broken : str or None
        The line declared broken (None: none yet).
    events : list of dict
        The decision, as logged.
    """

    def __init__(self, observer: Any, *, hypothesis_observer: Any = None, lines: Iterable[str] | None = None, method: str = "probability",
                 threshold: float = 0.99, hold: float = 20.0, p_min: float = 1e-6, max_nats: float = 50.0,
                 forgetting: float = 1.0 / 120.0, hysteresis: float = 0.3, dwell: float = 30.0,
                 warmup: float = 120.0,
                 use_heading: bool = True, innovation_cov: Any = None, monitor: Any = None):
        if not isinstance(observer, (EKFObserver, PassiveObserver)):
            raise EstimationError(f"observer = {observer!r} must be an EKFObserver or a PassiveObserver")
        if getattr(observer, "detector", None) is not None or getattr(observer, "monitor", None) is not None:
            raise EstimationError("observer has a detector or monitor of its own: the bank decides the breaks "
                                  "and feeds the monitor (give monitor= to the bank)")
        if method not in METHODS:
            raise EstimationError(f"method = {method!r} is not one of {', '.join(map(repr, METHODS))}")
        self.method = method
        self.threshold = _number("threshold", threshold, lo=0.5, hi=1.0)
        if self.threshold >= 1.0:
            raise EstimationError(f"threshold = {threshold!r} must be below 1 (a probability the floor p_min "
                                  "lets a hypothesis reach)")
        self.hold = _number("hold", hold, lo=0.0, strict_lo=False, unit="s")
        self.p_min = _number("p_min", p_min, lo=0.0, hi=0.01)
        self.max_nats = _number("max_nats", max_nats, lo=0.0)
        self.forgetting = _number("forgetting", forgetting, lo=0.0, unit="1/s")
        self.hysteresis = _number("hysteresis", hysteresis, lo=0.0, hi=1.0)
        if self.hysteresis >= 1.0:
            raise EstimationError(f"hysteresis = {hysteresis!r} must be below 1")
        self.dwell = _number("dwell", dwell, lo=0.0, strict_lo=False, unit="s")
        self.warmup = _number("warmup", warmup, lo=0.0, strict_lo=False, unit="s")
        if not isinstance(use_heading, bool):
            raise EstimationError(f"use_heading = {use_heading!r} must be True or False")
        self.use_heading = use_heading
        self.kind = "ekf" if isinstance(observer, EKFObserver) else "passive"
        model = observer.intact_model
        ids = tuple(str(i) for i in model.line_ids)
        if lines is None:
            chosen = ids
        else:
            if isinstance(lines, str):
                lines = [lines]
            chosen = tuple(dict.fromkeys(str(k) for k in lines))
            unknown = [k for k in chosen if k not in ids]
            if unknown or not chosen:
                raise EstimationError(f"lines = {list(chosen)!r}: {'unknown line ' + repr(unknown[0]) if unknown else 'no line'}"
                                      f" (the model's lines are {list(ids)})")
        if len(ids) < 2:
            raise EstimationError(f"the model has {len(ids)} line(s): a bank of line-break hypotheses needs at least 2")
        if innovation_cov is None:
            if self.kind == "ekf":
                S0 = _innovation_cov_default(observer.gnss_std, observer.heading_std, observer.wf_std)
            else:
                S0 = _innovation_cov_default()
        else:
            a = np.asarray(innovation_cov, dtype=float) if not isinstance(innovation_cov, str) else np.array(np.nan)
            if a.shape == (3,):
                a = np.diag(_vec3("innovation_cov", a, unit="m^2, m^2, rad^2"))
            if a.shape != (3, 3) or not np.all(np.isfinite(a)) or not np.allclose(a, a.T) \
                    or np.any(np.linalg.eigvalsh(0.5 * (a + a.T)) <= 0):
                raise EstimationError(f"innovation_cov = {np.asarray(innovation_cov).tolist() if not isinstance(innovation_cov, str) else innovation_cov!r}"
                                      " must be 3 positive numbers or a symmetric positive definite (3, 3) "
                                      "matrix [m^2, m^2, rad^2]")
            S0 = 0.5 * (a + a.T)
        self.innovation_cov = S0
        self._W = np.linalg.inv(S0)
        observer.reset()
        self.main = observer
        if hypothesis_observer is None:
            template = observer
        else:
            if type(hypothesis_observer) is not type(observer):
                raise EstimationError(f"hypothesis_observer = {hypothesis_observer!r} must be of the observer's kind "
                                      f"({type(observer).__name__})")
            if hypothesis_observer.intact_model is not model:
                raise EstimationError("hypothesis_observer must be built on the observer's intact model")
            template = hypothesis_observer
            template.reset()
        self._memo = {id(model): model, id(observer.vessel): observer.vessel}
        obs = [template]
        for k in chosen:
            h = copy.deepcopy(template, memo=dict(self._memo))
            h.intact_model = h.model = model.without({k})
            h.reset()
            obs.append(h)
        self.observers = obs
        self._separate = template is not observer
        self._after = None      # the estimating observer after a decision
        self.hypotheses = ("intact", *chosen)
        self.monitor = monitor
        self.detector = None
        self.reset()

    @classmethod
    def from_scenario(cls, system: Any, sea_state: Any = None, kind: str = "ekf", monitor: Any = None,
                      observer_kw: dict | None = None, bias_scale: float = 0.1, **kw: Any) -> "ObserverBank":
        """The bank of a :class:`~tapm_opt.models.system.System` (or a scenario): ``H0`` is
        ``KINDS[kind].from_scenario(system, sea_state, **observer_kw)`` (the scenario's vessel, intact
        lines, sensor noise and the sea state's WF model), one ``H_k`` per line. For the passive
        observer the fixed innovation covariance comes from the scenario's sensors
        (``gnss_std``, ``heading_std``) and the sea state's expected WF motion (the EKF's ``wf_std``
        of ``Hs``). The hypotheses' observers have the bias ``bias_scale`` (in (0, 1]) times as agile:
        EKF ``bias_std`` x ``bias_scale``, passive ``omega_b`` x ``bias_scale`` (default 0.1; 1: the
        hypotheses are copies of ``H0``). Other keyword arguments go to :class:`ObserverBank`."""
        if kind not in KINDS:
            raise EstimationError(f"kind = {kind!r} is not one of {', '.join(map(repr, KINDS))}")
        okw = dict(observer_kw or {})
        if "detector" in okw or "monitor" in okw:
            raise EstimationError("observer_kw must not hold a detector or monitor: the bank decides the breaks "
                                  "(give monitor= to the bank)")
        obs = KINDS[kind].from_scenario(system, sea_state=sea_state, **okw)
        scale = _number("bias_scale", bias_scale, lo=0.0, hi=1.0)
        if scale < 1.0 and "hypothesis_observer" not in kw:
            slow = {"bias_std": obs.bias_std * scale} if kind == "ekf" else {"omega_b": obs.omega_b * scale}
            kw["hypothesis_observer"] = KINDS[kind].from_scenario(system, sea_state=sea_state, **{**okw, **slow})
            kw["hypothesis_observer"].intact_model = kw["hypothesis_observer"].model = obs.intact_model
        if kind == "passive" and "innovation_cov" not in kw:
            ref = EKFObserver.from_scenario(system, sea_state=sea_state)
            kw["innovation_cov"] = _innovation_cov_default(ref.gnss_std, ref.heading_std, ref.wf_std)
        return cls(obs, monitor=monitor, **kw)

    # -- Estimator ----------------------------------------------------------------------------

    def reset(self) -> None:
        n = len(self.observers)
        self.main.reset()
        for o in self.observers:
            o.reset()
        self._after = None
        self._prior()
        self.residuals = np.zeros(n)
        self.log_likelihood = np.zeros(n)
        self.active = 0
        self.broken: str | None = None
        self.events: list[dict] = []
        self._t0 = None
        self._t_pos = self._t_hdg = -math.inf
        self._t_evidence = None
        self._since = None      # (candidate index, time the condition began)
        self._reset_parts()

    def _prior(self) -> None:
        n = len(self.observers)
        lp = np.full(n, math.log(self.p_min))
        lp[0] = math.log(1.0 - (n - 1) * self.p_min)
        self._logp = lp
        self.probabilities = np.exp(lp)

    def log(self) -> list[dict]:
        """The bank's decision (``{"t", "line", "event": "line break detected", ...}``), if any."""
        return list(self.events)

    def update(self, t: float, measurement: Measurement) -> Estimate:
        """Feed every observer the measurement (after a decision: only the chosen one), update the
        evidence at a new position/heading sample, decide; the active hypothesis' estimate with
        ``broken_lines`` and ``reliability`` of the bank."""
        m = measurement
        if self.broken is not None:
            est = self._after.update(t, m)
        else:
            est = self.main.update(t, m)                      # first: it checks t and m
            for o in (self.observers[1:] if not self._separate else self.observers):
                o.update(t, m)
            t = est.t
            if self._t0 is None:
                self._t0 = t
            tp, th = float(m.t_position), float(m.t_heading)
            new = (tp > self._t_pos, tp > self._t_pos, th > self._t_hdg)
            first = self._t_pos == -math.inf
            if new[0]:
                self._t_pos = tp
            if new[2]:
                self._t_hdg = th
            use = np.array([new[0], new[1], new[2] and self.use_heading])
            if use.any() and not first and t - self._t0 >= self.warmup:
                self._evidence(t, use)
                if self.broken is not None:
                    est = self._estimate_after(t, m)
        broken = frozenset() if self.broken is None else frozenset([self.broken])
        return replace(est, broken_lines=broken, reliability=self._reliability(t, m))

    # -- decision -----------------------------------------------------------------------------

    def _innovations(self, mask: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        out = []
        idx = np.flatnonzero(mask)
        for o in self.observers:
            v = np.array(o.innovation, dtype=float)
            v[2] = math.remainder(v[2], 2.0 * math.pi)
            if self.kind == "ekf" and self.method == "probability":
                S = np.asarray(o.innovation_cov, float)
            else:
                S = self.innovation_cov
            out.append((v[idx], S[np.ix_(idx, idx)]))
        return out

    def _evidence(self, t: float, mask: np.ndarray) -> None:
        vs = self._innovations(mask)
        if self.method == "probability":
            ll = np.empty(len(vs))
            for i, (v, S) in enumerate(vs):
                try:
                    L = np.linalg.cholesky(S)
                except np.linalg.LinAlgError:
                    raise EstimationError(f"innovation covariance of hypothesis {self.hypotheses[i]!r} = "
                                          f"{S.tolist()} is not positive definite") from None
                z = np.linalg.solve(L, v)
                ll[i] = -0.5 * (z @ z + 2.0 * np.log(np.diag(L)).sum() + len(v) * _LOG_2PI)
            ll = np.maximum(ll, ll.max() - self.max_nats)
            self.log_likelihood = ll
            lp = self._logp + ll
            lp -= _logsumexp(lp)
            lp = np.maximum(lp, math.log(self.p_min))
            lp -= _logsumexp(lp)
            self._logp = lp
            self.probabilities = np.exp(lp)
            best = int(np.argmax(lp))
            ok = best != 0 and self.probabilities[best] >= self.threshold
            score = {"probability": float(self.probabilities[best])}
        else:
            dt = 0.0 if self._t_evidence is None else t - self._t_evidence
            a = math.exp(-self.forgetting * dt)
            J = self.residuals
            Wi = self._W[np.ix_(mask, mask)]   # the same components for every hypothesis
            for i, (v, S) in enumerate(vs):
                J[i] = a * J[i] + dt * float(v @ Wi @ v)
            best = int(np.argmin(J))
            ok = best != self.active and J[best] < (1.0 - self.hysteresis) * J[self.active]
            score = {"residual": float(J[best]), "residual_intact": float(J[0])}
        self._t_evidence = t
        if not ok:
            self._since = None
            return
        if self._since is None or self._since[0] != best:
            self._since = (best, t)
        wait = self.hold if self.method == "probability" else self.dwell
        if t - self._since[1] >= wait - 1e-9:
            self._decide(t, best, score)

    def _estimate_after(self, t: float, m: Measurement) -> Estimate:
        """The estimating observer after the decision for ``H_k``: ``H_k`` itself, or (with a
        separate hypothesis bank) a copy of ``observer`` on the reduced model, with ``observer``'s
        bias dynamics and covariance and ``H_k``'s state (its bias has not absorbed the lost pull);
        its estimate at ``t``."""
        hk = self.observers[self.active]
        if not self._separate:
            self._after = hk
        else:
            a = copy.deepcopy(self.main, memo=dict(self._memo))
            a.intact_model = a.model = hk.intact_model
            a.set_state(hk.state(covariance=False))   # fed the same measurements: same time stamps
            self._after = a
        return self._after.estimate_now(t, m)

    def _decide(self, t: float, i: int, score: dict) -> None:
        self.active = i
        self.broken = self.hypotheses[i]
        self.events.append({"t": float(t), "line": self.broken, "event": "line break detected", **score})


def _logsumexp(a: np.ndarray) -> float:
    m = float(a.max())
    return m + math.log(float(np.exp(a - m).sum()))
