"""Roll–pitch damping in the MPC (survey §4.2.3; docs/controllers.md "Roll–pitch damping in the MPC").

The augmented prediction's roll and pitch against ``roll_pitch_rhs`` integrated in numpy (the
symbolic model inside the MPC's problem against the numeric one, both MPCs); the option off leaves
the MPC as it was (no roll–pitch states, the attitude ignored); the forced roll and pitch
oscillation of ``semi`` in still water (as ``tests/test_semi_roll_pitch.py`` does for the PID)
damped by the option; bad input refused with the field named.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.control.mpc import LinearMPC, MPCError, MPCSettings, NonlinearMPC, RollPitchWeights
from tapm_opt.interfaces import AttitudeAware, Estimate, Setpoint
from tapm_opt.models.system import System
from tapm_opt.models.vessel import roll_pitch_moments, roll_pitch_rhs
from tapm_opt.plant.simulator import Plant
from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
from tapm_opt.studies.controllers import ControllerSpecError, build_controller


@pytest.fixture(scope="module")
def semi():
    return System.from_scenario(load_scenario("semi"))


def _rk4(x, moment, rp, h, n):
    """``roll_pitch_rhs`` integrated over n RK4 steps of h [s] with the moment held (numpy)."""
    for _ in range(n):
        k1 = roll_pitch_rhs(x, moment, rp)
        k2 = roll_pitch_rhs(x + h / 2 * k1, moment, rp)
        k3 = roll_pitch_rhs(x + h / 2 * k2, moment, rp)
        k4 = roll_pitch_rhs(x + h * k3, moment, rp)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def _plan(ctrl, att, t=0.0):
    """One solve from the attitude ``att`` at rest on the setpoint; the plan's states (N+1, 10) in
    SI and the thrust of every step (N, 3)."""
    ctrl.set_attitude(t, att)
    est = Estimate(t=t, eta=np.array([1.0, -2.0, 0.02]), nu=np.zeros(3), tau_env=np.array([1e5, -5e4, 0.0]))
    ctrl.update(t, est, Setpoint(eta_d=np.zeros(3)))
    prob = ctrl._prob
    X = ctrl._z[prob.idx["X"]].reshape(-1, prob.nx) * prob.scale["x"]
    return X, ctrl.plan_u


@pytest.mark.parametrize("kind", ["lmpc", "mpc"])
def test_prediction_is_roll_pitch_rhs_integrated(semi, kind):
    """The plan's roll and pitch (the CasADi model inside the problem) step by step against the
    numpy ``roll_pitch_rhs`` under the moments of the planned thrust (``roll_pitch_moments``) plus
    the disturbance moment: equal to the same RK4 to rounding, and to a fine integration (100
    steps per prediction step) within RK4's error at dt = 5 s (2 % of each range)."""
    rp = semi.vessel.roll_pitch
    ctrl = build_controller(semi, {"type": kind, "roll_pitch_damping": {"disturbance_time_constant": 100.0}})
    assert ctrl._prob.nx == 10 and ctrl.settings.substeps == 1
    att = np.array([math.radians(1.5), math.radians(-0.8), math.radians(0.05), math.radians(-0.1)])
    X, U = _plan(ctrl, att, t=0.0)
    X, U = _plan(ctrl, att, t=20.0)   # the disturbance estimate moved off zero
    d = ctrl.roll_pitch_disturbance
    assert np.abs(d).min() > 1e5
    dt = ctrl.settings.dt
    assert X[0, 6:] == pytest.approx(att, abs=1e-12)
    assert np.abs(U[:, :2]).max() > 1e4       # it plans thrust, so the moments matter
    span = np.abs(X[:, 6:]).max(axis=0)
    for k in range(len(U)):
        moment = roll_pitch_moments(rp, U[k], np.zeros(3)) + d
        same = _rk4(X[k, 6:], moment, rp, dt, 1)
        fine = _rk4(X[k, 6:], moment, rp, dt / 100, 100)
        assert X[k + 1, 6:] == pytest.approx(same, abs=1e-9 * span.max(), rel=1e-8)
        assert np.all(np.abs(X[k + 1, 6:] - fine) < 2e-2 * span)   # RK4 at omega_5 dt = 0.88: 1 %
    # the moment's sign: a sway force to starboard at the keel heels to port (eq. RP4)
    assert roll_pitch_moments(rp, np.array([0.0, 1e6, 0.0]), np.zeros(3))[0] < 0


