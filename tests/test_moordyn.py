"""MoorDyn v2 interoperability: reading and writing MoorDyn files, and MoorDyn-C (the ``moordyn``
wheel, in the test extra) as a reference for the FEM plant under forced motion.

``moordyn`` is imported directly: a missing wheel fails these tests instead of skipping them.
"""

from __future__ import annotations

import dataclasses
import math
import re
import sys
from pathlib import Path

import moordyn  # noqa: F401 - in the test extra; its absence must fail, not skip
import numpy as np
import pytest

from tapm_opt.cli import main
from tapm_opt.config import load_scenario, validate
from tapm_opt.config.moordyn import (
    MoorDynError,
    moordyn_line_type,
    moordyn_text,
    moordyn_time_step,
    parse_moordyn,
    seabed_constants,
)
from tapm_opt.geometry import fairleads_E
from tapm_opt.models.moordyn_import import import_moordyn
from tapm_opt.models import MooringModel
from tapm_opt.plant.fem import FEMLines
from tapm_opt.plant.forced_motion import forced_motion
from tapm_opt.plant.mooring_fem import line_set_from_scenario
from tapm_opt.plant.moordyn_reference import MoorDynMooring, MoorDynUnavailable, moordyn_forced_motion, moordyn_module

BUILTINS = ("aamo4", "fpso_equivalent", "ren8")
"""The built-ins on homogeneous lines (one MoorDyn line per line); the composite ones (fpso, fpso_deep,
fang12) are exported and read back in tests/test_moordyn_composite.py."""
MBS = {"aamo4": {"cable": 5.0e6}, "fpso_equivalent": {"cwc137": 1.699e7}, "ren8": {"cable": 5.0e6}}

# A MoorDyn v2 file as a user keeps one: front matter, '---' headers, column and unit lines,
# trailing comments (MoorDyn-C refuses comment-only rows inside a table), a coupled vessel body at the hull origin with the fairleads given relative to it
# (a turret 91.44 m forward of the origin, 8 m fairlead radius, 18 m deep), 3 x 3 legs in 800 m.
HAND_WRITTEN = """\
--------------------- MoorDyn Input File ------------------------------------
Turret FPSO, 3 x 3 legs, 800 m water depth
(sample model for the MoorDyn import)
---------------------- LINE TYPES ----------------------------------------------------------------------
TypeName   Diam    Mass/m     EA       BA/-zeta    EI     Cd     Ca     CdAx    CaAx
(name)     (m)     (kg/m)     (N)      (N-s/-)   (N-m^2)  (-)    (-)    (-)     (-)
poly160    0.16    120.0      1.2e9     -1.0       0      1.2    1.0    0.05    0.1    # main leg
---------------------- BODIES ---------------------------------------------------------------------------
ID   Attachment  X0     Y0    Z0     r0      p0     y0     Mass  CG*   I*      Volume   CdA*   Ca*
(#)   (word)     (m)    (m)   (m)   (deg)   (deg)  (deg)   (kg)  (m)  (kg-m^2)  (m^3)   (m^2)  (-)
1     Vessel     0      0     0      0       0      0       0     0     0        0       0      0
---------------------- POINTS ---------------------------------------------------------------------------
ID   Attachment     X          Y         Z      Mass  Volume  CdA   Ca
(#)   (word/ID)    (m)        (m)       (m)     (kg)  (m^3)  (m^2)  (-)
1     Fixed      1735.161    143.807  -800.0    0     0      0     0   # bundle 1, facing north
2     Body1        99.4096     0.6972  -18.0    0     0      0     0   # fairlead on the turret
3     Fixed      1741.440      0.000  -800.0    0     0      0     0
4     Body1        99.4400     0.0000  -18.0    0     0      0     0
5     Fixed      1735.161   -143.807  -800.0    0     0      0     0
6     Body1        99.4096    -0.6972  -18.0    0     0      0     0
7     Fixed      -605.880  -1495.408  -800.0    0     0      0     0
8     Body1        88.0591    -7.2505  -18.0    0     0      0     0
9     Fixed      -733.560  -1428.942  -800.0    0     0      0     0
10    Body1        87.4400    -6.9282  -18.0    0     0      0     0
11    Fixed      -854.961  -1351.601  -800.0    0     0      0     0
12    Body1        86.8514    -6.5532  -18.0    0     0      0     0
13    Fixed      -854.961   1351.601  -800.0    0     0      0     0
14    Body1        86.8514     6.5532  -18.0    0     0      0     0
15    Fixed      -733.560   1428.942  -800.0    0     0      0     0
16    Body1        87.4400     6.9282  -18.0    0     0      0     0
17    Fixed      -605.880   1495.408  -800.0    0     0      0     0
18    Body1        88.0591     7.2505  -18.0    0     0      0     0
---------------------- LINES ----------------------------------------------------------------------------
ID   LineType   AttachA  AttachB  UnstrLen  NumSegs  LineOutputs
(#)   (name)     (ID)     (ID)      (m)       (-)      (-)
1     poly160     1        2        1900      25       -
2     poly160     3        4        1900      25       -
3     poly160     5        6        1900      25       -
4     poly160     7        8        1900      25       -
5     poly160     9        10       1900      25       -
6     poly160     11       12       1900      25       -
7     poly160     13       14       1900      25       -
8     poly160     15       16       1900      25       -
9     poly160     17       18       1900      25       -
---------------------- OPTIONS -----------------------------------------
1             writeLog      Write log file
0.01          dtM           time step to use in mooring integration (s)
RK4           tScheme       time integrator
3.0e6         kbot          bottom stiffness (Pa/m)
3.0e5         cbot          bottom damping (Pa-s/m)
800           WtrDpth       water depth (m)
1025          rho           water density (kg/m^3)
9.81          g             gravity (m/s^2)
1.0           dtIC          time interval for analyzing convergence during IC gen (s)
120           TmaxIC        max time for ic gen (s)
0.001         threshIC      threshold for IC convergence (-)
---------------------- OUTPUTS -----------------------------------------
FairTen1
FairTen2
AnchTen1
END
------------------------- need this line -------------------------------------
"""


