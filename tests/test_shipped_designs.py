"""The controller designs shipped for fpso: what ``tapm compare`` runs, and that they still give the
KPIs their tuning recorded (a plant change that moves them fails here until the tuning is rerun)."""

from __future__ import annotations

import csv
import json
import tomllib

import pytest

from tapm_opt.cli import main
from tapm_opt.design.registry import load_design
from tapm_opt.studies.shipped import SHIPPED_DIR, DesignChoiceError, compare_designs, shipped_designs

NAMES = ["PID", "MPC", "NMPC"]


def run(capsys, *args: str):
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_fpso_ships_a_design_per_controller_of_the_default_study():
    found = shipped_designs("fpso")
    assert sorted(found) == sorted(NAMES)
    kinds = {n: load_design(p)["type"] for n, p in found.items()}
    assert kinds == {"PID": "pid", "MPC": "lmpc", "NMPC": "mpc"}
    for p in found.values():
        text = p.read_text()
        assert "#   tapm tune studies/mpc_vs_pid.toml --out runs/tune_fpso --trials 60" in text   # how to redo it
        assert "# A controller design tuned by optimisation: tapm tune mpc_vs_pid.toml --out " in text
        d = tomllib.loads(text)["design"]
        assert d["study"] == "mpc_vs_pid" and {"offset_max", "thrust_energy", "time_outside_safe"} <= set(d["kpis"])
    assert shipped_designs("aamo4") == {}


def test_compare_design_choices(tmp_path):
    found, note = compare_designs("shipped", "fpso", NAMES)
    assert sorted(found) == sorted(NAMES) and "designs tuned for fpso shipped in the package" in note
    assert compare_designs("defaults", "fpso", NAMES) == ({}, "controllers at the registry's default tunings "
                                                              "(--designs defaults)")
    found, note = compare_designs("shipped", "aamo4", NAMES)
    assert found == {} and "no designs tuned for scenario 'aamo4' are shipped" in note
    run_dir = tmp_path / "tune"
    (run_dir / "tuned").mkdir(parents=True)
    (run_dir / "tuned" / "PID.toml").write_text((SHIPPED_DIR / "fpso" / "PID.toml").read_text())
    found, note = compare_designs(str(run_dir), "fpso", NAMES)
    assert list(found) == ["PID"] and "MPC, NMPC at the registry's default tuning" in note
    with pytest.raises(DesignChoiceError, match="must be 'shipped', 'defaults' or the directory of a tapm tune run"):
        compare_designs(str(tmp_path / "nowhere"), "fpso", NAMES)
    (tmp_path / "empty" / "tuned").mkdir(parents=True)
    with pytest.raises(DesignChoiceError, match="tuned/ holds no design for PID, MPC, NMPC"):
        compare_designs(str(tmp_path / "empty"), "fpso", NAMES)


def test_compare_runs_the_shipped_designs_and_says_so(capsys, tmp_path):
    out = tmp_path / "cmp"
    code, stdout, err = run(capsys, "compare", "--duration", "30", "--workers", "0", "--out", str(out))
    assert code == 0, err
    assert "controllers at the designs tuned for fpso shipped in the package (PID: PID.toml" in stdout
    cases = json.loads((out / "study.json").read_text())["cases"]
    by_name = {c["labels"]["controller"]: c["inputs"]["controller"] for c in cases}
    for name, path in shipped_designs("fpso").items():
        assert by_name[name] == load_design(path), name
    code, stdout, err = run(capsys, "compare", "--duration", "30", "--workers", "0", "--designs", "defaults",
                            "--out", str(tmp_path / "defaults"))
    assert code == 0, err and "registry's default tunings" in stdout
    cases = json.loads((tmp_path / "defaults" / "study.json").read_text())["cases"]
    assert {c["labels"]["controller"]: c["inputs"]["controller"]["type"] for c in cases} == \
        {"PID": "pid", "MPC": "lmpc", "NMPC": "mpc"}
    assert all(set(c["inputs"]["controller"]) == {"type"} for c in cases)


def test_compare_bad_designs_choice_is_named(capsys, tmp_path):
    code, _, err = run(capsys, "compare", "--designs", str(tmp_path / "nope"), "--out", str(tmp_path / "x"))
    assert code == 2 and "--designs" in err and "must be 'shipped', 'defaults'" in err
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
def test_shipped_designs_reproduce_their_tuning_kpis_on_the_main_job(capsys, tmp_path):
    """The main job (fpso storm, line 1 breaking half-way, seed 1, 10 segments, one hour) is the
    tuning's case: each shipped design gives the KPIs its file records. When the plant changes,
    this fails until the designs are tuned again (``tapm tune studies/mpc_vs_pid.toml``)."""
    out = tmp_path / "cmp"
    code, _, err = run(capsys, "compare", "--workers", "0", "--out", str(out))
    assert code == 0, err
    rows = {r["controller"]: r for r in csv.DictReader(open(out / "kpis.csv", newline=""))}
    for name, path in shipped_designs("fpso").items():
        kp = tomllib.loads(path.read_text())["design"]["kpis"]
        for k in ("offset_max", "thrust_energy", "time_outside_safe"):
            assert float(rows[name][k]) == pytest.approx(kp[k], rel=2e-3, abs=1.0 if k == "time_outside_safe" else 0), \
                (name, k)
