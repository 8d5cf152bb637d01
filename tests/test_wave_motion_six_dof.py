"""The hull's six-degree-of-freedom wave-frequency motion at the fairleads (``vessel.wave_motion``).

* Rigid-body kinematics of a fairlead for heave, roll and pitch against a hand computation at a
  point (the cross product written out, and the exact rotation to second order in the angles).
* The heave, roll and pitch sums on the heading grid against the RAO summed directly, at a grid
  heading and between two.
* The plant: compiled and numpy paths agree; long waves heave the fairleads with the surface;
  the plant's fairleads move as the kinematics says.
* Forced surge in the storm with the hull's wave-frequency motion gives more mooring damping than
  the current alone, and six degrees of freedom more than three (survey §2.4).
* Scenario checks name the missing hull field.
"""

from __future__ import annotations

import dataclasses
import math

import _six_dof
import numpy as np
import pytest
from _bitwise import assert_same
from _six_dof import six_dof

import tapm_opt
from tapm_opt.config import WaveMotion, validate
from tapm_opt.models import rao as rao_mod
from tapm_opt.plant import fem_kernel
from tapm_opt.plant.environment import (
    N_HEADINGS,
    Environment,
    PlantError,
    heading_interp,
)
from tapm_opt.plant.forced_motion import forced_motion
from tapm_opt.plant.mooring_fem import MooringFEM
from tapm_opt.plant.simulator import Plant, run_open_loop

#: fpso's hull for the closed form (the values of the built-in scenario file)
HULL = {"block_coefficient": 0.83, "GM_T": 6.0, "roll_period": 15.5, "roll_damping": 0.05}

fpso, fpso6 = _six_dof.fpso, _six_dof.fpso6   # fixtures: fpso horizontal, fpso6 in six degrees of freedom


def test_the_built_in_hull_is_the_tests(fpso):
    assert {k: getattr(fpso.vessel.wave_motion, k) for k in HULL} == HULL


@pytest.mark.parametrize("mode", ["locked", "free"])
def test_fairlead_displacement_is_rigid_body_kinematics_at_a_point(fpso, mode):
    sc = dataclasses.replace(fpso, turret=dataclasses.replace(fpso.turret, mode=mode))
    m = MooringFEM(sc)
    x, y, psi, hz, ph, th = 3.0, -2.0, 0.3, 0.7, 0.02, -0.015
    r3, _ = m.fairlead_state(np.array([x, y, psi]), np.zeros(3))
    r6, _ = m.fairlead_state(np.array([x, y, psi, hz, ph, th]), np.zeros(6))
    Rz = np.array([[math.cos(psi), -math.sin(psi), 0.0], [math.sin(psi), math.cos(psi), 0.0], [0.0, 0.0, 1.0]])
    for j in range(len(r3)):
        p_B = Rz.T @ (r3[j] - np.array([x, y, 0.0]))       # the fairlead in {B}: (x, y, depth below the water line)
        assert p_B[2] == pytest.approx(sc.turret.fairlead_depth)
        hand = r3[j] + Rz @ np.cross([ph, th, 0.0], p_B) + np.array([0.0, 0.0, hz])
        assert np.allclose(r6[j], hand, rtol=0, atol=1e-12)
        # the exact rotation (roll about x, then pitch about y, NED) agrees to second order in the angles
        Rx = np.array([[1, 0, 0], [0, math.cos(ph), -math.sin(ph)], [0, math.sin(ph), math.cos(ph)]])
        Ry = np.array([[math.cos(th), 0, math.sin(th)], [0, 1, 0], [-math.sin(th), 0, math.cos(th)]])
        exact = np.array([x, y, hz]) + Rz @ Ry @ Rx @ p_B
        assert np.linalg.norm(r6[j] - exact) <= (ph**2 + th**2) * np.linalg.norm(p_B)
    # a turret ahead of midships: pitch bow up lifts the fairleads (z down), roll to starboard lowers them there
    r_pitch, _ = m.fairlead_state(np.array([0, 0, 0, 0, 0, 0.01]), np.zeros(6))
    r0, _ = m.fairlead_state(np.zeros(3), np.zeros(3))
    assert np.all(r_pitch[:, 2] < r0[:, 2])
    stbd = r0[:, 1] > 0
    r_roll, _ = m.fairlead_state(np.array([0, 0, 0, 0, 0.01, 0]), np.zeros(6))
    assert np.all(r_roll[stbd, 2] > r0[stbd, 2]) and np.all(r_roll[~stbd, 2] < r0[~stbd, 2])


