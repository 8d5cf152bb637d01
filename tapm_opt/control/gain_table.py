"""The gain-table file format ``tapm_opt.gains/1``: rows, JSON, CSV and Markdown.

A gain table holds, per operating condition (sea state, mooring state, heading), the PID and LQR
design of that condition (``docs/gains.md``). This module is its one reader and writer: the
design code (:mod:`tapm_opt.design.gains`) makes and writes tables, and the scheduled controller
(:class:`~tapm_opt.control.scheduled.GainScheduledPID`) reads them without the design code, so
the imports point models -> control -> design.

``gains.json`` holds everything (complex arrays as ``{"re": [...], "im": [...]}``, non-finite
numbers as ``"inf"``, ``"-inf"``, ``"nan"``; floats in full precision, so a table read back is
identical); ``gains.csv`` one line per row, ``gains.md`` a summary.
"""

from __future__ import annotations

import json
import math
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .._io import atomic_write_text, csv_text, readonly
from ..geometry import ssa, turret_offset
from .pid import ControlError, PIDGains

__all__ = [
    "FORMAT",
    "GainTableError",
    "Condition",
    "PIDRow",
    "LQRRow",
    "GainRow",
    "GainTable",
    "write_gain_tables",
    "load_gain_table",
]

#: Format tag of the files, ``meta["format"]``.
FORMAT = "tapm_opt.gains/1"


class GainTableError(ControlError):
    """A gain table cannot be made or read (bad argument, no equilibrium, bad file)."""


# --- rows ---------------------------------------------------------------------------------

@dataclass(frozen=True, kw_only=True)
class Condition:
    """Operating condition of one table row.

    Attributes
    ----------
    sea_state : str
        Sea-state id of the scenario.
    sea_class : str
        ``"calm"``, ``"normal"`` or ``"extreme"`` (``tapm_opt.design.gains.SEA_CLASSES``).
    mode_set : str
        Key of :data:`~tapm_opt.control.pid.MODE_SETS` used in this condition (by the design:
        that of its class, ``tapm_opt.design.gains.CLASS_MODE_SETS``).
    broken : str
        ``"intact"`` or the id of the one broken line.
    heading : float
        Vessel heading held by the heading controller [rad].
    weathervane : bool
        True if ``heading`` is the weathervane heading of the condition (asked for with
        ``headings=["weathervane"]``), where the mooring balances the yaw moment without thrust.
    """

    sea_state: str
    sea_class: str
    mode_set: str
    broken: str
    heading: float
    weathervane: bool = False

    @property
    def label(self) -> str:
        h = "weathervane" if self.weathervane else f"{math.degrees(self.heading):g}deg"
        return f"{self.sea_state}/{self.broken}/{h}"


@dataclass(frozen=True, kw_only=True, eq=False)
class PIDRow:
    """PID design of one condition (:func:`~tapm_opt.control.pid_design.design_gains`).

    Attributes
    ----------
    periods, damping : ndarray, shape (3,)
        Designed undamped natural periods [s] and relative damping (surge, sway, yaw).
    integral_ratio : float
        Integral pole a / w.
    Kp, Ki, Kd : ndarray, shape (3,)
        Gain diagonals [N/m, N/m, N m/rad], [N/(m s), ..., N m/(rad s)], [N s/m, ..., N m s/rad].
    designed_poles, decoupled_poles : ndarray, shape (3, 3), complex
        Row i: poles asked for DOF i, and achieved on the decoupled DOF i [1/s].
    poles, natural_periods, damping_ratios : ndarray, shape (9,)
        Coupled MIMO closed loop with all four modes (python-control), by magnitude; 2 pi/|p| [s]
        and -Re(p)/|p|.
    stable : bool
        All ``poles`` in the open left half plane.
    poles_modes : ndarray, complex
        Coupled closed loop with only the condition's mode set (what the scheduler runs).
    stable_modes : bool
    gain_margin, phase_margin, crossover, delay_margin : ndarray, shape (3,)
        Loop-at-a-time margins per DOF (see ``docs/gains.md``): gain margin [-] (ratio, inf if
        the phase never crosses -180 deg), phase margin [deg], gain-crossover frequency
        [rad/s] and delay margin phase_margin / crossover [s].
    clamped : tuple of str
        Gains that came out negative and were set to 0 (the poles are then not as designed).
    """

    periods: np.ndarray
    damping: np.ndarray
    integral_ratio: float
    Kp: np.ndarray
    Ki: np.ndarray
    Kd: np.ndarray
    designed_poles: np.ndarray
    decoupled_poles: np.ndarray
    poles: np.ndarray
    natural_periods: np.ndarray
    damping_ratios: np.ndarray
    stable: bool
    poles_modes: np.ndarray
    stable_modes: bool
    gain_margin: np.ndarray
    phase_margin: np.ndarray
    crossover: np.ndarray
    delay_margin: np.ndarray
    clamped: tuple[str, ...] = ()

    @property
    def gains(self) -> PIDGains:
        """The gains as :class:`~tapm_opt.control.pid.PIDGains` (diagonal)."""
        return PIDGains(Kp=self.Kp, Ki=self.Ki, Kd=self.Kd)


