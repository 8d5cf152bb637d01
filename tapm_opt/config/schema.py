"""Scenario schema: frozen dataclasses, one per section of a scenario file.

Each field carries its unit, a one-line description and its allowed range in the dataclass field
metadata (see :func:`spec`). The loader (:mod:`tapm_opt.config.loader`) reads these to parse and
check a TOML file, and ``docs/scenarios.md`` is written from the same metadata, so a field is
described exactly once.

Units are SI. Angles are degrees in the file (keys ending in ``_deg``) and radians in code: a field
declared with ``unit="deg"`` is read from ``<name>_deg`` and stored in radians under ``<name>``.

Directions of environmental loads follow survey eq. (7): the direction a current, wave or wind is
*going to* (propagating toward), measured in {E} from north (x) toward east (y).
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field
from functools import cached_property
from typing import Any, Callable, Literal

import numpy as np

from .. import geometry
from .._io import readonly
from ..strain_table import StrainTable, secant_of_rows

Check = Callable[[Any], "str | None"]


def positive(v: float) -> str | None:
    return None if v > 0 else "must be > 0"


def nonneg(v: float) -> str | None:
    return None if v >= 0 else "must be >= 0"


def in_range(lo: float, hi: float) -> Check:
    def check(v: float) -> str | None:
        return None if lo <= v <= hi else f"must be in [{lo:g}, {hi:g}]"

    check.__doc__ = f"[{lo:g}, {hi:g}]"
    return check


def at_least(lo: float) -> Check:
    def check(v: float) -> str | None:
        return None if v >= lo else f"must be >= {lo:g}"

    check.__doc__ = f">= {lo:g}"
    return check


def positive_at_most(hi: float, why: str = "") -> Check:
    """``0 < v <= hi``; ``why`` (the reason for the bound) is added to the message."""
    def check(v: float) -> str | None:
        if v <= 0:
            return "must be > 0"
        return None if v <= hi else f"must be <= {hi:g}" + (f" ({why})" if why else "")

    check.__doc__ = f"(0, {hi:g}]"
    return check


def bounded(lo: float, hi: float, why: str) -> Check:
    """``lo <= v <= hi`` with the reason for the bound in the message."""
    def check(v: float) -> str | None:
        if v < lo:
            return f"must be >= {lo:g}"
        return None if v <= hi else f"must be <= {hi:g} ({why})"

    check.__doc__ = f"[{lo:g}, {hi:g}]"
    return check


#: Most FEM segments one line may have, and the bytes of FEM state and work arrays per node used
#: to estimate memory (measured about 0.4 KiB a node; 1 KiB leaves room for the plant around it).
MAX_SEGMENTS = 1000
FEM_BYTES_PER_NODE = 1024


def gib(n_bytes: float) -> str:
    """A size in GiB for messages (``2.5 GiB``, ``9.3e+02 GiB``)."""
    g = n_bytes / 2**30
    return f"{g:.3g} GiB"


def fem_segments(v: int) -> str | None:
    if 2 <= v <= MAX_SEGMENTS:
        return None
    if v < 2:
        return "must be >= 2"
    return (f"must be in [2, {MAX_SEGMENTS}]: the FEM arrays of this line alone would take about "
            f"{gib((v + 1) * FEM_BYTES_PER_NODE)}, and its stable step shrinks with the segment length")


#: Longest free text of each kind [characters]: ids (of line types, lines, thrusters, sea states,
#: and the ids faults name) and names are labels; a description is a paragraph; a source is one
#: reference. Longer text is a pasted file or a corrupted one, and would flood every report.
MAX_ID_LENGTH = 200
MAX_NAME_LENGTH = 200
MAX_DESCRIPTION_LENGTH = 10_000
MAX_SOURCE_LENGTH = 1_000


def text_limit(most: int, *, nonempty: bool = False, what: str = "text") -> Check:
    """A check of free text: at most ``most`` characters and, with ``nonempty``, not empty or
    blank. Its message never repeats a long value (only its length)."""
    def check(v: str) -> str | None:
        if nonempty and not v.strip():
            return f"= {v!r} must not be empty: {what} is 1-{most} characters"
        if len(v) > most:
            return f"is {len(v)} characters long, above the limit of {most} characters for {what}"
        return None

    check.__doc__ = f"1-{most} characters" if nonempty else f"at most {most} characters"
    return check


_ID_TEXT = text_limit(MAX_ID_LENGTH, nonempty=True, what="an id")
positive.__doc__ = "> 0"
nonneg.__doc__ = ">= 0"
fem_segments.__doc__ = f"[2, {MAX_SEGMENTS}]"
_COEF = "measured coefficients of chain, wire and rope are 0-3"
_ANGLE = bounded(-360.0, 360.0, "an angle beyond a full turn is a typo")


def spec(
    doc: str,
    unit: str = "",
    *,
    default: Any = MISSING,
    check: Check | None = None,
    shape: tuple[int, ...] | None = None,
    id_like: bool = False,
) -> Any:
    """Declare a scenario field.

    Parameters
    ----------
    doc : str
        One-line description (appears in ``docs/scenarios.md`` and error messages).
    unit : str
        SI unit; ``"deg"`` means the file key is ``<name>_deg`` and the value is stored in rad.
    default : optional
        Default value; absent means the field is required.
    check : callable, optional
        ``check(value) -> message or None`` applied to each number of the field.
    shape : tuple of int, optional
        Required shape of an array-valued field; ``-1`` allows any length.
    id_like : bool
        Accept an integer and store it as a string (ids); ids are checked to be 1 to
        :data:`MAX_ID_LENGTH` characters unless ``check`` says otherwise.
    """
    if id_like and check is None:
        check = _ID_TEXT
    meta = {"doc": doc, "unit": unit, "check": check, "shape": shape, "id_like": id_like}
    if default is MISSING:
        return field(metadata=meta)
    return field(default=default, metadata=meta)


Vec = tuple[float, ...]
Mat = tuple[tuple[float, ...], ...]


@dataclass(frozen=True, kw_only=True)
class Meta:
    """Identification of the scenario and where its numbers come from."""

    name: str = spec("Scenario name (used in reports).", check=text_limit(MAX_NAME_LENGTH, what="a name"))
    description: str = spec("What the scenario represents.", default="",
                            check=text_limit(MAX_DESCRIPTION_LENGTH, what="a description"))
    sources: tuple[str, ...] = spec("References the numbers are taken from.", default=(), shape=(-1,),
                                    check=text_limit(MAX_SOURCE_LENGTH, what="a source"))


@dataclass(frozen=True, kw_only=True)
class Environment:
    """Site constants."""

    water_depth: float = spec("Water depth at the site (flat seabed).", "m",
                               check=positive_at_most(12000.0, "the deepest ocean is 10 935 m"))
    water_density: float = spec("Sea water density.", "kg/m^3", default=1025.0, check=in_range(900.0, 1100.0))
    gravity: float = spec("Acceleration of gravity.", "m/s^2", default=9.81, check=in_range(9.7, 9.9))
    air_density: float = spec("Air density.", "kg/m^3", default=1.226, check=in_range(0.9, 1.5))


@dataclass(frozen=True, kw_only=True)
class WaveMotion:
    """First-order (wave-frequency) motion of the hull that the plant puts on the fairleads: surge,
    sway and yaw always (``docs/plant_environment.md``); heave, roll and pitch from the closed-form
    transfer functions of Jensen, Mansour and Olsen (2004) when ``model = "six_dof"``; all six from
    the user's RAO table when ``model = "table"``. The second-order drift takes the user's mean
    drift coefficients from ``drift_file`` when it is given (any model), else the wall-sided formula."""

    model: Literal["horizontal", "six_dof", "table"] = spec(
        "'horizontal': surge, sway and yaw only; 'six_dof': heave, roll and pitch too, from the closed-form "
        "RAOs (Jensen et al. 2004) of the hull's main dimensions and the fields below; 'table': all six from "
        "the RAO table in rao_file.",
        default="horizontal")
    rao_file: str | None = spec(
        "The hull's RAO table (model 'table'): a CSV (omega_rad_s, beta_deg, dof, amplitude, phase_deg; "
        "docs/plant_environment.md) or a WAMIT .4 file; a relative path is read from the scenario file's folder.",
        default=None, check=text_limit(4096, what="a path"))
    rao_ulen: float = spec("WAMIT's length scale ULEN of a .4 rao_file (its rotations are per A/ULEN).", "m",
                           default=1.0, check=positive)
    drift_file: str | None = spec(
        "The hull's mean wave drift coefficients, any model: a CSV (omega_rad_s, beta_deg, dof, D: surge, sway "
        "[N/m^2], yaw [N m/m^2] per unit wave amplitude squared; docs/plant_environment.md) or a WAMIT .8 or .9 "
        "file; absent: the wall-sided formula. A relative path is read from the scenario file's folder.",
        default=None, check=text_limit(4096, what="a path"))
    drift_ulen: float = spec("WAMIT's length scale ULEN of a .8 or .9 drift_file (forces per rho g A^2 ULEN, "
                             "moments per rho g A^2 ULEN^2).", "m", default=1.0, check=positive)
    block_coefficient: float | None = spec("Block coefficient C_B of the hull (six_dof).",
                                           default=None, check=in_range(0.3, 1.0))
    waterplane_coefficient: float | None = spec(
        "Water-plane area coefficient C_WP (six_dof); absent: (1 + 2 C_B) / 3.", default=None,
        check=in_range(0.3, 1.0))
    GM_T: float | None = spec("Transverse metacentric height (six_dof).", "m", default=None,
                              check=positive_at_most(50.0, "ships have GM_T of 0.3-10 m"))
    roll_period: float | None = spec("Natural roll period T_4 (six_dof).", "s", default=None,
                                     check=positive_at_most(60.0, "ships roll with periods of 8-30 s"))
    roll_damping: float = spec("Roll damping as a fraction of critical, zeta_4 (six_dof).", default=0.05,
                               check=bounded(0.0, 0.99, "below critical"))


@dataclass(frozen=True, kw_only=True)
class RollPitch:
    """Low-frequency roll and pitch of the hull (survey §4.2.3; ``docs/semi.md``): two uncoupled
    second-order modes about the centre of gravity, ``(I + A) phi_dd + B phi_d + rho g nabla GM phi =
    K``, driven by the thrusters, the mooring lines and the wind through their vertical lever arms.
    Absent: the vessel is 3-DOF (surge, sway, yaw) as before. For hulls whose roll and pitch periods
    lie within the positioning controller's bandwidth (semi-submersibles)."""

    displacement: float = spec("Displaced volume nabla.", "m^3", check=positive)
    GM_T: float = spec("Transverse metacentric height (C44 = rho g nabla GM_T).", "m",
                       check=positive_at_most(50.0, "floating units have GM of 0.3-10 m"))
    GM_L: float = spec("Longitudinal metacentric height (C55 = rho g nabla GM_L).", "m",
                       check=positive_at_most(500.0, "ships have GM_L of up to a few hundred m"))
    roll_gyration: float = spec("Roll radius of gyration r_44 about the centre of gravity (I44 = rho nabla r_44^2).",
                                "m", check=positive_at_most(200.0, "a radius of gyration beyond the largest hull"))
    pitch_gyration: float = spec("Pitch radius of gyration r_55 about the centre of gravity.", "m",
                                 check=positive_at_most(500.0, "a radius of gyration beyond the longest hull"))
    roll_added_inertia: float = spec("Low-frequency roll added inertia A44 about the centre of gravity.", "kg m^2",
                                     check=nonneg)
    pitch_added_inertia: float = spec("Low-frequency pitch added inertia A55 about the centre of gravity.", "kg m^2",
                                      check=nonneg)
    roll_damping: float = spec("Linear roll damping as a fraction of critical, zeta_4.",
                               check=bounded(0.0, 0.99, "below critical"))
    pitch_damping: float = spec("Linear pitch damping as a fraction of critical, zeta_5.",
                                check=bounded(0.0, 0.99, "below critical"))
    cg_depth: float = spec("Depth of the centre of gravity below the mean water line (negative: above it).", "m",
                           check=bounded(-100.0, 250.0, "a centre of gravity beyond the hull"))
    thruster_depth: float = spec("Depth below the mean water line at which the thrusters' horizontal thrust acts "
                                 "(all thrusters).", "m", check=bounded(0.0, 250.0, "below the deepest hull"))
    wind_height: float = spec("Height of the wind load's centre above the mean water line.", "m",
                              check=bounded(0.0, 300.0, "above the tallest derrick"))


