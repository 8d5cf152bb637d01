"""Tests of the 3-DOF LF vessel model (tapm_opt.models.vessel): analytic limits, invariants,
cross-checks between the numeric, symbolic and finite-difference paths, and bad input."""

from __future__ import annotations

import dataclasses
import types

import casadi as ca
import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from tapm_opt.errors import ModelError
from tapm_opt.geometry import rot_z
from tapm_opt.models.vessel import (
    VesselParams,
    coriolis,
    equilibrium,
    linearise,
    moored_function,
    vessel_function,
    vessel_rhs,
)

# FPSO-like magnitudes (order of a 250 m turret-moored FPSO).
M_DIAG = np.array([2.0e8, 3.0e8, 6.0e11])  # [kg, kg, kg m^2]
M_A_DIAG = np.array([1.0e7, 1.2e8, 2.0e11])
D_DIAG = np.array([1.0e6, 4.0e6, 3.0e9])  # [N s/m, N s/m, N m s]
G_DIAG = np.array([8.0e4, 1.5e5, 2.0e8])  # mooring stiffness [N/m, N/m, N m/rad]


def diag_params(**kw) -> VesselParams:
    base = dict(M=np.diag(M_DIAG), M_A=np.diag(M_A_DIAG), D_lin=np.diag(D_DIAG),
                d_quad=np.array([2.0e5, 3.0e6, 4.0e12]))
    base.update(kw)
    return VesselParams(**base)


def coupled_params() -> VesselParams:
    """Symmetric M with sway-yaw coupling (x_g != 0) and a non-symmetric D_lin."""
    m, xg, Iz = 2.0e8, 5.0, 6.0e11
    M_RB = np.array([[m, 0, 0], [0, m, m * xg], [0, m * xg, Iz]])
    M_A = np.array([[1.0e7, 0, 0], [0, 1.2e8, -3.0e8], [0, -3.0e8, 2.0e11]])
    D = np.array([[1.0e6, 0, 0], [0, 4.0e6, 2.0e7], [0, 1.0e7, 3.0e9]])
    return VesselParams(M=M_RB + M_A, M_A=M_A, D_lin=D, d_quad=[2.0e5, 3.0e6, 4.0e12])


def linear_spring(G: np.ndarray) -> ca.Function:
    """tau_moor(eta) = -R(psi)^T G eta (survey eq. 29 with eta0 = 0, g_moor(0) = 0)."""
    eta = ca.SX.sym("eta", 3)
    return ca.Function("spring", [eta], [-ca.mtimes(rot_z(eta[2]).T, ca.mtimes(G, eta))])


def call(fn: ca.Function, *args) -> tuple[np.ndarray, ...]:
    out = fn(*args)
    out = out if isinstance(out, tuple) else (out,)
    return tuple(np.asarray(o.full()).ravel() for o in out)


# --- analytic limits --------------------------------------------------------------------------

@pytest.mark.parametrize("params", [diag_params(), coupled_params()], ids=["diagonal", "coupled"])
def test_free_decay_equals_matrix_exponential(params):
    """Design form, no mooring, psi = 0: nu(t) = expm(-M^-1 D t) nu0."""
    f = vessel_function(params, "design")
    nu0 = np.array([1.5, -0.8, 0.004])

    def rhs(t, nu):
        return call(f, np.zeros(3), nu, np.zeros(3), np.zeros(2))[1]

    t_eval = np.linspace(0.0, 400.0, 9)
    sol = solve_ivp(rhs, (0.0, 400.0), nu0, t_eval=t_eval, method="DOP853",
                    rtol=1e-11, atol=1e-14)
    assert sol.success
    A = -params.M_inv @ params.D_lin
    for k, t in enumerate(t_eval):
        exact = scipy.linalg.expm(A * t) @ nu0
        np.testing.assert_allclose(sol.y[:, k], exact, rtol=1e-6, atol=1e-9)
    assert np.linalg.norm(sol.y[:, -1]) < 0.5 * np.linalg.norm(nu0)  # it did decay


def test_sign_conventions():
    """Heading east and surging moves the vessel east; +N gives +r_dot (clockwise from above)."""
    p = diag_params()
    eta_dot, _ = vessel_rhs([0, 0, np.pi / 2], [2.0, 0, 0], np.zeros(3), [0, 0], p)
    np.testing.assert_allclose(eta_dot, [0.0, 2.0, 0.0], atol=1e-15)
    _, nu_dot = vessel_rhs(np.zeros(3), np.zeros(3), [1e6, -2e6, 3e9], [0, 0], p)
    np.testing.assert_allclose(nu_dot, [1e6 / M_DIAG[0], -2e6 / M_DIAG[1], 3e9 / M_DIAG[2]])


