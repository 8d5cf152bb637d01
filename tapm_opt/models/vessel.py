"""3-DOF low-frequency vessel model as CasADi Functions (survey §3.2–3.3, eq. 8–15, 29–31).

Conventions (Fossen / survey notation, NED):

* ``eta = (x, y, psi)`` in the earth frame {E}: north [m], east [m], heading [rad] (clockwise
  seen from above, 0 = bow north).
* ``nu = (u, v, r)`` in the body frame {B}: surge [m/s], sway [m/s], yaw rate [rad/s].
* ``tau = (X, Y, N)`` in {B}: surge force [N] (+ forward), sway force [N] (+ starboard), yaw
  moment [N m] (+ turns the bow to starboard, i.e. clockwise seen from above).
* ``v_c`` is an irrotational current constant in {E} given as (V_x, V_y) [m/s] (eq. 7);
  ``nu_c = R(psi)^T v_c`` and ``nu_r = nu - nu_c``. The state always holds the *absolute* ``nu``.

``vessel_rhs`` is written once over numpy arrays and CasADi symbols; ``vessel_function`` and
``moored_function`` compile it into named ``casadi.Function`` objects that MPC uses symbolically
and the plant and tests call numerically. A control input is ``tau_thr``/``tau_cmd``, never ``u``.

A vessel may also have low-frequency roll and pitch (:class:`RollPitchParams`, the scenario's
``[vessel.roll_pitch]``, off by default; survey §4.2.3, ``docs/semi.md``): two uncoupled modes
about the centre of gravity, :func:`roll_pitch_rhs` under the moments of :func:`roll_pitch_moments`
(thrust, wind, drift) and of the lines (the plant); the surge–sway–yaw model above is unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import casadi as ca
import numpy as np

from .. import _backend as bk
from ..errors import ModelError
from ..geometry import rot2_apply, rot_z
from .statics import EquilibriumError, solve_equilibrium

if TYPE_CHECKING:  # python-control loads on first use (linearise)
    import control

__all__ = ["VesselParams", "RollPitchParams", "roll_pitch_rhs", "roll_pitch_moments", "coriolis", "vessel_rhs",
           "vessel_function", "moored_function",
           "linearise", "equilibrium", "FORMS", "STATE_NAMES", "INPUT_NAMES"]

#: Model forms: ``"design"`` (eq. 14–15) and ``"rich"`` (eq. 8–11).
FORMS = ("design", "rich")
#: Names of the 6 states x = (eta, nu) and of the 3 generalised thrust inputs.
STATE_NAMES = ("x", "y", "psi", "u", "v", "r")
INPUT_NAMES = ("X", "Y", "N")
_PSI, _R = 2, 2  # indices of psi in eta and of r in nu

_SYM_TOL = 1e-9  # relative tolerance for symmetry checks


def _matrix(name: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """Convert ``value`` to a read-only float array of ``shape``, else raise ModelError."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{name}={value!r} is not numeric: {exc}") from None
    if arr.shape != shape:
        raise ModelError(f"{name} has shape {arr.shape}, expected {shape}: {name}={arr.tolist()}")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{name} must be finite, got {name}={arr.tolist()}")
    arr.flags.writeable = False
    return arr


def _check_symmetric(name: str, A: np.ndarray) -> None:
    scale = max(float(np.max(np.abs(A))), 1.0)
    if np.max(np.abs(A - A.T)) > _SYM_TOL * scale:
        raise ModelError(f"{name} must be symmetric, got {name}={A.tolist()}")


def _min_eig(A: np.ndarray) -> float:
    return float(np.min(np.linalg.eigvalsh(0.5 * (A + A.T))))


def _check_psd(name: str, A: np.ndarray) -> None:
    """Symmetric part of A positive semidefinite (dissipative), with a round-off allowance."""
    lam = _min_eig(A)
    if lam < -_SYM_TOL * max(float(np.max(np.abs(A))), 1.0):
        raise ModelError(
            f"{name} must have a positive semidefinite symmetric part (dissipative); smallest "
            f"eigenvalue {lam:.6g}, {name}={A.tolist()}"
        )