def run(capsys, *args: str):
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


def _write(tmp_path: Path, text: str, name: str = "moor.dat") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _per_length(sc, lt):
    """Forces per length of a line type: (w, m, EA, drag n, drag t, added mass n, added mass t, zeta, mu)."""
    d = lt.diameter
    return np.array([lt.w(sc.environment), lt.mass_per_length, lt.EA, lt.Cd_normal * d, lt.Cd_tangential * d,
                     lt.Ca_normal * d * d, lt.Ca_tangential * d * d, lt.axial_damping_ratio, lt.seabed_friction])


# --------------------------------------------------------------------------------------------
# conventions
# --------------------------------------------------------------------------------------------


def test_line_type_mapping_keeps_forces_per_length():
    sc = load_scenario("fpso")
    lt, env = sc.line_types[0], sc.environment
    md = moordyn_line_type(lt, env)
    rho, g = env.water_density, env.gravity
    A_md = math.pi * md["d"] ** 2 / 4
    assert (md["mass"] - rho * A_md) * g == pytest.approx(lt.w(env), rel=1e-12)  # same submerged weight
    assert md["Cd"] * md["d"] == pytest.approx(lt.Cd_normal * lt.diameter, rel=1e-12)
    assert md["CdAx"] * math.pi * md["d"] == pytest.approx(lt.Cd_tangential * lt.diameter, rel=1e-12)  # on pi d
    assert md["Ca"] * md["d"] ** 2 == pytest.approx(lt.Ca_normal * lt.diameter**2, rel=1e-12)
    assert md["CaAx"] * md["d"] ** 2 == pytest.approx(lt.Ca_tangential * lt.diameter**2, rel=1e-12)
    assert md["BA"] == pytest.approx(-math.sqrt(2.0) * lt.axial_damping_ratio, rel=1e-12)


@pytest.mark.parametrize("name", BUILTINS)
def test_negative_ba_is_moordyns_damping_coefficient_of_the_fem(name):
    """MoorDyn's own log states the BA [N s] it derived from BA = -sqrt(2) zeta: it equals the
    FEM's c_int of the same segment."""
    sc = load_scenario(name)
    with MoorDynMooring(sc) as mm:
        mm.init(np.zeros(3))
        log = mm.log()
    got = [float(x) for x in re.findall(r"damping set to \S+ Pa-s = (\S+) Ns", log)]
    assert len(got) == len(sc.lines)
    fem = FEMLines(line_set_from_scenario(sc), np.array(sc.anchors), water_depth=sc.environment.water_depth,
                   rho_w=sc.environment.water_density)
    c_int = fem._c_int[fem.fairlead_seg]
    assert np.allclose(got, c_int, rtol=1e-5)  # MoorDyn logs 6 digits


def test_positive_ba_maps_to_the_same_damping(tmp_path):
    sc = load_scenario("aamo4")
    lt, ln = sc.line_types[0], sc.lines[0]
    l = ln.length / ln.segments
    BA = lt.axial_damping_ratio * math.sqrt(2) * l * math.sqrt(lt.EA * lt.mass_per_length)
    text = moordyn_text(sc)[0]
    text = re.sub(r"(230000000)  -0\.\d+", rf"\g<1>  {BA!r}", text)
    res = import_moordyn(_write(tmp_path, text), "aamo4", mbs={"cable": 5e6})
    assert res.scenario.line_types[0].axial_damping_ratio == pytest.approx(lt.axial_damping_ratio, rel=1e-12)


def test_seabed_constants_match_the_fem_seabed():
    """MoorDyn's contact force (kBot pen - cBot v) d l per node equals the FEM node spring w l / 0.01
    with 50 % of critical damping."""
    sc = load_scenario("fpso_equivalent")
    lt, env = sc.line_types[0], sc.environment
    d = moordyn_line_type(lt, env)["d"]
    kb, cb = seabed_constants(lt.w(env), lt.mass_per_length, d)
    fem = FEMLines(line_set_from_scenario(sc), np.array(sc.anchors), water_depth=env.water_depth,
                   rho_w=env.water_density)
    node = 5
    l = sc.lines[0].length / sc.lines[0].segments
    assert kb * d * l == pytest.approx(fem._kb[node], rel=1e-12)
    assert cb * d * l == pytest.approx(fem._cb[node], rel=1e-12)


def test_time_step_and_scheme():
    damped = load_scenario("aamo4")
    dt, scheme = moordyn_time_step(damped)
    assert scheme == "RK2" and 0.005 < dt < 0.05
    lt = dataclasses.replace(damped.line_types[0], axial_damping_ratio=0.0)
    undamped = dataclasses.replace(damped, line_types=(lt,))
    dt0, scheme0 = moordyn_time_step(undamped)
    assert scheme0 == "RK4"  # RK2 has no stable step on an undamped axial mode


def test_undamped_lines_run_stably_in_moordyn():
    sc = load_scenario("aamo4")
    sc = dataclasses.replace(sc, line_types=(dataclasses.replace(sc.line_types[0], axial_damping_ratio=0.0),))
    r = moordyn_forced_motion(sc, amplitude=5.0, period=50.0, duration=60.0, segments=10)
    assert r.scheme == "RK4"
    assert np.all(np.isfinite(r.T)) and r.T.max() < 1.5 * r.T[0].max()


def test_moordyn_c_reads_rho_not_rhow(tmp_path):
    """Why the export writes 'rho': MoorDyn-C 2.7 ignores MoorDyn-F's 'rhoW' (it keeps 1025)."""
    sc = load_scenario("aamo4")
    text = moordyn_text(sc, outputs=False, extra_options={"disableOutput": 1})[0]
    md = moordyn_module()
    from tapm_opt.plant.moordyn_reference import _console_to

    weights = {}
    for key in ("rho", "rhoW"):
        p = _write(tmp_path, text.replace("1025  rho ", f"1000  {key} "), f"{key}.dat")
        with _console_to(tmp_path / "log.txt"):
            s = md.Create(str(p))
            md.Init(s, [0.0] * 6, [0.0] * 6)
            ln = md.GetLine(s, 1)
            weights[key] = -md.GetLineNodeWeight(ln, 5)[2]
            md.Close(s)
    lt = moordyn_line_type(sc.line_types[0], sc.environment)
    l = sc.lines[0].length / sc.lines[0].segments
    vol = math.pi * lt["d"] ** 2 / 4 * l
    assert weights["rho"] == pytest.approx(9.81 * (lt["mass"] * l - 1000.0 * vol), rel=1e-9)
    assert weights["rhoW"] == pytest.approx(9.81 * (lt["mass"] * l - 1025.0 * vol), rel=1e-9)