# --- Coriolis ---------------------------------------------------------------------------------

finite = st.floats(-1e3, 1e3, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(upper=st.lists(finite, min_size=6, max_size=6), nu=st.lists(finite, min_size=3, max_size=3))
def test_coriolis_is_skew_and_does_no_work(upper, nu):
    M = np.zeros((3, 3))
    M[np.triu_indices(3)] = upper
    M = M + np.triu(M, 1).T
    nu = np.array(nu)
    C = coriolis(M, nu)
    np.testing.assert_array_equal(C + C.T, np.zeros((3, 3)))
    scale = np.linalg.norm(nu) ** 3 * np.abs(M).max() + 1e-300
    assert abs(nu @ C @ nu) <= 1e-13 * scale


def test_coriolis_rigid_body_matches_fossen_closed_form():
    """C_RB(nu) of Fossen (2021) eq. 6.99 (3 DOF, x_g != 0) and symbolic = numeric."""
    m, xg, Iz = 3.0e7, 4.0, 5.0e10
    M_RB = np.array([[m, 0, 0], [0, m, m * xg], [0, m * xg, Iz]])
    u, v, r = 1.2, -0.4, 0.02
    expected = np.array([[0, 0, -m * (xg * r + v)], [0, 0, m * u], [m * (xg * r + v), -m * u, 0]])
    np.testing.assert_allclose(coriolis(M_RB, np.array([u, v, r])), expected, rtol=1e-14)
    nu = ca.SX.sym("nu", 3)
    C_fn = ca.Function("C", [nu], [coriolis(M_RB, nu)])
    np.testing.assert_allclose(C_fn([u, v, r]).full(), expected, rtol=1e-14)


def test_munk_moment_closed_form():
    """Rich form, no current/damping, r = 0, diagonal M_RB with m11 = m22: the only yaw load is
    the Munk moment, C_A(nu) nu = (0, 0, (M_A22 - M_A11) u v), so r_dot = -(...)/M33."""
    m = 2.0e8
    M_RB = np.diag([m, m, 4.0e11])
    M_A = np.diag(M_A_DIAG)
    p = VesselParams(M=M_RB + M_A, M_A=M_A, D_lin=np.zeros((3, 3)))
    u, v = 1.5, -0.7
    _, nu_dot = vessel_rhs(np.zeros(3), [u, v, 0.0], np.zeros(3), [0, 0], p, form="rich")
    munk = (M_A[1, 1] - M_A[0, 0]) * u * v
    np.testing.assert_allclose(nu_dot, [0.0, 0.0, -munk / (M_RB[2, 2] + M_A[2, 2])], atol=1e-20)
    assert munk != 0.0


# --- current ----------------------------------------------------------------------------------

@pytest.mark.parametrize("psi", [0.0, 0.7, -2.5])
def test_vessel_drifting_with_current_feels_no_hydrodynamic_load(psi):
    """nu = nu_c: nu_r = 0, no damping or Coriolis; nu_dot = M^-1 tau and eta_dot = v_c^E."""
    p = coupled_params()
    v_c = np.array([0.6, -0.3])
    nu_c = rot_z(psi).T @ np.array([*v_c, 0.0])
    tau = np.array([1e5, -2e5, 3e7])
    eta_dot, nu_dot = vessel_rhs([10, -5, psi], nu_c, tau, v_c, p, form="rich")
    np.testing.assert_allclose(eta_dot, [*v_c, 0.0], atol=1e-14)
    np.testing.assert_allclose(nu_dot, p.M_inv @ tau, rtol=1e-12)


def test_current_frame_rotation_term():
    """Vessel translating with the current while turning (nu_r = (0, 0, r)): with diagonal M
    the surge/sway accelerations are exactly d/dt nu_c = (r v_c, -r u_c)."""
    p = diag_params()
    psi, r = 0.9, 0.01
    v_c = np.array([0.5, 0.8])
    u_c, v_c_B, _ = rot_z(psi).T @ np.array([*v_c, 0.0])
    _, nu_dot = vessel_rhs([0, 0, psi], [u_c, v_c_B, r], np.zeros(3), v_c, p, form="rich")
    np.testing.assert_allclose(nu_dot[:2], [r * v_c_B, -r * u_c], rtol=1e-12)
    yaw_damping = D_DIAG[2] * r + 4.0e12 * abs(r) * r
    np.testing.assert_allclose(nu_dot[2], -yaw_damping / M_DIAG[2], rtol=1e-12)


def test_design_form_ignores_current_rich_form_does_not():
    p = diag_params()
    args = (np.zeros(3), np.zeros(3), np.zeros(3), np.array([1.0, 0.0]))
    assert np.all(vessel_rhs(*args, p, form="design")[1] == 0.0)
    nu_dot = vessel_rhs(*args, p, form="rich")[1]
    assert nu_dot[0] == pytest.approx((D_DIAG[0] * 1.0 + 2.0e5) / M_DIAG[0], rel=1e-12)


@pytest.mark.parametrize("nu", [[0.0, 0.0, 0.03], [1.2, -0.5, 0.0]], ids=["pure_yaw", "r=0"])
def test_design_equals_rich_when_coriolis_quadratic_damping_and_current_vanish(nu):
    """M = diag(m, m, Iz) with M_A = 0, d_quad = 0, no current: C(nu) nu = 0 for r = 0 or
    u = v = 0, so both forms give the same right-hand side."""
    p = VesselParams(M=np.diag([2e8, 2e8, 6e11]), D_lin=np.array([[1e6, 2e5, 0], [2e5, 4e6, 1e7],
                                                                  [0, 1e7, 3e9]]))
    rng = np.random.default_rng(3)
    eta, tau = rng.normal(size=3), rng.normal(size=3) * 1e6
    d = vessel_rhs(eta, nu, tau, [0.0, 0.0], p, form="design")
    r = vessel_rhs(eta, nu, tau, [0.0, 0.0], p, form="rich")
    for a, b in zip(d, r):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-18)


