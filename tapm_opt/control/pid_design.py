"""Gains of the TAPM PID modes by pole placement, and the closed loop of the coupled 3-DOF model.

Per-DOF pole placement on the linearised moored vessel ([S] eq. 31 about an equilibrium):
:func:`design_gains` on a python-control state-space model, :func:`design_from_scenario` on a
scenario's (or a :class:`~tapm_opt.models.system.System`'s) vessel and catenary mooring linearised
at the offset equilibrium; :func:`closed_loop` gives the closed loop of the PID modes with the
coupled plant. The control law itself is :class:`~tapm_opt.control.pid.TAPMPID`. ``[S]`` = seed
survey-tapm-modeling-and-control.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from typing import Any, Literal, Sequence

import control
import numpy as np

from .._io import readonly
from ..errors import TapmError
from ..geometry import rot_z
from ..models.mooring import MooringModel
from ..models.system import as_system
from ..models.vessel import linearise, moored_function
from .pid import MODES, ControlError, GainClampWarning, PIDGains, _integrated, _projections, _resolve_modes, _vec3

__all__ = ["PIDDesign", "designed_poles", "dof_plant", "design_gains", "design_from_scenario", "closed_loop"]


def _per_dof(name: str, value: Any, *, positive: bool = True) -> np.ndarray:
    try:
        arr = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy()
    except (TypeError, ValueError):
        raise ControlError(f"{name}={value!r} must be a scalar or 3 values (surge, sway, "
                           f"yaw)") from None
    if not np.all(np.isfinite(arr)) or (np.any(arr <= 0.0) if positive else np.any(arr < 0.0)):
        rule = "> 0" if positive else ">= 0"
        raise ControlError(f"{name} must be finite and {rule}, got {name}={arr.tolist()}")
    return arr


def check_integral_ratio(value: Any, *, error: type[Exception] = ControlError) -> float:
    """``value`` as the integral ratio a / w, a finite number >= 0, else ``error`` naming it."""
    try:
        ratio = float(value)
    except (TypeError, ValueError):
        raise error(f"integral_ratio={value!r} must be a number >= 0") from None
    if not (np.isfinite(ratio) and ratio >= 0.0):
        raise error(f"integral_ratio={value!r} must be finite and >= 0")
    return ratio


def designed_poles(period: float, damping: float, integral_ratio: float) -> np.ndarray:
    """Closed-loop poles of one DOF: roots of (s^2 + 2 zeta w s + w^2)(s + a).

    Parameters
    ----------
    period : float
        Undamped natural period T_n [s], w = 2 pi / T_n.
    damping : float
        Relative damping zeta > 0.
    integral_ratio : float
        a / w >= 0 (a: the integral pole [1/s]).

    Returns
    -------
    ndarray, shape (3,), complex
        (-zeta w + i w sqrt(1 - zeta^2), its conjugate, -a) [1/s]; for zeta >= 1 the pair is
        real, -w (zeta -+ sqrt(zeta^2 - 1)).
    """
    w = 2.0 * np.pi / period
    root = np.sqrt(complex(damping**2 - 1.0))
    return np.array([w * (-damping + root), w * (-damping - root), -integral_ratio * w + 0j])


def dof_plant(m: float, d: float, k: float) -> control.StateSpace:
    """One decoupled DOF m e_ddot + d e_dot + k e = tau, augmented with its integral.

    States ``(xi, e, e_dot)`` with xi_dot = e; input ``tau`` [N or N m]. The PID is the state
    feedback tau = -[K_i, K_p, K_d] (xi, e, e_dot).

    Parameters
    ----------
    m, d, k : float
        Mass incl. added mass [kg or kg m^2], damping [N s/m or N m s], stiffness [N/m or N m].
    """
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -k / m, -d / m]])
    B = np.array([[0.0], [0.0], [1.0 / m]])
    return control.ss(A, B, np.eye(3), np.zeros((3, 1)), states=["xi", "e", "e_dot"],
                      inputs=["tau"], outputs=["xi", "e", "e_dot"])


def _plant_matrices(plant: Any) -> tuple[control.StateSpace, np.ndarray, np.ndarray, np.ndarray,
                                          np.ndarray]:
    """(plant with state output, M, D, K_B, R0) of a linearised moored vessel.

    ``plant`` is a 6-state ``control.StateSpace`` from :func:`~tapm_opt.models.vessel.linearise`
    (x = (eta, nu), input tau in {B}) or a tuple (M, D, K) in {B} at psi = 0. K_B = K R(psi0) is
    the stiffness seen by {B}-frame position errors e_b = R(psi0)^T d_eta.
    """
    if isinstance(plant, control.StateSpace):
        A, B = np.asarray(plant.A, dtype=float), np.asarray(plant.B, dtype=float)
        if A.shape != (6, 6) or B.shape != (6, 3):
            raise ControlError(f"plant must have 6 states (eta, nu) and 3 inputs (X, Y, N), got "
                               f"A {A.shape}, B {B.shape}")
        scale = max(float(np.max(np.abs(A))), 1.0)
        R0 = A[:3, 3:]
        psi0 = float(np.arctan2(R0[1, 0], R0[0, 0]))
        if (np.max(np.abs(A[:3, :3])) > 1e-9 * scale or np.max(np.abs(B[:3])) > 0.0
                or np.max(np.abs(R0 - rot_z(psi0))) > 1e-9):
            raise ControlError("plant is not a moored vessel linearised at rest: expected "
                               "eta_dot = R(psi0) nu (linearise() about an equilibrium with nu = 0)")
        try:
            M = np.linalg.inv(B[3:])
        except np.linalg.LinAlgError:
            raise ControlError("plant input matrix B[3:6] is singular; expected M^-1") from None
        D = -M @ A[3:, 3:]
        K_B = -M @ A[3:, :3] @ R0
        full = control.ss(A, B, np.eye(6), np.zeros((6, 3)))
        return full, M, D, K_B, R0
    try:
        M, D, K = (np.array(x, dtype=float) for x in plant)
    except (TypeError, ValueError):
        raise ControlError(f"plant must be a control.StateSpace or a tuple (M, D, K) of (3, 3) "
                           f"arrays, got {type(plant).__name__}") from None
    for name, X in (("M", M), ("D", D), ("K", K)):
        if X.shape != (3, 3) or not np.all(np.isfinite(X)):
            raise ControlError(f"{name} must be a finite (3, 3) array, got shape {X.shape}")
    if np.any(np.diag(M) <= 0.0):
        raise ControlError(f"M must have a positive diagonal, got diag(M)={np.diag(M).tolist()}")
    M_inv = np.linalg.inv(M)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-M_inv @ K, -M_inv @ D]])
    B = np.vstack([np.zeros((3, 3)), M_inv])
    full = control.ss(A, B, np.eye(6), np.zeros((6, 3)))
    return full, M, D, K, np.eye(3)


def reference_maps(R0: np.ndarray, reference_point: Any = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """(T_eta, T_nu): the linearised pose and velocity of the controller's reference point c in {B}
    (the centre of turret) from the body origin's, at heading psi0 (``R0 = R(psi0)``):
    ``d p_c = d p + R2'(psi0) c d psi`` and ``nu_c = (u - r c_y, v + r c_x, r)``, the maps
    :class:`~tapm_opt.control.pid.TAPMPID` applies with ``reference_point = c``."""
    c = np.asarray(reference_point, dtype=float)
    Rc = R0[:2, :2] @ c
    T_eta, T_nu = np.eye(3), np.eye(3)
    T_eta[0, 2], T_eta[1, 2] = -Rc[1], Rc[0]
    T_nu[0, 2], T_nu[1, 2] = -c[1], c[0]
    return T_eta, T_nu


def _controller_matrices(gains: PIDGains, modes: tuple[str, ...], R0: np.ndarray, reference_point: Any = (0.0, 0.0)):
    """Linearised controller about the operating point: integrated xi components, the maps
    (F_eta, F_nu, F_xi) with tau = F_eta d_eta + F_nu nu + F_xi xi of the body-origin state
    (setpoint at the point), and the map T_eta of the body pose to the reference point's, whose
    error is integrated (xi_dot = T_eta d_eta - d_eta_d)."""
    H_I, H_P, H_D = _projections(modes)
    Ki, Kp, Kd = H_I @ gains.Ki, H_P @ gains.Kp, H_D @ gains.Kd
    mask = _integrated(Ki)
    T_eta, T_nu = reference_maps(R0, reference_point)
    F_xi = -(Ki @ R0.T)[:, mask]
    return mask, -Kp @ R0.T @ T_eta, -Kd @ T_nu, F_xi, T_eta


def closed_loop(plant: Any, gains: PIDGains, modes: str | Sequence[str] = MODES, *,
                reference_point: Any = (0.0, 0.0)) -> control.StateSpace:
    """Linear closed loop of the moored vessel and the PID with ``modes`` (setpoint at the
    linearisation point, heading error small).

    Parameters
    ----------
    plant : control.StateSpace or tuple (M, D, K)
        As for :func:`design_gains`.
    gains : PIDGains
    modes : str or sequence of str
        As for :class:`TAPMPID`.
    reference_point : array_like, shape (2,)
        The PID's reference point in {B} [m] (:class:`TAPMPID`'s ``reference_point``; the centre
        of turret for a turret-moored vessel): the loop is that of the controller that runs.

    Returns
    -------
    control.StateSpace
        States ``x, y, psi, u, v, r`` (deviations) and the integrated ``xi_*``; inputs
        ``X_env, Y_env, N_env`` (load in {B} added to the thrust [N, N, N m]) and
        ``x_d, y_d, psi_d`` (setpoint deviation of the reference point in {E}); outputs ``x, y,
        psi`` (deviation of the reference point [m, m, rad]) and ``X_thr, Y_thr, N_thr``
        (command [N, N, N m]).
    """
    full, _, _, _, R0 = _plant_matrices(plant)
    modes = _resolve_modes(modes)
    mask, F_eta, F_nu, F_xi, T_eta = _controller_matrices(gains, modes, R0, reference_point)
    n_xi = int(mask.sum())
    A_p, B_p = np.asarray(full.A), np.asarray(full.B)
    F_x = np.hstack([F_eta, F_nu])          # tau from the plant state
    F_d = -(F_eta @ np.linalg.inv(T_eta))   # tau from the setpoint deviation (-Kp R0^T)
    S = np.eye(3)[mask]                     # selects the integrated components
    A = np.block([[A_p + B_p @ F_x, B_p @ F_xi],
                  [np.hstack([S @ T_eta, np.zeros((n_xi, 3))]), np.zeros((n_xi, n_xi))]])
    B = np.block([[B_p, B_p @ F_d], [np.zeros((n_xi, 3)), -S]])
    C = np.block([[T_eta, np.zeros((3, 3 + n_xi))], [F_x, F_xi]])
    D = np.block([[np.zeros((3, 6))], [np.zeros((3, 3)), F_d]])
    xi_names = [f"xi_{n}" for n, k in zip(("x", "y", "psi"), mask) if k]
    return control.ss(A, B, C, D, states=["x", "y", "psi", "u", "v", "r"] + xi_names,
                      inputs=["X_env", "Y_env", "N_env", "x_d", "y_d", "psi_d"],
                      outputs=["x", "y", "psi", "X_thr", "Y_thr", "N_thr"])


@dataclass(frozen=True, kw_only=True, eq=False)
class PIDDesign:
    """Result of :func:`design_gains`: gains, designed and achieved closed-loop poles.

    Attributes
    ----------
    gains : PIDGains
        Diagonal gains, negative values clamped to zero.
    periods : ndarray, shape (3,)
        Designed undamped natural periods (surge, sway, yaw) [s].
    damping : ndarray, shape (3,)
        Designed relative damping [-].
    integral_ratio : float
        Integral pole a = integral_ratio * 2 pi / T_n.
    M, D, K : ndarray, shape (3, 3)
        Mass incl. added mass, vessel + mooring damping, stiffness K R(psi0) seen by {B}-frame
        errors, at the operating point; the design used their diagonals.
    eta_op : ndarray, shape (3,)
        Operating point (x [m], y [m], psi [rad]) in {E} (zeros unless designed from a scenario).
    reference_point : ndarray, shape (2,)
        The PID's reference point in {B} [m] that ``poles`` and :meth:`closed_loop` assume.
    plant : control.StateSpace
        Linearised moored vessel, states (eta, nu), inputs tau in {B}, outputs the state.
    designed_poles : ndarray, shape (3, 3), complex
        Row i: the three poles asked for DOF i [1/s].
    decoupled_poles : ndarray, shape (3, 3), complex
        Row i: poles achieved on the decoupled DOF i (diagonal model) with ``gains``
        (python-control); equal to ``designed_poles`` unless a gain was clamped.
    poles : ndarray, complex
        Poles of the coupled closed loop, plant ``plant`` with all four modes and the reference
        point (python-control), sorted by magnitude.
    natural_periods, damping_ratios : ndarray, same shape as ``poles``
        2 pi / |p| [s] and -Re(p)/|p| of each pole (``control.damp``).
    clamped : tuple of str
        One message per gain that came out negative and was set to zero; empty if none.
    """

    gains: PIDGains
    periods: np.ndarray
    damping: np.ndarray
    integral_ratio: float
    M: np.ndarray
    D: np.ndarray
    K: np.ndarray
    plant: control.StateSpace
    designed_poles: np.ndarray
    decoupled_poles: np.ndarray
    poles: np.ndarray
    natural_periods: np.ndarray
    damping_ratios: np.ndarray
    clamped: tuple[str, ...] = ()
    eta_op: np.ndarray = field(default_factory=lambda: readonly(np.zeros(3)))
    reference_point: np.ndarray = field(default_factory=lambda: readonly(np.zeros(2)))

    @property
    def stable(self) -> bool:
        """All coupled closed-loop poles in the open left half plane."""
        return bool(np.all(self.poles.real < 0.0))

    def closed_loop(self, modes: str | Sequence[str] = MODES) -> control.StateSpace:
        """Linear closed loop with ``modes``; see :func:`closed_loop`."""
        return closed_loop(self.plant, self.gains, modes, reference_point=self.reference_point)


def design_gains(plant: Any, *, periods: Any, damping: Any, integral_ratio: float = 0.1,
                 method: Literal["formula", "acker"] = "formula", reference_point: Any = (0.0, 0.0)) -> PIDDesign:
    """PID gains by per-DOF pole placement on the linearised moored vessel.

    For each DOF i, decoupled (diagonals of M, D, K)::

        M s^3 + (D + K_d) s^2 + (K + K_p) s + K_i = M (s^2 + 2 zeta w s + w^2)(s + a)
        K_d = M (2 zeta w + a) - D,   K_p = M (w^2 + 2 zeta w a) - K,   K_i = M w^2 a

    with w = 2 pi / T_n and a = integral_ratio * w. A negative K_p (the mooring is already stiffer
    than asked) or K_d (already more damped) is set to zero and reported in ``clamped`` and by a
    :class:`GainClampWarning`.

    Parameters
    ----------
    plant : control.StateSpace or tuple (M, D, K)
        The moored vessel linearised at rest: a 6-state model from
        :func:`~tapm_opt.models.vessel.linearise` (states eta, nu; inputs tau in {B}), from which
        M = B[3:]^-1, D = -M A_nu,nu and K = -M A_nu,eta R(psi0) are read; or (M, D, K), each
        (3, 3) in {B} with psi0 = 0.
    periods : float or array_like, shape (3,)
        Desired undamped natural periods T_n (surge, sway, yaw) [s].
    damping : float or array_like, shape (3,)
        Desired relative damping zeta > 0.
    integral_ratio : float
        a / w >= 0; 0 gives a PD (K_i = 0).
    method : {"formula", "acker"}
        Closed form above, or python-control ``acker`` on :func:`dof_plant` (same result).
    reference_point : array_like, shape (2,)
        The PID's reference point in {B} [m] (the centre of turret for a turret-moored vessel).
        The per-DOF placement uses the body-origin diagonals as above; the coupled poles
        (``poles``) are those of the loop with this reference point, i.e. of the controller that
        runs, so the lever of the reference point shows as the difference between the two.

    Returns
    -------
    PIDDesign
    """
    full, M, D, K, R0 = _plant_matrices(plant)
    periods = _per_dof("periods", periods)
    zeta = _per_dof("damping", damping)
    ratio = check_integral_ratio(integral_ratio)
    if method not in ("formula", "acker"):
        raise ControlError(f"method={method!r} is unknown; choose 'formula' or 'acker'")

    wanted = np.array([designed_poles(periods[i], zeta[i], ratio) for i in range(3)])
    kp, ki, kd = np.zeros(3), np.zeros(3), np.zeros(3)
    clamped: list[str] = []
    dof = ("surge", "sway", "yaw")
    for i in range(3):
        m, d, k = M[i, i], D[i, i], K[i, i]
        if method == "formula":
            w = 2.0 * np.pi / periods[i]
            a = ratio * w
            ki[i] = m * w**2 * a
            kp[i] = m * (w**2 + 2.0 * zeta[i] * w * a) - k
            kd[i] = m * (2.0 * zeta[i] * w + a) - d
        else:
            row = np.asarray(control.acker(dof_plant(m, d, k).A, dof_plant(m, d, k).B,
                                           wanted[i]), dtype=float).ravel()
            ki[i], kp[i], kd[i] = row
        for name, arr, own, unit in (("Kp", kp, k, "stiffness K"), ("Kd", kd, d, "damping D")):
            if arr[i] < 0.0:
                clamped.append(
                    f"{name}[{dof[i]}] = {arr[i]:.4g} < 0 set to 0: the plant's {unit}[{i},{i}] = "
                    f"{own:.4g} already exceeds the design (T_n = {periods[i]:g} s, zeta = "
                    f"{zeta[i]:g}); the {dof[i]} poles will not be where asked")
                arr[i] = 0.0
        ki[i] = max(ki[i], 0.0)  # only round-off from acker can make it negative
    for msg in clamped:
        warnings.warn(msg, GainClampWarning, stacklevel=2)
    gains = PIDGains(Kp=kp, Ki=ki, Kd=kd)

    achieved = []
    for i in range(3):
        sys_i = dof_plant(M[i, i], D[i, i], K[i, i])
        fb = control.ss(np.zeros((0, 0)), np.zeros((0, 3)), np.zeros((1, 0)),
                        np.array([[-ki[i], -kp[i], -kd[i]]]))
        achieved.append(np.sort_complex(control.feedback(sys_i, fb, sign=1).poles()))

    # coupled loop with python-control: plant (full state out) in feedback with the controller
    ref = np.asarray(reference_point, dtype=float)
    if ref.shape != (2,) or not np.all(np.isfinite(ref)):
        raise ControlError(f"reference_point={reference_point!r} must be 2 finite numbers (x, y) in {{B}} [m]")
    mask, F_eta, F_nu, F_xi, T_eta = _controller_matrices(gains, MODES, R0, ref)
    n_xi = int(mask.sum())
    ctrl = control.ss(np.zeros((n_xi, n_xi)), np.hstack([np.eye(3)[mask] @ T_eta, np.zeros((n_xi, 3))]),
                      F_xi, np.hstack([F_eta, F_nu]))
    loop = control.feedback(full, ctrl, sign=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        wn, zeta_cl, poles = control.damp(loop, doprint=False)
    order = np.argsort(np.abs(poles), kind="stable")
    wn, zeta_cl, poles = wn[order], zeta_cl[order], poles[order]
    with np.errstate(divide="ignore"):
        periods_cl = np.where(wn > 0.0, 2.0 * np.pi / np.where(wn > 0.0, wn, 1.0), np.inf)

    return PIDDesign(
        gains=gains, periods=readonly(periods), damping=readonly(zeta), integral_ratio=ratio,
        M=readonly(M), D=readonly(D), K=readonly(K), plant=full,
        designed_poles=readonly(wanted, complex), decoupled_poles=readonly(np.array(achieved), complex),
        poles=readonly(poles, complex), natural_periods=readonly(periods_cl),
        damping_ratios=readonly(zeta_cl), clamped=tuple(clamped), reference_point=readonly(ref),
    )


def _mooring_equilibrium(moor: MooringModel, tau_env: np.ndarray, eta_guess: np.ndarray
                         ) -> np.ndarray:
    """Pose where tau_moor(eta) + tau_env = 0 (no thrust, at rest, heading free):
    :meth:`~tapm_opt.models.mooring.MooringModel.equilibrium`, its error as a ControlError."""
    try:
        return moor.equilibrium(tau_env, eta_guess=eta_guess)
    except TapmError as exc:
        raise ControlError(f"{exc} (from eta0={np.asarray(eta_guess).tolist()})") from None


def design_from_scenario(scenario: Any, *, periods: Any, damping: Any,
                         integral_ratio: float = 0.1, eta0: Any = (0.0, 0.0, 0.0),
                         tau_env: Any = (0.0, 0.0, 0.0), D_moor: Any = None,
                         broken: Sequence[str] = (),
                         method: Literal["formula", "acker"] = "formula",
                         reference_point: Any = None) -> PIDDesign:
    """Gains for a scenario's vessel and catenary mooring, linearised at the offset equilibrium.

    The vessel rests where the catenary mooring balances ``tau_env``
    (:meth:`~tapm_opt.models.mooring.MooringModel.equilibrium` from ``eta0``, heading free); the
    design model (vessel design form, [S] eq. 31, with the catenary restoring load) is
    linearised there with :func:`~tapm_opt.models.vessel.linearise`, so K is the exact
    catenary stiffness ``MooringModel.stiffness`` at that pose. Then :func:`design_gains`.

    Parameters
    ----------
    scenario : Scenario or System
        The scenario, or the :class:`~tapm_opt.models.system.System` built from it (its vessel and
        line system are used as they are).
    periods, damping, integral_ratio, method
        As for :func:`design_gains`.
    eta0 : array_like, shape (3,)
        Initial guess of the equilibrium (x [m], y [m], psi [rad]).
    tau_env : array_like, shape (3,)
        Mean environmental load in {B} [N, N, N m] (constant in {B}, as in the design model).
    D_moor : array_like, shape (3, 3), optional
        Linear mooring damping D_mo (eq. 30) [N s/m, N s, N m s], e.g. identified with
        ``tapm_opt.plant.forced_motion.identify_mooring_damping``; default zero.
    broken : sequence of str
        Ids of broken lines, left out of the mooring.
    reference_point : array_like shape (2,), optional
        The PID's reference point in {B} [m] for the coupled poles (default: the centre of turret,
        as :func:`~tapm_opt.studies.controllers.build_controller` makes the PID).

    Returns
    -------
    PIDDesign
        With ``eta_op`` the equilibrium.
    """
    eta0 = _vec3("eta0", eta0)
    tau_env = _vec3("tau_env", tau_env)
    system = as_system(scenario)
    params = system.vessel
    moor = system.with_broken(broken).lines if broken else system.lines
    eta_eq = _mooring_equilibrium(moor, tau_env, eta0)
    # linearised at eta_eq, where the characteristic kind has the catenary's exact Jacobian; composite
    # lines have no symbolic catenary
    kind = "characteristic" if moor.has_composite else "catenary"
    fn = moored_function(params, moor.force_function(kind, eta0=eta_eq), D_moor=D_moor)
    plant = linearise(fn, np.r_[eta_eq, np.zeros(3)], tau_env0=tau_env, outputs="state")
    ref = system.p_cot_B if reference_point is None else reference_point
    design = design_gains(plant, periods=periods, damping=damping, integral_ratio=integral_ratio, reference_point=ref,
                          method=method)
    return replace(design, eta_op=readonly(eta_eq))
