"""MoorDyn files with free points: lines in series become composite lines, clump weights and buoys
point types; what does not reduce to lines in series is refused, every problem at once; composite
scenarios are written as sections joined by Free points that MoorDyn-C runs, and read back
unchanged.

MoorPy is not a dependency: its numbers below were measured once and are hard-coded (see
``MOORPY``). ``moordyn`` (MoorDyn-C, in the test extra) is imported directly: a missing wheel fails
these tests instead of skipping them.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import moordyn  # noqa: F401 - in the test extra; its absence must fail, not skip
import numpy as np
import pytest

from tapm_opt.cli import main
from tapm_opt.config import load_scenario, scenario_from_dict, scenario_to_dict, validate
from tapm_opt.config.loader import builtin_scenarios
from tapm_opt.config.moordyn import MoorDynError, moordyn_text, parse_moordyn, scenario_toml
from tapm_opt.models import MooringModel, composite
from tapm_opt.models.moordyn_import import composite_joints, export_moordyn, import_moordyn

# Three chain-wire-chain legs at 0, 120 and 240 deg about fpso's centre of turret (91.44 m forward
# of the hull origin, fairlead radius 8 m, 18 m deep) in 300 m of water, anchors 900 m out. Each leg:
# 120 m of chain from the anchor, a buoy (3 t, 12 m^3: 91.2 kN net buoyancy), 720 m of wire, a
# clump weight (8 t, 1 m^3: 68.4 kN net weight), 100 m of chain to the fairlead. The middle leg has a
# plain joint (nothing) instead of the clump, and the last leg's top chain is written fairlead first.
CWC = """\
--------------------- MoorDyn Input File ------------------------------------
Three chain-wire-chain legs with a clump weight and a buoy (the middle leg: a plain joint)
---------------------- LINE TYPES ----------------------------------------------
TypeName   Diam    Mass/m     EA       BA/-zeta    EI     Cd     Ca     CdAx    CaAx
(name)     (m)     (kg/m)     (N)      (N-s/-)   (N-m^2)  (-)    (-)    (-)     (-)
chain      0.2     300.0      1.5e9     -1.0       0      2.4    1.0    0.4     0.5
wire       0.09    40.0       6.0e8     -1.0       0      1.2    1.0    0.008   0.0
---------------------- BODIES --------------------------------------------------
ID   Attachment  X0     Y0    Z0     r0      p0     y0     Mass  CG*   I*      Volume   CdA*   Ca*
(#)   (word)     (m)    (m)   (m)   (deg)   (deg)  (deg)   (kg)  (m)  (kg-m^2)  (m^3)   (m^2)  (-)
1     Vessel     0      0     0      0       0      0       0     0     0        0       0      0
---------------------- POINTS --------------------------------------------------
ID   Attachment     X          Y         Z      Mass  Volume  CdA   Ca
(#)   (word/ID)    (m)        (m)       (m)     (kg)  (m^3)  (m^2)  (-)
1    Fixed      991.4400    -0.0000  -300.0   0      0     0    0
2    Free       871.4400    -0.0000  -250.0   3000   12.0  4.0  0.8   # buoy
3    Free       191.4400    -0.0000  -80.0    8000   1.0   2.0  1.0   # clump
4    Body1       99.4400    -0.0000  -18.0    0      0     0    0
5    Fixed     -358.5600  -779.4229  -300.0   0      0     0    0
6    Free      -298.5600  -675.4998  -250.0   3000   12.0  4.0  0.8   # buoy
7    Free        41.4400   -86.6025  -80.0    0      0     0    0     # plain joint
8    Body1       87.4400    -6.9282  -18.0    0      0     0    0
9    Fixed     -358.5600   779.4229  -300.0   0      0     0    0
10   Free      -298.5600   675.4998  -250.0   3000   12.0  4.0  0.8   # buoy
11   Free        41.4400    86.6025  -80.0    8000   1.0   2.0  1.0   # clump
12   Body1       87.4400     6.9282  -18.0    0      0     0    0
---------------------- LINES ---------------------------------------------------
ID   LineType   AttachA  AttachB  UnstrLen  NumSegs  LineOutputs
(#)   (name)     (ID)     (ID)      (m)       (-)      (-)
1    chain    1   2   120    12   -
2    wire     2   3   720    24   -
3    chain    3   4   100    5    -
4    chain    5   6   120    12   -
5    wire     6   7   720    24   -
6    chain    7   8   100    5    -
7    chain    9   10   120    12   -
8    wire     10   11   720    24   -
9    chain    12   11   100    5    -
---------------------- OPTIONS -------------------------------------------------
300           WtrDpth       water depth (m)
1025          rho           water density (kg/m^3)
9.81          g             gravity (m/s^2)
---------------------- OUTPUTS -------------------------------------------------
FairTen3
END
------------------------- need this line ---------------------------------------
"""
MBS = {"chain": 1.2e7, "wire": 8.0e6}

# MoorPy 1.3.0 on CWC, measured once (MoorPy is not installed in CI):
#   ms = moorpy.System(file="cwc.dat", depth=300, rho=1025, g=9.81); ms.initialize()
#   ms.bodyList[0].setPosition([x, -y, 0, 0, 0, 0])    # the vessel moved x north, y east (MoorDyn y = west)
#   ms.solveEquilibrium(tol=1e-10, maxIter=5000)       # the buoys and clumps settle
#   T = [ms.lineList[2].TB, ms.lineList[5].TB, ms.lineList[8].TA]   # each leg's fairlead tension [N]
#   F = ms.bodyList[0].getForces(lines_only=True)[:2] * [1, -1]      # mooring force north, east [N]
# Every clump stays 8 m or more above the seabed at these poses (MoorPy's points feel the seabed
# from 2 m above it, tapm_opt's only on it).
MOORPY = {
    (0.0, 0.0): ([1351640.23448961, 1224904.52563238, 1351642.99788631], [45436.75622863, -78703.53479789]),
    (10.0, 0.0): ([887873.95330138, 1946167.15669001, 2092922.31225588], [-1186556.39543888, -98115.94443142]),
    (0.0, 10.0): ([1356150.10516935, 813704.51130076, 3526485.02925551], [-786741.18263702, -2301910.6739951]),
}


def run(capsys, *args: str):
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


def _write(tmp_path: Path, text: str, name: str = "moor.dat") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _no_meta(sc) -> dict:
    """The scenario's fields, all but meta (an import's meta says where it came from)."""
    d = scenario_to_dict(sc)
    d.pop("meta")
    return d


# --------------------------------------------------------------------------------------------
# free points -> composite lines
# --------------------------------------------------------------------------------------------


def test_lines_in_series_become_composite_lines_with_point_types(tmp_path):
    res = import_moordyn(_write(tmp_path, CWC), "fpso", mbs=MBS)
    sc = res.scenario
    assert validate(sc) == []
    assert [ln.id for ln in sc.lines] == ["1-2-3", "4-5-6", "7-8-9"]   # the file's lines, anchor up
    for ln in sc.lines:
        assert [(s.type, s.length, s.segments) for s in ln.sections] == [("chain", 120.0, 12), ("wire", 720.0, 24),
                                                                         ("chain", 100.0, 5)]
    # identical free points share a point type; the middle leg's empty one is a plain joint
    assert [s.top for ln in sc.lines for s in ln.sections] == ["buoy2", "clump3", None, "buoy2", None, None,
                                                               "buoy2", "clump3", None]
    pts = {p.id: (p.mass, p.volume, p.CdA, p.Ca) for p in sc.point_types}
    assert pts == {"buoy2": (3000.0, 12.0, 4.0, 0.8), "clump3": (8000.0, 1.0, 2.0, 1.0)}
    assert any("buoy2 (points 2, 6, 10" in n and "clump3 (points 3, 11" in n for n in res.notes), res.notes
    assert any("line 9 of composite line 7-8-9 runs from the upper end (A) down" in n for n in res.notes)
    assert np.allclose(sc.anchors[0], [991.44, 0.0, 300.0])
    assert sc.turret.fairlead_radius == pytest.approx(8.0, abs=1e-5) and sc.turret.fairlead_depth == 18.0
    # the written TOML reads back as the same scenario
    toml = _write(tmp_path, res.toml, "cwc.toml")
    assert load_scenario(toml) == dataclasses.replace(sc, meta=load_scenario(toml).meta)


def test_composite_statics_match_the_solver_and_moorpy(tmp_path):
    sc = import_moordyn(_write(tmp_path, CWC), "fpso", mbs=MBS).scenario
    model = MooringModel.from_scenario(sc)
    # the solver on the file's numbers, by hand: leg 1 (0 deg) runs from the anchor at x = 991.44 m
    # to the fairlead at 99.44 m, 282 m up; w = (Mass/m - rho pi Diam^2 / 4) g, W = (Mass - rho Volume) g
    g, rho = 9.81, 1025.0
    w = [(m - rho * math.pi * d * d / 4.0) * g for m, d in ((300.0, 0.2), (40.0, 0.09), (300.0, 0.2))]
    leg1 = composite.CompositeLine(L=np.array([120.0, 720.0, 100.0]), EA=np.array([1.5e9, 6e8, 1.5e9]),
                                   w=np.array(w), CB=np.zeros(3),
                                   W=np.array([(3000.0 - rho * 12.0) * g, (8000.0 - rho * 1.0) * g]))
    T1 = float(composite.solve(991.44 - 99.44, 300.0 - 18.0, leg1).TF)
    assert model.tensions(np.zeros(3))[0] == pytest.approx(T1, rel=1e-12)
    for (x, y), (T_mp, F_mp) in MOORPY.items():
        eta = np.array([x, y, 0.0])
        assert np.allclose(model.tensions(eta), T_mp, rtol=1e-7, atol=0.0), (x, y)
        F = model.force(eta)[:2]
        assert np.linalg.norm(F - F_mp) <= 1e-7 * np.linalg.norm(F_mp), (x, y, F, F_mp)


# --------------------------------------------------------------------------------------------
# what is refused
# --------------------------------------------------------------------------------------------

# MoorPy's bridle test (tests/case8.dat), one leg: two lines from the hull meet at a connection
# point 4, one line from it to the anchor.
BRIDLE = """\
--------------------- MoorDyn Input File ------------------------------------
one bridled leg
---------------------- LINE TYPES -----------------------------------------------------
Name        Diam   MassDen  EA       BA/-zeta   EI    Cd    Ca   CdAx   CaAx
(-)         (m)    (kg/m)   (N)      (N-s/-)   (-)   (-)   (-)   (-)   (-)
polyester  0.15     25      30e6     -1       0     4    1.0   4     0.0
----------------------- BODIES ------------------------------------------------------
ID   Attachment    X0     Y0     Z0     r0      p0     y0     Mass   CG*     I*      Volume   CdA*   Ca*
(#)     (-)        (m)    (m)    (m)   (deg)   (deg)  (deg)   (kg)   (m)   (kg-m^2)  (m^3)   (m^2)  (-)
1     coupled      0.00   0.00   0.00   0.00   0.00   0.00     0.0    0.0   0.0      0.0     0.00  0.00
---------------------- POINTS --------------------------------
Node Type      X         Y         Z     M        V     CdA   CA
(-)  (-)      (m)       (m)       (m)   (kg)     (m^3) (m^2) (-)
1   Fixed    172.7    -100.0   -100.0     0      0      0     0
2   Body1    6.82     3.9375   -21.0      0      0      0     0
3   Body1    0.00     -7.875   -21.0      0      0      0     0
4   Connect  34.64    -20.00   -50.0      0      0      0     0
---------------------- LINES -----------------------------------------------------
Line       LineType EndA     EndB    UnstrLen  NumSegs    Flags/Outputs
(-)        (-)      (-)       (-)      (m)       (-)        (-)
1       polyester     4         2      45.36       4          -
2       polyester     4         3      45.36       4          -
3       polyester      1         4    160         10          -
---------------------- SOLVER OPTIONS ----------------------------------------
100      WtrDpth
------------------------- need this line --------------------------------------
"""


def test_a_bridle_is_refused_with_the_reason(tmp_path, capsys):
    path = _write(tmp_path, BRIDLE)
    with pytest.raises(MoorDynError) as exc:
        parse_moordyn(path.read_text(), source="bridle.dat")
    assert str(exc.value) == (
        "bridle.dat:17: point 4 is a free point ('Connect') joining 3 lines (1, 2, 3): a bridle or Y-connection is "
        "not supported; tapm_opt's composite lines are sections in series, each free point joining two lines")
    code, _, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out",
                       str(tmp_path / "x.toml"), "--mbs", "polyester=2e6")
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
    assert "point 4 is a free point ('Connect') joining 3 lines" in err and not (tmp_path / "x.toml").exists()


def test_every_problem_of_the_lines_is_said_at_once(tmp_path, capsys):
    """A bridle, a weight hanging at a line's free end, lines in series between two anchors, lines
    in series between two hull points, and a refused line type: all named at once, in the file's
    order, by MoorDyn's point and line numbers and file lines; the good leg is not named."""
    text = CWC.replace(
        "wire       0.09    40.0       6.0e8     -1.0       0      1.2    1.0    0.008   0.0\n",
        "wire       0.09    40.0       6.0e8     -1.0       0      1.2    1.0    0.008   0.0\n"
        "rope       0.12    12.0       2e8|1e8   -1.0       0      1.2    1.0    0.008   0.0\n").replace(
        "12   Body1       87.4400     6.9282  -18.0    0      0     0    0\n",
        "12   Body1       87.4400     6.9282  -18.0    0      0     0    0\n"
        "13   Fixed      500.0      500.0    -300.0   0      0     0    0\n"
        "14   Free       500.0      500.0    -200.0   5000   0     0    0\n"
        "15   Fixed      600.0      600.0    -300.0   0      0     0    0\n"
        "16   Free       650.0      650.0    -250.0   0      0     0    0\n"
        "17   Fixed      700.0      700.0    -300.0   0      0     0    0\n"
        "18   Free        60.0       60.0    -60.0    0      0     0    0\n").replace(
        "9    chain    12   11   100    5    -\n",
        "9    chain    12   11   100    5    -\n"
        "10   chain    13   14   100    5    -\n"       # a clump on a free end
        "11   chain    15   16   100    5    -\n"       # anchor - joint - anchor
        "12   chain    16   17   100    5    -\n"
        "13   chain    4    18   100    5    -\n"       # hull - joint - hull
        "14   chain    18   8    100    5    -\n"
        "15   rope     3    11   100    5    -\n")      # joins both clumps: each joins three lines now
    path = _write(tmp_path, text)
    with pytest.raises(MoorDynError) as exc:
        parse_moordyn(text, source="all.dat")
    msg = str(exc.value)
    said = [
        "line 8: line type 'rope': viscoelastic EA = 2e8|1e8: the dynamic stiffness EA_d = 1e+08 N must be greater",
        "line 18: point 3 is a free point ('Free') joining 3 lines (2, 3, 15): a bridle or Y-connection",
        "line 26: point 11 is a free point ('Free') joining 3 lines (8, 9, 15): a bridle or Y-connection",
        "line 29: point 14 is a free point ('Free') at the end of line 10 alone: a free end",
        "line 47: lines 11, 12 run in series between two fixed points (15 and 17) through free point 16",
        "line 49: lines 13, 14 run in series between two vessel points (4 and 8) through free point 18",
    ]
    assert msg.startswith("all.dat: 6 problems: line 8: "), msg
    at = [msg.index(s) for s in said]   # every one, in the file's order
    assert at == sorted(at), msg
    assert "line 4-5-6" not in msg and "lines 4, 5, 6" not in msg   # the good leg
    code, _, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out",
                       str(tmp_path / "x.toml"), "--mbs", "chain=1.2e7", "--mbs", "wire=8e6")
    assert code == 2 and err.count("\n") == 1 and "6 problems" in err, err


# --------------------------------------------------------------------------------------------
# writing composite lines: MoorDyn-C runs them, and they read back unchanged
# --------------------------------------------------------------------------------------------


def test_exported_composite_lines_run_in_moordyn_c(tmp_path):
    """The written file: line k is line k's fairlead section, the joints Free points carrying the
    point types. MoorDyn-C loads it; held for 100 s at the field zero point, its buoys and clumps
    stay within 0.1 m of the quasi-static equilibrium where they start (measured 2 cm; a clump
    twice as heavy sinks 2 m), and its fairlead tensions are the catenary's to 2e-3 (measured
    6e-4 with the file's 41 segments per line, 3.6e-4 with 100)."""
    sc = import_moordyn(_write(tmp_path, CWC), "fpso", mbs=MBS).scenario
    path = tmp_path / "out.dat"
    export_moordyn(sc, path, extra_options={"writeLog": 0})
    model = parse_moordyn(path.read_text())
    assert [ch.name for ch in model.chains] == ["4-5-1", "6-7-2", "8-9-3"]     # fairlead sections first
    assert [model.point(p).carries for ch in model.chains for p in ch.joints] == [
        (3000.0, 12.0, 4.0, 0.8), (8000.0, 1.0, 2.0, 1.0), (3000.0, 12.0, 4.0, 0.8), (0.0, 0.0, 0.0, 0.0),
        (3000.0, 12.0, 4.0, 0.8), (8000.0, 1.0, 2.0, 1.0)]
    joints = composite_joints(sc)
    cot = np.array([sc.turret.position[0], -sc.turret.position[1], 0.0, 0.0, 0.0, 0.0])
    old = os.getcwd()
    os.chdir(tmp_path)   # MoorDyn writes its output files next to the input
    try:
        s = moordyn.Create(str(path))
        try:
            assert (moordyn.GetNumberLines(s), moordyn.GetNumberPoints(s)) == (9, 12)
            moordyn.Init(s, cot, np.zeros(6))
            t = 0.0
            for _ in range(10):
                moordyn.Step(s, cot, np.zeros(6), t, 10.0)
                t += 10.0
            pos = [np.array(moordyn.GetPointPos(moordyn.GetPoint(s, 7 + j))) for j in range(6)]
            T = []
            for k in range(3):
                ln = moordyn.GetLine(s, k + 1)
                n = moordyn.GetLineN(ln)
                # tapm_opt's fairlead tension: the top segment's tension and the end node's weight
                T.append(np.linalg.norm(np.subtract(moordyn.GetLineNodeWeight(ln, n), moordyn.GetLineNodeTen(ln, n))))
        finally:
            moordyn.Close(s)
    finally:
        os.chdir(old)
    expected = np.concatenate([joints[k] for k in range(3)]) * [1.0, -1.0, -1.0]   # NED -> MoorDyn
    assert np.max(np.abs(np.array(pos) - expected)) < 0.1, (pos, expected)
    T0 = MooringModel.from_scenario(sc).tensions(np.zeros(3))
    print(f"MoorDyn-C against the catenary: fairlead tensions {np.array(T) / T0 - 1}, joints "
          f"{np.max(np.abs(np.array(pos) - expected)):.3g} m")
    assert np.allclose(T, T0, rtol=2e-3), (T, T0)


def _composite_scenario() -> dict:
    """fpso_equivalent (fpso's former homogeneous lines) with six composite lines (chain-wire-chain,
    a clump and a buoy, sections sharing the line's segments or giving their own) and six
    homogeneous ones with winches, ids that are not the file's numbers, a line type given by
    density with a max_strain."""
    d = scenario_to_dict(load_scenario("fpso_equivalent"))
    d["line_types"] = [
        dict(id="chain", diameter=0.2466, mass_per_length=374.0, submerged_weight=3190.0, EA=1.6e9, MBS=1.7e7,
             MBS_std=8.5e5, Cd_normal=2.4, Cd_tangential=1.15, Ca_normal=1.0, Ca_tangential=0.5,
             axial_damping_ratio=0.7071),
        dict(id="wire", diameter=0.12, mass_per_length=70.0, density=7800.0, EA=1.4e9, MBS=1.4e7, MBS_std=6.1e5,
             Cd_normal=1.2, Cd_tangential=0.008 * math.pi, Ca_normal=1.0, Ca_tangential=0.0, max_strain=0.008,
             axial_damping_ratio=0.5),
    ]
    d["point_types"] = [dict(id="clump", mass=30000.0, volume=3.8, CdA=2.0, Ca=1.0),
                        dict(id="buoy", mass=8000.0, volume=40.0, CdA=10.0, Ca=0.8)]
    for i, ln in enumerate(d["lines"]):
        ln["id"] = f"L{i + 1}"
        if i % 2:
            ln["type"] = "chain"
            continue
        for k in ("type", "length", "winch_max_rate", "min_length", "max_length"):
            ln.pop(k)
        ln["sections"] = [dict(type="chain", length=700.0, top="clump"), dict(type="wire", length=1400.0),
                          dict(type="chain", length=200.0)]
        if i % 4 == 0:
            ln["sections"][1]["top"] = "buoy"
        ln["segments"] = 30
        if i == 4:   # sections with their own segments, the line's own count kept too
            for s, n in zip(ln["sections"], (10, 20, 4)):
                s["segments"] = n
    return d


def test_round_trip_keeps_every_field(tmp_path):
    """import(export(scenario)) with the scenario as the vessel: every field the same but meta (an
    import's meta says where it came from), without --mbs (the front matter gives MBS and
    MBS_std): the built-ins, and a composite scenario."""
    data = _composite_scenario()
    sc = scenario_from_dict(data)
    assert validate(sc) == []
    vessel = _write(tmp_path, scenario_toml(data), "composite.toml")
    cases = [(name, load_scenario(name), name) for name in builtin_scenarios()] + [("composite", sc, str(vessel))]
    assert len(cases) >= 4
    for name, s, vessel_name in cases:
        path = tmp_path / f"{name}.dat"
        export_moordyn(s, path)
        res = import_moordyn(path, vessel_name)
        assert _no_meta(res.scenario) == _no_meta(s), name
        assert res.scenario == dataclasses.replace(s, meta=res.scenario.meta), name
        assert any("max_strain 0.005" in n for n in res.notes) == (name == "ren8")
    new = res.scenario   # the composite one: the structure itself
    assert [ln.composite for ln in new.lines] == [True, False] * 6
    assert new.lines[4].sections[0].segments == 10 and new.lines[4].segments == 30
    assert new.lines[0].sections[0].segments is None and new.line_type_by_id("wire").density == 7800.0
    assert new.line_type_by_id("wire").max_strain == 0.008 and new.lines[1].winch_max_rate == 0.15
    # --mbs still overrides the front matter
    over = import_moordyn(tmp_path / "composite.dat", str(vessel), mbs={"wire": 1.5e7}, mbs_cov=0.1)
    assert over.scenario.line_type_by_id("wire").MBS == 1.5e7
    assert over.scenario.line_type_by_id("wire").MBS_std == pytest.approx(1.5e6)
    assert over.scenario.line_type_by_id("chain").MBS == 1.7e7


def test_an_edited_front_matter_is_not_used(tmp_path):
    """tapm_opt's own line-type values are used only while they give the file's MoorDyn row: a
    changed Cd in the table wins, and the import says why."""
    sc = load_scenario("aamo4")
    text = moordyn_text(sc)[0]
    row = next(r for r in text.splitlines() if r.startswith("cable  "))
    cols = row.split()
    cols[6] = "1.5"   # Cd
    res = import_moordyn(_write(tmp_path, text.replace(row, "  ".join(cols))), "aamo4")
    assert res.scenario.line_types[0].Cd_normal == 1.5
    assert res.scenario.line_types[0].diameter != sc.line_types[0].diameter   # MoorDyn's volume-equivalent one
    assert any("do not give the MoorDyn row" in n for n in res.notes), res.notes


def test_cli_writes_and_reads_composite_lines(tmp_path, capsys):
    toml = tmp_path / "cwc.toml"
    code, out, err = run(capsys, "scenario", "import-moordyn", str(_write(tmp_path, CWC)), "--vessel", "fpso",
                         "--out", str(toml), "--mbs", "chain=1.2e7", "--mbs", "wire=8e6")
    assert code == 0, err
    assert "3 lines, 2 line types" in out and "clump3" in out
    md_file = tmp_path / "cwc_out.dat"
    code, out, err = run(capsys, "scenario", "export-moordyn", str(toml), "--out", str(md_file))
    assert code == 0, err
    assert "start on the straight line" not in out   # the command starts the free points at equilibrium
    back = tmp_path / "back.toml"
    code, out, err = run(capsys, "scenario", "import-moordyn", str(md_file), "--vessel", str(toml), "--out", str(back))
    assert code == 0, err
    assert load_scenario(back) == dataclasses.replace(load_scenario(toml), meta=load_scenario(back).meta)
    # written without the equilibrium, the free points start on the straight line, and the export says so
    assert any("start on the straight line" in n for n in moordyn_text(load_scenario(toml))[1].notes)


# --------------------------------------------------------------------------------------------
# buoyant line types: sections of lazy waves
# --------------------------------------------------------------------------------------------

# Three lazy-wave legs at 0, 240 and 120 deg about fpso's centre of turret (fairlead radius 8 m,
# 18 m deep) in 300 m, anchors 700 m from the fairleads: 250 m of chain from the anchor (on the
# seabed), 150 m of buoyant line (Diam 0.6 m, 150 kg/m: 1371.6 N/m of lift) arching up, 450 m of
# wire to the vessel, sagging below the arch. The free points start near their equilibrium.
LAZY = """\
--------------------- MoorDyn Input File ------------------------------------
Three lazy-wave legs: chain on the seabed, buoyant line, wire to the vessel
---------------------- LINE TYPES ----------------------------------------------
TypeName   Diam    Mass/m     EA       BA/-zeta    EI     Cd     Ca     CdAx    CaAx
(name)     (m)     (kg/m)     (N)      (N-s/-)   (N-m^2)  (-)    (-)    (-)     (-)
chain      0.2     300.0      1.5e9     -1.0       0      2.4    1.0    0.4     0.5
float      0.6     150.0      3.0e8     -1.0       0      1.2    1.0    0.01    0.0
wire       0.09    40.0       6.0e8     -1.0       0      1.2    1.0    0.008   0.0
---------------------- BODIES --------------------------------------------------
ID   Attachment  X0     Y0    Z0     r0      p0     y0     Mass  CG*   I*      Volume   CdA*   Ca*
(#)   (word)     (m)    (m)   (m)   (deg)   (deg)  (deg)   (kg)  (m)  (kg-m^2)  (m^3)   (m^2)  (-)
1     Vessel     0      0     0      0       0      0       0     0     0        0       0      0
---------------------- POINTS --------------------------------------------------
ID   Attachment     X          Y         Z      Mass  Volume  CdA   Ca
(#)   (word/ID)    (m)        (m)       (m)     (kg)  (m^3)  (m^2)  (-)
1    Fixed      799.4400     0.0000   -300.0   0     0     0    0
2    Free       571.7951     0.0000   -256.2   0     0     0    0
3    Free       465.8945     0.0000   -179.4   0     0     0    0
4    Body1       99.4400     0.0000    -18.0   0     0     0    0
5    Fixed     -262.5600  -613.1460   -300.0   0     0     0    0
6    Free      -148.7375  -415.9997   -256.2   0     0     0    0
7    Free       -95.7872  -324.2871   -179.4   0     0     0    0
8    Body1       87.4400    -6.9282    -18.0   0     0     0    0
9    Fixed     -262.5600   613.1460   -300.0   0     0     0    0
10   Free      -148.7375   415.9997   -256.2   0     0     0    0
11   Free       -95.7872   324.2871   -179.4   0     0     0    0
12   Body1       87.4400     6.9282    -18.0   0     0     0    0
---------------------- LINES ---------------------------------------------------
ID   LineType   AttachA  AttachB  UnstrLen  NumSegs  LineOutputs
(#)   (name)     (ID)     (ID)      (m)       (-)      (-)
1    chain    1   2   250    10   -
2    float    2   3   150    10   -
3    wire     3   4   450    15   -
4    chain    5   6   250    10   -
5    float    6   7   150    10   -
6    wire     7   8   450    15   -
7    chain    9   10  250    10   -
8    float    10  11  150    10   -
9    wire     11  12  450    15   -
---------------------- OPTIONS -------------------------------------------------
300           WtrDpth       water depth (m)
1025          rho           water density (kg/m^3)
9.81          g             gravity (m/s^2)
---------------------- OUTPUTS -------------------------------------------------
FairTen3
END
------------------------- need this line ---------------------------------------
"""
LAZY_MBS = {"chain": 1.2e7, "float": 5.0e6, "wire": 8.0e6}

# MoorPy 1.3.0 on LAZY, measured once as MOORPY above (System(file, depth=300, rho=1025, g=9.81),
# the body moved, solveEquilibrium(tol=1e-10, maxIter=5000); T = each leg's TB, F the body's
# lines-only force north, east). Measured agreement: tensions 3e-12, force 1e-10 of its size off
# rest (at rest it is 0.007 N, round-off of three 128 kN legs).
MOORPY_LAZY = {
    (0.0, 0.0): ([128435.73372228243, 128435.74020773849, 128435.74020773849], [-0.006954735872568563, 0.0]),
    (6.0, 0.0): ([125993.18550778771, 129779.47170182175, 129779.47170182175], [-5769.5882424528245, 0.0]),
    (0.0, 6.0): ([128446.83483180743, 126306.71205037473, 130804.52373909787], [-92.1840362578223, -5861.935025805571]),
}


def test_a_buoyant_line_type_imports_as_the_arch_of_a_lazy_wave(tmp_path):
    """A buoyant MoorDyn line type becomes a line type given by its density (Mass/m over the
    displaced area, the same submerged weight), a section of the composite line; the leg's
    fairlead tension is composite.solve's on the file's numbers, the statics MoorPy's, and the
    written TOML reads back as the same scenario."""
    res = import_moordyn(_write(tmp_path, LAZY), "fpso", mbs=LAZY_MBS)
    sc = res.scenario
    assert validate(sc) == []
    g, rho = 9.81, 1025.0
    fl = sc.line_type_by_id("float")
    assert fl.submerged_weight is None and fl.density == pytest.approx(150.0 / (math.pi * 0.09), rel=1e-15)
    assert fl.w(sc.environment) == pytest.approx((150.0 - rho * math.pi * 0.09) * g, rel=1e-12)
    assert any("line type 'float' is buoyant (Mass/m 150 kg/m, Diam 0.6 m: submerged weight -1371.55 N/m), given by "
               "its density 530.516 kg/m^3" in n for n in res.notes), res.notes
    assert [[s.type for s in ln.sections] for ln in sc.lines] == [["chain", "float", "wire"]] * 3
    w = [(m - rho * math.pi * d * d / 4.0) * g for m, d in ((300.0, 0.2), (150.0, 0.6), (40.0, 0.09))]
    leg = composite.CompositeLine(L=np.array([250.0, 150.0, 450.0]), EA=np.array([1.5e9, 3e8, 6e8]), w=np.array(w),
                                  CB=np.zeros(3), W=np.zeros(2))
    model = MooringModel.from_scenario(sc)
    assert model.tensions(np.zeros(3))[0] == pytest.approx(float(composite.solve(700.0, 282.0, leg).TF), rel=1e-12)
    for (x, y), (T_mp, F_mp) in MOORPY_LAZY.items():
        eta = np.array([x, y, 0.0])
        assert np.allclose(model.tensions(eta), T_mp, rtol=1e-9, atol=0.0), (x, y)
        assert np.linalg.norm(model.force(eta)[:2] - F_mp) <= 1e-7 * sum(T_mp), (x, y)
    toml = _write(tmp_path, res.toml, "lazy.toml")
    assert load_scenario(toml) == dataclasses.replace(sc, meta=load_scenario(toml).meta)


def test_a_lazy_wave_round_trips_through_moordyn(tmp_path):
    """Written as MoorDyn (the buoyant type's row from its density) and read back: the same scenario."""
    sc = import_moordyn(_write(tmp_path, LAZY), "fpso", mbs=LAZY_MBS).scenario
    vessel = _write(tmp_path, scenario_toml(scenario_to_dict(sc)), "lazy.toml")
    export_moordyn(sc, tmp_path / "again.dat")
    again = import_moordyn(tmp_path / "again.dat", str(vessel)).scenario
    assert _no_meta(again) == _no_meta(sc)


@pytest.mark.parametrize("edit, said", [
    ((lambda t: t.replace("12   Body1       87.4400     6.9282    -18.0   0     0     0    0\n",
                          "12   Body1       87.4400     6.9282    -18.0   0     0     0    0\n"
                          "13   Fixed      500.0      500.0    -300.0   0     0     0    0\n"
                          "14   Body1       95.0       0.0      -18.0   0     0     0    0\n").replace(
        "9    wire     11  12  450    15   -\n", "9    wire     11  12  450    15   -\n10   float    13  14  700    20   -\n")),
     ("line 10 (file line 42): type = 'float' is not heavier than water (submerged weight -1371.55 N/m): a line of "
      "it floats and cannot hang from its fairlead")),
    ((lambda t: t.replace("1    chain    1   2   250    10   -", "1    float    1   2   250    10   -")),
     ("line 1-2-3, section 0 (MoorDyn line 1, file line 31): type = 'float' is not heavier than water (submerged "
      "weight -1371.55 N/m) and is the line's anchor section")),
])
def test_a_line_that_would_float_is_refused_with_the_reason(tmp_path, capsys, edit, said):
    """A leg all of the buoyant type (a line that floats), or one whose anchor section is buoyant:
    refused, in the file's terms, with the reason."""
    path = _write(tmp_path, edit(LAZY))
    with pytest.raises(MoorDynError, match="the imported scenario is invalid") as exc:
        import_moordyn(path, "fpso", mbs=LAZY_MBS)
    assert said in str(exc.value), str(exc.value)
    code, _, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out",
                       str(tmp_path / "x.toml"), *[f"--mbs={k}={v}" for k, v in LAZY_MBS.items()])
    assert code == 2 and said in err and not (tmp_path / "x.toml").exists(), err


def test_an_exported_lazy_wave_runs_in_moordyn_c_as_in_the_fem(tmp_path):
    """MoorDyn-C (its own lumped-mass lines, buoyant ones included) holds the exported lazy waves
    for 300 s at the field zero point: its joints and fairlead tensions are the settled FEM's at
    the same segments (10 / 10 / 15) to 0.2 m and 5e-4 (measured 9 cm, 1.6e-4), both 1.4 m and
    1.1e-3 from the quasi-static shape (the arch's 15 m segments)."""
    from tapm_opt.plant.mooring_fem import MooringFEM

    sc = import_moordyn(_write(tmp_path, LAZY), "fpso", mbs=LAZY_MBS).scenario
    path = tmp_path / "out.dat"
    export_moordyn(sc, path, extra_options={"writeLog": 0})
    cot = np.array([sc.turret.position[0], -sc.turret.position[1], 0.0, 0.0, 0.0, 0.0])
    old = os.getcwd()
    os.chdir(tmp_path)   # MoorDyn writes its output files next to the input
    try:
        s = moordyn.Create(str(path))
        try:
            moordyn.Init(s, cot, np.zeros(6))
            t = 0.0
            for _ in range(30):
                moordyn.Step(s, cot, np.zeros(6), t, 10.0)
                t += 10.0
            pos = np.array([moordyn.GetPointPos(moordyn.GetPoint(s, 7 + j)) for j in range(6)]) * [1.0, -1.0, -1.0]
            T = []
            for k in range(3):
                ln = moordyn.GetLine(s, k + 1)
                n = moordyn.GetLineN(ln)
                T.append(np.linalg.norm(np.subtract(moordyn.GetLineNodeWeight(ln, n), moordyn.GetLineNodeTen(ln, n))))
        finally:
            moordyn.Close(s)
    finally:
        os.chdir(old)
    m = MooringFEM(sc)
    m.initialise(np.zeros(3))
    m.settle(np.zeros(3), tol=1e-9, speed_tol=1e-5, max_time=3000.0)
    fem = m.fem
    assert fem.lines.sections[0]["segments"].tolist() == [10, 10, 15]
    r = np.concatenate([fem.r[fem.node_start[j] + np.cumsum(fem.lines.sections[j]["segments"])[:-1]] for j in range(3)])
    T_fem = fem.fairlead_tension()
    T0 = MooringModel.from_scenario(sc).tensions(np.zeros(3))
    qs = np.concatenate([composite_joints(sc)[k] for k in range(3)])
    print(f"MoorDyn-C against the FEM: joints {np.max(np.abs(pos - r)):.3g} m, tensions {np.array(T) / T_fem - 1}; "
          f"the FEM against the statics: joints {np.max(np.abs(r - qs)):.3g} m, tensions {T_fem / T0 - 1}")
    assert np.max(np.abs(pos - r)) < 0.2
    assert np.allclose(T, T_fem, rtol=5e-4)
    assert np.allclose(T_fem, T0, rtol=2e-3) and np.max(np.abs(r - qs)) < 2.0
