"""More MoorDyn files import: lines held between two fixed points (--fixed-as-fairleads), viscoelastic
line types (their static EA), VIV line types (Cl neglected); and what stays refused says why, in
MoorDyn's terms.

* a file with no vessel point whose lines run from a fixed point on the seabed to a fixed point
  higher up imports with ``fixed_as_fairleads`` (the CLI's ``--fixed-as-fairleads``): the upper
  point is a fairlead on the vessel; its statics are the elastic catenary's in closed form, and a
  composite one's the composite solver's on the file's numbers; ends at one depth, a fixed point
  that would be both fairlead and anchor, and fixed points in a file that has a vessel are refused;
* a viscoelastic EA (``EA_s|EA_d``, ``EA_s|EA_Dc|EA_D_Lm``) is read as its static stiffness, which
  is MoorDyn-C's own tension at rest (measured on the file), with the damping of its dynamic damper;
  the dynamic stiffness it neglects is said; what MoorDyn has no rest state for is refused;
* a VIV lift coefficient is neglected with a note: the statics are the same as without it;
* options are read as MoorDyn-C reads them: its older names are options, and an option set twice
  (under any of its names) counts as set last.

``moordyn`` (MoorDyn-C, in the test extra) is imported directly: a missing wheel fails these
tests instead of skipping them. MoorPy is not used.
"""

from __future__ import annotations

import math

import moordyn  # noqa: F401 - in the test extra; its absence must fail, not skip
import numpy as np
import pytest
from scipy.optimize import fsolve
from test_moordyn import _write, run
from test_moordyn_nonlinear import moordyn_fairlead_tensions

from tapm_opt.config import load_scenario
from tapm_opt.config.moordyn import MoorDynError, parse_moordyn, read_moordyn
from tapm_opt.geometry import fairleads_E
from tapm_opt.models import MooringModel, composite
from tapm_opt.models.moordyn_import import import_moordyn

G, RHO = 9.81, 1025.0


def _w(mass: float, diam: float) -> float:
    """Submerged weight per length of a MoorDyn line type [N/m]."""
    return (mass - RHO * math.pi * diam * diam / 4.0) * G


# --------------------------------------------------------------------------------------------
# lines between two fixed points: the upper one is the vessel's fairlead
# --------------------------------------------------------------------------------------------

# A chain held between a point on the seabed (150 m) and one 5 m below the surface 600 m away, as
# MoorDyn's wave-kinematics tests hold theirs; the line is written from the upper point down.
RIG = """\
--------------------- MoorDyn Input File ------------------------------------
A chain held between a point on the seabed and one 5 m below the surface (a test rig, no vessel)
----------------------- LINE TYPES ------------------------------------------
TypeName   Diam    Mass/m     EA         BA/-zeta    EI         Cd     Ca     CdAx    CaAx
(name)     (m)     (kg/m)     (N)        (N-s/-)     (N-m^2)    (-)    (-)    (-)     (-)
chain      0.15    140        1.2e9      -1.0        0          1.37   1.0    0.64    0.0
---------------------- POINT PROPERTIES --------------------------------
ID    Type      X       Y       Z       Mass   Volume  CdA    Ca
(#)   (-)       (m)     (m)     (m)     (kg)   (m^3)   (m^2)  (-)
1     Fixed     0.0     0.0     -5.0    0      0       0      0
2     Fixed    -600.0   0.0     -150.0  0      0       0      0
---------------------- LINES ----------------------------------------
ID   LineType   AttachA  AttachB  UnstrLen  NumSegs  LineOutputs
(#)   (name)     (#)      (#)       (m)       (-)     (-)
1     chain      1        2         660       40      -
---------------------- OPTIONS -----------------------------------------
150           WtrDpth              water depth (m)
1025          rho                  water density (kg/m^3)
9.81          g                    gravity (m/s^2)
------------------------- need this line --------------------------------------
"""


