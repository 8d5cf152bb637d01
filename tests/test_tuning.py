"""Controllers designed by optimisation (tapm tune): the tuner reaches a known optimum, fronts are
fronts, the storage is the run's memory (kill -9, two runs on one storage), constraints bind,
designs reproduce their KPIs, bad input is named."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from tapm_opt.cli import main
from tapm_opt.design.registry import ControllerKind, Dimension, register, unregister
from tapm_opt.studies.tuning import (Constraint, Objective, TrialEvaluator, TrialRow, TuningError, TuningSettings,
                                     dominates, front, hypervolume_2d, optimise, search_space, select,
                                     tuning_settings)

# -- a plant whose optimum is known: LQR ------------------------------------------------------
#
# x'' = -k x - c x' + u with u = -kp x - kd x' (a PD law, the form of the PID's position loop);
# J = integral of (q x^2 + r u^2) dt from x(0) = 1 is x0' P x0 with P from the closed loop's
# Lyapunov equation. LQR gives the optimal kp, kd and J.

M_, K_, C_, Q_, R_ = 1.0, 0.2, 0.05, 1.0, 0.5


def _cost(kp: float, kd: float) -> float:
    from scipy.linalg import solve_continuous_lyapunov

    A = np.array([[0.0, 1.0], [-(K_ + kp) / M_, -(C_ + kd) / M_]])
    if np.max(np.linalg.eigvals(A).real) >= 0:
        return 1e6
    Kg = np.array([[kp, kd]])
    Qc = np.diag([Q_, 0.0]) + R_ * Kg.T @ Kg
    P = solve_continuous_lyapunov(A.T, -Qc)
    return float(P[0, 0])


def _lqr() -> tuple[np.ndarray, float]:
    from scipy.linalg import solve_continuous_are

    A = np.array([[0.0, 1.0], [-K_ / M_, -C_ / M_]])
    B = np.array([[0.0], [1.0 / M_]])
    P = solve_continuous_are(A, B, np.diag([Q_, 0.0]), np.array([[R_]]))
    return (B.T @ P / R_).ravel(), float(P[0, 0])


@dataclasses.dataclass(frozen=True)
class PDOptions:
    """A PD law on a unit mass (test kind)."""

    kp: float = dataclasses.field(default=1.0, metadata={"doc": "stiffness", "unit": "N/m"})
    kd: float = dataclasses.field(default=1.0, metadata={"doc": "damping", "unit": "N s/m"})


PD_KIND = ControllerKind("pd_test", "PD law on a unit mass (test)", "PD", PDOptions, lambda s, o, c: None,
                         {"kp": Dimension(0.01, 20.0, log=True), "kd": Dimension(0.01, 20.0, log=True)})


def _lqr_evaluate(spec):   # the 'cases' of this plant: one, whose 'thrust_energy' is the quadratic cost J
    return [{"thrust_energy": _cost(spec["kp"], spec["kd"])}]


@pytest.fixture
def pd_kind():
    register(PD_KIND, replace=True)
    yield PD_KIND
    unregister("pd_test")


def test_tuner_reaches_the_lqr_optimum(pd_kind, tmp_path):
    k_opt, j_opt = _lqr()
    settings = TuningSettings(objectives=(Objective.parse("thrust_energy"),), trials=60, seed=3)
    params, fixed = search_space("pd_test", {})
    ev = TrialEvaluator({"type": "pd_test"}, params, fixed, settings, _lqr_evaluate)
    st = optimise(f"sqlite:///{tmp_path / 't.db'}", "lqr", ev, trials=60, workers=0)
    best = st.best_trial
    assert best.value <= 1.03 * j_opt, (best.value, j_opt)
    assert best.value >= j_opt * (1 - 1e-9)   # nothing beats the optimum
    assert best.params["kp"] == pytest.approx(k_opt[0], rel=0.35)
    assert best.params["kd"] == pytest.approx(k_opt[1], rel=0.35)


# -- fronts, selection, hypervolume ------------------------------------------------------------


def _row(n, a, b, feasible=True, state="COMPLETE"):
    return TrialRow("C", n, state, {"offset_max": a, "thrust_energy": b}, {}, {}, feasible, (a, b))


def test_front_is_non_dominated_and_holds_every_non_dominated_feasible_trial():
    rng = np.random.default_rng(1)
    rows = [_row(i, *rng.uniform(0, 1, 2), feasible=bool(rng.uniform() > 0.2)) for i in range(200)]
    rows += [_row(500, 0.0, 0.0, feasible=False), _row(501, 0.01, 0.01, state="FAIL")]
    f = front(rows)
    ok = [r for r in rows if r.feasible and r.state == "COMPLETE"]
    assert f and all(r.feasible and r.state == "COMPLETE" for r in f)   # constraints respected
    assert not any(dominates(a.objectives, b.objectives) for a in f for b in f)
    for r in ok:   # every non-dominated feasible finished trial is on it
        if not any(dominates(o.objectives, r.objectives) for o in ok):
            assert r in f
    assert 500 not in {r.number for r in f}   # infeasible, though it dominates everything


def test_knee_and_rule_selection():
    f = front([_row(0, 40.0, 10.0), _row(1, 45.0, 5.0), _row(2, 60.0, 4.5), _row(3, 41.0, 9.0)])
    s = TuningSettings()
    assert select(f, s).number == 1   # nearest the ideal point after scaling
    rule = dataclasses.replace(s, select="min thrust_energy with offset_max <= 44")
    assert select(f, rule).number == 3
    assert select(f, dataclasses.replace(s, select="min thrust_energy with offset_max <= 10")) is None


def test_hypervolume_2d_closed_form():
    assert hypervolume_2d([(1.0, 1.0)], (3.0, 3.0)) == pytest.approx(4.0)
    assert hypervolume_2d([(1.0, 2.0), (2.0, 1.0)], (3.0, 3.0)) == pytest.approx(3.0)
    assert hypervolume_2d([(1.0, 2.0), (2.0, 1.0), (2.5, 2.5)], (3.0, 3.0)) == pytest.approx(3.0)   # dominated
    assert hypervolume_2d([(4.0, 0.0)], (3.0, 3.0)) == 0.0


# -- bad input ----------------------------------------------------------------------------------


def test_bad_tuning_input_is_named():
    with pytest.raises(TuningError, match=r"unknown KPI 'ofset_max'.*offset_max"):
        tuning_settings({"objectives": ["ofset_max"]})
    with pytest.raises(TuningError, match="no better direction"):
        tuning_settings({"objectives": ["duration"]})
    with pytest.raises(TuningError, match="must read like"):
        Constraint.parse("time_outside_safe < 0")
    with pytest.raises(TuningError, match=r"tuning.trials = 0"):
        tuning_settings({"trials": 0})
    with pytest.raises(TuningError, match=r"tuning.samplr: unknown key; did you mean 'sampler'"):
        tuning_settings({"samplr": "tpe"})
    with pytest.raises(TuningError, match=r"tune.w_thrst: 'w_thrst' is not an option of lmpc; did you mean 'w_thrust'"):
        search_space("lmpc", {}, {"w_thrst": [1.0, 2.0]})
    with pytest.raises(TuningError, match=r"empty or inverted range"):
        search_space("lmpc", {}, {"w_thrust": [10.0, 1.0]})
    with pytest.raises(TuningError, match=r"log scale, so low must be > 0"):
        search_space("lmpc", {}, {"w_thrust": [0.0, 1.0]})
    with pytest.raises(TuningError, match=r"polygon_sides has no search space"):
        search_space("lmpc", {}, {"polygon_sides": [8, 16]})
    assert Constraint.parse("riser_delta_min >= 2").violation(1.5) == pytest.approx(0.5)
    assert Constraint.parse("time_outside_safe <= 0").violation(0.0) == 0.0


def test_search_space_fixes_what_the_study_sets_and_narrows_what_tune_says():
    params, fixed = search_space("lmpc", {"w_rate": 3.0}, {"w_thrust": [2.0, 20.0], "dead_band": 0.5})
    names = {p.name for p in params}
    assert "w_rate" not in names and "dead_band" not in names and fixed == {"dead_band": 0.5}
    (w,) = [p for p in params if p.name == "w_thrust"]
    assert (w.dim.low, w.dim.high, w.dim.log) == (2.0, 20.0, True)
    pid, _ = search_space("pid", {})
    assert {"periods[0]", "periods[1]", "periods[2]", "modes"} <= {p.name for p in pid}


# -- the command, on a small study -------------------------------------------------------------

STUDY = """
[study]
name = "t"
scenario = "fpso"
duration = {duration}
segments = 4
seeds = [1]

