"""Thruster-assisted mooring capability envelopes in the style of DNV-ST-0111 (``tapm capability``).

For each environment direction and each case (mooring alone; thrusters + intact mooring; each
single line broken; each single thruster failed) the largest environment of the table for which a
quasi-static equilibrium exists, and the limiting wind speed found by bisection between the
table's rows. The table is the standard's Beaufort table (:data:`BEAUFORT_TABLE`, 0-11) continued
by rows 12-15 of the same progression (:data:`EXTENSION_ROWS`, not the standard's), so that an
envelope beyond Beaufort 11 (fpso weathervaning) reports where it ends. ``losses=True`` applies
DNV-ST-0111's Level 1 thrust losses to the thrusters (:mod:`tapm_opt.design.thrust_losses`).
Method, conventions, sources and the fpso result: ``docs/capability.md``; the time-domain Level 3
is :mod:`tapm_opt.studies.capability_level3` (it uses :class:`CapabilityEnvironment` for its
environments and headings).

Equilibrium of one environment (a row, or a point between two rows)
--------------------------------------------------------------------
The mean environmental load ``tau_env`` in {B} is :func:`~tapm_opt.design.loads.mean_environmental_load`
(hull wind model, Newman mean drift, current on the hull at rest) of a sea state built from the
scenario's base sea state with :func:`dataclasses.replace`: the row's wind speed, Hs, Tp and
surface current, every direction set from the environment direction. With the dynamic allowance
``a`` (1.25, DNV-ST-0111 Level 1) a pose with turret offset ``p`` and heading ``psi`` is an
equilibrium when

    tau_moor(p, psi) + tau_T + a tau_env = 0,

* ``|p| <= safe_radius`` (the offset of the centre of turret from its field-zero-point position,
  :func:`~tapm_opt.geometry.turret_offset`);
* every remaining line's fairlead tension ``T_i <= S_C / gamma`` with the characteristic capacity
  ``S_C = 0.95 MBS`` (:data:`~tapm_opt.standards.DNV_CAPACITY_FACTOR`, as the KPIs' DNV check)
  and the DNV-OS-E301 (2008) quasi-static factor ``gamma`` (:data:`QUASI_STATIC_FACTORS`): ULS with
  the mooring intact, ALS with a line broken;
* the riser's top and bottom angles (:meth:`~tapm_opt.models.riser.RiserModel.angles`, in the
  environment's current) within the scenario's mean critical angles ``riser.critical_top_angle``
  and ``riser.critical_bottom_angle``;
* ``tau_T`` attainable: the thrust allocator (:class:`~tapm_opt.control.allocation.ThrustAllocator`
  with the scenario's forbidden sectors, failed thrusters marked with ``set_failed``) delivers it
  with a slack below :data:`SLACK_TOL` (in units of the allocator's force and moment scales), from
  rest with no rate limit binding (two calls with ``dt = 1e6 s`` after ``reset``, the second with
  the azimuths of the first). Mooring alone: ``tau_T = 0``.

Search (TAPM practice: the mooring takes what it can inside the safe region, the thrusters the
rest): the mooring load and the fairlead tensions are tabulated once per mooring case on a polar
grid of turret offsets (rings ``grid_spacing`` apart out to ``(1 + relax) safe_radius``, points
about ``grid_spacing`` apart on each ring): the tensions by one vectorised catenary solve
(:func:`~tapm_opt.models.catenary.solve`), the load by
:meth:`~tapm_opt.models.mooring.MooringModel.force_fast` at each point (the tabulated catenary,
within 1e-9 of it).
For an environment, the thrust each grid point needs is measured by the gauge of the attainable
polytope (:meth:`~tapm_opt.models.system.ThrusterSet.attainable_polytope`: ``max_k A_k tau / b_k``,
1 on its boundary); the ``candidates`` grid points that satisfy every mooring-side constraint with
the smallest gauge are handed, in that order, to the allocator, which decides. A free turret passes
only the net line force through its centre, so the table at heading 0 serves every heading (the
fairleads depend on the turret position alone); a locked turret is tabulated per heading.

Mooring alone: the static equilibrium, solved by :func:`~tapm_opt.models.statics.solve_equilibrium`
(the project's root finder) on the tabulated catenary load
(:meth:`~tapm_opt.models.mooring.MooringModel.force_fast`), then its offset, tensions
(:meth:`~tapm_opt.models.mooring.MooringModel.tensions`) and riser angles are checked. A free
turret: x and y with the heading held at the weathervane heading (where the mean load has no yaw
moment about the turret, so the turret balances yaw without thrust). A locked turret (a spread
mooring): x, y and psi together, the yaw held by the lines alone, the environmental load
re-evaluated at each heading the solver tries (the environment is fixed in {E}, its load in {B}
turns with the hull), from the field zero point's heading 0 (where the lines hold the hull at rest)
or the last equilibrium of the same direction; the heading is reported on that branch
(``psi0 + ssa(psi - psi0)``).

Heading (:func:`resolve_options`): ``heading=None`` (the default) is ``weathervane`` for a free
turret and ``fixed`` (``fixed_heading_deg``, 0: the field zero point's heading) for a locked one.
A spread-moored hull cannot turn into the weather: its heading is held by the lines (and the
thrusters), so ``weathervane`` with a locked turret is refused (:class:`CapabilityError`).

Envelope of one case and direction: the rows are walked upward from Beaufort 0 to the first that
fails; the wind speed is then bisected between the last passing and the first failing row to
``wind_tol``, with Hs, Tp and the current interpolated linearly in the wind speed. ``limit`` names
the binding constraint at the first failing environment: for mooring alone the most violated
(``offset`` also when no equilibrium exists), with thrust the one whose relaxation by ``relax``
(10 %) lowers the gauge needed most (``thrust``: the thrusters' capacity relaxed by the same
fraction helps most); ``table`` when the table's top row passes.

Failure cases (``line <id>``: ALS, the final quasi-static position after the break;
``thruster <id>``: ULS, one thruster out) hold an environment only if the intact system holds it
too (the failure happens in that environment), so intact is never below them;
``post_failure_only=True`` evaluates the system after the failure alone, which can exceed intact
(a broken leeward line). A, B are the lowest Beaufort numbers of ``intact`` within
:data:`DESIGN_SECTOR_DEG` of the design direction and over every direction; C, D the same over
the single-failure cases computed.

Size: one module on purpose — the envelope search, its Beaufort table, environments and the thrust
and mooring loads it balances are one method (``docs/capability.md``); its figures are in ``report.capability``.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._io import csv_text
from .._parallel import limit_threads, worker_threads
from ..errors import TapmError
from ..geometry import body_from_turret, ssa, turret_offset
from ..standards import DNV_CAPACITY_FACTOR, DNV_E301_QUASI_STATIC_FACTORS

__all__ = [
    "BEAUFORT_TABLE",
    "CONDITIONS",
    "CSV_COLUMNS",
    "DESIGN_SECTOR_DEG",
    "DIRECTIONS_DEG",
    "DYNAMIC_ALLOWANCE",
    "EXTENDED_TABLE",
    "EXTENSION_ROWS",
    "HEADINGS",
    "LEVELS",
    "QUASI_STATIC_FACTORS",
    "SLACK_TOL",
    "STANDARD_TOP",
    "STUDY_OPTIONS",
    "TABLES",
    "BeaufortRow",
    "CapabilityEnvironment",
    "CapabilityError",
    "CapabilityOptions",
    "CapabilityResult",
    "CaseEnvelope",
    "TableEnvironment",
    "capability",
    "case_names",
    "default_heading",
    "resolve_options",
    "table_name",
]

#: The :class:`CapabilityOptions` a study's ``[capability]`` table may set (the rest are numerical
#: settings with their defaults, or of the command line: workers, progress).
STUDY_OPTIONS = ("level", "heading", "condition", "directions_deg", "design_direction_deg", "fixed_heading_deg",
                 "sea_state", "dynamic_allowance", "consequence_class", "capacity_factor", "grid_spacing", "losses",
                 "thruster_diameter", "table")


class CapabilityError(TapmError, ValueError):
    """A capability option or scenario cannot be evaluated (the message names the field and value)."""


@dataclass(frozen=True)
class BeaufortRow:
    """One row of the DNV-ST-0111 Level 1 environment table.

    Attributes
    ----------
    number : int
        Beaufort number [-].
    wind_speed : float
        1-hour mean wind speed at 10 m [m/s].
    Hs : float
        Significant wave height [m].
    Tp : float
        Spectral peak period [s] (Beaufort 0, Hs = 0: the Beaufort 1 value, so that the JONSWAP
        spectrum is defined; no wave load either way).
    current_speed : float
        Surface current speed [m/s].
    checked : bool
        True where the row was checked against the project's standards notes (only Beaufort 8);
        the other rows are a secondary transcription (``docs/capability.md``).
    """

    number: int
    wind_speed: float
    Hs: float
    Tp: float
    current_speed: float
    checked: bool = False


#: DNV-ST-0111 (July 2021) Level 1 environment table, Beaufort 0-11 (wind speeds are the upper
#: limits of the WMO Beaufort classes). Only Beaufort 8 (20.7 m/s, 5.7 m, 10 s, 0.75 m/s) is
#: confirmed by the project's standards notes; every other row is a secondary transcription to be
#: checked against the standard (``docs/capability.md`` flags them).
BEAUFORT_TABLE: tuple[BeaufortRow, ...] = (
    BeaufortRow(0, 0.0, 0.0, 3.5, 0.0),
    BeaufortRow(1, 1.5, 0.1, 3.5, 0.25),
    BeaufortRow(2, 3.3, 0.4, 4.5, 0.50),
    BeaufortRow(3, 5.4, 0.8, 5.5, 0.75),
    BeaufortRow(4, 7.9, 1.3, 6.5, 0.75),
    BeaufortRow(5, 10.7, 2.1, 7.5, 0.75),
    BeaufortRow(6, 13.8, 3.1, 8.5, 0.75),
    BeaufortRow(7, 17.1, 4.2, 9.0, 0.75),
    BeaufortRow(8, 20.7, 5.7, 10.0, 0.75, checked=True),
    BeaufortRow(9, 24.4, 7.4, 10.5, 0.75),
    BeaufortRow(10, 28.4, 9.5, 11.5, 0.75),
    BeaufortRow(11, 32.6, 12.1, 12.0, 0.75),
)


def _extension(numbers: Sequence[int]) -> tuple[BeaufortRow, ...]:
    """Rows beyond Beaufort 11 with the table's own progression (``docs/capability.md``): the wind
    speed of the WMO relation ``V = 0.836 B^(3/2)`` at the upper limit of class B, ``B + 1/2``,
    rounded down to 0.1 m/s (which gives every wind speed of the standard's rows 1-11 exactly), Hs growing as the square
    of the wind speed from the top row (``Hs_11 (V / V_11)^2``, the wind-sea growth of a fully
    developed sea), Tp at the top row's wave steepness (``Tp_11 sqrt(Hs / Hs_11)``), the current the
    table keeps from Beaufort 3 on (0.75 m/s)."""
    top = BEAUFORT_TABLE[-1]
    out = []
    for b in numbers:
        V = math.floor(10.0 * 0.836 * (b + 0.5) ** 1.5) / 10.0
        Hs = round(top.Hs * (V / top.wind_speed) ** 2, 1)
        out.append(BeaufortRow(int(b), V, Hs, round(top.Tp * math.sqrt(Hs / top.Hs), 1), top.current_speed))
    return tuple(out)


#: Rows 12-15 beyond the standard's table (not the standard's; :func:`_extension`): 36.9, 41.4,
#: 46.1 and 51.0 m/s with Hs 15.5, 19.5, 24.2 and 29.6 m. It stops at Beaufort 15, the last row
#: whose Hs stays within the scenario schema's bound on a sea state (30 m).
EXTENSION_ROWS: tuple[BeaufortRow, ...] = _extension(range(12, 16))
#: The standard's table with the extension: the default table of :class:`CapabilityOptions`, so that
#: an envelope beyond Beaufort 11 reports where it ends instead of the table's top.
EXTENDED_TABLE: tuple[BeaufortRow, ...] = BEAUFORT_TABLE + EXTENSION_ROWS
#: The tables by name (``CapabilityOptions(table=name)``, ``tapm capability --table``).
TABLES: dict[str, tuple[BeaufortRow, ...]] = {"standard": BEAUFORT_TABLE, "extended": EXTENDED_TABLE}
#: Largest Beaufort number of the standard's table: a number above it is the extension's.
STANDARD_TOP = BEAUFORT_TABLE[-1].number

#: Dynamic allowance on the environmental load, DNV-ST-0111 Level 1.
DYNAMIC_ALLOWANCE = 1.25
#: Environment directions of DNV-ST-0111 Level 1 [deg]: 0-350 in 10 deg steps.
DIRECTIONS_DEG: tuple[float, ...] = tuple(float(d) for d in range(0, 360, 10))
#: Half-width of the sector about the design direction of the capability numbers A and C [deg].
DESIGN_SECTOR_DEG = 30.0
#: DNV-OS-E301 (October 2008) quasi-static safety factors on the line tension, by limit state and
#: consequence class (:data:`tapm_opt.standards.DNV_E301_QUASI_STATIC_FACTORS`).
QUASI_STATIC_FACTORS = DNV_E301_QUASI_STATIC_FACTORS
#: Largest allocation slack counted as "attained", as a fraction of the allocator's force scale
#: F_ref (X, Y) and moment scale F_ref L_ref (N).
SLACK_TOL = 1e-3
#: Levels, headings and conditions of :class:`CapabilityOptions`.
LEVELS = (1, 2)
HEADINGS = ("weathervane", "fixed")
CONDITIONS = ("all", "intact", "all-single-line", "thruster-failure")
#: Columns of ``capability.csv``.
CSV_COLUMNS = ("direction_deg", "case", "beaufort", "wind_speed", "limit")


# -- options ----------------------------------------------------------------------------------------

@dataclass(frozen=True, kw_only=True)
class CapabilityOptions:
    """Settings of :func:`capability` (angles in degrees at this edge, SI otherwise).

    Parameters
    ----------
    level : {1, 2}
        1: wind, waves and current collinear (DNV-ST-0111 Level 1); 2: wind and current keep the
        base sea state's directions relative to its waves (the scenario's own spreads).
    heading : {"weathervane", "fixed"} or None
        Heading of the thrust cases (None, the default: by the turret, :func:`default_heading`:
        ``weathervane`` for a free turret, ``fixed`` for a locked one; :func:`capability` resolves
        it; ``weathervane`` with a locked turret is refused): ``weathervane`` — bow into the environment (Level 1; with
        collinear loads on a port/starboard-symmetric hull the mean load then has no yaw moment
        about the turret) or the heading where the mean load has no yaw moment about the turret
        (Level 2, a stable zero as :func:`~tapm_opt.design.tables.weathervane_heading`);
        ``fixed`` — ``fixed_heading_deg``. Mooring alone: a free turret weathervanes (without
        thrust a heading cannot be held); a locked turret's heading is solved with x and y (the
        lines hold the yaw).
    condition : {"all", "intact", "all-single-line", "thruster-failure"} or "line <id>"
        ``intact``: the cases ``mooring`` and ``intact``; ``all-single-line`` adds ``line <id>``
        for every line; ``thruster-failure`` adds the worst ``thruster <id>``; ``all`` both;
        ``line <id>`` adds that line's case alone.
    directions_deg : sequence of float
        Environment directions [deg]: where the environment comes FROM, in {E}, clockwise from
        north (DNV-ST-0111 plots; the scenario's "going to" direction minus 180 deg).
    design_direction_deg : float, optional
        Centre of the sector of the numbers A and C [deg, coming from]; default the base sea
        state's wave direction (coming from).
    fixed_heading_deg : float
        Heading of ``heading="fixed"`` [deg] (default 0: the heading at the field zero point).
    sea_state : str, optional
        Base sea state (JONSWAP gamma, current profile, Level 2 spreads); default the first.
    dynamic_allowance : float
        Factor on the environmental load [-], >= 1.
    consequence_class : {1, 2}
        DNV-OS-E301 consequence class of :data:`QUASI_STATIC_FACTORS`.
    capacity_factor : float, optional
        Characteristic capacity S_C / MBS [-] in (0, 1] (default
        :data:`~tapm_opt.standards.DNV_CAPACITY_FACTOR`, 0.95; 1: the limit MBS / gamma).
    grid_spacing : float, optional
        Spacing of the offset grid [m] (default safe_radius / 25).
    wind_tol : float
        Bisection tolerance on the limiting wind speed [m/s], > 0.
    polytope_directions : int
        Support directions of the attainable polytope that ranks the candidates (>= 8).
    candidates : int
        Grid points tried with the allocator per environment (>= 1).
    relax : float
        Relaxation that names the binding constraint, and the grid's reach beyond the safe
        circle [-], in (0, 1].
    post_failure_only : bool
        False (default): a failure case holds an environment only if the intact system holds it
        too (the failure happens in that environment: ULS intact before, ALS after, the final
        quasi-static position); True: the system after the failure alone, which can exceed the
        intact envelope (a broken leeward line no longer pulls the vessel downwind, and the ALS
        factor is lower than the ULS one).
    workers : int
        Processes over the cases (1: in this process).
    seed : int
        Seed of the wave field (the drift's random frequencies).
    table : sequence of BeaufortRow, or {"extended", "standard"}
        The environment table, increasing wind speed, or its name in :data:`TABLES` (default
        :data:`EXTENDED_TABLE`: the standard's Beaufort 0-11 and the extension 12-15).
    losses : bool
        Apply DNV-ST-0111's Level 1 thrust losses to the thrusters
        (:func:`~tapm_opt.design.thrust_losses.apply_level1_losses`: the factor 0.9 on every
        thruster's thrust and the thruster-thruster interaction sectors). Default False: the
        thrusters as the scenario gives them, as the plant simulates them.
    thruster_diameter : float, optional
        One propeller diameter [m] for the interaction sectors of ``losses`` (default: each
        thruster's from its thrust, :func:`~tapm_opt.design.thrust_losses.default_diameter`).
    riser : bool
        Check the riser's angles (default True, when the scenario has a riser); False leaves them
        out (e.g. to compare with a time-domain check of the offset and tensions alone).
    tension_utilisation : float, optional
        A fraction of MBS in (0, 1] that replaces ``capacity_factor / gamma`` as every line's
        tension limit, intact and with a line broken (e.g. the scenario's
        ``limits.tension_utilisation``, the limit of the time-domain checks); default None: the
        DNV-OS-E301 quasi-static limits.
    """

    level: int = 1
    heading: str | None = None
    condition: str = "all"
    directions_deg: tuple[float, ...] = DIRECTIONS_DEG
    design_direction_deg: float | None = None
    fixed_heading_deg: float = 0.0
    sea_state: str | None = None
    dynamic_allowance: float = DYNAMIC_ALLOWANCE
    consequence_class: int = 1
    capacity_factor: float | None = None
    grid_spacing: float | None = None
    wind_tol: float = 0.1
    polytope_directions: int = 64
    candidates: int = 3
    relax: float = 0.1
    post_failure_only: bool = False
    workers: int = 1
    seed: int = 0
    table: tuple[BeaufortRow, ...] = EXTENDED_TABLE
    losses: bool = False
    thruster_diameter: float | None = None
    riser: bool = True
    tension_utilisation: float | None = None

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> CapabilityError:
            return CapabilityError(f"{name} = {getattr(self, name)!r} {why}")

        def number(name: str, lo: float | None = None, hi: float | None = None, strict: bool = False) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
                raise bad(name, "must be a finite number")
            if lo is not None and (v < lo or (strict and v == lo)):
                raise bad(name, f"must be {'>' if strict else '>='} {lo:g}")
            if hi is not None and v > hi:
                raise bad(name, f"must be <= {hi:g}")

        def whole(name: str, lo: int) -> None:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise bad(name, f"must be a whole number >= {lo}")

        if self.level not in LEVELS or isinstance(self.level, bool):
            raise bad("level", f"must be one of {', '.join(map(str, LEVELS))}")
        if self.heading is not None and self.heading not in HEADINGS:
            raise bad("heading", f"must be one of {', '.join(HEADINGS)} (or left out: by the turret)")
        if self.condition not in CONDITIONS and _single_line(self.condition) is None:
            raise bad("condition", f"must be one of {', '.join(CONDITIONS)} or 'line <id>'")
        try:
            dirs = tuple(float(d) for d in self.directions_deg)
        except (TypeError, ValueError):
            raise bad("directions_deg", "must be numbers of degrees") from None
        if not dirs or not all(math.isfinite(d) and -360.0 <= d <= 360.0 for d in dirs):
            raise bad("directions_deg", "must be one or more finite directions in [-360, 360] deg")
        if len({round(d % 360.0, 9) for d in dirs}) != len(dirs):
            raise bad("directions_deg", "must not repeat a direction")
        object.__setattr__(self, "directions_deg", dirs)
        if self.design_direction_deg is not None:
            number("design_direction_deg", -360.0, 360.0)
        number("fixed_heading_deg", -360.0, 360.0)
        number("dynamic_allowance", 1.0, 10.0)
        if self.consequence_class not in (1, 2) or isinstance(self.consequence_class, bool):
            raise bad("consequence_class", "must be 1 or 2")
        if self.capacity_factor is not None:
            number("capacity_factor", 0.0, 1.0, strict=True)
        if self.grid_spacing is not None:
            number("grid_spacing", 0.0, strict=True)
        number("wind_tol", 0.0, strict=True)
        whole("polytope_directions", 8)
        whole("candidates", 1)
        number("relax", 0.0, 1.0, strict=True)
        if not isinstance(self.post_failure_only, (bool, np.bool_)):
            raise bad("post_failure_only", "must be true or false")
        whole("workers", 1)
        whole("seed", 0)
        for name in ("losses", "riser"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise bad(name, "must be true or false")
        if self.thruster_diameter is not None:
            number("thruster_diameter", 0.0, strict=True)
        if self.tension_utilisation is not None:
            number("tension_utilisation", 0.0, 1.0, strict=True)
        if isinstance(self.table, str):
            if self.table not in TABLES:
                raise bad("table", f"must be one of {', '.join(TABLES)} or a sequence of BeaufortRow")
            object.__setattr__(self, "table", TABLES[self.table])
        rows = tuple(self.table)
        if len(rows) < 2 or not all(isinstance(r, BeaufortRow) for r in rows):
            raise bad("table", "must be two or more BeaufortRow")
        for i, r in enumerate(rows):
            vals = (r.wind_speed, r.Hs, r.Tp, r.current_speed)
            if not all(math.isfinite(v) and v >= 0 for v in vals) or r.Tp < 1.0:
                raise CapabilityError(f"table[{i}] (Beaufort {r.number}) = {r!r}: wind_speed, Hs, current_speed "
                                      "must be finite and >= 0, Tp >= 1 s")
        if any(b.wind_speed <= a.wind_speed for a, b in itertools.pairwise(rows)):
            raise bad("table", "must have strictly increasing wind speeds")
        object.__setattr__(self, "table", rows)

    def settings(self) -> dict:
        """The options as JSON-ready numbers (degrees where named ``_deg``)."""
        return {"level": self.level, "heading": self.heading, "condition": self.condition,
                "directions_deg": list(self.directions_deg), "design_direction_deg": self.design_direction_deg,
                "fixed_heading_deg": self.fixed_heading_deg, "sea_state": self.sea_state,
                "dynamic_allowance": self.dynamic_allowance, "consequence_class": self.consequence_class,
                "capacity_factor": self.capacity_factor, "grid_spacing": self.grid_spacing,
                "wind_tol": self.wind_tol, "polytope_directions": self.polytope_directions,
                "candidates": self.candidates, "relax": self.relax, "post_failure_only": bool(self.post_failure_only),
                "seed": self.seed, "table_name": table_name(self.table), "losses": bool(self.losses),
                "thruster_diameter": self.thruster_diameter, "riser": bool(self.riser),
                "tension_utilisation": self.tension_utilisation}


def default_heading(scenario: Any) -> str:
    """The default heading of :class:`CapabilityOptions` for ``scenario``: ``"weathervane"`` for a
    free turret (it turns into the weather), ``"fixed"`` for a locked turret (a spread mooring: the
    lines hold the heading; ``docs/capability.md`` "Spread moorings")."""
    return "fixed" if scenario.turret.mode == "locked" else "weathervane"


def resolve_options(scenario: Any, options: CapabilityOptions) -> CapabilityOptions:
    """``options`` with ``heading`` resolved for ``scenario`` (None: :func:`default_heading`).

    Raises
    ------
    CapabilityError
        ``heading = "weathervane"`` with a locked turret: a spread-moored hull cannot turn into the
        weather, and its lines, laid out for the field zero point's heading, do not follow it.
    """
    if options.heading is None:
        return dataclasses.replace(options, heading=default_heading(scenario))
    if options.heading == "weathervane" and scenario.turret.mode == "locked":
        raise CapabilityError(f"heading = 'weathervane' with scenario {scenario.name!r}'s turret.mode = 'locked' (a "
                              "spread mooring): the hull cannot turn into the weather, its heading is held by the "
                              "lines; use heading = 'fixed' (fixed_heading_deg, default 0) or leave heading out")
    return options


def table_name(table: Sequence[BeaufortRow]) -> str:
    """``"standard"`` or ``"extended"`` for those tables (:data:`TABLES`), else ``"custom"``."""
    rows = tuple(table)
    return next((name for name, t in TABLES.items() if t == rows), "custom")


# -- results ----------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class CaseEnvelope:
    """The capability envelope of one case over the directions.

    Attributes
    ----------
    name : str
        ``mooring``, ``intact``, ``line <id>`` or ``thruster <id>``.
    kind : str
        ``mooring``, ``intact``, ``line`` or ``thruster``.
    failed : str or None
        The broken line's or failed thruster's id.
    beaufort : ndarray of int, shape (n,)
        Largest passing Beaufort number per direction (-1: not even Beaufort 0).
    wind_speed : ndarray, shape (n,)
        Limiting wind speed [m/s] (the last passing environment of the bisection).
    limit : tuple of str
        Binding constraint per direction (module docstring).
    heading : ndarray, shape (n,)
        Heading at the limiting environment [rad].
    offset : ndarray, shape (n, 2)
        Turret offset (x, y) [m] of the equilibrium at the limiting environment (NaN if none).
    thrust : ndarray, shape (n,)
        Gauge of the thrust there on the attainable polytope [-] (0 for mooring alone).
    tension : ndarray, shape (n,)
        Largest line tension over its limit there [-].
    """

    name: str
    kind: str
    failed: str | None
    beaufort: np.ndarray
    wind_speed: np.ndarray
    limit: tuple[str, ...]
    heading: np.ndarray
    offset: np.ndarray
    thrust: np.ndarray
    tension: np.ndarray

    def as_json(self) -> dict:
        def num(v: float) -> float | None:
            return float(v) if math.isfinite(v) else None

        return {"name": self.name, "kind": self.kind, "failed": self.failed,
                "beaufort": [int(b) for b in self.beaufort], "wind_speed": [num(v) for v in self.wind_speed],
                "limit": list(self.limit), "heading_deg": [num(math.degrees(h)) for h in self.heading],
                "offset_m": [[num(x), num(y)] for x, y in self.offset],
                "thrust_utilisation": [num(v) for v in self.thrust],
                "tension_utilisation": [num(v) for v in self.tension]}


@dataclass(frozen=True, eq=False)
class CapabilityResult:
    """The answer of :func:`capability`.

    Attributes
    ----------
    scenario : str
        Scenario name.
    options : CapabilityOptions
    directions_deg : ndarray, shape (n,)
        Environment directions [deg, coming from].
    design_direction_deg : float
        Centre of the sector of A and C [deg, coming from].
    cases : tuple of CaseEnvelope
        The reported cases: ``mooring``, ``intact``, every ``line <id>`` (if computed) and the worst
        ``thruster <id>`` (if computed).
    thruster_cases : tuple of CaseEnvelope
        Every single-thruster failure computed (the worst is in ``cases``).
    numbers : dict
        ``A``, ``B`` (intact), ``C``, ``D`` (worst single failure; None when no failure case was
        computed), the cases that give C and D, and ``mooring_A``, ``mooring_B``; A, C and
        mooring_A are None when no direction lies within the design sector.
    info : dict
        Scenario-derived settings (limits, factors, base sea state, table, load models) and timing.
    """

    scenario: str
    options: CapabilityOptions
    directions_deg: np.ndarray
    design_direction_deg: float
    cases: tuple[CaseEnvelope, ...]
    thruster_cases: tuple[CaseEnvelope, ...]
    numbers: dict
    info: dict = field(default_factory=dict)

    def case(self, name: str) -> CaseEnvelope:
        """The envelope named ``name`` (reported or thruster case)."""
        for c in (*self.cases, *self.thruster_cases):
            if c.name == name:
                return c
        raise CapabilityError(f"case = {name!r} is not among {[c.name for c in self.cases]}")

    def data_files(self) -> dict[str, bytes]:
        """The computation's data files: ``capability.csv`` (:meth:`csv_text`) and
        ``capability.json`` (:meth:`as_json`); the report draws its figures from the JSON."""
        import json

        return {"capability.csv": self.csv_text().encode("utf-8"),
                "capability.json": (json.dumps(self.as_json(), indent=1, allow_nan=False) + "\n").encode("utf-8")}

    def csv_text(self) -> str:
        """``capability.csv``: one row per direction and reported case (:data:`CSV_COLUMNS`)."""
        rows = []
        for c in self.cases:
            for d, b, v, lim in zip(self.directions_deg, c.beaufort, c.wind_speed, c.limit):
                rows.append((float(d), c.name, int(b), round(float(v), 4), lim))
        return csv_text(CSV_COLUMNS, rows)

    def as_json(self) -> dict:
        """``capability.json``: the numbers A-D, the settings and every per-direction value."""
        return {"format": "tapm-capability/1", "scenario": self.scenario,
                "directions_deg": [float(d) for d in self.directions_deg],
                "design_direction_deg": self.design_direction_deg,
                "numbers": dict(self.numbers), "settings": {**self.options.settings(), **self.info},
                "cases": [c.as_json() for c in self.cases],
                "thruster_failures": [c.as_json() for c in self.thruster_cases]}


# -- the engine -------------------------------------------------------------------------------------

@dataclass
class TableEnvironment:
    """One environment of the table (a row, or a point between two rows): wind speed [m/s], Hs [m],
    Tp [s], surface current [m/s]."""

    wind_speed: float
    Hs: float
    Tp: float
    current_speed: float


@dataclass
class _Outcome:
    ok: bool
    limit: str = ""
    psi: float = math.nan
    offset: tuple[float, float] = (math.nan, math.nan)
    thrust: float = math.nan
    tension: float = math.nan
    eta: np.ndarray | None = None


@dataclass
class _Table:
    """Mooring load and constraint ratios on the offset grid at one heading."""

    tau: np.ndarray          # (npts, 3) tau_moor in {B}
    r_off: np.ndarray        # (npts,) |p| / safe radius
    r_T: np.ndarray          # (npts,) max_i T_i / T_lim,i
    worst: np.ndarray        # (npts,) index of that line
    hangoff: np.ndarray | None  # (npts, 2) riser hang-off in {E}


def _grid(radius: float, spacing: float, reach: float) -> np.ndarray:
    """Turret offsets (npts, 2) on rings ``spacing`` apart from 0 to ``reach`` with a ring at
    ``radius``; each ring has a multiple of 4 points, one at angle 0 (mirror-symmetric about both
    axes)."""
    n_in = max(2, math.ceil(radius / spacing))
    rings = list(np.linspace(0.0, radius, n_in + 1))
    r = radius
    while r < reach - 1e-9:
        r = min(r + spacing, reach)
        rings.append(r)
    pts = [np.zeros((1, 2))]
    for rk in rings[1:]:
        m = max(8, 4 * math.ceil(2.0 * math.pi * rk / spacing / 4.0))
        a = 2.0 * math.pi * np.arange(m) / m
        pts.append(np.column_stack([rk * np.cos(a), rk * np.sin(a)]))
    return np.vstack(pts)


#: Largest angle between two vertices of an azimuth's capacity polygon in :func:`_thrust_pieces`
#: [rad] (inscribed: the polygon reaches cos(2.5 deg) = 0.999 of the thrust between vertices).
_PIECE_STEP = math.radians(5.0)


def _thrust_pieces(specs: Sequence[Any], failed: str | None) -> list[list[np.ndarray]]:
    """Each working thruster's capacity as convex pieces, columns in tau = (X, Y, N): an azimuth's
    allowed arcs (the complement of its merged forbidden sectors), each split into pieces of at most
    180 deg, each the polygon of the origin and points at most :data:`_PIECE_STEP` apart on the arc
    of its thrust; a tunnel or fixed thruster's segment ``[-max_reverse, max]`` along its axis. The
    union of a thruster's pieces is what it can deliver (to the polygon's resolution)."""
    from ..geometry import merge_sectors
    from ..models.thrust import configuration_matrix

    out = []
    for t in specs:
        if t.id == failed:
            continue
        x, y = float(t.position[0]), float(t.position[1])
        if t.kind != "azimuth":
            ends = [a for a, f in ((t.angle, t.max_thrust), (t.angle + math.pi, t.max_reverse_thrust)) if f > 0]
            mags = [f for f in (t.max_thrust, t.max_reverse_thrust) if f > 0]
            cols = configuration_matrix(np.array(ends), np.full(len(ends), x), np.full(len(ends), y)) * np.array(mags)
            out.append([cols])
            continue
        starts, widths = merge_sectors(t.forbidden_sectors, t.id) if t.forbidden_sectors else ((), ())
        if starts:
            arcs = [(s0 + w0, starts[(k + 1) % len(starts)] + (2.0 * math.pi if k + 1 == len(starts) else 0.0))
                    for k, (s0, w0) in enumerate(zip(starts, widths))]
        else:
            arcs = [(0.0, 2.0 * math.pi)]
        pieces = []
        for a0, a1 in arcs:
            n_half = max(1, math.ceil((a1 - a0) / math.pi - 1e-12))
            edges = np.linspace(a0, a1, n_half + 1)
            for lo, hi in itertools.pairwise(edges):
                k = max(2, math.ceil((hi - lo) / _PIECE_STEP) + 1)
                ang = np.linspace(lo, hi, k)
                pieces.append(configuration_matrix(ang, np.full(k, x), np.full(k, y)) * t.max_thrust)
        out.append(pieces)
    return out


def _attained_in_pieces(pieces: list[list[np.ndarray]], tau: np.ndarray, tol_f: float, tol_m: float) -> bool:
    """Whether ``tau`` is a sum of one thrust per thruster, each in one of its convex pieces
    (:func:`_thrust_pieces`), to ``tol_f`` in X, Y and ``tol_m`` in N. A piece is the convex hull
    of its columns and the origin (weights >= 0 summing to at most 1). First the convex relaxation
    (each thruster anywhere in the hull of all its pieces; one LP): infeasible, no choice of pieces
    can do it; else the choice of each thruster's piece of largest weight in the relaxation, then
    every other choice, one LP each, until one is feasible."""
    import scipy.optimize

    tau = np.asarray(tau, float)
    scale = 1e-3 / np.array([max(tol_f, 1e-9), max(tol_f, 1e-9), max(tol_m, 1e-9)])
    t = tau * scale

    def lp(groups: list[list[np.ndarray]]) -> Any:
        cols = [c for g in groups for c in g]
        B = np.hstack(cols) * scale[:, None]
        A_ub = np.zeros((len(groups), B.shape[1]))
        j = 0
        for i, g in enumerate(groups):
            n = sum(c.shape[1] for c in g)
            A_ub[i, j:j + n] = 1.0
            j += n
        # the force balance relaxed by the slack tolerance: |B w - tau| <= tol (1e-3 after scaling)
        return scipy.optimize.linprog(np.zeros(B.shape[1]), A_ub=np.vstack([A_ub, B, -B]),
                                      b_ub=np.concatenate([np.ones(len(groups)), t + 1e-3, -t + 1e-3]),
                                      bounds=(0.0, None), method="highs")

    relaxed = lp(pieces)
    if relaxed.status != 0:
        return False
    best = []
    j = 0
    for g in pieces:
        w = []
        for c in g:
            w.append(float(relaxed.x[j:j + c.shape[1]].sum()))
            j += c.shape[1]
        best.append(int(np.argmax(w)))
    first = tuple(best)
    if all(len(g) == 1 for g in pieces):
        return True
    for choice in (first, *(c for c in itertools.product(*(range(len(g)) for g in pieces)) if c != first)):
        if lp([[g[k]] for g, k in zip(pieces, choice)]).status == 0:
            return True
    return False


class CapabilityEnvironment:
    """The environments of a capability computation (module docstring): the table's environment at
    a wind speed, its sea state for a direction, its mean load and the heading of each case.

    Parameters
    ----------
    scenario : Scenario
    options : CapabilityOptions
        ``table``, ``sea_state`` (the base), ``level`` (the spreads), ``heading``,
        ``fixed_heading_deg`` and ``seed`` are read.
    """

    def __init__(self, scenario: Any, options: CapabilityOptions):
        self.sc = sc = scenario
        self.opt = opt = resolve_options(scenario, options)
        try:
            self.base = sc.sea_state(opt.sea_state)
        except KeyError as exc:
            raise CapabilityError(f"sea_state = {opt.sea_state!r}: {exc.args[0]}") from None
        self.p_cot = np.asarray(sc.turret.position, float)
        # directions relative to the waves of the base sea state (Level 2 spreads)
        if opt.level == 2:
            self.rel_wind = float(ssa(self.base.wind_direction - self.base.wave_direction))
            self.rel_current = float(ssa(self.base.current_direction - self.base.wave_direction))
        else:
            self.rel_wind = self.rel_current = 0.0
        self._loads: dict = {}
        self._wv_rows: dict = {}
        self._wv_mid: dict = {}
        self.load_calls = 0

    def sea_state_from(self, wind: float, direction_deg: float) -> Any:
        """The sea state of the table at wind speed ``wind`` [m/s] with the environment coming from
        ``direction_deg`` [deg, clockwise from north]: the base sea state with the environment's
        values and directions (:meth:`env_at`, :meth:`sea_state`)."""
        return self.sea_state(self.env_at(wind), math.radians(direction_deg) + math.pi)


    # -- environment and loads -------------------------------------------------------------------
    def env_at(self, wind: float) -> TableEnvironment:
        """The environment at wind speed ``wind`` [m/s]: a table row, or Hs, Tp and current
        interpolated linearly in the wind speed between the two rows around it."""
        rows = self.opt.table
        V = [r.wind_speed for r in rows]
        if wind >= V[-1]:
            r = rows[-1]
            return TableEnvironment(r.wind_speed, r.Hs, r.Tp, r.current_speed)
        k = int(np.searchsorted(V, wind, side="right"))
        if k == 0:
            r = rows[0]
            return TableEnvironment(r.wind_speed, r.Hs, r.Tp, r.current_speed)
        r0, r1 = rows[k - 1], rows[k]
        t = (wind - r0.wind_speed) / (r1.wind_speed - r0.wind_speed)
        return TableEnvironment(float(wind), r0.Hs + t * (r1.Hs - r0.Hs), r0.Tp + t * (r1.Tp - r0.Tp),
                    r0.current_speed + t * (r1.current_speed - r0.current_speed))

    def sea_state(self, e: TableEnvironment, going_to: float) -> Any:
        """The base sea state with the environment's values and directions (waves going to
        ``going_to`` [rad]; wind and current collinear, or with the base's spreads at Level 2)."""
        return dataclasses.replace(self.base, Hs=e.Hs, Tp=e.Tp, wind_speed=e.wind_speed,
                                   current_speed=e.current_speed, wave_direction=float(ssa(going_to)),
                                   wind_direction=float(ssa(going_to + self.rel_wind)),
                                   current_direction=float(ssa(going_to + self.rel_current)))

    def load(self, e: TableEnvironment, beta_from: float, psi: float) -> np.ndarray:
        """Mean environmental load in {B} [N, N, N m] at heading ``psi`` of the environment coming
        from ``beta_from`` [rad] (:func:`~tapm_opt.design.loads.mean_environmental_load`); cached by
        the values and the direction relative to the heading (the load in {B} depends on no other
        angle)."""
        from .loads import mean_environmental_load

        rel = float(ssa(beta_from - psi))
        key = (round(e.wind_speed, 9), round(e.Hs, 9), round(e.Tp, 9), round(e.current_speed, 9), round(rel, 12))
        got = self._loads.get(key)
        if got is None:
            if e.wind_speed == 0.0 and e.Hs == 0.0 and e.current_speed == 0.0:
                got = np.zeros(3)
            else:
                ss = self.sea_state(e, rel + math.pi)   # the same relative geometry at heading 0
                got = np.asarray(mean_environmental_load(self.sc, ss, 0.0, seed=self.opt.seed).total, float)
                self.load_calls += 1
            got.flags.writeable = False
            self._loads[key] = got
        return got

    def current_E(self, e: TableEnvironment, beta_from: float) -> np.ndarray:
        """Surface current (x, y) in {E} [m/s] of the environment coming from ``beta_from``."""
        b = beta_from + math.pi + self.rel_current
        return np.array([e.current_speed * math.cos(b), e.current_speed * math.sin(b)])

    # -- headings ----------------------------------------------------------------------------------
    def _moment_about_turret(self, e: TableEnvironment, rel: float) -> tuple[float, float]:
        """(yaw moment of the mean load about the turret centre [N m], |X, Y| [N]) with the
        environment coming from ``rel`` relative to the bow."""
        tau = self.load(e, rel, 0.0)
        x, y = self.p_cot
        return float(tau[2] - (x * tau[1] - y * tau[0])), float(math.hypot(tau[0], tau[1]))

    def _weathervane_rel(self, e: TableEnvironment, guess: float | None = None) -> float:
        """Bow-relative direction the environment comes from at the weathervane heading [rad]
        (0: bow into it). Level 1: 0. Level 2: the stable zero of the yaw moment about the turret
        (a + to - sign change with the heading, as :func:`~tapm_opt.design.tables.weathervane_heading`),
        the one with the smallest horizontal load; with ``guess``, the zero within 15 deg of it if
        there is one."""
        if self.opt.level == 1:
            return 0.0
        import scipy.optimize

        def moment(psi: float) -> float:   # the heading psi with the environment from 0: rel = -psi
            return self._moment_about_turret(e, -psi)[0]

        if guess is not None:
            a, b = -guess - math.radians(15.0), -guess + math.radians(15.0)
            fa, fb = moment(a), moment(b)
            if fa > 0.0 > fb:
                return float(ssa(-scipy.optimize.brentq(moment, a, b, xtol=1e-8)))
        grid = np.linspace(-math.pi, math.pi, 37)
        vals = [moment(p) for p in grid]
        found = []
        for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:]):
            if fa > 0.0 > fb:
                p = scipy.optimize.brentq(moment, a, b, xtol=1e-8)
                found.append((self._moment_about_turret(e, -p)[1], float(ssa(-p))))
            elif fa == 0.0 and fb <= 0.0:
                found.append((self._moment_about_turret(e, -a)[1], float(ssa(-a))))
        if not found:
            return 0.0   # no yaw moment at any heading (calm): bow into the environment
        return min(found)[1]

    def weathervane(self, wind: float) -> float:
        """:meth:`_weathervane_rel` at wind speed ``wind``: at a table row from a scan over the
        headings, between rows from the heading interpolated linearly in the wind speed (Level 2;
        cached)."""
        if self.opt.level == 1:
            return 0.0
        rows = self.opt.table
        V = [r.wind_speed for r in rows]

        def at_row(k: int) -> float:
            if k not in self._wv_rows:
                self._wv_rows[k] = self._weathervane_rel(self.env_at(V[k]))
            return self._wv_rows[k]

        if wind >= V[-1]:
            return at_row(len(V) - 1)
        k = int(np.searchsorted(V, wind, side="right"))
        if k == 0 or wind == V[k - 1]:
            return at_row(max(k - 1, 0))
        key = round(float(wind), 9)
        if key not in self._wv_mid:
            h0, h1 = at_row(k - 1), at_row(k)
            t = (wind - V[k - 1]) / (V[k] - V[k - 1])
            self._wv_mid[key] = self._weathervane_rel(self.env_at(wind), float(ssa(h0 + t * float(ssa(h1 - h0)))))
        return self._wv_mid[key]

    def heading(self, kind: str, beta_from: float, wind: float) -> float:
        """Heading [rad] of case ``kind`` with the environment coming from ``beta_from`` [rad] at
        wind speed ``wind`` [m/s]: the fixed heading for a thrust case with ``heading="fixed"``;
        mooring alone with a locked turret: 0, the field zero point's heading (where the solve of
        x, y and psi starts); else the weathervane heading (mooring alone with a free turret always
        weathervanes)."""
        if kind == "mooring" and self.sc.turret.mode == "locked":
            return 0.0
        if kind != "mooring" and self.opt.heading == "fixed":
            return math.radians(self.opt.fixed_heading_deg)
        return float(ssa(beta_from - self.weathervane(wind)))

class _Engine(CapabilityEnvironment):
    """Everything one process needs to evaluate cases (built once per process)."""

    def __init__(self, scenario: Any, options: CapabilityOptions):
        from ..models.mooring import MooringModel
        from ..models.riser import RiserModel
        from ..models.system import ThrusterSet
        from .thrust_losses import ThrustLossError, apply_level1_losses

        super().__init__(scenario, options)
        sc, opt = self.sc, self.opt
        lim = sc.limits
        if lim.safe_radius is None:
            raise CapabilityError(f"scenario {sc.name!r}: limits.safe_radius = None: the capability needs the safe "
                                  "circle (set [limits] safe_radius)")
        self.R = float(lim.safe_radius)
        #: The thrusters as the capability counts them (with the Level 1 losses when asked).
        self.sc_thr = sc
        self.losses = None
        if opt.losses and sc.thrusters:
            try:
                self.sc_thr, self.losses = apply_level1_losses(sc, diameter=opt.thruster_diameter)
            except ThrustLossError as exc:
                raise CapabilityError(f"losses: {exc}") from None
        self.spacing = float(opt.grid_spacing) if opt.grid_spacing is not None else self.R / 25.0
        self.reach = (1.0 + opt.relax) * self.R
        self.P = _grid(self.R, self.spacing, self.reach)
        self.free = sc.turret.mode == "free"
        self.a = float(opt.dynamic_allowance)
        cf = DNV_CAPACITY_FACTOR if opt.capacity_factor is None else float(opt.capacity_factor)
        self.capacity_factor = cf
        cc = int(opt.consequence_class)
        self.gamma = {"ULS": QUASI_STATIC_FACTORS[("ULS", cc)], "ALS": QUASI_STATIC_FACTORS[("ALS", cc)]}
        self.intact = MooringModel.from_scenario(sc)
        self.thrusters = ThrusterSet.from_scenario(self.sc_thr)
        self.riser = None
        if sc.riser is not None and opt.riser:
            self.riser = RiserModel.from_scenario(sc, self.base)
            self.theta_lim = (float(sc.riser.critical_top_angle), float(sc.riser.critical_bottom_angle))
            co = self.riser.coefficients
            self.c_riser = (co["c_t"], co["c_b"])
        self._tables: dict = {}
        self._moor: dict = {}
        self._thr: dict = {}
        self._gauge_key: tuple | None = None
        self._gauge = np.zeros((0, 0))
        self.alloc_calls = 0
        self.exact_calls = 0
        self.evaluations = 0

    # -- mooring ----------------------------------------------------------------------------------
    def mooring(self, broken: str | None) -> tuple[Any, np.ndarray]:
        """(MooringModel, tension limits (n,) [N]) of the intact mooring or with ``broken`` out."""
        if broken not in self._moor:
            m = self.intact if broken is None else self.intact.without([broken])
            state = "ULS" if broken is None else "ALS"
            frac = (self.capacity_factor / self.gamma[state] if self.opt.tension_utilisation is None
                    else float(self.opt.tension_utilisation))
            self._moor[broken] = (m, frac * np.asarray(m.MBS, float))
        return self._moor[broken]

    def table(self, broken: str | None, psi: float) -> _Table:
        """The mooring on the offset grid at heading ``psi`` (free turret: computed once at
        heading 0, the {E} force rotated into {B}; locked: per heading)."""

        model, Tlim = self.mooring(broken)
        key0 = ("grid", broken, 0.0 if self.free else round(psi, 12))
        base = self._tables.get(key0)
        if base is None:
            psi0 = 0.0 if self.free else psi
            bx, by = body_from_turret(self.P.T, psi0, self.p_cot)
            etas = np.column_stack([bx, by, np.full(len(bx), psi0)])
            XF = np.stack([model.spans(e)[2] for e in etas])
            sol = model.solve_xf(XF)
            tau = np.stack([model.force_fast(e) for e in etas])   # the tabulated catenary (within 1e-9)
            ratio = sol.TF / Tlim[None, :]
            base = (tau, ratio.max(axis=1), ratio.argmax(axis=1))
            self._tables[key0] = base
        tau0, r_T, worst = base
        key = ("heading", broken, round(psi, 12))
        tab = self._tables.get(key)
        if tab is None:
            if self.free and psi != 0.0:
                # the same {E} force at the turret centre, in {B} at heading psi, and its moment about
                # the body origin: N = x_cot Y - y_cot X (the free turret of MooringModel.tau_from_forces)
                c, s = math.cos(psi), math.sin(psi)
                X = c * tau0[:, 0] + s * tau0[:, 1]
                Y = -s * tau0[:, 0] + c * tau0[:, 1]
                tau = np.column_stack([X, Y, self.p_cot[0] * Y - self.p_cot[1] * X])
            else:
                tau = tau0
            hang = None
            if self.riser is not None:
                bx, by = body_from_turret(self.P.T, psi, self.p_cot)
                hang = self.riser.hangoff_E(np.column_stack([bx, by, np.full(len(bx), psi)]))
            tab = _Table(tau=tau, r_off=np.hypot(self.P[:, 0], self.P[:, 1]) / self.R, r_T=r_T, worst=worst,
                         hangoff=hang)
            if len(self._tables) > 400:
                self._tables = {k: v for k, v in self._tables.items() if k[0] == "grid"}
            self._tables[key] = tab
        return tab

    def riser_ratios(self, hangoff: np.ndarray, v_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """|theta_top| / critical top angle and |theta_bottom| / critical bottom angle at hang-off
        positions (npts, 2) in {E}: :meth:`RiserModel.angles` at the first point, the rest by the
        model's exact affine map (``coefficients`` c_t, c_b)."""
        if self.riser is None:
            z = np.zeros(len(hangoff))
            return z, z
        t0, b0 = self.riser.angles(hangoff[0], v_c)
        d = hangoff - hangoff[0]
        top = np.hypot(t0[0] + self.c_riser[0] * d[:, 0], t0[1] + self.c_riser[0] * d[:, 1])
        bot = np.hypot(b0[0] + self.c_riser[1] * d[:, 0], b0[1] + self.c_riser[1] * d[:, 1])
        return top / self.theta_lim[0], bot / self.theta_lim[1]

    # -- thrusters ---------------------------------------------------------------------------------
    def thrust(self, failed: str | None) -> tuple[Any, np.ndarray]:
        """(allocator, ``(A / b)^T`` (3, m) of the attainable polytope) with ``failed`` out."""
        if failed not in self._thr:
            from ..control.allocation import ThrustAllocator

            if not self.sc.thrusters:
                raise CapabilityError(f"scenario {self.sc.name!r} has no thrusters: only the case 'mooring' can be "
                                      "computed")
            ts = self.thrusters if failed is None else self.thrusters.without([failed])
            try:
                A, b = ts.attainable_polytope(int(self.opt.polytope_directions))
            except TapmError as exc:
                raise CapabilityError(f"thrusters with {failed!r} failed: {exc}") from None
            specs = self.sc_thr.thrusters
            alloc = ThrustAllocator(specs, dt=1.0e6)
            if failed is not None:
                alloc.set_failed(failed)
            pieces = _thrust_pieces(specs, failed) if any(t.forbidden_sectors for t in specs) else None
            # the gauge max_k A_k tau / b_k as one product: tau @ At
            self._thr[failed] = (alloc, np.ascontiguousarray((np.asarray(A, float) / np.asarray(b, float)[:, None]).T),
                                 pieces)
        return self._thr[failed][:2]

    def attained(self, failed: str | None, tau: np.ndarray) -> bool:
        """Whether the thrusters (``failed`` out) deliver ``tau``: the allocator from rest (slack
        within :data:`SLACK_TOL`); with forbidden sectors, failing that, the exact check of
        :func:`_attained_in_pieces` (the allocator, linearised about its start for a control loop,
        keeps an azimuth on the allowed arc it starts on and inside a narrow arc's inscribed
        rectangle, so it can miss what the thrusters deliver)."""
        alloc, _, pieces = self._thr[failed]
        self.alloc_calls += 2
        alloc.reset()
        alloc.allocate(tau)
        r = alloc.allocate(tau)
        if not r.fallback:
            sl = np.abs(np.asarray(r.slack, float))
            if (sl[0] <= SLACK_TOL * alloc.F_ref and sl[1] <= SLACK_TOL * alloc.F_ref
                    and sl[2] <= SLACK_TOL * alloc.F_ref * alloc.L_ref):
                return True
        if pieces is None:
            return False
        self.exact_calls += 1
        return _attained_in_pieces(pieces, tau, SLACK_TOL * alloc.F_ref, SLACK_TOL * alloc.F_ref * alloc.L_ref)

    # -- one environment ---------------------------------------------------------------------------
    def evaluate_thrust(self, broken: str | None, failed: str | None, e: TableEnvironment, beta_from: float, psi: float,
                        *, diagnose: bool = False) -> _Outcome:
        """Whether an equilibrium with thrust exists (module docstring); with ``diagnose``, the
        binding constraint of a failure."""
        _, At = self.thrust(failed)
        tab = self.table(broken, psi)
        tau_env = self.load(e, beta_from, psi)
        key = (broken, failed, round(psi, 12))
        if self._gauge_key != key:      # -(tau_moor @ At) of every grid point, for the last heading
            self._gauge_key, self._gauge = key, -(tab.tau @ At)
        g = (self._gauge - self.a * (tau_env @ At)[None, :]).max(axis=1)
        r_top, r_bot = (self.riser_ratios(tab.hangoff, self.current_E(e, beta_from)) if self.riser is not None
                        else (np.zeros(len(g)), np.zeros(len(g))))
        feas = (tab.r_off <= 1.0) & (tab.r_T <= 1.0) & (r_top <= 1.0) & (r_bot <= 1.0)
        idx = np.flatnonzero(feas)
        if idx.size:
            K = min(int(self.opt.candidates), idx.size)
            best = idx[np.argpartition(g[idx], K - 1)[:K]] if idx.size > K else idx
            order = best[np.argsort(g[best], kind="stable")]
            for j in order:
                if self.attained(failed, -(tab.tau[j] + self.a * tau_env)):
                    return _Outcome(True, psi=psi, offset=(float(self.P[j, 0]), float(self.P[j, 1])),
                                    thrust=float(g[j]), tension=float(tab.r_T[j]))
        if not diagnose:
            return _Outcome(False, psi=psi)
        # binding constraint: the relaxation (by opt.relax) that lowers the gauge needed most
        rx = 1.0 + self.opt.relax
        base_g = float(g[idx].min()) if idx.size else math.inf
        trials = {"thrust": base_g / rx}
        masks = {"offset": (tab.r_off <= rx) & (tab.r_T <= 1.0) & (r_top <= 1.0) & (r_bot <= 1.0),
                 "tension": (tab.r_off <= 1.0) & (tab.r_T <= rx) & (r_top <= 1.0) & (r_bot <= 1.0)}
        if self.riser is not None:
            masks["riser top"] = (tab.r_off <= 1.0) & (tab.r_T <= 1.0) & (r_top <= rx) & (r_bot <= 1.0)
            masks["riser bottom"] = (tab.r_off <= 1.0) & (tab.r_T <= 1.0) & (r_top <= 1.0) & (r_bot <= rx)
        at = {}
        for name, m in masks.items():
            if m.any():
                j = int(np.flatnonzero(m)[np.argmin(g[m])])
                trials[name], at[name] = float(g[j]), j
            else:
                trials[name] = math.inf
        name = min(trials, key=lambda k: trials[k])
        if not math.isfinite(trials[name]):
            name = "offset"
        if name == "tension" and "tension" in at:
            model, _ = self.mooring(broken)
            name = f"tension {model.line_ids[int(tab.worst[at['tension']])]}"
        return _Outcome(False, limit=name, psi=psi)

    def evaluate_mooring(self, e: TableEnvironment, beta_from: float, psi: float, guess: np.ndarray | None, *,
                         diagnose: bool = False) -> _Outcome:
        """Whether the intact mooring alone holds the environment (module docstring)."""
        from ..models.statics import solve_equilibrium

        model, _ = self.mooring(None)
        target = self.a * self.load(e, beta_from, psi)
        if not self.free:
            return self._evaluate_spread(e, beta_from, psi, target, guess, diagnose=diagnose)
        if guess is None:   # the grid point whose mooring load balances best
            tab = self.table(None, psi)
            j = int(np.argmin(np.hypot(*(tab.tau[:, :2] + target[None, :2]).T)))
            bx, by = body_from_turret(self.P[j], psi, self.p_cot)
            guess = np.array([bx, by, psi])
        n = 2
        scale = max(float(np.max(np.abs(target[:n]))), 1.0e3)
        h = 1e-3

        def pose(x: np.ndarray) -> np.ndarray:
            return np.r_[x, psi] if n == 2 else np.asarray(x, float)

        def residual(x: np.ndarray, s: float) -> np.ndarray:
            return (model.force_fast(pose(x))[:n] + s * target[:n]) / scale

        def jacobian(x: np.ndarray, s: float) -> np.ndarray:
            J = np.empty((n, n))
            for k in range(n):
                dx = np.zeros(n)
                dx[k] = h
                J[:, k] = (model.force_fast(pose(x + dx))[:n] - model.force_fast(pose(x - dx))[:n]) / (2 * h * scale)
            return J

        try:
            x = solve_equilibrium(residual, jacobian, np.asarray(guess, float)[:n], tol=1e-9)
        except TapmError:
            return _Outcome(False, limit="offset", psi=psi)
        return self._check_mooring(e, beta_from, pose(x))

    def _evaluate_spread(self, e: TableEnvironment, beta_from: float, psi0: float, target: np.ndarray,
                         guess: np.ndarray | None, *, diagnose: bool = False) -> _Outcome:
        """Mooring alone with a locked turret: the root of ``tau_moor(eta) + a tau_env(psi) = 0`` in
        x, y and psi (module docstring), from ``guess`` (the last equilibrium) or the grid point at
        heading ``psi0`` whose mooring load balances ``target`` (the scaled load at ``psi0``) best."""
        from ..models.statics import solve_equilibrium

        model, _ = self.mooring(None)
        if guess is None:
            tab = self.table(None, psi0)
            j = int(np.argmin(np.hypot(*(tab.tau[:, :2] + target[None, :2]).T)))
            bx, by = body_from_turret(self.P[j], psi0, self.p_cot)
            guess = np.array([bx, by, psi0])
        start = float(guess[2])
        # forces scaled by the load (at least 1 kN), the yaw moment by it times the mooring's reach
        arm = max(float(np.max(np.hypot(*np.asarray(model.fairleads(np.zeros(3)), float)))), 1.0)
        f_scale = max(float(np.max(np.abs(target[:2]))), float(abs(target[2])) / arm, 1.0e3)
        scale = np.array([f_scale, f_scale, f_scale * arm])
        h = np.array([1e-3, 1e-3, 1e-5])

        def residual(x: np.ndarray, s: float) -> np.ndarray:
            return (model.force_fast(x) + s * self.a * self.load(e, beta_from, float(x[2]))) / scale

        def jacobian(x: np.ndarray, s: float) -> np.ndarray:
            J = np.empty((3, 3))
            for k in range(3):
                dx = np.zeros(3)
                dx[k] = h[k]
                J[:, k] = (residual(x + dx, s) - residual(x - dx, s)) / (2.0 * h[k])
            return J

        try:
            x = solve_equilibrium(residual, jacobian, np.asarray(guess, float), tol=1e-9)
        except TapmError:
            return _Outcome(False, limit="offset", psi=start)
        eta = np.array([x[0], x[1], start + float(ssa(x[2] - start))])
        return self._check_mooring(e, beta_from, eta)

    def _check_mooring(self, e: TableEnvironment, beta_from: float, eta: np.ndarray) -> _Outcome:
        """Offset, tensions and riser angles of the mooring-alone equilibrium ``eta``."""
        model, Tlim = self.mooring(None)
        p = np.array(turret_offset(eta, self.p_cot), float)
        r_off = float(np.hypot(*p)) / self.R
        if r_off > 2.0:   # far outside the safe circle: the tensions are not worth computing
            return _Outcome(False, limit="offset", psi=float(eta[2]), eta=eta)
        ratio = np.asarray(model.tensions(eta), float) / Tlim
        ratios = {"offset": r_off, f"tension {model.line_ids[int(np.argmax(ratio))]}": float(ratio.max())}
        if self.riser is not None:
            top, bot = self.riser_ratios(self.riser.hangoff_E(eta)[None, :], self.current_E(e, beta_from))
            ratios["riser top"], ratios["riser bottom"] = float(top[0]), float(bot[0])
        ok = all(v <= 1.0 for v in ratios.values())
        worst = max(ratios, key=lambda k: ratios[k])
        return _Outcome(ok, limit="" if ok else worst, psi=float(eta[2]), offset=(float(p[0]), float(p[1])),
                        thrust=0.0, tension=float(ratio.max()), eta=eta)

    # -- one case ------------------------------------------------------------------------------------
    def envelope(self, kind: str, failed: str | None,
                 ceiling: tuple[Sequence[float], Sequence[str]] | None = None) -> CaseEnvelope:
        """The envelope of one case over every direction (module docstring).

        ``ceiling``: the intact envelope (limiting wind speeds, limits) for a failure case held
        before and after the failure: an environment above the intact limit fails with the intact
        case's limit.
        """
        broken = failed if kind == "line" else None
        thr_failed = failed if kind == "thruster" else None
        rows = self.opt.table
        n = len(self.opt.directions_deg)
        bf = np.full(n, -1, dtype=int)
        wind = np.zeros(n)
        limits: list[str] = []
        heading = np.full(n, math.nan)
        offset = np.full((n, 2), math.nan)
        thrust = np.full(n, math.nan)
        tension = np.full(n, math.nan)
        top = rows[-1].wind_speed
        for i, d in enumerate(self.opt.directions_deg):
            beta = math.radians(d)
            guess: list = [None]
            cap = math.inf if ceiling is None or float(ceiling[0][i]) >= top else float(ceiling[0][i])

            def ev(V: float, diagnose: bool = False, cap: float = cap, i: int = i, beta: float = beta,
                   guess: list = guess) -> _Outcome:
                if V > cap + 1e-12:        # the intact system does not hold it before the failure
                    return _Outcome(False, limit=str(ceiling[1][i]))
                e = self.env_at(V)
                psi = self.heading(kind, beta, V)
                self.evaluations += 1
                if kind == "mooring":
                    out = self.evaluate_mooring(e, beta, psi, guess[0], diagnose=diagnose)
                    if out.ok and out.eta is not None:
                        guess[0] = out.eta
                    return out
                return self.evaluate_thrust(broken, thr_failed, e, beta, psi, diagnose=diagnose)

            last: _Outcome | None = None
            fail_k = None
            for k, r in enumerate(rows):
                out = ev(r.wind_speed)
                if not out.ok:
                    fail_k = k
                    break
                last = out
                bf[i], wind[i] = r.number, r.wind_speed
            if fail_k is None:
                lim = "table"
            elif fail_k == 0:
                lim = ev(rows[0].wind_speed, diagnose=True).limit
            else:
                lo, hi = rows[fail_k - 1].wind_speed, rows[fail_k].wind_speed
                if hi > cap >= lo:          # the intact limit lies in this interval: start there
                    out = ev(cap)
                    if out.ok:
                        lo, last = cap, out
                        hi = min(hi, cap + self.opt.wind_tol)
                    else:
                        hi = cap
                while hi - lo > self.opt.wind_tol:
                    mid = 0.5 * (lo + hi)
                    out = ev(mid)
                    if out.ok:
                        lo, last = mid, out
                    else:
                        hi = mid
                wind[i] = lo
                lim = ev(hi, diagnose=True).limit
            limits.append(lim or "offset")
            if last is not None:
                heading[i], offset[i], thrust[i], tension[i] = last.psi, last.offset, last.thrust, last.tension
        name = {"mooring": "mooring", "intact": "intact"}.get(kind, f"{kind} {failed}")
        return CaseEnvelope(name=name, kind=kind, failed=failed, beaufort=bf, wind_speed=wind, limit=tuple(limits),
                            heading=heading, offset=offset, thrust=thrust, tension=tension)


# -- driver -----------------------------------------------------------------------------------------

_WORKER: dict = {}


def _worker_init(scenario: Any, options: CapabilityOptions, threads: int) -> None:
    limit_threads(threads)   # its share of the cores (tapm_opt._parallel)
    _WORKER["engine"] = _Engine(scenario, options)


def _worker_case(spec: tuple[str, str | None], ceiling: tuple | None) -> CaseEnvelope:
    return _WORKER["engine"].envelope(*spec, ceiling=ceiling)


def _single_line(condition: Any) -> str | None:
    """The line id of a condition ``"line <id>"``, else None."""
    if isinstance(condition, str) and condition.startswith("line ") and condition[5:].strip():
        return condition[5:].strip()
    return None


def case_names(scenario: Any, condition: str) -> list[tuple[str, str | None]]:
    """The cases ``(kind, failed id)`` of a condition: mooring and intact, then every line
    (``all-single-line``, ``all``) or the one line of ``line <id>``, then every thruster
    (``thruster-failure``, ``all``)."""
    one = _single_line(condition)
    if condition not in CONDITIONS and one is None:
        raise CapabilityError(f"condition = {condition!r} must be one of {', '.join(CONDITIONS)} or 'line <id>'")
    out: list[tuple[str, str | None]] = [("mooring", None), ("intact", None)]
    if one is not None:
        ids = [ln.id for ln in scenario.lines]
        if one not in ids:
            raise CapabilityError(f"condition = {condition!r}: {one!r} is not a line of scenario {scenario.name!r}; "
                                  f"lines are {ids}")
        if len(ids) < 2:
            raise CapabilityError(f"condition = {condition!r}: scenario {scenario.name!r} has 1 line; a line "
                                  "broken leaves no mooring")
        return out + [("line", one)]
    if condition in ("all", "all-single-line"):
        if len(scenario.lines) < 2:
            raise CapabilityError(f"condition = {condition!r}: scenario {scenario.name!r} has "
                                  f"{len(scenario.lines)} line; a line broken leaves no mooring")
        out += [("line", ln.id) for ln in scenario.lines]
    if condition in ("all", "thruster-failure"):
        if len(scenario.thrusters) < 2:
            raise CapabilityError(f"condition = {condition!r}: scenario {scenario.name!r} has "
                                  f"{len(scenario.thrusters)} thruster; a failure leaves none")
        out += [("thruster", t.id) for t in scenario.thrusters]
    return out


def _sector_min(env: CaseEnvelope, dirs: np.ndarray, centre: float | None) -> int | None:
    """Lowest Beaufort number over the directions within ``DESIGN_SECTOR_DEG`` of ``centre`` (all
    directions for None); None when no direction lies in the sector."""
    if centre is None:
        sel = np.ones(len(dirs), bool)
    else:
        sel = np.abs(np.degrees(ssa(np.radians(dirs - centre)))) <= DESIGN_SECTOR_DEG + 1e-9
    return int(env.beaufort[sel].min()) if sel.any() else None


def _worst(cases: Sequence[CaseEnvelope]) -> CaseEnvelope:
    """The lowest envelope: lowest limiting wind speed over the directions, then lowest mean, then
    (envelopes that tie, e.g. all at the table's top) the highest mean thrust gauge at the limit."""
    def key(c: CaseEnvelope) -> tuple[float, float, float]:
        t = c.thrust[np.isfinite(c.thrust)]
        return float(c.wind_speed.min()), round(float(c.wind_speed.mean()), 9), -float(t.mean()) if t.size else 0.0

    return min(cases, key=key)


def capability(scenario: Any, options: CapabilityOptions | Mapping[str, Any] | None = None,
               *, progress: Callable[[str], None] | None = None, **kw: Any) -> CapabilityResult:
    """Capability envelopes of ``scenario`` (module docstring).

    Parameters
    ----------
    scenario : Scenario
    options : CapabilityOptions or mapping, optional
        Settings; keywords override (``capability(sc, level=2, directions_deg=(0, 90))``).
    progress : callable, optional
        Called with each case's name when it is done.

    Returns
    -------
    CapabilityResult

    Raises
    ------
    CapabilityError
        A bad option, a scenario without a safe radius, thrusters or the lines the condition
        needs.
    """
    t0 = time.perf_counter()
    if isinstance(options, CapabilityOptions):
        opt = dataclasses.replace(options, **kw) if kw else options
    else:
        given = dict(options or {})
        unknown = sorted((set(given) | set(kw)) - {f.name for f in dataclasses.fields(CapabilityOptions)})
        if unknown:
            raise CapabilityError(f"unknown option(s) {unknown}; options are "
                                  f"{[f.name for f in dataclasses.fields(CapabilityOptions)]}")
        opt = CapabilityOptions(**{**given, **kw})
    opt = resolve_options(scenario, opt)     # the heading by the turret (reported and stamped resolved)
    specs = case_names(scenario, opt.condition)
    engine = _Engine(scenario, opt)          # checks the scenario before any work (and serves workers=1)
    if not scenario.thrusters:   # every condition has the case "intact" (thrusters + mooring)
        raise CapabilityError(f"scenario {scenario.name!r} has no thrusters: only the case 'mooring' can be computed")
    results: dict[tuple[str, str | None], CaseEnvelope] = {}
    first = [s for s in specs if s[0] in ("intact", "mooring")]
    failures = [s for s in specs if s[0] in ("line", "thruster")]

    def ceiling() -> tuple | None:
        if opt.post_failure_only:
            return None
        env = results[("intact", None)]
        return (tuple(float(v) for v in env.wind_speed), env.limit)

    def done(spec: tuple[str, str | None], env: CaseEnvelope) -> None:
        results[spec] = env
        if progress is not None:
            progress(env.name)

    if opt.workers > 1 and len(specs) > 1:
        import concurrent.futures as cf
        import multiprocessing as mp

        ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
        n_workers = min(opt.workers, len(specs))
        with cf.ProcessPoolExecutor(max_workers=n_workers, mp_context=ctx, initializer=_worker_init,
                                    initargs=(scenario, opt, worker_threads(n_workers))) as pool:
            # intact first: the failure cases need its envelope; mooring alone meanwhile
            futs = {pool.submit(_worker_case, s, None): s for s in sorted(first, key=lambda s: s[0] != "intact")}
            while futs:
                fin, _ = cf.wait(futs, return_when=cf.FIRST_COMPLETED)
                for fut in fin:
                    spec = futs.pop(fut)
                    done(spec, fut.result())
                    if spec[0] == "intact":
                        cap = ceiling()
                        futs.update({pool.submit(_worker_case, s, cap): s for s in failures})
    else:
        for s in first:
            done(s, engine.envelope(*s))
        cap = ceiling() if failures else None
        for s in failures:
            done(s, engine.envelope(*s, ceiling=cap))
    ordered = [results[s] for s in specs]
    mooring = ordered[0]
    intact = ordered[1]
    lines = [c for c in ordered if c.kind == "line"]
    thr = [c for c in ordered if c.kind == "thruster"]
    reported = [mooring, intact, *lines] + ([_worst(thr)] if thr else [])
    dirs = np.asarray(opt.directions_deg, float)
    if opt.design_direction_deg is not None:
        design = float(opt.design_direction_deg) % 360.0
    else:
        design = math.degrees(float(engine.base.wave_direction) + math.pi) % 360.0
    design = round(design, 9) % 360.0
    numbers: dict[str, Any] = {"A": _sector_min(intact, dirs, design), "B": _sector_min(intact, dirs, None),
                               "mooring_A": _sector_min(mooring, dirs, design),
                               "mooring_B": _sector_min(mooring, dirs, None),
                               "C": None, "D": None, "C_case": None, "D_case": None}
    fails = lines + thr
    if fails:
        cs = [(v, c.name) for c in fails if (v := _sector_min(c, dirs, design)) is not None]
        ds = [(_sector_min(c, dirs, None), c.name) for c in fails]
        if cs:
            numbers["C"], numbers["C_case"] = min(cs, key=lambda t: t[0])
        numbers["D"], numbers["D_case"] = min(ds, key=lambda t: t[0])
    sc = scenario
    info = {
        "direction_convention": "environment coming from, in {E}, clockwise from north (going-to direction - 180 deg)",
        "design_sector_deg": DESIGN_SECTOR_DEG,
        "safe_radius_m": engine.R,
        "grid_spacing_m": engine.spacing,
        "grid_points": len(engine.P),
        "tension_limit": ({"capacity_factor": engine.capacity_factor, "gamma_ULS": engine.gamma["ULS"],
                           "gamma_ALS": engine.gamma["ALS"], "standard": "DNV-OS-E301 (October 2008), quasi-static"}
                          if opt.tension_utilisation is None else
                          {"capacity_factor": float(opt.tension_utilisation), "gamma_ULS": 1.0, "gamma_ALS": 1.0,
                           "standard": "tension_utilisation x MBS (given)"}),
        "riser_limits_deg": (None if sc.riser is None or not opt.riser else
                             [math.degrees(sc.riser.critical_top_angle), math.degrees(sc.riser.critical_bottom_angle)]),
        "thrust_losses": None if engine.losses is None else engine.losses.as_json(),
        "base_sea_state": engine.base.id,
        "spreads_deg": [math.degrees(engine.rel_wind), math.degrees(engine.rel_current)],
        "table": [dataclasses.asdict(r) for r in opt.table],
        "loads": "tapm_opt.design.loads.mean_environmental_load: hull wind model (WindParams c_x 0.8, c_y 0.9, "
                 "c_n 0.08, Fossen 2011 §8.1, the scenario's wind areas), Newman mean drift (wall-sided body, "
                 "Faltinsen 1990 ch. 5, WaveParams drift_yaw 0.05), current on the hull at rest (the vessel's "
                 "linear and quadratic damping)",
        "worst_thruster": _worst(thr).failed if thr else None,
        "elapsed_s": time.perf_counter() - t0,
        "workers": int(opt.workers),
    }
    if opt.workers == 1:   # counts of this process (the bench's reference workloads)
        info["counts"] = {"environments": engine.evaluations, "load_calls": engine.load_calls,
                          "allocations": engine.alloc_calls}
    return CapabilityResult(scenario=str(sc.name), options=opt, directions_deg=dirs, design_direction_deg=design,
                            cases=tuple(reported), thruster_cases=tuple(thr), numbers=numbers, info=info)
