"""Tests of the MPC controllers (tapm_opt.control.mpc) on the fpso scenario (6 azimuths, 12 lines).

Analytic limits (the first move of the MPC without active constraints equals the finite-horizon
Riccati feedback on the RK4-discretised linearised model, and tends to the discrete LQR as the
horizon grows), hard and soft constraints, agreement between the nonlinear and the linear MPC and
between the NLP solvers, the min-norm allocation implied by ``decision="thrusters"``, the fallback
to the shifted previous plan, warm starts and bad input. The plant used to roll plans out and to
close loops is an independent RK4 of ``moored_function`` (the design model) written here.
"""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import piqp
import pytest
import scipy.linalg

import tapm_opt
from tapm_opt.config import scenario_from_dict, scenario_to_dict
from tapm_opt.control.estimate import Estimate, Setpoint
from tapm_opt.control.mpc import LinearMPC, MPCError, MPCSettings, NonlinearMPC, build_problem
from tapm_opt.geometry import body_from_turret, rot_z, turret_offset
from tapm_opt.models.mooring import MooringModel
from tapm_opt.models.system import ThrusterSet
from tapm_opt.models.thrust import extended_columns
from tapm_opt.models.vessel import VesselParams, linearise, moored_function

# Settings under which no constraint is active for small offsets and the cost is quadratic: no
# dead band (w_position = 0), quadratic position, heading and velocity terms, no rate term, the
# soft constraints far away.
QUADRATIC = dict(w_position=0.0, dead_band=0.0, w_position_in=1.0, w_heading=1.0, w_velocity=1.0,
                 w_rate=0.0, w_thrust=1.0, w_terminal=3.0, safe_radius=1e4, tension_utilisation=0.99, dt=5.0,
                 max_iter=100, thrust_set="box", linearise_about="setpoint")
# A small offset about the field zero point (the equilibrium of the fpso mooring without load). Heading 0:
# the linear MPC linearises about the estimated heading, and the LQR here about the equilibrium.
X0 = np.array([2.0, -1.5, 0.0, 0.01, -0.005, 2e-4])
# Aggressive settings that saturate the thrust at a large offset (explicit: the defaults are tuned elsewhere).
AGGRESSIVE = dict(w_position=50.0, w_position_in=0.0, w_heading=20.0, psi_ref=math.radians(5.0), w_velocity=0.0,
                  w_rate=1.0, dead_band=0.0, max_iter=100, thrust_set="box")
SP0 = Setpoint(np.zeros(3))


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


@pytest.fixture(scope="module")
def equivalent():
    """fpso_equivalent: fpso on its former homogeneous equivalent lines, softer than the
    chain-wire-chain (K11 8.6e4 against 1.4e5 N/m at rest, a third of the restoring at 80 m); the
    tests whose loads and recorded states were set on that mooring run on it."""
    return tapm_opt.load_scenario("fpso_equivalent")


def _plant_fn(sc):
    vp = VesselParams.from_scenario(sc)
    f = MooringModel.from_scenario(sc).force_function("characteristic").expand()
    return moored_function(vp, f, form="design")


@pytest.fixture(scope="module")
def plant_fn(fpso):
    """Design model with the characteristic mooring, an SX Function (numeric calls only here)."""
    return _plant_fn(fpso)


@pytest.fixture(scope="module")
def plant_fn_equivalent(equivalent):
    return _plant_fn(equivalent)


def est(x, tau_env=(0.0, 0.0, 0.0), t=0.0) -> Estimate:
    x = np.asarray(x, float)
    return Estimate(t, x[:3], x[3:], tau_env)


def capacity(scenario, fraction=None):
    """(box [N, N, N m], rate per second [N/s, ...]) of ``decision="tau"``: the one capacity model
    of the thrusters (``ThrusterSet.capacity_box`` and ``rate_box``) at ``fraction`` (default:
    MPCSettings' capacity_fraction)."""
    fraction = MPCSettings().capacity_fraction if fraction is None else fraction
    ths = ThrusterSet.from_scenario(scenario)
    return np.asarray(ths.capacity_box(fraction)), np.asarray(ths.rate_box(fraction))