# --- numeric vs symbolic ----------------------------------------------------------------------

@pytest.mark.parametrize("form", ["design", "rich"])
def test_numeric_and_symbolic_paths_agree(form):
    p = coupled_params()
    f = vessel_function(p, form)
    assert f.name() == f"vessel_{form}"
    assert f.name_in() == ["eta", "nu", "tau", "v_c"] and f.name_out() == ["eta_dot", "nu_dot"]
    rng = np.random.default_rng(7)
    for _ in range(20):
        args = (rng.normal(size=3) * [50, 50, 3], rng.normal(size=3) * [2, 1, 0.02],
                rng.normal(size=3) * [1e6, 1e6, 1e9], rng.normal(size=2))
        num = vessel_rhs(*args, p, form=form)
        sym = call(f, *args)
        for a, b in zip(num, sym):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(a).max())


# --- moored model and linearisation -----------------------------------------------------------

def _fd_jacobian(fn, args, k, h):
    base = [np.array(a, dtype=float) for a in args]
    n = base[k].size
    J = np.zeros((6, n))
    for j in range(n):
        plus, minus = [a.copy() for a in base], [a.copy() for a in base]
        plus[k][j] += h[j]
        minus[k][j] -= h[j]
        J[:, j] = (call(fn, *plus)[0] - call(fn, *minus)[0]) / (2 * h[j])
    return J


@pytest.mark.parametrize("form", ["design", "rich"])
def test_linearise_matches_central_finite_differences(form):
    p = coupled_params()
    D_moor = np.diag([5e5, 5e5, 1e9])
    fn = moored_function(p, linear_spring(np.diag(G_DIAG)), form=form, D_moor=D_moor)
    x0 = np.array([12.0, -7.0, 0.4, 0.3, -0.2, 0.004])
    tau_thr0, tau_env0, v_c = np.array([2e5, -1e5, 1e7]), np.array([-3e5, 4e5, 2e7]), [0.5, 0.4]
    sys = linearise(fn, x0, tau_thr0, tau_env0, v_c, outputs="state")
    args = (x0, tau_thr0, tau_env0, v_c)
    A_fd = _fd_jacobian(fn, args, 0, 1e-5 * np.maximum(np.abs(x0), 1e-2))
    B_fd = _fd_jacobian(fn, args, 1, np.full(3, 1e2))
    for J, J_fd in ((sys.A, A_fd), (sys.B, B_fd)):  # per row: kinematic and dynamic scales
        for row, row_fd in zip(J, J_fd):
            np.testing.assert_allclose(row, row_fd, rtol=1e-6, atol=1e-6 * np.abs(row_fd).max())
    np.testing.assert_allclose(sys.B[3:], p.M_inv, rtol=1e-12)
    assert np.array_equal(sys.C, np.eye(6)) and not sys.D.any()
    assert [s for s in sys.state_labels] == ["x", "y", "psi", "u", "v", "r"]
    assert sys.input_labels == ["X", "Y", "N"]


