"""Tests of the quasi-static riser (tapm_opt.models.riser) and of the plant's riser-angle sensing:
closed forms of the tensioned string and the tensioned beam, convergence with the number of
elements, the CasADi path against the numpy path and finite differences, superposition and
symmetry, the plant's channels and measurements, and bad input.

Coordinates of the closed forms: s is the height above the wellhead (0 at the wellhead, L at the
hang-off), the angles are theta = dw/ds. With T(s) = T_b + w_s s and a uniform drag q per metre,
the string equation -(T w')' = q integrates once to

    T w' = C - q s,

and w(L) - w(0) = Delta fixes C (each test states its form of C).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math

import casadi as ca
import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import scenario_from_dict, scenario_to_dict
from tapm_opt.errors import ModelError, ScenarioError
from tapm_opt.estimation.lowpass import LowPassEstimator, TrueStateEstimator
from tapm_opt.models.mooring import MooringModel
from tapm_opt.models.riser import SPEED_EPS, RiserModel
from tapm_opt.plant.sensors import Sensors, SensorSpec
from tapm_opt.plant.simulator import Plant, run_open_loop

RHO = 1025.0
D = 0.5
CD = 1.0
K_DRAG = 0.5 * RHO * CD * D  # q = K_DRAG |v| v


@functools.lru_cache(maxsize=None)
def scenario(name: str):
    return tapm_opt.load_scenario(name)


def variant(name: str, edit):
    d = copy.deepcopy(scenario_to_dict(scenario(name)))
    edit(d)
    return scenario_from_dict(d)


def riser(*, L=1000.0, depth=None, T_top=2.0e6, w_s=0.0, EI=0.0, n=20, wellhead=(0.0, 0.0), **kw) -> RiserModel:
    """A riser from explicit numbers; still water unless a current is passed to the methods."""
    return RiserModel(length=L, water_depth=L if depth is None else depth, top_tension=T_top,
                      submerged_weight=w_s, diameter=D, rho=RHO, Cd=CD, EI=EI, wellhead=wellhead,
                      n_elements=n, **kw)


def fpso_EI() -> float:
    rs = scenario("fpso").riser
    return rs.youngs_modulus * math.pi / 64.0 * (rs.diameter**4 - (rs.diameter - 2 * rs.wall_thickness) ** 4)


# ------------------------------------------------------------------------------------------
# closed forms
# ------------------------------------------------------------------------------------------


def test_straight_riser_above_the_wellhead_in_still_water_has_zero_angles():
    sc = scenario("fpso")
    m = RiserModel.from_scenario(sc)
    top, bottom = m.angles(sc.riser.wellhead)
    assert np.array_equal(top, np.zeros(2)) and np.array_equal(bottom, np.zeros(2))
    # the vessel at the field zero point has its hang-off right above the wellhead
    np.testing.assert_array_equal(m.angles_at([0.0, 0.0, 0.0]), np.zeros(4))
    _, w = m.deflection(sc.riser.wellhead)
    np.testing.assert_array_equal(w, np.broadcast_to(sc.riser.wellhead, w.shape))


def test_schema_bending_stiffness_is_the_pipe_formula():
    """EI = E pi/64 (D^4 - (D - 2t)^4): fpso's steel pipe of 0.5 m with a 25 mm wall, 2.216e8 N m^2."""
    sc = scenario("fpso")
    assert sc.riser.EI == pytest.approx(fpso_EI(), rel=1e-15)
    assert sc.riser.EI == pytest.approx(2.2157e8, rel=1e-4)
    assert dataclasses.replace(sc.riser, wall_thickness=0.0).EI == 0.0


