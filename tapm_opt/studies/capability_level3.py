"""Capability in the time domain with the controller in the loop (DNV-ST-0111 Level 3 style).

For each environment direction, the strongest row of the capability table
(:data:`~tapm_opt.design.capability.EXTENDED_TABLE` by default, the one Level 1 uses) in which the
closed loop on the FEM plant (:class:`~tapm_opt.plant.simulator.Plant`) with the chosen controller
(a kind of the registry: ``pid``, ``lmpc``, ``mpc``) keeps, over a run of stated length after a
warm-up,

* the turret inside the safe circle: the largest low-frequency turret offset (the KPI
  ``offset_max``, :func:`~tapm_opt.geometry.turret_offset`) at most ``limits.safe_radius``;
* every line's fairlead tension at most its allowed tension: the largest FEM fairlead tension over
  MBS (the KPI ``util_max[<line>]``) at most ``limits.tension_utilisation`` (or the option's);
* the heading within ``heading_tolerance`` of its setpoint (the KPI ``heading_error_max``; a
  vessel that cannot hold its heading has lost position control, and a heading that yields to the
  weather carries another load than the one Level 1 balances);
* no line broken (an overload break is a failure whenever it happens, warm-up included) and the
  simulation sound (a diverged run fails);
* with ``riser=True`` also the riser's largest top and bottom angles within their mean critical
  angles (as Level 1 checks them).

Each run: the row's environment from the direction (wind, waves and current collinear, as Level
1; the base sea state's JONSWAP gamma and current profile), the heading Level 1 gives the case
``intact`` (bow into the environment, or ``fixed_heading_deg``), the setpoint at the field zero
point with that heading, the vessel started there (lines settled), the loop's defaults otherwise
(:class:`~tapm_opt.studies.closed_loop.ClosedLoopSettings`: the EKF, the tension-residual
line-break detector, control period 1 s), the plant's seed ``1..seeds``; a row passes when every
seed passes. The statistics leave out the first ``warmup`` seconds (the environment starts as a
step on a vessel at rest).

Search (``docs/capability.md``): Level 1 without thrust losses and with the same limits
(:func:`~tapm_opt.design.capability.capability`, case ``intact``, the DNV dynamic allowance 1.25) gives
each direction its first row to run; from there the rows are galloped (1, 2, 4, ... rows) up while
they pass or down while they fail, then bisected, on the assumption that a stronger row is never
easier. Directions run in parallel worker processes. The row above the capability is always run,
so its failure (which limit, by how much) is reported. Nothing is cached between calls.

Level 1 with the same limits and the dynamic allowance 1 (``level1_bound``) is the static
relaxation of this check: the time averages of a passing run are, to the approximations listed in
``docs/capability.md``, an equilibrium inside the same limits, so Level 3 does not exceed it
(``tests/test_capability_level3.py``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._io import csv_text
from .._parallel import limit_threads, worker_threads
from ..design.capability import (
    DIRECTIONS_DEG,
    DYNAMIC_ALLOWANCE,
    EXTENDED_TABLE,
    HEADINGS,
    BeaufortRow,
    CapabilityEnvironment,
    CapabilityError,
    CapabilityOptions,
    CapabilityResult,
    capability,
    case_names,
    table_name,
)
from ..errors import TapmError
from ..geometry import body_from_turret

__all__ = [
    "LEVEL3_CSV_COLUMNS",
    "LEVEL3_DURATION",
    "LEVEL3_HEADING_TOLERANCE",
    "LEVEL3_WARMUP",
    "STUDY_OPTIONS",
    "Level3Direction",
    "Level3Options",
    "Level3Result",
    "RunSummary",
    "capability_level3",
    "check_failed_line",
    "level3_file_stem",
    "run_row",
    "study_level3_options",
]

#: Default length of the checked part of a run [s]: 3 hours, the storm duration of the
#: mooring standard's characteristic tension (the most probable maximum of a 3-hour storm).
LEVEL3_DURATION = 10800.0
#: Default warm-up left out of the statistics [s]: about one surge natural period of fpso (259 s)
#: and the time its controllers take to take up a step of the environment.
LEVEL3_WARMUP = 300.0
#: Default largest heading error [deg] (the project's choice, the order of a DP heading alarm).
LEVEL3_HEADING_TOLERANCE = 5.0
#: Columns of ``capability_level3_<controller>.csv``.
LEVEL3_CSV_COLUMNS = ("direction_deg", "controller", "beaufort", "wind_speed", "limit", "offset_max", "util_max",
                      "util_line", "heading_error_max", "thrust_energy_MWh", "level1_beaufort",
                      "level1_bound_beaufort", "runs")


def level3_file_stem(controller: str, failed_line: str | None = None) -> str:
    """``capability_level3_<controller>`` (intact) or ``capability_level3_<controller>_line<id>``
    (after the loss of line ``failed_line``): the stem of a Level 3 computation's files."""
    return f"capability_level3_{controller}" + ("" if failed_line is None else f"_line{failed_line}")


