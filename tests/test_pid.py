"""Tests of the TAPM PID modes and their pole-placement design (tapm_opt.control.pid):
closed-form gains, closed-loop poles and responses with python-control, closed-loop simulation
of the discrete controller on the design model, projections, anti-windup and bad input."""

from __future__ import annotations

import casadi as ca
import control
import numpy as np
import pytest
import scipy.signal
from hypothesis import given, settings
from hypothesis import strategies as st

import tapm_opt
from tapm_opt.control.estimate import Estimate, Setpoint
from tapm_opt.control.pid import MODE_SETS, MODES, TAPMPID, ControlError, GainClampWarning, PIDGains
from tapm_opt.control.pid_design import (PIDDesign, closed_loop, design_from_scenario, design_gains, designed_poles,
                                         dof_plant)
from tapm_opt.errors import TapmError
from tapm_opt.geometry import rot_z
from tapm_opt.models.mooring import MooringModel
from tapm_opt.models.vessel import VesselParams, moored_function

# FPSO-like diagonal design model (the fpso scenario's M and D, its catenary stiffness at rest).
M = np.diag([2.371e8, 4.561e8, 2.584e12])  # [kg, kg, kg m^2]
D = np.diag([2.272e6, 8.42e6, 6.719e10])  # [N s/m, N s/m, N m s]
K = np.diag([8.6e4, 8.6e4, 7.18e8])  # [N/m, N/m, N m/rad]
PERIODS = (100.0, 120.0, 90.0)  # [s]
ZETA = (0.7, 0.8, 0.7)


def est(eta, nu=(0.0, 0.0, 0.0), t=0.0, tau_env=(0.0, 0.0, 0.0)) -> Estimate:
    return Estimate(t, eta, nu, tau_env)


def sp(eta_d=(0.0, 0.0, 0.0), nu_d=(0.0, 0.0, 0.0)) -> Setpoint:
    return Setpoint(eta_d, nu_d)


GAINS = PIDGains(Kp=[1.0e6, 2.0e6, 3.0e9], Ki=[1.0e4, 2.0e4, 3.0e7], Kd=[4.0e7, 5.0e7, 6.0e11])


# --- design -----------------------------------------------------------------------------------

@pytest.mark.parametrize("method", ["formula", "acker"])
def test_gains_equal_closed_form(method):
    """K_d = M(2 zeta w + a) - D, K_p = M(w^2 + 2 zeta w a) - K, K_i = M w^2 a per DOF."""
    ratio = 0.15
    d = design_gains((M, D, K), periods=PERIODS, damping=ZETA, integral_ratio=ratio,
                     method=method)
    for i in range(3):
        w = 2 * np.pi / PERIODS[i]
        a = ratio * w
        m, z = M[i, i], ZETA[i]
        assert d.gains.Kd[i, i] == pytest.approx(m * (2 * z * w + a) - D[i, i], rel=1e-9)
        assert d.gains.Kp[i, i] == pytest.approx(m * (w**2 + 2 * z * w * a) - K[i, i], rel=1e-9)
        assert d.gains.Ki[i, i] == pytest.approx(m * w**2 * a, rel=1e-9)
    off = ~np.eye(3, dtype=bool)
    for G in (d.gains.Kp, d.gains.Ki, d.gains.Kd):
        assert np.all(G[off] == 0.0)
    assert d.clamped == ()


