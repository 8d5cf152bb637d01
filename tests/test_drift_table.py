"""The hull's mean wave drift from the user's coefficient table (``vessel.wave_motion.drift_file``).

* The reader: a CSV round trip, the interpolation (linear in omega, held below, zero above,
  periodic in beta), bad files refused naming the row, column and value, WAMIT ``.8``/``.9`` rows
  turned into our frame and units.
* Newman with the table: a table equal to the wall-sided ``R(w) c(beta)`` gives today's drift to
  round-off; another shape gives the mean ``sum a^2 D`` at the grid headings and interpolates
  between them; the slowly varying force's 3-hour time mean is the mean drift; a short-crested
  sea takes each component's own heading; a developing sea's amplitudes of the moment.
* The plant: the compiled and numpy paths agree with a table (per-step and multi-step too), and
  the logged drift is the table's at each step's start; the design code's mean load is it.
* The scenario: a missing or misnamed file is refused at load, a relative path is read from the
  scenario file's folder, a file the reader refuses is named by the plant.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from _bitwise import assert_same

import tapm_opt
from tapm_opt.config import scenario_to_dict
from tapm_opt.config.moordyn import scenario_toml
from tapm_opt.config.schema import SeaStateRow
from tapm_opt.design.loads import mean_environmental_load
from tapm_opt.errors import ModelError, ScenarioError
from tapm_opt.interfaces import ThrusterCommand
from tapm_opt.models import rao as rao_mod
from tapm_opt.plant import fem_kernel
from tapm_opt.plant.environment import (
    N_HEADINGS,
    DevelopingWaveField,
    Environment,
    PlantError,
)
from tapm_opt.plant.simulator import Plant, run_open_loop

compiled_only = pytest.mark.skipif(not fem_kernel.AVAILABLE, reason="numba is not installed")

GRID = 2.0 * math.pi / N_HEADINGS * np.arange(N_HEADINGS)   # the plant's heading grid [rad]
T_3H = np.arange(0.0, 3.0 * 3600.0, 0.5)


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


def with_drift(sc, path):
    """The scenario with the drift table ``path``."""
    wm = dataclasses.replace(sc.vessel.wave_motion, drift_file=None if path is None else str(path))
    return dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, wave_motion=wm))


def with_sea(sc, sid, **changes):
    ss = [dataclasses.replace(s, **changes) if s.id == sid else s for s in sc.sea_states]
    return dataclasses.replace(sc, sea_states=tuple(ss))


def shaped(omega, beta):
    """Coefficients of another shape than the wall-sided one [N/m^2, N/m^2, N m/m^2]: one sign over
    the frequencies at each heading, changing with the heading."""
    w, b = np.broadcast_arrays(np.asarray(omega, float), np.asarray(beta, float))
    return np.stack([-2.0e5 * w / (1.0 + w * w) * np.cos(b), 8.0e5 * (1.0 - np.exp(-w * w)) * np.sin(b),
                     3.0e7 * w * np.exp(-w) * np.sin(2.0 * b)], axis=-1)


@pytest.fixture(scope="module")
def shaped_file(tmp_path_factory):
    w = np.linspace(0.2, 2.5, 24)
    b = np.radians(np.arange(0.0, 360.0, 10.0))
    path = tmp_path_factory.mktemp("drift") / "shaped.csv"
    rao_mod.write_drift_csv(rao_mod.DriftTable(w, b, shaped(w[:, None], b[None, :])), path)
    return path


def wall_sided_table(sc, waves):
    """The wall-sided coefficients ``R(w) c(beta)`` of the plant's default drift on the components'
    own frequencies and the plant's heading grid (so that the table is exact there)."""
    v, env = sc.vessel, sc.environment
    R = 1.0 - np.exp(-2.0 * waves.omega**2 / env.gravity * v.draught)
    cb, sb = np.cos(GRID), np.sin(GRID)
    c = 0.5 * env.water_density * env.gravity * np.stack(
        [v.breadth * cb * np.abs(cb), v.length_pp * sb * np.abs(sb), -waves.params.drift_yaw * v.length_pp**2
         * np.sin(2.0 * GRID)], axis=-1)
    return rao_mod.DriftTable(waves.omega, GRID, R[:, None, None] * c[None, :, :])