def test_frames_turret_offset_angle_and_yaw():
    """MoorDyn's fairlead points sit where tapm_opt puts them, (x, -y, -z) of NED, at rest and
    for a locked turret in a yawed pose."""
    sc = load_scenario("fpso")
    tur = dataclasses.replace(sc.turret, position=(60.0, 12.0), angle=math.radians(30.0), mode="locked")
    sc = dataclasses.replace(sc, turret=tur)
    assert validate(sc) == []
    md = moordyn_module()
    with MoorDynMooring(sc, segments=4) as mm:
        mm.init(np.zeros(3))
        for eta in (np.zeros(3), np.array([5.0, -3.0, 0.2])):
            x = mm.body_pose(eta)
            mm.step(x, np.zeros(6), 1e-4)
            fx, fy = fairleads_E(eta, np.array(tur.position), sc.fairleads_T, tur.angle)
            for i in range(len(sc.lines)):
                p = np.array(md.GetPointPos(md.GetPoint(mm.sys, 2 * i + 2)))
                assert p == pytest.approx([fx[i], -fy[i], -tur.fairlead_depth], abs=1e-6)


# --------------------------------------------------------------------------------------------
# export -> import
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", BUILTINS)
def test_round_trip_reproduces_the_mooring(tmp_path, name):
    sc = load_scenario(name)
    path = _write(tmp_path, moordyn_text(sc)[0])
    res = import_moordyn(path, name, mbs=MBS[name])
    new = res.scenario
    assert validate(new) == []
    env0, env1 = sc.environment, new.environment
    assert (env1.water_depth, env1.water_density, env1.gravity) == (env0.water_depth, env0.water_density, env0.gravity)
    assert len(new.lines) == len(sc.lines)
    for a, b in zip(sc.lines, new.lines):
        assert (b.id, b.type, b.length, b.segments) == (a.id, a.type, a.length, a.segments)
        assert np.allclose(new.anchors, sc.anchors, atol=1e-6)
        assert b.fairlead_angle == pytest.approx(a.fairlead_angle, abs=1e-9)
    assert np.allclose(new.fairleads_T, sc.fairleads_T, atol=1e-6)
    assert new.turret.fairlead_depth == pytest.approx(sc.turret.fairlead_depth, abs=1e-9)
    assert new.turret.position == sc.turret.position and new.turret.mode == sc.turret.mode
    for a, b in zip(sc.line_types, new.line_types):
        assert a.id == b.id and b.MBS == a.MBS
        assert np.allclose(_per_length(new, b), _per_length(sc, a), rtol=1e-9, atol=1e-12)
    # the rest comes from the vessel scenario unchanged
    assert new.vessel == sc.vessel and new.thrusters == sc.thrusters and new.sea_states == sc.sea_states
    assert new.riser == sc.riser and new.limits == sc.limits
    # and the imported mooring is the same system for the catenary
    T0 = MooringModel.from_scenario(sc).tensions(np.zeros(3))
    T1 = MooringModel.from_scenario(new).tensions(np.zeros(3))
    assert np.allclose(T1, T0, rtol=1e-9)


def test_round_trip_keeps_a_raised_anchor(tmp_path, capsys):
    """An anchor 30 m above the seabed (h_A = 30 m) is written as a Fixed point at its z and read
    back at the same place, by the functions and by the command line."""
    from tapm_opt.config import scenario_from_dict, scenario_to_dict
    from tapm_opt.config.moordyn import scenario_toml

    data = scenario_to_dict(load_scenario("aamo4"))
    depth = data["environment"]["water_depth"]
    x, y = data["lines"][0]["anchor"][:2]
    data["lines"][0]["anchor"] = [x, y, depth - 30.0]
    sc = scenario_from_dict(data)
    assert sc.line_arrays["h_A"].tolist() == [30.0, 0.0, 0.0, 0.0]
    vessel = _write(tmp_path, scenario_toml(data), "raised.toml")
    text = moordyn_text(sc)[0]
    anchor = parse_moordyn(text).point(1)
    assert anchor.kind == "fixed" and np.allclose(anchor.r, (x, -y, 30.0 - depth)), anchor
    path = _write(tmp_path, text)
    new = import_moordyn(path, vessel, mbs=MBS["aamo4"]).scenario
    assert validate(new) == []
    assert np.allclose(new.anchors, sc.anchors, atol=1e-6)
    assert np.array_equal(new.line_arrays["h_A"], sc.line_arrays["h_A"])
    T0 = MooringModel.from_scenario(sc).tensions(np.zeros(3))
    assert np.allclose(MooringModel.from_scenario(new).tensions(np.zeros(3)), T0, rtol=1e-9)
    out = tmp_path / "back.toml"
    code, _, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", str(vessel), "--out", str(out),
                       "--mbs", "cable=5e6")
    assert code == 0, err
    assert np.allclose(load_scenario(out).anchors, sc.anchors, atol=1e-6)


def test_point_below_wtrdpth_raises_the_depth_with_a_note(tmp_path):
    """A point below WtrDpth deepens the water, as MoorDyn-C does, and the import says so: the other
    anchors are then raised anchors, not silently moved."""
    text = _edit(HAND_WRITTEN, "1741.440      0.000  -800.0", "1741.440      0.000  -810.0")
    res = import_moordyn(_write(tmp_path, text), "fpso", mbs={"poly160": 1.5e7})
    assert res.scenario.environment.water_depth == 810.0
    assert any("WtrDpth = 800 m is above point 3" in n for n in res.notes), res.notes
    assert res.scenario.line_arrays["h_A"].tolist() == [10.0, 0.0] + [10.0] * 7


