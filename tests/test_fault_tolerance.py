"""Fault-tolerant reconfiguration on a detected line break (``fault_tolerance``): the PID's
feed-forward of the lost line's load and the MPC's prediction without the broken line."""

from __future__ import annotations

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.control.mpc import LinearMPC, MPCError, MPCSettings, NonlinearMPC
from tapm_opt.control.pid import ControlError
from tapm_opt.interfaces import Estimate, Setpoint
from tapm_opt.models.system import System
from tapm_opt.studies.controllers import ControllerSpecError, build_controller


@pytest.fixture(scope="module")
def system():
    return System.from_scenario(load_scenario("fpso"))


def _est(eta, broken=()):
    return Estimate(t=0.0, eta=np.asarray(eta, float), nu=np.zeros(3), tau_env=np.zeros(3),
                    broken_lines=frozenset(broken))


SP = Setpoint(eta_d=np.zeros(3))


def test_pid_feeds_the_lost_lines_load_forward(system):
    eta = np.array([-25.0, 8.0, 0.2])
    big = [1e9, 1e9, 1e12]   # no saturation: the difference is the feed-forward alone
    on = build_controller(system, {"type": "pid", "fault_tolerance": True, "modes": "normal", "tau_limit": big})
    off = build_controller(system, {"type": "pid", "modes": "normal", "tau_limit": big, "fault_tolerance": False})
    np.testing.assert_allclose(on.update(0.0, _est(eta), SP), off.update(0.0, _est(eta), SP))  # intact: the same
    on.reset()
    off.reset()
    d = on.update(0.0, _est(eta, ["1", "2"]), SP) - off.update(0.0, _est(eta, ["1", "2"]), SP)
    lost = system.lines.force(eta) - system.lines.without(["1", "2"]).force(eta)
    np.testing.assert_allclose(d, lost, rtol=1e-6, atol=1.0)
    assert np.hypot(*lost[:2]) > 1e6          # two lines of the loaded bundle: MN


def test_pid_fault_tolerance_settings_are_checked(system):
    with pytest.raises(ControllerSpecError, match="fault_tolerance"):
        build_controller(system, {"type": "pid", "fault_tolerance": "yes"})
    from tapm_opt.control.pid import TAPMPID
    pid = build_controller(system, {"type": "pid"})
    with pytest.raises(ControlError, match="line_model"):
        TAPMPID(pid.gains, fault_tolerance=True)


@pytest.mark.parametrize("cls", [NonlinearMPC, LinearMPC])
def test_mpc_predicts_without_the_broken_line(system, cls):
    """The zeroed characteristics give the load and tensions of the reduced line model (centred
    at the same pose; to the accuracy of the tabulated catenary the MPC reads them from, 1e-9 in
    the tensions and about 1e-7 in the slopes), and the broken line pulls nothing in the
    prediction."""
    ctrl = cls(system, MPCSettings(fault_tolerance=True))
    eta = np.array([-30.0, 5.0, 0.1])
    p = ctrl._params(_est(eta, ["3"]), SP)
    moor = p[ctrl._prob.p_idx["moor"]]
    coeffs = [moor.reshape(5, -1)[i] for i in range(5)]
    tau, T = system.lines.characteristic_load(eta + [1.0, -2.0, 0.01], coeffs)
    red = system.lines.without(["3"])
    tau_r, T_r = red.characteristic_load(eta + [1.0, -2.0, 0.01], list(red.characteristics(eta)))
    np.testing.assert_allclose(np.asarray(tau, float).ravel(), np.asarray(tau_r, float).ravel(), rtol=1e-7, atol=1e-3)
    T = np.asarray(T, float).ravel()
    assert T[2] == 0.0
    np.testing.assert_allclose(np.delete(T, 2), np.asarray(T_r, float).ravel(), rtol=1e-7)
    plain = cls(system, MPCSettings(fault_tolerance=False))._params(_est(eta, ["3"]), SP)
    assert np.any(plain[ctrl._prob.p_idx["moor"]] != moor)     # without the option the model stays intact