[[sea_states]]
id = "normal"

[[controllers]]
name = "PID"
type = "pid"
modes = "normal_restoring"
tune = {{ damping = 0.8, integral_ratio = 0.1, periods = [150.0, 400.0] }}

[tuning]
trials = {trials}
{extra}
"""


def _study(tmp_path, trials=3, duration=40.0, extra=""):
    p = tmp_path / "study.toml"
    p.write_text(STUDY.format(trials=trials, duration=duration, extra=extra))
    return p


def _complete(db: Path, name: str = "t/PID") -> list:
    import optuna

    st = optuna.load_study(study_name=name, storage=f"sqlite:///{db}")
    return [t for t in st.get_trials(deepcopy=False) if t.state.name == "COMPLETE"]


def test_tune_writes_fronts_and_a_design_that_reproduces_its_kpis(tmp_path, capsys):
    p = _study(tmp_path, trials=3, extra='constraints = ["time_outside_safe <= 0"]\nverify_seeds = [5]')
    out = tmp_path / "tune"
    code = main(["tune", str(p), "--out", str(out), "--workers", "0"])
    text = capsys.readouterr()
    assert code == 0, text.err
    assert "PID: 3/3 trials finished" in text.out
    import csv

    trials = list(csv.DictReader(open(out / "trials.csv")))
    assert len(trials) == 3 and {"offset_max", "thrust_energy", "time_outside_safe", "params"} <= set(trials[0])
    fr = list(csv.DictReader(open(out / "front.csv")))
    assert fr and all(float(r["time_outside_safe"]) <= 0 for r in fr)
    design = out / "tuned" / "PID.toml"
    import tomllib

    d = tomllib.loads(design.read_text())["design"]
    assert d["controller"]["type"] == "pid" and len(d["controller"]["periods"]) == 3
    code = main(["report", str(out)])   # the tuning report: the answer first
    assert code == 0, capsys.readouterr().err
    md = (out / "report.md").read_text()
    assert md.startswith("# Tuning: t") and md.index("## The answer") < md.index("## The selected designs")
    assert "Hypervolume" in md and (out / "report_files" / "tuning_fronts.png").stat().st_size > 1000
    verify = list(csv.DictReader(open(out / "verify.csv")))
    assert {r["kpi"] for r in verify} >= {"offset_max", "thrust_energy"}
    info = json.loads((out / "tuning.json").read_text())
    assert info["limits"]["safe_radius"] == 50.0 and info["delta_s"] == 2.0
    held = info["verify"]["PID"]
    assert held["per_seed"]["5"]["offset_max"] == pytest.approx(held["kpis"]["offset_max"])   # one held-out seed
    assert "## Held-out seeds" in md and "per held-out seed" in md
    # the design in tapm simulate: the same case (sea state, seed, duration, segments) gives its KPIs
    code = main(["simulate", "fpso", "--option", f"design={design}", "--sea-state", "normal", "--seed", "1",
                 "--duration", "40", "--segments", "4", "--out", str(tmp_path / "sim")])
    assert code == 0, capsys.readouterr().err
    k = json.loads((tmp_path / "sim" / "summary.json").read_text())["kpis"]
    assert k["offset_max"] == pytest.approx(d["kpis"]["offset_max"], rel=1e-9)
    assert k["thrust_energy"] == pytest.approx(d["kpis"]["thrust_energy"], rel=1e-9)
    # and from a study file
    s2 = tmp_path / "s2.toml"
    s2.write_text(textwrap.dedent(f"""
        [study]
        name = "d"
        scenario = "fpso"
        duration = 40.0
        segments = 4
        seeds = [1]
        [[sea_states]]
        id = "normal"
        [[controllers]]
        name = "tuned"
        design = "{design}"
    """))
    code = main(["study", "run", str(s2), "--out", str(tmp_path / "s2"), "--workers", "0", "--no-progress"])
    assert code == 0, capsys.readouterr().err
    row = next(csv.DictReader(open(tmp_path / "s2" / "kpis.csv")))
    assert float(row["offset_max"]) == pytest.approx(d["kpis"]["offset_max"], rel=1e-9)


def test_a_constraint_no_trial_meets_is_said(tmp_path, capsys):
    p = _study(tmp_path, trials=2, extra='constraints = ["offset_max <= 0.001"]')
    code = main(["tune", str(p), "--out", str(tmp_path / "o"), "--workers", "0"])
    out = capsys.readouterr().out
    assert code == 0
    assert "no finished trial meets the constraints offset_max <= 0.001; no design written" in out
    assert not (tmp_path / "o" / "tuned" / "PID.toml").exists()


def test_bad_command_input_is_named(tmp_path, capsys):
    p = _study(tmp_path, extra='objectives = ["offset_maxx"]')
    assert main(["tune", str(p), "--out", str(tmp_path / "o")]) == 2
    assert "unknown KPI 'offset_maxx'" in capsys.readouterr().err
    p = _study(tmp_path)
    assert main(["tune", str(p), "--out", str(tmp_path / "o"), "--storage", "nosuchdb://x/y"]) == 2
    assert "--storage 'nosuchdb://x/y' cannot be opened" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text(STUDY.format(trials=2, duration=40.0, extra="").replace("periods = [150.0, 400.0]",
                                                                          "periods = [400.0, 150.0]"))
    assert main(["tune", str(bad), "--out", str(tmp_path / "o2")]) == 2
    assert "empty or inverted range" in capsys.readouterr().err


def _tune_process(study: Path, out: Path, *extra: str) -> subprocess.Popen:
    """``tapm tune`` in its own process group; its output goes to a file beside OUT (a pipe nobody
    reads could fill and stall it)."""
    log = open(f"{out}.log", "ab")
    return subprocess.Popen([sys.executable, "-m", "tapm_opt", "tune", str(study), "--out", str(out),
                             "--workers", "0", *extra], stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)


def _output(out: Path) -> str:
    return Path(f"{out}.log").read_text(errors="replace")[-4000:]


@pytest.mark.slow
def test_kill_9_loses_no_finished_trial_and_repeats_none(tmp_path):
    n = 30   # a budget the first run cannot finish between two polls of its storage
    p = _study(tmp_path, trials=n, duration=60.0)
    out = tmp_path / "o"
    proc = _tune_process(p, out)
    db = out / "tuning.db"
    t0 = time.monotonic()
    done = 0
    # a first process may compile the plant's kernels before its first trial: wait for it, not a clock
    while time.monotonic() - t0 < 1200 and proc.poll() is None:
        if db.exists():
            try:
                done = len(_complete(db))
            except Exception:  # noqa: BLE001 - the study not created yet
                pass
            if done >= 2:
                break
        time.sleep(0.5)
    assert proc.poll() is None, f"the first run ended before it was killed ({done} trials):\n{_output(out)}"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert done >= 2, f"the first run did not finish 2 trials before it was stopped:\n{_output(out)}"
    before = {t.number: (t.params, t.values) for t in _complete(db)}
    assert 2 <= len(before) < n
    proc = _tune_process(p, out)
    assert proc.wait(timeout=1200) == 0, _output(out)
    after = {t.number: (t.params, t.values) for t in _complete(db)}
    assert len(after) == n
    for k, pv in before.items():   # every finished trial kept, unchanged
        assert after[k] == pv
    params = [json.dumps(v[0], sort_keys=True) for v in after.values()]
    assert len(set(params)) == len(params)   # none run twice


@pytest.mark.slow
def test_two_runs_on_one_storage_share_the_trials(tmp_path):
    p = _study(tmp_path, trials=4, duration=60.0)
    url = f"sqlite:///{tmp_path / 'shared.db'}"
    a = _tune_process(p, tmp_path / "a", "--storage", url)
    time.sleep(1.0)
    b = _tune_process(p, tmp_path / "b", "--storage", url)
    assert a.wait(timeout=1200) == 0, _output(tmp_path / "a")
    assert b.wait(timeout=1200) == 0, _output(tmp_path / "b")
    done = _complete(tmp_path / "shared.db")
    assert len(done) == 4   # the budget once, not once per run
    params = [json.dumps(t.params, sort_keys=True) for t in done]
    assert len(set(params)) == 4   # the two runs drew different parameters
    import csv

    for d in ("a", "b"):
        rows = [r for r in csv.DictReader(open(tmp_path / d / "trials.csv")) if r["state"] == "COMPLETE"]
        assert len(rows) == 4


def test_trials_that_keep_failing_end_the_run_with_the_reason(tmp_path, capsys):
    p = tmp_path / "study.toml"
    p.write_text(STUDY.format(trials=3, duration=20.0, extra="").replace(
        "tune = {{ damping".replace("{{", "{"), "tune = { tau_limit = -1.0, damping"))
    code = main(["tune", str(p), "--out", str(tmp_path / "o"), "--workers", "0"])
    err = capsys.readouterr().err
    assert code == 2
    assert "t/PID: 11 trials failed (at most 10 for 3 trials); the last (trial 10): ControllerSpecError" in err
    assert "tau_limit" in err


def test_coverage_of_one_front_over_another():
    from tapm_opt.report.tuning import coverage

    pid = [(40.0, 10.0), (45.0, 8.0), (50.0, 5.0)]
    mpc = [(40.3, 9.0), (45.0, 8.0), (60.0, 3.0)]
    cv = coverage(mpc, pid, tol=0.5)
    assert cv["covered"] == pytest.approx(2 / 3)           # 40.3 <= 40.5 with less energy; 45 equal
    assert cv["savings"] == pytest.approx([0.1, 0.0])
    assert cv["uncovered"] == [(50.0, 5.0)]                 # where the PID is better
    assert coverage(pid, pid, tol=0.0)["covered"] == 1.0   # a front covers itself


@pytest.mark.slow
def test_trials_run_on_a_dask_cluster(tmp_path):
    """--scheduler: the workers' trial loops run as tasks on the cluster, on the same storage."""
    distributed = pytest.importorskip("distributed")
    from tapm_opt.studies.tuning import tune_study

    p = _study(tmp_path, trials=3, duration=30.0)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        summary = tune_study(p, tmp_path / "o", workers=2, scheduler=cl.scheduler_address, echo=lambda s: None,
                             poll=0.5)
    assert summary["controllers"]["PID"]["complete"] == 3
    assert len(_complete(tmp_path / "o" / "tuning.db")) == 3
    assert (tmp_path / "o" / "tuned" / "PID.toml").is_file()


