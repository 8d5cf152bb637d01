"""Plausibility checks (docs/scenarios.md, "Plausibility checks"): input that is well typed yet
physically impossible, or so large that it would hang, exhaust memory or print nonsense, is refused
with a ScenarioError (or, on the command line, one ``error:`` line and exit status 2) that names
the field or option and the value. The built-in scenarios and the documented example still load."""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from tapm_opt.cli import main
from tapm_opt.config import builtin_scenarios, load_scenario, scenario_from_dict, scenario_to_dict, validate
from tapm_opt.config.loader import MAX_LOG_BYTES, fem_size_issues, log_size_issues
from tapm_opt.errors import ScenarioError
from tapm_opt.studies.spec import _to_toml

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "scenarios.md"
TINY = ROOT / "studies" / "tiny.toml"


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=None)
def _builtin_dict(name: str) -> dict:
    if name == "doc_example":
        return tomllib.loads(re.findall(r"```toml\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)[0])
    return scenario_to_dict(load_scenario(name))


def base(name: str) -> dict:
    """A fresh, valid scenario dictionary (file keys and units) to corrupt."""
    return copy.deepcopy(_builtin_dict(name))


def _parts(path: str) -> list:
    parts: list = []
    for name, idx in re.findall(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)", path):
        parts.append(name)
        parts += [int(i) for i in re.findall(r"\d+", idx)]
    return parts


def set_path(d: dict, path: str, value) -> None:
    """Set ``d`` at a file path such as ``lines[0].length`` or ``vessel.mass_matrix[0][0]``."""
    parts = _parts(path)
    for p in parts[:-1]:
        d = d[p]
    d[parts[-1]] = value


def set_length(d: dict, i: int, value: float) -> dict:
    """Set ``lines[i].length`` and drop that line's winch (its length limits would be the first
    problem found), so a test of the length rule sees the length rule. On a composite line the
    fairlead section takes the change (a length that is not the sections' sum is another problem)."""
    ln = d["lines"][i]
    ln["length"] = value
    if ln.get("sections"):
        ln["sections"][-1]["length"] = value - sum(s["length"] for s in ln["sections"][:-1])
    for k in ("min_length", "max_length", "winch_max_rate"):
        ln.pop(k, None)
    return d


def get_path(d: dict, path: str):
    """The value of ``d`` at a file path (as :func:`set_path` names it)."""
    for p in _parts(path):
        d = d[p]
    return d


def issue_at(data: dict, path: str):
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data)
    found = [i for i in info.value.issues if i.path == path]
    assert found, f"no issue at {path!r}; issues: {[str(i) for i in info.value.issues]}"
    return found[0]


def run(capsys, *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


def assert_one_line_error(code: int, err: str, *needles: str) -> None:
    assert code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    for n in needles:
        assert n in err, f"{n!r} not in {err!r}"


def write_scenario(tmp_path: Path, name: str, edit, file: str = "bad.toml") -> str:
    d = base(name)
    edit(d)
    path = tmp_path / file
    path.write_text(_to_toml(d), encoding="utf-8")
    return str(path)


# ------------------------------------------------------------------------------------------
# the built-in scenarios and the documented example keep validating
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted({"aamo4", "fpso", "ren8"} | set(builtin_scenarios())) + ["doc_example"])
def test_builtin_scenarios_pass_every_check(name):
    sc = scenario_from_dict(base(name))
    assert validate(sc) == []
    assert fem_size_issues(sc) == []
    assert log_size_issues(sc, 3600.0, 1.0) == []


# ------------------------------------------------------------------------------------------
# field ranges: one value just outside each bound is refused, naming the field and the value
# ------------------------------------------------------------------------------------------

FIELD_RANGES = [
    # (base, path, bad value, text of the value in the message, a value just inside that passes)
    ("fpso", "environment.water_depth", 2.0e4, "= 20000 m", None),
    ("fpso", "vessel.length_pp", 2000.0, "= 2000 m", None),
    ("fpso", "vessel.breadth", 500.0, "= 500 m", 190.0),
    # spars draw 80-200 m; on fpso_equivalent, whose hull moves in surge, sway and yaw only (fpso's
    # six-degree-of-freedom motion also needs CO on the water line, which a new draught moves)
    ("fpso_equivalent", "vessel.draught", 300.0, "= 300 m", 240.0),
    ("fpso", "turret.angle_deg", 400.0, "= 400 deg", -360.0),
    ("fpso", "lines[0].fairlead_angle_deg", -400.0, "= -400 deg", None),
    ("fpso", "thrusters[0].angle_deg", 1e300, "= 1e+300 deg", 350.0),
    ("fpso", "thrusters[0].max_azimuth_rate_deg_s", 1000.0, "= 1000", 360.0),
    ("fpso", "thrusters[0].time_constant", 1000.0, "= 1000 s", 100.0),
    ("doc_example", "thrusters[0].forbidden_sectors_deg[0][1]", 800.0, "= 800 deg", None),
    ("fpso", "line_types[0].diameter", 3.0, "= 3 m", None),
    ("aamo4", "line_types[0].density", 3.0e4, "= 30000 kg/m^3", 2.0e4),
    ("fpso", "line_types[0].Cd_normal", 50.0, "= 50", 10.0),
    ("fpso", "line_types[0].Ca_normal", 50.0, "= 50", None),
    ("fpso", "line_types[0].seabed_friction", 10.0, "= 10", 5.0),
    ("fpso", "lines[0].segments", 10**9, "= 1000000000", None),
    ("fpso", "lines[0].winch_max_rate", 100.0, "= 100 m/s", None),
    ("fpso", "sea_states[0].Hs", 40.0, "= 40 m", None),
    ("fpso", "sea_states[0].Tp", 0.5, "= 0.5 s", None),
    ("fpso", "sea_states[0].Tp", 100.0, "= 100 s", 40.0),
    ("fpso", "sea_states[0].wind_speed", 200.0, "= 200 m/s", 100.0),
    ("fpso", "sea_states[0].current_speed", 20.0, "= 20 m/s", 10.0),
    ("fpso", "sea_states[0].current_profile_factors[1]", 5.0, "= 5", 3.0),
    ("fpso", "riser.diameter", 10.0, "= 10 m", None),
    ("fpso", "riser.Cd", 20.0, "= 20", None),
    ("fpso", "riser.critical_top_angle_deg", 120.0, "= 120 deg", 90.0),
    ("fpso", "sensors.gnss_std", 1000.0, "= 1000 m", None),
    ("fpso", "sensors.heading_std_deg", 200.0, "= 200 deg", None),
    ("fpso", "sensors.tension_std_rel", 2.0, "= 2", 1.0),
]


@pytest.mark.parametrize("name, path, bad, text, inside", FIELD_RANGES,
                         ids=[f"{p}={v!r}" for _, p, v, _, _ in FIELD_RANGES])
def test_field_range(name, path, bad, text, inside):
    data = base(name)
    if inside is not None:  # the bound is not stricter than documented
        set_path(data, path, inside)
        scenario_from_dict(data)
    set_path(data, path, bad)
    assert issue_at(data, path).message.startswith(text)


def test_segments_message_gives_the_memory_in_gib():
    data = base("fpso")
    data["lines"][0]["segments"] = 10**9
    issue = issue_at(data, "lines[0].segments")
    assert re.search(r"about \d+ GiB", issue.message), issue.message


# ------------------------------------------------------------------------------------------
# cross-field rules
# ------------------------------------------------------------------------------------------


def _lt(d, **kw):
    d["line_types"][0].update(kw)


def _tunnel(d, **kw):
    d["thrusters"][3].update(kw)


def _winch(**kw):
    def edit(d):
        d["lines"][0].update(winch_max_rate=0.5, **kw)
    return edit


def _many_lines(d):
    lines = d["lines"]
    d["lines"] = [dict(lines[i % len(lines)], id=f"L{i}", segments=1000) for i in range(101)]


def _stiff(d):
    """The documented example's chain made as stiff as the bounds allow: axial wave speed 18 900 m/s,
    strain at MBS 1.2e-4. With 1000 segments of 0.9 m its FEM would need 1.26e8 node updates per
    simulated second."""
    d["line_types"][0]["EA"] = 5.0e10


def _shallow(d):
    d["environment"]["water_depth"] = 15.0


CROSS_FIELD = [
    # (id, base, edit, path, texts the message must contain)
    ("EA 1e300: strain at MBS", "fpso", lambda d: _lt(d, EA=1e300), "line_types[0].EA",
     ["= 1e+300 N", "strain at MBS", "1.7e-293"]),
    ("EA = MBS: strain at MBS 100 %", "aamo4", lambda d: _lt(d, EA=5.0e6), "line_types[0].EA",
     ["= 5e+06 N", "strain at MBS (MBS/EA) of 1"]),
    ("axial wave speed", "fpso_equivalent", lambda d: _lt(d, EA=1e12, MBS=1e10, MBS_std=1e8), "line_types[0].EA",
     ["= 1e+12 N", "axial wave speed", "8.04e+04 m/s"]),
    ("density of the cross-section", "fpso_equivalent", lambda d: _lt(d, mass_per_length=1e4),
     "line_types[0].mass_per_length",
     ["= 10000 kg/m", "3.97e+05 kg/m^3"]),
    ("submerged weight above the weight in air", "fpso_equivalent", lambda d: _lt(d, submerged_weight=5000.0),
     "line_types[0].submerged_weight", ["= 5000 N/m", "1518 N/m"]),
    ("MBS_std above half the MBS", "aamo4", lambda d: _lt(d, MBS_std=3.0e6), "line_types[0].MBS_std",
     ["= 3e+06 N", "0.5 x MBS"]),
    ("max_strain beyond the strain at MBS", "ren8", lambda d: _lt(d, max_strain=0.05), "line_types[0].max_strain",
     ["= 0.05", "breaks first"]),
    ("line 1e30 m long", "fpso", lambda d: set_length(d, 0, 1e30), "lines[0].length",
     ["= 1e+30 m", "10 x"]),
    ("line too short to install", "aamo4", lambda d: set_length(d, 0, 1200.0), "lines[0].length",
     ["= 1200 m", "cannot reach"]),
    ("winch max_length 1e6 m", "aamo4", _winch(max_length=1e6), "lines[0].max_length", ["= 1e+06 m", "10 x"]),
    ("winch min_length out of reach", "aamo4", _winch(min_length=1000.0), "lines[0].min_length",
     ["= 1000 m", "cannot reach"]),
    ("FEM cost: 1000 segments on every stiff line", "doc_example",
     lambda d: _stiff(d) or [ln.update(segments=1000) for ln in d["lines"]], "lines[0].segments",
     ["= 1000", "node updates per simulated second", "1.26e+08"]),
    ("FEM size: 101 lines of 1000 segments", "aamo4", _many_lines, "lines[0].segments",
     ["= 1000", "101101 FEM nodes", "GiB"]),
    ("forbidden sector of 360 deg", "fpso", lambda d: set_path(d, "thrusters[0].forbidden_sectors_deg", [[0.0, 360.0]]),
     "thrusters[0].forbidden_sectors_deg[0]", ["= (0, 360)", "full turn"]),
    ("forbidden sector of -360 deg", "fpso",
     lambda d: set_path(d, "thrusters[0].forbidden_sectors_deg", [[10.0, 20.0], [180.0, -180.0]]),
     "thrusters[0].forbidden_sectors_deg[1]", ["= (180, -180)", "full turn"]),
    ("empty forbidden sector", "fpso", lambda d: set_path(d, "thrusters[0].forbidden_sectors_deg", [[30.0, 30.0]]),
     "thrusters[0].forbidden_sectors_deg[0]", ["= (30, 30)", "empty"]),
    ("reverse thrust above forward thrust", "aamo4", lambda d: _tunnel(d, max_reverse_thrust=5e8),
     "thrusters[3].max_reverse_thrust", ["= 5e+08 N", "max_thrust = 500000 N"]),
    ("sea steeper than the breaking limit", "fpso",
     lambda d: d["sea_states"][0].update(Hs=30.0, Tp=4.0), "sea_states[0].Hs", ["= 30 m", "Tp = 4 s", "1/7", "1.2"]),
    ("10 m riser in 1000 m of water", "fpso", lambda d: set_path(d, "riser.length", 10.0), "riser.length",
     ["= 10 m", "cannot reach the wellhead", "982 m"]),
    ("riser 100 km long", "fpso", lambda d: set_path(d, "riser.length", 1e5), "riser.length",
     ["= 100000 m", "3 x"]),
    ("riser top tension below its weight", "fpso", lambda d: set_path(d, "riser.top_tension", 1e3),
     "riser.top_tension", ["= 1000 N", "cannot hold up"]),
    ("riser top tension of 1e12 N", "fpso", lambda d: set_path(d, "riser.top_tension", 1e12),
     "riser.top_tension", ["= 1e+12 N", "10 x"]),
    ("riser hang-off off the hull", "fpso", lambda d: set_path(d, "riser.hangoff", [5000.0, 0.0]),
     "riser.hangoff", ["= (5000, 0) m", "outside the hull"]),
    ("vessel aground", "fpso", _shallow, "vessel.draught", ["= 18.46 m", "aground"]),
    ("surge mass 1e15 kg", "fpso", lambda d: set_path(d, "vessel.mass_matrix[0][0]", 1e15), "vessel.mass_matrix[0][0]",
     ["= 1e+15 kg", "box"]),
    ("yaw inertia 1e19", "fpso", lambda d: set_path(d, "vessel.mass_matrix[2][2]", 1e19), "vessel.mass_matrix[2][2]",
     ["= 1e+19", "radius of gyration"]),
    ("negative added mass", "fpso", lambda d: set_path(d, "vessel.added_mass[0][0]", -1e6), "vessel.added_mass",
     ["positive semidefinite", "-1e+06"]),
    ("linear damping 1e12", "fpso", lambda d: set_path(d, "vessel.linear_damping[0][0]", 1e12),
     "vessel.linear_damping[0][0]", ["= 1e+12", "M/D"]),
    ("quadratic damping 1e13", "fpso", lambda d: set_path(d, "vessel.quadratic_damping[0]", 1e13),
     "vessel.quadratic_damping[0]", ["= 1e+13", "M/d"]),
    ("wind area 1e9 m^2", "fpso", lambda d: set_path(d, "vessel.wind_area_frontal", 1e9), "vessel.wind_area_frontal",
     ["= 1e+09 m^2", "200 m"]),
    ("CO 100 km from the hull", "fpso", lambda d: set_path(d, "vessel.reference_point", [1e5, 0.0, 18.46]),
     "vessel.reference_point", ["= (100000, 0, 18.46) m", "outside the hull"]),
    ("turret off the hull", "aamo4", lambda d: set_path(d, "turret.position", [1000.0, 0.0]), "turret.position",
     ["= (1000, 0) m", "outside the hull"]),
    ("thruster off the hull", "fpso", lambda d: set_path(d, "thrusters[0].position", [-1000.0, 0.0]),
     "thrusters[0].position", ["= (-1000, 0) m", "outside the hull"]),
    ("fairlead circle beyond the hull", "ren8", lambda d: set_path(d, "turret.fairlead_radius", 300.0),
     "turret.fairlead_radius", ["= 300 m", "beyond the hull", "length_pp 230 m"]),
    ("line's fairlead beyond the hull", "ren8", lambda d: set_path(d, "lines[2].fairlead_radius", 231.0),
     "lines[2].fairlead_radius", ["= 231 m", "beyond the hull", "length_pp 230 m"]),
    ("CO far above the waterline", "fpso", lambda d: set_path(d, "vessel.reference_point", [152.4, 0.0, 300.0]),
     "vessel.reference_point", ["= (152.4, 0, 300) m", "outside the hull", "218.46"]),
    ("draught that typo'd a spar's 200 m", "fpso", lambda d: set_path(d, "vessel.draught", 2000.0), "vessel.draught",
     ["= 2000 m", "spars 80-200 m"]),
    ("alert radius beyond every line", "fpso", lambda d: set_path(d, "limits.alert_radius", 1e6),
     "limits.alert_radius", ["= 1e+06 m", "longest line (2300 m)"]),
    ("anchor below the seabed", "aamo4", lambda d: set_path(d, "lines[0].anchor", [2000.0, 0.0, 2000.0]),
     "lines[0].anchor[2]", ["= 2000 m", "below the seabed"]),
    ("fairleads below the seabed", "aamo4", lambda d: set_path(d, "turret.fairlead_depth", 1500.0),
     "turret.fairlead_depth", ["= 1500 m", "below the seabed"]),
]


@pytest.mark.parametrize("name, edit, path, texts", [c[1:] for c in CROSS_FIELD], ids=[c[0] for c in CROSS_FIELD])
def test_cross_field_rule(name, edit, path, texts):
    data = base(name)
    edit(data)
    issue = issue_at(data, path)
    for t in texts:
        assert t in issue.message, f"{t!r} not in {issue.message!r}"


def test_one_bad_number_gives_one_problem():
    """EA = 1e300 breaks several rules that follow from it (strain, wave speed, FEM step): only the
    first is reported, so the command line shows one line."""
    data = base("fpso")
    data["line_types"][0]["EA"] = 1e300
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data)
    assert len(info.value.issues) == 1 and str(info.value).count("\n") == 0


