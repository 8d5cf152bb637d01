"""The catalogue of every KPI a case can write: one entry per KPI with its unit, its direction
(is a lower or a higher value better, or neither) and a one-line meaning.

Every other place that needs a KPI fact reads it here: the KPI module's units and column order
(:mod:`tapm_opt.studies.kpis`), the report's units and its marking of the better value
(:mod:`tapm_opt.report.kpi_tables`), and the tables of ``docs/kpis.md`` (checked against this one
by ``tests/test_kpi_catalogue.py``). The full definitions are in ``docs/kpis.md``.

KPIs built per scenario line (``T_max[3]``) have one *pattern* entry named with the line-id token
``<id>`` (``T_max[<id>]``, ``per="line"``); :func:`kpi` resolves a concrete name to it.

This module imports the standard library only (and the package's error base class), so a
controller tuner or a report can read it without the numerical stack.

>>> kpi("util_max").unit, kpi("util_max").direction
('-', 'minimise')
>>> kpi("delta_min[7]").name
'delta_min[<id>]'
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Iterable, Mapping

from ..errors import TapmError

__all__ = ["KpiDef", "UnknownKpiError", "KPIS", "DIRECTIONS", "KINDS", "PER_LINE_ID", "kpi", "find_kpi",
           "is_kpi", "directions", "units", "kpi_unit", "kpi_sign", "kpi_order", "per_line_kpis"]

#: Allowed directions: a lower value is better, a higher value is better, neither.
DIRECTIONS = ("minimise", "maximise", "none")
#: Kinds of value: a real number, a count (an integer), a 0/1 flag, a text.
KINDS = ("real", "count", "flag", "text")
#: The token that stands for the line id in a per-line pattern entry's name.
PER_LINE_ID = "<id>"

_SIGN = {"minimise": -1, "maximise": 1, "none": 0}
_INDEXED = re.compile(r"^(?P<base>[^\[\]]+)\[(?P<id>[^\[\]]+)\]$")


class UnknownKpiError(TapmError, KeyError):
    """A name that is not in the KPI catalogue (``name``; ``suggestions``: close catalogue names)."""

    def __init__(self, name: str, suggestions: tuple[str, ...] = ()):
        self.name = name
        self.suggestions = tuple(suggestions)
        hint = f"; did you mean {' or '.join(repr(s) for s in self.suggestions)}?" if self.suggestions else \
            "; the KPIs are listed in tapm_opt.studies.kpi_catalogue.KPIS (docs/kpis.md)"
        super().__init__(f"unknown KPI {name!r}{hint}")

    def __str__(self) -> str:  # a KeyError would show the message's repr
        return str(self.args[0])


@dataclass(frozen=True)
class KpiDef:
    """One KPI of the catalogue.

    Attributes
    ----------
    name : str
        The KPI's name as written in ``kpis.json`` (``offset_max``), or for a per-line KPI its
        pattern with the line-id token ``<id>`` (``T_max[<id>]``).
    unit : str
        Unit as written in the docs and table headers: SI symbols (``"m"``, ``"s"``, ``"N"``,
        ``"J"``, ``"W"``, ``"kg"``, ``"m/s"``), ``"deg"`` for angles, ``"lines"`` for a number of lines,
        ``"-"`` for a dimensionless number, a count or a text.
    direction : {"minimise", "maximise", "none"}
        Which value is better when cases are compared on the same condition; ``"none"``: neither.
    meaning : str
        One line: what the number is (and, where the direction is not obvious, why it is that).
    per : str
        ``"line"`` for a pattern entry built per scenario line, ``""`` otherwise.
    kind : {"real", "count", "flag", "text"}
        The value's type: a real number, an integer count, 0/1, or a text (never charted).
    """

    name: str
    unit: str
    direction: str
    meaning: str
    per: str = ""
    kind: str = "real"
    _pattern: re.Pattern | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.direction not in DIRECTIONS:
            raise ValueError(f"KPI {self.name!r}: direction {self.direction!r} is not one of {DIRECTIONS}")
        if self.kind not in KINDS:
            raise ValueError(f"KPI {self.name!r}: kind {self.kind!r} is not one of {KINDS}")
        if not self.unit or not self.meaning:
            raise ValueError(f"KPI {self.name!r} needs a unit and a meaning")
        if self.per:
            if self.per != "line" or not self.name.endswith(f"[{PER_LINE_ID}]"):
                raise ValueError(f"per-line KPI {self.name!r} must be named '<quantity>[{PER_LINE_ID}]'")
            object.__setattr__(self, "_pattern", re.compile(rf"^{re.escape(self.base)}\[(?P<id>[^\[\]]+)\]$"))

    @property
    def base(self) -> str:
        """The quantity: the name without ``[<id>]`` (``T_max`` of ``T_max[<id>]``)."""
        return self.name[: -len(PER_LINE_ID) - 2] if self.per else self.name

    @property
    def pattern(self) -> re.Pattern | None:
        """For a per-line entry, the regular expression of its concrete names (group ``id``)."""
        return self._pattern

    @property
    def sign(self) -> int:
        """-1 when lower is better, +1 when higher is better, 0 for neither."""
        return _SIGN[self.direction]

    def name_for(self, line_id: str) -> str:
        """The concrete name of a per-line KPI for line ``line_id`` (``T_max[3]``)."""
        if not self.per:
            raise ValueError(f"KPI {self.name!r} is not built per line")
        return f"{self.base}[{line_id}]"

    def matches(self, name: str) -> bool:
        """Whether the concrete KPI name ``name`` is this entry."""
        return bool(self._pattern.match(name)) if self._pattern is not None else name == self.name


def _k(name, unit, direction, meaning, *, kind="real"):
    return KpiDef(name, unit, direction, meaning, kind=kind)


def _line(name, unit, direction, meaning, *, kind="real"):
    return KpiDef(f"{name}[{PER_LINE_ID}]", unit, direction, meaning, per="line", kind=kind)


# The catalogue, in the documented column order of the KPI tables (kpi_order): the aggregate
# KPIs, then the per-line quantities.
_ENTRIES: tuple[KpiDef, ...] = (
    _k("duration", "s", "none", "length of the evaluated window (t_end - t_0): a setting, not a result"),
    # offsets and heading
    _k("offset_max", "m", "minimise", "max horizontal distance of the LF turret centre from its field-zero-point position"),
    _k("offset_mean", "m", "minimise", "time-weighted mean of the turret offset"),
    _k("offset_std", "m", "minimise", "time-weighted standard deviation of the turret offset"),
    _k("time_outside_safe", "s", "minimise", "time with the turret offset beyond limits.safe_radius"),
    _k("time_outside_alert", "s", "minimise", "time with the turret offset beyond limits.alert_radius"),
    _k("heading_error_max", "deg", "minimise", "max |ssa(psi - psi_d)| against the logged heading setpoint"),
    # line tensions
    _k("T_max", "N", "minimise", "max fairlead tension over the lines, a break's tension included"),
    _k("util_max", "-", "minimise", "max tension utilisation T/MBS over the lines, a break's tension included"),
    _k("utilisation_max", "-", "minimise", "util_max under its older name, written by basic_kpis (tapm simulate)"),
    # structural reliability index
    _k("delta_min", "-", "maximise", "min over the lines of the causal reliability index (survey eq. 32): a higher "
                                     "index is a lower failure probability"),
    _k("delta_frac_below", "-", "minimise", "max over the lines of the fraction of ready time with the causal "
                                            "index below delta_s"),
    _k("delta_min_offline", "-", "maximise", "min over the lines of the offline (whole-record) reliability index"),
    # fatigue (Miner's damage of the fairlead tension record, docs/fatigue_setpoint.md)
    _k("fatigue_damage_max", "-", "minimise", "max over the lines of fatigue_damage[<id>]: the worst line's "
                                              "accumulated damage over the record"),
    _k("fatigue_damage_spread", "-", "minimise", "fatigue_damage_max over the mean of fatigue_damage[<id>] over the "
                                                 "lines: 1 when every line takes the same damage"),
    # DNV-OS-E301 line check
    _k("dnv_uls_max", "-", "minimise", "max over the lines of the DNV-OS-E301 ULS utilisation (<= 1 passes)"),
    _k("dnv_uls_pass", "lines", "maximise", "lines whose ULS utilisation is <= 1", kind="count"),
    _k("dnv_uls_fail", "lines", "minimise", "lines whose ULS utilisation is > 1", kind="count"),
    _k("dnv_als_max", "-", "minimise", "max over the remaining lines of the ALS utilisation after a break"),
    _k("dnv_als_pass", "lines", "maximise", "remaining lines whose ALS utilisation is <= 1", kind="count"),
    _k("dnv_als_fail", "lines", "minimise", "remaining lines whose ALS utilisation is > 1", kind="count"),
    _k("lines_broken", "lines", "minimise", "lines that broke (prescribed or overload): cases compared on one "
                                            "condition share the prescribed ones, so more is overload", kind="count"),
    # line-break detection
    _k("break_detected_at", "s", "none", "time of the first detection of a broken line: an instant on the "
                                         "record's clock, compare detection_delay", ),
    _k("detection_delay", "s", "minimise", "time from the line's break to its detection"),
    _k("break_isolated", "-", "maximise", "1 when the first line detected after the first break is one that "
                                          "broke, else 0", kind="flag"),
    _k("break_isolated_line", "-", "none", "id of the first line detected after the first break (a text)",
       kind="text"),
    _k("false_alarms", "-", "minimise", "detections of a line break or buoy loss that had not happened by then",
       kind="count"),
    # buoy-loss detection
    _k("buoys_lost", "-", "none", "buoys the plant lost from composite lines (prescribed faults)", kind="count"),
    _k("buoy_loss_detected_at", "s", "none", "time of the first detection of a lost buoy: an instant on the "
                                             "record's clock, compare buoy_loss_detection_delay"),
    _k("buoy_loss_detection_delay", "s", "minimise", "time from a buoy's loss to its detection"),
    _k("buoy_loss_isolated", "-", "maximise", "1 when the first fault detected after the first buoy loss is a buoy "
                                              "lost by then (not a break, not another buoy), else 0", kind="flag"),
    # sensor faults (tapm_opt.estimation.redundancy)
    _k("sensor_fault_detected_at", "s", "none", "time of the first detection of the first sensor fault's sensor: an "
                                                "instant on the record's clock, compare sensor_fault_detection_delay"),
    _k("sensor_fault_detection_delay", "s", "minimise", "time from the first sensor fault to its detection"),
    _k("sensor_fault_isolated", "-", "maximise", "1 when the first sensor found failed after the first sensor fault "
                                                 "is its sensor, else 0", kind="flag"),
    _k("sensor_false_alarms", "-", "minimise", "detections of a sensor fault (GNSS, tension cell, gyro) that had "
                                               "not happened by then", kind="count"),
    _k("turret_error_fault_max", "m", "minimise", "max error of the estimated turret position during the first "
                                                  "sensor fault"),
    _k("turret_error_fault_rms", "m", "minimise", "RMS error of the estimated turret position during the first "
                                                  "sensor fault"),
    _k("mode_switches", "-", "none", "controller mode, gain-row or dead-band switches: a switch the weather or a "
                                     "break calls for is wanted, so the count alone is neither good nor bad",
       kind="count"),
    # current-profile estimation
    _k("current_speed_error", "m/s", "minimise", "RMS error of the estimated surface current speed against the "
                                                 "plant's, over the estimates after t_start"),
    _k("current_direction_error", "deg", "minimise", "RMS error of the estimated current direction against the "
                                                     "plant's, over the estimates after t_start"),
    _k("current_seabed_factor_error", "-", "minimise", "RMS error of the estimated seabed factor of the profile "
                                                       "against the plant's, over the estimates after t_start"),
    # riser
    _k("riser_top_angle_max_deg", "deg", "minimise", "max riser angle at the hang-off"),
    _k("riser_bottom_angle_max_deg", "deg", "minimise", "max riser angle at the wellhead"),
    _k("riser_delta_min", "-", "maximise", "min over both riser ends of the causal angle reliability index"),
    _k("riser_delta_top_min", "-", "maximise", "min causal reliability index of the riser's top angle"),
    _k("riser_delta_bottom_min", "-", "maximise", "min causal reliability index of the riser's bottom angle"),
    _k("riser_delta_frac_below", "-", "minimise", "fraction of ready time with the worse riser end's index below "
                                                  "delta_s"),
    # low-frequency roll and pitch (a vessel with vessel.roll_pitch; docs/semi.md)
    _k("roll_std_deg", "deg", "minimise", "standard deviation of the roll angle about its mean"),
    _k("roll_max_deg", "deg", "minimise", "max roll angle magnitude"),
    _k("pitch_std_deg", "deg", "minimise", "standard deviation of the pitch angle about its mean"),
    _k("pitch_max_deg", "deg", "minimise", "max pitch angle magnitude"),
    # energy
    _k("thrust_energy", "J", "minimise", "thruster shaft energy, integral of the summed thruster power"),
    _k("thrust_power_mean", "W", "minimise", "thrust_energy / duration"),
    _k("fuel", "kg", "minimise", "fuel proxy: specific fuel consumption times thrust_energy"),
    _k("thrust_to_command_ratio", "-", "none", "delivered over commanded horizontal thrust: lower under winch "
                                               "control is the mooring's share, below 1 without winches is "
                                               "saturation, so neither way is better"),
    _k("winch_energy", "J", "minimise", "work the winches deliver hauling in (paying out costs nothing)"),
    # controller and allocation statistics
    _k("solver_time_median", "s", "minimise", "median MPC solve time per call (wall clock)"),
    _k("solver_time_p95", "s", "minimise", "95th percentile of the MPC solve time per call (wall clock)"),
    _k("solver_time_max", "s", "minimise", "max MPC solve time per call (wall clock)"),
    _k("solver_failures", "-", "minimise", "MPC solves that did not succeed", kind="count"),
    _k("solver_fallbacks", "-", "minimise", "MPC calls answered by the fallback law", kind="count"),
    _k("allocation_fallbacks", "-", "minimise", "thrust-allocation calls that fell back", kind="count"),
    # per line
    _line("T_max", "N", "minimise", "max fairlead tension of the line over its record, its break's tension included"),
    _line("T_mean", "N", "minimise", "time-weighted mean fairlead tension of the line over its record"),
    _line("util_max", "-", "minimise", "T_max[<id>] / MBS of the line"),
    _line("delta_min", "-", "maximise", "min causal reliability index of the line"),
    _line("delta_frac_below", "-", "minimise", "fraction of the line's ready time with the causal index below "
                                               "delta_s"),
    _line("delta_min_offline", "-", "maximise", "min offline reliability index of the line"),
    _line("fatigue_damage", "-", "minimise", "Miner's damage of the line's fairlead tension record (rainflow "
                                             "ranges, its type's T-N curve)"),
    _line("dnv_uls", "-", "minimise", "DNV-OS-E301 ULS utilisation of the line on the intact record"),
    _line("dnv_als", "-", "minimise", "DNV-OS-E301 ALS utilisation of a remaining line after the first break"),
)

#: Every KPI by its catalogue name (per-line entries by their pattern name, ``T_max[<id>]``), in
#: the documented column order.
KPIS: Mapping[str, KpiDef] = MappingProxyType({e.name: e for e in _ENTRIES})
if len(KPIS) != len(_ENTRIES):  # pragma: no cover - a duplicate in the table above
    raise RuntimeError("duplicate name in the KPI catalogue")
_BY_BASE = {e.base: e for e in _ENTRIES if e.per}
_ORDER_FIXED = {e.name: i for i, e in enumerate(e for e in _ENTRIES if not e.per)}
_ORDER_LINE = {e.base: i for i, e in enumerate(e for e in _ENTRIES if e.per)}


def per_line_kpis() -> tuple[KpiDef, ...]:
    """The per-line pattern entries, in column order."""
    return tuple(_BY_BASE.values())


def find_kpi(name: str) -> KpiDef | None:
    """The catalogue entry of ``name`` (a concrete per-line name resolves to its pattern entry),
    or None."""
    e = KPIS.get(name)
    if e is not None:
        return e
    m = _INDEXED.match(name)
    if m:
        return _BY_BASE.get(m.group("base"))
    return None


def kpi(name: str) -> KpiDef:
    """The catalogue entry of KPI ``name`` (``"offset_max"``; ``"T_max[3]"`` and ``"T_max[<id>]"``
    give the per-line pattern entry).

    Raises
    ------
    UnknownKpiError
        ``name`` is not in the catalogue; the message suggests close names.
    """
    e = find_kpi(name)
    if e is None:
        raise UnknownKpiError(name, _suggest(name))
    return e


def _suggest(name: str) -> tuple[str, ...]:
    m = _INDEXED.match(str(name))
    if m:  # a per-line name with a misspelt quantity: suggest the concrete name
        return tuple(f"{b}[{m.group('id')}]" for b in difflib.get_close_matches(m.group("base"), list(_BY_BASE),
                                                                                  n=3, cutoff=0.6))
    return tuple(difflib.get_close_matches(str(name), list(KPIS), n=3, cutoff=0.6))


def is_kpi(name: str) -> bool:
    """Whether ``name`` is a catalogue KPI (concrete per-line names included)."""
    return find_kpi(name) is not None


def directions() -> dict[str, str]:
    """``{catalogue name: "minimise" | "maximise" | "none"}`` of every KPI, in column order."""
    return {n: e.direction for n, e in KPIS.items()}


def units() -> dict[str, str]:
    """``{catalogue name: unit}`` of every KPI, in column order."""
    return {n: e.unit for n, e in KPIS.items()}


def kpi_unit(name: str) -> str:
    """Unit of KPI ``name`` (``"N"`` for ``T_max[3]``); ``""`` for a name not in the catalogue
    (a table column that is not a KPI)."""
    e = find_kpi(name)
    return e.unit if e is not None else ""


def kpi_sign(name: str) -> int:
    """-1 if a lower value of KPI ``name`` is better, +1 if higher is better, 0 for neither or a
    name not in the catalogue."""
    e = find_kpi(name)
    return e.sign if e is not None else 0


def _natural(s: str) -> tuple:
    return tuple((0, int(p), "") if p.isdigit() else (1, 0, p) for p in re.split(r"(\d+)", s) if p)


def kpi_order(names: Iterable[str]) -> list[str]:
    """Sort KPI names (duplicates dropped) into the documented column order: the aggregate KPIs in
    catalogue order, then the per-line KPIs grouped by quantity (catalogue order) with line ids
    in natural order (2 before 10), then any other names alphabetically."""

    def key(n: str) -> tuple:
        if n in _ORDER_FIXED:
            return (0, _ORDER_FIXED[n], ())
        m = _INDEXED.match(n)
        if m and m.group("base") in _ORDER_LINE:
            return (1, _ORDER_LINE[m.group("base")], _natural(m.group("id")))
        return (2, 0, (n,))

    return sorted(dict.fromkeys(names), key=key)
