"""Tests of the plant (tapm_opt.plant.simulator): moored free decay against the catenary stiffness,
line breaks, reproducibility and result files, an open-loop storm run with fixed thrust, winches,
and the errors raised for bad input."""

from __future__ import annotations

import copy
import functools
import json
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import Fault, scenario_from_dict, scenario_to_dict
from tapm_opt.errors import ModelError, TapmError
from tapm_opt.models.mooring import MooringModel
from tapm_opt.plant.environment import Environment, PlantError
from tapm_opt.plant.simulator import Plant, ThrusterCommand, run_open_loop
from tapm_opt.results import Result

ZERO = np.zeros(3)


@functools.lru_cache(maxsize=None)
def scenario(name: str):
    return tapm_opt.load_scenario(name)


def variant(name: str, edit) -> object:
    """A built-in scenario changed through its dictionary form."""
    d = copy.deepcopy(scenario_to_dict(scenario(name)))
    edit(d)
    return scenario_from_dict(d)


def zero_crossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times where x changes sign (linear interpolation between samples)."""
    i = np.flatnonzero(np.sign(x[1:]) != np.sign(x[:-1]))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


# ------------------------------------------------------------------------------------------
# free decay
# ------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def decay():
    """aamo4 released from x = 30 m in calm water with no thrust (lines settled there first)."""
    plant = Plant(scenario("aamo4"), sea_state="none", segments=10, eta0=(30.0, 0.0, 0.0))
    assert plant.settle_info.converged
    return run_open_loop(plant, 900.0, dt_log=1.0)


def test_free_decay_surge_period_matches_catenary_stiffness(decay):
    """Surge free decay: the period from zero crossings agrees with 2 pi sqrt(M11 / K11), K from
    the catenary stiffness at the field zero point.

    With the vessel's own linear damping alone the decay is already at zeta = D11 / (2 sqrt(M11
    K11)) = 0.28, so the zero-crossing (damped) period is ~4 % longer than the natural one; the
    natural period is recovered from it with the damping ratio measured from the decay itself
    (logarithmic decrement), omega_n = omega_d / sqrt(1 - zeta^2), and must agree within 2 %."""
    sc = scenario("aamo4")
    K11 = MooringModel.from_scenario(sc).stiffness(ZERO)[0, 0]
    M11 = float(np.asarray(sc.vessel.M)[0, 0])
    T_n = 2 * math.pi * math.sqrt(M11 / K11)
    t, x = decay.time, decay["x"]
    assert np.all(np.isfinite(x)) and x[0] == 30.0
    x_mean = float(np.mean(x[t >= 600.0]))
    assert abs(x_mean) < 0.5  # back at the symmetric equilibrium
    xi = x - x_mean
    tc = zero_crossings(t, xi)
    assert tc.size >= 4
    T_d = np.mean(tc[2:4] - tc[0:2])  # the first two full periods
    assert T_d == pytest.approx(T_n, rel=0.05)
    # peaks of successive half cycles: decaying, and their ratio gives the damping
    halves = np.split(np.arange(t.size), np.flatnonzero(np.sign(xi[1:]) != np.sign(xi[:-1])) + 1)
    peaks = np.array([np.max(np.abs(xi[h])) for h in halves[:5]])
    assert np.all(np.diff(peaks) < 0), peaks
    delta = np.mean(np.log(peaks[:-1] / peaks[1:]))  # per half cycle
    zeta = delta / math.sqrt(math.pi**2 + delta**2)
    zeta_vessel = float(np.asarray(sc.vessel.linear_damping)[0, 0]) / (2 * math.sqrt(M11 * K11))
    assert zeta > zeta_vessel  # the lines' drag adds to the hull's damping
    assert zeta < 0.5
    assert T_d * math.sqrt(1 - zeta**2) == pytest.approx(T_n, rel=0.02)


def test_free_decay_stays_in_surge(decay):
    """A symmetric mooring released along x: no sway and no yaw develop."""
    assert np.max(np.abs(decay["y"])) < 1e-6
    assert np.max(np.abs(decay["psi"])) < 1e-9


# ------------------------------------------------------------------------------------------
# line break
# ------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def broken():
    fault = Fault(kind="line_break", line="1", time=60.0)
    plant = Plant(scenario("aamo4"), sea_state="none", segments=10, faults=[fault])
    return plant, run_open_loop(plant, 200.0, dt_log=1.0)


def test_line_break_zeroes_its_tension(broken):
    plant, r = broken
    names = r.group_names("T_fairlead")
    assert names == ["1", "2", "3", "4"]
    T = r.group("T_fairlead")
    T1 = r["T_fairlead[1]"]
    np.testing.assert_array_equal(T[:, 0], T1)
    # logged times carry the round-off of 600 additions of 0.1 s (60.00000000000058 for 60)
    t = np.round(r.time, 6)
    np.testing.assert_allclose(r.time, np.arange(201.0), rtol=0, atol=1e-9)
    before, after = t < 60.0, t > 60.0
    assert np.all(T1[before] > 0) and np.all(T1[after] == 0.0)
    # intact and at rest before the break: every line holds its tension (no drift > 0.1 %)
    assert np.max(np.abs(T[before] / T[0] - 1.0)) < 1e-3
    # the other lines keep pulling
    assert np.all(T[after][:, 1:] > 0)
    assert any("line 1 broke" in e for _, e in plant.events)
    assert plant.metadata()["events"][0][0] == pytest.approx(60.0)


def test_vessel_drifts_away_from_the_broken_lines_anchor(broken):
    _, r = broken
    anchor = np.asarray(scenario("aamo4").anchors[0, :2])
    u = anchor / np.linalg.norm(anchor)
    s = r["x"] * u[0] + r["y"] * u[1]  # displacement toward the broken line's anchor [m]
    t = np.round(r.time, 6)
    after = t > 60.0
    assert np.max(np.abs(s[t <= 60.0])) < 1e-6
    assert np.all(s[after] < 0)
    assert np.all(np.diff(s[after]) < 0)  # and keeps moving away during the run
    assert s[-1] < -20.0
    # moving toward anchor 3 slackens line 3; lines 2 and 4 (anchors at +-y) are stretched and
    # now hold the vessel, equally by symmetry
    T2, T3, T4 = r["T_fairlead[2]"], r["T_fairlead[3]"], r["T_fairlead[4]"]
    assert T3[-1] < 0.9 * T3[0]
    assert T2[-1] > T2[0] + 1e-3 * T2[0]
    np.testing.assert_allclose(T2, T4, rtol=1e-6)


# ------------------------------------------------------------------------------------------
# reproducibility and result files
# ------------------------------------------------------------------------------------------

def storm_run(seed: int, duration: float = 40.0) -> Result:
    plant = Plant(scenario("fpso"), sea_state="extreme", segments=6, seed=seed)
    return run_open_loop(plant, duration, dt_log=0.5, meta={"seed": seed})


@pytest.fixture(scope="module")
def repro():
    return storm_run(7), storm_run(7), storm_run(8)


def test_same_seed_same_result_other_seed_other_result(repro):
    a, b, c = repro
    assert np.array_equal(a.time, b.time) and np.array_equal(a.data, b.data)
    assert a.channels == b.channels and a.meta == b.meta
    assert np.array_equal(a.time, c.time)
    assert not np.array_equal(a.data, c.data)
    # the difference is in the weather, not in round-off: the wave-frequency motion differs
    assert np.max(np.abs(a["x_wf"] - c["x_wf"])) > 0.1
    assert np.ptp(a["x_wf"]) > 1.0  # there is a storm


def test_result_save_load_roundtrip(repro, tmp_path):
    r = repro[0]
    path = r.save(tmp_path / "storm")
    assert path == tmp_path / "storm.npz" and path.exists()
    back = Result.load(path)
    assert np.array_equal(back.time, r.time) and np.array_equal(back.data, r.data)
    assert back.channels == r.channels and back.units == r.units
    assert back.meta == r.meta
    assert back.meta["seed"] == 7 and back.meta["scenario"] == "fpso" and back.meta["sea_state"] == "extreme"
    assert back.unit("T_fairlead[1]") == "N" and back.unit("psi") == "rad"
    with np.load(path, allow_pickle=False) as z:
        channels = [str(c) for c in z["channels"]]
        assert channels == list(r.channels)
        assert np.array_equal(z["data"][:, channels.index("x")], r["x"])
        assert [str(u) for u in z["units"]] == list(r.units)
        assert json.loads(str(z["meta"]))["seed"] == 7


# ------------------------------------------------------------------------------------------
# open loop through a storm
# ------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def storm():
    """fpso, "extreme" sea state, every azimuth at 30 % thrust against the mean wind and drift
    load (computed at the field zero point), 300 s."""
    sc = scenario("fpso")
    env = Environment(sc, "extreme", seed=0)
    loads = [env.loads(t, ZERO, ZERO) for t in np.arange(0.0, 600.0, 1.0)]
    tau = np.mean([ld["tau_wind"] + ld["tau_drift"] for ld in loads], axis=0)
    plant = Plant(sc, sea_state="extreme", segments=10, seed=3)
    n = plant.thrusters.n
    cmd = ThrusterCommand(f=0.3 * plant.thrusters.limits.f_max, alpha=np.full(n, math.atan2(-tau[1], -tau[0])))
    return plant, cmd, tau, run_open_loop(plant, 300.0, thruster_cmd=cmd, dt_log=1.0)


def test_storm_run_is_finite(storm):
    plant, _, _, r = storm
    assert np.all(np.isfinite(r.data))
    assert r.meta["sea_state"] == "extreme" and r.meta["settle"]["converged"]
    # the storm does move the vessel and load the lines
    assert np.ptp(r["x"]) > 5.0 and np.ptp(r["x_wf"]) > 1.0
    assert np.all(r.group("T_fairlead") > 0)


def test_storm_thrusters_within_limits(storm):
    plant, cmd, tau_env, r = storm
    lim = plant.thrusters.limits
    f, alpha = r.group("f"), r.group("alpha")
    assert np.all(f >= lim.f_min - 1e-9) and np.all(f <= lim.f_max + 1e-9)
    # thrust rate limit between log samples (1 s)
    assert np.all(np.abs(np.diff(f, axis=0)) <= lim.rate * 1.0 + 1e-6)
    # the thrust settles at the command and points where it was told to
    np.testing.assert_allclose(f[-1], cmd.f, rtol=1e-6)
    np.testing.assert_allclose(alpha[-1], cmd.alpha, atol=1e-9)
    tau_thr = np.column_stack([r["tau_thr[X]"], r["tau_thr[Y]"]])[-1]
    assert np.dot(tau_thr, tau_env[:2]) < 0  # against the environment


def test_storm_power_follows_thrust_to_the_power_one_and_a_half(storm):
    plant, _, _, r = storm
    f, P = r.group("f"), r.group("P")
    on = f > 1e3
    assert on.sum() > 50 and np.ptp(f[on]) > 0.5 * np.max(f)  # samples along the ramp up
    np.testing.assert_allclose(P[~on & (f == 0)], 0.0, atol=0.0)
    for i in range(f.shape[1]):
        m = on[:, i]
        slope = np.polyfit(np.log(f[m, i]), np.log(P[m, i]), 1)[0]
        assert slope == pytest.approx(1.5, abs=1e-9)
        np.testing.assert_allclose(P[m, i] / f[m, i] ** 1.5, plant.thrusters.limits.k_power[i], rtol=1e-12)


# ------------------------------------------------------------------------------------------
# winches
# ------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def winch():
    """aamo4 with a winch on line 1 (0.5 m/s, lengths 2240..2265 m): pay out for 60 s at a
    commanded 1 m/s (limited to 0.5 m/s), then haul in for 120 s."""

    def edit(d):
        ln = d["lines"][0]
        ln.update(winch_max_rate=0.5, min_length=2240.0, max_length=2265.0)

    plant = Plant(variant("aamo4", edit), sea_state="none", segments=10)
    out = run_open_loop(plant, 60.0, winch_cmd=[1.0, 0.0, 0.0, 0.0], dt_log=1.0)
    back = run_open_loop(plant, 120.0, winch_cmd=[-1.0, 0.0, 0.0, 0.0], dt_log=1.0)
    return out, back


def test_paying_out_lowers_the_tension(winch):
    out, back = winch
    L, T = out["L[1]"], out["T_fairlead[1]"]
    # rate-limited to 0.5 m/s, then held at max_length
    assert L[10] == pytest.approx(2255.0, abs=1e-9)
    assert L[-1] == pytest.approx(2265.0, abs=1e-9)
    assert np.all(np.diff(L) >= 0)
    assert np.all(T[1:31] < T[0])
    assert T[30] < 0.8 * T[0]
    assert T[-1] < T[0]
    # the catenary of the longer line at the same fairlead position agrees on the sign and size
    # of the drop (the vessel has moved a little toward -x by then)
    d = copy.deepcopy(scenario_to_dict(scenario("aamo4")))
    d["lines"][0]["length"] = 2265.0
    qs = MooringModel.from_scenario(scenario_from_dict(d)).tensions(np.array([out["x"][-1], out["y"][-1], 0.0]))[0]
    assert T[-1] == pytest.approx(qs, rel=0.05)
    # the other lines' lengths never change
    for k in ("2", "3", "4"):
        assert np.all(out[f"L[{k}]"] == 2250.0) and np.all(back[f"L[{k}]"] == 2250.0)
    # hauling in raises it again
    assert back["T_fairlead[1]"][-1] > T[-1]


def test_winch_keeps_the_length_within_its_limits(winch):
    out, back = winch
    L = np.concatenate([out["L[1]"], back["L[1]"]])
    assert np.all(L >= 2240.0 - 1e-9) and np.all(L <= 2265.0 + 1e-9)
    assert L.max() == pytest.approx(2265.0) and L.min() == pytest.approx(2240.0)
    assert back["L[1]"][-1] == pytest.approx(2240.0, abs=1e-9)


# ------------------------------------------------------------------------------------------
# bad input
# ------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def calm_fpso():
    return Plant(scenario("fpso"), sea_state="none", segments=4)


@pytest.fixture(scope="module")
def calm_aamo4():
    """aamo4 with the winches of lines 1 and 3 taken off (line 1 then has none to command)."""
    import dataclasses

    sc = scenario("aamo4")
    lines = tuple(dataclasses.replace(ln, winch_max_rate=0.0, min_length=None, max_length=None)
                  if ln.id in ("1", "3") else ln for ln in sc.lines)
    return Plant(dataclasses.replace(sc, lines=lines), sea_state="none", segments=4)


@pytest.mark.parametrize("cmd,match", [
    ([0.1, 0.0, 0.0, 0.0], r"winch_cmd\[0\].*line '1'.*no winch.*winch_max_rate"),
    ([np.nan, 0.0, 0.0, 0.0], r"winch_cmd\[0\].*line '1'.*finite"),
    ([0.0, 0.0, 0.0], r"winch_cmd has shape \(3,\), expected \(4,\)"),
])
def test_bad_winch_command(calm_aamo4, cmd, match):
    t = calm_aamo4.t
    with pytest.raises(PlantError, match=match):
        calm_aamo4.step(1.0, winch_cmd=cmd)
    assert calm_aamo4.t == t  # nothing happened


def test_fault_on_a_missing_line():
    with pytest.raises(PlantError, match=r"line_break.*'99'.*does not exist.*\['1', '2', '3', '4'\]"):
        Plant(scenario("aamo4"), sea_state="none", segments=4,
              faults=[Fault(kind="line_break", line="99", time=1.0)])


@pytest.mark.parametrize("f,alpha,match", [
    ([np.nan, 0, 0, 0, 0, 0], None, r"thruster_cmd\.f\[0\].*'A1'.*finite"),
    ([0, 0, 0, 0, 0, 0], [0, 0, np.inf, 0, 0, 0], r"thruster_cmd\.alpha\[2\].*'A3'.*finite"),
    ([0, 0, 0, 0, 0], None, r"thruster_cmd\.f has shape \(5,\), expected \(6,\)"),
])
def test_bad_thruster_command(calm_fpso, f, alpha, match):
    cmd = ThrusterCommand(np.array(f, dtype=float), None if alpha is None else np.array(alpha, dtype=float))
    with pytest.raises(PlantError, match=match):
        calm_fpso.step(1.0, cmd)


@pytest.mark.parametrize("dt", [0.0, -1.0, math.nan, math.inf])
def test_bad_step_length(calm_aamo4, dt):
    with pytest.raises(PlantError, match="dt"):
        calm_aamo4.step(dt)


def test_bad_plant_settings():
    sc = scenario("fpso")
    with pytest.raises(PlantError, match="hurricane.*normal"):
        Plant(sc, sea_state="hurricane", segments=4)
    with pytest.raises(PlantError, match="outer_dt"):
        Plant(sc, sea_state="none", segments=4, outer_dt=0.0)
    with pytest.raises(PlantError, match="eta0"):
        Plant(sc, sea_state="none", segments=4, eta0=(1.0, 2.0))
    with pytest.raises(ModelError, match="segments"):
        Plant(sc, sea_state="none", segments=1)
    with pytest.raises(ModelError, match="safety"):
        Plant(sc, sea_state="none", segments=4, safety=1.5)


def test_bad_run_settings(calm_aamo4):
    with pytest.raises(PlantError, match="duration"):
        run_open_loop(calm_aamo4, 0.0)
    with pytest.raises(PlantError, match="dt_log"):
        run_open_loop(calm_aamo4, 10.0, dt_log=-1.0)


def test_plant_errors_are_tapm_errors():
    assert issubclass(PlantError, TapmError) and issubclass(ModelError, TapmError)
