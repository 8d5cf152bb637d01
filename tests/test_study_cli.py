"""``tapm study run`` and ``tapm compare`` as a user runs them: exit status, messages, sea states."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from tapm_opt.cli import _compare_sea_state, main
from tapm_opt.config import load_scenario
from tapm_opt.studies.study import load_study

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "studies" / "tiny.toml"


def run(capsys, *args: str):
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


# -- tapm compare on scenarios without a 'storm' ------------------------------------------------


@pytest.mark.parametrize("scenario, sea_state, which", [
    ("aamo4", "tidal", "its most severe sea state (largest Hs)"),   # tidal and tidal_rotating, both Hs 0
    ("ren8", "table3_vv9", "its most severe sea state (largest Hs)"),   # Hs 6.9 m against 1.9 m
])
def test_compare_without_storm_uses_the_most_severe_sea_state(capsys, tmp_path, scenario, sea_state, which):
    out = tmp_path / "cmp"
    code, stdout, err = run(capsys, "compare", scenario, "--duration", "40", "--workers", "0", "--out", str(out))
    assert code == 0, err
    assert f"scenario {scenario} has no sea state 'storm': using {which}, '{sea_state}'" in stdout
    rows = list(csv.DictReader(open(out / "kpis.csv", newline="")))
    assert sorted(r["controller"] for r in rows) == ["MPC", "NMPC", "PID"]
    assert {(r["scenario"], r["sea_state"], r["condition"]) for r in rows} == {(scenario, sea_state,
                                                                                "line 1 broken at 20 s")}
    assert all(float(r["offset_max"]) > 0 for r in rows)
    desc = json.loads((out / "study.json").read_text())["description"]
    assert f"on {scenario} in sea state {sea_state}" in desc and "line 1 breaks at 20 s" in desc, desc
    assert (out / "report.html").is_file() and f"report: {out / 'report.html'}" in stdout
    assert stdout.count(f", {sea_state}, line 1 broken at 20 s") == 3   # the headline rows


def test_compare_sea_state_choice():
    fpso = load_scenario("fpso")
    assert _compare_sea_state(fpso, None) == ("storm", None)
    assert _compare_sea_state(fpso, "calm") == ("calm", None)
    sid, note = _compare_sea_state(load_scenario("ren8"), None)
    assert sid == "table3_vv9" and "Hs 6.9 m" in note


def test_compare_unknown_sea_state_names_the_choices(capsys, tmp_path):
    code, _, err = run(capsys, "compare", "ren8", "--sea-state", "storm", "--out", str(tmp_path / "x"))
    assert code == 2 and "--sea-state" in err and "'storm' is not a sea state of scenario 'ren8'" in err
    assert "table3_vv3, table3_vv9" in err
    assert not (tmp_path / "x").exists()


# -- tapm study run: exit status ----------------------------------------------------------------


def test_study_run_exits_1_and_counts_failed_cases(capsys, tmp_path):
    out = tmp_path / "run"
    a, b = load_study(TINY).cases
    (out / "cases" / a.id / "result.npz").mkdir(parents=True)   # the result of case a cannot be written
    code, stdout, err = run(capsys, "study", "run", str(TINY), "--out", str(out), "--workers", "0", "--no-progress")
    assert code == 1
    assert "1 finished, 1 failed, 0 already done" in stdout
    assert "error: 1 of 2 cases failed" in err and f"case {a.id}: IsADirectoryError" in err, err
    assert (out / "cases" / a.id / "error.json").is_file()

    (out / "cases" / a.id / "result.npz").rmdir()   # fixed: the re-run runs only the failed case
    code, stdout, err = run(capsys, "study", "run", str(TINY), "--out", str(out), "--workers", "0", "--no-progress")
    assert code == 0 and "1 finished, 0 failed, 1 already done" in stdout and "error" not in err


@pytest.mark.parametrize("args, message", [
    (["study", "run", "{tmp}/none.toml", "--out", "{tmp}/o"], "no study file"),
    (["study", "run", "{tmp}/bad.toml", "--out", "{tmp}/o"], "bad.toml is not valid TOML"),
    (["study", "run", "{tmp}", "--out", "{tmp}/o"], "is a directory"),
    (["study", "run", "{tiny}", "--out", "{tmp}/bad.toml"], "is a file"),
    (["study", "run", "{tiny}", "--out", "{tmp}/bad.toml/o"], "cannot create the study directory"),
    (["study", "run", "{tiny}", "--out", "{tmp}/o", "--workers", "-2"], "'--workers': -2 is not in the range"),
    (["study", "run", "{tiny}", "--out", "{tmp}/o", "--workers", "two"], "'--workers': 'two' is not a valid integer"),
    (["compare", "--out", "{tmp}/o", "--duration", "-5"], "--duration = -5.0 must be a positive number"),
    (["compare", "nowhere", "--out", "{tmp}/o"], "nowhere"),
])
def test_study_commands_bad_input_is_one_message(capsys, tmp_path, args, message):
    (tmp_path / "bad.toml").write_text("[study\n")
    args = [a.format(tmp=tmp_path, tiny=TINY) for a in args]
    code, _, err = run(capsys, *args)
    assert code == 2 and message in err and "Traceback" not in err, err
    assert not (tmp_path / "o").exists()