def test_coupled_points_reversed_line_and_turret_angle(tmp_path):
    """Fairleads given as global Coupled points, one line written fairlead first, and a vessel
    (a TOML file) whose turret is off the body origin at a turret angle: the same fairleads."""
    from tapm_opt.config import scenario_to_dict
    from tapm_opt.config.moordyn import scenario_toml

    sc = load_scenario("fpso_equivalent")
    sc = dataclasses.replace(sc, turret=dataclasses.replace(sc.turret, position=(60.0, 12.0),
                                                            angle=math.radians(30.0), mode="locked"))
    vessel = tmp_path / "vessel.toml"
    vessel.write_text(scenario_toml(scenario_to_dict(sc)), encoding="utf-8")
    text = moordyn_text(sc)[0]
    model = parse_moordyn(text)
    rows = []
    for row in text.splitlines():
        t = row.split()
        if len(t) == 9 and t[1] == "Body1":
            g = model.global_position(model.point(int(t[0])))
            row = f"{t[0]}  Coupled  {float(g[0])!r}  {float(g[1])!r}  {float(g[2])!r}  0  0  0  0"
        elif t[:4] == ["1", "cwc137", "1", "2"]:
            row = row.replace("1  cwc137  1  2", "1  cwc137  2  1")
        rows.append(row)
    text = re.sub(r"-+ BODIES -+\n.*?\n.*?\n.*?\n", "", "\n".join(rows) + "\n")
    res = import_moordyn(_write(tmp_path, text), vessel, mbs={"cwc137": 1.7e7})
    new = res.scenario
    assert any("line 1 runs from the fairlead" in n for n in res.notes)
    assert new.turret.position == (60.0, 12.0) and new.turret.angle == pytest.approx(math.radians(30.0))
    assert np.allclose(new.fairleads_T, sc.fairleads_T, atol=1e-6)
    assert np.allclose(new.anchors, sc.anchors, atol=1e-6)
    assert [ln.fairlead_angle for ln in new.lines] == pytest.approx([ln.fairlead_angle for ln in sc.lines], abs=1e-9)


def test_cli_export_import_validate_and_run(tmp_path, capsys):
    md_file, toml = tmp_path / "fpso.dat", tmp_path / "fpso_md.toml"
    code, out, err = run(capsys, "scenario", "export-moordyn", "fpso_equivalent", "--out", str(md_file))
    assert code == 0, err
    assert "dtM" in out and md_file.is_file()
    code, out, err = run(capsys, "scenario", "import-moordyn", str(md_file), "--vessel", "fpso_equivalent", "--out", str(toml),
                         "--mbs", "cwc137=1.699e7")
    assert code == 0, err
    assert "12 lines" in out
    code, out, err = run(capsys, "scenario", "validate", str(toml))
    assert code == 0 and "OK" in out
    code, out, err = run(capsys, "plant", "forced-motion", str(toml), "--amplitude", "2", "--period", "20",
                         "--duration", "10", "--segments", "4")
    assert code == 0, err
    assert "fpso_md" in out


# --------------------------------------------------------------------------------------------
# a hand-written MoorDyn file
# --------------------------------------------------------------------------------------------


def test_hand_written_file_imports(tmp_path, capsys):
    path = _write(tmp_path, HAND_WRITTEN)
    toml = tmp_path / "semi.toml"
    code, out, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out", str(toml),
                         "--mbs", "poly160=1.5e7", "--name", "fpso_800")
    assert code == 0, err
    assert "kbot" in out  # MoorDyn's default-like seabed is not the FEM's: said so
    sc = load_scenario(toml)
    env = sc.environment
    assert (env.water_depth, env.water_density, env.gravity) == (800.0, 1025.0, 9.81)
    assert sc.turret.fairlead_depth == 18.0 and sc.turret.fairlead_radius == pytest.approx(8.0, abs=1e-4)
    angles = [math.degrees(ln.fairlead_angle) for ln in sc.lines]
    assert np.allclose(angles, [355, 0, 5, 115, 120, 125, 235, 240, 245], atol=1e-3)
    assert sc.lines[0].anchor == pytest.approx((1735.161, -143.807, 800.0))  # NED: y = -Y
    assert all(ln.segments == 25 and ln.length == 1900 for ln in sc.lines)
    lt = sc.line_types[0]
    assert lt.diameter == 0.16 and lt.MBS == 1.5e7 and lt.MBS_std == pytest.approx(0.05 * 1.5e7)
    assert lt.submerged_weight == pytest.approx((120.0 - 1025.0 * math.pi * 0.16**2 / 4) * 9.81, rel=1e-12)
    assert lt.Cd_tangential == pytest.approx(math.pi * 0.05, rel=1e-12)  # CdAx acts on pi d
    assert lt.axial_damping_ratio == pytest.approx(1 / math.sqrt(2), rel=1e-12)
    assert sc.vessel == load_scenario("fpso").vessel
    # writing it back gives the user's own MoorDyn numbers (the import is the inverse of the export)
    back = parse_moordyn(moordyn_text(sc)[0])
    orig = parse_moordyn(HAND_WRITTEN)
    a, b = orig.line_types[0], back.line_types[0]
    for f in ("d", "mass", "EA", "BA", "Cd", "Ca", "CdAx", "CaAx"):
        assert getattr(b, f) == pytest.approx(getattr(a, f), rel=1e-12), f
    for la, lb in zip(orig.lines, back.lines):
        for pa, pb in ((la.a, lb.a), (la.b, lb.b)):
            assert back.global_position(back.point(pb)) == pytest.approx(orig.global_position(orig.point(pa)), abs=1e-6)