@pytest.mark.slow
def test_pid_tuned_per_sea_state_and_condition_becomes_a_gain_table_that_drives_the_loop(tmp_path, capsys):
    p = tmp_path / "per.toml"
    p.write_text(textwrap.dedent("""
        [study]
        name = "per"
        scenario = "fpso"
        duration = 20.0
        segments = 4
        seeds = [1]
        [[sea_states]]
        id = "calm"
        [[sea_states]]
        id = "normal"
        [[controllers]]
        name = "PID"
        type = "pid"
        modes = "normal_restoring"
        tune = { damping = 0.8 }
        [[conditions]]
        name = "intact"
        [[conditions]]
        line_break = { line = "1", time = 0.0 }
        [tuning]
        trials = 3
        per = ["sea_state", "condition"]
    """))
    out = tmp_path / "tune"
    assert main(["tune", str(p), "--out", str(out), "--workers", "0"]) == 0, capsys.readouterr().err
    info = json.loads((out / "tuning.json").read_text())
    assert len(info["controllers"]) == 4   # one design per sea state and condition
    from tapm_opt.studies.tuning import gain_designs

    designs = gain_designs(out)
    assert set(designs) == {("calm", "intact"), ("calm", "1"), ("normal", "intact"), ("normal", "1")}
    assert main(["gains", "fpso", "--designs", str(out), "--out", str(tmp_path / "g")]) == 0
    assert "4 with the tuned PID design" in capsys.readouterr().out
    assert main(["gains", "fpso", "--sea-states", "calm,normal", "--broken", "1", "--out", str(tmp_path / "g0")]) == 0
    tuned = json.loads((tmp_path / "g" / "gains.json").read_text())["rows"]
    plain = {(r["condition"]["sea_state"], r["condition"]["broken"]): r
             for r in json.loads((tmp_path / "g0" / "gains.json").read_text())["rows"]}
    for r in tuned:
        key = (r["condition"]["sea_state"], r["condition"]["broken"])
        np.testing.assert_allclose(r["pid"]["periods"], designs[key]["periods"], rtol=1e-12)
        assert not np.allclose(r["pid"]["Kp"], plain[key]["pid"]["Kp"])   # the tuned design, not the class's
    capsys.readouterr()
    code = main(["simulate", "fpso", "--controller", "pid", "--option", f"gain_table={tmp_path / 'g' / 'gains.json'}",
                 "--sea-state", "normal", "--duration", "60", "--segments", "4", "--out", str(tmp_path / "sim")])
    assert code == 0, capsys.readouterr().err
    k = json.loads((tmp_path / "sim" / "summary.json").read_text())["kpis"]
    assert 0.0 < k["offset_max"] < 50.0


