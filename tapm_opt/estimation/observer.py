"""Model-based DP observers with wave filtering and bias estimation: a nonlinear passive observer
and a discrete extended Kalman filter, both :class:`~tapm_opt.interfaces.Estimator` s.

Observer model (seed *tension-based-anchor-slam*, eq. 1a–1e; Fossen 2011, Handbook §11.3–11.4),
with ``eta = (x, y, psi)`` [m, m, rad] in {E}, ``nu = (u, v, r)`` [m/s, m/s, rad/s] in {B}::

    eta'  = R(psi) nu                                   (1a)
    b'    = -T_b^-1 b + E_b w_b                         (1b)  b in {E} [N, N, N m]
    M nu' = -D nu + R(psi)^T b + tau_m(eta) + tau_c     (1c)
    xi'   = A_w xi + E_w w_w                            (1d)
    eta_w = C_w xi                                      (1e)
    y     = eta + eta_w + v                             (measured x, y, psi)

``M`` (incl. added mass) and ``D = D_lin`` are the design model's
(:meth:`~tapm_opt.models.vessel.VesselParams.from_scenario`); ``tau_m(eta)`` is the line system's
quasi-static mooring load in {B} (:class:`~tapm_opt.models.mooring.MooringModel`, evaluated by its
tabulated :meth:`~tapm_opt.models.mooring.MooringModel.load_evaluator`, as in
:class:`~tapm_opt.estimation.lowpass.LowPassEstimator`); ``tau_c`` is the delivered thrust of the
thruster feedback (``Measurement.tau_thr``, zeros when absent). The bias ``b`` takes whatever the
model leaves out — wind, wave drift, the current's damping, mooring-model error — so
``Estimate.tau_env = R(psi)^T b`` ({B}). The wave-frequency (WF) model is, per DOF i, the
second-order resonator (Fossen 2011 eq. 8.125) with ``xi = (xi_1, xi_2)``, ``xi_1 = int eta_w``::

    A_w = [[0, I], [-Omega^2, -2 Lambda Omega]],  C_w = [0, I],  E_w = [0; diag(sigma_w)]

``Omega = omega_0 I`` (``omega_0 = 2 pi / Tp`` of the sea state, or given; without either the
default peak period :data:`DEFAULT_TP` = 10 s) and ``Lambda = lambda I`` (relative damping, default
0.1). ``Estimate.eta_wf = C_w xi_hat`` ({E}); ``Estimate.eta`` is the LF estimate.

A detected broken line (``detector``, e.g. :class:`~tapm_opt.estimation.detection.TensionDropDetector`)
leaves the model (``self.model = self.intact_model.without(broken)``) from then on, so its lost
restoring load is not absorbed into the bias; so does a buoy the detector reports lost (the model
is ``intact_model.damaged(broken, lost_points)``). ``Estimate.broken_lines``, ``lost_points`` and
``reliability`` come from the shared detector/monitor base, the measured tensions and riser angles
pass through.

Without a GNSS fix (``Measurement.position_valid`` False: a dropout) the position is not
corrected: the EKF only predicts x and y (its covariance grows), the passive observer takes its
own prediction as the measurement (zero position innovation): dead reckoning on the model (1a)-(1c)
with the bias held. A redundant position reference that takes over instead is
:class:`~tapm_opt.estimation.redundancy.SensorVoting`.

Headings are unwrapped next to the observer's predicted heading (``ssa`` of the difference), the
internal LF heading is continuous and reported wrapped to [-pi, pi).

:class:`PassiveObserver` — Fossen & Strand (1999), Fossen 2011 §11.4.1, eq. (11.117)–(11.121),
with the mooring load added to the kinetics exactly as eq. (1c) has it::

    y~      = y - eta_hat - C_w xi_hat
    xi_hat' = A_w xi_hat + K1 y~
    eta_hat'= R(psi) nu_hat + K2 y~
    b_hat'  = -T_b^-1 b_hat + K3 y~
    M nu_hat' = -D nu_hat + R^T b_hat + tau_m(eta_hat) + tau_c + R^T K4 y~

Gains (Fossen 2011 eq. 11.123–11.124, per DOF): ``K1 = [diag(-2 (zeta_n - lambda) omega_c /
omega_0); diag(2 omega_0 (zeta_n - lambda))]``, ``K2 = diag(omega_c)``. Without the LF kinetics
they make the measurement-to-``eta_hat`` transfer a notch at ``omega_0`` times a first-order
low-pass at ``omega_c``: ``(s^2 + 2 lambda omega_0 s + omega_0^2) omega_c / ((s^2 + 2 zeta_n omega_0 s
+ omega_0^2)(s + omega_c))``. Defaults ``zeta_n = 1.1``, ``omega_c = 1.05 omega_0``: a moored ship's
WF surge motion has its energy below the wave peak (the surge RAO rises towards long periods; on
fpso 80 % of it lies in about 0.75–1.05 omega_0), on the notch's lower flank; the wider notch and
the cut-off just above ``omega_0`` (passivity needs only ``omega_c > omega_0``) attenuate that
flank (``|y -> eta_hat|`` at 0.8 omega_0: 0.17, against 0.20 with ``zeta_n = 1``, ``omega_c = 1.2
omega_0``) for 0.3 / omega_0 more low-frequency delay (docs/estimation.md). ``K3`` and ``K4``
must satisfy the passivity ordering ``1/T_b << K3/K4 < omega_0 < omega_c`` (Fossen 2011 eq. 11.137);
the defaults place the linearised LF error dynamics per DOF, ``m s^3 + (d + m omega_c) s^2 + (d
omega_c + k + K4) s + K3 = 0`` (``m = M_ii``, ``d = D_ii``, ``k`` the mooring stiffness ``K_ii`` at the
field zero point), at ``(s + p)(s^2 + 2 zeta_b omega_b s + omega_b^2)`` with ``p = omega_c + d/m - 2
zeta_b omega_b``: ``K3 = m p omega_b^2``, ``K4 = m (2 zeta_b omega_b p + omega_b^2) - d omega_c - k``,
with the bias bandwidth ``omega_b`` (default 2 pi / 200 s) and ``zeta_b = 1``; this gives ``K3/K4 ~
omega_b / 2``, inside the passivity ordering. Default ``T_b = 1e4 s`` (a constant load is estimated
``1 / (1 + K4 / (T_b K3))`` of its size: 0.6 % low; 6 % with Fossen's usual 1000 s).

Discretisation (passive): the measurement ``y_k`` that arrives at ``t_k`` is held over the step
``(t_{k-1}, t_k]`` (zero-order hold; between sensor samples the sensors' held values are used as
delivered). The fast linear part per DOF, ``(xi_1, xi_2, eta_hat)`` with the injection ``K1 y~, K2 y~``
and the input ``R(psi) nu_hat`` held, is integrated exactly (matrix exponential, cached per step
length), so the wave filter is stable and exact at any ``dt``; the slow part — ``b_hat`` (exact
exponential decay with ``K3 y~`` held) and ``nu_hat`` (damping implicit, ``(I + dt M^-1 D)^-1``) — is
advanced first, from the innovation at the start of the step, and the fast part then uses the new
``nu_hat`` (semi-implicit, like the plant's ``nu``-then-``eta`` Euler step). ``innovation`` is the
continuous observer's injection signal ``y~(t_k) = y_k - y_hat(t_k)`` after the step.

:class:`EKFObserver` — discrete extended Kalman filter on the same model, state ``x = (xi_1 (3),
xi_2 (3), eta (3), nu (3), b (3))``, 15 states. Prediction over ``dt``: ``xi`` by the exact
``exp(A_w dt)`` (process noise by Van Loan's method, both cached per step length), ``b`` by the exact
decay ``exp(-dt/T_b)``, ``nu`` then ``eta`` by the semi-implicit Euler step with implicit damping;
the covariance with the exact Jacobian of that discrete map. The mooring Jacobian ``d tau_m / d
eta`` is by central differences of the load evaluator (steps 0.1 m, 0.1 m, 1e-3 rad), refreshed
when the estimated pose has moved more than (1 m, 1 m, 0.01 rad) from where it was last taken or
the model changed. Correction only at new sensor samples (``Measurement.t_position`` and
``t_heading`` later than the last used ones; without a new sample the filter dead-reckons),
``R = diag(gnss_std^2, gnss_std^2, heading_std^2)``; Joseph-form covariance update, symmetrised.
``innovation`` (3,) and ``innovation_cov`` (3, 3) are the a-priori ``y - H x_hat^-`` and ``H P^- H^T +
R`` of the latest update (all three components; ``innovation_mask`` says which were used).
Process noise: the WF intensity from the expected WF standard deviation per DOF (``wf_std``:
stationary variance ``sigma_w^2 / (4 lambda omega_0)`` of (1d)), the bias as a Gauss-Markov process
of stationary standard deviation ``bias_std`` (``q_b = 2 bias_std^2 / T_b``), and a small white
force ``force_noise`` [N/sqrt(Hz)] on the kinetics (gusts, unmodelled damping).

Validation figures and the recommended closed-loop default: ``docs/estimation.md`` ("Observers").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.linalg import expm

from .._checks import vector
from ..errors import TapmError
from ..interfaces import Estimate, Measurement, _frozen, _trusted
from ..models.mooring import MooringModel
from ..models.vessel import VesselParams
from .lowpass import EstimationError, _WithDetectorAndMonitor
from .ekf_kernel import kernels as ekf_kernels

__all__ = ["PassiveObserver", "EKFObserver", "wave_filter_matrices", "passive_gains", "DEFAULT_TP",
           "PASSIVE_ZETA_N", "PASSIVE_OMEGA_C_RATIO", "EstimationError"]

#: Peak period [s] of the WF model when neither ``omega_0`` nor a sea state is given.
DEFAULT_TP = 10.0

#: Default relative damping of the passive observer's notch [-] (module docstring: why 1.1).
PASSIVE_ZETA_N = 1.1

#: Default cut-off of the passive observer's wave filter, ``omega_c / omega_0`` [-] (> 1: passivity).
PASSIVE_OMEGA_C_RATIO = 1.05

_TWO_PI = 2.0 * math.pi


def _wrap(a: float) -> float:
    """Smallest signed angle of a float [rad], in [-pi, pi)."""
    return a - _TWO_PI * math.floor((a + math.pi) / _TWO_PI)


def _number(name: str, v: Any, *, lo: float | None = None, hi: float | None = None, strict_lo: bool = True,
            unit: str = "") -> float:
    """``v`` as a finite float in the range, else EstimationError naming ``name`` and the value."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise EstimationError(f"{name} = {v!r} must be a number{' [' + unit + ']' if unit else ''}") from None
    if isinstance(v, bool) or not math.isfinite(x):
        raise EstimationError(f"{name} = {v!r} must be a finite number{' [' + unit + ']' if unit else ''}")
    if lo is not None and (x <= lo if strict_lo else x < lo):
        raise EstimationError(f"{name} = {v!r}{' ' + unit if unit else ''} must be {'>' if strict_lo else '>='} {lo:g}")
    if hi is not None and x > hi:
        raise EstimationError(f"{name} = {v!r}{' ' + unit if unit else ''} must be <= {hi:g}")
    return x


