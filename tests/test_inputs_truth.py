"""Every run tells the truth about its input: input that used to be accepted silently, or refused
later with a misleading message, is now either a typed error naming the field, the value and what
is allowed, or accepted with a statement of what happens (a warning of ``tapm scenario validate``).
"""

from __future__ import annotations

import copy
import functools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import tapm_opt.cli  # noqa: F401 - registers the commands
from tapm_opt.cli._common import cli
from tapm_opt.config import load_scenario, scenario_from_dict, scenario_to_dict
from tapm_opt.errors import ScenarioError
from tapm_opt.studies.spec import _to_toml


@functools.lru_cache(maxsize=None)
def _builtin(name: str) -> dict:
    return scenario_to_dict(load_scenario(name))


def base(name: str) -> dict:
    return copy.deepcopy(_builtin(name))


def write(tmp_path: Path, d: dict, name: str = "s.toml") -> Path:
    p = tmp_path / name
    p.write_text(_to_toml(d), encoding="utf-8")
    return p


def issues_of(d: dict) -> list:
    with pytest.raises(ScenarioError) as exc:
        scenario_from_dict(d)
    return list(exc.value.issues)


def validate_cli(*paths) -> tuple[int, str]:
    res = CliRunner().invoke(cli, ["scenario", "validate", *map(str, paths)])
    return res.exit_code, res.output


def engineering(d: dict):
    from tapm_opt.models.sanity import engineering_issues

    return engineering_issues(scenario_from_dict(d))


def no_winch(line: dict) -> dict:
    for k in ("min_length", "max_length", "winch_max_rate"):
        line.pop(k, None)
    return line


# ------------------------------------------------------------------------------------------
# 1. a line whose anchor lies straight under its fairlead
# ------------------------------------------------------------------------------------------


def test_line_straight_under_its_fairlead_is_refused_by_validate(tmp_path):
    d = base("fpso")
    d["lines"][0]["anchor"] = [91.44, 0.0, 1000.0]  # under the centre of turret: 8 m from its fairlead
    found = engineering(d)
    err = [i for i in found if i.severity == "error"]
    assert [i.path for i in err] == ["lines[0].anchor"]
    assert "straight under" in err[0].message and "8 m" in err[0].message
    code, out = validate_cli(write(tmp_path, d))
    assert code == 1 and "INVALID" in out and "lines[0].anchor" in out


def test_unbalanced_mooring_is_a_warning():
    d = base("fpso_equivalent")   # homogeneous lines: line 1 moved and shortened as one line type
    d["lines"][0]["anchor"] = [-80.0, 0.0, 1000.0]
    d["lines"][0]["length"] = 1100.0
    no_winch(d["lines"][0])
    found = engineering(d)
    assert [(i.path, i.severity) for i in found] == [("lines", "warning")]
    assert "does not balance at the field zero point" in found[0].message


# ------------------------------------------------------------------------------------------
# 2. faults that break every line
# ------------------------------------------------------------------------------------------


def test_faults_breaking_every_line_are_refused_by_validation(tmp_path):
    d = base("aamo4")
    d["faults"] = [{"kind": "line_break", "time": 100.0 * (k + 1), "line": ln["id"]} for k, ln in enumerate(d["lines"])]
    iss = issues_of(d)
    assert [i.path for i in iss] == ["faults[3].line"]
    assert "breaks the last intact line" in iss[0].message and "'4'" in iss[0].message
    code, out = validate_cli(write(tmp_path, d))
    assert code == 1 and "faults[3].line" in out


# ------------------------------------------------------------------------------------------
# 3. pretension against MBS
# ------------------------------------------------------------------------------------------


def test_pretension_at_or_above_mbs_is_an_error(tmp_path):
    d = base("fpso")
    d["line_types"][0]["MBS"] = 3.24e6  # the pretension is 3.27 MN: 101 % MBS at rest
    found = engineering(d)
    assert all(i.severity == "error" for i in found) and len(found) == 12
    assert found[0].path == "lines[0].length" and "101 %" in found[0].message and "breaks at rest" in found[0].message
    code, out = validate_cli(write(tmp_path, d))
    assert code == 1 and "INVALID (12 problems)" in out