@dataclass(frozen=True, kw_only=True, eq=False)
class VesselParams:
    """Low-frequency 3-DOF vessel parameters (survey eq. 8–15). Arrays are read-only copies;
    equality is identity (``eq=False``) since numpy arrays have no truth value. Variants with
    ``dataclasses.replace`` (validated again).

    Parameters
    ----------
    M : array_like, shape (3, 3)
        Total mass matrix M = M_RB + M_A incl. added mass [kg, kg m, kg m^2]; symmetric
        positive definite.
    M_A : array_like, shape (3, 3), optional
        Added-mass part of ``M`` (same units), symmetric; default zeros (then M_RB = M).
        M_RB = M - M_A must be positive definite.
    D_lin : array_like, shape (3, 3)
        Linear damping D_lin [N s/m, N s, N m s]; its symmetric part must be positive
        semidefinite.
    d_quad : array_like, shape (3,), optional
        Quadratic damping (X_|u|u [N s^2/m^2], Y_|v|v [N s^2/m^2], N_|r|r [N m s^2]) >= 0; the
        force is ``-d_quad[i] * |nu_r[i]| * nu_r[i]``. Default zeros. Used by the rich form only.
    roll_pitch : RollPitchParams, optional
        Low-frequency roll and pitch (survey §4.2.3, ``docs/semi.md``); None (default): the
        vessel is 3-DOF and every model of this module is unchanged.
    """

    M: np.ndarray
    D_lin: np.ndarray
    M_A: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    d_quad: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: Low-frequency roll and pitch (:class:`RollPitchParams`), or None: 3-DOF (the default).
    roll_pitch: RollPitchParams | None = None
    #: Inverse of ``M`` [1/kg, ...], derived.
    M_inv: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        M = _matrix("M", self.M, (3, 3))
        M_A = _matrix("M_A", self.M_A, (3, 3))
        D_lin = _matrix("D_lin", self.D_lin, (3, 3))
        d_quad = _matrix("d_quad", self.d_quad, (3,))
        _check_symmetric("M", M)
        if _min_eig(M) <= 0.0:
            raise ModelError(f"M must be positive definite, smallest eigenvalue "
                             f"{_min_eig(M):.6g}, M={M.tolist()}")
        _check_symmetric("M_A", M_A)
        if _min_eig(M - M_A) <= 0.0:
            raise ModelError(
                f"M_RB = M - M_A must be positive definite (is M the total mass incl. added "
                f"mass?), smallest eigenvalue {_min_eig(M - M_A):.6g}, M_A={M_A.tolist()}"
            )
        _check_psd("D_lin", D_lin)
        if np.any(d_quad < 0.0):
            raise ModelError(f"d_quad must be >= 0, got d_quad={d_quad.tolist()}")
        if self.roll_pitch is not None and not isinstance(self.roll_pitch, RollPitchParams):
            raise ModelError(f"roll_pitch must be a RollPitchParams or None, got {type(self.roll_pitch).__name__}")
        M_inv = np.linalg.inv(M)
        M_inv.flags.writeable = False
        for name, val in (("M", M), ("M_A", M_A), ("D_lin", D_lin), ("d_quad", d_quad),
                          ("M_inv", M_inv)):
            object.__setattr__(self, name, val)

    @property
    def M_RB(self) -> np.ndarray:
        """Rigid-body mass matrix M_RB = M - M_A, shape (3, 3)."""
        return self.M - self.M_A

    @classmethod
    def from_scenario(cls, scenario: Any) -> VesselParams:
        """Build from ``scenario.vessel`` (``mass_matrix`` = total M incl. added mass,
        ``added_mass`` or None, ``linear_damping``, ``quadratic_damping``), all SI."""
        ves = scenario.vessel
        M_A = ves.added_mass if getattr(ves, "added_mass", None) is not None else np.zeros((3, 3))
        rp = getattr(ves, "roll_pitch", None)
        return cls(M=np.asarray(ves.mass_matrix, dtype=float), M_A=np.asarray(M_A, dtype=float),
                   D_lin=np.asarray(ves.linear_damping, dtype=float),
                   d_quad=np.asarray(ves.quadratic_damping, dtype=float),
                   roll_pitch=None if rp is None else RollPitchParams.from_config(rp, scenario.environment))