def test_mpc_fault_tolerance_needs_parametric_lines():
    with pytest.raises(MPCError, match="fault_tolerance needs mooring = 'characteristic'"):
        MPCSettings(fault_tolerance=True, mooring="catenary")
    with pytest.raises(MPCError, match="fault_tolerance"):
        MPCSettings(fault_tolerance=1)


def _result_with(log, events):
    from tapm_opt.results import ResultBuilder

    rb = ResultBuilder([("T_fairlead[1]", "N"), ("T_fairlead[2]", "N")], capacity=3)
    for t in (0.0, 1.0, 2.0):
        rb.append(t, np.array([1e6, 1e6]))
    meta = {"events": events}
    if log is not None:
        meta["estimator_log"] = log
    return rb.build(meta)


def test_detection_kpis_from_the_estimators_log():
    from tapm_opt.studies.kpis import _detection, break_times as _break_times

    ev = [[100.0, "line 2 broke"]]
    log = [{"t": 50.0, "line": "1", "event": "line break detected"},
           {"t": 106.0, "line": "2", "event": "line break detected"}]
    r = _result_with(log, ev)
    k = _detection(r, _break_times(r, ["1", "2"]))
    assert k == {"false_alarms": 1, "break_isolated": 1.0, "break_isolated_line": "2", "break_detected_at": 106.0,
                 "detection_delay": 6.0}
    r = _result_with([{"t": 120.0, "line": "1", "event": "line break detected"}], ev)   # the wrong line
    k = _detection(r, _break_times(r, ["1", "2"]))
    assert k == {"false_alarms": 1, "break_isolated": 0.0, "break_isolated_line": "1"}
    assert _detection(_result_with([], ev), {"2": 100.0}) == {"false_alarms": 0, "break_isolated": 0.0,
                                                               "break_isolated_line": ""}   # missed
    r = _result_with([], [])                                                           # intact, quiet
    assert _detection(r, {}) == {"false_alarms": 0}
    assert _detection(_result_with(None, ev), {"2": 100.0}) == {}                     # no detector


def test_fault_tolerance_is_on_by_default_in_specs(system):
    assert build_controller(system, {"type": "pid"})._ft
    assert build_controller(system, {"type": "lmpc"}).settings.fault_tolerance
    assert not build_controller(system, {"type": "mpc", "mooring": "catenary"}).settings.fault_tolerance


@pytest.mark.parametrize("cls", [NonlinearMPC, LinearMPC])
def test_mpc_tightens_its_dead_band_once_a_break_is_known(system, cls):
    """``dead_band_damaged``: 20 m off with a 30 m dead band the position term is zero while the
    mooring is intact (the dead band's slack is 0 over the plan) and stays zero with a break but
    no damaged dead band; with a 10 m damaged dead band and a break reported, the slack is the
    distance beyond 10 m (about 1 r_ref) and the plan moves the turret back towards the
    setpoint."""
    eta = np.array([20.0, 0.0, 0.0])
    base = dict(fault_tolerance=True, dead_band=30.0, horizon=8, w_velocity=1.0)
    runs = {}
    for name, kw, broken in (("intact", {"dead_band_damaged": 10.0}, ()),
                             ("damaged", {"dead_band_damaged": 10.0}, ["9"]),
                             ("plain", {}, ["9"])):
        ctrl = cls(system, MPCSettings(**base, **kw))
        ctrl.update(0.0, _est(eta, broken), SP)
        assert ctrl.last_step().success, ctrl.last_step().status
        z = ctrl._z
        S = z[ctrl._prob.idx["S_db"]]
        runs[name] = (S, z[ctrl._prob.idx["X"]].reshape(-1, 6) * ctrl._prob.scale["x"])
    r_ref = MPCSettings().r_ref
    assert np.max(runs["intact"][0]) < 1e-4 and np.max(runs["plain"][0]) < 1e-4
    S, X = runs["damaged"]
    assert S[0] == pytest.approx(10.0 / r_ref, rel=0.1)            # 20 m against 10 m: 1 r_ref beyond
    assert X[-1, 0] < runs["plain"][1][-1, 0] - 0.5                  # the plan heads back
    assert np.mean(X[1:, 3]) < np.mean(runs["plain"][1][1:, 3])      # surging towards the setpoint