def test_pretension_above_the_tension_utilisation_is_a_warning(tmp_path):
    d = base("fpso")
    d["line_types"][0]["MBS"] = 4.3e6  # 76 % MBS at rest, above limits.tension_utilisation 59.9 %
    found = engineering(d)
    assert {i.severity for i in found} == {"warning"} and len(found) == 12
    # fpso's 3.270 MN pretension over the chain's 4.3 MN: 76.0 % (the equivalent line's 3.273 MN: 76.1 %)
    assert "76 % of the MBS" in found[0].message and "tension_utilisation" in found[0].message
    code, out = validate_cli(write(tmp_path, d))
    assert code == 0 and "12 warnings" in out and "warning: lines[0].length" in out


@pytest.mark.parametrize("name", ["fpso", "aamo4", "ren8"])
def test_builtins_have_no_engineering_findings(name):
    from tapm_opt.models.sanity import engineering_issues

    assert engineering_issues(load_scenario(name)) == []
    code, out = validate_cli(name)
    assert code == 0 and "warning" not in out


# ------------------------------------------------------------------------------------------
# 4. unit slips
# ------------------------------------------------------------------------------------------


def test_fairleads_far_above_the_water_are_an_error():
    d = base("aamo4")
    d["turret"]["fairlead_depth"] = -500.0
    for ln in d["lines"]:
        ln["length"] = 2700.0
        no_winch(ln)
    iss = issues_of(d)
    assert [i.path for i in iss] == ["turret.fairlead_depth"]
    assert "500 m above the water line" in iss[0].message and "30 m" in iss[0].message


def test_fairleads_a_little_above_the_water_are_a_warning():
    d = base("aamo4")
    d["turret"]["fairlead_depth"] = -5.0
    found = engineering(d)
    assert [(i.path, i.severity) for i in found] == [("turret.fairlead_depth", "warning")]


def test_thrust_in_kN_is_an_error():
    d = base("fpso")
    for t in d["thrusters"]:
        t["max_thrust"] /= 1000.0
        t["max_thrust_rate"] /= 1000.0
        if t.get("max_reverse_thrust"):
            t["max_reverse_thrust"] /= 1000.0
    iss = issues_of(d)
    assert len(iss) == 1 and re.fullmatch(r"thrusters\[\d\]\.max_thrust", iss[0].path)
    assert "not kN" in iss[0].message and "7200 N" in iss[0].message


def test_water_depth_in_feet_is_an_error():
    d = base("aamo4")
    d["environment"]["water_depth"] = 1000.0 / 0.3048
    iss = issues_of(d)
    assert [i.path for i in iss] == ["environment.water_depth"]
    assert "3280.84" in iss[0].message and "in feet" in iss[0].message


def test_one_anchor_far_above_the_seabed_is_a_warning():
    d = base("aamo4")
    d["lines"][0]["anchor"][2] = 400.0  # 600 m above the seabed
    found = engineering(d)
    assert ("lines[0].anchor[2]", "warning") in [(i.path, i.severity) for i in found]


# ------------------------------------------------------------------------------------------
# 5. a line broken twice, empty ids
# ------------------------------------------------------------------------------------------


def test_the_same_line_broken_twice_is_refused():
    d = base("fpso")
    d["faults"] = [{"kind": "line_break", "time": 100.0, "line": "1"},
                   {"kind": "line_break", "time": 200.0, "line": "1"}]
    iss = issues_of(d)
    assert [i.path for i in iss] == ["faults[1].line"]
    assert "faults[0] already breaks line '1'" in iss[0].message


def test_the_same_thruster_failed_twice_is_refused():
    d = base("fpso")
    tid = d["thrusters"][0]["id"]
    d["faults"] = [{"kind": "thruster_failure", "time": 10.0, "thruster": tid},
                   {"kind": "thruster_failure", "time": 20.0, "thruster": tid}]
    assert [i.path for i in issues_of(d)] == ["faults[1].thruster"]