def test_decoupled_closed_loop_poles_equal_designed():
    d = design_gains((M, D, K), periods=PERIODS, damping=ZETA, integral_ratio=0.1)
    for i in range(3):
        want = np.sort_complex(designed_poles(PERIODS[i], ZETA[i], 0.1))
        # independent path: the characteristic polynomial of the augmented DOF model
        sys_i = dof_plant(M[i, i], D[i, i], K[i, i])
        k_row = np.array([[d.gains.Ki[i, i], d.gains.Kp[i, i], d.gains.Kd[i, i]]])
        got = np.sort_complex(np.linalg.eigvals(sys_i.A - sys_i.B @ k_row))
        np.testing.assert_allclose(got, want, rtol=1e-6)
        np.testing.assert_allclose(np.sort_complex(d.decoupled_poles[i]), want, rtol=1e-6)
    # the coupled loop of a diagonal plant has exactly the designed poles
    want_all = np.sort_complex(d.designed_poles.ravel())
    np.testing.assert_allclose(np.sort_complex(d.poles), want_all, rtol=1e-6)
    np.testing.assert_allclose(np.sort_complex(d.closed_loop().poles()), want_all, rtol=1e-6)
    osc = np.abs(d.poles.imag) > 0
    assert sorted(set(np.round(d.natural_periods[osc], 6))) == sorted(set(PERIODS))
    assert sorted(set(np.round(d.damping_ratios[osc], 9))) == sorted(set(ZETA))
    assert d.stable


def test_overdamped_design_with_repeated_poles():
    """zeta = 1 gives a double real pole; acker (python-control) and the formula still agree."""
    f = design_gains((M, D, K), periods=150.0, damping=1.0, method="formula")
    a = design_gains((M, D, K), periods=150.0, damping=1.0, method="acker")
    for G in ("Kp", "Ki", "Kd"):
        np.testing.assert_allclose(getattr(a.gains, G), getattr(f.gains, G), rtol=1e-6)
    w = 2 * np.pi / 150.0
    np.testing.assert_allclose(f.designed_poles[0], [-w, -w, -0.1 * w], rtol=1e-12)


def test_heading_step_response_has_designed_period_and_damping():
    """Step in psi_d on the linear closed loop: damped period from the peaks of the yaw rate and
    damping from their logarithmic decrement match T_n and zeta of the design."""
    Tn, zeta = 90.0, 0.2
    d = design_gains((M, D, K), periods=(100.0, 100.0, Tn), damping=(0.7, 0.7, zeta))
    assert d.clamped == ()
    cl = d.closed_loop()
    t = np.linspace(0.0, 800.0, 80001)
    resp = control.step_response(cl, T=t, input=cl.input_labels.index("psi_d"),
                                 output=cl.output_labels.index("psi"))
    psi = np.squeeze(resp.outputs)
    assert psi[-1] == pytest.approx(1.0, abs=1e-3)  # integral action: no steady-state error
    r = np.gradient(psi, t)
    peaks, _ = scipy.signal.find_peaks(r)
    Td = np.mean(np.diff(t[peaks[:3]]))
    delta = np.log(r[peaks[0]] / r[peaks[1]])
    zeta_est = delta / np.sqrt(4 * np.pi**2 + delta**2)
    assert zeta_est == pytest.approx(zeta, rel=0.03)
    assert Td * np.sqrt(1 - zeta_est**2) == pytest.approx(Tn, rel=0.02)
    # and python-control's damp on the yaw poles
    wn, z, p = control.damp(cl, doprint=False)
    yaw = np.isclose(wn, 2 * np.pi / Tn, rtol=1e-9) & (np.abs(p.imag) > 0)
    assert yaw.sum() == 2
    np.testing.assert_allclose(z[yaw], zeta, rtol=1e-9)


def test_negative_gains_clamped_and_reported():
    stiff = np.diag([2.0e7, 8.6e4, 7.18e8])  # surge mooring far stiffer than a 100 s period asks
    with pytest.warns(GainClampWarning, match=r"Kp\[surge\]"):
        d = design_gains((M, D, stiff), periods=100.0, damping=0.7)
    assert len(d.clamped) == 1 and "Kp[surge]" in d.clamped[0]
    assert d.gains.Kp[0, 0] == 0.0 and d.gains.Kp[1, 1] > 0.0
    assert not np.allclose(np.sort_complex(d.decoupled_poles[0]),
                           np.sort_complex(d.designed_poles[0]), rtol=1e-3)
    np.testing.assert_allclose(np.sort_complex(d.decoupled_poles[1]),
                               np.sort_complex(d.designed_poles[1]), rtol=1e-6)
    heavy = np.diag([1e9, 8.42e6, 6.719e10])  # surge already over-damped
    with pytest.warns(GainClampWarning, match=r"Kd\[surge\]"):
        d = design_gains((M, heavy, K), periods=100.0, damping=0.7)
    assert d.gains.Kd[0, 0] == 0.0 and any("Kd[surge]" in m for m in d.clamped)


