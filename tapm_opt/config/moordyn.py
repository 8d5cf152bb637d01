"""MoorDyn v2 input files: read them into scenarios, write scenarios as MoorDyn models.

Conventions (all of them, with the evidence, in ``docs/moordyn.md``):

* **Frames.** MoorDyn is z up; tapm_opt is NED (x north, y east, z down; body y to starboard).
  ``(x, y, z)_MoorDyn = (x, -y, -z)_NED``: x (north, surge) is kept, MoorDyn's y points west
  (to port at heading 0) and z up. A heading psi (NED, clockwise seen from above) is a MoorDyn yaw
  of ``-psi``.
* **Diameter.** MoorDyn has one diameter, the volume-equivalent one: buoyancy, drag and added
  mass all use it. tapm_opt has a hydrodynamic diameter ``d`` (drag, added mass) and a separately
  given submerged weight ``w``. Writing, MoorDyn's diameter is the one that reproduces ``w``:
  ``w = (m - rho_w pi d_md^2 / 4) g``; the coefficients are rescaled so the forces per length stay
  the same: ``Cd = C_DN d / d_md``, ``Ca = C_MN (d / d_md)^2``, ``CaAx = C_MT (d / d_md)^2`` and
  ``CdAx = C_DT d / (pi d_md)`` (MoorDyn's axial drag acts on ``pi d``, tapm_opt's on ``d``).
  Reading, the inverse with ``d = d_md``: ``C_DT = pi CdAx``, ``w = (m - rho_w pi d_md^2/4) g``.
* **Axial damping.** MoorDyn's negative ``BA = -zeta_md`` is the damping ratio of the zig-zag
  (highest) axial mode, ``BA = zeta_md (L/N) sqrt(EA m)`` [N s]; tapm_opt's
  ``axial_damping_ratio`` zeta is a fraction of the critical damping of one segment with half the
  segment mass, ``c_int = zeta 2 sqrt((EA/l) m l / 2) l = zeta sqrt(2) l sqrt(EA m)``. So
  ``BA = -sqrt(2) zeta``; a positive BA [N s] maps to ``zeta = BA / (sqrt(2) l sqrt(EA m))``.
* **Seabed.** MoorDyn's ``kBot``, ``cBot`` act on ``d_md`` per length; the FEM's node spring is
  the node weight over a 0.01 m penetration with 50 % of critical damping, so
  ``kBot = w / (0.01 d_md)`` and ``cBot = sqrt(w m / 0.01) / d_md``.
* **Representation.** A written file has one ``Coupled`` body at the centre of turret (COT) with
  the turret's orientation, each fairlead a ``Body1`` point on it, each anchor a ``Fixed`` point;
  line k of the file is line k of the scenario (anchor end A, fairlead end B), or its fairlead
  section for a composite line, whose lower sections follow the n fairlead sections, joined by
  ``Free`` points carrying the point types. The front matter keeps what MoorDyn has no column for
  (:class:`FrontMatter`), so a written file reads back as the same scenario.
* **Composite lines.** Reading, lines in series through free points that each join two lines, from
  a fixed point to the vessel, are one composite line (:class:`MDChain`); a free point with a mass,
  volume, drag or added mass is a point type at its joint.
* **Fixed points as fairleads.** With ``fixed_as_fairleads``, in a file without a vessel point or
  body, a line (or lines in series) between two fixed points runs from the lower one (the anchor)
  to the upper one, a fairlead on the vessel; ends at one depth, or a point that would be both,
  are refused.
* **Viscoelastic EA.** ``EA_s|EA_d`` (or ``EA_s|EA_Dc|EA_D_Lm``) is read as ``EA_s``, MoorDyn's
  tension at rest exactly (its static and dynamic springs in series); the dynamic stiffness is
  neglected, and the FEM's damper is the dynamic damper ``BA_d``, at most critical. A VIV ``Cl``
  is neglected (no lift at rest). Each with a note.

Every problem is a :class:`MoorDynError` (a :class:`~tapm_opt.errors.TapmError`) naming the file,
its line number and the item: the ``tapm`` command prints it on one line.

Size: one module on purpose — reading and writing MoorDyn files share one table of conventions
(frames, line types, options) so the round trip stays exact (``docs/moordyn.md``).
"""

from __future__ import annotations

import difflib
import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Iterable, Mapping

import numpy as np

from .._io import toml_key, toml_value
from ..errors import TapmError
from ..geometry import fairleads_B
from ..strain_table import table_problem
from .loader import BUILTIN_DIR, fairlead_reach, hangoff_depth_limit, load_scenario
from .schema import Line, LineType, Scenario, Section

__all__ = [
    "MoorDynError",
    "MoorDynModel",
    "MDLineType",
    "MDPoint",
    "MDBody",
    "MDLine",
    "MDChain",
    "FrontMatter",
    "read_moordyn",
    "parse_moordyn",
    "scenario_data_from_moordyn",
    "moordyn_text",
    "export_moordyn",
    "moordyn_line_type",
    "moordyn_time_step",
    "seabed_constants",
    "scenario_toml",
    "ImportResult",
    "RISER_CHOICES",
    "RECENTRE_CHOICES",
    "vessel_data_of",
    "problem_in_file_terms",
    "TURRET_CHOICES",
    "ExportInfo",
    "SEABED_PENETRATION",
    "SEABED_DAMPING_RATIO",
    "MOORDYN_DEFAULT_G",
    "MOORDYN_DEFAULT_RHO",
]

#: Static penetration of a line resting on the seabed in the FEM (``FEMLines`` default) [m].
SEABED_PENETRATION = 0.01
#: Seabed contact damping ratio of the FEM (``FEMLines`` default).
SEABED_DAMPING_RATIO = 0.5
#: MoorDyn-C's gravity when the file sets none (``env->g`` in MoorDyn2.cpp; its docs print 9.81).
MOORDYN_DEFAULT_G = 9.80665
#: MoorDyn's water density when the file sets none.
MOORDYN_DEFAULT_RHO = 1025.0
#: Fraction of the largest stable step used as MoorDyn's dtM.
DTM_SAFETY = 0.8

_SQRT2 = math.sqrt(2.0)


class MoorDynError(TapmError, ValueError):
    """A MoorDyn file that cannot be read or converted, or a scenario MoorDyn cannot represent.

    ``source`` is the file (or ``""``), ``lineno`` the 1-based line of the file (or None).
    """

    def __init__(self, message: str, *, source: str = "", lineno: int | None = None):
        self.source, self.lineno, self.detail = source, lineno, message
        where = source
        if lineno is not None:
            where = f"{source}:{lineno}" if source else f"line {lineno}"
        super().__init__(f"{where}: {message}" if where else message)


# --------------------------------------------------------------------------------------------
# the parsed file
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MDLineType:
    """A row of LINE TYPES (SI units, MoorDyn's meaning of every column)."""

    name: str
    d: float
    mass: float
    EA: float
    BA: float
    EI: float
    Cd: float
    Ca: float
    CdAx: float
    CaAx: float
    lineno: int
    EA_table: tuple[tuple[float, float], ...] | None = None
    """The tension-strain curve (rows strain, tension) when the EA column names a curve file; EA
    is then its secant at the last row (MoorDyn-C's one EA of a curve)."""
    EA_file: str = ""
    """The curve file as the EA column names it."""
    EA_dynamic: str = ""
    """A viscoelastic EA's dynamic part as written after the first bar (``EA_d``, or
    ``EA_Dc|EA_D_Lm`` for a load-dependent one); EA is then the static stiffness, the tension at
    rest (MoorDyn's static and dynamic springs in series). Empty for an elastic line."""
    BA_dynamic: float | None = None
    """A viscoelastic line's dynamic damping ``BA_d`` [N s] (the value after the bar of BA, the
    damper across the dynamic spring); None when BA has no bar. BA is then the static damping."""
    Cl: float = 0.0
    """The cross-flow VIV lift coefficient (0: no VIV)."""

    @property
    def viscoelastic(self) -> bool:
        return bool(self.EA_dynamic)


#: Most rows of a curve MoorDyn-C reads (its ``nCoef``).
MAX_CURVE_ROWS = 30


@dataclass(frozen=True)
class MDBody:
    """A row of BODIES: attachment word, pose (x, y, z [m], roll, pitch, yaw [deg]), MoorDyn frame."""

    id: int
    attachment: str
    pose: tuple[float, float, float, float, float, float]
    lineno: int


@dataclass(frozen=True)
class MDPoint:
    """A row of POINTS. ``kind`` is 'fixed', 'coupled' (global coordinates), 'body'
    (coordinates relative to body ``body``) or 'free' (a connection between lines, which may carry
    a clump weight or a buoy: ``mass`` [kg], ``volume`` [m^3], ``CdA`` [m^2], ``Ca``); ``r`` in the
    MoorDyn frame [m]."""

    id: int
    attachment: str
    kind: str
    body: int | None
    r: tuple[float, float, float]
    lineno: int
    mass: float = 0.0
    volume: float = 0.0
    CdA: float = 0.0
    Ca: float = 0.0

    @property
    def carries(self) -> tuple[float, float, float, float]:
        """(mass, volume, CdA, Ca): all zero for a plain joint."""
        return (self.mass, self.volume, self.CdA, self.Ca)


@dataclass(frozen=True)
class MDLine:
    """A row of LINES: ``a`` and ``b`` are point ids (end A, end B)."""

    id: int
    type: str
    a: int
    b: int
    length: float
    segments: int
    lineno: int


@dataclass(frozen=True)
class MDChain:
    """Lines in series from a fixed point (the anchor) up to a vessel point (the fairlead; with
    ``fixed_as_fairleads``, the upper fixed point of a file without a vessel point),
    joined by free points that each join exactly two lines: one tapm_opt line, composite when it
    has more than one section. ``lines`` and ``flipped`` run from the anchor up (``flipped[k]``:
    line k's end B is its lower end in the chain); ``points`` are the point ids from the anchor
    up (anchor, joints..., fairlead)."""

    lines: tuple[MDLine, ...]
    flipped: tuple[bool, ...]
    points: tuple[int, ...]

    @property
    def anchor(self) -> int:
        return self.points[0]

    @property
    def fairlead(self) -> int:
        return self.points[-1]

    @property
    def joints(self) -> tuple[int, ...]:
        return self.points[1:-1]

    @property
    def top(self) -> MDLine:
        """The fairlead section's line."""
        return self.lines[-1]

    @property
    def name(self) -> str:
        """The file's line numbers from the anchor up, joined by '-' (a single line: its number)."""
        return "-".join(str(ln.id) for ln in self.lines)

    def said(self) -> str:
        """'line 3' or 'lines 1, 2, 3 (from the anchor up)' for messages."""
        if len(self.lines) == 1:
            return f"line {self.lines[0].id}"
        return f"lines {', '.join(str(ln.id) for ln in self.lines)} (from the anchor up)"


@dataclass(frozen=True)
class FrontMatter:
    """What a file written by :func:`moordyn_text` says of the scenario in its front matter (text
    before the first section), which MoorDyn ignores: per line type its tapm_opt values
    (``types[name] = (values, line number)``), per MoorDyn line number of a fairlead section the
    tapm_opt line's own fields (``lines``), per free point its point type id (``points``)."""

    types: dict[str, tuple[dict[str, float], int]] = field(default_factory=dict)
    lines: dict[int, tuple[dict[str, Any], int]] = field(default_factory=dict)
    points: dict[int, tuple[str, int]] = field(default_factory=dict)


@dataclass(frozen=True)
class MoorDynModel:
    """The mooring content of a MoorDyn v2 file (after the checks of :func:`parse_moordyn`).

    ``options`` maps lower-case option names to ``(value text, line number)``; ``notes`` lists
    what was read but has no counterpart in tapm_opt (ignored on import).
    """

    source: str
    line_types: tuple[MDLineType, ...]
    bodies: tuple[MDBody, ...]
    points: tuple[MDPoint, ...]
    lines: tuple[MDLine, ...]
    options: dict[str, tuple[str, int]]
    notes: tuple[str, ...] = ()
    #: The lines in series from each anchor to the vessel (:class:`MDChain`), in the order of their
    #: fairlead sections' line numbers: the tapm_opt lines.
    chains: tuple[MDChain, ...] = ()
    #: What a tapm_opt front matter (written by :func:`moordyn_text`) gives; empty otherwise.
    front: FrontMatter = field(default_factory=FrontMatter)
    #: The fixed points read as fairleads on the vessel (``fixed_as_fairleads``, a file without a
    #: vessel point); empty otherwise.
    fixed_fairleads: tuple[int, ...] = ()

    @property
    def max_strain(self) -> dict[str, tuple[float, int]]:
        """``max_strain`` (and its line number) of line types whose tapm_opt front-matter comment
        gives one; MoorDyn itself has no such property."""
        return {k: (v["max_strain"], i) for k, (v, i) in self.front.types.items() if "max_strain" in v}

    # -- derived -------------------------------------------------------------------------
    def option(self, *names: str) -> tuple[str, int] | None:
        """The value text and line of the last of ``names`` (lower case, one option's spellings)
        the file sets: MoorDyn-C (``MoorDyn::readOptionsLine``) and MoorPy read the options in
        order, a later row overwriting an earlier one of the same option."""
        got = [self.options[n] for n in names if n in self.options]
        return max(got, key=lambda v: v[1]) if got else None

    def number_option(self, *names: str, default: float | None = None) -> float | None:
        got = self.option(*names)
        if got is None:
            return default
        text, lineno = got
        try:
            val = float(text)
        except ValueError:
            raise MoorDynError(f"option {names[0]}: {text!r} is not a number", source=self.source,
                               lineno=lineno) from None
        if not math.isfinite(val):
            raise MoorDynError(f"option {names[0]} = {text} is not finite", source=self.source, lineno=lineno)
        return val

    @property
    def gravity(self) -> float:
        return float(self.number_option("g", "gravity", default=MOORDYN_DEFAULT_G))

    @property
    def water_density(self) -> float:
        """``rho`` or ``WtrDnsty`` (MoorDyn-C), else MoorDyn-F's ``rhoW``, else 1025 kg/m^3."""
        rho = self.number_option("rho", "wtrdnsty")
        return float(rho if rho is not None else self.number_option("rhow", default=MOORDYN_DEFAULT_RHO))

    @property
    def water_depth(self) -> float:
        """WtrDpth, raised to the deepest point as MoorDyn-C does when a point lies below it."""
        depth = self.number_option("wtrdpth", "depth", "waterdepth", default=0.0)
        deepest = max((-self.global_position(p)[2] for p in self.points), default=0.0)
        return float(max(depth or 0.0, deepest))

    def point(self, pid: int) -> MDPoint:
        return self.points[pid - 1]

    def body(self, bid: int) -> MDBody:
        return self.bodies[bid - 1]

    def global_position(self, p: MDPoint) -> np.ndarray:
        """Position of point ``p`` at the start (bodies at their BODIES pose), MoorDyn frame [m]."""
        r = np.array(p.r, dtype=float)
        if p.kind != "body":
            return r
        b = self.body(int(p.body))
        x, y, z, _, _, yaw = b.pose  # roll and pitch are 0 (checked)
        c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
        return np.array([x + c * r[0] - s * r[1], y + s * r[0] + c * r[1], z + r[2]])

    def line_type(self, name: str) -> MDLineType:
        for lt in self.line_types:
            if lt.name == name:
                return lt
        raise KeyError(name)


# --------------------------------------------------------------------------------------------
# reading
# --------------------------------------------------------------------------------------------

