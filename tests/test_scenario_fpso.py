"""The built-in fpso on its true chain-wire-chain composite lines, and fpso_equivalent, the
homogeneous equivalent line it had before, kept for comparison.

* both load, validate and are listed with the built-ins; fpso's lines are the header's sections,
  with winches on the top chain;
* the numbers fpso's header gives are what the quasi-static model computes (pretension at the
  design's 19.3 % MBS on the 2021.7 m anchor circle, touchdown, stiffness, natural periods,
  restoring curve, winch range);
* the header's comparison with the equivalent line (pretension, touchdown, stiffness at rest and
  under offset, most loaded line) is what the two scenarios give;
* the FEM plant at fpso's own segments settles on the quasi-static solution, at a stable step not
  much smaller than the equivalent's.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tapm_opt.config import builtin_scenarios, load_scenario, validate
from tapm_opt.models.mooring import MooringModel
from tapm_opt.plant.mooring_fem import MooringFEM

ZERO = np.zeros(3)
COT = np.array([91.44, 0.0])


@pytest.fixture(scope="module")
def sc():
    return load_scenario("fpso")


@pytest.fixture(scope="module")
def eq():
    return load_scenario("fpso_equivalent")


@pytest.fixture(scope="module")
def model(sc):
    return MooringModel.from_scenario(sc)


@pytest.fixture(scope="module")
def model_eq(eq):
    return MooringModel.from_scenario(eq)


def south(d: float) -> np.ndarray:
    return np.array([-d, 0.0, 0.0])


# --------------------------------------------------------------------------------------------
# loads and validates
# --------------------------------------------------------------------------------------------


def test_both_load_validate_and_are_builtins(sc, eq):
    assert {"fpso", "fpso_equivalent"} <= set(builtin_scenarios())
    assert sc.name == "fpso" and eq.name == "fpso_equivalent"
    assert validate(sc) == [] and validate(eq) == []
    for ln, sec in zip(sc.lines, sc.line_sections):
        assert ln.composite and [s.type for s in ln.sections] == ["chain137", "wire165", "chain137"]
        assert sec["L"].tolist() == [300.0, 1900.0, 100.0] and sec["segments"].tolist() == [3, 16, 1]
        assert ln.length == 2300.0 and ln.winch_max_rate == 0.15
        assert ln.length_limits == (2250.0, 2350.0)   # the winch hauls in at most half the top chain
        # anchors on the 2021.7 m circle about the COT, rounded to 0.1 mm
        assert np.hypot(*(np.array(ln.anchor[:2]) - COT)) == pytest.approx(2021.7, abs=1e-4)
    for ln in eq.lines:
        assert not ln.composite and ln.type == "cwc137" and ln.length == 2300.0
        assert np.hypot(*(np.array(ln.anchor[:2]) - COT)) == pytest.approx(1970.0, abs=1e-3)
    # the wire is the stronger: the chain's MBS is the line's
    assert sc.line_type_by_id("wire165").MBS > sc.line_type_by_id("chain137").MBS == sc.line_arrays["MBS"][0]
    # everything but the mooring and the hull's wave motion model is the equivalent's (fpso moves
    # in six degrees of freedom, the equivalent keeps the earlier surge, sway and yaw)
    assert sc.vessel.wave_motion.model == "six_dof" and eq.vessel.wave_motion.model == "horizontal"
    assert dataclasses.replace(sc.vessel.wave_motion, model="horizontal") == eq.vessel.wave_motion
    assert dataclasses.replace(sc.vessel, wave_motion=eq.vessel.wave_motion) == eq.vessel
    for f in ("environment", "turret", "thrusters", "sea_states", "riser", "limits"):
        assert getattr(sc, f) == getattr(eq, f), f


# --------------------------------------------------------------------------------------------
# the header's numbers (tapm_opt/config/scenarios/fpso.toml, "CHECKED WITH ...")
# --------------------------------------------------------------------------------------------


def test_header_pretension_touchdown_and_net_load(sc, model):
    sol = model.solve_lines(ZERO)
    MBS = sc.line_arrays["MBS"]
    _, _, XF = model.spans(ZERO)
    np.testing.assert_allclose(XF, 2013.7, atol=1e-3)
    np.testing.assert_allclose(model.ZF, 982.0)
    np.testing.assert_allclose(sol.LBot, 187.0, atol=0.5)               # in the 300 m bottom chain
    np.testing.assert_allclose(sol.TF, 3.270e6, rtol=5e-4)
    np.testing.assert_allclose(sol.TF / MBS, 0.192, atol=5e-4)
    np.testing.assert_allclose(sol.HF, 2.178e6, rtol=5e-4)
    np.testing.assert_allclose(sol.VF, 2.439e6, rtol=5e-4)
    np.testing.assert_allclose(np.degrees(np.arctan2(sol.VF, sol.HF)), 48.2, atol=0.05)
    np.testing.assert_allclose(sol.TF / sc.line_type_by_id("chain137").EA, 0.0020, atol=5e-5)
    tau = model.force(ZERO)
    assert abs(tau[0]) < 2.0 and abs(tau[1]) < 1e-3 and abs(tau[2]) < 1e-3   # |X| = 1 N


def test_header_stiffness_periods_and_restoring_curve(sc, model):
    K = model.stiffness(ZERO)
    assert K[0, 0] == pytest.approx(1.398e5, rel=1e-3) and K[1, 1] == pytest.approx(K[0, 0], rel=1e-6)
    assert K[2, 2] == pytest.approx(1.169e9, rel=1e-3) and K[1, 2] == pytest.approx(1.278e7, rel=1e-3)
    T = 2 * np.pi * np.sqrt(np.diag(sc.vessel.M) / np.diag(K))
    np.testing.assert_allclose(T, [258.7, 358.9, 295.4], atol=0.1)
    MBS = sc.line_arrays["MBS"][0]
    for d, F, Tm in zip((20.0, 40.0, 60.0, 80.0), (3.07e6, 6.89e6, 12.96e6, 26.92e6),
                        (3.825e6, 4.629e6, 6.094e6, 9.800e6)):
        assert model.force(south(d))[0] == pytest.approx(F, abs=0.01e6), d
        T_d = model.tensions(south(d))
        assert np.argmax(T_d) == 1 and np.max(T_d) == pytest.approx(Tm, abs=0.005e6), d
    assert model.stiffness(south(40.0))[0, 0] == pytest.approx(2.17e5, rel=2e-3)
    assert model.stiffness(south(80.0))[0, 0] == pytest.approx(1.03e6, rel=2e-3)
    # the most loaded line lifts its anchor from about 40 m and is near its MBS at 100 m
    s60, s80 = model.solve_lines(south(60.0)), model.solve_lines(south(80.0))
    assert np.degrees(np.arctan2(s60.VA[1], s60.HA[1])) == pytest.approx(7.5, abs=0.05)
    assert np.degrees(np.arctan2(s80.VA[1], s80.HA[1])) == pytest.approx(14.9, abs=0.05)
    assert np.max(model.tensions(south(100.0))) / MBS == pytest.approx(0.998, abs=5e-4)
    # the alert radius is just inside the utilisation limit
    assert np.max(model.tensions(south(sc.limits.alert_radius))) < sc.limits.tension_utilisation * MBS


def test_header_winch_range(sc, model):
    _, _, XF = model.spans(ZERO)
    MBS = sc.line_arrays["MBS"][0]
    short = model.solve_xf(XF, L=np.full(12, 2250.0))
    long = model.solve_xf(XF, L=np.full(12, 2350.0))
    np.testing.assert_allclose(short.TF, 5.45e6, rtol=1e-3)
    assert np.all(short.LBot == 0.0)
    np.testing.assert_allclose(long.TF, 2.632e6, rtol=1e-3)
    np.testing.assert_allclose(long.TF / MBS, 0.155, atol=5e-4)


def test_header_comparison_with_the_homogeneous_equivalent(sc, eq, model, model_eq):
    """The header's table: the equivalent line at the same pretension is too soft, lays too much
    on the seabed and carries about half the real most-loaded-line tension at 80 m."""
    a, b = model_eq.solve_lines(ZERO), model.solve_lines(ZERO)
    assert a.TF[0] == pytest.approx(3.273e6, rel=5e-4) and a.TF[0] / b.TF[0] - 1 == pytest.approx(0.001, abs=5e-4)
    assert a.HF[0] == pytest.approx(1.980e6, rel=1e-3) and a.VF[0] == pytest.approx(2.606e6, rel=1e-3)
    assert a.LBot[0] == pytest.approx(325.0, abs=0.5) and a.LBot[0] / b.LBot[0] - 1 == pytest.approx(0.74, abs=0.005)
    rows = [(0.0, 8.59e4, 1.398e5, -0.39), (40.0, 1.02e5, 2.17e5, -0.53), (80.0, 1.70e5, 1.03e6, -0.83)]
    for d, k_eq, k, off in rows:
        ke, kc = model_eq.stiffness(south(d))[0, 0], model.stiffness(south(d))[0, 0]
        assert ke == pytest.approx(k_eq, rel=5e-3) and kc == pytest.approx(k, rel=5e-3), d
        assert ke / kc - 1 == pytest.approx(off, abs=0.005), d
    T_eq, T = np.max(model_eq.tensions(south(80.0))), np.max(model.tensions(south(80.0)))
    assert T_eq == pytest.approx(4.93e6, abs=0.005e6) and T == pytest.approx(9.80e6, abs=0.005e6)
    assert T_eq / T - 1 == pytest.approx(-0.50, abs=0.005)
    assert model_eq.force(south(80.0))[0] / model.force(south(80.0))[0] - 1 == pytest.approx(-0.68, abs=0.005)
    T_p = 2 * np.pi * np.sqrt(sc.vessel.M[0, 0] / model_eq.stiffness(ZERO)[0, 0])
    assert T_p == pytest.approx(330.1, abs=0.1)


# --------------------------------------------------------------------------------------------
# the FEM plant at rest
# --------------------------------------------------------------------------------------------


def test_fem_at_rest_and_its_stable_step(sc, eq, model):
    """At fpso's own segments (3 / 16 / 1) the settled FEM's fairlead tension is 0.12 % below the
    quasi-static one (the discretisation; 0.08 % on the equivalent's 20 segments), and the stable
    step 13.9 ms, 11 % below the equivalent's 15.6 ms."""
    m = MooringFEM(sc)
    m.initialise(ZERO)
    m.settle(ZERO, tol=1e-9, speed_tol=1e-4, max_time=3000.0)
    err = m.fairlead_tension() / model.tensions(ZERO) - 1.0
    assert np.all(np.abs(err + 0.0012) < 3e-4), err
    dt, dt_eq = m.dt, MooringFEM(eq).dt
    assert dt == pytest.approx(0.0139, abs=1e-4) and dt_eq == pytest.approx(0.0156, abs=1e-4)
    assert dt > 0.85 * dt_eq