def test_hand_written_file_statics_match_moordyn(tmp_path):
    """MoorDyn-C on the user's own file and tapm_opt's catenary on the imported scenario give the
    same fairlead tensions (lumped-mass vs continuous line: < 0.3 %)."""
    path = _write(tmp_path, HAND_WRITTEN)
    sc = import_moordyn(path, "fpso", mbs={"poly160": 1.5e7}).scenario
    md = moordyn_module()
    from tapm_opt.plant.moordyn_reference import _console_to

    with _console_to(tmp_path / "console.txt"):
        s = md.Create(str(path))
        md.Init(s, [0.0] * 6, [0.0] * 6)
        T = []
        for i in range(len(sc.lines)):
            ln = md.GetLine(s, i + 1)
            n = md.GetLineN(ln)
            T.append(np.linalg.norm(np.subtract(md.GetLineNodeWeight(ln, n), md.GetLineNodeTen(ln, n))))
        md.Close(s)
    T_cat = MooringModel.from_scenario(sc).tensions(np.zeros(3))
    assert np.allclose(T, T_cat, rtol=3e-3)


# --------------------------------------------------------------------------------------------
# unsupported features and mistakes: one line, non-zero exit, the item named
# --------------------------------------------------------------------------------------------


def _edit(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


BAD_FILES = {
    "rod": (lambda t: _edit(t, "---------------------- POINTS", "---------------------- RODS ----\nID RodType Att Xa Ya Za "
            "Xb Yb Zb N Out\n(#) (-) (-) (m) (m) (m) (m) (m) (m) (-) (-)\n1 can Body1 0 0 0 0 0 -5 4 -\n"
            "---------------------- POINTS"), "rod 1"),
    "free point": (lambda t: _edit(t, "7     Fixed      -605.880", "7     Free       -605.880"), "point 7"),
    "clump weight": (lambda t: _edit(t, "-18.0    0     0      0     0   # fairlead", "-18.0    500   0      0     0   # fairlead"),
                     "point 2: Mass = 500"),
    "EI": (lambda t: _edit(t, "-1.0       0      1.2", "-1.0       1e12   1.2"),
           "line type 'poly160' (file line 7): EI = 1e+12 N m^2 matters: EI / (H l^2) ="),
    "dynamic damping of an elastic line": (lambda t: _edit(t, "1.2e9     -1.0", "1.2e9     -1.0|1e6"),
                                           "static|dynamic damping BA = -1.0|1e6 needs a viscoelastic EA"),
    "viscoelastic without a rest state": (lambda t: _edit(t, "1.2e9     -1.0", "1.2e9|1e9     -1.0"),
                                          "the dynamic stiffness EA_d = 1e+09 N must be greater than the static"),
    "second body": (lambda t: _edit(t, "1     Vessel     0      0     0      0       0      0       0     0     0        0"
                                       "       0      0\n",
                                    "1     Vessel     0      0     0      0       0      0       0     0     0        0"
                                    "       0      0\n2     Free  0 0 -50 0 0 0 1e5 0 0 0 0 0\n"), "body 2"),
    "fairlead depths": (lambda t: _edit(t, "99.4400     0.0000  -18.0", "99.4400     0.0000  -20.0"),
                        "fairlead depths differ"),
    "anchor above the fairleads": (lambda t: _edit(t, "1741.440      0.000  -800.0", "1741.440      0.000  -10.0"),
                                   "point 3 (anchor of line 2) is at z = -10 m, not below the fairleads"),
    "two anchors": (lambda t: _edit(t, "1     poly160     1        2 ", "1     poly160     1        3 "), "line 1"),
    "v1 layout": (lambda t: _edit(t, "-1.0       0      1.2    1.0    0.05    0.1", "-1.0   1.0  0.1  1.2  0.05"),
                  "v1 layout"),
    "undefined type": (lambda t: _edit(t, "9     poly160", "9     chain"), "line 9"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_unsupported_feature_is_a_one_line_error(tmp_path, capsys, case):
    edit, needle = BAD_FILES[case]
    path = _write(tmp_path, edit(HAND_WRITTEN))
    code, out, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out",
                         str(tmp_path / "x.toml"), "--mbs", "poly160=1.5e7")
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert needle in err, err
    assert "Traceback" not in err and not (tmp_path / "x.toml").exists()


def test_missing_breaking_strength_names_the_line_type(tmp_path, capsys):
    path = _write(tmp_path, HAND_WRITTEN)
    code, out, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out",
                         str(tmp_path / "x.toml"))
    assert code == 2 and err.count("\n") == 1
    assert "'poly160' has no breaking strength" in err and "--mbs poly160=NEWTONS" in err


def test_errors_raise_typed_exceptions():
    with pytest.raises(MoorDynError, match=r"x\.dat:7: line type 'poly160' Mass/m"):
        parse_moordyn(HAND_WRITTEN.replace("0.16    120.0", "0.16    abc"), source="x.dat")
    with pytest.raises(MoorDynError, match="no MoorDyn section header"):
        parse_moordyn("just some text\n")


def test_missing_moordyn_package_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "moordyn", None)
    with pytest.raises(MoorDynUnavailable, match="pip install"):
        moordyn_module()


# --------------------------------------------------------------------------------------------
# MoorDyn's force on the vessel
# --------------------------------------------------------------------------------------------


def test_coupled_body_force_is_end_node_force_minus_end_node_inertia():
    """Evidence for docs/moordyn.md: MoorDyn-C's coupled-body force is the sum of the end nodes'
    net force (tension with internal damping, submerged weight, drag) minus their mass and added
    mass times the body acceleration."""
    sc = load_scenario("aamo4")
    md = moordyn_module()
    A, w = 10.0, 2 * math.pi / 20.0  # fast, so drag and inertia show
    with MoorDynMooring(sc, segments=10) as mm:
        mm.init(np.zeros(3))
        h = mm.dtM
        x = mm.body_pose(np.zeros(3))
        xd_prev = np.zeros(6)
        for i in range(300):
            x_n = mm.body_pose(np.array([A * math.sin(w * (i + 1) * h), 0.0, 0.0]))
            xd = (x_n - x) / h
            f6 = mm.step(x, xd, h)
            a = (xd - xd_prev) / h
            x, xd_prev = x_n, xd
        fnet, mass, drag = np.zeros(3), np.zeros((3, 3)), np.zeros(3)
        for ln in mm.lines:
            n = md.GetLineN(ln)
            fnet += md.GetLineNodeForce(ln, n)
            mass += np.array(md.GetLineNodeM(ln, n))
            drag += md.GetLineNodeDrag(ln, n)
    inertia = mass @ a[:3]
    assert np.abs(inertia[0]) > 1e3 and np.abs(drag[0]) > 1e3
    assert f6[:3] == pytest.approx(fnet - inertia, rel=1e-9, abs=1e-6)