def test_a_trial_drawing_parameters_already_run_is_pruned_not_run(pd_kind, tmp_path):
    """Two runs that draw the same parameters (the same seed, joining at the same moment) do not
    evaluate them twice: the second trial is pruned before it runs."""
    calls = []

    def evaluate(spec):
        calls.append((spec["kp"], spec["kd"]))
        return _lqr_evaluate(spec)

    settings = TuningSettings(objectives=(Objective.parse("thrust_energy"),), trials=3, seed=1)
    params, fixed = search_space("pd_test", {})
    url = f"sqlite:///{tmp_path / 't.db'}"
    from tapm_opt.studies.tuning import WorkerJob, create_study, run_worker

    create_study(url, "dup", settings, {})
    job = WorkerJob(url, "dup", TrialEvaluator({"type": "pd_test"}, params, fixed, settings, evaluate), trials=3)
    run_worker(job)
    first = list(calls)
    import optuna

    st = optuna.load_study(study_name="dup", storage=url)
    job2 = dataclasses.replace(job, trials=4)
    # the second run with the first run's seed and no offset draws trial 0's parameters again
    from unittest import mock

    with mock.patch("tapm_opt.studies.tuning._sampler", lambda *a, **k: optuna.samplers.RandomSampler(seed=1)):
        run_worker(job2)
    states = [t.state.name for t in st.get_trials()]
    assert states.count("COMPLETE") == 4 and "PRUNED" in states
    assert len(set(calls)) == len(calls)   # no parameter set evaluated twice
    assert calls[:3] == first


