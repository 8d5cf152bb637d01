"""Tests of the lumped-mass FEM mooring (tapm_opt.plant.fem, .mooring_fem, .forced_motion).

Static limit against the elastic catenary (and its second-order convergence in the number of
segments), a settled line at rest, energy dissipation of the symplectic-Euler scheme, convergence
of forced-motion results in time step and segments, the direction and symmetry of the tension
response, the damping's dependence on amplitude and period, the divergence diagnostics, the node
loads (weight, drag, added mass) in closed form and the fairlead kinematics.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import scenario_from_dict, scenario_to_dict
from tapm_opt.errors import ModelError
from tapm_opt.models.mooring import MooringModel
from tapm_opt.plant.fem import FEMLines, LineSet, SimulationDiverged
from tapm_opt.plant.forced_motion import forced_motion
from tapm_opt.plant.mooring_fem import MooringFEM

SCENARIOS = ("aamo4", "ren8", "fpso")
ZERO = np.zeros(3)


@functools.lru_cache(maxsize=None)
def scenario(name: str):
    return tapm_opt.load_scenario(name)


@functools.lru_cache(maxsize=None)
def catenary_tensions(name: str) -> np.ndarray:
    return MooringModel.from_scenario(scenario(name)).tensions(ZERO)


@functools.lru_cache(maxsize=None)
def settled_error(name: str, segments: int) -> float:
    """Largest relative difference between the settled FEM and the catenary fairlead tensions."""
    m = MooringFEM(scenario(name), segments=segments)
    m.initialise(ZERO)
    info = m.settle(ZERO)
    assert info.converged, info
    return float(np.max(np.abs(m.fairlead_tension() / catenary_tensions(name) - 1.0)))


def hold(m: MooringFEM, seconds: float, callback=None) -> None:
    """Step the lines with the fairleads held where they are, in still water."""
    fem = m.fem
    r_fl = fem.r[fem.fairlead_idx].copy()
    v_fl = np.zeros_like(r_fl)
    vc = np.zeros((fem.n_nodes, 3))
    for _ in range(int(round(seconds / m.dt))):
        if callback is not None:
            callback()
        fem.step(m.dt, r_fl, v_fl, vc)


# ------------------------------------------------------------------------------------------
# static limit
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", SCENARIOS)
def test_settled_tension_matches_catenary(name):
    """FEM static equilibrium at 20 segments = elastic catenary fairlead tension within 0.5 %."""
    assert settled_error(name, 20) < 5e-3


@pytest.mark.parametrize("name", SCENARIOS)
def test_static_error_falls_with_segments(name):
    """The lumping error falls monotonically 10 -> 20 -> 40 segments and is < 0.1 % at 40."""
    e10, e20, e40 = (settled_error(name, n) for n in (10, 20, 40))
    assert e10 > e20 > e40, (e10, e20, e40)
    assert e40 < 1e-3


def test_static_error_is_second_order_for_a_suspended_line():
    """aamo4's lines hang free of the seabed (no contact model involved): the error is that of
    the lumped weight alone and falls ~4x per doubling of the segments (observed order >= 1.8)."""
    regimes = MooringModel.from_scenario(scenario("aamo4")).solve_lines(ZERO).regime_names()
    assert set(regimes) == {"suspended"}
    e = [settled_error("aamo4", n) for n in (10, 20, 40)]
    orders = np.log2(np.array(e[:-1]) / np.array(e[1:]))
    assert np.all(orders > 1.8), orders


@pytest.mark.parametrize("name", SCENARIOS)
def test_settled_lines_keep_their_tension(name):
    """No motion and no environment: after settling, a free run of 100 s (no settling damping)
    keeps every fairlead tension within 0.1 %."""
    m = MooringFEM(scenario(name), segments=20)
    m.initialise(ZERO)
    m.settle(ZERO)
    T0 = m.fairlead_tension()
    worst = [0.0]

    def track():
        worst[0] = max(worst[0], float(np.max(np.abs(m.fairlead_tension() / T0 - 1.0))))

    hold(m, 100.0, callback=track)
    track()
    assert worst[0] < 1e-3


# ------------------------------------------------------------------------------------------
# energy
# ------------------------------------------------------------------------------------------

def test_energy_never_grows_in_a_free_run():
    """Still water, fairleads fixed, lines started off equilibrium (a smooth 20 m sideways bow
    and random node velocities): the lines only dissipate energy.

    Symplectic Euler conserves a *staggered* energy (kinetic energy from the velocities before
    and after the step, ``1/2 m v_n . v_n+1``, with the potential at the position the step
    starts from) -- exactly for a linear undamped system. That discrete energy must never grow
    (round-off allowance 1e-9 relative). ``FEMLines.energy()`` itself, evaluated at one time
    level, oscillates by O(dt) within a step, so for it we check that it never rises above its
    starting value and that most of the excess energy has been dissipated after 100 s.
    """
    m = MooringFEM(scenario("aamo4"), segments=10)
    m.initialise(ZERO)
    m.settle(ZERO)
    fem = m.fem
    E_rest = fem.energy()
    rng = np.random.default_rng(20240611)
    for j in range(fem.n_lines):
        n = int(fem.lines.segments[j])
        s = np.arange(n + 1) / n
        sl = slice(fem.node_start[j], fem.node_start[j] + n + 1)
        fem.r[sl, 1] += 20.0 * np.sin(np.pi * s)
    free = ~fem.fixed
    fem.v[free] = rng.normal(0.0, 0.3, (int(free.sum()), 3))
    E0 = fem.energy()
    assert E0 - E_rest > 1e6  # the perturbation holds a real amount of energy [J]
    staggered, plain, deepest = [], [E0], [float(np.max(fem.r[:, 2]))]
    state = {}

    def before():
        state["v"] = fem.v.copy()
        state["V"] = fem.energy() - 0.5 * np.sum(fem.node_mass * np.einsum("ij,ij->i", fem.v, fem.v))

    def after_previous():
        if state:
            kin = 0.5 * np.sum(fem.node_mass * np.einsum("ij,ij->i", state["v"], fem.v))
            staggered.append(state["V"] + kin)
            plain.append(fem.energy())
            deepest.append(float(np.max(fem.r[:, 2])))
        before()

    hold(m, 100.0, callback=after_previous)
    after_previous()
    # no node went below the seabed (the contact spring's energy is not part of energy())
    assert max(deepest) <= fem.depth + 1e-9
    staggered, plain = np.array(staggered), np.array(plain)
    tol = 1e-9 * abs(E0)
    assert np.max(np.diff(staggered)) <= tol, np.max(np.diff(staggered))
    assert np.max(plain) <= E0 + tol
    assert plain[-1] - E_rest < 0.5 * (E0 - E_rest)


# ------------------------------------------------------------------------------------------
# forced motion: convergence and physics
# ------------------------------------------------------------------------------------------

SURGE = dict(dof="surge", amplitude=20.0, period=100.0, duration=300.0, dt_out=1.0)


@pytest.fixture(scope="module")
def surge():
    """aamo4 forced surge runs: reference (20 segments, safety 0.9) and its variants."""
    sc = scenario("aamo4")
    runs = {
        "ref": forced_motion(sc, segments=20, **SURGE),
        "half_dt": forced_motion(sc, segments=20, safety=0.45, **SURGE),
        "seg40": forced_motion(sc, segments=40, **SURGE),
        "A10": forced_motion(sc, segments=20, **{**SURGE, "amplitude": 10.0}),
        "P200": forced_motion(sc, segments=20, **{**SURGE, "period": 200.0, "duration": 400.0}),
    }
    return runs


def test_forced_motion_converges_in_time_step(surge):
    ref, half = surge["ref"], surge["half_dt"]
    assert half.dt < 0.6 * ref.dt
    np.testing.assert_array_equal(half.t, ref.t)
    assert np.max(np.abs(half.T - ref.T)) < 0.01 * np.max(ref.T)
    assert half.damping == pytest.approx(ref.damping, rel=0.03)


def test_forced_motion_converges_in_segments(surge):
    ref, fine = surge["ref"], surge["seg40"]
    assert np.max(np.abs(fine.T - ref.T)) < 0.01 * np.max(ref.T)
    assert fine.damping == pytest.approx(ref.damping, rel=0.03)


def test_forced_surge_loads_the_line_behind_and_unloads_the_line_ahead(surge):
    """aamo4 surge: line "1" runs to the anchor at +x, line "3" to the anchor at -x. Near the
    turning points (|x| >= 0.9 A, where the lines hardly move and drag vanishes) the tension of
    line 3 is above its static value when x > 0 and below it when x < 0; line 1 the reverse.
    (Between the turning points drag leads the tension ahead of the position, so the sign is
    not tied to x there.) The catenary agrees at the same poses."""
    r = surge["ref"]
    ids = list(r.line_ids)
    i1, i3 = ids.index("1"), ids.index("3")
    x, T = r.eta[:, 0], r.T
    T0 = T[0]
    ahead = x >= 0.9 * r.amplitude
    behind = x <= -0.9 * r.amplitude
    assert ahead.sum() >= 3 and behind.sum() >= 3
    assert np.all(T[ahead, i3] > T0[i3]) and np.all(T[ahead, i1] < T0[i1])
    assert np.all(T[behind, i3] < T0[i3]) and np.all(T[behind, i1] > T0[i1])
    qs = r.T_quasi_static
    assert np.all(qs[ahead, i3] > qs[0, i3]) and np.all(qs[ahead, i1] < qs[0, i1])
    # over the whole run the tension of line 3 goes with x and that of line 1 against it
    assert np.corrcoef(x, T[:, i3])[0, 1] > 0.5
    assert np.corrcoef(x, T[:, i1])[0, 1] < -0.5


def test_forced_surge_keeps_the_perpendicular_lines_equal(surge):
    """Lines 2 (+y) and 4 (-y) are mirror images about the direction of motion."""
    r = surge["ref"]
    ids = list(r.line_ids)
    T2, T4 = r.T[:, ids.index("2")], r.T[:, ids.index("4")]
    np.testing.assert_allclose(T2, T4, rtol=1e-6)
    # and they do respond (the test would be empty if they stayed at their static value)
    assert np.ptp(T2) > 1e-3 * T2[0]


def test_forced_motion_damping_positive_and_grows_with_velocity(surge):
    """Quadratic drag: the equivalent linear damping b = W / (pi w A^2) is positive and grows
    with the velocity amplitude A w -- smaller with half the amplitude or twice the period."""
    ref, a10, p200 = surge["ref"], surge["A10"], surge["P200"]
    assert ref.damping > 0 and ref.energy_per_cycle > 0
    assert a10.cycles_analysed >= 1 and p200.cycles_analysed >= 1
    assert 0 < a10.damping < ref.damping
    assert 0 < p200.damping < ref.damping


def test_dynamic_amplification_tends_to_quasi_static_for_slow_motion(surge):
    """Drag adds to the tension range of the in-line lines (amplification > 1) and matters less
    the slower the motion: at twice the period the amplification is closer to 1."""
    ref, p200 = surge["ref"], surge["P200"]
    ids = list(ref.line_ids)
    for i in (ids.index("1"), ids.index("3")):
        assert ref.amplification[i] > 1.0
        assert 1.0 <= p200.amplification[i] < ref.amplification[i]


@pytest.mark.parametrize("name,dof,amplitude,segments", [
    ("aamo4", "surge", 5.0, 10), ("ren8", "sway", 5.0, 10), ("fpso", "yaw", math.radians(3.0), None),
    ("fpso", "yaw", math.radians(3.0), 10)])
def test_forced_motion_on_every_builtin(name, dof, amplitude, segments):
    """Short runs on each built-in scenario: finite histories that start at the catenary
    tensions, a positive damping estimate, and a table with one column per line (fpso at its own
    segments and at the studies' 10, where the 300 m bottom chain gets two segments)."""
    sc = scenario(name)
    r = forced_motion(sc, dof=dof, amplitude=amplitude, period=50.0, duration=100.0, segments=segments)
    assert np.all(np.isfinite(r.T)) and np.all(np.isfinite(r.force))
    k = ("surge", "sway", "yaw").index(dof)
    np.testing.assert_allclose(r.eta[:, k], amplitude * np.sin(2 * np.pi * r.t / 50.0), atol=1e-12)
    np.testing.assert_allclose(r.T[0], catenary_tensions(name), rtol=5e-3)
    np.testing.assert_allclose(r.T_quasi_static[0], catenary_tensions(name), rtol=1e-9)
    assert r.cycles_analysed == 1 and r.damping > 0
    header, data = r.table()
    assert len(header) == 4 + len(sc.lines) and data.shape == (len(r.t), len(header))


def three_line_scenario():
    """A scenario written by hand: 3 chain lines at 120 deg in 150 m of water."""
    chain = dict(id="chain", diameter=0.1, mass_per_length=200.0, density=7850.0, EA=8.0e8,
                 MBS=8.0e6, MBS_std=4.0e5, Cd_normal=2.4, Cd_tangential=0.4, Ca_normal=1.0)
    lines = [dict(id=f"L{k}", type="chain", anchor=[800.0 * math.cos(a), 800.0 * math.sin(a)],
                  fairlead_angle_deg=math.degrees(a), length=850.0, segments=24)
             for k, a in enumerate((0.0, 2 * math.pi / 3, -2 * math.pi / 3))]
    d = {
        "meta": {"name": "three_line", "description": "hand-written 3-line test mooring"},
        "environment": {"water_depth": 150.0, "water_density": 1025.0, "gravity": 9.81},
        "vessel": {"name": "barge", "mass_matrix": [[2e7, 0, 0], [0, 3e7, 0], [0, 0, 2e10]],
                   "linear_damping": [[2e5, 0, 0], [0, 4e5, 0], [0, 0, 5e8]],
                   "length_pp": 100.0, "breadth": 30.0, "draught": 6.0,
                   "wind_area_frontal": 600.0, "wind_area_lateral": 1500.0},
        "turret": {"position": [0.0, 0.0], "mode": "locked", "fairlead_radius": 5.0, "fairlead_depth": 6.0},
        "line_types": [chain],
        "lines": lines,
    }
    return scenario_from_dict(d)


def test_forced_motion_on_a_hand_written_scenario():
    sc = three_line_scenario()
    A = 8.0
    r = forced_motion(sc, dof="surge", amplitude=A, period=40.0, duration=120.0, segments=24)
    ids = list(r.line_ids)
    assert ids == ["L0", "L1", "L2"]
    # most of each line lies on the seabed; the lumping error depends on where the touchdown
    # point falls between two nodes (+0.55 % at 24 segments, -0.14 % at 48, -0.03 % at 96)
    np.testing.assert_allclose(r.T[0], MooringModel.from_scenario(sc).tensions(ZERO), rtol=1e-2)
    x, T = r.eta[:, 0], r.T
    # the motion starts at full speed, which sets off axial ringing in the stiff chain during
    # the first cycle; look at the later cycles (as forced_motion's estimates do)
    ahead = (x >= 0.9 * A) & (r.t >= r.period)
    assert ahead.sum() >= 6
    # L0's anchor is at +x: it slackens as the vessel moves toward it; L1, L2 tighten equally
    assert np.all(T[ahead, 0] < T[0, 0])
    assert np.all(T[ahead, 1] > T[0, 1])
    np.testing.assert_allclose(T[:, 1], T[:, 2], rtol=1e-6)
    assert r.damping > 0 and r.cycles_analysed == 2


def test_forced_motion_bad_input():
    sc = scenario("aamo4")
    with pytest.raises(ModelError, match="dof"):
        forced_motion(sc, dof="heave", amplitude=1.0, period=10.0, duration=10.0)
    for name in ("amplitude", "period", "duration", "dt_out"):
        kw = dict(amplitude=1.0, period=10.0, duration=10.0, dt_out=1.0)
        kw[name] = -1.0
        with pytest.raises(ModelError, match=name):
            forced_motion(sc, **kw)
    with pytest.raises(ModelError, match="segments"):
        MooringFEM(sc, segments=1)
    with pytest.raises(ModelError, match="safety"):
        MooringFEM(sc, safety=0.0)
    with pytest.raises(ModelError, match="99"):
        MooringFEM(sc, segments=4).break_line("99")


# ------------------------------------------------------------------------------------------
# divergence
# ------------------------------------------------------------------------------------------

def test_too_long_a_step_is_reported_as_simulation_diverged():
    """20x the stable step blows up; check_health names the time, the line and the node and
    tells the user what to do."""
    m = MooringFEM(scenario("aamo4"), segments=10)
    m.initialise(ZERO)
    fem = m.fem
    fem.check_health()  # healthy to start with
    dt = 20.0 * fem.stable_dt(1.0)
    r_fl = fem.r[fem.fairlead_idx].copy()
    v_fl = np.zeros_like(r_fl)
    vc = np.zeros((fem.n_nodes, 3))
    with pytest.raises(SimulationDiverged) as info, np.errstate(all="ignore"):
        for _ in range(100):
            fem.step(dt, r_fl, v_fl, vc)
            fem.check_health()
    err = info.value
    assert isinstance(err, tapm_opt.errors.TapmError)
    assert err.time == pytest.approx(fem.t) and err.time > 0
    assert err.line in fem.lines.ids
    assert isinstance(err.node, int) and 0 < err.node < int(fem.lines.segments[fem.lines.ids.index(err.line)])
    msg = str(err)
    assert f"line {err.line!r}" in msg and f"node {err.node}" in msg and f"t = {err.time:.3f} s" in msg
    assert "time step" in msg and "safety" in msg


def test_check_health_flags_a_non_finite_node():
    m = MooringFEM(scenario("ren8"), segments=6)
    m.initialise(ZERO)
    fem = m.fem
    j = fem.lines.ids.index("5")
    fem.r[fem.node_start[j] + 3, 0] = np.nan
    with pytest.raises(SimulationDiverged, match="non-finite") as info:
        fem.check_health()
    assert (info.value.line, info.value.node) == ("5", 3)


# ------------------------------------------------------------------------------------------
# node loads in closed form (seed line-tension-control-fem eq. 2-5) and fairlead kinematics
# ------------------------------------------------------------------------------------------

RHO_W = 1025.0


def straight_line(**coef) -> FEMLines:
    """One 800 m line held straight at its unstretched length along x, 500 m deep in 1000 m of
    water: no tension and no seabed contact, so an interior node feels only weight and drag."""
    n, L = 8, 800.0
    c = dict(Cdn=2.4, Cdt=0.4, Can=1.0, Cat=0.5, **coef)
    one = lambda v: np.array([float(v)])  # noqa: E731
    ls = LineSet(ids=("a",), L=one(L), EA=one(8e8), w=one(770.0), mass=one(90.0), d=one(0.12),
                 Cdn=one(c["Cdn"]), Cdt=one(c["Cdt"]), Can=one(c["Can"]), Cat=one(c["Cat"]),
                 segments=np.array([n]), damping_ratio=one(0.0), mu=one(0.0))
    fem = FEMLines(ls, np.array([[0.0, 0.0, 500.0]]), water_depth=1000.0, rho_w=RHO_W)
    fem.r[:] = np.column_stack([np.linspace(0.0, L, n + 1), np.zeros(n + 1), np.full(n + 1, 500.0)])
    return fem


def test_node_weight_and_added_mass_are_seed_eq2_and_eq5():
    """At rest in still water an interior node sinks with a = w / (m + C_MN rho pi d^2 / 4): its
    weight per length over its mass plus the normal added mass per length."""
    fem = straight_line()
    a, T = fem.accelerations(fem.r, np.zeros_like(fem.r), np.zeros_like(fem.r))
    inner = slice(1, -1)
    m_an = 1.0 * RHO_W * math.pi * 0.12**2 / 4.0
    np.testing.assert_allclose(a[inner, 2], 770.0 / (90.0 + m_an), rtol=1e-9)
    np.testing.assert_allclose(a[inner, :2], 0.0, atol=1e-9)
    assert np.max(T) < 1e-3  # [N]: the line is not stretched


@pytest.mark.parametrize("axis", ["normal", "tangential"])
def test_node_drag_in_a_uniform_current_is_seed_eq3_and_eq4(axis):
    """A node at rest in a current V: drag 1/2 rho C d V^2 per length along the current (C_DN
    across the line, C_DT along it), accelerating it through the mass plus the added mass of that
    direction (C_MN across, the tangential coefficient along)."""
    V = 1.5
    fem = straight_line()
    k = 1 if axis == "normal" else 0
    vc = np.zeros_like(fem.r)
    vc[:, k] = V
    a, _ = fem.accelerations(fem.r, np.zeros_like(fem.r), vc)
    Cd, Ca = (2.4, 1.0) if axis == "normal" else (0.4, 0.5)
    expected = 0.5 * RHO_W * Cd * 0.12 * V**2 / (90.0 + Ca * RHO_W * math.pi * 0.12**2 / 4.0)
    np.testing.assert_allclose(a[1:-1, k], expected, rtol=1e-9)
    np.testing.assert_allclose(a[1:-1, 1 - k], 0.0, atol=1e-9)


@pytest.mark.parametrize("mode", ["free", "locked"])
def test_fairlead_velocities_are_the_time_derivative_of_eq5(mode):
    """MooringFEM.fairlead_state: the velocities equal the central difference of the positions
    (survey eq. 5) along a smooth pose history, for a weathervaning and a locked turret."""
    data = scenario_to_dict(scenario("fpso"))
    data["turret"]["mode"] = mode
    m = MooringFEM(scenario_from_dict(data), segments=4)

    def eta(t):
        return np.array([30.0 * math.sin(0.1 * t), -20.0 * math.cos(0.07 * t), 0.4 * math.sin(0.05 * t)])

    def eta_dot(t):
        return np.array([3.0 * math.cos(0.1 * t), 1.4 * math.sin(0.07 * t), 0.02 * math.cos(0.05 * t)])

    h = 1e-4
    for t in (0.0, 7.0, 31.0):
        r, v = m.fairlead_state(eta(t), eta_dot(t))
        r_p, _ = m.fairlead_state(eta(t + h), eta_dot(t + h))
        r_m, _ = m.fairlead_state(eta(t - h), eta_dot(t - h))
        np.testing.assert_allclose(v, (r_p - r_m) / (2.0 * h), atol=1e-6)
        assert np.all(v[:, 2] == 0.0) and np.all(r[:, 2] == m.fairlead_z)