def _vec3(name: str, v: Any, *, lo: float = 0.0, strict: bool = True, unit: str = "") -> np.ndarray:
    """A scalar or 3 numbers as a float (3,) array, each ``> lo`` (``>= lo`` if not strict)."""
    return vector(name, v, 3, lo=lo, strict=strict, unit=unit, what="(x, y, psi)", broadcast=True,
                  error=EstimationError)


def wave_filter_matrices(omega_0: float, lam: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """``A_w`` (6, 6) and ``C_w`` (3, 6) of eq. (1d)–(1e) for ``xi = (xi_1 (3), xi_2 (3))``:
    ``A_w = [[0, I], [-omega_0^2 I, -2 lam omega_0 I]]`` [1/s, 1/s^2], ``C_w = [0, I]``.

    Parameters
    ----------
    omega_0 : float
        WF peak frequency [rad/s], > 0.
    lam : float
        Relative damping of the resonator [-], in (0, 1.5].
    """
    w = _number("omega_0", omega_0, lo=0.0, unit="rad/s")
    lam = _number("lam", lam, lo=0.0, hi=1.5)
    I = np.eye(3)
    A = np.block([[np.zeros((3, 3)), I], [-w * w * I, -2.0 * lam * w * I]])
    C = np.hstack([np.zeros((3, 3)), I])
    return A, C


def passive_gains(omega_0: float, lam: float = 0.1, zeta_n: float = PASSIVE_ZETA_N,
                  omega_c: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Wave-filter gains ``K1`` (6, 3) and ``K2`` (3, 3) of the passive observer (Fossen 2011
    eq. 11.123–11.124): ``K1 = [diag(-2 (zeta_n - lam) omega_c / omega_0); diag(2 omega_0 (zeta_n -
    lam))]`` [-, rad/s], ``K2 = diag(omega_c)`` [rad/s]; ``zeta_n`` default :data:`PASSIVE_ZETA_N`
    (1.1), ``omega_c`` default :data:`PASSIVE_OMEGA_C_RATIO` ``omega_0`` (1.05 omega_0).

    Raises EstimationError unless ``0 < lam < zeta_n <= 1.5`` and ``omega_c > omega_0`` (the
    notch needs ``zeta_n > lam``; passivity ``omega_0 < omega_c``, Fossen 2011 eq. 11.137).
    """
    w = _number("omega_0", omega_0, lo=0.0, unit="rad/s")
    lam = _number("lam", lam, lo=0.0, hi=1.5)
    zeta_n = _number("zeta_n", zeta_n, lo=0.0, hi=1.5)
    if zeta_n <= lam:
        raise EstimationError(f"zeta_n = {zeta_n!r} must exceed lam = {lam!r} (the notch's damping above the "
                              "wave resonator's)")
    wc = PASSIVE_OMEGA_C_RATIO * w if omega_c is None else _number("omega_c", omega_c, lo=0.0, unit="rad/s")
    if wc <= w:
        raise EstimationError(f"omega_c = {wc!r} rad/s must exceed omega_0 = {w!r} rad/s (passivity: "
                              "omega_0 < omega_c)")
    I = np.eye(3)
    K1 = np.vstack([-2.0 * (zeta_n - lam) * wc / w * I, 2.0 * w * (zeta_n - lam) * I])
    return K1, wc * I


def _omega_0(omega_0: Any, sea_state: Any) -> float:
    """The WF peak frequency [rad/s]: ``omega_0`` if given, else 2 pi / Tp of ``sea_state``, else
    2 pi / DEFAULT_TP."""
    if omega_0 is not None:
        return _number("omega_0", omega_0, lo=0.0, unit="rad/s")
    if sea_state is None:
        return _TWO_PI / DEFAULT_TP
    if isinstance(sea_state, str):
        raise EstimationError(f"sea_state = {sea_state!r}: give a SeaState object here, or use from_scenario() "
                              "to look a sea state up by its id")
    Tp = getattr(sea_state, "Tp", None)
    if Tp is None:
        raise EstimationError(f"sea_state = {sea_state!r} has no peak period Tp")
    return _TWO_PI / _number("sea_state.Tp", Tp, lo=0.0, unit="s")


class _ModelObserver(_WithDetectorAndMonitor):
    """What both observers share: the vessel and line models, the mooring-load evaluator, the
    line-break swap, the measurement checks and ``from_scenario``."""

    def _init_common(self, model: Any, vessel: Any, detector: Any, monitor: Any) -> None:
        if not callable(getattr(model, "force", None)):
            raise EstimationError(f"model = {model!r} must be a MooringModel (it has no force(eta))")
        if not isinstance(vessel, VesselParams):
            raise EstimationError(f"vessel = {vessel!r} must be a VesselParams (VesselParams.from_scenario(sc))")
        self.model = self.intact_model = model
        self.vessel = vessel
        self.detector = detector
        self.monitor = monitor
        self._M_inv = np.array(vessel.M_inv, dtype=float)
        self._D = np.array(vessel.D_lin, dtype=float)
        self._load = None
        self._load_of = None
        self._eta_det = None  # the latest LF pose, for a model-based detector

    @classmethod
    def from_scenario(cls, scenario_or_system: Any, sea_state: Any = None, **kw: Any):
        """The observer of a scenario or :class:`~tapm_opt.models.system.System`: ``M`` (incl. added
        mass) and ``D_lin`` of the vessel, the intact line model (``system.lines``), the WF peak
        frequency ``2 pi / Tp`` of ``sea_state`` (an id of the scenario's sea states or a SeaState;
        None: ``DEFAULT_TP``) and, for the EKF, the sensor noise of ``scenario.sensors`` and the
        expected WF motion from the sea state's ``Hs``. Keyword arguments override any of these."""
        from ..models.system import System

        if isinstance(scenario_or_system, System):
            system = scenario_or_system
            sc = system.scenario
            model, vessel = system.lines, system.vessel
        else:
            sc = scenario_or_system
            if not hasattr(sc, "vessel") or not hasattr(sc, "lines"):
                raise EstimationError(f"scenario_or_system = {scenario_or_system!r} is neither a Scenario nor a System")
            model, vessel = MooringModel.from_scenario(sc), VesselParams.from_scenario(sc)
        if isinstance(sea_state, str):
            try:
                sea_state = sc.sea_state(sea_state)
            except (KeyError, TapmError) as exc:
                raise EstimationError(f"sea_state = {sea_state!r}: {str(exc).strip(chr(39) + chr(34))}") from None
        kw = {**cls._scenario_kw(sc, sea_state), **kw}
        return cls(model, vessel, sea_state=sea_state, **kw)

    @classmethod
    def _scenario_kw(cls, sc: Any, sea_state: Any) -> dict:
        return {}

    def _read(self, t: Any, m: Measurement) -> tuple[float, np.ndarray, np.ndarray]:
        """Check the time and the measurement; (t, y = (x, y, psi) raw, tau_c (3,) {B})."""
        if not isinstance(m, Measurement):
            raise EstimationError(f"measurement = {m!r} must be a Measurement")
        if type(t) is not float or not math.isfinite(t):
            t = _number("t", t, unit="s", lo=None)
        if self._t is not None and t < self._t:
            raise EstimationError(f"t = {t!r} s is before the previous update {self._t!r} s")
        p = m.position
        if p is None or np.shape(p) != (2,):
            raise EstimationError(f"measurement.position = {p!r} must be 2 numbers (x, y) [m]")
        y = np.array([p[0], p[1], m.heading], dtype=float)
        self._fix = m.position_valid
        if not (math.isfinite(y[0] + y[1] + y[2]) or (not self._fix and math.isfinite(y[2]))):
            raise EstimationError(f"measurement position = {list(p)}, heading = {m.heading!r} must be finite "
                                  "(a position without a GNSS fix is flagged position_valid = False)")
        if not self._fix and self._t is None:
            raise EstimationError(f"measurement.position_valid is False at the first update (t = {t!r} s): the "
                                  "observer needs one GNSS fix to start (or a redundant position reference: "
                                  "tapm_opt.estimation.redundancy)")
        if m.tau_thr is None:
            tau_c = np.zeros(3)
        else:
            tau_c = np.asarray(m.tau_thr, dtype=float)
            if tau_c.shape != (3,) or not math.isfinite(tau_c[0] + tau_c[1] + tau_c[2]):
                raise EstimationError(f"measurement.tau_thr = {np.ravel(tau_c).tolist()} must be 3 finite numbers "
                                      "(X [N], Y [N], N [N m]) or None")
        return t, y, tau_c

    def _estimate(self, t: float, m: Measurement, eta: np.ndarray, nu: np.ndarray, b: np.ndarray,
                  eta_wf: np.ndarray, broken: frozenset, lost: frozenset | None = None) -> Estimate:
        psi = eta[2]
        c, s = math.cos(psi), math.sin(psi)
        tau_env = np.array([c * b[0] + s * b[1], -s * b[0] + c * b[1], b[2]])
        est = np.array([eta[0], eta[1], _wrap(psi)])
        self._eta_det = est
        return _estimate_of(t, est, nu, tau_env, m, broken, self._reliability(t, m), eta_wf,
                            self.lost_points if lost is None else lost)


def _estimate_of(t: float, eta: np.ndarray, nu: np.ndarray, tau_env: np.ndarray, m: Measurement, broken: Any,
                 reliability: Any, eta_wf: np.ndarray, lost_points: frozenset = frozenset()) -> Estimate:
    """The :class:`Estimate` the constructor makes of these fields, without its copies: ``eta``,
    ``nu``, ``tau_env``, ``eta_wf`` are new float64 (3,) arrays of the caller's (made read-only
    here), the tensions and riser angles the measurement's read-only arrays (shared)."""
    if type(t) is not float or not (nu.flags.owndata and eta_wf.flags.owndata and nu.dtype == eta_wf.dtype == np.float64) \
            or type(broken) is not frozenset or not all(type(b) is str for b in broken) \
            or (m.tensions is not None and m.tensions.flags.writeable) \
            or (m.riser_angles is not None and m.riser_angles.flags.writeable):
        return Estimate(t=t, eta=eta, nu=nu, tau_env=tau_env, tensions=m.tensions, riser_angles=m.riser_angles,
                        broken_lines=broken, reliability=reliability, eta_wf=eta_wf, lost_points=lost_points)
    return _trusted(Estimate, t=t, eta=_frozen(eta), nu=_frozen(nu), tau_env=_frozen(tau_env), tensions=m.tensions,
                    riser_angles=m.riser_angles, broken_lines=broken, reliability=reliability,
                    eta_wf=_frozen(eta_wf), lost_points=lost_points)


def _implicit_damping(M_inv: np.ndarray, D: np.ndarray, dt: float) -> np.ndarray:
    """``(I + dt M^-1 D)^-1`` [-]: the implicit damping step of the kinetics (1c)."""
    return np.linalg.inv(np.eye(3) + dt * (M_inv @ D))


class PassiveObserver(_ModelObserver):
    """Nonlinear passive observer with wave filtering and bias estimation (Fossen & Strand 1999;
    Fossen 2011 §11.4.1) with the mooring load in the kinetics (module docstring).

    Parameters
    ----------
    model : MooringModel
        Line model of ``tau_m(eta)`` (eq. 1c).
    vessel : VesselParams
        ``M`` (incl. added mass) [kg, kg m^2] and ``D_lin`` [N s/m, N m s] of eq. (1c).
    omega_0 : float, optional
        WF peak frequency [rad/s]; default 2 pi / Tp of ``sea_state``, else 2 pi / DEFAULT_TP.
    sea_state : SeaState, optional
        Gives ``Tp`` [s] when ``omega_0`` is not given.
    lam : float
        Relative damping of the WF resonator (1d) [-], in (0, 1.5]; default 0.1.
    zeta_n : float
        Relative damping of the notch [-], in (lam, 1.5]; default :data:`PASSIVE_ZETA_N` = 1.1.
    omega_c : float, optional
        Cut-off of the wave filter [rad/s], > omega_0; default :data:`PASSIVE_OMEGA_C_RATIO`
        omega_0 = 1.05 omega_0.
    T_b : float or (3,)
        Bias time constants of (1b) [s], > 0; default 1e4 s. A constant load ``b`` is estimated as
        ``b / (1 + K4 / (T_b K3))`` in steady state (``b_hat' = 0`` needs ``y~ = b_hat / (T_b K3)``),
        about 0.6 % low with the default gains (6 % with T_b = 1000 s).
    omega_b : float
        Bandwidth of the bias estimation [rad/s] used for the default K3, K4 (module docstring);
        default 2 pi / 200 s.
    K3, K4 : float or (3,), optional
        Bias and kinetics injection gains (diagonal) [N/(m s), N/m; N m/(rad s), N m/rad]; default
        by the placement in the module docstring. Must satisfy K3/K4 < omega_0.
    detector, monitor :
        Optional line-break detector and reliability monitor (as for ``LowPassEstimator``).

    Attributes
    ----------
    innovation : ndarray (3,)
        The latest ``y~ = y - y_hat`` (x [m], y [m], psi [rad]); zeros before the first step.
    K1, K2, K3, K4 : ndarray
        The gains in use ((6, 3), (3, 3), (3,), (3,)).
    """

    def __init__(self, model: MooringModel, vessel: VesselParams, *, omega_0: float | None = None,
                 sea_state: Any = None, lam: float = 0.1, zeta_n: float = PASSIVE_ZETA_N,
                 omega_c: float | None = None,
                 T_b: Any = 1.0e4, omega_b: float = _TWO_PI / 200.0, K3: Any = None, K4: Any = None,
                 detector: Any = None, monitor: Any = None):
        self._init_common(model, vessel, detector, monitor)
        w0 = _omega_0(omega_0, sea_state)
        self.K1, self.K2 = passive_gains(w0, lam, zeta_n, omega_c)
        self.omega_0, self.lam, self.zeta_n = w0, float(lam), float(zeta_n)
        self.omega_c = float(self.K2[0, 0])
        self.T_b = _vec3("T_b", T_b, unit="s")
        self.omega_b = _number("omega_b", omega_b, lo=0.0, unit="rad/s")
        if self.omega_b >= w0:
            raise EstimationError(f"omega_b = {omega_b!r} rad/s must be below omega_0 = {w0:g} rad/s")
        wc, wb = self.omega_c, self.omega_b
        m = np.diag(vessel.M).astype(float)
        d = np.diag(vessel.D_lin).astype(float)
        if K3 is None or K4 is None:
            try:
                k = np.clip(np.diag(model.stiffness(np.zeros(3))), 0.0, None)
            except (TapmError, AttributeError, ValueError):
                k = np.zeros(3)
            p = wc + d / m - 2.0 * wb
            if np.any(p <= 0):
                raise EstimationError(f"omega_b = {wb!r} rad/s is too large for omega_c = {wc:g} rad/s "
                                      f"(the fast pole p = {p.tolist()} must be > 0)")
            K3d = m * p * wb * wb
            K4d = m * (2.0 * wb * p + wb * wb) - d * wc - k
            K4d = np.maximum(K4d, 0.05 * m * wb * p)  # keep it positive on a stiff, heavily damped DOF
        self.K3 = _vec3("K3", K3d if K3 is None else K3, unit="N/(m s)")
        self.K4 = _vec3("K4", K4d if K4 is None else K4, unit="N/m")
        ratio = self.K3 / self.K4
        if np.any(ratio >= w0):
            i = int(np.argmax(ratio >= w0))
            raise EstimationError(f"K3[{i}] / K4[{i}] = {ratio[i]:g} 1/s must be below omega_0 = {w0:g} rad/s "
                                  "(passivity, Fossen 2011 eq. 11.137)")
        # per-DOF fast subsystem z = (xi_1, xi_2, eta_hat), y~ = y - xi_2 - eta_hat
        k1, k2 = float(self.K1[0, 0]), float(self.K1[3, 0])
        self._A_fast = np.array([[0.0, 1.0 - k1, -k1],
                                 [-w0 * w0, -2.0 * self.lam * w0 - k2, -k2],
                                 [0.0, -wc, -wc]])
        self._B_fast = np.array([[k1, 0.0], [k2, 0.0], [wc, 1.0]])
        self._disc_dt = None
        self.reset()

    def reset(self) -> None:
        self._z = None          # (3, 3): rows xi_1, xi_2, eta_hat (psi unwrapped); columns x, y, psi
        self._nu = np.zeros(3)
        self._b = np.zeros(3)
        self._t = None
        self._eta_det = None
        self.innovation = np.zeros(3)
        self.model = self.intact_model
        self._reset_parts()

    def state(self, covariance: bool = True) -> dict:
        """The observer's state, to hand to another observer (:meth:`set_state`): ``z`` (3, 3)
        (rows xi_1, xi_2, eta with psi unwrapped), ``nu`` (3,), ``b`` (3,), the time ``t`` [s] and
        the latest ``innovation``; copies. ``covariance`` is ignored (the passive observer has
        none)."""
        return {"z": None if self._z is None else self._z.copy(), "nu": self._nu.copy(), "b": self._b.copy(),
                "t": self._t, "innovation": np.array(self.innovation, float)}

    def set_state(self, state: dict) -> None:
        """Take a :meth:`state` (of an observer fed the same measurements)."""
        self._z = None if state["z"] is None else np.array(state["z"], float)
        self._nu, self._b = np.array(state["nu"], float), np.array(state["b"], float)
        self._t = state["t"]
        self.innovation = np.array(state["innovation"], float)

    def estimate_now(self, t: float, m: Measurement) -> Estimate:
        """The estimate of the present state at ``t`` (measurement ``m`` for the pass-through
        fields), without an update; no broken line reported."""
        return self._estimate(t, m, self._z[2], self._nu.copy(), self._b, self._z[1].copy(), frozenset(), frozenset())

    def _discretise(self, dt: float) -> None:
        """Exact ZOH discretisation of the fast subsystem over ``dt`` [s] (cached), and the implicit
        damping of the slow one."""
        n = 3
        aug = np.zeros((n + 2, n + 2))
        aug[:n, :n] = self._A_fast * dt
        aug[:n, n:] = self._B_fast * dt
        E = expm(aug)
        self._Phi = E[:n, :n].copy()
        self._G_y = E[:n, n].copy()
        self._G_u = E[:n, n + 1].copy()
        self._A_nu = _implicit_damping(self._M_inv, self._D, dt)
        self._decay = np.exp(-dt / self.T_b)
        self._disc_dt = dt

    def update(self, t: float, measurement: Measurement) -> Estimate:
        """The :class:`~tapm_opt.interfaces.Estimator` step (module docstring): advance from the
        previous update to ``t`` [s] with the measured pose held; thrust = ``measurement.tau_thr``."""
        m = measurement
        t, y, tau_c = self._read(t, m)
        broken = self._broken(t, m)
        if self._z is None:
            self._z = np.zeros((3, 3))
            self._z[2] = y
            tm = self.mooring_load(y)
            c, s = math.cos(y[2]), math.sin(y[2])
            q = -(tm + tau_c)  # quasi-static balance, {B}, as the low-pass estimator's start
            self._b = np.array([c * q[0] - s * q[1], s * q[0] + c * q[1], q[2]])
            self._t = t
        else:
            dt = t - self._t
            self._t = t
            z = self._z
            y[2] = z[2, 2] + z[1, 2] + _wrap(y[2] - z[2, 2] - z[1, 2])  # unwrap next to y_hat
            if not self._fix:   # no GNSS fix: the predicted position in its place (no correction)
                y[:2] = z[1, :2] + z[2, :2]
            if dt > 0:
                self._step(dt, y, tau_c)
            else:
                self.innovation = y - z[1] - z[2]
        z = self._z
        return self._estimate(t, m, z[2], self._nu.copy(), self._b, z[1].copy(), broken)

    def _step(self, dt: float, y: np.ndarray, tau_c: np.ndarray) -> None:
        if self._disc_dt is None or abs(dt - self._disc_dt) > 1e-9 * max(1.0, dt):
            self._discretise(dt)
        z, nu, b = self._z, self._nu, self._b
        e0 = y - z[1] - z[2]
        eta = z[2]
        c, s = math.cos(eta[2]), math.sin(eta[2])
        # slow part first: bias (exact decay, K3 y~ held) and kinetics (implicit damping)
        a = self._decay
        b = a * b + (1.0 - a) * self.T_b * (self.K3 * e0)
        f = b + self.K4 * e0                      # {E}
        tm = self.mooring_load(eta)
        g = np.array([c * f[0] + s * f[1] + tm[0] + tau_c[0], -s * f[0] + c * f[1] + tm[1] + tau_c[1],
                      f[2] + tm[2] + tau_c[2]])
        nu = self._A_nu @ (nu + dt * (self._M_inv @ g))
        u = np.array([c * nu[0] - s * nu[1], s * nu[0] + c * nu[1], nu[2]])
        # fast part, exact: z+ = Phi z + G_y y + G_u u (per DOF, same matrices)
        z = self._Phi @ z + np.outer(self._G_y, y) + np.outer(self._G_u, u)
        self._z, self._nu, self._b = z, nu, b
        self.innovation = y - z[1] - z[2]


class EKFObserver(_ModelObserver):
    """Discrete extended Kalman filter on the observer model (1a)–(1e) (module docstring).

    Parameters
    ----------
    model : MooringModel
        Line model of ``tau_m(eta)`` (eq. 1c).
    vessel : VesselParams
        ``M`` (incl. added mass) and ``D_lin`` of eq. (1c).
    omega_0 : float, optional
        WF peak frequency [rad/s]; default 2 pi / Tp of ``sea_state``, else 2 pi / DEFAULT_TP.
    sea_state : SeaState, optional
        Gives ``Tp`` [s] when ``omega_0`` is not given.
    lam : float
        Relative damping of the WF resonator [-], in (0, 1.5]; default 0.1.
    T_b : float or (3,)
        Bias time constants [s], > 0; default 1000 s.
    gnss_std : float
        Position measurement noise per axis [m], >= 0 (floored at 1 mm); default 0.5 m.
    heading_std : float
        Heading measurement noise [rad], >= 0 (floored at 1e-5 rad); default 0.1 deg.
    wf_std : float or (3,)
        Expected standard deviation of the WF motion (x [m], y [m], psi [rad]), > 0, which sets the
        WF process noise; default (0.5 m, 0.5 m, 0.005 rad) (``from_scenario``: from the sea
        state's Hs, see :meth:`_scenario_kw`).
    bias_std : float or (3,)
        Stationary standard deviation of the bias (X [N], Y [N], N [N m]) in {E}, > 0; default
        (2 MN, 2 MN, 200 MN m).
    force_noise : float or (3,)
        White force noise on the kinetics [N/sqrt(Hz), N m/sqrt(Hz)], >= 0; default
        (1e5, 1e5, 1e7).
    detector, monitor :
        Optional line-break detector and reliability monitor.

    Attributes
    ----------
    x : ndarray (15,)
        State (xi_1, xi_2, eta, nu, b); ``P`` (15, 15) its covariance.
    innovation : ndarray (3,)
        A-priori innovation of the latest update (x [m], y [m], psi [rad]); zeros before one.
    innovation_cov : ndarray (3, 3)
        Its covariance ``H P^- H^T + R`` [m^2, m rad, rad^2].
    innovation_mask : ndarray of bool (3,)
        Which components were new samples and corrected the state.
    """

    def __init__(self, model: MooringModel, vessel: VesselParams, *, omega_0: float | None = None,
                 sea_state: Any = None, lam: float = 0.1, T_b: Any = 1000.0, gnss_std: float = 0.5,
                 heading_std: float = math.radians(0.1), wf_std: Any = (0.5, 0.5, 0.005),
                 bias_std: Any = (2.0e6, 2.0e6, 2.0e8), force_noise: Any = (1.0e5, 1.0e5, 1.0e7),
                 detector: Any = None, monitor: Any = None):
        self._init_common(model, vessel, detector, monitor)
        w0 = _omega_0(omega_0, sea_state)
        self.A_w, self.C_w = wave_filter_matrices(w0, lam)
        self.omega_0, self.lam = w0, float(lam)
        self.T_b = _vec3("T_b", T_b, unit="s")
        self.gnss_std = max(_number("gnss_std", gnss_std, lo=0.0, strict_lo=False, unit="m"), 1e-3)
        self.heading_std = max(_number("heading_std", heading_std, lo=0.0, strict_lo=False, unit="rad"), 1e-5)
        self.wf_std = _vec3("wf_std", wf_std)
        self.bias_std = _vec3("bias_std", bias_std, unit="N")
        self.force_noise = _vec3("force_noise", force_noise, strict=False, unit="N/sqrt(Hz)")
        self._r = np.array([self.gnss_std ** 2, self.gnss_std ** 2, self.heading_std ** 2])
        self._R = np.diag(self._r)
        # WF noise intensity: stationary var of xi_2 = q / (4 lam omega_0)
        self._q_w = 4.0 * self.lam * w0 * self.wf_std ** 2
        self._q_b = 2.0 * self.bias_std ** 2 / self.T_b
        Mi = self._M_inv
        self._Q_nu = Mi @ np.diag(self.force_noise ** 2) @ Mi.T
        H = np.zeros((3, 15))
        H[:, 3:6] = np.eye(3)
        H[:, 6:9] = np.eye(3)
        self._H = H
        self._I15 = np.eye(15)
        self._disc_dt = None
        self._J = np.zeros((3, 3))
        self._J_at = None
        self._J_of = None
        self.reset()

    @classmethod
    def _scenario_kw(cls, sc: Any, sea_state: Any) -> dict:
        """From the scenario: ``gnss_std`` [m] and ``heading_std`` [rad] of ``scenario.sensors``;
        with a sea state, ``wf_std = (0.04 Hs, 0.04 Hs, 4e-4 Hs / m)`` [m, m, rad] (a conservative
        bound of the fpso's WF motion: 0.11 m in x at Hs 7 m, 0.40 m at Hs 10 m, the heading's far
        smaller; docs/estimation.md) and floored at 5 cm, 5 cm, 5e-4 rad."""
        kw = {"gnss_std": float(sc.sensors.gnss_std), "heading_std": float(sc.sensors.heading_std)}
        if sea_state is not None and getattr(sea_state, "Hs", None) is not None:
            Hs = float(sea_state.Hs)
            kw["wf_std"] = (max(0.04 * Hs, 0.05), max(0.04 * Hs, 0.05), max(4e-4 * Hs, 5e-4))
        return kw

    def reset(self) -> None:
        self.x = None
        self.P = None
        self._t = None
        self._t_pos = self._t_hdg = -math.inf
        self._eta_det = None
        self._J_at = None
        self.innovation = np.zeros(3)
        self.innovation_cov = np.zeros((3, 3))
        self.innovation_mask = np.zeros(3, dtype=bool)
        self.model = self.intact_model
        self._reset_parts()

    def state(self, covariance: bool = True) -> dict:
        """The filter's state, to hand to another filter (:meth:`set_state`): ``x`` (15,), ``P``
        (15, 15) if ``covariance``, the sample times ``t_position``, ``t_heading``, the time ``t``
        [s], the latest ``innovation`` and the mooring Jacobian with the pose it was taken at
        (``J``, ``J_at``: reused within 1 m / 0.01 rad, so a filter given the state continues
        exactly as the one it came from, on the same model); copies."""
        return {"x": None if self.x is None else self.x.copy(),
                "P": None if (self.P is None or not covariance) else self.P.copy(),
                "t_position": self._t_pos, "t_heading": self._t_hdg, "t": self._t,
                "innovation": np.array(self.innovation, float),
                "J": self._J.copy(), "J_at": None if self._J_at is None else self._J_at.copy()}

    def set_state(self, state: dict) -> None:
        """Take a :meth:`state` (of a filter fed the same measurements, on the same line model:
        its mooring Jacobian is taken over); without ``P`` the covariance is kept."""
        self.x = None if state["x"] is None else np.array(state["x"], float)
        if state.get("P") is not None:
            self.P = np.array(state["P"], float)
        self._t_pos, self._t_hdg, self._t = state["t_position"], state["t_heading"], state["t"]
        self.innovation = np.array(state["innovation"], float)
        if state.get("J_at") is not None:   # the Jacobian of this observer's model at that pose
            self._J, self._J_at, self._J_of = np.array(state["J"], float), np.array(state["J_at"], float), self.model

    def estimate_now(self, t: float, m: Measurement) -> Estimate:
        """The estimate of the present state at ``t`` (measurement ``m`` for the pass-through
        fields), without an update; no broken line reported."""
        x = self.x
        return self._estimate(t, m, x[6:9], x[9:12].copy(), x[12:], x[3:6].copy(), frozenset(), frozenset())

    def _discretise(self, dt: float) -> None:
        """Exact WF transition and process noise (Van Loan) over ``dt`` [s], the bias decay and its
        noise, the kinetics' implicit damping (cached per step length)."""
        Ew = np.zeros((6, 3))
        Ew[3:, :] = np.diag(np.sqrt(self._q_w))
        vl = np.zeros((12, 12))
        vl[:6, :6] = -self.A_w * dt
        vl[:6, 6:] = Ew @ Ew.T * dt
        vl[6:, 6:] = self.A_w.T * dt
        E = expm(vl)
        Phi_w = E[6:, 6:].T
        Q_w = Phi_w @ E[:6, 6:]
        Q = np.zeros((15, 15))
        Q[:6, :6] = 0.5 * (Q_w + Q_w.T)
        Q[9:12, 9:12] = self._Q_nu * dt
        a = np.exp(-dt / self.T_b)
        Q[12:, 12:] = np.diag(self._q_b * self.T_b / 2.0 * (1.0 - a * a))
        self._Q = Q
        Phi = np.eye(15)
        Phi[:6, :6] = Phi_w
        Phi[12:, 12:] = np.diag(a)
        self._Phi = Phi
        self._Phi_w = Phi_w
        self._decay = a
        self._A_nu = _implicit_damping(self._M_inv, self._D, dt)
        self._G = dt * (self._A_nu @ self._M_inv)
        self._X = np.zeros((3, 9))
        self._disc_dt = dt

    def _jacobian(self, eta: np.ndarray) -> np.ndarray:
        """``d tau_m / d eta`` (3, 3) [N/m, N/rad; N m/m, N m/rad] by central differences of the load
        evaluator (steps 0.1 m, 0.1 m, 1e-3 rad), refreshed when ``eta`` moved > (1 m, 1 m, 0.01 rad)
        from where it was taken, or the model changed."""
        at = self._J_at
        if (at is None or self._J_of is not self.model or abs(eta[0] - at[0]) > 1.0 or abs(eta[1] - at[1]) > 1.0
                or abs(eta[2] - at[2]) > 0.01):
            J = np.empty((3, 3))
            for j, h in enumerate((0.1, 0.1, 1e-3)):
                e = eta.copy()
                e[j] += h
                fp = self.mooring_load(e)
                e[j] -= 2 * h
                J[:, j] = (fp - self.mooring_load(e)) / (2 * h)
            self._J, self._J_at, self._J_of = J, eta.copy(), self.model
        return self._J

    def _initialise(self, y: np.ndarray, tau_c: np.ndarray) -> None:
        x = np.zeros(15)
        x[6:9] = y
        tm = self.mooring_load(y)
        c, s = math.cos(y[2]), math.sin(y[2])
        q = -(tm + tau_c)  # quasi-static balance, {B}
        x[12:] = [c * q[0] - s * q[1], s * q[0] + c * q[1], q[2]]
        P = np.zeros((15, 15))
        # stationary WF covariance: var(xi_2) = wf_std^2, var(xi_1) = wf_std^2 / omega_0^2
        P[0:3, 0:3] = np.diag(self.wf_std ** 2 / self.omega_0 ** 2)
        P[3:6, 3:6] = np.diag(self.wf_std ** 2)
        P[6:9, 6:9] = self._R
        P[9:12, 9:12] = np.diag([0.5 ** 2, 0.5 ** 2, 0.005 ** 2])
        P[12:, 12:] = np.diag(self.bias_std ** 2)
        self.x, self.P = x, P

    def update(self, t: float, measurement: Measurement) -> Estimate:
        """The :class:`~tapm_opt.interfaces.Estimator` step: predict to ``t`` [s], then correct with
        the components of the measurement sampled since the previous correction (module docstring)."""
        m = measurement
        t, y, tau_c = self._read(t, m)
        broken = self._broken(t, m)
        tp, th = float(m.t_position), float(m.t_heading)
        if self.x is None:
            self._initialise(y, tau_c)
            self._t = t
            self._t_pos, self._t_hdg = tp, th
        else:
            dt = t - self._t
            self._t = t
            if dt > 0:
                self._predict(dt, tau_c)
            new_p, new_h = tp > self._t_pos, th > self._t_hdg
            if not self._fix:   # no GNSS fix: the prediction in its place, and no position correction
                y[:2] = self.x[6:8] + self.x[3:5]
                new_p = False
            self._correct(y, (new_p, new_p, new_h))
            if new_p:
                self._t_pos = tp
            if new_h:
                self._t_hdg = th
        x = self.x
        return self._estimate(t, m, x[6:9], x[9:12].copy(), x[12:], x[3:6].copy(), broken)

    def _predict(self, dt: float, tau_c: np.ndarray) -> None:
        if self._disc_dt is None or abs(dt - self._disc_dt) > 1e-9 * max(1.0, dt):
            self._discretise(dt)
        kern = ekf_kernels()   # compiled predict and correct (None: the numpy path)
        if kern is None:
            return self._predict_numpy(dt, tau_c)
        x = self.x
        eta = x[6:9]
        tm = self.mooring_load(eta)
        J = self._jacobian(eta)
        xn, Pn = np.empty(15), np.empty((15, 15))
        kern[0](x, self.P, self._Phi_w, self._A_nu, self._M_inv, self._G, self._decay, self._Q, dt,
                np.asarray(tm, float), J, tau_c, self._Phi, xn, Pn)
        self.P = Pn
        self.x = xn

    def _predict_numpy(self, dt: float, tau_c: np.ndarray) -> None:
        """:meth:`_predict` in numpy operations (the reference of the compiled kernel,
        :mod:`tapm_opt.estimation.ekf_kernel`; used without numba)."""
        x = self.x
        eta, nu, b = x[6:9], x[9:12], x[12:]
        psi = float(eta[2])
        c, s = math.cos(psi), math.sin(psi)
        b0, b1 = float(b[0]), float(b[1])
        tm = self.mooring_load(eta)
        J = self._jacobian(eta)
        Rtb = np.array([c * b0 + s * b1, -s * b0 + c * b1, b[2]])
        nu_new = self._A_nu @ (nu + dt * (self._M_inv @ (Rtb + tm + tau_c)))
        n0, n1 = float(nu_new[0]), float(nu_new[1])
        xn = np.empty(15)
        xn[:6] = self._Phi_w @ x[:6]
        xn[6:9] = eta + dt * np.array([c * n0 - s * n1, s * n0 + c * n1, nu_new[2]])
        xn[9:12] = nu_new
        xn[12:] = self._decay * b
        # Jacobian of the discrete map, LF rows: nu+ = An (nu + dt M^-1 (R^T b + tau_m + tau_c)),
        # eta+ = eta + dt R(psi) nu+; G = dt An M^-1 (cached)
        X = self._X
        X[:, 0:3] = J
        X[0, 2] += -s * b0 + c * b1           # d(R^T b)/d psi
        X[1, 2] += -c * b0 - s * b1
        X[:, 6:9] = ((c, s, 0.0), (-s, c, 0.0), (0.0, 0.0, 1.0))   # d(R^T b)/db = R(psi)^T
        Fnu = self._G @ X
        Fnu[:, 3:6] = self._A_nu
        dtR = np.array([[dt * c, -dt * s, 0.0], [dt * s, dt * c, 0.0], [0.0, 0.0, dt]])
        Feta = dtR @ Fnu
        Feta[0, 0] += 1.0
        Feta[1, 1] += 1.0
        Feta[2, 2] += 1.0
        Feta[0, 2] += dt * (-s * n0 - c * n1)   # d(R nu+)/d psi
        Feta[1, 2] += dt * (c * n0 - s * n1)
        F = self._Phi
        F[6:9, 6:] = Feta
        F[9:12, 6:] = Fnu
        self.P = F @ self.P @ F.T + self._Q
        self.x = xn

    def _correct(self, y: np.ndarray, new: tuple) -> None:
        kern = ekf_kernels()   # compiled predict and correct (None: the numpy path)
        if kern is None or not (new[0] and new[1] and new[2]):
            return self._correct_numpy(y, new)
        xn, Pn, innov, S = np.empty(15), np.empty((15, 15)), np.empty(3), np.empty((3, 3))
        ok = kern[1](self.x, self.P, y, self._r, xn, Pn, innov, S)
        self.innovation = innov
        self.innovation_cov = S
        self.innovation_mask = np.array(new)
        if not ok:
            raise EstimationError(f"innovation covariance S = {S.tolist()} is singular")
        self.x, self.P = xn, Pn

    def _correct_numpy(self, y: np.ndarray, new: tuple) -> None:
        """:meth:`_correct` in numpy operations (the reference of the compiled kernel; used for a
        partial correction and without numba)."""
        x, P = self.x, self.P
        innov = y - x[6:9] - x[3:6]
        innov[2] = _wrap(float(innov[2]))
        PHt = P[:, 3:6] + P[:, 6:9]
        S = PHt[3:6] + PHt[6:9] + self._R
        self.innovation = innov
        self.innovation_cov = S
        self.innovation_mask = np.array(new)
        if not any(new):
            return
        if all(new):
            K = PHt @ _inv3(S)
            KH = K @ self._H
            r = self._r
            v = innov
        else:
            idx = [i for i in range(3) if new[i]]
            K = PHt[:, idx] @ np.linalg.inv(S[np.ix_(idx, idx)])
            KH = K @ self._H[idx]
            r = self._r[idx]
            v = innov[idx]
        self.x = x + K @ v
        IKH = self._I15 - KH
        P = IKH @ P @ IKH.T + (K * r) @ K.T      # Joseph form (R diagonal)
        self.P = 0.5 * (P + P.T)


def _inv3(S: np.ndarray) -> np.ndarray:
    """Inverse of a 3x3 matrix by cofactors (no LAPACK call per update)."""
    (a, b, c), (d, e, f), (g, h, i) = S.tolist()
    A, B, C = e * i - f * h, -(d * i - f * g), d * h - e * g
    det = a * A + b * B + c * C
    if det == 0.0 or not math.isfinite(det):
        raise EstimationError(f"innovation covariance S = {S.tolist()} is singular")
    return np.array([[A, -(b * i - c * h), b * f - c * e],
                     [B, a * i - c * g, -(a * f - c * d)],
                     [C, -(a * h - b * g), a * e - b * d]]) / det
