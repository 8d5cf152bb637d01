"""Fatigue-aware setpoint chasing (survey §4.2.4): on-line damage per line against the offline
verification's, the T-N definitions moved without changing the verification's numbers, the layer
against plain chasing in closed loop, bad options named."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.control.fatigue_setpoint import (FatigueAwareSetpoint, FatigueOptions, FatigueSetpointError,
                                               LineDamageMonitor)
from tapm_opt.interfaces import Estimate
from tapm_opt.models import fatigue as fat
from tapm_opt.studies import verification as v


def _record(seed: int, n: int = 1500, plateaus: bool = True) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = 3.0e6 + np.cumsum(rng.normal(0.0, 4.0e4, n))
    if plateaus:   # held samples (a tension cell slower than the loop) and rounding
        x[200:215] = x[200]
        x = np.round(x, -3)
    return x


# -- on-line damage against the offline count ----------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_streaming_damage_is_the_offline_damage_of_the_record_so_far(seed):
    """At every prefix of the record the streaming Miner sum (closed cycles + the residue as half
    cycles) equals the verification's miner_damage (rainflow package) of that prefix."""
    x = _record(seed)
    c = v.TN_CURVES["studless_chain"]
    area = v.nominal_area("studless_chain", 0.137)
    s = fat.StreamingDamage(c.a_D, c.m, area)
    checked = 0
    for k, val in enumerate(x):
        s.push(val)
        if k in (0, 1, 2, 3, 10, 214, 215, 777) or k % 250 == 0 or k == len(x) - 1:
            off = v.miner_damage(x[:k + 1], c.a_D, c.m, area) if k >= 1 else 0.0
            assert s.damage == pytest.approx(off, rel=1e-12, abs=1e-300), k
            checked += 1
    assert checked > 10 and s.damage > 0
    # the residue stays short (the streaming state does not grow with the record)
    assert len(s.residue) < 40


def test_streaming_damage_of_a_sinusoid_is_the_closed_form():
    """N whole cycles of range 2A: N (2A / area / 1e6)^m / a_D, whether counted whole or
    half-cycle by half-cycle in the residue."""
    N, A, per = 30, 5.0e5, 40
    t = np.arange(N * per + 1) / per
    x = 3.0e6 - A * np.cos(2 * np.pi * t)
    c = v.TN_CURVES["six_strand_wire"]
    area = v.nominal_area("six_strand_wire", 0.1)
    s = fat.StreamingDamage(c.a_D, c.m, area)
    s.extend(x)
    assert s.damage == pytest.approx(N * (2 * A / area / 1e6) ** c.m / c.a_D, rel=1e-9)


def test_the_layers_monitor_counts_the_measured_tensions_it_is_given():
    """The layer's per-line damage is the offline damage of the tension cells it was handed (not
    the truth), line by line with each line's curve."""
    sc = load_scenario("fpso")
    curves = fat.line_curves(sc)
    ids = list(curves)
    rng = np.random.default_rng(5)
    T = 3.2e6 + np.cumsum(rng.normal(0.0, 3.0e4, (400, len(ids))), axis=0) * (1 + np.arange(len(ids)) / 6)
    mon = LineDamageMonitor(curves)
    for row in T:
        mon.push(row)
    c = curves[ids[0]]
    off = np.array([v.miner_damage(T[:, j], c.a_D, c.m, c.area) for j in range(len(ids))])
    np.testing.assert_allclose(mon.damage, off, rtol=1e-12)
    assert np.argmax(mon.damage) == np.argmax(off) and len(set(np.round(off, 20))) > 1


# -- the move of the T-N definitions left the verification's numbers alone ------------------------

def test_the_verification_uses_the_moved_definitions():
    from tapm_opt.studies import verification_study as vs

    for name in ("TN_CURVES", "TNCurve", "nominal_area", "rainflow_ranges", "miner_damage", "VerificationError"):
        assert getattr(v, name) is getattr(fat, name), name
    assert vs.CHAIN_HYDRODYNAMIC_RATIO == fat.CHAIN_HYDRODYNAMIC_RATIO == 1.8


