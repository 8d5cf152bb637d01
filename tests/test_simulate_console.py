"""tapm simulate says what happened: each line break and thruster failure on the console with its
time, the number of lines broken, and summary.json with its stable keys."""

from __future__ import annotations

import json

import tapm_opt
from tapm_opt.cli import main
from tapm_opt.config import scenario_to_dict


def _write(tmp_path, name: str, faults: list[dict]) -> str:
    """fpso renamed, with ``faults``, as a scenario file."""
    from tapm_opt.config import scenario_from_dict
    from tapm_opt.config.moordyn import scenario_toml

    d = scenario_to_dict(tapm_opt.load_scenario("fpso"))
    d["meta"]["name"] = name
    d["faults"] = faults
    path = tmp_path / "sc.toml"
    path.write_text(scenario_toml(scenario_to_dict(scenario_from_dict(d))))
    return str(path)


def test_simulate_prints_breaks_and_failures_with_their_time(tmp_path, capsys):
    sc = _write(tmp_path, "fpso\x1b[31m red", [{"kind": "line_break", "time": 5.0, "line": "1"},
                                               {"kind": "thruster_failure", "time": 7.0, "thruster": "A1"}])
    code = main(["simulate", sc, "--controller", "pid", "--duration", "12", "--sea-state", "normal",
                 "--segments", "4", "--out", str(tmp_path / "run")])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert "t = 5.0 s: line 1 broke" in out.out
    assert "t = 7.0 s: thruster A1 failed" in out.out
    assert "1 line broken" in out.out
    assert "\x1b" not in out.out and "\\x1b[31m red" in out.out   # the name's escape shown, not obeyed
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    for key in ("kpis", "diagnostics", "events", "wall_time", "settle", "sea_state", "seed", "controller"):
        assert key in summary
    for key in ("offset_max", "time_outside_safe", "thrust_energy", "utilisation_max", "util_max", "lines_broken"):
        assert key in summary["kpis"]
    assert summary["kpis"]["lines_broken"] == 1
    assert [e[1] for e in summary["events"]] == ["line 1 broke", "thruster A1 failed"]