# --- the reader ---------------------------------------------------------------------------------

def test_a_table_written_and_read_back_is_the_same(tmp_path):
    w = np.array([0.3, 0.6, 1.1, 2.0])
    b = np.radians([0.0, 45.0, 180.0, 270.0])
    D = np.random.default_rng(0).normal(size=(4, 4, 3)) * 1e5
    rao_mod.write_drift_csv(rao_mod.DriftTable(w, b, D), tmp_path / "d.csv")
    t = rao_mod.read_drift_csv(tmp_path / "d.csv")
    assert np.array_equal(t.omega, w) and np.allclose(t.beta, b, rtol=1e-15, atol=0) and np.array_equal(t.D, D)
    # rows in any order, the columns in any order, blank lines and headings beyond 360 degrees
    lines = (tmp_path / "d.csv").read_text().splitlines()
    rows = [ln.split(",") for ln in lines[1:]]
    text = "dof,D,beta_deg,omega_rad_s\n\n" + "\n".join(
        f"{r[2]},{r[3]},{float(r[1]) + 360.0},{r[0]}" for r in reversed(rows))
    (tmp_path / "e.csv").write_text(text)
    t2 = rao_mod.read_drift_csv(tmp_path / "e.csv")
    assert np.array_equal(t2.D, D) and np.allclose(t2.beta, b, atol=1e-12)


def test_the_table_interpolates_as_the_rao_table_does():
    w = np.array([0.4, 0.8])
    b = np.radians([0.0, 90.0, 180.0, 270.0])
    D = np.zeros((2, 4, 3))
    D[0, :, 0], D[1, :, 0] = [1.0, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.0]
    D[:, :, 2] = -D[:, :, 0]
    t = rao_mod.DriftTable(w, b, D)
    assert t.evaluate(0.6, 0.0)[0] == pytest.approx(3.0)             # linear in omega
    assert t.evaluate(0.1, np.radians(90.0))[0] == pytest.approx(2.0)  # the first row held below
    assert np.all(t.evaluate(0.81, 1.0) == 0.0)                      # zero above
    assert t.evaluate(0.4, np.radians(315.0))[0] == pytest.approx(2.5)   # periodic: 270 to 360 = 0
    assert t.evaluate(0.4, np.radians(-45.0))[0] == pytest.approx(2.5)
    assert t.evaluate(0.4, np.radians(45.0))[2] == pytest.approx(-1.5)
    assert t.evaluate(np.array([[0.4], [0.8]]), np.zeros((1, 3))).shape == (2, 3, 3)
    one = rao_mod.DriftTable(w, [0.5], D[:, :1])   # a single heading applies to all
    assert np.array_equal(one.evaluate(0.6, 2.0), one.evaluate(0.6, 0.5))
    with pytest.raises(ModelError, match="omega"):
        t.evaluate(-0.1, 0.0)


HEADER = "omega_rad_s,beta_deg,dof,D\n"
GOOD = "0.5,0,surge,1\n0.5,0,sway,2\n0.5,0,yaw,3\n"


@pytest.mark.parametrize("text, match", [
    ("", "empty file"),
    ("omega_rad_s,beta_deg,dof\n", r"missing column\(s\) \['D'\]"),
    ("omega_rad_s,beta_deg,dof,D,amplitude\n" + GOOD, r"extra column\(s\) \['amplitude'\]"),
    (HEADER + "0.5,0,surge,x\n", "row 2, column D: 'x' is not a number"),
    (HEADER + GOOD + "0.5,0,surge,nan\n", "row 5, column D: 'nan' must be finite"),
    (HEADER + "0.5,0,heave,1\n", "row 2, column dof: 'heave' must be one of"),
    (HEADER + "-0.5,0,surge,1\n", "row 2, column omega_rad_s: -0.5 must be > 0"),
    (HEADER + "0.5,abc,surge,1\n", "row 2, column beta_deg: 'abc' is not a number"),
    (HEADER + "0.5,0,surge\n", "row 2 has 3 values"),
    (HEADER + GOOD + "0.5,360,yaw,4\n", "row 5 repeats row 4"),
    (HEADER + "0.5,0,surge,1\n0.5,0,yaw,3\n", "has no sway row"),
    (HEADER + GOOD + "0.7,90,surge,1\n0.7,90,sway,1\n0.7,90,yaw,1\n", "not a full omega x beta product"),
])
def test_bad_files_are_refused_naming_the_row_and_column(tmp_path, text, match):
    (tmp_path / "bad.csv").write_text(text)
    with pytest.raises(ModelError, match=match):
        rao_mod.read_drift_csv(tmp_path / "bad.csv")