def test_a_trial_killed_before_its_first_heartbeat_does_not_hold_a_resumed_run(pd_kind, tmp_path, monkeypatch):
    """A worker killed between starting a trial and its first heartbeat leaves a running trial
    without a heartbeat, which optuna's stale-trial check never fails. A resumed run whose budget
    that trial holds gives it one heartbeat, fails it after the grace period and finishes the
    budget, instead of waiting for ever (measured: it waited until killed)."""
    import threading

    import optuna

    from tapm_opt.studies import tuning
    from tapm_opt.studies.tuning import WorkerJob, create_study, run_worker

    monkeypatch.setattr(tuning, "HEARTBEAT", 1)
    monkeypatch.setattr(tuning, "GRACE", 2)
    settings = TuningSettings(objectives=(Objective.parse("thrust_energy"),), trials=3, seed=1)
    params, fixed = search_space("pd_test", {})
    url = f"sqlite:///{tmp_path / 't.db'}"
    create_study(url, "dead", settings, {})
    job = WorkerJob(url, "dead", TrialEvaluator({"type": "pd_test"}, params, fixed, settings, _lqr_evaluate), trials=2)
    run_worker(job)
    st = optuna.load_study(study_name="dead", storage=tuning._storage(url))
    st.ask()                         # the dead worker's trial: running, never beaten
    assert [t.state.name for t in st.get_trials()].count("RUNNING") == 1
    done = []
    worker = threading.Thread(target=lambda: done.append(run_worker(dataclasses.replace(job, trials=3))),
                              daemon=True)
    worker.start()
    worker.join(timeout=120)
    assert not worker.is_alive(), "the resumed run waited for the dead trial"
    states = [t.state.name for t in st.get_trials()]
    assert states.count("COMPLETE") == 3 and states.count("FAIL") == 1 and "RUNNING" not in states