# (section key, phrases) in the order they are tested: the longer phrases first
_SECTIONS = (
    ("line_types", ("LINE TYPES", "LINE DICTIONARY")),
    ("rod_types", ("ROD TYPES", "ROD DICTIONARY")),
    ("bodies", ("BODIES", "BODY LIST", "BODY PROPERTIES")),
    ("rods", ("RODS", "ROD LIST", "ROD PROPERTIES")),
    ("points", ("POINTS", "POINT LIST", "POINT PROPERTIES", "CONNECTION PROPERTIES", "NODE PROPERTIES")),
    ("lines", ("LINES", "LINE LIST", "LINE PROPERTIES")),
    ("options", ("OPTIONS",)),
    ("outputs", ("OUTPUT",)),
    ("failure", ("FAILURE",)),
    ("control", ("CONTROL",)),
    ("external_loads", ("EXTERNAL LOADS",)),
    ("syrope", ("SYROPE",)),
)
_TABLES = {"line_types", "rod_types", "bodies", "rods", "points", "lines", "failure", "control",
           "external_loads"}
_UNSUPPORTED_SECTIONS = {
    "rods": "rods are not supported",
    "failure": "line failures are not supported (give faults in the vessel scenario)",
    "control": "line control channels are not supported",
    "external_loads": "external loads are not supported",
    "syrope": "the Syrope polyester model is not supported",
}

_FIXED = {"ANCHOR", "FIXED", "FIX"}
_COUPLED = {"FAIRLEAD", "VESSEL", "VES", "COUPLED", "CPLD"}
_FREE = {"POINT", "CONNECT", "CON", "FREE"}


def _section_of(header: str) -> str | None:
    up = header.upper()
    for key, phrases in _SECTIONS:
        if any(p in up for p in phrases):
            return key
    return None


def _tokens(raw: str) -> list[str]:
    """Whitespace-separated values of a row; ``#`` starts a comment (as in MoorDyn)."""
    return raw.split("#", 1)[0].split()


def _word_number(word: str) -> tuple[str, str]:
    m = re.fullmatch(r"([A-Za-z_]+)(\d*)(.*)", word)
    if not m:
        return word.upper(), ""
    return m.group(1).upper(), m.group(2) + m.group(3)


def _looks_like_data(tokens: list[str], n_min: int) -> bool:
    if len(tokens) < n_min:
        return False
    try:
        float(tokens[-1] if tokens[-1] != "-" else "0")
        int(tokens[0])
        return True
    except ValueError:
        return False


class _AlreadySaid(Exception):
    """A row refused because of another row whose problem is said already (a point on a refused body)."""


def _raise_all(problems: list[MoorDynError], source: str) -> None:
    """One error for all ``problems`` (a single one as it is), each with its file line, in the
    order of the file."""
    if len(problems) == 1:
        raise problems[0]
    if problems:
        problems = sorted(problems, key=lambda e: math.inf if e.lineno is None else e.lineno)
        listed = "; ".join((f"line {e.lineno}: " if e.lineno is not None else "") + e.detail for e in problems)
        raise MoorDynError(f"{len(problems)} problems: {listed}", source=source)