@dataclass(frozen=True, kw_only=True)
class Vessel:
    """Hull and low-frequency hydrodynamics in 3 DOF (surge, sway, yaw) about the body origin CO."""

    name: str = spec("Vessel name.", default="vessel", check=text_limit(MAX_NAME_LENGTH, what="a name"))
    mass_matrix: Mat = spec(
        "Generalised mass matrix M = M_RB + M_A incl. zero-frequency added mass, about CO.",
        "kg, kg m, kg m^2",
        shape=(3, 3),
    )
    added_mass: Mat | None = spec(
        "Added-mass part M_A of mass_matrix (for the added-mass Coriolis term); absent: M_A = 0.",
        "kg, kg m, kg m^2",
        default=None,
        shape=(3, 3),
    )
    linear_damping: Mat = spec("Linear damping matrix D_lin.", "N s/m, N s, N m s", shape=(3, 3))
    quadratic_damping: Vec = spec(
        "Quadratic damping (X_|u|u, Y_|v|v, N_|r|r) on relative velocity; force -d|nu_r|nu_r.",
        "N s^2/m^2, N s^2/m^2, N m s^2",
        default=(0.0, 0.0, 0.0),
        shape=(3,),
        check=nonneg,
    )
    length_pp: float = spec("Length between perpendiculars.", "m",
                             check=positive_at_most(1000.0, "twice the longest ship ever built"))
    breadth: float = spec("Moulded breadth.", "m", check=positive_at_most(
        200.0, "ships are up to about 75 m wide, the largest semi-submersibles about 130 m"))
    draught: float = spec("Draught.", "m", check=positive_at_most(
        250.0, "ships draw up to about 30 m, semi-submersibles 20-40 m, spars 80-200 m"))
    wind_area_frontal: float = spec("Projected frontal wind area (above water).", "m^2", check=positive)
    wind_area_lateral: float = spec("Projected lateral wind area (above water).", "m^2", check=positive)
    reference_point: Vec = spec(
        "Position of the body origin CO from aft perpendicular, centre line and keel (fwd, stbd, up).",
        "m",
        default=(math.nan, 0.0, math.nan),
        shape=(3,),
    )
    wave_motion: WaveMotion = spec("Wave-frequency motion of the hull at the fairleads.", default=WaveMotion())
    roll_pitch: RollPitch | None = spec(
        "Low-frequency roll and pitch (docs/semi.md); absent: surge, sway and yaw only.", default=None)

    @cached_property
    def M(self) -> np.ndarray:
        """Generalised mass matrix, shape (3, 3), read-only."""
        return readonly(self.mass_matrix)

    @cached_property
    def M_A(self) -> np.ndarray:
        """Added-mass matrix, shape (3, 3) (zeros when not given), read-only."""
        return readonly(self.added_mass if self.added_mass is not None else np.zeros((3, 3)))

    @cached_property
    def D_lin(self) -> np.ndarray:
        """Linear damping matrix, shape (3, 3), read-only."""
        return readonly(self.linear_damping)