def test_fairlead_velocity_and_acceleration_are_the_derivatives_of_the_position(fpso):
    m = MooringFEM(fpso)
    pose = lambda t: np.array([1.0 + 0.3 * t, -0.5 * t, 0.1 + 0.02 * t, 0.5 * math.sin(t), 0.01 * math.cos(2 * t),
                               0.02 * math.sin(0.7 * t)])
    t, h = 0.4, 1e-5
    rate = (pose(t + h) - pose(t - h)) / (2 * h)
    acc = (pose(t + h) - 2 * pose(t) + pose(t - h)) / h**2
    r_p, _ = m.fairlead_state(pose(t + h), rate)
    r_m, _ = m.fairlead_state(pose(t - h), rate)
    _, v = m.fairlead_state(pose(t), rate)
    # the levers' own change (the rates times the angles' offsets, about 1e-2 m/s here) is left
    # out: a small difference only (a wrong sign of a rate term is 0.1-1 m/s)
    assert np.allclose(v, (r_p - r_m) / (2 * h), rtol=0, atol=1e-2)
    # at a steady heading the levers do not turn: position, velocity and acceleration agree closely
    pose2 = lambda t: pose(t) * np.array([1, 1, 0, 1, 1, 1]) + np.array([0, 0, 0.1, 0, 0, 0])
    h = 1e-3
    rate = (pose2(t + h) - pose2(t - h)) / (2 * h)
    acc = (pose2(t + h) - 2 * pose2(t) + pose2(t - h)) / h**2
    r_p, r_0, r_m = (m.fairlead_state(pose2(s), rate)[0] for s in (t + h, t, t - h))
    assert np.allclose(m.fairlead_state(pose2(t), rate)[1], (r_p - r_m) / (2 * h), rtol=0, atol=1e-6)
    assert np.allclose(m.fairlead_acceleration(pose2(t), rate, acc), (r_p - 2 * r_0 + r_m) / h**2, rtol=0, atol=1e-5)


def test_heave_roll_pitch_sums_on_the_heading_grid_are_the_rao_summed(fpso6):
    w = Environment(fpso6, "storm", seed=5).waves
    hull = rao_mod.HullMotionParams(length_pp=fpso6.vessel.length_pp, breadth=fpso6.vessel.breadth,
                                    draught=fpso6.vessel.draught, waterplane_coefficient=(1 + 2 * 0.83) / 3, **HULL)
    t = 123.4
    th = w.omega * t + w.phase

    def direct(beta):
        H = rao_mod.closed_form_rao(w.omega, beta, hull, g=fpso6.environment.gravity)
        return np.real(H * (w.amplitude * np.exp(1j * th))[:, None]).sum(axis=0)

    step = 2 * math.pi / N_HEADINGS
    for g in (0, 7, 36, 50):   # on the grid: the direct sum
        beta = g * step
        assert np.allclose(w.vertical(t, w.direction - beta), direct(beta), rtol=1e-10, atol=1e-12)
    # between two grid headings: linear between them, and close to the direct sum (5 degree grid)
    beta = 40.4 * step
    v = w.vertical(t, w.direction - beta)
    lo, hi = direct(40 * step), direct(41 * step)
    assert np.allclose(v, lo + 0.4 * (hi - lo), rtol=1e-9, atol=1e-12)
    assert np.all(np.abs(v - direct(beta)) <= 0.02 * np.maximum(np.abs(lo), np.abs(hi)))
    # the rate is the time derivative
    dt = 1e-4
    num = (w.vertical(t + dt, 0.3) - w.vertical(t - dt, 0.3)) / (2 * dt)
    assert np.allclose(w.vertical_dot(t, 0.3), num, rtol=1e-6, atol=1e-9)


def test_the_heading_grid_is_the_compiled_plants():
    assert fem_kernel.N_HEADINGS == N_HEADINGS


