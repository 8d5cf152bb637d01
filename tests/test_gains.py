"""Tests of the gain tables (tapm_opt.design.gains) and the gain-scheduled PID
(tapm_opt.control.scheduled): designed vs achieved poles, the offset equilibrium and its catenary
stiffness, mirror symmetry of broken lines, LQR against python-control, the JSON round trip, the
mean-load model against closed forms, and bumpless switching."""

from __future__ import annotations

import csv
import dataclasses
import math
import subprocess
import sys
import warnings

import control
import numpy as np
import pytest

import tapm_opt
from tapm_opt.control.estimate import Estimate, Setpoint
from tapm_opt.control.pid import MODE_SETS, MODES, TAPMPID, ControlError
from tapm_opt.control.pid_design import closed_loop, design_from_scenario, designed_poles, dof_plant
from tapm_opt.control.scheduled import GainScheduledPID
from tapm_opt.design.gains import (
    CLASS_MODE_SETS,
    DEFAULT_LQR,
    GainTable,
    GainTableError,
    gain_table,
    load_gain_table,
    mean_environmental_load,
    sea_state_class,
    weathervane_heading,
    write_gain_tables,
)
from tapm_opt.geometry import rot_z
from tapm_opt.models.mooring import MooringModel
from tapm_opt.models.system import ThrusterSet
from tapm_opt.plant.environment import Environment

SEA_STATES = ("normal", "extreme")
BROKEN = ("1", "4")  # mirror images of each other about the x axis (352.5 deg and 7.5 deg)


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


@pytest.fixture(scope="module")
def table(fpso) -> GainTable:
    return gain_table(fpso, sea_states=SEA_STATES, broken=BROKEN)


@pytest.fixture(scope="module")
def head_sea(fpso):
    """fpso with one sea state whose mean load is a pure -X at heading 0 (waves and current
    from the north, no wind): the load respects the mooring's mirror symmetry about x."""
    ss = dataclasses.replace(fpso.sea_state("normal"), id="head", wind_speed=0.0,
                             wave_direction=math.pi, current_direction=math.pi)
    sc = dataclasses.replace(fpso, sea_states=(ss,))
    return sc, gain_table(sc, broken=BROKEN)


def _row(tab, sea_state, broken="intact"):
    return tab.find(sea_state, broken, 0.0)


# --- poles --------------------------------------------------------------------------------

def test_every_row_places_the_designed_poles(table):
    """Decoupled DOF loops rebuilt from the row's M, D, K and gains have the designed poles, except
    where the mooring alone is already stiffer than the design asks: then Kp is clamped to 0 and
    said, and the loop keeps the plant's own (stable) poles. On fpso's chain-wire-chain lines that
    is surge in the extreme rows only (equilibria 85-103 m off, K11 3.4e5-4.4e5 N/m against the
    2.9e5 N/m of T_n = 180 s)."""
    assert len(table) == len(SEA_STATES) * (1 + len(BROKEN))
    dof = ("surge", "sway", "yaw")
    for r in table:
        p = r.pid
        clamped = {i for i in range(3) if any(f"Kp[{dof[i]}]" in c for c in p.clamped)}
        assert len(clamped) == len(p.clamped) and clamped <= ({0} if r.condition.sea_state == "extreme" else set())
        for i in range(3):
            want = np.sort_complex(designed_poles(p.periods[i], p.damping[i], p.integral_ratio))
            sys_i = dof_plant(r.M[i, i], r.D[i, i], r.K[i, i])
            k = np.array([[p.Ki[i], p.Kp[i], p.Kd[i]]])
            got = np.sort_complex(np.linalg.eigvals(np.asarray(sys_i.A) - np.asarray(sys_i.B) @ k))
            np.testing.assert_allclose(np.sort_complex(p.decoupled_poles[i]), got, rtol=1e-6)
            if i in clamped:
                w = 2.0 * np.pi / p.periods[i]
                need = r.M[i, i] * (w**2 + 2.0 * p.damping[i] * w * p.integral_ratio * w)
                assert p.Kp[i] == 0.0 and r.K[i, i] > need and np.all(got.real < 0.0)
                continue
            np.testing.assert_allclose(got, want, rtol=1e-6, atol=0.0)