@dataclass(frozen=True, kw_only=True)
class Turret:
    """Internal turret and its fairlead circle (survey eq. 2–6)."""

    position: Vec = spec("Centre of turret p_cot^B in {B} (x fwd, y stbd).", "m", shape=(2,))
    mode: Literal["locked", "free"] = spec(
        "'locked': turret fixed to the hull at alpha_t; 'free': ideal bearing, turret keeps its "
        "heading in {E} and transmits no yaw moment about the COT.",
        default="free",
    )
    angle: float = spec(
        "Turret angle alpha_t relative to the hull x-axis at the field zero point (eq. 3).", "deg", default=0.0,
        check=_ANGLE,
    )
    fairlead_radius: float = spec("Radius r of the fairlead circle (eq. 2).", "m", default=0.0, check=nonneg)
    fairlead_depth: float = spec("Depth of the fairleads below the mean water line.", "m", default=0.0)


@dataclass(frozen=True, kw_only=True)
class LineType:
    """Mooring line material and hydrodynamic properties (per unit unstretched length)."""

    id: str = spec("Name referenced by lines[].type.", id_like=True)
    diameter: float = spec(
        "Hydrodynamic diameter d used in Morison drag and added mass (seed FEM eq. 3–5).", "m",
        check=positive_at_most(2.0, "the largest chains and ropes are under 0.5 m"),
    )
    mass_per_length: float = spec("Mass per unit length in air rho_0.", "kg/m", check=positive)
    density: float | None = spec(
        "Material density rho_c; submerged weight w = rho_0 g (rho_c - rho_w)/rho_c (seed FEM eq. 2). "
        "Give exactly one of density and submerged_weight.",
        "kg/m^3",
        default=None,
        check=positive_at_most(25000.0, "osmium, the densest material, is 22 600 kg/m^3"),
    )
    submerged_weight: float | None = spec(
        "Submerged weight per unit length w (instead of density).", "N/m", default=None, check=positive
    )
    EA: float | None = spec(
        "Axial stiffness. With EA_table: the table's secant at its last row, T_n / eps_n (MoorDyn's one "
        "number for a tabulated line, its damping ratio's stiffness); then leave it out or give that value.",
        "N", default=None, check=positive)
    EA_table: Mat | None = spec(
        "Nonlinear axial stiffness (polyester, nylon, HMPE): rows [strain, tension] from [0, 0], both "
        "strictly increasing, linear between rows and beyond the last (at least 2 rows); absent: constant EA.",
        "-, N", default=None, shape=(-1, 2))
    MBS: float = spec("Minimum breaking strength (mean breaking strength in the reliability index).", "N", check=positive)
    MBS_std: float = spec("Standard deviation of the breaking strength sigma_b (survey eq. 32).", "N", check=nonneg)
    Cd_normal: float = spec("Normal drag coefficient C_DN (on diameter).", check=bounded(0.0, 10.0, _COEF))
    Cd_tangential: float = spec(
        "Tangential drag coefficient C_DT (on diameter; MoorDyn's CdAx acts on pi x diameter, so C_DT = pi CdAx).",
        check=bounded(0.0, 10.0 * math.pi, "measured coefficients of chain, wire and rope are 0-3; the bound is "
                      "MoorDyn's CdAx <= 10 on pi x diameter"))
    Ca_normal: float = spec("Normal added-mass coefficient C_MN.", check=bounded(0.0, 10.0, _COEF))
    Ca_tangential: float = spec("Tangential added-mass coefficient.", default=0.0, check=bounded(0.0, 10.0, _COEF))
    max_strain: float | None = spec(
        "Largest allowed axial strain; absent: the strain at MBS (MBS/EA, or from EA_table).", default=None,
        check=in_range(0.0, 1.0)
    )
    seabed_friction: float = spec("Seabed friction coefficient C_B (catenary and FEM seabed contact).", default=0.0,
                                  check=bounded(0.0, 5.0, "chain on clay or sand is about 0.7-1"))
    axial_damping_ratio: float = spec(
        "FEM axial internal damping as a fraction of the critical damping of one segment's axial mode.",
        default=0.0, check=in_range(0.0, 1.0))

    def __post_init__(self) -> None:
        if self.EA is None and self.EA_table is not None:  # EA is the table's secant (a bad table: validation says)
            ea = secant_of_rows(self.EA_table)
            if ea is not None:
                object.__setattr__(self, "EA", ea)

    def w(self, env: Environment) -> float:
        """Submerged weight per unit unstretched length [N/m]."""
        if self.submerged_weight is not None:
            return float(self.submerged_weight)
        assert self.density is not None  # guaranteed by validation
        return float(self.mass_per_length * env.gravity * (self.density - env.water_density) / self.density)

    @cached_property
    def strain_table(self) -> StrainTable | None:
        """The nonlinear axial law of :attr:`EA_table` (:class:`~tapm_opt.strain_table.StrainTable`),
        or None for a constant EA."""
        return None if self.EA_table is None else StrainTable.from_rows(self.EA_table)

    @property
    def strain_limit(self) -> float:
        """Largest strain the line may take: ``max_strain``, else the strain at MBS (MBS/EA, or the
        table's strain at MBS) [-]."""
        if self.max_strain is not None:
            return float(self.max_strain)
        if self.EA_table is not None:
            return float(self.strain_table.strain_at(self.MBS))
        return float(self.MBS / self.EA)

    @property
    def max_EA(self) -> float:
        """The stiffest axial stiffness the line reaches [N]: EA, or the table's largest slope
        (the FEM's stable step, the axial wave speed)."""
        return float(self.EA if self.EA_table is None else self.strain_table.max_slope)


@dataclass(frozen=True, kw_only=True)
class PointType:
    """A connection point between two sections of a composite line that carries a clump weight or a
    buoy (MoorDyn's point: mass, volume, CdA, Ca). Its net submerged weight is
    ``W = (mass - rho_w volume) g`` [N], positive down (a clump), negative up (a buoy)."""

    id: str = spec("Name referenced by lines[].sections[].top.", id_like=True)
    mass: float = spec("Mass in air (clump weight, buoy hull and ballast).", "kg", default=0.0,
                       check=bounded(0.0, 1e7, "the largest clumps and buoys weigh a few hundred tonnes"))
    volume: float = spec("Displaced volume (buoyancy).", "m^3", default=0.0,
                         check=bounded(0.0, 1e4, "the largest mooring buoys displace a few hundred m^3"))
    CdA: float = spec("Drag coefficient times frontal area, isotropic (MoorDyn's CdA).", "m^2", default=0.0,
                      check=bounded(0.0, 1e3, "a 10 m buoy has CdA of about 80 m^2"))
    Ca: float = spec("Added-mass coefficient on the displaced volume: added mass Ca rho_w volume (MoorDyn's Ca).",
                     default=0.0, check=bounded(0.0, 10.0, _COEF))

    def net_weight(self, env: "Environment") -> float:
        """Net submerged weight [N], positive down: ``(mass - rho_w volume) g``."""
        return float((self.mass - env.water_density * self.volume) * env.gravity)


