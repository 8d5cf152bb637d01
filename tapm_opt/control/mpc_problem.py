"""The MPC's optimal control problem, written once as CasADi expressions (see
:mod:`tapm_opt.control.mpc` for the controllers that solve it).

:class:`MPCSettings` holds the weights, limits and solver options; :func:`build_problem` writes the
problem over CasADi symbols in scaled variables with multiple shooting — the prediction model (the
design form of the vessel with the chosen mooring model and the slowly varying environmental load),
the thrust decision (generalised thrust in the one capacity box, or the thrusters' force
components), the cost and the hard and soft constraints, all position terms on the turret offset.
With ``linear_about`` the dynamics and tensions are linearised about an operating point and the
problem is a QP.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import casadi as ca
import numpy as np

from ..errors import TapmError
from ..geometry import R2, rot_z
from ..interfaces import ControllerStep
from ..models.mooring import MooringModel
from ..models.system import CAPACITY_FRACTION, as_system
from ..models.vessel import moored_function

__all__ = ["MPCSettings", "MPCError", "MPCStep", "build_problem"]


class MPCError(TapmError, ValueError):
    """Bad MPC settings or arguments."""


@dataclass(frozen=True, kw_only=True)
class MPCSettings:
    """Settings of :class:`NonlinearMPC` and :class:`LinearMPC` (weights are dimensionless: every
    term is normalised by the reference values below).

    Attributes
    ----------
    horizon : int
        Prediction steps N.
    dt : float
        Prediction step [s]; also the default re-solve period.
    substeps : int
        RK4 steps per prediction step.
    mooring : {"characteristic", "catenary", "linear"}
        Mooring model in the prediction (``models.mooring.MooringModel.force_function``).
    decision : {"tau", "thrusters"}
        Optimise the generalised thrust (allocation after) or the thruster forces directly.
    solver : {"sqp", "ipopt", "fatrop"}
        NLP solver of :class:`NonlinearMPC` (SQP: CasADi ``sqpmethod`` with the active-set
        ``qrqp`` for its QP subproblems, retried with OSQP when it fails; IPOPT; fatrop).
    w_thrust, w_rate : float
        Weights on (tau / tau_ref)^2 (or (f_i / f_max,i)^2) and on its change per step.
    w_position : float
        Weight on (distance outside the dead band / r_ref)^2.
    w_position_in : float
        Weight on (position error / r_ref)^2 everywhere (0: free inside the dead band).
    w_heading, w_velocity : float
        Weights on (heading error / psi_ref)^2 and (nu / nu_ref)^2.
    w_terminal : float
        Multiplier of the state terms at the end of the horizon.
    dead_band : float
        Radius of the dead band of the turret offset about the position setpoint [m] (0: none).
    safe_radius : float or None
        Soft constraint radius of the turret offset about the field zero point [m] (None: from the
        scenario, or none).
    tension_utilisation : float or None
        Soft tension limit as a fraction of MBS (None: the scenario's ``limits.tension_utilisation``).
    soft_l1, soft_l2 : float
        Exact (L1) and quadratic penalties on the normalised soft-constraint violations.
    r_ref, psi_ref, nu_ref, r_rate_ref : float
        Normalisation: position [m], heading [rad], speed [m/s], yaw rate [rad/s].
    capacity_fraction : float
        ``decision="tau"``: the thrust box on X, Y, N is
        ``ThrusterSet.capacity_box(capacity_fraction)`` (the one capacity model,
        ``models.system``).
    polygon_sides : int
        Sides of the polygons approximating circles (dead band, safe circle, thrust circles).
    max_iter : int
        Iteration limit of the NLP solver (SQP iterations or IPOPT iterations).
    max_time : float
        Wall-clock limit of one IPOPT solve [s]; SQP is bounded by ``max_iter`` and its QP solver's
        own iteration limit.
    """

    horizon: int = 20
    dt: float = 5.0
    substeps: int = 1
    mooring: Literal["characteristic", "catenary", "linear"] = "characteristic"
    decision: Literal["tau", "thrusters"] = "tau"
    solver: Literal["sqp", "ipopt", "fatrop"] = "sqp"
    w_thrust: float = 1.0
    w_rate: float = 1.0
    w_position: float = 1.0
    w_position_in: float = 0.0
    w_heading: float = 1.0
    w_velocity: float = 1.0
    w_terminal: float = 5.0
    dead_band: float = 0.0
    safe_radius: float | None = None
    tension_utilisation: float | None = None
    soft_l1: float = 1e3
    soft_l2: float = 1e2
    r_ref: float = 10.0
    psi_ref: float = math.radians(10.0)
    nu_ref: float = 0.5
    r_rate_ref: float = math.radians(0.5)
    capacity_fraction: float = CAPACITY_FRACTION
    polygon_sides: int = 16
    max_iter: int = 30
    max_time: float = 10.0

    def __post_init__(self) -> None:
        pos = ("dt", "r_ref", "psi_ref", "nu_ref", "r_rate_ref", "capacity_fraction", "max_time")
        nonneg = ("w_thrust", "w_rate", "w_position", "w_position_in", "w_heading", "w_velocity", "w_terminal",
                  "dead_band", "soft_l1", "soft_l2")
        for name in pos:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise MPCError(f"MPCSettings.{name} = {v!r} must be a positive number")
        for name in nonneg:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise MPCError(f"MPCSettings.{name} = {v!r} must be a number >= 0")
        for name, lo in (("horizon", 1), ("substeps", 1), ("polygon_sides", 3), ("max_iter", 1)):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= lo):
                raise MPCError(f"MPCSettings.{name} = {v!r} must be a whole number >= {lo}")
        for name, allowed in (("mooring", ("characteristic", "catenary", "linear")), ("decision", ("tau", "thrusters")),
                              ("solver", ("sqp", "ipopt", "fatrop"))):
            if getattr(self, name) not in allowed:
                raise MPCError(f"MPCSettings.{name} = {getattr(self, name)!r} is not one of {', '.join(allowed)}")
        for name, what, hi in (("safe_radius", "a positive number", math.inf),
                               ("tension_utilisation", "a number in (0, 1]", 1.0)):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and 0 < v <= hi):
                raise MPCError(f"MPCSettings.{name} = {v!r} must be {what} or None")


@dataclass(frozen=True, kw_only=True)
class MPCStep(ControllerStep):
    """Diagnostics of one MPC update: a :class:`~tapm_opt.interfaces.ControllerStep` with the
    optimal cost and the largest normalised soft-constraint violation."""

    cost: float = math.nan
    max_soft_violation: float = 0.0


# ------------------------------------------------------------------------------------------
# the problem
# ------------------------------------------------------------------------------------------


@dataclass
class _Problem:
    z: ca.SX | ca.MX
    p: ca.SX | ca.MX
    f: Any
    g: Any
    lbz: np.ndarray
    ubz: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    idx: dict
    scale: dict
    n_u: int
    B_thr: np.ndarray | None


def _polygon(n: int) -> np.ndarray:
    """Outward unit normals of a regular n-gon circumscribing the unit circle."""
    a = 2 * np.pi * np.arange(n) / n
    return np.stack([np.cos(a), np.sin(a)], axis=1)


def _turret(eta: Any, p_cot_B: np.ndarray, psi_op: Any) -> Any:
    """Turret offset of the CasADi pose ``eta`` (``geometry.turret_offset``) expanded to first
    order in the heading about ``psi_op`` (a number or a CasADi parameter):
    ``p + R2(psi_op) c - c + R2'(psi_op) c (psi - psi_op)``, linear in eta. The error is
    ``|c| (1 - cos(psi - psi_op))`` (1.4 m for the fpso's 91 m at 10 deg); the expansion keeps the
    position terms convex, so the SQP's Hessian stays as definite as without the turret."""
    c = ca.DM(np.asarray(p_cot_B, float))
    Rp = ca.mtimes(R2(psi_op), c)
    dRp = ca.vertcat(-Rp[1], Rp[0])
    return eta[0:2] + Rp - c + dRp * (eta[2] - psi_op)


def build_problem(system: Any, settings: MPCSettings, *, linear_about: tuple | None = None,
                  model: MooringModel | None = None) -> _Problem:
    """Write the MPC problem (module docstring) as CasADi expressions.

    Parameters
    ----------
    system : System or Scenario
        The vessel, line system and thrusters (a scenario is built into its :class:`System`).
    linear_about : (x_op (6,), u_op (3,), b_op (3,)) or None
        None: nonlinear prediction. Otherwise the dynamics are linearised about this point, the
        tensions about ``x_op``'s pose, and the heading error is used unwrapped: the problem is a QP.

    Returns the decision vector ``z`` (scaled), parameters ``p = (x0, u_prev, eta_d, b)`` in SI, cost
    ``f``, constraints ``g`` with bounds, and index maps.
    """
    s = settings
    N = s.horizon
    system = as_system(system)
    if not system.thrusters.n:
        raise MPCError(f"scenario {system.name!r} has no thrusters: there is nothing to control")
    vp = system.vessel
    moor = model or system.lines
    p_cot = np.asarray(system.p_cot_B, float)
    eta_op = np.zeros(3) if linear_about is None else np.asarray(linear_about[0][:3], float)
    kind = s.mooring
    tau_moor = moor.force_function(kind, eta0=eta_op)
    if kind != "catenary":
        tau_moor = tau_moor.expand()  # pure SX: evaluated without the MX virtual machine
    rhs = moored_function(vp, tau_moor, form="design")
    # thrust variables
    B_thr, u_lo, u_hi, kinds, owner = system.thrusters.extended()
    fmax = np.maximum(np.abs(u_lo), np.abs(u_hi))
    fmax = np.where(fmax > 0, fmax, system.thrusters.f_max[owner])  # a failed thruster keeps its scale
    rate = system.thrusters.rate[owner]
    if s.decision == "tau":
        # the one capacity model: a box the thrusters can deliver in X, Y and N at once
        cap = np.asarray(system.thrusters.capacity_box(s.capacity_fraction), float)
        n_u = 3
        u_ref = cap
        u_lo_s, u_hi_s = -np.ones(3), np.ones(3)
        rate_s = np.asarray(system.thrusters.rate_box(s.capacity_fraction), float) / cap
        Bu = np.eye(3)
    else:
        n_u = B_thr.shape[1]
        u_ref = fmax
        u_lo_s, u_hi_s = u_lo / fmax, u_hi / fmax
        rate_s = rate / fmax
        Bu = B_thr
    x_ref = np.array([s.r_ref, s.r_ref, s.psi_ref, s.nu_ref, s.nu_ref, s.r_rate_ref])
    util = system.limits.tension_utilisation if s.tension_utilisation is None else s.tension_utilisation
    T_allow = util * np.asarray(moor.MBS, float)
    R_safe = system.limits.safe_radius if s.safe_radius is None else s.safe_radius
    psi_lin = float(eta_op[2]) if linear_about is not None else None
    polyg = _polygon(s.polygon_sides)

    Sym = ca.MX if kind == "catenary" and linear_about is None else ca.SX
    p = Sym.sym("p", 6 + n_u + 3 + 3)
    x0, u_prev, eta_d, b_E = p[0:6], p[6:6 + n_u], p[6 + n_u:9 + n_u], p[9 + n_u:12 + n_u]
    if psi_lin is None:
        psi_lin = x0[2]  # the turret offset is expanded about the present heading

    # discrete dynamics (RK4) in SI, with thrust tau = Bu u
    xs, us, bs = ca.SX.sym("x", 6), ca.SX.sym("u", n_u), ca.SX.sym("b", 3)
    if kind == "catenary":
        xs, us, bs = ca.MX.sym("x", 6), ca.MX.sym("u", n_u), ca.MX.sym("b", 3)
    h = s.dt / s.substeps
    xk = xs
    tau_u = ca.mtimes(ca.DM(Bu), us)
    for _ in range(s.substeps):
        def fx(xx):
            tau_env = ca.mtimes(rot_z(xx[2]).T, bs)
            return rhs(xx, tau_u, tau_env, ca.DM.zeros(2))
        k1 = fx(xk)
        k2 = fx(xk + h / 2 * k1)
        k3 = fx(xk + h / 2 * k2)
        k4 = fx(xk + h * k3)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    F = ca.Function("F", [xs, us, bs], [xk])
    tension = moor.tension_function("catenary" if kind == "catenary" else "characteristic", eta0=eta_op)
    if kind != "catenary":
        tension = tension.expand()
    if linear_about is not None:
        x_op, u_op, b_op = (np.asarray(a, float) for a in linear_about)
        A = np.array(ca.Function("A", [xs, us, bs], [ca.jacobian(xk, xs)])(x_op, u_op, b_op))
        Bm = np.array(ca.Function("B", [xs, us, bs], [ca.jacobian(xk, us)])(x_op, u_op, b_op))
        G = np.array(ca.Function("G", [xs, us, bs], [ca.jacobian(xk, bs)])(x_op, u_op, b_op))
        F0 = np.array(F(x_op, u_op, b_op)).ravel()
        xs2, us2, bs2 = ca.SX.sym("x", 6), ca.SX.sym("u", n_u), ca.SX.sym("b", 3)
        F = ca.Function("F_lin", [xs2, us2, bs2], [ca.DM(F0) + ca.mtimes(ca.DM(A), xs2 - x_op)
                                                   + ca.mtimes(ca.DM(Bm), us2 - u_op) + ca.mtimes(ca.DM(G), bs2 - b_op)])
        e_s = ca.SX.sym("e", 3)
        T0 = np.array(tension(x_op[:3])).ravel()
        JT = _jac(tension, x_op[:3])
        tension = ca.Function("T_lin", [e_s], [ca.DM(T0) + ca.mtimes(ca.DM(JT), e_s - x_op[:3])])

    # decision variables (scaled): X (6 x N+1), U (n_u x N), slacks: dead band, safe, tension (N each)
    nX, nU = 6 * (N + 1), n_u * N
    z = Sym.sym("z", nX + nU + 3 * N)
    X = ca.reshape(z[:nX], 6, N + 1)
    U = ca.reshape(z[nX:nX + nU], n_u, N)
    S_db = z[nX + nU:nX + nU + N]
    S_safe = z[nX + nU + N:nX + nU + 2 * N]
    S_T = z[nX + nU + 2 * N:nX + nU + 3 * N]
    Dx, Du = ca.DM(x_ref), ca.DM(u_ref)

    g, lbg, ubg = [], [], []
    cost = 0
    g.append(X[:, 0] - x0 / Dx)
    lbg += [0.0] * 6
    ubg += [0.0] * 6
    u_last = u_prev / Du
    for k in range(N):
        xk_si = X[:, k] * Dx
        uk_si = U[:, k] * Du
        xn = F(xk_si, uk_si, b_E)
        g.append(X[:, k + 1] - xn / Dx)
        lbg += [0.0] * 6
        ubg += [0.0] * 6
        # thrust rate (hard)
        g.append(U[:, k] - u_last)
        lbg += list(-rate_s * s.dt)
        ubg += list(rate_s * s.dt)
        # thrust circles of azimuths and the rate of their force vectors (thruster decision):
        # |f| <= f_max and |f_k - f_k-1| <= rate dt, as inscribed polygons (so the magnitude too
        # changes by at most rate dt)
        if s.decision == "thrusters":
            col = 0
            while col < n_u:
                if kinds[col] == "az":
                    uv = U[col:col + 2, k]
                    duv = uv - u_last[col:col + 2]
                    for nrm in polyg:
                        g.append(nrm[0] * uv[0] + nrm[1] * uv[1])
                        lbg.append(-ca.inf)
                        ubg.append(math.cos(math.pi / s.polygon_sides))  # inscribed polygon
                        g.append(nrm[0] * duv[0] + nrm[1] * duv[1])
                        lbg.append(-ca.inf)
                        ubg.append(rate_s[col] * s.dt * math.cos(math.pi / s.polygon_sides))
                    col += 2
                else:
                    col += 1
        cost += s.w_thrust * ca.sumsqr(U[:, k]) + s.w_rate * ca.sumsqr(U[:, k] - u_last)
        u_last = U[:, k]
        # state terms at k+1
        xe = X[:, k + 1] * Dx
        w_state = s.w_terminal if k == N - 1 else 1.0
        p_t = _turret(xe[0:3], p_cot, psi_lin)  # turret offset: the point safety refers to
        dp = p_t - eta_d[0:2]
        if s.dead_band > 0:
            for nrm in polyg:
                g.append((nrm[0] * dp[0] + nrm[1] * dp[1]) / s.r_ref - S_db[k])
                lbg.append(-ca.inf)
                ubg.append(s.dead_band / s.r_ref)
            cost += w_state * s.w_position * S_db[k] ** 2
        elif s.w_position > 0:
            # no dead band: the distance itself, squared (the polygon's slack would put 16
            # degenerate faces through the setpoint, on which the active-set QP solver cycles)
            cost += w_state * s.w_position * ca.sumsqr(dp / s.r_ref)
        cost += w_state * s.w_position_in * ca.sumsqr(dp / s.r_ref)
        dpsi = xe[2] - eta_d[2]
        if linear_about is None:
            cost += w_state * s.w_heading * 2.0 * (1.0 - ca.cos(dpsi)) / s.psi_ref ** 2
        else:
            cost += w_state * s.w_heading * (dpsi / s.psi_ref) ** 2
        cost += w_state * s.w_velocity * (ca.sumsqr(xe[3:5] / s.nu_ref) + (xe[5] / s.r_rate_ref) ** 2)
        # soft: safe circle of the turret offset about the field zero point, line tensions
        if R_safe is not None:
            for nrm in polyg:
                g.append((nrm[0] * p_t[0] + nrm[1] * p_t[1]) / R_safe - S_safe[k])
                lbg.append(-ca.inf)
                ubg.append(1.0)
        T = tension(xe[0:3])
        g.append(T / ca.DM(T_allow) - S_T[k])
        lbg += [-ca.inf] * len(T_allow)
        ubg += [1.0] * len(T_allow)
        cost += s.soft_l1 * (S_safe[k] + S_T[k]) + s.soft_l2 * (S_safe[k] ** 2 + S_T[k] ** 2)
    g = ca.vertcat(*g)
    lbz = np.concatenate([np.full(nX, -np.inf), np.tile(u_lo_s, N), np.zeros(3 * N)])
    ubz = np.concatenate([np.full(nX, np.inf), np.tile(u_hi_s, N), np.full(3 * N, np.inf)])
    idx = {"X": slice(0, nX), "U": slice(nX, nX + nU), "S_db": slice(nX + nU, nX + nU + N),
           "S_safe": slice(nX + nU + N, nX + nU + 2 * N), "S_T": slice(nX + nU + 2 * N, nX + nU + 3 * N)}
    scale = {"x": x_ref, "u": u_ref, "T_allow": T_allow, "R_safe": R_safe, "p_cot_B": p_cot}
    return _Problem(z=z, p=p, f=cost, g=g, lbz=lbz, ubz=ubz, lbg=np.array(lbg, float), ubg=np.array(ubg, float),
                    idx=idx, scale=scale, n_u=n_u, B_thr=Bu if s.decision == "thrusters" else None)


def _jac(fn: ca.Function, x: np.ndarray) -> np.ndarray:
    q = ca.MX.sym("q", fn.size1_in(0))
    return np.array(ca.Function("J", [q], [ca.jacobian(fn(q), q)])(x))
