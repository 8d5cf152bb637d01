"""A simple state estimate from measurements: low-pass filters (the runner's default; the DP
observers are in :mod:`tapm_opt.estimation.observer`).

Position and heading: each of x, y and the unwrapped heading passes through a critically damped
second-order low-pass filter (cut-off ``omega_c``), a state-variable filter whose second state is
the filtered rate; it removes most wave-frequency motion (periods ~ 5–20 s) and delays the LF
motion (periods ~ 100–400 s) by about ``2 / omega_c``. The velocity in {B} is the filtered rate
rotated by the filtered heading.

Environmental load: a quasi-static balance, assuming the LF motion is slow enough for inertia
and damping to be small on average: ``b = -(tau_moor(eta_hat) + tau_thr)`` expressed in {E} and
low-pass filtered with time constant ``T_env``; handed to controllers in {B} as ``tau_env``. The
mooring load is the design model's (``MooringModel``) at the estimated pose, so a broken line that
the model still contains shows up as part of the "environment"; with a line-break ``detector``
(:class:`~tapm_opt.estimation.detection.TensionDropDetector`) a detected line leaves the model. It is evaluated by the model's
:meth:`~tapm_opt.models.mooring.MooringModel.load_evaluator` (the same catenary, tabulated per line
configuration: each line's horizontal tension within 1e-9 of ``MooringModel.force``'s, relative to
its tension or pretension; exact ``force`` beyond the tables), a few microseconds per step instead
of a catenary solve per line.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import TapmError
from ..geometry import rot_z, ssa
from ..interfaces import Estimate, Measurement
from ..models.mooring import MooringModel
from .reliability import monitor_signals

__all__ = ["LowPassEstimator", "TrueStateEstimator", "EstimationError", "critically_damped_step",
           "estimator_complement"]


class EstimationError(TapmError, ValueError):
    """Bad estimator settings or measurements."""


class _WithDetectorAndMonitor:
    """The parts every estimator here carries: an optional line-break detector and reliability
    monitor, fed the measured tensions (and riser angles), reset with the estimator, their log
    shared; and, for the model-based ones, the mooring load of the model and the switch to the
    model without a detected line."""

    detector: Any = None
    monitor: Any = None
    _load_of: Any = None
    _eta_det: Any = None

    def log(self) -> list[dict]:
        """The detector's events (``{"t", "line", "event"}``, a buoy loss's with its ``"joint"``), if
        there is a detector."""
        return [] if self.detector is None else list(self.detector.events)

    @property
    def lost_points(self) -> frozenset:
        """The buoys the detector reports lost, (line id, joint) (empty without a detector or one
        that tests no buoy)."""
        return frozenset() if self.detector is None else getattr(self.detector, "lost_points", frozenset())

    def _reset_parts(self) -> None:
        for part in (self.detector, self.monitor):
            if part is not None:
                part.reset()

    def _detect(self, t: float, m: Measurement, eta: np.ndarray | None = None) -> frozenset:
        """The lines the detector reports broken so far (empty without a detector or tensions).
        ``eta`` is the estimator's latest LF pose (None before its first estimate): a model-based
        detector compares the measured tensions with the line model's at that pose."""
        if self.detector is None or m.tensions is None:
            return frozenset()
        return self.detector.update(t, m.tensions, eta)

    def mooring_load(self, eta: Any) -> np.ndarray:
        """Mooring load (3,) in {B} [N, N, N m] at pose ``eta`` of the estimator's model: its
        tabulated evaluator (each line's horizontal tension within 1e-9 of ``MooringModel.force``'s),
        or ``self.model.force`` for a model without one; rebuilt when the model is replaced."""
        if self._load_of is not self.model:  # first call, or the model was replaced
            make = getattr(self.model, "load_evaluator", None)
            try:
                self._load = make() if make is not None else self.model.force
            except TapmError:  # no table for this model: the exact load
                self._load = self.model.force
            self._load_of = self.model
        return self._load(eta)

    def _broken(self, t: float, m: Measurement) -> frozenset:
        """Feed the detector (with the previous LF pose ``self._eta_det``); on a new break, leave
        the line out of the model, on a buoy found lost take it off its line
        (``self.model = self.intact_model.damaged(broken, lost_points)``)."""
        broken = self._detect(t, m, self._eta_det)
        lost = self.lost_points
        if (broken and set(broken) & set(self.model.line_ids)) or \
                (lost and lost != frozenset(getattr(self.model, "lost_points", ()))):
            self.model = self.intact_model.damaged(broken, lost)
        return broken

    def _reliability(self, t: float, m: Measurement) -> Any:
        """Feed the monitor the measured tensions and riser-angle magnitudes (when it has both)."""
        if self.monitor is None or m.tensions is None:
            return None
        return self.monitor.update(t, monitor_signals(m.tensions, m.riser_angles, self.monitor.m))


