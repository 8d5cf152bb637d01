"""Tests of the plant environment (tapm_opt.plant.environment): spectra against closed forms and
hand-computed values, statistics of the synthesised records, sign conventions of the loads,
reproducibility of the random streams, and bad input."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from tapm_opt.config import SeaState, load_scenario
from tapm_opt.errors import ModelError
from tapm_opt.plant.environment import (
    CurrentProfile,
    Environment,
    PlantError,
    WaveField,
    WaveParams,
    Wind,
    WindParams,
    jonswap,
    npd_spectrum,
)

SC = load_scenario("aamo4")  # vessel L_pp 230 m, B 41 m, T 12 m, A_F 1100 m^2, A_L 4600 m^2
VES, ENV = SC.vessel, SC.environment
RHO_A = ENV.air_density
N, E, S, W = 0.0, math.pi / 2, math.pi, -math.pi / 2  # directions going to


def sea(**kw) -> SeaState:
    base = dict(id="test", Hs=0.0, Tp=10.0)
    base.update(kw)
    return SeaState(**base)


# --- JONSWAP ------------------------------------------------------------------------------------

@pytest.mark.parametrize("gamma", [1.0, 2.0, 3.3, 5.0, 7.0])
@pytest.mark.parametrize("Hs, Tp", [(2.0, 7.0), (8.0, 14.0)])
def test_jonswap_area_is_Hs2_over_16(gamma, Hs, Tp):
    wp = 2 * math.pi / Tp
    m0 = quad(lambda w: float(jonswap(w, Hs, Tp, gamma)), 0.0, 30 * wp, points=[wp], limit=400)[0]
    assert m0 == pytest.approx(Hs**2 / 16, rel=0.02)


def test_jonswap_gamma_1_is_pierson_moskowitz_and_peak_enhancement():
    Hs, Tp = 4.0, 10.0
    wp = 2 * math.pi / Tp
    w = np.linspace(0.2, 3.0, 57)
    pm = 5 / 16 * Hs**2 * wp**4 * w**-5 * np.exp(-1.25 * (w / wp) ** -4)
    np.testing.assert_allclose(jonswap(w, Hs, Tp, 1.0), pm, rtol=1e-12)
    # at the peak the enhancement is exactly A_gamma * gamma
    g = 3.3
    ratio = jonswap(wp, Hs, Tp, g) / jonswap(wp, Hs, Tp, 1.0)
    assert ratio == pytest.approx((1 - 0.287 * math.log(g)) * g, rel=1e-12)
    assert jonswap(0.0, Hs, Tp) == 0.0
    assert np.all(jonswap(w, 0.0, Tp) == 0.0)


@pytest.mark.parametrize("kw, field", [(dict(Hs=-1.0), "Hs"), (dict(Hs=math.nan), "Hs"), (dict(Tp=0.0), "Tp"),
                                       (dict(gamma=0.5), "gamma"), (dict(omega=[1.0, -0.1]), "omega[1]")])
def test_jonswap_bad_input(kw, field):
    args = dict(omega=[1.0], Hs=2.0, Tp=8.0, gamma=3.3)
    args.update(kw)
    with pytest.raises(PlantError, match=re.escape(field)):
        jonswap(**args)


# --- current ------------------------------------------------------------------------------------

def test_current_uniform_direction_and_shape():
    c = CurrentProfile(sea(current_speed=1.2, current_direction=E), 500.0)
    v = c.velocity(np.array([0.0, 100.0, 500.0]))
    assert v.shape == (3, 3)
    np.testing.assert_allclose(v, [[0.0, 1.2, 0.0]] * 3, atol=1e-15)
    assert c.velocity(20.0).shape == (3,)


def test_current_linear_endpoints_and_midpoint():
    c = CurrentProfile(sea(current_speed=2.0, current_direction=N, current_profile="linear",
                           current_profile_factors=(0.25,)), 1000.0)
    u = c.velocity([0.0, 500.0, 1000.0, 1200.0])[:, 0]
    np.testing.assert_allclose(u, [2.0, 2.0 * 0.625, 0.5, 0.5])  # below the seabed: clamped


def test_current_piecewise_interpolation_and_constant_beyond():
    c = CurrentProfile(sea(current_speed=1.0, current_direction=S, current_profile="piecewise",
                           current_profile_depths=(0.0, 50.0, 200.0), current_profile_factors=(1.0, 0.6, 0.2)), 1000.0)
    u = c.velocity([0.0, 25.0, 50.0, 125.0, 200.0, 800.0])[:, 0]
    np.testing.assert_allclose(u, -np.array([1.0, 0.8, 0.6, 0.4, 0.2, 0.2]), atol=1e-15)


def test_current_bad_input():
    """The profile is the models' (a ModelError); the plant's Environment reports it as a PlantError."""
    with pytest.raises(ModelError, match="current_profile"):
        CurrentProfile(sea(current_profile="piecewise", current_profile_depths=(0.0, 10.0),
                           current_profile_factors=(1.0,)), 100.0)
    with pytest.raises(ModelError, match="current_speed"):
        CurrentProfile(sea(current_speed=-1.0), 100.0)
    with pytest.raises(ModelError, match=r"z\[1\]"):
        CurrentProfile(sea(current_speed=1.0), 100.0).velocity([1.0, math.nan])
    sc = dataclasses.replace(SC, sea_states=(sea(id="bad", current_speed=-1.0),))
    with pytest.raises(PlantError, match="current_speed"):
        Environment(sc, "bad", 0)


# --- waves --------------------------------------------------------------------------------------

def waves(seed=0, **kw) -> WaveField:
    return WaveField(sea(**{"Hs": 6.0, "Tp": 12.0, **kw}), VES, ENV, seed)


T_LONG = np.arange(0.0, 3 * 3600.0, 1.0)


def test_wave_elevation_std_is_Hs_over_4():
    wf = waves(seed=3)
    assert np.sum(wf.amplitude**2) / 2 == pytest.approx(6.0**2 / 16, rel=0.02)
    assert np.std(wf.elevation(T_LONG)) == pytest.approx(6.0 / 4, rel=0.04)


def test_wf_surge_zero_in_beam_seas_nonzero_in_head_seas():
    beam = waves(wave_direction=E).eta_wf(T_LONG, 0.0)
    head = waves(wave_direction=S).eta_wf(T_LONG, 0.0)
    assert np.std(beam[:, 0]) < 1e-12
    assert np.std(beam[:, 1]) > 0.5
    assert np.std(head[:, 0]) > 0.1
    assert np.std(head[:, 1]) < 1e-12
    # R(psi) maps the body motion into {E}: waves going east on a vessel heading east move it
    # east exactly as waves going north move a vessel heading north (same seed, same realisation)
    rot = waves(wave_direction=E).eta_wf(T_LONG[:500], E)
    ref = waves(wave_direction=N).eta_wf(T_LONG[:500], 0.0)
    np.testing.assert_allclose(rot[:, [1, 0, 2]] * [1, -1, 1], ref, atol=1e-12)


def test_wf_long_waves_follow_orbital_motion_with_90_degree_phase():
    wf = waves(Tp=30.0, wave_direction=N)  # following seas, waves much longer than the hull
    zeta, x, xdot = wf.elevation(T_LONG), wf.eta_wf(T_LONG, 0.0)[:, 0], wf.eta_wf_dot(T_LONG, 0.0)[:, 0]
    assert 0.7 * np.std(zeta) < np.std(x) < np.std(zeta)
    assert abs(np.corrcoef(x, zeta)[0, 1]) < 0.1  # displacement in quadrature with the elevation
    assert np.corrcoef(xdot, zeta)[0, 1] > 0.9  # orbital velocity in phase with the elevation


def test_wf_short_waves_are_filtered_by_the_hull():
    short, long_ = waves(Tp=5.0, wave_direction=S), waves(Tp=20.0, wave_direction=S)
    assert np.std(short.eta_wf(T_LONG, 0.0)[:, 0]) < 0.02 * np.std(short.elevation(T_LONG))
    assert np.std(long_.eta_wf(T_LONG, 0.0)[:, 0]) > 0.4 * np.std(long_.elevation(T_LONG))


def test_wf_yaw_zero_in_head_and_beam_seas_nonzero_oblique():
    for d in (S, E):
        assert np.max(np.abs(waves(wave_direction=d).eta_wf(T_LONG[:2000], 0.0)[:, 2])) < 1e-12
    yaw = waves(wave_direction=3 * math.pi / 4).eta_wf(T_LONG, 0.0)[:, 2]
    assert 1e-3 < np.std(yaw) < math.radians(3.0)


def test_eta_wf_dot_is_the_time_derivative():
    wf = waves(wave_direction=2.5)
    t, h = np.array([3.0, 100.0, 1234.5]), 1e-4
    fd = (wf.eta_wf(t + h, 0.4) - wf.eta_wf(t - h, 0.4)) / (2 * h)
    np.testing.assert_allclose(wf.eta_wf_dot(t, 0.4), fd, rtol=1e-6, atol=1e-9)
    # scalar and array evaluation agree (cached scalar path)
    np.testing.assert_allclose(wf.eta_wf(100.0, 0.4), wf.eta_wf(t, 0.4)[1], rtol=1e-12)


def test_drift_time_mean_equals_newman_mean_and_hand_formula():
    wf = waves(seed=5, wave_direction=2.2)
    psi = 0.3
    F = wf.tau_drift(T_LONG, psi)
    newman = wf.mean_drift(psi)
    np.testing.assert_allclose(F.mean(axis=0), newman, rtol=0.03)
    # independent evaluation of sum_k D(w_k) a_k^2
    beta = 2.2 - psi
    k = wf.omega**2 / ENV.gravity
    R = 1 - np.exp(-2 * k * VES.draught)
    c = 0.5 * ENV.water_density * ENV.gravity
    D = np.stack([c * VES.breadth * R * math.cos(beta) * abs(math.cos(beta)),
                  c * VES.length_pp * R * math.sin(beta) * abs(math.sin(beta)),
                  -c * VES.length_pp**2 * WaveParams().drift_yaw * R * math.sin(2 * beta)], axis=1)
    np.testing.assert_allclose(newman, wf.amplitude**2 @ D, rtol=1e-12)


@settings(max_examples=30, deadline=None)
@given(direction=st.floats(-math.pi, math.pi), psi=st.floats(-math.pi, math.pi))
def test_mean_drift_pushes_along_wave_direction(direction, psi):
    wf = waves(wave_direction=direction)
    X, Y, _ = wf.mean_drift(psi)
    F_E = np.array([math.cos(psi) * X - math.sin(psi) * Y, math.sin(psi) * X + math.cos(psi) * Y])
    assert F_E @ [math.cos(direction), math.sin(direction)] > 0
    # the slowly varying force never reverses direction (Newman form keeps the sign)
    F = wf.tau_drift(np.arange(0.0, 600.0, 7.0), psi)
    assert np.all(F[:, 0] * X >= 0) and np.all(F[:, 1] * Y >= 0)


def test_drift_magnitudes_and_yaw_turns_broadside():
    head, beam = waves(wave_direction=S).mean_drift(0.0), waves(wave_direction=E).mean_drift(0.0)
    assert head[0] < 0 and beam[1] > 0
    assert 1e5 < -head[0] < 2e6 and 1e6 < beam[1] < 1e7  # FPSO order of magnitude in Hs = 6 m
    # waves from the port bow (going to beta in (pi/2, pi)): + N turns the bow to starboard,
    # bringing the waves toward the beam; from the starboard bow: - N
    assert waves(wave_direction=S - 0.4).mean_drift(0.0)[2] > 0
    assert waves(wave_direction=-(S - 0.4)).mean_drift(0.0)[2] < 0


def test_calm_sea_gives_zero_waves_and_drift():
    wf = waves(Hs=0.0)
    t = np.arange(0.0, 100.0, 0.5)
    assert np.all(wf.tau_drift(t, 0.2) == 0) and np.all(wf.eta_wf(t, 0.2) == 0)
    assert np.all(wf.eta_wf_dot(t, 0.2) == 0) and np.all(wf.elevation(t) == 0)


def test_waves_bad_input():
    with pytest.raises(PlantError, match="sea_state.Hs"):
        waves(Hs=-1.0)
    with pytest.raises(PlantError, match="sea_state.Tp"):
        waves(Tp=math.nan)
    with pytest.raises(PlantError, match="psi"):
        waves().eta_wf(1.0, math.nan)
    with pytest.raises(PlantError, match="t"):
        waves().tau_drift(math.inf, 0.0)
    with pytest.raises(PlantError, match="omega_max"):
        WaveParams(omega_min=2.0, omega_max=1.0)


# --- wind ---------------------------------------------------------------------------------------

def test_npd_spectrum_hand_computed_points():
    # U10 = 20, z = 10, f = 0.01: x = 172*0.01*2^-0.75 = 1.02273, 1 + x^0.468 = 2.01056,
    # S = 320*4 / 2.01056^3.5613 = 1280 / 12.028 = 106.42 m^2/s
    assert npd_spectrum(0.01, 20.0) == pytest.approx(106.42, rel=2e-4)
    # U10 = 10, z = 10, f = 0: S = 320 m^2/s (low-frequency plateau)
    assert npd_spectrum(0.0, 10.0) == pytest.approx(320.0, rel=1e-12)
    # U10 = 10, z = 40, f = 0.1: x = 172*0.1*4^(2/3) = 43.341, x^0.468 = 5.8354,
    # S = 320*4^0.45 / 6.8354^3.5613 = 597.14 / 939.30 = 0.63573
    assert npd_spectrum(0.1, 10.0, 40.0) == pytest.approx(0.63573, rel=2e-4)
    assert np.all(npd_spectrum([0.0, 0.1], 0.0) == 0.0)


def test_gust_variance_matches_spectrum():
    p = WindParams()
    w = Wind(sea(wind_speed=20.0), VES, ENV, 11, params=p)
    target = quad(lambda f: float(npd_spectrum(f, 20.0)), p.f_min, p.f_max, limit=400,
                  points=[1e-3, 1e-2, 1e-1])[0]
    assert np.sum(w.amplitude**2) / 2 == pytest.approx(target, rel=0.03)
    V = w.speed(np.arange(0.0, 20 * 3600.0, 1.0))
    assert np.var(V) == pytest.approx(target, rel=0.1)
    assert np.mean(V) == pytest.approx(20.0, rel=0.02)
    assert w.speed(123.0) == pytest.approx(float(w.speed(np.array([123.0]))[0]), rel=1e-12)


def wind_load_case(direction, psi, nu=None, t=50.0):
    w = Wind(sea(wind_speed=15.0, wind_direction=direction), VES, ENV, 2)
    return w.tau_wind(t, psi, nu), w.speed(t)


def test_wind_sign_conventions():
    p = WindParams()
    tau, V = wind_load_case(N, 0.0)  # wind going north, vessel heading north: pushed forward
    np.testing.assert_allclose(tau, [0.5 * RHO_A * V**2 * p.c_x * VES.wind_area_frontal, 0, 0], atol=1e-6)
    tau, V = wind_load_case(E, 0.0)  # wind going east: pushed to starboard
    np.testing.assert_allclose(tau, [0, 0.5 * RHO_A * V**2 * p.c_y * VES.wind_area_lateral, 0], atol=1e-6)
    tau, V = wind_load_case(N, E)  # vessel heading east, wind going north = toward port
    assert tau[1] == pytest.approx(-0.5 * RHO_A * V**2 * p.c_y * VES.wind_area_lateral)
    # from the starboard bow (coming from +45 deg, going to -135 deg): bow turned away, N < 0
    tau, V = wind_load_case(-3 * math.pi / 4, 0.0)
    assert tau[0] < 0 and tau[1] < 0
    assert tau[2] == pytest.approx(-0.5 * RHO_A * V**2 * p.c_n * VES.wind_area_lateral * VES.length_pp)


def test_relative_wind():
    _, V = wind_load_case(N, 0.0)
    tau, _ = wind_load_case(N, 0.0, nu=[V, 0.0, 0.01])  # moving with the wind
    np.testing.assert_allclose(tau, 0.0, atol=1e-9)
    still, _ = wind_load_case(N, 0.0)
    against, _ = wind_load_case(N, 0.0, nu=[-V, 0.0, 0.0])
    assert against[0] == pytest.approx(4 * still[0])
    with pytest.raises(PlantError, match="nu"):
        wind_load_case(N, 0.0, nu=[0.0, math.nan, 0.0])


def test_no_wind_gives_zero():
    w = Wind(sea(wind_speed=0.0), VES, ENV, 0)
    assert w.speed(10.0) == 0.0
    np.testing.assert_array_equal(w.tau_wind(10.0, 0.3), 0.0)


# --- Environment --------------------------------------------------------------------------------

def env(seed=0, **kw) -> Environment:
    ss = sea(**{"Hs": 5.0, "Tp": 11.0, "wave_direction": 2.0, "wind_speed": 18.0, "wind_direction": 2.3,
                "current_speed": 0.8, **kw})
    return Environment(SC, ss, seed)


def test_environment_loads_shapes_and_consistency():
    e = env()
    eta, nu = np.array([3.0, -2.0, 0.4]), np.array([0.1, 0.0, 0.0])
    out = e.loads(12.0, eta, nu)
    assert set(out) == {"tau_wind", "tau_drift"}
    np.testing.assert_array_equal(out["tau_wind"], e.wind.tau_wind(12.0, 0.4, nu))
    np.testing.assert_array_equal(out["tau_drift"], e.waves.tau_drift(12.0, 0.4))
    assert e.eta_wf(12.0, 0.4).shape == (3,) and e.current_at(np.zeros(7)).shape == (7, 3)
    # the sea state can be chosen by id; an unknown id is a PlantError
    sc = dataclasses.replace(SC, sea_states=(sea(id="calm"), sea(id="storm", Hs=9.0, Tp=14.0)))
    assert Environment(sc, "storm", 0).waves.Hs == 9.0
    assert Environment(sc, None, 0).waves.Hs == 0.0
    with pytest.raises(PlantError, match="nope"):
        Environment(sc, "nope", 0)


def test_environment_reproducible_and_independent_streams():
    t = np.arange(0.0, 300.0, 3.0)
    a, b, c = env(seed=7), env(seed=7), env(seed=8)
    np.testing.assert_array_equal(a.eta_wf(t, 0.1), b.eta_wf(t, 0.1))
    np.testing.assert_array_equal(a.wind.speed(t), b.wind.speed(t))
    assert not np.allclose(a.eta_wf(t, 0.1), c.eta_wf(t, 0.1))
    assert not np.allclose(a.wind.speed(t), c.wind.speed(t))
    # a different wind leaves the wave realisation unchanged, and vice versa
    np.testing.assert_array_equal(env(seed=7, wind_speed=5.0).eta_wf(t, 0.1), a.eta_wf(t, 0.1))
    np.testing.assert_array_equal(env(seed=7, Hs=2.0).wind.speed(t), a.wind.speed(t))
    # frequencies are drawn at random inside their bins (no repetition period), from two
    # independent streams (the wave and wind draws are not the same numbers)
    wp, p = 2 * math.pi / 11.0, WaveParams()
    dw = (p.omega_max - p.omega_min) * wp / p.n_components
    u_wave = (a.waves.omega - p.omega_min * wp) / dw - np.arange(p.n_components)
    edges = np.geomspace(WindParams().f_min, WindParams().f_max, WindParams().n_components + 1)
    u_wind = (a.wind.freq - edges[:-1]) / np.diff(edges)
    for u in (u_wave, u_wind):
        assert np.all((u >= 0) & (u <= 1)) and np.std(u) > 0.2
    assert abs(np.corrcoef(u_wave[:u_wind.size], u_wind)[0, 1]) < 0.3
    assert not np.allclose(a.waves.omega, c.waves.omega) and not np.allclose(a.wind.freq, c.wind.freq)


def test_environment_calm():
    e = env(Hs=0.0, wind_speed=0.0)
    out = e.loads(33.0, [0.0, 0.0, 1.0])
    np.testing.assert_array_equal(out["tau_wind"], 0.0)
    np.testing.assert_array_equal(out["tau_drift"], 0.0)
    np.testing.assert_array_equal(e.eta_wf(33.0, 1.0), 0.0)


def test_heading_is_periodic():
    e, tw = env(), 2 * math.pi
    for key in ("tau_drift", "tau_wind"):
        np.testing.assert_allclose(e.loads(5.0, [0, 0, 0.3])[key], e.loads(5.0, [0, 0, 0.3 + tw])[key],
                                   rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(e.eta_wf(5.0, 0.3), e.eta_wf(5.0, 0.3 - tw), rtol=1e-9, atol=1e-12)