def test_wamit_mean_drift_rows_are_turned_into_our_frame_and_units(tmp_path):
    rho, g, ulen = 1025.0, 9.81, 2.0
    w = np.array([0.4, 0.9])
    b = np.radians([0.0, 30.0, 180.0])
    D = np.random.default_rng(1).normal(size=(2, 3, 3)) * 1e5
    lines = []
    for i, wi in enumerate(w):
        for j, bj in enumerate(b):
            beta_w = -math.degrees(float(bj))   # WAMIT's heading: toward port
            for mode, m, sign, k in ((1, 0, 1, 1), (2, 1, -1, 1), (6, 2, -1, 2)):
                v = float(sign * D[i, j, m] / (rho * g * ulen**k))
                lines.append(f"{2 * math.pi / float(wi)!r} {beta_w!r} {beta_w!r} {mode} {abs(v)!r} "
                             f"{0.0 if v >= 0 else 180.0} {v!r} 0.0")
            per = 2 * math.pi / float(wi)
            lines.append(f"{per!r} {beta_w!r} {beta_w!r} 3 1.0 0.0 1.0 0.0")        # heave: skipped
            lines.append(f"{per!r} {beta_w!r} {beta_w + 30!r} 1 5.0 0.0 3.0 4.0")   # a pair: skipped
    (tmp_path / "hull.9").write_text("\n".join(lines) + "\n")
    t = rao_mod.read_wamit_drift(tmp_path / "hull.9", ulen=ulen, rho=rho, g=g)
    assert np.allclose(t.omega, w, rtol=1e-14) and np.allclose(t.beta, b, atol=1e-14)
    assert np.allclose(t.D, D, rtol=1e-13, atol=0)
    (tmp_path / "bad.8").write_text("10.0 0.0 0.0 1 1.0 0.0 1.0\n")
    with pytest.raises(ModelError, match="line 1: .* is not 8 numbers"):
        rao_mod.read_wamit_drift(tmp_path / "bad.8", ulen=1.0, rho=rho, g=g)
    (tmp_path / "bad.8").write_text("10.0 0.0 0.0 1 2.0 0.0 1.0 0.0\n")
    with pytest.raises(ModelError, match="line 1: Mod = 2.0"):
        rao_mod.read_wamit_drift(tmp_path / "bad.8", ulen=1.0, rho=rho, g=g)
    (tmp_path / "bad.8").write_text("-1.0 0.0 0.0 1 1.0 0.0 1.0 0.0\n")
    with pytest.raises(ModelError, match="line 1: PER = -1.0"):
        rao_mod.read_wamit_drift(tmp_path / "bad.8", ulen=1.0, rho=rho, g=g)


# --- Newman with the table ----------------------------------------------------------------------

@pytest.mark.parametrize("sea", ["storm", "normal"])
def test_a_wall_sided_table_gives_todays_drift(tmp_path, fpso, sea):
    base = Environment(fpso, sea, seed=6).waves
    rao_mod.write_drift_csv(wall_sided_table(fpso, base), tmp_path / "wall.csv")
    w = Environment(with_drift(fpso, tmp_path / "wall.csv"), sea, seed=6).waves
    assert w.drift_table and not base.drift_table
    assert np.array_equal(w.omega, base.omega) and np.array_equal(w.amplitude, base.amplitude)
    t = np.arange(0.0, 900.0, 0.7)
    for g in (0, 5, 17, 36, 40, 61):   # head seas (36), beam seas (18), quartering
        psi = w.direction - GRID[g]
        F0, F1 = base.tau_drift(t, psi), w.tau_drift(t, psi)
        scale = np.abs(F0).max()
        assert scale > 1e3
        assert np.abs(F1 - F0).max() <= 1e-12 * scale
        m0, m1 = base.mean_drift(psi), w.mean_drift(psi)
        assert np.abs(m1 - m0).max() <= 1e-12 * np.abs(m0).max()
        assert abs(F1[11, 0] - w.tau_drift(t[11], psi)[0]) <= 1e-12 * scale   # a scalar time