@dataclass(frozen=True, kw_only=True)
class Section:
    """One section of a composite line: a length of one line type. Sections run from the anchor up
    to the fairlead; the point between a section and the next one up may carry a clump or a buoy."""

    type: str = spec("Line type id (line_types[].id).", id_like=True)
    length: float = spec("Unstretched length of the section.", "m", check=positive)
    segments: int | None = spec(
        "FEM segments of the section; absent: the line's segments shared by length (at least 1 each).",
        default=None, check=positive)
    top: str | None = spec(
        "Point type id (point_types[].id) at the section's upper end, where it joins the next section up; "
        "absent: a plain joint without mass. Not allowed on the last (fairlead) section.",
        default=None, id_like=True)


@dataclass(frozen=True, kw_only=True)
class Line:
    """One mooring line from its lower end, the anchor (on the seabed or above it: z between the
    fairlead depth and the water depth), to its fairlead on the turret. A homogeneous line gives
    ``type`` and ``length``; a composite line gives ``sections`` instead (from the anchor up), and
    then ``type`` is read as the fairlead section's type and ``length`` as the total length."""

    id: str = spec("Line name (unique).", id_like=True)
    type: str | None = spec("Line type id (line_types[].id); absent when sections are given.", default=None,
                            id_like=True)
    sections: tuple[Section, ...] = spec(
        "Composite line: sections in series from the anchor up to the fairlead (at least 2); absent: one "
        "section of type and length.", default=())
    anchor: Vec = spec(
        "Lower end in {E}: (x, y) on the seabed, or (x, y, z) with z (down) between the fairlead depth and "
        "the water depth: an anchor on the seabed (z = water depth) or above it (a clump, a buoy, a slope).",
        "m",
        shape=(-1,),
    )
    fairlead_angle: float = spec("Fairlead angle gamma_i on the turret circle in {T} (eq. 2).", "deg", check=_ANGLE)
    fairlead_radius: float | None = spec(
        "Fairlead radius r_i; absent: turret.fairlead_radius.", "m", default=None, check=nonneg
    )
    length: float | None = spec("Unstretched length L; absent when sections are given (then their sum).", "m",
                                default=None, check=positive)
    segments: int = spec("Number of FEM segments n (nodes 0..n, 0 at the anchor); for a composite line the total "
                         "when its sections do not give theirs, shared so that the longest segment is shortest "
                         "(each section at least one).", default=20, check=fem_segments)
    winch_max_rate: float = spec("Largest winch pay-out/haul-in speed (0: no winch); on a composite line the winch "
                                 "pays out and hauls in the fairlead section.", "m/s", default=0.0,
                                 check=bounded(0.0, 10.0, "mooring winches run at about 0.1-0.5 m/s"))
    min_length: float | None = spec("Shortest unstretched length the winch may haul in to; absent: length. On a "
                                    "composite line more than its other sections' length.", "m",
                                    default=None, check=positive)
    max_length: float | None = spec("Longest unstretched length the winch may pay out to; absent: length.", "m",
                                    default=None, check=positive)

    def __post_init__(self) -> None:
        # a composite line reads as its fairlead section's type and its total length where one
        # type and one length are asked for (strain limit, MBS at the fairlead, reach checks)
        if self.sections:
            if self.type is None:
                object.__setattr__(self, "type", self.sections[-1].type)
            if self.length is None:
                object.__setattr__(self, "length", float(sum(s.length for s in self.sections)))
            if self.segments == 20 and all(s.segments is not None for s in self.sections):
                object.__setattr__(self, "segments", int(sum(s.segments for s in self.sections)))

    @property
    def composite(self) -> bool:
        """True for a line of several sections."""
        return len(self.sections) > 1

    @property
    def parts(self) -> tuple[Section, ...]:
        """The line's sections from the anchor up (one for a homogeneous line)."""
        if self.sections:
            return self.sections
        return (Section(type=self.type or "", length=float(self.length or 0.0), segments=self.segments),)

    def section_segments(self) -> tuple[int, ...]:
        """FEM segments of each section: the sections' own, or the line's ``segments`` shared so that
        the longest segment is as short as it can be (each section at least one; a segment at a time
        to the section whose segments are longest, ties to the lower section).

        Sharing by length alone can leave a short section with one segment across its touchdown
        (fpso at 10 segments: 300 / 1900 / 100 m gave 1 / 8 / 1, a 300 m chain segment longer than
        the wire's 237 m); this rule gives 2 / 7 / 1 (150, 271, 100 m)."""
        parts = self.parts
        if all(s.segments is not None for s in parts):
            return tuple(int(s.segments) for s in parts)
        L = np.array([s.length for s in parts], float)
        free = np.array([s.segments is None for s in parts])
        n = np.array([1 if s.segments is None else int(s.segments) for s in parts])
        for _ in range(int(self.segments) - int(n.sum())):
            seg = np.where(free, L / n, -np.inf)
            n[int(np.argmax(seg))] += 1
        return tuple(int(k) for k in n)

    @property
    def length_limits(self) -> tuple[float, float]:
        """(shortest, longest) unstretched length the winch allows [m]."""
        lo = self.length if self.min_length is None else self.min_length
        hi = self.length if self.max_length is None else self.max_length
        return float(lo), float(hi)


@dataclass(frozen=True, kw_only=True)
class Thruster:
    """A thruster; thrust f acts along the azimuth alpha measured from x^B toward y^B."""

    id: str = spec("Thruster name (unique).", id_like=True)
    kind: Literal["azimuth", "tunnel", "fixed"] = spec(
        "'azimuth' (rotatable, thrust >= 0), 'tunnel' (fixed axis, reversible), 'fixed' (fixed axis)."
    )
    position: Vec = spec("Position in {B} (x fwd, y stbd).", "m", shape=(2,))
    angle: float = spec(
        "Thrust direction alpha for tunnel/fixed (tunnel: 90 = toward starboard); initial azimuth.",
        "deg",
        default=0.0,
        check=_ANGLE,
    )
    max_thrust: float = spec("Largest thrust along +alpha.", "N", check=positive)
    max_reverse_thrust: float = spec(
        "Largest thrust along -alpha (tunnel and fixed; must be 0 for azimuth).", "N", default=0.0, check=nonneg
    )
    max_thrust_rate: float = spec("Largest rate of change of thrust.", "N/s", check=positive)
    max_azimuth_rate: float | None = spec(
        "Largest azimuth turning rate (azimuth thrusters only).", "deg/s", default=None,
        check=positive_at_most(360.0, "azimuth thrusters turn at about 2-30 deg/s"),
    )
    time_constant: float = spec("First-order thrust response time constant.", "s",
                                check=positive_at_most(100.0, "thrusters respond in about 1-10 s"))
    forbidden_sectors: tuple[tuple[float, ...], ...] = spec(
        "Azimuth sectors (from, to) the thrust may not point into (azimuth only), degrees.",
        "deg",
        default=(),
        shape=(-1, 2),
        check=bounded(-720.0, 720.0, "a sector's ends lie within two turns"),
    )


