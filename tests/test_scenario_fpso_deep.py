"""The built-in fpso_deep: fpso's FPSO in 2000 m on 12 semi-taut chain-polyester-chain composite
lines with a subsurface buoy at each lower joint.

* it loads, validates and is listed with the built-ins; its lines are the header's sections;
* the numbers its header gives are what the quasi-static model computes (pretension, anchor uplift,
  buoy depth, stiffness, natural periods, restoring curve, the buoy's effect on a slack line);
* the FEM plant settled at rest agrees with the quasi-static composite solution to its
  discretisation error, which falls at second order in the segment length;
* a short closed-loop run with the PID in the design storm stays inside the safe circle.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tapm_opt.config import builtin_scenarios, load_scenario, validate
from tapm_opt.models import composite
from tapm_opt.models.mooring import MooringModel
from tapm_opt.plant.mooring_fem import MooringFEM

ZERO = np.zeros(3)


@pytest.fixture(scope="module")
def sc():
    return load_scenario("fpso_deep")


@pytest.fixture(scope="module")
def model(sc):
    return MooringModel.from_scenario(sc)


def joint_points(model: MooringModel, sc, eta, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Line j's joints at pose ``eta``: distance from the anchor and height above the seabed [m]."""
    _, _, XF = model.spans(np.asarray(eta, dtype=float))
    px, pz = composite.points(XF[j], model.ZF[j], composite.CompositeLine.from_arrays(sc.line_sections[j]),
                              h_A=model.h_A[j])
    return np.ravel(px), np.ravel(pz)


# --------------------------------------------------------------------------------------------
# loads and validates
# --------------------------------------------------------------------------------------------


def test_loads_validates_and_is_a_builtin(sc):
    assert "fpso_deep" in builtin_scenarios() and sc.name == "fpso_deep"
    assert validate(sc) == []
    assert sc.environment.water_depth == 2000.0 and len(sc.lines) == 12 and len(sc.thrusters) == 6
    assert {s.id for s in sc.sea_states} == {"normal", "calm", "storm", "extreme"}
    buoy = sc.point_type("buoy")
    assert buoy.net_weight(sc.environment) == pytest.approx(-296.5e3, rel=1e-3)   # header: 296.5 kN up
    for ln, sec in zip(sc.lines, sc.line_sections):
        assert ln.composite and ln.winch_max_rate == 0.0
        assert [s.type for s in ln.sections] == ["chain137", "poly240", "chain137"]
        assert sec["L"].tolist() == [300.0, 2790.0, 150.0] and sec["segments"].tolist() == [3, 18, 2]
        assert [s.top for s in ln.sections] == ["buoy", None, None]
    # the rope is stronger than the top chain, whose MBS is the line's
    assert sc.line_type_by_id("poly240").MBS > sc.line_type_by_id("chain137").MBS == sc.line_arrays["MBS"][0]
    assert sc.line_type_by_id("poly240").EA == pytest.approx(14.0 * sc.line_type_by_id("poly240").MBS, rel=1e-3)
    # the riser reaches from the fairlead depth to the seabed, its bottom tension [R]'s 1.2 MN
    rs = sc.riser
    assert rs.length == pytest.approx(sc.environment.water_depth - sc.turret.fairlead_depth)
    assert rs.top_tension - rs.submerged_weight * rs.length == pytest.approx(1.2e6, rel=1e-3)


# --------------------------------------------------------------------------------------------
# the header's numbers (tapm_opt/config/scenarios/fpso_deep.toml, "CHECKED WITH ...")
# --------------------------------------------------------------------------------------------


def test_header_pretension_anchor_uplift_and_buoy_depths(sc, model):
    sol = model.solve_lines(ZERO)
    MBS = sc.line_arrays["MBS"]
    _, _, XF = model.spans(ZERO)
    np.testing.assert_allclose(XF, 2592.0, atol=1e-3)
    np.testing.assert_allclose(sol.TF, 2.887e6, rtol=5e-4)                    # 2.887 MN
    np.testing.assert_allclose(sol.TF / MBS, 0.170, atol=5e-4)                # 17.0 % MBS
    np.testing.assert_allclose(sol.HF, 1.952e6, rtol=5e-4)
    np.testing.assert_allclose(sol.VF, 2.127e6, rtol=5e-4)
    np.testing.assert_allclose(np.degrees(np.arctan2(sol.VF, sol.HF)), 47.5, atol=0.05)
    np.testing.assert_allclose(sol.TF / sc.line_type_by_id("poly240").EA, 0.0116, atol=5e-5)   # rope strain
    # semi-taut: nothing on the seabed, the anchor pulled up at 20.1 deg
    assert np.all(sol.LBot == 0.0)
    np.testing.assert_allclose(sol.VA, 0.715e6, rtol=1e-3)
    np.testing.assert_allclose(np.degrees(np.arctan2(sol.VA, sol.HA)), 20.1, atol=0.05)
    # the buoys 154.2 m above the seabed (1846 m deep), 256 m from the anchor; the upper joints 122 m deep
    for j in range(12):
        x, z = joint_points(model, sc, ZERO, j)
        assert z[0] == pytest.approx(154.2, abs=0.05) and x[0] == pytest.approx(256.0, abs=0.5)
        assert sc.environment.water_depth - z[1] == pytest.approx(122.3, abs=0.05)
    # net load at the field zero point: under 5 N (anchors rounded to 0.1 mm)
    assert np.all(np.abs(model.force(ZERO)[:2]) < 5.0)