class _Reader:
    def __init__(self, text: str, source: str, base_dir: Path | None = None, fixed_as_fairleads: bool = False):
        self.source = source
        self.fixed_as_fairleads = fixed_as_fairleads
        # a row of BODIES or a coupled or body point, refused or not: the file has a vessel
        self.has_vessel = False
        #: the fixed points taken as fairleads (fixed_as_fairleads)
        self.fixed_fairleads: list[int] = []
        self.base_dir = Path(".") if base_dir is None else Path(base_dir)
        self.rows = text.splitlines()
        self.notes: list[str] = []
        # what the file has that cannot be imported, all of it: said at once at the end
        self.problems: list[MoorDynError] = []
        self.refused_types: set[str] = set()
        self.refused_points: set[int] = set()
        self.refused_bodies: set[int] = set()
        self.ends: list[tuple[int, int | None, int | None, int]] = []

    def raise_problems(self) -> None:
        """One error for every refused row and section (the single one as it is)."""
        _raise_all(self.problems, self.source)

    def err(self, msg: str, lineno: int | None = None) -> MoorDynError:
        return MoorDynError(msg, source=self.source, lineno=lineno)

    def num(self, text: str, what: str, lineno: int) -> float:
        try:
            v = float(text)
        except ValueError:
            raise self.err(f"{what} = {text!r} is not a number", lineno) from None
        if not math.isfinite(v):
            raise self.err(f"{what} = {text} is not finite", lineno)
        return v

    def sections(self) -> dict[str, list[tuple[int, list[str]]]]:
        """Data rows (line number, tokens) of each section, header and column lines skipped."""
        out: dict[str, list[tuple[int, list[str]]]] = {}
        key: str | None = None
        skip = 0
        started = False
        ended = False
        for i, raw in enumerate(self.rows, start=1):
            if "---" in raw:
                k = _section_of(raw)
                if k is None:
                    if started:
                        ended = True  # e.g. "--- need this line ---": nothing after it is read
                    key = None
                    continue
                if k in out:
                    raise self.err(f"section {k.replace('_', ' ').upper()} appears twice", i)
                started, ended = True, False
                key = k
                out[key] = []
                skip = 2 if k in _TABLES else 0
                continue
            if key is None or ended:
                continue
            if skip:
                skip -= 1
                toks = _tokens(raw)
                need = {"lines": 7, "points": 9, "bodies": 14}.get(key)
                if need and _looks_like_data(toks, need):
                    raise self.err(
                        f"this row of {key.upper()} looks like data but is read as a column-title line: "
                        "MoorDyn skips the two lines after a section header (column names and units)", i)
                continue
            toks = _tokens(raw)
            if not toks:
                continue
            if key == "outputs" and toks[0].upper() == "END":
                key = None
                continue
            out[key].append((i, toks))
        if not started:
            raise self.err("no MoorDyn section header found (lines such as '---- LINE TYPES ----')")
        return out

    # -- sections -------------------------------------------------------------------------
    def line_types(self, rows) -> list[MDLineType]:
        out = []
        for i, t in rows:
            name = t[0]
            try:
                out.append(self._line_type(name, t, i, out))
            except MoorDynError as exc:
                self.problems.append(exc)
                self.refused_types.add(name)
        if not out and not self.problems:
            raise self.err("the file defines no line type (section LINE TYPES)")
        return out

    def _line_type(self, name: str, t: list[str], i: int, out: list[MDLineType]) -> MDLineType:
        if len(t) == 9:
            raise self.err(f"line type {name!r} has 9 columns: the MoorDyn v1 layout (Diam MassDen EA BA Can Cat "
                           "Cdn Cdt) is not supported; write the v2 layout (Diam Mass/m EA BA/-zeta EI Cd Ca CdAx "
                           "CaAx)", i)
        if len(t) not in (10, 11, 13):
            raise self.err(f"line type {name!r} has {len(t)} columns; MoorDyn v2 takes 10 (TypeName Diam Mass/m "
                           "EA BA/-zeta EI Cd Ca CdAx CaAx), 11 (+ Cl) or 13 (+ Cl dF cF)", i)
        ea = t[3]
        if ea.upper().startswith("SYROPE"):
            raise self.err(f"line type {name!r}: the Syrope model (EA = {ea}) is not supported", i)
        parts = ea.split("|")
        if len(parts) > 3:
            raise self.err(f"line type {name!r}: EA = {ea} has {len(parts)} bar-separated values; MoorDyn takes EA, "
                           "EA_s|EA_d (viscoelastic) or EA_s|EA_Dc|EA_D_Lm (viscoelastic, the dynamic stiffness "
                           "growing with the mean load)", i)
        dynamic = "|".join(parts[1:])
        if dynamic:
            try:
                float(parts[0])
            except ValueError:
                raise self.err(f"line type {name!r}: viscoelastic EA = {ea}: its static stiffness {parts[0]!r} is not a "
                               "number; a tension-strain curve as the static part is not supported (MoorDyn's "
                               "viscoelastic model takes the curve's secant as a constant)", i) from None
            ea = parts[0]
        curve, curve_file = None, ""
        try:
            EA = float(ea)
        except ValueError:
            curve_file = ea
            curve = self._curve(name, ea, i)
            EA = curve[-1][1] / curve[-1][0]
        ba = t[4].split("|")
        BA_d = None
        if len(ba) > 1:
            if not dynamic:
                raise self.err(f"line type {name!r}: static|dynamic damping BA = {t[4]} needs a viscoelastic EA "
                               f"(EA_s|EA_d); EA = {t[3]} has one value, and MoorDyn refuses more BA values than EA "
                               "values", i)
            if len(ba) > 2:
                raise self.err(f"line type {name!r}: BA = {t[4]} has {len(ba)} bar-separated values; MoorDyn takes "
                               "at most 2 (static|dynamic damping)", i)
            BA_d = self.num(ba[1], f"line type {name!r} BA (dynamic damping, after the bar)", i)
            if BA_d < 0:
                raise self.err(f"line type {name!r}: BA = {t[4]}: the dynamic damping {ba[1]} must be >= 0 N s "
                               "(MoorDyn takes no damping ratio for it)", i)
        try:
            BA = float(ba[0])
        except ValueError:
            raise self.err(f"line type {name!r}: BA = {t[4]!r} names a nonlinear damping curve, which is not "
                           "supported", i) from None
        try:
            EI = float(t[5])
        except ValueError:
            raise self.err(f"line type {name!r}: EI = {t[5]!r} names a bending stiffness curve; bending "
                           "stiffness is not supported", i) from None
        if EI < 0:
            raise self.err(f"line type {name!r}: EI = {t[5]} N m^2 must be >= 0", i)
        vals = [self.num(t[k], f"line type {name!r} {col}", i)
                for k, col in ((1, "Diam"), (2, "Mass/m"), (6, "Cd"), (7, "Ca"), (8, "CdAx"), (9, "CaAx"))]
        Cl = self.num(t[10], f"line type {name!r} Cl", i) if len(t) >= 11 else 0.0
        d, mass, Cd, Ca, CdAx, CaAx = vals
        for col, v in (("Diam", d), ("Mass/m", mass), ("EA", EA)):
            if not v > 0:
                raise self.err(f"line type {name!r}: {col} = {v:g} must be > 0", i)
        for col, v in (("Cd", Cd), ("Ca", Ca), ("CdAx", CdAx), ("CaAx", CaAx)):
            if v < 0:
                raise self.err(f"line type {name!r}: {col} = {v:g} must be >= 0", i)
        if dynamic:
            self._viscoelastic(name, t[3], EA, [self.num(x, f"line type {name!r} EA (dynamic part)", i)
                                                for x in parts[1:]], i)
        if any(lt.name == name for lt in out):
            raise self.err(f"line type {name!r} is defined twice", i)
        if Cl > 0:
            self.notes.append(
                f"line type {name!r}: Cl = {t[10]} (line {i}): MoorDyn's vortex-induced vibration, a cross-flow lift "
                "0.5 rho_w d Cl |v_n|^2 cos(phi) per unit length on the inner nodes (v_n the line's velocity normal to "
                "it, relative to the water), is neglected: it is zero with the line at rest and off in MoorDyn's "
                "initial condition, so the statics are unchanged; under current or motion the FEM's lines have no "
                "such lift")
        return MDLineType(name, d, mass, EA, BA, EI, Cd, Ca, CdAx, CaAx, i, EA_table=curve, EA_file=curve_file,
                          EA_dynamic=dynamic, BA_dynamic=BA_d, Cl=max(Cl, 0.0))

    def _viscoelastic(self, name: str, entry: str, EA: float, dyn: list[float], i: int) -> None:
        """Check a viscoelastic EA (``EA_s|EA_d`` or ``EA_s|EA_Dc|EA_D_Lm``) and say how it is read:
        its static stiffness EA_s is the line's EA, exact at rest; the dynamic one is neglected."""
        if len(dyn) == 1:
            if not dyn[0] > EA:
                raise self.err(f"line type {name!r}: viscoelastic EA = {entry}: the dynamic stiffness EA_d = {dyn[0]:g} N "
                               f"must be greater than the static EA_s = {EA:g} N (MoorDyn's static spring "
                               "EA_d EA_s / (EA_d - EA_s), in series with EA_d, is otherwise negative or infinite, and "
                               "the line has no rest state)", i)
            said = f"the dynamic EA_d = {dyn[0]:g} N"
        else:
            Dc, Lm = dyn
            if not Dc > EA:
                raise self.err(f"line type {name!r}: viscoelastic EA = {entry}: the dynamic stiffness at zero mean load "
                               f"EA_Dc = {Dc:g} N must be greater than the static EA_s = {EA:g} N (MoorDyn refuses a "
                               "dynamic stiffness equal to the static one, and a smaller one has no rest state)", i)
            if Lm < 0:
                raise self.err(f"line type {name!r}: viscoelastic EA = {entry}: EA_D_Lm = {Lm:g}, the growth of the "
                               "dynamic stiffness with the mean load, must be >= 0", i)
            said = f"the dynamic EA_Dc + EA_D_Lm x mean load = {Dc:g} N + {Lm:g} x mean load"
        self.notes.append(
            f"line type {name!r}: viscoelastic EA = {entry} (line {i}): the static stiffness EA_s = {EA:g} N is the line's "
            f"EA, its tension at rest as MoorDyn's (a static spring EA_1 = EA_d EA_s / (EA_d - EA_s) in series with "
            f"the dynamic EA_d: EA_1 EA_d / (EA_1 + EA_d) = EA_s whatever EA_d, once the dampers carry nothing); {said} "
            "is neglected: under motion MoorDyn's line is stiffer, up to EA_d, so the FEM's dynamic tensions differ "
            "from MoorDyn's")

    def _curve(self, name: str, entry: str, i: int) -> tuple[tuple[float, float], ...]:
        """The tension-strain curve a line type's EA column names, read as MoorDyn-C reads it: a
        file next to the input file (or at an absolute path), three header lines, then rows
        ``strain tension``. Also read: MoorPy's quoted name (``"poly.txt"``), blank lines, and an
        end at a ``---`` line (MoorPy's). Refused, naming the file and its line: a file that cannot
        be read, a row that is not two numbers, a curve that is not a valid law
        (:func:`tapm_opt.strain_table.table_problem`)."""
        fname = entry
        if len(entry) >= 2 and entry[0] == entry[-1] and entry[0] in "\"'":
            fname = entry[1:-1]
            self.notes.append(f"line type {name!r}: EA = {entry} is MoorPy's quoted curve file name; MoorDyn-C reads "
                              f"the name as written, quotes and all (write it unquoted for MoorDyn-C)")
        path = Path(fname) if Path(fname).is_absolute() else self.base_dir / fname
        what = f"line type {name!r}: EA = {entry!r} names a tension-strain curve"
        try:
            text = path.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            raise self.err(f"{what}, but {path} cannot be read ({exc.strerror or exc}); MoorDyn reads it next to the "
                           "input file", i) from None
        rows: list[tuple[float, float]] = []
        for k, raw in enumerate(text.splitlines()[3:], start=4):
            if "---" in raw:
                break
            toks = raw.split("#", 1)[0].split()
            if not toks:
                continue
            try:
                x, y = float(toks[0]), float(toks[1])
            except (ValueError, IndexError):
                raise self.err(f"{what}: line {k} of {fname} ({raw.strip()!r}) is not a row of two numbers "
                               "'strain tension' (after three header lines)", i) from None
            rows.append((x, y))
        bad = table_problem(rows) if rows else (None, "has no rows (three header lines, then 'strain tension' rows)")
        if bad is not None:
            k, msg = bad
            raise self.err(f"{what} {fname}" + ("" if k is None else f", row {k}") + f" {msg}", i)
        if text.endswith(("\n", "\r")):
            self.notes.append(f"line type {name!r}: curve file {fname} ends with a line break, which MoorDyn-C 2.7 reads "
                              "as an empty row and refuses (the file the exporter writes has none)")
        if len(rows) > MAX_CURVE_ROWS:
            self.notes.append(f"line type {name!r}: curve file {fname} has {len(rows)} rows; MoorDyn-C reads at most "
                              f"{MAX_CURVE_ROWS}")
        self.notes.append(f"line type {name!r}: nonlinear EA, {len(rows)} rows of tension-strain curve {fname} from "
                          f"[0, 0] to [{rows[-1][0]:g}, {rows[-1][1]:g}] (EA_table; its secant {rows[-1][1] / rows[-1][0]:g} "
                          "N is the line type's EA); beyond the last row tapm_opt continues its slope, MoorDyn holds "
                          "its tension")
        return tuple(rows)

    def bodies(self, rows) -> list[MDBody]:
        out = []
        for k, (i, t) in enumerate(rows, start=1):
            if len(t) < 8:
                raise self.err(f"body row has {len(t)} columns; MoorDyn v2 takes ID Attachment X0 Y0 Z0 r0 p0 y0 Mass "
                               "CG I Volume CdA Ca", i)
            bid = int(self.num(t[0], "body ID", i))
            if bid != k:
                raise self.err(f"body ID {t[0]} is out of sequence (IDs run 1, 2, ...; expected {k})", i)
            self.has_vessel = True
            word, _ = _word_number(t[1])
            try:
                if word not in _COUPLED:
                    raise self.err(f"body {bid} is attached as {t[1]!r}: only one coupled body (the vessel, 'Coupled' "
                                   "or 'Vessel') is supported, not free, fixed or pinned bodies", i)
                if out:
                    raise self.err(f"body {bid}: only one coupled body (the vessel) is supported; body {out[0].id} "
                                   "already is", i)
                pose = tuple(self.num(t[j], f"body {bid} {c}", i) for j, c in
                             zip(range(2, 8), ("X0", "Y0", "Z0", "r0", "p0", "y0")))
                if abs(pose[3]) > 1e-12 or abs(pose[4]) > 1e-12:
                    raise self.err(f"body {bid}: roll r0 = {t[5]} deg and pitch p0 = {t[6]} deg must be 0 "
                                   "(tapm_opt moves the vessel in surge, sway and yaw)", i)
            except MoorDynError as exc:
                # said once, here: its points and lines are not named again
                self.problems.append(exc)
                self.refused_bodies.add(bid)
                continue
            if len(t) > 8 and any(_nonzero(x) for x in t[8:]):
                self.notes.append(f"body {bid}: its mass, inertia, volume and drag (line {i}) are vessel properties; "
                                  "the vessel scenario's are used")
            out.append(MDBody(bid, t[1], pose, i))  # type: ignore[arg-type]
        return out

    def points(self, rows, n_bodies: int) -> list[MDPoint]:
        out = []
        for k, (i, t) in enumerate(rows, start=1):
            if len(t) < 9:
                raise self.err(f"point row has {len(t)} columns; MoorDyn v2 takes ID Attachment X Y Z Mass Volume "
                               "CdA Ca", i)
            pid = int(self.num(t[0], "point ID", i))
            if pid != k:
                raise self.err(f"point ID {t[0]} is out of sequence (IDs run 1, 2, ...; expected {k})", i)
            word = _word_number(t[1])[0]
            self.has_vessel = self.has_vessel or word in _COUPLED or word == "BODY"
            try:
                out.append(self._point(pid, t, i, n_bodies))
            except MoorDynError as exc:
                self.problems.append(exc)
                self.refused_points.add(pid)
            except _AlreadySaid:
                self.refused_points.add(pid)
        return out

    def _point(self, pid: int, t: list[str], i: int, n_bodies: int) -> MDPoint:
        r = tuple(self.num(t[j], f"point {pid} {c}", i) for j, c in zip((2, 3, 4), "XYZ"))
        M = self.num(t[5], f"point {pid} Mass", i)
        V = self.num(t[6], f"point {pid} Volume", i)
        if len(t) >= 12:
            F = [self.num(t[j], f"point {pid} {c}", i) for j, c in zip((7, 8, 9), ("FX", "FY", "FZ"))]
            CdA, Ca = self.num(t[10], f"point {pid} CdA", i), self.num(t[11], f"point {pid} Ca", i)
        else:
            F = [0.0, 0.0, 0.0]
            CdA, Ca = self.num(t[7], f"point {pid} CdA", i), self.num(t[8], f"point {pid} Ca", i)
        word, num = _word_number(t[1])
        body = None
        if word in _FIXED:
            kind = "fixed"
        elif word in _COUPLED:
            kind = "coupled"
        elif word == "BODY":
            kind = "body"
            if num.isdigit() and int(num) in self.refused_bodies:
                raise _AlreadySaid
            if not num.isdigit() or not 1 <= int(num) <= n_bodies:
                raise self.err(f"point {pid} is attached to {t[1]!r}, but the file defines "
                               f"{n_bodies} coupled bod{'y' if n_bodies == 1 else 'ies'}", i)
            body = int(num)
        elif word in _FREE:
            kind = "free"
            for what, v in (("Mass", M), ("Volume", V), ("CdA", CdA), ("Ca", Ca)):
                if v < 0:
                    raise self.err(f"point {pid}: {what} = {v:g} must be >= 0", i)
            if any(F):
                raise self.err(f"point {pid}: a steady external force on a free point is not supported", i)
            return MDPoint(pid, t[1], kind, None, r, i, M, V, CdA, Ca)  # type: ignore[arg-type]
        else:
            raise self.err(f"point {pid}: attachment {t[1]!r} is not supported (use Fixed for anchors, Coupled or "
                           "Body1 for fairleads, Free for the joints of lines in series)", i)
        if kind != "fixed":
            for what, v in (("Mass", M), ("Volume", V), ("CdA", CdA), ("Ca", Ca)):
                if v != 0:
                    raise self.err(f"point {pid}: {what} = {v:g}: a fairlead point with its own mass, volume, drag "
                                   "or added mass (clump weight or buoy) is not supported", i)
            if any(F):
                raise self.err(f"point {pid}: a steady external force on a fairlead point is not supported", i)
        return MDPoint(pid, t[1], kind, body, r, i)  # type: ignore[arg-type]

    def lines(self, rows, types: list[MDLineType], points: list[MDPoint]) -> list[MDLine]:
        """The lines read; ``self.ends`` gets every line row's (id, end A, end B, file line), an end
        None where it is a rod's, for :meth:`chains`."""
        out = []
        names = {lt.name for lt in types} | self.refused_types
        n_points = len(points) + len(self.refused_points)
        self.ends = []
        for k, (i, t) in enumerate(rows, start=1):
            if len(t) < 6:
                raise self.err(f"line row has {len(t)} columns; MoorDyn v2 takes ID LineType AttachA AttachB UnstrLen "
                               "NumSegs LineOutputs", i)
            lid = int(self.num(t[0], "line ID", i))
            if lid != k:
                raise self.err(f"line ID {t[0]} is out of sequence (IDs run 1, 2, ...; expected {k})", i)
            if t[1] not in names:
                raise self.err(f"line {lid}: line type {t[1]!r} is not defined in LINE TYPES ({', '.join(sorted(names))})",
                               i)
            ends: list[int | None] = []
            said = False
            for col, word in (("AttachA", t[2]), ("AttachB", t[3])):
                if not word.isdigit():
                    if not said:
                        self.problems.append(self.err(f"line {lid}: {col} = {word!r}: lines attached to rod ends are "
                                                      "not supported", i))
                    said = True
                    ends.append(None)
                    continue
                pid = int(word)
                if not 1 <= pid <= n_points:
                    if not said:
                        self.problems.append(self.err(f"line {lid}: {col} = {pid} is not a point (the file has "
                                                      f"{n_points})", i))
                    said = True
                    ends.append(None)
                    continue
                ends.append(pid)
            self.ends.append((lid, ends[0], ends[1], i))
            if said or t[1] in self.refused_types or set(ends) & self.refused_points:
                continue   # its type, an end or a point of it is refused already: said once, there
            L = self.num(t[4], f"line {lid} UnstrLen", i)
            if not L > 0:
                raise self.err(f"line {lid}: UnstrLen = {t[4]} must be > 0", i)
            try:
                n = int(t[5])
            except ValueError:
                raise self.err(f"line {lid}: NumSegs = {t[5]!r} is not a whole number", i) from None
            if n < 1:
                raise self.err(f"line {lid}: NumSegs = {n} must be >= 1", i)
            out.append(MDLine(lid, t[1], int(ends[0]), int(ends[1]), L, n, i))  # type: ignore[arg-type]
        if not out and not self.problems:
            raise self.err("the file defines no line (section LINES)")
        return out

    def chains(self, points: list[MDPoint], lines: list[MDLine]) -> list[MDChain]:
        """The lines in series from each fixed point to a vessel point (:class:`MDChain`).

        A free point must join exactly two lines. A free point at one line's end only (a free end),
        one joining three or more (a bridle, a Y-connection, lines sharing an anchor through it),
        lines in series between two fixed or two vessel points and loops of free points are
        problems, each said once, at the point or the lines that make it; lines ending at a refused
        point, body or rod are said there already.
        """
        by_id = {p.id: p for p in points}
        good = {ln.id: ln for ln in lines}
        at: dict[int, list[int]] = {}   # point id -> rows of self.ends that end there
        loops = set()
        for k, (lid, a, b, i) in enumerate(self.ends):
            if a is not None and a == b:
                self.problems.append(self.err(f"line {lid} starts and ends at point {a}", i))
                loops.add(k)
                continue
            for e in (a, b):
                if e is not None:
                    at.setdefault(e, []).append(k)
        bad_free: set[int] = set()
        for p in points:
            if p.kind != "free":
                continue
            uses = sorted({self.ends[k][0] for k in at.get(p.id, [])})
            n = len(at.get(p.id, []))
            if n == 0:
                self.notes.append(f"point {p.id} (line {p.lineno}) is a free point that no line uses: ignored")
            elif n == 1:
                self.problems.append(self.err(
                    f"point {p.id} is a free point ({p.attachment!r}) at the end of line {uses[0]} alone: a free end "
                    "(a hanging line, or a weight or buoy on a line's end) is not supported; every line runs from a "
                    "fixed anchor to the vessel, through free points that each join two lines", p.lineno))
            elif n > 2:
                self.problems.append(self.err(
                    f"point {p.id} is a free point ({p.attachment!r}) joining {n} lines ({', '.join(map(str, uses))}): "
                    "a bridle or Y-connection is not supported; tapm_opt's composite lines are sections in series, "
                    "each free point joining two lines", p.lineno))
            if n != 2:
                bad_free.add(p.id)

        def kind(pid: int | None) -> str:
            if pid is None:
                return "rod"
            p = by_id.get(pid)
            return "refused" if p is None else p.kind

        def terminal(pid: int | None) -> bool:
            return kind(pid) != "free" or pid in bad_free

        out = []
        visited = set(loops)
        vessel = ("coupled", "body")
        hinted = False
        for k0, (_, a0, b0, _) in enumerate(self.ends):
            if k0 in visited or not (terminal(a0) or terminal(b0)):
                continue
            cur = a0 if terminal(a0) else b0
            k, rows, flips, pts = k0, [], [], [cur]
            while True:
                visited.add(k)
                _, ea, eb, _ = self.ends[k]
                flipped = cur != ea
                cur = ea if flipped else eb
                rows.append(k)
                flips.append(flipped)
                pts.append(cur)
                if terminal(cur):
                    break
                k = next(j for j in at[cur] if j != k)   # the free point's other line
            ka, kb = kind(pts[0]), kind(pts[-1])
            if {ka, kb} & {"rod", "refused"} or pts[0] in bad_free or pts[-1] in bad_free:
                continue   # said at the rod, the refused point or the free point
            ids = [self.ends[j][0] for j in rows]
            first = self.ends[rows[0]][3]
            said = f"line {ids[0]} runs" if len(rows) == 1 else f"lines {', '.join(map(str, ids))} run in series"
            through = "" if len(rows) == 1 else (f" through free point{'s' * (len(pts) > 3)} "
                                                 f"{', '.join(map(str, pts[1:-1]))}")
            if ka in vessel and kb == "fixed":
                rows, flips, pts = rows[::-1], [not f for f in flips[::-1]], pts[::-1]
            elif ka == kb == "fixed" and self.fixed_as_fairleads and not self.has_vessel:
                za, zb = by_id[pts[0]].r[2], by_id[pts[-1]].r[2]
                if abs(za - zb) <= 1e-6:
                    self.problems.append(self.err(
                        f"{said} between two fixed points ({pts[0]} and {pts[-1]}){through} at the same depth (z = "
                        f"{za:g} m): neither end is the upper one, which --fixed-as-fairleads takes as the fairlead", first))
                    continue
                if za > zb:   # end A is the upper one: the fairlead last
                    rows, flips, pts = rows[::-1], [not f for f in flips[::-1]], pts[::-1]
            elif not (ka == "fixed" and kb in vessel):
                if ka == "fixed":
                    why = "every line must run from a fixed anchor to the vessel"
                    level = abs(by_id[pts[0]].r[2] - by_id[pts[-1]].r[2]) <= 1e-6
                    if self.fixed_as_fairleads and self.has_vessel:
                        why += (" (--fixed-as-fairleads applies to files without a vessel point or body: this file "
                                "has one, so its fixed points stay fixed)")
                    elif not self.has_vessel and not level and not hinted:
                        hinted = True   # said once
                        why += (" (the file has no vessel point: --fixed-as-fairleads takes the upper fixed point of "
                                "each line, or lines in series, between two fixed points as a fairlead on the vessel)")
                    elif not self.has_vessel and level:
                        why += f" (both at z = {by_id[pts[0]].r[2]:g} m: neither could be taken as the fairlead)"
                else:
                    why = ("a line with both ends on the vessel moves with it, its end forces cancel: it is no mooring "
                           "line; every line must run from a fixed anchor to the vessel")
                what = "fixed" if ka == "fixed" else "vessel"   # both ends fixed, or both on the vessel
                self.problems.append(self.err(
                    f"{said} between two {what} points ({pts[0]} and {pts[-1]}){through}; {why}", first))
                continue
            mdl = [good.get(self.ends[j][0]) for j in rows]
            if any(ln is None for ln in mdl):
                continue   # a line of a refused type: said at the type
            if len(mdl) == 1 and mdl[0].segments < 2:   # type: ignore[union-attr]
                self.problems.append(self.err(f"line {ids[0]}: NumSegs = {mdl[0].segments}: tapm_opt needs at least "  # type: ignore[union-attr]
                                              "2 segments on a line of one section", first))
                continue
            out.append(MDChain(tuple(mdl), tuple(flips), tuple(int(p) for p in pts)))  # type: ignore[arg-type]
        if self.fixed_as_fairleads and not self.has_vessel:
            out = self._fixed_fairleads(out, points)
        left = [k for k in range(len(self.ends)) if k not in visited]
        if left:
            self.problems.append(self.err(
                f"line{'s' * (len(left) > 1)} {', '.join(str(self.ends[k][0]) for k in left)} join only free points to "
                "each other (a loop with no anchor and no vessel point)", self.ends[left[0]][3]))
        out.sort(key=lambda ch: ch.top.id)
        if not out and not self.problems:
            raise self.err("no line runs from a fixed point (an anchor) to the vessel")
        return out

    def _fixed_fairleads(self, chains: list[MDChain], points: list[MDPoint]) -> list[MDChain]:
        """With ``fixed_as_fairleads`` in a file without a vessel point: the chains between two fixed
        points, each read from its lower end (the anchor) to its upper end (the fairlead, on the
        vessel). A fixed point that is the upper end of one and the lower end of another is a
        problem (it would be both fairlead and anchor), said once per point; the others are said in
        a note."""
        tops = {ch.fairlead for ch in chains}
        both = sorted(tops & {ch.anchor for ch in chains})
        by_id = {p.id: p for p in points}
        for pid in both:
            up = [ch.said() for ch in chains if ch.fairlead == pid]
            down = [ch.said() for ch in chains if ch.anchor == pid]
            self.problems.append(self.err(
                f"point {pid} (fixed) is the upper end of {', '.join(up)} and the lower end of {', '.join(down)}: "
                "--fixed-as-fairleads would make it both a fairlead on the vessel and an anchor", by_id[pid].lineno))
        chains = [ch for ch in chains if ch.fairlead not in both and ch.anchor not in both]
        if chains:
            self.fixed_fairleads = sorted({ch.fairlead for ch in chains})
            rows = "; ".join(
                f"point {ch.fairlead} (z = {by_id[ch.fairlead].r[2]:g} m) over point {ch.anchor} (z = "
                f"{by_id[ch.anchor].r[2]:g} m), {ch.said()}" for ch in sorted(chains, key=lambda c: c.top.id))
            self.notes.append(
                "the file has no vessel point (no coupled point or body); --fixed-as-fairleads: the upper fixed point "
                "of each line (or lines in series) between two fixed points is taken as a fairlead on the vessel, held "
                f"where the file has it at rest, the lower one as its anchor: {rows}")
        return chains


