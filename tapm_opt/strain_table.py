"""Nonlinear axial stiffness of a rope: a piecewise-linear tension–strain table.

A synthetic rope (polyester, nylon, HMPE) stiffens or softens with load: its axial law is given as
a table of rows ``(strain, tension)`` [-, N] from ``(0, 0)``, both columns strictly increasing, as
MoorDyn reads it (a strain column and a tension column) and MoorPy too. Between the rows the law is
linear; beyond the last row it continues with the last row's slope (MoorDyn and MoorPy hold the
last tension there instead, which lets a line stretch without bound under a larger load: a table
should reach beyond the tensions of use, e.g. to the breaking strength).

Written in tension, the strain of segment ``k`` (``T_k <= T <= T_{k+1}``) is

    eps(T) = a_k + c_k T,       c_k = (eps_{k+1} - eps_k) / (T_{k+1} - T_k)  (compliance, 1/N),
                                a_k = eps_k - c_k T_k,

continuous, so its integral ``E(T) = int_0^T eps(t) dt`` (the complementary energy, piecewise
quadratic) is continuously differentiable. The quasi-static catenary
(:mod:`tapm_opt.models.catenary`) integrates ``eps`` along the line exactly in these terms; the
FEM plant reads the tension of a segment from its strain, ``T(e) = T_k + s_k (e - eps_k)`` with the
slope ``s_k = 1 / c_k`` [N].

One number stands for the table where a single stiffness is needed (a line type's ``EA``): the
secant at the last row, ``T_n / eps_n`` (:attr:`StrainTable.secant`), the number MoorDyn-C takes
for a tabulated line's internal damping ratio and time-step estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from .errors import TapmError

__all__ = ["MIN_ROWS", "StrainTable", "StrainTableError", "table_problem"]

MIN_ROWS = 2
"""Fewest rows of a table: the origin and one more (one row more is a linear law)."""


class StrainTableError(TapmError, ValueError):
    """A tension–strain table is not a valid axial law (the message names the row and its values)."""


def table_problem(rows: Any) -> tuple[int | None, str] | None:
    """What is wrong with a tension–strain table ``rows`` (a sequence of ``[strain, tension]``
    [-, N]), or None when it is a valid law: ``(row index or None, message)``, the message starting
    with the offending value(s) as a scenario issue does (``= ...``).

    Valid: at least :data:`MIN_ROWS` rows of two finite numbers, the first ``(0, 0)``, strain and
    tension both strictly increasing (so that each is a function of the other; a negative value is
    then impossible after the origin)."""
    try:
        a = np.asarray(rows, dtype=float)
    except (TypeError, ValueError):
        return None, f"= {rows!r} must be rows of two numbers [strain, tension]"
    if a.ndim != 2 or a.shape[1] != 2:
        return None, f"has shape {a.shape}: it must be rows of two numbers [strain, tension] (shape (n, 2))"
    n = a.shape[0]
    if n < MIN_ROWS:
        return None, (f"has {n} row{'s' if n != 1 else ''}: a tension-strain table needs at least {MIN_ROWS}, "
                      "from [0, 0] (two rows are a linear law)")
    for k in range(n):
        if not np.all(np.isfinite(a[k])):
            return k, f"= [{a[k, 0]:g}, {a[k, 1]:g}] must be finite"
    if a[0, 0] != 0.0 or a[0, 1] != 0.0:
        return 0, f"= [{a[0, 0]:g}, {a[0, 1]:g}] must be [0, 0]: the table starts at zero strain and zero tension"
    for k in range(1, n):
        for col, name in ((0, "strain"), (1, "tension")):
            if a[k, col] < 0:
                return k, (f"= [{a[k, 0]:g}, {a[k, 1]:g}] has a negative {name}: the table runs from [0, 0] to "
                           "positive strain and tension")
            if not a[k, col] > a[k - 1, col]:
                return k, (f"= [{a[k, 0]:g}, {a[k, 1]:g}] does not increase the {name} of row {k - 1} "
                           f"[{a[k - 1, 0]:g}, {a[k - 1, 1]:g}]: strain and tension must both increase strictly "
                           "(a monotonic law)")
    return None


@dataclass(frozen=True, eq=False)
class StrainTable:
    """A piecewise-linear tension–strain law (module docstring), vectorised over numpy arrays.

    Build with :meth:`from_rows` (rows ``[strain, tension]``) or ``StrainTable(strain, tension)``;
    an invalid table raises :class:`StrainTableError`. Tensions below 0 read the first segment
    (callers clip: a rope carries no compression); beyond the last row the last segment continues.

    Attributes
    ----------
    strain, tension : ndarray, shape (n + 1,)
        The rows [-] and [N], from (0, 0).
    slope : ndarray, shape (n,)
        Tangent stiffness ``dT/d eps`` of each segment [N].
    compliance : ndarray, shape (n,)
        ``d eps/dT = 1 / slope`` [1/N].
    intercept : ndarray, shape (n,)
        ``a_k`` of ``eps = a_k + c_k T`` on segment k [-] (0 on the first).
    energy_at_rows : ndarray, shape (n + 1,)
        ``E(T_k) = int_0^T_k eps dT`` [N].
    """

    strain: np.ndarray
    tension: np.ndarray
    slope: np.ndarray = field(init=False, repr=False)
    compliance: np.ndarray = field(init=False, repr=False)
    intercept: np.ndarray = field(init=False, repr=False)
    energy_at_rows: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        e = np.array(self.strain, dtype=float).ravel()
        T = np.array(self.tension, dtype=float).ravel()
        if e.shape != T.shape:
            raise StrainTableError(f"tension-strain table: {e.size} strains and {T.size} tensions (one each a row)")
        bad = table_problem(np.column_stack([e, T]))
        if bad is not None:
            k, msg = bad
            raise StrainTableError(f"tension-strain table{'' if k is None else f' row {k}'} {msg}")
        de, dT = np.diff(e), np.diff(T)
        comp = de / dT
        arrays = {"strain": e, "tension": T, "slope": dT / de, "compliance": comp,
                  "intercept": e[:-1] - comp * T[:-1],
                  "energy_at_rows": np.concatenate([[0.0], np.cumsum(0.5 * dT * (e[:-1] + e[1:]))])}
        for k, v in arrays.items():
            v.setflags(write=False)
            object.__setattr__(self, k, v)

    @classmethod
    def from_rows(cls, rows: Sequence[Sequence[float]]) -> "StrainTable":
        """The law of rows ``[[strain, tension], ...]`` [-, N]."""
        bad = table_problem(rows)
        if bad is not None:
            k, msg = bad
            raise StrainTableError(f"tension-strain table{'' if k is None else f' row {k}'} {msg}")
        a = np.asarray(rows, dtype=float)
        return cls(a[:, 0], a[:, 1])

    # -- scalars ---------------------------------------------------------------------------
    @property
    def n_segments(self) -> int:
        return int(self.slope.size)

    @property
    def secant(self) -> float:
        """The secant stiffness at the last row, ``T_n / eps_n`` [N]: the table's one ``EA``."""
        return float(self.tension[-1] / self.strain[-1])

    @property
    def max_slope(self) -> float:
        """The largest tangent stiffness [N] (sets the FEM's stable step)."""
        return float(np.max(self.slope))

    @property
    def initial_slope(self) -> float:
        """The small-strain stiffness, the first segment's slope [N]."""
        return float(self.slope[0])

    def rows(self) -> tuple[tuple[float, float], ...]:
        """The rows as ``((strain, tension), ...)``."""
        return tuple((float(a), float(b)) for a, b in zip(self.strain, self.tension))

    def key(self) -> tuple:
        """Hashable description (equal tables, equal keys)."""
        return ("EA_table",) + self.rows()

    def __eq__(self, other: object) -> bool:
        return isinstance(other, StrainTable) and self.key() == other.key()

    def __hash__(self) -> int:
        return hash(self.key())

    def is_linear(self) -> bool:
        """True when every segment has the same slope (the law is ``T = EA eps``)."""
        return bool(np.all(self.slope == self.slope[0]))

    # -- the law, vectorised ---------------------------------------------------------------
    def segment_of_tension(self, T):
        """Index of the segment holding tension ``T`` (the last row's segment beyond it)."""
        k = np.searchsorted(self.tension, np.asarray(T, dtype=float), side="right") - 1
        return np.clip(k, 0, self.n_segments - 1)

    def segment_of_strain(self, e):
        """Index of the segment holding strain ``e``."""
        k = np.searchsorted(self.strain, np.asarray(e, dtype=float), side="right") - 1
        return np.clip(k, 0, self.n_segments - 1)

    def strain_at(self, T):
        """Strain [-] at tension ``T`` [N]."""
        T = np.asarray(T, dtype=float)
        k = self.segment_of_tension(T)
        return self.strain[k] + self.compliance[k] * (T - self.tension[k])

    def compliance_at(self, T):
        """``d eps/dT`` [1/N] at tension ``T`` (the segment above a row)."""
        return self.compliance[self.segment_of_tension(T)]

    def tension_at(self, e):
        """Tension [N] at strain ``e`` [-]: ``T_k + s_k (e - eps_k)`` (the FEM's formula)."""
        e = np.asarray(e, dtype=float)
        k = self.segment_of_strain(e)
        return self.tension[k] + self.slope[k] * (e - self.strain[k])

    def tangent_at(self, e):
        """``dT/d eps`` [N] at strain ``e``."""
        return self.slope[self.segment_of_strain(e)]

    def energy(self, T):
        """``E(T) = int_0^T eps dt`` [N] (complementary energy per unit length)."""
        T = np.asarray(T, dtype=float)
        k = self.segment_of_tension(T)
        u = T - self.tension[k]
        return self.energy_at_rows[k] + u * (self.strain[k] + 0.5 * self.compliance[k] * u)

    def strain_energy(self, e):
        """``int_0^e T de`` [N] (strain energy per unit unstretched length), 0 for ``e <= 0``."""
        e = np.maximum(np.asarray(e, dtype=float), 0.0)
        T = self.tension_at(e)
        return e * T - self.energy(T)

    def mean_strain(self, T_hi, dT):
        """The mean strain over the tensions ``[T_hi - dT, T_hi]`` [-], ``(E(T_hi) - E(T_hi - dT)) / dT``,
        summed segment by segment (no cancellation for a small ``dT``); ``eps(T_hi)`` at ``dT = 0``."""
        T_hi = np.asarray(T_hi, dtype=float)
        dT = np.asarray(dT, dtype=float)
        T_lo = T_hi - dT
        acc = np.zeros(np.broadcast(T_hi, dT).shape)
        n = self.n_segments
        for k in range(n):
            lo = self.tension[k] if k > 0 else -np.inf
            hi = self.tension[k + 1] if k < n - 1 else np.inf
            t1 = np.clip(T_lo, lo, hi)
            t2 = np.clip(T_hi, lo, hi)
            acc = acc + (t2 - t1) * (self.intercept[k] + 0.5 * self.compliance[k] * (t1 + t2))
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(dT > 0, acc / np.where(dT > 0, dT, 1.0), self.strain_at(T_hi))

    def mean_compliance(self, T_lo, T_hi):
        """``(eps(T_hi) - eps(T_lo)) / (T_hi - T_lo)`` [1/N], summed segment by segment; the
        compliance at ``T_lo`` where the two are equal."""
        T_lo = np.asarray(T_lo, dtype=float)
        T_hi = np.asarray(T_hi, dtype=float)
        num = np.zeros(np.broadcast(T_lo, T_hi).shape)
        den = np.zeros_like(num)
        n = self.n_segments
        for k in range(n):
            lo = self.tension[k] if k > 0 else -np.inf
            hi = self.tension[k + 1] if k < n - 1 else np.inf
            d = np.clip(T_hi, lo, hi) - np.clip(T_lo, lo, hi)
            num = num + self.compliance[k] * d
            den = den + d
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(den > 0, num / np.where(den > 0, den, 1.0), self.compliance_at(T_lo))

    def rise(self, T0, R, alpha: float = 1.0):
        """``dT >= 0`` with ``alpha dT + E(T0 + dT) - E(T0) = R`` for ``R >= 0`` (arrays): the
        tension gained over a rise, solved segment by segment in closed form (each a quadratic).

        With ``alpha = 1`` and ``T0`` a horizontal tension ``H``, ``R = w h`` gives the tension at
        the top of a catenary that rises ``h`` from its lowest point (``w h = T + E(T) - H - E(H)``);
        with ``T0 = 0`` the tension ``w Ls`` at the top of a line hanging vertically over ``h``.
        With ``alpha = 0``, the tension whose energy is ``E(T0) + R``."""
        T0, R = np.broadcast_arrays(np.asarray(T0, dtype=float), np.asarray(R, dtype=float))
        T = T0.copy()
        rem = np.maximum(R, 0.0).copy()
        delta = np.zeros(T.shape)
        active = rem > 0
        n = self.n_segments
        for _ in range(n + 1):
            if not np.any(active):
                break
            k = self.segment_of_tension(T)
            eT = self.strain[k] + self.compliance[k] * (T - self.tension[k])
            b = alpha + eT
            c = self.compliance[k]
            last = k >= n - 1
            top = self.tension[np.minimum(k + 1, n)]
            umax = np.where(last, np.inf, top - T)
            dF = np.where(last, np.inf, umax * (alpha + 0.5 * (eT + self.strain[np.minimum(k + 1, n)])))
            inside = active & (rem <= dF)
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                u = 2.0 * rem / (b + np.sqrt(b * b + 2.0 * c * rem))
            u = np.where(rem > 0, u, 0.0)
            delta = np.where(inside, delta + np.minimum(u, umax), delta)
            cross = active & ~inside
            delta = np.where(cross, delta + umax, delta)
            rem = np.where(cross, rem - dF, rem)
            T = np.where(cross, top, T)
            active = cross
        return delta

    def solve_mean_strain(self, target, dT):
        """``T`` with ``mean_strain(T, dT) = target`` (arrays, ``target >= 0``, ``dT >= 0``), ``T >= dT``:
        the top tension of a run whose tension falls linearly by ``dT`` and whose mean strain is
        ``target`` (a vertical taut line, ``dT = w L``; a line dragged over the seabed, ``dT = mu w L``).
        Safeguarded Newton in the bracket ``[max(dT, T(target)), T(target) + dT]``."""
        target, dT = np.broadcast_arrays(np.asarray(target, dtype=float), np.asarray(dT, dtype=float))
        Ts = self.tension_at(target)
        lo = np.maximum(dT, Ts)
        hi = np.maximum(Ts + dT, lo)
        T = 0.5 * (lo + hi)
        scale = np.maximum(hi, 1.0)
        for _ in range(200):
            f = self.mean_strain(T, dT) - target
            lo = np.where(f < 0, T, lo)
            hi = np.where(f > 0, T, hi)
            slope = self.mean_compliance(T - dT, T)
            with np.errstate(invalid="ignore", divide="ignore"):
                Tn = T - f / slope
            bad = ~np.isfinite(Tn) | (Tn <= lo) | (Tn >= hi)
            Tn = np.where(bad, 0.5 * (lo + hi), Tn)
            done = (np.abs(Tn - T) <= 4e-16 * scale) | (hi - lo <= 4e-16 * scale) | (f == 0)
            T = np.where(f == 0, T, Tn)
            if np.all(done):
                break
        return T


def secant_of_rows(rows: Any) -> float | None:
    """``T_n / eps_n`` of table rows, or None when the rows are not a valid table."""
    if table_problem(rows) is not None:
        return None
    a = np.asarray(rows, dtype=float)
    v = float(a[-1, 1] / a[-1, 0])
    return v if math.isfinite(v) else None