# Computed with the verification before the move (commit b26a592), on _record(42)'s generator.
_BEFORE = {
    "studlink_chain": (0.02948227625761342, 1.902457130718004e-05),
    "studless_chain": (0.02948227625761342, 3.804914261436008e-05),
    "six_strand_wire": (0.01474113812880671, 1.6789606609095008e-05),
    "spiral_strand_wire": (0.01474113812880671, 3.4251893349190234e-06),
    "polyester_rope": (15.0, 4.341145170853306e-07),
}


@pytest.mark.parametrize("comp", list(_BEFORE))
def test_the_verifications_damage_is_what_it_was_before_the_move(comp):
    rng = np.random.default_rng(42)
    x = 3.0e6 + np.cumsum(rng.normal(0.0, 4.0e4, 2000))
    c = v.TN_CURVES[comp]
    area = v.nominal_area(comp, 0.137) if c.bars else v.nominal_area(comp, MBS=1.5e7)
    assert area == _BEFORE[comp][0]
    assert v.miner_damage(x, c.a_D, c.m, area) == pytest.approx(_BEFORE[comp][1], rel=1e-13)


@pytest.mark.parametrize("name, type_id, comp, area", [
    ("fpso", "chain137", "studless_chain", 0.02948227625761342),
    ("aamo4", "cable", "six_strand_wire", 0.00502654824574367),
    ("fang12", "chain100", "studless_chain", 0.015707963267948963),
])
def test_line_curves_are_the_verifications_default_curves(name, type_id, comp, area):
    """The controller's per-line curves (models.fatigue.line_curves) are the verification's default
    line-type curves (as before the move), so the on-line and the offline damage agree."""
    from tapm_opt.studies.verification_study import VerificationSettings, line_type_curves

    sc = load_scenario(name)
    ver = line_type_curves(VerificationSettings(consequence_class=1), sc)[type_id]
    assert (ver.component, ver.area) == (comp, area)
    for ln in sc.lines:
        c = fat.line_curves(sc)[ln.id]
        assert ln.type == type_id and (c.component, c.a_D, c.m, c.area) == (comp, ver.a_D, ver.m, ver.area)


# -- the layer ---------------------------------------------------------------------------------

def _layer(options=None):
    from tapm_opt.models.system import System

    sc = load_scenario("fpso")
    system = System.from_scenario(sc)
    return system, FatigueAwareSetpoint(system.lines, fat.line_curves(sc), system.thrusters.max_tau(), 300.0,
                                        40.0, 0.0, p_cot_B=system.p_cot_B, options=options)


def test_the_prediction_moves_the_setpoint_toward_the_damaged_lines_anchors():
    """A line that cycles alone (its measured sigma the largest, its damage the largest): the optimum
    lies toward its anchor (its stiffness, hence its cycles, fall there), and the move is bounded by
    the step limit per update and by the search radius."""
    system, lay = _layer({"warmup": 0.0, "period": 20.0, "max_rate": 0.5, "K_T": 0.05, "grid": 5})
    ids = list(lay.monitor.ids)
    j = ids.index("8")
    rng = np.random.default_rng(1)
    prev = np.zeros(2)
    for k in range(120):
        T = np.full(len(ids), 3.2e6) + rng.normal(0.0, 5e3, len(ids))
        T[j] += 2.0e5 * math.sin(2 * math.pi * k / 10.0)
        est = Estimate(t=float(k), eta=np.zeros(3), nu=np.zeros(3), tau_env=np.zeros(3), tensions=T)
        sp = lay.update(float(k), est)
        if k > 0:
            assert np.hypot(*(sp.eta_d[:2] - prev)) <= 0.5 * 1.0 + 1e-9   # step limit (the chased point is at 0)
        prev = np.array(sp.eta_d[:2])
    anchor = system.lines.anchors[j, :2]
    p = np.asarray(lay.target)
    assert np.hypot(*p) <= lay.opts.search_radius + 1e-9
    assert np.dot(p, anchor / np.hypot(*anchor)) > 5.0   # toward line 8's anchor
    assert lay.log() and lay.log()[-1]["J"] < lay.log()[-1]["J_chase"]