@pytest.mark.parametrize("name, path, value", [
    ("fpso", "sea_states[0].Hs", 0.14 * 9.81 * 10.0 ** 2 / (2 * math.pi)),   # steepness 0.14 < 1/7
    ("fpso", "line_types[0].EA", 1.7e7 / 0.49),                               # strain at MBS 49 %
    ("aamo4", "lines[0].length", 9.9 * (2000.0 + 1000.0)),                    # 9.9 x the spans
    ("aamo4", "thrusters[3].max_reverse_thrust", 5.0e5),                      # symmetric tunnel thruster
    ("fpso", "riser.length", 982.0),                                          # fairlead depth to seabed
])
def test_values_inside_the_bounds_are_accepted(name, path, value):
    data = base(name)
    if path.startswith("lines[") and path.endswith(".length"):   # without the winch's length limits
        set_length(data, int(path[6:path.index("]")]), value)
    set_path(data, path, value)
    sc = scenario_from_dict(data)  # raises ScenarioError if a bound rejects the value
    assert get_path(scenario_to_dict(sc), path) == pytest.approx(value)


# ------------------------------------------------------------------------------------------
# real designs of every kind pass: the bounds catch typos, not unusual vessels or sites
# ------------------------------------------------------------------------------------------

CHAIN = dict(id="chain", diameter=0.15, mass_per_length=250.0, density=7850.0, EA=1.5e9, MBS=2.0e7, MBS_std=1.0e6,
             Cd_normal=2.4, Cd_tangential=1.15, Ca_normal=1.0)
