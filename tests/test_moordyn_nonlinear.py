"""MoorDyn line types whose EA is a tension-strain curve (nonlinear EA): import, export, MoorDyn-C.

* a line type's EA column naming a curve file next to the input (MoorDyn-C's rule; MoorPy's
  quoted name too) imports as the line type's ``EA_table``, its EA the curve's secant;
* the imported lines' quasi-static tensions are MoorDyn-C's settled ones on the same file (its
  lumped-mass lines with the curve), and not those of the secant's constant EA;
* a bad curve or a missing file is refused naming the file, its row and value;
* the export writes the curve file next to the input, as MoorDyn-C 2.7 reads it (no line break
  after the last row), MoorDyn-C runs it to the quasi-static tensions, and it reads back to the
  same line type.

``moordyn`` is a test dependency: its absence fails these tests instead of skipping them.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import moordyn  # noqa: F401 - in the test extra; its absence must fail, not skip
import numpy as np
import pytest

from tapm_opt.config import scenario_from_dict
from tapm_opt.config.moordyn import MAX_CURVE_ROWS, MoorDynError, moordyn_text, parse_moordyn, read_moordyn
from tapm_opt.models import MooringModel
from tapm_opt.models.moordyn_import import export_moordyn, import_moordyn

CURVE = [[0.0, 0.0], [0.002, 0.6e6], [0.005, 2.4e6], [0.01, 7.0e6], [0.02, 2.2e7]]
"""A rope that stiffens strongly with load: slopes 300, 600, 920 and 1500 MN, secant 1100 MN."""

# three legs of 1900 m in 800 m of water from a turret 8 m in radius, 91.44 m forward of the hull
# origin (a coupled body), their EA column naming the curve file
LEGS = """\
--------------------- MoorDyn Input File ------------------------------------
Turret FPSO, 3 legs of a synthetic rope, 800 m water depth
---------------------- LINE TYPES ----------------------------------------------------------------------
TypeName   Diam    Mass/m     EA         BA/-zeta    EI     Cd     Ca     CdAx    CaAx
(name)     (m)     (kg/m)     (N)        (N-s/-)   (N-m^2)  (-)    (-)    (-)     (-)
rope       0.16    120.0      {ea}    -1.0       0      1.2    1.0    0.05    0.1
---------------------- BODIES ---------------------------------------------------------------------------
ID   Attachment  X0     Y0    Z0     r0      p0     y0     Mass  CG*   I*      Volume   CdA*   Ca*
(#)   (word)     (m)    (m)   (m)   (deg)   (deg)  (deg)   (kg)  (m)  (kg-m^2)  (m^3)   (m^2)  (-)
1     Vessel     0      0     0      0       0      0       0     0     0        0       0      0
---------------------- POINTS ---------------------------------------------------------------------------
ID   Attachment     X          Y         Z      Mass  Volume  CdA   Ca
(#)   (word/ID)    (m)        (m)       (m)     (kg)  (m^3)  (m^2)  (-)
1     Fixed      1741.440      0.000  -800.0    0     0      0     0
2     Body1        99.4400     0.0000  -18.0    0     0      0     0
3     Fixed      -733.560  -1428.942  -800.0    0     0      0     0
4     Body1        87.4400    -6.9282  -18.0    0     0      0     0
5     Fixed      -733.560   1428.942  -800.0    0     0      0     0
6     Body1        87.4400     6.9282  -18.0    0     0      0     0
---------------------- LINES ----------------------------------------------------------------------------
ID   LineType   AttachA  AttachB  UnstrLen  NumSegs  LineOutputs
(#)   (name)     (ID)     (ID)      (m)       (-)      (-)
1     rope        1        2        1900      {n}       -
2     rope        3        4        1900      {n}       -
3     rope        5        6        1900      {n}       -
---------------------- OPTIONS -----------------------------------------
0             writeLog      Write log file
0.002         dtM           time step to use in mooring integration (s)
RK4           tScheme       time integrator
3.0e6         kbot          bottom stiffness (Pa/m)
3.0e5         cbot          bottom damping (Pa-s/m)
800           WtrDpth       water depth (m)
1025          rho           water density (kg/m^3)
9.81          g             gravity (m/s^2)
1.0           dtIC          time interval for analyzing convergence during IC gen (s)
120           TmaxIC        max time for ic gen (s)
0.001         threshIC      threshold for IC convergence (-)
------------------------- need this line -------------------------------------
"""
MBS = {"rope": 2.5e7}


def curve_text(rows, *, end="") -> str:
    """A curve file as MoorDyn's documentation shows it: three header lines, then ``strain tension``."""
    return "----Rope----\nStrain    Tension\n(-)       (N)\n" + "\n".join(f"{a:g} {b:g}" for a, b in rows) + end


def write_legs(tmp_path: Path, ea: str = "rope_EA.txt", rows=CURVE, n: int = 40) -> Path:
    path = tmp_path / "legs.dat"
    path.write_text(LEGS.format(ea=ea, n=n))
    (tmp_path / "rope_EA.txt").write_text(curve_text(rows))
    return path


def moordyn_fairlead_tensions(path: Path, body=np.zeros(6), seconds: float = 50.0) -> np.ndarray:
    """MoorDyn-C's fairlead tensions (tapm_opt's: the top segment's tension and the end node's
    weight) after its initial-condition solve and ``seconds`` held at ``body``."""
    old = os.getcwd()
    os.chdir(path.parent)   # MoorDyn writes its output files next to the input
    try:
        s = moordyn.Create(str(path))
        try:
            moordyn.Init(s, body, np.zeros(6))
            t = 0.0
            while t < seconds:
                moordyn.Step(s, body, np.zeros(6), t, 10.0)
                t += 10.0
            T = []
            for k in range(moordyn.GetNumberLines(s)):
                ln = moordyn.GetLine(s, k + 1)
                n = moordyn.GetLineN(ln)
                T.append(np.linalg.norm(np.subtract(moordyn.GetLineNodeWeight(ln, n), moordyn.GetLineNodeTen(ln, n))))
        finally:
            moordyn.Close(s)
    finally:
        os.chdir(old)
    return np.array(T)


def test_a_curve_file_imports_as_the_line_types_table(tmp_path):
    path = write_legs(tmp_path)
    model = read_moordyn(path)
    lt = model.line_types[0]
    assert lt.EA_table == tuple(tuple(r) for r in CURVE) and lt.EA_file == "rope_EA.txt"
    assert lt.EA == pytest.approx(1.1e9)
    r = import_moordyn(path, "fpso", mbs=MBS)
    t = r.scenario.line_types[0]
    assert t.EA_table == tuple(tuple(r) for r in CURVE) and t.EA == pytest.approx(1.1e9)
    assert "EA_table" in r.data["line_types"][0] and "EA" not in r.data["line_types"][0]
    assert any("tension-strain curve rope_EA.txt" in n for n in r.notes)
    assert "EA curve rope_EA.txt (5 rows, secant 1.1e+09 N)" in r.toml
    # read next to the file, not from the working directory; MoorPy's quoted name read too
    other = tmp_path / "elsewhere"
    other.mkdir()
    old = os.getcwd()
    os.chdir(other)
    try:
        assert read_moordyn(path).line_types[0].EA_table is not None
    finally:
        os.chdir(old)
    quoted = parse_moordyn(LEGS.format(ea='"rope_EA.txt"', n=40), source=str(path))
    assert quoted.line_types[0].EA_table == lt.EA_table
    assert any("quoted" in n for n in quoted.notes)


def test_imported_tensions_are_moordyn_c_s_on_the_same_file(tmp_path):
    """The import's quasi-static fairlead tensions (the catenary of the curve, the lines touching
    down) against MoorDyn-C's settled lumped-mass lines on the very file (40 segments): within 2e-3
    (measured 5.9e-4, the lumped-mass chords' error); the secant's constant EA is 2.4 % off."""
    path = write_legs(tmp_path)
    sc = import_moordyn(path, "fpso", mbs=MBS).scenario
    model = MooringModel.from_scenario(sc)
    T = model.tensions(np.zeros(3))
    assert set(model.solve_lines(np.zeros(3)).regime_names()) == {"touchdown"}
    Tm = moordyn_fairlead_tensions(path)
    print(f"import against MoorDyn-C on a file with a tension-strain curve: {T / Tm - 1}")
    assert np.allclose(T, Tm, rtol=2e-3), (T, Tm)
    d = import_moordyn(path, "fpso", mbs=MBS).data
    d["line_types"][0].pop("EA_table")
    d["line_types"][0]["EA"] = 1.1e9
    T_secant = MooringModel.from_scenario(scenario_from_dict(d)).tensions(np.zeros(3))
    assert np.all(np.abs(T_secant / Tm - 1.0) > 0.02), T_secant / Tm - 1


@pytest.mark.parametrize("rows, ea, needle", [
    (CURVE, "nothere.txt", "legs.dat:6: line type 'rope': EA = 'nothere.txt' names a tension-strain curve, but"),
    ([[0.0, 0.0], [0.002, 6e5], [0.001, 9e5]], "rope_EA.txt",
     "rope_EA.txt, row 2 = [0.001, 900000] does not increase the strain of row 1 [0.002, 600000]"),
    ([[0.001, 0.0], [0.002, 6e5]], "rope_EA.txt", "rope_EA.txt, row 0 = [0.001, 0] must be [0, 0]"),
    ([[0.0, 0.0]], "rope_EA.txt", "rope_EA.txt has 1 row: a tension-strain table needs at least 2"),
])
def test_a_bad_curve_is_refused_naming_the_file_and_row(tmp_path, rows, ea, needle):
    path = write_legs(tmp_path, ea=ea, rows=rows)
    with pytest.raises(MoorDynError) as exc:
        read_moordyn(path)
    assert needle in str(exc.value), str(exc.value)


def test_a_curve_row_that_is_not_two_numbers_is_refused(tmp_path):
    path = write_legs(tmp_path)
    (tmp_path / "rope_EA.txt").write_text(curve_text(CURVE[:3]) + "\n0.01 lots\n")
    with pytest.raises(MoorDynError, match=r"line 7 of rope_EA.txt \('0.01 lots'\) is not a row of two numbers"):
        read_moordyn(path)


def test_a_curve_as_viscoelastic_static_ea_and_syrope_stay_refused(tmp_path):
    """A viscoelastic EA reads as its static stiffness (tests/test_moordyn_import_more.py), which
    must be a number: MoorDyn's viscoelastic model takes a curve's secant as a constant."""
    with pytest.raises(MoorDynError, match=re.escape("viscoelastic EA = rope_EA.txt|2e9: its static stiffness "
                                                     "'rope_EA.txt' is not a number")):
        parse_moordyn(LEGS.format(ea="rope_EA.txt|2e9", n=40))
    with pytest.raises(MoorDynError, match="Syrope model"):
        parse_moordyn(LEGS.format(ea="SYROPE:syrope.dat|1.5e8|23", n=40))


def test_the_export_writes_the_curve_next_to_the_file_and_moordyn_c_runs_it(tmp_path):
    """Export of the imported scenario: the EA column names EA_<stem>_<type>.txt, written next to
    the input with MoorDyn's three header lines and no line break after the last row (MoorDyn-C
    2.7 refuses one); MoorDyn-C loads it and settles to the quasi-static tensions within 2e-3
    (measured 3.1e-4 at 40 segments, the time step of every slope of the curve: RK2 at the largest
    slope's step blows up, the soft slopes being the more damped); the export reads back to the
    same line type."""
    sc = import_moordyn(write_legs(tmp_path), "fpso", mbs=MBS).scenario
    out = tmp_path / "out" / "legs_out.dat"
    out.parent.mkdir()
    info = export_moordyn(sc, out, extra_options={"writeLog": 0})
    assert list(info.curves) == ["EA_legs_out_rope.txt"]
    curve = (out.parent / "EA_legs_out_rope.txt").read_text()
    assert not curve.endswith("\n")
    rows = [tuple(float(x) for x in ln.split()) for ln in curve.splitlines()[3:]]
    assert rows == [tuple(r) for r in CURVE]
    assert " EA_legs_out_rope.txt " in out.read_text()
    assert any("EA_legs_out_rope.txt" in n for n in info.notes)
    back = import_moordyn(out, "fpso")
    assert back.scenario.line_types == sc.line_types
    T0 = MooringModel.from_scenario(sc).tensions(np.zeros(3))
    cot = np.array([sc.turret.position[0], -sc.turret.position[1], 0.0, 0.0, 0.0, 0.0])
    Tm = moordyn_fairlead_tensions(out, body=cot)
    print(f"MoorDyn-C on the export against the catenary: {Tm / T0 - 1}")
    assert np.allclose(Tm, T0, rtol=2e-3), (Tm, T0)


def test_the_export_refuses_more_rows_than_moordyn_c_reads(tmp_path):
    rows = [[0.0, 0.0]] + [[0.001 * k, 3e5 * k + 1e3 * k * k] for k in range(1, MAX_CURVE_ROWS + 1)]
    d = import_moordyn(write_legs(tmp_path), "fpso", mbs=MBS).data
    d["line_types"][0]["EA_table"] = rows
    sc = scenario_from_dict(d)
    with pytest.raises(MoorDynError, match=f"EA_table has {MAX_CURVE_ROWS + 1} rows; MoorDyn-C reads a "
                                           f"tension-strain curve of at most {MAX_CURVE_ROWS}"):
        moordyn_text(sc)