@pytest.mark.parametrize("opts, field", [
    ({"grid": 4}, "setpoint_options.grid"),
    ({"grid": True}, "setpoint_options.grid"),
    ({"max_rate": 0.0}, "setpoint_options.max_rate"),
    ({"K_T": -1.0}, "setpoint_options.K_T"),
    ({"period": float("nan")}, "setpoint_options.period"),
    ({"search_radius": "10"}, "setpoint_options.search_radius"),
    ({"K_T": 0.0, "K_D": 0.0}, "setpoint_options.K_T"),
    ({"spread": 1.0}, "unknown option(s) ['spread']"),
])
def test_bad_options_are_refused_naming_the_field(opts, field):
    with pytest.raises(FatigueSetpointError) as info:
        FatigueOptions.from_mapping(opts)
    assert field in str(info.value)


def test_a_study_refuses_bad_fatigue_options_naming_the_controller(tmp_path):
    from tapm_opt.studies.spec import load_study
    from tapm_opt.studies.store import StudyError

    f = tmp_path / "s.toml"
    f.write_text("""
[study]
name = "s"
scenario = "fpso"
duration = 600.0
setpoint = "unified"
setpoint_options = { w_bottom = 20.0 }
[[sea_states]]
id = "storm"
[[controllers]]
name = "ok"
type = "pid"
setpoint = "fatigue"
[[controllers]]
name = "bad"
type = "pid"
setpoint = "fatigue"
setpoint_options = { max_rate = -1 }
""")
    with pytest.raises(StudyError) as exc:
        load_study(f)
    assert "controllers[1].setpoint_options.max_rate = -1" in str(exc.value)
    f.write_text(f.read_text().replace("max_rate = -1", "max_rate = 0.1"))
    loops = {c.labels["controller"]: c.inputs["closed_loop"] for c in load_study(f).cases}
    # the unified setpoint's options are not the fatigue layer's
    assert loops["ok"]["setpoint"] == "fatigue" and "setpoint_options" not in loops["ok"]
    assert loops["bad"]["setpoint_options"] == {"max_rate": 0.1}


# -- closed loop: the layer against plain chasing, same sea, same seed ----------------------------

class _Recorder:
    """A setpoint layer that hands on to ``inner`` and keeps the measured tensions it was given."""

    def __init__(self, inner):
        self.inner, self.tensions = inner, []

    def update(self, t, estimate):
        self.tensions.append(np.array(estimate.tensions, float))
        return self.inner.update(t, estimate)

    def reset(self):
        self.inner.reset()
        self.tensions = []