@dataclass(frozen=True, kw_only=True)
class SeaStateRow:
    """A row of a developing sea state's time table: the values at time ``t``; a value a row leaves
    out is interpolated between the rows that give it (the sea state's own value at t = 0)."""

    t: float = spec("Time from the start of the run.", "s", check=bounded(0.0, 1.0e6, "about 11 days"))
    Hs: float | None = spec("Significant wave height.", "m", default=None,
                            check=bounded(0.0, 30.0, "the largest measured Hs is about 19 m"))
    Tp: float | None = spec("Spectral peak period.", "s", default=None,
                            check=bounded(1.0, 40.0, "ocean wind sea and swell peak at 2-25 s"))
    wind_speed: float | None = spec("1-hour mean wind speed at 10 m (a squall: its time series).", "m/s",
                                    default=None, check=bounded(0.0, 100.0, "beyond any recorded mean wind"))
    wind_direction: float | None = spec("Wind direction (going to).", "deg", default=None, check=_ANGLE)
    current_speed: float | None = spec("Surface current speed.", "m/s", default=None,
                                       check=bounded(0.0, 10.0, "the strongest tidal races run at about 5 m/s"))
    current_direction: float | None = spec("Current direction (going to).", "deg", default=None, check=_ANGLE)


#: The sea-state fields a development table may change in time (:class:`SeaStateRow`).
DEVELOPING_FIELDS = ("Hs", "Tp", "wind_speed", "wind_direction", "current_speed", "current_direction")


@dataclass(frozen=True, kw_only=True)
class SeaState:
    """Environmental condition. Directions are where the wave/wind/current is going to, from north."""

    id: str = spec("Sea state name (unique).", id_like=True)
    Hs: float = spec("Significant wave height.", "m", check=bounded(0.0, 30.0, "the largest measured Hs is about 19 m"))
    Tp: float = spec("Spectral peak period.", "s", check=bounded(1.0, 40.0, "ocean wind sea and swell peak at 2-25 s"))
    gamma: float = spec("JONSWAP peak enhancement factor.", default=3.3, check=in_range(1.0, 10.0))
    wave_direction: float = spec("Mean wave direction (going to).", "deg", default=0.0, check=_ANGLE)
    wind_speed: float = spec("1-hour mean wind speed at 10 m.", "m/s", default=0.0,
                              check=bounded(0.0, 100.0, "beyond any recorded mean wind"))
    wind_direction: float = spec("Wind direction (going to).", "deg", default=0.0, check=_ANGLE)
    current_speed: float = spec("Surface current speed V_c.", "m/s", default=0.0,
                                 check=bounded(0.0, 10.0, "the strongest tidal races run at about 5 m/s"))
    current_direction: float = spec("Current direction beta_c (going to, eq. 7).", "deg", default=0.0, check=_ANGLE)
    current_turn_rate: float = spec(
        "Rate of turn of the current direction: beta_c(t) = current_direction + rate t (a tidal current "
        "that rotates; 0: steady).", "deg/s", default=0.0,
        check=bounded(-1.0, 1.0, "a tidal current turns once in about 12 h, 0.008 deg/s"),
    )
    current_profile: Literal["uniform", "linear", "piecewise"] = spec(
        "Current speed over depth: 'uniform'; 'linear' from 1 at the surface to "
        "current_profile_factors[0] at the seabed; 'piecewise' linear through (depths, factors).",
        default="uniform",
    )
    current_profile_depths: Vec = spec(
        "Depths of the piecewise profile, increasing from 0.", "m", default=(), shape=(-1,), check=nonneg
    )
    current_profile_factors: Vec = spec(
        "Speed factors (times current_speed) at those depths, or the seabed factor for 'linear'.",
        default=(),
        shape=(-1,),
        check=bounded(0.0, 3.0, "currents below the surface are rarely faster than at it"),
    )
    wave_spreading: float | None = spec(
        "Directional spreading exponent s of the short-crested sea, D = cos^(2s)((theta - wave_direction)/2) "
        "normalised (DNV-RP-C205 §3.5.8.4; s = 6-15 wind sea, 15-75 swell); absent: long-crested.",
        default=None, check=bounded(1.0, 200.0, "s = 200 is all but long-crested"))
    development: tuple[SeaStateRow, ...] = spec(
        "A sea state that develops within a run: rows of (t and) the values at t, linear between rows, "
        "held after the last; the fields above are the values at t = 0 (absent: steady).", default=())


@dataclass(frozen=True, kw_only=True)
class Riser:
    """A single riser treated quasi-statically (reliability seed §2.1). The plant's riser model
    (``tapm_opt.models.riser``, a tensioned beam) needs a top-tensioned riser: no longer than the
    water depth, hanging from a hang-off at depth water_depth - length."""

    hangoff: Vec = spec("Hang-off point in {B}.", "m", shape=(2,))
    wellhead: Vec = spec("Lower end (wellhead / touchdown) in {E}.", "m", shape=(2,))
    length: float = spec("Riser length.", "m", check=positive)
    diameter: float = spec("Outer (hydrodynamic) diameter.", "m",
                           check=positive_at_most(5.0, "risers and their buoyancy are under 2 m"))
    submerged_weight: float = spec("Submerged weight per unit length, contents included.", "N/m", check=positive)
    top_tension: float = spec("Mean top tension.", "N", check=positive)
    Cd: float = spec("Normal drag coefficient (on diameter).", default=1.0, check=bounded(0.0, 10.0, _COEF))
    wall_thickness: float = spec(
        "Wall thickness t of the riser pipe, less than diameter / 2 (0: no bending stiffness, a tensioned "
        "string).", "m", default=0.0, check=nonneg)
    youngs_modulus: float = spec("Young's modulus E of the pipe wall (steel: 2.1e11 Pa).", "Pa", default=2.1e11,
                                 check=positive_at_most(1.2e12, "diamond, the stiffest material, is about 1.2e12 Pa"))
    critical_top_angle: float = spec("Mean critical top angle (threshold r_t).", "deg", check=positive_at_most(90.0))
    critical_top_angle_std: float = spec("Standard deviation of the critical top angle.", "deg",
                                         check=positive_at_most(90.0))
    critical_bottom_angle: float = spec("Mean critical bottom angle.", "deg", check=positive_at_most(90.0))
    critical_bottom_angle_std: float = spec("Standard deviation of the critical bottom angle.", "deg",
                                            check=positive_at_most(90.0))

    @property
    def EI(self) -> float:
        """Bending stiffness of the pipe, ``E pi/64 (D^4 - (D - 2 t)^4)`` [N m^2] (0 for
        ``wall_thickness = 0``)."""
        D, t = self.diameter, self.wall_thickness
        if t <= 0.0:
            return 0.0
        return self.youngs_modulus * math.pi / 64.0 * (D**4 - max(D - 2.0 * t, 0.0) ** 4)


#: The sensor faults (:class:`Fault` kinds that corrupt a measurement, not the physics): GNSS
#: dropout and drift, a fairlead tension cell stuck, drifting or noisy, a gyro-compass stuck or
#: drifting (:mod:`tapm_opt.plant.sensors`).
SENSOR_FAULT_KINDS = ("gnss_dropout", "gnss_drift", "cell_stuck", "cell_drift", "cell_noisy", "gyro_stuck",
                      "gyro_drift")