def _touchdown(XF: float, ZF: float, L: float, w: float, EA: float) -> tuple[float, float]:
    """H, V at the upper end of an elastic catenary resting on a frictionless seabed, from the
    closed-form closure equations (L_B = L - V/w on the seabed):
    XF = L - V/w + (H/w) asinh(V/H) + H L/EA,  ZF = (H/w)(sqrt(1 + (V/H)^2) - 1) + V^2/(2 EA w)."""

    def res(x):
        H, V = x
        return [L - V / w + H / w * math.asinh(V / H) + H * L / EA - XF,
                H / w * (math.sqrt(1.0 + (V / H) ** 2) - 1.0) + V * V / (2.0 * EA * w) - ZF]

    H, V = fsolve(res, [0.2 * w * L, w * ZF * 1.2], xtol=1e-14)
    assert max(abs(r) for r in res([H, V])) < 1e-6
    assert V / w < L   # some of the line on the seabed
    return float(H), float(V)


def test_a_line_between_two_fixed_points_hangs_from_the_vessel(tmp_path):
    """The upper fixed point is a fairlead on the vessel (said in a note, naming both points), the
    lower one its anchor; the fairlead tension is the closed-form catenary's at rest and when the
    vessel has moved 5 m north, the fairlead with it (as MoorPy, moving the fixed point, has it)."""
    path = _write(tmp_path, RIG)
    res = import_moordyn(path, "fpso", mbs={"chain": 1.2e7}, fixed_as_fairleads=True)
    sc = res.scenario
    note = next(n for n in res.notes if "--fixed-as-fairleads" in n)
    assert "point 1 (z = -5 m) over point 2 (z = -150 m), line 1" in note, note
    assert any("line 1 runs from the fairlead (end A, point 1) to the anchor (end B)" in n for n in res.notes)
    assert sc.turret.fairlead_depth == 5.0 and sc.environment.water_depth == 150.0
    assert sc.lines[0].anchor == pytest.approx((-600.0, 0.0, 150.0))
    model = MooringModel.from_scenario(sc)
    w = _w(140.0, 0.15)
    for surge in (0.0, 5.0):
        eta = np.array([surge, 0.0, 0.0])
        fx, fy = fairleads_E(eta, sc.turret.position, sc.fairleads_T, sc.turret.angle)
        assert (float(fx[0]), float(fy[0])) == pytest.approx((surge, 0.0), abs=1e-9)   # where the file has it
        H, V = _touchdown(600.0 + surge, 145.0, 660.0, w, 1.2e9)
        assert model.tensions(eta)[0] == pytest.approx(math.hypot(H, V), rel=1e-9), surge
        assert model.force(eta)[0] == pytest.approx(-H, rel=1e-9)   # pulled back towards the anchor
    # the TOML reads back as the same scenario
    back = load_scenario(_write(tmp_path, res.toml, "rig.toml"))
    assert back.lines == sc.lines and back.turret == sc.turret


def test_without_the_option_the_refusal_names_it(tmp_path, capsys):
    """Off by default: a fixed point does not move in MoorDyn, so only the user can say it stands
    for a fairlead; the refusal names the option once, and the command takes it."""
    path = _write(tmp_path, RIG)
    with pytest.raises(MoorDynError) as exc:
        import_moordyn(path, "fpso", mbs={"chain": 1.2e7})
    assert str(exc.value) == (
        "moor.dat:15: line 1 runs between two fixed points (1 and 2); every line must run from a fixed anchor to the "
        "vessel (the file has no vessel point: --fixed-as-fairleads takes the upper fixed point of each line, or lines "
        "in series, between two fixed points as a fairlead on the vessel)")
    out = tmp_path / "rig.toml"
    code, _, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out", str(out),
                       "--mbs", "chain=1.2e7")
    assert code == 2 and "--fixed-as-fairleads" in err and not out.exists()
    code, stdout, err = run(capsys, "scenario", "import-moordyn", str(path), "--vessel", "fpso", "--out", str(out),
                            "--mbs", "chain=1.2e7", "--fixed-as-fairleads")
    assert code == 0, err
    assert "taken as a fairlead on the vessel" in stdout and load_scenario(out).turret.fairlead_depth == 5.0


