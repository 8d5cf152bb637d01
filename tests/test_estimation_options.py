"""Choosing the estimation from study files, ``tapm simulate`` and the runner's settings: the
``estimator`` (lowpass / passive / ekf) and ``detector`` (tension / drop / bank / none) keys, their
validation, and that each choice builds the component it names."""

from __future__ import annotations

import pytest
from tapm_opt.cli import main
from tapm_opt.config import load_scenario
from tapm_opt.estimation.detection import TensionDropDetector, TensionResidualDetector
from tapm_opt.estimation.observer import EKFObserver, PassiveObserver
from tapm_opt.estimation.lowpass import LowPassEstimator, TrueStateEstimator
from tapm_opt.models.system import System
from tapm_opt.studies.closed_loop import DEFAULT_ESTIMATOR, ClosedLoopError, ClosedLoopSettings, default_estimator
from tapm_opt.studies.spec import expand_cases
from tapm_opt.studies.store import StudyError

BASE = {"study": {"name": "s", "scenario": "fpso", "duration": 60.0, "segments": 6, "seeds": [1]},
        "sea_states": [{"id": "storm"}], "controllers": [{"name": "PID", "type": "pid"}]}


@pytest.fixture(scope="module")
def system():
    return System.from_scenario(load_scenario("fpso"))


def _study(study=None, controllers=None):
    d = {k: (dict(v) if isinstance(v, dict) else [dict(x) for x in v]) for k, v in BASE.items()}
    d["study"].update(study or {})
    if controllers is not None:
        d["controllers"] = controllers
    return expand_cases(d, base_dir=".", source="s.toml")


def test_every_case_names_its_estimation_so_a_new_default_cannot_reuse_old_results():
    from tapm_opt.studies.closed_loop import ClosedLoopSettings

    (c,) = _study()
    d = ClosedLoopSettings()
    assert (c.inputs["closed_loop"]["estimator"], c.inputs["closed_loop"]["detector"]) == (d.estimator, d.detector)
    (c2,) = _study({"detector": "drop"})
    assert c2.inputs["closed_loop"]["detector"] == "drop" and c2.id != c.id
    (c3,) = _study({"detector": d.detector})    # naming the default is the same case
    assert c3.id == c.id


def test_controller_tables_override_the_studys_estimation_key_by_key():
    cases = _study({"estimator": "ekf", "detector": "drop"},
                   [{"name": "a", "type": "pid"}, {"name": "b", "type": "pid", "detector": "tension"},
                    {"name": "c", "type": "lmpc", "estimator": "passive", "detector": "none"}])
    loops = {c.labels["controller"]: c.inputs["closed_loop"] for c in cases}
    assert (loops["a"]["estimator"], loops["a"]["detector"]) == ("ekf", "drop")
    assert (loops["b"]["estimator"], loops["b"]["detector"]) == ("ekf", "tension")
    assert (loops["c"]["estimator"], loops["c"]["detector"]) == ("passive", "none")
    assert all("estimator" not in c.inputs["controller"] for c in cases)   # not a controller option


@pytest.mark.parametrize("where, table, message", [
    ("study", {"estimator": "kalman"}, "study.estimator = 'kalman' is not one of lowpass, passive, ekf"),
    ("controller", {"detector": "banks"}, "controllers[0].detector = 'banks' is not one of tension, drop, bank, none"),
    ("controller", {"detector": "bank", "estimator": "lowpass"}, "controllers[0].detector"),
])
def test_bad_estimation_keys_are_named(where, table, message):
    with pytest.raises(StudyError) as exc:
        if where == "study":
            _study(table)
        else:
            _study(controllers=[{"name": "PID", "type": "pid", **table}])
    assert message in str(exc.value)


def test_settings_validate_and_the_default_estimator_is_what_they_name(system):
    for bad in ({"estimator": "kalman"}, {"detector": "cusum"}, {"detector": "bank", "estimator": "lowpass"}):
        with pytest.raises(ClosedLoopError):
            ClosedLoopSettings(**bad)
    e = default_estimator(system, ClosedLoopSettings())
    assert ClosedLoopSettings().estimator == DEFAULT_ESTIMATOR == "ekf"
    assert type(e) is EKFObserver and type(e.detector) is TensionResidualDetector and e.monitor is not None
    lp = default_estimator(system, ClosedLoopSettings(estimator="lowpass"))
    assert type(lp) is LowPassEstimator and type(lp.detector) is TensionResidualDetector
    assert type(default_estimator(system, ClosedLoopSettings(detector="drop")).detector) is TensionDropDetector
    for kind, cls in (("passive", PassiveObserver), ("ekf", EKFObserver)):
        o = default_estimator(system, ClosedLoopSettings(estimator=kind), system.scenario.sea_state("storm"))
        assert type(o) is cls and type(o.detector) is TensionResidualDetector
    assert default_estimator(system, ClosedLoopSettings(detector="none")).detector is None
    t = default_estimator(system, ClosedLoopSettings(true_state=True, detector="drop"))
    assert type(t) is TrueStateEstimator and type(t.detector) is TensionDropDetector