def test_damaged_dead_band_settings_are_checked(system):
    for bad in (0.0, -5.0, float("nan"), "10"):
        with pytest.raises(MPCError, match="dead_band_damaged"):
            MPCSettings(fault_tolerance=True, dead_band=30.0, dead_band_damaged=bad)
    with pytest.raises(MPCError, match="dead_band_damaged = 10.0 needs a dead band"):
        MPCSettings(fault_tolerance=True, dead_band=0.0, dead_band_damaged=10.0)
    with pytest.raises(MPCError, match="needs fault_tolerance"):
        MPCSettings(fault_tolerance=False, dead_band=30.0, dead_band_damaged=10.0)
    with pytest.raises(MPCError, match="dead_band_budget"):
        MPCSettings(fault_tolerance=True, dead_band=30.0, dead_band_damaged=10.0, dead_band_budget="no")
    # study specs: 0.75 of the dead band, budgeted, by default with fault tolerance; taken when
    # given, checked; none without fault tolerance
    st = build_controller(system, {"type": "lmpc"}).settings
    assert (st.dead_band, st.dead_band_damaged, st.dead_band_budget) == (30.0, 22.5, True)
    assert build_controller(system, {"type": "mpc", "dead_band": 20.0}).settings.dead_band_damaged == 15.0
    assert build_controller(system, {"type": "lmpc", "dead_band_damaged": 25.0}).settings.dead_band_damaged == 25.0
    assert build_controller(system, {"type": "lmpc", "fault_tolerance": False}).settings.dead_band_damaged is None
    assert build_controller(system, {"type": "lmpc", "dead_band": 0.0}).settings.dead_band_damaged is None
    assert not build_controller(system, {"type": "lmpc", "dead_band_budget": False}).settings.dead_band_budget
    for spec in ({"fault_tolerance": False}, {"dead_band": 0.0}, {"mooring": "catenary"}):
        with pytest.raises(ControllerSpecError, match="dead_band_budget = False has nothing to budget"):
            build_controller(system, {"type": "lmpc", "dead_band_budget": False, **spec})
    with pytest.raises(ControllerSpecError, match="dead_band_damaged"):
        build_controller(system, {"type": "lmpc", "dead_band_damaged": -1.0})


# --- the dead band after a break within the intact thrust budget ---------------------------------

PSI_STORM = 0.33   # rad: about where the heading chasing holds the bow in the fpso design storm


@pytest.fixture(scope="module")
def storm_load(system):
    """The fpso design storm's mean wind, drift and current load in {E} at PSI_STORM [N, N, N m]
    (waves going south, about 5 MN)."""
    from tapm_opt.design.loads import mean_environmental_load
    from tapm_opt.geometry import rot_z

    return rot_z(PSI_STORM) @ mean_environmental_load(system.scenario, "storm", PSI_STORM).total


def test_net_load_along_the_load_falls_as_the_mooring_takes_it_up(system, storm_load):
    """Without thrust the vessel rests where the net load along the mean load is zero; closer in
    the load wins (positive), further out the mooring (negative), and the net load falls
    steadily with the radius. Cross-check: with no environment it is the catenary mooring's
    exact force (``MooringModel.force``) projected on the direction."""
    from tapm_opt.control.mpc import net_load_along
    from tapm_opt.geometry import rot_z, turret_offset

    e = storm_load[:2] / np.hypot(*storm_load[:2])
    radii = np.arange(0.0, 61.0, 5.0)
    net = np.array([net_load_along(system.lines, storm_load, PSI_STORM, r, e) for r in radii])
    assert net[0] > 1e6 and net[-1] < 0.0 and np.all(np.diff(net) < 0.0)
    c = np.array([-6.0, 4.0])   # a setpoint off the field zero point: the dead band's centre
    for r in (10.0, 40.0):
        # the pose written out: the turret, p_cot_B ahead of the body origin, at c + r e
        R = rot_z(PSI_STORM)[:2, :2]
        xy = c + r * e + system.p_cot_B - R @ system.p_cot_B
        eta = np.array([xy[0], xy[1], PSI_STORM])
        np.testing.assert_allclose(turret_offset(eta, system.p_cot_B), c + r * e, atol=1e-9)
        exact = (R @ system.lines.force(eta)[:2]) @ e
        assert net_load_along(system.lines, np.zeros(3), PSI_STORM, r, e, c) == pytest.approx(exact, rel=1e-6)