#: The fields each sensor fault kind needs (besides ``kind`` and ``time``; ``end_time`` is optional
#: for every one of them) and may carry; ``cell_drift`` takes exactly one of ``rate`` and ``rate_rel``.
SENSOR_FAULT_FIELDS = {"gnss_dropout": ((), ()), "gnss_drift": (("speed", "direction"), ()),
                       "cell_stuck": (("line",), ()), "cell_drift": (("line",), ("rate", "rate_rel")),
                       "cell_noisy": (("line", "factor"), ()), "gyro_stuck": ((), ("gyro",)),
                       "gyro_drift": (("heading_rate",), ("gyro",))}
#: The fields of a :class:`Fault` only a sensor fault carries.
SENSOR_FAULT_ONLY = ("end_time", "speed", "direction", "rate", "rate_rel", "heading_rate", "factor", "gyro")


def _finite_nonzero(v: float) -> str | None:
    return None if math.isfinite(v) and v != 0 else "must be a finite number other than 0"


_finite_nonzero.__doc__ = "finite, not 0"


@dataclass(frozen=True, kw_only=True)
class Fault:
    """A fault injected into the plant at a given time: a line breaks at its fairlead, a thruster
    fails, or a buoy comes off a joint of a composite line (from then on the joint carries no
    point: its mass, buoyancy, added mass and drag are gone); or a sensor fault
    (:data:`SENSOR_FAULT_KINDS`) from ``time`` to ``end_time``: the GNSS gives no fix
    (``gnss_dropout``: the measurement says its position is invalid) or drifts silently at
    ``speed`` toward ``direction`` (``gnss_drift``); the tension cell of ``line`` holds its last
    reading (``cell_stuck``), drifts at ``rate`` [N/s] or ``rate_rel`` [MBS/s] (``cell_drift``) or
    has its noise multiplied by ``factor`` (``cell_noisy``); gyro-compass ``gyro`` holds its last
    heading (``gyro_stuck``) or drifts at ``heading_rate`` (``gyro_drift``)."""

    kind: Literal["line_break", "thruster_failure", "buoy_loss", "gnss_dropout", "gnss_drift", "cell_stuck",
                  "cell_drift", "cell_noisy", "gyro_stuck", "gyro_drift"] = spec("Fault kind.")
    time: float = spec("Time the fault occurs.", "s", check=nonneg)
    line: str | None = spec("Line id (line_break, buoy_loss; the line whose tension cell fails for cell_stuck, "
                            "cell_drift, cell_noisy).", default=None, id_like=True)
    thruster: str | None = spec("Thruster id (thruster_failure).", default=None, id_like=True)
    joint: int | None = spec(
        "Joint of the buoy (buoy_loss): its index from the anchor up, 0 joining the line's sections 0 and 1; "
        "give joint or point.", default=None, check=nonneg)
    point: str | None = spec(
        "Point type id of the buoy (buoy_loss), instead of joint: the one joint of the line that carries it.",
        default=None, id_like=True)
    end_time: float | None = spec("End of a sensor fault: the sensor is healthy again from then on (none: to the "
                                  "end of the run); after time.", "s", default=None, check=nonneg)
    speed: float | None = spec("Speed of the GNSS position's silent drift (gnss_drift).", "m/s", default=None,
                               check=positive_at_most(10.0, "a drift faster than a vessel moves is no silent drift"))
    direction: float | None = spec("Direction the GNSS position drifts to (gnss_drift), from north (x) toward east "
                                   "(y).", "deg", default=None, check=_ANGLE)
    rate: float | None = spec("Drift of the tension cell's reading (cell_drift), + up.", "N/s", default=None,
                              check=_finite_nonzero)
    rate_rel: float | None = spec("Drift of the tension cell's reading (cell_drift) as a fraction of the line's MBS "
                                  "per second, + up; instead of rate.", "1/s", default=None,
                                  check=bounded(-0.1, 0.1, "10 % of MBS a second is a break, not a drift"))
    heading_rate: float | None = spec("Drift of the gyro-compass heading (gyro_drift), + clockwise.", "deg/s",
                                      default=None, check=_finite_nonzero)
    factor: float | None = spec("Multiplier of the tension cell's noise standard deviation (cell_noisy).",
                                default=None, check=bounded(1.0, 1000.0, "a cell's noise grows when it fails"))
    gyro: int | None = spec("Gyro-compass that fails (gyro_stuck, gyro_drift): 1 or 2 (default 1).", default=None,
                            check=in_range(1, 2))


def sensor_fault_issues(fault: Any, line_ids: Any) -> list[tuple[str, str]]:
    """``(field, message)`` of everything wrong with a sensor fault's fields (empty when it is
    right, or when ``fault`` is not a sensor fault): the fields its kind needs
    (:data:`SENSOR_FAULT_FIELDS`), the ones it may not carry, the line of a cell fault among
    ``line_ids``, ``end_time`` after ``time``. The one statement of these rules (scenario loader,
    plant, study files). A message follows the field name (``"= 3.0 must be ..."``)."""
    kind = getattr(fault, "kind", None)
    out: list[tuple[str, str]] = []
    if kind not in SENSOR_FAULT_KINDS:
        for name in SENSOR_FAULT_ONLY:
            if getattr(fault, name, None) is not None:
                out.append((name, f"is only for a sensor fault ({', '.join(SENSOR_FAULT_KINDS)}), not a {kind}"))
        return out
    need, may = SENSOR_FAULT_FIELDS[kind]
    for name in need:
        if getattr(fault, name, None) is None:
            out.append((name, f"is required for a {kind}"))
    for name in ("line", "thruster", "joint", "point", *SENSOR_FAULT_ONLY):
        if name not in need and name not in may and name != "end_time" and getattr(fault, name, None) is not None:
            out.append((name, f"is not a field of a {kind}"))
    if kind == "cell_drift" and (fault.rate is None) == (fault.rate_rel is None):
        out.append(("rate", "give exactly one of rate [N/s] and rate_rel [MBS/s] for a cell_drift"))
    ids = [str(i) for i in line_ids]
    if "line" in need and fault.line is not None and str(fault.line) not in ids:
        out.append(("line", f"= {fault.line!r} is not a line id; lines are {ids}"))
    for name, check in (("time", nonneg), ("end_time", nonneg), ("speed", positive), ("factor", at_least(1.0)),
                        ("rate", _finite_nonzero), ("rate_rel", _finite_nonzero), ("heading_rate", _finite_nonzero),
                        ("direction", _ANGLE)):
        v = getattr(fault, name, None)
        if v is None:
            continue
        try:
            bad = None if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else \
                "must be a finite number"
            bad = bad or check(v)
        except TypeError:
            bad = "must be a number"
        if bad:
            out.append((name, f"= {v!r} {bad}"))
    g = getattr(fault, "gyro", None)
    if g is not None and (isinstance(g, bool) or g not in (1, 2)):
        out.append(("gyro", f"= {g!r} must be 1 or 2 (the vessel's two gyro-compasses)"))
    e = getattr(fault, "end_time", None)
    if e is not None and isinstance(e, (int, float)) and isinstance(fault.time, (int, float)) and e <= fault.time:
        out.append(("end_time", f"= {e:g} s must be after time = {fault.time:g} s"))
    return out