#: Polyester rope of 160 mm: 17 kg/m, MBS 12 MN, strain at MBS 15 %.
POLYESTER = dict(id="polyester", diameter=0.16, mass_per_length=17.0, density=1380.0, EA=8.0e7, MBS=1.2e7,
                 MBS_std=6.0e5, Cd_normal=1.2, Cd_tangential=0.05, Ca_normal=1.0)


def design(L: float, B: float, T: float, depth: float, *, mass: float = 0.8, radius: float = 0.0,
           fairlead_depth: float = 0.0, line_type: dict = CHAIN, spread: float | None = None,
           taut: bool = False, Hs: float = 3.0, Tp: float = 10.0, co_z: float | None = None,
           per_line_radius: bool = False) -> dict:
    """A four-line locked-turret scenario of a hull L x B x T in ``depth`` of water: surge mass
    ``mass`` x the box rho L B T (sway 1.5 x), yaw radius of gyration 0.3 L, decay times of 100 s,
    fairleads on a circle of ``radius`` (per line with ``per_line_radius``), anchors ``spread`` from
    the centre (default 5 x depth), catenary lines 10 % longer than the spans or taut-leg lines 2 %
    shorter than the straight distance."""
    d = base("aamo4")
    box = 1025.0 * L * B * T
    m = [mass * box, 1.5 * mass * box, mass * box * (0.3 * L) ** 2]
    v = d["vessel"]
    for key in ("added_mass", "quadratic_damping", "reference_point"):
        v.pop(key, None)
    v.update(mass_matrix=[[m[0], 0, 0], [0, m[1], 0], [0, 0, m[2]]],
             linear_damping=[[m[0] / 100, 0, 0], [0, m[1] / 100, 0], [0, 0, m[2] / 100]],
             length_pp=L, breadth=B, draught=T, wind_area_frontal=10.0 * B, wind_area_lateral=10.0 * L)
    if co_z is not None:
        v["reference_point"] = [L / 2, 0.0, co_z]
    d["environment"]["water_depth"] = depth
    d["turret"].update(position=[0.0, 0.0], mode="locked", fairlead_radius=0.0 if per_line_radius else radius,
                       fairlead_depth=fairlead_depth)
    d["line_types"] = [dict(line_type)]
    spread = 5.0 * depth if spread is None else spread
    straight = math.hypot(spread - radius, depth - fairlead_depth)
    length = 0.98 * straight if taut else 1.1 * (spread - radius + depth - fairlead_depth)
    d["lines"] = []
    for k in range(4):
        a = math.radians(45.0 + 90.0 * k)
        d["lines"].append(dict(id=str(k + 1), type=line_type["id"], anchor=[spread * math.cos(a), spread * math.sin(a)],
                               fairlead_angle_deg=math.degrees(a), length=length))
        if per_line_radius:
            d["lines"][-1]["fairlead_radius"] = radius
    d["thrusters"] = [dict(id="T1", kind="azimuth", position=[-0.4 * L, 0.0], max_thrust=1e5, max_thrust_rate=1e4,
                           max_azimuth_rate_deg_s=10.0, time_constant=5.0)]
    d["sea_states"] = [dict(id="s", Hs=Hs, Tp=Tp)]
    for key in ("riser", "faults", "limits"):
        d.pop(key, None)
    return d