def _nonzero(text: str) -> bool:
    for part in text.split("|"):
        try:
            if float(part) != 0.0:
                return True
        except ValueError:
            return True
    return False


#: OPTIONS names MoorDyn-C and MoorDyn-F read (lower case; MoorDyn docs/inputs.rst, "Options"),
#: with the spelling used in messages. The numeric ones must hold a number; WtrDpth may also be a
#: bathymetry file (refused below), tScheme, SeafloorFile and WaterKin are text.
_OPTION_CASE = {n.lower(): n for n in (
    "writeLog", "dtM", "CFL", "tScheme", "g", "gravity", "rho", "WtrDnsty", "rhoW", "WtrDpth", "depth", "WaterDepth",
    "kBot", "kb", "cBot", "cb", "dtIC", "TmaxIC", "CdScaleIC", "threshIC", "WaveKin", "dtWave", "waveKin_rampT",
    "Currents", "UnifyCurrentGrid", "WriteUnits", "FrictionCoefficient", "FricDamp", "StatDynFricScale", "dtOut",
    "SeafloorFile", "ICgenDynamic", "disableOutput", "disableOutTime", "WaterKin", "MU_KT", "MU_KA", "MC", "CV",
    "inertialF", "inertialF_rampT", "OutSwitch", "Echo",
    # the older names MoorDyn-C 2.7 still reads (MoorDyn::readOptionsLine; MoorDyn's v1 docs use them)
    "dt", "ICdt", "ICTmax", "ICDfac", "ICthresh", "genDynamicIC", "fileIC", "ICfile")}
_KNOWN_OPTIONS = frozenset(_OPTION_CASE)
_NUMERIC_OPTIONS = _KNOWN_OPTIONS - {"tscheme", "seafloorfile", "waterkin", "wtrdpth", "depth", "waterdepth",
                                     "echo", "fileic", "icfile"}
#: Spellings of one option (MoorDyn-C's, MoorPy's depth), each to its first: a later row of any of
#: them overwrites an earlier one.
_OPTION_SAME = {n: group[0] for group in (
    ("g", "gravity"), ("rho", "wtrdnsty"), ("wtrdpth", "depth", "waterdepth"), ("kbot", "kb"), ("cbot", "cb"),
    ("dtm", "dt"), ("dtic", "icdt"), ("tmaxic", "ictmax"), ("cdscaleic", "icdfac"), ("threshic", "icthresh"),
    ("icgendynamic", "gendynamicic"), ("fileic", "icfile")) for n in group}
_NUM = r"([-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?)"
#: A line type's tapm_opt values in the front matter written by :func:`moordyn_text`:
#: ``Line type NAME: tapm_opt d = .. m, w = .. N/m, C_DN .., C_DT .. (on d), C_MN .., C_MT ..,
#: axial_damping_ratio .., MBS .. N, MBS_std .. N[, density .. kg/m^3][, max_strain ..].``
_FRONT_MATTER_TYPE = re.compile(r"^Line type (\S+): tapm_opt (.*)$")
_FRONT_TYPE_KEYS = {
    "d": rf"\bd = {_NUM} m\b", "w": rf"\bw = {_NUM} N/m", "Cd_normal": rf"\bC_DN {_NUM}",
    "Cd_tangential": rf"\bC_DT {_NUM}", "Ca_normal": rf"\bC_MN {_NUM}", "Ca_tangential": rf"\bC_MT {_NUM}",
    "axial_damping_ratio": rf"\baxial_damping_ratio {_NUM}", "MBS": rf"\bMBS {_NUM} N",
    "MBS_std": rf"\bMBS_std {_NUM} N", "density": rf"\bdensity {_NUM} kg/m\^3", "max_strain": rf"\bmax_strain {_NUM}",
}
#: A tapm_opt line in the front matter: ``Line K: tapm_opt line {json}`` (K the MoorDyn line of its
#: fairlead section), and a free point's point type: ``Point P: tapm_opt point type "ID"``.
_FRONT_MATTER_LINE = re.compile(r"^Line (\d+): tapm_opt line (\{.*\})\s*$")
_FRONT_MATTER_POINT = re.compile(r"^Point (\d+): tapm_opt point type (\"(?:[^\"\\]|\\.)*\")")


def _front_matter(text: str) -> FrontMatter:
    """What a front matter written by :func:`moordyn_text` gives (:class:`FrontMatter`); rows
    that do not read are left out (the importer then uses the MoorDyn tables alone)."""
    fm = FrontMatter()
    for i, raw in enumerate(text.splitlines(), start=1):
        if "---" in raw and _section_of(raw) is not None:
            break  # the front matter ends at the first section
        row = raw.strip()
        m = _FRONT_MATTER_TYPE.match(row)
        if m:
            vals = {}
            for key, pat in _FRONT_TYPE_KEYS.items():
                got = re.search(pat, m.group(2))
                if got:
                    vals[key] = float(got.group(1))
            if vals:
                fm.types[m.group(1)] = (vals, i)
            continue
        m = _FRONT_MATTER_LINE.match(row)
        if m:
            try:
                item = json.loads(m.group(2))
            except ValueError:
                continue
            if isinstance(item, dict) and isinstance(item.get("id"), str):
                fm.lines[int(m.group(1))] = (item, i)
            continue
        m = _FRONT_MATTER_POINT.match(row)
        if m:
            try:
                fm.points[int(m.group(1))] = (str(json.loads(m.group(2))), i)
            except ValueError:
                continue
    return fm


def parse_moordyn(text: str, *, source: str = "", base_dir: str | Path | None = None,
                  fixed_as_fairleads: bool = False) -> MoorDynModel:
    """Parse MoorDyn v2 input text; unsupported features raise :class:`MoorDynError`, every one of
    them in the file at once (a row whose line type or point is refused is not named again).

    Supported: line types (linear EA or a tension-strain curve file, read from ``base_dir``,
    default the directory of ``source``; a viscoelastic EA read as its static stiffness; constant
    BA, or static|dynamic BA of a viscoelastic line; EI, checked on import; VIV ``Cl``, neglected
    with a note), at most one coupled body (the vessel, roll = pitch = 0), Fixed points (anchors),
    Coupled and Body1 points (fairleads), Free points joining two lines in series
    (:class:`MDChain`), lines from an anchor to a fairlead directly or through free points, and
    OPTIONS. Rods, free ends, bridles, other bodies, failures, the Syrope model and nonlinear
    damping or bending are refused, naming the item and the line of the file.

    ``fixed_as_fairleads``: in a file with no vessel point (no coupled point, no body), lines (or
    lines in series) between two fixed points run from the lower one (the anchor) to the upper one,
    taken as a fairlead on the vessel (:attr:`MoorDynModel.fixed_fairleads`, with a note); ends at
    the same depth, and a fixed point that would be both a fairlead and an anchor, are refused.
    """
    rd = _Reader(text, source, Path(base_dir) if base_dir is not None else Path(source).parent if source else None,
                 fixed_as_fairleads=fixed_as_fairleads)
    sec = rd.sections()
    for key, why in _UNSUPPORTED_SECTIONS.items():
        if sec.get(key):
            i, t = sec[key][0]
            item = f"rod {t[0]}" if key == "rods" else f"section {key.replace('_', ' ').upper()}"
            more = f" ({len(sec[key])} rows)" if key == "rods" and len(sec[key]) > 1 else ""
            rd.problems.append(rd.err(f"{item}{more}: {why}", i))
    types = rd.line_types(sec.get("line_types", []))
    bodies = rd.bodies(sec.get("bodies", []))
    points = rd.points(sec.get("points", []), len(bodies) + len(rd.refused_bodies))
    lines = rd.lines(sec.get("lines", []), types, points)
    chains = rd.chains(points, lines)
    rd.raise_problems()
    options: dict[str, tuple[str, int]] = {}
    spelled: dict[str, str] = {}
    rows_of: dict[str, list[tuple[str, str, int]]] = {}   # an option's rows (spelling, value, line), any spelling
    for i, t in sec.get("options", []):
        if len(t) >= 2:
            name = t[1].lower()
            options[name] = (t[0], i)   # a later row overwrites an earlier one, as in MoorDyn-C and MoorPy
            spelled[name] = t[1]
            rows_of.setdefault(_OPTION_SAME.get(name, name), []).append((t[1], t[0], i))
        else:
            rd.notes.append(f"OPTIONS row {t[0]!r} (line {i}) has a value but no option name: ignored")
    for rows in rows_of.values():
        if len({v for _, v, _ in rows}) > 1:
            last = rows[-1]
            rd.notes.append(f"option {last[0]} = {last[1]} (line {last[2]}) is used: the file sets the same option "
                            "before (" + ", ".join(f"{n} = {v}, line {i}" for n, v, i in rows[:-1]) + "), and MoorDyn-C "
                            "and MoorPy read the options in order, the last row counting")
    for name, (val, i) in options.items():
        if name not in _KNOWN_OPTIONS:
            hint = difflib.get_close_matches(name, sorted(_KNOWN_OPTIONS), n=1)
            rd.notes.append(f"option {spelled[name]} = {val} (line {i}) is not a MoorDyn option" +
                            (f" (did you mean {_OPTION_CASE.get(hint[0], hint[0])}?)" if hint else "") + ": ignored")
        elif name in _NUMERIC_OPTIONS:
            try:
                ok = math.isfinite(float(val))
            except ValueError:
                ok = False
            if not ok:
                raise rd.err(f"option {_OPTION_CASE.get(name, name)} = {val!r} must be a finite number", i)
    if "seafloorfile" in options:
        raise rd.err("option SeafloorFile: a 3D seafloor is not supported (tapm_opt has a flat seabed)",
                     options["seafloorfile"][1])
    for name, what in (("wavekin", "waves"), ("currents", "currents")):
        if name in options and _nonzero(options[name][0]):
            rd.notes.append(f"option {spelled[name]} = {options[name][0]} (line {options[name][1]}) is ignored: {what} "
                            "come from the vessel scenario's sea states")
    if "rhow" in options and not any(k in options for k in ("rho", "wtrdnsty")):
        rd.notes.append(f"option rhoW (line {options['rhow'][1]}) is read as the water density, as MoorDyn-F does; "
                        "MoorDyn-C 2.7 reads only 'rho' or 'WtrDnsty' and would run with 1025 kg/m^3")
    model = MoorDynModel(source=source, line_types=tuple(types), bodies=tuple(bodies), points=tuple(points),
                         lines=tuple(lines), options=options, notes=tuple(rd.notes), chains=tuple(chains),
                         front=_front_matter(text), fixed_fairleads=tuple(rd.fixed_fairleads))
    wd = model.option("wtrdpth", "depth", "waterdepth")
    if wd is not None:
        try:
            float(wd[0])
        except ValueError:
            raise rd.err(f"option WtrDpth = {wd[0]!r}: a bathymetry file is not supported (tapm_opt has a flat seabed)",
                         wd[1]) from None
    return model


def read_moordyn(path: str | Path, *, fixed_as_fairleads: bool = False) -> MoorDynModel:
    """Read and parse a MoorDyn v2 input file (see :func:`parse_moordyn`)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise MoorDynError(f"cannot read the MoorDyn file: {exc.strerror or exc}", source=str(p)) from None
    return parse_moordyn(text, source=p.name, base_dir=p.parent, fixed_as_fairleads=fixed_as_fairleads)


# --------------------------------------------------------------------------------------------
# conversions shared by reading and writing
# --------------------------------------------------------------------------------------------


def md_from_ned(p: Iterable[float]) -> np.ndarray:
    """A position or vector in {E} (NED) expressed in MoorDyn's frame: ``(x, -y, -z)``."""
    x, y, z = (float(v) for v in p)
    return np.array([x, -y, -z])


ned_from_md = md_from_ned  # the map is its own inverse


def moordyn_line_type(lt: Any, env: Any) -> dict[str, float]:
    """MoorDyn v2 LINE TYPES values of a tapm_opt line type (same forces per length).

    Returns ``d`` (volume-equivalent diameter giving the same submerged weight), ``mass``, ``EA``,
    ``BA`` (``-sqrt(2) axial_damping_ratio``), ``Cd``, ``Ca``, ``CdAx``, ``CaAx``, and ``slopes``,
    the axial stiffnesses the line takes (``(EA,)``, or the slopes of a tension-strain table's
    segments, whose ``EA`` is the secant at its last row: the stiffness MoorDyn-C takes for the
    damping ratio).
    """
    g, rho = float(env.gravity), float(env.water_density)
    m = float(lt.mass_per_length)
    w = float(lt.w(env))
    vol = m / rho - w / (rho * g)  # displaced volume per length [m^2]
    if not vol > 0:
        raise MoorDynError(f"line type {lt.id!r}: its submerged weight {w:g} N/m is not less than its weight in air "
                           f"{m * g:g} N/m, so no MoorDyn diameter reproduces it (MoorDyn's buoyancy is "
                           "rho_w g pi d^2/4)")
    d_md = math.sqrt(4.0 * vol / math.pi)
    d = float(lt.diameter)
    r = d / d_md
    zeta = float(getattr(lt, "axial_damping_ratio", 0.0))
    table = getattr(lt, "EA_table", None)
    slopes = (float(lt.EA),) if table is None else tuple((b[1] - a[1]) / (b[0] - a[0]) for a, b in zip(table, table[1:]))
    return {"d": d_md, "mass": m, "EA": float(lt.EA), "slopes": slopes, "BA": -_SQRT2 * zeta if zeta > 0 else 0.0,
            "Cd": float(lt.Cd_normal) * r, "Ca": float(lt.Ca_normal) * r * r,
            "CdAx": float(lt.Cd_tangential) * r / math.pi, "CaAx": float(lt.Ca_tangential) * r * r}


def seabed_constants(w: float, m: float, d_md: float) -> tuple[float, float]:
    """MoorDyn (kBot [Pa/m], cBot [Pa s/m]) equal to the FEM seabed of a line type.

    MoorDyn's contact force per node is ``(kBot pen - cBot v_z) d_md l_node``; the FEM's node
    spring is ``w l_node / 0.01 m`` with ``0.5 * 2 sqrt(k m_node)`` damping; a buoyant type's
    (``w < 0``) is its weight's magnitude's, as the FEM's.
    """
    w = abs(w)
    k = w / (SEABED_PENETRATION * d_md)
    c = SEABED_DAMPING_RATIO * 2.0 * math.sqrt(w * m / SEABED_PENETRATION) / d_md
    return k, c


