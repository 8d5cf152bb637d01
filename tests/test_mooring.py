"""Tests of the quasi-static catenary mooring model (tapm_opt.models.mooring, survey eq. 17–29):
symmetry and analytic stiffness of a spread mooring, turret modes, finite differences, the
symbolic and linearised force functions, line breaks, force directions and bad input; anchors above
the seabed, with the FEM plant's static equilibrium on their catenaries."""

from __future__ import annotations

import copy
import dataclasses
import math

import casadi as ca
import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import scenario_from_dict, scenario_to_dict
from tapm_opt.errors import ModelError
from tapm_opt.geometry import rot_z
from tapm_opt.models import catenary as cat
from tapm_opt.models.mooring import MooringModel

# ------------------------------------------------------------------------------------------
# scenarios
# ------------------------------------------------------------------------------------------

AAMO4 = tapm_opt.load_scenario("aamo4")


def base_dict() -> dict:
    d = copy.deepcopy(scenario_to_dict(AAMO4))
    # scenario_to_dict writes the default reference_point (nan, 0, nan), which scenario_from_dict
    # then rejects as non-finite (reported); it plays no part in the mooring, so leave it out.
    ref = d["vessel"].get("reference_point")
    if ref is not None and not all(math.isfinite(v) for v in ref):
        del d["vessel"]["reference_point"]
    return d


def scenario(*, turret=None, shift_anchors=(0.0, 0.0), mirror=False, edit_lines=None):
    """aamo4 with turret fields replaced, anchors shifted by (dx, dy) [m] (to keep the COT at the
    centre of the pattern), optionally mirrored about the x axis (y -> -y, angles -> -angles)."""
    d = base_dict()
    d["turret"].update(turret or {})
    for ln in d["lines"]:
        ln["anchor"][0] += shift_anchors[0]
        ln["anchor"][1] += shift_anchors[1]
    if edit_lines:
        edit_lines(d["lines"])
    if mirror:
        d["turret"]["position"][1] *= -1
        d["turret"]["angle_deg"] *= -1
        for ln in d["lines"]:
            ln["anchor"][1] *= -1
            ln["fairlead_angle_deg"] *= -1
    return scenario_from_dict(d)


def model(**kw) -> MooringModel:
    broken = kw.pop("broken", ())
    return MooringModel.from_scenario(scenario(**kw), broken=broken)