# --------------------------------------------------------------------------------------------
# MoorDyn against the FEM plant under forced surge
# --------------------------------------------------------------------------------------------


def _compare(name: str, *, duration: float, segments: int | None = None):
    kw = dict(dof="surge", amplitude=10.0, period=100.0, duration=duration, segments=segments, dt_out=1.0)
    m = moordyn_forced_motion(load_scenario(name), **kw)
    f = forced_motion(load_scenario(name), **kw)
    assert np.allclose(m.t, f.t) and np.allclose(m.eta, f.eta)
    d = m.T - f.T
    rms = np.sqrt((d**2).mean(axis=0)) / f.T.mean(axis=0)
    peak = np.abs(d).max(axis=0) / f.T.mean(axis=0)
    return m, f, rms, peak


def test_forced_surge_tensions_match_the_fem_aamo4():
    m, f, rms, peak = _compare("aamo4", duration=300.0)
    assert m.settle_converged
    assert rms.max() <= 0.02, rms
    assert peak.max() <= 0.05, peak
    assert m.damping == pytest.approx(f.damping, rel=0.05)
    # the surge force follows the FEM's too
    assert np.sqrt(((m.force - f.force)[:, 0] ** 2).mean()) <= 0.02 * np.abs(f.force[:, 0]).max()


@pytest.mark.slow
def test_forced_surge_tensions_match_the_fem_fpso():
    m, f, rms, peak = _compare("fpso", duration=500.0)
    assert rms.max() <= 0.02, rms
    assert peak.max() <= 0.05, peak
    assert m.damping == pytest.approx(f.damping, rel=0.05)


def test_locked_turret_yaw_moment_matches_the_fem():
    """The yaw moment about the body origin (turret lever arm plus MoorDyn's moment about the COT
    for a locked turret) and the yaw damping follow the FEM's."""
    sc = load_scenario("fpso")
    sc = dataclasses.replace(sc, turret=dataclasses.replace(sc.turret, mode="locked", angle=math.radians(20.0)))
    kw = dict(dof="yaw", amplitude=math.radians(5.0), period=100.0, duration=300.0, segments=10, dt_out=1.0)
    m, f = moordyn_forced_motion(sc, **kw), forced_motion(sc, **kw)
    d = m.T - f.T
    assert (np.sqrt((d**2).mean(axis=0)) / f.T.mean(axis=0)).max() <= 0.02
    assert np.sqrt(((m.force - f.force)[:, 2] ** 2).mean()) <= 0.02 * np.abs(f.force[:, 2]).max()
    assert m.damping == pytest.approx(f.damping, rel=0.05)


@pytest.mark.parametrize("command", ["export-moordyn", "import-moordyn"])
def test_cli_out_must_be_a_writable_file(capsys, tmp_path, command):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    head = ["scenario", command] + (["fpso"] if command == "export-moordyn" else
                                    [str(_write(tmp_path, HAND_WRITTEN)), "--vessel", "fpso", "--mbs", "chain=1.7e7"])
    for bad, says in (("", "is empty"), (str(blocker / "x.dat"), "is a file, not a directory")):
        code, out, err = run(capsys, *head, "--out", bad)
        assert code == 2 and says in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_riser_adapted_kept_or_dropped_in_another_depth(tmp_path, capsys):
    """fpso's 982 m riser does not fit 200 m of water: auto adapts it (length and top tension
    scaled by the hang-off-to-wellhead distance, a vertical riser from the hang-off to the seabed
    again), keep refuses it naming the field, drop leaves it out; each is said."""
    def at(depth: int) -> str:
        return re.sub(r"^800(\s+)WtrDpth", rf"{depth}\1WtrDpth", HAND_WRITTEN.replace("-800.0", f"-{depth}.0"),
                      flags=re.M)

    path = _write(tmp_path, at(200), "shallow.dat")
    fpso = load_scenario("fpso")
    rs0 = fpso.riser
    res = import_moordyn(path, "fpso", mbs={"poly160": 1.5e7})
    assert res.scenario.environment.water_depth == 200.0
    rs = res.scenario.riser
    top = max(fpso.turret.fairlead_depth, fpso.vessel.draught)
    k = (200.0 - top) / (1000.0 - top)   # fpso's riser hangs straight down from the turret
    assert rs.length == pytest.approx(rs0.length * k, rel=1e-9) and rs.length == pytest.approx(200.0 - top, abs=0.6)
    assert rs.top_tension == pytest.approx(rs0.top_tension * k, rel=1e-9)
    assert rs.top_tension / (rs.submerged_weight * rs.length) == pytest.approx(
        rs0.top_tension / (rs0.submerged_weight * rs0.length), rel=1e-9)   # the tensioners' ratio kept
    assert (rs.critical_bottom_angle, rs.diameter, rs.hangoff) == (rs0.critical_bottom_angle, rs0.diameter,
                                                                   rs0.hangoff)
    assert any("riser is adapted to the water depth 200 m (from 1000 m" in n for n in res.notes)
    assert import_moordyn(path, "fpso", mbs={"poly160": 1.5e7}, riser="adapt").scenario.riser == rs
    dropped = import_moordyn(path, "fpso", mbs={"poly160": 1.5e7}, riser="drop")
    assert dropped.scenario.riser is None and any("left out (--riser drop)" in n for n in dropped.notes)
    with pytest.raises(MoorDynError, match=r"riser.length = 982 m is over 3 x"):
        import_moordyn(path, "fpso", mbs={"poly160": 1.5e7}, riser="keep")
    with pytest.raises(MoorDynError, match="riser = 'cut' must be one of auto, keep, adapt, drop"):
        import_moordyn(path, "fpso", mbs={"poly160": 1.5e7}, riser="cut")
    # the same depth keeps it unchanged and says nothing
    same = import_moordyn(_write(tmp_path, at(1000), "deep.dat"), "fpso", mbs={"poly160": 1.5e7})
    assert same.scenario.riser == rs0 and not any("riser" in n for n in same.notes)
    # from the command line
    out = tmp_path / "s.toml"
    code, stdout, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out", str(out),
                            "--mbs", "poly160=1.5e7", "--riser", "drop")
    assert code == 0, err and "left out (--riser drop)" in stdout
    assert load_scenario(out).riser is None