@dataclass(frozen=True, kw_only=True, eq=False)
class LQRRow:
    """LQR design of one condition: ``tau = tau_thr - K (x - x_op)``, x = (eta, nu).

    Attributes
    ----------
    Q : ndarray, shape (6,)
        State weight diagonal (1/eta_ref^2, 1/nu_ref^2).
    R : ndarray, shape (3,)
        Input weight diagonal 1/tau_ref^2.
    K : ndarray, shape (3, 6)
        State-feedback gain (``control.lqr``) [N/m, ..., N m s/rad].
    poles, natural_periods, damping_ratios : ndarray, shape (6,)
        eig(A - B K) by magnitude, 2 pi/|p| [s], -Re(p)/|p|.
    stable : bool
    """

    Q: np.ndarray
    R: np.ndarray
    K: np.ndarray
    poles: np.ndarray
    natural_periods: np.ndarray
    damping_ratios: np.ndarray
    stable: bool


@dataclass(frozen=True, kw_only=True, eq=False)
class GainRow:
    """One condition of a :class:`GainTable`.

    Attributes
    ----------
    condition : Condition
    tau_env : ndarray, shape (3,)
        Mean environmental load in {B} [N, N, N m] (``tau_wind + tau_drift + tau_current``).
    tau_wind, tau_drift, tau_current : ndarray, shape (3,)
        Its parts [N, N, N m].
    tau_thr : ndarray, shape (3,)
        Thrust at the operating point: (0, 0, N) with N the yaw moment the heading controller
        holds, ``-(N_moor + N_env)`` [N, N, N m].
    eta : ndarray, shape (3,)
        Offset equilibrium (x [m], y [m], psi [rad]) in {E}.
    M, D, K : ndarray, shape (3, 3)
        Design model at ``eta``: mass incl. added mass, damping, and the catenary stiffness seen
        by {B}-frame errors ``K = MooringModel.stiffness(eta) R(psi)`` [N/m, N/rad, N m/rad].
    A, B : ndarray, shapes (6, 6), (6, 3)
        Linearised design model, states (eta, nu), inputs tau in {B}.
    pid : PIDRow
    lqr : LQRRow
    p_cot_B : ndarray, shape (2,)
        Centre of turret in {B} [m], the reference of :attr:`offset`.
    """

    condition: Condition
    tau_env: np.ndarray
    tau_wind: np.ndarray
    tau_drift: np.ndarray
    tau_current: np.ndarray
    tau_thr: np.ndarray
    eta: np.ndarray
    M: np.ndarray
    D: np.ndarray
    K: np.ndarray
    A: np.ndarray
    B: np.ndarray
    pid: PIDRow
    lqr: LQRRow
    p_cot_B: np.ndarray = field(default_factory=lambda: readonly(np.zeros(2)))

    @property
    def offset(self) -> float:
        """Turret offset of the equilibrium [m]: the centre of turret's distance from its
        field-zero-point position (``geometry.turret_offset``)."""
        return float(math.hypot(*turret_offset(self.eta, self.p_cot_B)))