def test_selection_rules_are_tried_in_order_and_name_the_one_that_chose():
    from tapm_opt.studies.tuning import TrialRow, select_with
    from tapm_opt.studies.tuning_space import TuningError, tuning_settings

    def row(n, off, e, riser):
        v = {"offset_max": off, "thrust_energy": e, "time_outside_safe": 0.0, "riser_delta_min": riser}
        return TrialRow("C", n, "COMPLETE", v, {}, {}, True, (off, e))

    f = [row(0, 40.0, 9.0, 1.0), row(1, 44.0, 7.0, -1.0), row(2, 52.0, 5.0, -2.0)]
    st = tuning_settings({"select": ["min thrust_energy with offset_max <= 45", "knee"]})
    chosen, rule = select_with(f, st)
    assert (chosen.number, rule) == (1, "min thrust_energy with offset_max <= 45")
    st = tuning_settings({"select": ["min thrust_energy with offset_max <= 30", "knee"]})
    chosen, rule = select_with(f, st)
    assert rule == "knee" and chosen.number == 1   # scaled to [0, 1]: (0.33, 0.5) is nearest the ideal
    st = tuning_settings({"select": ["max riser_delta_min with offset_max <= 50"]})
    assert select_with(f, st)[0].number == 0       # a rule may read a context KPI
    assert "riser_delta_min" in [c for c, _ in st.reported()]
    st = tuning_settings({"select": ["min thrust_energy with offset_max <= 30"]})
    assert select_with(f, st) == (None, None)
    with pytest.raises(TuningError, match=r"tuning.select = \[\]"):
        tuning_settings({"select": []})
    with pytest.raises(TuningError, match="tuning.select = 'cheapest'"):
        tuning_settings({"select": ["knee", "cheapest"]})


