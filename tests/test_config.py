"""Tests of scenario loading and validation (tapm_opt.config): the built-in scenarios are valid,
immutable, round-trip through dicts and are physically sound (checked with the catenary); bad input
gives a ScenarioError naming the field path and the value; the field reference in
docs/scenarios.md follows the schema."""

from __future__ import annotations

import dataclasses
import functools
import math
import re
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, Literal, get_args, get_origin, get_type_hints

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import tapm_opt
from tapm_opt.config import (
    builtin_scenarios,
    load_scenario,
    scenario_from_dict,
    scenario_to_dict,
    schema,
)
from tapm_opt.config.loader import file_key
from tapm_opt.config.reference import BEGIN_MARKER, END_MARKER, SECTIONS, field_reference_markdown
from tapm_opt.errors import ScenarioError, ScenarioIssue
from tapm_opt.models.mooring import MooringModel

DOC = Path(__file__).resolve().parents[1] / "docs" / "scenarios.md"
EXPECTED_BUILTINS = {"aamo4", "fang12", "fpso", "fpso_deep", "fpso_equivalent", "ren8", "semi"}


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=None)
def builtin(name: str) -> schema.Scenario:
    return load_scenario(name)


def doc_example_text() -> str:
    blocks = re.findall(r"```toml\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)
    assert len(blocks) == 1, "docs/scenarios.md must hold exactly one ```toml block: the complete example"
    return blocks[0]


def base(name: str = "aamo4") -> dict:
    """A fresh, valid scenario dict (file keys, degrees) to corrupt."""
    if name == "doc_example":
        return tomllib.loads(doc_example_text())
    return scenario_to_dict(builtin(name))


def issues_of(data: dict) -> tuple[ScenarioIssue, ...]:
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data)
    return info.value.issues


def issue_at(issues: tuple[ScenarioIssue, ...], path: str) -> ScenarioIssue:
    found = [i for i in issues if i.path == path]
    assert found, f"no issue at {path!r}; issues: {[str(i) for i in issues]}"
    return found[0]


