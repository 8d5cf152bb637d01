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
    # study specs: not set by default (the dead band stays), taken when given, checked
    assert build_controller(system, {"type": "lmpc"}).settings.dead_band_damaged is None
    assert build_controller(system, {"type": "lmpc", "dead_band_damaged": 22.5}).settings.dead_band_damaged == 22.5
    with pytest.raises(ControllerSpecError, match="dead_band_damaged"):
        build_controller(system, {"type": "lmpc", "dead_band_damaged": -1.0})