def test_budgeted_dead_band_tightens_after_lee_and_side_breaks_not_weather_ones(system, storm_load):
    """In the design storm's mean load, losing a lee line (9-12: they pull downwind) or a side line
    (5-8) leaves the mooring restoring as much or more along the load, so the damaged mooring
    holds 22.5 m within the intact budget; losing a weather line (1-4) takes restoring away and
    the dead band stays at 30 m. Widening the bracket puts the weather break's radius inside it,
    where the damaged mooring needs exactly the budget (bisection against the closed budget)."""
    from tapm_opt.control.mpc import budgeted_dead_band, net_load_along

    lines = system.lines
    for lid in ("9", "10", "11", "12"):      # the lee bundle: 0.6-0.9 MN below the budget at 22.5 m
        assert budgeted_dead_band(lines, lines.without([lid]), storm_load, PSI_STORM, 22.5, 30.0) == 22.5, lid
    for lid in ("5", "6", "7", "8"):         # the side bundle: 2-15 % below it, at this heading
        assert budgeted_dead_band(lines, lines.without([lid]), storm_load, PSI_STORM, 22.5, 30.0) < 25.0, lid
    for lid in ("1", "2", "3", "4"):         # the weather bundle: 2 MN above it
        assert budgeted_dead_band(lines, lines.without([lid]), storm_load, PSI_STORM, 22.5, 30.0) == 30.0, lid
    e = storm_load[:2] / np.hypot(*storm_load[:2])
    damaged = lines.without(["4"])
    budget = net_load_along(lines, storm_load, PSI_STORM, 22.5, e)
    r = budgeted_dead_band(lines, damaged, storm_load, PSI_STORM, 22.5, 80.0)
    assert 30.0 < r < 80.0
    assert net_load_along(damaged, storm_load, PSI_STORM, r, e) <= budget
    assert net_load_along(damaged, storm_load, PSI_STORM, r - 0.02, e) > budget     # the smallest such radius
    # nothing broken: the budget is the need, the damaged radius holds; no load: nothing to budget
    assert budgeted_dead_band(lines, lines, storm_load, PSI_STORM, 22.5, 30.0) == 22.5
    assert budgeted_dead_band(lines, damaged, np.zeros(3), PSI_STORM, 22.5, 30.0) == 22.5
    assert budgeted_dead_band(lines, damaged, storm_load, PSI_STORM, 35.0, 30.0) == 35.0   # not a tightening
    # a mild sea the intact mooring holds at 15 m without thrust (zero budget): the weather break's
    # dead band is where the damaged mooring alone holds the vessel
    mild = 0.25 * storm_load
    assert net_load_along(lines, mild, PSI_STORM, 15.0, e) < 0.0
    r = budgeted_dead_band(lines, damaged, mild, PSI_STORM, 15.0, 80.0)
    assert 25.0 < r < 80.0     # 27.1 m on fpso's chain-wire-chain lines (42.3 m on fpso_equivalent's)
    assert net_load_along(damaged, mild, PSI_STORM, r, e) == pytest.approx(0.0, abs=5e3)   # N: 1 cm x stiffness