_RK_POLY = {"RK2": (1.0, 1.0, 1.0 / 2.0), "RK4": (1.0, 1.0, 1.0 / 2.0, 1.0 / 6.0, 1.0 / 24.0)}
_RK_STAGES = {"RK2": 2, "RK4": 4}


def _rk_limit(scheme: str, zeta: float) -> float:
    """Largest ``W = omega h`` for which the scheme's amplification ``|R(lambda h)| <= 1`` on a mode
    ``x'' + 2 zeta omega x' + omega^2 x = 0`` (for every smaller W too); 0 if there is none."""
    c = _RK_POLY[scheme]
    if zeta < 1.0:
        lams = [complex(-zeta, math.sqrt(1.0 - zeta * zeta))]
    else:
        s = math.sqrt(zeta * zeta - 1.0)
        lams = [complex(-zeta - s, 0.0), complex(-zeta + s, 0.0)]

    def ok(W: float) -> bool:
        for lam in lams:
            z = lam * W
            R = sum(ck * z**k for k, ck in enumerate(c))
            if abs(R) ** 2 > 1.0 + 1e-14:
                return False
        return True

    W, step = 0.0, 1e-3
    while W < 10.0 and ok(W + step):
        W += step
    if W < 1e-2:  # no useful stable step (e.g. RK2 without damping is unstable at any step)
        return 0.0
    lo, hi = W, W + step
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def moordyn_time_step(scenario: Scenario, *, segments: int | None = None,
                      safety: float = DTM_SAFETY) -> tuple[float, str]:
    """MoorDyn ``dtM`` [s] and time scheme ('RK2' or 'RK4') stable for the scenario's lines.

    Per line, a free node's stiffest mode is bounded (Gershgorin, as the FEM's step) by the
    zig-zag axial mode ``omega^2 = 4 EA / (l m l)``, ``2 zeta omega = 4 BA / (l m l)`` (``BA``
    MoorDyn's damping coefficient [N s]) for a suspended node, and with the seabed contact spring
    and damper added for a node on the seabed (``kBot d l``, ``cBot d l``).
    For each scheme the largest stable ``omega h`` on that damped mode follows from its
    stability polynomial; the cheaper scheme per simulated second (stages / step) is chosen, and
    for a tension-strain table every slope of it is such a mode with the same ``BA`` (a soft slope
    is the more heavily damped, which limits RK2 and RK4 more than the stiffest one does), and
    ``dtM = safety * h`` rounded down to 3 significant digits. RK2 (MoorDyn's default) has no
    stable step on an undamped mode, so lines without axial damping get RK4.
    """
    env = scenario.environment
    cache: dict[str, dict[str, float]] = {}
    modes = []
    for ln, (sec, n) in ((ln, sn) for ln in scenario.lines for sn in _sections_written(ln, segments)):
        # every section of a composite line (a joint between two sections is no stiffer than both:
        # its stiffness over mass is the mediant of theirs; a clump or buoy only adds mass)
        lt = scenario.line_type_by_id(sec.type)
        if lt.id not in cache:
            cache[lt.id] = moordyn_line_type(lt, env)
        md = cache[lt.id]
        l = sec.length / n
        BA = md["BA"] if md["BA"] >= 0 else -md["BA"] * l * math.sqrt(md["EA"] * md["mass"])
        kb, cb = seabed_constants(lt.w(env), md["mass"], md["d"])
        m = md["mass"] * l
        # a suspended node: internal damping only; a node on the seabed: the contact spring too
        for EA in md["slopes"]:
            for k, c in ((4.0 * EA / l, 4.0 * BA / l),
                         (4.0 * EA / l + kb * md["d"] * l, 4.0 * BA / l + cb * md["d"] * l)):
                omega = math.sqrt(k / m)
                modes.append((omega, c / (2.0 * m * omega)))
    best = None
    for scheme in ("RK2", "RK4"):
        hs = [_rk_limit(scheme, z) / w for w, z in modes]
        h = min(hs)
        if h <= 0:
            continue
        cost = _RK_STAGES[scheme] / h
        if best is None or cost < best[0]:
            best = (cost, scheme, h)
    assert best is not None  # RK4 is stable on every damped or undamped mode for a small enough step
    _, scheme, h = best
    dt = safety * h
    q = 10.0 ** (math.floor(math.log10(dt)) - 2)
    return float(f"{math.floor(dt / q) * q:.3g}"), scheme


# --------------------------------------------------------------------------------------------
# writing a MoorDyn file
# --------------------------------------------------------------------------------------------


def _f(v: float) -> str:
    """Shortest text that reads back as the same float."""
    v = float(v) + 0.0  # no "-0.0"
    text = repr(v)
    return text[:-2] if text.endswith(".0") else text


@dataclass(frozen=True)
class ExportInfo:
    """What :func:`moordyn_text` chose: time step, scheme, seabed constants, and notes."""

    dtM: float
    scheme: str
    kBot: float
    cBot: float
    n_lines: int
    notes: tuple[str, ...] = ()
    curves: Mapping[str, str] = field(default_factory=dict)
    """The tension-strain curve files the text names (file name -> text), to be written next to it."""


def _sections_written(ln: Any, segments: int | None) -> list[tuple[Any, int]]:
    """(section, its NumSegs) of a line from the anchor up: the sections' own segments, or with
    ``segments`` given, that many for the line shared among its sections by length."""
    parts = ln.parts
    if segments is None:
        return list(zip(parts, ln.section_segments()))
    if len(parts) == 1:
        return [(parts[0], int(segments))]
    shared = Line(id="x", sections=tuple(Section(type=s.type, length=s.length, top=s.top) for s in parts),
                  segments=int(segments), anchor=(0.0, 0.0), fairlead_angle=0.0)
    return list(zip(parts, shared.section_segments()))


def _joint_guess(anchor: np.ndarray, fairlead: np.ndarray, lengths: list[float]) -> list[np.ndarray]:
    """First positions of a composite line's joints (NED) when no better ones are given: on the
    straight line from the anchor to the fairlead at their unstretched length's fraction, the
    sections slack between them."""
    s = np.cumsum(lengths)[:-1] / float(np.sum(lengths))
    return [anchor + f * (fairlead - anchor) for f in s]


def moordyn_text(scenario: Scenario, *, segments: int | None = None, dtM: float | None = None,
                 scheme: str | None = None, outputs: bool = True, extra_options: Mapping[str, Any] | None = None,
                 ic: Mapping[str, Any] | None = None,
                 joints: Mapping[int, Any] | None = None, curve_prefix: str = "") -> tuple[str, ExportInfo]:
    """MoorDyn v2 input text of the scenario's mooring at the field zero point.

    One ``Coupled`` body at the centre of turret with the turret's orientation (MoorDyn yaw
    ``-alpha_t``); every fairlead a ``Body1`` point, every anchor a ``Fixed`` point at its
    position (on the seabed, or above it for a raised anchor: ``Scenario.anchors``);
    line k runs from point 2k-1 (anchor, end A) to point 2k (fairlead, end B). Drive the body with
    the turret's pose: position of the COT, yaw ``-(psi + alpha_t)`` for a locked turret, ``-alpha_t``
    for a free one. No waves, current or faults are written.

    A composite line k is its sections in series: MoorDyn line k is its fairlead section (so
    ``FairTen k`` is line k's fairlead tension), the sections below are lines n+1, n+2, ...
    (after the n fairlead sections, line by line from the anchor up), joined by ``Free`` points
    2n+1, 2n+2, ... that carry the point type's Mass, Volume, CdA and Ca (0 for a plain joint).
    The front matter keeps what MoorDyn has no column for: each line type's tapm_opt values,
    MBS and ``max_strain``; each line's id, fairlead angle, winch and segment sharing; each
    joint's point type id (read back by the importer).

    A line type with a tension-strain table (``EA_table``) names in its EA column a curve file,
    ``EA_<curve_prefix><type id>.txt``, whose text :attr:`ExportInfo.curves` holds (written next to
    the input file by :func:`export_moordyn`): three header lines, then the rows ``strain tension``,
    with no line break after the last (MoorDyn-C 2.7 reads one as an empty row and refuses it); at
    most :data:`MAX_CURVE_ROWS` rows.

    Parameters
    ----------
    segments : int, optional
        Segments of every line (default: each line's ``segments``); a composite line's are shared
        among its sections by length.
    dtM, scheme : optional
        Time step and scheme (default: :func:`moordyn_time_step`).
    outputs : bool
        Write FairTen channels in OUTPUTS (MoorDyn then writes its ``.out`` file).
    extra_options : mapping, optional
        Further OPTIONS (name -> value), e.g. ``{"disableOutput": 1}``.
    ic : mapping, optional
        Initial-condition options (default ``dtIC`` 2 s, ``TmaxIC`` 600 s, ``threshIC`` 1e-3: the
        stationary solution then matches the FEM's settled tensions to about 1e-4).
    joints : mapping, optional
        Line index -> positions in {E} (NED) [m] of its joints from the anchor up, shape
        (sections - 1, 3), where MoorDyn starts its free points (e.g. the quasi-static equilibrium,
        :func:`tapm_opt.models.moordyn_import.composite_joints`); default: on the straight line
        from the anchor to the fairlead, from where they settle in simulated time (MoorDyn's
        initial-condition solver barely moves free points), with a note.
    """
    env = scenario.environment
    g, rho, depth = env.gravity, env.water_density, env.water_depth
    notes: list[str] = []
    for lt in scenario.line_types:
        if re.search(r"[\s#|]", lt.id) or not lt.id:
            raise MoorDynError(f"line type id {lt.id!r} cannot be a MoorDyn TypeName (no spaces, '#' or '|')")
    types = {lt.id: moordyn_line_type(lt, env) for lt in scenario.line_types}
    curves: dict[str, str] = {}
    ea_column = {lt.id: _f(types[lt.id]["EA"]) for lt in scenario.line_types}
    for lt in scenario.line_types:
        if lt.EA_table is None:
            continue
        if len(lt.EA_table) > MAX_CURVE_ROWS:
            raise MoorDynError(f"line type {lt.id!r}: EA_table has {len(lt.EA_table)} rows; MoorDyn-C reads a "
                               f"tension-strain curve of at most {MAX_CURVE_ROWS}")
        fname = "EA_" + re.sub(r"[^A-Za-z0-9_.-]", "_", f"{curve_prefix}{lt.id}") + ".txt"
        ea_column[lt.id] = fname
        curves[fname] = "\n".join([f"---- tension-strain curve of line type {lt.id} (tapm_opt EA_table) ----",
                                    "Strain  Tension", "(-)  (N)"]
                                   + [f"{_f(e)}  {_f(T)}" for e, T in lt.EA_table])
        notes.append(f"line type {lt.id!r}: nonlinear EA in curve file {fname} ({len(lt.EA_table)} rows); beyond its "
                     "last row MoorDyn holds the last tension where tapm_opt continues the last slope")
    mus = {lt.id: lt.seabed_friction for lt in scenario.line_types}
    if len(set(mus.values())) > 1:
        raise MoorDynError("line types have different seabed friction (" + ", ".join(f"{k}: {v:g}" for k, v in
                           mus.items()) + "); MoorDyn's FrictionCoefficient is one value for the whole model")
    # seabed constants: from the line type with the most line length
    length_of = {lt.id: 0.0 for lt in scenario.line_types}
    for ln in scenario.lines:
        for sec in ln.parts:
            length_of[sec.type] += sec.length
    main = max(scenario.line_types, key=lambda t: length_of[t.id])
    kb, cb = seabed_constants(main.w(env), main.mass_per_length, types[main.id]["d"])
    others = [t.id for t in scenario.line_types if length_of[t.id] > 0 and t.id != main.id
              and not np.allclose(seabed_constants(t.w(env), t.mass_per_length, types[t.id]["d"]), (kb, cb),
                                  rtol=1e-9)]
    if others:
        notes.append(f"kBot and cBot are those of line type {main.id!r} (most line length); line types "
                     f"{', '.join(map(repr, others))} sink a little more or less than 1 cm")
    if dtM is None or scheme is None:
        dt0, sch0 = moordyn_time_step(scenario, segments=segments)
        dtM = dt0 if dtM is None else dtM
        scheme = sch0 if scheme is None else scheme
    tur = scenario.turret
    p_cot = np.array([tur.position[0], tur.position[1], 0.0])
    body = md_from_ned(p_cot)
    yaw = -math.degrees(tur.angle)
    fT = scenario.fairleads_T
    anchors = scenario.anchors
    n = len(scenario.lines)
    ptypes = {pt.id: pt for pt in scenario.point_types}
    # the file's points and lines: the n fairlead sections first, then the sections below them
    free_rows: list[tuple[int, np.ndarray, Any, int]] = []    # (point id, NED position, point type, line index)
    line_rows: list[tuple[int, str, int, int, float, int]] = []  # (id, type, A, B, length, NumSegs)
    low_rows: list[tuple[int, str, int, int, float, int]] = []
    front_lines: list[str] = []
    n_pt, n_ln = 2 * n, n
    for i, ln in enumerate(scenario.lines):
        secs = _sections_written(ln, segments)
        anchor = np.asarray(anchors[i], dtype=float)
        fx, fy = fairleads_B(tur.position, fT[i:i + 1], tur.angle)   # in {E} at the field zero point
        fair_E = np.array([float(fx[0]), float(fy[0]), tur.fairlead_depth])
        pos = (list(joints[i]) if joints is not None and i in joints else
               _joint_guess(anchor, fair_E, [s.length for s, _ in secs]))
        if len(pos) != len(secs) - 1:
            raise MoorDynError(f"line {ln.id}: {len(pos)} joint positions given for its {len(secs) - 1} joints")
        below = 2 * i + 1
        ids = []
        for k, (sec, nseg) in enumerate(secs):
            if k == len(secs) - 1:
                line_rows.append((i + 1, sec.type, below, 2 * i + 2, sec.length, nseg))
                ids.append(i + 1)
                break
            n_pt += 1
            n_ln += 1
            free_rows.append((n_pt, np.asarray(pos[k], dtype=float), ptypes.get(sec.top) if sec.top else None, i))
            low_rows.append((n_ln, sec.type, below, n_pt, sec.length, nseg))
            ids.append(n_ln)
            below = n_pt
        own: dict[str, Any] = {"id": ln.id, "fairlead_angle_deg": math.degrees(ln.fairlead_angle)}
        if ln.fairlead_radius is not None:
            own["fairlead_radius"] = ln.fairlead_radius
        if ln.composite:
            own["moordyn_lines"] = ids
            own["segments"] = int(segments) if segments is not None else int(ln.segments)
            shared = (list(range(len(ln.sections))) if segments is not None else
                      [k for k, s in enumerate(ln.sections) if s.segments is None])
            if shared:
                own["shared_segments"] = shared
        if ln.winch_max_rate:
            own["winch_max_rate"] = ln.winch_max_rate
        for key in ("min_length", "max_length"):
            if getattr(ln, key) is not None:
                own[key] = getattr(ln, key)
        front_lines.append(f"Line {i + 1}: tapm_opt line {json.dumps(own)}")

    out: list[str] = []
    w = out.append
    w("--------------------- MoorDyn Input File ------------------------------------")
    w(f"Mooring of tapm_opt scenario {scenario.name!r}: {scenario.meta.description}")
    w("Written by tapm scenario export-moordyn; conventions in tapm_opt's docs/moordyn.md.")
    w("Frame: z up, x north (surge), y west (port at heading 0): (x, y, z) = (x, -y, -z) of tapm_opt's NED {E}.")
    w("Body 1 is the turret: drive it at the centre of turret with the turret's heading (yaw = -(psi + alpha_t)")
    w("for a locked turret, -alpha_t for a free one). Line k: anchor = point 2k-1 (end A), fairlead = point 2k (end B).")
    if free_rows:
        w(f"Composite lines: line k is the fairlead section; the sections below run from the anchor up as lines "
          f"{n + 1}-{n_ln}, joined by Free points {2 * n + 1}-{n_pt} (clump weights, buoys, plain joints).")
    w("Diam reproduces the submerged weight; Cd, Ca, CdAx, CaAx are rescaled to tapm_opt's forces per length.")
    w("The rows below are tapm_opt's own values, which MoorDyn has no column for (read back on import).")
    for lt in scenario.line_types:
        w(f"Line type {lt.id}: tapm_opt d = {_f(lt.diameter)} m, w = {_f(lt.w(env))} N/m, C_DN {_f(lt.Cd_normal)}, "
          f"C_DT {_f(lt.Cd_tangential)} (on d), C_MN {_f(lt.Ca_normal)}, C_MT {_f(lt.Ca_tangential)}, "
          f"axial_damping_ratio {_f(getattr(lt, 'axial_damping_ratio', 0.0))}, MBS {_f(lt.MBS)} N, "
          f"MBS_std {_f(lt.MBS_std)} N"
          + (f", density {_f(lt.density)} kg/m^3" if lt.density is not None else "")
          + (f", max_strain {_f(lt.max_strain)}" if lt.max_strain is not None else "") + ".")
    for row in front_lines:
        w(row)
    for pid, _, pt, i in free_rows:
        if pt is not None:
            w(f"Point {pid}: tapm_opt point type {json.dumps(pt.id)} (line {json.dumps(scenario.lines[i].id)}).")
    w("---------------------- LINE TYPES -----------------------------------------------------")
    w("TypeName   Diam    Mass/m    EA     BA/-zeta    EI      Cd     Ca     CdAx    CaAx")
    w("(name)     (m)     (kg/m)    (N)    (N-s/-)   (N-m^2)   (-)    (-)    (-)     (-)")
    for lt in scenario.line_types:
        t = types[lt.id]
        w(f"{lt.id}  {_f(t['d'])}  {_f(t['mass'])}  {ea_column[lt.id]}  {_f(t['BA'])}  0  {_f(t['Cd'])}  {_f(t['Ca'])}  "
          f"{_f(t['CdAx'])}  {_f(t['CaAx'])}")
    w("---------------------- BODIES -----------------------------------------------------------")
    w("ID  Attachment  X0   Y0   Z0   r0   p0   y0   Mass  CG*  I*  Volume  CdA*  Ca*")
    w("(#) (word)      (m)  (m)  (m) (deg) (deg) (deg) (kg)  (m) (kg-m^2) (m^3) (m^2) (-)")
    w(f"1   Coupled  {_f(body[0])}  {_f(body[1])}  0  0  0  {_f(yaw)}  0  0  0  0  0  0")
    w("---------------------- POINTS -----------------------------------------------------------")
    w("ID  Attachment  X    Y    Z    Mass  Volume  CdA   Ca")
    w("(#) (word/ID)  (m)  (m)  (m)  (kg)  (m^3)  (m^2)  (-)")
    for i, ln in enumerate(scenario.lines):
        a = [_clean(v) for v in md_from_ned(anchors[i])]
        f = [_clean(v) for v in md_from_ned((fT[i, 0], fT[i, 1], tur.fairlead_depth))]
        w(f"{2 * i + 1}  Fixed  {_f(a[0])}  {_f(a[1])}  {_f(a[2])}  0  0  0  0")
        w(f"{2 * i + 2}  Body1  {_f(f[0])}  {_f(f[1])}  {_f(f[2])}  0  0  0  0")
    for pid, r, pt, _ in free_rows:
        x = [_clean(v, 6) for v in md_from_ned(r)]
        m, v, cda, cam = (pt.mass, pt.volume, pt.CdA, pt.Ca) if pt is not None else (0.0, 0.0, 0.0, 0.0)
        w(f"{pid}  Free  {_f(x[0])}  {_f(x[1])}  {_f(x[2])}  {_f(m)}  {_f(v)}  {_f(cda)}  {_f(cam)}")
    w("---------------------- LINES ------------------------------------------------------------")
    w("ID  LineType  AttachA  AttachB  UnstrLen  NumSegs  LineOutputs")
    w("(#)  (name)    (ID)     (ID)      (m)      (-)      (-)")
    for lid, typ, pa, pb, length, nseg in line_rows + low_rows:
        w(f"{lid}  {typ}  {pa}  {pb}  {_f(length)}  {int(nseg)}  -")
    w("---------------------- OPTIONS ----------------------------------------------------------")
    w(f"{_f(dtM)}  dtM  time step [s]: {DTM_SAFETY:g} x the {scheme} stability limit of the stiffest line mode")
    w(f"{scheme}  tScheme  time integration scheme")
    w(f"{_f(g)}  g  gravity [m/s^2]")
    w(f"{_f(rho)}  rho  water density [kg/m^3] (MoorDyn-C reads rho, MoorDyn-F rho or rhoW)")
    w(f"{_f(depth)}  WtrDpth  water depth [m]")
    w(f"{_f(kb)}  kBot  seabed stiffness [Pa/m]: a line on the seabed sinks {SEABED_PENETRATION * 100:g} cm")
    w(f"{_f(cb)}  cBot  seabed damping [Pa-s/m]: {SEABED_DAMPING_RATIO * 100:g} % of critical per node")
    if mus and next(iter(mus.values())) > 0:
        w(f"{_f(next(iter(mus.values())))}  FrictionCoefficient  seabed friction coefficient")
    ic_opts = {"dtIC": 2.0, "TmaxIC": 600.0, "threshIC": 1e-3}
    ic_opts.update(ic or {})
    for k, v in ic_opts.items():
        w(f"{v if isinstance(v, str) else _f(v)}  {k}")
    for k, v in (extra_options or {}).items():
        w(f"{v if isinstance(v, str) else _f(v)}  {k}")
    w("---------------------- OUTPUTS ----------------------------------------------------------")
    if outputs:
        for i in range(len(scenario.lines)):
            w(f"FairTen{i + 1}")
    w("------------------------- need this line ------------------------------------------------")
    guessed = [scenario.lines[i].id for i in sorted({i for *_, i in free_rows}) if joints is None or i not in joints]
    if guessed:
        notes.append(f"the free points of composite line{'s' * (len(guessed) > 1)} {', '.join(guessed)} start on the "
                     "straight line from the anchor to the fairlead: MoorDyn's initial-condition solver barely moves "
                     "free points, so they settle only in simulated time; tapm_opt.models.moordyn_import.export_moordyn "
                     "(and tapm scenario export-moordyn) start them at the quasi-static equilibrium")
    info = ExportInfo(dtM=float(dtM), scheme=str(scheme), kBot=kb, cBot=cb, n_lines=len(scenario.lines),
                      notes=tuple(notes), curves=curves)
    return "\n".join(out) + "\n", info