def test_header_stiffness_periods_and_restoring_curve(sc, model):
    K = model.stiffness(ZERO)
    assert K[0, 0] == pytest.approx(2.410e5, rel=1e-3) and K[1, 1] == pytest.approx(K[0, 0], rel=1e-6)
    assert K[2, 2] == pytest.approx(2.015e9, rel=1e-3) and K[1, 2] == pytest.approx(2.204e7, rel=1e-3)
    T = 2 * np.pi * np.sqrt(np.diag(sc.vessel.M) / np.diag(K))
    np.testing.assert_allclose(T, [197.1, 273.3, 225.0], atol=0.1)
    # restoring load and most loaded line for an offset toward the south (bundle 1 loaded)
    offsets = [20.0, 40.0, 60.0, 80.0, 100.0]
    restoring = [5.08e6, 10.31e6, 15.44e6, 20.46e6, 25.44e6]
    t_max = [4.00e6, 5.27e6, 6.61e6, 7.97e6, 9.35e6]
    for d, F, Tm in zip(offsets, restoring, t_max):
        eta = np.array([-d, 0.0, 0.0])
        assert model.force(eta)[0] == pytest.approx(F, abs=0.01e6), d
        assert np.max(model.tensions(eta)) == pytest.approx(Tm, abs=0.005e6), d
    # at the safe radius the intact lines are still within the utilisation limit
    eta = np.array([-sc.limits.safe_radius, 0.0, 0.0])
    assert np.max(model.tensions(eta)) < sc.limits.tension_utilisation * sc.line_arrays["MBS"][0]


def test_header_the_buoy_keeps_the_rope_off_the_seabed(sc, model):
    """Line 2 (357.5 deg) slackened by a northward offset: its lower joint (the rope's end) stays
    high with the buoy, and comes down to the seabed without it."""
    light = dataclasses.replace(sc.point_type("buoy"), mass=0.0, volume=0.0)
    sc_bare = dataclasses.replace(sc, point_types=(light,))
    bare = MooringModel.from_scenario(sc_bare)
    for d, with_buoy, without in ((50.0, 111.0, 82.0), (100.0, 79.0, 36.0), (200.0, 63.0, 4.0)):
        eta = np.array([d, 0.0, 0.0])
        assert joint_points(model, sc, eta, 1)[1][0] == pytest.approx(with_buoy, abs=0.5), d
        assert joint_points(bare, sc_bare, eta, 1)[1][0] == pytest.approx(without, abs=0.5), d


# --------------------------------------------------------------------------------------------
# the FEM plant at rest against the quasi-static solution
# --------------------------------------------------------------------------------------------


def _fem_errors(scenario, lines: range):
    """Settled FEM at eta = 0 against models.composite on the FEM's own anchor-fairlead spans:
    (largest relative fairlead-tension error, largest joint-position error [m])."""
    m = MooringFEM(scenario)
    m.initialise(ZERO)
    m.settle(ZERO, tol=1e-9, speed_tol=1e-4, max_time=3000.0)
    fem, T = m.fem, m.fairlead_tension()
    eT = eP = 0.0
    for j in lines:
        a, rf = fem.anchors[j], fem.r[fem.fairlead_idx[j]]
        XF, ZF = float(np.hypot(*(rf[:2] - a[:2]))), float(a[2] - rf[2])
        line = composite.CompositeLine.from_arrays(scenario.line_sections[j])
        px, pz = (np.ravel(v) for v in composite.points(XF, ZF, line))
        eT = max(eT, abs(T[j] / float(composite.solve(XF, ZF, line).TF) - 1.0))
        r = fem.r[fem.node_start[j] + np.cumsum(fem.lines.sections[j]["segments"])[:-1]]
        x, z = np.hypot(r[:, 0] - a[0], r[:, 1] - a[1]), fem.depth - r[:, 2]
        eP = max(eP, float(np.max(np.hypot(x - px, z - pz))))
    return eT, eP


def test_fem_at_rest_agrees_with_the_quasi_static_model(sc):
    """At the scenario's own segments (chain 100 m, rope 155 m, chain 75 m) the FEM's fairlead
    tension is 0.47 % below the quasi-static one and its joints lie within 0.16 m of the points'
    equilibrium: the discretisation (chords of length l0 with the weight lumped at the nodes),
    not settling (to 1e-9 per 5 s). The tolerances are those errors with 25 % margin. Halving every
    segment divides both by 4.0 (second order), so they are the discretisation's."""
    eT, eP = _fem_errors(sc, range(12))
    assert eT < 6e-3 and eP < 0.2, (eT, eP)
    one = dataclasses.replace(sc.lines[0], segments=46, sections=tuple(
        dataclasses.replace(s, segments=2 * s.segments) for s in sc.lines[0].sections))
    eT2, eP2 = _fem_errors(dataclasses.replace(sc, lines=(one,)), range(1))
    assert eT2 < eT / 3.0 and eP2 < eP / 3.0, (eT, eT2, eP, eP2)


# --------------------------------------------------------------------------------------------
# closed loop
# --------------------------------------------------------------------------------------------


def test_short_closed_loop_run_with_pid_stays_in_the_safe_circle(sc):
    from tapm_opt.plant.simulator import Plant
    from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller
    from tapm_opt.studies.kpis import basic_kpis

    plant = Plant(sc, sea_state="storm", seed=1)
    res = run_closed_loop(plant, build_controller(sc, {"type": "pid"}),
                          ClosedLoopSettings(duration=300.0, heading="chasing"))
    k = basic_kpis(res, sc)
    assert np.all(np.isfinite(res.data))
    assert k["offset_max"] < sc.limits.safe_radius
    assert k["utilisation_max"] < sc.limits.tension_utilisation
    # the heading settles: no swing of 1 deg or more per second over the last minute
    psi = res.data[:, res.channels.index("psi")]
    assert np.all(np.abs(np.diff(psi[-60:])) < math.radians(1.0))
