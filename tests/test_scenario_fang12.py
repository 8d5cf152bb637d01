"""The built-in fang12, the reliability paper's case (seed reliability-setpoint-riser-mooring §3):
it loads and validates, the numbers its header states are what the models give, lines 9 and 11
come to the paper's threshold delta_s = 2 once line 10 is broken and the mooring carries the mean
load, and in closed loop the reliability setpoint leaves the field zero point and lifts the riser's
index above the fixed setpoint's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tapm_opt.config import builtin_scenarios, load_scenario, validate
from tapm_opt.control.setpoint_opt import DELTA_S_DEFAULT, SetpointProblem, WorkingPoint
from tapm_opt.design.loads import mean_environmental_load
from tapm_opt.design.tables import weathervane_heading
from tapm_opt.geometry import body_from_turret
from tapm_opt.models.mooring import MooringModel
from tapm_opt.models.riser import RiserModel
from tapm_opt.models.system import System

BUNDLE3 = ("9", "10", "11", "12")


@pytest.fixture(scope="module")
def sc():
    return load_scenario("fang12")


@pytest.fixture(scope="module")
def moor(sc):
    return MooringModel.from_scenario(sc)


def _index(sc, T):
    """Quasi-static reliability index (MBS - T) / MBS_std of the governing (chain) section; k sigma
    left out: 0.05 % of MBS in this sea, 0.001 of the index (header)."""
    lt = sc.line_type_by_id("chain100")
    return (lt.MBS - np.asarray(T, float)) / lt.MBS_std


def _body(sc, p, psi):
    """Body pose (x, y, psi) with the turret at offset ``p`` from its field-zero-point position."""
    bx, by = body_from_turret(np.asarray(p, float), float(psi), np.asarray(sc.turret.position, float))
    return np.array([float(bx), float(by), float(psi)])


@pytest.fixture(scope="module")
def weather(sc):
    """The weathervane heading in [R]'s sea and the mean load there (a free turret: the same heading
    with any line broken, the mean load's moment about the turret being zero)."""
    psi = weathervane_heading(sc, "normal", n_scan=6)   # a coarse scan finds the default's heading (to 1e-9 deg)
    return psi, np.asarray(mean_environmental_load(sc, "normal", psi).total, float)


@pytest.fixture(scope="module")
def equilibria(sc, weather):
    """The mooring alone under the mean load of [R]'s sea at the weathervane heading, intact and
    with line 10 broken: {broken: (model, turret offset (2,))}."""
    psi, tau = weather
    system = System.from_scenario(sc)
    out = {}
    for broken in ((), ("10",)):
        m = MooringModel.from_scenario(sc, broken=broken)
        out[broken] = (m, np.asarray(system.turret_offset(m.equilibrium(tau, psi=psi)), float)[:2])
    return out


def test_fang12_is_a_valid_builtin(sc):
    assert "fang12" in builtin_scenarios()
    assert sc.name == "fang12" and validate(sc) == []
    assert [ln.id for ln in sc.lines] == [str(i) for i in range(1, 13)]
    assert not sc.faults                   # the break is the study's condition, not the built-in's
    # [R] §3: 1000 m, the paper's sea state first, its riser (tensions read as kN)
    ss = sc.sea_states[0]
    assert sc.environment.water_depth == 1000.0
    assert (ss.id, ss.Hs, ss.Tp, ss.current_speed, ss.wind_speed) == ("normal", 7.0, 10.0, 0.8, 8.0)
    assert ss.current_profile_depths == (0.0, 500.0, 1000.0) and ss.current_profile_factors == (1.0, 0.75, 0.15)
    r = sc.riser
    assert (r.diameter, r.wall_thickness, r.top_tension, r.youngs_modulus) == (0.5, 0.025, 2.5e6, 2.1e11)
    assert r.top_tension - r.submerged_weight * r.length == pytest.approx(1.2e6, rel=1e-3)
    # lines 9-12 are the weather-side bundle: anchors to the north, line 10 an inner one
    angles = {ln.id: ln.fairlead_angle % (2 * math.pi) for ln in sc.lines}
    np.testing.assert_allclose(np.degrees([angles[i] for i in BUNDLE3]), [352.5, 357.5, 2.5, 7.5])
    assert all(sc.lines[sc.line_index(i)].anchor[0] > 2500.0 for i in BUNDLE3)