def test_linear_spring_eigenvalues_and_surge_natural_period():
    """Diagonal M, D = D_lin + D_mo, G, psi0 = 0 (eq. 31): A has the roots of
    M_ii s^2 + D_ii s + G_ii; surge period is 2 pi sqrt(M11 / G11) for small damping."""
    D = np.diag(0.01 * 2 * np.sqrt(M_DIAG * G_DIAG))  # 1 % of critical damping
    p = VesselParams(M=np.diag(M_DIAG), D_lin=0.3 * D)
    fn = moored_function(p, linear_spring(np.diag(G_DIAG)), D_moor=0.7 * D)
    assert fn.name() == "moored_design"
    sys = linearise(fn, np.zeros(6))
    assert np.array_equal(sys.C, np.eye(6)[:3]) and sys.output_labels == ["x", "y", "psi"]
    expected = np.concatenate([np.roots([M_DIAG[i], D[i, i], G_DIAG[i]]) for i in range(3)])
    eig, vec = np.linalg.eig(sys.A)
    np.testing.assert_allclose(np.sort_complex(eig), np.sort_complex(expected), rtol=1e-10)
    surge = np.abs(vec[0]) + np.abs(vec[3]) > 0.5 * np.linalg.norm(vec, axis=0)
    T_n = 2 * np.pi / np.abs(eig[surge].imag)
    np.testing.assert_allclose(T_n, 2 * np.pi * np.sqrt(M_DIAG[0] / G_DIAG[0]), rtol=1e-4)
    assert T_n[0] > 300.0  # FPSO surge: several minutes