def test_simulate_takes_the_estimation_as_options_and_rejects_bad_ones(tmp_path, capsys):
    code = main(["simulate", "fpso", "--duration", "5", "--out", str(tmp_path / "o"), "--option", "estimator=kalman"])
    err = capsys.readouterr().err
    assert code == 2 and "estimator = 'kalman'" in err
    assert not (tmp_path / "o").exists()
    code = main(["simulate", "fpso", "--duration", "5", "--out", str(tmp_path / "o"), "--option", "detector=bank",
                 "--option", "estimator=lowpass"])
    assert code == 2 and "passive" in capsys.readouterr().err


# --- gain tables and the sea-state supervisor from specs --------------------------------------

@pytest.fixture(scope="module")
def gains_json(tmp_path_factory):
    from tapm_opt.control.gain_table import write_gain_tables
    from tapm_opt.design.gains import gain_table

    d = tmp_path_factory.mktemp("gains")
    write_gain_tables(gain_table(load_scenario("fpso"), sea_states=("calm", "storm"), broken=("3",)), d)
    return d / "gains.json"


def test_a_pid_spec_with_a_gain_table_or_a_supervisor_is_supervised(system, gains_json):
    from tapm_opt.control.scheduled import GainScheduledPID
    from tapm_opt.control.supervisor import SupervisedController
    from tapm_opt.studies.controllers import ControllerSpecError, build_controller

    c = build_controller(system, {"type": "pid", "gain_table": str(gains_json)})
    assert isinstance(c, SupervisedController) and isinstance(c.controller, GainScheduledPID)
    c = build_controller(system, {"type": "pid", "supervisor": {"dwell": 600.0}})
    assert isinstance(c, SupervisedController) and c.supervisor.dwell == 600.0
    for bad, msg in (({"supervisor": "yes"}, "controller.supervisor = 'yes'"),
                     ({"gain_table": 3}, "controller.gain_table = 3"),
                     ({"initial_sea_state": "storm"}, "initial_sea_state needs"),
                     ({"gain_table": str(gains_json), "initial_sea_state": "normal"}, "initial_sea_state = 'normal'")):
        with pytest.raises(ControllerSpecError, match=msg):
            build_controller(system, {"type": "pid", **bad})


def test_a_study_embeds_its_gain_table_relative_to_the_study_file(gains_json, tmp_path):
    import json

    from tapm_opt.control.gain_table import load_gain_table
    from tapm_opt.studies.spec import load_study

    (tmp_path / "g").mkdir()
    (tmp_path / "g" / "gains.json").write_text(gains_json.read_text())
    f = tmp_path / "s.toml"
    f.write_text('[study]\nname = "s"\nscenario = "fpso"\nduration = 60.0\nsegments = 6\n[[sea_states]]\nid = "storm"\n'
                 '[[controllers]]\nname = "scheduled"\ntype = "pid"\ngain_table = "g/gains.json"\n')
    (case,) = load_study(f).cases
    assert case.inputs["controller"]["gain_table"] == load_gain_table(gains_json).to_dict()
    json.dumps(case.inputs)   # self-contained and JSON-ready
    f.write_text(f.read_text().replace("g/gains.json", "missing/gains.json"))
    with pytest.raises(StudyError, match=r"controllers\[0\]\.gain_table = 'missing/gains.json'"):
        load_study(f)


def test_a_supervised_controllers_case_carries_every_sea_state_others_only_their_own():
    cases = _study(controllers=[{"name": "PID", "type": "pid"},
                                {"name": "sup", "type": "pid", "supervisor": True, "initial_sea_state": "normal"}])
    ids = {c.labels["controller"]: [s["id"] for s in c.inputs["scenario"]["sea_states"]] for c in cases}
    assert ids["PID"] == ["storm"]
    assert ids["sup"] == [s.id for s in load_scenario("fpso").sea_states] and "storm" in ids["sup"]


def test_an_empty_supervisor_table_is_supervised_and_the_study_sea_states_are_candidates():
    cases = _study(controllers=[{"name": "sup", "type": "pid", "supervisor": {}, "initial_sea_state": "normal"}])
    assert [s["id"] for s in cases[0].inputs["scenario"]["sea_states"]] == \
        [s.id for s in load_scenario("fpso").sea_states]
    d = {k: (dict(v) if isinstance(v, dict) else [dict(x) for x in v]) for k, v in BASE.items()}
    d["sea_states"] = [{"id": "storm"}, {"id": "mine", "Hs": 3.0, "Tp": 8.0}]
    d["controllers"] = [{"name": "sup", "type": "pid", "supervisor": True, "initial_sea_state": "normal"}]
    cand = {c.inputs["sea_state"]: [s["id"] for s in c.inputs["scenario"]["sea_states"]]
            for c in expand_cases(d, base_dir=".", source="s.toml")}
    assert cand["storm"] == cand["mine"] and cand["mine"][-1] == "mine"   # the same candidates for every case


def test_the_bank_with_the_true_state_is_refused(system):
    with pytest.raises(ClosedLoopError, match="true_state"):
        ClosedLoopSettings(true_state=True, detector="bank", estimator="ekf")
    with pytest.raises(StudyError, match=r"controllers\[0\]\.detector = 'bank' needs the observers"):
        _study({"true_state": True}, [{"name": "PID", "type": "pid", "detector": "bank", "estimator": "ekf"}])


def test_a_supervisor_samples_at_the_loops_control_period(system):
    from tapm_opt.studies.controllers import build_controller

    c = build_controller(system, {"type": "pid", "supervisor": True}, dt_control=0.5, estimator="ekf")
    assert c.supervisor.dt == 0.5