REAL_DESIGNS = {
    "supply vessel 80 x 18 x 6 m spread-moored in 50 m": lambda: design(80, 18, 6, 50.0, radius=40.0,
                                                                         fairlead_depth=2.0),
    "spread-moored FPSO, fairleads at the hull ends (r = 150 m)": lambda: design(300, 58, 20, 1000.0, radius=150.0,
                                                                                 fairlead_depth=15.0),
    "spread mooring given per line (r = 150 m)": lambda: design(300, 58, 20, 1000.0, radius=150.0,
                                                                 per_line_radius=True),
    "semi-submersible 110 x 90 x 25 m, polyester taut-leg in 3000 m": lambda: design(
        110, 90, 25, 3000.0, mass=0.3, radius=60.0, fairlead_depth=20.0, line_type=POLYESTER, spread=3000.0, taut=True),
    "spar 40 x 40 x 200 m in 1500 m": lambda: design(40, 40, 200, 1500.0, mass=1.6, radius=20.0, fairlead_depth=100.0,
                                                     co_z=200.0),
    "deep spar, 240 m draught, CO at the waterline": lambda: design(40, 40, 240, 1500.0, mass=1.6, radius=20.0,
                                                                    fairlead_depth=100.0, co_z=240.0),
    "swell Hs 3 m, Tp 20 s": lambda: design(300, 58, 20, 1000.0, Hs=3.0, Tp=20.0),
}