# --- low-frequency roll and pitch (survey §4.2.3) -------------------------------------------

def _positive(name: str, value: Any, *, zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{name}={value!r} is not a number") from None
    if not math.isfinite(v) or v < 0.0 or (v == 0.0 and not zero):
        raise ModelError(f"{name}={value!r} must be {'>= 0' if zero else '> 0'} and finite")
    return v


@dataclass(frozen=True, kw_only=True)
class RollPitchParams:
    """Low-frequency roll and pitch of the hull: two uncoupled modes about the centre of gravity
    (survey §4.2.3; ``docs/semi.md`` eq. RP1–RP4)::

        (I44 + A44) phi_dd   + B44 phi_d   + C44 phi   = K      C44 = rho g nabla GM_T   (RP1, RP2)
        (I55 + A55) theta_dd + B55 theta_d + C55 theta = M      C55 = rho g nabla GM_L

    with ``I44 = rho nabla r44^2`` (rigid body, mass rho nabla), ``B = 2 zeta sqrt(C (I + A))``.
    phi [rad] is roll (starboard down), theta [rad] pitch (bow up), as
    :func:`tapm_opt.plant.mooring_fem.vertical_offset`.

    Parameters
    ----------
    displacement : float
        Displaced volume nabla [m^3].
    GM_T, GM_L : float
        Transverse and longitudinal metacentric heights [m].
    roll_gyration, pitch_gyration : float
        Radii of gyration r44, r55 about the centre of gravity [m].
    roll_added_inertia, pitch_added_inertia : float
        A44, A55 [kg m^2] about the centre of gravity.
    roll_damping, pitch_damping : float
        zeta_4, zeta_5: linear damping as a fraction of critical [-], in [0, 1).
    cg_depth : float
        Depth z_G of the centre of gravity below the mean water line [m] (negative: above).
    thruster_depth : float
        Depth z_T at which the horizontal thrust acts [m].
    wind_height : float
        Height h_W of the wind load's centre above the mean water line [m].
    rho, g : float
        Water density [kg/m^3] and gravity [m/s^2].
    """

    displacement: float
    GM_T: float
    GM_L: float
    roll_gyration: float
    pitch_gyration: float
    roll_added_inertia: float
    pitch_added_inertia: float
    roll_damping: float
    pitch_damping: float
    cg_depth: float
    thruster_depth: float
    wind_height: float
    rho: float = 1025.0
    g: float = 9.81

    def __post_init__(self) -> None:
        for name in ("displacement", "GM_T", "GM_L", "roll_gyration", "pitch_gyration", "rho", "g"):
            object.__setattr__(self, name, _positive(name, getattr(self, name)))
        for name in ("roll_added_inertia", "pitch_added_inertia", "roll_damping", "pitch_damping"):
            object.__setattr__(self, name, _positive(name, getattr(self, name), zero=True))
        for name in ("roll_damping", "pitch_damping"):
            if getattr(self, name) >= 1.0:
                raise ModelError(f"{name}={getattr(self, name)!r} must be below 1 (a fraction of critical)")
        for name in ("cg_depth", "thruster_depth", "wind_height"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise ModelError(f"{name}={v!r} must be a finite number [m]")
            object.__setattr__(self, name, float(v))

    @classmethod
    def from_config(cls, rp: Any, environment: Any) -> RollPitchParams:
        """From a scenario's ``vessel.roll_pitch`` section and its ``environment`` (density, gravity)."""
        return cls(displacement=rp.displacement, GM_T=rp.GM_T, GM_L=rp.GM_L, roll_gyration=rp.roll_gyration,
                   pitch_gyration=rp.pitch_gyration, roll_added_inertia=rp.roll_added_inertia,
                   pitch_added_inertia=rp.pitch_added_inertia, roll_damping=rp.roll_damping,
                   pitch_damping=rp.pitch_damping, cg_depth=rp.cg_depth, thruster_depth=rp.thruster_depth,
                   wind_height=rp.wind_height, rho=float(environment.water_density), g=float(environment.gravity))

    @property
    def mass(self) -> float:
        """Rigid-body mass rho nabla [kg]."""
        return self.rho * self.displacement

    @property
    def C(self) -> tuple[float, float]:
        """Hydrostatic restoring (C44, C55) = rho g nabla (GM_T, GM_L) [N m/rad] (eq. RP2)."""
        w = self.rho * self.g * self.displacement
        return w * self.GM_T, w * self.GM_L

    @property
    def inertia(self) -> tuple[float, float]:
        """Total inertia (I44 + A44, I55 + A55) [kg m^2], I = rho nabla r^2."""
        m = self.mass
        return (m * self.roll_gyration ** 2 + self.roll_added_inertia,
                m * self.pitch_gyration ** 2 + self.pitch_added_inertia)

    @property
    def critical_damping(self) -> tuple[float, float]:
        """Critical damping (2 sqrt(C44 I44), 2 sqrt(C55 I55)) [N m s/rad]: a damping ratio zeta
        gives B = zeta times it (eq. RP3; also the roll–pitch damping mode's gains)."""
        (c4, c5), (i4, i5) = self.C, self.inertia
        return 2.0 * math.sqrt(c4 * i4), 2.0 * math.sqrt(c5 * i5)

    @property
    def B(self) -> tuple[float, float]:
        """Linear damping (B44, B55) = 2 zeta sqrt(C I) [N m s/rad] (eq. RP3)."""
        b4, b5 = self.critical_damping
        return self.roll_damping * b4, self.pitch_damping * b5

    @property
    def natural_periods(self) -> tuple[float, float]:
        """Undamped natural periods (T4, T5) = 2 pi sqrt(I / C) [s]."""
        (c4, c5), (i4, i5) = self.C, self.inertia
        return 2.0 * math.pi * math.sqrt(i4 / c4), 2.0 * math.pi * math.sqrt(i5 / c5)

    @property
    def thruster_lever(self) -> float:
        """Vertical lever of the thrust below the centre of gravity, z_T - z_G [m]: a sway force Y
        makes the roll moment ``-lever Y``, a surge force X the pitch moment ``+lever X`` (eq. RP4)."""
        return self.thruster_depth - self.cg_depth


def roll_pitch_rhs(x: Any, moment: Any, rp: RollPitchParams) -> Any:
    """Time derivative of the roll–pitch state ``x = (phi, theta, p, q)`` [rad, rad, rad/s, rad/s]
    under the moments ``(K, M)`` [N m] about the centre of gravity (eq. RP1), numpy or CasADi::

        phi_d = p,  theta_d = q,  p_d = (K - B44 p - C44 phi) / (I44 + A44),  q_d likewise.

    Returns an ndarray (4,) or a CasADi 4-vector [rad/s, rad/s, rad/s^2, rad/s^2]."""
    (c4, c5), (i4, i5), (b4, b5) = rp.C, rp.inertia, rp.B
    p_d = (moment[0] - b4 * x[2] - c4 * x[0]) / i4
    q_d = (moment[1] - b5 * x[3] - c5 * x[1]) / i5
    return _vec(x[2], x[3], p_d, q_d)


def roll_pitch_moments(rp: RollPitchParams, tau_thr: Any, tau_wind: Any, tau_wave: Any = (0.0, 0.0, 0.0)) -> Any:
    """Roll and pitch moments (K, M) [N m] about the centre of gravity of the horizontal loads
    in {B} (eq. RP4): thrust at depth z_T, wind at height h_W, wave drift at the water line; a force
    (X, Y) at depth z makes ``K = -(z - z_G) Y`` and ``M = (z - z_G) X``. The lines' moments come
    from their fairlead forces (:meth:`tapm_opt.plant.simulator.Plant` adds them). numpy or CasADi."""
    lt, lw, l0 = rp.thruster_depth - rp.cg_depth, -rp.wind_height - rp.cg_depth, -rp.cg_depth
    K = -(lt * tau_thr[1] + lw * tau_wind[1] + l0 * tau_wave[1])
    M = lt * tau_thr[0] + lw * tau_wind[0] + l0 * tau_wave[0]
    return _vec(K, M)


# --- generic numpy / CasADi helpers ---------------------------------------------------------

def _vec(*xs):
    """Column vector from scalars: CasADi if any is symbolic, else a float ndarray (n,)."""
    return ca.vertcat(*xs) if bk.is_symbolic(*xs) else np.array(xs, dtype=float)


def _mv(A, x):
    """Matrix-vector product for numpy or CasADi operands."""
    return ca.mtimes(A, x) if bk.is_symbolic(A, x) else np.asarray(A) @ x


def _check_form(form: str) -> None:
    if form not in FORMS:
        raise ModelError(f"form={form!r} is unknown; choose one of {FORMS}")


def _as_vec(name: str, x, n: int, symbolic: bool):
    if symbolic:
        x = ca.DM(np.asarray(x, dtype=float)) if not bk.is_symbolic(x) else x
        if x.numel() != n:
            raise ModelError(f"{name} must have {n} elements, got shape {x.shape}")
        return ca.reshape(x, n, 1)
    arr = np.asarray(x, dtype=float)
    if arr.shape != (n,):
        raise ModelError(f"{name} must have shape ({n},), got {arr.shape}")
    return arr


def coriolis(M: Any, nu: Any) -> Any:
    """3-DOF Coriolis–centripetal matrix in skew form from the momentum p = M nu (eq. 8, 11).

    ``C(nu) = [[0, 0, -p2], [0, 0, p1], [p2, -p1, 0]]`` with p = M nu. With ``M = M_RB`` this is
    C_RB(nu); with ``M = M_A`` it is C_A(nu_r), incl. the Munk moment (M_A22 - M_A11) u v.
    C(nu) is skew-symmetric, so nu^T C(nu) nu = 0 (no work).

    Parameters
    ----------
    M : array_like, shape (3, 3)
        Symmetric mass matrix [kg, kg m, kg m^2].
    nu : ndarray shape (3,) or CasADi 3-vector
        Velocity (u [m/s], v [m/s], r [rad/s]).

    Returns
    -------
    ndarray, shape (3, 3), or CasADi 3x3 [kg/s, kg m/s, kg m^2/s].
    """
    p = _mv(M, nu)
    if bk.is_symbolic(p):
        return ca.vertcat(ca.horzcat(0, 0, -p[1]), ca.horzcat(0, 0, p[0]),
                          ca.horzcat(p[1], -p[0], 0))
    return np.array([[0.0, 0.0, -p[1]], [0.0, 0.0, p[0]], [p[1], -p[0], 0.0]])


def vessel_rhs(eta: Any, nu: Any, tau: Any, v_c_E: Any, params: VesselParams, *,
               form: str = "design") -> tuple[Any, Any]:
    """Right-hand side (eta_dot, nu_dot) of the 3-DOF LF vessel model, numpy or CasADi.

    ``form="design"`` (eq. 14–15, eq. 31 with the mooring in ``tau``)::

        eta_dot = R(psi) nu,      M nu_dot + D_lin nu = tau

    The current is ignored: in the design model it is part of the bias b(t) (eq. 15).

    ``form="rich"`` (eq. 8–11, constant irrotational current)::

        nu_c = R(psi)^T (V_x, V_y, 0),  nu_r = nu - nu_c
        M nu_r_dot + C_RB(nu_r) nu_r + C_A(nu_r) nu_r + D_lin nu_r + D_quad(nu_r) nu_r = tau
        nu_dot = nu_r_dot + (r v_c, -r u_c, 0),   eta_dot = R(psi) nu

    where (r v_c, -r u_c, 0) = d/dt nu_c for a current fixed in {E}.

    Parameters
    ----------
    eta : array_like shape (3,) or CasADi 3-vector
        (x [m], y [m], psi [rad]) in {E}.
    nu : array_like shape (3,) or CasADi 3-vector
        Absolute velocity (u [m/s], v [m/s], r [rad/s]) in {B}.
    tau : array_like shape (3,) or CasADi 3-vector
        Total external load (X [N], Y [N], N [N m]) in {B}: thrust + environment + mooring.
    v_c_E : array_like shape (2,) or CasADi 2-vector
        Current velocity (V_x, V_y) in {E} [m/s] (eq. 7). Unused by the design form.
    params : VesselParams
    form : {"design", "rich"}

    Returns
    -------
    eta_dot, nu_dot : ndarray shape (3,) each, or CasADi 3-vectors
        [m/s, m/s, rad/s] and [m/s^2, m/s^2, rad/s^2].
    """
    _check_form(form)
    sym = bk.is_symbolic(eta, nu, tau, v_c_E)
    eta, nu, tau = (_as_vec(n, a, 3, sym) for n, a in (("eta", eta), ("nu", nu), ("tau", tau)))
    v_c_E = _as_vec("v_c_E", v_c_E, 2, sym)
    psi = eta[_PSI]
    eta_dot = _mv(rot_z(psi), nu)
    if form == "design":
        return eta_dot, _mv(params.M_inv, tau - _mv(params.D_lin, nu))
    u_c, v_c = rot2_apply(-psi, v_c_E[0], v_c_E[1])  # R2(psi)^T v_c^E
    nu_r = nu - _vec(u_c, v_c, 0.0)
    d_quad = ca.DM(params.d_quad) if sym else params.d_quad
    damping = _mv(params.D_lin, nu_r) + d_quad * bk.fabs(nu_r) * nu_r
    cor = _mv(coriolis(params.M_RB, nu_r) + coriolis(params.M_A, nu_r), nu_r)
    nu_r_dot = _mv(params.M_inv, tau - cor - damping)
    r = nu[_R]
    return eta_dot, nu_r_dot + _vec(r * v_c, -r * u_c, 0.0)


def vessel_function(params: VesselParams, form: str = "design") -> ca.Function:
    """Compile :func:`vessel_rhs` into ``casadi.Function`` ``vessel_<form>``.

    Inputs ``eta`` (3), ``nu`` (3), ``tau`` (3, {B}), ``v_c`` (2, {E}); outputs ``eta_dot`` (3),
    ``nu_dot`` (3). Units as in :func:`vessel_rhs`. Built once with SX symbols.
    """
    _check_form(form)
    eta, nu, tau, v_c = (ca.SX.sym(n, k) for n, k in
                         (("eta", 3), ("nu", 3), ("tau", 3), ("v_c", 2)))
    eta_dot, nu_dot = vessel_rhs(eta, nu, tau, v_c, params, form=form)
    return ca.Function(f"vessel_{form}", [eta, nu, tau, v_c], [eta_dot, nu_dot],
                       ["eta", "nu", "tau", "v_c"], ["eta_dot", "nu_dot"])


def moored_function(params: VesselParams, tau_moor: ca.Function | None, *, form: str = "design",
                    D_moor: Any = None) -> ca.Function:
    """Moored vessel x_dot = f(x, tau_thr, tau_env, v_c) as ``casadi.Function`` ``moored_<form>``.

    ``tau = tau_thr + tau_env + tau_moor(eta) - D_moor nu`` (eq. 8, 16, 30, 31) enters
    :func:`vessel_rhs`. With the linear spring ``tau_moor(eta) = -R(psi)^T G_mo eta`` and the
    design form this is eq. (31) without the bias.

    Parameters
    ----------
    params : VesselParams
    tau_moor : casadi.Function or None
        Mooring restoring load eta (3) -> g_moor (3) in {B} [N, N, N m] (eq. 28/29); its first
        output is used. None means no mooring restoring load.
    form : {"design", "rich"}
    D_moor : array_like, shape (3, 3), optional
        Linear mooring damping D_mo (eq. 30) [N s/m, N s, N m s], acting on the absolute nu.

    Returns
    -------
    casadi.Function
        Inputs ``x`` (6: eta, nu), ``tau_thr`` (3, {B}), ``tau_env`` (3, {B}), ``v_c`` (2, {E});
        output ``x_dot`` (6).
    """
    _check_form(form)
    D_moor = np.zeros((3, 3)) if D_moor is None else _matrix("D_moor", D_moor, (3, 3))
    _check_psd("D_moor", D_moor)
    if tau_moor is not None and not (
            isinstance(tau_moor, ca.Function) and tau_moor.n_in() == 1 and tau_moor.n_out() >= 1
            and tau_moor.numel_in(0) == 3 and tau_moor.numel_out(0) == 3):
        raise ModelError(f"tau_moor must be a casadi.Function eta(3) -> tau(3), got {tau_moor!r}")
    # SX symbols: CasADi embeds MX Functions (even a rootfinder) in SX expressions as calls
    x, tau_thr, tau_env, v_c = (ca.SX.sym(n, k) for n, k in
                                (("x", 6), ("tau_thr", 3), ("tau_env", 3), ("v_c", 2)))
    eta, nu = x[0:3], x[3:6]
    tau = tau_thr + tau_env - ca.mtimes(D_moor, nu)
    if tau_moor is not None:
        tau = tau + ca.reshape(tau_moor.call([eta])[0], 3, 1)
    eta_dot, nu_dot = vessel_rhs(eta, nu, tau, v_c, params, form=form)
    return ca.Function(f"moored_{form}", [x, tau_thr, tau_env, v_c], [ca.vertcat(eta_dot, nu_dot)],
                       ["x", "tau_thr", "tau_env", "v_c"], ["x_dot"])


def _check_moored(fn: Any) -> None:
    if (not isinstance(fn, ca.Function) or fn.name_in() != ["x", "tau_thr", "tau_env", "v_c"]
            or fn.name_out() != ["x_dot"]):
        raise ModelError(f"fn must be a casadi.Function from moored_function(), got {fn!r}")


def _point(name: str, value: Any, n: int) -> np.ndarray:
    try:
        arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    except ValueError:
        raise ModelError(f"{name}={value!r} must be a scalar or have {n} elements") from None
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{name} must be finite, got {name}={arr.tolist()}")
    return arr


def linearise(fn: ca.Function, x0: Any, tau_thr0: Any = 0.0, tau_env0: Any = 0.0,
              v_c: Any = 0.0, *, outputs: Literal["eta", "state"] = "eta") -> control.StateSpace:
    """Continuous LTI model dx/dt = A dx + B dtau_thr about (x0, tau_thr0, tau_env0, v_c).

    A = d x_dot / d x and B = d x_dot / d tau_thr are exact CasADi Jacobians of ``fn``. The
    point should be an equilibrium (x_dot(x0, ...) ~ 0, e.g. eta0 from :func:`equilibrium` with
    nu0 = 0); otherwise the model describes deviations along a moving trajectory and the
    constant term x_dot(x0) is dropped. Note that |nu_r| in the rich form is not differentiable
    at nu_r = 0, where the quadratic damping then linearises to zero.

    Parameters
    ----------
    fn : casadi.Function
        From :func:`moored_function`.
    x0 : array_like, shape (6,)
        Operating state (x [m], y [m], psi [rad], u [m/s], v [m/s], r [rad/s]).
    tau_thr0, tau_env0 : array_like, shape (3,) or scalar
        Operating thrust and environmental loads in {B} [N, N, N m].
    v_c : array_like, shape (2,) or scalar
        Current (V_x, V_y) in {E} [m/s].
    outputs : {"eta", "state"}
        C selects eta (3x6) or the whole state (6x6). D = 0.

    Returns
    -------
    control.StateSpace
        States ``x, y, psi, u, v, r``, inputs ``X, Y, N``.
    """
    _check_moored(fn)
    if outputs not in ("eta", "state"):
        raise ModelError(f"outputs={outputs!r} is unknown; choose 'eta' or 'state'")
    args = (_point("x0", x0, 6), _point("tau_thr0", tau_thr0, 3),
            _point("tau_env0", tau_env0, 3), _point("v_c", v_c, 2))
    jac = fn.factory("jac_" + fn.name(), ["x", "tau_thr", "tau_env", "v_c"],
                     ["jac:x_dot:x", "jac:x_dot:tau_thr"])
    A, B = (np.asarray(J.full(), dtype=float) for J in jac(*args))
    n_out = 3 if outputs == "eta" else 6
    C = np.eye(6)[:n_out]
    import control  # python-control loads only when a state-space model is asked for

    return control.ss(A, B, C, np.zeros((n_out, 3)), states=list(STATE_NAMES),
                      inputs=list(INPUT_NAMES), outputs=list(STATE_NAMES[:n_out]))


def equilibrium(fn: ca.Function, tau_env: Any, *, tau_thr: Any = 0.0, v_c: Any = 0.0,
                eta_guess: Any = 0.0, tol: float = 1e-9) -> np.ndarray:
    """Position and heading eta0 where the vessel rests (nu = 0, x_dot = 0).

    Solves nu_dot(eta, nu=0) = 0, i.e. tau_moor(eta) + tau_env + tau_thr (+ current drag in
    the rich form) = 0, with :func:`~tapm_opt.models.statics.solve_equilibrium` (Powell's hybrid
    method, the exact CasADi Jacobian; continuation in tau_env and tau_thr if the direct solve
    fails). For the catenary mooring of a scenario without a vessel model,
    :meth:`~tapm_opt.models.mooring.MooringModel.equilibrium` solves the same balance.

    Parameters
    ----------
    fn : casadi.Function
        From :func:`moored_function`.
    tau_env, tau_thr : array_like, shape (3,) or scalar
        Mean environmental and thrust loads in {B} [N, N, N m].
    v_c : array_like, shape (2,) or scalar
        Current in {E} [m/s] (affects the rich form only).
    eta_guess : array_like, shape (3,) or scalar
        Start point [m, m, rad].
    tol : float
        Largest accepted |nu_dot| at the solution [m/s^2, rad/s^2].

    Returns
    -------
    ndarray, shape (3,)
        eta0 (x [m], y [m], psi [rad]); psi is not wrapped, because a mooring model such as
        the linear spring of eq. (29) is not 2 pi-periodic in psi.

    Raises
    ------
    ModelError
        If the solver does not converge (e.g. no mooring stiffness in some direction).
    """
    _check_moored(fn)
    tau_env, tau_thr = _point("tau_env", tau_env, 3), _point("tau_thr", tau_thr, 3)
    v_c, eta_guess = _point("v_c", v_c, 2), _point("eta_guess", eta_guess, 3)
    eta = ca.SX.sym("eta", 3) if fn.is_a("SXFunction") else ca.MX.sym("eta", 3)
    s = ca.SX.sym("s") if fn.is_a("SXFunction") else ca.MX.sym("s")
    res = fn(ca.vertcat(eta, ca.DM.zeros(3)), s * tau_thr, s * tau_env, v_c)[3:6]
    g = ca.Function("g_eq", [eta, s], [res, ca.jacobian(res, eta)])

    def f(e, s):
        return np.asarray(g(e, s)[0].full()).ravel()

    def J(e, s):
        return np.asarray(g(e, s)[1].full())

    try:
        return solve_equilibrium(f, J, eta_guess, tol=tol)
    except EquilibriumError as exc:
        raise EquilibriumError(
            f"equilibrium not found for tau_env={tau_env.tolist()}, tau_thr={tau_thr.tolist()}: "
            f"{exc.reason}", residual=exc.residual, reason=exc.reason) from None