@pytest.mark.parametrize("cls", [NonlinearMPC, LinearMPC])
def test_mpc_uses_and_logs_the_budgeted_dead_band(system, storm_load, cls):
    """In the loop: the radius in use is the step's ``dead_band`` and the log's record; a lee
    break gives 22.5 m, a weather break keeps 30 m, and without the budget any break gives 22.5 m."""
    from tapm_opt.geometry import rot_z

    tau_B = rot_z(PSI_STORM).T @ storm_load
    eta = np.array([-28.0, -10.0, PSI_STORM])

    def run(broken, **kw):
        ctrl = cls(system, MPCSettings(fault_tolerance=True, dead_band=30.0, dead_band_damaged=22.5, horizon=6, **kw))
        for t, b in ((0.0, ()), (5.0, broken)):
            ctrl.update(t, Estimate(t=t, eta=eta, nu=np.zeros(3), tau_env=tau_B, broken_lines=frozenset(b)), SP)
        return ctrl

    intact = run(())
    assert intact.last_step().dead_band == 30.0 and intact.log() == []
    lee, weather, tight = run(["9"]), run(["4"]), run(["4"], dead_band_budget=False)
    assert [c.last_step().dead_band for c in (lee, weather, tight)] == [22.5, 30.0, 22.5]
    assert lee.log() == [{"t": 5.0, "event": "mode switch", "from": "intact", "to": "damaged", "radius": 22.5,
                          "broken": ["9"]}]
    assert weather.log()[0]["radius"] == 30.0 and tight.log()[0]["radius"] == 22.5
    assert [s.dead_band for s in lee.diagnostics] == [30.0, 22.5]
    # the report withdrawn: back to the intact dead band, logged; every line reported: no budget
    lee.update(10.0, Estimate(t=10.0, eta=eta, nu=np.zeros(3), tau_env=tau_B, broken_lines=frozenset()), SP)
    assert lee.last_step().dead_band == 30.0 and lee.log()[-1]["to"] == "intact"
    everything = run(list(system.lines.line_ids))
    assert everything.last_step().dead_band == 30.0
    lee.reset()
    assert lee.log() == []


def test_budget_follows_the_setpoint(system, storm_load):
    """The dead band is centred on the position setpoint, and so is the budget: about a setpoint
    15 m up-weather a lee break still tightens and a weather break does not, and the interior
    radius of a wide bracket moves with the centre and meets the budget there."""
    from tapm_opt.control.mpc import budgeted_dead_band, net_load_along

    lines, e = system.lines, storm_load[:2] / np.hypot(*storm_load[:2])
    c = -15.0 * e
    for lid, want in (("9", 22.5), ("4", 30.0)):
        assert budgeted_dead_band(lines, lines.without([lid]), storm_load, PSI_STORM, 22.5, 30.0, c) == want
    # and the radius differs from the one about the field zero point where it is interior
    r0 = budgeted_dead_band(lines, lines.without(["4"]), storm_load, PSI_STORM, 22.5, 80.0)
    r1 = budgeted_dead_band(lines, lines.without(["4"]), storm_load, PSI_STORM, 22.5, 80.0, c)
    assert abs(r1 - r0) > 1.0
    b = net_load_along(lines, storm_load, PSI_STORM, 22.5, e, c)
    assert net_load_along(lines.without(["4"]), storm_load, PSI_STORM, r1, e, c) <= max(b, 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("line, radius", [("9", 22.5), ("4", 30.0)])
def test_in_the_storm_the_mpc_tightens_after_a_lee_break_not_a_weather_one(line, radius):
    """Closed loop with the study defaults (the EKF, the tension test, heading chasing, the linear
    MPC's 30 m dead band and 22.5 m once a break is known, budgeted; fpso, design storm, 10
    segments): a break at 400 s is reported 16 s later and the MPC's next solve (at 420 s) switches to
    the damaged dead band — 22.5 m for the lee line 9, 30 m for the weather line 4 — from the mean
    load so far (the running mean before 300 s of estimates have passed), and the KPI counts the
    switch."""
    from tapm_opt.config.schema import Fault
    from tapm_opt.plant.simulator import Plant
    from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.kpis import case_kpis

    sc = load_scenario("fpso")
    sysm = System.from_scenario(sc)
    plant = Plant(sc, sea_state="storm", seed=1, segments=10, faults=[Fault(kind="line_break", line=line, time=400.0)])
    r = run_closed_loop(plant, build_controller(sysm, {"type": "lmpc"}),
                        ClosedLoopSettings(duration=430.0, heading="chasing"), system=sysm)
    assert [(e["t"], e["line"]) for e in r.meta["estimator_log"]] == [(416.0, line)]
    assert r.meta["controller_log"] == [{"t": 420.0, "event": "mode switch", "from": "intact", "to": "damaged",
                                         "radius": radius, "broken": [line]}]
    assert case_kpis(r, sc)["mode_switches"] == 1
