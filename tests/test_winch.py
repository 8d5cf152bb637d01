"""Passivity-based winch (line-tension) control ([AF] = seed line-tension-control-fem, §III-IV):
the configuration matrix, the controller's limits and anti-windup, the passivity of the winch port
on the FEM (Proposition 1), the closed loop on aamo4 in Table I's current, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.control.winch import (AF_KC, WinchError, WinchSettings, WinchTensionController, configuration_matrix,
                                    horizontal_force)
from tapm_opt.errors import TapmError
from tapm_opt.interfaces import Estimate, WinchController
from tapm_opt.models.system import System
from tapm_opt.plant.environment import Environment
from tapm_opt.plant.mooring_fem import MooringFEM
from tapm_opt.studies.closed_loop import ClosedLoopError, ClosedLoopSettings, run_closed_loop
from tapm_opt.studies.controllers import ControllerSpecError, build_controller
from tapm_opt.studies.kpis import case_kpis, kpi_unit


@pytest.fixture(scope="module")
def aamo4():
    return System.from_scenario(load_scenario("aamo4"))


def _est(eta=(0.0, 0.0, 0.0), tensions=None, t=0.0):
    return Estimate(t=t, eta=np.asarray(eta, float), nu=np.zeros(3), tau_env=np.zeros(3),
                    tensions=None if tensions is None else np.asarray(tensions, float))


# -- configuration matrix ---------------------------------------------------------------------

def test_configuration_matrix_is_the_papers_on_aamo4(aamo4):
    """[AF] §IV: p_j = I* r_0^j / |I* r_0^j| with r_0 = (2000, 0), (0, 2000), (-2000, 0), (0, -2000)."""
    B = configuration_matrix(aamo4.lines)
    hand = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    np.testing.assert_allclose(B, hand, atol=1e-12)
    # at an offset pose: the unit vectors from the fairlead (at the body origin) to the anchors
    B2 = configuration_matrix(aamo4.lines, (30.0, -40.0, 0.3))
    a = np.array([[2000.0, 0.0], [0.0, 2000.0], [-2000.0, 0.0], [0.0, -2000.0]]) - [30.0, -40.0]
    np.testing.assert_allclose(B2[:, :2], a / np.linalg.norm(a, axis=1)[:, None], atol=1e-12)
    np.testing.assert_allclose(horizontal_force(B, [3.0, 1.0, 1.0, 2.0]), [2.0, -1.0, 0.0])


def test_fpso_b_rows_are_unit_vectors_toward_the_anchors():
    s = System.from_scenario(load_scenario("fpso"))
    B = configuration_matrix(s.lines)
    np.testing.assert_allclose(np.linalg.norm(B, axis=1), 1.0)
    fx, fy = s.lines.fairleads(np.zeros(3))
    d = np.column_stack([s.lines.anchors[:, 0] - fx, s.lines.anchors[:, 1] - fy])
    np.testing.assert_allclose(np.einsum("ij,ij->i", B[:, :2], d), np.linalg.norm(d, axis=1))


# -- the law, limits and anti-windup ----------------------------------------------------------

def test_p_law_signs_and_gain(aamo4):
    """A command toward +x hauls line 1 (anchor at +x) in and pays line 3 out at k_c |e|."""
    c = WinchTensionController(aamo4)
    assert isinstance(c, WinchController)
    T0 = aamo4.lines.solve_lines(np.zeros(3)).TF
    c.update(0.0, _est(tensions=T0), np.zeros(3))
    u = c.update(1.0, _est(tensions=T0, t=1.0), [2.0e5, 0.0, 0.0])
    e = 2.0e5 - c.mooring_force_E()[0]
    np.testing.assert_allclose(u, [-AF_KC * e, 0.0, AF_KC * e, 0.0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(c.mooring_load()[:2], 0.0, atol=1.0)   # symmetric pattern at rest
    # the command is in {B}: at psi = 90 deg a surge command points to +y in {E} (line 2)
    c.reset()
    u = c.update(0.0, _est(eta=(0.0, 0.0, math.pi / 2), tensions=T0), [2.0e5, 0.0, 0.0])
    assert u[1] < 0 < u[3] and abs(u[0]) < 1e-9 and abs(u[2]) < 1e-9


def test_rate_length_and_tension_limits(aamo4):
    c = WinchTensionController(aamo4)
    T0 = aamo4.lines.solve_lines(np.zeros(3)).TF
    u = c.update(0.0, _est(tensions=T0), [1e8, 0.0, 0.0])          # absurd command: rate limit
    np.testing.assert_allclose(u, [-0.2, 0.0, 0.2, 0.0])
    assert c.limited[0] and c.limited[2]
    # line 1 at its tension ceiling: no haul-in, it pays out at k_c (T - T_max)
    T = T0.copy()
    T[0] = c.T_max[0] + 1e5
    u = c.update(1.0, _est(tensions=T, t=1.0), [1e8, 0.0, 0.0])   # the law wants to haul in hard
    assert u[0] == pytest.approx(AF_KC * 1e5)
    # line 3 below its floor: no pay-out
    T = T0.copy()
    T[2] = c.T_min[2] - 1e4
    u = c.update(2.0, _est(tensions=T, t=2.0), [1e6, 0.0, 0.0])
    assert u[2] <= 0.0
    # length limits: run line 1 in to its shortest length; it stops there
    c.reset()
    t = 0.0
    for _ in range(400):
        u = c.update(t, _est(tensions=T0, t=t), [1e6, 0.0, 0.0])
        t += 1.0
    lo = aamo4.scenario.lines[0].length_limits[0]
    assert c.lengths[0] == pytest.approx(lo) and u[0] == pytest.approx(0.0, abs=1e-12)
    assert aamo4.scenario.lines[2].length < c.lengths[2] <= aamo4.scenario.lines[2].length_limits[1]


def test_pi_anti_windup_freezes_the_integrator_in_saturation(aamo4):
    T0 = aamo4.lines.solve_lines(np.zeros(3)).TF
    pi = WinchTensionController(aamo4, {"kc": 2.5e-7, "ki": 1e-9})
    raw = WinchTensionController(aamo4, {"kc": 2.5e-7, "ki": 1e-9})
    t = 0.0
    for _ in range(50):                       # saturated by the rate limit all along
        pi.update(t, _est(tensions=T0, t=t), [3e6, 0.0, 0.0])
        t += 1.0
    z_sat = pi.integrator().copy()
    assert abs(z_sat[0]) < 2 * 3e6 * 1.0      # frozen after the first step, not 50 x 3e6 N s
    # unsaturated: the integral grows with the error
    t = 0.0
    for _ in range(50):
        raw.update(t, _est(tensions=T0, t=t), [1e4, 0.0, 0.0])
        t += 1.0
    assert raw.integrator()[0] == pytest.approx(49 * (1e4 - raw.mooring_force_E()[0]), rel=0.05)
    # the frozen integral's share of the speed is small (wound up, it would be 1e-9 x 1.5e8 = 0.15 m/s)
    assert 1e-9 * abs(z_sat[0]) < 0.01


# -- passivity on the FEM ([AF] Proposition 1) ------------------------------------------------

def test_winch_port_is_passive_on_the_fem():
    """Fairleads held at the field zero point ([AF] Problem 1: r(L) = 0), still water, the four
    winches hauling and paying out at 0.1-0.2 m/s: the storage S (kinetic + strain energy of (12)
    plus the submerged-weight potential, see docs/controllers.md) never rises above the supplied
    energy ∫ Σ u_j y_j dt, u_j the haul-in speed (-dL_j/dt) and y_j the top tension; the bound is
    tight to within the drag and internal damping (more than half of the work is stored), and the
    wrong sign (pay-out speed) violates it."""
    sc = load_scenario("aamo4")
    m = MooringFEM(sc, segments=8)
    eta = np.zeros(3)
    m.initialise(eta)
    m.settle(eta)
    fem = m.fem
    h = 0.1
    S0, W, W_wrong = fem.energy(), 0.0, 0.0
    speeds = np.array([-0.2, 0.2, 0.1, -0.1])
    worst = -np.inf
    stored_frac = None
    for k in range(3000):                     # 300 s: haul/pay 100 s, reverse 100 s, hold 100 s
        w = speeds * (1.0 if k < 1000 else (-1.0 if k < 2000 else 0.0))
        y0 = m.fairlead_tension()
        fem.L = fem.L + h * w
        fem._update_lengths()
        n = max(1, int(math.ceil(h / fem.stable_dt(m.safety))))
        m.dt = h / n
        m.advance(np.zeros((n, 3)), np.zeros((n, 3)))
        y = 0.5 * (y0 + m.fairlead_tension())
        W += h * float(np.sum(-w * y))
        W_wrong += h * float(np.sum(w * y))
        dS = fem.energy() - S0
        worst = max(worst, dS - W)
        if k == 999:
            stored_frac = dS / W
    assert worst <= 1e-3 * abs(W) + 1e3, f"S(t) - S(0) exceeded the supplied energy by {worst:.3g} J"
    assert 0.5 < stored_frac <= 1.0
    assert fem.energy() - S0 > W_wrong


# -- the turning current ----------------------------------------------------------------------

def test_table_i_current_turns():
    sc = load_scenario("aamo4")
    env = Environment(sc, "tidal_rotating")
    for t in (0.0, 1000.0, 6875.0 * math.pi / 2):
        np.testing.assert_allclose(env.current_surface(t), [-math.cos(t / 6875), math.sin(t / 6875), 0.0],
                                   atol=1e-9)
    np.testing.assert_allclose(env.current_velocity(np.array([0.0, 900.0]), 1000.0)[1],
                               [-math.cos(1000 / 6875), math.sin(1000 / 6875), 0.0], atol=1e-9)


# -- the closed loop on aamo4 -----------------------------------------------------------------

def _run(system, winch, duration=900.0):
    from tapm_opt.plant.simulator import Plant

    ctrl = build_controller(system, {"type": "pid", "modes": "extreme_restoring"})
    st = ClosedLoopSettings(duration=duration, dt_control=1.0, dt_log=5.0, heading="fixed", detector="none",
                            winch=winch)
    plant = Plant(system, sea_state="tidal_rotating", seed=1, segments=8)
    return run_closed_loop(plant, ctrl, st, system=system)


def test_force_capacity_is_the_tension_range_of_an_opposed_pair_on_aamo4(aamo4):
    """Four lines at 90 deg: along an axis one line hauls to its ceiling, the opposite one pays out
    to its floor, the two across give nothing, so the weakest direction gives
    (T_max - w ZF) - (T_min - w ZF) = T_max - T_min; the diagonal gives sqrt(2) times that. The
    relation H = T - w ZF (the inextensible catenary's) holds for aamo4's elastic lines at the
    pretension within 2 % (1.9 %)."""
    w = WinchTensionController(aamo4)
    np.testing.assert_allclose(w.T_max, 0.95 * aamo4.scenario.limits.tension_utilisation * np.asarray(aamo4.lines.MBS))
    r = w.force_capacity()
    assert r == pytest.approx(w.T_max[0] - w.T_min[0], rel=1e-9)
    assert w.force_capacity(directions=8) == pytest.approx(r, rel=1e-9)   # the axes are among the 8
    sol = aamo4.lines.solve_lines(np.zeros(3))
    hang = np.asarray(aamo4.lines.w) * np.asarray(aamo4.lines.ZF)
    np.testing.assert_allclose(np.asarray(sol.TF) - hang, sol.HF, rtol=0.02)


def test_with_winch_control_the_pids_command_box_adds_the_mooring_capacity(aamo4):
    box = aamo4.thrusters.capacity_box()
    r = WinchTensionController(aamo4, {"T_max_fraction": 0.5}).force_capacity()
    plain = build_controller(aamo4, {"type": "pid"})
    winched = build_controller(aamo4, {"type": "pid"}, winch={"T_max_fraction": 0.5})
    np.testing.assert_allclose(plain.tau_limit, box)
    np.testing.assert_allclose(winched.tau_limit, box + np.array([r, r, 0.0]))
    given = build_controller(aamo4, {"type": "pid", "tau_limit": [1e6, 1e6, 1e8]}, winch={})
    np.testing.assert_allclose(given.tau_limit, [1e6, 1e6, 1e8])   # an explicit limit is kept
    with pytest.raises(ControllerSpecError, match="winch_options.kc"):
        build_controller(aamo4, {"type": "pid"}, winch={"kc": -1.0})


def test_closed_loop_aamo4_mooring_carries_the_command(aamo4):
    """Shortened (900 s, 8 segments) [AF] Fig. 3: the thrusters deliver <= 20 % of the commanded
    horizontal force, the tensions stay below limits.tension_utilisation x MBS."""
    res = _run(aamo4, "tension")
    k = case_kpis(res, aamo4.scenario)
    assert k["thrust_to_command_ratio"] <= 0.2
    T_lim = aamo4.scenario.limits.tension_utilisation * aamo4.lines.MBS
    for j, lid in enumerate(aamo4.lines.line_ids):
        assert res[f"T_fairlead[{lid}]"].max() < T_lim[j]
    assert k["winch_energy"] > 0 and kpi_unit("winch_energy") == "J"
    assert not np.allclose(res["L[1]"], res["L[1]"][0])
    assert res.meta["winch"] == "tension" and "u_winch[1]" in res.channels


def test_without_winch_control_the_thrusters_carry_the_command(aamo4):
    res = _run(aamo4, "none", duration=300.0)
    k = case_kpis(res, aamo4.scenario)
    assert k["thrust_to_command_ratio"] > 0.8 and k["winch_energy"] == 0.0
    np.testing.assert_array_equal(res["L[1]"], res["L[1]"][0])


# -- bad input --------------------------------------------------------------------------------

def test_bad_input_raises_typed_errors(aamo4):
    for opts, field in (({"kc": -1.0}, "kc"), ({"ki": float("nan")}, "ki"), ({"T_max_fraction": 1.5}, "T_max_fraction"),
                        ({"geometry": "odd"}, "geometry"), ({"gain": 1.0}, "gain")):
        with pytest.raises(WinchError, match=field):
            WinchSettings.from_mapping(opts)
    assert issubclass(WinchError, TapmError)
    c = WinchTensionController(aamo4)
    with pytest.raises(WinchError, match="tau_cmd"):
        c.update(0.0, _est(), [1.0, 2.0])
    with pytest.raises(WinchError, match="estimate.tensions"):
        c.update(0.0, _est(tensions=[1.0, 2.0, float("nan"), 3.0]), np.zeros(3))
    c.update(5.0, _est(t=5.0), np.zeros(3))
    with pytest.raises(WinchError, match="before the previous"):
        c.update(4.0, _est(t=4.0), np.zeros(3))
    with pytest.raises(WinchError, match="no winch"):
        WinchTensionController(_no_winch_scenario())
    with pytest.raises(ClosedLoopError, match="winch = 'spin'"):
        ClosedLoopSettings(winch="spin", detector="none")
    with pytest.raises(ClosedLoopError, match="detector = 'none'"):
        ClosedLoopSettings(winch="tension")
    with pytest.raises(ClosedLoopError, match="kc"):
        ClosedLoopSettings(winch="tension", detector="none", winch_options={"kc": -1})
    with pytest.raises(ClosedLoopError, match="winch_options are for"):
        ClosedLoopSettings(winch_options={"kc": 1e-7})


def _no_winch_scenario():
    import dataclasses

    sc = load_scenario("aamo4")
    lines = tuple(dataclasses.replace(ln, winch_max_rate=0.0, min_length=None, max_length=None) for ln in sc.lines)
    return dataclasses.replace(sc, lines=lines)


# -- CLI and study file (need the --winch option of tapm simulate and the study keys) -----------

def test_cli_simulate_winch_tension(tmp_path):
    import json

    from click.testing import CliRunner

    from tapm_opt.cli import cli

    out = tmp_path / "run"
    r = CliRunner().invoke(cli, ["simulate", "aamo4", "--sea-state", "tidal_rotating", "--duration", "120",
                                 "--segments", "6", "--winch", "tension",
                                 "--winch-option", "kc=2.5e-7", "--out", str(out)])
    assert r.exit_code == 0, r.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["winch"] == "tension" and summary["detector"] == "none"
    from tapm_opt.results import Result

    res = Result.load(out / "result.npz")
    assert res.meta["heading"] == "fixed"   # the default with winch control: chasing reads tau_env
    assert "thrust_to_command_ratio" in summary["kpis"]
    bad = CliRunner().invoke(cli, ["simulate", "aamo4", "--duration", "10", "--winch", "tension",
                                   "--winch-option", "kc=-1", "--out", str(tmp_path / "bad")])
    assert bad.exit_code != 0 and "kc" in bad.output


def test_winch_study_file_parses():
    from pathlib import Path

    from tapm_opt.studies.spec import load_study

    st = load_study(Path(__file__).resolve().parents[1] / "studies" / "winch_tension.toml")
    loops = {c.name: c.inputs["closed_loop"] for c in st.cases}
    assert sorted(lp.get("winch", "none") for lp in loops.values()) == ["none", "tension"]
    assert all(lp["detector"] == "none" for lp in loops.values())