class FaultTargetError(ValueError):
    """A fault names something the scenario does not have; ``field`` is the fault's field to blame
    (``"line"``, ``"joint"``, ``"point"``) and the message starts as a scenario issue does."""

    def __init__(self, field_name: str, message: str):
        self.field = field_name
        super().__init__(message)


def buoy_of_fault(scenario: "Scenario", line: str | None, joint: int | None = None,
                  point: str | None = None) -> tuple[int, int]:
    """(line index, joint index) of the buoy a ``buoy_loss`` fault takes off ``line`` at ``joint``
    (index from the anchor up) or at the one joint carrying point type ``point``.

    Raises :class:`FaultTargetError` naming the field when the line is unknown or homogeneous (no
    joint), the joint is out of range or carries no point, the point is not buoyant (net weight
    ``(mass - rho_w volume) g >= 0``: a clump), or ``point`` is at no joint of the line or at
    several; exactly one of ``joint`` and ``point`` must be given."""
    ids = [ln.id for ln in scenario.lines]
    if line is None:
        raise FaultTargetError("line", "is required for a buoy_loss (the composite line that loses the buoy)")
    if str(line) not in ids:
        raise FaultTargetError("line", f"= {line!r} is not a line id; lines are {ids}")
    i = ids.index(str(line))
    ln = scenario.lines[i]
    if not ln.composite:
        raise FaultTargetError("line", f"= {line!r} is a homogeneous line: it has no joints, so no buoy to lose "
                                       "(a buoy sits at a joint of a composite line's sections)")
    tops = [s.top for s in ln.parts[:-1]]
    env = scenario.environment
    where = ", ".join(f"{j}: {t!r}" for j, t in enumerate(tops) if t is not None) or "none"
    if (joint is None) == (point is None):
        raise FaultTargetError("joint", f"give exactly one of joint and point for a buoy_loss (the joint's index "
                                        f"from the anchor up, or the point type id); line {line!r} has points at "
                                        f"joints {{{where}}}")
    if point is not None:
        at = [j for j, t in enumerate(tops) if t == str(point)]
        if not at:
            raise FaultTargetError("point", f"= {point!r} is at no joint of line {line!r}; its points are at joints "
                                            f"{{{where}}}")
        if len(at) > 1:
            raise FaultTargetError("point", f"= {point!r} is at joints {at} of line {line!r}: give joint instead")
        j, fld = at[0], "point"
    else:
        j, fld = int(joint), "joint"
        if not 0 <= j < len(tops):
            raise FaultTargetError("joint", f"= {j}: line {line!r} has {len(tops) + 1} sections, so joints 0 to "
                                            f"{len(tops) - 1} from the anchor up")
        if tops[j] is None:
            raise FaultTargetError("joint", f"= {j}: joint {j} of line {line!r} is a plain joint with no point type; "
                                            f"its points are at joints {{{where}}}")
    pt = scenario.point_type(tops[j])
    W = pt.net_weight(env)
    if not W < 0:
        val = j if fld == "joint" else repr(tops[j])
        raise FaultTargetError(fld, f"= {val}: the point at joint {j} of line {line!r} ({tops[j]!r}, net weight "
                                    f"{W / 1e3:+.4g} kN, positive down) is not buoyant: a buoy_loss takes off a buoy "
                                    "(mass - water_density x volume < 0)")
    return i, j


@dataclass(frozen=True, kw_only=True)
class Sensors:
    """Measurement noise and rates of the plant's sensors (sample and hold at each rate)."""

    gnss_std: float = spec("GNSS position noise, standard deviation per axis.", "m", default=0.5,
                           check=bounded(0.0, 100.0, "uncorrected GNSS is within about 10 m"))
    gnss_rate: float = spec("GNSS update rate.", "Hz", default=1.0, check=positive)
    heading_std: float = spec("Gyro-compass heading noise, standard deviation.", "deg", default=math.radians(0.1),
                              check=bounded(0.0, 180.0, "half a turn"))
    heading_rate: float = spec("Heading update rate.", "Hz", default=10.0, check=positive)
    tension_std_rel: float = spec("Tension-cell noise, standard deviation as a fraction of the line's MBS.",
                                  default=0.002, check=bounded(0.0, 1.0, "a noise of the whole MBS"))
    tension_rate: float = spec("Tension-cell update rate.", "Hz", default=1.0, check=positive)
    riser_angle_std: float = spec("Riser-angle noise (inclinometers at the top and bottom flex joints), standard "
                                  "deviation per component.", "deg", default=math.radians(0.05),
                                  check=bounded(0.0, 90.0, "an angle from the vertical"))
    riser_angle_rate: float = spec("Riser-angle update rate.", "Hz", default=1.0, check=positive)
    mru_angle_std: float = spec("Motion reference unit (vessels with vessel.roll_pitch): roll and pitch noise, "
                                "standard deviation.", "deg", default=math.radians(0.02),
                                check=bounded(0.0, 90.0, "an inclination"))
    mru_rate_std: float = spec("Motion reference unit: roll and pitch rate noise, standard deviation.", "deg/s",
                               default=math.radians(0.01),
                               check=bounded(0.0, 90.0, "a rate of a quarter turn a second"))
    mru_rate: float = spec("Motion reference unit update rate.", "Hz", default=10.0, check=positive)


@dataclass(frozen=True, kw_only=True)
class PlantSettings:
    """Physics options of the FEM plant."""

    break_on_overload: Literal["mbs", "sampled", "never"] = spec(
        "A line whose fairlead or anchor tension reaches its breaking strength breaks: 'mbs' at the "
        "line type's MBS, 'sampled' at a strength drawn once per line from N(MBS, MBS_std) with the "
        "case seed, 'never' to let tensions exceed MBS (analysis only).",
        default="mbs")


@dataclass(frozen=True, kw_only=True)
class Limits:
    """Operational limits of the position-mooring system."""

    safe_radius: float | None = spec("Radius of the safe (green) circle about the field zero point.", "m",
                                     default=None, check=positive)
    alert_radius: float | None = spec("Radius of the alert (red) circle; larger than safe_radius.", "m",
                                      default=None, check=positive)
    tension_utilisation: float = spec(
        "Allowed fairlead tension as a fraction of MBS (default 1/1.67, API RP 2SK intact dynamic).",
        default=round(1 / 1.67, 4),
        check=in_range(0.0, 1.0),
    )