def export_moordyn(scenario: Scenario | str | Path, path: str | Path, **kwargs: Any) -> ExportInfo:
    """Write :func:`moordyn_text` of a scenario (object, built-in name or TOML path) to ``path``,
    and the tension-strain curve files it names next to it (``EA_<file stem>_<type id>.txt``)."""
    from .._io import atomic_write_text

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    kwargs.setdefault("curve_prefix", Path(path).stem + "_")
    text, info = moordyn_text(sc, **kwargs)
    for fname, curve in info.curves.items():
        atomic_write_text(Path(path).parent / fname, curve)
    atomic_write_text(path, text)
    return info


# --------------------------------------------------------------------------------------------
# reading a MoorDyn file into a scenario
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ImportResult:
    """A scenario built by :func:`import_moordyn`: the validated scenario, its file data (TOML
    keys and units), the TOML text, and notes on what was ignored or assumed."""

    scenario: Scenario
    data: dict
    toml: str
    notes: tuple[str, ...] = field(default_factory=tuple)


def vessel_data_of(vessel: str | Path) -> tuple[dict, str]:
    """The vessel scenario's file dictionary (as written, exact numbers) and its display name."""
    load_scenario(vessel)  # validates it, with the usual messages
    text = str(vessel)
    path = Path(text)
    if not path.suffix and (BUILTIN_DIR / f"{text}.toml").is_file():
        path = BUILTIN_DIR / f"{text}.toml"
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    name = path.stem if path.parent == BUILTIN_DIR else str(path)
    return data, name


def _clean(v: float, nd: int = 9) -> float:
    return float(round(float(v), nd)) + 0.0