def test_import_problems_are_all_said_in_the_files_terms(tmp_path):
    """A large CdAx (MoorDyn's axial drag on pi d) imports up to MoorDyn's 10; beyond it, and with a
    second bad coefficient, every problem is listed at once and named by the file's column."""
    row = "poly160    0.16    120.0      1.2e9     -1.0       0      1.2    1.0    0.05    0.1"
    assert row in HAND_WRITTEN
    ok = import_moordyn(_write(tmp_path, HAND_WRITTEN.replace(row, row.replace("0.05 ", "4.0  ")), "a.dat"), "fpso",
                        mbs={"poly160": 1.5e7})
    assert ok.scenario.line_types[0].Cd_tangential == pytest.approx(4.0 * math.pi, rel=1e-12)
    bad = HAND_WRITTEN.replace(row, row.replace("0.05 ", "12.0 ").replace("1.2    1.0", "1.2    40.0"))
    with pytest.raises(MoorDynError) as exc:
        import_moordyn(_write(tmp_path, bad, "b.dat"), "fpso", mbs={"poly160": 1.5e7})
    msg = str(exc.value)
    assert "(2 problems)" in msg, msg
    assert "line type 'poly160' (file line 7): CdAx = 12 gives tapm_opt's Cd_tangential" in msg, msg
    assert "line type 'poly160' (file line 7): Ca = 40 gives tapm_opt's Ca_normal" in msg, msg


def test_hull_fixed_fairleads_lock_the_turret_unless_they_form_one(tmp_path, capsys):
    """MoorDyn's fairleads on a coupled body are fixed to the hull. On one circle about fpso's
    centre of turret they are its turret (the vessel's free mode kept, nothing said); spread about
    the hull origin instead they make a spread mooring: the turret locked, said in a note, and the
    mooring's yaw stiffness is there (a free turret would have none about the COT)."""
    turret = import_moordyn(_write(tmp_path, HAND_WRITTEN, "t.dat"), "fpso", mbs={"poly160": 1.5e7})
    assert turret.scenario.turret.mode == "free" and not any("MoorDyn has no turret" in n for n in turret.notes)
    spread_text = HAND_WRITTEN
    # the whole mooring moved 91.44 m aft: the fairleads about the hull origin, the anchors with them
    for x in ("99.4096", "99.4400", "88.0591", "87.4400", "86.8514", "1735.161", "1741.440", "-605.880",
              "-733.560", "-854.961"):
        spread_text = spread_text.replace(f" {x} ", f" {float(x) - 91.44:.4f} ")
    path = _write(tmp_path, spread_text, "s.dat")
    spread = import_moordyn(path, "fpso", mbs={"poly160": 1.5e7})
    assert spread.scenario.turret.mode == "locked"
    note = next(n for n in spread.notes if "MoorDyn has no turret" in n)
    assert "not on one circle" in note and "--turret free" in note and "the vessel scenario's turret is free" in note
    free = import_moordyn(path, "fpso", mbs={"poly160": 1.5e7}, turret="free")
    assert free.scenario.turret.mode == "free" and any("no yaw moment" in n for n in free.notes)
    # the hull turned 5 deg about the centre of turret, which stays put: the locked mooring resists
    # the turn with a yaw moment about the COT, the free turret transmits none
    p = np.asarray(spread.scenario.turret.position, float)
    psi = math.radians(5.0)
    R = np.array([[math.cos(psi), -math.sin(psi)], [math.sin(psi), math.cos(psi)]])
    eta = np.array([*(p - R @ p), psi])

    def moment_about_cot(sc):
        X, Y, N = MooringModel.from_scenario(sc).force(eta)
        return N - (p[0] * Y - p[1] * X)

    m_locked, m_free = moment_about_cot(spread.scenario), moment_about_cot(free.scenario)
    assert m_locked < -1e6 and abs(m_free) < 1e-6 * abs(m_locked), (m_locked, m_free)   # restoring
    with pytest.raises(MoorDynError, match="turret = 'spread' must be one of auto, locked, free"):
        import_moordyn(path, "fpso", mbs={"poly160": 1.5e7}, turret="spread")
    out = tmp_path / "s.toml"
    code, stdout, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out", str(out),
                            "--mbs", "poly160=1.5e7", "--turret", "free")
    assert code == 0, err
    assert load_scenario(out).turret.mode == "free"


def test_every_problem_in_a_file_is_said_at_once(tmp_path, capsys):
    """A rod, a free point and a line type with a bending stiffness curve in one file: all three named
    with their file lines in one error, and the lines that use the refused type or point not named again."""
    text = HAND_WRITTEN
    for case in ("rod", "free point"):
        text = BAD_FILES[case][0](text)
    text = text.replace("---------------------- BODIES",
                        "stiff      0.16    120.0      1.2e9     -1.0       EI.txt 1.2    1.0    0.05    0.1\n"
                        "---------------------- BODIES", 1)
    text = text.replace("9     poly160", "9     stiff  ")
    path = _write(tmp_path, text)
    with pytest.raises(MoorDynError) as exc:
        parse_moordyn(path.read_text(), source=str(path))
    msg = str(exc.value)
    assert msg.startswith(f"{path}: 3 problems: "), msg
    for needle in ("rod 1: rods are not supported", "line type 'stiff': EI = 'EI.txt' names a bending stiffness curve",
                   "point 7 is a free point ('Free')"):
        assert needle in msg, (needle, msg)
    # three, not more: lines 4 (on point 7) and 9 (of type 'stiff') are not named again
    code, _, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out",
                       str(tmp_path / "x.toml"), "--mbs", "poly160=1.5e7")
    assert code == 2 and err.count("\n") == 1 and "3 problems" in err, err