@pytest.mark.parametrize("make", REAL_DESIGNS.values(), ids=list(REAL_DESIGNS))
def test_real_designs_are_accepted(make):
    sc = scenario_from_dict(make())
    assert validate(sc) == [] and fem_size_issues(sc) == []


def test_spread_mooring_of_a_moordyn_import_with_fairleads_at_the_hull_ends(tmp_path):
    """A MoorDyn file whose fairleads sit at the bow and stern of a 300 m hull imports."""
    from tapm_opt.config.moordyn import moordyn_text, scenario_toml
    from tapm_opt.models.moordyn_import import import_moordyn

    data = design(300, 58, 20, 1000.0, radius=150.0, fairlead_depth=15.0)
    sc = scenario_from_dict(data)
    vessel = tmp_path / "vessel.toml"
    vessel.write_text(scenario_toml(data), encoding="utf-8")
    path = tmp_path / "spread.dat"
    path.write_text(moordyn_text(sc)[0], encoding="utf-8")
    new = import_moordyn(path, vessel, mbs={"chain": 2.0e7}).scenario
    assert new.turret.fairlead_radius == pytest.approx(150.0)


# ------------------------------------------------------------------------------------------
# scenarios built in code, sizes of runs, and files that cannot be read
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("replace, path, text", [
    (lambda sc: dataclasses.replace(sc, line_types=(dataclasses.replace(sc.line_types[0], EA=math.nan),)),
     "line_types[0].EA", "= nan must be a finite number"),
    (lambda sc: dataclasses.replace(sc, environment=dataclasses.replace(sc.environment, water_depth=-5.0)),
     "environment.water_depth", "= -5 must be > 0"),
    (lambda sc: dataclasses.replace(sc, turret=dataclasses.replace(sc.turret, angle=math.radians(720.0))),
     "turret.angle_deg", "= 720 must be <= 360"),
    (lambda sc: dataclasses.replace(sc, lines=(dataclasses.replace(sc.lines[0], segments=10**9),) + sc.lines[1:]),
     "lines[0].segments", "= 1000000000 must be in [2, 1000]"),
])
def test_validate_checks_fields_of_a_scenario_built_in_code(replace, path, text):
    sc = replace(load_scenario("aamo4"))
    issues = validate(sc)
    found = [i for i in issues if i.path == path]
    assert found and found[0].message.startswith(text), [str(i) for i in issues]