def test_header_quasi_static_numbers(sc, moor):
    """The header's CHECKED WITH THE QUASI-STATIC MODEL block."""
    chain = sc.line_type_by_id("chain100")
    assert all(ln.composite for ln in sc.lines)
    assert [(s.type, s.length) for s in sc.lines[0].sections] == [("chain100", 1100.0), ("wire125", 1700.0),
                                                                    ("chain100", 100.0)]
    assert sc.line_type_by_id("wire125").MBS > chain.MBS          # the chain governs the strength
    sol = moor.solve_lines(np.zeros(3))
    _, _, XF = moor.spans(np.zeros(3))
    np.testing.assert_allclose(XF, 2585.3, atol=0.1)
    np.testing.assert_allclose(moor.ZF, 982.0)
    np.testing.assert_allclose(sol.LBot / 2900.0, 1 / 3, atol=0.002)     # a third on the seabed [R]
    assert np.all(sol.LBot < 1100.0)                                       # touchdown in the bottom chain
    np.testing.assert_allclose(sol.TF, 1.662e6, rtol=1e-3)
    np.testing.assert_allclose(sol.TF / chain.MBS, 0.168, atol=1e-3)
    np.testing.assert_allclose([sol.HF[0], sol.VF[0]], [1.035e6, 1.300e6], rtol=1e-3)
    assert sol.TF[0] / chain.EA == pytest.approx(0.0019, abs=1e-4)
    assert np.max(np.abs(moor.force(np.zeros(3))[:2])) < 10.0
    K = moor.stiffness(np.zeros(3))
    np.testing.assert_allclose([K[0, 0], K[1, 1], K[2, 2], K[1, 2]], [6.36e4, 6.36e4, 5.31e8, 5.81e6], rtol=3e-3)
    M = np.asarray(sc.vessel.mass_matrix) + np.asarray(sc.vessel.added_mass)
    periods = [2 * math.pi * math.sqrt(M[i, i] / K[i, i]) for i in range(3)]
    np.testing.assert_allclose(periods, [393.0, 653.0, 535.0], rtol=3e-3)
    for x, load, t_max in ((20, 1.38e6, 0.194), (40, 3.03e6, 0.229), (60, 5.05e6, 0.276), (80, 7.54e6, 0.336)):
        eta = np.array([-float(x), 0.0, 0.0])
        assert np.hypot(*moor.force(eta)[:2]) == pytest.approx(load, rel=5e-3)
        assert moor.tensions(eta).max() / chain.MBS == pytest.approx(t_max, abs=1e-3)


def test_mooring_alone_equilibria_and_line_indices(sc, moor, weather, equilibria):
    """The header's STRENGTH SCATTER table: lines 9 and 11 at delta_s = 2 once line 10 is broken
    and the mooring alone carries [R]'s mean load, 0.13 higher intact; at the field zero point the
    break does not change them (a line's tension depends only on where the turret is)."""
    psi, tau = weather
    m_i, p_i = equilibria[()]
    m_b, p_b = equilibria[("10",)]
    assert math.degrees(psi) == pytest.approx(3.3, abs=0.05)
    assert np.hypot(*tau[:2]) == pytest.approx(3.11e6, rel=3e-3)
    np.testing.assert_allclose(p_i, [-40.9, -1.7], atol=0.1)
    np.testing.assert_allclose(p_b, [-61.0, 0.1], atol=0.1)
    chain = sc.line_type_by_id("chain100")
    t_i = dict(zip(m_i.line_ids, m_i.tensions(_body(sc, p_i, psi)) / chain.MBS))
    t_b = dict(zip(m_b.line_ids, m_b.tensions(_body(sc, p_b, psi)) / chain.MBS))
    np.testing.assert_allclose([t_i[i] for i in BUNDLE3], 0.230, atol=0.001)
    np.testing.assert_allclose([t_b[i] for i in ("9", "11", "12")], 0.2775, atol=0.001)
    d_i = {k: float(_index(sc, v * chain.MBS)) for k, v in t_i.items()}
    d_b = {k: float(_index(sc, v * chain.MBS)) for k, v in t_b.items()}
    for i in ("9", "11"):
        assert d_b[i] == pytest.approx(2.00, abs=0.01)
        assert abs(d_b[i] - DELTA_S_DEFAULT) < 0.05                    # at [R]'s threshold
        assert d_i[i] == pytest.approx(2.14, abs=0.01)
        assert d_i[i] - d_b[i] == pytest.approx(0.13, abs=0.01)        # all the break does to them
        # the break adds 4.8 % MBS to them between the two equilibria
        assert t_b[i] - t_i[i] == pytest.approx(0.048, abs=0.002)
    assert min(d_i.values()) == pytest.approx(2.14, abs=0.01)            # intact: bundle 3 lowest
    others = [v for k, v in d_b.items() if k not in BUNDLE3]
    assert 2.36 < min(others) and max(others) < 2.40                     # lines 1-8 after the break
    others = [v for k, v in d_i.items() if k not in BUNDLE3]
    assert 2.34 < min(others) and max(others) < 2.38
    # at the field zero point the break changes nothing
    np.testing.assert_allclose(_index(sc, moor.tensions(np.zeros(3))), 2.31, atol=0.005)
    np.testing.assert_allclose(_index(sc, m_b.tensions(np.zeros(3))), 2.31, atol=0.005)