def test_heading_interp_wraps_the_relative_heading():
    G = N_HEADINGS
    grid = np.repeat(np.arange(G, dtype=float), 3)
    step = 2 * math.pi / G
    # beyond the last grid heading: between it (value G - 1) and the first (value 0)
    assert heading_interp(grid, 0.0, -(G - 0.5) * step)[0] == pytest.approx((G - 1) * 0.5)
    assert heading_interp(grid, 0.0, -(G - 0.25) * step)[0] == pytest.approx((G - 1) * 0.25)
    assert heading_interp(grid, 1.0, 1.0 + 3 * step)[0] == pytest.approx(G - 3)
    rows = np.vstack([grid, 2 * grid])
    assert np.allclose(heading_interp(rows, 0.0, -2.5 * step), [[2.5] * 3, [5.0] * 3])


@pytest.mark.skipif(not fem_kernel.AVAILABLE, reason="numba is not installed")
def test_compiled_and_numpy_plants_agree_with_heave_roll_and_pitch(fpso6):
    runs = []
    for compiled in (True, False):
        p = Plant(fpso6, sea_state="storm", seed=3)
        p.compiled = compiled
        runs.append((p, run_open_loop(p, 20.0)))
    (pa, ra), (_pb, rb) = runs
    assert pa.six_dof and [c for c, _ in pa.channels()][-3:] == ["heave_wf", "roll_wf", "pitch_wf"]
    assert_same(ra.data, rb.data)
    assert np.abs(ra.data[:, -3]).max() > 0.1   # the hull heaves in the storm


def test_the_plant_fairleads_follow_the_hull(fpso6):
    p = Plant(fpso6, sea_state="storm", seed=8)
    run_open_loop(p, 12.3)
    pose = np.concatenate([p.eta_total, p._vert])
    assert np.abs(p._vert).max() > 0
    r, _ = p.mooring.fairlead_state(pose, np.zeros(6))
    fem = p.mooring.fem
    assert np.allclose(fem.r[fem.fairlead_idx], r, rtol=0, atol=1e-9)


def test_long_waves_heave_the_hull_with_the_surface(fpso6):
    swell = dataclasses.replace(fpso6.sea_states[0], id="swell", Hs=2.0, Tp=30.0, wind_speed=0.0, current_speed=0.0)
    w = Environment(dataclasses.replace(fpso6, sea_states=(swell,)), "swell", seed=2).waves
    t = np.arange(0.0, 1800.0, 1.0)
    heave = w.vertical(t, 0.0)[:, 0]
    zeta = w.elevation(t)
    # long waves (lambda = 1400 m, four ship lengths): heave (down) is minus the elevation
    assert np.corrcoef(heave, -zeta)[0, 1] > 0.95
    assert 0.85 < heave.std() / zeta.std() <= 1.0


def test_six_dof_needs_the_hull_fields(fpso):
    sc = dataclasses.replace(fpso, vessel=dataclasses.replace(
        fpso.vessel, wave_motion=WaveMotion(model="six_dof", block_coefficient=0.8)))
    msgs = {i.path: i.message for i in validate(sc)}
    assert "vessel.wave_motion.GM_T" in msgs and "six_dof" in msgs["vessel.wave_motion.GM_T"]
    assert "vessel.wave_motion.roll_period" in msgs
    sc = six_dof(fpso, waterplane_coefficient=0.7)
    msgs = {i.path: i.message for i in validate(sc)}
    assert "below block_coefficient = 0.83" in msgs["vessel.wave_motion.waterplane_coefficient"]
    assert not validate(six_dof(fpso))


def test_the_hull_fields_are_read_from_a_file(tmp_path, fpso):
    import tomllib  # noqa: F401  (the loader reads TOML)

    from tapm_opt.config import scenario_to_dict

    d = scenario_to_dict(six_dof(fpso))
    assert d["vessel"]["wave_motion"]["model"] == "six_dof"
    back = tapm_opt.scenario_from_dict(d)
    assert back.vessel.wave_motion == six_dof(fpso).vessel.wave_motion
    d["vessel"]["wave_motion"]["block_coefficent"] = 0.8
    with pytest.raises(Exception, match="block_coefficient"):
        tapm_opt.scenario_from_dict(d)