def test_report_says_where_one_front_beats_another_and_why(tmp_path):
    """A synthetic run: B reaches closer than A ever came, and runs cheaper than any A trial ran
    (outside the safe circle); A covers the middle. The report's answer names each region with its
    reason, the riser's cost and the held-out gap."""
    from tapm_opt.report.tuning import write_tuning_report

    d = tmp_path / "run"
    d.mkdir()
    cols = ["controller", "trial", "state", "offset_max", "thrust_energy", "time_outside_safe", "riser_delta_min",
            "feasible", "params"]
    mwh = 3.6e9
    A = [(0, 45.0, 20.0, 0.0, 1.0), (1, 50.0, 15.0, 0.0, 0.5), (2, 55.0, 12.0, 300.0, -0.5), (3, 60.0, 14.0, 900.0, -1.0)]
    B = [(0, 40.0, 30.0, 0.0, 2.5), (1, 49.9, 16.0, 0.0, 0.2), (2, 70.0, 8.0, 3500.0, -2.0)]
    rows = [",".join(cols)]
    for name, pts in (("A", A), ("B", B)):
        for n, o, e, t, r in pts:
            rows.append(f'{name},{n},COMPLETE,{o},{e * mwh},{t},{r},true,"{{}}"')
    (d / "trials.csv").write_text("\n".join(rows) + "\n")
    front_rows = [rows[0]] + [r for r in rows[1:] if not r.startswith("A,3,")]
    (d / "front.csv").write_text("\n".join(front_rows) + "\n")
    info = {"format": "tapm-tuning/1", "study": "syn", "storage": "sqlite:///x.db", "limits": {"safe_radius": 50.0},
            "delta_s": 2.0,
            "settings": {"objectives": ["max(offset_max)", "sum(thrust_energy)"], "constraints": [], "trials": 4,
                         "sampler": "tpe", "seed": 0, "select": "knee", "verify_seeds": [7]},
            "controllers": {"A": {"selected": 1, "kpis": {"offset_max": 50.0, "thrust_energy": 15.0 * mwh,
                                                          "time_outside_safe": 0.0, "riser_delta_min": 0.5},
                                  "spec": {"type": "pid"}, "front": [0, 1, 2], "complete": 4},
                            "B": {"selected": 1, "kpis": {"offset_max": 49.9, "thrust_energy": 16.0 * mwh,
                                                          "time_outside_safe": 0.0, "riser_delta_min": 0.2},
                                  "spec": {"type": "pid"}, "front": [0, 1, 2], "complete": 3}},
            "verify": {"A": {"seeds": [7], "kpis": {"offset_max": 52.0, "thrust_energy": 15.6 * mwh},
                             "per_seed": {"7": {"offset_max": 52.0, "thrust_energy": 15.6 * mwh}}}}}
    (d / "tuning.json").write_text(json.dumps(info))
    _, md_path = write_tuning_report(d)
    md = md_path.read_text()
    assert "**A over B: does not cover.** For 33 % of B's 3 front designs" in md   # only B's 49.9 m / 16 MWh
    why = md[md.index("*Where B is better than A, and why:*"):].split("\n")[0]
    assert "B reaches offset_max 40 m (1 design), closer than any design of A came (its least offset_max is 45 m)" in why
    assert "B runs on 8.00 MWh at offset_max 70 m (1 design), less than any trial of A spent: A's cheapest trial " \
           "spent 12.00 MWh at 55 m" in why
    assert "outside the 50 m safe circle for 3500 s" in why
    assert "**B over A: does not cover.** For 0 % of A's 3 front designs" in md
    assert ("at offset_max 45 m to 55 m (3 designs) B's front reaches the offset_max but spends more thrust_energy "
            "(7–50 % more); A's designs there leave the turret outside the 50 m safe circle for up to 300 s") in md
    assert "no trial kept it at 2 or above: the best reached 1.00 (trial 0, 45 m, 20.00 MWh)" in md   # A's riser
    assert "the cheapest trial keeping it at 2 or above spends 30.00 MWh at 40 m (trial 0)" in md      # B's riser
    assert "| A | offset_max | 50 m | 52 m | +4.0 % | seed 7: 52 m |" in md