def scenario_data_from_moordyn(model: MoorDynModel, vessel_data: dict, *, mbs: Mapping[str, float],
                               mbs_cov: float = 0.05, name: str | None = None,
                               vessel_name: str = "", riser: str = "auto",
                               turret: str = "auto", recentre: str = "auto") -> tuple[dict, list[str], dict]:
    """Scenario file dictionary: mooring from ``model``, everything else from ``vessel_data``.

    Returns ``(data, notes, comments)`` where ``comments[("line_types", i)]`` are comment lines
    for the TOML writer. See :func:`import_moordyn`.
    """
    src = model.source
    notes = list(model.notes)
    g, rho, depth = model.gravity, model.water_density, model.water_depth
    if not depth > 0:
        raise MoorDynError("no water depth: set option WtrDpth (or put the anchors on the seabed)", source=src)
    if not g > 0:
        got = model.option("g", "gravity")
        raise MoorDynError(f"option g = {g:g} m/s^2: tapm_opt's lines hang under gravity, which must be > 0 (a "
                           "weightless line has no catenary)", source=src, lineno=got[1] if got else None)
    wd = model.number_option("wtrdpth", "depth", "waterdepth", default=0.0) or 0.0
    if 0.0 < wd < depth:
        deepest = max(model.points, key=lambda p: -model.global_position(p)[2])
        notes.append(f"option WtrDpth = {wd:g} m is above point {deepest.id} (z = {-depth:g} m): the water depth is "
                     f"{depth:g} m, as MoorDyn-C raises it; anchors above -{depth:g} m are read as raised anchors")
    # -- line types -----------------------------------------------------------------------
    problems: list[MoorDynError] = []
    front = model.front
    used = [lt for lt in model.line_types if any(ln.type == lt.name for ch in model.chains for ln in ch.lines)]
    missing = [lt.name for lt in used if lt.name not in mbs and "MBS" not in front.types.get(lt.name, ({}, 0))[0]]
    if missing:
        raise MoorDynError(f"line type {missing[0]!r} has no breaking strength: MoorDyn files carry none; give it with "
                           f"--mbs {missing[0]}=NEWTONS" + (f" (also missing: {', '.join(missing[1:])})"
                                                            if len(missing) > 1 else ""), source=src)
    unknown = sorted(set(mbs) - {lt.name for lt in model.line_types})
    if unknown:
        raise MoorDynError(f"--mbs names line type {unknown[0]!r}, which the file does not define (it has "
                           f"{', '.join(lt.name for lt in model.line_types)})", source=src)
    seabed = [(k, model.number_option(*names), model.option(*names)) for k, names in enumerate((("kbot", "kb"),
                                                                                                 ("cbot", "cb")))]
    seabed = [(k, v, got) for k, v, got in seabed if got is not None]
    if seabed:
        ref = [seabed_constants(w, lt.mass, lt.d) for lt in used
               if (w := (lt.mass - rho * math.pi * lt.d**2 / 4.0) * g) > 0]
        for k, v, (_, at) in seabed:
            n = next(name for name, (_, i) in model.options.items() if i == at)
            if not any(r[k] > 0 and abs(float(v) / r[k] - 1.0) < 1e-6 for r in ref):
                notes.append(f"option {n} = {v:g} (line {at}) is not used: the FEM seabed sinks "
                             f"{SEABED_PENETRATION * 100:g} cm under a line's weight with {SEABED_DAMPING_RATIO * 100:g} % "
                             "of critical damping (docs/moordyn.md)")
    mu = float(model.number_option("frictioncoefficient", default=0.0) or 0.0)
    if mu:
        notes.append(f"seabed friction {mu:g} (FrictionCoefficient) for every line type; MoorDyn's saturated-damping "
                     "friction model and the FEM's tanh-regularised Coulomb friction differ at low speed")
    line_types, comments = [], {}
    for lt in used:
        w = (lt.mass - rho * math.pi * lt.d**2 / 4.0) * g
        # a buoyant type (w <= 0) is given by its density, the mass over the displaced volume (the
        # scenario's submerged_weight is positive); where it may be in a line, the loader says
        # (config.loader.buoyant_line_problem: between weighted sections of a composite line)
        density = lt.mass / (math.pi * lt.d**2 / 4.0) if not w > 0 else None
        BA = lt.BA if not lt.viscoelastic else (lt.BA_dynamic or 0.0)   # the damper across the whole segment
        if BA < 0:
            zeta = -BA / _SQRT2
        elif BA > 0:
            seg = {ln.length / ln.segments for ln in model.lines if ln.type == lt.name}
            if max(seg) - min(seg) > 1e-9 * max(seg):
                what = f"BA = {lt.BA:g} N s" if not lt.viscoelastic else f"the dynamic damping BA_d = {BA:g} N s"
                problems.append(MoorDynError(
                    f"line type {lt.name!r}: {what} with lines of different segment lengths "
                    f"({', '.join(f'{s:g}' for s in sorted(seg))} m); tapm_opt's axial damping is one ratio per line type: "
                    "give the lines the same UnstrLen/NumSegs" + ("" if lt.viscoelastic else
                                                                   ", or BA as a negative damping ratio"),
                    source=src, lineno=lt.lineno))
                continue
            l = seg.pop()
            zeta = BA / (_SQRT2 * l * math.sqrt(lt.EA * lt.mass))
        else:
            zeta = 0.0
        if lt.viscoelastic:
            zeta = _viscoelastic_damping(lt, zeta, notes)
        if zeta > 1.0:
            problems.append(MoorDynError(f"line type {lt.name!r}: BA = {lt.BA:g} is {zeta:.3g} of the critical damping "
                                         "of tapm_opt's segment mode; at most 1 (BA = -1.414) is allowed", source=src,
                                         lineno=lt.lineno))
            continue
        fm, at = front.types.get(lt.name, ({}, 0))
        if lt.name in mbs:
            MBS, MBS_std, said = float(mbs[lt.name]), mbs_cov * float(mbs[lt.name]), "--mbs"
        else:
            MBS = fm["MBS"]
            MBS_std = fm.get("MBS_std", mbs_cov * MBS)
            said = f"the front matter (line {at})"
            notes.append(f"line type {lt.name!r}: MBS {MBS:g} N" + (f" and MBS_std {MBS_std:g} N" if "MBS_std" in fm
                                                                   else "") +
                         f" from the file's tapm_opt front matter (line {at}); --mbs {lt.name}=NEWTONS overrides")
        item = {
            "id": lt.name, "diameter": lt.d, "mass_per_length": lt.mass, "submerged_weight": w, "EA": lt.EA,
            "MBS": MBS, "MBS_std": MBS_std, "Cd_normal": lt.Cd, "Cd_tangential": math.pi * lt.CdAx,
            "Ca_normal": lt.Ca, "Ca_tangential": lt.CaAx, "seabed_friction": mu, "axial_damping_ratio": zeta,
        }
        if lt.EA_table is not None:  # EA is the curve's secant: the table alone says it
            del item["EA"]
            item = {k: v for k, v in item.items() if k != "MBS"} | {"EA_table": [list(r) for r in lt.EA_table],
                                                                   "MBS": MBS}
            item = {k: item[k] for k in ("id", "diameter", "mass_per_length", "submerged_weight", "EA_table", "MBS",
                                         "MBS_std", "Cd_normal", "Cd_tangential", "Ca_normal", "Ca_tangential",
                                         "seabed_friction", "axial_damping_ratio")}
        if density is not None:  # in the place of the submerged weight
            item = {("density" if k == "submerged_weight" else k): (density if k == "submerged_weight" else v)
                    for k, v in item.items()}
            notes.append(f"line type {lt.name!r} is buoyant (Mass/m {lt.mass:g} kg/m, Diam {lt.d:g} m: submerged weight "
                         f"{w:.6g} N/m), given by its density {density:.6g} kg/m^3 (Mass/m over pi Diam^2/4)")
        own = _front_type_values(lt, fm, g, rho)
        if own is not None:
            item.update(own)
            if item["submerged_weight"] is None:
                del item["submerged_weight"]   # the density gives it
            else:
                item.pop("density", None)      # the front matter's submerged weight gives it
            notes.append(f"line type {lt.name!r}: tapm_opt's own {', '.join(k for k in own if own[k] is not None)} "
                         f"from the file's front matter (line {at}), which give its MoorDyn row")
        elif any(k in fm for k in ("d", "Cd_normal")):
            notes.append(f"line type {lt.name!r}: the front matter's tapm_opt values (line {at}) do not give the "
                         f"MoorDyn row (line {lt.lineno}), which is read instead")
        if "max_strain" in fm:
            item["max_strain"] = fm["max_strain"]
            notes.append(f"line type {lt.name!r}: max_strain {fm['max_strain']:g} from the file's tapm_opt front matter "
                         f"(line {at})")
        ea_said = f"EA {lt.EA:g} N" if lt.EA_table is None else (
            f"EA curve {lt.EA_file} ({len(lt.EA_table)} rows, secant {lt.EA:g} N)")
        if lt.viscoelastic:
            ea_said = f"EA {lt.EA:g}|{lt.EA_dynamic} N (viscoelastic: the static {lt.EA:g} N used)"
        ba_said = f"BA {lt.BA:g}" + (f"|{lt.BA_dynamic:g}" if lt.BA_dynamic is not None else "")
        comments[("line_types", len(line_types))] = [
            f"MoorDyn {lt.name} ({src}:{lt.lineno}): Diam {lt.d:g} m, Mass/m {lt.mass:g} kg/m, {ea_said}, "
            f"{ba_said}, Cd {lt.Cd:g}, Ca {lt.Ca:g}, CdAx {lt.CdAx:g} (on pi d), CaAx {lt.CaAx:g}"
            + (f", Cl {lt.Cl:g} (VIV, neglected)" if lt.Cl > 0 else ""),
            f"MBS from {said}" + (f"; MBS_std = {mbs_cov:g} x MBS (--mbs-cov)" if said == "--mbs" else ""),
        ]
        line_types.append(item)
    # -- points at the joints of composite lines ----------------------------------------------
    point_types, top_of = _point_types(model, rho, g, notes)
    # -- geometry -------------------------------------------------------------------------
    tur = dict(vessel_data.get("turret", {}))
    p_cot = np.array([float(x) for x in tur.get("position", (0.0, 0.0))], dtype=float)
    alpha = math.radians(float(tur.get("angle_deg", 0.0)))
    ca, sa = math.cos(-alpha), math.sin(-alpha)
    tol_z = 1e-6 * max(1.0, depth)
    lines, fair, anchors = [], [], []
    for ch in model.chains:
        anc, fl = model.point(ch.anchor), model.point(ch.fairlead)
        if len(ch.lines) == 1 and ch.flipped[0]:
            notes.append(f"line {ch.top.id} runs from the fairlead (end A, point {fl.id}) to the anchor (end B): "
                         "read with its anchor first, as tapm_opt numbers nodes from the anchor")
        elif any(ch.flipped):
            down = [str(ln.id) for ln, f in zip(ch.lines, ch.flipped) if f]
            notes.append(f"line{'s' * (len(down) > 1)} {', '.join(down)} of composite line {ch.name} run{'s' * (len(down) == 1)} "
                         "from the upper end (A) down: read from the anchor up, as tapm_opt numbers nodes from the anchor")
        a = ned_from_md(model.global_position(anc))
        f = ned_from_md(model.global_position(fl))
        fair.append((fl, ch, f))
        z_anc = depth if abs(a[2] - depth) <= tol_z else _clean(a[2])  # on the seabed, or above it
        anchors.append((anc, ch, z_anc))
        item: dict[str, Any] = {"id": ch.name}
        if len(ch.lines) == 1:
            item["type"] = ch.top.type
        else:
            item["sections"] = [{"type": ln.type, "length": ln.length, "segments": ln.segments}
                                | ({"top": top_of[p]} if k < len(ch.lines) - 1 and (p := ch.points[k + 1]) in top_of
                                   else {}) for k, ln in enumerate(ch.lines)]
        item["anchor"] = [_clean(a[0]), _clean(a[1]), _clean(z_anc)]
        if len(ch.lines) == 1:
            item.update(length=ch.top.length, segments=ch.top.segments)
        lines.append(item)
    zs = [f[2] for _, _, f in fair]
    if max(zs) - min(zs) > 1e-6:
        hi = max(fair, key=lambda x: x[2][2])
        lo = min(fair, key=lambda x: x[2][2])
        problems.append(MoorDynError(
            f"fairlead depths differ: point {lo[0].id} (line {lo[1].name}) is {lo[2][2]:g} m deep, point {hi[0].id} "
            f"(line {hi[1].name}) {hi[2][2]:g} m; tapm_opt's turret has one fairlead depth", source=src,
            lineno=hi[0].lineno))
    fl_depth = _clean(float(np.mean(zs)))
    if fl_depth >= depth:
        problems.append(MoorDynError(f"the fairleads ({fl_depth:g} m deep) are not above the seabed ({depth:g} m)",
                                     source=src))
    for anc, ch, z_anc in anchors:
        if z_anc <= fl_depth:
            problems.append(MoorDynError(
                f"point {anc.id} (anchor of line {ch.name}) is at z = {-z_anc:g} m, not below the fairleads at "
                f"-{fl_depth:g} m: an anchor lies on the seabed (-{depth:g} m) or above it, below the fairleads",
                source=src, lineno=anc.lineno))
    _raise_all(problems, src)
    fair, lines = _recentred(model, fair, lines, p_cot, vessel_data.get("vessel", {}), recentre, notes)
    radii = []
    for (fl, ln, f), item in zip(fair, lines):
        dx, dy = f[0] - p_cot[0], f[1] - p_cot[1]
        xT, yT = ca * dx - sa * dy, sa * dx + ca * dy
        r = math.hypot(xT, yT)
        if r < 1e-9:
            r = 0.0
            ax, ay = item["anchor"][0] - p_cot[0], item["anchor"][1] - p_cot[1]
            gam = math.degrees(math.atan2(sa * ax + ca * ay, ca * ax - sa * ay))
        else:
            gam = math.degrees(math.atan2(yT, xT))
        item["fairlead_angle_deg"] = _clean(gam % 360.0) % 360.0
        radii.append(_clean(r))
    one_circle = max(radii) - min(radii) <= 1e-6
    if one_circle:
        tur["fairlead_radius"] = radii[0]
    else:
        tur["fairlead_radius"] = float(np.median(radii))
        for item, r in zip(lines, radii):
            item["fairlead_radius"] = r
    vessel_mode = str(tur.get("mode", "free"))
    # a turret's fairleads written to a file's precision still lie on one circle: 1 cm, or 0.1 % of it
    a_turret = max(radii) - min(radii) <= max(0.01, 1e-3 * float(np.median(radii)))
    mode = turret if turret != "auto" else (vessel_mode if a_turret else "locked")
    tur["mode"] = mode
    where = (f"on one circle of radius {float(np.median(radii)):g} m about the vessel's centre of turret" if a_turret else
             f"at {min(radii):g}-{max(radii):g} m from the vessel's centre of turret, not on one circle")
    if mode != vessel_mode or (mode == "free" and not a_turret):
        how = {"locked": "the turret is locked to the hull at its angle (a spread mooring), as MoorDyn has them",
               "free": "the turret is free (weathervaning): the fairleads turn about the centre of turret, so the "
                       "mooring gives no yaw moment about it, unlike MoorDyn's hull-fixed points"}[mode]
        other = "free" if mode == "locked" else "locked"
        notes.append(f"MoorDyn has no turret: its fairleads on the vessel are fixed to the hull. They lie {where}; "
                     f"{how} (--turret {other} for the other; the vessel scenario's turret is {vessel_mode})")
    tur["fairlead_depth"] = fl_depth
    _front_lines(model, lines, notes)
    order = ("id", "type", "sections", "anchor", "fairlead_angle_deg", "fairlead_radius", "length", "segments",
             "winch_max_rate", "min_length", "max_length")
    lines = [{k: it[k] for k in order if k in it} for it in lines]
    # -- the rest from the vessel -----------------------------------------------------------
    data = {k: v for k, v in vessel_data.items()}
    old_depth = float(vessel_data.get("environment", {}).get("water_depth", depth))
    if old_depth != depth and any(ss.get("current_profile_depths") for ss in vessel_data.get("sea_states", [])):
        scale = depth / old_depth
        data["sea_states"] = [dict(ss, current_profile_depths=[_clean(z * scale) for z in ss["current_profile_depths"]])
                              if ss.get("current_profile_depths") else ss for ss in vessel_data["sea_states"]]
        notes.append(f"the current profile depths of the vessel scenario's sea states are scaled by {depth:g}/"
                     f"{old_depth:g} (the water depth of the MoorDyn file over the vessel scenario's)")
    if "riser" in vessel_data:
        riser_data, note = _imported_riser(vessel_data, tur, depth, old_depth, riser)
        data.pop("riser", None)
        if riser_data is not None:
            data["riser"] = riser_data
        if note:
            notes.append(note)
    env = dict(vessel_data.get("environment", {}))
    env.update({"water_depth": depth, "water_density": rho, "gravity": g})
    vname = vessel_name or str(vessel_data.get("meta", {}).get("name", "vessel"))
    meta = dict(vessel_data.get("meta", {}))
    meta["name"] = name or Path(src).stem or "moordyn"
    meta["description"] = f"mooring of MoorDyn file {src} with the vessel of {vname}"
    meta["sources"] = [f"MoorDyn file {src}: lines, line types, anchors, fairleads, depth, density, gravity",
                       *[str(s) for s in vessel_data.get("meta", {}).get("sources", [])]]
    data["meta"] = meta
    data["environment"] = env
    data["turret"] = tur
    data["line_types"] = line_types
    data["lines"] = lines
    data.pop("point_types", None)
    if point_types:
        data["point_types"] = point_types
    ids = {it["id"] for it in lines}
    faults = []
    for f in vessel_data.get("faults", []):
        if f.get("kind") == "line_break" and str(f.get("line")) not in ids:
            notes.append(f"fault line_break of line {f.get('line')!r} at {f.get('time')} s dropped: the MoorDyn file "
                         "has no such line")
            continue
        faults.append(f)
    data.pop("faults", None)
    if faults:
        data["faults"] = faults
    unused = [lt.name for lt in model.line_types if lt not in used]
    if unused:
        notes.append(f"line type{'s' if len(unused) > 1 else ''} {', '.join(map(repr, unused))} used by no line: "
                     "left out")
    # keep the table order of the schema
    keys = ["meta", "environment", "vessel", "turret", "line_types", "lines", "point_types"]
    data = {k: data[k] for k in keys if k in data} | {k: v for k, v in data.items() if k not in keys}
    return data, notes, comments


def _viscoelastic_damping(lt: MDLineType, zeta: float, notes: list[str]) -> float:
    """The FEM's axial damping ratio of a viscoelastic line type, from ``zeta``, the ratio its
    dynamic damping BA_d gives: at most 1 (critical, the FEM's most), with a note saying what
    becomes of MoorDyn's two dampers."""
    static = f"the static damping {lt.BA:g}" + (" (a ratio)" if lt.BA < 0 else " N s")
    head = (f"line type {lt.name!r}: viscoelastic damping BA = {lt.BA:g}" +
            (f"|{lt.BA_dynamic:g}" if lt.BA_dynamic is not None else "") + f" (line {lt.lineno}): ")
    tail = (f"; {static}, across MoorDyn's static spring, sets how fast the line creeps from the dynamic to the "
            "static stiffness and is neglected with the dynamic stiffness")
    if not lt.BA_dynamic:
        notes.append(head + "MoorDyn's dynamic spring, which carries fast motion, has no damper (no BA_d), so the "
                     "FEM's axial damping is 0" + tail)
        return 0.0
    EA_d = float(lt.EA_dynamic.split("|")[0])   # EA_d, or EA_Dc at zero mean load
    said = (f"the FEM's axial damper, across the whole segment, is MoorDyn's dynamic damper BA_d = {lt.BA_dynamic:g} "
            "N s across the dynamic spring, which carries fast motion")
    if zeta <= 1.0:
        notes.append(head + said + f" (axial_damping_ratio {zeta:.4g})" + tail)
        return zeta
    # capped: the damper's coefficient becomes critical's; the frequencies above which either
    # damper matters against its spring
    c_fem = lt.BA_dynamic / zeta
    notes.append(head + said + f", {zeta:.3g} times the critical damping of the FEM's segment mode: the FEM takes "
                 f"critical (axial_damping_ratio 1, its most). Both damp the segments' zig-zag mode without ringing; "
                 f"the damping matters against the stiffness above EA_d / BA_d = {EA_d / lt.BA_dynamic:.3g} rad/s in "
                 f"MoorDyn and EA_s / c = {lt.EA / c_fem:.3g} rad/s in the FEM" + tail)
    return 1.0


def _front_type_values(lt: MDLineType, fm: Mapping[str, float], g: float, rho: float) -> dict[str, float] | None:
    """tapm_opt's own values of a line type from the front matter written by :func:`moordyn_text`
    (hydrodynamic diameter, coefficients on it, damping ratio, density or submerged weight), if
    they give the file's MoorDyn row (to 1e-9); None otherwise (an edited file: the row is read)."""
    need = ("d", "Cd_normal", "Cd_tangential", "Ca_normal", "Ca_tangential", "axial_damping_ratio")
    if not all(k in fm for k in need) or not ("w" in fm or "density" in fm):
        return None
    dens = fm.get("density")
    own = {"diameter": fm["d"], "Cd_normal": fm["Cd_normal"], "Cd_tangential": fm["Cd_tangential"],
           "Ca_normal": fm["Ca_normal"], "Ca_tangential": fm["Ca_tangential"],
           "axial_damping_ratio": fm["axial_damping_ratio"]}
    try:
        t = LineType(id=lt.name, mass_per_length=lt.mass, EA=lt.EA, MBS=1.0, MBS_std=0.0, density=dens,
                     submerged_weight=None if dens is not None else fm["w"], **own)
        md = moordyn_line_type(t, SimpleNamespace(gravity=g, water_density=rho))
    except (MoorDynError, ValueError, ZeroDivisionError):
        return None
    row = {"d": lt.d, "mass": lt.mass, "EA": lt.EA, "BA": lt.BA, "Cd": lt.Cd, "Ca": lt.Ca, "CdAx": lt.CdAx,
           "CaAx": lt.CaAx}
    if not all(math.isclose(md[k], v, rel_tol=1e-9, abs_tol=1e-12) for k, v in row.items()):
        return None
    if dens is not None:
        own["density"] = dens
        own["submerged_weight"] = None   # given by the density instead
    else:
        own["submerged_weight"] = fm["w"]   # as the scenario gives it, not its MoorDyn round-off
    return own