def test_the_layer_lowers_the_worst_lines_damage_against_chasing_in_the_same_sea():
    """fpso storm, PID, seed 1, 900 s: chasing leaves the cycles on bundle 2 (line 8 worst, ~3 times
    the mean); the fatigue-aware layer moves toward bundle 2's anchors and lowers the worst line's
    damage (plant tension, the fatigue_damage KPIs) and the spread, paying thrust. Its on-line
    damage is the offline damage of the measured tensions it was handed."""
    from tapm_opt.models.system import System
    from tapm_opt.plant.simulator import Plant
    from tapm_opt.studies import ClosedLoopSettings
    from tapm_opt.studies.closed_loop import default_setpoint_layer, run_closed_loop
    from tapm_opt.studies.controllers import build_controller
    from tapm_opt.studies.kpis import case_kpis

    sc = load_scenario("fpso")
    system = System.from_scenario(sc)
    opts = {"K_T": 0.3, "max_rate": 0.2, "warmup": 60.0, "period": 30.0, "grid": 7}
    out = {}
    for sp in ("chasing", "fatigue"):
        st = ClosedLoopSettings(duration=900.0, setpoint=sp, setpoint_options=opts if sp == "fatigue" else None,
                                heading="chasing")
        layer = _Recorder(default_setpoint_layer(system, st))
        ctrl = build_controller(system, {"type": "pid"}, dt_control=st.dt_control, estimator=st.estimator)
        plant = Plant(system, sea_state="storm", seed=1, segments=6)
        res = run_closed_loop(plant, ctrl, st, system=system, setpoint_layer=layer)
        out[sp] = (case_kpis(res, system), layer)
    kc, kf = out["chasing"][0], out["fatigue"][0]
    worst = max((k for k in kc if k.startswith("fatigue_damage[")), key=kc.get)
    assert worst in ("fatigue_damage[7]", "fatigue_damage[8]") and kc["fatigue_damage_spread"] > 2.5
    assert kf["fatigue_damage_max"] < 0.92 * kc["fatigue_damage_max"]
    assert kf["fatigue_damage_spread"] < 0.92 * kc["fatigue_damage_spread"]
    assert kf["thrust_energy"] > kc["thrust_energy"]            # the price
    # the on-line count of the measured tensions is the offline count of the same record
    lay = out["fatigue"][1]
    fl = lay.inner.inner                                            # inside the heading layer
    assert isinstance(fl, FatigueAwareSetpoint)
    T = np.array(lay.tensions)
    curves = fat.line_curves(sc)
    off = [v.miner_damage(T[:, j], c.a_D, c.m, c.area) for j, c in enumerate(curves.values())]
    np.testing.assert_allclose(fl.monitor.damage, off, rtol=1e-10)
    assert fl.log() and fl.target is not None


def test_narrow_band_rate_is_the_rayleigh_mean_of_the_sinusoids_damage():
    """A narrow-band Gaussian tension (many sinusoids within +-3 % of f0, random phases): its
    rainflow damage over a long record is the narrow-band rate times the duration (within the
    sampling scatter), and the rate scales as sigma^m."""
    rng = np.random.default_rng(3)
    f0, sigma, dur, fs = 0.1, 8.0e4, 40000.0, 4.0
    t = np.arange(0.0, dur, 1.0 / fs)
    f = f0 * (1 + rng.uniform(-0.03, 0.03, 60))
    a = sigma * math.sqrt(2.0 / len(f))
    x = 3.0e6 + a * np.cos(2 * np.pi * np.outer(t, f) + rng.uniform(0, 2 * np.pi, len(f))).sum(axis=1)
    c = v.TN_CURVES["studless_chain"]
    area = v.nominal_area("studless_chain", 0.137)
    s_meas = float(np.std(x))
    wd = x - x.mean()
    nu0 = np.sum((wd[:-1] < 0) & (wd[1:] >= 0)) / dur
    D = v.miner_damage(x, c.a_D, c.m, area)
    rate = float(fat.narrow_band_damage_rate(s_meas, nu0, c.a_D, c.m, area))
    assert D == pytest.approx(rate * dur, rel=0.1)
    assert float(fat.narrow_band_damage_rate(2 * s_meas, nu0, c.a_D, c.m, area)) == pytest.approx(8 * rate, rel=1e-12)


def test_simulate_takes_the_fatigue_layer_and_refuses_its_bad_options(tmp_path, capsys):
    """``tapm simulate --setpoint fatigue``: its options checked as a study's are (the option named,
    nothing written), and a short run logs the layer."""
    from tapm_opt.cli import main

    code = main(["simulate", "aamo4", "--duration", "10", "--setpoint", "fatigue", "--setpoint-option", "bogus=1",
                 "--out", str(tmp_path / "bad")])
    err = capsys.readouterr().err
    assert code != 0 and "--setpoint-option" in err and "bogus" in err
    assert not (tmp_path / "bad").exists()
    code = main(["simulate", "aamo4", "--duration", "30", "--segments", "4", "--setpoint", "fatigue",
                 "--setpoint-option", "period=10", "--out", str(tmp_path / "ok")])
    assert code == 0
    from tapm_opt.results import Result

    assert Result.load(tmp_path / "ok" / "result.npz").meta["setpoint"] == "fatigue"
