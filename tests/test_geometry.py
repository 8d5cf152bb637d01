"""Tests of frames and kinematics (tapm_opt.geometry, survey eq. 1–6): rotation properties,
angle wrapping, fairlead positions against the scalar form of eq. (6), the turret position and
turret-referenced offset, numpy vs CasADi paths."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tapm_opt.geometry import (
    R,
    R2,
    body_from_turret,
    fairleads_B,
    fairleads_E,
    fairleads_T,
    rot2_apply,
    rot_z,
    ssa,
    turret_offset,
    turret_position,
)

angles = st.floats(-50.0, 50.0, allow_nan=False)
wide_angles = st.floats(-1e4, 1e4, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(angles)
def test_rot_z_is_a_proper_rotation(psi):
    Rm = rot_z(psi)
    assert Rm.shape == (3, 3)
    np.testing.assert_allclose(Rm.T @ Rm, np.eye(3), atol=1e-15)
    assert np.linalg.det(Rm) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_array_equal(Rm[2], [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(Rm[:, 2], [0.0, 0.0, 1.0])
    # eq. (1): eta_dot = R nu, a pure surge at heading psi moves along (cos psi, sin psi)
    np.testing.assert_allclose(Rm @ [1.0, 0.0, 0.0], [math.cos(psi), math.sin(psi), 0.0], atol=1e-15)
    np.testing.assert_allclose(Rm @ [0.0, 1.0, 0.0], [-math.sin(psi), math.cos(psi), 0.0], atol=1e-15)


@settings(max_examples=200, deadline=None)
@given(angles, angles)
def test_rotations_compose(a, b):
    np.testing.assert_allclose(rot_z(a) @ rot_z(b), rot_z(a + b), atol=1e-13)
    np.testing.assert_allclose(R2(a) @ R2(b), R2(a + b), atol=1e-13)
    np.testing.assert_allclose(rot_z(a).T, rot_z(-a), atol=1e-15)


def test_rot_z_vectorises_and_R_is_its_alias():
    psi = np.array([[0.0, 0.3], [-2.0, 4.0]])
    Rm = rot_z(psi)
    assert Rm.shape == (2, 2, 3, 3)
    for idx in np.ndindex(psi.shape):
        np.testing.assert_array_equal(Rm[idx], rot_z(float(psi[idx])))
    assert R is rot_z
    assert R2(psi).shape == (2, 2, 2, 2)
    np.testing.assert_allclose(R2(0.7), rot_z(0.7)[:2, :2], atol=0)


@settings(max_examples=300, deadline=None)
@given(wide_angles)
def test_ssa_range_and_congruence(x):
    y = ssa(x)
    # [-pi, pi) up to the rounding of x - 2 pi floor(...): at odd multiples of pi the result can
    # fall a few ulp of x below -pi (e.g. ssa(11 pi) = -pi - 1.3e-15; reported)
    assert -math.pi - 8 * np.spacing(max(abs(x), math.pi)) <= y < math.pi
    k = (x - y) / (2 * math.pi)  # an integer number of turns
    assert abs(k - round(k)) < 1e-9
    assert math.cos(y) == pytest.approx(math.cos(x), abs=1e-9)
    assert math.sin(y) == pytest.approx(math.sin(x), abs=1e-9)


@settings(max_examples=100, deadline=None)
@given(st.floats(-math.pi + 1e-9, math.pi - 1e-9))
def test_ssa_is_identity_inside_its_range(x):
    assert ssa(x) == pytest.approx(x, abs=1e-15)


def test_ssa_edges_and_arrays():
    assert ssa(math.pi) == pytest.approx(-math.pi)  # half-open interval [-pi, pi)
    assert ssa(-math.pi) == pytest.approx(-math.pi)
    assert ssa(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert ssa(-3 * math.pi / 2) == pytest.approx(math.pi / 2)
    for k in range(-50, 51):  # (rounded) odd multiples of pi land on the edge of the range
        assert abs(ssa((2 * k + 1) * math.pi)) == pytest.approx(math.pi, abs=1e-13)
    x = np.linspace(-20, 20, 101)
    y = ssa(x)
    assert y.shape == x.shape and np.all((y >= -np.pi) & (y < np.pi))
    # smallest signed difference between headings: 350 deg -> 10 deg is +20 deg
    assert ssa(math.radians(10) - math.radians(350)) == pytest.approx(math.radians(20))


def test_ssa_on_casadi_matches_numpy():
    s = ca.SX.sym("s")
    f = ca.Function("ssa", [s], [ssa(s)])
    for x in (-13.0, -math.pi, -1.0, 0.0, 2.5, math.pi + 0.1, 40.0):
        assert float(f(x)) == pytest.approx(ssa(x), abs=1e-12)


# ------------------------------------------------------------------------------------------
# fairleads, eq. (2)-(6)
# ------------------------------------------------------------------------------------------


def eq6(eta, p_cot_B, p_T, alpha_t):
    """Survey eq. (6), the scalar form of the fairlead position in {E}, written out."""
    x, y, psi = eta
    xc, yc = p_cot_B
    out = []
    for xt, yt in p_T:
        out.append((
            x + xc * math.cos(psi) - yc * math.sin(psi) + xt * math.cos(psi + alpha_t) - yt * math.sin(psi + alpha_t),
            y + yc * math.cos(psi) + xc * math.sin(psi) + xt * math.sin(psi + alpha_t) + yt * math.cos(psi + alpha_t),
        ))
    return np.array(out)


coords = st.floats(-300.0, 300.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(coords, coords, angles, coords, coords, st.floats(0.0, 40.0), angles, angles)
def test_fairleads_E_equals_scalar_eq6(x, y, psi, xc, yc, r, gamma0, alpha_t):
    gamma = gamma0 + np.arange(5) * 2 * np.pi / 5
    p_T = fairleads_T(np.full(5, r), gamma)
    fx, fy = fairleads_E(np.array([x, y, psi]), np.array([xc, yc]), p_T, alpha_t)
    np.testing.assert_allclose(np.column_stack([fx, fy]), eq6((x, y, psi), (xc, yc), p_T, alpha_t),
                               rtol=1e-12, atol=1e-9)


def test_fairleads_T_is_eq2():
    p = fairleads_T([10.0, 20.0, 5.0], [0.0, np.pi / 2, np.pi])
    np.testing.assert_allclose(p, [[10.0, 0.0], [0.0, 20.0], [-5.0, 0.0]], atol=1e-14)
    assert p.shape == (3, 2)


def test_fairleads_B_is_eq3_and_chains_to_eq5():
    p_cot = np.array([80.0, -2.0])
    p_T = fairleads_T([12.0, 12.0], [0.2, 2.0])
    a = 0.6
    bx, by = fairleads_B(p_cot, p_T, a)
    np.testing.assert_allclose(np.column_stack([bx, by]), p_cot + p_T @ R2(a).T, atol=1e-12)
    eta = np.array([5.0, -7.0, 1.1])
    ex, ey = fairleads_E(eta, p_cot, p_T, a)
    np.testing.assert_allclose(np.column_stack([ex, ey]),
                               eta[:2] + np.column_stack([bx, by]) @ R2(eta[2]).T, atol=1e-12)


def test_free_turret_at_the_body_origin_keeps_its_fairleads_fixed_in_E():
    """Survey §3.1: p_cot = 0 and alpha_t = -psi give p^E = p + p^T for any heading."""
    p_T = fairleads_T(np.full(4, 15.0), np.arange(4) * np.pi / 2)
    for psi in (0.0, 0.7, -2.9):
        fx, fy = fairleads_E(np.array([3.0, -4.0, psi]), np.zeros(2), p_T, -psi)
        np.testing.assert_allclose(np.column_stack([fx, fy]), p_T + [3.0, -4.0], atol=1e-12)


def test_rot2_apply_matches_R2():
    x, y = np.array([1.0, -2.0, 3.0]), np.array([0.5, 4.0, -1.0])
    for a in (0.0, 0.4, -2.2):
        rx, ry = rot2_apply(a, x, y)
        np.testing.assert_allclose(np.column_stack([rx, ry]), np.column_stack([x, y]) @ R2(a).T, atol=1e-14)


@pytest.mark.parametrize("sym", [ca.SX, ca.MX])
def test_numpy_and_casadi_paths_agree(sym):
    psi = sym.sym("psi")
    eta = sym.sym("eta", 3)
    alpha = sym.sym("alpha")
    p_cot = np.array([45.0, 3.0])
    p_T = fairleads_T(np.full(6, 11.0), np.arange(6) * np.pi / 3 + 0.1)
    f_rot = ca.Function("rot", [psi], [rot_z(psi), R2(psi)])
    fx, fy = fairleads_E(eta, p_cot, p_T, alpha)
    f_fl = ca.Function("fl", [eta, alpha], [fx, fy])
    rng = np.random.default_rng(11)
    for _ in range(10):
        e = rng.uniform([-100, -100, -7], [100, 100, 7])
        a = rng.uniform(-4, 4)
        Rs, R2s = f_rot(e[2])
        np.testing.assert_allclose(np.array(Rs), rot_z(e[2]), atol=1e-15)
        np.testing.assert_allclose(np.array(R2s), R2(e[2]), atol=1e-15)
        sx, sy = f_fl(e, a)
        nx, ny = fairleads_E(e, p_cot, p_T, a)
        np.testing.assert_allclose(np.array(sx).ravel(), nx, rtol=1e-14, atol=1e-11)
        np.testing.assert_allclose(np.array(sy).ravel(), ny, rtol=1e-14, atol=1e-11)
    # CasADi derivative of the fairlead position: d p^E / d psi = R2(psi + pi/2) (p^E - p)
    J = ca.Function("J", [eta, alpha], [ca.jacobian(ca.vertcat(fx, fy), eta)])
    e, a = np.array([10.0, -3.0, 0.8]), 0.25
    Jn = np.array(J(e, a))
    nx, ny = fairleads_E(e, p_cot, p_T, a)
    rel = np.column_stack([nx - e[0], ny - e[1]])
    np.testing.assert_allclose(Jn[:6, 2], -rel[:, 1], atol=1e-12)
    np.testing.assert_allclose(Jn[6:, 2], rel[:, 0], atol=1e-12)
    np.testing.assert_allclose(Jn[:6, 0], 1.0) and np.testing.assert_allclose(Jn[6:, 1], 1.0)


@settings(max_examples=100, deadline=None)
@given(coords, coords, angles, coords, coords)
def test_turret_position_is_eq5_without_fairlead_radius(x, y, psi, xc, yc):
    """The centre of turret is a fairlead with r = 0 (eq. 5); turret_offset subtracts where it
    rests at eta = 0, and body_from_turret inverts that."""
    eta, p_cot = np.array([x, y, psi]), np.array([xc, yc])
    fx, fy = fairleads_E(eta, p_cot, np.zeros((1, 2)), 0.3)
    tx, ty = turret_position(eta, p_cot)
    np.testing.assert_allclose([tx, ty], [fx[0], fy[0]], rtol=1e-12, atol=1e-9)
    ox, oy = turret_offset(eta, p_cot)
    np.testing.assert_allclose([ox, oy], [tx - xc, ty - yc], rtol=1e-12, atol=1e-9)
    bx, by = body_from_turret((ox, oy), psi, p_cot)
    np.testing.assert_allclose([bx, by], [x, y], rtol=1e-9, atol=1e-8)


def test_turret_offset_of_rotations_about_the_turret_is_zero_and_rows_vectorise():
    p_cot = np.array([91.44, 0.0])
    psi = np.linspace(-3.0, 3.0, 13)
    x, y = body_from_turret((0.0, 0.0), psi, p_cot)
    ox, oy = turret_offset(np.column_stack([x, y, psi]), p_cot)
    assert ox.shape == psi.shape
    np.testing.assert_allclose(np.hypot(ox, oy), 0.0, atol=1e-12)
    # a half turn about the body origin swings the turret 2 |p_cot| aft
    np.testing.assert_allclose(turret_offset([0.0, 0.0, np.pi], p_cot), (-2 * 91.44, 0.0), atol=1e-12)


def test_turret_offset_on_casadi_matches_numpy():
    eta = ca.SX.sym("eta", 3)
    p_cot = np.array([45.0, 3.0])
    f = ca.Function("off", [eta], [ca.vertcat(*turret_offset(eta, p_cot))])
    for e in ([0.0, 0.0, 0.0], [10.0, -4.0, 0.7], [-30.0, 12.0, -2.5]):
        np.testing.assert_allclose(np.array(f(e)).ravel(), turret_offset(np.array(e), p_cot), atol=1e-12)