def test_fem_size_of_a_segment_override():
    sc = load_scenario("fpso")
    assert fem_size_issues(sc, 20) == [] and fem_size_issues(sc, 1000) == []  # 3e7 updates per second
    (iss,) = fem_size_issues(sc, 10**9, where="--segments")
    assert iss.path == "--segments" and "= 1000000000" in iss.message and "GiB" in iss.message
    data = base("doc_example")
    _stiff(data)
    stiff = scenario_from_dict(data)
    assert fem_size_issues(stiff) == [] and fem_size_issues(stiff, 700) == []
    (iss,) = fem_size_issues(stiff, 1000, where="--segments")
    assert iss.path == "--segments" and "node updates per simulated second" in iss.message


def test_log_size():
    sc = load_scenario("fpso")
    assert log_size_issues(sc, 86400.0, 1.0) == []
    (iss,) = log_size_issues(sc, 1e12, 1.0, where="--duration")
    assert iss.path == "--duration" and iss.message.startswith("= 1e+12 s") and "GiB" in iss.message
    longest = float(re.search(r"at most ([\d.e+]+) s", iss.message).group(1))
    assert log_size_issues(sc, 0.999 * longest, 1.0) == []
    assert log_size_issues(sc, 1.01 * longest, 1.0) != []
    assert 0.99 * MAX_LOG_BYTES < (longest + 2) * (36 + 3 * 18) * 8 <= 1.001 * MAX_LOG_BYTES


@pytest.mark.parametrize("make, text", [
    (lambda p: (p / "deep.toml").write_text("a = " + "[" * 5000 + "]" * 5000 + "\n") and p / "deep.toml",
     "nests arrays or tables too deeply"),
    (lambda p: (p / "empty.toml").write_text("") or p / "empty.toml", "is empty"),
    (lambda p: (p / "folder").mkdir() or p / "folder", "is a directory"),
    (lambda p: "", "the scenario name is empty"),
])
def test_unreadable_scenario_files(tmp_path, make, text):
    target = make(tmp_path)
    with pytest.raises(ScenarioError) as info:
        load_scenario(target)
    assert text in str(info.value) and str(info.value).count("\n") == 0


# ------------------------------------------------------------------------------------------
# the command line: one error line naming the option and the value, exit status 2
# ------------------------------------------------------------------------------------------