def test_thrust_and_riser_at_the_field_zero_point(sc, weather):
    """The header's thrust needed at the field zero point and 10 m upstream (intact and line 10
    broken), and the riser's angles and bottom index in [R]'s current."""
    system = System.from_scenario(sc)
    riser = RiserModel.from_scenario(sc, sc.sea_state("normal"))
    psi, tau = weather
    for broken, ft0, ft10 in (((), 0.32, 0.39), (("10",), 0.43, 0.49)):
        prob = SetpointProblem(system.with_broken(broken) if broken else system, riser, "unified")
        wp = WorkingPoint(p=np.zeros(2), psi=psi, tau_env=tau, ksigma_lines=np.zeros(len(prob.line_ids)),
                          v_c=np.asarray(riser.v_c, float)[:2])
        n = len(prob.line_ids)
        ev = {x: prob.evaluate(np.array([x, 0.0]), wp) for x in (-10.0, 0.0, 10.0, 20.0)}
        assert math.sqrt(ev[0.0]["FT2"]) == pytest.approx(ft0, abs=0.005)
        assert math.sqrt(ev[10.0]["FT2"]) == pytest.approx(ft10, abs=0.005)
        np.testing.assert_allclose(np.degrees(ev[0.0]["theta"]), [1.31, 0.99], atol=0.01)
        np.testing.assert_allclose([ev[x]["delta"][n + 1] for x in (-10.0, 0.0, 10.0)], [1.31, 3.01, 4.71], atol=0.01)
        # upstream the lower end stands straighter: its angle is smallest about 10 m north
        th = [float(np.degrees(ev[x]["theta"][1])) for x in (0.0, 10.0, 20.0)]
        assert th[1] == pytest.approx(0.15, abs=0.01) and th[1] < th[2] < th[0]
    # with fpso's 1.2 MN units the damaged mooring could not be held upstream within the PID's box
    scale = System.from_scenario(load_scenario("fpso")).thrusters.max_tau()[0] / system.thrusters.max_tau()[0]
    assert 0.43 / scale == pytest.approx(0.58, abs=0.01) and 0.49 / scale > 0.6


@pytest.mark.slow
def test_reliability_setpoint_leaves_the_field_zero_point_and_lifts_the_riser_index():
    """Closed loop on the FEM plant ([R]'s PID with integral action, the EKF and the tension test,
    4 segments per line, [R]'s sea, line 10 broken at 600 s): the reliability setpoint re-solves on
    the reduced line model when the break is reported, sits well north of the field zero point
    (upstream, where the riser's lower end stands straighter) after the break, and its lowest riser
    bottom index after the break is well above 2 and more than 1 above the fixed setpoint's (which
    comes to about 2: the causal KPI, with the waves' allowance, is 1.6 in the 5000 s study)."""
    from tapm_opt.config.schema import Fault
    from tapm_opt.plant.simulator import Plant
    from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller

    sc = load_scenario("fang12")
    system = System.from_scenario(sc)
    r_crit, r_std = sc.riser.critical_bottom_angle, sc.riser.critical_bottom_angle_std
    t_break, duration = 600.0, 1500.0
    out = {}
    for setpoint in ("fixed", "reliability"):
        plant = Plant(sc, sea_state="normal", seed=1, segments=4,
                      faults=[Fault(kind="line_break", line="10", time=t_break)])
        opts = {"warmup": 120.0} if setpoint != "fixed" else None
        r = run_closed_loop(plant, build_controller(system, {"type": "pid", "modes": "extreme_restoring"}),
                            ClosedLoopSettings(duration=duration, heading="chasing", setpoint=setpoint,
                                               setpoint_options=opts), system=system)
        after = r.time > t_break + 300.0
        theta_b = np.asarray(r["riser_bottom_angle"], float)[after]
        out[setpoint] = (r, float(np.min((r_crit - theta_b) / r_std)))
    rel, d_rel = out["reliability"]
    _, d_fix = out["fixed"]
    log = rel.meta["setpoint_log"]
    broken_at = [e["t"] for e in log if e["broken"] == ["10"]]
    assert broken_at and t_break < broken_at[0] <= t_break + 25.0          # re-solved when the break was reported (16 s)
    after = rel.time > t_break + 300.0
    assert np.min(np.asarray(rel["x_d"], float)[after]) > 5.0           # north of the field zero point
    # the lowest instantaneous bottom index (no wave allowance) after the break: lifted well above 2
    assert d_rel > DELTA_S_DEFAULT + 1.0 and d_rel - d_fix > 1.0, (d_fix, d_rel)


def test_the_reliability_paper_study_is_the_papers_case():
    """studies/reliability_paper.toml: fang12 in [R]'s sea, 5000 s, line 10 broken at 2500 s,
    [R]'s PID law behind the fixed, chasing, unified and reliability setpoints."""
    from pathlib import Path

    from tapm_opt.studies.spec import load_study

    st = load_study(Path(__file__).resolve().parents[1] / "studies" / "reliability_paper.toml")
    layers = {c.labels["controller"]: c.inputs["closed_loop"]["setpoint"] for c in st.cases}
    assert layers == {"PID fixed": "fixed", "PID chasing": "chasing", "PID unified": "unified",
                      "PID reliability": "reliability"}
    for c in st.cases:
        assert c.labels["scenario"] == "fang12" and c.inputs["sea_state"] == "normal"
        assert c.inputs["duration"] == 5000.0 and c.inputs["controller"]["modes"] == "extreme_restoring"
        faults = c.inputs["scenario"]["faults"]
        assert [(f["kind"], f["line"], f["time"]) for f in faults] == [("line_break", "10", 2500.0)]