@pytest.mark.parametrize("n", [10, 20])
def test_string_with_constant_tension_in_a_uniform_current_is_the_parabola(n):
    """EI = 0, w_s = 0: -T w'' = q, w = q s (L - s) / (2 T); the angles are -/+ q L / (2 T) at the
    top / bottom (the current bows the riser downstream). The parabola lies in the cubic elements'
    space, so the FE solution is exact at any n."""
    L, T, V = 1000.0, 2.0e6, 1.3
    m = riser(L=L, T_top=T, n=n)
    q = K_DRAG * V * math.sqrt(V**2 + SPEED_EPS**2)
    top, bottom = m.angles([0.0, 0.0], v_c=[V, 0.0])
    np.testing.assert_allclose(top, [-q * L / (2 * T), 0.0], rtol=1e-12, atol=1e-16)
    np.testing.assert_allclose(bottom, [q * L / (2 * T), 0.0], rtol=1e-12, atol=1e-16)
    assert bottom[0] > 0 > top[0]
    z, w = m.deflection([0.0, 0.0], v_c=[V, 0.0])
    s = L - z  # water depth = L: s = depth of the wellhead - z
    np.testing.assert_allclose(w[:, 0], q * s * (L - s) / (2 * T), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(w[:, 1], 0.0, atol=1e-15)
    # the drag per metre the model uses
    np.testing.assert_allclose(m.drag([500.0], v_c=[V, 0.0]), [[q, 0.0]], rtol=1e-15)


def string_closed_form(L, T_top, w_s, q, delta):
    """Angles (top, bottom) of the string -(T w')' = q, T = T_b + w_s s, w(L) - w(0) = delta.

    T w' = C - q s; with (C - q u) = (C + q T_b / w_s) - (q / w_s) T(u),
    w(L) - w(0) = (C + q T_b / w_s) ln(T_top / T_b) / w_s - q L / w_s = delta, so
    C = (delta + q L / w_s) w_s / ln(T_top / T_b) - q T_b / w_s;
    theta_bottom = C / T_b, theta_top = (C - q L) / T_top."""
    T_b = T_top - w_s * L
    C = (delta + q * L / w_s) * w_s / math.log(T_top / T_b) - q * T_b / w_s
    return (C - q * L) / T_top, C / T_b


def test_string_with_linearly_varying_tension_in_a_uniform_current_matches_the_closed_form():
    """fpso's tension range (2.5 MN at the top, 1.2 MN at the wellhead), EI = 0, a uniform 1 m/s
    current and a 15 m offset: the angles within 1e-4 relative at 20 elements (measured 2.7e-5),
    and the error falls at least 20-fold from 10 to 40 elements."""
    L, T_top, w_s, V, delta = 982.0, 2.5e6, 1323.8, 1.0, 15.0
    q = K_DRAG * V * math.sqrt(V**2 + SPEED_EPS**2)
    exact = np.array(string_closed_form(L, T_top, w_s, q, delta))
    errs = {}
    for n in (10, 20, 40):
        m = riser(L=L, depth=1000.0, T_top=T_top, w_s=w_s, n=n)
        top, bottom = m.angles([delta, 0.0], v_c=[V, 0.0])
        got = np.array([top[0], bottom[0]])
        errs[n] = np.max(np.abs(got - exact) / np.abs(exact))
        assert top[1] == 0.0 and bottom[1] == 0.0
    assert errs[20] < 1e-4, errs
    assert errs[40] < errs[10] / 20, errs


def test_offset_of_a_taut_string_with_varying_tension_in_still_water():
    """Still water: (T w')' = 0, w' = C / T(s), C = Delta w_s / ln(T_top / T_b); the top angle is
    C / T_top, the bottom one C / T_b (the slacker bottom leans more). Agreement to the FE error:
    within 2e-5 relative at 20 elements (measured top 1.3e-6, bottom 1.0e-5), converging with the
    number of elements (10 -> 40 elements: measured about 60-fold)."""
    L, T_top, w_s, delta = 982.0, 2.5e6, 1323.8, 20.0
    T_b = T_top - w_s * L
    C = delta * w_s / math.log(T_top / T_b)
    exact = np.array([C / T_top, C / T_b])
    errs = {}
    for n in (10, 20, 40):
        top, bottom = riser(L=L, depth=1000.0, T_top=T_top, w_s=w_s, n=n).angles([0.0, delta])
        assert top[0] == 0.0 and bottom[0] == 0.0
        errs[n] = np.abs(np.array([top[1], bottom[1]]) - exact) / exact
    assert np.all(errs[20] < 2e-5), errs
    assert np.all(errs[40] < errs[10] / 20), errs
    # a straight line would give Delta / L at both ends; the tension profile makes them differ
    assert exact[1] > delta / L > exact[0]


def beam_closed_form_bottom(L, T, EI, q):
    """Pinned-pinned tensioned beam, constant T, uniform q: EI w'''' - T w'' = q, w = w'' = 0 at
    both ends. With k^2 = T / EI, w = q s (L - s) / (2 T) + C (cosh ks - 1 - tanh(kL/2) sinh ks),
    C = q / (T k^2); the end slope is q L / (2 T) - q tanh(kL/2) / (T k) (the string's, less a
    boundary-layer term)."""
    k = math.sqrt(T / EI)
    return q * L / (2 * T) - q * math.tanh(k * L / 2) / (T * k)


def test_tensioned_beam_with_constant_tension_matches_the_closed_form():
    """fpso's section (EI = 2.2e8 N m^2) at a constant 1.85 MN in a uniform 1 m/s current: the
    bending stiffness lowers the end angles by about 2 / (kL) = 2.2 %; the FE angles agree with the
    closed form within 3e-3 at 20 elements (measured 1.9e-3: the boundary layer 1/k = 11 m is
    shorter than an element) and within 1e-4 at 80 (measured 2.2e-5)."""
    L, T, V = 982.0, 1.85e6, 1.0
    EI = fpso_EI()
    q = K_DRAG * V * math.sqrt(V**2 + SPEED_EPS**2)
    exact = beam_closed_form_bottom(L, T, EI, q)
    assert 0.015 < 1 - exact / (q * L / (2 * T)) < 0.03
    for n, tol in ((20, 3e-3), (80, 1e-4)):
        top, bottom = riser(L=L, T_top=T, EI=EI, n=n).angles([0.0, 0.0], v_c=[V, 0.0])
        assert bottom[0] == pytest.approx(exact, rel=tol)
        assert top[0] == pytest.approx(-exact, rel=tol)  # symmetric: constant tension


def test_beam_angles_approach_the_string_as_EI_vanishes_and_differ_boundedly_for_fpso():
    """fpso's tension profile and current: the difference between beam and string end angles falls
    as EI -> 0 (monotonically, about as sqrt(EI), the boundary-layer length), and for the fpso
    section it is a few per cent of the angle (bounded by 5 %)."""
    sc = scenario("fpso")
    rs = sc.riser
    ss = sc.sea_state("extreme")
    string = RiserModel.from_scenario(variant("fpso", lambda d: d["riser"].update(wall_thickness=0.0)), ss)
    beam = RiserModel.from_scenario(sc, ss)
    assert string.EI == 0.0 and beam.EI == pytest.approx(fpso_EI())
    p = np.asarray(rs.wellhead) + [12.0, -7.0]
    ref = np.concatenate(string.angles(p))
    diffs = []
    for scale in (1.0, 1e-2, 1e-4, 1e-6):
        m = RiserModel(length=rs.length, water_depth=sc.environment.water_depth, top_tension=rs.top_tension,
                       submerged_weight=rs.submerged_weight, diameter=rs.diameter, rho=sc.environment.water_density,
                       Cd=rs.Cd, EI=scale * beam.EI, wellhead=rs.wellhead, current=beam.current)
        if scale == 1.0:  # the explicit constructor and from_scenario build the same riser
            np.testing.assert_array_equal(np.concatenate(m.angles(p)), np.concatenate(beam.angles(p)))
        diffs.append(np.max(np.abs(np.concatenate(m.angles(p)) - ref)) / np.max(np.abs(ref)))
    assert 1e-3 < diffs[0] < 0.05, diffs
    assert all(b < a for a, b in zip(diffs, diffs[1:])), diffs
    assert diffs[-1] < 1e-3 * diffs[0], diffs


def test_pinned_ends_are_moment_free():
    """The zero end moment is the natural boundary condition: the FE end moments are small against
    the largest moment along the riser and fall with refinement (measured top end 44 % of the
    largest at 20 elements, boundary layer unresolved; 2.8 % at 160)."""
    sc = scenario("fpso")
    p = np.asarray(sc.riser.wellhead) + [10.0, 0.0]
    ratio = {}
    for n in (20, 160):
        z, M = RiserModel.from_scenario(sc, "extreme", n_elements=n).bending_moment(p)
        mag = np.linalg.norm(M, axis=2)
        assert z[0, 0] == pytest.approx(1000.0) and z[-1, 1] == pytest.approx(18.0)
        ratio[n] = max(mag[0, 0], mag[-1, 1]) / mag.max()
    assert ratio[160] < 0.05 and ratio[160] < ratio[20] / 5, ratio
    # a string has no bending moment at all
    string = riser(n=20)
    _, M = string.bending_moment([5.0, 0.0], v_c=[1.0, 0.0])
    assert np.all(M == 0.0)


# ------------------------------------------------------------------------------------------
# CasADi path, influence coefficients, superposition and symmetry
# ------------------------------------------------------------------------------------------


def test_casadi_function_equals_the_numpy_path_and_its_jacobians_finite_differences():
    sc = scenario("fpso")
    m = RiserModel.from_scenario(sc, "extreme")
    fn = m.angle_function()
    assert fn is m.angle_function()  # cached
    assert fn.name_in() == ["p_top", "v_c"] and fn.name_out() == ["theta_top", "theta_bottom"]
    rng = np.random.default_rng(11)
    wh = np.asarray(sc.riser.wellhead)
    for _ in range(5):
        p = wh + rng.uniform(-40.0, 40.0, 2)
        v = rng.uniform(-1.5, 1.5, 2)
        top, bottom = m.angles(p, v)
        ft, fb = fn(p, v)
        np.testing.assert_allclose(np.ravel(ft.full()), top, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(np.ravel(fb.full()), bottom, rtol=1e-10, atol=1e-14)
        c_t, c_b = m.influence(p, v)
        h = 1e-3
        fd_t, fd_b = np.zeros((2, 2)), np.zeros((2, 2))
        for j in range(2):
            e = np.zeros(2)
            e[j] = h
            tp, bp = m.angles(p + e, v)
            tm, bm = m.angles(p - e, v)
            fd_t[:, j], fd_b[:, j] = (tp - tm) / (2 * h), (bp - bm) / (2 * h)
        np.testing.assert_allclose(c_t, fd_t, rtol=1e-7, atol=1e-12)
        np.testing.assert_allclose(c_b, fd_b, rtol=1e-7, atol=1e-12)
        # the model is affine in p_top: the influence is c I with the documented coefficients
        co = m.coefficients
        np.testing.assert_allclose(c_t, co["c_t"] * np.eye(2), rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(c_b, co["c_b"] * np.eye(2), rtol=1e-12, atol=1e-18)
    # derivative with respect to the current: finite differences of the numpy path
    p, v = wh + [5.0, 5.0], np.array([0.8, -0.3])
    ps, vs = ca.SX.sym("p", 2), ca.SX.sym("v", 2)
    jac_v = ca.Function("dv", [ps, vs], [ca.jacobian(fn(ps, vs)[1], vs)])(p, v).full()
    fd = np.column_stack([(m.angles(p, v + e)[1] - m.angles(p, v - e)[1]) / 2e-6 for e in np.eye(2) * 1e-6])
    np.testing.assert_allclose(jac_v, fd, rtol=1e-6)


def test_offset_response_superposes_and_does_not_depend_on_the_current():
    """Affine in the hang-off: theta(p1) + theta(p2) - theta(p0) = theta(p1 + p2 - p0) at any
    current; the offset part is the same in still water and in a current."""
    sc = scenario("fpso")
    still = RiserModel.from_scenario(sc)
    cur = RiserModel.from_scenario(sc, "extreme")
    p0 = np.asarray(sc.riser.wellhead)
    p1, p2 = p0 + [13.0, -4.0], p0 + [-6.0, 21.0]
    for m in (still, cur):
        a1, a2, a0, a12 = (np.concatenate(m.angles(p)) for p in (p1, p2, p0, p1 + p2 - p0))
        np.testing.assert_allclose(a1 + a2 - a0, a12, rtol=1e-12, atol=1e-15)
    d_still = np.concatenate(still.angles(p1)) - np.concatenate(still.angles(p0))
    d_cur = np.concatenate(cur.angles(p1)) - np.concatenate(cur.angles(p0))
    np.testing.assert_allclose(d_cur, d_still, rtol=1e-12, atol=1e-15)
    # in still water a top offset of +Delta x gives both angles about (+Delta / L, 0), positive
    top, bottom = still.angles(p0 + [10.0, 0.0])
    assert top[0] > 0 and bottom[0] > 0 and top[1] == 0 and bottom[1] == 0
    assert 0.5 < top[0] / (10.0 / sc.riser.length) < 1.0 < bottom[0] / (10.0 / sc.riser.length) < 2.0


def test_current_direction_symmetry():
    """A current going to +y gives the +x result turned by 90 deg; a reversed current the
    negated angles (q is odd in v_c)."""
    sc = scenario("fpso")
    m = RiserModel.from_scenario(sc, "extreme")
    wh = np.asarray(sc.riser.wellhead)
    tx, bx = m.angles(wh, [0.9, 0.0])
    ty, by = m.angles(wh, [0.0, 0.9])
    rot = np.array([[0.0, -1.0], [1.0, 0.0]])
    np.testing.assert_allclose(ty, rot @ tx, rtol=1e-14, atol=1e-18)
    np.testing.assert_allclose(by, rot @ bx, rtol=1e-14, atol=1e-18)
    tn, bn = m.angles(wh, [-0.9, 0.0])
    np.testing.assert_allclose(tn, -tx, rtol=1e-14)
    np.testing.assert_allclose(bn, -bx, rtol=1e-14)
    assert bx[0] > 0 > tx[0]  # bowed downstream: bottom angle along the current, top against it
    # drag is quadratic in the speed
    t2, b2 = m.angles(wh, [1.8, 0.0])
    np.testing.assert_allclose(b2, 4 * bx, rtol=1e-10)


def test_sheared_current_profile_of_the_sea_state_acts_on_the_riser():
    """fpso's piecewise profile (1, 0.75, 0.15 of the surface speed at 0, 500, 1000 m): the drag
    follows phi^2, and the profile's angles are smaller than a uniform current's of the surface
    speed."""
    sc = scenario("fpso")
    ss = sc.sea_state("extreme")
    m = RiserModel.from_scenario(sc, ss)
    v = m.v_c
    np.testing.assert_allclose(v, ss.current_speed * np.array([math.cos(ss.current_direction),
                                                              math.sin(ss.current_direction)]), rtol=1e-14)
    q = m.drag([0.0, 500.0, 1000.0])
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), K_DRAG * ss.current_speed**2 * np.array([1, 0.75, 0.15]) ** 2,
                               rtol=1e-9)
    uniform = RiserModel.from_scenario(sc, dataclasses.replace(ss, current_profile="uniform"))
    wh = sc.riser.wellhead
    assert np.linalg.norm(m.angles(wh)[1]) < np.linalg.norm(uniform.angles(wh)[1])
    assert np.linalg.norm(m.angles(wh)[0]) < np.linalg.norm(uniform.angles(wh)[0])


def test_hangoff_follows_the_hull():
    sc = variant("fpso", lambda d: d["riser"].update(hangoff=[80.0, 5.0]))
    m = RiserModel.from_scenario(sc)
    eta = np.array([3.0, -2.0, 0.5])
    c, s = math.cos(0.5), math.sin(0.5)
    expect = np.array([3.0 + c * 80.0 - s * 5.0, -2.0 + s * 80.0 + c * 5.0])
    np.testing.assert_allclose(m.hangoff_E(eta), expect, rtol=1e-14)
    np.testing.assert_allclose(m.angles_at(eta), np.concatenate(m.angles(expect)), rtol=1e-14)
    assert m.hangoff_E(np.zeros((4, 3))).shape == (4, 2)


# ------------------------------------------------------------------------------------------
# the plant
# ------------------------------------------------------------------------------------------

RISER_CHANNELS = ["riser_top[x]", "riser_top[y]", "riser_bottom[x]", "riser_bottom[y]", "riser_top_angle",
                  "riser_bottom_angle"]


def test_plant_riser_channels_in_still_water_stay_near_zero():
    plant = Plant(scenario("fpso"), sea_state="none", segments=6, seed=2)
    assert plant.riser is not None
    names = [c for c, _ in plant.channels()]
    assert names[-6:] == RISER_CHANNELS and all(u == "rad" for _, u in plant.channels()[-6:])
    r = run_open_loop(plant, 60.0, dt_log=5.0)
    for c in RISER_CHANNELS:
        assert np.all(np.abs(r[c]) < 2e-3), (c, r[c])  # the vessel rests within ~1 m of the zero point
    np.testing.assert_allclose(r["riser_top_angle"], np.hypot(r["riser_top[x]"], r["riser_top[y]"]))
    np.testing.assert_allclose(r["riser_bottom_angle"], np.hypot(r["riser_bottom[x]"], r["riser_bottom[y]"]))


@pytest.fixture(scope="module")
def storm_run():
    sc = scenario("fpso")
    plant = Plant(sc, sea_state="storm", segments=6, seed=5)
    r = run_open_loop(plant, 40.0, dt_log=2.0)
    return sc, plant, r


def test_plant_riser_channels_are_the_model_at_the_total_hangoff(storm_run):
    """The logged angles are RiserModel.angles at the hang-off of the LF + wave-frequency pose in the
    sea state's current."""
    sc, plant, r = storm_run
    model = RiserModel.from_scenario(sc, "storm")
    eta_total = np.column_stack([r["x"] + r["x_wf"], r["y"] + r["y_wf"], r["psi"] + r["psi_wf"]])
    p = model.hangoff_E(eta_total)
    want = np.array([np.concatenate(model.angles(pk)) for pk in p])
    got = np.column_stack([r[c] for c in RISER_CHANNELS[:4]])
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    assert np.any(r["x_wf"] != 0) and np.ptp(r["riser_top[x]"]) > 0  # the waves move the hang-off


def test_plant_measures_riser_angles_with_the_sensor_noise(storm_run):
    sc, plant, _ = storm_run
    m = plant.measure()
    truth = plant.riser.angles_at(plant.eta_total)
    assert m.riser_angles.shape == (4,) and not m.riser_angles.flags.writeable
    assert m.t_riser_angles == pytest.approx(m.t)  # 1 Hz: sampled at t = 40 s
    assert np.all(np.abs(m.riser_angles - truth) < 5 * sc.sensors.riser_angle_std)
    assert np.any(m.riser_angles != truth)
    # the estimators pass the angles through
    np.testing.assert_array_equal(LowPassEstimator(MooringModel.from_scenario(sc)).update(m.t, m).riser_angles,
                                  m.riser_angles)
    mt = plant.measure(truth=True)
    np.testing.assert_array_equal(TrueStateEstimator().update(mt.t, mt).riser_angles, mt.riser_angles)


def test_riser_angle_sensor_noise_has_the_set_std_and_rate():
    std = 0.01
    spec = SensorSpec(riser_angle_std=std, riser_angle_rate=0.5)
    s = Sensors(spec, 0, seed=3)
    truth = np.array([0.01, -0.02, 0.03, 0.0])
    ms = [s.sample(0.25 * k, [0.0, 0.0, 0.0], [], truth) for k in range(16000)]
    held = np.array([m.riser_angles for m in ms])
    fresh = held[::8]  # one new sample every 2 s = 8 calls
    assert np.all(held[1:8] == held[0])  # held between the instants
    err = fresh - truth
    assert np.all(np.abs(err.mean(axis=0)) < 4 * std / math.sqrt(len(fresh)))
    np.testing.assert_allclose(err.std(axis=0), std, rtol=0.06)
    assert ms[9].t_riser_angles == pytest.approx(2.0)
    # the riser's noise stream leaves the GNSS and heading noise as without a riser
    a, b = Sensors(spec, 0, seed=3), Sensors(spec, 0, seed=3)
    for k in range(20):
        ma, mb = a.sample(float(k), [1.0, 2.0, 0.1], [], truth), b.sample(float(k), [1.0, 2.0, 0.1], [])
        assert np.array_equal(ma.position, mb.position) and ma.heading == mb.heading
        assert mb.riser_angles is None and mb.t_riser_angles is None


def test_scenario_without_riser_has_no_riser_channels_or_measurement():
    plant = Plant(scenario("aamo4"), sea_state="none", segments=6)
    assert plant.riser is None
    assert not any(c.startswith("riser") for c, _ in plant.channels())
    assert len(plant.sample_row()) == len(plant.channels())
    m = plant.measure()
    assert m.riser_angles is None
    assert LowPassEstimator(plant.system.lines).update(m.t, m).riser_angles is None


# ------------------------------------------------------------------------------------------
# bad input
# ------------------------------------------------------------------------------------------


def test_riser_longer_than_the_water_depth_is_refused():
    sc = variant("fpso", lambda d: d["riser"].update(length=1100.0))  # a valid scenario (a lazy wave)
    with pytest.raises(ModelError, match=r"riser\.length=1100\.0 m exceeds the water depth 1000 m.*no longer than"):
        RiserModel.from_scenario(sc)
    with pytest.raises(ModelError, match="riser.length"):
        Plant(sc, sea_state="none", segments=6)
    with pytest.raises(ModelError, match=r"length=1000\.5 m"):
        riser(L=1000.5, depth=1000.0)
    riser(L=1000.0, depth=1000.0)  # exactly the depth is fine


def test_tension_that_is_not_positive_down_to_the_wellhead_is_refused():
    with pytest.raises(ModelError, match=r"top_tension=1000000\.0 N.*-1e\+06 N not positive"):
        riser(L=1000.0, T_top=1.0e6, w_s=2000.0)
    sc = scenario("fpso")
    bad = dataclasses.replace(sc, riser=dataclasses.replace(sc.riser, top_tension=1.0e6))
    with pytest.raises(ModelError, match=r"riser\.top_tension=1000000\.0 N"):
        RiserModel.from_scenario(bad)


def test_wall_thickness_of_half_the_diameter_is_refused():
    data = copy.deepcopy(scenario_to_dict(scenario("fpso")))
    data["riser"]["wall_thickness"] = 0.25
    with pytest.raises(ScenarioError, match=r"riser\.wall_thickness = 0\.25 m must be less than half"):
        scenario_from_dict(data)
    data["riser"]["wall_thickness"] = -0.01
    with pytest.raises(ScenarioError, match=r"riser\.wall_thickness"):
        scenario_from_dict(data)
    data["riser"]["wall_thickness"] = 0.249
    assert scenario_from_dict(data).riser.EI > 0


def test_non_finite_or_misshapen_input_is_refused():
    m = RiserModel.from_scenario(scenario("fpso"), "extreme")
    with pytest.raises(ModelError, match=r"p_top_E=\[nan, 0\.0\] must be 2 finite"):
        m.angles([math.nan, 0.0])
    with pytest.raises(ModelError, match=r"p_top_E=\[1\.0, 2\.0, 3\.0\]"):
        m.angles([1.0, 2.0, 3.0])
    with pytest.raises(ModelError, match=r"v_c=\[inf, 0\.0\]"):
        m.angles([0.0, 0.0], v_c=[math.inf, 0.0])
    with pytest.raises(ModelError, match="p_top_E"):
        m.influence([0.0, math.nan])
    with pytest.raises(ModelError, match="p_top_E"):
        m.deflection("here")
    with pytest.raises(ModelError, match="eta"):
        m.angles_at([0.0, math.inf, 0.0])
    with pytest.raises(ModelError, match=r"n_elements=5 must be an integer >= 10"):
        RiserModel.from_scenario(scenario("fpso"), n_elements=5)
    with pytest.raises(ModelError, match="has no"):
        RiserModel.from_scenario(scenario("aamo4"))
    with pytest.raises(ModelError, match=r"EI=-1\.0"):
        riser(EI=-1.0)


def test_plant_riser_angles_follow_a_turning_current():
    """With a turning current the plant's riser angles are those of the current of the step (the
    hull's), not of the sea state's current at t = 0: recomputed from the logged pose and the
    current at that time, they agree; with the t = 0 current they would not (the current has
    turned 30 deg)."""
    sc = tapm_opt.load_scenario("fpso")
    ss = dataclasses.replace(sc.sea_state("normal"), Hs=0.0, wind_speed=0.0, current_speed=0.8,
                             current_turn_rate=math.radians(0.5))
    plant = Plant(sc, sea_state=ss, seed=0, segments=4, wave_frequency=False)
    run_open_loop(plant, 60.0)
    env = plant.env
    v_now = env.current_surface(plant.t - 0.1)[:2]   # held over the last outer step from its start
    v_0 = env.current_surface(0.0)[:2]
    turned = math.degrees(math.atan2(v_now[1], v_now[0]) - math.atan2(v_0[1], v_0[0]))
    assert (turned + 180.0) % 360.0 - 180.0 == pytest.approx(29.95, abs=0.1)
    pose = plant.eta + plant._eta_wf
    want = plant.riser.angles_at(pose, v_now)
    np.testing.assert_allclose(plant._riser_angles, want, rtol=1e-12, atol=1e-15)
    stale = plant.riser.angles_at(pose)
    assert np.max(np.abs(stale - want)) > 0.2 * np.max(np.abs(want))
