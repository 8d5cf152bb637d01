"""Sensor redundancy and voting: the tension cells as a second position reference, and the tests
that find a failed GNSS, tension cell or gyro-compass and leave it out (survey §4.7; the
anchor-SLAM seed's motivation, §1: a position reference when GNSS or hydroacoustics fail).

:class:`SensorVoting` wraps any :class:`~tapm_opt.interfaces.Estimator` (the EKF, the passive
observer, the low-pass filters, with their line-break detector). At each update it screens the
:class:`~tapm_opt.interfaces.Measurement` and hands the wrapped estimator a measurement in which a
sensor found failed is replaced:

**Tension-based position** (the mooring model inverted from the cells). At each new tension sample
``k``, with ``eta_hat`` the wrapped estimator's latest LF pose and ``T_model`` the quasi-static
catenary tensions of the lines not known broken (the tabulated model of
:class:`~tapm_opt.estimation.detection.TensionResidualDetector`)::

    r_i   = T_i - T_model,i(eta_hat) - beta_i                        (R1)
    dp    = argmin_d  sum_{i in U} ((r_i - J_i d) / s_n,i)^2           (R2)
    p_T   = (x_hat, y_hat) + dp                                        (R3)
    e_i   = r_i - J_i dp                                               (R4)

``J = dT_model / d(x, y)`` (central differences, 0.5 m), ``s_n,i`` the cell noise, ``beta_i`` the
line's mean residual learnt while every sensor is healthy (the quasi-static model's own error:
current drag on the line, the LF lag; an exponentially weighted mean, time constant ``tau_learn``,
the plain mean before), ``U`` the cells neither excluded nor reading below ``break_fraction`` of
their model tension (a line that may have just broken). (R2) is solved by up to three
Gauss-Newton steps of the inverse of the mooring model from the estimate (the model re-evaluated
at each iterate; ``e`` then is the residual at the last one), the same inversion as the range
measurements of :class:`~tapm_opt.estimation.anchor_slam.TensionPositionEstimator` without its
filter; ``e`` is the *parity residual*, the part of the residual no position error
explains (Chow & Willsky 1984), in which one cell's fault shows and a position error does not.

**GNSS**. No fix (``position_valid`` False) or a GNSS excluded: the position handed on is
``p_T`` (R3): the *position reference switches to the tensions*, and back when a fix returns (a
dropout; an excluded GNSS stays excluded). A silent drift is found by voting the GNSS against the
tensions: ``dp`` low-passed (time constant ``tau_test``) and standardised by its standard deviation
learnt while healthy, ``z_p = dp_lp / s_p`` per axis; the GNSS is excluded when ``|z_p| >= z_alarm``
and ``|dp_lp| >= gnss_floor`` for ``confirm`` s, while the gyros agree (a heading error moves the
estimated turret as a GNSS error would; that is the gyros' test, below) and no cell's statistic is
past the alarm level (a cell's fault leaks a little into ``dp``).

**Tension cells**. *Stuck*: the cell repeats its reading exactly over ``stuck_time`` [s] (at least
three samples). With noise of standard deviation > 0 two samples are equal with probability 0 (2^-52
for float64 draws): no false alarm; the test is off for a noiseless cell. *Drifting*: the parity
residual low-passed (``tau_test``) and standardised by its healthy standard deviation, ``z_i = e_lp,i
/ s_e,i`` (``s_e`` floored at the cell noise over the square root of the samples in the low-pass);
``|z_i| >= z_alarm`` for ``confirm`` s while the cell reads at least ``break_fraction`` of its model
tension. *Noisy*: the mean square of the parity residual's sample-to-sample change over ``tau_test``
against its healthy value, divided by the median of that ratio over the cells (a rougher sea
raises them all), ``>= noise_ratio`` for ``confirm`` s. A cell found failed leaves (R2) and is handed
on as ``T_model,i(eta_hat) + beta_i``: the line-break detector and the reliability monitor see the
model's value, so **a failed cell is not declared a broken line**. A break is not a cell fault: its
cell falls below ``break_fraction`` of its model tension at once (to zero or the hanging weight,
50-100 % down: :class:`~tapm_opt.estimation.detection.TensionResidualDetector`), which the drift test
does not count and the line-break detector does.

Scales: the standard deviations (``s_e``, ``s_p``, the healthy noise ratio, the spread of the
GNSS-tension heading) are exponentially weighted means of Huber-clipped squares (at 3 standard
deviations) with time constant ``tau_learn`` until the tests arm (``t_arm``); then ten times
slower, and not while the statistic is past half the alarm level, so that a slow drift is not
absorbed into its own scale. ASSUMPTION: the sea changes slowly against ``10 tau_learn``.

Threshold and false alarms: for Gaussian residuals, ``|z| >= 5`` has probability 5.7e-7 per
independent sample of the low-passed statistic (one per about ``2 tau_test`` = 60 s), so about one
false alarm per 3 years per statistic (the 12 cells, the GNSS's two axes and the noise ratios of
fpso: one every two to three months of operation, before the confirmation over ``confirm`` s,
which lowers it). ASSUMPTION: the residuals are Gaussian and stationary over
``tau_learn``; the real ones are neither (wave groups, a changing sea), and the confirmation time and
the floors are what protect against that: the study ``studies/sensor_faults.toml`` runs the intact
case through the same tests and reports the false alarms (docs/sensor_faults.md).

**Gyro-compasses** (the plant has two: ``Measurement.heading`` and ``heading2``). *Stuck*: as a
cell, over ``stuck_time``. *Drifting*: the two disagree, ``|ssa(psi_1 - psi_2)|`` low-passed over
``tau_gyro`` at least ``gyro_floor`` (and ``z_alarm`` of its noise) for ``confirm`` s; the faulty one
is isolated by a third vote, the heading the GNSS and the tensions give together: the tensions
place the turret (R3 moves the turret of the estimate onto the tensions'), the GNSS the body
origin, and the line between them, ``L = |p_cot|`` long (91 m on fpso: 0.5 m of position is 0.3
deg), points along the hull: at each tension sample ``psi_GT = psi_hat + (R(psi_hat) p_cot x dp) / L^2``. Once the
gyros' difference also exceeds 4 standard deviations of ``psi_GT``'s own error (learnt while the
gyros agree), the gyro farther from ``psi_GT`` (each difference low-passed over ``tau_test``) is
excluded and the other's heading handed on; until then the heading handed on is the two gyros'
mean. Why a second gyro rather
than an innovation test against the model's yaw prediction: the observers' bias state absorbs a
slow heading drift as an environmental yaw moment, so the innovation stays white; two gyros are
what a DP-classed vessel carries, and the GNSS-tension heading breaks their tie.

Every detection is logged (:meth:`log`, with the wrapped estimator's events): ``{"t", "event":
"sensor fault detected", "sensor": "gnss" | "cell" | "gyro", "fault": "dropout" | "drift" | "stuck"
| "noisy", "line" (a cell) | "gyro" (1 or 2), "statistic"}``, and ``{"t", "event": "position
reference", "reference": "tensions" | "gnss"}`` at each switch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import TapmError
from ..geometry import ssa
from ..interfaces import Estimate, Measurement
from .detection import _TensionTable

__all__ = ["SensorVoting", "VotingSettings", "RedundancyError"]


class RedundancyError(TapmError, ValueError):
    """Bad settings of the sensor voting (the message names the field and the value)."""


@dataclass(frozen=True)
class VotingSettings:
    """Settings of :class:`SensorVoting` (module docstring).

    Attributes
    ----------
    z_alarm : float
        Alarm level of the standardised statistics [-] (default 5).
    confirm : float
        Time an alarm must last [s] (default 5).
    tau_test : float
        Time constant of the low-passed test statistics [s] (default 30).
    tau_learn : float
        Time constant of the healthy baselines and scales [s] (default 300).
    t_arm : float
        Time after the first update before any test may alarm [s] (default 120): the baselines
        are learnt first.
    stuck_time : float
        Time a reading must repeat exactly to be stuck [s] (default 5).
    noise_ratio : float
        Alarm level of a cell's noise ratio [-] (default 4).
    break_fraction : float
        A cell reading below this fraction of its model tension may be a broken line [-]
        (default 0.5).
    gnss_floor : float
        Smallest GNSS-tension disagreement that excludes the GNSS [m] (default 2).
    gyro_floor : float
        Smallest disagreement of the two gyros that is a fault [rad] (default 0.5 deg).
    tau_gyro : float
        Time constant of the gyros' low-passed difference [s] (default 10).
    """

    z_alarm: float = 5.0
    confirm: float = 5.0
    tau_test: float = 30.0
    tau_learn: float = 300.0
    t_arm: float = 120.0
    stuck_time: float = 5.0
    noise_ratio: float = 4.0
    break_fraction: float = 0.5
    gnss_floor: float = 2.0
    gyro_floor: float = math.radians(0.5)
    tau_gyro: float = 10.0

    def __post_init__(self) -> None:
        for name in ("z_alarm", "confirm", "tau_test", "tau_learn", "stuck_time", "noise_ratio", "gnss_floor",
                     "gyro_floor", "tau_gyro"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise RedundancyError(f"{name} = {v!r} must be a number > 0")
        if isinstance(self.t_arm, bool) or not isinstance(self.t_arm, (int, float)) or not (
                math.isfinite(self.t_arm) and self.t_arm >= 0):
            raise RedundancyError(f"t_arm = {self.t_arm!r} s must be a number >= 0")
        if not (isinstance(self.break_fraction, (int, float)) and 0 < self.break_fraction < 1):
            raise RedundancyError(f"break_fraction = {self.break_fraction!r} must be in (0, 1)")
        if self.noise_ratio <= 1:
            raise RedundancyError(f"noise_ratio = {self.noise_ratio!r} must be > 1")


def _ewma(old: Any, new: Any, dt: float, tau: float, n: int) -> Any:
    """Exponentially weighted mean with time constant ``tau`` [s], the plain mean of the ``n``
    samples so far while they span less than ``tau`` (no start-up bias)."""
    a = max(1.0 - math.exp(-dt / tau), 1.0 / n)
    return old + a * (new - old)


class SensorVoting:
    """Redundant position reference and sensor voting around an estimator (module docstring).

    Parameters
    ----------
    system : System
        The design system (its intact lines, turret, sensors' noise).
    base : Estimator
        The wrapped estimator (its line-break detector and reliability monitor included).
    settings : VotingSettings, optional
    """

    def __init__(self, system: Any, base: Any, settings: VotingSettings | None = None):
        from ..models.system import System

        if not isinstance(system, System):
            raise RedundancyError(f"system = {system!r} must be a System (System.from_scenario(scenario))")
        if not (callable(getattr(base, "update", None)) and callable(getattr(base, "reset", None))):
            raise RedundancyError(f"base = {base!r} must be an Estimator (update(t, measurement), reset())")
        self.settings = settings or VotingSettings()
        if not isinstance(self.settings, VotingSettings):
            raise RedundancyError(f"settings = {settings!r} must be a VotingSettings")
        self.system, self.base = system, base
        self.intact_model = system.lines
        self.line_ids = tuple(system.lines.line_ids)
        sens = system.scenario.sensors
        self._s_n = float(sens.tension_std_rel) * np.asarray(system.lines.MBS, float)
        self._h_std = float(sens.heading_std)
        self._tables: dict = {}
        self._p_cot = np.asarray(system.p_cot_B, float)
        self.reset()

    # -- state ------------------------------------------------------------------------------
    def reset(self) -> None:
        self.base.reset()
        n = len(self.line_ids)
        self._t0 = None
        self._est: Estimate | None = None
        self._tT = self._tH = -math.inf
        self._broken: frozenset = frozenset()
        self._table = None
        self._J_at = None
        self.excluded_cells: set[int] = set()
        self.excluded_gyro: int | None = None
        self.gnss_excluded = False
        self.reference = "gnss"
        self.events: list[dict] = []
        self._n = 0
        self._nd = 0
        self._beta = np.zeros(n)
        self._e_lp = np.zeros(n)
        self._e_var = np.zeros(n)
        self._d2_fast = np.zeros(n)
        self._d2_slow = np.zeros(n)
        self._d2_short = np.zeros(n)
        self._e_prev = None
        self._T_prev = None
        self._T_same_since = np.full(n, math.nan)
        self._T_same_n = np.zeros(n, int)
        self._dp = np.zeros(2)
        self._dp_lp = np.zeros(2)
        self._dp_var = np.zeros(2)
        self._p_T: np.ndarray | None = None
        self._T_sub: dict[int, float] = {}
        self._h_prev = [None, None]
        self._h_same_since = [math.nan, math.nan]
        self._h_same_n = [0, 0]
        self._dh_lp = 0.0
        self._gyro_n = 0
        self._h_last = None
        self._d_gt = np.zeros(2)
        self._n_gt = 0
        self._gt_var = 0.0
        self._gyro_suspect = False
        self._alarm_since: dict[tuple, float] = {}
        self._tT_last = -math.inf
        self._prev_tT = math.nan
        self._prev_tH = -math.inf
        #: The latest statistics (for tests and figures): ``z_cells`` (n,), ``z_gnss`` (2,),
        #: ``noise_ratio`` (n,), ``gyro_diff`` [rad], ``dp`` (2,) [m].
        self.stats: dict[str, Any] = {}

    def log(self) -> list[dict]:
        """The wrapped estimator's events and this one's (detections, reference switches), by time."""
        base = list(self.base.log()) if callable(getattr(self.base, "log", None)) else []
        return sorted(base + self.events, key=lambda e: float(e["t"]))

    @property
    def lost_points(self) -> frozenset:
        return getattr(self.base, "lost_points", frozenset())

    # -- helpers ----------------------------------------------------------------------------
    def _event(self, t: float, **kw: Any) -> None:
        self.events.append({"t": float(t), **kw})

    def _confirmed(self, key: tuple, alarm: bool, t: float) -> bool:
        """True when ``alarm`` has held since at least ``confirm`` s ago (per test ``key``)."""
        if not alarm:
            self._alarm_since.pop(key, None)
            return False
        t0 = self._alarm_since.setdefault(key, t)
        return t - t0 >= self.settings.confirm - 1e-9

    def _active(self) -> tuple[Any, np.ndarray]:
        """The tension table of the lines not known broken and their indices in the scenario."""
        broken = frozenset(self._est.broken_lines) if self._est is not None else frozenset()
        lost = self._est.lost_points if self._est is not None else frozenset()
        if self._table is None or broken != self._broken:
            model = self.intact_model.damaged(broken, lost) if (broken or lost) else self.intact_model
            self._table = _TensionTable(model, tables=self._tables)
            self._idx = np.array([self.line_ids.index(i) for i in model.line_ids], int)
            self._broken = broken
            self._J_at = None
        return self._table, self._idx

    def _jacobian(self, table: Any, eta: np.ndarray) -> np.ndarray:
        at = self._J_at
        if at is None or abs(eta[0] - at[0]) > 1.0 or abs(eta[1] - at[1]) > 1.0 or abs(eta[2] - at[2]) > 0.01:
            J = np.empty((len(self._idx), 2))
            for j in range(2):
                e = eta.copy()
                e[j] += 0.5
                tp = table(e).copy()
                e[j] -= 1.0
                J[:, j] = (tp - table(e)) / 1.0
            self._J, self._J_at = J, eta.copy()
        return self._J

    # -- the tests --------------------------------------------------------------------------
    def _cells(self, t: float, T: np.ndarray, learn: bool, armed: bool, gyros_agree: bool) -> None:
        """One new tension sample: stuck test, (R1)-(R4), the drift, noise and GNSS tests."""
        s = self.settings
        n = len(T)
        # stuck: an exactly repeated reading (cells with noise only)
        if self._T_prev is not None:
            same = (T == self._T_prev) & (self._s_n > 0)
            self._T_same_n = np.where(same, self._T_same_n + 1, 0)
            self._T_same_since = np.where(same, np.where(np.isnan(self._T_same_since), self._prev_tT,
                                                         self._T_same_since), math.nan)
            for i in np.flatnonzero(same):
                if (armed and i not in self.excluded_cells and self._T_same_n[i] >= 2
                        and t - self._T_same_since[i] >= s.stuck_time - 1e-9):
                    self._exclude_cell(t, int(i), "stuck", float(self._T_same_n[i] + 1))
        self._T_prev = T.copy()
        self._prev_tT = t
        eta = np.array(self._est.eta, float)
        table, idx = self._active()
        Tp_act = table(eta)
        Tp = np.full(n, math.nan)
        Tp[idx] = Tp_act
        r = T - Tp - self._beta
        J = np.zeros((n, 2))
        J[idx] = self._jacobian(table, eta)
        alive = np.zeros(n, bool)
        alive[idx] = True
        ok = alive & (T >= s.break_fraction * Tp)
        U = ok.copy()
        U[list(self.excluded_cells)] = False
        w = 1.0 / np.maximum(self._s_n, 1.0)
        dp = np.zeros(2)
        rr = r
        if U.sum() >= 3:
            # Gauss-Newton on the inverse mooring model: the step from the residual at the last
            # iterate, the model re-evaluated there (up to 3 steps, until one is below 0.1 m)
            A = J[U] * w[U, None]
            for _ in range(3):
                step = np.linalg.lstsq(A, (rr - J @ np.zeros(2))[U] * w[U], rcond=None)[0]
                dp = dp + step
                e_it = eta.copy()
                e_it[:2] += dp
                Tq = np.full(n, math.nan)
                Tq[idx] = table(e_it)
                rr = T - Tq - self._beta
                if float(np.hypot(*step)) < 0.1:
                    break
        e = np.where(alive, rr, 0.0)
        self._dp = dp
        self._p_T = eta[:2] + dp
        # the GNSS-tension heading of this sample (module docstring) and each gyro's difference from it
        c, sn = math.cos(eta[2]), math.sin(eta[2])
        arm = np.array([c * self._p_cot[0] - sn * self._p_cot[1], sn * self._p_cot[0] + c * self._p_cot[1]])
        L2 = float(arm @ arm)
        if L2 > 0 and self._h_last is not None:
            psi_gt = eta[2] + float(arm[0] * dp[1] - arm[1] * dp[0]) / L2
            dd = np.array([ssa(h - psi_gt) if h is not None else 0.0 for h in self._h_last])
            self._n_gt += 1
            dtg = max(t - self._tT_last, 1e-9) if math.isfinite(self._tT_last) else 1.0
            self._d_gt = _ewma(self._d_gt, dd, dtg, self.settings.tau_test, self._n_gt)
            if learn and not self._gyro_suspect and self.excluded_gyro is None:   # the third vote's spread
                tau_g = 10.0 * self.settings.tau_learn if armed else self.settings.tau_learn
                g2 = float(np.mean(self._d_gt ** 2))
                self._gt_var = _ewma(self._gt_var, min(g2, 9.0 * self._gt_var) if self._n_gt > 1 else g2, dtg,
                                     tau_g, self._n_gt)
        dt = 1.0 if self._e_prev is None else max(t - self._tT_last, 1e-9)
        self._tT_last = t
        self._n += 1
        k = self._n
        # low-passed statistics
        self._e_lp = _ewma(self._e_lp, e, dt, s.tau_test, k)
        self._dp_lp = _ewma(self._dp_lp, dp, dt, s.tau_test, k)
        if self._e_prev is not None:
            d2 = (e - self._e_prev) ** 2
            self._nd += 1
            self._d2_fast = _ewma(self._d2_fast, d2, dt, s.tau_test, self._nd)
            self._d2_short = _ewma(self._d2_short, d2, dt, s.confirm, self._nd)
        self._e_prev = e
        # the healthy baselines and scales, learnt while every sensor is trusted and no alarm builds
        n_eff = 2.0 * s.tau_test / dt
        floor_e = self._s_n / math.sqrt(n_eff)
        s_e = np.maximum(np.sqrt(self._e_var), floor_e)
        z = np.where(alive, self._e_lp / np.maximum(s_e, 1e-9), 0.0)
        s_p = np.maximum(np.sqrt(self._dp_var), 0.05)
        z_p = self._dp_lp / s_p
        quiet = (np.abs(z) < 0.5 * s.z_alarm) & ok
        quiet[list(self.excluded_cells)] = False
        if learn:
            # the scales from Huber-clipped squares (3 sigma: bounded influence), calibrated until
            # the tests arm; then refined ten times slower, and not while a statistic is past
            # half the alarm level (a fault building), so a drift is not absorbed into its own scale
            kl = max(k, 1)
            learnt = alive.copy()
            learnt[list(self.excluded_cells)] = False
            hold = 0.5 * s.z_alarm if armed else math.inf
            tau_s = 10.0 * s.tau_learn if armed else s.tau_learn
            self._beta = np.where(quiet & alive, _ewma(self._beta, self._beta + r, dt, s.tau_learn, kl), self._beta)
            x2 = np.minimum(self._e_lp ** 2, 9.0 * s_e ** 2) if k > 1 else self._e_lp ** 2
            self._e_var = np.where(learnt & (np.abs(z) < hold), _ewma(self._e_var, x2, dt, tau_s, kl),
                                   self._e_var)
            if float(np.max(np.abs(z_p))) < hold:
                p2 = np.minimum(self._dp_lp ** 2, 9.0 * s_p ** 2) if k > 1 else self._dp_lp ** 2
                self._dp_var = _ewma(self._dp_var, p2, dt, tau_s, kl)
            if self._nd:
                d2s = np.minimum(self._d2_fast, 9.0 * np.maximum(self._d2_slow, 1e-300)) if self._nd > 1 \
                    else self._d2_fast
                q_now = np.full(n, math.inf)
                np.divide(self._d2_fast, self._d2_slow, out=q_now, where=self._d2_slow > 0)
                keep = learnt & ((q_now < 0.5 * s.noise_ratio) if armed else True)
                self._d2_slow = np.where(keep, _ewma(self._d2_slow, d2s, dt, tau_s, self._nd), self._d2_slow)
        ratio = np.ones(n)
        np.divide(self._d2_fast, self._d2_slow, out=ratio, where=alive & (self._d2_slow > 0))
        healthy = [i for i in range(n) if alive[i] and i not in self.excluded_cells]
        med = float(np.median(ratio[healthy])) if healthy else 1.0
        q = ratio / max(med, 1e-12)
        self.stats = {"e_rel": np.where(alive, self._e_lp / np.where(alive, Tp, 1.0), 0.0), "z_cells": z, "z_gnss": z_p, "noise_ratio": q, "dp": dp.copy(), "dp_lp": self._dp_lp.copy(),
                      "gyro_diff": self._dh_lp}
        if not armed:
            return
        for i in range(n):
            if i in self.excluded_cells or not alive[i]:
                continue
            noisy = self._confirmed(("noisy", i), q[i] >= s.noise_ratio and ok[i], t)
            if noisy or self._confirmed(("drift", i), abs(z[i]) >= s.z_alarm and ok[i], t):
                # a noisy cell also moves its low-passed residual: its noise ratio over the last
                # confirm seconds names it
                loud = noisy or (self._d2_short[i] / max(self._d2_slow[i], 1e-300)) / max(med, 1e-12) >= s.noise_ratio
                self._exclude_cell(t, i, "noisy" if loud else "drift", float(q[i] if loud else z[i]))
        # GNSS against the tensions (only while the GNSS is the reference and the gyros agree)
        if self.reference == "gnss" and not self.gnss_excluded:
            cells_quiet = all(abs(z[i]) < s.z_alarm for i in healthy)
            alarm = (float(np.max(np.abs(z_p))) >= s.z_alarm and float(np.hypot(*self._dp_lp)) >= s.gnss_floor
                     and gyros_agree and cells_quiet)
            if self._confirmed(("gnss",), alarm, t):
                self.gnss_excluded = True
                self._event(t, event="sensor fault detected", sensor="gnss", fault="drift",
                            statistic=float(np.max(np.abs(z_p))))

    def _exclude_cell(self, t: float, i: int, fault: str, stat: float) -> None:
        self.excluded_cells.add(i)
        self._event(t, event="sensor fault detected", sensor="cell", fault=fault, line=self.line_ids[i],
                    statistic=stat)

    def _gyros(self, t: float, m: Measurement, armed: bool) -> bool:
        """One new heading sample: stuck tests, the gyros' difference and its isolation; True
        while the gyros agree (or one is already excluded)."""
        s = self.settings
        h = [float(m.heading), None if m.heading2 is None else float(m.heading2)]
        self._h_last = h
        for g in (0, 1):
            if h[g] is None:
                continue
            if h[g] == self._h_prev[g] and self._h_std > 0:
                self._h_same_n[g] += 1
                if math.isnan(self._h_same_since[g]):
                    self._h_same_since[g] = self._prev_tH
                if (armed and self.excluded_gyro is None and self._h_same_n[g] >= 2
                        and t - self._h_same_since[g] >= s.stuck_time - 1e-9):
                    self._exclude_gyro(t, g + 1, "stuck", float(self._h_same_n[g] + 1))
            else:
                self._h_same_n[g], self._h_same_since[g] = 0, math.nan
            self._h_prev[g] = h[g]
        dt = 1.0 if not math.isfinite(self._prev_tH) else max(t - self._prev_tH, 1e-9)
        self._prev_tH = t
        if h[1] is None or self.excluded_gyro is not None:
            return True
        self._gyro_n += 1
        self._dh_lp = _ewma(self._dh_lp, float(ssa(h[0] - h[1])), dt, s.tau_gyro, self._gyro_n)
        floor = max(s.gyro_floor, s.z_alarm * math.sqrt(2.0) * self._h_std / math.sqrt(2.0 * s.tau_gyro / dt))
        alarm = abs(self._dh_lp) >= floor
        if armed and self._confirmed(("gyro",), alarm, t):
            # the third vote: each gyro's low-passed difference from the GNSS-tension heading; the
            # farther one is excluded once the gyros disagree by 4 standard deviations of that
            # heading's own error (then it is on the wrong side with probability 2 %); until
            # then the heading handed on is the two gyros' mean
            self._gyro_suspect = True
            if abs(self._dh_lp) >= 4.0 * math.sqrt(self._gt_var):
                a1, a2 = abs(float(self._d_gt[0])), abs(float(self._d_gt[1]))
                self._gyro_suspect = False
                self._exclude_gyro(t, 1 if a1 > a2 else 2, "drift", float(self._dh_lp))
                return True
        return abs(self._dh_lp) < 0.5 * floor

    def _exclude_gyro(self, t: float, g: int, fault: str, stat: float) -> None:
        self.excluded_gyro = g
        self._event(t, event="sensor fault detected", sensor="gyro", fault=fault, gyro=g, statistic=stat)

    # -- the estimator ----------------------------------------------------------------------
    def update(self, t: float, measurement: Measurement) -> Estimate:
        """Screen the measurement (module docstring) and update the wrapped estimator with it."""
        m = measurement
        if not isinstance(m, Measurement):
            raise RedundancyError(f"measurement = {m!r} must be a Measurement")
        if self._t0 is None:
            if not m.position_valid:
                raise RedundancyError(f"measurement.position_valid is False at the first update (t = {t!r} s): "
                                      "the tension reference is calibrated against a GNSS fix first")
            self._t0 = float(t)
            self._prev_tH = -math.inf
        s = self.settings
        armed = float(t) - self._t0 >= s.t_arm
        new_T = m.tensions is not None and float(m.t_tensions) > self._tT
        new_H = float(m.t_heading) > self._tH
        agree = True
        if new_H:
            self._tH = float(m.t_heading)
            agree = self._gyros(float(t), m, armed) if self._est is not None else True
        if not m.position_valid and not self.gnss_excluded and self.reference == "gnss":
            self._event(t, event="sensor fault detected", sensor="gnss", fault="dropout", statistic=1.0)
        use_tensions = self.gnss_excluded or not m.position_valid
        if new_T and self._est is not None:
            self._tT = float(m.t_tensions)
            learn = not use_tensions and self.excluded_gyro is None
            self._cells(float(t), np.asarray(m.tensions, float), learn, armed, agree)
            use_tensions = self.gnss_excluded or not m.position_valid
            # the failed cells' readings replaced by the model's (+ the line's learnt mean residual)
            if self.excluded_cells:
                table, idx = self._active()
                Tp = table(np.array(self._est.eta, float))
                pos = {j: k for k, j in enumerate(idx)}
                self._T_sub = {i: float(Tp[pos[i]] + self._beta[i]) for i in self.excluded_cells if i in pos}
        reference = "tensions" if use_tensions else "gnss"
        if reference != self.reference:
            self.reference = reference
            self._event(t, event="position reference", reference=reference)
        changes: dict[str, Any] = {}
        if use_tensions:
            p = self._p_T if self._p_T is not None else (np.array(self._est.eta[:2], float) if self._est is not None
                                                         else None)
            if p is None:
                raise RedundancyError(f"no position at t = {t!r} s: no GNSS fix and no tension sample yet")
            changes.update(position=np.array(p, float), position_valid=True)
        if self.excluded_gyro == 1 and m.heading2 is not None:
            changes["heading"] = float(m.heading2)
        elif self._gyro_suspect and self.excluded_gyro is None and m.heading2 is not None:
            changes["heading"] = float(ssa(m.heading + 0.5 * ssa(m.heading2 - m.heading)))
        if self._T_sub and m.tensions is not None:
            T = np.array(m.tensions, float)
            for i, v in self._T_sub.items():
                T[i] = v
            changes["tensions"] = T
        mm = replace(m, **changes) if changes else m
        self._est = self.base.update(t, mm)
        return self._est