def test_a_new_run_starts_from_the_registry_default(tmp_path, capsys):
    """Trial 0 of a new run is the kind's registry default (so no front is worse than the
    hand-picked design), with the KPIs the default controller gives on the same case; a range
    narrowed past the default, or start_from_defaults = false, starts from the sampler instead."""
    import csv

    import optuna

    from tapm_opt.design.registry import kind

    p = _study(tmp_path, trials=2)
    out = tmp_path / "tune"
    assert main(["tune", str(p), "--out", str(out), "--workers", "0"]) == 0, capsys.readouterr().err
    t0 = optuna.load_study(study_name="t/PID", storage=f"sqlite:///{out / 'tuning.db'}").trials[0]
    d = kind("pid").options()
    assert t0.user_attrs.get("origin") == "registry default"
    assert [t0.params[f"periods[{i}]"] for i in range(3)] == list(d.periods)
    assert t0.params["capacity_fraction"] == d.capacity_fraction
    plain = tmp_path / "plain.toml"
    plain.write_text(STUDY.format(trials=2, duration=40.0, extra="").split("tune =")[0].replace("[tuning]", ""))
    assert main(["study", "run", str(plain), "--out", str(tmp_path / "plain"), "--workers", "0", "--no-progress"]) == 0
    row = next(csv.DictReader(open(tmp_path / "plain" / "kpis.csv")))
    assert t0.user_attrs["kpis"]["offset_max"] == pytest.approx(float(row["offset_max"]), rel=1e-12)
    assert t0.user_attrs["kpis"]["thrust_energy"] == pytest.approx(float(row["thrust_energy"]), rel=1e-12)
    for extra, name in (("", "narrow"), ("start_from_defaults = false", "off")):
        q = tmp_path / f"{name}.toml"
        text = STUDY.format(trials=1, duration=40.0, extra=extra)
        if name == "narrow":
            text = text.replace("periods = [150.0, 400.0]", "periods = [300.0, 400.0]")   # 250 s is outside
        q.write_text(text)
        assert main(["tune", str(q), "--out", str(tmp_path / name), "--workers", "0"]) == 0
        t = optuna.load_study(study_name="t/PID", storage=f"sqlite:///{tmp_path / name / 'tuning.db'}").trials[0]
        assert "origin" not in t.user_attrs, name
    with pytest.raises(TuningError, match="start_from_defaults = 'yes' must be true or false"):
        tuning_settings({"start_from_defaults": "yes"})


@pytest.mark.slow
def test_the_default_trial_runs_once_before_parallel_workers(tmp_path, capsys):
    """With two worker processes the default design is run once, before they start (two workers
    asking at once could both take the one waiting trial, and the second could not report it)."""
    import optuna

    p = _study(tmp_path, trials=3, duration=20.0)
    out = tmp_path / "tune"
    assert main(["tune", str(p), "--out", str(out), "--workers", "2"]) == 0, capsys.readouterr().err
    trials = optuna.load_study(study_name="t/PID", storage=f"sqlite:///{out / 'tuning.db'}").trials
    done = [t for t in trials if t.state.name == "COMPLETE"]
    assert len(done) == 3 and sum(t.user_attrs.get("origin") == "registry default" for t in trials) == 1
    assert trials[0].user_attrs.get("origin") == "registry default" and trials[0].state.name == "COMPLETE"
    assert len({json.dumps(t.params, sort_keys=True) for t in done}) == 3


def _open_storage(url, q):   # a process pool's target: module level
    import warnings

    from tapm_opt.studies.tuning import _storage

    warnings.filterwarnings("ignore")
    try:
        _storage(url)
        q.put("ok")
    except Exception as exc:  # noqa: BLE001 - reported to the test
        q.put(f"{type(exc).__name__}: {exc}")


def test_processes_opening_a_new_storage_at_once_all_open_it(tmp_path):
    """A second run joining, or a poller, may create a new SQLite storage's tables at the same
    moment as the first run: each of them opens it (one used to fail with 'UNIQUE constraint
    failed: alembic_version' or 'table ... already exists')."""
    import multiprocessing

    ctx = multiprocessing.get_context("spawn")
    results = []
    for k in range(4):
        url = f"sqlite:///{tmp_path / f's{k}.db'}"
        q = ctx.Queue()
        procs = [ctx.Process(target=_open_storage, args=(url, q)) for _ in range(3)]
        for p in procs:
            p.start()
        for p in procs:
            p.join(120)
        results += [q.get(timeout=10) for _ in procs]
    assert results == ["ok"] * len(results), results