def test_another_shape_gives_its_mean_at_grid_headings_and_interpolates_between(fpso, shaped_file):
    w = Environment(with_drift(fpso, shaped_file), "storm", seed=2).waves
    table = rao_mod.read_drift_csv(shaped_file)
    a2 = w.amplitude**2
    grid_means = []
    for g in range(N_HEADINGS):
        psi = w.direction - GRID[g]
        exact = a2 @ table.evaluate(w.omega, GRID[g])
        grid_means.append(exact)
        assert np.allclose(w.mean_drift(psi), exact, rtol=1e-12, atol=1e-12 * np.abs(exact).max())
    # its own shape, not the wall-sided one: sway in beam seas, yaw in quartering seas
    assert grid_means[18][1] > 1e5 and abs(grid_means[9][2]) > 1e6 and abs(grid_means[18][2]) < 1e-6 * grid_means[18][1]
    # between the grid headings: linear in the heading, within the grid's curvature of the exact mean
    scale = np.abs(np.array(grid_means)).max(axis=0)
    for beta in (0.3, 1.234, 2.9, 4.0, 5.5):
        g0 = int(beta // (2 * math.pi / N_HEADINGS))
        f = beta / (2 * math.pi / N_HEADINGS) - g0
        lin = grid_means[g0] + f * (grid_means[(g0 + 1) % N_HEADINGS] - grid_means[g0])
        m = w.mean_drift(w.direction - beta)
        assert np.allclose(m, lin, rtol=0, atol=1e-9 * scale)
        assert np.all(np.abs(m - a2 @ table.evaluate(w.omega, beta)) <= 2e-3 * scale)


@pytest.mark.parametrize("seed, beta", [(1, 2.2), (4, 0.9), (9, 3.6)])
def test_the_slowly_varying_force_has_the_mean_drift_as_its_time_mean(fpso, shaped_file, seed, beta):
    w = Environment(with_drift(fpso, shaped_file), "storm", seed=seed).waves
    psi = w.direction - beta
    F = w.tau_drift(T_3H, psi)
    mean = w.mean_drift(psi)
    assert np.all(np.abs(F.mean(axis=0) - mean) <= 0.05 * np.abs(mean))   # 3 hours of a slow process
    # Newman's form keeps each degree of freedom's sign (one sign over the frequencies here)
    assert np.all(F * np.sign(mean) >= 0)
    # and it varies slowly: it is not its mean
    assert np.all(F.std(axis=0) > 0.3 * np.abs(mean))


def test_where_the_coefficient_changes_sign_with_frequency_the_mean_takes_the_sign_of_the_sum(tmp_path, fpso):
    """Newman's approximation takes one sign per heading: where D changes sign with the
    frequency, the plant's mean is ``s sum a^2 |D|``, ``s`` the sign of ``sum a^2 D``."""
    w_tab = np.linspace(0.2, 2.5, 24)
    b = np.radians([0.0, 90.0, 180.0, 270.0])
    D = np.ones((24, 4, 3)) * 1e5
    D[w_tab > 0.6, :, 0] = -2e5   # surge changes sign at 0.6 rad/s
    path = tmp_path / "signs.csv"
    rao_mod.write_drift_csv(rao_mod.DriftTable(w_tab, b, D), path)
    w = Environment(with_drift(fpso, path), "storm", seed=3).waves
    Dk = rao_mod.read_drift_csv(path).evaluate(w.omega, 0.0)[:, 0]
    a2 = w.amplitude**2
    s = np.sign(a2 @ Dk)
    assert (Dk > 0).any() and (Dk < 0).any() and s != 0
    assert w.mean_drift(w.direction)[0] == pytest.approx(s * (a2 @ np.abs(Dk)), rel=1e-12)
    assert abs(w.mean_drift(w.direction)[0]) > abs(a2 @ Dk)


def test_a_short_crested_sea_takes_each_components_own_heading(fpso, shaped_file):
    sc = with_sea(with_drift(fpso, shaped_file), "storm", wave_spreading=4.0)
    w = Environment(sc, "storm", seed=3).waves
    table = rao_mod.read_drift_csv(shaped_file)
    a2 = w.amplitude**2
    for g in (0, 9, 18, 36, 50):
        D = table.evaluate(w.omega, GRID[g] + w.delta)   # (N, 3)
        expect = np.sign(a2 @ D) * (a2 @ np.abs(D))
        assert np.allclose(w.mean_drift(w.direction - GRID[g]), expect, rtol=1e-12,
                           atol=1e-12 * np.abs(expect).max())
        # the slowly varying force of the same heading: 2 s q^2, q = sum a sqrt|D| cos theta
        t = np.array([10.0, 333.3])
        q = np.cos(np.multiply.outer(t, w.omega) + w.phase) @ (w.amplitude[:, None] * np.sqrt(np.abs(D)))
        F = w.tau_drift(t, w.direction - GRID[g])
        assert np.allclose(F, 2.0 * q * q * np.sign(a2 @ D), rtol=1e-12, atol=1e-12 * np.abs(F).max())
    long = Environment(with_drift(fpso, shaped_file), "storm", seed=3).waves
    assert not np.allclose(w.mean_drift(w.direction - GRID[36]), long.mean_drift(long.direction - GRID[36]))


def test_a_developing_sea_drifts_with_the_amplitudes_of_the_moment(fpso, shaped_file):
    a, b = fpso.sea_state("normal"), fpso.sea_state("storm")
    keep = {f: getattr(a, f) for f in ("Hs", "Tp")}
    top = {f: getattr(b, f) for f in ("Hs", "Tp")}
    sc = with_sea(with_drift(fpso, shaped_file), "normal",
                  development=(SeaStateRow(t=600.0, **keep), SeaStateRow(t=1200.0, **top)))
    w = Environment(sc, "normal", seed=5).waves
    assert isinstance(w, DevelopingWaveField) and w.drift_table
    table = rao_mod.read_drift_csv(shaped_file)
    g = 30
    D = table.evaluate(w.omega, GRID[g])
    t = np.array([0.0, 700.0, 1500.0])
    A = w.amplitudes(t)
    q = np.cos(np.multiply.outer(t, w.omega) + w.phase) * A @ np.sqrt(np.abs(D))
    expect = 2.0 * q * q * np.sign(A**2 @ D)
    F = w.tau_drift(t, w.direction - GRID[g])
    assert np.allclose(F, expect, rtol=1e-12, atol=1e-12 * np.abs(expect).max())
    assert np.allclose(w.mean_drift(w.direction - GRID[g]), w.amplitude**2 @ D, rtol=1e-12)   # at t = 0
    # the storm drifts harder than the sea it grew from
    early, late = w.tau_drift(np.arange(0.0, 600.0, 0.5), 0.4), w.tau_drift(np.arange(1200.0, 3600.0, 0.5), 0.4)
    assert np.abs(late.mean(axis=0)[0]) > 1.5 * np.abs(early.mean(axis=0)[0])


# --- the plant ----------------------------------------------------------------------------------

def _cmd(n):
    return lambda t: ThrusterCommand(np.full(n, 4.0e5), np.full(n, 1.0 if t < 10.0 else -1.0))


@compiled_only
@pytest.mark.parametrize("spread", [None, 5.0])
def test_compiled_and_numpy_plants_agree_with_a_table(fpso, shaped_file, spread):
    sc = with_sea(with_drift(fpso, shaped_file), "storm", wave_spreading=spread)
    runs = []
    for compiled, multi in ((True, True), (True, False), (False, True)):
        p = Plant(sc, sea_state="storm", seed=2)
        p.compiled, p._multi_step = compiled, multi
        runs.append((p, run_open_loop(p, 20.0, thruster_cmd=_cmd(len(fpso.thrusters)), dt_log=0.1)))
    (p, r), (_, r_single), (_, r_numpy) = runs
    assert r.meta["drift_file"] == sc.vessel.wave_motion.drift_file and r.meta["wave_motion"] == "six_dof"
    assert np.array_equal(r.data, r_single.data)   # the same compiled functions, one call or many
    assert_same(r.data, r_numpy.data)
    # the logged drift is the table's at each outer step's start time and heading
    ch = [c for c, _ in p.channels()]
    i_d, i_psi = ch.index("tau_drift[X]"), ch.index("psi")
    w = p.env.waves
    assert w.drift_table
    for k in range(1, len(r.time), 13):
        F = w.tau_drift(float(r.time[k - 1]), float(r.data[k - 1, i_psi]))
        assert np.allclose(r.data[k, i_d:i_d + 3], F, rtol=1e-9, atol=1e-9 * np.abs(F).max())
    # and it is not the wall-sided drift of the same sea
    q = Plant(with_sea(fpso, "storm", wave_spreading=spread), sea_state="storm", seed=2)
    rq = run_open_loop(q, 20.0, thruster_cmd=_cmd(len(fpso.thrusters)), dt_log=0.1)
    assert not np.allclose(rq.data[:, i_d:i_d + 3], r.data[:, i_d:i_d + 3], rtol=0.05)


@compiled_only
def test_the_plant_runs_a_developing_sea_with_a_table(fpso, shaped_file):
    a, b = fpso.sea_state("normal"), fpso.sea_state("storm")
    rows = (SeaStateRow(t=20.0, Hs=a.Hs, Tp=a.Tp), SeaStateRow(t=60.0, Hs=b.Hs, Tp=b.Tp))
    sc = with_sea(with_drift(fpso, shaped_file), "normal", development=rows)
    runs = []
    for compiled in (True, False):
        p = Plant(sc, sea_state="normal", seed=4)
        p.compiled = compiled
        runs.append(run_open_loop(p, 80.0))
    assert_same(runs[0].data, runs[1].data)


def test_the_design_mean_load_is_the_tables_mean_drift(fpso, shaped_file):
    sc = with_drift(fpso, shaped_file)
    for psi in (0.0, 0.7):
        load = mean_environmental_load(sc, "storm", psi, seed=3)
        w = Environment(sc, "storm", seed=3).waves
        np.testing.assert_allclose(load.drift, w.mean_drift(psi), rtol=1e-12)
        assert not np.allclose(load.drift, mean_environmental_load(fpso, "storm", psi, seed=3).drift, rtol=0.05)


# --- the scenario -------------------------------------------------------------------------------

def test_the_scenario_names_its_drift_file(tmp_path, fpso, shaped_file):
    (tmp_path / "hull_drift.csv").write_bytes(shaped_file.read_bytes())
    d = scenario_to_dict(fpso)
    d["vessel"]["wave_motion"] = {"drift_file": "hull_drift.csv"}
    (tmp_path / "sc.toml").write_text(scenario_toml(d), encoding="utf-8")
    sc = tapm_opt.load_scenario(tmp_path / "sc.toml")   # a relative path: from the scenario's folder
    assert sc.vessel.wave_motion.drift_file == str(tmp_path / "hull_drift.csv")
    assert sc.vessel.wave_motion.model == "horizontal"   # any model takes a drift table
    assert Environment(sc, "storm").waves.drift_table
    for name, match in (("nowhere.csv", r"vessel\.wave_motion\.drift_file.*no such file"),
                        ("hull_drift.txt", r"vessel\.wave_motion\.drift_file.*\.csv table .* WAMIT \.8 or \.9")):
        d["vessel"]["wave_motion"]["drift_file"] = name
        (tmp_path / "bad.toml").write_text(scenario_toml(d), encoding="utf-8")
        with pytest.raises(ScenarioError, match=match):
            tapm_opt.load_scenario(tmp_path / "bad.toml")
    # a file the reader refuses: the plant names the field, the file, the row and the column
    (tmp_path / "broken.csv").write_text(HEADER + "0.5,0,surge,lots\n", encoding="utf-8")
    d["vessel"]["wave_motion"]["drift_file"] = "broken.csv"
    (tmp_path / "bad.toml").write_text(scenario_toml(d), encoding="utf-8")
    with pytest.raises(PlantError, match=r"drift_file = .*broken\.csv.*row 2, column D: 'lots'"):
        Environment(tapm_opt.load_scenario(tmp_path / "bad.toml"), "storm")