@pytest.mark.parametrize("where", ["lines[0].id", "line_types[0].id", "thrusters[0].id", "sea_states[0].id"])
def test_an_empty_id_is_refused(where):
    d = base("fpso")
    sect, idx = re.match(r"(\w+)\[(\d)\]", where).groups()
    d[sect][int(idx)]["id"] = "  "
    iss = issues_of(d)
    assert iss[0].path == where and "must not be empty" in iss[0].message


# ------------------------------------------------------------------------------------------
# 6. control characters in names reach the terminal escaped
# ------------------------------------------------------------------------------------------


def test_terminal_text_escapes_control_characters():
    from tapm_opt._io import terminal_text as exported
    from tapm_opt._text import terminal_text

    assert exported is terminal_text
    assert terminal_text("evil\n\x1b[31mred\x1b[0m") == "evil\\n\\x1b[31mred\\x1b[0m"
    assert terminal_text("a\u202eb\tc\x7f") == "a\\u202eb\\tc\\x7f"
    assert terminal_text("plain C:\\path, 75 % MBS — ok") == "plain C:\\path, 75 % MBS — ok"
    assert terminal_text("x" * 50, limit=10) == "x" * 10 + "... (50 characters)"


def test_scenario_name_and_description_are_printed_escaped(tmp_path):
    d = base("fpso")
    d["meta"]["name"] = "evil\n\x1b[31mRED\x1b[0m"
    d["meta"]["description"] = "clear\x1b[2Jscreen"
    p = write(tmp_path, d)
    code, out = validate_cli(p)
    assert code == 0 and "\x1b" not in out and "evil\\n\\x1b[31mRED" in out
    assert len(out.strip().splitlines()) == 1
    res = CliRunner().invoke(cli, ["scenario", "show", str(p)])
    assert res.exit_code == 0, res.output
    assert "\x1b" not in res.output and res.output.startswith("Scenario evil\\n\\x1b[31mRED\\x1b[0m: clear\\x1b[2Jscreen\n")


# ------------------------------------------------------------------------------------------
# 7. a UTF-8 byte-order mark
# ------------------------------------------------------------------------------------------


def test_a_utf8_bom_is_accepted(tmp_path):
    from tapm_opt.config import BUILTIN_DIR

    p = tmp_path / "bom.toml"
    p.write_bytes(b"\xef\xbb\xbf" + (BUILTIN_DIR / "aamo4.toml").read_bytes())
    assert load_scenario(p) == load_scenario("aamo4")


# ------------------------------------------------------------------------------------------
# 8. free-text lengths
# ------------------------------------------------------------------------------------------


def test_a_huge_description_is_an_error_naming_the_limit(tmp_path):
    d = base("aamo4")
    d["meta"]["description"] = "x" * 5_000_000
    iss = issues_of(d)
    assert [i.path for i in iss] == ["meta.description"]
    assert "5000000 characters" in iss[0].message and "10000" in iss[0].message
    assert len(str(iss[0])) < 200  # the value itself is not repeated
    code, out = validate_cli(write(tmp_path, d))
    assert code == 1 and len(out) < 500


@pytest.mark.parametrize("where, n", [("meta.name", 201), ("lines[0].id", 201), ("meta.sources[0]", 1001)])
def test_long_names_ids_and_sources_are_errors(where, n):
    d = base("aamo4")
    if where == "meta.name":
        d["meta"]["name"] = "n" * n
    elif where == "lines[0].id":
        d["lines"][0]["id"] = "n" * n
    else:
        d["meta"]["sources"] = ["s" * n]
    iss = issues_of(d)
    assert iss[0].path == where and f"{n} characters" in iss[0].message


def test_text_limits_hold_for_a_scenario_built_in_code():
    import dataclasses

    from tapm_opt.config import validate

    sc = load_scenario("aamo4")
    bad = dataclasses.replace(sc, meta=dataclasses.replace(sc.meta, description="d" * 20_000))
    assert [i.path for i in validate(bad)] == ["meta.description"]


