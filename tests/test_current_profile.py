"""Current-profile estimation from the tension cells and riser inclinometers
(tapm_opt.estimation.current_profile; docs/current_estimation.md).

The measurements are the plant's own models of the lines and the riser, independent of the
estimator's response model: the FEM's fairlead tensions settled under the true profile
(``studies.anchor_network.current_tension_share``, the plant's ``MooringFEM``) and the plant's
quasi-static riser in the true sea state's current (``RiserModel.from_scenario``), with the
scenario's sensor noise.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.estimation.current_profile import (CurrentEstimationError, CurrentProfileEstimator,
                                                 CurrentResponseModel, profile_shape)
from tapm_opt.models.riser import RiserModel
from tapm_opt.plant.mooring_fem import MooringFEM
from tapm_opt.studies.anchor_network import current_tension_share
from tapm_opt.studies.closed_loop import fem_static_tensions

SEGMENTS = 10


@pytest.fixture(scope="module")
def fpso():
    return load_scenario("fpso")


@pytest.fixture(scope="module")
def model(fpso):
    return CurrentResponseModel(fpso, fem_static_tensions(fpso, SEGMENTS), fpso.sea_state("normal"))


def _sea(sc, V, beta_deg):
    return dataclasses.replace(sc.sea_state("normal"), current_speed=V, current_direction=math.radians(beta_deg))


@pytest.fixture(scope="module")
def truth(fpso):
    """Per true current (V, beta): the FEM's fairlead tensions at rest at eta = 0 and the plant's
    riser model in that current."""
    fem = MooringFEM(fpso, segments=SEGMENTS)
    fem.initialise(np.zeros(3))
    fem.settle(np.zeros(3), max_time=3000.0)
    T_still = fem.fairlead_tension().copy()
    out = {}
    for V, b in ((0.8, 180.0), (0.6, 150.0), (1.0, 200.0)):
        ss = _sea(fpso, V, b)
        out[(V, b)] = (T_still + current_tension_share(fpso, ss, np.zeros(3), segments=SEGMENTS),
                       RiserModel.from_scenario(fpso, ss))
    return out


def _feed(est, sc, truth, schedule, seed=0):
    """Feed ``est`` 1-Hz samples of the truth with the scenario's sensor noise; ``schedule`` a list
    of (t_end, (V, beta_deg)). Returns the estimates."""
    rng = np.random.default_rng(seed)
    sig_T = sc.sensors.tension_std_rel * np.asarray(est.model.lines.MBS, float)
    sig_a = sc.sensors.riser_angle_std
    t = 0.0
    for t_end, key in schedule:
        T_true, riser = truth[key]
        u = key[0] * np.array([math.cos(math.radians(key[1])), math.sin(math.radians(key[1]))])
        a_true = riser.angles_at(np.zeros(3), u)
        while t < t_end:
            est.update(t, np.zeros(3), T_true + sig_T * rng.standard_normal(T_true.size),
                       a_true + sig_a * rng.standard_normal(4))
            t += 1.0
    return est.history


def test_response_model_matches_the_fem_under_current_off_its_grid(fpso, model):
    """Cross-check of two paths: eq. (CP2)'s superposed, Fourier-interpolated drag shares against the
    FEM settled under the true piecewise profile, at a speed and a direction off the basis grid
    (the basis is at 0.8 m/s, every 30 deg): within 6 kN, a quarter of the largest share (the
    linearity ASSUMPTION's error); and the riser path (CP3) against the riser in that profile."""
    ss = _sea(fpso, 1.1, 200.0)
    fem = current_tension_share(fpso, ss, np.zeros(3), segments=SEGMENTS)
    u = 1.1 * np.array([math.cos(ss.current_direction), math.sin(ss.current_direction)])
    mod = model.tension_share(u, 0.15)
    assert np.max(np.abs(fem)) > 30e3          # the share is there to be read
    assert np.max(np.abs(mod - fem)) < max(6e3, 0.25 * np.max(np.abs(fem)))
    assert np.max(np.abs(mod - fem)) < 0.25 * np.max(np.abs(fem))
    # a wrong direction is visibly worse: the model does depend on it
    u_wrong = 1.1 * np.array([math.cos(ss.current_direction + 1.0), math.sin(ss.current_direction + 1.0)])
    assert np.max(np.abs(model.tension_share(u_wrong, 0.15) - fem)) > 3 * np.max(np.abs(mod - fem))
    riser = RiserModel.from_scenario(fpso, ss)
    eta = np.array([4.0, -3.0, 0.1])
    share = riser.angles_at(eta, u) - riser.angles_at(eta, np.zeros(2))
    np.testing.assert_allclose(model.riser_share(eta, u, 0.15), share, rtol=0.01, atol=1e-6)


def test_profile_shape_of_the_piecewise_and_the_uniform_profile(fpso):
    """w(z) is 0 at the surface and 1 at the seabed; for fpso's 100/75/15 % profile
    phi = 1 - (1 - f_b) w reproduces it, f_b = 0.15; a uniform profile gets the linear shape."""
    ss = fpso.sea_state("normal")
    w, fb = profile_shape(ss, 1000.0)
    assert fb == pytest.approx(0.15)
    np.testing.assert_allclose(1 - (1 - fb) * w(np.array([0.0, 500.0, 1000.0])), [1.0, 0.75, 0.15], atol=1e-12)
    w_u, fb_u = profile_shape(dataclasses.replace(ss, current_profile="uniform", current_profile_depths=(),
                                                  current_profile_factors=()), 1000.0)
    assert fb_u == 1.0
    np.testing.assert_allclose(w_u(np.array([0.0, 250.0, 1000.0])), [0.0, 0.25, 1.0])


def test_converges_on_a_constant_profile(fpso, model, truth):
    """Tensions and riser angles of 0.8 m/s going south with the 100/75/15 % profile: after
    10 min the speed is within 0.03 m/s, the direction within 2 deg and the seabed factor within
    0.05 of the truth; the filter's 1-sigma covers the error within 4 sigma."""
    sc = fpso
    est = CurrentProfileEstimator(model, warmup=0.0,
                                  tension_noise=sc.sensors.tension_std_rel * np.asarray(model.lines.MBS),
                                  angle_noise=sc.sensors.riser_angle_std)
    h = _feed(est, sc, truth, [(600.0, (0.8, 180.0))])
    e = h[-1]
    assert len(h) >= 19
    assert abs(e.speed - 0.8) < 0.03
    assert abs(math.degrees(math.remainder(e.direction - math.pi, 2 * math.pi))) < 2.0
    assert abs(e.seabed_factor - 0.15) < 0.05
    assert abs(e.speed - 0.8) < 4 * e.std[0] + 0.01


def test_tensions_alone_give_the_speed_and_direction_with_the_shape_held(fpso, model, truth):
    """Without the riser the seabed factor is held (not observable, see the next test) and the
    speed and direction still converge: within 0.1 m/s and 8 deg after 10 min."""
    sc = fpso
    est = CurrentProfileEstimator(model, warmup=0.0,
                                  tension_noise=sc.sensors.tension_std_rel * np.asarray(model.lines.MBS),
                                  use_riser=False)
    assert not est.fit_seabed_factor
    e = _feed(est, sc, truth, [(600.0, (0.8, 180.0))])[-1]
    assert e.seabed_factor == pytest.approx(model.nominal_seabed_factor)
    assert abs(e.speed - 0.8) < 0.1
    assert abs(math.degrees(math.remainder(e.direction - math.pi, 2 * math.pi))) < 8.0


def test_observability_the_seabed_factor_needs_the_riser(fpso, model):
    """From the tensions alone, the tension pattern of f_b is that of the speed (the columns of the
    sensitivity are within 6 deg of parallel (5.1 deg)): the Fisher information of (V, f_b) is near singular.
    The riser angles (top and bottom weigh the profile differently) make it well conditioned."""
    sc = fpso
    est = CurrentProfileEstimator(model, use_riser=True)
    x = np.array([-0.8, 0.0, 0.15])
    J = est.jacobian(x, np.zeros(3))
    M = model.n_lines
    JT = J[:M]
    cosang = abs(JT[:, 0] @ JT[:, 2]) / (np.linalg.norm(JT[:, 0]) * np.linalg.norm(JT[:, 2]))
    assert cosang > math.cos(math.radians(6.0))
    sig = np.concatenate([sc.sensors.tension_std_rel * np.asarray(model.lines.MBS),
                          np.full(4, sc.sensors.riser_angle_std)])
    F_T = JT.T @ (JT / sig[:M, None] ** 2)
    F_all = J.T @ (J / sig[:, None] ** 2)
    sd_T = math.sqrt(np.linalg.inv(F_T)[2, 2])
    sd_all = math.sqrt(np.linalg.inv(F_all)[2, 2])
    assert sd_T > 1.0            # one tension sample: f_b unknown over its whole range
    assert sd_all < 0.1 * sd_T   # the inclinometers pin it


def test_tracks_a_step_in_the_current(fpso, model, truth):
    """0.6 m/s going 150 deg, then a step to 1.0 m/s going 200 deg at 600 s: 5 min after the
    step the estimate is within 0.05 m/s and 3 deg of the new current."""
    sc = fpso
    est = CurrentProfileEstimator(model, warmup=0.0,
                                  tension_noise=sc.sensors.tension_std_rel * np.asarray(model.lines.MBS),
                                  angle_noise=sc.sensors.riser_angle_std)
    h = _feed(est, sc, truth, [(600.0, (0.6, 150.0)), (900.0, (1.0, 200.0))], seed=3)
    before = [e for e in h if e.t <= 600.0][-1]
    assert abs(before.speed - 0.6) < 0.05
    e = h[-1]
    assert abs(e.speed - 1.0) < 0.05
    assert abs(math.degrees(math.remainder(e.direction - math.radians(200.0), 2 * math.pi))) < 3.0


def test_bad_input_is_refused_with_the_field_named(fpso, model):
    from tapm_opt.studies.closed_loop import ClosedLoopError, ClosedLoopSettings

    with pytest.raises(CurrentEstimationError, match="tension_noise"):
        CurrentProfileEstimator(model, tension_noise=-1.0)
    with pytest.raises(CurrentEstimationError, match="block"):
        CurrentProfileEstimator(model, block=0.0)
    with pytest.raises(CurrentEstimationError, match="x0"):
        CurrentProfileEstimator(model, x0=(0.0, math.nan, 0.1))
    est = CurrentProfileEstimator(model)
    with pytest.raises(CurrentEstimationError, match="tensions"):
        est.update(0.0, np.zeros(3), np.full(model.n_lines, math.nan))
    with pytest.raises(CurrentEstimationError, match="eta"):
        est.update(0.0, np.zeros(2), np.zeros(model.n_lines))
    with pytest.raises(CurrentEstimationError, match="riser_angles"):
        est.update(0.0, np.zeros(3), np.zeros(model.n_lines), np.zeros(3))
    with pytest.raises(CurrentEstimationError, match="n_directions"):
        CurrentResponseModel(fpso, fem_static_tensions(fpso, SEGMENTS), n_directions=2)
    with pytest.raises(CurrentEstimationError, match="settle"):
        CurrentResponseModel(fpso, None)
    with pytest.raises(ClosedLoopError, match="current = 'guess'"):
        ClosedLoopSettings(current="guess")
    with pytest.raises(ClosedLoopError, match="current"):
        ClosedLoopSettings(current="estimated", winch="tension", detector="none")


def test_study_file_refuses_a_bad_current_mode(tmp_path):
    from tapm_opt.studies.study import StudyError, load_study

    p = tmp_path / "s.toml"
    p.write_text('[study]\nname = "x"\nscenario = "fpso"\nduration = 10.0\n[[sea_states]]\nid = "normal"\n'
                 '[[controllers]]\ntype = "pid"\ncurrent = "guessed"\n')
    with pytest.raises(StudyError, match=r"controllers\[0\]\.current"):
        load_study(p)


def test_the_optimal_setpoint_reads_the_estimated_current(fpso):
    """The unified setpoint's working point takes the current source's surface current in place of
    the riser model's (the sea state's), and the riser model's while the source has none."""
    from tapm_opt.control.setpoint_opt import OptimalSetpoint
    from tapm_opt.interfaces import Estimate
    from tapm_opt.models.system import System

    system = System.from_scenario(fpso)
    riser = system.riser("normal")
    box = {"v": None}
    layer = OptimalSetpoint(system, "unified", riser=riser, current_source=lambda: box["v"])
    est = Estimate(t=0.0, eta=np.zeros(3), nu=np.zeros(3), tau_env=np.zeros(3))
    np.testing.assert_allclose(layer.working_point(est, frozenset()).v_c, riser.v_c)
    box["v"] = np.array([0.1, -0.5])
    np.testing.assert_allclose(layer.working_point(est, frozenset()).v_c, [0.1, -0.5])


def test_closed_loop_estimate_against_the_running_plant(fpso):
    """The whole path on the plant itself: fpso 'normal' (0.8 m/s going south, 100/75/15 %), PID,
    240 s with ``current = "estimated"``: the estimator's log carries an estimate per 30-s block
    after the 60-s warm-up, and the KPIs against the plant's current are within 0.02 m/s, 1 deg
    and 0.05 of the seabed factor."""
    from tapm_opt.models.system import System
    from tapm_opt.studies import ClosedLoopSettings, run_case_on

    run = run_case_on(System.from_scenario(fpso), "pid",
                      ClosedLoopSettings(duration=240.0, current="estimated", heading="fixed"),
                      sea_state="normal", seed=2, segments=SEGMENTS)
    result, kpis = run.result, run.kpis
    est = [e for e in result.meta["estimator_log"] if e.get("event") == "current estimate"]
    assert [round(e["t"]) for e in est] == [90, 120, 150, 180, 210, 240]
    assert result.meta["current"] == "estimated"
    assert kpis["current_speed_error"] < 0.02
    assert kpis["current_direction_error"] < 1.0
    assert kpis["current_seabed_factor_error"] < 0.05
