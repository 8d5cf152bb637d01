"""Fatigue of mooring lines: T-N curves, rainflow counting, Miner's damage — offline (a whole
record) and on-line (a stream of samples, one at a time).

The one definition of the fatigue limit state's curves and damage sum, shared by the design
verification (:mod:`tapm_opt.studies.verification`, which re-exports these names) and the
fatigue-aware setpoint layer (:mod:`tapm_opt.control.fatigue_setpoint`), which may not import the
studies.

Units: tensions and tension ranges in N, diameters in m, areas in m², stresses in MPa.

Sources and what is unchecked
-----------------------------
The T-N curves and nominal areas are transcribed from the project's standards notes, which were
read from **secondary transcriptions** of DNV-OS-E301 ("as commonly transcribed"; the wire-rope
curves from secondary sources); none has been checked against the standard. Rainflow counting is
ASTM E1049-85 (2011), section 5.4.4, as the ``rainflow`` package implements it
(:func:`rainflow_ranges`); :class:`StreamingDamage` is the same algorithm run one sample at a time.
See ``docs/verification.md`` and ``docs/fatigue_setpoint.md``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._checks import finite
from ..errors import TapmError

__all__ = [
    "VerificationError",
    "finite_series",
    "TNCurve",
    "TN_CURVES",
    "nominal_area",
    "rainflow_ranges",
    "range_damage",
    "miner_damage",
    "CHAIN_HYDRODYNAMIC_RATIO",
    "default_component",
    "default_nominal_diameter",
    "LineCurve",
    "line_curves",
    "StreamingDamage",
    "narrow_band_damage_rate",
]


class VerificationError(TapmError, ValueError):
    """An input of a limit-state statistic (strength or fatigue) is invalid; the message names the
    argument and value."""


def finite_series(name: str, x: object, *, min_len: int = 0) -> np.ndarray:
    """``x`` as a 1-D array of finite floats with at least ``min_len`` values, else a
    :class:`VerificationError` naming ``name`` (and the first bad element)."""
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise VerificationError(f"{name}: expected a sequence of numbers, got {x!r}") from exc
    if a.ndim != 1:
        raise VerificationError(f"{name}: expected a 1-D sequence, got an array of shape {a.shape}")
    if a.size < min_len:
        raise VerificationError(f"{name}: need at least {min_len} values, got {a.size} ({a.tolist()!r})")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        i = int(bad[0])
        raise VerificationError(f"{name}[{i}] = {float(a[i])!r} is not finite")
    return a


def _positive(name: str, x: object) -> float:
    return finite(name, x, lo=0.0, strict=True, error=VerificationError)


# -- T-N curves ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class TNCurve:
    """A T-N curve ``n_c(s) = a_D s^(-m)``: cycles to failure at the nominal stress range ``s``
    [MPa]. ``bars`` is how many bar cross-sections of diameter ``d`` make the nominal area
    (2 for a chain link, 1 for a wire rope); 0 for a curve in the tension ratio ``R = range /
    MBS`` (fibre rope), whose "area" is ``MBS / 1 MPa`` so that ``s = range / area`` is ``R``
    (:func:`nominal_area`)."""

    m: float
    a_D: float
    bars: int


#: T-N curves of DNV-OS-E301 as commonly transcribed (project standards notes; edition unchecked;
#: the wire-rope values from secondary sources, unchecked). Polyester rope: ``n_c(R) = 0.259
#: R^-13.46`` in the ratio R of the tension range to the rope's characteristic strength (MBS), the
#: curve DNV-OS-E301 gives for polyester (as widely quoted in the fibre-mooring literature;
#: secondary, unchecked against the standard).
TN_CURVES: dict[str, TNCurve] = {
    "studlink_chain": TNCurve(m=3.0, a_D=1.2e11, bars=2),
    "studless_chain": TNCurve(m=3.0, a_D=6.0e10, bars=2),
    "six_strand_wire": TNCurve(m=4.0, a_D=3.4e14, bars=1),
    "spiral_strand_wire": TNCurve(m=4.8, a_D=1.7e17, bars=1),
    "polyester_rope": TNCurve(m=13.46, a_D=0.259, bars=0),
}


def nominal_area(component: str, d: float | None = None, *, MBS: float | None = None) -> float:
    """Nominal cross-section area [m²] used to turn a tension range into a stress range.

    Chain (``"studlink_chain"``, ``"studless_chain"``): the two bars of a link, ``2 pi d^2 / 4``
    with ``d`` [m] the bar (nominal chain) diameter. Wire rope (``"six_strand_wire"``,
    ``"spiral_strand_wire"``): ``pi d^2 / 4`` with ``d`` the nominal rope diameter (the project's
    convention; the standard's definition of the wire's nominal area is unchecked).
    Fibre rope (``"polyester_rope"``, a curve in the tension ratio): ``MBS / 1e6`` with ``MBS`` [N]
    the rope's strength, the area on which the MBS is 1 MPa, so that the stress range ``range /
    area`` in MPa is the ratio ``range / MBS`` the curve takes (``d`` unused).
    Source: DNV-OS-E301 as transcribed in the project's standards notes (chain).
    """
    if component not in TN_CURVES:
        raise VerificationError(f"component = {component!r}: expected one of {', '.join(TN_CURVES)}")
    if TN_CURVES[component].bars == 0:
        if MBS is None:
            raise VerificationError(f"component = {component!r}: its T-N curve is in range / MBS; give MBS [N]")
        return _positive("MBS", MBS) / 1e6
    dd = _positive("d", d)
    return TN_CURVES[component].bars * math.pi * dd * dd / 4.0


#: The hydrodynamic diameter of chain as a multiple of its nominal (bar) diameter, the convention
#: of the built-in scenarios (OrcaFlex's chain line types: 1.8 d): a chain line type's default
#: nominal diameter is its ``diameter`` / 1.8.
CHAIN_HYDRODYNAMIC_RATIO = 1.8


def default_component(type_id: str) -> str:
    """The T-N curve (a key of :data:`TN_CURVES`) of a line type named ``type_id`` when none is
    given: ``studlink`` in the id: studlink chain, else ``chain``: studless chain, else ``spiral``:
    spiral-strand wire, else ``polyester``, or ``poly`` then a digit (``poly240``): polyester rope,
    else six-strand wire (the most damaging wire curve). ASSUMPTION: the type's id says what it is
    (the built-in scenarios' ids do)."""
    import re

    s = type_id.lower()
    if "studlink" in s or "stud_link" in s:
        return "studlink_chain"
    if "chain" in s:
        return "studless_chain"
    if "spiral" in s:
        return "spiral_strand_wire"
    if "polyester" in s or re.match(r"poly\d", s):   # "poly240"; not polypropylene, polyethylene
        return "polyester_rope"
    return "six_strand_wire"


def default_nominal_diameter(component: str, diameter: float) -> float:
    """A line type's nominal diameter [m] from its (hydrodynamic) ``diameter`` [m]: divided by
    :data:`CHAIN_HYDRODYNAMIC_RATIO` for chain, the ``diameter`` itself otherwise."""
    return float(diameter) / (CHAIN_HYDRODYNAMIC_RATIO if component.endswith("_chain") else 1.0)


@dataclass(frozen=True)
class LineCurve:
    """The T-N curve ``n = a_D s^-m`` (s in MPa) and nominal area ``area`` [m²] of one line's
    fairlead line type, as :func:`miner_damage` takes them; ``component`` its :data:`TN_CURVES` key."""

    component: str
    a_D: float
    m: float
    area: float


def line_curves(scenario: Any) -> dict[str, LineCurve]:
    """``{line id: LineCurve}`` of every line of ``scenario``, from its fairlead line type
    (``line.type``) with the defaults of the verification (:func:`default_component`,
    :func:`default_nominal_diameter`, :func:`nominal_area`; a polyester type's area from its MBS).
    These are the curves ``tapm study verify`` uses for a line type its ``[verification]`` table
    does not describe."""
    out: dict[str, LineCurve] = {}
    for ln in scenario.lines:
        lt = scenario.line_type_by_id(ln.type)
        comp = default_component(ln.type)
        curve = TN_CURVES[comp]
        area = (nominal_area(comp, MBS=float(lt.MBS)) if curve.bars == 0
                else nominal_area(comp, default_nominal_diameter(comp, lt.diameter)))
        out[str(ln.id)] = LineCurve(component=comp, a_D=curve.a_D, m=curve.m, area=float(area))
    return out


# -- rainflow and Miner -------------------------------------------------------------------------

def rainflow_ranges(series: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rainflow-counted ranges of a record (ASTM E1049-85, rainflow counting, section 5.4.4).

    ``series`` [N, or any unit]: the tension record, at least 2 finite samples. Returns
    ``(ranges, counts)``, ranges ascending in the unit of ``series``, counts in cycles with each
    half cycle (the residue, and ranges containing the start point) counted as 0.5. Equal ranges
    are merged; ranges of zero (a constant record) are left out, as they do no damage. Counting
    is done by the ``rainflow`` package (``rainflow.count_cycles``), which reduces the record to
    its reversals first.
    """
    import rainflow

    x = finite_series("series", series, min_len=2)
    pairs = [(r, n) for r, n in rainflow.count_cycles(x) if r > 0]
    if not pairs:
        return np.zeros(0), np.zeros(0)
    r, n = zip(*pairs)
    return np.asarray(r, dtype=float), np.asarray(n, dtype=float)


def range_damage(ranges: Any, counts: Any, a_D: float, m: float, area: float) -> float:
    """Palmgren-Miner sum of counted tension ranges, ``D = sum_i n_i s_i^m / a_D`` with
    ``s_i = R_i / area / 1e6`` [MPa] (``ranges`` R_i [N], ``counts`` n_i [cycles], ``area`` [m²],
    the T-N curve ``n_c = a_D s^-m``). The one statement of the damage sum: :func:`miner_damage`
    and :class:`StreamingDamage` both use it. Source: DNV-OS-E301 FLS as transcribed (unchecked)."""
    s = np.asarray(ranges, dtype=float) / area / 1e6
    return float(np.sum(np.asarray(counts, dtype=float) * s ** m) / a_D)


def miner_damage(series: Sequence[float] | np.ndarray, a_D: float, m: float, area: float) -> float:
    """Miner's fatigue damage of a tension record (dimensionless).

    ``D = sum_i n_i / n_c(s_i) = sum_i n_i s_i^m / a_D``, with ``(R_i, n_i)`` the rainflow ranges
    [N] and counts of ``series`` (:func:`rainflow_ranges`), ``s_i = R_i / area / 1e6`` the nominal
    stress range [MPa], ``area`` [m²] the nominal area (:func:`nominal_area`), and ``a_D``, ``m``
    the T-N curve (:data:`TN_CURVES`) (:func:`range_damage`). Source: DNV-OS-E301 fatigue limit
    state as transcribed in the project's standards notes (unchecked); counting per ASTM E1049.
    """
    aD = _positive("a_D", a_D)
    mm = _positive("m", m)
    A = _positive("area", area)
    ranges, counts = rainflow_ranges(series)
    return range_damage(ranges, counts, aD, mm, A)


class StreamingDamage:
    """Miner's damage of a tension signal counted on-line, one sample at a time.

    The rainflow count of ASTM E1049-85 §5.4.4 (three-point rule, a range that holds the start
    point counted as half a cycle), run as the samples arrive: a sample becomes a reversal once the
    next different sample shows the slope's sign changed; each reversal enters the stack of the
    count, and a cycle closed by it adds ``s^m / a_D`` (:func:`range_damage`) to the closed damage
    at once and is dropped. The state is the last two samples and the stack of open reversals (the
    residue), which stays short in a stationary record, so a long record costs nothing to keep.

    :attr:`damage` is the closed damage plus the residue counted as the standard counts it at the
    end of a record: the present sample taken as the last reversal, and every range left open
    counted as half a cycle. It therefore equals :func:`miner_damage` of every sample pushed so far
    (to rounding), at any time; the half cycles of the residue are a provisional part that later
    samples may close into whole cycles or replace.

    Parameters
    ----------
    a_D, m : float
        The T-N curve ``n_c = a_D s^-m`` (s in MPa).
    area : float
        Nominal area [m²] (:func:`nominal_area`).
    """

    def __init__(self, a_D: float, m: float, area: float):
        self.a_D = _positive("a_D", a_D)
        self.m = _positive("m", m)
        self.area = _positive("area", area)
        self.reset()

    def reset(self) -> None:
        self.n = 0                       # samples pushed
        self._x_last = 0.0               # the sample before the candidate reversal
        self._x = 0.0                    # the candidate reversal (the last different sample)
        self._d_last = 0.0               # slope into the candidate
        self._stack: list[float] = []    # open reversals (the residue)
        self.closed = 0.0                # damage of the cycles and half cycles closed so far

    def _cycle(self, r: float, count: float) -> float:
        return range_damage(abs(r), count, self.a_D, self.m, self.area) if r != 0.0 else 0.0

    def _reduce(self, stack: list[float]) -> float:
        """The three-point rule on ``stack`` (in place) after a reversal was appended; the damage
        it closes."""
        d = 0.0
        while len(stack) >= 3:
            X = abs(stack[-1] - stack[-2])
            Y = abs(stack[-2] - stack[-3])
            if X < Y:
                break
            if len(stack) == 3:          # Y holds the start point: half a cycle
                d += self._cycle(Y, 0.5)
                stack.pop(0)
            else:                        # a whole cycle: drop its peak and valley
                d += self._cycle(Y, 1.0)
                last = stack.pop()
                del stack[-2:]
                stack.append(last)
        return d

    def push(self, value: float) -> None:
        """Add one sample (a finite tension [N])."""
        v = float(value)
        if not math.isfinite(v):
            raise VerificationError(f"tension sample {self.n} = {value!r} is not finite")
        self.n += 1
        if self.n == 1:
            self._x_last = v
            return
        if self.n == 2:
            self._x = v
            self._d_last = v - self._x_last
            self._stack.append(self._x_last)       # the first sample is a reversal
            self.closed += self._reduce(self._stack)
            return
        if v == self._x:                           # a plateau: not a reversal
            return
        d_next = v - self._x
        if self._d_last * d_next < 0:
            self._stack.append(self._x)
            self.closed += self._reduce(self._stack)
        self._x_last, self._x, self._d_last = self._x, v, d_next

    def extend(self, values: Any) -> None:
        """Push every sample of ``values`` in order."""
        for v in np.asarray(values, dtype=float).ravel():
            self.push(v)

    @property
    def residue(self) -> list[float]:
        """The open reversals with the present sample as the last (the residue at the end of the
        record so far)."""
        st = list(self._stack)
        if self.n >= 3:
            st.append(self._x)
            self._reduce(st)
        return st

    @property
    def damage(self) -> float:
        """Miner's damage of every sample so far: closed cycles plus the residue as half cycles."""
        st = list(self._stack)
        d = self.closed
        if self.n >= 3:
            st.append(self._x)
            d += self._reduce(st)
        for a, b in zip(st[:-1], st[1:]):
            d += self._cycle(b - a, 0.5)
        return d


def narrow_band_damage_rate(sigma: Any, nu0: float, a_D: float, m: float, area: float) -> np.ndarray:
    """Expected Miner damage per second [1/s] of a narrow-band Gaussian tension of standard
    deviation ``sigma`` [N] and mean zero up-crossing rate ``nu0`` [1/s]: the ranges are Rayleigh
    distributed, ``E[R^m] = (2 sqrt(2) sigma)^m Gamma(1 + m/2)``, so
    ``dD/dt = nu0 (2 sqrt(2) sigma / area / 1e6)^m Gamma(1 + m/2) / a_D`` (e.g. Naess & Moan,
    *Stochastic Dynamics of Marine Structures*, §12; a standard result). For a broad-band
    tension it is an upper bound (the rainflow ranges of a broad-band process are smaller).
    ``sigma`` may be an array."""
    s = np.asarray(sigma, dtype=float)
    return nu0 * (2.0 * math.sqrt(2.0) * s / area / 1e6) ** m * math.gamma(1.0 + m / 2.0) / a_D
