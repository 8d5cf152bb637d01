"""The ``tapm`` command as a user runs it: outputs, exit codes, and messages for mistakes."""

from __future__ import annotations

import csv
import subprocess
import sys

import numpy as np
import pytest

import tapm_opt
from tapm_opt.cli import main
from tapm_opt.config import BUILTIN_DIR, builtin_scenarios
from tapm_opt.models import MooringModel, catenary


def run(capsys, *args: str):
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


def read_csv(path):
    with open(path) as fh:
        rows = [r for r in csv.reader(line for line in fh if not line.startswith("#"))]
    return rows[0], rows[1:]


def test_scenario_list_names_every_builtin(capsys):
    code, out, _ = run(capsys, "scenario", "list")
    assert code == 0
    for name in builtin_scenarios():
        assert name in out


def test_scenario_show_reports_catenary_pretension(capsys):
    code, out, _ = run(capsys, "scenario", "show", "aamo4")
    assert code == 0
    sc = tapm_opt.load_scenario("aamo4")
    T = MooringModel.from_scenario(sc).tensions(np.zeros(3))
    assert f"{T[0] / 1e3:9.1f}".strip() in out
    assert "suspended" in out or "touchdown" in out


def test_validate_good_file_exits_zero(capsys):
    code, out, _ = run(capsys, "scenario", "validate", str(BUILTIN_DIR / "aamo4.toml"))
    assert code == 0
    assert "OK" in out


def test_validate_reports_all_problems_with_paths_and_exits_one(capsys, tmp_path):
    text = (BUILTIN_DIR / "aamo4.toml").read_text()
    text = text.replace("water_depth = 1000.0", "water_depth = -5.0").replace("EA = 230.0e6", 'EA = "stiff"')
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    code, out, err = run(capsys, "scenario", "validate", str(bad))
    assert code == 1
    assert "environment.water_depth = -5 m must be > 0" in out
    assert "line_types[0].EA: must be a number" in out
    assert "Traceback" not in out + err


def test_missing_scenario_is_one_line_error(capsys):
    code, out, err = run(capsys, "lines", "no_such_scenario")
    assert code == 2
    assert err.startswith("error: ") and "no_such_scenario" in err
    assert "Traceback" not in err and err.count("\n") == 1


def test_lines_writes_consistent_tables(capsys, tmp_path):
    out_csv = tmp_path / "a.csv"
    code, out, _ = run(capsys, "lines", "aamo4", "--out", str(out_csv), "--points", "5", "--range", "50")
    assert code == 0
    sc = tapm_opt.load_scenario("aamo4")
    model = MooringModel.from_scenario(sc)
    header, rows = read_csv(out_csv)
    assert header == ["line", "XF_m", "H_N", "V_N", "T_N", "regime"]
    assert len(rows) == 4 * 5
    XF = np.array([float(r[1]) for r in rows])
    H = np.array([float(r[2]) for r in rows])
    sol = catenary.solve(XF, model.ZF[0], model.L[0], model.EA[0], model.w[0])
    np.testing.assert_allclose(H, sol.HF, rtol=1e-12)
    header, rows = read_csv(tmp_path / "a_stiffness.csv")
    K = np.array([[float(x) for x in r[1:]] for r in rows])
    np.testing.assert_allclose(K, model.stiffness(np.zeros(3)), rtol=1e-12, atol=1e-9)
    header, rows = read_csv(tmp_path / "a_offsets.csv")
    first = [float(x) for x in rows[0]]
    assert first[1] == 0.0 and abs(first[2]) < 1e-6  # no load at the field zero point
    # an offset to the north is restored southward
    north = [r for r in rows if float(r[0]) == 0.0 and float(r[1]) > 0]
    assert all(float(r[2]) < 0 for r in north)


def test_lines_bad_option_writes_nothing(capsys, tmp_path):
    out_csv = tmp_path / "x.csv"
    code, _, err = run(capsys, "lines", "aamo4", "--out", str(out_csv), "--range", "-3")
    assert code == 2
    assert "--range" in err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("cmd", [[], ["scenario"], ["scenario", "validate"], ["lines"]])
def test_help_everywhere(cmd):
    res = subprocess.run([sys.executable, "-m", "tapm_opt", *cmd, "--help"], capture_output=True, text=True)
    assert res.returncode == 0
    assert "Usage:" in res.stdout


def test_gains_writes_tables_that_load_back(capsys, tmp_path):
    from tapm_opt.design.gains import load_gain_table

    code, out, err = run(capsys, "gains", "fpso", "--out", str(tmp_path), "--sea-states", "calm",
                         "--broken", "none", "--headings", "0")
    assert code == 0, err
    table = load_gain_table(tmp_path / "gains.json")
    assert len(table.rows) == 1 and table.rows[0].pid.stable
    assert (tmp_path / "gains.csv").exists() and (tmp_path / "gains.md").exists()
    code, _, err = run(capsys, "gains", "fpso", "--out", str(tmp_path / "x"), "--headings", "north")
    assert code == 2 and "--headings" in err


def test_simulate_offers_every_setpoint_kind_the_closed_loop_has():
    """``tapm simulate --setpoint`` lists the kinds itself (the CLI does not import the closed loop
    to start): the list must be the closed loop's ``SETPOINT_KINDS``, so a kind added there is
    added here too."""
    import click

    from tapm_opt.cli.simulate import simulate
    from tapm_opt.studies.closed_loop import SETPOINT_KINDS

    opt = next(p for p in simulate.params if p.name == "setpoint")
    assert isinstance(opt.type, click.Choice) and tuple(opt.type.choices) == SETPOINT_KINDS