def _point_types(model: MoorDynModel, rho: float, g: float, notes: list[str]) -> tuple[list[dict], dict[int, str]]:
    """Point types of the free points at the joints of composite lines that carry something (mass,
    volume, drag or added mass), one per distinct row (and front-matter id), and each such point's
    point type id. Named by the front matter written by :func:`moordyn_text`, else
    ``clump``/``buoy``/``point`` + the first point's number (net weight down, up or none)."""
    out: list[dict] = []
    top_of: dict[int, str] = {}
    seen: dict[tuple, str] = {}
    taken: set[str] = set()
    for ch in model.chains:
        for pid in ch.joints:
            p = model.point(pid)
            if not any(p.carries):
                continue
            named = model.front.points.get(pid, (None, 0))[0]
            key = (named, p.carries)
            if key not in seen:
                pt_id = named
                if pt_id is None or pt_id in taken:
                    W = (p.mass - rho * p.volume) * g
                    base = "clump" if W > 0 else "buoy" if W < 0 else "point"
                    pt_id, k = f"{base}{pid}", 1
                    while pt_id in taken:
                        k += 1
                        pt_id = f"{base}{pid}_{k}"
                seen[key] = pt_id
                taken.add(pt_id)
                out.append({"id": pt_id, "mass": p.mass, "volume": p.volume, "CdA": p.CdA, "Ca": p.Ca})
            top_of[pid] = seen[key]
    if out:
        notes.append("free points with a mass, volume, drag or added mass become point types at the joints of "
                     "composite lines: " + "; ".join(
                         f"{pt['id']} (point{'s' * (n > 1)} {', '.join(str(q) for q, t in top_of.items() if t == pt['id'])}"
                         f"; net weight {(pt['mass'] - rho * pt['volume']) * g:.4g} N)"
                         for pt in out if (n := sum(t == pt['id'] for t in top_of.values()))))
    return out, top_of


def _front_lines(model: MoorDynModel, lines: list[dict], notes: list[str]) -> None:
    """tapm_opt's own fields of each line from the front matter written by :func:`moordyn_text`
    (id, fairlead angle and radius to the file's precision, winch, segments shared among the
    sections), where its row names the same MoorDyn lines; in place."""
    rows = []
    for ch, item in zip(model.chains, lines):
        got = model.front.lines.get(ch.top.id)
        if got is None:
            continue
        fm, at = got
        if list(fm.get("moordyn_lines", [ch.top.id])) != [ln.id for ln in ch.lines]:
            notes.append(f"the front matter's line {fm.get('id')!r} (line {at}) names MoorDyn lines "
                         f"{fm.get('moordyn_lines')}, not {ch.said()}: not used")
            continue
        rows.append((ch, item, fm, at))
    new_ids = [fm["id"] for _, _, fm, _ in rows]
    ids_ok = len(set(new_ids)) == len(new_ids) and not (set(new_ids) & {it["id"] for it in lines} - set(
        it["id"] for _, it, _, _ in rows))
    for ch, item, fm, _ in rows:
        if ids_ok:
            item["id"] = fm["id"]
        for key, tol in (("fairlead_angle_deg", 1e-6), ("fairlead_radius", 1e-6)):
            v = fm.get(key)
            if isinstance(v, (int, float)) and key in item:
                d = float(v) - float(item[key])
                if key == "fairlead_angle_deg":
                    d = (d + 180.0) % 360.0 - 180.0
                if abs(d) <= tol:
                    item[key] = float(v)
        for key in ("winch_max_rate", "min_length", "max_length"):
            if isinstance(fm.get(key), (int, float)):
                item[key] = float(fm[key])
        shared = fm.get("shared_segments", [])
        if "sections" in item and isinstance(fm.get("segments"), int) and isinstance(shared, list):
            secs = tuple(Section(type=s["type"], length=s["length"], top=s.get("top"),
                                 segments=None if k in shared else s["segments"])
                         for k, s in enumerate(item["sections"]))
            ln = Line(id="x", sections=secs, segments=fm["segments"], anchor=(0.0, 0.0), fairlead_angle=0.0)
            if list(ln.section_segments()) == [s["segments"] for s in item["sections"]]:
                if shared or fm["segments"] != sum(s["segments"] for s in item["sections"]):
                    item["segments"] = fm["segments"]   # (all sections giving theirs, the sum is the default)
                for k, sec in enumerate(item["sections"]):
                    if k in shared:
                        sec.pop("segments")
    if rows:
        notes.append(f"line{'s' * (len(rows) > 1)} {', '.join(str(it['id']) for _, it, _, _ in rows)}: tapm_opt's own "
                     "ids, fairlead angles, winches and segment counts from the file's front matter (lines "
                     f"{rows[0][3]}-{rows[-1][3]})")


#: tapm_opt's line-type fields as the MoorDyn columns they come from: (column, tapm_opt value -> file value).
_MD_COLUMNS: dict[str, tuple[str, Any]] = {
    "Cd_tangential": ("CdAx", lambda v: v / math.pi), "Cd_normal": ("Cd", None), "Ca_normal": ("Ca", None),
    "Ca_tangential": ("CaAx", None), "diameter": ("Diam", None), "mass_per_length": ("Mass/m", None),
    "submerged_weight": ("Mass/m and Diam", None), "EA": ("EA", None), "axial_damping_ratio": ("BA", None),
    "EA_table": ("EA", None),
}


def problem_in_file_terms(issue: Any, model: MoorDynModel, data: Mapping[str, Any]) -> str:
    """A scenario problem of an imported field said in the MoorDyn file's own terms: the line
    type or line, the file's line number and column, then tapm_opt's field and reason."""
    m = re.fullmatch(r"(line_types|lines|point_types)\[(\d+)\](?:\.sections\[(\d+)\])?\.(\w+)", str(issue.path))
    if not m:
        return str(issue)
    table, k, sec, field_name = m.group(1), int(m.group(2)), m.group(3), m.group(4)
    try:
        item = data[table][k]
    except (KeyError, IndexError, TypeError):
        return str(issue)
    if table == "lines":
        ch = model.chains[k] if k < len(model.chains) else None
        if ch is not None and sec is not None and int(sec) < len(ch.lines):
            ln = ch.lines[int(sec)]
            return (f"line {item.get('id')}, section {sec} (MoorDyn line {ln.id}, file line {ln.lineno}): {field_name} "
                    f"{issue.message}")
        where = f"line {item.get('id')}" + (f" (file line{'s' * (len(ch.lines) > 1)} "
                                             f"{', '.join(str(x.lineno) for x in ch.lines)})" if ch is not None else "")
        return f"{where}: {field_name} {issue.message}"
    if table == "point_types":
        pts = [model.point(pid) for c in model.chains for pid in c.joints
               if model.point(pid).carries == (item.get("mass"), item.get("volume"), item.get("CdA"), item.get("Ca"))]
        col = {"mass": "Mass", "volume": "Volume", "CdA": "CdA", "Ca": "Ca"}.get(field_name, field_name)
        where = f"point type {item.get('id')!r}" + (
            f" (point{'s' * (len(pts) > 1)} {', '.join(str(p.id) for p in pts)}, file line {pts[0].lineno})" if pts else "")
        v = item.get(field_name)
        return f"{where}: {col} = {v:g} gives tapm_opt's {field_name} {issue.message}" if isinstance(
            v, (int, float)) else f"{where}: {field_name} {issue.message}"
    name = str(item.get("id"))
    lt = next((x for x in model.line_types if x.name == name), None)
    col, back = _MD_COLUMNS.get(field_name, (None, None))
    where = f"line type {name!r}" + (f" (file line {lt.lineno})" if lt is not None else "")
    if col is None:
        return f"{where}: {field_name} {issue.message}"
    value = item.get(field_name)
    shown = ""
    if back is not None and isinstance(value, (int, float)):
        shown = f" = {back(float(value)):g}"
    elif lt is not None and col in ("Cd", "Ca", "CaAx", "Diam", "EA", "BA", "Mass/m"):
        attr = {"Cd": "Cd", "Ca": "Ca", "CaAx": "CaAx", "Diam": "d", "EA": "EA", "BA": "BA", "Mass/m": "mass"}[col]
        shown = f" = {getattr(lt, attr):g}"
    return f"{where}: {col}{shown} gives tapm_opt's {field_name} {issue.message} (docs/moordyn.md)"


#: How the importer places the file's mooring about the vessel (:func:`import_moordyn`).
RECENTRE_CHOICES = ("auto", "no")


def _recentred(model: MoorDynModel, fair: list, lines: list[dict], p_cot: np.ndarray, vessel: Mapping[str, Any],
               recentre: str, notes: list[str]) -> tuple[list, list[dict]]:
    """The fairleads ``(point, line, NED position)`` and line tables moved so that the vessel sits
    at the field zero point (:func:`import_moordyn`, ``recentre``); unchanged with ``"no"``."""
    if recentre == "no" or not fair:
        return fair, lines
    shift, turn, why = np.zeros(2), 0.0, ""
    xy = np.array([f[:2] for _, _, f in fair], dtype=float)
    reach = float(np.max(np.hypot(xy[:, 0] - p_cot[0], xy[:, 1] - p_cot[1])))
    hull = fairlead_reach(vessel.get("length_pp", 0.0) or 0.0, vessel.get("breadth", 0.0) or 0.0)
    if not (hull > 0 and reach > hull):
        return fair, lines   # the fairleads fit the hull where they are (tapm_opt's own exports among them)
    if model.bodies:
        b = model.bodies[0]
        x, y, _, _, _, yaw = b.pose
        shift = ned_from_md(np.array([x, y, 0.0]))[:2]
        turn = -math.radians(yaw)   # MoorDyn's yaw is about z up; tapm_opt's psi about z down
        why = (f"the vessel body {b.id} is at x = {x:g} m, y = {y:g} m, yaw {yaw:g} deg in the file (line "
               f"{b.lineno}), its fairleads up to {reach:g} m from the vessel's centre of turret, beyond its hull "
               f"({hull:g} m): the mooring is moved and turned with the body so that the body sits at the field zero "
               "point with heading 0 (--recentre no keeps the file's coordinates)")
    else:
        shift = xy.mean(axis=0) - p_cot
        why = (f"the fairleads are up to {reach:g} m from the vessel's centre of turret at the file's origin, beyond "
               f"its hull ({hull:g} m): the mooring is moved by ({-shift[0]:g}, {-shift[1]:g}) m (north, east) so "
               "that their centroid is the centre of turret (--recentre no keeps the file's coordinates)")
    if not why:
        return fair, lines
    c, s_ = math.cos(-turn), math.sin(-turn)

    def move(x: float, y: float) -> tuple[float, float]:
        dx, dy = x - shift[0], y - shift[1]
        return c * dx - s_ * dy, s_ * dx + c * dy

    out_fair = []
    for (fl, ln, f) in fair:
        fx, fy = move(f[0], f[1])
        out_fair.append((fl, ln, np.array([fx, fy, f[2]])))
    out_lines = []
    for item in lines:
        ax, ay = move(item["anchor"][0], item["anchor"][1])
        out_lines.append({**item, "anchor": [_clean(ax), _clean(ay), item["anchor"][2]]})
    notes.append(why)
    return out_fair, out_lines


#: What the importer may do with the vessel scenario's riser (:func:`import_moordyn`).
RISER_CHOICES = ("auto", "keep", "adapt", "drop")
#: How the importer sets the turret (:func:`import_moordyn`).
TURRET_CHOICES = ("auto", "locked", "free")


def _imported_riser(vessel_data: Mapping[str, Any], turret: Mapping[str, Any], depth: float, old_depth: float,
                    choice: str) -> tuple[dict | None, str]:
    """The riser table of the imported scenario and its note (empty when nothing changed)."""
    rs = dict(vessel_data["riser"])
    if choice == "drop":
        return None, (f"the vessel scenario's riser (length {rs.get('length')} m) is left out (--riser drop): the "
                      "riser's angles and reliability index are not computed")
    if choice == "keep" or (choice == "auto" and old_depth == depth):
        if old_depth != depth:
            return rs, (f"the vessel scenario's riser (length {rs.get('length')} m) is kept as it is (--riser keep): "
                        f"check it against the water depth {depth:g} m of the MoorDyn file")
        return rs, ""
    hang, well = rs.get("hangoff", [0.0, 0.0]), rs.get("wellhead", [0.0, 0.0])
    horiz = math.hypot(float(well[0]) - float(hang[0]), float(well[1]) - float(hang[1]))
    vessel = vessel_data.get("vessel", {})
    old_turret = vessel_data.get("turret", {})

    def top(fairlead_depth: Any) -> float:   # as the scenario check has it
        return hangoff_depth_limit(fairlead_depth or 0.0, vessel.get("draught", 0.0) or 0.0)

    chord_old = math.hypot(horiz, old_depth - top(old_turret.get("fairlead_depth")))
    chord_new = math.hypot(horiz, depth - top(turret.get("fairlead_depth")))
    if not (chord_old > 0 and chord_new > 0):
        return None, (f"the vessel scenario's riser is left out: the MoorDyn file's water depth {depth:g} m leaves "
                      "it no water column below its hang-off")
    k = chord_new / chord_old
    length, tension = float(rs["length"]), float(rs["top_tension"])
    rs["length"] = _clean(length * k)
    rs["top_tension"] = _clean(tension * k)
    return rs, (f"the vessel scenario's riser is adapted to the water depth {depth:g} m (from {old_depth:g} m; "
                f"--riser adapt): length {length:g} -> {rs['length']:g} m and top tension {tension:.4g} -> "
                f"{rs['top_tension']:.4g} N, both x {k:.4g} (the hang-off-to-wellhead distance's ratio), the rest "
                "kept; --riser keep or drop to choose otherwise")


# --------------------------------------------------------------------------------------------
# TOML text of a scenario dictionary
# --------------------------------------------------------------------------------------------


def _toml_value(v: Any) -> str:
    """:func:`tapm_opt._io.toml_value`, refusing non-finite numbers (a scenario has none)."""
    if isinstance(v, float) and not math.isfinite(v):
        raise MoorDynError(f"cannot write the non-finite number {v!r} to TOML")
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    try:
        return toml_value(v)
    except TypeError as exc:
        raise MoorDynError(str(exc)) from None


def _table(name: str, d: Mapping[str, Any], out: list[str], header: str) -> None:
    out.append(header)
    subs = []
    for k, v in d.items():
        if isinstance(v, Mapping):
            subs.append((k, v))
        else:
            out.append(f"{toml_key(k)} = {_toml_value(v)}")
    for k, v in subs:
        out.append("")
        _table(f"{name}.{toml_key(k)}", v, out, f"[{name}.{toml_key(k)}]")


def scenario_toml(data: Mapping[str, Any], *, header: Iterable[str] = (),
                  comments: Mapping[tuple[str, int], Iterable[str]] | None = None) -> str:
    """TOML text of a scenario file dictionary (tables and arrays of tables), with ``#`` comments:
    ``header`` at the top, ``comments[(key, i)]`` above item i of array ``key``."""
    comments = comments or {}
    out = [f"# {h}" if h else "#" for h in header]
    top = [(k, v) for k, v in data.items() if not isinstance(v, Mapping)
           and not (isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v))]
    for k, v in top:
        out.append(f"{toml_key(k)} = {_toml_value(v)}")
    for k, v in data.items():
        key = toml_key(k)
        if isinstance(v, Mapping):
            out.append("")
            _table(key, v, out, f"[{key}]")
        elif isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v):
            for i, item in enumerate(v):
                out.append("")
                out += [f"# {c}" for c in comments.get((k, i), ())]
                _table(key, item, out, f"[[{key}]]")
    text = "\n".join(out) + "\n"
    if tomllib.loads(text) != _plain(data):  # pragma: no cover - writer bug
        raise MoorDynError("internal error: the TOML text does not read back as the scenario")
    return text


def _plain(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, float):
        return float(v) + 0.0
    return v
