"""Closed loop: estimator, setpoint chasing, runner, the `tapm simulate` command, and the
MPC-vs-PID comparison on the FEM plant in the fpso design storm."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.cli import main
from tapm_opt.estimation.lowpass import EstimationError, LowPassEstimator
from tapm_opt.models import MooringModel
from tapm_opt.plant.simulator import Plant
from tapm_opt.results import Result
from tapm_opt.control.setpoint import FixedSetpoint, HeadingChasing
from tapm_opt.geometry import body_from_turret
from tapm_opt.interfaces import Estimate
from tapm_opt.studies.closed_loop import ClosedLoopError, ClosedLoopSettings, SetpointChasing, run_closed_loop
from tapm_opt.studies.controllers import ControllerSpecError, build_controller
from tapm_opt.studies.kpis import basic_kpis

FPSO = tapm_opt.load_scenario("fpso")


# -- estimator -----------------------------------------------------------------------------

def test_lowpass_passes_constant_and_attenuates_wave_motion():
    est = LowPassEstimator(MooringModel.from_scenario(FPSO))
    T_wave, A = 10.0, 2.0
    out = []
    for k in range(3000):
        t = 0.2 * k
        out.append(est.filter(t, [20.0 + A * math.sin(2 * math.pi * t / T_wave), -5.0], 0.1, np.zeros(3))[0])
    out = np.array(out)[-500:]
    assert np.allclose(out[:, 0].mean(), 20.0, atol=0.05)
    # |H| of a critically damped 2nd-order low pass at w: 1 / (1 + (w/wc)^2)
    w, wc = 2 * math.pi / T_wave, est.omega_c
    expected = A / (1 + (w / wc) ** 2)
    assert (out[:, 0].max() - out[:, 0].min()) / 2 == pytest.approx(expected, rel=0.05)
    assert np.allclose(out[:, 1], -5.0, atol=1e-6) and np.allclose(out[:, 2], 0.1, atol=1e-9)


def test_lowpass_velocity_is_the_rate_in_body_frame():
    est = LowPassEstimator(MooringModel.from_scenario(FPSO), omega_c=2 * math.pi / 20)
    psi = math.radians(90.0)  # heading east: a northward motion is a port (negative sway) velocity
    for k in range(2000):
        eta, nu, _ = est.filter(0.5 * k, [0.3 * 0.5 * k, 0.0], psi, np.zeros(3))
    # (the sampled, held input lags a ramp by half a sample: 0.2 % here)
    assert nu[0] == pytest.approx(0.0, abs=1e-6) and nu[1] == pytest.approx(-0.3, rel=5e-3)


def test_environment_estimate_is_the_quasi_static_balance():
    model = MooringModel.from_scenario(FPSO)
    est = LowPassEstimator(model, T_env=10.0)
    eta = np.array([30.0, -10.0, 0.2])
    tau_thr = np.array([1e6, -2e5, 3e7])
    for k in range(400):
        *_, tau_env = est.filter(float(k), eta[:2], eta[2], tau_thr)
    np.testing.assert_allclose(tau_env, -(model.force(eta) + tau_thr), rtol=1e-6, atol=1.0)


def test_estimator_rejects_bad_input():
    est = LowPassEstimator(MooringModel.from_scenario(FPSO))
    with pytest.raises(EstimationError, match="finite"):
        est.filter(0.0, [math.nan, 0.0], 0.0, np.zeros(3))
    with pytest.raises(EstimationError, match="omega_c"):
        LowPassEstimator(MooringModel.from_scenario(FPSO), omega_c=-1.0)


# -- setpoint and settings -----------------------------------------------------------------

def _est(t, eta, tau_env=(0.0, 0.0, 0.0)):
    return Estimate(t=t, eta=eta, nu=np.zeros(3), tau_env=tau_env)


def test_setpoint_chasing_follows_and_is_projected_into_the_safe_circle():
    ch = SetpointChasing(T=100.0, R=40.0, psi_d=0.3)
    sp = None
    for k in range(2000):
        sp = ch.update(float(k), _est(k, [30.0, 0.0, 0.0])).eta_d
    assert sp[0] == pytest.approx(30.0, rel=1e-6) and sp[2] == 0.3
    for k in range(2000, 4000):
        sp = ch.update(float(k), _est(k, [80.0, 60.0, 0.0])).eta_d
    assert math.hypot(sp[0], sp[1]) == pytest.approx(40.0, rel=1e-9)
    assert math.atan2(sp[1], sp[0]) == pytest.approx(math.atan2(60.0, 80.0), rel=1e-6)


def test_setpoint_chasing_follows_the_turret_not_the_body_origin():
    """The hull turned 25 deg about a turret 10 m off: the chased setpoint is the turret offset."""
    p_cot = np.array([91.44, 0.0])
    psi = math.radians(25.0)
    x, y = body_from_turret((8.0, -6.0), psi, p_cot)
    ch = SetpointChasing(T=50.0, R=None, psi_d=0.0, p_cot_B=p_cot)
    for k in range(2000):
        sp = ch.update(float(k), _est(k, [x, y, psi])).eta_d
    np.testing.assert_allclose(sp[:2], [8.0, -6.0], atol=1e-9)


def test_heading_chasing_turns_the_bow_into_the_weather():
    """A mean load toward the east (b_E = (0, 1 MN) in {E}) turns the heading setpoint until the bow
    points into it: psi_d = atan2(-b_y, -b_x) = -90 deg; the position setpoint is untouched."""
    layer = HeadingChasing(FixedSetpoint((0.0, 0.0, 0.3)), T=10.0, psi_0=0.3)
    for k in range(400):
        sp = layer.update(float(k), _est(k, [0.0, 0.0, 0.0], tau_env=(0.0, 1e6, 0.0))).eta_d
    assert sp[2] == pytest.approx(-math.pi / 2, abs=1e-6)
    assert tuple(sp[:2]) == (0.0, 0.0)


@pytest.mark.parametrize("kw, field", [({"duration": -1.0}, "duration"), ({"dt_log": 1.5}, "dt_log"),
                                       ({"setpoint": "chase"}, "setpoint"), ({"heading": "free"}, "heading")])
def test_closed_loop_settings_reject_bad_values(kw, field):
    with pytest.raises(ClosedLoopError, match=field):
        ClosedLoopSettings(**kw)


def test_controller_spec_errors_name_the_option():
    with pytest.raises(ControllerSpecError, match="type"):
        build_controller(FPSO, {"type": "lqg"})
    with pytest.raises(ControllerSpecError, match="horizn"):
        build_controller(FPSO, {"type": "mpc", "horizn": 10})
    with pytest.raises(ControllerSpecError, match="dt"):
        build_controller(FPSO, {"type": "lmpc", "dt": -1.0})


# -- runner and CLI ------------------------------------------------------------------------

def test_short_closed_loop_run_logs_consistent_channels(tmp_path):
    plant = Plant(FPSO, sea_state="normal", seed=1, segments=6)
    ctrl = build_controller(FPSO, {"type": "pid"})
    res = run_closed_loop(plant, ctrl, ClosedLoopSettings(duration=60.0, dt_log=2.0))
    assert res.time[-1] == pytest.approx(60.0) and len(res) == 31
    assert np.all(np.isfinite(res.data))
    # the thrusters deliver what was allocated (up to their lag): no force beyond capacity
    fmax = np.array([t.max_thrust for t in FPSO.thrusters])
    assert np.all(np.abs(res.group("f")) <= fmax * (1 + 1e-9))
    assert res.meta["diagnostics"]["controller_calls"] == 60
    res.save(tmp_path / "r.npz")
    assert Result.load(tmp_path / "r.npz").channels == res.channels


def test_tapm_simulate_writes_result_and_summary(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["simulate", "fpso", "--controller", "lmpc", "--duration", "30", "--sea-state", "normal",
                 "--segments", "6", "--out", str(out), "--option", "horizon=10"])
    text = capsys.readouterr().out
    assert code == 0, text
    summary = json.loads((out / "summary.json").read_text())
    res = Result.load(out / "result.npz")
    assert summary["kpis"]["offset_max"] == pytest.approx(basic_kpis(res, FPSO)["offset_max"])
    assert summary["controller"] == {"type": "lmpc", "horizon": 10}
    assert "offset max" in text


def test_tapm_simulate_bad_option_is_a_clear_error(tmp_path, capsys):
    code = main(["simulate", "fpso", "--controller", "mpc", "--duration", "10", "--out", str(tmp_path / "x"),
                 "--option", "horizn=5"])
    err = capsys.readouterr().err
    assert code == 2 and "horizn" in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()


# -- the comparison the workbench exists for -------------------------------------------------

@pytest.fixture(scope="module")
def storm_runs():
    """PID and linear MPC (default tunings) in the fpso design storm, 20 min, same seed."""
    out = {}
    for kind in ("pid", "lmpc"):
        plant = Plant(FPSO, sea_state="storm", seed=3, segments=10)
        res = run_closed_loop(plant, build_controller(FPSO, {"type": kind}),
                              ClosedLoopSettings(duration=1200.0, heading="chasing"))
        out[kind] = (res, basic_kpis(res, FPSO))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["pid", "lmpc"])
def test_storm_vessel_stays_inside_safe_circle_and_tensions_below_limit(storm_runs, kind):
    res, k = storm_runs[kind]
    assert k["offset_max"] < FPSO.limits.safe_radius
    assert k["utilisation_max"] < FPSO.limits.tension_utilisation
    assert k.get("solver_failures", 0.0) == 0.0


@pytest.mark.slow
def test_storm_mpc_uses_no_more_thrust_energy_than_pid(storm_runs):
    e_pid = storm_runs["pid"][1]["thrust_energy"]
    e_mpc = storm_runs["lmpc"][1]["thrust_energy"]
    assert e_mpc <= e_pid, f"MPC {e_mpc / 3.6e9:.2f} MWh vs PID {e_pid / 3.6e9:.2f} MWh"
