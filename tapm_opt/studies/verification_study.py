"""Limit-state verification of a study run: the ``[verification]`` table of a study file and
``DIR/verification.csv`` / ``DIR/verification.json``, computed from the stored tensions.

A study with a ``[verification]`` table gets, after its cases have run (:func:`run_study
<tapm_opt.studies.runner.run_study>`), or on an existing study directory (``tapm study verify
DIR``, :func:`verify_study`), per controller, condition, sea state and line:

* **ULS** (a condition without a fault) and **ALS** (a condition with one: a line break, a
  thruster failure or a buoy loss; the whole record, the transient after the fault included): the
  most probable maximum (Gumbel fit of the per-seed maxima of ``T_fairlead[<line>]``,
  :func:`~tapm_opt.studies.verification.gumbel_mpm`), the characteristic tension with the
  consequence class's partial safety factors on its mean and dynamic parts
  (:func:`~tapm_opt.studies.verification.characteristic_tension`), the utilisation against the
  line's characteristic capacity (:func:`~tapm_opt.studies.verification.utilisation`) and the
  verdict. The line a condition breaks is left out of its ALS rows (its record after the break
  is 0).
* every line is checked at its fairlead section (``T_fairlead[<line>]``) and, on a composite
  line, at the top of every section below it (``T_section[<line>/<k>]``, :func:`checked_sections`),
  each against its own line type (MBS, capacity factor, T-N curve);
* **FLS** (conditions without a fault): rainflow ranges of each section's tension, its line
  type's T-N curve, the nominal area, Miner's damage per record
  (:func:`~tapm_opt.studies.verification.miner_damage`, the mean over the seeds) and, with
  sea-state probabilities, each sea state's annual damage and the line's fatigue life with the
  design fatigue factor (:func:`~tapm_opt.studies.verification.annual_damage`,
  :func:`~tapm_opt.studies.verification.fatigue_life`), the design fatigue factor a number or
  DNV-OS-E301's from the adjacent line (``design_fatigue_factor = "adjacent"``,
  :func:`~tapm_opt.studies.verification.adjacent_fatigue_factor`).
* per controller, condition and sea state: the most probable maximum of the turret offset against
  the safe circle and, with a riser, of the riser's end angles against their critical angles
  (``verification.json`` and the report; not rows of the CSV, whose rows are lines).

Every formula is one of :mod:`tapm_opt.studies.verification`; this module only selects the
records, groups them and writes the files. Conventions, columns and sources: ``docs/verification.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .._checks import fmt as _fmt
from .._io import atomic_write_text, csv_text
from ..geometry import turret_offset
from ..models.fatigue import CHAIN_HYDRODYNAMIC_RATIO, default_component, default_nominal_diameter
from ..plant.simulator import section_channel
from ..standards import DNV_CAPACITY_FACTOR
from . import store
from ._checks import Checker
from .kpis import _tmean, break_times
from .store import StudyError
from .verification import (DFF_ADJACENT_BASE, TN_CURVES, adjacent_fatigue_factor, annual_damage,
                           characteristic_tension, damage_ratio, fatigue_life, gumbel_mpm, line_neighbours,
                           miner_damage, nominal_area, partial_safety_factors, recommended_realisations,
                           utilisation)

__all__ = [
    "VERIFICATION_CSV", "VERIFICATION_JSON", "CSV_COLUMNS", "STANDARDS", "MPM_METHODS", "COMPONENTS",
    "CHAIN_HYDRODYNAMIC_RATIO", "DEFAULT_DESIGN_FATIGUE_FACTOR", "SAMPLES_PER_PEAK_PERIOD", "DFF_RULES",
    "VerificationSettings", "LineTypeCurve", "Verification",
    "check_verification", "verification_settings", "line_type_curves", "dt_log_warning",
    "verify_study", "write_verification", "read_verification_table", "checked_sections",
]

#: The files a verification writes into the study directory.
VERIFICATION_CSV = "verification.csv"
VERIFICATION_JSON = "verification.json"

#: The columns of ``verification.csv``, in order (kept stable; new ones only at the end).
CSV_COLUMNS: tuple[str, ...] = (
    "controller", "condition", "sea_state", "line", "limit_state",
    "n_seeds", "T_mpm", "T_c", "utilisation", "verdict",
    "a_D", "m", "area", "damage", "annual_damage", "life_years",
    "section", "line_type", "channel", "dff",
)

#: Standards a ``[verification]`` table may name.
STANDARDS: tuple[str, ...] = ("DNV-OS-E301",)
#: Ways of fitting the Gumbel distribution to the per-seed maxima (:func:`gumbel_mpm`).
MPM_METHODS: tuple[str, ...] = ("mle", "moments")
#: Components a line type's T-N curve may be taken from: the curves of :data:`TN_CURVES`, or
#: ``"custom"`` (then ``a_D``, ``m`` and ``area`` are given).
COMPONENTS: tuple[str, ...] = (*TN_CURVES, "custom")
#: Default design fatigue factor: the lowest of the 5-10 quoted in the project's standards notes
#: (secondary transcription of DNV-OS-E301, unchecked); set ``design_fatigue_factor``.
DEFAULT_DESIGN_FATIGUE_FACTOR = 5.0
#: Rules a ``design_fatigue_factor`` may name instead of a number: ``"adjacent"``, DNV-OS-E301's
#: factor from the damage ratio of a line and its more damaged neighbour
#: (:func:`~tapm_opt.studies.verification.adjacent_fatigue_factor`; secondary reading, unchecked).
DFF_RULES: tuple[str, ...] = ("adjacent",)
#: Fewest logged samples per peak period of a sea state before the fatigue ranges and the maxima
#: are flagged as under-sampled: ``dt_log > Tp / 10`` warns. A sinusoid at the peak period sampled
#: 10 times a cycle loses up to ``1 - cos(pi / 10)`` = 4.9 % of its range (up to 14 % of its damage
#: for m = 3); the shorter waves of the spectrum lose more. ``dt_log <= Tp / 20`` keeps the loss
#: at the peak period under 1.3 %.
SAMPLES_PER_PEAK_PERIOD = 10

_KEYS = {"standard", "consequence_class", "mpm_method", "common_factor", "t_start", "design_fatigue_factor",
         "design_life", "probabilities", "line_types", "sections"}
_LINE_TYPE_KEYS = {"component", "nominal_diameter", "a_D", "m", "area", "capacity_factor"}
_FAULTS_ALS = ("line_break", "thruster_failure", "buoy_loss")


# -- the [verification] table -----------------------------------------------------------------


@dataclass(frozen=True)
class VerificationSettings:
    """A checked ``[verification]`` table.

    Attributes
    ----------
    standard : str
        ``"DNV-OS-E301"`` (the only one).
    consequence_class : int
        1 or 2 (DNV-OS-E301): the partial safety factors of the strength check.
    mpm_method : str
        ``"mle"`` (default) or ``"moments"``: the Gumbel fit of the per-seed maxima.
    common_factor : bool
        The class-1 ULS common factor 1.3 (:func:`characteristic_tension`; default True).
    t_start : float
        Samples before this time [s] are left out of every statistic (default 0: the whole record).
    design_fatigue_factor : float or str
        DFF >= 1 on the fatigue damage (default :data:`DEFAULT_DESIGN_FATIGUE_FACTOR`), or
        ``"adjacent"`` (:data:`DFF_RULES`): per FLS row DNV-OS-E301's factor from the damage ratio
        with the more damaged neighbouring line (docs/verification.md).
    design_life : float or None
        Design life [years]; with probabilities, the FLS verdict is life >= design_life.
    probabilities : dict or None
        ``{sea state id: probability of occurrence}`` for every sea state of the study (each in
        [0, 1], summing to at most 1), or None: no annual damage.
    line_types : dict
        ``{line type id: {component, nominal_diameter, a_D, m, area, capacity_factor}}`` as given
        (any subset; the rest by default, :func:`line_type_curves`).
    sections : bool
        Also check every section below the fairlead section of a composite line, at its top
        (``T_section[<line>/<k>]``, :func:`checked_sections`), each against its own line type
        (default False: one row per line and limit state, from ``T_fairlead[<line>]``; with True
        the rows of a line are told apart by ``section`` and ``channel``).
    """

    consequence_class: int
    standard: str = "DNV-OS-E301"
    mpm_method: str = "mle"
    common_factor: bool = True
    t_start: float = 0.0
    design_fatigue_factor: float | str = DEFAULT_DESIGN_FATIGUE_FACTOR
    design_life: float | None = None
    probabilities: dict | None = None
    line_types: dict = field(default_factory=dict)
    sections: bool = False

    def as_dict(self) -> dict:
        """JSON-ready, every default filled in."""
        return {"standard": self.standard, "consequence_class": self.consequence_class,
                "mpm_method": self.mpm_method, "common_factor": self.common_factor, "t_start": self.t_start,
                "design_fatigue_factor": self.design_fatigue_factor, "design_life": self.design_life,
                "probabilities": None if self.probabilities is None else dict(self.probabilities),
                "line_types": {k: dict(v) for k, v in self.line_types.items()}, "sections": self.sections}


def check_verification(ck: Checker, table: Any, scenario: Any, sea_states: Sequence[str] | None, *,
                       duration: float | None = None, where: str = "verification") -> VerificationSettings | None:
    """Check a ``[verification]`` table, every problem recorded in ``ck`` with its field path.

    ``scenario`` (the study's, or None when it could not be loaded: the line types are then not
    checked) gives the line type ids; ``sea_states`` the study's sea-state ids (None: not
    checked); ``duration`` [s] the study's, which ``t_start`` must be below. Returns the settings,
    or None when anything was wrong.
    """
    n0 = len(ck.issues)
    tab = ck.table(table, where)
    if tab is None:
        return None
    ck.keys(tab, _KEYS, where)
    standard = ck.choice(tab.get("standard", STANDARDS[0]), STANDARDS, f"{where}.standard")
    cc = None
    if "consequence_class" not in tab:
        ck.err(f"{where}.consequence_class", "missing required field (1 or 2, DNV-OS-E301's consequence class)")
    else:
        v = tab["consequence_class"]
        if isinstance(v, bool) or not isinstance(v, int) or v not in (1, 2):
            ck.err(f"{where}.consequence_class", f"= {_fmt(v)} is not one of 1, 2 (DNV-OS-E301's consequence "
                   "classes)")
        else:
            cc = int(v)
    method = ck.choice(tab.get("mpm_method", "mle"), MPM_METHODS, f"{where}.mpm_method")
    common = ck.boolean(tab.get("common_factor", True), f"{where}.common_factor")
    with_sections = ck.boolean(tab.get("sections", False), f"{where}.sections")
    t_start = ck.number(tab.get("t_start", 0.0), f"{where}.t_start", unit="s", nonneg=True)
    if t_start is not None and duration is not None and t_start >= duration:
        ck.err(f"{where}.t_start", f"= {_fmt(float(t_start))} s must be below the study's duration ({duration:g} s)")
    dff_in = tab.get("design_fatigue_factor", DEFAULT_DESIGN_FATIGUE_FACTOR)
    if isinstance(dff_in, str):
        dff = ck.choice(dff_in, DFF_RULES, f"{where}.design_fatigue_factor")
    else:
        dff = ck.number(dff_in, f"{where}.design_fatigue_factor", positive=True)
        if dff is not None and dff < 1.0:
            ck.err(f"{where}.design_fatigue_factor", f"= {_fmt(dff)} must be >= 1 (it multiplies the damage)")
    life = None
    if "design_life" in tab:
        life = ck.number(tab["design_life"], f"{where}.design_life", unit="years", positive=True)
    probs = _check_probabilities(ck, tab["probabilities"], sea_states, f"{where}.probabilities") \
        if "probabilities" in tab else None
    lts = _check_line_types(ck, tab["line_types"], scenario, f"{where}.line_types") if "line_types" in tab else {}
    if len(ck.issues) > n0:
        return None
    return VerificationSettings(standard=standard, consequence_class=cc, mpm_method=method, common_factor=common,
                                t_start=float(t_start),
                                design_fatigue_factor=dff if isinstance(dff, str) else float(dff),
                                design_life=None if life is None else float(life), probabilities=probs,
                                line_types=lts, sections=bool(with_sections))


def _check_probabilities(ck: Checker, value: Any, sea_states: Sequence[str] | None, where: str) -> dict | None:
    tab = ck.table(value, where)
    if tab is None:
        return None
    out: dict[str, float] = {}
    for sid, p in tab.items():
        if sea_states is not None and sid not in sea_states:
            ck.err(f"{where}.{sid}", f"is not a sea state of the study (its sea states: {', '.join(sea_states)})")
            continue
        x = ck.number(p, f"{where}.{sid}", at_most=1.0, nonneg=True)
        if x is not None:
            out[str(sid)] = float(x)
    total = sum(out.values())
    if total > 1.0 + 1e-9:
        ck.err(where, f"sum to {total:g}, more than 1 (each is the share of the year in that sea state)")
    if sea_states is not None:
        missing = [s for s in sea_states if s not in tab]
        if missing:
            ck.err(where, "no probability for sea state(s) " + ", ".join(repr(s) for s in missing)
                   + ": give every sea state of the study one (0 for a sea state that should not count)")
    return out


def _check_line_types(ck: Checker, value: Any, scenario: Any, where: str) -> dict:
    tab = ck.table(value, where)
    if tab is None:
        return {}
    ids = None if scenario is None else [lt.id for lt in scenario.line_types]
    out: dict[str, dict] = {}
    for tid, e in tab.items():
        p = f"{where}.{tid}"
        if ids is not None and tid not in ids:
            ck.err(p, f"is not a line type of scenario {scenario.name!r} (line types: {', '.join(ids)})")
            continue
        t = ck.table(e, p)
        if t is None:
            continue
        ck.keys(t, _LINE_TYPE_KEYS, p)
        got: dict[str, Any] = {}
        if "component" in t:
            got["component"] = ck.choice(t["component"], COMPONENTS, f"{p}.component")
        for key, unit in (("nominal_diameter", "m"), ("a_D", ""), ("m", ""), ("area", "m^2"),
                          ("capacity_factor", "")):
            if key in t:
                x = ck.number(t[key], f"{p}.{key}", unit=unit, positive=True,
                              at_most=1.0 if key == "capacity_factor" else None)
                if x is not None and key == "nominal_diameter" and x > 2.0:
                    ck.err(f"{p}.{key}", f"= {_fmt(x)} m is larger than any chain or rope: give it in metres "
                           "(0.137 for 137 mm)")
                    x = None
                got[key] = x
        if got.get("component") == "custom":
            need = [k for k in ("a_D", "m", "area") if k not in t]
            if need:
                ck.err(p, "component = 'custom' needs " + ", ".join(need) + " (no curve to take them from)")
        if None not in got.values():
            out[str(tid)] = got
    return out


def verification_settings(table: Any, scenario: Any = None, sea_states: Sequence[str] | None = None, *,
                          duration: float | None = None, source: str = "") -> VerificationSettings:
    """The checked settings of a ``[verification]`` table (:func:`check_verification`).

    Raises
    ------
    StudyError
        Listing every problem, each naming its field (``verification.consequence_class = 3 is not
        one of 1, 2 ...``).
    """
    ck = Checker()
    s = check_verification(ck, table, scenario, sea_states, duration=duration)
    if ck.issues or s is None:
        raise StudyError(list(dict.fromkeys(ck.issues)) or "verification: invalid table", source=source)
    return s


# -- T-N curves of the line types ------------------------------------------------------------


@dataclass(frozen=True)
class LineTypeCurve:
    """The fatigue curve and strength of one line type as the verification uses them.

    ``component`` a key of :data:`TN_CURVES` or ``"custom"``; ``nominal_diameter`` [m] (None when
    ``area`` was given for a custom curve); ``a_D``, ``m`` the T-N curve ``n = a_D s^-m`` (s in
    MPa); ``area`` [m²] the nominal area; ``capacity_factor`` the characteristic capacity as a
    fraction of the MBS; ``inferred`` which of ``component`` and ``nominal_diameter`` were taken by
    default (from the line type's id and diameter) rather than from the table.
    """

    line_type: str
    component: str
    nominal_diameter: float | None
    a_D: float
    m: float
    area: float
    capacity_factor: float
    inferred: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        return {"component": self.component, "nominal_diameter": self.nominal_diameter, "a_D": self.a_D,
                "m": self.m, "area": self.area, "capacity_factor": self.capacity_factor,
                "inferred": list(self.inferred)}


def line_type_curves(settings: VerificationSettings, scenario: Any,
                     type_ids: Sequence[str] | None = None) -> dict[str, LineTypeCurve]:
    """The :class:`LineTypeCurve` of each line type (default: the type of every section the
    verification checks, :func:`checked_sections`: the lines' fairlead types first, then the
    other sections' types).

    Defaults for what ``settings.line_types[<id>]`` does not give: ``component`` from the type's
    id — ``studlink`` in it: studlink chain, else ``chain``: studless chain, else ``spiral``:
    spiral-strand wire, else ``polyester``, or ``poly`` then a digit (``poly240``): polyester rope (its curve in range / MBS, the area
    ``MBS / 1 MPa``), else six-strand wire (the most damaging wire curve); ``nominal_diameter``
    the type's ``diameter`` divided by :data:`CHAIN_HYDRODYNAMIC_RATIO` for chain (whose
    ``diameter`` is the hydrodynamic one, 1.8 d, in the built-in scenarios), the ``diameter`` itself
    otherwise; ``a_D`` and ``m`` the component's :data:`TN_CURVES`; ``area``
    :func:`~tapm_opt.studies.verification.nominal_area`; ``capacity_factor``
    :data:`~tapm_opt.standards.DNV_CAPACITY_FACTOR` (0.95, chain's definition).
    """
    ids = list(dict.fromkeys(type_ids if type_ids is not None else [ln.type for ln in scenario.lines]
                             + [c[1] for ln in scenario.lines for c in checked_sections(ln, settings.sections)]))
    out: dict[str, LineTypeCurve] = {}
    for tid in ids:
        lt = scenario.line_type_by_id(tid)
        given = settings.line_types.get(tid, {})
        inferred: list[str] = []
        comp = given.get("component")
        if comp is None:
            comp = default_component(tid)
            inferred.append("component")
        curve = TN_CURVES.get(comp)
        d = given.get("nominal_diameter")
        if "area" in given:
            area = float(given["area"])
        elif curve is not None and curve.bars == 0:   # a curve in range / MBS: the type's strength
            area = nominal_area(comp, MBS=float(lt.MBS))
        else:
            if d is None:
                d = default_nominal_diameter(comp, lt.diameter)
                inferred.append("nominal_diameter")
            area = nominal_area(comp, d)
        out[tid] = LineTypeCurve(
            line_type=tid, component=comp, nominal_diameter=None if d is None else float(d),
            a_D=float(given.get("a_D", curve.a_D if curve else math.nan)),
            m=float(given.get("m", curve.m if curve else math.nan)), area=float(area),
            capacity_factor=float(given.get("capacity_factor", DNV_CAPACITY_FACTOR)), inferred=tuple(inferred))
    return out


def dt_log_warning(dt_log: float, sea_state: Any) -> str | None:
    """A warning when ``dt_log`` [s] is too coarse for the wave cycles of ``sea_state`` (``Tp``
    [s], ``Hs`` [m]): ``dt_log > Tp / SAMPLES_PER_PEAK_PERIOD`` in a sea state with waves; None when
    fine."""
    if sea_state is None or float(getattr(sea_state, "Hs", 0.0)) <= 0.0:
        return None
    tp = float(sea_state.Tp)
    limit = tp / SAMPLES_PER_PEAK_PERIOD
    if dt_log <= limit * (1.0 + 1e-9):
        return None
    return (f"sea state {sea_state.id!r}: dt_log = {dt_log:g} s is coarser than Tp/{SAMPLES_PER_PEAK_PERIOD} = "
            f"{limit:.3g} s (Tp = {tp:g} s): the wave-frequency tension cycles are under-sampled, so the rainflow "
            f"ranges (FLS damage) and the maxima (ULS/ALS) are underestimated; run with dt_log <= {tp / 20:.3g} s "
            "(Tp/20) for fatigue")


def checked_sections(line: Any, sections: bool = True) -> list[tuple[int, str, str, str]]:
    """The sections of a scenario line the verification checks, each ``(k, line type id, channel,
    kind)``: the fairlead section first (``k`` = its index, 0 for a line of one section; channel
    ``T_fairlead[<id>]``; kind ``"fairlead"``), then, with ``sections`` (the table's ``sections =
    true``), every section below it from the top down (channel ``T_section[<id>/<k>]``,
    :func:`~tapm_opt.plant.simulator.section_channel`; kind ``"section"``). ``k`` counts from the
    anchor up from 0, the scenario's ``sections`` order."""
    parts = line.parts
    n = len(parts)
    out = [(n - 1, str(line.type), f"T_fairlead[{line.id}]", "fairlead")]
    if sections:
        out += [(k, str(parts[k].type), section_channel(line.id, k), "section") for k in range(n - 2, -1, -1)]
    return out


# -- the computation -----------------------------------------------------------------------------


@dataclass
class Verification:
    """A study run's verification (:func:`verify_study`).

    Attributes
    ----------
    settings : VerificationSettings
    curves : dict
        ``{line type id: LineTypeCurve}`` used.
    rows : list of dict
        One per controller, condition, sea state, line and limit state: the :data:`CSV_COLUMNS`
        (None where a column does not apply) and the details of ``verification.json`` (``T_mean``,
        ``T_dyn``, ``gamma_mean``, ``gamma_dyn``, ``MBS``, ``capacity_factor``, ``mu``, ``beta``,
        ``seeds``, ``maxima``, ``cases``, ``damages``, ``record_durations``, ...).
    offsets : list of dict
        One per controller, condition, sea state and quantity (``"turret offset"`` against the
        safe radius; ``"riser top angle"``, ``"riser bottom angle"`` against the critical angles):
        ``n_seeds``, ``mpm``, ``limit``, ``ratio``, ``verdict``, ``unit`` (m or rad), ``maxima``.
    excluded : list of dict
        The lines left out of ALS rows (broken by the condition): controller, condition,
        sea_state, line, reason.
    warnings : list of str
    csv_path, json_path : Path or None
        The files written (None when not written).
    """

    settings: VerificationSettings
    curves: dict
    rows: list
    offsets: list
    excluded: list
    warnings: list
    csv_path: Path | None = None
    json_path: Path | None = None

    def csv_text(self) -> str:
        """The text of ``verification.csv``: :data:`CSV_COLUMNS`, full-precision floats, empty
        cells where a column does not apply."""
        return csv_text(CSV_COLUMNS, ([r.get(c) for c in CSV_COLUMNS] for r in self.rows))

    def as_json(self) -> dict:
        """The content of ``verification.json`` (non-finite numbers as the strings "inf", "nan")."""
        from .. import __version__

        return _json_ready({"format": "tapm-verification/1", "tapm_opt_version": __version__,
                            "settings": self.settings.as_dict(),
                            "partial_safety_factors": {ls: list(partial_safety_factors(
                                self.settings.consequence_class, ls)) for ls in ("ULS", "ALS")},
                            "line_types": {k: c.as_dict() for k, c in self.curves.items()},
                            "columns": list(CSV_COLUMNS), "rows": self.rows, "offsets": self.offsets,
                            "excluded": self.excluded, "warnings": self.warnings})


def _json_ready(o: Any) -> Any:
    if isinstance(o, dict):
        return {k: _json_ready(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_json_ready(v) for v in o]
    if isinstance(o, (float, np.floating)):
        f = float(o)
        return f if math.isfinite(f) else ("inf" if f > 0 else "-inf" if f < 0 else "nan")
    if isinstance(o, np.integer):
        return int(o)
    return o


def read_verification_table(study_dir: str | Path, study_file: str | Path | None = None) -> Any:
    """The ``[verification]`` table of ``study_file`` (default ``DIR/study.toml``, the study file as
    run), or None when it has none.

    Raises
    ------
    StudyError
        The file is missing or not valid TOML.
    """
    path = Path(study_file) if study_file is not None else Path(study_dir) / store.STUDY_TOML
    data, _ = store.read_study_file(path)
    return data.get("verification")


@dataclass
class _Group:
    controller: str
    condition: str
    sea_state: str
    records: list = field(default_factory=list)


def verify_study(study_dir: str | Path, table: Any = None, *, write: bool = True,
                 source: str = "") -> Verification:
    """The verification of the study run in ``study_dir`` from its stored results.

    Parameters
    ----------
    study_dir : path
        A study run directory (:mod:`tapm_opt.studies.store`); its finished cases are used (failed
        and unfinished cases are left out, with a warning).
    table : mapping, optional
        The ``[verification]`` table; default: the one of ``DIR/study.toml``.
    write : bool
        Write ``DIR/verification.csv`` and ``DIR/verification.json`` (each atomically, after
        everything is computed: an error writes nothing).
    source : str
        Name of the table's file in error messages.

    Raises
    ------
    StudyError
        ``study_dir`` is not a study directory, has no ``[verification]`` table (and none is
        given), or the table is invalid (every problem named with its field).
    """
    out = Path(study_dir)
    records = store.load_study_results(out)
    if table is None:
        table = read_verification_table(out)
        source = source or str(out / store.STUDY_TOML)
        if table is None:
            raise StudyError(f"{out / store.STUDY_TOML} has no [verification] table: add one (docs/verification.md) "
                             "or pass the table")
    done = [r for r in records if r.status == "finished"]
    warnings: list[str] = []
    left = [r for r in records if r.status != "finished"]
    if left:
        warnings.append(f"{len(left)} of {len(records)} cases are not finished ("
                        + ", ".join(f"{r.name}: {r.status}" for r in left[:5]) + (", ..." if len(left) > 5 else "")
                        + "): left out of the verification")
    scenario = done[0].scenario() if done else None
    sea_ids = list(dict.fromkeys(str(r.labels.get("sea_state")) for r in records))
    durations = [float(r.inputs.get("duration", math.inf)) for r in records]
    settings = verification_settings(table, scenario, sea_ids, duration=max(durations, default=None),
                                     source=source)
    res = Verification(settings=settings, curves={}, rows=[], offsets=[], excluded=[], warnings=warnings)
    # at least two logged samples from t_start on
    short = [r for r in done if not float(r.inputs.get("duration", math.inf)) >= settings.t_start + float(
        (r.inputs.get("closed_loop") or {}).get("dt_log", 1.0))]
    if short:
        warnings.append(f"{len(short)} case(s) end before t_start = {settings.t_start:g} s (" + ", ".join(
            r.name for r in short[:5]) + (", ..." if len(short) > 5 else "") + "): left out of the verification")
        done = [r for r in done if r not in short]
    if scenario is None:
        warnings.append("no finished case: nothing to verify")
    else:
        res.curves = line_type_curves(settings, scenario)
        for tid, c in res.curves.items():
            if c.inferred:
                warnings.append(f"line type {tid!r}: " + ", ".join(
                    f"{k} = {_fmt(getattr(c, k)) if k != 'component' else repr(c.component)}" for k in c.inferred)
                    + " by default (docs/verification.md); set [verification.line_types." + tid + "] to state them")
        _compute(res, _groups(done), scenario)
    if write:
        write_verification(res, out)
    return res


def write_verification(res: Verification, study_dir: str | Path) -> tuple[Path, Path]:
    """Write ``verification.json`` and ``verification.csv`` of ``res`` into ``study_dir``, each
    atomically (both texts are built before either is written)."""
    import json

    out = Path(study_dir)
    csv_t = res.csv_text()
    json_t = json.dumps(res.as_json(), indent=2, allow_nan=False) + "\n"
    res.json_path = atomic_write_text(out / VERIFICATION_JSON, json_t)
    res.csv_path = atomic_write_text(out / VERIFICATION_CSV, csv_t)
    return res.csv_path, res.json_path


def _groups(done: Sequence[Any]) -> list[_Group]:
    """The finished cases by (controller, condition, sea state), ordered by controller, then
    condition, then sea state, each in the order the study lists them."""
    order: dict[str, dict[str, int]] = {"controller": {}, "condition": {}, "sea_state": {}}
    groups: dict[tuple[str, str, str], _Group] = {}
    for r in done:
        key = tuple(str(r.labels.get(k)) for k in ("controller", "condition", "sea_state"))
        for k, v in zip(order, key):
            order[k].setdefault(v, len(order[k]))
        g = groups.setdefault(key, _Group(*key))
        g.records.append(r)
    return sorted(groups.values(), key=lambda g: (order["controller"][g.controller],
                                                   order["condition"][g.condition],
                                                   order["sea_state"][g.sea_state]))


def _sea_state_of(record: Any) -> Any:
    """The sea state a case ran in (None for still water)."""
    sid = record.inputs.get("sea_state")
    try:
        return None if sid is None else record.scenario().sea_state(sid)
    except KeyError:
        return None


def _fit(values: Sequence[float], method: str) -> Any:
    return gumbel_mpm(values, method=method) if len(values) >= 2 else None


def _compute(res: Verification, groups: Sequence[_Group], scenario: Any) -> None:
    s = res.settings
    lines = list(scenario.lines)
    sections = {ln.id: checked_sections(ln, s.sections) for ln in lines}
    # (controller, condition, line, section) -> FLS rows
    fls_by_line: dict[tuple[str, str, str, int], list[dict]] = {}
    fls_rows: list[dict] = []
    missing: dict[str, list[str]] = {}
    warned_dt: set[tuple[str, float]] = set()
    for g in groups:
        where = f"{g.controller}, {g.condition}, {g.sea_state}"
        faults = [f for f in (g.records[0].inputs.get("scenario", {}).get("faults") or [])
                  if isinstance(f, Mapping) and f.get("kind") in _FAULTS_ALS]
        ls = "ALS" if faults else "ULS"
        broken = {str(f.get("line")) for f in faults if f.get("kind") == "line_break"}
        t_fault = min((float(f.get("time", 0.0)) for f in faults), default=None)
        if t_fault is not None and s.t_start > t_fault:
            res.warnings.append(f"{where}: t_start = {s.t_start:g} s is after the fault at {t_fault:g} s: the ALS "
                                "statistics miss the transient")
        durations = sorted({float(r.inputs.get("duration", math.nan)) for r in g.records})
        if len(durations) > 1:
            res.warnings.append(f"{where}: records of different durations ({', '.join(f'{d:g}' for d in durations)} "
                                "s) in one group: the Gumbel fit and the mean damage assume one duration")
        ss = _sea_state_of(g.records[0])
        for r in g.records:
            dt_log = float((r.inputs.get("closed_loop") or {}).get("dt_log", math.nan))
            w = dt_log_warning(dt_log, ss)
            if w and (g.sea_state, dt_log) not in warned_dt:
                warned_dt.add((g.sea_state, dt_log))
                res.warnings.append(w)
        n_rec, warn = recommended_realisations(len(g.records))
        if warn:
            res.warnings.append(f"{where}: {warn}" + ("; no Gumbel fit with one seed: T_mpm, T_c and utilisation are "
                                                      "left empty, verdict n/a" if len(g.records) < 2 else ""))
        per_seed = [_seed_stats(r, lines, scenario, s.t_start, t_fault, broken, sections) for r in g.records]
        seeds = [int(r.labels.get("seed", -1)) for r in g.records]
        ids = [r.id for r in g.records]
        for ln in lines:
            lid = ln.id
            if ls == "ALS" and lid in broken:
                res.excluded.append({"controller": g.controller, "condition": g.condition, "sea_state": g.sea_state,
                                     "line": lid, "reason": "broken by the condition: its record after the break "
                                                            "is 0"})
                continue
            for k, tid, channel, _kind in sections[lid]:
                st = [p["sections"][(lid, k)] for p in per_seed]
                if any(x is None for x in st):   # a result stored before the plant logged the channel
                    missing.setdefault(channel, []).extend(str(r.name) for r, x in zip(g.records, st) if x is None)
                    continue
                where_s = {"section": k, "line_type": tid, "channel": channel}
                mbs = float(scenario.line_type_by_id(tid).MBS)
                res.rows.append(_strength_row(g, ls, lid, st, seeds, ids, mbs, res.curves[tid], s,
                                              n_rec, res.warnings, where) | where_s)
                if ls == "ULS":
                    row = _fatigue_row(g, lid, st, seeds, ids, res.curves[tid]) | where_s
                    res.rows.append(row)
                    fls_rows.append(row)
                    fls_by_line.setdefault((g.controller, g.condition, lid, k), []).append(row)
        _offset_rows(res, g, ls, per_seed, seeds, scenario, where)
    for channel, cases in missing.items():
        res.warnings.append(f"channel {channel} is not in the stored results of {len(cases)} case(s) ("
                            + ", ".join(cases[:3]) + (", ..." if len(cases) > 3 else "")
                            + "), run before the plant logged the tension at the top of each section: that "
                            "section is not checked there; run the study again in a new directory to check it")
    if s.probabilities is not None:
        _annual(res, fls_by_line)
    _design_fatigue_factors(res, fls_rows, scenario, fls_by_line)


def _seed_stats(r: Any, lines: Sequence[Any], scenario: Any, t_start: float, t_fault: float | None,
                broken: set[str], sections: Mapping[str, list] | None = None) -> dict:
    """One case's per-line maximum, mean and damage inputs (``lines``: the fairlead tension;
    ``sections``: every checked section's channel, :func:`checked_sections`, None where the stored
    result lacks it), and its offset and riser maxima."""
    result = r.load_result()
    t_all = np.asarray(result.time, float)
    win = t_all >= t_start - 1e-9
    t = t_all[win]
    eps = 1e-9 * max(1.0, abs(float(t[-1]))) if len(t) else 0.0
    ids = [ln.id for ln in lines]
    brk = break_times(result, ids)
    out: dict[str, Any] = {"lines": {}, "sections": {}, "duration": float(t[-1] - t[0]) if len(t) > 1 else 0.0}
    chans = set(result.channels)
    for lid in ids:
        T = np.asarray(result[f"T_fairlead[{lid}]"], float)[win]
        out["lines"][lid] = _channel_stats(T, t, brk.get(lid, math.inf), eps, t_fault, lid in brk and lid not in broken)
        for k, _tid, ch, kind in (sections or {}).get(lid, ()):   # the fairlead section is the line's
            out["sections"][(lid, k)] = (out["lines"][lid] if kind == "fairlead" else
                                         _channel_stats(np.asarray(result[ch], float)[win], t, brk.get(lid, math.inf),
                                                        eps, t_fault, False) if ch in chans else None)
    off = np.hypot(*turret_offset(np.stack([result["x"][win], result["y"][win], result["psi"][win]], axis=-1),
                                  scenario.turret.position))
    out["offset"] = float(off.max()) if off.size else math.nan
    for end in ("top", "bottom"):
        ch = f"riser_{end}_angle"
        if ch in result:
            a = np.asarray(result[ch], float)[win]
            out[f"riser_{end}"] = float(a.max()) if a.size else math.nan
    return out


def _channel_stats(T: np.ndarray, t: np.ndarray, t_break: float, eps: float, t_fault: float | None,
                   overload: bool) -> dict:
    """Maximum, time-weighted mean (after ``t_fault``, the damaged condition's, when given), the
    series and its duration of one tension channel ``T`` [N] at times ``t`` [s] while its line is
    alive (up to ``t_break``); ``overload``: the line broke from overload (not by the condition)."""
    alive = t <= t_break + eps
    ta, Ta = t[alive], T[alive]
    if t_fault is not None:
        after = ta >= t_fault - eps
        tm_t, tm_T = (ta[after], Ta[after]) if after.sum() >= 2 else (ta, Ta)
    else:
        tm_t, tm_T = ta, Ta
    return {
        "max": float(Ta.max()) if Ta.size else math.nan,
        "mean": _tmean(tm_t, tm_T) if tm_T.size else math.nan,
        "series": Ta, "duration": float(ta[-1] - ta[0]) if ta.size > 1 else 0.0,
        "overload": overload,
    }


def _strength_row(g: _Group, ls: str, lid: str, st: Sequence[dict], seeds: list, ids: list, mbs: float,
                  curve: LineTypeCurve, s: VerificationSettings, n_rec: int, warnings: list, where: str) -> dict:
    maxima = [x["max"] for x in st]
    means = [x["mean"] for x in st]
    fit = _fit(maxima, s.mpm_method)
    row: dict[str, Any] = {"controller": g.controller, "condition": g.condition, "sea_state": g.sea_state,
                           "line": lid, "limit_state": ls, "n_seeds": len(st)}
    t_mean = float(np.mean(means))
    g_mean, g_dyn = partial_safety_factors(s.consequence_class, ls)
    detail = {"T_mean": t_mean, "gamma_mean": g_mean, "gamma_dyn": g_dyn, "MBS": mbs,
              "capacity_factor": curve.capacity_factor, "mpm_method": s.mpm_method, "seeds": seeds,
              "maxima": maxima, "means": means, "cases": ids, "recommended_seeds": n_rec}
    if fit is None:
        row.update(T_mpm=None, T_c=None, utilisation=None, verdict="n/a")
    else:
        t_dyn = max(fit.mpm - t_mean, 0.0)
        t_c = characteristic_tension(t_mean, t_dyn, s.consequence_class, ls, common_factor=s.common_factor)
        u = utilisation(t_c, mbs, curve.capacity_factor)
        row.update(T_mpm=fit.mpm, T_c=t_c, utilisation=u, verdict="pass" if u <= 1.0 else "fail")
        detail.update(T_dyn=t_dyn, mu=fit.mu, beta=fit.beta)
    broke = [sd for sd, x in zip(seeds, st) if x["overload"]]
    if broke:
        row["verdict"] = "fail"
        detail["overload_seeds"] = broke
        warnings.append(f"{where}: line {lid} broke from overload in seed(s) {', '.join(map(str, broke))}: its stored "
                        "maximum misses the tension that broke it (between two logged samples); verdict fail")
    row.update(detail)
    return row


def _fatigue_row(g: _Group, lid: str, st: Sequence[dict], seeds: list, ids: list, curve: LineTypeCurve) -> dict:
    damages = [miner_damage(x["series"], curve.a_D, curve.m, curve.area) if x["series"].size >= 2 else 0.0
               for x in st]
    return {"controller": g.controller, "condition": g.condition, "sea_state": g.sea_state, "line": lid,
            "limit_state": "FLS", "n_seeds": len(st), "T_mpm": None, "T_c": None, "utilisation": None,
            "verdict": None, "a_D": curve.a_D, "m": curve.m, "area": curve.area,
            "damage": float(np.mean(damages)), "annual_damage": None, "life_years": None,
            "component": curve.component, "nominal_diameter": curve.nominal_diameter, "seeds": seeds,
            "damages": damages, "record_durations": [x["duration"] for x in st], "cases": ids}


def _annual(res: Verification, fls_by_line: Mapping[tuple[str, str, str, int], list[dict]]) -> None:
    """Each FLS row's sea-state share of the annual damage and, per (controller, condition, line,
    section), their sum ``annual_damage_total`` (the life follows with the design fatigue factor,
    :func:`_design_fatigue_factors`)."""
    s = res.settings
    probs = s.probabilities or {}
    for (ctrl, cond, lid, _k), rows in fls_by_line.items():
        total = 0.0
        for row in rows:
            p = probs.get(row["sea_state"], 0.0)
            # mean damage rate over the seeds [1/s] as a damage per record of the mean duration
            dur = float(np.mean(row["record_durations"]))
            if not dur > 0:
                continue
            row["annual_damage"] = annual_damage([row["damage"]], [p], dur)
            total += row["annual_damage"]
        missing = [sid for sid, p in probs.items() if p > 0 and sid not in {r["sea_state"] for r in rows}]
        if missing and str(rows[0].get("channel", "")).startswith("T_fairlead["):   # once per line
            res.warnings.append(f"{ctrl}, {cond}, line {lid}: no finished case in sea state(s) "
                                f"{', '.join(missing)}: the annual damage and the life leave them out")
        for row in rows:
            row["annual_damage_total"] = total


def _design_fatigue_factors(res: Verification, fls_rows: Sequence[dict], scenario: Any,
                            fls_by_line: Mapping[tuple[str, str, str, int], list[dict]]) -> None:
    """The design fatigue factor of every FLS row (``dff``) and, with probabilities, the life and
    the verdict of each (controller, condition, line, section).

    A number: that factor. ``"adjacent"``: DNV-OS-E301's ``gamma_F`` from ``d_F``
    (:func:`~tapm_opt.studies.verification.adjacent_fatigue_factor`,
    :func:`~tapm_opt.studies.verification.damage_ratio`) of the row's damage and the larger of its
    two neighbouring lines' (:func:`~tapm_opt.studies.verification.line_neighbours` on the lines'
    fairlead angles), the neighbours' rows of the same section index (a neighbour without that
    section: its fairlead section's row). The damage compared is the annual damage over the sea
    states with probabilities (one factor per line and section), else the damage per record of the
    row's sea state."""
    s = res.settings
    probs = s.probabilities is not None
    if s.design_fatigue_factor not in DFF_RULES:
        for row in fls_rows:
            row["dff"] = float(s.design_fatigue_factor)
    else:
        lines = list(scenario.lines)
        ids = [ln.id for ln in lines]
        top = {ln.id: len(ln.parts) - 1 for ln in lines}
        nb = line_neighbours([ln.fairlead_angle for ln in lines])
        key = (lambda r: (r["controller"], r["condition"], None if probs else r["sea_state"], r["line"], r["section"]))
        index = {key(r): r for r in fls_rows}
        value = (lambda r: r["annual_damage_total"]) if probs else (lambda r: r["damage"])
        lonely = False
        for row in fls_rows:
            i = ids.index(row["line"])
            best = None
            for n in dict.fromkeys(nb[i]):
                if n == i:
                    continue
                k0 = key(row)
                other = index.get(k0[:3] + (ids[n], row["section"])) or index.get(k0[:3] + (ids[n], top[ids[n]]))
                if other is not None and (best is None or value(other) > value(best)):
                    best = other
            if best is None:
                lonely = True
                row.update(dff=DFF_ADJACENT_BASE, d_F=None, dff_neighbour=None)
                continue
            d_F = damage_ratio(value(row), value(best))
            row.update(dff=adjacent_fatigue_factor(d_F), d_F=d_F, dff_neighbour=best["line"],
                       dff_neighbour_section=best["section"])
        if lonely:
            res.warnings.append("design_fatigue_factor = 'adjacent': a line without a neighbouring line (the "
                                f"study's scenario has one line) takes the base factor {DFF_ADJACENT_BASE:g}")
    if not probs:
        return
    for rows in fls_by_line.values():
        life = fatigue_life(rows[0]["annual_damage_total"], rows[0]["dff"])
        for row in rows:
            row["life_years"] = life
            if s.design_life is not None:
                row["verdict"] = "pass" if life >= s.design_life else "fail"


def _offset_rows(res: Verification, g: _Group, ls: str, per_seed: Sequence[dict], seeds: list, scenario: Any,
                 where: str) -> None:
    items = [("turret offset", "offset", "m", scenario.limits.safe_radius, "safe radius")]
    riser = getattr(scenario, "riser", None)
    if riser is not None:
        items += [("riser top angle", "riser_top", "rad", riser.critical_top_angle, "critical top angle"),
                  ("riser bottom angle", "riser_bottom", "rad", riser.critical_bottom_angle, "critical bottom angle")]
    for name, key, unit, limit, limit_name in items:
        maxima = [p[key] for p in per_seed if key in p]
        if len(maxima) != len(per_seed):
            continue
        fit = _fit(maxima, res.settings.mpm_method)
        mpm = None if fit is None else fit.mpm
        ratio = None if (mpm is None or not limit) else mpm / float(limit)
        res.offsets.append({"controller": g.controller, "condition": g.condition, "sea_state": g.sea_state,
                            "limit_state": ls, "quantity": name, "unit": unit, "n_seeds": len(maxima), "mpm": mpm,
                            "limit": None if not limit else float(limit), "limit_name": limit_name,
                            "ratio": ratio,
                            "verdict": "n/a" if ratio is None else ("pass" if ratio <= 1.0 else "fail"),
                            "maxima": maxima, "seeds": seeds})