def test_coupled_poles_are_those_of_the_stored_model(table):
    """The MIMO poles recorded are the closed loop of the row's (A, B) with its gains."""
    for r in table:
        plant = control.ss(r.A, r.B, np.eye(6), np.zeros((6, 3)))
        got = closed_loop(plant, r.pid.gains, MODES, reference_point=r.p_cot_B).poles()
        np.testing.assert_allclose(np.sort_complex(got), np.sort_complex(r.pid.poles),
                                   rtol=1e-7, atol=1e-12)
        got_modes = closed_loop(plant, r.pid.gains, r.condition.mode_set, reference_point=r.p_cot_B).poles()
        np.testing.assert_allclose(np.sort_complex(got_modes), np.sort_complex(r.pid.poles_modes),
                                   rtol=1e-7, atol=1e-12)
        assert r.pid.stable == bool(np.all(got.real < 0))
        osc = np.abs(r.pid.poles.imag) > 0
        np.testing.assert_allclose(r.pid.natural_periods[osc], 2 * np.pi / np.abs(r.pid.poles[osc]))


# --- operating point ------------------------------------------------------------------------

def test_linearised_at_the_offset_equilibrium(fpso, table):
    K0 = MooringModel.from_scenario(fpso).stiffness(np.zeros(3))
    for r in table:
        broken = () if r.condition.broken == "intact" else (r.condition.broken,)
        moor = MooringModel.from_scenario(fpso, broken=broken)
        tau_moor = moor.force(r.eta)
        # mooring balances the horizontal mean load; the heading controller holds the yaw moment
        np.testing.assert_allclose(tau_moor[:2] + r.tau_env[:2], 0.0,
                                   atol=1e-8 * np.abs(r.tau_env[:2]).max())
        # to the solves' tolerance (the table's equilibria start each composite line's solve from its
        # last one: the same answer to 1e-10 of the line's weight, not to the bit)
        assert tau_moor[2] + r.tau_env[2] + r.tau_thr[2] == pytest.approx(0.0, abs=1e-3 + 1e-8 * abs(r.tau_thr[2]))
        np.testing.assert_array_equal(r.tau_thr[:2], 0.0)
        assert r.eta[2] == r.condition.heading
        # K is the catenary stiffness there (analytic chain rule vs CasADi linearisation)
        K_eta = moor.stiffness(r.eta) @ rot_z(r.eta[2])
        np.testing.assert_allclose(r.K, K_eta, rtol=1e-6, atol=1e-6 * np.abs(K_eta).max())
        M_inv = np.linalg.inv(r.M)
        np.testing.assert_allclose(r.A[3:, :3], -M_inv @ moor.stiffness(r.eta), rtol=1e-6,
                                   atol=1e-6 * np.abs(M_inv @ K_eta).max())
        assert r.offset > 20.0
    # the catenary stiffens with offset: the intact design differs from the zero-point stiffness
    for ss in SEA_STATES:
        r = _row(table, ss)
        assert r.K[0, 0] > 1.1 * K0[0, 0]
    assert _row(table, "extreme").K[0, 0] > 1.5 * _row(table, "normal").K[0, 0]


def test_broken_line_breaks_the_mirror_symmetry(head_sea):
    sc, tab = head_sea
    intact, b1, b4 = (tab.find("head", b) for b in ("intact", "1", "4"))
    assert intact.tau_env[1] == pytest.approx(0.0, abs=1e-6)
    assert intact.tau_env[2] == pytest.approx(0.0, abs=1e-3)
    assert intact.tau_env[0] < -1e6
    # intact: the load and the 3 x 4 pattern are mirror-symmetric about x
    s = np.abs(intact.K).max()
    assert abs(intact.eta[1]) < 1e-6 and intact.eta[0] < -10.0
    assert abs(intact.K[0, 1]) < 1e-9 * s and abs(intact.K[1, 0]) < 1e-9 * s
    assert abs(intact.K[0, 2]) < 1e-9 * s
    # line 1 broken: a new equilibrium, off the axis, and cross-coupled stiffness
    assert b1.offset > intact.offset + 5.0
    assert abs(b1.eta[1]) > 1.0
    assert abs(b1.K[0, 1]) > 1e-3 * b1.K[0, 0]
    # line 4 is line 1 mirrored: mirrored equilibrium and stiffness
    np.testing.assert_allclose(b4.eta[0], b1.eta[0], rtol=1e-6)
    np.testing.assert_allclose(b4.eta[1], -b1.eta[1], rtol=1e-6)
    mirror = np.diag([1.0, -1.0, -1.0])
    np.testing.assert_allclose(b4.K, mirror @ b1.K @ mirror, rtol=1e-5, atol=1e-6 * s)
    np.testing.assert_allclose(b4.pid.Kp, b1.pid.Kp, rtol=1e-5)