def test_substeps_refine_the_prediction(semi):
    """With 10 RK4 substeps the plan's roll and pitch match the fine integration to 1e-6."""
    rp = semi.vessel.roll_pitch
    ctrl = LinearMPC(semi, MPCSettings(horizon=8, substeps=10, roll_pitch_damping=True, w_thrust=10.0),
                     qp_solver="piqp")
    X, U = _plan(ctrl, np.array([math.radians(2.0), math.radians(1.0), 0.0, 0.0]))
    d = ctrl.roll_pitch_disturbance
    assert np.all(d == 0.0)   # started at zero
    for k in range(len(U)):
        fine = _rk4(X[k, 6:], roll_pitch_moments(rp, U[k], np.zeros(3)) + d, rp, 0.05, 100)
        assert X[k + 1, 6:] == pytest.approx(fine, abs=1e-6 * math.radians(2.0))


def test_the_plan_damps_the_predicted_motion(semi):
    """Released from 2 deg roll, 1 deg pitch: the planned thrust's moments oppose the predicted
    rates (negative power over the horizon), and the predicted rates are smaller than those of the
    free decay."""
    rp = semi.vessel.roll_pitch
    ctrl = LinearMPC(semi, MPCSettings(horizon=20, roll_pitch_damping=True, w_thrust=10.0, w_rate=5.0),
                     qp_solver="daqp")
    att = np.array([math.radians(2.0), math.radians(1.0), 0.0, 0.0])
    X, U = _plan(ctrl, att)
    M = np.array([roll_pitch_moments(rp, u, np.zeros(3)) for u in U])
    power = np.sum(M * X[:-1, 8:10], axis=0)
    assert power[0] < 0 and power[1] < 0
    free = [att]
    for _ in range(len(U)):
        free.append(_rk4(free[-1], np.zeros(2), rp, 5.0, 1))
    free = np.array(free)
    assert np.sqrt(np.mean(X[:, 8] ** 2)) < 0.9 * np.sqrt(np.mean(free[:, 2] ** 2))
    assert np.sqrt(np.mean(X[:, 9] ** 2)) < 0.9 * np.sqrt(np.mean(free[:, 3] ** 2))


def test_option_off_is_the_3dof_mpc(semi):
    """Off (the default): 6 states, no disturbance parameter, the attitude ignored (the same command
    with and without it, bit for bit); on: 10 states, the controller is AttitudeAware."""
    cmds = []
    for feed in (False, True):
        ctrl = build_controller(semi, "lmpc")
        assert ctrl._prob.nx == 6 and "rp_dist" not in ctrl._prob.p_idx and ctrl.settings.roll_pitch_damping is False
        out = []
        for k in range(3):
            if feed:
                ctrl.set_attitude(5.0 * k, [math.radians(2.0), 0.01, 0.002, -0.003])
            est = Estimate(t=5.0 * k, eta=np.array([2.0, 1.0, 0.01]), nu=np.array([0.1, 0.0, 0.0]),
                           tau_env=np.array([2e5, 1e5, 1e6]))
            out.append(ctrl.update(5.0 * k, est, Setpoint(eta_d=np.zeros(3))))
        assert ctrl.roll_pitch_disturbance is None
        cmds.append(np.array(out))
    assert cmds[0].tobytes() == cmds[1].tobytes()
    assert isinstance(build_controller(semi, {"type": "mpc", "roll_pitch_damping": True}), AttitudeAware)


# -- the forced roll and pitch oscillation in still water (as the PID's, test_semi_roll_pitch) ---------

def _forced_run(system, spec):
    ctrl = build_controller(system, spec)
    p = Plant(system, sea_state="none", seed=2, segments=10)
    p.rp[:2] = (math.radians(2.0), math.radians(1.0))   # released from 2 deg roll, 1 deg pitch
    return run_closed_loop(p, ctrl, ClosedLoopSettings(duration=220.0), system=system)


