"""Short-crested seas (directional spreading) and sea states that develop within a run.

* Spreading: the components' directions follow the cos-2s distribution; the spectrum's energy is
  the long-crested one's; the surge motion in head seas shrinks by the mean cos^2 of the
  directions; the mean drift is the components' directional mean; the compiled and numpy plants
  agree; a long-crested sea is untouched.
* Development: the elevation is continuous where the table turns; Hs, the wind and the current
  reach their table values; the rows are checked; the supervisor switches the PID's modes in
  closed loop as a storm builds (survey §4.5), not on replayed estimates.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from _bitwise import assert_same
from _six_dof import horizontal, six_dof

import tapm_opt
from tapm_opt.config import scenario_from_dict, scenario_to_dict, validate
from tapm_opt.config.schema import SeaStateRow
from tapm_opt.plant import fem_kernel
from tapm_opt.plant.environment import (
    N_HEADINGS,
    DevelopingWaveField,
    DevelopingWind,
    Environment,
    spreading_directions,
)
from tapm_opt.plant.simulator import Plant, run_open_loop


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


def with_sea(sc, sid, **changes):
    """The scenario with sea state ``sid`` changed."""
    ss = [dataclasses.replace(s, **changes) if s.id == sid else s for s in sc.sea_states]
    return dataclasses.replace(sc, sea_states=tuple(ss))


# --- short-crested seas -------------------------------------------------------------------------

@pytest.mark.parametrize("s", [2.0, 8.0, 40.0])
def test_spreading_directions_follow_the_cos_2s_distribution(s):
    rng = np.random.default_rng(0)
    d = spreading_directions(s, rng, 4000)
    assert np.all(np.abs(d) <= math.pi)
    # moments of D = cos^(2s)(theta/2): E[cos theta] = s/(s+1), E[cos 2 theta] = s(s-1)/((s+1)(s+2))
    assert np.mean(np.cos(d)) == pytest.approx(s / (s + 1), abs=2e-3)
    assert np.mean(np.cos(2 * d)) == pytest.approx(s * (s - 1) / ((s + 1) * (s + 2)), abs=4e-3)
    assert abs(np.mean(np.sin(d))) < 0.01   # symmetric about the mean direction


def test_spreading_keeps_the_energy_and_spreads_the_motion(fpso):
    long = Environment(fpso, "storm", seed=7).waves
    short = Environment(with_sea(fpso, "storm", wave_spreading=6.0), "storm", seed=7).waves
    # the same components (frequencies, phases, amplitudes): the spectrum's energy and the elevation
    assert np.array_equal(long.amplitude, short.amplitude) and np.array_equal(long.omega, short.omega)
    t = np.arange(0.0, 3.0 * 3600.0, 0.5)
    assert np.array_equal(long.elevation(t), short.elevation(t))
    # surge in head seas (heading 0, waves going south): variance sum a^2 h_L^2 cos^2(delta) / 2
    x_l, x_s = long.eta_wf(t, 0.0)[:, 0], short.eta_wf(t, 0.0)[:, 0]
    w, a, g = long.omega, long.amplitude, fpso.environment.gravity
    h_L = 1.0 / (1.0 + (w / math.sqrt(math.pi * g / fpso.vessel.length_pp)) ** 4)
    ratio = np.sum(a**2 * h_L**2 * np.cos(short.delta) ** 2) / np.sum(a**2 * h_L**2)
    assert x_s.var() / x_l.var() == pytest.approx(ratio, rel=0.05)
    s = 6.0
    assert ratio == pytest.approx(0.5 * (1 + s * (s - 1) / ((s + 1) * (s + 2))), abs=0.05)   # E[cos^2]
    # and the sea now sways the hull in head seas, which a long-crested one does not
    assert np.abs(long.eta_wf(t, 0.0)[:, 1]).max() < 1e-9 < short.eta_wf(t, 0.0)[:, 1].std()


def test_short_crested_mean_drift_is_the_directional_mean(fpso):
    sc = with_sea(fpso, "storm", wave_spreading=4.0)
    w = Environment(sc, "storm", seed=3).waves
    B, L = fpso.vessel.breadth, fpso.vessel.length_pp
    rho, g = fpso.environment.water_density, fpso.environment.gravity
    c0 = 0.5 * rho * g * np.array([B, L, w.params.drift_yaw * L**2])
    for psi in (0.0, 0.3, 1.2, -2.0):
        beta = w.direction - psi + w.delta
        cb, sb = np.cos(beta), np.sin(beta)
        c = np.stack([cb * np.abs(cb), sb * np.abs(sb), -np.sin(2 * beta)], axis=-1) * c0
        direct = (w.amplitude**2 * w.reflection) @ c
        scale = np.abs(direct).max()
        assert np.allclose(w.mean_drift(psi), direct, rtol=0, atol=0.01 * scale)   # the 5-degree grid
    # head seas: a spread sea drifts less along the hull than a long-crested one, and sideways at all
    long = Environment(fpso, "storm", seed=3).waves
    assert abs(w.mean_drift(0.0)[0]) < abs(long.mean_drift(0.0)[0])


@pytest.mark.skipif(not fem_kernel.AVAILABLE, reason="numba is not installed")
@pytest.mark.parametrize("model", ["horizontal", "six_dof"])
def test_compiled_and_numpy_plants_agree_in_a_short_crested_sea(fpso, model):
    sc = with_sea(fpso, "storm", wave_spreading=5.0)
    sc = dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, wave_motion=dataclasses.replace(
        sc.vessel.wave_motion, model=model)))
    runs = []
    for compiled in (True, False):
        p = Plant(sc, sea_state="storm", seed=2)
        p.compiled = compiled
        runs.append(run_open_loop(p, 20.0))
    assert_same(runs[0].data, runs[1].data)
    i = runs[0].channels.index("y_wf")
    assert np.abs(runs[0].data[:, i]).max() > 0.01   # the spread sea sways the hull in head seas


def test_a_long_crested_sea_carries_no_grid(fpso):
    """Without spreading and heave, roll and pitch no heading grid; the closed form's heave, roll
    and pitch alone carry one of three columns per heading."""
    w = Environment(horizontal(fpso), "storm", seed=1).waves
    assert w.spreading is None and w._drift_grid.size == 0 and w._Wv.shape[1] == 0
    assert not w.grid_horizontal
    w6 = Environment(six_dof(fpso), "storm", seed=1).waves
    assert w6.spreading is None and w6._drift_grid.size == 0 and w6._Wv.shape[1] == 3 * N_HEADINGS
    assert not w6.grid_horizontal
    assert N_HEADINGS == fem_kernel.N_HEADINGS


# --- developing sea states ----------------------------------------------------------------------

def storm_building(sc, *, hold=1200.0, ramp=600.0, end=7200.0):
    """fpso's normal sea state (Hs 7 m) that builds to the storm's Hs, Tp, wind and current
    between ``hold`` and ``hold + ramp`` seconds and stays there until ``end``."""
    a, b = sc.sea_state("normal"), sc.sea_state("storm")
    keep = {f: getattr(a, f) for f in ("Hs", "Tp", "wind_speed", "current_speed")}
    top = {f: getattr(b, f) for f in ("Hs", "Tp", "wind_speed", "current_speed")}
    rows = (SeaStateRow(t=hold, **keep), SeaStateRow(t=hold + ramp, **top), SeaStateRow(t=end, **top))
    return with_sea(sc, "normal", development=rows)


def test_a_developing_sea_is_continuous_and_reaches_its_table(fpso):
    sc = storm_building(fpso)
    env = Environment(sc, "normal", seed=4)
    assert isinstance(env.waves, DevelopingWaveField) and isinstance(env.wind, DevelopingWind) and env.develops
    w = env.waves
    # no jump where the table turns: the elevation is continuous at the corners
    for tc in (1200.0, 1800.0):
        e = 1e-7
        assert abs(w.elevation(tc + e) - w.elevation(tc - e)) < 1e-5
    # Hs before and after (4 sigma of the elevation over 20 and 90 minutes: sampling error a few %)
    t = np.arange(0.0, 7200.0, 0.25)
    z = w.elevation(t)
    assert 4 * z[t < 1200].std() == pytest.approx(fpso.sea_state("normal").Hs, rel=0.1)
    assert 4 * z[t >= 1800].std() == pytest.approx(fpso.sea_state("storm").Hs, rel=0.1)
    # the block sums are the scalar sums (the plant's path)
    S, C = w.block(1500.0, 0.1, 300)
    for j in (0, 150, 299):
        s, c = w._sums(1500.0 + 0.1 * j)
        assert np.allclose(S[j], s, rtol=1e-9, atol=1e-12) and np.allclose(C[j], c, rtol=1e-9, atol=1e-12)
    # the wind's mean and the current follow the table
    V = env.wind.speed(t)
    assert V[t < 1200].mean() == pytest.approx(fpso.sea_state("normal").wind_speed, rel=0.15)
    assert V[t >= 1800].mean() == pytest.approx(fpso.sea_state("storm").wind_speed, rel=0.1)
    assert np.allclose(env.wind.block(0.0, 0.25, t.size), V, rtol=0, atol=1e-9)
    for tc, sid in ((600.0, "normal"), (5000.0, "storm")):
        assert np.hypot(*env.current_surface(tc)[:2]) == pytest.approx(fpso.sea_state(sid).current_speed)


def test_a_steady_sea_state_with_a_table_that_changes_nothing_is_steady(fpso):
    a = fpso.sea_state("normal")
    sc = with_sea(fpso, "normal", development=(SeaStateRow(t=600.0, Hs=a.Hs),))
    env = Environment(sc, "normal", seed=1)
    assert not env.develops and type(env.waves).__name__ == "WaveField"


def test_the_plant_runs_a_developing_sea(fpso):
    sc = storm_building(fpso, hold=30.0, ramp=60.0, end=200.0)
    p = Plant(sc, sea_state="normal", seed=5)
    r = run_open_loop(p, 150.0)
    assert p._developing and np.isfinite(r.data).all()
    q = Plant(sc, sea_state="normal", seed=5)
    q.compiled = False
    assert_same(r.data, run_open_loop(q, 150.0).data)


def test_development_rows_are_checked(fpso):
    bad = with_sea(fpso, "normal", development=(SeaStateRow(t=600.0, Hs=9.0), SeaStateRow(t=300.0, Hs=8.0)))
    msgs = {i.path: i.message for i in validate(bad)}
    assert "later than the row before" in msgs["sea_states[0].development[1].t"]
    bad = with_sea(fpso, "normal", development=(SeaStateRow(t=0.0, Hs=9.0),))
    msgs = {i.path: i.message for i in validate(bad)}
    assert "differs from the sea state's Hs = 7" in msgs["sea_states[0].development[0].Hs"]
    bad = with_sea(fpso, "normal", development=(SeaStateRow(t=0.0, wind_direction=1.0),))
    assert "sea_states[0].development[0].wind_direction_deg" in {i.path for i in validate(bad)}
    # read from a file, with degrees at the edge
    d = scenario_to_dict(storm_building(fpso))
    d["sea_states"][0]["development"][1]["wind_direction_deg"] = 200.0
    sc = scenario_from_dict(d)
    assert sc.sea_state("normal").development[1].wind_direction == pytest.approx(math.radians(200.0))
    d["sea_states"][0]["development"][1]["Hs"] = 40.0
    with pytest.raises(tapm_opt.errors.ScenarioError, match=r"development\[1\]\.Hs"):
        scenario_from_dict(d)


@pytest.mark.slow
def test_the_supervisor_switches_the_pid_as_a_storm_builds(fpso):
    """A normal sea that builds to the storm between 30 and 40 minutes: the supervised PID, in
    closed loop on the FEM plant, starts in normal and switches to the storm's mode set once,
    after the storm has built (survey §4.5, Fig. 9)."""
    from tapm_opt.control.supervisor import SupervisedController
    from tapm_opt.design.supervisor import sea_state_supervisor
    from tapm_opt.models.system import System
    from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller

    system = System.from_scenario(fpso)
    sup = sea_state_supervisor(system, initial="normal")
    ctrl = SupervisedController(build_controller(system, "pid"), sup)
    sc = storm_building(fpso, hold=1800.0, ramp=600.0, end=5400.0)
    plant = Plant(sc, sea_state="normal", seed=1)
    run_closed_loop(plant, ctrl, ClosedLoopSettings(duration=4200.0, estimator="lowpass"), estimator=None)
    switches = [(e["t"], e["from"], e["to"]) for e in sup.events]
    assert switches and switches[-1][2] == "storm" and len(switches) <= 2
    assert all(t > 1800.0 for t, _, _ in switches)   # nothing before the sea builds