@dataclass(frozen=True, eq=False)
class GainTable:
    """Rows of gains per condition and the settings that made them.

    Attributes
    ----------
    rows : tuple of GainRow
    meta : dict
        JSON-serialisable: format, scenario, code version, sea-state classes, design settings,
        margin settings, units.
    """

    rows: tuple[GainRow, ...]
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self):
        return iter(self.rows)

    @property
    def sea_states(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.condition.sea_state for r in self.rows))

    @property
    def broken(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.condition.broken for r in self.rows))

    @property
    def headings(self) -> tuple[float, ...]:
        return tuple(dict.fromkeys(r.condition.heading for r in self.rows))

    def find(self, sea_state: str, broken: str = "intact",
             heading: float | str = 0.0) -> GainRow:
        """The row of ``sea_state`` and ``broken`` (``"intact"`` or a line id) whose heading is
        nearest to ``heading`` [rad] (wrapped with ``ssa``); ``heading="weathervane"`` selects
        the weathervane row.

        Raises
        ------
        GainTableError
            No row for that sea state and mooring state.
        """
        cands = [r for r in self.rows
                 if r.condition.sea_state == str(sea_state) and r.condition.broken == str(broken)]
        if not cands:
            raise GainTableError(
                f"no gain-table row for sea_state={sea_state!r}, broken={broken!r}; the table "
                f"has sea states {list(self.sea_states)} and mooring states {list(self.broken)}")
        if heading == "weathervane":
            wv = [r for r in cands if r.condition.weathervane]
            if not wv:
                raise GainTableError(f"no weathervane row for sea_state={sea_state!r}, "
                                     f"broken={broken!r}; make the table with "
                                     f"headings=[..., 'weathervane']")
            return wv[0]
        try:
            h = float(heading)
        except (TypeError, ValueError):
            raise GainTableError(f"heading={heading!r} must be a heading [rad] or "
                                 f"'weathervane'") from None
        return min(cands, key=lambda r: abs(ssa(r.condition.heading - h)))

    # -- serialisation -------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain JSON-able dict (complex as ``{"re": ..., "im": ...}``, inf/nan as strings)."""
        return {"meta": _enc(self.meta), "rows": [_dc_to_dict(r) for r in self.rows]}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> GainTable:
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        GainTableError
            Not a mapping with ``meta.format`` = :data:`FORMAT`, or a malformed row.
        """
        meta = data.get("meta") if isinstance(data, Mapping) else None
        fmt = meta.get("format") if isinstance(meta, Mapping) else None
        if fmt != FORMAT:
            raise GainTableError(f"not a gain table: meta.format={fmt!r}, expected {FORMAT!r}")
        try:
            meta = _dec(meta)
            rows = tuple(_from(GainRow, r) for r in data["rows"])
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, GainTableError):
                raise
            raise GainTableError(f"malformed gain table: {type(exc).__name__}: {exc}") from None
        return cls(rows=rows, meta=meta)


# --- JSON encoding (without the code that made it) ------------------------------------------

def _enc_float(v: float) -> float | str:
    return v if math.isfinite(v) else repr(v)  # 'inf', '-inf', 'nan'


def _enc(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        if np.iscomplexobj(obj):
            return {"re": _enc(obj.real), "im": _enc(obj.imag)}
        return _enc(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (float, np.floating)):
        return _enc_float(float(obj))
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, Mapping):
        return {str(k): _enc(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_enc(v) for v in obj]
    return obj


def _dec(obj: Any) -> Any:
    if isinstance(obj, str) and obj in ("inf", "-inf", "nan"):
        return float(obj)
    if isinstance(obj, list):
        return [_dec(v) for v in obj]
    if isinstance(obj, dict):
        return {k: _dec(v) for k, v in obj.items()}
    return obj


def _arr(value: Any) -> np.ndarray:
    if isinstance(value, dict) and set(value) == {"re", "im"}:
        return readonly(np.asarray(_dec(value["re"]), dtype=float)
                   + 1j * np.asarray(_dec(value["im"]), dtype=float), complex)
    return readonly(np.asarray(_dec(value), dtype=float))


def _dc_to_dict(obj: Any) -> dict:
    out = {}
    for f in fields(obj):
        v = getattr(obj, f.name)
        out[f.name] = _dc_to_dict(v) if isinstance(v, (PIDRow, LQRRow, Condition)) else _enc(v)
    return out


def _from(cls: type, data: Mapping[str, Any]) -> Any:
    kw = {}
    for f in fields(cls):
        if f.name not in data and f.default_factory is not MISSING:
            continue  # a field added later, with a default (tables written before it)
        v = data[f.name]
        if f.type == "bool":
            kw[f.name] = bool(v)
        elif f.type == "str":
            kw[f.name] = str(v)
        elif f.type == "float":
            kw[f.name] = float(_dec(v))
        elif f.type.startswith("tuple"):
            kw[f.name] = tuple(str(s) for s in v)
        elif f.type == "Condition":
            kw[f.name] = _from(Condition, v)
        elif f.type == "PIDRow":
            kw[f.name] = _from(PIDRow, v)
        elif f.type == "LQRRow":
            kw[f.name] = _from(LQRRow, v)
        else:
            kw[f.name] = _arr(v)
    return cls(**kw)


# --- files ----------------------------------------------------------------------------------

_CSV_COLUMNS = (
    "sea_state", "class", "mode_set", "broken", "heading_deg", "weathervane", "x_m", "y_m", "psi_deg",
    "offset_m", "X_env_N", "Y_env_N", "N_env_Nm", "N_thr_Nm", "K11_N_per_m", "K22_N_per_m",
    "K33_Nm_per_rad", "T_surge_s", "T_sway_s", "T_yaw_s", "zeta_surge", "zeta_sway", "zeta_yaw",
    "Kp_x", "Kp_y", "Kp_psi", "Ki_x", "Ki_y", "Ki_psi", "Kd_x", "Kd_y", "Kd_psi",
    "cl_min_damping", "cl_max_period_s", "stable", "stable_modes",
    "gm_surge", "gm_sway", "gm_yaw", "pm_surge_deg", "pm_sway_deg", "pm_yaw_deg",
    "dm_surge_s", "dm_sway_s", "dm_yaw_s", "clamped",
    "lqr_min_damping", "lqr_max_period_s", "lqr_stable")


def _longest(T: np.ndarray) -> float:
    """Longest finite natural period [s] (inf if none)."""
    fin = T[np.isfinite(T)]
    return float(np.max(fin)) if fin.size else math.inf


def _csv_row(r: GainRow) -> list[Any]:
    c, p, q = r.condition, r.pid, r.lqr
    return [c.sea_state, c.sea_class, c.mode_set, c.broken, math.degrees(c.heading),
            int(c.weathervane),
            float(r.eta[0]), float(r.eta[1]), math.degrees(r.eta[2]), r.offset,
            *map(float, r.tau_env), float(r.tau_thr[2]), *map(float, np.diag(r.K)),
            *map(float, p.periods), *map(float, p.damping), *map(float, p.Kp), *map(float, p.Ki),
            *map(float, p.Kd), float(np.min(p.damping_ratios)), _longest(p.natural_periods),
            int(p.stable), int(p.stable_modes), *map(float, p.gain_margin),
            *map(float, p.phase_margin), *map(float, p.delay_margin), len(p.clamped),
            float(np.min(q.damping_ratios)), _longest(q.natural_periods), int(q.stable)]


def _fmt_cutoff(wc: float | None) -> str:
    return "none" if wc is None else f"{wc:.4g} rad/s (2π/{2 * math.pi / wc:.3g} s)"


def _md(table: GainTable) -> str:
    m = table.meta
    lines = [f"# Gain table — {m.get('scenario', '?')}", "",
             f"tapm_opt {m.get('tapm_opt_version', '?')}, environment seed {m.get('seed')}. "
             "Guide: docs/gains.md. Full numbers: gains.json (gains.csv: one line per row).", "",
             "Sea-state classes and mode sets ([S] Table 3): "
             + ", ".join(f"{s} → {c} ({m['mode_sets'][c]['name']})"
                         for s, c in m.get("sea_state_classes", {}).items()) + ".", "",
             f"Margins: {m['margins']['method']}; thrust lag "
             f"{m['margins']['thrust_time_constant_s']:g} s, estimator cut-off "
             f"{_fmt_cutoff(m['margins']['estimator_cutoff_rad_s'])}.", "",
             "ψ: heading held, (wv) = weathervane heading; N_thr: yaw moment the heading "
             "controller holds there; PM/GM/DM per DOF surge/sway/yaw; DM = delay margin.", "",
             "| sea state | broken | ψ [°] | x, y [m] | N_thr [MN m] | K11, K22 [kN/m] | "
             "T_n [s] | ζ | Kp x, y [kN/m] | PM [°] s/s/y | GM s/s/y | DM [s] min | PID | LQR ζ min |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in table.rows:
        c, p = r.condition, r.pid
        ok = ("stable" if p.stable else "UNSTABLE") + (f", {len(p.clamped)} clamped" if p.clamped else "")
        lines.append(
            f"| {c.sea_state} ({c.sea_class}) | {c.broken} | {math.degrees(c.heading):.1f}"
            f"{' (wv)' if c.weathervane else ''} | "
            f"{r.eta[0]:.1f}, {r.eta[1]:.1f} | {r.tau_thr[2] / 1e6:.1f} | "
            f"{r.K[0, 0] / 1e3:.1f}, {r.K[1, 1] / 1e3:.1f} | "
            f"{'/'.join(f'{t:g}' for t in p.periods)} | {'/'.join(f'{z:g}' for z in p.damping)} | "
            f"{p.Kp[0] / 1e3:.0f}, {p.Kp[1] / 1e3:.0f} | "
            f"{'/'.join(f'{v:.0f}' for v in p.phase_margin)} | "
            f"{'/'.join(f'{v:.2f}' for v in p.gain_margin)} | {float(np.min(p.delay_margin)):.1f} | "
            f"{ok} | {float(np.min(r.lqr.damping_ratios)):.2f} |")
    return "\n".join(lines) + "\n"


def write_gain_tables(table: GainTable, out_dir: str | Path) -> list[Path]:
    """Write ``gains.json`` (everything), ``gains.csv`` (one line per row) and ``gains.md``
    (summary) into ``out_dir`` (created), each atomically.

    Returns
    -------
    list of Path
        The three files, in the order json, csv, md.
    """
    if not isinstance(table, GainTable):
        raise GainTableError(f"table must be a GainTable, got {type(table).__name__}")
    out = Path(out_dir)
    text_json = json.dumps(table.to_dict(), indent=1, allow_nan=False) + "\n"
    units = ("units: m, rad shown in deg where named _deg, N, N m; K = catenary stiffness seen by "
             "{B} errors; T/zeta designed; gm ratio, pm deg, dm s (loop-at-a-time with lag)")
    text_csv = csv_text(_CSV_COLUMNS, (_csv_row(r) for r in table.rows),
                        comments=[f"gain table {FORMAT}, scenario {table.meta.get('scenario')}",
                                  units])
    return [atomic_write_text(out / "gains.json", text_json),
            atomic_write_text(out / "gains.csv", text_csv),
            atomic_write_text(out / "gains.md", _md(table))]


def load_gain_table(path: str | Path) -> GainTable:
    """Read a gain table from ``gains.json`` (or a folder holding it).

    Raises
    ------
    GainTableError
        Missing or unreadable file, or not a gain table.
    """
    p = Path(path)
    if p.is_dir():
        p = p / "gains.json"
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise GainTableError(f"no gain table at {p}") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise GainTableError(f"cannot read the gain table {p}: {exc}") from None
    if not isinstance(data, dict):
        raise GainTableError(f"{p} does not hold a gain table (a JSON object)")
    return GainTable.from_dict(data)