SIM = ("simulate", "aamo4", "--duration", "2", "--segments", "4")
FM = ("plant", "forced-motion", "aamo4", "--amplitude", "1", "--period", "10", "--duration", "2", "--segments", "4")

CLI = [
    (SIM + ("--out", "OUT", "--seed", "-1"), ["--seed", "-1"]),
    (SIM + ("--out", "OUT", "--dt-control", "100"), ["--dt-control", "100"]),
    (SIM + ("--out", "OUT", "--dt-control", "1e-9"), ["--dt-control", "1e-09"]),
    (SIM + ("--out", "OUT", "--dt-control", "nan"), ["--dt-control", "nan"]),
    (SIM + ("--out", ""), ["--out", "''", "empty"]),
    (SIM + ("--out", "FILE/sub"), ["--out", "is a file"]),
    (SIM + ("--out", "OUT", "--sea-state", "nope"), ["--sea-state", "'nope'"]),
    (("simulate", "STIFF", "--duration", "2", "--out", "OUT", "--segments", "1000"),
     ["--segments", "1000", "node updates"]),
    (FM[:2] + ("STIFF",) + FM[3:] + ("--segments", "1000"), ["--segments", "1000", "node updates"]),
    (SIM + ("--out", "OUT", "--controller", "lmpc", "--option", "horizon=100000"), ["horizon", "100000"]),
    (SIM + ("--out", "OUT", "--option", "periods=1e-9"), ["periods", "1e-09"]),
    (FM + ("--amplitude", "1e12"), ["--amplitude", "1e+12"]),
    (FM + ("--dof", "yaw", "--amplitude", "1000"), ["--amplitude", "1000 deg"]),
    (FM + ("--amplitude", "1000", "--period", "100"), ["--amplitude", "62.8 m/s"]),
    (FM + ("--period", "1e-9"), ["--period", "1e-09"]),
    (FM + ("--duration", "1e12"), ["--duration", "1e+12", "GiB"]),
    (FM + ("--dt-out", "1e-9"), ["--dt-out", "1e-09", "GiB"]),
    (FM + ("--dt-out", "1e9"), ["--dt-out", "1e+09"]),
    (FM + ("--out", ""), ["--out", "''"]),
    (("simulate", "aamo4", "--duration", "0.5", "--dt-control", "0.1", "--out", "OUT"),
     ["--duration", "0.5 s", "single sample"]),
    (("lines", "aamo4", "--range", "1e12"), ["--range", "1e+12"]),
    (("lines", "aamo4", "--directions", "0,1e300"), ["--directions", "1e300"]),
    (("lines", "aamo4", "--out", ""), ["--out", "''"]),
    (("lines", "aamo4", "--out", "FILE/x.csv"), ["--out", "is a file"]),
    (("gains", "aamo4", "--out", "OUT", "--headings", "nan"), ["--headings", "'nan'"]),
    (("gains", "aamo4", "--out", "OUT", "--headings", "1e300"), ["--headings", "'1e300'"]),
    (("gains", "aamo4", "--out", "OUT", "--sea-states", ","), ["--sea-states", "','"]),
    (("gains", "aamo4", "--out", "OUT", "--sea-states", "tidal,nope"), ["--sea-states", "nope"]),
    (("gains", "aamo4", "--out", "OUT", "--broken", ","), ["--broken", "','"]),
    (("gains", "aamo4", "--out", ""), ["--out", "''"]),
    (("compare", "aamo4", "--out", "OUT", "--duration", "1e12"), ["--duration", "1e+12", "GiB"]),
    (("compare", "aamo4", "--out", ""), ["--out", "''"]),
    (("compare", "aamo4", "--out", "OUT", "--duration", "0.5"), ["--duration", "0.5 s", "single sample"]),
    (("study", "run", "", "--out", "OUT"), ["STUDY.toml", "''"]),
    (("study", "run", str(TINY), "--out", ""), ["--out", "''"]),
    (("report", ""), ["DIR", "''"]),
    (("report", "OUT", "--html", ""), ["--html", "''"]),
    (("scenario", "show", "DIR"), ["is a directory"]),
]


@pytest.mark.parametrize("args, needles", CLI, ids=[" ".join(a[:1] + a[-2:]) for a, _ in CLI])
def test_cli_bad_option(capsys, tmp_path, args, needles):
    (tmp_path / "file").write_text("x")
    (tmp_path / "dir").mkdir()
    subst = {"OUT": str(tmp_path / "out"), "FILE/sub": str(tmp_path / "file" / "sub"),
             "FILE/x.csv": str(tmp_path / "file" / "x.csv"), "DIR": str(tmp_path / "dir"),
             "STIFF": write_scenario(tmp_path, "doc_example", _stiff, "stiff.toml")}
    code, _, err = run(capsys, *(subst.get(a, a) for a in args))
    assert_one_line_error(code, err, *needles)
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


