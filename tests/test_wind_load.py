"""Tests of the one wind-load formula (tapm_opt.models.environment.HullWindLoad): closed forms
for head, beam and quartering wind, broadcasting, and the two callers (the plant's gusty wind
with the vessel velocity, the gain design's mean load) against it."""

from __future__ import annotations

import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.design.loads import mean_environmental_load
from tapm_opt.errors import ModelError
from tapm_opt.models.environment import HullWindLoad
from tapm_opt.plant.environment import Environment

HULL = dict(c_x=0.8, c_y=0.9, c_n=0.08, A_F=1200.0, A_L=6000.0, L_pp=250.0, rho_a=1.226)


@pytest.fixture(scope="module")
def hull():
    return HullWindLoad(**HULL)


def test_head_wind_pushes_astern(hull):
    """Wind going south onto a vessel heading north: gamma = 0, X = -1/2 rho V^2 c_x A_F."""
    V = 20.0
    tau = hull.tau(V, math.pi, 0.0)
    q = 0.5 * HULL["rho_a"] * V**2
    np.testing.assert_allclose(tau, [-q * HULL["c_x"] * HULL["A_F"], 0.0, 0.0], atol=1e-9 * q)


def test_beam_wind_from_port_pushes_to_starboard(hull):
    """Wind going east onto a vessel heading north comes from port (gamma = -90 deg):
    Y = +1/2 rho V^2 c_y A_L, no yaw moment (sin 2 gamma = 0)."""
    V = 15.0
    tau = hull.tau(V, 0.5 * math.pi, 0.0)
    q = 0.5 * HULL["rho_a"] * V**2
    np.testing.assert_allclose(tau, [0.0, q * HULL["c_y"] * HULL["A_L"], 0.0], atol=1e-9 * q * 1e3)


def test_quartering_wind_turns_the_bow_away(hull):
    """Wind from 45 deg off the starboard bow (gamma = 45 deg): every component against the
    closed form; the moment is negative, turning the bow to port, away from the wind."""
    V, gamma = 25.0, math.radians(45.0)
    beta_w = math.pi + gamma  # going to: opposite to where it comes from, heading 0
    tau = hull.tau(V, beta_w, 0.0)
    q = 0.5 * HULL["rho_a"] * V**2
    want = -q * np.array([HULL["c_x"] * math.cos(gamma) * HULL["A_F"],
                          HULL["c_y"] * math.sin(gamma) * HULL["A_L"],
                          HULL["c_n"] * math.sin(2 * gamma) * HULL["A_L"] * HULL["L_pp"]])
    np.testing.assert_allclose(tau, want, rtol=1e-12)
    assert tau[2] < 0.0 and tau[1] < 0.0
    # turning the vessel with the wind changes nothing: only beta_w - psi counts
    np.testing.assert_allclose(hull.tau(V, beta_w + 0.3, 0.3), tau, rtol=1e-12)


def test_arrays_broadcast_like_a_loop(hull):
    rng = np.random.default_rng(4)
    V, psi, u, v = rng.uniform(0, 30, 7), rng.uniform(-3, 3, 7), rng.normal(size=7), rng.normal(size=7)
    tau = hull.tau(V, 0.4, psi, u, v)
    assert tau.shape == (7, 3)
    for i in range(7):
        np.testing.assert_array_equal(tau[i], hull.tau(V[i], 0.4, psi[i], u[i], v[i]))
    # the vessel sailing with the wind at the wind speed feels no wind
    np.testing.assert_allclose(hull.tau(12.0, 0.0, 0.0, u=12.0), 0.0, atol=1e-9)


def test_bad_hull_raises():
    with pytest.raises(ModelError, match="rho_a"):
        HullWindLoad(**{**HULL, "rho_a": 0.0})
    with pytest.raises(ModelError, match="A_L"):
        HullWindLoad(**{**HULL, "A_L": float("nan")})


def test_plant_and_design_give_the_same_load():
    """The plant's wind load (gusts and vessel velocity) is HullWindLoad at the relative wind,
    and the gain design's mean wind load is the plant's at the mean speed (both call it)."""
    sc = tapm_opt.load_scenario("fpso")
    env = Environment(sc, "storm", seed=5)
    w = env.wind
    ves = sc.vessel
    hull = HullWindLoad(c_x=w.params.c_x, c_y=w.params.c_y, c_n=w.params.c_n,
                        A_F=ves.wind_area_frontal, A_L=ves.wind_area_lateral, L_pp=ves.length_pp,
                        rho_a=sc.environment.air_density)
    nu = np.array([0.4, -0.3, 0.002])
    for t, psi in ((0.0, 0.0), (37.5, 0.6), (800.0, -2.1)):
        np.testing.assert_array_equal(w.tau_wind(t, psi, nu),
                                      hull.tau(w.speed(t), w.direction, psi, nu[0], nu[1]))
        np.testing.assert_array_equal(w.tau_wind(t, psi), hull.tau(w.speed(t), w.direction, psi))
    for psi in (0.0, 1.0):
        load = mean_environmental_load(sc, "storm", psi, seed=5)
        np.testing.assert_array_equal(load.wind, hull.tau(w.mean_speed, w.direction, psi))
        assert np.abs(load.wind).max() > 1e5  # a real storm load, not zeros