def check_failed_line(scenario: Any, options: Level3Options) -> None:
    """Refuse ``options.failed_line`` when it is not a line of ``scenario`` (or the scenario's only
    line): the Level 1 case's own check (:func:`~tapm_opt.design.capability.case_names`), its
    :class:`CapabilityError` named as this option."""
    if options.failed_line is None:
        return
    try:
        case_names(scenario, options.case)
    except CapabilityError as exc:
        raise CapabilityError(str(exc).replace(f"condition = {options.case!r}: {options.failed_line!r}",
                                               f"failed_line = {options.failed_line!r}")) from None


def study_level3_options(table: Mapping[str, Any]) -> list[Level3Options]:
    """The :class:`Level3Options` of a study's ``[capability]`` table with ``level = 3``, one per
    kind in its ``controllers`` (default ``["pid"]``), each checked.

    Raises
    ------
    CapabilityError
        An unknown key, ``controllers`` not a non-empty list of distinct kinds, or a bad option
        (named, as :class:`Level3Options` names it).
    """
    bad = sorted(set(table) - set(STUDY_OPTIONS))
    if bad:
        raise CapabilityError(f"{bad[0]}: unknown option with level = 3; allowed: {', '.join(STUDY_OPTIONS)}")
    from .controllers import controller_types

    kinds = table.get("controllers", ["pid"])
    if not (isinstance(kinds, (list, tuple)) and kinds and all(isinstance(k, str) for k in kinds)
            and len(set(kinds)) == len(kinds)):
        raise CapabilityError(f"controllers = {kinds!r} must be a non-empty list of distinct controller kinds "
                              f"({', '.join(controller_types())})")
    unknown = [k for k in kinds if k not in controller_types()]
    if unknown:
        raise CapabilityError(f"controllers = {list(kinds)!r}: {unknown[0]!r} is not a controller kind "
                              f"({', '.join(controller_types())})")
    rest = {k: v for k, v in table.items() if k not in ("level", "controllers")}
    try:
        return [Level3Options(controller=k, **rest) for k in kinds]
    except TypeError as exc:
        raise CapabilityError(str(exc)) from None


