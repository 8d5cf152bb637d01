"""Sensor faults (GNSS dropout and drift, a tension cell stuck, drifting or noisy, a gyro stuck or
drifting) as plant faults, and the estimator's redundancy that finds and excludes them
(tapm_opt.estimation.redundancy; docs/sensor_faults.md).

The closed-loop runs are fpso in its normal sea with the PID, 420 s, the fault at 250 s (the
voting arms at 120 s); about 4 s each.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tapm_opt.config import load_scenario, scenario_from_dict, scenario_to_dict
from tapm_opt.config.schema import Fault
from tapm_opt.errors import TapmError
from tapm_opt.estimation.redundancy import RedundancyError, SensorVoting, VotingSettings
from tapm_opt.interfaces import Measurement
from tapm_opt.models.system import System
from tapm_opt.plant.environment import PlantError
from tapm_opt.plant.simulator import Plant
from tapm_opt.studies.closed_loop import ClosedLoopSettings
from tapm_opt.studies.recipe import run_case_on
from tapm_opt.studies.spec import study_from_dict
from tapm_opt.studies.store import StudyError

FPSO = load_scenario("fpso")
T_F = 250.0
DURATION = 420.0


# -- the plant's sensors -----------------------------------------------------------------------

def _readings(faults, n=8):
    """Measurements at t = 0..n-1 s of fpso in still water with the thrusters off (seed 3)."""
    p = Plant(FPSO, sea_state="none", seed=3, segments=5, faults=faults)
    out = []
    for _ in range(n):
        out.append(p.measure(truth=True))
        p.step(1.0, (np.zeros(len(p.thrusters.ids)), None))
    return out, p


def test_each_sensor_fault_corrupts_only_its_sensor_as_declared():
    """Same seed with and without the faults: the differences are exactly the declared
    corruptions (the noise draws are shared), and nothing else changes."""
    ref, _ = _readings([])
    faults = [Fault(kind="gnss_drift", time=2.0, speed=0.2, direction=math.radians(90.0)),
              Fault(kind="cell_drift", time=2.0, line="2", rate=1000.0),
              Fault(kind="cell_stuck", time=2.0, line="3"),
              Fault(kind="cell_noisy", time=2.0, line="4", factor=5.0),
              Fault(kind="gyro_drift", time=2.0, heading_rate=math.radians(0.5)),
              Fault(kind="gyro_stuck", time=2.0, gyro=2)]
    got, plant = _readings(faults)
    assert [e[1] for e in plant.events][:1] and all("sensor fault" in e[1] for e in plant.events)
    for a, b in zip(ref, got):
        # faults act from the first sample after the step at whose start they are due (t = 3 s)
        dt = a.t - T0 if (T0 := 2.0) and a.t > T0 + 0.5 else 0.0
        assert np.allclose(b.position - a.position, [0.0, 0.2 * dt], atol=1e-9)
        assert b.tensions[1] - a.tensions[1] == pytest.approx(1000.0 * dt, abs=1e-6)
        assert math.isclose(float(b.heading), float(a.heading) + math.radians(0.5) * dt, abs_tol=1e-12)
        # the other lines read what they read without the faults
        keep = [i for i in range(12) if i not in (1, 2, 3)]
        assert np.array_equal(a.tensions[keep], b.tensions[keep])
        if dt:
            true = np.asarray(a.tensions[3]) - (a.tensions[3] - b.tensions[3]) / -4.0   # a - T = (b - T) / 5
            assert (b.tensions[3] - true) == pytest.approx(5.0 * (a.tensions[3] - true))
    # stuck: the held reading at the fault's start is repeated
    assert len({float(m.tensions[2]) for m in got[2:]}) == 1 and len({float(m.tensions[2]) for m in ref[2:]}) > 1
    assert len({m.heading2 for m in got[2:]}) == 1 and len({m.heading2 for m in ref[2:]}) > 1


def test_gnss_dropout_flags_the_position_invalid_and_recovers():
    got, _ = _readings([Fault(kind="gnss_dropout", time=2.0, end_time=5.0)])
    valid = [m.position_valid for m in got]
    assert valid == [True, True, True, False, False, True, True, True]
    for m in got:
        assert np.isnan(m.position).all() != m.position_valid
    # the receiver keeps reporting (no fix) at its rate
    assert [m.t_position for m in got] == [m.t for m in got]


# -- bad input ---------------------------------------------------------------------------------

@pytest.mark.parametrize("fault, field", [
    ({"kind": "gnss_drift", "time": 10.0, "direction_deg": 0.0}, "faults[0].speed"),
    ({"kind": "cell_drift", "time": 10.0, "line": "1"}, "faults[0].rate"),
    ({"kind": "cell_drift", "time": 10.0, "line": "99", "rate": 1.0}, "faults[0].line"),
    ({"kind": "cell_noisy", "time": 10.0, "line": "1", "factor": 0.5}, "faults[0].factor"),
    ({"kind": "gnss_dropout", "time": 10.0, "end_time": 5.0}, "faults[0].end_time"),
    ({"kind": "gyro_stuck", "time": 10.0, "gyro": 3}, "faults[0].gyro"),
    ({"kind": "line_break", "time": 10.0, "line": "1", "speed": 1.0}, "faults[0].speed"),
])
def test_a_bad_sensor_fault_in_a_scenario_is_refused_naming_the_field(fault, field):
    d = scenario_to_dict(FPSO)
    d["faults"] = [fault]
    with pytest.raises(TapmError) as exc:
        scenario_from_dict(d)
    assert field in str(exc.value)


def test_a_bad_sensor_fault_given_to_the_plant_or_a_study_is_refused_naming_the_field():
    with pytest.raises(PlantError, match="heading_rate"):
        Plant(FPSO, sea_state="none", segments=5, faults=[Fault(kind="gyro_drift", time=1.0)])
    with pytest.raises(PlantError, match="line = 'x'"):
        Plant(FPSO, sea_state="none", segments=5, faults=[Fault(kind="cell_stuck", time=1.0, line="x")])
    study = {"study": {"name": "s", "scenario": "fpso", "duration": 100.0},
             "controllers": [{"type": "pid", "redundancy": "vote"}],
             "conditions": [{"name": "a", "cell_drift": {"time": 10.0, "line": "1", "rate": 1.0, "speed": 2.0}},
                            {"name": "b", "gnss_drift": {"time": 10.0, "speed": -1.0, "direction_deg": 0.0}},
                            {"name": "c", "gyro_drift": {"time": 10.0}}]}
    with pytest.raises(StudyError) as exc:
        study_from_dict(study)
    msg = str(exc.value)
    assert "conditions[0].cell_drift" in msg and "speed" in msg
    assert "conditions[1].gnss_drift.speed" in msg
    assert "conditions[2].gyro_drift.heading_rate_deg_s" in msg
    with pytest.raises(RedundancyError, match="z_alarm"):
        VotingSettings(z_alarm=-1.0)
    with pytest.raises(StudyError, match="redundancy"):
        study_from_dict({**study, "controllers": [{"type": "pid", "redundancy": "maybe"}], "conditions": []})


# -- closed loop -------------------------------------------------------------------------------

_RUNS: dict = {}


def _run(key, faults, redundancy="vote"):
    """One closed-loop case (cached per module): (result, kpis)."""
    if (key, redundancy) not in _RUNS:
        sysm = System.from_scenario(dataclasses.replace(FPSO, faults=tuple(faults)))
        run = run_case_on(sysm, "pid", ClosedLoopSettings(duration=DURATION, redundancy=redundancy,
                                                          heading="chasing"),
                          sea_state="normal", seed=1, segments=10)
        _RUNS[(key, redundancy)] = (run.result, run.kpis)
    return _RUNS[(key, redundancy)]


def _detections(result):
    return [e for e in result.meta.get("estimator_log", []) if e.get("event") == "sensor fault detected"]


def _commands_finite(result):
    return all(np.isfinite(result[c]).all() for c in ("tau_cmd[X]", "tau_cmd[Y]", "tau_cmd[N]",
                                                      "x_hat", "y_hat", "psi_hat"))


FAULTS = {
    "gnss_drift": ([Fault(kind="gnss_drift", time=T_F, speed=0.05, direction=math.radians(90.0))], ("gnss", None)),
    "cell_stuck": ([Fault(kind="cell_stuck", time=T_F, line="1")], ("cell", "1")),
    "cell_drift": ([Fault(kind="cell_drift", time=T_F, line="1", rate_rel=-0.0002)], ("cell", "1")),
    "cell_noisy": ([Fault(kind="cell_noisy", time=T_F, line="1", factor=10.0)], ("cell", "1")),
    "gyro_stuck": ([Fault(kind="gyro_stuck", time=T_F)], ("gyro", 1)),
    "gyro_drift": ([Fault(kind="gyro_drift", time=T_F, heading_rate=math.radians(0.05))], ("gyro", 1)),
}


@pytest.mark.parametrize("name", list(FAULTS))
def test_each_sensor_fault_is_detected_isolated_and_ridden_out(name):
    faults, (sensor, which) = FAULTS[name]
    res, k = _run(name, faults)
    det = _detections(res)
    assert det, f"{name} not detected"
    first = det[0]
    assert first["sensor"] == sensor and first["t"] >= T_F
    assert first["fault"] == name.split("_")[1] if name != "gnss_drift" else first["fault"] == "drift"
    if sensor == "cell":
        assert first["line"] == which
    if sensor == "gyro":
        assert first["gyro"] == which
    assert k["sensor_fault_isolated"] == 1.0 and k["sensor_false_alarms"] == 0
    assert k["sensor_fault_detection_delay"] < 120.0
    assert _commands_finite(res)
    assert k["false_alarms"] == 0    # no line declared broken
    assert k["turret_error_fault_max"] < 4.0


def test_the_voting_keeps_the_estimate_where_a_single_sensor_would_lead_it_astray():
    """Drifting GNSS and gyro: without the voting the estimate follows the drift (the error grows
    with it), with it the failed sensor is excluded and the error stays a few metres."""
    for name in ("gnss_drift", "gyro_drift"):
        _, on = _run(name, FAULTS[name][0])
        _, off = _run(name, FAULTS[name][0], redundancy="none")
        assert off["turret_error_fault_max"] > 2.5 * on["turret_error_fault_max"], name


def test_a_gnss_dropout_switches_the_position_reference_to_the_tensions():
    faults = [Fault(kind="gnss_dropout", time=T_F, end_time=T_F + 120.0)]
    res, k = _run("dropout", faults)
    log = res.meta["estimator_log"]
    ref = [(e["t"], e["reference"]) for e in log if e.get("event") == "position reference"]
    assert ref[0][1] == "tensions" and T_F <= ref[0][0] <= T_F + 2.0
    assert ref[1][1] == "gnss" and ref[1][0] == pytest.approx(T_F + 120.0, abs=1.5)
    assert _commands_finite(res) and k["sensor_fault_detection_delay"] <= 2.0
    # the error during the dropout: bounded with the tensions, and smaller than dead reckoning's
    res0, k0 = _run("dropout", faults, redundancy="none")
    assert _commands_finite(res0)
    assert k["turret_error_fault_max"] < 3.0
    assert k0["turret_error_fault_max"] > 2.0 * k["turret_error_fault_max"]


def test_a_stuck_or_drifting_cell_is_not_a_broken_line_and_a_real_break_still_is():
    for name in ("cell_stuck", "cell_drift"):
        res, k = _run(name, FAULTS[name][0])
        assert not [e for e in res.meta["estimator_log"] if e.get("event") == "line break detected"], name
    # a faster drift (-8.5 kN/s): without the voting the cell is declared a broken line once it
    # reads 25 % low; with it the cell is excluded first
    fast = [Fault(kind="cell_drift", time=T_F, line="1", rate_rel=-0.0005)]
    res, k = _run("cell_drift_fast", fast, redundancy="none")
    assert k["false_alarms"] >= 1
    assert [e["line"] for e in res.meta["estimator_log"] if e.get("event") == "line break detected"] == ["1"]
    res, k = _run("cell_drift_fast", fast)
    assert k["false_alarms"] == 0 and k["sensor_fault_isolated"] == 1.0
    # a real break: the line-break detector finds it, the cell tests leave it alone
    res, k = _run("break", [Fault(kind="line_break", time=T_F, line="1")])
    assert k["break_isolated_line"] == "1" and k["false_alarms"] == 0 and k["detection_delay"] < 30.0
    assert _detections(res) == [] and k["sensor_false_alarms"] == 0


def test_no_sensor_is_excluded_in_an_intact_run():
    res, k = _run("intact", [])
    assert _detections(res) == [] and k["sensor_false_alarms"] == 0


# -- the estimators without a fix ----------------------------------------------------------------

@pytest.mark.parametrize("kind", ["lowpass", "passive", "ekf"])
def test_every_estimator_holds_its_prediction_without_a_gnss_fix(kind):
    from tapm_opt.studies.closed_loop import default_estimator

    sysm = System.from_scenario(FPSO)
    est = default_estimator(sysm, ClosedLoopSettings(estimator=kind, detector="none"))
    T = np.asarray(sysm.lines.tensions(np.zeros(3)), float)

    def meas(t, ok):
        return Measurement(t=t, position=np.array([0.3, -0.2]) if ok else np.full(2, np.nan), heading=0.01,
                           tensions=T, t_position=t, t_heading=t, t_tensions=t, position_valid=ok)

    with pytest.raises(TapmError, match="position_valid"):
        est.update(0.0, meas(0.0, False))   # no fix at the start: a clear error
    est.reset()
    e = est.update(0.0, meas(0.0, True))
    for t in range(1, 30):
        e = est.update(float(t), meas(float(t), t < 10))
        assert np.isfinite(e.eta).all() and np.isfinite(e.nu).all() and np.isfinite(e.tau_env).all()


def test_the_voting_needs_a_system_and_a_fix_to_start():
    sysm = System.from_scenario(FPSO)
    with pytest.raises(RedundancyError, match="system"):
        SensorVoting(FPSO, object())
    from tapm_opt.studies.closed_loop import default_estimator

    v = default_estimator(sysm, ClosedLoopSettings(redundancy="vote"))
    assert isinstance(v, SensorVoting)
    m = Measurement(t=0.0, position=np.full(2, np.nan), heading=0.0, tensions=np.ones(12) * 3e6, t_position=0.0,
                    t_heading=0.0, t_tensions=0.0, position_valid=False)
    with pytest.raises(RedundancyError, match="position_valid"):
        v.update(0.0, m)


def test_simulate_takes_the_voting_as_an_estimation_option(tmp_path, capsys):
    """``tapm simulate --option redundancy=vote`` reaches the runner's estimator (a bad value named,
    nothing written)."""
    from tapm_opt.cli import main
    from tapm_opt.results import Result

    code = main(["simulate", "aamo4", "--duration", "10", "--option", "redundancy=bogus", "--out", str(tmp_path / "b")])
    assert code != 0 and "redundancy" in capsys.readouterr().err and not (tmp_path / "b").exists()
    code = main(["simulate", "aamo4", "--duration", "30", "--segments", "4", "--option", "redundancy=vote",
                 "--out", str(tmp_path / "v")])
    assert code == 0
    assert Result.load(tmp_path / "v" / "result.npz").meta["redundancy"] == "vote"