# lines in series between two fixed points: 350 m of chain from the seabed, a 2 t clump, 260 m of
# wire written from the upper point (10 m deep) down to the clump
RIG_SERIES = """\
--------------------- MoorDyn Input File ------------------------------------
Chain, clump and wire between a point on the seabed and one 10 m deep
----------------------- LINE TYPES ------------------------------------------
TypeName   Diam    Mass/m     EA         BA/-zeta    EI    Cd     Ca     CdAx    CaAx
(name)     (m)     (kg/m)     (N)        (N-s/-)   (N-m^2) (-)    (-)    (-)     (-)
chain      0.15    140        1.2e9      -1.0        0     1.37   1.0    0.64    0.0
wire       0.08    30         5.0e8      -1.0        0     1.2    1.0    0.008   0.0
---------------------- POINTS --------------------------------
ID    Type      X       Y       Z       Mass   Volume  CdA    Ca
(#)   (-)       (m)     (m)     (m)     (kg)   (m^3)   (m^2)  (-)
1     Fixed    -500.0   0.0     -200.0  0      0       0      0
2     Free     -200.0   0.0     -120.0  2000   0       0      0
3     Fixed     0.0     0.0     -10.0   0      0       0      0
---------------------- LINES ----------------------------------------
ID   LineType   AttachA  AttachB  UnstrLen  NumSegs  LineOutputs
(#)   (name)     (#)      (#)       (m)       (-)     (-)
1     chain      1        2         350       20      -
2     wire       3        2         260       20      -
---------------------- OPTIONS -----------------------------------------
200           WtrDpth
1025          rho
9.81          g
------------------------- need this line --------------------------------------
"""


def test_lines_in_series_between_fixed_points_are_a_composite_line_to_the_vessel(tmp_path):
    res = import_moordyn(_write(tmp_path, RIG_SERIES), "fpso", mbs={"chain": 1.2e7, "wire": 8e6},
                         fixed_as_fairleads=True)
    sc = res.scenario
    assert [ln.id for ln in sc.lines] == ["1-2"]
    assert [(s.type, s.length, s.top) for s in sc.lines[0].sections] == [("chain", 350.0, "clump2"), ("wire", 260.0, None)]
    assert any("point 3 (z = -10 m) over point 1 (z = -200 m), lines 1, 2 (from the anchor up)" in n for n in res.notes)
    line = composite.CompositeLine(L=np.array([350.0, 260.0]), EA=np.array([1.2e9, 5e8]),
                                   w=np.array([_w(140.0, 0.15), _w(30.0, 0.08)]), CB=np.zeros(2),
                                   W=np.array([2000.0 * G]))
    T = float(composite.solve(500.0, 190.0, line).TF)
    assert MooringModel.from_scenario(sc).tensions(np.zeros(3))[0] == pytest.approx(T, rel=1e-12)


