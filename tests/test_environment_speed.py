"""The plant's per-step environment path (scalar-time wave sums and wind speed with work arrays,
the float path of ``HullWindLoad.tau`` with ``math.cos``/``math.sin``, the unclamped
``np.interp`` of a piecewise current profile, the float pose of ``RiserModel.angles_at``) against
the original numpy formulas, written out here independently: every comparison is bit-identical
(np.array_equal, no tolerance; the wind load, whose fast path takes its cosines from the C library,
to round-off on a machine whose numpy has its own float64 sin/cos, ``_bitwise.LIBM_TRIG``), and the
cached sums are recomputed when the time or the heading changes."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.models.environment import CurrentProfile, HullWindLoad
from tapm_opt.plant.environment import Environment

from _bitwise import assert_same

TIMES = (0.0, 0.1, 12.3, 299.9, 1234.5)
HEADINGS = (0.0, 0.05, -1.3, 2.9)


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


@pytest.fixture(scope="module")
def env(fpso):
    return Environment(fpso, "normal", seed=3)


def _hull_numpy(hull, V, beta_w, psi, u, v):
    """The original wind-load formula, numpy on scalars (np.subtract, np.cos, np.sin)."""
    b = np.subtract(beta_w, psi)
    u_rw = u - V * np.cos(b)
    v_rw = v - V * np.sin(b)
    V_rw = np.hypot(u_rw, v_rw)
    return hull.k * np.array((V_rw * u_rw, V_rw * v_rw, u_rw * v_rw))


def _wave_numpy(waves, t, psi):
    """Original sums, WF motion, its rate and the drift load at one time and heading."""
    th = t * waves.omega + waves.phase
    S, C = waves._Ws @ np.sin(th), waves._Wc @ np.cos(th)
    beta = waves.direction - psi
    cb, sb, s2b = math.cos(beta), math.sin(beta), math.sin(2.0 * beta)
    c, s = math.cos(psi), math.sin(psi)
    rot = lambda xb, yb, z: np.array([c * xb - s * yb, s * xb + c * yb, z])
    drift = waves._drift_c * np.array([cb * abs(cb), sb * abs(sb), -s2b])
    return (rot(cb * S[0], sb * S[1], s2b * C[0]), rot(cb * C[2], sb * C[3], -s2b * S[2]),
            np.multiply.outer(2.0 * C[1] * C[1], drift))


def test_float_wind_load_is_the_numpy_formula(env):
    hull = env.wind.hull
    rng = np.random.default_rng(0)
    for V, beta, psi, u, v in rng.uniform(-4.0, 30.0, (200, 5)):
        fast = hull.tau(float(V), float(beta), float(psi), float(u), float(v))
        assert_same(fast, _hull_numpy(hull, V, beta, psi, u, v))


def test_array_wind_load_keeps_the_numpy_path():
    hull = HullWindLoad(c_x=0.8, c_y=0.9, c_n=0.08, A_F=1000.0, A_L=4000.0, L_pp=250.0, rho_a=1.226)
    V, psi = np.array([5.0, 20.0, 0.0]), np.array([0.1, -2.0, 1.0])
    tau = hull.tau(V, 0.7, psi)
    assert tau.shape == (3, 3)
    assert_same(tau[1], _hull_numpy(hull, 20.0, 0.7, -2.0, 0.0, 0.0))


def test_wind_speed_and_load_are_the_original_formulas(env):
    w = env.wind
    nu = np.array([0.3, -0.2, 0.001])
    for t in TIMES:
        V = max(w.mean_speed + float(w.amplitude @ np.cos(t * w._w + w.phase)), 0.0)
        assert w.speed(t) == V
        for psi in HEADINGS:
            assert_same(w.tau_wind(t, psi, nu), _hull_numpy(w.hull, V, w.direction, psi, 0.3, -0.2))
            assert_same(w.tau_wind(t, psi), _hull_numpy(w.hull, V, w.direction, psi, 0.0, 0.0))


def test_wind_load_still_rejects_bad_velocity(env):
    with pytest.raises(ValueError, match="must be 3 finite numbers"):
        env.wind.tau_wind(1.0, 0.0, [0.1, math.nan, 0.0])
    with pytest.raises(ValueError, match="must be 3 finite numbers"):
        env.wind.tau_wind(1.0, 0.0, [0.1, 0.2])


def test_wave_motion_and_drift_are_the_original_formulas_and_the_cache_follows_t_and_psi(env):
    waves = env.waves
    seen = []
    for t in TIMES + TIMES[::-1]:  # revisits every time after others: a stale cache would show
        for psi in HEADINGS:
            ref = _wave_numpy(waves, t, psi)
            got = (env.eta_wf(t, psi), env.eta_wf_dot(t, psi), waves.tau_drift(t, psi))
            assert all(np.array_equal(g, r) for g, r in zip(got, ref)), (t, psi)
            seen.append(got[0])
    assert not np.array_equal(seen[0], seen[len(HEADINGS)])  # the motion does change with t


def test_cached_sums_are_not_overwritten_by_the_next_time(env):
    waves = env.waves
    S1, C1 = waves._sums(7.0)
    keep = S1.copy(), C1.copy()
    waves._sums(8.0)
    assert np.array_equal(S1, keep[0]) and np.array_equal(C1, keep[1])
    assert waves._sums(7.0)[0] is not S1 and np.array_equal(waves._sums(7.0)[0], keep[0])


def test_loads_of_the_plant_are_the_original_formulas(env):
    eta, nu = np.array([3.0, -2.0, 0.2]), np.array([0.1, 0.05, -0.002])
    loads = env.loads(42.0, eta, nu)
    V = env.wind.speed(42.0)
    assert_same(loads["tau_wind"], _hull_numpy(env.wind.hull, V, env.wind.direction, 0.2, 0.1, 0.05))
    assert np.array_equal(loads["tau_drift"], _wave_numpy(env.waves, 42.0, 0.2)[2])


@pytest.mark.parametrize("depths, factors", [((0.0, 500.0, 1000.0), (1.0, 0.75, 0.15)),
                                             ((100.0, 400.0), (0.9, 0.2)),
                                             ((50.0, 700.0, 1500.0), (1.0, 0.5, 0.0))])
def test_piecewise_current_is_the_clamped_interpolation(fpso, depths, factors):
    ss = dataclasses.replace(fpso.sea_state("normal"), current_profile="piecewise",
                             current_profile_depths=depths, current_profile_factors=factors)
    prof = CurrentProfile(ss, 1000.0)
    assert prof._interp_clamps == (depths[-1] <= 1000.0)
    z = np.concatenate([[-np.inf, -5.0, -0.0, 0.0, 1000.0, 1e4, np.inf], depths,
                        np.linspace(-50.0, 1200.0, 301)])
    ref = np.interp(np.minimum(np.maximum(z, 0.0), 1000.0), np.array(depths), np.array(factors))
    assert np.array_equal(prof.factor(z), ref)
    fin = np.isfinite(z)
    assert np.array_equal(prof.velocity(z[fin]), np.multiply.outer(ref[fin], prof.surface))


def test_riser_angles_of_an_array_pose_are_those_of_its_floats(fpso):
    from tapm_opt.models.riser import RiserModel

    riser = RiserModel.from_scenario(fpso, "normal")
    eta = np.array([4.0, -3.0, 0.3])
    assert np.array_equal(riser.angles_at(eta), riser.angles_at([4.0, -3.0, 0.3]))
    assert np.array_equal(riser.angles_at(eta.astype(np.float32)), riser.angles_at(eta.astype(np.float32).tolist()))
    with pytest.raises(tapm_opt.errors.ModelError, match="finite"):
        riser.angles_at(np.array([0.0, math.nan, 0.0]))


def test_one_blas_thread_sets_and_restores_the_blas_threads():
    """The drift and vertical blocks' BLAS context: inside it every BLAS library the process loaded
    runs one thread, outside it the count it had (restored, also after an exception)."""
    pytest.importorskip("threadpoolctl")
    from threadpoolctl import threadpool_info

    from tapm_opt.plant import environment as env

    def counts():
        return [d["num_threads"] for d in threadpool_info() if d["user_api"] == "blas"]

    before = counts()
    with env._one_blas_thread():
        assert counts() and all(n == 1 for n in counts())
    assert counts() == before
    with pytest.raises(RuntimeError), env._one_blas_thread():
        raise RuntimeError("inside")
    assert counts() == before