def test_locked_turret_equilibrium_agrees_with_design_from_scenario(fpso):
    """Independent path: with a locked turret design_from_scenario solves all three DOF; under
    the mean load plus the row's thrust it lands on the row's pose with the same gains."""
    sc = dataclasses.replace(fpso, turret=dataclasses.replace(fpso.turret, mode="locked"))
    r = gain_table(sc, sea_states=["normal"], broken=()).rows[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = design_from_scenario(sc, periods=r.pid.periods, damping=r.pid.damping,
                                 integral_ratio=r.pid.integral_ratio,
                                 tau_env=r.tau_env + r.tau_thr, eta0=r.eta + [1.0, -1.0, 0.01])
    np.testing.assert_allclose(d.eta_op, r.eta, atol=1e-6)
    np.testing.assert_allclose(np.diag(d.gains.Kp), r.pid.Kp, rtol=1e-6)
    np.testing.assert_allclose(d.K, r.K, rtol=1e-6, atol=1e-6 * np.abs(r.K).max())


# --- mean load ----------------------------------------------------------------------------

def test_mean_wind_is_the_plant_wind_load_without_gusts(fpso, monkeypatch):
    for ss in ("normal", "extreme"):
        for psi in (0.0, 0.7, -2.0):
            load = mean_environmental_load(fpso, ss, psi, seed=3)
            env = Environment(fpso, ss, seed=3)
            monkeypatch.setattr(env.wind, "speed", lambda t, w=env.wind: w.mean_speed)
            np.testing.assert_allclose(load.wind, env.wind.tau_wind(0.0, psi), rtol=1e-12)
            np.testing.assert_allclose(load.drift, env.waves.mean_drift(psi), rtol=1e-12)
            np.testing.assert_allclose(load.total, load.wind + load.drift + load.current)


def test_head_current_load_is_linear_plus_quadratic_drag(fpso):
    """Current from ahead on a vessel at rest: X = -(D11 V + X_|u|u V^2), Y = N = 0."""
    V = 0.8
    ss = dataclasses.replace(fpso.sea_state("normal"), id="cur", Hs=0.0, wind_speed=0.0,
                             current_speed=V, current_direction=math.pi,
                             current_profile="uniform", current_profile_depths=(),
                             current_profile_factors=())
    sc = dataclasses.replace(fpso, sea_states=(ss,))
    load = mean_environmental_load(sc, "cur", 0.0)
    D11 = np.asarray(fpso.vessel.linear_damping)[0, 0]
    d1 = np.asarray(fpso.vessel.quadratic_damping)[0]
    np.testing.assert_allclose(load.current, [-(D11 * V + d1 * V**2), 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(load.total, load.current, atol=1e-6)


# --- LQR ----------------------------------------------------------------------------------

def test_lqr_rows_match_python_control(fpso, table):
    # the one capacity model: largest |X|, |Y|, |N| each attainable alone (LP)
    capacity = ThrusterSet.from_scenario(fpso).max_tau()
    f = np.array([t.max_thrust for t in fpso.thrusters])
    arm = np.array([math.hypot(*t.position) for t in fpso.thrusters])
    bound = np.array([f.sum(), f.sum(), (f * arm).sum()])  # 7.2 MN, 7.2 MN, ~1e9 N m
    assert np.all(capacity <= bound)  # each thruster at full thrust in the best direction
    # surge: the six azimuths all push ahead with no sway or yaw (y symmetric), less the 0.03 %
    # of the 128-gon inscribed in each thrust disk
    assert capacity[0] == pytest.approx(bound[0], rel=5e-4)
    for r in table:
        q = r.lqr
        K, _, _ = control.lqr(r.A, r.B, np.diag(q.Q), np.diag(q.R))
        np.testing.assert_allclose(q.K, K, rtol=1e-9, atol=1e-12 * np.abs(K).max())
        poles = np.linalg.eigvals(r.A - r.B @ q.K)
        np.testing.assert_allclose(np.sort_complex(q.poles), np.sort_complex(poles), rtol=1e-8)
        assert q.stable and np.all(poles.real < 0.0)
        np.testing.assert_allclose(q.damping_ratios, -q.poles.real / np.abs(q.poles), rtol=1e-9)
        # Bryson weights of the class: tau_ref = share x thrust capacity of the fpso thrusters
        w = DEFAULT_LQR[r.condition.sea_class]
        np.testing.assert_allclose(q.Q, 1.0 / np.r_[w.eta_ref, w.nu_ref] ** 2, rtol=1e-12)
        np.testing.assert_allclose(q.R, 1.0 / (w.tau_share * capacity) ** 2, rtol=1e-12)
    assert table.meta["lqr_capacity"]["max_tau"] == capacity.tolist()


# --- margins ------------------------------------------------------------------------------

def test_margins_are_finite_and_positive_for_stable_rows(table):
    assert all(r.pid.stable for r in table)
    for r in table:
        p = r.pid
        assert np.all(np.isfinite(p.gain_margin)) and np.all(p.gain_margin > 1.0)
        assert np.all(np.isfinite(p.phase_margin)) and np.all(p.phase_margin > 0.0)
        assert np.all(np.isfinite(p.delay_margin)) and np.all(p.delay_margin > 0.0)
        np.testing.assert_allclose(p.delay_margin, np.radians(p.phase_margin) / p.crossover)


def test_surge_margin_matches_the_decoupled_loop(fpso):
    """Head load at heading 0, intact: surge is decoupled from sway/yaw, so the loop-at-a-time
    margin equals that of C(s) P(s) lag(s) built by hand."""
    ss = dataclasses.replace(fpso.sea_state("normal"), id="head", wind_speed=0.0,
                             wave_direction=math.pi, current_direction=math.pi)
    sc = dataclasses.replace(fpso, sea_states=(ss,))
    T_thr, wc = 5.0, 2 * np.pi / 40.0
    r = gain_table(sc, broken=(), thrust_time_constant=T_thr, estimator_cutoff=wc).rows[0]
    p = r.pid
    C = control.tf([p.Kd[0], p.Kp[0], p.Ki[0]], [1.0, 0.0])
    P = control.tf([1.0], [r.M[0, 0], r.D[0, 0], r.K[0, 0]])
    lag = control.tf([1.0], [T_thr, 1.0]) * control.tf([wc**2], [1.0, 2 * wc, wc**2])
    gm, pm, *_ = control.stability_margins(C * P * lag)
    assert p.phase_margin[0] == pytest.approx(pm, abs=0.05)
    assert p.gain_margin[0] == pytest.approx(gm, rel=1e-3)
    # a slower estimator leaves less margin
    slow = gain_table(sc, broken=(), thrust_time_constant=T_thr, estimator_cutoff=wc / 2).rows[0]
    assert np.all(slow.pid.phase_margin < p.phase_margin - 5.0)


# --- files and scheduling -------------------------------------------------------------------

def test_json_round_trip(table, tmp_path):
    paths = write_gain_tables(table, tmp_path / "out")
    assert [p.name for p in paths] == ["gains.json", "gains.csv", "gains.md"]
    assert all(p.is_file() for p in paths)
    back = load_gain_table(paths[0])
    assert back.to_dict() == table.to_dict()
    assert back.meta == table.meta
    for a, b in zip(back.rows, table.rows):
        assert a.condition == b.condition
        for name in ("eta", "tau_env", "K", "A", "B"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        for name in ("Kp", "Ki", "Kd", "designed_poles", "poles", "gain_margin", "phase_margin"):
            x, y = getattr(a.pid, name), getattr(b.pid, name)
            assert x.dtype == y.dtype
            np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(a.lqr.K, b.lqr.K)
        assert a.pid.stable is b.pid.stable
    assert load_gain_table(tmp_path / "out").to_dict() == table.to_dict()  # the folder works too
    with open(paths[1], newline="") as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    assert len(rows) == len(table)
    assert float(rows[0]["Kp_x"]) == table.rows[0].pid.Kp[0]
    assert "| normal (normal) | intact |" in paths[2].read_text()


def test_load_rejects_a_file_that_is_not_a_gain_table(tmp_path):
    (tmp_path / "gains.json").write_text('{"meta": {"format": "other"}, "rows": []}')
    with pytest.raises(GainTableError, match="not a gain table"):
        load_gain_table(tmp_path)
    with pytest.raises(GainTableError, match="no gain table"):
        load_gain_table(tmp_path / "missing.json")


def _drive(ctrl, t0=0.0):
    """Same estimate sequence for any controller: returns the commands."""
    sp = Setpoint([2.0, -1.0, 0.02])
    out = []
    for k in range(4):
        t = t0 + 5.0 * k
        est = Estimate(t, [-30.0 + k, -5.0, 0.05 - 0.01 * k], [0.1, -0.05, 1e-3], np.zeros(3))
        out.append(ctrl.update(t, est, sp))
    return np.array(out)


def test_scheduled_pid_from_json_equals_tapmpid_of_the_row(fpso, table, tmp_path):
    write_gain_tables(table, tmp_path)
    limit = (4e6, 4e6, 6e8)
    for r in table:
        c = r.condition
        sched = GainScheduledPID.from_json(tmp_path / "gains.json", scenario=fpso, tau_limit=limit)
        active = sched.select(sea_state=c.sea_state, broken=c.broken, heading=c.heading)
        assert (active.sea_state, active.broken, active.mode_set) == (c.sea_state, c.broken,
                                                                      c.mode_set)
        assert sched.modes == MODE_SETS[CLASS_MODE_SETS[c.sea_class]]
        # with a scenario the scheduled PID is turret-referenced, as the one build_controller makes
        direct = TAPMPID(r.pid.gains, modes=c.mode_set, tau_limit=limit, reference_point=fpso.turret.position)
        np.testing.assert_array_equal(_drive(sched), _drive(direct))


def test_scheduled_pid_takes_the_capacity_box_and_the_turret_from_its_scenario(fpso, table):
    from tapm_opt.models.system import ThrusterSet

    sched = GainScheduledPID(table, scenario=fpso)
    np.testing.assert_allclose(sched.controller.tau_limit, ThrusterSet.from_scenario(fpso).capacity_box())
    plain = GainScheduledPID(table)
    assert plain.controller.tau_limit is None


def test_switch_is_bumpless_in_the_integral(table):
    sched = GainScheduledPID(table)
    sched.select(sea_state="normal", broken="intact")
    _drive(sched)
    before = np.array(sched.integral_load)
    assert abs(before[2]) > 1e5 and np.all(before[:2] == 0.0)  # normal: no surge-sway integral
    sched.select(sea_state="extreme")  # keeps broken and heading
    assert sched.active.sea_state == "extreme" and "mean" in sched.modes
    np.testing.assert_allclose(sched.integral_load, before, rtol=1e-12, atol=1e-9)
    _drive(sched, t0=20.0)
    x_y = np.array(sched.integral_load)[:2]
    assert np.all(x_y != 0.0)  # the surge-sway integral started after the switch
    sched.select(broken=["1"])  # extreme, line 1 broken: both integrate x, y and psi
    np.testing.assert_allclose(sched.integral_load, np.r_[x_y, sched.integral_load[2]])
    kept = np.array(sched.integral_load)
    sched.select(sea_state="normal")  # back to a mode set without the mean mode
    np.testing.assert_allclose(sched.integral_load, [0.0, 0.0, kept[2]], rtol=1e-12, atol=1e-9)


def test_scheduler_reads_the_table_with_the_one_format_module(table, tmp_path):
    """The scheduler takes a GainTable, its dict or its file through control.gain_table, and
    never imports the design code."""
    write_gain_tables(table, tmp_path)
    from_obj, from_dict = GainScheduledPID(table), GainScheduledPID(table.to_dict())
    from_file = GainScheduledPID.from_json(tmp_path)
    assert from_obj.conditions == from_dict.conditions == from_file.conditions
    assert from_obj.conditions == tuple(r.condition for r in table.rows)
    np.testing.assert_array_equal(_drive(from_dict), _drive(from_obj))
    np.testing.assert_array_equal(_drive(from_file), _drive(GainScheduledPID(table)))
    code = ("import sys, tapm_opt.control.scheduled; "
            "print(sorted(m for m in sys.modules if m.startswith('tapm_opt.design')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    bad = table.to_dict()
    bad["rows"][0]["pid"]["Kp"] = [1.0, -2.0, 3.0]
    with pytest.raises(ControlError, match="Kp"):
        GainScheduledPID(bad)
    bad["rows"][0]["pid"].pop("Kp")
    with pytest.raises(GainTableError, match="malformed gain table"):
        GainScheduledPID(bad)


def test_scheduler_rejects_unknown_conditions(fpso, table):
    sched = GainScheduledPID(table)
    with pytest.raises(ControlError, match="no gains for sea_state='storm'"):
        sched.select(sea_state="storm")
    assert sched.active.sea_state == "normal"  # unchanged
    with pytest.raises(ControlError, match="single-line"):
        sched.select(broken=["1", "4"])
    other = dataclasses.replace(fpso, meta=dataclasses.replace(fpso.meta, name="other"))
    with pytest.raises(ControlError, match="made for scenario 'fpso'"):
        GainScheduledPID(table, scenario=other)
    with pytest.raises(ControlError, match="not a gain table"):
        GainScheduledPID({"meta": {}, "rows": [{}]})


# --- conditions ---------------------------------------------------------------------------

def test_classes_and_mode_sets(fpso, table):
    assert sea_state_class(fpso.sea_state("storm")) == "extreme"
    assert sea_state_class(fpso.sea_state("calm")) == "calm"
    odd = dataclasses.replace(fpso.sea_state("normal"), id="x", Hs=1.0)
    assert sea_state_class(odd) == "calm"
    assert sea_state_class(odd, {"x": "extreme"}) == "extreme"
    assert CLASS_MODE_SETS == {"calm": "calm", "normal": "normal_restoring",
                               "extreme": "extreme_restoring"}
    for r in table:
        assert r.condition.mode_set == CLASS_MODE_SETS[r.condition.sea_class]
    assert [r.condition.broken for r in table][:3] == ["intact", "1", "4"]


def test_bad_arguments_raise(fpso):
    with pytest.raises(GainTableError, match="no sea state 'nope'"):
        gain_table(fpso, sea_states=["nope"], broken=())
    with pytest.raises(GainTableError, match=r"broken line id\(s\) \['99'\]"):
        gain_table(fpso, sea_states=["calm"], broken=["99"])
    with pytest.raises(GainTableError, match="headings"):
        gain_table(fpso, sea_states=["calm"], broken=(), headings=[float("nan")])
    with pytest.raises(GainTableError, match="periods"):
        gain_table(fpso, sea_states=["calm"], broken=(), periods=(100.0, -1.0, 100.0))
    with pytest.raises(GainTableError, match="unknown class"):
        gain_table(fpso, sea_states=["calm"], broken=(), damping={"stormy": 0.7})


def test_weathervane_heading_needs_no_yaw_thrust(fpso):
    psi = weathervane_heading(fpso, "normal")
    r = gain_table(fpso, sea_states=["normal"], broken=(), headings=["weathervane"]).rows[0]
    assert r.condition.weathervane and r.condition.heading == psi
    assert abs(r.tau_thr[2]) < 1e-6 * abs(_yaw(fpso, psi + 0.1))
    # stable: turning further brings a restoring moment
    assert _yaw(fpso, psi + 0.1) < 0.0 < _yaw(fpso, psi - 0.1)


def _yaw(sc, psi):
    """Yaw moment on the hull at its offset equilibrium with heading psi (free turret: the mean
    load's moment about the turret, N_env - x_cot Y_env)."""
    tau = mean_environmental_load(sc, "normal", psi).total
    return tau[2] - sc.turret.position[0] * tau[1] + sc.turret.position[1] * tau[0]


def test_row_offsets_are_turret_offsets_and_survive_the_file(fpso, tmp_path):
    from tapm_opt.geometry import turret_offset

    table = gain_table(fpso, sea_states=["storm"], broken=[], headings=[0.0, "weathervane"])
    write_gain_tables(table, tmp_path)
    back = load_gain_table(tmp_path / "gains.json")
    for r, b in zip(table, back):
        np.testing.assert_allclose(r.p_cot_B, fpso.turret.position)
        assert r.offset == pytest.approx(float(np.hypot(*turret_offset(r.eta, fpso.turret.position))), rel=1e-12)
        assert b.offset == pytest.approx(r.offset, rel=1e-12)
    turned = [r for r in table if abs(r.eta[2]) > 0.05]
    assert turned, "the table has no row with the hull turned"
    for r in turned:  # turned about the turret: the body origin is further off than the turret
        assert r.offset < float(np.hypot(r.eta[0], r.eta[1]))