@pytest.fixture(scope="module")
def forced(semi):
    return {(kind, on): _forced_run(semi, {"type": kind, "roll_pitch_damping": on})
            for kind in ("lmpc", "mpc") for on in (False, True)}


def _rms(r, ch):
    w = r.time >= 40.0
    return float(np.sqrt(np.mean(r[ch][w] ** 2)))


@pytest.mark.parametrize("kind", ["lmpc", "mpc"])
def test_option_reduces_a_forced_roll_and_pitch_oscillation(semi, forced, kind):
    """Released from 2 deg roll and 1 deg pitch in still water, with and without the option
    (figures: docs/controllers.md): without it the MPC's position control feeds the roll and the
    pitch (positive work of the thrust's moments); with it the thrust takes energy out of both, the
    RMS roll after the first 40 s is smaller and the late roll swings too. (The RMS pitch is not
    asserted: the semi-taut lines' 32 s pitch is damped, but the MPC's steady surge thrust trims
    the hull by a fraction of a degree, which the RMS counts.)"""
    off, on = forced[(kind, False)], forced[(kind, True)]
    rp = semi.vessel.roll_pitch
    ell = rp.thruster_lever
    assert _rms(on, "roll") < 0.9 * _rms(off, "roll")

    def work(r):
        return (-ell * np.trapezoid(r["tau_thr[Y]"] * r["roll_rate"], r.time),
                ell * np.trapezoid(r["tau_thr[X]"] * r["pitch_rate"], r.time))

    (wr_off, wp_off), (wr_on, wp_on) = work(off), work(on)
    E_roll = 0.5 * rp.C[0] * math.radians(2.0) ** 2
    E_pitch = 0.5 * rp.C[1] * math.radians(1.0) ** 2
    assert wr_off > 2 * E_roll and wr_on < -2 * E_roll
    assert wp_off > 0 and wp_on < -0.25 * E_pitch
    late = on.time >= 110.0
    assert np.abs(on["roll"][late]).max() < 0.7 * np.abs(off["roll"][late]).max()


# -- bad input -----------------------------------------------------------------------------------

def test_bad_input_is_refused_naming_the_field(semi):
    fpso = System.from_scenario(load_scenario("fpso"))
    for kind in ("lmpc", "mpc"):
        with pytest.raises(ControllerSpecError, match=r"controller\.roll_pitch_damping: scenario 'fpso' has no"):
            build_controller(fpso, {"type": kind, "roll_pitch_damping": True})
    with pytest.raises(ControllerSpecError, match=r"roll_pitch_damping: unknown option\(s\) \['w_rol'\]"):
        build_controller(semi, {"type": "lmpc", "roll_pitch_damping": {"w_rol": 1.0}})
    with pytest.raises(ControllerSpecError, match=r"roll_pitch_damping\.w_pitch_rate = -1"):
        build_controller(semi, {"type": "lmpc", "roll_pitch_damping": {"w_pitch_rate": -1}})
    with pytest.raises(ControllerSpecError, match=r"roll_pitch_damping\.rate_ref = 0"):
        build_controller(semi, {"type": "mpc", "roll_pitch_damping": {"rate_ref": 0}})
    with pytest.raises(ControllerSpecError, match=r"roll_pitch_damping = 'yes' must be true, false or a table"):
        build_controller(semi, {"type": "lmpc", "roll_pitch_damping": "yes"})
    with pytest.raises(MPCError, match=r"roll_pitch_damping\.disturbance_time_constant = nan"):
        RollPitchWeights(disturbance_time_constant=float("nan"))
    with pytest.raises(MPCError, match="roll_pitch_damping: scenario 'fpso' has no"):
        NonlinearMPC(fpso, MPCSettings(roll_pitch_damping=True))
    ctrl = build_controller(semi, {"type": "lmpc", "roll_pitch_damping": True})
    with pytest.raises(MPCError, match="attitude"):
        ctrl.set_attitude(0.0, [0.0, float("nan"), 0.0, 0.0])
    with pytest.raises(MPCError, match="attitude"):
        ctrl.set_attitude(0.0, [0.0, 0.0, 0.0])