def test_equilibrium_of_linear_spring_and_failure_without_mooring():
    p = diag_params()
    tau_env = np.array([3e5, -2e5, 0.0])
    fn = moored_function(p, linear_spring(np.diag(G_DIAG)))
    eta0 = equilibrium(fn, tau_env)
    np.testing.assert_allclose(eta0, tau_env / G_DIAG, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(call(fn, [*eta0, 0, 0, 0], 0, tau_env, [0, 0])[0], 0, atol=1e-12)
    # large yaw moment: psi0 = N / G33 = 4 rad (> pi) is returned unwrapped
    eta_yaw = equilibrium(fn, [0.0, 0.0, 4.0 * G_DIAG[2]], eta_guess=[0.0, 0.0, 3.0])
    np.testing.assert_allclose(eta_yaw, [0.0, 0.0, 4.0], atol=1e-9)
    # rich form with current: the current drag is balanced by the mooring too
    fn_rich = moored_function(p, linear_spring(np.diag(G_DIAG)), form="rich")
    eta_c = equilibrium(fn_rich, 0.0, v_c=[0.5, 0.0])
    assert eta_c[0] == pytest.approx((D_DIAG[0] * 0.5 + 2.0e5 * 0.25) / G_DIAG[0], rel=1e-8)
    with pytest.raises(ModelError, match="equilibrium not found"):
        equilibrium(moored_function(p, None), tau_env)


def test_moored_function_accepts_mx_only_mooring_model():
    """A mooring model defined implicitly (MX rootfinder) gives the same x_dot and A."""
    G = np.diag(G_DIAG)
    eta, z = ca.MX.sym("eta", 3), ca.MX.sym("z", 3)
    res = ca.Function("res", [z, eta], [z + ca.mtimes(rot_z(eta[2]).T, ca.mtimes(G, eta))])
    solver = ca.rootfinder("solve_tau", "newton", res)
    tau_mx = ca.Function("spring_mx", [eta], [solver(ca.DM.zeros(3), eta)])
    p = diag_params()
    f_mx = moored_function(p, tau_mx, form="rich")
    f_sx = moored_function(p, linear_spring(G), form="rich")
    args = ([20.0, -10.0, 0.3, 0.5, 0.1, 0.002], [1e5, 0, 0], [0, 2e5, 1e7], [0.3, 0.2])
    np.testing.assert_allclose(call(f_mx, *args)[0], call(f_sx, *args)[0], rtol=1e-10)
    lin_mx, lin_sx = linearise(f_mx, *args), linearise(f_sx, *args)
    np.testing.assert_allclose(lin_mx.A, lin_sx.A, rtol=1e-9, atol=1e-15)


# --- parameters and bad input -----------------------------------------------------------------

def test_from_scenario_and_read_only_arrays():
    M = ((2e8, 0, 0), (0, 3e8, 0), (0, 0, 6e11))
    ves = types.SimpleNamespace(mass_matrix=M, added_mass=None,
                                linear_damping=tuple(map(tuple, np.diag(D_DIAG))),
                                quadratic_damping=(1.0, 2.0, 3.0))
    p = VesselParams.from_scenario(types.SimpleNamespace(vessel=ves))
    np.testing.assert_array_equal(p.M, np.array(M))
    np.testing.assert_array_equal(p.M_A, np.zeros((3, 3)))
    np.testing.assert_array_equal(p.M_RB, p.M)
    np.testing.assert_array_equal(p.d_quad, [1.0, 2.0, 3.0])
    ves.added_mass = tuple(map(tuple, np.diag(M_A_DIAG)))
    p2 = VesselParams.from_scenario(types.SimpleNamespace(vessel=ves))
    np.testing.assert_array_equal(p2.M_RB, np.array(M) - np.diag(M_A_DIAG))
    with pytest.raises(ValueError):
        p.M[0, 0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.M = np.eye(3)
    p3 = dataclasses.replace(p, d_quad=np.zeros(3))
    np.testing.assert_allclose(p3.M_inv @ p3.M, np.eye(3), atol=1e-12)


GOOD = dict(M=np.diag(M_DIAG), M_A=np.diag(M_A_DIAG), D_lin=np.diag(D_DIAG), d_quad=np.ones(3))


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("M", np.diag(M_DIAG) + np.triu(np.ones((3, 3)) * 1e7, 1), r"^M must be symmetric"),
        ("M", np.diag([2e8, -3e8, 6e11]), r"^M must be positive definite"),
        ("M", np.ones((3, 2)), r"^M has shape \(3, 2\)"),
        ("M_A", np.diag(M_A_DIAG) + np.triu(np.ones((3, 3)) * 1e7, 1), r"^M_A must be symmetric"),
        ("M_A", np.diag([3e8, 0, 0]), r"M_RB = M - M_A must be positive definite"),
        ("D_lin", np.diag([1e6, np.nan, 1e9]), r"^D_lin must be finite.*nan"),
        ("D_lin", np.diag([1e6, -4e6, 1e9]), r"^D_lin must have a positive semidefinite"),
        ("D_lin", np.eye(2), r"^D_lin has shape \(2, 2\)"),
        ("d_quad", [1.0, -2.0, 3.0], r"^d_quad must be >= 0.*-2\.0"),
        ("d_quad", [1.0, 2.0], r"^d_quad has shape \(2,\)"),
        ("d_quad", ["a", 1, 2], r"^d_quad="),
    ],
)
def test_bad_parameters_raise_model_error_naming_the_field(field, value, match):
    with pytest.raises(ModelError, match=match):
        VesselParams(**{**GOOD, field: value})


def test_bad_arguments_raise_model_error():
    p = VesselParams(**GOOD)
    with pytest.raises(ModelError, match="form='full'"):
        vessel_rhs(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(2), p, form="full")
    with pytest.raises(ModelError, match="form='Rich'"):
        vessel_function(p, "Rich")
    with pytest.raises(ModelError, match="form='plant'"):
        moored_function(p, None, form="plant")
    with pytest.raises(ModelError, match=r"v_c_E must have shape \(2,\)"):
        vessel_rhs(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), p)
    with pytest.raises(ModelError, match="D_moor"):
        moored_function(p, None, D_moor=-np.eye(3))
    with pytest.raises(ModelError, match="tau_moor"):
        a = ca.SX.sym("a", 2)
        moored_function(p, ca.Function("bad", [a], [-a]))
    fn = moored_function(p, None)
    with pytest.raises(ModelError, match="outputs="):
        linearise(fn, np.zeros(6), outputs="y")
    with pytest.raises(ModelError, match="x0"):
        linearise(fn, np.zeros(5))
    with pytest.raises(ModelError, match="moored_function"):
        linearise(vessel_function(p), np.zeros(6))