@dataclass(frozen=True, kw_only=True)
class Level3Options:
    """Settings of :func:`capability_level3` (angles in degrees at this edge, SI otherwise).

    Parameters
    ----------
    controller : str
        Controller kind of the registry (``pid``, ``lmpc``, ``mpc``), with its tuned defaults.
    duration : float
        Checked length of each run [s] after the warm-up (default :data:`LEVEL3_DURATION`, 3 h).
    warmup : float
        Start of each run left out of the statistics [s], >= 0 (default :data:`LEVEL3_WARMUP`).
    seeds : int
        Runs per row, plant seeds 1..seeds; a row passes when all pass (default 1).
    directions_deg : sequence of float
        Environment directions [deg, coming from] (default 0-350 in 10 deg steps, as Level 1).
    heading, fixed_heading_deg, sea_state, table
        As :class:`~tapm_opt.design.capability.CapabilityOptions` (table: default the extended one;
        heading: default by the scenario's turret, :func:`~tapm_opt.design.capability.default_heading`,
        resolved by :func:`capability_level3` and :meth:`resolved`).
    losses : bool
        Run the plant and the controller with the Level 1 thrust losses applied to the thrusters
        (:func:`~tapm_opt.design.thrust_losses.apply_level1_losses`); default False.
    thruster_diameter : float, optional
        Diameter of the losses' interaction sectors [m].
    riser : bool
        Also check the riser's largest angles (default False: turret offset and line tensions).
    heading_tolerance : float
        Largest heading error allowed [deg], in (0, 180] (default :data:`LEVEL3_HEADING_TOLERANCE`).
    tension_utilisation : float, optional
        Allowed fairlead tension over MBS (default the scenario's ``limits.tension_utilisation``).
    segments : int, optional
        FEM segments per line (default each line's own).
    failed_line : str, optional
        The system after the loss of this line (its id): the plant and the controllers' model
        without it from the start, the post-failure capability of DNV-ST-0111's single-failure
        cases (their Level 1 references the case ``line <id>`` with ``post_failure_only``); None
        (default): intact.
    workers : int
        Processes over the directions (1: in this process).
    """

    controller: str = "pid"
    duration: float = LEVEL3_DURATION
    warmup: float = LEVEL3_WARMUP
    seeds: int = 1
    directions_deg: tuple[float, ...] = DIRECTIONS_DEG
    heading: str | None = None
    fixed_heading_deg: float = 0.0
    sea_state: str | None = None
    table: tuple[BeaufortRow, ...] = EXTENDED_TABLE
    losses: bool = False
    thruster_diameter: float | None = None
    riser: bool = False
    heading_tolerance: float = LEVEL3_HEADING_TOLERANCE
    tension_utilisation: float | None = None
    segments: int | None = None
    failed_line: str | None = None
    workers: int = 1

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> CapabilityError:
            return CapabilityError(f"{name} = {getattr(self, name)!r} {why}")

        from .controllers import controller_types

        kinds = controller_types()
        if self.controller not in kinds:
            raise bad("controller", f"must be one of {', '.join(kinds)}")
        for name, lo, strict in (("duration", 0.0, True), ("warmup", 0.0, False), ("heading_tolerance", 0.0, True)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < lo or (
                    strict and v == lo):
                raise bad(name, f"must be a number {'>' if strict else '>='} {lo:g}")
        if self.heading_tolerance > 180.0:
            raise bad("heading_tolerance", "must be an angle of at most 180 deg")
        for name, lo in (("seeds", 1), ("workers", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise bad(name, f"must be a whole number >= {lo}")
        if self.segments is not None and (isinstance(self.segments, bool) or not isinstance(self.segments, int)
                                          or self.segments < 1):
            raise bad("segments", "must be a whole number >= 1")
        if self.heading is not None and self.heading not in HEADINGS:
            raise bad("heading", f"must be one of {', '.join(HEADINGS)} (or absent: by the turret)")
        if self.failed_line is not None and not (isinstance(self.failed_line, str) and self.failed_line.strip()):
            raise bad("failed_line", "must be a line id (text) or absent (intact)")
        if self.tension_utilisation is not None and not (
                isinstance(self.tension_utilisation, (int, float)) and 0.0 < self.tension_utilisation <= 1.0):
            raise bad("tension_utilisation", "must be a number in (0, 1]")
        # the Level 1 options check the rest (directions, table, angles, sea state name, and the
        # losses' switch and diameter, which the Level 1 references themselves leave out)
        lv1 = self.level1_options()
        dataclasses.replace(lv1, losses=self.losses, thruster_diameter=self.thruster_diameter)
        object.__setattr__(self, "directions_deg", lv1.directions_deg)
        object.__setattr__(self, "table", lv1.table)

    def resolved(self, scenario: Any) -> "Level3Options":
        """These options with ``heading`` resolved for ``scenario`` as Level 1 resolves it
        (:func:`~tapm_opt.design.capability.resolve_options`: None takes the turret's default;
        ``"weathervane"`` on a locked turret is refused)."""
        from ..design.capability import resolve_options

        return dataclasses.replace(self, heading=resolve_options(scenario, self.level1_options()).heading)

    @property
    def case(self) -> str:
        """The Level 1 case compared (and its condition): ``intact``, or ``line <id>`` after a
        line's loss."""
        return "intact" if self.failed_line is None else f"line {self.failed_line}"

    def level1_options(self, *, dynamic_allowance: float = DYNAMIC_ALLOWANCE, tension_utilisation: float | None = None,
                       workers: int = 1) -> CapabilityOptions:
        """The Level 1 options of the same environments, heading and limits, without thrust losses,
        condition :attr:`case` (``intact``, or with ``failed_line`` that line's case, the system after
        the failure alone: ``post_failure_only``) (``tension_utilisation`` None: this one's, which
        may itself be None)."""
        tu = self.tension_utilisation if tension_utilisation is None else tension_utilisation
        return CapabilityOptions(level=1, heading=self.heading, condition=self.case,
                                 post_failure_only=self.failed_line is not None, directions_deg=self.directions_deg,
                                 fixed_heading_deg=self.fixed_heading_deg, sea_state=self.sea_state,
                                 table=self.table,
                                 losses=False, riser=self.riser, tension_utilisation=tu,
                                 dynamic_allowance=dynamic_allowance, workers=workers)

    def settings(self) -> dict:
        return {"level": 3, "controller": self.controller, "duration_s": self.duration, "warmup_s": self.warmup,
                "seeds": self.seeds, "directions_deg": list(self.directions_deg), "heading": self.heading,
                "fixed_heading_deg": self.fixed_heading_deg, "sea_state": self.sea_state,
                "table_name": table_name(self.table), "table": [dataclasses.asdict(r) for r in self.table],
                "losses": bool(self.losses), "thruster_diameter": self.thruster_diameter, "riser": bool(self.riser),
                "heading_tolerance_deg": self.heading_tolerance, "tension_utilisation": self.tension_utilisation,
                "segments": self.segments, "failed_line": self.failed_line}


#: The keys of a study's ``[capability]`` table with ``level = 3``: :class:`Level3Options`' own
#: fields but ``controller`` and ``workers``, and ``controllers``, the controller kinds run (default
#: ``["pid"]``; the study's workers run the directions).
STUDY_OPTIONS = ("level", "controllers",
                 *(f.name for f in dataclasses.fields(Level3Options) if f.name not in ("controller", "workers")))


@dataclass(frozen=True)
class RunSummary:
    """One row's runs (every seed run until one fails).

    Attributes
    ----------
    number : int
        Beaufort number of the row.
    wind_speed : float
        Its wind speed [m/s].
    passed : bool
    limit : str
        What failed (``offset``, ``tension <line>``, ``heading``, ``riser top``, ``riser bottom``,
        ``line break <line>``, ``diverged``), "" when it passed.
    seeds : tuple of int
        Seeds run.
    offset_max : float
        Largest LF turret offset over the runs [m] (NaN if none finished).
    util_max : float
        Largest fairlead tension over MBS [-], on line ``util_line``.
    util_line : str
    heading_error_max : float
        Largest heading error over the runs [deg].
    thrust_energy : float
        Mean thrust energy of the runs over the checked window [J].
    riser_max_deg : tuple of float
        Largest riser top and bottom angles [deg] (NaN without a riser).
    detail : str
        The failure's message (the break event or the error).
    wall_time : float
        Wall-clock time of the runs [s].
    offset_by_seed : tuple of float
        Each seed's largest LF turret offset [m], in the order of ``seeds`` (the spread of the
        maxima: how near the row is to its limit beyond the one realisation).
    util_by_seed : tuple of float
        Each seed's largest fairlead tension over MBS [-].
    """

    number: int
    wind_speed: float
    passed: bool
    limit: str
    seeds: tuple
    offset_max: float
    util_max: float
    util_line: str
    thrust_energy: float
    heading_error_max: float = math.nan
    riser_max_deg: tuple = (math.nan, math.nan)
    detail: str = ""
    wall_time: float = 0.0
    offset_by_seed: tuple = ()
    util_by_seed: tuple = ()

    def as_json(self) -> dict:
        def num(v: float) -> float | None:
            return float(v) if math.isfinite(v) else None

        return {"beaufort": self.number, "wind_speed": self.wind_speed, "passed": self.passed, "limit": self.limit,
                "seeds": list(self.seeds), "offset_max_m": num(self.offset_max), "util_max": num(self.util_max),
                "util_line": self.util_line, "heading_error_max_deg": num(self.heading_error_max),
                "thrust_energy_J": num(self.thrust_energy),
                "riser_max_deg": [num(v) for v in self.riser_max_deg], "detail": self.detail,
                "wall_time_s": self.wall_time, "offset_max_by_seed_m": [num(v) for v in self.offset_by_seed],
                "util_max_by_seed": [num(v) for v in self.util_by_seed]}


@dataclass(frozen=True)
class Level3Direction:
    """The Level 3 capability of one direction.

    Attributes
    ----------
    direction_deg : float
    beaufort : int
        Largest passing row's Beaufort number (-1: not even the first row).
    wind_speed : float
        Its wind speed [m/s] (0 with none).
    limit : str
        What failed in the row above (``table``: the top row passed).
    decided : RunSummary or None
        The runs of the capability row (None with none).
    above : RunSummary or None
        The runs of the row above, which failed (None at the table's top).
    tested : tuple of RunSummary
        Every row run, in the order run.
    """

    direction_deg: float
    beaufort: int
    wind_speed: float
    limit: str
    decided: RunSummary | None
    above: RunSummary | None
    tested: tuple = ()

    def as_json(self) -> dict:
        return {"direction_deg": self.direction_deg, "beaufort": self.beaufort, "wind_speed": self.wind_speed,
                "limit": self.limit, "decided": None if self.decided is None else self.decided.as_json(),
                "above": None if self.above is None else self.above.as_json(),
                "tested": [r.as_json() for r in self.tested]}


@dataclass(frozen=True, eq=False)
class Level3Result:
    """The answer of :func:`capability_level3`.

    Attributes
    ----------
    scenario : str
    options : Level3Options
    directions : tuple of Level3Direction
    level1 : CapabilityResult
        Level 1 without losses with the same limits and allowance 1.25 (the search's start).
    level1_bound : CapabilityResult
        The same with the dynamic allowance 1 (the static relaxation; Level 3 does not exceed it).
    info : dict
        Limits, run counts and wall time.
    """

    scenario: str
    options: Level3Options
    directions: tuple
    level1: CapabilityResult
    level1_bound: CapabilityResult
    info: dict = field(default_factory=dict)

    @property
    def beaufort(self) -> np.ndarray:
        return np.array([d.beaufort for d in self.directions], int)

    @property
    def wind_speed(self) -> np.ndarray:
        return np.array([d.wind_speed for d in self.directions], float)

    def csv_text(self) -> str:
        """One row per direction (:data:`LEVEL3_CSV_COLUMNS`)."""
        rows = []
        b1 = self.level1.case(self.options.case).beaufort
        b0 = self.level1_bound.case(self.options.case).beaufort
        for i, d in enumerate(self.directions):
            s = d.decided

            def r(v: float, n: int, s: RunSummary | None = s) -> Any:
                return round(float(v), n) if s is not None and math.isfinite(v) else ""

            rows.append((d.direction_deg, self.options.controller, d.beaufort, d.wind_speed, d.limit,
                         r(s.offset_max, 3) if s else "", r(s.util_max, 4) if s else "", s.util_line if s else "",
                         r(s.heading_error_max, 3) if s else "", r(s.thrust_energy / 3.6e9, 4) if s else "",
                         int(b1[i]), int(b0[i]), len(d.tested)))
        return csv_text(LEVEL3_CSV_COLUMNS, rows)

    def as_json(self) -> dict:
        """``capability_level3_<controller>.json``: settings, limits, every direction's result and
        the two Level 1 references (their reported envelopes: ``mooring``, ``intact`` and, after a
        line's loss, that ``line <id>``; :attr:`Level3Options.case` is the one compared)."""
        def ref(res: CapabilityResult) -> dict:
            return {"dynamic_allowance": res.options.dynamic_allowance,
                    "cases": [c.as_json() for c in res.cases]}

        return {"format": "tapm-capability-level3/1", "scenario": self.scenario,
                "controller": self.options.controller,
                "directions_deg": [d.direction_deg for d in self.directions],
                "settings": {**self.options.settings(), **self.info},
                "beaufort": [d.beaufort for d in self.directions],
                "wind_speed": [d.wind_speed for d in self.directions],
                "limit": [d.limit for d in self.directions],
                "directions": [d.as_json() for d in self.directions],
                "level1": ref(self.level1), "level1_bound": ref(self.level1_bound)}

    def data_files(self) -> dict[str, bytes]:
        """``capability_level3_<controller>.csv`` and ``.json``."""
        import json

        stem = level3_file_stem(self.options.controller, self.options.failed_line)
        return {f"{stem}.csv": self.csv_text().encode("utf-8"),
                f"{stem}.json": (json.dumps(self.as_json(), indent=1, allow_nan=False) + "\n").encode("utf-8")}


# -- one row ----------------------------------------------------------------------------------------

class _Runner:
    """The runs of one direction: the scenario with the table's sea states of that direction, its
    System (built once), the heading of each row."""

    def __init__(self, scenario: Any, opt: Level3Options, direction_deg: float):
        from ..models.system import System

        self.opt = opt
        self.direction = float(direction_deg)
        sc = scenario
        if opt.losses:
            from ..design.thrust_losses import ThrustLossError, apply_level1_losses

            try:
                sc, _ = apply_level1_losses(sc, diameter=opt.thruster_diameter)
            except ThrustLossError as exc:
                raise CapabilityError(f"losses: {exc}") from None
        env = CapabilityEnvironment(sc, opt.level1_options())
        self.rows = tuple(opt.table)
        self.states = []
        self.headings = []
        for k, row in enumerate(self.rows):
            ss = env.sea_state_from(row.wind_speed, self.direction)
            self.states.append(dataclasses.replace(ss, id=f"capability-{k}-BF{row.number}"))
            self.headings.append(env.heading("intact", math.radians(self.direction), row.wind_speed))
        # the table's sea states in the scenario, so that the loop's observers find theirs by id; after
        # a line's loss the system without it (plant and controllers' model)
        lines = tuple(ln for ln in sc.lines if ln.id != opt.failed_line)
        self.scenario = dataclasses.replace(sc, sea_states=tuple(self.states) + tuple(sc.sea_states), faults=(),
                                            lines=lines)
        self.system = System.from_scenario(self.scenario)
        self.R = float(sc.limits.safe_radius)
        self.util_lim = float(sc.limits.tension_utilisation if opt.tension_utilisation is None
                              else opt.tension_utilisation)
        self.p_cot = np.asarray(sc.turret.position, float)

    def run(self, k: int, seed: int) -> dict:
        """One closed-loop run at row ``k``: its statistics and what failed ("" if nothing)."""
        from ..plant.environment import PlantError
        from ..plant.fem import SimulationDiverged
        from ..plant.simulator import Plant
        from .closed_loop import ClosedLoopSettings, run_closed_loop
        from .controllers import build_controller
        from .kpis import KpiError, case_kpis

        opt, system = self.opt, self.system
        psi = float(self.headings[k])
        bx, by = body_from_turret((0.0, 0.0), psi, self.p_cot)
        settings = ClosedLoopSettings(duration=opt.warmup + opt.duration, eta_d=(0.0, 0.0, psi), heading="fixed")
        out = {"offset_max": math.nan, "util_max": math.nan, "util_line": "", "thrust_energy": math.nan,
               "heading_error_max": math.nan, "riser": (math.nan, math.nan), "limit": "", "detail": ""}
        ctrl = build_controller(system, {"type": opt.controller}, where="controller",
                                dt_control=settings.dt_control, estimator=settings.estimator)
        plant = Plant(system, sea_state=self.states[k].id, seed=int(seed), segments=opt.segments,
                      eta0=(bx, by, psi), faults=())
        try:
            result = run_closed_loop(plant, ctrl, settings, system=system,
                                     meta={"capability_row": self.rows[k].number, "direction_deg": self.direction})
            kp = case_kpis(result, system, t_start=float(opt.warmup))
        except (SimulationDiverged, PlantError, KpiError, FloatingPointError, TapmError) as exc:
            # a run that cannot go on fails the row: lines broken by overload first (the loop's models
            # may give up once every line is gone), else a diverged simulation
            breaks = [msg for _, msg in plant.events if "broke" in msg]
            if breaks:
                out.update(limit=f"line break {breaks[0].split()[1]}",
                           detail="; ".join(breaks) + f"; then {type(exc).__name__}: {exc}")
            else:
                out.update(limit="diverged", detail=f"{type(exc).__name__}: {exc}")
            return out
        line_ids = [ln.id for ln in system.scenario.lines]
        utils = {i: float(kp[f"util_max[{i}]"]) for i in line_ids if f"util_max[{i}]" in kp}
        worst = max(utils, key=lambda i: utils[i]) if utils else ""
        riser = (float(kp.get("riser_top_angle_max_deg", math.nan)), float(kp.get("riser_bottom_angle_max_deg", math.nan)))
        out.update(offset_max=float(kp["offset_max"]), util_max=utils.get(worst, math.nan), util_line=worst,
                   thrust_energy=float(kp["thrust_energy"]), heading_error_max=float(kp["heading_error_max"]),
                   riser=riser)
        breaks = [msg for _, msg in plant.events if "broke" in msg]
        ratios = {"offset": out["offset_max"] / self.R, "heading": out["heading_error_max"] / opt.heading_tolerance}
        if worst:
            ratios[f"tension {worst}"] = utils[worst] / self.util_lim
        rs = system.scenario.riser
        if opt.riser and rs is not None:
            ratios["riser top"] = riser[0] / math.degrees(rs.critical_top_angle)
            ratios["riser bottom"] = riser[1] / math.degrees(rs.critical_bottom_angle)
        if breaks:
            lid = breaks[0].split()[1]
            out.update(limit=f"line break {lid}", detail="; ".join(breaks))
        elif any(v > 1.0 for v in ratios.values()):
            name = max(ratios, key=lambda n: ratios[n])
            out.update(limit=name, detail=f"{name}: {ratios[name]:.3f} of its limit")
        return out

    def row(self, k: int) -> RunSummary:
        """Row ``k``'s runs: seeds 1..seeds until one fails."""
        w0 = time.perf_counter()
        runs = []
        failed = None
        for seed in range(1, self.opt.seeds + 1):
            r = self.run(k, seed)
            runs.append((seed, r))
            if r["limit"]:
                failed = r
                break

        def mx(key: str) -> float:
            v = [r[key] for _, r in runs if math.isfinite(r[key])]
            return max(v) if v else math.nan

        utils = [(r["util_max"], r["util_line"]) for _, r in runs if math.isfinite(r["util_max"])]
        u, line = max(utils) if utils else (math.nan, "")
        energy = [r["thrust_energy"] for _, r in runs if math.isfinite(r["thrust_energy"])]
        riser = tuple(max((r["riser"][j] for _, r in runs if math.isfinite(r["riser"][j])), default=math.nan)
                      for j in (0, 1))
        row = self.rows[k]
        return RunSummary(number=row.number, wind_speed=row.wind_speed, passed=failed is None,
                          limit="" if failed is None else failed["limit"], seeds=tuple(s for s, _ in runs),
                          offset_max=mx("offset_max"), util_max=u, util_line=line, heading_error_max=mx("heading_error_max"),
                          thrust_energy=float(np.mean(energy)) if energy else math.nan, riser_max_deg=riser,
                          detail="" if failed is None else failed["detail"], wall_time=time.perf_counter() - w0,
                          offset_by_seed=tuple(float(r["offset_max"]) for _, r in runs),
                          util_by_seed=tuple(float(r["util_max"]) for _, r in runs))


def run_row(scenario: Any, options: Level3Options, direction_deg: float, beaufort: int) -> RunSummary:
    """The runs of one row (by its Beaufort number in ``options.table``) and direction, as the
    search runs them: to check a capability number by hand."""
    runner = _Runner(scenario, options, direction_deg)
    numbers = [r.number for r in runner.rows]
    if beaufort not in numbers:
        raise CapabilityError(f"beaufort = {beaufort!r} is not a row of the table ({numbers})")
    return runner.row(numbers.index(beaufort))


def _search(runner: _Runner, start: int) -> Level3Direction:
    """Gallop from row ``start`` (up while passing, down while failing), then bisect (module
    docstring)."""
    n = len(runner.rows)
    done: dict[int, RunSummary] = {}
    order: list[RunSummary] = []

    def ok(k: int) -> bool:
        if k not in done:
            done[k] = runner.row(k)
            order.append(done[k])
        return done[k].passed

    k = min(max(start, 0), n - 1)
    lo: int | None
    hi: int | None
    if ok(k):
        lo, hi, step = k, None, 1
        while lo < n - 1:
            nxt = min(lo + step, n - 1)
            if ok(nxt):
                lo, step = nxt, 2 * step
            else:
                hi = nxt
                break
    else:
        lo, hi, step = -1, k, 1
        while hi > 0:
            nxt = max(hi - step, 0)
            if ok(nxt):
                lo = nxt
                break
            hi, step = nxt, 2 * step
    while hi is not None and hi - lo > 1:
        mid = (lo + hi) // 2
        if ok(mid):
            lo = mid
        else:
            hi = mid
    decided = done.get(lo) if lo >= 0 else None
    above = done.get(hi) if hi is not None else None
    return Level3Direction(direction_deg=runner.direction, beaufort=-1 if lo < 0 else runner.rows[lo].number,
                           wind_speed=0.0 if lo < 0 else runner.rows[lo].wind_speed,
                           limit="table" if above is None else above.limit, decided=decided, above=above,
                           tested=tuple(order))


_WORKER: dict = {}


def _worker_init(scenario: Any, options: Level3Options, threads: int) -> None:
    limit_threads(threads)
    _WORKER["args"] = (scenario, options)


def _worker_direction(direction: float, start: int) -> Level3Direction:
    scenario, options = _WORKER["args"]
    return _search(_Runner(scenario, options, direction), start)


def capability_level3(scenario: Any, options: Level3Options | Mapping[str, Any] | None = None, *,
                      progress: Callable[[str], None] | None = None, **kw: Any) -> Level3Result:
    """Level 3 capability of ``scenario`` (module docstring).

    Parameters
    ----------
    scenario : Scenario
    options : Level3Options or mapping, optional
        Settings; keywords override.
    progress : callable, optional
        Called with a line of text as each direction is done.

    Raises
    ------
    CapabilityError
        A bad option (named), a scenario without a safe radius or thrusters, a controller that
        cannot be built for it.
    """
    t0 = time.perf_counter()
    if isinstance(options, Level3Options):
        opt = dataclasses.replace(options, **kw) if kw else options
    else:
        given = dict(options or {})
        names = {f.name for f in dataclasses.fields(Level3Options)}
        unknown = sorted((set(given) | set(kw)) - names)
        if unknown:
            raise CapabilityError(f"unknown option(s) {unknown}; options are {sorted(names)}")
        opt = Level3Options(**{**given, **kw})
    if scenario.limits.safe_radius is None:
        raise CapabilityError(f"scenario {scenario.name!r}: limits.safe_radius = None: Level 3 needs the safe circle")
    if not scenario.thrusters:
        raise CapabilityError(f"scenario {scenario.name!r} has no thrusters: Level 3 runs a controller")
    opt = opt.resolved(scenario)
    check_failed_line(scenario, opt)
    util = float(scenario.limits.tension_utilisation if opt.tension_utilisation is None else opt.tension_utilisation)
    workers = min(opt.workers, max(1, len(opt.directions_deg)))
    lv1 = capability(scenario, opt.level1_options(tension_utilisation=util, workers=min(2, opt.workers)))
    bound = capability(scenario, opt.level1_options(tension_utilisation=util, dynamic_allowance=1.0,
                                                    workers=min(2, opt.workers)))
    # a controller that cannot be built fails here, not in a worker
    from .controllers import ControllerSpecError, build_controller

    try:
        build_controller(scenario, {"type": opt.controller}, where="controller")
    except (ControllerSpecError, TapmError) as exc:
        raise CapabilityError(f"controller = {opt.controller!r}: {exc}") from None
    numbers = [r.number for r in opt.table]
    starts = [numbers.index(int(b)) if int(b) in numbers else 0 for b in lv1.case(opt.case).beaufort]
    dirs = list(opt.directions_deg)
    out: dict[float, Level3Direction] = {}

    def done(d: Level3Direction) -> None:
        out[d.direction_deg] = d
        if progress is not None:
            progress(f"{d.direction_deg:g} deg: Beaufort {d.beaufort} ({d.limit} above), {len(d.tested)} rows run")

    if workers > 1:
        import concurrent.futures as cf
        import multiprocessing as mp

        ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
        with cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init,
                                    initargs=(scenario, opt, worker_threads(workers))) as pool:
            futs = [pool.submit(_worker_direction, d, s) for d, s in zip(dirs, starts)]
            for fut in cf.as_completed(futs):
                done(fut.result())
    else:
        for d, s in zip(dirs, starts):
            done(_search(_Runner(scenario, opt, d), s))
    entries = tuple(out[float(d)] for d in dirs)
    runs = sum(len(r.seeds) for e in entries for r in e.tested)
    info = {"safe_radius_m": float(scenario.limits.safe_radius), "tension_utilisation_used": util,
            "riser_limits_deg": (None if scenario.riser is None or not opt.riser else
                                 [math.degrees(scenario.riser.critical_top_angle),
                                  math.degrees(scenario.riser.critical_bottom_angle)]),
            "heading_tolerance_deg": float(opt.heading_tolerance),
            "closed_loop": "ClosedLoopSettings defaults (EKF, tension-residual detector, dt_control 1 s), fixed "
                           "setpoint at the field zero point with the Level 1 heading",
            "runs": runs, "simulated_s": runs * (opt.warmup + opt.duration),
            "elapsed_s": time.perf_counter() - t0, "workers": int(workers)}
    return Level3Result(scenario=str(scenario.name), options=opt, directions=entries, level1=lv1, level1_bound=bound,
                        info=info)