def rk4(fn, x, tau, b_E, h, substeps=1):
    """One step of length h (tau held) of the moored model with tau_env = R(psi)^T b_E."""
    dt = h / substeps

    def f(xx):
        return np.asarray(fn(xx, tau, rot_z(xx[2]).T @ b_E, np.zeros(2))).ravel()

    for _ in range(substeps):
        k1 = f(x)
        k2 = f(x + dt / 2 * k1)
        k3 = f(x + dt / 2 * k2)
        k4 = f(x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def closed_loop(ctrl, fn, x0, b_E, steps, dt):
    """Apply every first move for dt to the design model; returns (tau (steps, 3), x (steps+1, 6))."""
    x, taus, xs = np.asarray(x0, float), [], [np.asarray(x0, float)]
    for k in range(steps):
        tau = ctrl.update(k * dt, est(x, rot_z(x[2]).T @ b_E, t=k * dt), SP0)
        taus.append(tau)
        x = rk4(fn, x, tau, b_E, dt, substeps=5)
        xs.append(x)
    return np.array(taus), np.array(xs)


def rk4_discrete(A, B, h):
    """Jacobians of one RK4 step of x' = A x + B u (u held): at an equilibrium these are the
    Jacobians of the RK4 step of the nonlinear model, since every stage is evaluated there."""
    M = h * A
    I = np.eye(A.shape[0])
    Ad = I + M + M @ M / 2 + M @ M @ M / 6 + M @ M @ M @ M / 24
    Bd = h * (I + M / 2 + M @ M / 6 + M @ M @ M / 24) @ B
    return Ad, Bd


def weights(settings, scale):
    """Q (6x6) and R_tau (3x3) in SI of the MPC cost (build_problem's normalisation). The position
    terms weigh the turret offset, to first order about heading 0 ``(x - c_y psi, y + c_x psi)``
    with ``c = p_cot_B``: Q = S^T diag(w / x_ref^2) S."""
    s = settings
    c = np.asarray(scale["p_cot_B"], float)
    S = np.eye(6)
    S[0, 2], S[1, 2] = -c[1], c[0]
    Qd = np.diag(np.array([s.w_position_in, s.w_position_in, s.w_heading, s.w_velocity, s.w_velocity, s.w_velocity])
                 / np.asarray(scale["x"]) ** 2)
    return S.T @ Qd @ S, s.w_thrust * np.diag(1.0 / np.asarray(scale["u"]) ** 2)


def riccati_gains(Ad, Bd, Q, R, N, P_N):
    """(K_N: first-move gain of the N-step problem with terminal weight P_N, K: infinite-horizon LQR).

    The MPC weighs x_1..x_N (x_N by P_N) and u_0..u_{N-1}: the backward recursion from P_N."""
    P = P_N
    for _ in range(N):
        K_N = np.linalg.solve(R + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
        P = Q + Ad.T @ P @ (Ad - Bd @ K_N)
    P_inf = scipy.linalg.solve_discrete_are(Ad, Bd, Q, R)
    K = np.linalg.solve(R + Bd.T @ P_inf @ Bd, Bd.T @ P_inf @ Ad)
    return K_N, K


@pytest.fixture(scope="module")
def discrete_model(fpso):
    """RK4 Jacobians (dt = 5 s) of the design model with the linear mooring about the field zero point,
    from the continuous linearisation of ``vessel.linearise`` (python-control)."""
    vp = VesselParams.from_scenario(fpso)
    fn = moored_function(vp, MooringModel.from_scenario(fpso).force_function("linear"), form="design")
    sys_c = linearise(fn, np.zeros(6), outputs="state")
    return rk4_discrete(np.asarray(sys_c.A), np.asarray(sys_c.B), QUADRATIC["dt"])


def replace_solver(s, solver, **kw):
    return replace(s, solver=solver, **kw)


def rel(a, b, scale):
    return float(np.linalg.norm((np.asarray(a) - np.asarray(b)) / scale) / np.linalg.norm(np.asarray(b) / scale))


# --- LQR limit -----------------------------------------------------------------------------------

def test_linear_mpc_first_move_is_riccati_feedback_and_tends_to_lqr(fpso, discrete_model):
    """Unconstrained quadratic MPC = finite-horizon LQR (terminal weight w_terminal Q); its first move
    approaches u = -K x of the discrete LQR as the horizon grows."""
    Ad, Bd = discrete_model
    err_inf = []
    for N in (10, 20, 40, 80):
        s = MPCSettings(horizon=N, **QUADRATIC)
        scale = build_problem(fpso, s).scale
        Q, R = weights(s, scale)
        K_N, K = riccati_gains(Ad, Bd, Q, R, N, s.w_terminal * Q)
        ctrl = LinearMPC(fpso, s)
        tau = ctrl.update(0.0, est(X0), SP0)
        d = ctrl.diagnostics[-1]
        assert d.success and not d.fallback and d.active == ()
        assert rel(tau, -K_N @ X0, scale["u"]) < 1e-4, N
        err_inf.append(rel(tau, -K @ X0, scale["u"]))
    assert err_inf[0] > 0.05  # a short horizon is visibly not the LQR ...
    assert all(b < a for a, b in zip(err_inf, err_inf[1:])), err_inf  # ... and the error falls with N
    assert err_inf[-1] < 0.02


def test_linear_mpc_thruster_decision_is_lqr_with_allocation_weight(fpso, discrete_model):
    """decision="thrusters" with w_thrust sum (f_i/f_max)^2: for a given tau the cheapest forces are
    the weighted min-norm allocation, so the problem is LQR with R = w (B F^2 B^T)^-1, F = diag(f_max)."""
    Ad, Bd = discrete_model
    B = np.hstack([extended_columns(*t.position) for t in fpso.thrusters])
    F2 = np.diag(np.repeat([t.max_thrust for t in fpso.thrusters], 2) ** 2)
    cap, _ = capacity(fpso)
    for N in (20, 50):
        s = MPCSettings(horizon=N, decision="thrusters", **QUADRATIC)
        Q, _ = weights(s, build_problem(fpso, s).scale)
        R = s.w_thrust * np.linalg.inv(B @ F2 @ B.T)
        K_N, K = riccati_gains(Ad, Bd, Q, R, N, s.w_terminal * Q)
        ctrl = LinearMPC(fpso, s)
        tau = ctrl.update(0.0, est(X0), SP0)
        assert ctrl.diagnostics[-1].success and ctrl.diagnostics[-1].active == ()
        assert rel(tau, -K_N @ X0, cap) < 1e-4, N
    assert rel(tau, -K @ X0, cap) < 0.02


def test_nonlinear_mpc_linear_mooring_tends_to_lqr(fpso, discrete_model):
    """The NLP path (SQP) with the "linear" mooring, near the equilibrium: the same limits. The offset
    is 10x smaller than above: the rotation R(psi) and the cos heading cost are nonlinear, and the
    difference to the linear answer scales with the offset (0.5 % of the move at X0)."""
    Ad, Bd = discrete_model
    x0 = 0.1 * X0
    err_inf = []
    for N in (20, 50):
        s = MPCSettings(horizon=N, mooring="linear", solver="sqp", **QUADRATIC)
        scale = build_problem(fpso, s).scale
        Q, R = weights(s, scale)
        K_N, K = riccati_gains(Ad, Bd, Q, R, N, s.w_terminal * Q)
        ctrl = NonlinearMPC(fpso, s)
        tau = ctrl.update(0.0, est(x0), SP0)
        assert ctrl.diagnostics[-1].success and ctrl.diagnostics[-1].active == ()
        assert rel(tau, -K_N @ x0, scale["u"]) < 2e-3, N
        err_inf.append(rel(tau, -K @ x0, scale["u"]))
    assert err_inf[1] < err_inf[0] and err_inf[1] < 0.02, err_inf


# --- hard constraints ------------------------------------------------------------------------------

@pytest.mark.parametrize("make", [
    pytest.param(lambda sc, s: LinearMPC(sc, s), id="linear"),
    pytest.param(lambda sc, s: NonlinearMPC(sc, replace_solver(s, "sqp", horizon=10)), id="nonlinear-sqp"),
])
def test_applied_tau_respects_capacity_box_and_rate(fpso, plant_fn, make):
    """A 43 m offset saturates the thrust; the applied tau never leaves the box and changes at most
    rate x dt between updates (from zero at the first one)."""
    s = MPCSettings(**AGGRESSIVE)
    cap, rate = capacity(fpso, s.capacity_fraction)
    assert np.allclose(build_problem(fpso, s).scale["u"], cap)  # the box is the one computed here
    ctrl = make(fpso, s)
    taus, _ = closed_loop(ctrl, plant_fn, [35.0, -25.0, 0.1, 0.0, 0.0, 0.0], np.zeros(3), 6, s.dt)
    assert np.all(np.isfinite(taus))
    assert np.all(np.abs(taus) <= cap * (1 + 1e-9))
    steps = np.diff(np.vstack([np.zeros(3), taus]), axis=0)
    # (OSQP, the linear MPC's QP solver, meets its constraints to its eps = 1e-5)
    assert np.all(np.abs(steps) <= rate * s.dt * (1 + 1e-4) + 1e-9 * cap)
    assert np.max(np.abs(taus) / cap) > 0.999  # the case does saturate
    assert any("thrust_capacity" in d.active for d in ctrl.diagnostics)


def thruster_forces(ctrl):
    """Force vectors (n, 2) [N] of the last applied move, from last_thruster_command()."""
    cmd = ctrl.thruster_command()
    f, alpha = cmd.f, cmd.alpha
    return np.stack([f * np.cos(alpha), f * np.sin(alpha)], axis=1)


@pytest.mark.parametrize("make", [
    pytest.param(lambda sc, s: LinearMPC(sc, s), id="linear"),
    pytest.param(lambda sc, s: NonlinearMPC(sc, replace_solver(s, "ipopt", horizon=10)), id="nonlinear-ipopt"),
])
def test_thruster_decision_respects_thrust_circles_and_rate(fpso, plant_fn, make):
    """decision="thrusters": every azimuth's force magnitude <= max_thrust (inscribed polygon), each
    component changes at most max_thrust_rate x dt per update, and tau is B u of those forces."""
    s = MPCSettings(decision="thrusters", **AGGRESSIVE)
    fmax = np.array([t.max_thrust for t in fpso.thrusters])
    rate = np.array([t.max_thrust_rate for t in fpso.thrusters])
    ctrl = make(fpso, s)
    x = np.array([35.0, -25.0, 0.1, 0.0, 0.0, 0.0])
    prev = np.zeros((len(fmax), 2))
    peak = 0.0
    B = np.hstack([extended_columns(*t.position) for t in fpso.thrusters])
    for k in range(5):
        tau = ctrl.update(k * s.dt, est(x, t=k * s.dt), SP0)
        fv = thruster_forces(ctrl)
        mag = np.hypot(fv[:, 0], fv[:, 1])
        assert np.all(mag <= fmax * (1 + 1e-4)), mag / fmax  # (OSQP's eps = 1e-5)
        assert np.all(np.hypot(*(fv - prev).T) <= rate * s.dt * (1 + 1e-4) + 1e-6 * fmax)
        assert np.allclose(tau, B @ fv.ravel(), rtol=1e-9, atol=1e-6 * fmax.max())
        peak = max(peak, float(np.max(mag / fmax)))
        prev = fv
        x = rk4(plant_fn, x, tau, np.zeros(3), s.dt, substeps=5)
    assert peak > 0.95  # the thrusters do saturate
    assert all(d.success for d in ctrl.diagnostics)


def test_thruster_decision_respects_magnitude_rate(fpso):
    """The rate limit bounds the change of each azimuth's force vector (an inscribed polygon), so
    from rest the thrust magnitude reaches at most max_thrust_rate x dt in one update."""
    s = MPCSettings(decision="thrusters", **AGGRESSIVE)
    ctrl = LinearMPC(fpso, s)
    ctrl.update(0.0, est([35.0, -25.0, 0.1, 0.0, 0.0, 0.0]), SP0)
    f = ctrl.thruster_command().f
    rate = np.array([t.max_thrust_rate for t in fpso.thrusters])
    assert np.all(f <= rate * s.dt * (1 + 1e-4))  # (OSQP's eps = 1e-5)
    assert np.max(f / (rate * s.dt)) > 0.9  # the limit is reached: it is what binds


# --- soft constraints ------------------------------------------------------------------------------

# lazy settings: nothing pulls the vessel to the setpoint but the safe circle (tensions far away)
LAZY = dict(w_position=0.0, w_position_in=0.0, w_heading=1.0, w_velocity=0.0, w_rate=0.0, w_terminal=1.0,
            tension_utilisation=0.99, max_iter=100, thrust_set="box")


def rollout(ctrl, fn, x0, b_E, dt):
    xs = [np.asarray(x0, float)]
    for u in ctrl.plan_u:
        xs.append(rk4(fn, xs[-1], ctrl.tau_from_u(u), b_E, dt))
    return np.array(xs)


@pytest.mark.parametrize("solver", ["ipopt", "sqp"])
def test_safe_circle_is_kept_when_it_can_be(equivalent, plant_fn_equivalent, solver):
    """6 MN (fixed in {E}; the vessel heads 30 deg off it) push the turret from 45 m to ~70 m on
    fpso_equivalent's soft mooring (on fpso's chain-wire-chain only to 51 m); the thrusters (4.3 MN)
    can hold it at 50 m: the MPC does so with no soft violation, and its plan, rolled out through
    the independent model, keeps the turret inside the circle. Without the circle the same MPC
    lets it drift out (the constraint is what acts)."""
    fpso, plant_fn = equivalent, plant_fn_equivalent
    b = np.array([6.0e6, 0.0, 0.0])
    psi0 = math.radians(30.0)
    x0 = np.array([*body_from_turret((45.0, 0.0), psi0, fpso.turret.position), psi0, 0.0, 0.0, 0.0])
    radii = {}
    for R in (50.0, 1e4):
        s = MPCSettings(solver=solver, safe_radius=R, **LAZY)
        ctrl = NonlinearMPC(fpso, s)
        for _ in range(3):
            tau = ctrl.update(0.0, est(x0, rot_z(x0[2]).T @ b), SP0)
        d = ctrl.diagnostics[-1]
        assert d.success and not d.fallback
        assert d.max_soft_violation < 1e-6
        xs = rollout(ctrl, plant_fn, x0, b, s.dt)
        radii[R] = float(np.max(np.hypot(*turret_offset(xs[:, :3], fpso.turret.position))))
        if R == 50.0:
            assert (rot_z(x0[2]) @ tau)[0] < -0.2 * capacity(fpso)[0][0]  # thrust against the load
    # the polygon circumscribes the circle; the MPC expands the turret offset to first order in the
    # heading about the present one (error |p_cot| (1 - cos dpsi), a few cm here)
    assert radii[50.0] <= 50.0 / math.cos(math.pi / MPCSettings().polygon_sides) + 0.1, radii
    assert radii[1e4] > 60.0, radii


@pytest.mark.parametrize("cls", [LinearMPC, NonlinearMPC], ids=["linear", "nonlinear-sqp"])
def test_safe_circle_violated_only_when_infeasible(fpso, cls):
    """30 MN exceed thrust (4.3 MN) plus mooring (~4 MN at 50 m): the solve still succeeds, reports a
    soft violation and the active circle, and the thrust goes to its bound against the load."""
    b = np.array([3.0e7, 0.0, 0.0])
    x0 = np.array([45.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    s = MPCSettings(solver="sqp", safe_radius=50.0, **LAZY)
    cap, _ = capacity(fpso)
    ctrl = cls(fpso, s)
    for _ in range(3):  # the rate limit takes two updates from 0 to the bound
        tau = ctrl.update(0.0, est(x0, b), SP0)
    d = ctrl.diagnostics[-1]
    assert d.success and not d.fallback
    assert d.max_soft_violation > 0.1
    assert "safe_circle" in d.active and "thrust_capacity" in d.active
    assert tau[0] == pytest.approx(-cap[0], rel=1e-6)


@pytest.mark.parametrize("cls,solver", [
    pytest.param(LinearMPC, "sqp", id="linear"),
    pytest.param(NonlinearMPC, "ipopt", id="nonlinear-ipopt"),
    pytest.param(NonlinearMPC, "sqp", id="nonlinear-sqp"),
])
def test_no_thrust_at_a_loaded_equilibrium(fpso, cls, solver):
    """The vessel rests at its setpoint (25 m off, heading 30 deg) where a load fixed in {E} balances
    the mooring: nothing is to be corrected, so the MPC plans no thrust. Checks the frames of the
    load (tau_env = R(psi)^T b) and of the mooring in the prediction model. The balancing load is that
    of the prediction's mooring: the line characteristics centred at the operating pose (the
    setpoint here), i.e. the elastic catenary there, for both MPCs. (With SQP this once stopped with
    Search_Direction_Becomes_Too_Small: started at the optimum without multipliers.)"""
    eta = np.array([20.0, 15.0, math.radians(30.0)])
    model = MooringModel.from_scenario(fpso)
    tau_moor = model.force(eta)
    cap, _ = capacity(fpso)
    ctrl = cls(fpso, MPCSettings(solver=solver, **QUADRATIC))
    sp = Setpoint([*turret_offset(eta, fpso.turret.position), eta[2]])  # the turret's own position
    ctrl.update(0.0, Estimate(0.0, eta, np.zeros(3), -tau_moor), sp)
    assert ctrl.diagnostics[-1].success, ctrl.diagnostics[-1].status
    assert np.max(np.abs(ctrl.plan_u) / cap) < 1e-4
    assert np.linalg.norm(tau_moor[:2]) > 1e6  # the load is not small


# --- nonlinear vs linear ---------------------------------------------------------------------------

@pytest.mark.parametrize("mooring", ["characteristic", "linear"])
def test_nonlinear_and_linear_mpc_agree_near_equilibrium(fpso, mooring):
    """Same settings (dead band polygon included), a few metres off, a small load: first moves agree
    to 2 % of the capacity (they differ by the linearisation only)."""
    s = MPCSettings(mooring=mooring, w_position=2.0, w_position_in=1.0, w_heading=2.0, w_velocity=1.0, w_rate=1.0,
                    dead_band=0.0, max_iter=100, thrust_set="box")
    e = est([3.0, -2.0, math.radians(1.0), 0.01, 0.0, 0.0], (3e5, 1e5, 0.0))
    cap, rate = capacity(fpso)
    a = NonlinearMPC(fpso, s).update(0.0, e, SP0)
    b = LinearMPC(fpso, s).update(0.0, e, SP0)
    assert np.all(np.abs(a) < rate * s.dt * 0.9)  # no bound active: a meaningful comparison
    assert np.max(np.abs(a - b) / cap) < 0.02
    assert np.max(np.abs(a) / cap) > 0.1


# with the dead-band polygon (a slack above 16 half-planes per stage): the cost is only piecewise smooth
DEAD_BAND = dict(w_position=2.0, w_position_in=0.0, w_heading=2.0, w_velocity=1.0, w_rate=1.0, dead_band=2.0,
                 max_iter=100)


@pytest.fixture(scope="module")
def sqp_first_moves(fpso):
    """First move of the SQP path with the QUADRATIC and the DEAD_BAND settings, N = 10."""
    e = est([3.0, -2.0, math.radians(1.0), 0.01, 0.0, 0.0], (3e5, 1e5, 0.0))
    out = {}
    for name, kw in (("quadratic", QUADRATIC), ("dead_band", DEAD_BAND)):
        ctrl = NonlinearMPC(fpso, MPCSettings(horizon=10, solver="sqp", **kw))
        out[name] = ctrl.update(0.0, e, SP0)
        assert ctrl.diagnostics[-1].success
    return e, out


@pytest.mark.parametrize("solver,case", [
    ("ipopt", "quadratic"), ("fatrop", "quadratic"), ("ipopt", "dead_band"),
    ("fatrop", "dead_band"),
])
def test_nlp_solvers_agree(fpso, sqp_first_moves, solver, case):
    """IPOPT and fatrop give SQP's first move to 1e-3 of the capacity (the problem is the same NLP)."""
    e, ref = sqp_first_moves
    cap, _ = capacity(fpso)
    kw = QUADRATIC if case == "quadratic" else DEAD_BAND
    ctrl = NonlinearMPC(fpso, MPCSettings(horizon=10, solver=solver, **kw))
    tau = ctrl.update(0.0, e, SP0)
    assert ctrl.diagnostics[-1].success, ctrl.diagnostics[-1].status
    assert np.max(np.abs(tau - ref[case]) / cap) < 1e-3
    assert np.max(np.abs(ref[case]) / cap) > 0.05


# --- thrusters vs tau ------------------------------------------------------------------------------

def attainable_multiple(scenario, tau):
    """Largest t with t tau = B u, |f_i| <= f_max,i (the thrusters' attainable set), by SOCP."""
    cp = pytest.importorskip("cvxpy")
    B = np.hstack([extended_columns(*t.position) for t in scenario.thrusters])
    fmax = np.array([t.max_thrust for t in scenario.thrusters])
    sc = np.abs(tau).max()
    u, t = cp.Variable(B.shape[1]), cp.Variable()
    cons = [B @ u == t * tau / sc] + [cp.norm(u[2 * i:2 * i + 2]) <= fmax[i] / sc for i in range(len(fmax))]
    cp.Problem(cp.Maximize(t), cons).solve()
    return float(t.value)


@pytest.mark.parametrize("cls,solver", [(LinearMPC, "sqp"), (NonlinearMPC, "ipopt")], ids=["linear", "nonlinear-ipopt"])
def test_thruster_and_tau_decisions(fpso, cls, solver):
    """Without active bounds and rate weight, every stage of the thruster plan is the min-norm
    allocation of its own tau (u = B^+ B u, equal f_max); its tau is close to the tau-decision's
    (their thrust weights differ: |tau/cap|^2 vs sum (f/f_max)^2), which the thrusters can deliver."""
    s = dict(QUADRATIC, solver=solver)
    e = est(X0, (3e5, 1e5, 0.0))
    cap, _ = capacity(fpso)
    c_tau = cls(fpso, MPCSettings(decision="tau", **s))
    c_thr = cls(fpso, MPCSettings(decision="thrusters", **s))
    a = c_tau.update(0.0, e, SP0)
    b = c_thr.update(0.0, e, SP0)
    assert c_tau.diagnostics[-1].success and c_thr.diagnostics[-1].success
    assert attainable_multiple(fpso, a) > 1.0  # the tau solution is inside the thrusters' capacity
    B = np.hstack([extended_columns(*t.position) for t in fpso.thrusters])
    U = c_thr.plan_u
    fmax = fpso.thrusters[0].max_thrust
    assert np.max(np.abs(U.T - np.linalg.pinv(B) @ (B @ U.T))) < 1e-5 * fmax
    mag = np.hypot(U[:, 0::2], U[:, 1::2])
    assert np.all(mag <= fmax * (1 + 1e-6))
    assert np.allclose(b, B @ U[0])
    assert np.max(np.abs(a - b) / cap) < 0.15
    assert np.all(np.sign(a) == np.sign(b))


# --- failures --------------------------------------------------------------------------------------

def test_failed_nlp_solve_applies_shifted_previous_plan(fpso, monkeypatch):
    s = MPCSettings(solver="sqp", **QUADRATIC)
    cap, _ = capacity(fpso)
    ctrl = NonlinearMPC(fpso, s)
    ctrl.update(0.0, est(X0), SP0)
    plan = ctrl.plan_u.copy()

    def broken(**kwargs):
        raise RuntimeError("Error in Function::call for 'mpc': simulated failure")

    monkeypatch.setattr(ctrl, "_solver", broken)
    monkeypatch.setattr(ctrl, "_retry", broken)
    for k in (1, 2):  # each failure moves one step further along the last good plan
        tau = ctrl.update(k * s.dt, est(X0), SP0)
        d = ctrl.diagnostics[-1]
        assert d.fallback and not d.success and "simulated failure" in d.status
        assert np.all(np.isfinite(tau)) and np.all(np.abs(tau) <= cap * (1 + 1e-9))
        assert np.allclose(tau, plan[k], rtol=1e-12, atol=1e-9 * cap.max())


def test_ipopt_iteration_limit_falls_back_without_a_plan(fpso):
    """max_iter=1 fails the very first solve: no previous plan, so the previous thrust (none: zero)
    is held; nothing is raised."""
    ctrl = NonlinearMPC(fpso, MPCSettings(solver="ipopt", horizon=10, **dict(QUADRATIC, max_iter=1)))
    tau = ctrl.update(0.0, est(X0), SP0)
    d = ctrl.diagnostics[-1]
    assert d.fallback and not d.success and "Maximum" in d.status
    assert np.array_equal(tau, np.zeros(3))


@pytest.mark.parametrize("qp_solver, failure", [("piqp", "status"), ("piqp", "error"), ("osqp", "status")])
def test_failed_qp_applies_shifted_previous_plan(fpso, monkeypatch, qp_solver, failure):
    """A QP that stops unsolved (or raises) is reported and the shifted previous plan applied."""
    s = MPCSettings(**QUADRATIC)
    cap, _ = capacity(fpso)
    ctrl = LinearMPC(fpso, s, qp_solver=qp_solver)
    ctrl.update(0.0, est(X0), SP0)
    plan = ctrl.plan_u.copy()
    if qp_solver == "osqp":
        failed = SimpleNamespace(x=None, info=SimpleNamespace(status_val=-2, status="maximum iterations reached",
                                                              obj_val=math.nan, iter=20000))
        monkeypatch.setattr(ctrl._qp, "solve", lambda *args, **kwargs: failed)
        expect = "maximum iterations reached"
    else:   # the solver stops at its iteration limit, or raises on bad data
        def broken():
            raise ValueError("P must be square\nmore")

        stop = (lambda: piqp.Status.PIQP_MAX_ITER_REACHED) if failure == "status" else broken
        monkeypatch.setattr(ctrl, "_qp", SimpleNamespace(update=lambda **kw: None, solve=stop, result=ctrl._qp.result))
        expect = "PIQP_MAX_ITER_REACHED" if failure == "status" else "error: P must be square"
    tau = ctrl.update(s.dt, est(X0), SP0)
    d = ctrl.diagnostics[-1]
    assert d.fallback and not d.success and d.status == expect
    assert np.all(np.isfinite(tau)) and np.all(np.abs(tau) <= cap)
    assert np.allclose(tau, plan[1], rtol=1e-12, atol=1e-9 * cap.max())


def test_linear_mpc_qp_solvers_agree_in_a_storm(equivalent):
    """piqp and OSQP solve the same QP (45 m off, a 3 MN load, the thrust polytope and the safe
    circle in play): first moves agree to 1e-3 of the single-DOF maxima. On fpso_equivalent's soft
    mooring, where this load needs thrust (fpso's stiffer lines hold it nearly alone)."""
    fpso = equivalent
    x = np.array([44.0, -10.0, math.radians(5.0), 0.1, 0.02, 0.0])
    b = np.array([-3.0e6, -1.0e6, -2.0e7])
    moves = {}
    for qp in ("piqp", "osqp"):
        ctrl = LinearMPC(fpso, MPCSettings(dead_band=40.0, w_thrust=10.0, w_rate=5.0), qp_solver=qp)
        for k in range(3):
            moves[qp] = ctrl.update(5.0 * k, est(x, rot_z(x[2]).T @ b), Setpoint([0.0, 0.0, 0.1]))
            assert ctrl.diagnostics[-1].success, ctrl.diagnostics[-1].status
    scale = ThrusterSet.from_scenario(fpso).max_tau()
    assert np.max(np.abs(moves["piqp"] - moves["osqp"]) / scale) < 1e-3
    assert np.max(np.abs(moves["piqp"]) / scale) > 0.05
    with pytest.raises(MPCError, match="qp_solver"):
        LinearMPC(fpso, MPCSettings(horizon=3), qp_solver="qrqp")


# --- warm start ------------------------------------------------------------------------------------

@pytest.mark.parametrize("make", [
    pytest.param(lambda sc, s: LinearMPC(sc, s, qp_solver="osqp"), id="linear-osqp"),
    pytest.param(lambda sc, s: NonlinearMPC(sc, replace_solver(s, "ipopt")), id="nonlinear-ipopt"),
])
def test_warm_start_reduces_iterations(fpso, plant_fn, make):
    """Closed loop from 7 m off with a steady load: once warm, every solve takes fewer iterations
    than the cold first one."""
    s = MPCSettings(**dict(QUADRATIC, dt=2.0, w_rate=0.1))
    ctrl = make(fpso, s)
    closed_loop(ctrl, plant_fn, [6.0, -4.0, math.radians(2.0), 0.0, 0.0, 0.0], np.array([3e5, 1e5, 0.0]), 8, s.dt)
    its = [d.iterations for d in ctrl.diagnostics]
    assert all(d.success for d in ctrl.diagnostics)
    assert max(its[2:]) < its[0], its


def test_load_enters_the_prediction_through_its_low_pass_filter(fpso):
    """The load parameter is the first-order low-pass (time constant T) of the estimate in {E}:
    a step of the estimate at t = 0 reaches 1 - exp(-t/T) of itself; T = 0 passes it through."""
    T = 100.0
    ctrl = LinearMPC(fpso, MPCSettings(horizon=5, load_time_constant=T, **QUADRATIC))
    pi = ctrl._prob.p_idx
    x = X0.copy()
    x[2] = math.radians(30.0)
    step_B = np.array([1.0e6, -4.0e5, 2.0e7])
    step_E = rot_z(x[2]) @ step_B
    assert np.all(ctrl._params(est(x, (0.0, 0.0, 0.0), t=0.0), SP0)[pi["b"]] == 0.0)
    for t in (0.0, 50.0, 100.0, 300.0):   # the step is held from t = 0 on
        b = ctrl._params(est(x, step_B, t=t), SP0)[pi["b"]]
        np.testing.assert_allclose(b, (1.0 - math.exp(-t / T)) * step_E, rtol=1e-12, atol=1e-6)
    ctrl.reset()                           # a reset starts the filter at the next estimate
    np.testing.assert_allclose(ctrl._params(est(x, step_B, t=400.0), SP0)[pi["b"]], step_E, rtol=1e-12)
    raw = LinearMPC(fpso, MPCSettings(horizon=5, load_time_constant=0.0, **QUADRATIC))
    raw._params(est(x, (0.0, 0.0, 0.0), t=0.0), SP0)
    np.testing.assert_allclose(raw._params(est(x, step_B, t=1.0), SP0)[pi["b"]], step_E, rtol=1e-12)


def test_line_characteristics_parameters_are_the_catenary_at_the_centre_pose(fpso, monkeypatch):
    """The ``moor`` parameters are every line's characteristic at the centre pose, read from the
    model's tabulated catenary: H0, T0 within 1e-8 and the slopes within 1e-5 of
    ``MooringModel.characteristics`` there; the first move with them is the first move with the
    exact characteristics to 1e-6 of the thrust scale."""
    import tapm_opt.control.mpc as mpc_module

    x = np.array([38.0, -14.0, math.radians(12.0), 0.1, 0.0, 0.0])
    e = est(x, (6e5, -2e5, 1e6))
    ctrl = LinearMPC(fpso, MPCSettings(horizon=8, **QUADRATIC))
    pi = ctrl._prob.p_idx
    got = ctrl._params(e, SP0)[pi["moor"]].reshape(5, -1)
    want = ctrl.model.characteristics(ctrl._centre(x[:3], SP0.eta_d))
    np.testing.assert_allclose(got[[0, 3]], want[[0, 3]], rtol=1e-8)
    np.testing.assert_array_equal(got[2], want[2])
    for row in (1, 4):
        assert np.max(np.abs(got[row] - want[row])) <= 1e-5 * np.max(np.abs(want[row]))
    tabulated = LinearMPC(fpso, MPCSettings(horizon=8, **QUADRATIC))
    u_tab = tabulated.update(0.0, e, SP0)
    monkeypatch.setattr(mpc_module, "mooring_parameters", lambda m, eta_c: m.characteristics(eta_c).ravel())
    exact = LinearMPC(fpso, MPCSettings(horizon=8, **QUADRATIC))
    u_exact = exact.update(0.0, e, SP0)
    assert tabulated.last_step().success and exact.last_step().success
    np.testing.assert_allclose(u_tab, u_exact, rtol=0, atol=1e-6 * np.max(np.abs(u_exact)))


# --- bad input -------------------------------------------------------------------------------------

@pytest.mark.parametrize("field,value", [
    ("dt", -1.0), ("dt", 0.0), ("dt", math.nan), ("horizon", 0), ("horizon", 2.5), ("substeps", 0),
    ("solver", "qpoases"), ("mooring", "spring"), ("decision", "forces"), ("w_thrust", -1.0),
    ("safe_radius", -5.0), ("safe_radius", "far"), ("tension_utilisation", 0.0), ("tension_utilisation", 1.5),
    ("tension_utilisation", math.nan), ("polygon_sides", 2), ("max_iter", 0), ("capacity_fraction", 0.0),
    ("load_time_constant", -1.0), ("load_time_constant", math.inf),
])
def test_bad_settings_raise_naming_the_field(field, value):
    with pytest.raises(MPCError, match=rf"MPCSettings\.{field} ="):
        MPCSettings(**{field: value})


@pytest.mark.parametrize("cls", [LinearMPC, NonlinearMPC], ids=["linear", "nonlinear"])
def test_bad_estimate_or_setpoint_raise(fpso, cls):
    ctrl = cls(fpso, MPCSettings(horizon=5, **QUADRATIC))
    good = np.zeros(3)
    for e, sp, name in ((Estimate(0.0, [math.nan, 0, 0], good, good), SP0, "eta"),
                        (Estimate(0.0, good, [0, math.inf, 0], good), SP0, "nu"),
                        (Estimate(0.0, good, good, [math.nan, 0, 0]), SP0, "tau_env"),
                        (Estimate(0.0, [0, 0], good, good), SP0, "eta"),
                        (Estimate(0.0, good, good, good), Setpoint([math.nan, 0, 0]), "eta_d")):
        with pytest.raises(MPCError, match=name):
            ctrl.update(0.0, e, sp)
    assert ctrl.diagnostics == []  # nothing was solved or applied


def test_scenario_without_thrusters_and_bad_settings_object(fpso):
    d = scenario_to_dict(fpso)
    d["thrusters"] = []
    bare = scenario_from_dict(d)
    with pytest.raises(MPCError, match="no thrusters"):
        NonlinearMPC(bare, MPCSettings(horizon=3))
    with pytest.raises(MPCError, match="no thrusters"):
        LinearMPC(bare, MPCSettings(horizon=3)).update(0.0, est(np.zeros(6)), SP0)
    with pytest.raises(MPCError, match="MPCSettings"):
        LinearMPC(fpso, {"horizon": 3})


@pytest.mark.parametrize("cls", [LinearMPC, NonlinearMPC], ids=["linear", "nonlinear-sqp"])
def test_failed_thrusters_shrink_the_thrust_box(fpso, cls):
    """Thruster feedback reports two of six azimuths failed: the saturated command stays inside the
    capacity box of the remaining four (the one capacity model), which is smaller than the intact
    box."""
    s = MPCSettings(solver="sqp", **AGGRESSIVE)
    ctrl = cls(fpso, s)
    failed = frozenset(t.id for t in fpso.thrusters[:2])
    ctrl.set_failed_thrusters(failed)
    box = np.asarray(ThrusterSet.from_scenario(fpso).without(failed).capacity_box())
    intact, _ = capacity(fpso)
    assert np.all(box < intact)
    x = est([35.0, -25.0, 0.1, 0.0, 0.0, 0.0])
    for k in range(6):
        tau = ctrl.update(k * s.dt, x, SP0)
        assert np.all(np.abs(tau) <= box * (1 + 1e-4)), tau / box
    assert ctrl.diagnostics[-1].success
    assert np.max(np.abs(tau) / box) > 0.99  # saturated at the reduced box


def test_sqp_converges_where_gauss_newton_is_slow(equivalent):
    """A state of the design storm after line 1 broke, recorded on fpso_equivalent (57 m off, the
    thrust saturated, 7.7 MN and 1.4e8 N m of load in {E}, the study defaults): the Gauss-Newton SQP contracts its dual infeasibility
    by only ~0.83 per iteration here, so with sqpmethod's absolute 1e-6 it stopped at the earlier
    30-iteration limit (77 to converge) and the loop applied the shifted previous plan. With the
    tolerance relative to the L1 weight (NonlinearMPC.SQP_DUAL_TOLERANCE) it converges within 30,
    to the first move and the cost of a solve run to 1e-6 with 200 iterations."""
    from tapm_opt.studies.controllers import MPC_DEFAULTS

    fpso = equivalent

    s = MPCSettings(**MPC_DEFAULTS, dead_band=30.0, fault_tolerance=True)
    x = np.array([-44.61138, -35.77943, 0.403389, -0.2378754, 0.1077731, 1.140355e-03])
    u_prev = np.array([6.511067e6, -2.886157e6, -1.121037e8])
    b = np.array([-7.685705e6, 6.458398e5, 1.427865e8])
    e = Estimate(0.0, x[:3], x[3:], rot_z(x[2]).T @ b, broken_lines=frozenset({"1"}))
    sp = Setpoint([0.0, 0.0, 0.319821])

    def solve(settings, tol):
        class Tight(NonlinearMPC):
            SQP_DUAL_TOLERANCE = tol
        ctrl = Tight(fpso, settings)
        ctrl._u_prev = u_prev.copy()   # the move applied at the step before
        return ctrl, ctrl.update(0.0, e, sp)

    ctrl, u = solve(s, NonlinearMPC.SQP_DUAL_TOLERANCE)
    d = ctrl.diagnostics[-1]
    assert d.success and not d.fallback and d.iterations <= 30, d.status
    absolute, _ = solve(replace(s, max_iter=30), 1e-9)   # sqpmethod's own 1e-6, the earlier limit
    assert not absolute.diagnostics[-1].success and "Maximum_Iterations" in absolute.diagnostics[-1].status
    ref, u_ref = solve(replace(s, max_iter=200), 1e-9)
    assert ref.diagnostics[-1].success, ref.diagnostics[-1].status
    assert np.max(np.abs(u - u_ref) / ThrusterSet.from_scenario(fpso).max_tau()) < 1e-6
    assert d.cost == pytest.approx(ref.diagnostics[-1].cost, rel=1e-6)
    assert "thrust_capacity" in d.active


def test_failed_sqp_solve_is_retried_with_osqp(fpso, monkeypatch):
    """When the SQP with piqp fails, the same SQP with OSQP for its subproblems solves the step:
    the move is that of an undisturbed solve and the diagnostics say so."""
    s = MPCSettings(solver="sqp", **QUADRATIC)
    ref = NonlinearMPC(fpso, s).update(0.0, est(X0), SP0)
    ctrl = NonlinearMPC(fpso, s)

    def broken(**kwargs):
        raise RuntimeError("Error in Function::call for 'mpc': simulated failure")

    monkeypatch.setattr(ctrl, "_solver", broken)
    tau = ctrl.update(0.0, est(X0), SP0)
    d = ctrl.diagnostics[-1]
    assert d.success and not d.fallback and "retry after error" in d.status and ctrl.retries == 1
    cap, _ = capacity(fpso)
    assert np.max(np.abs(tau - ref) / cap) < 1e-4



def _prescribed_trajectory(n, dt):
    """Estimates of a slowly moving state (28 m out along 30 deg at 0.1 m/s, heading drifting 0.05 deg
    a step, 0.5 MN of load in {E}) and the field zero point as setpoint."""
    bearing, speed = math.radians(30.0), 0.1
    b_E = 0.5e6 * np.array([math.cos(bearing), math.sin(bearing), 0.0])
    out = []
    for k in range(n):
        r, psi = 28.0 + speed * k * dt, math.radians(2.0 + 0.05 * k)
        v = rot_z(psi).T @ np.array([speed * math.cos(bearing), speed * math.sin(bearing), 0.0])
        v[2] = math.radians(0.05) / dt
        out.append(Estimate(k * dt, [r * math.cos(bearing), r * math.sin(bearing), psi], v, rot_z(psi).T @ b_E))
    return out


def test_rti_is_one_sqp_iteration_per_step_and_tracks_the_converged_sqp(fpso):
    """solver="rti" (the real-time iteration): every step is one Gauss-Newton SQP iteration from the
    shifted previous solution, reported as a success with its own status; along a slowly moving state
    with the study defaults its first moves stay within 5 % of the thrust scale of the converged SQP's
    (measured: 2 % at N = 20), while the converged SQP takes 2 or more iterations a step."""
    from tapm_opt.studies.controllers import MPC_DEFAULTS

    base = dict(MPC_DEFAULTS, dead_band=30.0, horizon=10)
    moves = {}
    for solver in ("sqp", "rti"):
        ctrl = NonlinearMPC(fpso, MPCSettings(solver=solver, **base))
        moves[solver] = np.array([ctrl.update(e.t, e, SP0) for e in _prescribed_trajectory(12, 5.0)])
        its = [d.iterations for d in ctrl.diagnostics]
        assert all(d.success and not d.fallback for d in ctrl.diagnostics), [d.status for d in ctrl.diagnostics]
        if solver == "rti":
            assert its == [1] * 12 and {d.status for d in ctrl.diagnostics} == {NonlinearMPC.RTI_STATUS}
        else:
            assert min(its) >= 2
    scale = ThrusterSet.from_scenario(fpso).max_tau()
    err = np.max(np.abs(moves["rti"] - moves["sqp"]) / scale)
    assert 0.0 < err < 0.05, err


def test_rti_settles_to_the_sqp_steady_thrust_in_closed_loop(fpso, plant_fn):
    """In closed loop on the design model under a steady load the RTI controller settles where the
    converged SQP settles: the same thrust after 200 s (to 1e-4 of the thrust scale, while the
    thrust itself still moves by up to 1e-3 a step) and the same position to 1 cm."""
    s = MPCSettings(**dict(QUADRATIC, horizon=10, dt=5.0))
    b_E = np.array([4e5, -2e5, 1e6])
    out = {}
    for solver in ("sqp", "rti"):
        ctrl = NonlinearMPC(fpso, replace_solver(s, solver))
        out[solver] = closed_loop(ctrl, plant_fn, [6.0, -4.0, math.radians(2.0), 0.0, 0.0, 0.0], b_E, 40, s.dt)
        assert all(d.success and not d.fallback for d in ctrl.diagnostics)
    scale = ThrusterSet.from_scenario(fpso).max_tau()
    (tau_s, x_s), (tau_r, x_r) = out["sqp"], out["rti"]
    assert np.max(np.abs(tau_s[-1] - tau_s[-2]) / scale) < 1e-3    # (nearly) settled
    assert np.max(np.abs(tau_r[-1] - tau_s[-1]) / scale) < 1e-4    # measured 2.7e-6
    np.testing.assert_allclose(x_r[-1][:2], x_s[-1][:2], atol=0.01)


def test_failed_rti_step_is_retried_then_falls_back(fpso, monkeypatch):
    """An RTI step whose QP fails is retried with OSQP (one iteration too); when that fails as well
    the loop gets the shifted previous plan, reported as a fallback."""
    ctrl = NonlinearMPC(fpso, MPCSettings(solver="rti", **QUADRATIC))
    ctrl.update(0.0, est(X0), SP0)

    def broken(**kwargs):
        raise RuntimeError("Error in Function::call for 'mpc': simulated failure")

    monkeypatch.setattr(ctrl, "_solver", broken)
    ctrl.update(5.0, est(X0), SP0)
    d = ctrl.diagnostics[-1]
    assert d.success and "retry after error" in d.status and ctrl.retries == 1
    monkeypatch.setattr(ctrl, "_retry", broken)
    ctrl.update(10.0, est(X0), SP0)
    d = ctrl.diagnostics[-1]
    assert not d.success and d.fallback


# --- attainable thrust polytope and the linearisation about the state --------------------------------

@pytest.mark.parametrize("cls", [LinearMPC, NonlinearMPC], ids=["linear", "nonlinear-sqp"])
def test_planned_thrust_is_attainable_and_rate_limited_as_a_vector(fpso, plant_fn, cls):
    """thrust_set="polytope" (the default): a 43 m offset saturates the thrust; every planned tau is
    one the six azimuths can deliver together (checked by the independent SOCP of
    attainable_multiple), reaches beyond the 0.6 capacity box in some component, and changes
    between updates by a vector inside the polytope scaled by rate/max_thrust x dt."""
    s = MPCSettings(**dict(AGGRESSIVE, thrust_set="polytope"))
    ctrl = cls(fpso, s)
    taus, _ = closed_loop(ctrl, plant_fn, [35.0, -25.0, 0.1, 0.0, 0.0, 0.0], np.zeros(3), 8, s.dt)
    ths = ThrusterSet.from_scenario(fpso)
    A, b = ths.attainable_polytope(s.polytope_directions)
    ratio = min(t.max_thrust_rate / t.max_thrust for t in fpso.thrusters)
    prev = np.zeros(3)
    for tau in taus:
        assert np.all(A @ tau <= b * (1 + 1e-4) + 1e-6)
        assert attainable_multiple(fpso, tau) >= 1.0 - 1e-4
        assert np.all(A @ (tau - prev) <= ratio * s.dt * b * (1 + 1e-4) + 1e-6)
        prev = tau
    cap, _ = capacity(fpso)
    assert np.max(np.abs(taus) / cap) > 1.02  # the polytope is larger than the box
    assert any("thrust_capacity" in d.active for d in ctrl.diagnostics)
    assert all(d.success for d in ctrl.diagnostics)


def test_attainable_polytope_is_inside_the_thrusters_reach_and_nearly_fills_it(fpso):
    """Every vertex of the polytope is attainable (SOCP); the polytope's support in the single-DOF
    directions is at most the LP maxima of max_tau and within 10 % of them (the set is convex and the
    support points lie on its boundary)."""
    from scipy.spatial import HalfspaceIntersection

    ths = ThrusterSet.from_scenario(fpso)
    A, b = ths.attainable_polytope()
    hs = HalfspaceIntersection(np.hstack([A, -b[:, None]]), np.zeros(3))
    for v in hs.intersections[::7]:
        assert attainable_multiple(fpso, v) >= 1.0 - 1e-6
    import scipy.optimize

    for d in range(3):  # the polytope's reach along each DOF alone, against the capacity LP's
        for sgn in (1.0, -1.0):
            c = np.zeros(3)
            c[d] = -sgn
            eq = np.delete(np.eye(3), d, axis=0)
            res = scipy.optimize.linprog(c, A_ub=A * ths.max_tau(), b_ub=b, A_eq=eq, b_eq=np.zeros(2),
                                         bounds=[(None, None)] * 3)  # in tau / max_tau
            assert res.status == 0, res.message
            assert 0.9 <= -res.fun <= 1 + 1e-6, (d, sgn, -res.fun)
    with pytest.raises(Exception, match="n_directions"):
        ths.attainable_polytope(3)


def test_linear_mpc_about_the_state_predicts_better_far_out(fpso):
    """40 m off, where the catenary has hardened: the linear MPC's predicted first state, linearised
    about the state estimate, matches the nonlinear model (the independent RK4 of the design model
    with the exact catenary mooring) far better than linearised about the setpoint."""
    vp = VesselParams.from_scenario(fpso)
    exact = moored_function(vp, MooringModel.from_scenario(fpso).force_function("catenary"), form="design")
    x0 = np.array([40.0, -12.0, math.radians(5.0), 0.2, 0.0, 0.0])
    b = np.array([3.0e6, -1.0e6, 0.0])
    errs = {}
    for about in ("state", "setpoint"):
        ctrl = LinearMPC(fpso, MPCSettings(linearise_about=about, horizon=10, dead_band=0.0, w_position=1.0))
        for k in range(3):
            ctrl.update(k * 5.0, est(x0, rot_z(x0[2]).T @ b), SP0)
        X = ctrl._z[ctrl._prob.idx["X"]].reshape(-1, 6) * ctrl._prob.scale["x"]
        x1 = rk4(exact, x0, ctrl.tau_from_u(ctrl.plan_u[0]), b, 5.0, substeps=5)
        errs[about] = np.linalg.norm((X[1] - x1)[:2])
    assert errs["state"] < 0.2 * errs["setpoint"], errs
    assert errs["state"] < 0.05, errs


def test_linear_mpc_qp_moves_with_the_operating_point_on_one_sparsity(fpso):
    """One parametric QP: at two poses 30 m apart the constraint matrix values differ (the mooring
    stiffness and the rotation are linearised where the vessel is) on the same sparsity, and the
    reported cost is the problem's f(z) (the QP's constant f(0) added back): the nonlinear MPC at
    the same small offset reports the same cost."""
    ctrl = LinearMPC(fpso, MPCSettings(**QUADRATIC))
    p = ctrl._params(est(X0), SP0)
    pi = ctrl._prob.p_idx
    data = []
    for x in (X0, X0 + np.array([30.0, 0.0, 0.0, 0.0, 0.0, 0.0])):
        p = ctrl._params(est(x), SP0)
        p[pi["x_op"]], p[pi["u_op"]], p[pi["b_op"]] = p[pi["x0"]], p[pi["u_prev"]], p[pi["b"]]
        data.append([v.copy() for v in ctrl._qp_arrays(p)])
    assert data[0][1].shape == data[1][1].shape == (ctrl._mats[1][0].nnz(),)
    assert np.max(np.abs(data[0][1] - data[1][1])) > 1e-3
    x = 0.1 * X0
    a, b = LinearMPC(fpso, MPCSettings(**QUADRATIC)), NonlinearMPC(fpso, MPCSettings(**QUADRATIC))
    a.update(0.0, est(x), SP0)
    b.update(0.0, est(x), SP0)
    assert a.last_step().cost == pytest.approx(b.last_step().cost, rel=1e-3)


@pytest.mark.parametrize("cls", [LinearMPC, NonlinearMPC], ids=["linear", "nonlinear-sqp"])
def test_thruster_failure_while_saturated_keeps_the_polytope_feasible(fpso, plant_fn, cls):
    """Saturated against a 43 m offset with the default polytope, then the three aft azimuths fail:
    the previous move lies far outside what the bow thrusters can deliver, yet every later solve
    succeeds and every applied tau is inside the reduced polytope (the rate rows start from the
    part of the previous move the remaining thrusters can deliver). With five of six failed no
    polytope has an interior: the capacity box of the last one stands in, and nothing raises."""
    s = MPCSettings(**dict(AGGRESSIVE, thrust_set="polytope", horizon=5))
    ctrl = cls(fpso, s)
    taus, _ = closed_loop(ctrl, plant_fn, [35.0, -25.0, 0.1, 0.0, 0.0, 0.0], np.zeros(3), 4, s.dt)
    aft = frozenset(t.id for t in fpso.thrusters[:3])
    ths = ThrusterSet.from_scenario(fpso).without(aft)
    A, b = ths.attainable_polytope(s.polytope_directions)
    assert np.max(A @ taus[-1] / b) > 2.0  # the last move is far outside the reduced set
    ctrl.set_failed_thrusters(aft)
    x = est([35.0, -25.0, 0.1, 0.0, 0.0, 0.0])
    for k in range(4, 8):
        tau = ctrl.update(k * s.dt, x, SP0)
        assert ctrl.last_step().success, ctrl.last_step().status
        assert np.all(A @ tau <= b * (1 + 1e-4) + 1e-6), np.max(A @ tau / b)
    five = frozenset(t.id for t in fpso.thrusters[:5])
    ctrl.set_failed_thrusters(five)
    box = ThrusterSet.from_scenario(fpso).without(five).capacity_box(s.capacity_fraction)
    tau = ctrl.update(40.0, x, SP0)
    assert np.all(np.abs(tau) <= box * (1 + 1e-4) + 1e-6)


def test_study_spec_takes_the_linear_mpc_qp_solver_and_bounds_the_polytope(fpso):
    from tapm_opt.studies.controllers import ControllerSpecError, build_controller

    assert build_controller(fpso, {"type": "lmpc", "horizon": 3, "qp_solver": "osqp"}).qp_solver == "osqp"
    assert build_controller(fpso, {"type": "lmpc", "horizon": 3}).qp_solver == "daqp"   # the fast default (control.registry)
    with pytest.raises(ControllerSpecError, match="qp_solver"):
        build_controller(fpso, {"type": "mpc", "horizon": 3, "qp_solver": "osqp"})  # the NLP has its solver
    with pytest.raises(ControllerSpecError, match="qp_solver = 'qrqp'"):
        build_controller(fpso, {"type": "lmpc", "horizon": 3, "qp_solver": "qrqp"})
    with pytest.raises(ControllerSpecError, match="polytope_directions = 5000 is above 400"):
        build_controller(fpso, {"type": "lmpc", "horizon": 3, "polytope_directions": 5000})
