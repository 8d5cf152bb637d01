"""Tests of the plant thrusters (tapm_opt.plant.thrusters) and sensors (tapm_opt.plant.sensors):
closed-form responses, limits, hand-computed generalised forces and power, failures, bad input,
sample-and-hold timing, noise statistics and reproducibility."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tapm_opt.config import Thruster, load_scenario
from tapm_opt.geometry import ssa
from tapm_opt.plant.environment import PlantError
from tapm_opt.plant.sensors import Measurement, Sensors, SensorSpec
from tapm_opt.plant.thrusters import EFFICIENCY, THRUST_LOADING, ThrusterBank

RHO_W = 1025.0


def azimuth(**kw) -> Thruster:
    base = dict(id="az", kind="azimuth", position=(-100.0, 0.0), angle=0.0, max_thrust=5e5,
                max_thrust_rate=1e9, max_azimuth_rate=math.radians(10.0), time_constant=4.0)
    base.update(kw)
    return Thruster(**base)


def tunnel(**kw) -> Thruster:
    base = dict(id="tn", kind="tunnel", position=(100.0, 0.0), angle=math.pi / 2, max_thrust=2e5,
                max_reverse_thrust=1.5e5, max_thrust_rate=1e9, time_constant=2.0)
    base.update(kw)
    return Thruster(**base)


def run(bank: ThrusterBank, seconds: float, dt: float, f_cmd, alpha_cmd=None) -> None:
    for _ in range(round(seconds / dt)):
        bank.step(dt, f_cmd, alpha_cmd)


# --- thrust response ----------------------------------------------------------------------------

@pytest.mark.parametrize("dt", [0.01, 0.1, 0.5])
def test_first_order_step_reaches_63_percent_at_T(dt):
    bank = ThrusterBank([azimuth(), tunnel()], RHO_W)
    cmd = np.array([4e5, -1e5])
    run(bank, 4.0, dt, cmd)  # t = T of the azimuth (4 s) and 2 T of the tunnel (2 s)
    np.testing.assert_allclose(bank.f, cmd * [1 - math.exp(-1.0), 1 - math.exp(-2.0)], rtol=1e-9)


def test_thrust_rate_limit_gives_a_ramp():
    bank = ThrusterBank([azimuth(max_thrust_rate=2e4)], RHO_W)
    f_prev, dt = 0.0, 0.05
    for k in range(1, 101):
        bank.step(dt, [5e5])
        assert bank.f[0] - f_prev <= 2e4 * dt * (1 + 1e-12)
        f_prev = bank.f[0]
    assert bank.f[0] == pytest.approx(2e4 * 5.0)  # rate-limited the whole 5 s (lag would be faster)


def test_saturation():
    bank = ThrusterBank([azimuth(), tunnel()], RHO_W)
    run(bank, 150.0, 0.1, [9e9, -9e9])
    np.testing.assert_allclose(bank.f, [5e5, -1.5e5], rtol=1e-9)
    run(bank, 150.0, 0.1, [-9e9, 9e9])  # an azimuth cannot push backwards
    np.testing.assert_allclose(bank.f, [0.0, 2e5], atol=1e-6)


def test_azimuth_turns_the_shortest_way_at_its_rate():
    bank = ThrusterBank([azimuth(angle=math.radians(170.0))], RHO_W)
    target, rate, dt = math.radians(-170.0), math.radians(10.0), 0.1
    bank.step(dt, [0.0], [target])
    assert ssa(bank.alpha[0] - math.radians(170.0)) == pytest.approx(rate * dt)  # through 180 deg
    for _ in range(18):  # 19 steps of 1 deg in total
        bank.step(dt, [0.0], [target])
    assert ssa(bank.alpha[0] - math.radians(170.0)) == pytest.approx(math.radians(19.0))
    bank.step(dt, [0.0], [target])
    bank.step(dt, [0.0], [target])  # the 20 deg are covered; no overshoot
    assert bank.alpha[0] == pytest.approx(target)
    assert -math.pi <= bank.alpha[0] < math.pi


def test_tunnel_keeps_its_axis_and_instantaneous_azimuth():
    bank = ThrusterBank([tunnel(), azimuth(max_azimuth_rate=None)], RHO_W)
    bank.step(0.1, [0.0, 0.0], [1.0, 2.5])
    np.testing.assert_allclose(bank.alpha, [math.pi / 2, 2.5])


@settings(max_examples=40, deadline=None)
@given(dt=st.floats(1e-3, 2.0), f=st.lists(st.floats(-1e6, 1e6), min_size=2, max_size=2),
       a=st.lists(st.floats(-10.0, 10.0), min_size=2, max_size=2), f0=st.floats(0.0, 5e5),
       a0=st.floats(-math.pi, math.pi))
def test_limits_always_hold(dt, f, a, f0, a0):
    bank = ThrusterBank([azimuth(max_thrust_rate=3e4), tunnel(max_thrust_rate=1e4)], RHO_W)
    bank.reset(f=[f0, 0.0], alpha=[a0, 0.0])
    f_before, a_before = bank.f, bank.alpha
    bank.step(dt, f, a)
    assert np.all(np.abs(bank.f - f_before) <= np.array([3e4, 1e4]) * dt * (1 + 1e-9) + 1e-9)
    assert 0.0 <= bank.f[0] <= 5e5 and -1.5e5 <= bank.f[1] <= 2e5
    assert abs(ssa(bank.alpha[0] - a_before[0])) <= math.radians(10.0) * dt * (1 + 1e-9)
    assert bank.alpha[1] == pytest.approx(math.pi / 2)


# --- outputs ------------------------------------------------------------------------------------

def test_tau_two_thrusters_by_hand():
    bank = ThrusterBank([tunnel(position=(50.0, 0.0)), azimuth(position=(-40.0, 10.0))], RHO_W)
    bank.reset(f=[1e5, 2e5], alpha=[0.0, 0.0])
    # tunnel at x = 50 pushing to starboard: (0, 1e5, +50*1e5); azimuth at (-40, 10) pushing
    # forward: (2e5, 0, -10*2e5)
    np.testing.assert_allclose(bank.tau(), [2e5, 1e5, 5e6 - 2e6], atol=1e-6)
    bank.reset(f=[-1e5, 2e5], alpha=[0.0, math.pi / 2])  # azimuth at x = -40 pushing starboard
    np.testing.assert_allclose(bank.tau(), [0.0, -1e5 + 2e5, -5e6 - 40 * 2e5], atol=1e-6)
    np.testing.assert_allclose(bank.T_alloc() @ bank.f, bank.tau())


def test_power_is_actuator_disk_with_documented_constants():
    bank = ThrusterBank([azimuth(), tunnel()], RHO_W)
    bank.reset(f=[1e5, -1e5])
    p1 = bank.power()
    bank.reset(f=[4e5, 1e5])
    p2 = bank.power()
    assert p2[0] / p1[0] == pytest.approx(4**1.5)
    assert p2[1] == pytest.approx(p1[1])  # reverse thrust costs the same
    area = 5e5 / THRUST_LOADING  # 10 m^2, i.e. a 3.57 m disk
    assert p2[0] == pytest.approx(4e5**1.5 / (EFFICIENCY * math.sqrt(2 * RHO_W * area)))
    bank.reset(f=[5e5, 0.0])  # full thrust: about 3.5 MW, 0.14 kN/kW
    assert 5e5 / bank.power()[0] == pytest.approx(EFFICIENCY * math.sqrt(2 * RHO_W / THRUST_LOADING))
    assert 3e6 < bank.power()[0] < 4e6


def test_failed_thruster_gives_zero():
    bank = ThrusterBank([tunnel(), azimuth()], RHO_W)
    run(bank, 10.0, 0.1, [1e5, 1e5])
    bank.fail("tn")
    assert bank.f[0] == 0.0 and bank.failed.tolist() == [True, False]
    run(bank, 10.0, 0.1, [1e5, 1e5])
    assert bank.f[0] == 0.0 and bank.f[1] > 0 and bank.power()[0] == 0.0
    np.testing.assert_allclose(bank.tau(), [bank.f[1], 0.0, 0.0], atol=1e-9)
    with pytest.raises(PlantError, match="no such thruster"):
        bank.fail(5)


def test_bad_commands_raise_and_do_not_change_the_state():
    bank = ThrusterBank([tunnel(), azimuth()], RHO_W)
    run(bank, 1.0, 0.1, [1e5, 1e5])
    f = bank.f
    with pytest.raises(PlantError, match=r"f_cmd\[1\]=nan for thruster 'az'"):
        bank.step(0.1, [1e5, math.nan])
    with pytest.raises(PlantError, match=r"alpha_cmd\[0\]=inf"):
        bank.step(0.1, [1e5, 1e5], [math.inf, 0.0])
    with pytest.raises(PlantError, match="shape"):
        bank.step(0.1, [1e5])
    with pytest.raises(PlantError, match="dt"):
        bank.step(0.0, [1e5, 1e5])
    np.testing.assert_array_equal(bank.f, f)
    assert np.all(np.isfinite(bank.alpha))


def test_from_scenario_and_bad_parameters():
    sc = dataclasses.replace(load_scenario("aamo4"), thrusters=(azimuth(), tunnel()))
    bank = ThrusterBank.from_scenario(sc)
    assert bank.ids == ("az", "tn") and bank.n == 2
    np.testing.assert_allclose(bank.alpha, [0.0, math.pi / 2])
    with pytest.raises(PlantError, match=r"thrusters\[0\].time_constant"):
        ThrusterBank([azimuth(time_constant=-1.0)], RHO_W)
    assert ThrusterBank([], RHO_W).tau().tolist() == [0.0, 0.0, 0.0]


# --- sensors ------------------------------------------------------------------------------------

MBS = np.array([5e6, 6e6, 7e6])
ETA = np.array([10.0, -5.0, 0.3])
TENS = np.array([1e6, 1.2e6, 0.9e6])


def test_sample_and_hold_timing():
    s = Sensors(SensorSpec(), 3, seed=1, MBS=MBS)
    first = s.sample(0.0, ETA, TENS)
    heading_times = {first.t_heading}
    for k in range(1, 10):  # t = 0.11 ... 0.99 s: the 1 Hz GNSS and tension values are held
        m = s.sample(0.11 * k, ETA, TENS)
        np.testing.assert_array_equal(m.position, first.position)
        np.testing.assert_array_equal(m.tensions, first.tensions)
        assert m.t_position == 0.0 and m.t_tensions == 0.0
        heading_times.add(m.t_heading)
    assert len(heading_times) == 10  # 10 Hz heading: new sample each 0.11 s call
    m = s.sample(1.0, ETA, TENS)
    assert m.t_position == 1.0 and not np.array_equal(m.position, first.position)
    # a step of 30 ms: the 1 Hz sensors refresh only once the next whole second is crossed
    m2 = s.sample(1.03, ETA, TENS)
    assert m2.t_position == 1.0 and m2.t_tensions == 1.0


def test_noise_statistics_match_spec():
    spec = SensorSpec()
    s = Sensors(spec, 3, seed=4, MBS=MBS)
    ms = [s.sample(float(k), ETA, TENS) for k in range(4000)]
    pos = np.array([m.position for m in ms])
    hdg = np.array([m.heading for m in ms])
    ten = np.array([m.tensions for m in ms])
    np.testing.assert_allclose(pos.std(axis=0), spec.gnss_std, rtol=0.05)
    np.testing.assert_allclose(pos.mean(axis=0), ETA[:2], atol=4 * spec.gnss_std / math.sqrt(4000))
    assert hdg.std() == pytest.approx(spec.heading_std, rel=0.05)
    np.testing.assert_allclose(ten.std(axis=0), spec.tension_std_rel * MBS, rtol=0.05)
    # the tension noise scales with each line's MBS
    s2 = Sensors(dataclasses.replace(spec, tension_std_rel=0.01), 3, seed=4, MBS=MBS)
    ten2 = np.array([s2.sample(float(k), ETA, TENS).tensions for k in range(2000)])
    np.testing.assert_allclose(ten2.std(axis=0), 0.01 * MBS, rtol=0.07)


def test_heading_is_wrapped():
    s = Sensors(SensorSpec(heading_std=0.05), 0, seed=0)
    h = np.array([s.sample(0.1 * k, [0.0, 0.0, math.pi - 1e-3], []).heading for k in range(500)])
    assert np.all((h >= -math.pi) & (h < math.pi)) and np.any(h < 0) and np.any(h > 0)


def test_sensors_reproducible():
    def record(seed):
        s = Sensors(SensorSpec(), 3, seed=seed, MBS=MBS)
        return np.array([np.r_[m.position, m.heading, m.tensions]
                         for m in (s.sample(0.5 * k, ETA, TENS) for k in range(50))])
    np.testing.assert_array_equal(record(9), record(9))
    assert not np.allclose(record(9), record(10))


def test_sensors_bad_input_and_immutability():
    s = Sensors(SensorSpec(), 3, seed=0, MBS=MBS)
    m = s.sample(1.0, ETA, TENS)
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.heading = 0.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        m.position[0] = 0.0
    with pytest.raises(PlantError, match=r"bad lines \[1\]"):
        s.sample(2.0, ETA, [1e6, math.nan, 1e6])
    with pytest.raises(PlantError, match="eta_total"):
        s.sample(2.0, [0.0, 0.0], TENS)
    with pytest.raises(PlantError, match="before"):
        s.sample(0.5, ETA, TENS)
    with pytest.raises(PlantError, match="MBS"):
        Sensors(SensorSpec(), 3, seed=0)
    with pytest.raises(PlantError, match="gnss_rate"):
        Sensors(SensorSpec(gnss_rate=0.0), 3, seed=0, MBS=MBS)
    with pytest.raises(PlantError, match="heading_std"):
        Sensors(SensorSpec(heading_std=math.nan), 3, seed=0, MBS=MBS)
    sc = load_scenario("aamo4")
    assert isinstance(Sensors.from_scenario(sc, seed=1).sample(0.0, ETA, np.ones(4)), Measurement)