class LowPassEstimator(_WithDetectorAndMonitor):
    """Low-pass state and environmental-load estimate (module docstring).

    Parameters
    ----------
    model : MooringModel
        Mooring model used for the load balance.
    omega_c : float
        Cut-off of the position/heading filters [rad/s] (default 2 pi / 40 s).
    T_env : float
        Time constant of the environmental-load filter [s].
    detector : TensionResidualDetector or TensionDropDetector, optional
        Line-break detector fed with the measured tensions (and the previous LF pose): the lines it reports broken are left
        out of the load balance's model from then on and reported in ``Estimate.broken_lines``.
    monitor : ReliabilityMonitor, optional
        On-line reliability statistics of the measured tensions and riser angles
        (:func:`~tapm_opt.estimation.reliability.monitor_for`), handed on as
        ``Estimate.reliability``.
    """

    def __init__(self, model: MooringModel, *, omega_c: float = 2 * math.pi / 40.0, T_env: float = 60.0,
                 detector: Any = None, monitor: Any = None):
        for name, v in (("omega_c", omega_c), ("T_env", T_env)):
            if not (math.isfinite(v) and v > 0):
                raise EstimationError(f"{name} = {v!r} must be a positive number")
        self.model = self.intact_model = model
        self.detector = detector
        self.monitor = monitor
        self.omega_c = float(omega_c)
        self.T_env = float(T_env)
        self._y = None  # filtered (x, y, psi_unwrapped)
        self._yd = np.zeros(3)
        self._psi_prev = None
        self._b = None
        self._t = None
        self._load = None  # the mooring-load evaluator, built on first use for self.model
        self._load_of = None
        self._eta_det = None  # the latest estimate of eta, for a model-based detector

    def reset(self) -> None:
        self._y, self._yd, self._psi_prev, self._b, self._t = None, np.zeros(3), None, None, None
        self._eta_det = None
        self.model = self.intact_model
        self._reset_parts()

    def update(self, t: float, measurement: Measurement) -> Estimate:
        """The :class:`~tapm_opt.interfaces.Estimator` step: filter the measured position and
        heading; the thrust in the load balance is the thruster feedback ``measurement.tau_thr``
        (zero when the measurement carries none). The measured tensions and riser angles pass
        through unfiltered."""
        m = measurement
        tau_thr = np.zeros(3) if m.tau_thr is None else m.tau_thr
        broken = self._broken(t, m)
        pos = m.position
        if not m.position_valid:   # no GNSS fix: the filtered position in its place (held)
            if self._y is None:
                raise EstimationError(f"measurement.position_valid is False at the first update (t = {t!r} s): "
                                      "the estimator needs one GNSS fix to start")
            pos = self._y[:2].copy()
        eta, nu, tau_env = self.filter(t, pos, m.heading, tau_thr)
        self._eta_det = eta
        eta_wf = np.array([pos[0] - eta[0], pos[1] - eta[1], ssa(m.heading - eta[2])])
        return Estimate(t=t, eta=eta, nu=nu, tau_env=tau_env, tensions=m.tensions, riser_angles=m.riser_angles,
                        broken_lines=broken, reliability=self._reliability(t, m), eta_wf=eta_wf,
                        lost_points=self.lost_points)

    def filter(self, t: float, position: np.ndarray, heading: float, tau_thr: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Feed one measurement; returns (eta_hat (3,), nu_hat (3,), tau_env_hat (3,) in {B}).

        Parameters
        ----------
        t : float
            Time [s] (non-decreasing).
        position : (2,) measured position in {E} [m].
        heading : measured heading [rad].
        tau_thr : (3,) thrust applied in {B} [N, N, N m] (the command of the previous step).
        """
        z = np.array([position[0], position[1], heading], dtype=float)
        if not np.all(np.isfinite(z)):
            raise EstimationError(f"measurement position = {list(position)}, heading = {heading!r} must be finite")
        if self._y is None:
            self._y = z.copy()
            self._psi_prev = heading
            self._t = t
        else:
            dt = t - self._t
            if dt < 0:
                raise EstimationError(f"t = {t!r} s is before the previous update {self._t!r} s")
            self._t = t
            z[2] = self._y[2] + ssa(heading - self._y[2])  # unwrap next to the filtered heading
            self._filter(z, dt)
        eta = np.array([self._y[0], self._y[1], ssa(self._y[2])])
        R = rot_z(eta[2])
        nu = R.T @ self._yd
        b_now = R @ (-(self.mooring_load(eta) + np.asarray(tau_thr, float)))
        if self._b is None:
            self._b = b_now
        else:
            self._b = first_order_step(self._b, b_now, t - self._t_env, self.T_env)
        self._t_env = t
        return eta, nu, R.T @ self._b

    def _filter(self, z: np.ndarray, dt: float) -> None:
        """Exact discretisation of y'' = w^2 (z - y) - 2 w y' over dt with z held."""
        if dt == 0:
            return
        self._y, self._yd = critically_damped_step(self._y, self._yd, z, self.omega_c, dt)


def first_order_step(y: Any, u: Any, dt: float, T: float) -> Any:
    """One exact step of the first-order low-pass ``T y' = u - y`` over ``dt`` [s] with the input
    ``u`` held (time constant ``T`` [s]; floats or arrays): the new ``y``. A step back in time
    (``dt < 0``) holds ``y``. The filter of :class:`LowPassEstimator`'s load, the MPC's load and
    riser-angle filters and the setpoint layers' averages."""
    a = math.exp(-max(dt, 0.0) / T)
    return a * y + (1.0 - a) * u


def critically_damped_step(y: Any, yd: Any, z: Any, w: float, dt: float) -> tuple[Any, Any]:
    """One exact step of ``y'' = w^2 (z - y) - 2 w y'`` over ``dt`` [s] with the input ``z`` held
    (cut-off ``w`` [rad/s]; floats or arrays): the new ``(y, y')``. The filter of
    :class:`LowPassEstimator`, also what a sea-state supervisor models its ``eta_wf`` with."""
    e = y - z
    ex = math.exp(-w * dt)
    # critically damped: e(t) = (e0 + (ed0 + w e0) t) exp(-w t)
    c1 = yd + w * e
    return z + (e + c1 * dt) * ex, (c1 - w * (e + c1 * dt)) * ex


def estimator_complement(dt: float, omega_c: float) -> tuple[np.ndarray, np.ndarray]:
    """``(b, a)`` of ``z - y`` with y the low-pass of :class:`LowPassEstimator` (critically
    damped, cut-off ``omega_c`` [rad/s], exact over ``dt`` [s] with the new sample held): the
    transfer function (``scipy.signal.lfilter`` coefficients) of its ``eta_wf``. The state-space
    matrices are read off the estimator's recursion (:func:`critically_damped_step`) itself. The
    sea-state supervisor's expected wave-frequency features (``design.wave_reference``) pass the
    plant's wave motion through it."""
    import scipy.signal

    def step(y: float, yd: float, z: float) -> tuple[float, float]:  # the estimator's own recursion
        return critically_damped_step(y, yd, z, omega_c, dt)

    A = np.array([step(1.0, 0.0, 0.0), step(0.0, 1.0, 0.0)]).T
    B = np.array(step(0.0, 0.0, 1.0)).reshape(2, 1)
    C = np.array([[1.0, 0.0]])
    # s_k = A s_{k-1} + B z_k, out_k = z_k - C s_k: state x_k = s_{k-1}
    b, a = scipy.signal.ss2tf(A, B, -C @ A, 1.0 - C @ B)
    return np.atleast_1d(np.squeeze(b)), np.asarray(a, float)


class TrueStateEstimator(_WithDetectorAndMonitor):
    """Validation estimator: hands on the plant's true LF state and mean environmental load
    (``measurement.truth``), to separate controller performance from estimation error; the
    measured tensions and riser angles pass through."""

    def __init__(self, *, detector: Any = None, monitor: Any = None):
        self.detector = detector
        self.monitor = monitor

    def update(self, t: float, measurement: Measurement) -> Estimate:
        tr = measurement.truth
        if tr is None:
            raise EstimationError("the measurement carries no truth: TrueStateEstimator needs a simulated plant")
        return Estimate(t=t, eta=tr.eta, nu=tr.nu, tau_env=tr.tau_env, tensions=measurement.tensions,
                        riser_angles=measurement.riser_angles, broken_lines=self._detect(t, measurement, tr.eta),
                        reliability=self._reliability(t, measurement), lost_points=self.lost_points)

    def reset(self) -> None:
        self._reset_parts()
