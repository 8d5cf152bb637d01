"""More MoorDyn files import: viscoelastic line types (their static EA), VIV line types (Cl
neglected); and what stays refused says why, in MoorDyn's terms.

* a viscoelastic EA (``EA_s|EA_d``, ``EA_s|EA_Dc|EA_D_Lm``) is read as its static stiffness, which
  is MoorDyn-C's own tension at rest (measured on the file), with the damping of its dynamic damper;
  the dynamic stiffness it neglects is said; what MoorDyn has no rest state for is refused;
* a VIV lift coefficient is neglected with a note: the statics are the same as without it.

``moordyn`` (MoorDyn-C, in the test extra) is imported directly: a missing wheel fails these
tests instead of skipping them. MoorPy is not used.
"""

from __future__ import annotations

import math
from pathlib import Path

import moordyn  # noqa: F401 - in the test extra; its absence must fail, not skip
import numpy as np
import pytest
from test_moordyn_nonlinear import moordyn_fairlead_tensions

from tapm_opt.config.moordyn import MoorDynError, parse_moordyn, read_moordyn
from tapm_opt.models import MooringModel
from tapm_opt.models.moordyn_import import import_moordyn

G, RHO = 9.81, 1025.0


def _write(tmp_path: Path, text: str, name: str = "moor.dat") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def _w(mass: float, diam: float) -> float:
    """Submerged weight per length of a MoorDyn line type [N/m]."""
    return (mass - RHO * math.pi * diam * diam / 4.0) * G


def _edit(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


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