def _edit(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


def test_what_cannot_be_a_fairlead_is_refused_with_the_reason(tmp_path):
    """Ends at one depth (neither is the upper one), a fixed point that would be a fairlead of one
    line and the anchor of another, all said at once; and in a file with a vessel the fixed points
    stay fixed, the option or not."""
    level = _edit(RIG, "2     Fixed    -600.0   0.0     -150.0", "2     Fixed    -600.0   0.0     -5.0  ")
    with pytest.raises(MoorDynError, match=r"line 1 runs between two fixed points \(1 and 2\) at the same depth "
                                           r"\(z = -5 m\): neither end is the upper one"):
        parse_moordyn(level, fixed_as_fairleads=True)
    with pytest.raises(MoorDynError, match=r"\(both at z = -5 m: neither could be taken as the fairlead\)"):
        parse_moordyn(level)
    # a third point above point 1, joined to it: point 1 is the top of line 2's rig and the bottom of line 3's
    both = _edit(_edit(RIG, "2     Fixed    -600.0   0.0     -150.0  0      0       0      0\n",
                       "2     Fixed    -600.0   0.0     -150.0  0      0       0      0\n"
                       "3     Fixed     300.0   0.0     -1.0    0      0       0      0\n"),
                 "1     chain      1        2         660       40      -\n",
                 "1     chain      1        2         660       40      -\n"
                 "2     chain      1        3         310       20      -\n")
    with pytest.raises(MoorDynError) as exc:
        parse_moordyn(both, source="both.dat", fixed_as_fairleads=True)
    assert str(exc.value) == (
        "both.dat:10: point 1 (fixed) is the upper end of line 1 and the lower end of line 2: --fixed-as-fairleads "
        "would make it both a fairlead on the vessel and an anchor")
    vessel = _edit(RIG, "2     Fixed    -600.0   0.0     -150.0  0      0       0      0\n",
                   "2     Fixed    -600.0   0.0     -150.0  0      0       0      0\n"
                   "3     Vessel    0.0     0.0     0.0     0      0       0      0\n")
    with pytest.raises(MoorDynError, match=r"--fixed-as-fairleads applies to files without a vessel point or body: "
                                           r"this file has one, so its fixed points stay fixed"):
        parse_moordyn(vessel, fixed_as_fairleads=True)


# --------------------------------------------------------------------------------------------
# viscoelastic line types: the static EA
# --------------------------------------------------------------------------------------------

# three 1900 m legs of a synthetic rope in 800 m of water from a turret 8 m in radius, 91.44 m
# forward of the hull origin (a coupled body): taut enough that EA matters (4 % between 3e8 and 1.1e9)
LEGS = """\
--------------------- MoorDyn Input File ------------------------------------
Turret FPSO, 3 legs of a synthetic rope, 800 m water depth
---------------------- LINE TYPES ----------------------------------------------------------------------
TypeName   Diam    Mass/m     EA         BA/-zeta    EI     Cd     Ca     CdAx    CaAx {more}
(name)     (m)     (kg/m)     (N)        (N-s/-)   (N-m^2)  (-)    (-)    (-)     (-)
rope       0.16    120.0      {ea}    {ba}       0      1.2    1.0    0.05    0.1  {cl}
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
1     rope        1        2        1900      40       -
2     rope        3        4        1900      40       -
3     rope        5        6        1900      40       -
---------------------- OPTIONS -----------------------------------------
0             writeLog      Write log file
0.002         dtM           time step to use in mooring integration (s)
RK4           tScheme       time integrator
800           WtrDpth       water depth (m)
1025          rho           water density (kg/m^3)
9.81          g             gravity (m/s^2)
1.0           dtIC          time interval for analyzing convergence during IC gen (s)
120           TmaxIC        max time for ic gen (s)
0.001         threshIC      threshold for IC convergence (-)
------------------------- need this line -------------------------------------
"""
MBS = {"rope": 2.5e7}


def legs(ea: str = "3e8", ba: str = "-1.0", cl: str = "") -> str:
    return LEGS.format(ea=ea, ba=ba, cl=cl, more="Cl" if cl else "")


def test_a_viscoelastic_ea_imports_as_its_static_stiffness(tmp_path):
    """EA_s|EA_d and EA_s|EA_Dc|EA_D_Lm: the line type's EA is EA_s, the statics exactly those of
    the elastic line of EA_s; the notes say why (MoorDyn's springs in series) and what is neglected."""
    elastic = import_moordyn(_write(tmp_path, legs(), "elastic.dat"), "fpso", mbs=MBS).scenario
    T0 = MooringModel.from_scenario(elastic).tensions(np.zeros(3))
    for ea in ("3e8|1.1e9", "3e8|1.1e9|0.4"):
        res = import_moordyn(_write(tmp_path, legs(ea, "-1.0|1e6"), "visco.dat"), "fpso", mbs=MBS)
        lt = res.scenario.line_types[0]
        assert lt.EA == 3e8 and lt.EA_table is None
        np.testing.assert_array_equal(MooringModel.from_scenario(res.scenario).tensions(np.zeros(3)), T0)
        note = next(n for n in res.notes if "viscoelastic EA" in n)
        assert f"viscoelastic EA = {ea} (line 6): the static stiffness EA_s = 3e+08 N is the line's EA" in note, note
        assert "EA_1 EA_d / (EA_1 + EA_d) = EA_s" in note and "the FEM's dynamic tensions differ from MoorDyn's" in note
        assert f"EA 3e+08|{ea.split('|', 1)[1]} N (viscoelastic: the static 3e+08 N used), BA -1|1e+06" in res.toml


def test_moordyn_c_settles_a_viscoelastic_line_at_the_static_ea(tmp_path):
    """MoorDyn-C on the very file (EA_s|EA_d = 3e8|1.1e9): its settled fairlead tensions are the
    import's within 1e-3 (measured 3.4e-4, the lumped-mass chords), and 4 % from those of EA_d."""
    path = _write(tmp_path, legs("3e8|1.1e9", "-1.0|1e6"), "visco.dat")
    res = import_moordyn(path, "fpso", mbs=MBS)
    T = MooringModel.from_scenario(res.scenario).tensions(np.zeros(3))
    dyn = import_moordyn(_write(tmp_path, legs("1.1e9"), "dynamic.dat"), "fpso", mbs=MBS).scenario
    T_d = MooringModel.from_scenario(dyn).tensions(np.zeros(3))
    Tm = moordyn_fairlead_tensions(path)
    print(f"viscoelastic line, import against MoorDyn-C: {T / Tm - 1}; EA_d's: {T_d / Tm - 1}")
    assert np.allclose(T, Tm, rtol=1e-3), (T, Tm)
    assert np.all(np.abs(T_d / Tm - 1.0) > 0.03), T_d / Tm - 1


def test_a_viscoelastic_line_is_damped_by_its_dynamic_damper(tmp_path):
    """The FEM's axial damper is MoorDyn's dynamic damper BA_d [N s] (the same coefficient, as a
    ratio on the segment); above critical it is critical, said with the frequencies where either
    damper matters; without BA_d it is 0, as MoorDyn's dynamic spring is then undamped."""
    l, EA, m = 1900.0 / 40, 3e8, 120.0
    crit = math.sqrt(2.0) * l * math.sqrt(EA * m)   # the FEM's damper at ratio 1 [N s]
    res = import_moordyn(_write(tmp_path, legs("3e8|1.1e9", "-1.0|1e6")), "fpso", mbs=MBS)
    assert res.scenario.line_types[0].axial_damping_ratio == pytest.approx(1e6 / crit, rel=1e-12)
    note = next(n for n in res.notes if "viscoelastic damping" in n)
    assert "is MoorDyn's dynamic damper BA_d = 1e+06 N s across the dynamic spring" in note, note
    assert "the static damping -1 (a ratio), across MoorDyn's static spring" in note
    over = import_moordyn(_write(tmp_path, legs("3e8|1.1e9", "-1.0|1e8")), "fpso", mbs=MBS)
    assert over.scenario.line_types[0].axial_damping_ratio == 1.0
    note = next(n for n in over.notes if "viscoelastic damping" in n)
    assert f"{1e8 / crit:.3g} times the critical damping of the FEM's segment mode: the FEM takes critical" in note
    assert f"above EA_d / BA_d = {1.1e9 / 1e8:.3g} rad/s in MoorDyn and EA_s / c = {EA / crit:.3g} rad/s" in note
    none = import_moordyn(_write(tmp_path, legs("3e8|1.1e9", "-1.0")), "fpso", mbs=MBS)
    assert none.scenario.line_types[0].axial_damping_ratio == 0.0
    assert any("has no damper (no BA_d), so the FEM's axial damping is 0" in n for n in none.notes)


@pytest.mark.parametrize("ea, ba, needle", [
    ("3e8|2e8", "-1.0", ("line type 'rope': viscoelastic EA = 3e8|2e8: the dynamic stiffness EA_d = 2e+08 N must be "
                         "greater than the static EA_s = 3e+08 N")),
    ("3e8|3e8", "-1.0", "the dynamic stiffness EA_d = 3e+08 N must be greater than the static EA_s = 3e+08 N"),
    ("3e8|2e8|0.4", "-1.0", "the dynamic stiffness at zero mean load EA_Dc = 2e+08 N must be greater than the static"),
    ("3e8|4e8|-0.4", "-1.0", "EA_D_Lm = -0.4, the growth of the dynamic stiffness with the mean load, must be >= 0"),
    ("3e8|4e8|0.4|1", "-1.0", "EA = 3e8|4e8|0.4|1 has 4 bar-separated values"),
    ("rope_EA.txt|4e8", "-1.0", ("its static stiffness 'rope_EA.txt' is not a number; a tension-strain curve as "
                                 "the static part is not supported")),
    ("3e8", "-1.0|1e6", ("static|dynamic damping BA = -1.0|1e6 needs a viscoelastic EA (EA_s|EA_d); EA = 3e8 has "
                         "one value")),
    ("3e8|4e8", "-1.0|1e6|2", "BA = -1.0|1e6|2 has 3 bar-separated values; MoorDyn takes at most 2"),
    ("3e8|4e8", "-1.0|-0.5", "BA = -1.0|-0.5: the dynamic damping -0.5 must be >= 0 N s"),
])
def test_what_has_no_rest_state_or_is_not_moordyn_is_refused(ea, ba, needle):
    with pytest.raises(MoorDynError) as exc:
        parse_moordyn(legs(ea, ba), source="legs.dat")
    assert str(exc.value).startswith("legs.dat:6: line type 'rope'") and needle in str(exc.value), str(exc.value)


# --------------------------------------------------------------------------------------------
# VIV: neglected, said
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("cl", ["0.8", "0.8  0.08  0.18"])
def test_a_viv_lift_coefficient_is_neglected_with_a_note(tmp_path, cl):
    """MoorDyn's VIV lift is on the line's normal velocity relative to the water, zero at rest:
    the statics are the same as without it (11 or 13 columns), and a note says what the FEM lacks."""
    T0 = MooringModel.from_scenario(import_moordyn(_write(tmp_path, legs(), "a.dat"), "fpso",
                                                   mbs=MBS).scenario).tensions(np.zeros(3))
    res = import_moordyn(_write(tmp_path, legs(cl=cl), "b.dat"), "fpso", mbs=MBS)
    np.testing.assert_array_equal(MooringModel.from_scenario(res.scenario).tensions(np.zeros(3)), T0)
    note = next(n for n in res.notes if "vortex-induced vibration" in n)
    assert note.startswith("line type 'rope': Cl = 0.8 (line 6): MoorDyn's vortex-induced vibration") and \
        "is zero with the line at rest" in note and "the FEM's lines have no such lift" in note
    assert "Cl 0.8 (VIV, neglected)" in res.toml


def test_no_gravity_is_refused_naming_the_option(tmp_path):
    """MoorDyn's viscoelastic unit test runs without gravity: a weightless line has no catenary."""
    text = _edit(legs(), "9.81          g ", "0             g ")
    with pytest.raises(MoorDynError, match=r"moor.dat:32: option g = 0 m/s\^2: tapm_opt's lines hang under gravity"):
        import_moordyn(_write(tmp_path, text), "fpso", mbs=MBS)
    assert read_moordyn(_write(tmp_path, text)).gravity == 0.0


# --------------------------------------------------------------------------------------------
# options as MoorDyn-C reads them
# --------------------------------------------------------------------------------------------


def test_moordyn_c_s_older_option_names_are_options(tmp_path):
    """MoorDyn-C 2.7 still reads the older names (``MoorDyn::readOptionsLine``): MoorDyn's chain
    tests set ``fileIC``, MoorPy's ``case4.dat`` ``ICDfac`` and ``ICthresh``. They are options,
    not unknown names, and a number is checked as for the newer names."""
    old = ("5.0           ICDfac       drag factor of the IC\n1e-4          ICthresh     IC threshold\n"
           "1.0           ICdt         IC interval\n30            ICTmax       IC time\n0.001         dt   step\n"
           "0             genDynamicIC IC solver\nrig.txt.ic    fileIC       IC file\n")
    text = _edit(RIG, "9.81          g ", old + "9.81          g ")
    notes = read_moordyn(_write(tmp_path, text, "rig.txt"), fixed_as_fairleads=True).notes
    assert not [n for n in notes if "option" in n], notes
    with pytest.raises(MoorDynError, match=r"option ICDfac = 'abc' must be a finite number"):
        parse_moordyn(_edit(text, "5.0           ICDfac", "abc           ICDfac"), fixed_as_fairleads=True)
    unknown = read_moordyn(_write(tmp_path, _edit(text, "ICTmax ", "ICTmaxx"), "rig.txt"), fixed_as_fairleads=True)
    assert any("option ICTmaxx = 30 (line 22) is not a MoorDyn option (did you mean ICTmax?)" in n
               for n in unknown.notes), unknown.notes


def test_an_option_set_twice_counts_as_set_last(tmp_path):
    """MoorDyn-C and MoorPy read the options in order, a later row overwriting an earlier one of the
    same option under any of its names (MoorDyn's ``polyester/visco.txt`` sets ``1025 rho`` and
    then ``0.0 WtrDnsty``, and runs with 0): the import takes the last, and says so."""
    text = _edit(_edit(RIG, "9.81          g ", "1000          WtrDnsty  water density\n9.81          g "),
                 "------------------------- need", "9.80665       gravity\n150  WtrDpth\n------------------------- need")
    res = import_moordyn(_write(tmp_path, text, "rig.txt"), "fpso", mbs={"chain": 1.2e7}, fixed_as_fairleads=True)
    env = res.scenario.environment
    assert (env.water_density, env.gravity, env.water_depth) == (1000.0, 9.80665, 150.0)
    assert any(n.startswith("option WtrDnsty = 1000 (line 19) is used: the file sets the same option before (rho = "
                            "1025, line 18), and MoorDyn-C and MoorPy read the options in order") for n in res.notes)
    assert any(n.startswith("option gravity = 9.80665 (line 21) is used: the file sets the same option before (g = "
                            "9.81, line 20)") for n in res.notes), res.notes
    assert not any("WtrDpth = 150" in n for n in res.notes)   # set twice to the same value: nothing to say
    # the same name twice: the last
    twice = _edit(RIG, "9.81          g ", "1030          rho\n9.81          g ")
    assert read_moordyn(_write(tmp_path, twice, "rig.txt"), fixed_as_fairleads=True).water_density == 1030.0
    # rhoW (MoorDyn-F) is read only where neither rho nor WtrDnsty is set, wherever it is in the file
    rhow = _edit(_edit(RIG, "1025          rho ", "1000          rho "), "9.81          g ", "1030  rhoW\n9.81          g ")
    assert read_moordyn(_write(tmp_path, rhow, "rig.txt"), fixed_as_fairleads=True).water_density == 1000.0


def test_wave_kinematics_are_said_to_be_ignored_as_waves(tmp_path):
    """``WaveKin`` switches MoorDyn's waves, ``Currents`` its currents: the notes say which."""
    text = _edit(RIG, "9.81          g ", "3             WaveKin\n1             Currents\n9.81          g ")
    notes = read_moordyn(_write(tmp_path, text, "rig.txt"), fixed_as_fairleads=True).notes
    assert "option WaveKin = 3 (line 19) is ignored: waves come from the vessel scenario's sea states" in notes
    assert "option Currents = 1 (line 20) is ignored: currents come from the vessel scenario's sea states" in notes