@dataclass(frozen=True, kw_only=True)
class Scenario:
    """A complete, validated TAPM scenario. Immutable; derive variants with ``dataclasses.replace``
    (re-validate with :func:`tapm_opt.config.validate`)."""

    meta: Meta = spec("Name, description, sources.")
    environment: Environment = spec("Site constants.")
    vessel: Vessel = spec("Hull and hydrodynamics.")
    turret: Turret = spec("Turret and fairlead circle.")
    line_types: tuple[LineType, ...] = spec("Line materials.")
    lines: tuple[Line, ...] = spec("Mooring lines.")
    point_types: tuple[PointType, ...] = spec("Clump weights and buoys at the joints of composite lines.",
                                              default=())
    thrusters: tuple[Thruster, ...] = spec("Thrusters.", default=())
    sea_states: tuple[SeaState, ...] = spec("Sea states; the first is the default.", default=())
    riser: Riser | None = spec("Optional riser.", default=None)
    faults: tuple[Fault, ...] = spec("Faults to inject.", default=())
    sensors: Sensors = spec("Sensor noise and rates.", default=Sensors())
    limits: Limits = spec("Operational limits.", default=Limits())
    plant: PlantSettings = spec("FEM plant physics options.", default=PlantSettings())

    @property
    def name(self) -> str:
        return self.meta.name

    def line_type(self, line: Line | int) -> LineType:
        """The :class:`LineType` of a line (given as object or index)."""
        if isinstance(line, int):
            line = self.lines[line]
        for lt in self.line_types:
            if lt.id == line.type:
                return lt
        raise KeyError(line.type)

    def line_type_by_id(self, type_id: str) -> LineType:
        """The :class:`LineType` with id ``type_id``; ``KeyError`` if there is none."""
        for lt in self.line_types:
            if lt.id == type_id:
                return lt
        raise KeyError(type_id)

    def line_index(self, line_id: str | int) -> int:
        """Index of the line with id ``line_id``; ``KeyError`` if there is none."""
        for i, ln in enumerate(self.lines):
            if ln.id == str(line_id):
                return i
        raise KeyError(f"no line with id {line_id!r}; lines are {[ln.id for ln in self.lines]}")

    def sea_state(self, sea_state_id: str | None = None) -> SeaState:
        """The sea state with the given id (default: the first)."""
        if not self.sea_states:
            raise KeyError("the scenario defines no sea state")
        if sea_state_id is None:
            return self.sea_states[0]
        for s in self.sea_states:
            if s.id == str(sea_state_id):
                return s
        raise KeyError(f"no sea state {sea_state_id!r}; sea states are {[s.id for s in self.sea_states]}")

    @cached_property
    def anchors(self) -> np.ndarray:
        """Anchor positions in {E}, shape (n_lines, 3) [m]; z down: the water depth less the anchor's
        height above the seabed (``line_arrays["h_A"]``)."""
        depth = self.environment.water_depth
        h = self.line_arrays["h_A"]
        return readonly([(ln.anchor[0], ln.anchor[1], depth - h[i]) for i, ln in enumerate(self.lines)])

    @cached_property
    def fairleads_T(self) -> np.ndarray:
        """Fairlead positions in {T}, shape (n_lines, 2) [m] (eq. 2, :func:`tapm_opt.geometry.fairleads_T`)."""
        r = [self.turret.fairlead_radius if ln.fairlead_radius is None else ln.fairlead_radius for ln in self.lines]
        g = [ln.fairlead_angle for ln in self.lines]
        return readonly(geometry.fairleads_T(r, g))

    @cached_property
    def line_arrays(self) -> dict[str, np.ndarray]:
        """Per-line properties as arrays of shape (n_lines,): L, EA, w, CB, MBS, MBS_std, d, segments,
        and h_A. For a composite line (:attr:`line_sections`) L is the total length, EA the series
        stiffness ``L / sum(L_k / EA_k)``, w the mean submerged weight with the points' net weights,
        ``(sum w_k L_k + sum W_j) / L``, CB the bottom section's friction, and MBS, MBS_std, d and the
        strain limit the fairlead section's (its type is the line's ``type``); the composite-line
        models read the sections themselves. h_A is the height of the anchor above the seabed [m] (water depth - anchor z; 0 for an
        anchor given as (x, y) or with |z - water depth| <= 1e-6 water depth, on the seabed as the
        file check has it)."""
        env = self.environment
        types = [self.line_type(ln) for ln in self.lines]
        secs = self.line_sections
        out = {
            "L": [ln.length for ln in self.lines],
            "EA": [float(sc["L"].sum() / np.sum(sc["L"] / sc["EA"])) for sc in secs],
            "w": [float((np.sum(sc["w"] * sc["L"]) + np.sum(sc["W"])) / sc["L"].sum()) for sc in secs],
            "CB": [float(sc["CB"][0]) for sc in secs],
            "MBS": [t.MBS for t in types],
            "MBS_std": [t.MBS_std for t in types],
            "d": [t.diameter for t in types],
            "strain_limit": [t.strain_limit for t in types],
            "segments": [int(sum(ln.section_segments())) for ln in self.lines],
            "h_A": [0.0 if len(ln.anchor) < 3 or abs(env.water_depth - ln.anchor[2]) <= 1e-6 * env.water_depth
                    else env.water_depth - ln.anchor[2] for ln in self.lines],
        }
        return {k: readonly(v) for k, v in out.items()}

    def point_type(self, point_id: str) -> PointType:
        """The :class:`PointType` with id ``point_id``; ``KeyError`` if there is none."""
        for pt in self.point_types:
            if pt.id == point_id:
                return pt
        raise KeyError(point_id)

    @cached_property
    def line_sections(self) -> tuple[dict[str, np.ndarray], ...]:
        """Per line, its sections from the anchor up and the points between them, as arrays.

        Section arrays, shape (n_sections,): ``L`` [m], ``EA`` [N], ``w`` submerged weight [N/m],
        ``mass`` [kg/m], ``d`` [m], ``Cdn``, ``Cdt``, ``Can``, ``Cat``, ``CB``, ``damping_ratio``,
        ``MBS`` [N], ``segments``. Point arrays, shape (n_sections - 1,), point j joining section j
        to section j + 1: ``W`` net submerged weight [N] (positive down), ``point_mass`` [kg],
        ``point_volume`` [m^3], ``point_CdA`` [m^2], ``point_Ca`` [-] (zeros for a plain joint).
        ``EA_table``: per section its :class:`~tapm_opt.strain_table.StrainTable` (nonlinear axial
        stiffness; its ``EA`` the table's secant) or None, a tuple. ``surface`` (a line with a
        buoyant section only): the sea surface's height above the seabed [m], the water depth,
        which the section may not reach. A homogeneous line is the one-section case."""
        env = self.environment
        types = {t.id: t for t in self.line_types}
        points = {p.id: p for p in self.point_types}
        out = []
        for ln in self.lines:
            parts = ln.parts
            ts = [types[s.type] for s in parts]
            pts = [points[s.top] if s.top is not None else None for s in parts[:-1]]
            d = {
                "L": [s.length for s in parts],
                "EA": [t.EA for t in ts],
                "w": [t.w(env) for t in ts],
                "mass": [t.mass_per_length for t in ts],
                "d": [t.diameter for t in ts],
                "Cdn": [t.Cd_normal for t in ts],
                "Cdt": [t.Cd_tangential for t in ts],
                "Can": [t.Ca_normal for t in ts],
                "Cat": [t.Ca_tangential for t in ts],
                "CB": [t.seabed_friction for t in ts],
                "damping_ratio": [t.axial_damping_ratio for t in ts],
                "MBS": [t.MBS for t in ts],
                "segments": list(ln.section_segments()),
                "W": [p.net_weight(env) if p else 0.0 for p in pts],
                "point_mass": [p.mass if p else 0.0 for p in pts],
                "point_volume": [p.volume if p else 0.0 for p in pts],
                "point_CdA": [p.CdA if p else 0.0 for p in pts],
                "point_Ca": [p.Ca if p else 0.0 for p in pts],
            }
            arrays = {k: readonly(np.asarray(v, dtype=int if k == "segments" else float)) for k, v in d.items()}
            arrays["EA_table"] = tuple(t.strain_table for t in ts)
            if np.any(arrays["w"] <= 0):   # a buoyant section: the sea surface bounds it (the water depth)
                arrays["surface"] = float(env.water_depth)
            out.append(arrays)
        return tuple(out)