def test_design_from_linearised_state_space_reads_rotated_stiffness():
    """A plant linearised at psi0 != 0: the design uses K R(psi0) (errors in {B})."""
    psi0 = 0.6
    G = np.array([[9e4, 1e4, 0.0], [1e4, 7e4, 5e6], [0.0, 5e6, 8e8]])  # {E} stiffness
    R0 = rot_z(psi0)
    A = np.block([[np.zeros((3, 3)), R0], [-np.linalg.solve(M, R0.T @ G), -np.linalg.solve(M, D)]])
    B = np.vstack([np.zeros((3, 3)), np.linalg.inv(M)])
    d = design_gains(control.ss(A, B, np.eye(6), 0), periods=PERIODS, damping=ZETA)
    np.testing.assert_allclose(d.K, R0.T @ G @ R0, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(d.M, M, rtol=1e-12)
    np.testing.assert_allclose(d.D, D, rtol=1e-9)
    assert d.stable


def test_design_from_fpso_scenario_at_offset_equilibrium():
    sc = tapm_opt.load_scenario("fpso")
    moor = MooringModel.from_scenario(sc)
    x_cot = sc.turret.position[0]
    tau_env = np.array([-3.0e6, 2.0e5, x_cot * 2.0e5])  # free turret: N = x_cot Y balances
    d = design_from_scenario(sc, periods=(150.0, 150.0, 120.0), damping=0.7, tau_env=tau_env,
                             reference_point=(0.0, 0.0))
    eta_op = d.eta_op
    # to the equilibrium's tolerance: 1e-9 of its residual scale, the lines' pull (about 2.4e7 N)
    pull = float(np.sum(np.abs(moor.solve_lines(eta_op).HF)))
    np.testing.assert_allclose(moor.force(eta_op), -tau_env, rtol=0, atol=1e-9 * pull)
    assert eta_op[0] < -10.0  # pushed south by the load
    np.testing.assert_allclose(d.K, moor.stiffness(eta_op) @ rot_z(eta_op[2]), rtol=1e-6,
                               atol=1e-6 * np.abs(d.K).max())
    np.testing.assert_allclose(d.M, np.asarray(sc.vessel.mass_matrix), rtol=1e-12)
    assert d.stable and isinstance(d, PIDDesign)
    # the sway-yaw coupling of the free turret moves the coupled poles only a little
    osc = np.abs(d.poles.imag) > 0
    assert np.all(np.abs(d.natural_periods[osc] / 135.0 - 1.0) < 0.2)
    ctrl = TAPMPID.from_design(d, modes="extreme")
    assert ctrl.modes == MODE_SETS["extreme"]
    # the PID that runs acts on the turret offset (the default reference point): the lever of the
    # turret couples sway and yaw, so its coupled poles are those of another, still stable, loop
    dt = design_from_scenario(sc, periods=(150.0, 150.0, 120.0), damping=0.7, tau_env=tau_env)
    np.testing.assert_allclose(dt.reference_point, sc.turret.position)
    assert dt.stable and not np.allclose(np.sort_complex(dt.poles), np.sort_complex(d.poles), rtol=1e-3)
    np.testing.assert_allclose(np.sort_complex(dt.closed_loop().poles()), np.sort_complex(dt.poles),
                               rtol=1e-7, atol=1e-12)


def test_no_equilibrium_for_unbalanced_yaw_load_on_free_turret():
    sc = tapm_opt.load_scenario("fpso")
    with pytest.raises(ControlError, match="weathervanes"):
        design_from_scenario(sc, periods=150.0, damping=0.7, tau_env=[-2e6, 5e5, 1e7])


# --- closed-loop simulation of the discrete controller on the design model ------------------

def _design_model() -> ca.Function:
    """Design-form vessel with the linear spring tau_moor = -R(psi)^T K eta ([S] eq. 29, 31)."""
    eta = ca.SX.sym("eta", 3)
    spring = ca.Function("spring", [eta], [-ca.mtimes(rot_z(eta[2]).T, ca.mtimes(ca.DM(K), eta))])
    return moored_function(VesselParams(M=M, D_lin=D), spring)


def simulate(ctrl: TAPMPID, t_end: float, dt: float, tau_env, eta_d):
    """RK4 on the moored design model, thrust held over each step (zero-order hold)."""
    fn = _design_model()
    tau_env = np.asarray(tau_env, dtype=float)
    n = int(round(t_end / dt))
    x = np.zeros(6)
    X, T, I = [x], [], []

    def f(x, tau):
        return np.asarray(fn(x, tau, tau_env, np.zeros(2)).full()).ravel()

    for k in range(n):
        t = k * dt
        tau = ctrl.update(t, Estimate(t, x[:3], x[3:], tau_env), Setpoint(eta_d))
        k1 = f(x, tau)
        k2 = f(x + dt / 2 * k1, tau)
        k3 = f(x + dt / 2 * k2, tau)
        k4 = f(x + dt * k3, tau)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        X.append(x)
        T.append(tau)
        I.append(ctrl.integral_load)
    return np.arange(n + 1) * dt, np.array(X), np.array(T), np.array(I)


@pytest.fixture(scope="module")
def fast_design() -> PIDDesign:
    return design_gains((M, D, K), periods=60.0, damping=0.7, integral_ratio=0.2)


def test_mean_mode_removes_constant_load_offset(fast_design):
    F = 1.0e6
    ctrl = TAPMPID.from_design(fast_design, modes="extreme_restoring")
    t, X, T, _ = simulate(ctrl, 1500.0, 0.5, [F, 0.0, 0.0], np.zeros(3))
    assert abs(X[-1, 0]) < 1e-6
    assert T[-1, 0] == pytest.approx(-F, rel=1e-6)  # the thrusters carry the mean load
    assert X[:, 0].max() > 0.05  # the load did displace the vessel first


def test_discrete_controller_converges_to_linear_closed_loop(fast_design):
    """The sampled controller (zero-order hold) on the nonlinear design model approaches the
    continuous linear closed loop of ``closed_loop`` at first order in the sample time."""
    F = 1.0e6
    cl = fast_design.closed_loop("extreme_restoring")
    err = []
    for dt in (1.0, 0.5):
        ctrl = TAPMPID.from_design(fast_design, modes="extreme_restoring")
        t, X, _, _ = simulate(ctrl, 600.0, dt, [F, 0.0, 0.0], np.zeros(3))
        u = np.zeros((6, t.size))
        u[0] = F
        lin = control.forced_response(cl, t, u)
        err.append(np.abs(X[:, 0] - lin.outputs[0]).max() / np.abs(X[:, 0]).max())
    assert err[1] < 0.02
    assert err[0] / err[1] == pytest.approx(2.0, rel=0.1)


def test_without_mean_mode_offset_is_F_over_K_plus_Kp(fast_design):
    F = 1.0e6
    ctrl = TAPMPID.from_design(fast_design, modes="normal_restoring")
    _, X, _, _ = simulate(ctrl, 1500.0, 0.5, [F, 0.0, 0.0], np.zeros(3))
    expected = F / (K[0, 0] + fast_design.gains.Kp[0, 0])
    assert X[-1, 0] == pytest.approx(expected, rel=1e-3)
    # and damping alone leaves the passive offset F/K
    ctrl = TAPMPID.from_design(fast_design, modes="normal")
    _, X, _, _ = simulate(ctrl, 3000.0, 1.0, [F, 0.0, 0.0], np.zeros(3))
    assert X[-1, 0] == pytest.approx(F / K[0, 0], rel=1e-2)


def test_anti_windup_bounds_integral_and_cuts_overshoot(fast_design):
    """A 30 m surge setpoint step with +-3 MN thrust: the output saturates for a long time."""
    lim = np.array([3.0e6, 3.0e6, 1.0e9])
    runs = {}
    for aw in (True, False):
        ctrl = TAPMPID.from_design(fast_design, tau_limit=lim, anti_windup=aw)
        runs[aw] = simulate(ctrl, 1500.0, 0.5, np.zeros(3), [30.0, 0.0, 0.0])
    _, X_aw, T_aw, I_aw = runs[True]
    _, X_no, T_no, I_no = runs[False]
    assert np.all(np.abs(T_aw) <= lim) and np.all(np.abs(T_no) <= lim)
    assert np.sum(np.abs(T_aw[:, 0]) == lim[0]) > 40  # saturated for > 20 s
    assert np.all(np.abs(I_aw[:, 0]) <= lim[0] * (1 + 1e-12))  # integral stays bounded
    assert np.abs(I_no[:, 0]).max() > 3 * lim[0]  # ... and winds up without anti-windup
    over_aw = X_aw[:, 0].max() - 30.0
    over_no = X_no[:, 0].max() - 30.0
    assert over_aw < 0.25 * over_no
    assert X_aw[-1, 0] == pytest.approx(30.0, abs=1e-3)


def test_integral_limit_clamps_integral_load():
    ctrl = TAPMPID(GAINS, modes=("mean",), integral_limit=[5.0e5, 1.0e5, 0.0])
    for k in range(200):  # 10 m north, 5 m east error, heading 30 deg: integral grows
        tau = ctrl.update(10.0 * k, est([10.0, 5.0, np.deg2rad(30)]), sp())
    np.testing.assert_allclose(np.abs(tau), [5.0e5, 1.0e5, 0.0], rtol=1e-9)
    np.testing.assert_allclose(ctrl.integral_load, tau)


# --- projections and kinematics -----------------------------------------------------------

state = st.lists(st.floats(-50, 50, allow_nan=False), min_size=3, max_size=3)


@settings(max_examples=100, deadline=None)
@given(eta=state, nu=state, eta_d=state)
def test_heading_mode_leaves_surge_sway_zero(eta, nu, eta_d):
    ctrl = TAPMPID(GAINS, modes=("heading",))
    for k in range(3):
        tau = ctrl.update(float(k), est(eta, nu), sp(eta_d))
        assert tau[0] == 0.0 and tau[1] == 0.0
    assert np.all(ctrl.integral[:2] == 0.0)


def test_damping_mode_is_minus_Kd_nu_in_surge_sway():
    ctrl = TAPMPID(GAINS, modes="damping")
    nu, nu_d = np.array([0.3, -0.2, 0.004]), np.array([0.1, 0.0, 0.001])
    tau = ctrl.update(0.0, est([12.0, -7.0, 1.0], nu), sp([0.0, 0.0, 0.0], nu_d))
    assert tau[2] == 0.0
    np.testing.assert_allclose(tau[:2], -np.diag(GAINS.Kd)[:2] * (nu - nu_d)[:2], rtol=1e-15)
    # a full K_d: the H_xy rows of K_d act on the whole velocity error (incl. the yaw rate)
    Kd = np.array([[4e7, 1e6, 2e8], [1e6, 5e7, 3e8], [2e8, 3e8, 6e11]])
    ctrl = TAPMPID(PIDGains(Kp=GAINS.Kp, Ki=GAINS.Ki, Kd=Kd), modes="damping")
    tau = ctrl.update(0.0, est([0.0, 0.0, 0.0], nu), sp())
    np.testing.assert_allclose(tau, -(np.diag([1.0, 1.0, 0.0]) @ Kd @ nu), rtol=1e-15)


def test_body_rotation_north_error_heading_east_gives_sway_force():
    """Heading east (psi = 90 deg), 1 m north of the setpoint: R^T turns the error into body
    -y (port), so the restoring force pushes to starboard (+Y), i.e. south."""
    ctrl = TAPMPID(GAINS, modes="restoring")
    tau = ctrl.update(0.0, est([1.0, 0.0, np.pi / 2]), sp([0.0, 0.0, np.pi / 2]))
    assert tau[0] == pytest.approx(0.0, abs=1e-9 * GAINS.Kp[1, 1])
    assert tau[1] == pytest.approx(GAINS.Kp[1, 1], rel=1e-12)
    assert tau[2] == 0.0
    force_E = rot_z(np.pi / 2) @ tau
    assert force_E[0] == pytest.approx(-GAINS.Kp[1, 1], rel=1e-12)  # toward the setpoint


@settings(max_examples=100, deadline=None)
@given(psi=st.floats(-10, 10, allow_nan=False), err=st.lists(st.floats(-100, 100, allow_nan=False),
                                                            min_size=2, max_size=2))
def test_isotropic_restoring_force_is_frame_invariant(psi, err):
    """With K_p,x = K_p,y the restoring force in {E} is -K_p (p - p_d) for every heading."""
    kp = 2.0e6
    ctrl = TAPMPID(PIDGains(Kp=[kp, kp, 1e9], Ki=GAINS.Ki, Kd=GAINS.Kd), modes="restoring")
    tau = ctrl.update(0.0, est([err[0], err[1], psi]), sp([0.0, 0.0, psi]))
    np.testing.assert_allclose((rot_z(psi) @ tau)[:2], -kp * np.array(err), rtol=1e-9,
                               atol=1e-6 * kp)


def test_heading_error_is_wrapped_with_ssa():
    """psi = 350 deg with psi_d = 0 is an error of -10 deg, for P and for the integral."""
    ctrl = TAPMPID(GAINS, modes="heading")
    for psi in (np.deg2rad(350.0), np.deg2rad(350.0 + 720.0), np.deg2rad(-10.0)):
        ctrl.reset()
        tau = ctrl.update(0.0, est([0.0, 0.0, psi]), sp())
        assert tau[2] == pytest.approx(GAINS.Kp[2, 2] * np.deg2rad(10.0), rel=1e-9)
        ctrl.update(2.0, est([0.0, 0.0, psi]), sp())
        assert ctrl.integral[2] == pytest.approx(-np.deg2rad(10.0) * 2.0, rel=1e-9)


def test_integral_uses_actual_elapsed_time_and_first_call_initialises():
    ctrl = TAPMPID(GAINS, modes=("mean",))
    e = np.array([2.0, -1.0, 0.0])
    tau0 = ctrl.update(100.0, est(e), sp())
    np.testing.assert_array_equal(tau0, 0.0)  # first call: clock only
    ctrl.update(100.5, est(e), sp())
    ctrl.update(103.5, est(e), sp())
    np.testing.assert_allclose(ctrl.integral, e * 3.5, rtol=1e-12)
    tau = ctrl.update(103.5, est(e), sp())  # same time again: no integration
    np.testing.assert_allclose(tau, -np.diag(GAINS.Ki) * e * 3.5, rtol=1e-12)
    with pytest.raises(ControlError, match="earlier than the previous call"):
        ctrl.update(50.0, est(e), sp())
    ctrl.reset()
    np.testing.assert_array_equal(ctrl.integral, 0.0)
    ctrl.update(50.0, est(e), sp())


def test_mode_sets_match_table_3_and_switching_zeroes_unused_integral():
    assert MODE_SETS["calm"] == ("heading",)
    assert MODE_SETS["normal"] == ("heading", "damping")
    assert MODE_SETS["normal_restoring"] == ("heading", "damping", "restoring")
    assert MODE_SETS["extreme"] == ("heading", "damping", "mean")
    assert MODE_SETS["extreme_restoring"] == MODES
    ctrl = TAPMPID(GAINS, modes="extreme")
    for k in range(3):
        ctrl.update(float(k), est([3.0, 1.0, 0.1]), sp())
    assert np.all(ctrl.integral != 0.0)
    ctrl.set_modes("calm")
    assert np.all(ctrl.integral[:2] == 0.0) and ctrl.integral[2] != 0.0


def test_all_modes_sum_to_the_multivariable_pid():
    """Modes 1+2+3+4 = tau of [G] §2.3 with full gain matrices."""
    rng = np.random.default_rng(11)
    Kp, Ki, Kd = (np.abs(rng.normal(size=(3, 3))) * s for s in (1e6, 1e4, 1e8))
    g = PIDGains(Kp=Kp, Ki=Ki, Kd=Kd)
    full = TAPMPID(g)
    parts = [TAPMPID(g, modes=(m,)) for m in MODES]
    eta, nu, eta_d = np.array([4.0, -3.0, 0.3]), np.array([0.2, 0.1, 0.002]), np.zeros(3)
    for t in (0.0, 1.0):
        tau = full.update(t, est(eta, nu), sp(eta_d))
        tau_sum = sum(c.update(t, est(eta, nu), sp(eta_d)) for c in parts)
    Rt = rot_z(eta[2]).T
    expected = -Ki @ Rt @ (eta * 1.0) - Kp @ Rt @ eta - Kd @ nu
    np.testing.assert_allclose(tau, expected, rtol=1e-12)
    np.testing.assert_allclose(tau_sum, expected, rtol=1e-12)


def test_env_feedforward_subtracts_estimated_load():
    ctrl = TAPMPID(GAINS, env_feedforward=True)
    tau_env = np.array([1e6, -2e5, 3e7])
    tau = ctrl.update(0.0, est([0.0, 0.0, 0.0], tau_env=tau_env), sp())
    np.testing.assert_allclose(tau, -tau_env)
    assert np.all(TAPMPID(GAINS).update(0.0, est([0, 0, 0], tau_env=tau_env), sp()) == 0.0)


# --- bad input ------------------------------------------------------------------------------

def test_control_error_is_typed():
    assert issubclass(ControlError, TapmError) and issubclass(ControlError, ValueError)


@pytest.mark.parametrize("estimate, setpoint, match", [
    (est([np.nan, 0.0, 0.0]), sp(), "estimate.eta"),
    (est([0.0, 0.0, 0.0], nu=[0.0, np.inf, 0.0]), sp(), "estimate.nu"),
    (est([0.0, 0.0]), sp(), r"estimate.eta must have shape \(3,\)"),
    (est([0.0, 0.0, 0.0], nu=np.zeros((3, 1))), sp(), "estimate.nu must have shape"),
    (est([0.0, 0.0, 0.0]), sp([0.0, np.nan, 0.0]), "setpoint.eta_d"),
    (est([0.0, 0.0, 0.0]), sp(nu_d=[0.0, 0.0]), "setpoint.nu_d"),
])
def test_bad_estimate_or_setpoint_raises(estimate, setpoint, match):
    ctrl = TAPMPID(GAINS)
    with pytest.raises(ControlError, match=match):
        ctrl.update(0.0, estimate, setpoint)


def test_bad_time_and_feedforward_load():
    ctrl = TAPMPID(GAINS, env_feedforward=True)
    with pytest.raises(ControlError, match="t=nan"):
        ctrl.update(float("nan"), est([0, 0, 0]), sp())
    with pytest.raises(ControlError, match="estimate.tau_env"):
        ctrl.update(0.0, est([0, 0, 0], tau_env=[np.nan, 0, 0]), sp())


@pytest.mark.parametrize("modes, match", [
    (("heading", "sway"), r"unknown control mode\(s\) \['sway'\]"),
    ("stormy", r"unknown control mode\(s\) \['stormy'\]"),
    ((), "modes is empty"),
])
def test_unknown_mode_raises(modes, match):
    with pytest.raises(ControlError, match=match):
        TAPMPID(GAINS, modes=modes)


@pytest.mark.parametrize("kwargs, match", [
    (dict(Kp=[1.0, -1.0, 1.0], Ki=[0, 0, 0], Kd=[0, 0, 0]), "Kp must have a non-negative"),
    (dict(Kp=np.ones((2, 2)), Ki=[0, 0, 0], Kd=[0, 0, 0]), r"Kp must have shape"),
    (dict(Kp=[1, 1, 1], Ki=[0, np.nan, 0], Kd=[0, 0, 0]), "Ki must be finite"),
])
def test_bad_gains_raise(kwargs, match):
    with pytest.raises(ControlError, match=match):
        PIDGains(**kwargs)


@pytest.mark.parametrize("kwargs, match", [
    (dict(tau_limit=[1e6, 0.0, 1e9]), "tau_limit must be > 0"),
    (dict(integral_limit=-1.0), "integral_limit must be >= 0"),
    (dict(tau_limit=[1.0, 2.0]), "tau_limit"),
])
def test_bad_limits_raise(kwargs, match):
    with pytest.raises(ControlError, match=match):
        TAPMPID(GAINS, **kwargs)


@pytest.mark.parametrize("kwargs, match", [
    (dict(periods=(100.0, -1.0, 90.0), damping=0.7), "periods must be finite and > 0"),
    (dict(periods=100.0, damping=np.nan), "damping must be finite"),
    (dict(periods=100.0, damping=0.7, integral_ratio=-0.1), "integral_ratio"),
    (dict(periods=100.0, damping=0.7, method="lqr"), "method='lqr' is unknown"),
])
def test_bad_design_arguments_raise(kwargs, match):
    with pytest.raises(ControlError, match=match):
        design_gains((M, D, K), **kwargs)


def test_bad_plant_raises():
    with pytest.raises(ControlError, match="6 states"):
        design_gains(control.ss(-np.eye(2), np.ones((2, 1)), np.eye(2), 0), periods=100.0,
                     damping=0.7)
    with pytest.raises(ControlError, match=r"\(M, D, K\)"):
        design_gains("fpso", periods=100.0, damping=0.7)
    with pytest.raises(ControlError, match="must be a PIDDesign"):
        TAPMPID.from_design(GAINS)  # type: ignore[arg-type]


def test_closed_loop_io_labels():
    cl = closed_loop((M, D, K), GAINS, "calm")
    assert cl.input_labels == ["X_env", "Y_env", "N_env", "x_d", "y_d", "psi_d"]
    assert cl.output_labels == ["x", "y", "psi", "X_thr", "Y_thr", "N_thr"]
    assert cl.nstates == 7  # plant + the heading integral only


def test_estimate_and_setpoint_are_read_only_copies():
    eta = np.array([1.0, 2.0, 0.1])
    e = Estimate(0.0, eta, [0, 0, 0], [0, 0, 0])
    eta[0] = 99.0
    assert e.eta[0] == 1.0
    with pytest.raises(ValueError):
        e.eta[0] = 5.0
    s = Setpoint([0, 0, 0])
    np.testing.assert_array_equal(s.nu_d, np.zeros(3))
    assert not s.nu_d.flags.writeable and e.tensions is None


def test_linear_closed_loop_with_reference_point_matches_the_nonlinear_law():
    """The linear loop's controller map (reference_maps) is the first-order expansion of what
    TAPMPID with a reference point computes: a small pose and velocity perturbation gives the same
    command from both, to second order."""
    from tapm_opt.control.pid_design import reference_maps
    from tapm_opt.control.estimate import Estimate, Setpoint
    from tapm_opt.geometry import rot_z

    c = np.array([91.44, 5.0])
    psi0 = 0.4
    gains = PIDGains(Kp=np.diag([2e5, 3e5, 4e8]), Ki=np.zeros((3, 3)), Kd=np.diag([5e6, 6e6, 7e9]))
    pid = TAPMPID(gains, modes=("heading", "damping", "restoring"), reference_point=c)
    T_eta, T_nu = reference_maps(rot_z(psi0), c)
    d_eta = np.array([0.3, -0.2, 1e-3])
    nu = np.array([0.01, -0.02, 2e-4])
    eta0 = np.array([5.0, -3.0, psi0])
    from tapm_opt.geometry import turret_offset

    sp = Setpoint([*turret_offset(eta0, c), psi0])
    tau = pid.update(0.0, Estimate(0.0, eta0 + d_eta, nu, np.zeros(3)), sp)
    lin = -gains.Kp @ rot_z(psi0).T @ T_eta @ d_eta - gains.Kd @ T_nu @ nu
    np.testing.assert_allclose(tau, lin, rtol=2e-3, atol=1e-6 * np.abs(lin).max())