# ------------------------------------------------------------------------------------------
# 9. MoorDyn round trip and options
# ------------------------------------------------------------------------------------------


def test_moordyn_round_trip_keeps_max_strain(tmp_path):
    from tapm_opt.config.moordyn import export_moordyn
    from tapm_opt.models.moordyn_import import import_moordyn

    sc = load_scenario("ren8")
    assert sc.line_types[0].max_strain == 0.005
    export_moordyn(sc, tmp_path / "ren8.dat")
    res = import_moordyn(tmp_path / "ren8.dat", "ren8", mbs={"cable": sc.line_types[0].MBS})
    assert res.scenario.line_types[0].max_strain == 0.005
    assert any("max_strain 0.005" in n for n in res.notes)


def _with_options(tmp_path, extra: str) -> Path:
    from tapm_opt.config.moordyn import export_moordyn

    p = tmp_path / "aamo4.dat"
    export_moordyn(load_scenario("aamo4"), p)
    text = p.read_text().replace("  tScheme  time integration scheme\n", "  tScheme  time integration scheme\n" + extra)
    p.write_text(text)
    return p


def test_moordyn_unknown_options_are_reported(tmp_path):
    from tapm_opt.models.moordyn_import import import_moordyn

    p = _with_options(tmp_path, "0.5  FooBar\n1  writeLogg\n7\n")
    notes = import_moordyn(p, "aamo4", mbs={"cable": 5e6}).notes
    assert any("option FooBar = 0.5" in n and "not a MoorDyn option" in n for n in notes)
    assert any("writeLogg" in n and "did you mean writeLog?" in n for n in notes)
    assert any("'7'" in n and "no option name" in n for n in notes)


def test_moordyn_non_numeric_known_option_is_an_error(tmp_path):
    from tapm_opt.config.moordyn import MoorDynError
    from tapm_opt.models.moordyn_import import import_moordyn

    p = _with_options(tmp_path, "abc  CdScaleIC\n")
    with pytest.raises(MoorDynError, match=r"option CdScaleIC = 'abc' must be a finite number"):
        import_moordyn(p, "aamo4", mbs={"cable": 5e6})


# ------------------------------------------------------------------------------------------
# 10. no usable thrust
# ------------------------------------------------------------------------------------------


def test_no_thrusters_is_a_warning(tmp_path):
    d = base("aamo4")
    d.pop("thrusters")
    found = engineering(d)
    assert [(i.path, i.severity) for i in found] == [("thrusters", "warning")]
    assert "no thrust capacity" in found[0].message
    code, out = validate_cli(write(tmp_path, d))
    assert code == 0 and "warning: thrusters" in out


def test_thrusters_forbidden_almost_everywhere_are_a_warning():
    d = base("aamo4")
    d["thrusters"] = [t for t in d["thrusters"] if t["kind"] == "azimuth"]
    for t in d["thrusters"]:
        t["forbidden_sectors_deg"] = [[0.05, 359.95]]
    found = engineering(d)
    assert [(i.path, i.severity) for i in found] == [("thrusters", "warning")]
    assert "no usable thrust capacity in surge (X), sway (Y), yaw (N)" in found[0].message
    assert "thrusters[0].forbidden_sectors_deg" in found[0].message


# ------------------------------------------------------------------------------------------
# 11. settling advice a user can follow
# ------------------------------------------------------------------------------------------


def test_settling_that_creeps_names_what_the_user_can_change():
    from tapm_opt.plant.environment import Environment
    from tapm_opt.plant.mooring_fem import MooringFEM, SettlingNotConverged

    sc = load_scenario("aamo4")
    env = Environment(sc, sc.sea_states[0], seed=1)
    m = MooringFEM(sc, segments=10, current=env.current_at)
    m.initialise(np.zeros(3))
    with pytest.raises(SettlingNotConverged) as exc:
        m.settle(np.zeros(3), max_time=20.0)
    msg = str(exc.value)
    assert "still creeping" in msg and "--sea-state" in msg and "current_speed" in msg
    assert "safety factor" not in msg
    assert math.isfinite(exc.value.info.max_speed)