def assert_close(a: Any, b: Any, where: str = "scenario") -> None:
    """Recursive equality with a tolerance on floats (angles pass through degrees and back)."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            assert_close(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_close(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-12), \
            f"{where}: {a!r} != {b!r}"
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


# ------------------------------------------------------------------------------------------
# built-in scenarios: load, immutable, round trip
# ------------------------------------------------------------------------------------------


def test_builtin_names():
    assert set(builtin_scenarios()) == EXPECTED_BUILTINS


@pytest.mark.parametrize("name", sorted(EXPECTED_BUILTINS))
def test_builtin_loads_by_name_and_path(name):
    sc = tapm_opt.load_scenario(name)
    assert isinstance(sc, schema.Scenario)
    assert sc.name == name
    assert sc.lines and sc.sea_states and sc.limits.safe_radius is not None
    from_path = load_scenario(tapm_opt.config.BUILTIN_DIR / f"{name}.toml")
    assert from_path == sc


@pytest.mark.parametrize("name", sorted(EXPECTED_BUILTINS))
def test_builtin_is_immutable(name):
    sc = builtin(name)
    with pytest.raises(dataclasses.FrozenInstanceError):
        sc.meta = schema.Meta(name="other")  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        sc.environment.water_depth = 1.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        sc.lines[0].length = 1.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        sc.lines[0] = sc.lines[1]  # type: ignore[index]
    with pytest.raises(ValueError):  # derived arrays are read-only
        sc.vessel.M[0, 0] = 1.0
    with pytest.raises(ValueError):
        sc.anchors[0, 0] = 1.0


@pytest.mark.parametrize("name", sorted(EXPECTED_BUILTINS))
def test_builtin_round_trips_through_dict(name):
    sc = builtin(name)
    data = scenario_to_dict(sc)
    assert_close(scenario_from_dict(data), sc)
    # angles leave in degrees under their file keys
    assert "fairlead_angle_deg" in data["lines"][1]
    assert data["lines"][1]["fairlead_angle_deg"] == pytest.approx(math.degrees(sc.lines[1].fairlead_angle))


def test_round_trip_keeps_an_unset_reference_point_unset():
    sc = builtin("aamo4")
    assert math.isnan(sc.vessel.reference_point[0])  # default: unknown
    data = scenario_to_dict(sc)
    assert "reference_point" not in data["vessel"]  # NaN cannot be written to TOML
    assert math.isnan(scenario_from_dict(data).vessel.reference_point[0])


def test_round_trip_converts_degrees_back():
    data = scenario_to_dict(builtin("fpso"))
    extreme = next(s for s in data["sea_states"] if s["id"] == "extreme")
    assert extreme["current_direction_deg"] == pytest.approx(210.0)
    assert data["thrusters"][0]["max_azimuth_rate_deg_s"] == pytest.approx(10.0)


# ------------------------------------------------------------------------------------------
# built-in scenarios: physics at the field zero point (catenary)
# ------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=None)
def at_rest(name: str):
    sc = builtin(name)
    model = MooringModel.from_scenario(sc)
    return sc, model, model.solve_lines(np.zeros(3))


@pytest.mark.parametrize("name", sorted(EXPECTED_BUILTINS))
def test_builtin_net_mooring_load_vanishes_at_field_zero_point(name):
    # every built-in is a symmetric pattern about the centre of turret at eta = 0
    sc, model, sol = at_rest(name)
    tau = model.force(np.zeros(3))
    scale = float(np.sum(sol.HF))
    assert abs(tau[0]) < 1e-6 * scale and abs(tau[1]) < 1e-6 * scale
    assert abs(tau[2]) < 1e-6 * scale * max(sc.vessel.length_pp, 1.0)
    # and it is a restoring mooring: pushing the vessel north pulls it back south
    assert model.force(np.array([10.0, 0.0, 0.0]))[0] < -1e-3 * scale


@pytest.mark.parametrize("name", sorted(EXPECTED_BUILTINS))
def test_builtin_pretension_below_mbs_and_strain_within_limit(name):
    sc, _, sol = at_rest(name)
    la = sc.line_arrays
    assert np.all(sol.TF > 0)
    assert np.all(sol.TF < la["MBS"])
    assert np.all(sol.TF < sc.limits.tension_utilisation * la["MBS"])
    # each section's strain at the fairlead tension within its type's limit (the fairlead carries the most
    # while no buoy lifts more than the line above it weighs, as in every built-in)
    for ln, sec, T in zip(sc.lines, sc.line_sections, sol.TF):
        assert np.all(T / sec["EA"] < [sc.line_type_by_id(s.type).strain_limit for s in ln.parts]), ln.id


@pytest.mark.parametrize("name, regime", [("fpso", "composite"), ("fpso_equivalent", "touchdown")])
def test_fpso_lines_touch_down_with_realistic_pretension_and_periods(name, regime):
    """fpso on its chain-wire-chain composite lines and fpso_equivalent on the homogeneous
    equivalent line: both with chain on the seabed at rest, at the same pretension."""
    sc, model, sol = at_rest(name)
    assert set(sol.regime_names()) == {regime}
    assert all(ln.composite == (regime == "composite") for ln in sc.lines)
    assert np.all(sol.LBot > 0.05 * sc.line_arrays["L"])
    utilisation = sol.TF / sc.line_arrays["MBS"]
    assert np.all((utilisation > 0.10) & (utilisation < 0.20))
    K = model.stiffness(np.zeros(3))
    assert K[0, 0] == pytest.approx(K[1, 1], rel=1e-6)  # 3 x 4 bundles: isotropic
    T_surge = 2 * np.pi * np.sqrt(sc.vessel.M[0, 0] / K[0, 0])
    assert 100.0 < T_surge < 350.0
    assert 2.0e8 < sc.vessel.M[0, 0] < 3.0e8
    assert len(sc.thrusters) == 6 and all(t.kind == "azimuth" for t in sc.thrusters)
    assert {s.id for s in sc.sea_states} >= {"calm", "normal", "extreme"}
    assert sc.riser is not None


def test_ren8_corrections_make_the_seed_system_physical():
    sc, _, sol = at_rest("ren8")
    lt = sc.line_types[0]
    assert lt.max_strain == 0.005 and lt.submerged_weight == 275.0  # Table 2, weight reading
    assert lt.Cd_normal > lt.Cd_tangential  # Table 2's swapped drag coefficients put back
    radii = np.hypot(sc.anchors[:, 0], sc.anchors[:, 1])
    np.testing.assert_allclose(radii, 1960.0, atol=0.1)  # one anchor circle
    assert np.all(sol.TF / lt.EA < 0.005)
    assert set(sol.regime_names()) == {"touchdown"}
    # as printed (cardinal anchors at 2030 m) the line would exceed Table 2's strain limit
    from tapm_opt.models import catenary
    printed = catenary.solve(2030.0 - 20.0, 1000.0, 2250.0, lt.EA, lt.w(sc.environment))
    assert printed.TF / lt.EA > 0.005


# ------------------------------------------------------------------------------------------
# bad input: each error names the field path and the value
# ------------------------------------------------------------------------------------------


def test_missing_field():
    data = base()
    del data["environment"]["water_depth"]
    issue = issue_at(issues_of(data), "environment.water_depth")
    assert "missing required field" in issue.message and "[m]" in issue.message


def test_unknown_key_suggests_the_closest():
    data = base()
    data["environment"]["water_dpeth"] = data["environment"].pop("water_depth")
    issues = issues_of(data)
    assert "did you mean 'water_depth'" in issue_at(issues, "environment.water_dpeth").message
    issue_at(issues, "environment.water_depth")  # and the real key is reported missing


def test_unknown_angle_key_suggests_the_deg_key():
    data = base()
    data["lines"][0]["fairlead_angle"] = data["lines"][0].pop("fairlead_angle_deg")
    assert "did you mean 'fairlead_angle_deg'" in issue_at(issues_of(data), "lines[0].fairlead_angle").message


def test_wrong_type():
    data = base()
    data["lines"][2]["length"] = "long"
    message = issue_at(issues_of(data), "lines[2].length").message
    assert "must be a number" in message and "'long'" in message


@pytest.mark.parametrize("literal, path", [
    ("nan", "environment.water_depth"),
    ("inf", "environment.water_depth"),
    ("-inf", "environment.water_depth"),
])
def test_nan_and_inf_in_toml_are_rejected(literal, path):
    text = (tapm_opt.config.BUILTIN_DIR / "aamo4.toml").read_text()
    text = text.replace("water_depth = 1000.0", f"water_depth = {literal}")
    issue = issue_at(issues_of(tomllib.loads(text)), path)
    assert literal.lstrip("-") in issue.message and "finite" in issue.message


def test_nan_inside_a_matrix_names_the_entry():
    data = base()
    data["vessel"]["mass_matrix"][1][2] = float("nan")
    assert "finite" in issue_at(issues_of(data), "vessel.mass_matrix[1][2]").message


@pytest.mark.parametrize("section, index, key, value, expect", [
    ("lines", 1, "length", 0.0, "= 0 m must be > 0"),
    ("lines", 1, "length", -1200.0, "= -1200 m must be > 0"),
    ("line_types", 0, "mass_per_length", -27.6, "= -27.6 kg/m must be > 0"),
    ("line_types", 0, "EA", 0.0, "= 0 N must be > 0"),
    ("line_types", 0, "MBS", -1.0, "= -1 N must be > 0"),
    ("line_types", 0, "diameter", 0.0, "= 0 m must be > 0"),
])
def test_non_positive_sizes(section, index, key, value, expect):
    data = base()
    data[section][index][key] = value
    assert expect in issue_at(issues_of(data), f"{section}[{index}].{key}").message


def test_non_positive_vessel_size_and_depth():
    data = base()
    data["vessel"]["length_pp"] = -230.0
    data["environment"]["water_depth"] = 0.0
    issues = issues_of(data)
    assert "= -230 m must be > 0" in issue_at(issues, "vessel.length_pp").message
    assert "= 0 m must be > 0" in issue_at(issues, "environment.water_depth").message


def test_anchor_above_the_seabed_is_a_raised_lower_end():
    data = base()
    data["lines"][0]["anchor"] = [2000.0, 0.0, 900.0]
    sc = scenario_from_dict(data)  # valid: no issue
    assert sc.line_arrays["h_A"][0] == pytest.approx(sc.environment.water_depth - 900.0)
    assert sc.anchors[0, 2] == pytest.approx(900.0) and sc.line_arrays["h_A"][1] == 0.0


def test_anchor_below_the_seabed_or_above_the_fairleads():
    data = base()
    depth = data["environment"]["water_depth"]
    data["lines"][0]["anchor"] = [2000.0, 0.0, depth + 100.0]
    message = issue_at(issues_of(data), "lines[0].anchor[2]").message
    assert f"= {depth + 100:g} m" in message and "below the seabed" in message
    data["lines"][0]["anchor"] = [2000.0, 0.0, data["turret"]["fairlead_depth"] - 1.0]
    message = issue_at(issues_of(data), "lines[0].anchor[2]").message
    assert "not below the fairleads" in message


def test_anchor_with_wrong_number_of_components():
    data = base()
    data["lines"][0]["anchor"] = [2000.0]
    assert "got 1 numbers" in issue_at(issues_of(data), "lines[0].anchor").message


def test_fairleads_below_the_seabed():
    data = base()
    data["turret"]["fairlead_depth"] = 1200.0
    message = issue_at(issues_of(data), "turret.fairlead_depth").message
    assert "= 1200 m" in message and "below the seabed" in message


def test_mass_matrix_not_symmetric():
    data = base()
    data["vessel"]["mass_matrix"][1][2] = -5.0e9
    data["vessel"]["mass_matrix"][2][1] = -4.0e9
    message = issue_at(issues_of(data), "vessel.mass_matrix").message
    assert "symmetric" in message and "-5e+09" in message and "-4e+09" in message


def test_mass_matrix_not_positive_definite():
    data = base()
    data["vessel"]["mass_matrix"][0][0] = -9.6e7
    message = issue_at(issues_of(data), "vessel.mass_matrix").message
    assert "positive definite" in message and "-9.6e+07" in message


def test_linear_damping_not_positive_semidefinite():
    data = base()
    data["vessel"]["linear_damping"][0][0] = -9.2e5
    assert "positive semidefinite" in issue_at(issues_of(data), "vessel.linear_damping").message


def test_duplicate_ids():
    data = base()
    data["lines"][2]["id"] = data["lines"][0]["id"]
    message = issue_at(issues_of(data), "lines[2].id").message
    assert "'1'" in message and "unique" in message


def test_line_type_not_defined_suggests_the_closest():
    data = base()
    data["lines"][1]["type"] = "cabel"
    message = issue_at(issues_of(data), "lines[1].type").message
    assert "'cabel' is not a line type" in message and "did you mean 'cable'" in message


def test_line_too_short_to_reach_its_anchor():
    data = base()  # aamo4: anchor 4 at (0, -2000), 1000 m deep, fairlead at the turret centre
    data["lines"][3]["length"] = 1200.0
    for k in ("min_length", "max_length"):   # aamo4's winch limits would flag the length first
        data["lines"][3].pop(k, None)
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data)
    issue = issue_at(info.value.issues, "lines[3].length")
    assert "= 1200 m cannot reach the anchor from the fairlead (distance 2236 m) within" in issue.message
    assert "lines[3].length = 1200 m cannot reach the anchor from the fairlead (distance 2236 m) within the line " \
           "type's strain at MBS 2.17 %" in str(info.value)


def test_line_reach_uses_the_max_strain_when_given():
    data = base("ren8")  # straight span 2182.6 m, L = 2250 m: fine
    data["lines"][0]["length"] = 2180.0  # 2180 * 1.005 = 2190.9 > 2182.6: reaches
    scenario_from_dict(data)
    data["lines"][0]["length"] = 2170.0  # 2170 * 1.005 = 2180.9 < 2182.6: too short
    assert "max strain 0.5 %" in issue_at(issues_of(data), "lines[0].length").message


# a polyester-like tension-strain law (EA_table): slopes 200 to 390 MN, secant 340 MN at 5 %
POLY_TABLE = [[0.0, 0.0], [0.005, 1.0e6], [0.01, 2.4e6], [0.02, 5.6e6], [0.03, 9.2e6], [0.05, 17.0e6]]


def tabled(table=POLY_TABLE, *, EA=None, winch=False) -> dict:
    """fpso_equivalent (homogeneous lines of one line type) with its line type given by a
    tension-strain table instead of EA (its winches off)."""
    data = base("fpso_equivalent")
    lt = data["line_types"][0]
    del lt["EA"]
    lt["EA_table"] = table
    if EA is not None:
        lt["EA"] = EA
    if not winch:
        for ln in data["lines"]:
            for k in ("winch_max_rate", "min_length", "max_length"):
                ln.pop(k, None)
    return data


def test_a_tension_strain_table_gives_the_line_types_ea_and_strain_limit():
    """EA_table: the line type's EA is the secant at the last row (also when given equal), the
    strain at MBS read from the table (the 16.99 MN MBS at 4.80 %), the table kept through the dict."""
    sc = scenario_from_dict(tabled())
    lt = sc.line_types[0]
    assert lt.EA == pytest.approx(3.4e8) and lt.EA_table == tuple(tuple(r) for r in POLY_TABLE)
    assert lt.strain_limit == pytest.approx(0.03 + (16.99e6 - 9.2e6) / 3.9e8)
    assert lt.max_EA == pytest.approx(3.9e8)
    assert scenario_from_dict(scenario_to_dict(sc)) == sc
    assert scenario_from_dict(tabled(EA=3.4e8)) == sc
    assert sc.line_sections[0]["EA_table"][0] == lt.strain_table
    assert MooringModel.from_scenario(sc).composite[0].tables == (lt.strain_table,)


@pytest.mark.parametrize("table, path, message", [
    ([[0.0, 0.0]], "line_types[0].EA_table", "has 1 row: a tension-strain table needs at least 2"),
    ([[0.001, 0.0], [0.01, 1e6]], "line_types[0].EA_table[0]", "= [0.001, 0] must be [0, 0]"),
    ([[0.0, 0.0], [0.01, 1e6], [0.008, 2e6]], "line_types[0].EA_table[2]",
     "= [0.008, 2e+06] does not increase the strain of row 1 [0.01, 1e+06]"),
    ([[0.0, 0.0], [0.01, 1e6], [0.02, 1e6]], "line_types[0].EA_table[2]", "does not increase the tension"),
    ([[0.0, 0.0], [0.01, -1e6]], "line_types[0].EA_table[1]", "has a negative tension"),
    ([[0.0, 0.0], [0.01, 1e6, 3.0]], "line_types[0].EA_table", "rows must all have the same length"),
    ([[0.0, 0.0, 0.0], [0.01, 1e6, 3.0]], "line_types[0].EA_table", "must have shape (-1, 2)"),
    ([[0.0, 0.0], [0.01, "x"]], "line_types[0].EA_table[1][1]", "must be a number"),
])
def test_a_bad_tension_strain_table_is_named_with_its_value(table, path, message):
    assert message in issue_at(issues_of(tabled(table)), path).message


def test_ea_and_its_table_must_agree_and_one_of_them_be_given():
    assert "differs from EA_table's secant at its last row, T_n / eps_n = 340000000 N" in issue_at(
        issues_of(tabled(EA=1.163e9)), "line_types[0].EA").message
    data = base("fpso_equivalent")
    del data["line_types"][0]["EA"]
    assert "is missing: give the axial stiffness EA" in issue_at(issues_of(data), "line_types[0].EA").message


def test_a_winch_on_a_line_of_a_table_pays_out_its_one_section():
    """A line of a tension-strain table is a one-section composite line: its winch is accepted, and
    the model at another length is the catenary of the table at that length."""
    from tapm_opt.models import catenary

    sc = scenario_from_dict(tabled(winch=True))
    assert sc.lines[0].winch_max_rate > 0
    m = MooringModel.from_scenario(sc)
    _, _, XF = m.spans(np.zeros(3))
    L = np.array(m.L, float)
    L[0] += 12.0
    sol = m.solve_xf(XF, L=L)
    ref = catenary.solve(XF[0], float(m.ZF[0]), L[0], float(m.EA[0]), float(m.w[0]), CB=float(m.CB[0]),
                         h_A=float(m.h_A[0]), table=sc.line_types[0].strain_table)
    assert float(sol.TF[0]) == pytest.approx(float(ref.TF), rel=1e-12)
    assert sol.TF[0] < m.solve_xf(XF).TF[0]


def test_plausibility_reads_the_strain_at_mbs_from_the_table():
    """A table in kN read as N puts the strain at MBS far beyond 20 %: named at EA_table."""
    table = [[e, T / 1000.0] for e, T in POLY_TABLE]
    message = issue_at(issues_of(tabled(table)), "line_types[0].EA_table").message
    assert "strain at MBS (from the table)" in message


def test_line_reach_uses_the_fairleads_of_eq3_with_the_turret_angle():
    """ren8 line 0 (radial, fairlead at 20 m on the anchor's side): turning the turret by 180 deg
    puts its fairlead on the far side, 40 m further from the anchor, out of reach."""
    data = base("ren8")
    data["lines"][0]["length"] = 2180.0  # reaches at turret angle 0 (see above)
    scenario_from_dict(data)
    data["turret"]["angle_deg"] = 180.0
    ln, env, tur = data["lines"][0], data["environment"], data["turret"]
    g = math.radians(ln["fairlead_angle_deg"])
    r = tur["fairlead_radius"]
    fx, fy = tur["position"][0] - r * math.cos(g), tur["position"][1] - r * math.sin(g)   # R2(pi) p^T
    dist = math.hypot(math.hypot(ln["anchor"][0] - fx, ln["anchor"][1] - fy), env["water_depth"] - tur["fairlead_depth"])
    message = issue_at(issues_of(data), "lines[0].length").message
    assert f"(distance {dist:.0f} m)" in message and dist > 2180.0 * 1.005


def test_scenario_fairleads_are_eq2():
    sc = builtin("ren8")
    r = sc.turret.fairlead_radius
    g = np.array([ln.fairlead_angle for ln in sc.lines])
    np.testing.assert_allclose(sc.fairleads_T, np.column_stack([r * np.cos(g), r * np.sin(g)]), atol=1e-12)
    assert not sc.fairleads_T.flags.writeable


def test_submerged_weight_from_density_is_seed_fem_eq2():
    """w = rho_0 g (rho_c - rho_w) / rho_c (line-tension-control-fem eq. 2, unstretched)."""
    env = schema.Environment(water_depth=1000.0, water_density=1025.0, gravity=9.81)
    lt = schema.LineType(id="chain", diameter=0.137, mass_per_length=375.0, density=7850.0, EA=1.6e9, MBS=1.7e7,
                         MBS_std=8.5e5, Cd_normal=2.4, Cd_tangential=1.15, Ca_normal=1.0)
    assert lt.w(env) == pytest.approx(375.0 * 9.81 * (7850.0 - 1025.0) / 7850.0, rel=1e-14)
    assert dataclasses.replace(lt, density=None, submerged_weight=3200.0).w(env) == 3200.0


def test_azimuth_thruster_without_azimuth_rate():
    data = base("fpso")
    del data["thrusters"][2]["max_azimuth_rate_deg_s"]
    assert "required for an azimuth" in issue_at(issues_of(data), "thrusters[2].max_azimuth_rate_deg_s").message


def test_reverse_thrust_on_an_azimuth_thruster():
    data = base("fpso")
    data["thrusters"][0]["max_reverse_thrust"] = 1.0e5
    message = issue_at(issues_of(data), "thrusters[0].max_reverse_thrust").message
    assert "= 100000 N must be 0" in message


def test_azimuth_rate_on_a_tunnel_thruster():
    data = base("doc_example")
    data["thrusters"][1]["max_azimuth_rate_deg_s"] = 5.0
    assert "only allowed for azimuth" in issue_at(issues_of(data), "thrusters[1].max_azimuth_rate_deg_s").message


def test_fault_naming_a_missing_line():
    data = base("doc_example")
    data["faults"][0]["line"] = "99"
    message = issue_at(issues_of(data), "faults[0].line").message
    assert "'99' is not a line id" in message and "'1'" in message


def test_fault_naming_a_missing_thruster():
    data = base("doc_example")
    data["faults"].append({"kind": "thruster_failure", "time": 10.0, "thruster": "stern"})
    assert "'stern' is not a thruster id" in issue_at(issues_of(data), "faults[1].thruster").message


def test_alert_radius_below_safe_radius():
    data = base()
    data["limits"]["alert_radius"] = 40.0
    message = issue_at(issues_of(data), "limits.alert_radius").message
    assert "= 40 m must exceed safe_radius = 50 m" in message


def test_all_parse_errors_are_reported_at_once():
    data = base()
    del data["environment"]["water_depth"]
    data["vessel"]["draught"] = "deep"
    data["line_types"][0]["EA"] = float("inf")
    data["lines"][1]["length"] = -3.0
    data["turret"]["modee"] = "free"
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data)
    paths = {i.path for i in info.value.issues}
    assert paths == {"environment.water_depth", "vessel.draught", "line_types[0].EA", "lines[1].length",
                     "turret.modee"}
    assert "5 problems" in str(info.value)
    for path in paths:
        assert path in str(info.value)


def test_all_cross_field_errors_are_reported_at_once():
    data = base("doc_example")
    data["lines"][2]["id"] = "1"
    data["lines"][1]["type"] = "rope"
    data["turret"]["fairlead_depth"] = 400.0
    data["thrusters"][0]["max_reverse_thrust"] = 1.0e4
    data["faults"][0]["line"] = "7"
    data["limits"]["alert_radius"] = 10.0
    paths = {i.path for i in issues_of(data)}
    assert {"lines[2].id", "lines[1].type", "turret.fairlead_depth", "thrusters[0].max_reverse_thrust",
            "faults[0].line", "limits.alert_radius"} <= paths


def test_load_scenario_unknown_name_lists_the_builtins():
    with pytest.raises(ScenarioError) as info:
        load_scenario("no_such")
    message = str(info.value)
    assert "'no_such'" in message
    for name in EXPECTED_BUILTINS:
        assert name in message


def test_malformed_toml_reports_the_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[meta]\nname = "x"\nwater_depth 1000.0\n', encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(bad)
    message = str(info.value)
    assert "bad.toml" in message and "not valid TOML" in message and "line 3" in message


def test_a_file_with_errors_names_the_file(tmp_path):
    text = (tapm_opt.config.BUILTIN_DIR / "aamo4.toml").read_text().replace("length = 2250.0", "length = -1.0", 1)
    bad = tmp_path / "short.toml"
    bad.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(bad)
    assert info.value.source.endswith("short.toml")
    assert "lines[0].length" in str(info.value) and "-1" in str(info.value)


# ------------------------------------------------------------------------------------------
# property: corrupt one field, get a ScenarioError naming it (or a valid scenario) — never a crash
# ------------------------------------------------------------------------------------------

_TOKEN = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)")


def _leaves(d: dict, prefix: str = ""):
    for k, v in d.items():
        p = f"{prefix}.{k}" if prefix else k
        if isinstance(v, dict):
            yield from _leaves(v, p)
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for i, x in enumerate(v):
                yield from _leaves(x, f"{p}[{i}]")
        else:
            yield p


def _parts(path: str) -> list[str | int]:
    out: list[str | int] = []
    for name, idx in _TOKEN.findall(path):
        out.append(name)
        out += [int(i) for i in re.findall(r"\d+", idx)]
    return out


def _set(d: Any, path: str, value: Any) -> None:
    parts = _parts(path)
    for p in parts[:-1]:
        d = d[p]
    d[parts[-1]] = value


def _get(d: Any, path: str) -> Any:
    for p in _parts(path):
        d = d[p]
    return d


def _unwrap(tp: Any) -> Any:
    if get_origin(tp) in (typing.Union, types.UnionType):
        tp = next(a for a in get_args(tp) if a is not type(None))
    return tp


def _field(path: str) -> tuple[dataclasses.Field, Any]:
    """Schema field and (unwrapped) type of a file path such as ``lines[3].anchor``."""
    cls: Any = schema.Scenario
    names = [p for p in _parts(path) if isinstance(p, str)]
    for i, name in enumerate(names):
        fields = {file_key(f): f for f in dataclasses.fields(cls)}
        f = fields[name]
        tp = _unwrap(get_type_hints(cls)[f.name])
        if i == len(names) - 1:
            return f, tp
        cls = get_args(tp)[0] if get_origin(tp) is tuple else tp
    raise AssertionError(path)  # pragma: no cover


def _is_text(tp: Any) -> bool:
    return tp is str or (get_origin(tp) is tuple and get_args(tp)[0] is str)


def _is_numeric(tp: Any) -> bool:
    if tp in (int, float):
        return True
    if get_origin(tp) is tuple:
        inner = get_args(tp)[0]
        return inner in (int, float) or (get_origin(inner) is tuple and get_args(inner)[0] in (int, float))
    return False


def _first_number_path(value: Any, path: str) -> str:
    while isinstance(value, list):
        value, path = value[0], f"{path}[0]"
    return path


BASES = ("aamo4", "ren8", "fpso", "doc_example")
KINDS = ("negative", "nan", "inf", "bool", "string", "list", "empty")


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_property_one_corrupted_field_is_reported_by_path(data):
    """Corrupt one field of a valid scenario: it still loads, or a ScenarioError names that field
    (always when the value breaks the field's own type or range); never another exception."""
    scenario = base(data.draw(st.sampled_from(BASES), label="base"))
    path = data.draw(st.sampled_from(sorted(_leaves(scenario))), label="path")
    f, tp = _field(path)
    is_array = get_origin(tp) is tuple
    kinds = [k for k in KINDS
             if not (k == "string" and _is_text(tp) and get_origin(tp) is not Literal)
             and not (k == "negative" and not _is_numeric(tp))
             and not (k == "list" and is_array)
             and not (k == "empty" and not (is_array and _is_numeric(tp)))]
    kind = data.draw(st.sampled_from(kinds), label="kind")
    original = _get(scenario, path)
    target = path
    if isinstance(original, list) and original and kind not in ("string", "empty"):
        target = _first_number_path(original, path)  # corrupt one entry of the array
        original = _get(scenario, target)
    shape = f.metadata.get("shape") or ()
    bad: Any = {
        "negative": -abs(original) - 1 if isinstance(original, (int, float)) else -1.0,
        "nan": float("nan"),
        "inf": data.draw(st.sampled_from([float("inf"), float("-inf")])),
        "bool": True,
        "string": data.draw(st.sampled_from(["oops", "", "1e3", "nan"])),
        "list": [1.5],
        "empty": [[]] if len(shape) == 2 else [],
    }[kind]
    _set(scenario, target, bad)

    check = f.metadata.get("check")
    if kind == "negative":
        invalid_here = check is not None and check(bad) is not None
    elif kind == "empty":  # an empty array is wrong where the shape fixes a length
        invalid_here = (shape[0] != -1) if bad == [] else (shape[1] != -1)
    else:
        invalid_here = True
    try:
        scenario_from_dict(scenario)
    except ScenarioError as exc:
        assert exc.issues and all(i.path for i in exc.issues), str(exc)
        if invalid_here:
            assert path in str(exc), f"{path} <- {bad!r}: {exc}"
    else:
        assert not invalid_here, f"{path} <- {bad!r} was accepted"


@pytest.mark.parametrize("where, path, value", [
    ("turret", "position", []),
    ("vessel", "quadratic_damping", []),
    ("vessel", "mass_matrix", [[]]),
])
def test_empty_arrays_of_fixed_shape_are_rejected(where, path, value):
    data = base("fpso")
    data[where][path] = value
    assert "must have shape" in issue_at(issues_of(data), f"{where}.{path}").message


def test_empty_forbidden_sector_is_rejected():
    data = base("doc_example")
    data["thrusters"][0]["forbidden_sectors_deg"] = [[]]
    assert "must have shape (-1, 2)" in issue_at(issues_of(data), "thrusters[0].forbidden_sectors_deg").message
    data["thrusters"][0]["forbidden_sectors_deg"] = []  # no sector at all is fine
    assert scenario_from_dict(data).thrusters[0].forbidden_sectors == ()


def test_overlapping_forbidden_sectors_count_once():
    """Two 200 deg sectors that overlap by 100 deg forbid 300 deg, not 400: valid; sectors whose
    union is the whole turn are not."""
    data = base("doc_example")
    data["thrusters"][0]["forbidden_sectors_deg"] = [[0.0, 200.0], [100.0, 300.0]]
    assert len(scenario_from_dict(data).thrusters[0].forbidden_sectors) == 2
    data["thrusters"][0]["forbidden_sectors_deg"] = [[0.0, 200.0], [150.0, 10.0]]
    assert "forbid every direction" in issue_at(issues_of(data), "thrusters[0].forbidden_sectors_deg").message


# ------------------------------------------------------------------------------------------
# docs/scenarios.md follows the schema
# ------------------------------------------------------------------------------------------


def test_doc_field_reference_matches_the_schema():
    text = DOC.read_text(encoding="utf-8")
    assert text.count(BEGIN_MARKER) == 1 and text.count(END_MARKER) == 1
    between = text.split(BEGIN_MARKER, 1)[1].split(END_MARKER, 1)[0]
    assert between.strip() == field_reference_markdown().strip(), \
        "docs/scenarios.md is stale: run python -m tapm_opt.config.reference docs/scenarios.md"


def test_field_reference_covers_every_field_with_unit_default_and_range():
    md = field_reference_markdown()
    top = {key for key, _, _ in SECTIONS if "." not in key}
    assert top == {file_key(f) for f in dataclasses.fields(schema.Scenario)}
    # and the tables within them
    assert {key for key, _, _ in SECTIONS if "." in key} == {"vessel.wave_motion", "vessel.roll_pitch", "lines.sections",
                                                              "sea_states.development"}
    tables = md.split("\n### ")
    for key, toml_name, cls in SECTIONS:
        table = next(t for t in tables if t.startswith(f"`{toml_name}`"))
        rows = {r.split(" | ")[0].strip("| `"): r for r in table.splitlines() if r.startswith("| `")}
        for f in dataclasses.fields(cls):
            row = rows[file_key(f)]
            if f.metadata.get("unit"):
                assert f.metadata["unit"].replace("|", "\\|") in row
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                assert "| required |" in row
            check = f.metadata.get("check")
            if check is not None:
                assert check.__doc__ in row
    assert "| `fairlead_angle_deg` | number | deg | required |" in md
    assert "| `water_density` | number | kg/m^3 | `1025` | [900, 1100] |" in md


def test_doc_example_loads():
    sc = scenario_from_dict(tomllib.loads(doc_example_text()))
    assert len(sc.lines) == 3
    assert sc.lines[1].fairlead_angle == pytest.approx(math.radians(120.0))
    sol = MooringModel.from_scenario(sc).solve_lines(np.zeros(3))
    assert np.all(sol.TF < 0.2 * sc.line_arrays["MBS"])  # the pretension the doc claims (about 14 %)
    assert set(sol.regime_names()) == {"touchdown"}


def test_docs_state_the_anchor_rule_as_the_loader_checks_it():
    """An anchor lies on the seabed or above it (z between the fairlead depth and the water depth):
    the Line docstring, the rule tables and the field reference say so, none says 'on the seabed'
    alone."""
    text = DOC.read_text(encoding="utf-8")
    for stale in ("from its anchor (on the seabed)", "anchors on the seabed,", "anchors on the\nseabed;",
                  "anchors lie on the seabed"):
        assert stale not in text, stale
    assert "(on the seabed)" not in schema.Line.__doc__
    assert "on the seabed or above it" in " ".join(schema.Line.__doc__.split())
    rule = next(r for r in text.splitlines() if r.startswith("| `lines[].anchor[2]`"))
    assert "between the fairlead depth and the water depth" in rule and "above it" in rule
