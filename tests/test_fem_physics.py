"""FEM plant physics: the damped stable step, settling that must converge, the fairlead node's
load on the vessel, and lines that break when overloaded (docs/plant.md)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.errors import ModelError
from tapm_opt.plant.fem import FEMLines, LineSet, SimulationDiverged
from tapm_opt.plant.forced_motion import forced_motion
from tapm_opt.plant.mooring_fem import MooringFEM, SettlingNotConverged
from tapm_opt.plant.simulator import Plant, PlantError

RHO = 1025.0


def _taut_line(zeta: float, *, n: int = 20, strain: float = 0.01) -> FEMLines:
    """One straight horizontal line under 1 % strain, weightless and drag-free, far above the seabed."""
    ls = LineSet(ids=("1",), L=np.array([100.0]), EA=np.array([1e8]), w=np.array([0.0]), mass=np.array([50.0]),
                 d=np.array([0.1]), Cdn=np.array([0.0]), Cdt=np.array([0.0]), Can=np.array([0.0]),
                 Cat=np.array([0.0]), segments=np.array([n]), damping_ratio=np.array([zeta]), mu=np.array([0.0]))
    fem = FEMLines(ls, np.array([[0.0, 0.0, 100.0]]), water_depth=1000.0, rho_w=RHO)
    x = np.linspace(0.0, 100.0 * (1 + strain), n + 1)
    fem.r[:] = np.column_stack([x, np.zeros(n + 1), np.full(n + 1, 100.0)])
    return fem


def _growth(fem: FEMLines, dt: float, steps: int = 400) -> float:
    """Largest node displacement after ``steps`` steps from a 1 um random axial perturbation,
    relative to the initial one."""
    rng = np.random.default_rng(0)
    r_eq = fem.r.copy()
    free = ~fem.fixed
    fem.r[free, 0] += 1e-6 * rng.standard_normal(int(free.sum()))
    d0 = np.max(np.abs(fem.r - r_eq))
    fl_r, fl_v = r_eq[fem.fairlead_idx], np.zeros((1, 3))
    vc = np.zeros((fem.n_nodes, 3))
    with np.errstate(all="ignore"):
        for _ in range(steps):
            fem.step(dt, fl_r, fl_v, vc)
            g = np.max(np.abs(fem.r - r_eq)) / d0
            if not np.isfinite(g) or g > 1e6:
                return math.inf
    return float(g)


@pytest.mark.parametrize("zeta", [0.0, 0.2, 1 / math.sqrt(2), 1.0])
def test_chosen_step_is_stable_and_ten_percent_above_is_not(zeta):
    dt = _taut_line(zeta).stable_dt(1.0)
    assert _growth(_taut_line(zeta), dt) < 10.0
    assert _growth(_taut_line(zeta), 1.1 * dt) > 1e3


def test_stable_step_falls_with_damping_like_the_zigzag_mode():
    # uniform line: zig-zag mode w^2 = 4k/m (Gershgorin), damped at sqrt(2) zeta
    k, m = 1e8 / 5.0, 50.0 * 5.0
    w = math.sqrt(4 * k / m)
    for zeta in (0.0, 0.5, 1 / math.sqrt(2)):
        z = math.sqrt(2) * zeta
        expected = 2 * (math.sqrt(1 + z * z) - z) / w
        assert _taut_line(zeta).stable_dt(1.0) == pytest.approx(expected, rel=1e-12)


def test_settling_damping_shortens_the_step():
    fem = _taut_line(0.3)
    assert fem.stable_dt(1.0, extra_damping=50.0) < fem.stable_dt(1.0)


def _damped(name: str, zeta: float = 1 / math.sqrt(2)):
    sc = load_scenario(name)
    return dataclasses.replace(sc, line_types=tuple(dataclasses.replace(t, axial_damping_ratio=zeta)
                                                     for t in sc.line_types))


def test_settling_on_the_old_undamped_bound_fails_loudly():
    """The issue's case: zeta = 1/sqrt(2) stepped with the bound that ignored the zig-zag mode's
    extra damping (W = 0.93 against 0.83) must not report 'settled'."""
    m = MooringFEM(_damped("aamo4"))
    z = 1 / math.sqrt(2)
    old = m.fem.stable_dt(1.0) / (2 * (math.sqrt(1 + 2 * z * z) - math.sqrt(2) * z)) * 2 * (math.sqrt(1 + z * z) - z) * 0.9
    m.dt = old
    m.fem.stable_dt = lambda safety=0.8, extra_damping=0.0: old  # the old bound, as if still in use
    m.initialise(np.zeros(3))
    with pytest.raises((SettlingNotConverged, SimulationDiverged)) as exc:
        m.settle(np.zeros(3), max_time=120.0)
    if isinstance(exc.value, SettlingNotConverged):
        assert "safety" in str(exc.value) and exc.value.info.max_speed > 0.1


def test_settling_that_runs_out_of_time_is_reported():
    m = MooringFEM(load_scenario("aamo4"), segments=10)
    m.initialise(np.zeros(3))
    m.fem.r[m.fem.line_of_node == 0, 2] -= 5.0  # lift line 1: far from rest
    with pytest.raises(SettlingNotConverged, match="did not settle within 5 s"):
        m.settle(np.zeros(3), max_time=5.0)
    m.initialise(np.zeros(3))
    m.fem.r[m.fem.line_of_node == 0, 2] -= 5.0
    info = m.settle(np.zeros(3), max_time=5.0, strict=False)
    assert not info.converged and info.time == pytest.approx(5.0, abs=0.1) and info.wall_time > 0
    info = m.settle(np.zeros(3))
    assert info.converged and info.max_speed < 0.01 and info.tension_change < 1e-6


def test_fairlead_load_adds_the_half_segment_drag_and_inertia():
    m = MooringFEM(load_scenario("fpso"), segments=10)
    m.initialise(np.zeros(3))
    m.settle(np.zeros(3))
    fem = m.fem
    fl = fem.fairlead_idx
    rng = np.random.default_rng(1)
    fem.v[fl] = rng.normal(0.0, 1.0, (len(fl), 3))
    vc = rng.normal(0.0, 0.5, (len(fl), 3))
    a = rng.normal(0.0, 0.3, (len(fl), 3))
    lt = load_scenario("fpso").line_types[0]
    d, l0 = lt.diameter, fem.l0[fem.fairlead_seg]
    lv = fem.r[fl] - fem.r[fl - 1]
    eps = np.linalg.norm(lv, axis=1)
    q = lv / eps[:, None]
    vr = fem.v[fl] - vc
    vt = np.sum(vr * q, axis=1)
    vn = vr - vt[:, None] * q
    half = eps / 2.0
    drag = -0.5 * RHO * d * half[:, None] * (lt.Cd_normal * np.linalg.norm(vn, axis=1)[:, None] * vn
                                             + lt.Cd_tangential * (np.abs(vt) * vt)[:, None] * q)
    m_node = lt.mass_per_length * l0 / 2.0
    area = math.pi * d * d / 4.0
    at = np.sum(a * q, axis=1)
    an = a - at[:, None] * q
    inertia = -(m_node + lt.Ca_normal * RHO * area * half)[:, None] * an \
        - ((m_node + lt.Ca_tangential * RHO * area * half) * at)[:, None] * q
    static = fem.fairlead_forces()
    fem.v[fl] = 0.0
    static = fem.fairlead_forces()  # tension and weight only (no motion, no current)
    fem.v[fl] = vr + vc
    got = fem.fairlead_forces(vc, a)
    # the top segment's internal damping sees the fairlead velocity too: remove it via the tensions
    _, _, T_moving = fem.segment_state(fem.r, fem.v, fem.fairlead_seg)
    fem.v[fl] = 0.0
    _, _, T_rest = fem.segment_state(fem.r, fem.v, fem.fairlead_seg)
    damping = -(T_moving - T_rest)[:, None] * q
    np.testing.assert_allclose(got, static + damping + drag + inertia, rtol=1e-10, atol=1e-6)
    assert np.max(np.linalg.norm(drag, axis=1)) > 100.0  # the terms are not negligible here


def test_current_load_on_the_vessel_includes_the_fairlead_node():
    sc = load_scenario("fpso")
    plant = Plant(sc, sea_state="storm", seed=0, segments=10, wave_frequency=False)
    m = plant.mooring
    vc = m._vc[m.fem.fairlead_idx]
    assert np.linalg.norm(vc[:, :2]) > 0.1
    with_drag = m.tau(plant.eta_total)
    f_static = m.fem.fairlead_forces()
    tau_static = m.geometry.tau_from_forces(plant.eta_total, f_static[:, 0], f_static[:, 1],
                                            fairleads=(m._r_fl[:, 0], m._r_fl[:, 1]))
    extra = with_drag[:2] - tau_static[:2]
    # the fairlead nodes' drag pushes the turret downstream
    v_surface = np.asarray(plant.env.current.surface[:2])
    assert np.dot(extra, v_surface) > 0


def _overload_scenario(mbs_line1: float, mode: str = "mbs", std: float = 0.0):
    sc = load_scenario("aamo4")
    weak = dataclasses.replace(sc.line_types[0], id="weak", MBS=mbs_line1, MBS_std=std)
    lines = (dataclasses.replace(sc.lines[0], type="weak"),) + sc.lines[1:]
    return dataclasses.replace(sc, line_types=sc.line_types + (weak,), lines=lines,
                               plant=dataclasses.replace(sc.plant, break_on_overload=mode))


def test_an_overloaded_line_breaks_and_the_break_is_logged():
    probe = Plant(load_scenario("aamo4"), sea_state="none", segments=10)
    T1 = probe.mooring.fairlead_tension()[0]
    plant = Plant(_overload_scenario(0.9 * T1), sea_state="none", segments=10)
    plant.step(1.0)
    assert not plant.mooring.fem.active[0] and plant.mooring.fem.active[1:].all()
    assert plant.mooring.fairlead_tension()[0] == 0.0
    (t, text), = plant.events
    assert t <= 0.1 + 1e-9 and text.startswith("line 1 broke: overload")
    assert plant.metadata()["events"] == [[t, text]]
    # the others take the load: the vessel drifts away from the broken line's side
    plant.step(30.0)
    assert plant.mooring.fem.active[1:].all()


def test_never_lets_the_tension_exceed_mbs_and_strong_lines_hold():
    probe = Plant(load_scenario("aamo4"), sea_state="none", segments=10)
    T1 = probe.mooring.fairlead_tension()[0]
    plant = Plant(_overload_scenario(0.9 * T1, mode="never"), sea_state="none", segments=10)
    plant.step(1.0)
    assert plant.mooring.fem.active.all() and not plant.events
    plant = Plant(_overload_scenario(1.5 * T1), sea_state="none", segments=10)
    plant.step(1.0)
    assert plant.mooring.fem.active.all() and not plant.events


def test_sampled_strength_is_drawn_from_the_seed():
    sc = _overload_scenario(1e7, mode="sampled", std=1e6)
    a = Plant(sc, sea_state="none", segments=10, seed=3).strength
    b = Plant(sc, sea_state="none", segments=10, seed=3).strength
    c = Plant(sc, sea_state="none", segments=10, seed=4).strength
    np.testing.assert_array_equal(a, b)
    assert a[0] != c[0] and abs(a[0] - 1e7) < 5e6
    mbs = sc.line_type(sc.lines[1]).MBS
    assert np.all(np.abs(a[1:] - mbs) <= 6 * sc.line_type(sc.lines[1]).MBS_std + 1e-9)
    assert Plant(sc, sea_state="none", segments=10, break_on_overload="mbs").strength[0] == 1e7
    with pytest.raises(PlantError, match="break_on_overload"):
        Plant(sc, sea_state="none", segments=10, break_on_overload="sometimes")


def test_forced_motion_separates_the_start_up_and_takes_a_sea_state_current():
    sc = load_scenario("aamo4")
    still = forced_motion(sc, amplitude=5.0, period=50.0, duration=150.0, segments=10)
    assert still.cycles_analysed == 2 and still.sea_state is None
    mo = still.t >= 50.0 - 1e-9
    np.testing.assert_allclose(still.T_range[:, 0], still.T[mo].min(axis=0))
    np.testing.assert_allclose(still.T_range[:, 1], still.T[mo].max(axis=0))
    first = still.t <= 50.0 + 1e-9
    np.testing.assert_allclose(still.T_startup[:, 1], still.T[first].max(axis=0))
    assert still.wall_time >= still.settle.wall_time > 0
    ss = next(s for s in sc.sea_states if s.current_speed > 0)
    cur = forced_motion(sc, amplitude=5.0, period=50.0, duration=150.0, segments=10, sea_state=ss.id)
    assert cur.sea_state == ss.id
    assert not np.allclose(cur.T_range, still.T_range, rtol=1e-4)
    with pytest.raises(PlantError, match="sea_state"):
        forced_motion(sc, amplitude=5.0, period=50.0, duration=150.0, segments=10, sea_state="tsunami")


@pytest.mark.parametrize("kernel", ["numba", "numpy"])
def test_seabed_friction_stops_a_sliding_node_like_coulomb(kernel):
    """A slack line lying on the seabed, its middle node pushed sideways at 5 cm/s: Coulomb friction
    decelerates it at mu w/m, it stops after v0 m/(mu w) having slid v0^2 m/(2 mu w), and then
    sticks (exactly 0), whatever the step; friction acts on the velocity over the seabed."""
    mu, w, m, depth = 0.7, 1000.0, 150.0, 100.0
    ls = LineSet(ids=("1",), L=np.array([30.0]), EA=np.array([1e9]), w=np.array([w]), mass=np.array([m]),
                 d=np.array([0.1]), Cdn=np.array([0.0]), Cdt=np.array([0.0]), Can=np.array([0.0]),
                 Cat=np.array([0.0]), segments=np.array([2]), damping_ratio=np.array([0.0]), mu=np.array([mu]))
    fem = FEMLines(ls, np.array([[0.0, 0.0, depth]]), water_depth=depth, rho_w=RHO, kernel=kernel)
    pen = 0.01  # at rest the node sinks 1 cm: k_b pen = its weight
    fem.r[:] = [[0.0, 0.0, depth], [10.0, 0.0, depth + pen], [20.0, 0.0, depth]]
    v0 = 0.05
    fem.v[1] = [0.0, v0, 0.0]
    dt = 1e-3
    a_fric = mu * w / m
    t_stop = v0 / a_fric
    fl_r, fl_v = fem.r[[2]].copy(), np.zeros((1, 3))
    current = np.tile([0.0, 0.3, 0.0], (3, 1))  # a bottom current does not drag the node along
    n = int(round(1.5 * t_stop / dt))
    for _ in range(n):
        fem.step(dt, fl_r, fl_v, current)
    assert fem.v[1, 1] == 0.0 and fem.v[1, 0] == 0.0
    slid = fem.r[1, 1]
    # semi-implicit Euler moves with the velocity after each step's friction: -v0 dt / 2 in all
    assert slid == pytest.approx(v0 * v0 / (2 * a_fric) - v0 * dt / 2, rel=0.01)
    for _ in range(200):
        fem.step(dt, fl_r, fl_v, current)
    assert fem.r[1, 1] == slid  # stuck


def test_overload_counts_the_fairlead_node_weight_on_a_coarse_mesh():
    """At 10 segments the fpso fairlead tension exceeds the top segment's by ~4 % (the node's
    weight): a strength between the two must still break the line."""
    sc = load_scenario("fpso")
    probe = Plant(sc, sea_state="none", segments=10)
    fem = probe.mooring.fem
    T_fl = probe.mooring.fairlead_tension()[0]
    T_top = fem.segment_state(fem.r, fem.v, fem.fairlead_seg)[2][0]
    assert T_top < 0.97 * T_fl
    weak = dataclasses.replace(sc.line_types[0], id="weak", MBS=0.995 * T_fl)
    sc2 = dataclasses.replace(sc, line_types=sc.line_types + (weak,),
                              lines=(dataclasses.replace(sc.lines[0], type="weak"),) + sc.lines[1:])
    plant = Plant(sc2, sea_state="none", segments=10)
    plant.step(0.2)
    assert not plant.mooring.fem.active[0] and plant.events and "line 1 broke: overload" in plant.events[0][1]


def test_forced_motion_analyses_only_what_it_simulated_and_samples_every_cycle():
    sc = load_scenario("aamo4")
    kw = dict(amplitude=5.0, period=12.5, segments=6, dt_out=1.25)
    whole = forced_motion(sc, duration=25.0, **kw)
    ragged = forced_motion(sc, duration=26.0, **kw)  # simulated to 25 s: the same single cycle
    assert ragged.cycles_analysed == whole.cycles_analysed == 1
    assert ragged.damping == pytest.approx(whole.damping, rel=1e-12)
    with pytest.raises(ModelError, match="dt_out = 2 s must be at most period / 10"):
        forced_motion(sc, duration=25.0, amplitude=5.0, period=12.5, segments=6, dt_out=2.0)