@pytest.mark.slow
def test_wave_frequency_motion_raises_the_mooring_damping(fpso, fpso6):
    """Forced surge (5 m, 100 s) in the storm: the current alone, then with the hull's horizontal
    wave-frequency motion, then with heave, roll and pitch too; each damps more (survey §2.4)."""
    kw = {"dof": "surge", "amplitude": 5.0, "period": 100.0, "duration": 300.0, "dt_out": 1.0}
    still = forced_motion(fpso, **kw).damping
    current = forced_motion(fpso, sea_state="storm", **kw).damping
    three = forced_motion(fpso, sea_state="storm", waves=True, **kw).damping
    six = forced_motion(fpso6, sea_state="storm", waves=True, **kw).damping
    assert still < current < three < six
    assert 2.0 <= six / still <= 4.0   # the survey's range
    with pytest.raises(tapm_opt.errors.ModelError, match="needs a sea_state"):
        forced_motion(fpso6, waves=True, **kw)


def _table_like_the_closed_form(sc, w):
    """An RAO table with the closed form's heave, roll and pitch and the plant's own parametric
    surge, sway and yaw (docs/plant_environment.md), on the plant's heading grid and a fine
    frequency grid."""
    v, env = sc.vessel, sc.environment
    g = env.gravity
    hull = rao_mod.HullMotionParams(length_pp=v.length_pp, breadth=v.breadth, draught=v.draught,
                                    waterplane_coefficient=(1 + 2 * 0.83) / 3, **HULL)
    omega = np.linspace(0.9 * w.omega.min(), 1.1 * w.omega.max(), 3001)
    beta = 2 * math.pi / N_HEADINGS * np.arange(N_HEADINGS)
    H = np.zeros((omega.size, beta.size, 6), complex)
    H[:, :, 2:5] = rao_mod.closed_form_rao(omega[:, None], beta[None, :], hull, g=g)
    k = omega**2 / g
    h_L = 1.0 / (1.0 + (omega / math.sqrt(math.pi * g / v.length_pp)) ** 4)
    h_B = 1.0 / (1.0 + (omega / math.sqrt(math.pi * g / v.breadth)) ** 4)
    H[:, :, 0] = -1j * h_L[:, None] * np.cos(beta)           # surge_B = cos beta sum a h_L sin theta
    H[:, :, 1] = -1j * h_B[:, None] * np.sin(beta)           # sway_B = sin beta sum a h_B sin theta
    H[:, :, 5] = (w.params.yaw_rao * k * h_L)[:, None] * np.sin(2 * beta)   # yaw = sin 2beta sum c k h_L a cos theta
    # the field's own parametric surge, sway and yaw (short-crested seas take them) are the same
    assert np.allclose(w.horizontal_rao(omega[:, None], beta[None, :]), H[:, :, [0, 1, 5]], rtol=1e-13, atol=0)
    return rao_mod.RAOTable(omega=omega, beta=beta, H=H)