def test_bending_stiffness_is_neglected_where_it_does_not_matter(tmp_path):
    """EI against H l^2 (H the horizontal tension at rest, l the segment length): the MHK_RM1 tidal
    line's 0.8 N m^2 on a chain is nothing (neglected, said); a stiff pipe's is refused with the ratio.
    The neglected line's statics are the cable's."""
    row = "poly160    0.16    120.0      1.2e9     -1.0       0      1.2"
    soft = import_moordyn(_write(tmp_path, HAND_WRITTEN.replace(row, row.replace(" 0      1.2", " 0.8    1.2")), "a.dat"),
                          "fpso", mbs={"poly160": 1.5e7})
    note = next(n for n in soft.notes if "bending stiffness EI = 0.8 N m^2" in n)
    assert "is neglected: EI / (H l^2) is at most" in note
    cable = import_moordyn(_write(tmp_path, HAND_WRITTEN, "b.dat"), "fpso", mbs={"poly160": 1.5e7})
    np.testing.assert_array_equal(MooringModel.from_scenario(soft.scenario).tensions(np.zeros(3)),
                                  MooringModel.from_scenario(cable.scenario).tensions(np.zeros(3)))
    H = MooringModel.from_scenario(cable.scenario).solve_lines(np.zeros(3)).HF.min()
    EI = 0.02 * H * (1900.0 / 25) ** 2     # twice the criterion on the slackest line
    with pytest.raises(MoorDynError, match=r"EI = .* N m\^2 matters: EI / \(H l\^2\) = 0.02 on line"):
        import_moordyn(_write(tmp_path, HAND_WRITTEN.replace(row, row.replace(" 0      1.2", f" {EI:.6e} 1.2")), "c.dat"),
                       "fpso", mbs={"poly160": 1.5e7})


def _moved(text: str, x0: float, y0: float, yaw_deg: float) -> str:
    """HAND_WRITTEN with its vessel body at (x0, y0) and yaw, the anchors moved with it (MoorDyn frame)."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    out = []
    for row in text.splitlines():
        t = row.split()
        if len(t) >= 9 and t[1] == "Fixed":
            x, y = float(t[2]), float(t[3])
            t[2], t[3] = f"{x0 + c * x - s * y:.6f}", f"{y0 + s * x + c * y:.6f}"
            row = "  ".join(t[:9])
        elif len(t) >= 8 and t[1] == "Vessel":
            t[2], t[3], t[7] = f"{x0:g}", f"{y0:g}", f"{yaw_deg:g}"
            row = "  ".join(t)
        out.append(row)
    return "\n".join(out) + "\n"


def test_a_vessel_off_the_files_origin_is_moved_to_the_field_zero_point(tmp_path, capsys):
    """The same mooring with its vessel body at (3000, -1200) m and yaw 30 deg imports as the one at the
    origin (said in a note); --recentre no keeps the file's coordinates. A file without a body whose
    one fairlead is 1360 m from the origin (MoorDyn's polyester test) is moved so the fairlead is at
    the centre of turret."""
    base = import_moordyn(_write(tmp_path, HAND_WRITTEN, "base.dat"), "fpso", mbs={"poly160": 1.5e7}).scenario
    path = _write(tmp_path, _moved(HAND_WRITTEN, 3000.0, -1200.0, 30.0), "moved.dat")
    res = import_moordyn(path, "fpso", mbs={"poly160": 1.5e7})
    assert any("the vessel body 1 is at x = 3000 m, y = -1200 m, yaw 30 deg" in n for n in res.notes), res.notes
    for a, b in zip(res.scenario.lines, base.lines):
        assert a.anchor == pytest.approx(b.anchor, abs=1e-4)
        assert a.fairlead_angle == pytest.approx(b.fairlead_angle, abs=1e-7)
    assert res.scenario.turret.fairlead_radius == pytest.approx(base.turret.fairlead_radius, abs=1e-4)
    with pytest.raises(MoorDynError, match="fairlead_radius"):
        import_moordyn(path, "fpso", mbs={"poly160": 1.5e7}, recentre="no")
    single = """--------------------- MoorDyn Input File ------------------------------------
one polyester line, its fairlead far from the origin
----------------------- LINE TYPES ------------------------------------------
TypeName         Diam    Mass/m     EA         BA/-zeta    EI         Cd     Ca     CdAx    CaAx
(name)           (m)     (kg/m)     (N)        (N-s/-)     (N-m^2)    (-)    (-)    (-)     (-)
poly             0.217   52.0       3.339E+08  -1.0        0.0        1.6    1.79   0.008   0.0
---------------------- POINT PROPERTIES --------------------------------
ID    Type      X       Y       Z         Mass   Volume  CdA    Ca
(#)   (-)       (m)     (m)     (m)       (kg)   (m^3)   (m^2)  (-)
1    Fixed      0.0     0.0     -372.3    0.0    0.0     0.0    0.0
2    Coupled    1360.0  0.0     -18.0     0.0    0.0     0.0    0.0
---------------------- LINES ----------------------------------------
ID   LineType         AttachA  AttachB   UnstrLen  NumSegs  LineOutputs
(#)  (name)           (#)      (#)       (m)       (-)      (-)
1    poly             1        2         1400.0    70       -
---------------------- OPTIONS -----------------------------------------
372.3         WtrDpth              water depth (m)
------------------------- need this line --------------------------------------
"""
    one = import_moordyn(_write(tmp_path, single, "single.dat"), "fpso", mbs={"poly": 1e7})
    sc = one.scenario
    assert sc.turret.fairlead_radius == pytest.approx(0.0, abs=1e-9)
    p = np.asarray(sc.turret.position)
    assert sc.lines[0].anchor[:2] == pytest.approx((p[0] - 1360.0, p[1]), abs=1e-6)   # the span kept
    assert any("moved by (-1268.56, -0) m" in n or "moved by (-1268.56, 0) m" in n for n in one.notes), one.notes
    code, _, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out",
                       str(tmp_path / "x.toml"), "--mbs", "poly160=1.5e7", "--recentre", "no")
    assert code == 2 and "fairlead_radius" in err