STUDY_EDITS = [
    ("segments = 6", "segments = 1000000000", ["study.segments", "1000000000", "GiB"]),
    ("duration = 60.0", "duration = 1e12", ["study.duration", "1e+12", "GiB"]),
    ("dt_control = 1.0", "dt_control = 1e-9", ["study.dt_control", "1e-09"]),
    ('scenario = "fpso"', 'scenario = "BAD"', ["study.scenario", "line_types[0].EA", "1e+300"]),
]


@pytest.mark.parametrize("old, new, needles", STUDY_EDITS, ids=[n for _, n, _ in STUDY_EDITS])
def test_cli_bad_study_file(capsys, tmp_path, old, new, needles):
    bad_sc = write_scenario(tmp_path, "fpso", lambda d: _lt(d, EA=1e300))
    text = TINY.read_text(encoding="utf-8")
    assert old in text
    study = tmp_path / "study.toml"
    study.write_text(text.replace(old, new.replace("BAD", bad_sc)), encoding="utf-8")
    code, _, err = run(capsys, "study", "run", str(study), "--out", str(tmp_path / "out"), "--workers", "0")
    assert_one_line_error(code, err, *needles)
    assert not (tmp_path / "out" / "cases").exists()


def test_cli_deeply_nested_files(capsys, tmp_path):
    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    code, _, err = run(capsys, "study", "run", str(deep), "--out", str(tmp_path / "out"))
    assert_one_line_error(code, err, "deep.toml", "too deeply")
    code, _, err = run(capsys, "lines", str(deep))
    assert_one_line_error(code, err, "deep.toml", "too deeply")
    code, out, err = run(capsys, "scenario", "validate", str(deep))
    assert code == 1 and "too deeply" in out and "Traceback" not in out + err


@pytest.mark.parametrize("edit, needles", [
    (lambda d: set_length(d, 0, 1e30), ["lines[0].length", "1e+30"]),
    (lambda d: d["sea_states"][0].update(Hs=30.0, Tp=4.0), ["sea_states[0].Hs", "30 m", "1/7"]),
])
def test_cli_commands_refuse_implausible_scenarios(capsys, tmp_path, edit, needles):
    """``tapm scenario show`` and ``tapm lines`` printed 5.5e26 % MBS and exited 0 for a 1e30 m line."""
    path = write_scenario(tmp_path, "fpso", edit)
    for cmd in (("scenario", "show", path), ("lines", path, "--points", "3")):
        code, _, err = run(capsys, *cmd)
        assert_one_line_error(code, err, *needles)
    code, out, _ = run(capsys, "scenario", "validate", path)
    assert code == 1 and all(n in out for n in needles)


@pytest.mark.parametrize("args, needles", [
    # each of these hung (> 3 min) or raised MemoryError before the checks
    (("simulate", "BAD_EA", "--duration", "2", "--out", "OUT"), ["line_types[0].EA", "1e+300"]),
    (("simulate", "BAD_SEG", "--duration", "2", "--out", "OUT"), ["lines[0].segments", "1000000000", "GiB"]),
    (("simulate", "aamo4", "--duration", "1e12", "--out", "OUT"), ["--duration", "1e+12", "GiB"]),
    (("plant", "forced-motion", "aamo4", "--amplitude", "1", "--period", "10", "--duration", "2", "--dt-out", "1e-9"),
     ["--dt-out", "1e-09"]),
], ids=["EA 1e300", "segments 1e9", "duration 1e12", "dt-out 1e-9"])
def test_cli_inputs_that_hung_fail_fast(tmp_path, args, needles):
    paths = {"BAD_EA": write_scenario(tmp_path, "fpso", lambda d: _lt(d, EA=1e300), "ea.toml"),
             "BAD_SEG": write_scenario(tmp_path, "aamo4", lambda d: set_path(d, "lines[0].segments", 10**9),
                                       "seg.toml"),
             "OUT": str(tmp_path / "out")}
    res = subprocess.run([sys.executable, "-m", "tapm_opt", *(paths.get(a, a) for a in args)],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert_one_line_error(res.returncode, res.stderr, *needles)


def test_simulate_logs_every_control_step_at_least_one_second_apart(capsys, tmp_path):
    """--dt-control 0.4 used to fail blaming 'dt_log', an option tapm simulate does not have: the
    run is now logged every 3 control steps (1.2 s)."""
    import numpy as np

    out = tmp_path / "run"
    code, _, err = run(capsys, "simulate", "aamo4", "--duration", "3.6", "--dt-control", "0.4", "--segments", "4",
                       "--sea-state", "none", "--out", str(out))
    assert code == 0, err
    t = np.load(out / "result.npz")["time"]
    np.testing.assert_allclose(np.diff(t), 1.2, rtol=1e-9)