def test_a_users_rao_table_moves_the_hull_as_its_numbers_say(tmp_path, fpso, fpso6):
    """A table holding the closed form's heave, roll and pitch and the parametric surge, sway and
    yaw, written as CSV next to a scenario file that names it by a relative path: the plant on it
    moves as the six-degree-of-freedom plant does (up to the table's frequency interpolation)."""
    from tapm_opt.config import scenario_to_dict
    from tapm_opt.config.moordyn import scenario_toml

    w6 = Environment(fpso6, "storm", seed=4).waves
    rao_mod.write_rao_csv(_table_like_the_closed_form(fpso6, w6), tmp_path / "hull_rao.csv")
    d = scenario_to_dict(fpso)
    d["vessel"]["wave_motion"] = {"model": "table", "rao_file": "hull_rao.csv"}
    (tmp_path / "sc.toml").write_text(scenario_toml(d), encoding="utf-8")
    sc_t = tapm_opt.load_scenario(tmp_path / "sc.toml")
    assert sc_t.vessel.wave_motion.rao_file == str(tmp_path / "hull_rao.csv")
    wt = Environment(sc_t, "storm", seed=4).waves
    assert wt.six_dof and wt.grid_horizontal
    t = np.arange(0.0, 600.0, 0.5)
    # off the grid's headings the table is interpolated linearly in beta (5 degrees: cos beta within
    # 0.1 %), the closed form and the parametric motion are exact: a few 1e-3 apart
    for psi in (0.0, 0.4):
        for a, b in ((wt.vertical(t, psi), w6.vertical(t, psi)), (wt.eta_wf(t, psi), w6.eta_wf(t, psi))):
            assert np.all(np.abs(a - b).max(axis=0) <= 4e-3 * np.abs(b).max(axis=0) + 1e-12)
    runs = [run_open_loop(Plant(s, sea_state="storm", seed=4), 30.0) for s in (sc_t, fpso6)]
    assert runs[0].channels == runs[1].channels
    assert (runs[0].meta["wave_motion"], runs[0].meta["rao_file"]) == ("table", sc_t.vessel.wave_motion.rao_file)
    assert (runs[1].meta["wave_motion"], runs[1].meta["rao_file"], runs[1].meta["drift_file"]) == ("six_dof", None, None)
    scale = np.abs(runs[1].data).max(axis=0)
    assert np.all(np.abs(runs[0].data - runs[1].data).max(axis=0) <= 5e-3 * scale + 1e-6)
    # a missing or misnamed file is named in the scenario's own terms
    d["vessel"]["wave_motion"]["rao_file"] = "nowhere.csv"
    (tmp_path / "bad.toml").write_text(scenario_toml(d), encoding="utf-8")
    with pytest.raises(tapm_opt.errors.ScenarioError, match="rao_file.*no such file"):
        tapm_opt.load_scenario(tmp_path / "bad.toml")
    (tmp_path / "hull_rao.txt").write_text("x", encoding="utf-8")
    d["vessel"]["wave_motion"]["rao_file"] = "hull_rao.txt"
    (tmp_path / "bad.toml").write_text(scenario_toml(d), encoding="utf-8")
    with pytest.raises(tapm_opt.errors.ScenarioError, match=r"rao_file.*\.csv table or a WAMIT \.4"):
        tapm_opt.load_scenario(tmp_path / "bad.toml")
    # a table the reader refuses: the plant says which file
    (tmp_path / "broken.csv").write_text("omega_rad_s,beta_deg,dof,amplitude,phase_deg\n0.5,0,heave,x,0\n",
                                         encoding="utf-8")
    d["vessel"]["wave_motion"]["rao_file"] = "broken.csv"
    (tmp_path / "bad.toml").write_text(scenario_toml(d), encoding="utf-8")
    with pytest.raises(PlantError, match="rao_file.*broken.csv"):
        Environment(tapm_opt.load_scenario(tmp_path / "bad.toml"), "storm")


def test_six_dof_needs_the_body_origin_where_the_closed_form_is(fpso):
    sc = six_dof(fpso)
    aft = dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, reference_point=(0.0, 0.0, 18.46)))
    msgs = {i.path: i.message for i in validate(aft)}
    assert "off midships" in msgs["vessel.reference_point"] and "-152 m" in msgs["vessel.reference_point"]
    keel = dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, reference_point=(152.4, 0.0, 0.0)))
    assert "off the water line" in {i.path: i.message for i in validate(keel)}["vessel.reference_point"]
    unknown = dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, reference_point=(math.nan, 0.0, math.nan)))
    assert not validate(unknown)
    table = dataclasses.replace(aft, vessel=dataclasses.replace(aft.vessel, wave_motion=dataclasses.replace(
        aft.vessel.wave_motion, model="horizontal")))
    assert not validate(table)


def test_the_hull_motion_starts_from_rest_and_ramps_in_over_a_peak_period(fpso6):
    w = Environment(fpso6, "storm", seed=1).waves
    assert np.all(w.vertical(0.0, 0.0) == 0) and np.all(w.vertical_dot(0.0, 0.0) == 0)
    t = np.arange(0.0, 3 * w.Tp, 0.05)
    v = w.vertical(t, 0.0)
    s, _ = w.ramp(t)
    assert np.all((s >= 0) & (s <= 1)) and np.all(s[t >= w.Tp] == 1.0) and np.all(np.diff(s) >= 0)
    # past the ramp: the full motion; the block sums carry the same ramp as the scalar path
    grid = w.vertical_block(0.0, 0.05, t.size)
    rows = np.array([w.vertical_of(g, 0.0) for g in grid])
    assert np.allclose(rows, v, rtol=0, atol=1e-9 * np.abs(v).max())
    dt = 1e-5
    tm = 0.3 * w.Tp
    assert np.allclose(w.vertical_dot(tm, 0.1), (w.vertical(tm + dt, 0.1) - w.vertical(tm - dt, 0.1)) / (2 * dt),
                       rtol=1e-5, atol=1e-9)