def numeric_stiffness(m: MooringModel, eta, h=(1e-2, 1e-2, 1e-5)):
    """-d tau / d eta by central differences of m.force."""
    eta = np.asarray(eta, dtype=float)
    K = np.zeros((3, 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = h[j]
        K[:, j] = -(m.force(eta + e) - m.force(eta - e)) / (2 * h[j])
    return K


def as_array(dm) -> np.ndarray:
    return np.array(dm, dtype=float).ravel()


# ------------------------------------------------------------------------------------------
# symmetric spread mooring
# ------------------------------------------------------------------------------------------

SYMMETRIC = {
    "aamo4 (free, fairleads at the COT = CO)": dict(),
    "locked, fairleads at the COT = CO": dict(turret={"mode": "locked"}),
    "locked, r = 20 m": dict(turret={"mode": "locked", "fairlead_radius": 20.0}),
    "free, r = 20 m": dict(turret={"fairlead_radius": 20.0}),
    "free, COT 50 m fwd, r = 10 m": dict(turret={"position": [50.0, 0.0], "fairlead_radius": 10.0},
                                         shift_anchors=(50.0, 0.0)),
    # turret turned 30 deg, fairleads at gamma - 30 deg: in {E} they still face their anchors
    "locked, COT 50 m fwd, turned 30 deg": dict(turret={"mode": "locked", "position": [50.0, 0.0],
                                                        "fairlead_radius": 15.0, "angle_deg": 30.0},
                                                shift_anchors=(50.0, 0.0), edit_lines=lambda lines: [
                                                    ln.update(fairlead_angle_deg=ln["fairlead_angle_deg"] - 30.0)
                                                    for ln in lines]),
}


@pytest.mark.parametrize("case", list(SYMMETRIC))
def test_symmetric_mooring_has_zero_net_force_at_the_field_zero_point(case):
    m = model(**copy.deepcopy(SYMMETRIC[case]))
    T = m.tensions(np.zeros(3))
    assert np.all(T > 0) and np.ptp(T) <= 1e-9 * T.max()  # four equal lines, equally loaded
    tau = m.force(np.zeros(3))
    assert np.all(np.abs(tau[:2]) < 1e-6 * T.max())
    assert abs(tau[2]) < 1e-6 * T.max() * 1.0  # [N m] with a 1 m lever


@pytest.mark.parametrize("case", list(SYMMETRIC))
def test_symmetric_mooring_stiffness_is_isotropic_and_positive(case):
    m = model(**copy.deepcopy(SYMMETRIC[case]))
    K = m.stiffness(np.zeros(3))
    Kh = K[:2, :2]
    assert Kh[0, 0] > 0
    assert Kh[0, 0] == pytest.approx(Kh[1, 1], rel=1e-10)  # 4 equal lines at 90 deg
    assert abs(Kh[0, 1]) <= 1e-10 * Kh[0, 0] and abs(Kh[1, 0]) <= 1e-10 * Kh[0, 0]
    np.testing.assert_allclose(Kh, Kh.T, rtol=0, atol=1e-10 * Kh[0, 0])
    assert np.all(np.linalg.eigvalsh(Kh) > 0)


def test_spread_mooring_surge_stiffness_equals_the_line_formula():
    """Four lines at 90 deg, fairleads at the origin: pushing in x loads the two x lines axially
    (dH/dXF each) and turns the two y lines (H/XF each): K_xx = 2 (dH/dXF + H/XF)."""
    m = MooringModel.from_scenario(AAMO4)
    sol = cat.solve(2000.0, 1000.0, 2250.0, m.EA[0], m.w[0])
    K = m.stiffness(np.zeros(3))
    expected = 2.0 * (float(sol.dHF_dXF) + float(sol.HF) / 2000.0)
    assert K[0, 0] == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("mode", ["free", "locked"])
def test_no_yaw_stiffness_when_fairleads_sit_at_the_body_origin(mode):
    """All lines meet at the COT, which is the body origin: no line has a lever arm about CO, so
    there is no yaw moment and no yaw stiffness. Turning the hull does not move the fairleads
    either; it only turns {B}, so the body-frame force (X, Y) rotates: dX/dpsi = Y, dY/dpsi = -X."""
    m = model(turret={"mode": mode})
    assert np.all(m.stiffness(np.zeros(3))[:, 2] == 0.0)
    for eta in ([0.0, 0.0, 0.0], [20.0, -10.0, 0.3], [-15.0, 5.0, -1.2]):
        K = m.stiffness(np.array(eta))
        tau = m.force(np.array(eta))
        assert np.all(K[2, :] == 0.0) and tau[2] == 0.0
        np.testing.assert_allclose(K[:2, 2], [-tau[1], tau[0]], rtol=1e-10, atol=1e-9 * np.abs(tau).max())


def test_locked_turret_yaw_stiffness_from_the_fairlead_circle():
    """Locked turret with fairleads on a circle of radius r at the body origin, anchors at radius
    R_a in line with them: turning the hull by dpsi moves each fairlead sideways by r dpsi and
    turns its line by r dpsi / XF, so each line gives N = -H r (1 + r/XF) dpsi:
    K_psipsi = sum H_i r R_a / XF_i > 0."""
    r, Ra = 20.0, 2000.0
    m = model(turret={"mode": "locked", "fairlead_radius": r})
    sol = m.solve_lines(np.zeros(3))
    _, _, XF = m.spans(np.zeros(3))
    np.testing.assert_allclose(XF, Ra - r, rtol=1e-14)
    K = m.stiffness(np.zeros(3))
    assert K[2, 2] > 0
    assert K[2, 2] == pytest.approx(np.sum(sol.HF * r * Ra / XF), rel=1e-10)
    assert abs(K[0, 2]) <= 1e-8 * K[0, 0] * r and abs(K[2, 0]) <= 1e-8 * K[0, 0] * r


@pytest.mark.parametrize("x_cot", [100.0, -100.0])
def test_free_turret_weathervaning_yaw_stiffness(x_cot):
    """Free turret at (x_cot, 0) in {B}: the hull feels only the net line force F(p_cot^E) at the
    COT, so N = (R(psi) p_cot) x F. Turning the hull by dpsi about CO moves the COT sideways by
    x_cot dpsi; at psi = 0

        K_psipsi = -dN/dpsi = x_cot X + x_cot^2 K_yy,     K_yy = K[1, 1] = -dY/dy,

    with X the mooring's surge force. Pushed aft by the environment (x < 0), the mooring pulls
    forward (X > 0): a turret forward of CO (x_cot > 0) gains yaw stiffness (stable
    weathervaning), a turret aft of CO loses it."""
    m = model(turret={"position": [x_cot, 0.0]}, shift_anchors=(x_cot, 0.0))
    K0 = m.stiffness(np.zeros(3))
    assert K0[2, 2] == pytest.approx(x_cot**2 * K0[1, 1], rel=1e-10)  # no mean load: geometric only
    for eta in ([-10.0, 0.0, 0.0], [-25.0, 4.0, 0.0], [10.0, 0.0, 0.0], [-10.0, -6.0, 0.0]):
        eta = np.array(eta)
        tau, K = m.force(eta), m.stiffness(eta)
        assert K[2, 2] == pytest.approx(x_cot * tau[0] + x_cot**2 * K[1, 1], rel=1e-9)
    pushed_aft = np.array([-25.0, 0.0, 0.0])
    X = m.force(pushed_aft)[0]
    assert X > 0  # the mooring pulls the vessel forward, back toward the field zero point
    gain = m.stiffness(pushed_aft)[2, 2] - x_cot**2 * m.stiffness(pushed_aft)[1, 1]
    assert np.sign(gain) == np.sign(x_cot)  # stabilising for a turret forward of CO


def test_free_turret_force_depends_only_on_the_turret_centre():
    """Turning the hull about the COT leaves the line forces in {E} unchanged (the turret keeps
    its heading); the moment about CO is that force at the lever R(psi) p_cot."""
    x_cot = 60.0
    m = model(turret={"position": [x_cot, 0.0], "fairlead_radius": 12.0}, shift_anchors=(x_cot, 0.0))
    p_c = np.array([x_cot + 14.0, -9.0])  # COT position in {E}
    forces = []
    for psi in (0.0, 0.4, -1.1, 2.5):
        pos = p_c - rot_z(psi)[:2, :2] @ np.array([x_cot, 0.0])
        eta = np.array([pos[0], pos[1], psi])
        tau_E = rot_z(psi) @ m.force(eta)
        lever = rot_z(psi)[:2, :2] @ np.array([x_cot, 0.0])
        assert tau_E[2] == pytest.approx(lever[0] * tau_E[1] - lever[1] * tau_E[0], rel=1e-12)
        forces.append(tau_E[:2])
    np.testing.assert_allclose(forces, np.broadcast_to(forces[0], (4, 2)), rtol=1e-10)


@pytest.mark.parametrize("mode", ["locked", "free"])
def test_load_equals_survey_eq19_written_out(mode):
    """Eq. (17)-(19) per line in scalar form: h_i = H_i (cos beta_i, sin beta_i) toward the
    fairlead, g = [-hx c - hy s, -hy c + hx s, hy (y^B s - x^B c) + hx (y^B c + x^B s)], with
    p^B the fairlead in {B} (locked) or the COT (free: the bearing passes no moment)."""
    x_cot, r = 40.0, 18.0
    m = model(turret={"mode": mode, "position": [x_cot, 5.0], "fairlead_radius": r, "angle_deg": 25.0},
              shift_anchors=(x_cot, 5.0))
    rng = np.random.default_rng(7)
    for _ in range(5):
        eta = np.array([rng.uniform(-30, 30), rng.uniform(-30, 30), rng.uniform(-np.pi, np.pi)])
        x, y, psi = eta
        c, s = math.cos(psi), math.sin(psi)
        fx, fy = m.fairleads(eta)
        H = m.solve_lines(eta).HF
        g = np.zeros(3)
        for i in range(m.n_lines):
            beta = math.atan2(fy[i] - m.anchors[i, 1], fx[i] - m.anchors[i, 0])  # eq. (17)
            hx, hy = H[i] * math.cos(beta), H[i] * math.sin(beta)  # eq. (18)
            if mode == "locked":  # p^B of the fairlead: rotate back from {E}
                xB = c * (fx[i] - x) + s * (fy[i] - y)
                yB = -s * (fx[i] - x) + c * (fy[i] - y)
            else:
                xB, yB = x_cot, 5.0
            g += [-hx * c - hy * s, -hy * c + hx * s, hy * (yB * s - xB * c) + hx * (yB * c + xB * s)]
        np.testing.assert_allclose(m.force(eta), g, rtol=1e-10, atol=1e-6)


def test_mirrored_mooring_gives_mirrored_load():
    """Mirror an asymmetric mooring about the x axis (y -> -y): at the mirrored pose
    (x, -y, -psi) the load is (X, -Y, -N)."""
    def skew(lines):
        lines[0]["anchor"][1] += 150.0
        lines[1]["length"] = 2270.0
        lines[2]["anchor"][0] += 60.0
        lines[3]["fairlead_angle_deg"] = 250.0

    kw = dict(turret={"mode": "locked", "position": [30.0, 8.0], "fairlead_radius": 15.0, "angle_deg": 20.0},
              edit_lines=skew)
    m, mm = model(**kw), model(mirror=True, **kw)
    for eta in ([0.0, 0.0, 0.0], [12.0, -7.0, 0.3], [-20.0, 15.0, -0.8]):
        eta = np.array(eta)
        tau = m.force(eta)
        tau_m = mm.force(eta * [1, -1, -1])
        assert np.abs(tau).max() > 1e4  # the skewed mooring does push at these poses
        np.testing.assert_allclose(tau_m, tau * [1, -1, -1], rtol=1e-10, atol=1e-6 * np.abs(tau).max())
        np.testing.assert_allclose(mm.stiffness(eta * [1, -1, -1]),
                                   m.stiffness(eta) * np.outer([1, -1, -1], [1, -1, -1]), rtol=1e-8,
                                   atol=1e-8 * np.abs(m.stiffness(eta)).max())


# ------------------------------------------------------------------------------------------
# stiffness vs finite differences
# ------------------------------------------------------------------------------------------

FD_MODELS = {
    "aamo4": dict(),
    "locked r=20": dict(turret={"mode": "locked", "fairlead_radius": 20.0}),
    "locked off-centre": dict(turret={"mode": "locked", "position": [30.0, -4.0], "fairlead_radius": 15.0,
                                      "angle_deg": 10.0}, shift_anchors=(30.0, -4.0)),
    "free off-centre": dict(turret={"mode": "free", "position": [30.0, -4.0], "fairlead_radius": 15.0,
                                    "angle_deg": 10.0}, shift_anchors=(30.0, -4.0)),
}
FD_POSES = [(0.0, 0.0, 0.0), (15.0, -10.0, 0.2), (-30.0, 5.0, -0.4), (5.0, 25.0, 1.0), (-20.0, -15.0, 2.8),
            (-65.0, -15.0, 0.3)]


@pytest.mark.parametrize("case", list(FD_MODELS))
def test_stiffness_equals_finite_differences(case):
    m = model(**copy.deepcopy(FD_MODELS[case]))
    for eta in FD_POSES:
        K = m.stiffness(np.array(eta))
        K_fd = numeric_stiffness(m, eta)
        scale = np.abs(K_fd).max(axis=0)  # per column: N/m and N m/rad differ by orders
        np.testing.assert_allclose(K, K_fd, rtol=1e-6, atol=1e-6 * scale.max() if scale.max() else 0,
                                   err_msg=f"{case} eta={eta}")
        for j in range(3):
            if scale[j] > 0:
                np.testing.assert_allclose(K[:, j], K_fd[:, j], rtol=0, atol=1e-6 * scale[j])


@pytest.mark.parametrize("case", list(FD_MODELS))
def test_lines_touch_down_at_the_large_fd_offset(case):
    """The finite-difference poses include lines in both regular regimes, below breaking load."""
    m = model(**copy.deepcopy(FD_MODELS[case]))
    sol = m.solve_lines(np.array(FD_POSES[-1]))
    assert {"touchdown", "suspended"} <= set(sol.regime_names())
    assert np.all(sol.TF < m.MBS)


# ------------------------------------------------------------------------------------------
# CasADi force functions
# ------------------------------------------------------------------------------------------

SYM_POSES = [(0.0, 0.0, 0.0), (10.0, 5.0, 0.1), (30.0, -20.0, 0.5), (-40.0, 15.0, -1.0), (55.0, 10.0, 2.0)]


@pytest.mark.parametrize("case", ["aamo4", "locked off-centre", "free off-centre"])
def test_catenary_force_function_matches_numeric_force_and_stiffness(case):
    m = model(**copy.deepcopy(FD_MODELS[case]))
    f = m.force_function("catenary")
    assert f.name_in() == ["eta"] and f.name_out() == ["tau_moor"]
    eta = ca.MX.sym("eta", 3)
    J = ca.Function("J", [eta], [ca.jacobian(f(eta), eta)])
    for pose in SYM_POSES:
        pose = np.array(pose)
        tau, tau_sym = m.force(pose), as_array(f(pose))
        scale = max(np.abs(tau[:2]).max(), 1.0)  # [N]; moments are compared with a 100 m lever
        np.testing.assert_allclose(tau_sym[:2], tau[:2], rtol=1e-8, atol=1e-8 * scale)
        np.testing.assert_allclose(tau_sym[2], tau[2], rtol=1e-8, atol=1e-8 * scale * 100.0)
        K = m.stiffness(pose)
        np.testing.assert_allclose(-np.array(J(pose)), K, rtol=1e-7, atol=1e-7 * np.abs(K).max())


def test_catenary_force_function_at_a_large_offset():
    """110 m surge offset (1.8 x MBS in the most loaded line, but within the solver's domain)."""
    m = MooringModel.from_scenario(AAMO4)
    pose = np.array([110.0, 0.0, 0.0])
    np.testing.assert_allclose(as_array(m.force_function("catenary")(pose)), m.force(pose), rtol=1e-6)


def test_linear_force_function_is_eq29():
    m = model(turret={"mode": "locked", "fairlead_radius": 20.0, "position": [30.0, 0.0]},
              shift_anchors=(30.0, 0.0))
    eta0 = np.array([12.0, -6.0, 0.15])
    lin = m.linearised(eta0)
    np.testing.assert_allclose(lin.g0, m.force(eta0), rtol=1e-12)
    np.testing.assert_allclose(lin.G_mo, rot_z(eta0[2]) @ m.stiffness(eta0), rtol=1e-12)
    f = m.force_function("linear", eta0=eta0)
    rng = np.random.default_rng(3)
    for _ in range(5):
        eta = eta0 + rng.normal(size=3) * [20.0, 20.0, 0.5]
        expected = lin.g0 - rot_z(eta[2]).T @ lin.G_mo @ (eta - eta0)
        np.testing.assert_allclose(as_array(f(eta)), expected, rtol=1e-12, atol=1e-6)
        np.testing.assert_allclose(lin.force(eta), expected, rtol=1e-12, atol=1e-6)


@pytest.mark.parametrize("kind", ["linear", "characteristic"])
def test_linearised_force_functions_are_first_order_accurate(kind):
    """Error against the catenary is O(offset^2): halving the offset quarters it."""
    m = model(turret={"mode": "locked", "fairlead_radius": 20.0, "position": [30.0, 0.0]},
              shift_anchors=(30.0, 0.0))
    eta0 = np.array([12.0, -6.0, 0.15])
    f = m.force_function(kind, eta0=eta0)
    d = np.array([1.0, 0.6, 0.004])  # [m, m, rad] per unit offset
    errs = []
    for s in (4.0, 2.0, 1.0, 0.5):
        eta = eta0 + s * d
        errs.append(np.linalg.norm((as_array(f(eta)) - m.force(eta)) / [1, 1, 30.0]))
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert np.all((ratios > 3.8) & (ratios < 4.3)), ratios
    assert np.all(np.diff(np.abs(ratios - 4.0)) < 0), ratios  # and tend to 4 as the offset shrinks
    # and exact at the working point
    np.testing.assert_allclose(as_array(f(eta0)), m.force(eta0), rtol=1e-10)


def test_characteristic_and_linear_agree_to_first_order():
    m = MooringModel.from_scenario(AAMO4)
    fl, fc = m.force_function("linear"), m.force_function("characteristic")
    eta = ca.MX.sym("eta", 3)
    Jl = ca.Function("Jl", [eta], [ca.jacobian(fl(eta), eta)])(np.zeros(3))
    Jc = ca.Function("Jc", [eta], [ca.jacobian(fc(eta), eta)])(np.zeros(3))
    np.testing.assert_allclose(np.array(Jl), np.array(Jc), rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(-np.array(Jl), m.stiffness(np.zeros(3)), rtol=1e-9, atol=1e-6)


def test_unknown_force_function_kind_raises():
    with pytest.raises(ModelError, match="kind"):
        MooringModel.from_scenario(AAMO4).force_function("spline")


# ------------------------------------------------------------------------------------------
# line break, directions, bad input
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("broken,direction", [("1", (-1.0, 0.0)), ("2", (0.0, -1.0)),
                                              ("3", (1.0, 0.0)), ("4", (0.0, 1.0))])
def test_broken_line_leaves_a_net_force_toward_the_opposite_anchor(broken, direction):
    m = MooringModel.from_scenario(AAMO4, broken=[broken])
    assert m.n_lines == 3 and broken not in m.line_ids
    tau = m.force(np.zeros(3))
    intact_T = MooringModel.from_scenario(AAMO4).tensions(np.zeros(3))[0]
    H = float(MooringModel.from_scenario(AAMO4).solve_lines(np.zeros(3)).HF[0])
    # the opposite line is no longer balanced: its full H remains
    np.testing.assert_allclose(tau[:2], H * np.array(direction), rtol=1e-12, atol=1e-6 * intact_T)
    anchor = AAMO4.anchors[AAMO4.line_index(broken), :2]
    assert tau[:2] @ anchor < 0  # away from the broken line's anchor


def test_broken_line_ids_are_checked():
    with pytest.raises(ModelError, match="7"):
        MooringModel.from_scenario(AAMO4, broken=["7"])
    with pytest.raises(ModelError, match="every line"):
        MooringModel.from_scenario(AAMO4, broken=["1", "2", "3", "4"])
    assert MooringModel.from_scenario(AAMO4, broken=[2]).line_ids == ("1", "3", "4")  # ints accepted


@pytest.mark.parametrize("mode", ["free", "locked"])
def test_surge_offset_is_restored_and_loads_the_lines_behind(mode):
    m = model(turret={"mode": mode, "fairlead_radius": 10.0})
    T0 = m.tensions(np.zeros(3))
    for x in (5.0, 20.0, 50.0):
        eta = np.array([x, 0.0, 0.0])
        tau, T = m.force(eta), m.tensions(eta)
        assert tau[0] < 0  # restoring
        assert abs(tau[1]) < 1e-9 * abs(tau[0]) and abs(tau[2]) < 1e-6 * abs(tau[0])
        i1, i3 = m.line_ids.index("1"), m.line_ids.index("3")  # anchors at +x and -x
        assert T[i1] < T0[i1] and T[i3] > T0[i3]
        assert T[m.line_ids.index("2")] == pytest.approx(T[m.line_ids.index("4")], rel=1e-12)
    # monotone: further out, harder pull
    X = [m.force(np.array([x, 0.0, 0.0]))[0] for x in (5.0, 20.0, 50.0)]
    assert X[0] > X[1] > X[2]


def test_restoring_force_is_in_the_body_frame():
    """Same offset in {E}, vessel turned 90 deg: the surge-restoring force appears in sway."""
    m = MooringModel.from_scenario(AAMO4)
    X = m.force(np.array([20.0, 0.0, 0.0]))
    tau = m.force(np.array([20.0, 0.0, np.pi / 2]))  # x^B points along y^E
    np.testing.assert_allclose(tau, [0.0, -X[0], 0.0], atol=1e-6 * abs(X[0]))


@pytest.mark.parametrize("bad", [np.zeros(2), np.zeros(4), np.zeros((3, 1)), [0.0, np.nan, 0.0],
                                 [np.inf, 0.0, 0.0], [0.0, 0.0, -np.inf]])
@pytest.mark.parametrize("method", ["force", "stiffness", "tensions", "solve_lines", "linearised"])
def test_bad_eta_raises_model_error(bad, method):
    m = MooringModel.from_scenario(AAMO4)
    with pytest.raises(ModelError, match="eta"):
        getattr(m, method)(np.asarray(bad, dtype=float))


# ------------------------------------------------------------------------------------------
# anchors above the seabed (lower end h_A above it)
# ------------------------------------------------------------------------------------------


def raised(base, heights):
    """``base`` with anchor i at ``heights[i]`` [m] above the seabed: anchor (x, y, depth - h_A).
    Built with ``dataclasses.replace`` (the scenario file check takes anchors on the seabed)."""
    depth = base.environment.water_depth
    lines = tuple(dataclasses.replace(ln, anchor=(ln.anchor[0], ln.anchor[1], depth - h))
                  for ln, h in zip(base.lines, heights))
    return dataclasses.replace(base, lines=lines)


def lengthen_line_1(lines):
    lines[0]["length"] = 2450.0


# locked off-centre turret; line 1 lengthened so that it touches down from its raised anchor, line 2
# on the seabed, lines 3 and 4 from high anchors, sagging below them (checked in the first test)
RAISED_HEIGHTS = (60.0, 0.0, 400.0, 700.0)


def raised_model() -> MooringModel:
    kw = copy.deepcopy(FD_MODELS["locked off-centre"])
    return MooringModel.from_scenario(raised(scenario(edit_lines=lengthen_line_1, **kw), RAISED_HEIGHTS))


def test_anchor_heights_come_from_the_scenario():
    m = raised_model()
    np.testing.assert_array_equal(m.h_A, RAISED_HEIGHTS)
    np.testing.assert_array_equal(m.ZF, 1000.0 - np.array(RAISED_HEIGHTS))  # fairleads at the surface
    eta = np.array([15.0, -10.0, 0.2])
    _, _, XF = m.spans(eta)
    sol = m.solve_lines(eta)
    ref = cat.solve(XF, m.ZF, m.L, m.EA, m.w, CB=m.CB, h_A=np.array(RAISED_HEIGHTS))
    np.testing.assert_array_equal(sol.HF, ref.HF)
    names = sol.regime_names()
    assert names[0] == "touchdown" and sol.LBot[0] > 0 and sol.VA[0] < 0  # from its raised anchor
    assert np.all(names[2:] == "suspended") and np.all(sol.VA[2:] < 0)  # sagging below A
    # raising an anchor changes the line's tension (same horizontal distance, different ZF and seabed)
    kw = copy.deepcopy(FD_MODELS["locked off-centre"])
    flat = MooringModel.from_scenario(scenario(edit_lines=lengthen_line_1, **kw))
    assert np.all(np.abs(m.tensions(eta)[[0, 2, 3]] / flat.tensions(eta)[[0, 2, 3]] - 1) > 0.01)
    assert m.tensions(eta)[1] == flat.tensions(eta)[1]


def test_stiffness_equals_finite_differences_with_anchors_above_the_seabed():
    m = raised_model()
    h = (1e-2, 1e-2, 1e-5)
    for eta in FD_POSES:
        # no line changes regime within the difference stencil (the stiffness has kinks there)
        regimes = {tuple(m.solve_lines(np.array(eta) + s * np.eye(3)[j] * h[j]).regime) for j in range(3)
                   for s in (-1, 1)}
        assert len(regimes) == 1, eta
        K, K_fd = m.stiffness(np.array(eta)), numeric_stiffness(m, eta, h)
        scale = np.abs(K_fd).max(axis=0)
        for j in range(3):
            np.testing.assert_allclose(K[:, j], K_fd[:, j], rtol=0, atol=1e-6 * scale[j], err_msg=f"eta={eta}")


def test_catenary_force_function_with_anchors_above_the_seabed():
    m = raised_model()
    f = m.force_function("catenary", with_closure_error=True)
    eta = ca.MX.sym("eta", 3)
    J = ca.Function("J", [eta], [ca.jacobian(f(eta)[0], eta)])
    for pose in SYM_POSES:
        pose = np.array(pose)
        tau, err = f(pose)
        assert float(err) < 1e-8
        np.testing.assert_allclose(as_array(tau), m.force(pose), rtol=1e-8, atol=1e-8 * np.abs(m.force(pose)).max())
        K = m.stiffness(pose)
        np.testing.assert_allclose(-np.array(J(pose)), K, rtol=1e-7, atol=1e-7 * np.abs(K).max())
    T = m.tension_function("catenary")(SYM_POSES[2])
    np.testing.assert_allclose(as_array(T), m.tensions(np.array(SYM_POSES[2])), rtol=1e-8)


def test_linear_spring_model_with_anchors_above_the_seabed():
    m = raised_model()
    eta0 = np.array([12.0, -6.0, 0.15])
    lin = m.linearised(eta0)
    np.testing.assert_allclose(lin.g0, m.force(eta0), rtol=1e-12)
    np.testing.assert_allclose(lin.G_mo, rot_z(eta0[2]) @ m.stiffness(eta0), rtol=1e-12)
    np.testing.assert_allclose(lin.k, m.solve_lines(eta0).dHF_dXF, rtol=1e-12)
    d = np.array([1.0, 0.6, 0.004])
    for kind in ("linear", "characteristic"):
        f = m.force_function(kind, eta0=eta0)
        errs = [np.linalg.norm((as_array(f(eta0 + s * d)) - m.force(eta0 + s * d)) / [1, 1, 30.0]) for s in (2.0, 1.0)]
        assert 3.5 < errs[0] / errs[1] < 4.5, (kind, errs)  # second-order error: first-order accurate


def test_line_characteristics_with_anchors_above_the_seabed():
    from tapm_opt.models.characteristics import line_characteristics

    m = raised_model()
    ch = line_characteristics(m, half_range=50.0, n_points=5)
    np.testing.assert_array_equal(ch.XF[:, 2], ch.XF0)
    np.testing.assert_allclose(ch.H[:, 2], m.solve_lines(np.zeros(3)).HF, rtol=1e-12)
    np.testing.assert_allclose(ch.T[:, 2], m.tensions(np.zeros(3)), rtol=1e-12)


@pytest.mark.parametrize("z,match", [
    (1000.5, r"lines\[0\] \(id '1'\): anchor z = 1000.5 m puts the anchor below the seabed \(water depth 1000 m"),
    (0.0, r"lines\[0\] \(id '1'\): anchor z = 0 m is not below the fairleads \(fairlead depth 0 m"),
    (-20.0, r"lines\[0\] \(id '1'\): anchor z = -20 m is not below the fairleads"),
    (np.nan, r"lines\[0\] \(id '1'\): anchor z = nan m must be finite"),
    (np.inf, r"lines\[0\] \(id '1'\): anchor z = inf m must be finite"),
])
def test_bad_anchor_depth_raises_model_error(z, match):
    sc = raised(AAMO4, (0.0, 0.0, 0.0, 0.0))
    lines = (dataclasses.replace(sc.lines[0], anchor=(2000.0, 0.0, z)),) + sc.lines[1:]
    with pytest.raises(ModelError, match=match):
        MooringModel.from_scenario(dataclasses.replace(sc, lines=lines))
    # a broken line's anchor is checked too: the scenario itself is wrong
    with pytest.raises(ModelError, match="anchor z"):
        MooringModel.from_scenario(dataclasses.replace(sc, lines=lines), broken=["1"])


@pytest.mark.parametrize("z", [1000.0, 1000.0 * (1 + 5e-7), 1000.0 * (1 - 5e-7)])
def test_anchor_depth_within_round_off_of_the_water_depth_is_on_the_seabed(z):
    """An anchor depth the scenario check accepts as on the seabed (1e-6 relative) gives h_A = 0:
    the line keeps its seabed friction and is not rejected as below the seabed."""
    lines = tuple(dataclasses.replace(ln, anchor=(ln.anchor[0], ln.anchor[1], z)) for ln in AAMO4.lines)
    m = MooringModel.from_scenario(dataclasses.replace(AAMO4, lines=lines))
    np.testing.assert_array_equal(m.h_A, 0.0)
    np.testing.assert_array_equal(m.ZF, MooringModel.from_scenario(AAMO4).ZF)


def chain_scenario():
    """3 chain lines at 120 deg in 150 m of water, most of each line on the seabed."""
    chain = dict(id="chain", diameter=0.1, mass_per_length=200.0, density=7850.0, EA=8.0e8,
                 MBS=8.0e6, MBS_std=4.0e5, Cd_normal=2.4, Cd_tangential=0.4, Ca_normal=1.0)
    lines = [dict(id=f"L{k}", type="chain", anchor=[800.0 * math.cos(a), 800.0 * math.sin(a)],
                  fairlead_angle_deg=math.degrees(a), length=850.0)
             for k, a in enumerate((0.0, 2 * math.pi / 3, -2 * math.pi / 3))]
    d = base_dict()  # aamo4's vessel, with these lines
    d.update(line_types=[chain], lines=lines)
    d["environment"]["water_depth"] = 150.0
    d["turret"].update(mode="locked", fairlead_radius=5.0, fairlead_depth=6.0)
    return scenario_from_dict(d)


@pytest.mark.parametrize("name,heights,segments", [
    ("chain touching down from anchors 60 m above the seabed", (60.0, 60.0, 60.0), 24),
    ("aamo4, anchors 300 m up, the lines sag below them", (300.0,) * 4, 10),
])
def test_fem_settles_on_the_catenary_with_anchors_above_the_seabed(name, heights, segments):
    """MooringFEM.initialise puts the nodes on the catenary from the raised anchors; settled, the
    FEM's fairlead tensions are the catenary's within 0.5 %, its anchor nodes held where the
    scenario puts them, the grounded stretch on the seabed."""
    from tapm_opt.plant.mooring_fem import MooringFEM

    base = chain_scenario() if name.startswith("chain") else AAMO4
    sc = raised(base, heights)
    model = MooringModel.from_scenario(sc)
    sol = model.solve_lines(np.zeros(3))
    expected = "touchdown" if name.startswith("chain") else "suspended"
    assert np.all(sol.regime_names() == expected) and np.all(sol.VA < 0)
    fem_model = MooringFEM(sc, segments=segments)
    fem_model.initialise(np.zeros(3))
    fem = fem_model.fem
    depth = sc.environment.water_depth
    np.testing.assert_allclose(fem.r[fem.anchor_idx, 2], depth - np.array(heights), rtol=0, atol=1e-9)
    info = fem_model.settle(np.zeros(3))
    assert info.converged, info
    np.testing.assert_allclose(fem_model.fairlead_tension(), sol.TF, rtol=5e-3)
    np.testing.assert_allclose(fem.r[fem.anchor_idx, 2], depth - np.array(heights), rtol=0, atol=1e-9)
    grounded = fem.r[:, 2] > depth - 0.1  # within 10 cm of the seabed (the contact spring lets it sink 1 cm)
    if expected == "touchdown":
        share = grounded.sum() / fem.n_nodes
        assert share == pytest.approx(np.mean(sol.LBot) / np.mean(model.L), abs=2.0 / segments)
    else:
        assert not np.any(grounded) and np.all(fem.r[:, 2] < depth - 0.5 * min(heights))


@pytest.mark.parametrize("drop", [[0], [0, 4], [0, 1]])
@pytest.mark.parametrize("psi", [None, 0.0, 0.3])
def test_equilibrium_of_a_mooring_unbalanced_at_the_origin(drop, psi):
    """fpso with lines removed is far from balance at the field zero point (its lines pull tens of MN):
    the residual is scaled by the lines' pull, so the rest pose is found (it failed with 'residual
    1.16e-09 > tol' when scaled by 1 kN, below the rounding of MN tensions), and the mooring load
    there balances to a tiny fraction of that pull."""
    import dataclasses

    import tapm_opt

    sc = tapm_opt.load_scenario("fpso")
    sc = dataclasses.replace(sc, lines=tuple(ln for i, ln in enumerate(sc.lines) if i not in drop))
    m = MooringModel.from_scenario(sc)
    eta = m.equilibrium(np.zeros(3), psi=psi)
    pull = np.sum(np.abs(m.solve_lines(eta).HF))
    tau = m.force(eta)
    balanced = slice(0, 3) if psi is None else slice(0, 2)
    assert np.all(np.abs(tau[balanced]) < 1e-6 * pull), tau
    assert np.hypot(eta[0], eta[1]) > 10.0   # it really moved: the lost lines' pull is taken up elsewhere
