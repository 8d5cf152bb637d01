"""Line characteristics and system restoring curves (survey eq. 25–29), as plain tables.

These functions compute; writing files is the caller's job (see ``tapm lines``).

They take a :class:`~tapm_opt.models.mooring.MooringModel` as an argument and read its lines; the
mooring model builds its :class:`TabulatedMooringLoad` from here
(:meth:`~tapm_opt.models.mooring.MooringModel.load_evaluator`), so this module does not import it
back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ModelError

__all__ = ["LineCharacteristics", "LengthTables", "OffsetCurves", "TabulatedMooringLoad", "line_characteristics",
           "offset_curves", "tension_source"]


@dataclass(frozen=True)
class LineCharacteristics:
    """Fairlead tensions of every line against the horizontal anchor–fairlead distance.

    Arrays have shape (n_lines, n_points): ``XF`` [m], ``H``, ``V``, ``T`` [N] (fairlead), and
    ``regime`` (index into :data:`tapm_opt.models.catenary.REGIMES`); ``XF0`` (n_lines,) is the
    distance at the field zero point.
    """

    line_ids: tuple[str, ...]
    XF0: np.ndarray
    XF: np.ndarray
    H: np.ndarray
    V: np.ndarray
    T: np.ndarray
    regime: np.ndarray


@dataclass(frozen=True)
class OffsetCurves:
    """Restoring load and line tensions against a horizontal offset of the vessel (heading 0).

    ``direction`` (n_dir,) [rad], ``offset`` (n_off,) [m]; ``tau`` (n_dir, n_off, 3) mooring load in
    {B} = {E} at psi = 0 [N, N, N m]; ``T`` (n_dir, n_off, n_lines) fairlead tensions [N].
    """

    line_ids: tuple[str, ...]
    direction: np.ndarray
    offset: np.ndarray
    tau: np.ndarray
    T: np.ndarray


def line_characteristics(model: Any, *, half_range: float, n_points: int = 41) -> LineCharacteristics:
    """H, V, T of each line for XF in [XF0 - half_range, XF0 + half_range] (eq. 25).

    Parameters
    ----------
    model : MooringModel
    half_range : float
        Half-width of the distance range about the field-zero-point distance [m], > 0.
    n_points : int
        Points per line, >= 2.
    """
    if not (np.isfinite(half_range) and half_range > 0):
        raise ModelError(f"half_range = {half_range!r} m must be a positive number")
    if n_points < 2:
        raise ModelError(f"n_points = {n_points} must be >= 2")
    _, _, XF0 = model.spans(np.zeros(3))
    grid = np.linspace(-half_range, half_range, n_points)
    XF = np.maximum(XF0[:, None] + grid[None, :], 0.0)
    sol = model.solve_xf(XF.T)
    return LineCharacteristics(line_ids=model.line_ids, XF0=XF0, XF=XF, H=sol.HF.T, V=sol.VF.T, T=sol.TF.T,
                               regime=sol.regime.T)


def offset_curves(model: Any, directions: np.ndarray, offsets: np.ndarray) -> OffsetCurves:
    """Mooring load and tensions for the vessel displaced by ``offsets`` along ``directions``.

    Parameters
    ----------
    model : MooringModel
    directions : array_like, shape (n_dir,)
        Offset directions in {E} from north [rad].
    offsets : array_like, shape (n_off,)
        Offset magnitudes [m].
    """
    directions = np.atleast_1d(np.asarray(directions, dtype=float))
    offsets = np.atleast_1d(np.asarray(offsets, dtype=float))
    tau = np.zeros((directions.size, offsets.size, 3))
    T = np.zeros((directions.size, offsets.size, model.n_lines))
    for i, d in enumerate(directions):
        for j, r in enumerate(offsets):
            eta = np.array([r * np.cos(d), r * np.sin(d), 0.0])
            sol = model.solve_lines(eta)
            tau[i, j] = model.tau_from_H(eta, sol.HF)
            T[i, j] = sol.TF
    return OffsetCurves(line_ids=model.line_ids, direction=directions, offset=offsets, tau=tau, T=T)


# ------------------------------------------------------------------------------------------
# tabulated mooring load: the catenary characteristics as cubic Hermite tables
# ------------------------------------------------------------------------------------------

#: Points per interval at which a table is checked against the catenary, as fractions of the
#: interval (the leading error term of a cubic Hermite interpolant, t^2 (1 - t)^2, peaks at 1/2).
_CHECK_POINTS = (0.25, 0.5, 0.75)


def _hermite(x0, x1, H0, H1, k0, k1, x):
    """Cubic Hermite interpolant through (x0, H0, slope k0) and (x1, H1, slope k1), at x."""
    h = x1 - x0
    t = (x - x0) / h
    a, b, dH = k0 * h, k1 * h, H1 - H0
    return H0 + t * (a + t * ((3.0 * dH - 2.0 * a - b) + t * (a + b - 2.0 * dH)))


def _hermite_slope(x0, x1, H0, H1, k0, k1, x):
    """Derivative d/dx of :func:`_hermite` at x."""
    h = x1 - x0
    t = (x - x0) / h
    a, b, dH = k0 * h, k1 * h, H1 - H0
    return (a + t * (2.0 * (3.0 * dH - 2.0 * a - b) + 3.0 * t * (a + b - 2.0 * dH))) / h


@dataclass(frozen=True)
class _LineTable:
    """H(XF) and T(XF) of one line configuration: nodes ``X`` [m] (increasing), ``H`` [N],
    slopes ``K`` [N/m] (one-sided at a regime change, which sits between two nodes 1e-9 relative
    apart), the fairlead tension ``T`` [N] and its slopes ``KT`` [N/m] on the same nodes, ``ok``
    (per interval: both checked within tolerance), ``err`` (per interval: largest checked error of
    H or T relative to the tolerance scale)."""

    X: np.ndarray
    H: np.ndarray
    K: np.ndarray
    T: np.ndarray
    KT: np.ndarray
    ok: np.ndarray
    err: np.ndarray


def _regime_changes(solve, lo: float, hi: float, n: int) -> list[tuple[float, float]]:
    """Brackets (a, b), b - a <= 1e-9 max(|a|, 1) m, of every regime change of ``solve`` seen on
    ``n`` points over [lo, hi] (a regime narrower than the spacing can be missed; the refinement
    of :func:`_line_table` then resolves it by its error check, or leaves it to the exact model)."""
    xg = np.linspace(lo, hi, n)
    rg = solve(xg).regime
    out = []
    for j in np.flatnonzero(rg[1:] != rg[:-1]):
        a, b, ra = xg[j], xg[j + 1], rg[j]
        while b - a > 1e-9 * max(abs(a), 1.0):
            xs = np.linspace(a, b, 33)
            rs = solve(xs).regime
            q = int(np.flatnonzero(rs != ra)[0])
            a, b = xs[q - 1], xs[q]
        out.append((float(a), float(b)))
    return out


def _line_table(solve, lo: float, hi: float, *, rtol: float, H_ref: float,
                max_nodes: int = 200_000) -> _LineTable:
    """Adaptive cubic Hermite tables of a line's HF(XF) and TF(XF) over [lo, hi], from its
    quasi-static solution ``solve(XF) -> CatenarySolution`` (``MooringModel.line_solver``).

    Nodes start ~ (hi - lo)/64 apart with a node pair at every regime change; an interval is split
    in two while either interpolant misses :func:`catenary.solve` by more than
    ``rtol * max(HF, H_ref)`` (``rtol * max(TF, H_ref)`` for TF) at any of :data:`_CHECK_POINTS`.
    Intervals still off when they are shorter than 2^-20 (hi - lo), or when the table reaches
    ``max_nodes``, are marked not ``ok`` (the evaluator then uses the exact model there).
    """
    kinks = _regime_changes(solve, lo, hi, 257)
    edges = [lo, *[v for ab in kinks for v in ab], hi]
    h0 = (hi - lo) / 64.0
    pieces = []
    for a, b in zip(edges[0::2], edges[1::2]):
        pieces.append(np.linspace(a, b, max(int(np.ceil((b - a) / h0)), 1) + 1))
    X = np.unique(np.concatenate(pieces))
    s = solve(X)
    H, K, T, KT = s.HF, s.dHF_dXF, s.TF, s.dTF_dXF
    h_min = (hi - lo) * 2.0 ** -20
    pending = np.ones(X.size - 1, dtype=bool)  # intervals still to check
    ok = np.ones(X.size - 1, dtype=bool)
    err = np.zeros(X.size - 1)
    while np.any(pending):
        j = np.flatnonzero(pending)
        x0, x1 = X[j], X[j + 1]
        worst = np.zeros(j.size)
        mid = None
        for t in _CHECK_POINTS:
            xt = x0 + t * (x1 - x0)
            st = solve(xt)
            e = np.abs(_hermite(x0, x1, H[j], H[j + 1], K[j], K[j + 1], xt) - st.HF)
            eT = np.abs(_hermite(x0, x1, T[j], T[j + 1], KT[j], KT[j + 1], xt) - st.TF)
            worst = np.maximum(worst, np.maximum(e / (rtol * np.maximum(st.HF, H_ref)),
                                                 eT / (rtol * np.maximum(st.TF, H_ref))))
            if t == 0.5:
                mid = (xt, st.HF, st.dHF_dXF, st.TF, st.dTF_dXF)
        err[j] = worst
        split = (worst > 1.0) & (x1 - x0 > h_min) & (X.size + np.cumsum(worst > 1.0) <= max_nodes)
        ok[j] = worst <= 1.0
        pending[:] = False
        if not np.any(split):
            break
        # insert the midpoints of the split intervals (already solved); their halves are pending
        js = j[split]
        at = js + 1
        X = np.insert(X, at, mid[0][split])
        H = np.insert(H, at, mid[1][split])
        K = np.insert(K, at, mid[2][split])
        T = np.insert(T, at, mid[3][split])
        KT = np.insert(KT, at, mid[4][split])
        new_pending = np.insert(pending, at, True)
        new_pending[js + np.arange(js.size)] = True  # left halves (indices shift by earlier inserts)
        pending = new_pending
        ok = np.insert(ok, at, True)
        err = np.insert(err, at, 0.0)
    return _LineTable(X=X, H=H, K=K, T=T, KT=KT, ok=ok, err=err)


_TABLES: dict = {}
_TABLES_MAX = 64
"""Line tables shared between mooring models (a model and its reduced copies, one per broken line
or lost point, have the same lines): keyed by the line's physics (``MooringModel.line_key``),
the range, the tolerance and the scale; at most :data:`_TABLES_MAX`, oldest dropped first."""


def _shared_line_table(model: Any, i: int, lo: float, hi: float, *, rtol: float, H_ref: float,
                       L: float | None = None) -> _LineTable:
    """:func:`_line_table` of line ``i`` of ``model`` (at the unstretched length ``L`` [m] if given,
    ``MooringModel.line_solver``), from the shared cache when an equal line was tabulated over the
    same range before (a composite line's table costs about a second)."""
    key = (model.line_key(i), float(lo), float(hi), float(rtol), float(H_ref), None if L is None else float(L))
    tb = _TABLES.get(key)
    if tb is None:
        tb = _line_table(model.line_solver(i, L=L), lo, hi, rtol=rtol, H_ref=H_ref)
        if len(_TABLES) >= _TABLES_MAX:
            _TABLES.pop(next(iter(_TABLES)))
        _TABLES[key] = tb
    return tb


class LengthTables:
    """A line's fairlead tensions at horizontal distances and unstretched lengths (a winch's), from
    tables: ``(HF, TF) = tables(XF, L)`` [N] at ``XF`` [m] and ``L`` [m].

    Per length on the grid ``L0 + k dL`` (k whole), the adaptive cubic Hermite tables of HF(XF) and
    TF(XF) over [``lo``, ``hi``] (:func:`_line_table`, to ``rtol``; ``MooringModel.line_solver``
    at that length: a composite line's change of length is its fairlead section's), built when a
    length first needs them and shared in the process; at ``L``, linear between the two grid
    lengths around it. Outside [lo, hi], or in an interval a table marks unusable, the line's exact
    solve at ``L``. For a controller's model of a line whose exact solve is expensive (a composite
    line: ~13 ms a call) and whose length changes every step; ``tests/test_winch_composite.py``
    measures the interpolation in L against the exact solve.
    """

    def __init__(self, model: Any, i: int, lo: float, hi: float, *, L0: float, dL: float, H_ref: float,
                 rtol: float = 1e-7):
        if not (math.isfinite(dL) and dL > 0):
            raise ValueError(f"dL = {dL!r} m must be a positive length")
        self.model, self.i, self.lo, self.hi = model, int(i), float(lo), float(hi)
        self.L0, self.dL, self.H_ref, self.rtol = float(L0), float(dL), float(H_ref), float(rtol)
        self._tabs: dict[int, _LineTable] = {}
        self.exact_calls = 0

    def _table(self, k: int) -> _LineTable:
        tb = self._tabs.get(k)
        if tb is None:
            tb = self._tabs[k] = _shared_line_table(self.model, self.i, self.lo, self.hi, rtol=self.rtol,
                                                    H_ref=self.H_ref, L=self.L0 + k * self.dL)
        return tb

    def __call__(self, XF: float, L: float) -> tuple[float, float]:
        XF, L = float(XF), float(L)
        q = (L - self.L0) / self.dL
        k = math.floor(q)
        f = q - k
        out = np.zeros(2)
        for kk, wgt in ((k, 1.0 - f), (k + 1, f)):
            if wgt == 0.0:
                continue
            tb = self._table(kk)
            if not (tb.X[0] <= XF <= tb.X[-1]):
                return self._exact(XF, L)
            j = min(max(int(np.searchsorted(tb.X, XF, side="right")) - 1, 0), tb.X.size - 2)
            if not tb.ok[j]:
                return self._exact(XF, L)
            x0, x1 = tb.X[j], tb.X[j + 1]
            out[0] += wgt * _hermite(x0, x1, tb.H[j], tb.H[j + 1], tb.K[j], tb.K[j + 1], XF)
            out[1] += wgt * _hermite(x0, x1, tb.T[j], tb.T[j + 1], tb.KT[j], tb.KT[j + 1], XF)
        return float(out[0]), float(out[1])

    def _exact(self, XF: float, L: float) -> tuple[float, float]:
        self.exact_calls += 1
        sol = self.model.line_solver(self.i, L=L)(XF)
        return float(sol.HF), float(sol.TF)


_KERNEL = None


def _tau_kernel_py(eta, par, geo, seg, tab, out):  # pragma: no cover - compiled by numba
    """Mooring load in {B} of the tabulated lines at pose ``eta``, into ``out`` (3,).

    ``par`` = (x_cot, y_cot, turret angle, free turret 1/0); ``geo`` (n, 5) = anchor x, y,
    fairlead in {T} x, y, table index of each line; ``seg`` (n_tables, 2) the node range
    [start, stop) of each table in ``tab``; ``tab`` (m, 4) = XF [m], HF [N], dHF/dXF [N/m], 1 if
    the interval that starts at the node is usable. Returns 0, or 1 for a non-finite pose, 2 if a
    line's distance lies outside its table or in an interval marked unusable (``out`` undefined).
    Same operations as ``MooringModel.tau_from_H`` (eq. 5, 17–23).
    """
    x, y, psi = eta[0], eta[1], eta[2]
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(psi)):
        return 1
    free = par[3] != 0.0
    c, s = math.cos(psi), math.sin(psi)
    cx = c * par[0] - s * par[1]
    cy = s * par[0] + c * par[1]
    ang = psi + (par[2] - psi if free else par[2])
    ct, st = math.cos(ang), math.sin(ang)
    Fx = 0.0
    Fy = 0.0
    Nz = 0.0
    for i in range(geo.shape[0]):
        fx = x + cx + (ct * geo[i, 2] - st * geo[i, 3])
        fy = y + cy + (st * geo[i, 2] + ct * geo[i, 3])
        dx = fx - geo[i, 0]
        dy = fy - geo[i, 1]
        d = math.hypot(dx, dy)
        j = int(geo[i, 4])
        a = seg[j, 0]
        b = seg[j, 1] - 1
        if not (d >= tab[a, 0] and d <= tab[b, 0]):
            return 2
        while b - a > 1:  # the interval [tab[a], tab[a + 1]] that holds d
            m = (a + b) // 2
            if tab[m, 0] <= d:
                a = m
            else:
                b = m
        if tab[a, 3] == 0.0:
            return 2
        x0 = tab[a, 0]
        h = tab[a + 1, 0] - x0
        t = (d - x0) / h
        H0 = tab[a, 1]
        dH = tab[a + 1, 1] - H0
        k0 = tab[a, 2] * h
        k1 = tab[a + 1, 2] * h
        H = H0 + t * (k0 + t * ((3.0 * dH - 2.0 * k0 - k1) + t * (k0 + k1 - 2.0 * dH)))
        if H < 0.0:
            H = 0.0
        ds = d if d > 0.0 else 1.0
        flx = -H * dx / ds
        fly = -H * dy / ds
        Fx += flx
        Fy += fly
        Nz += (fx - x) * fly - (fy - y) * flx
    if free:
        Nz = cx * Fy - cy * Fx
    out[0] = c * Fx + s * Fy
    out[1] = -s * Fx + c * Fy
    out[2] = Nz
    return 0


def _compiled_kernel():
    """:func:`_tau_kernel_py` compiled by numba (cached on disk when possible), or None without
    numba. Compiled on first use, so importing tapm_opt does not load numba."""
    global _KERNEL
    if _KERNEL is None:
        from .._jit import jit

        _KERNEL = jit(_tau_kernel_py, fallback=False)
    return _KERNEL or None


class TabulatedMooringLoad:
    """Fast evaluation of the quasi-static mooring load ``tau_moor(eta)`` of a
    :class:`~tapm_opt.models.mooring.MooringModel` from tabulated line characteristics.

    Build with :meth:`MooringModel.load_evaluator <tapm_opt.models.mooring.MooringModel.load_evaluator>`.

    Model: the same elastic catenary as :meth:`MooringModel.force
    <tapm_opt.models.mooring.MooringModel.force>` (:func:`tapm_opt.models.catenary.solve`, with
    each line's ``h_A``, seabed friction ``CB`` and every regime), tabulated once per distinct line
    configuration (ZF, L, EA, w, CB, h_A) as the horizontal fairlead tension ``HF`` against the
    horizontal anchor–fairlead distance ``XF`` (eq. 25): a piecewise cubic Hermite interpolant
    through the exact ``HF`` and ``dHF/dXF`` at its nodes, with a node pair at each regime change
    (where the stiffness has a kink), refined until it matches the catenary to ``rtol`` at three
    points of every interval. The geometry (eq. 5, 17–23, locked or free turret) is exact, the
    same operations as :meth:`MooringModel.tau_from_H`. The lines are those of the model (broken
    lines are not in it). Evaluated by one compiled (numba) function over all lines, or, without
    numba, by numpy (``kernel``).

    Accuracy: each line's ``HF`` is within ``rtol * max(HF, H_0)`` of the exact catenary at the
    checked points (a quarter, half and three quarters into every interval; the Hermite error
    peaks at the half), with ``H_0`` the largest pretension at the field zero point among the lines
    of that configuration (its weight ``w L`` if it is slack there); :attr:`max_error` is the
    largest checked error in that unit. The load then differs from ``MooringModel.force`` by at most
    ``sum_i rtol max(HF_i, H_0,i)`` [N] in X and Y, and in N by that sum weighted with the lever
    arm about the body origin of each fairlead (locked turret) or of the centre of turret (free)
    [N m]. Default
    ``rtol = 1e-9``: on fpso (12 lines) at most 0.11 N in X, Y over 3000 random poses within 100 m
    of the field zero point, where single lines carry up to 49 MN.

    Coverage: the tables span every distance a line takes with the body origin up to
    ``max_offset`` [m] from the field zero point at any heading. A pose where any line's distance
    falls outside its table (or in an interval the refinement could not bring within tolerance)
    is computed by the exact ``MooringModel.force``, so the answer is always the catenary's, only
    slower there (:attr:`exact_calls` counts them).

    Call ``load(eta)`` or ``load.force(eta)``: ``eta`` (3,) = (x [m], y [m], psi [rad]) in {E};
    returns ``tau_moor`` (3,) in {B} [N, N, N m], a new array. A pose that is not 3 finite numbers
    raises :class:`~tapm_opt.errors.ModelError` naming it. The evaluator keeps no state between
    calls: the answer depends on ``eta`` alone.

    Parameters
    ----------
    model : MooringModel
    max_offset : float, optional
        Offset radius [m] the tables cover at any heading; default 30 % of the deepest seabed
        below the fairleads (``max(ZF + h_A)``), 295 m on fpso.
    rtol : float
        Relative tolerance of each line's tabulated ``HF`` (above), in (0, 1e-3].
    kernel : {"auto", "numba", "numpy"}
        ``"auto"``: numba if it can be imported, else numpy.

    Attributes
    ----------
    model : MooringModel
        The model tabulated (and called beyond the tables).
    max_offset, rtol : float
        As given (``max_offset`` resolved to its default) [m], [-].
    max_error : float
        Largest checked error of the usable intervals, in units of ``rtol * max(HF, H_0)`` (<= 1).
    kernel : {"numba", "numpy"}
        The path in use.
    exact_calls : int
        Calls answered by ``MooringModel.force`` because a line's distance was not covered.
    """

    def __init__(self, model: Any, *, max_offset: float | None = None, rtol: float = 1e-9,
                 kernel: str = "auto"):
        if kernel not in ("auto", "numba", "numpy"):
            raise ModelError(f"kernel = {kernel!r} is not one of 'auto', 'numba', 'numpy'")
        if not (isinstance(rtol, (int, float)) and math.isfinite(rtol) and 0 < rtol <= 1e-3):
            raise ModelError(f"rtol = {rtol!r} must be a number in (0, 1e-3]")
        if max_offset is None:
            max_offset = 0.3 * float(np.max(model.ZF + model.h_A))
        if not (isinstance(max_offset, (int, float)) and math.isfinite(max_offset) and max_offset >= 0):
            raise ModelError(f"max_offset = {max_offset!r} m must be a finite number >= 0")
        self.model = model
        self.max_offset = float(max_offset)
        self.rtol = float(rtol)
        self.exact_calls = 0
        eta0 = np.zeros(3)
        _, _, XF0 = model.spans(eta0)
        H0 = model.solve_lines(eta0).HF
        # a line's fairlead moves at most |p| + 2 |p_cot| + 2 |p_T| from where it is at eta = 0
        reach = self.max_offset + 2.0 * float(np.hypot(*model.p_cot_B)) + 2.0 * np.hypot(model.p_T[:, 0], model.p_T[:, 1])
        first: dict = {}
        line_table = np.array([first.setdefault(model.line_key(i), len(first)) for i in range(model.n_lines)],
                              dtype=np.int64)
        reps = [int(np.flatnonzero(line_table == j)[0]) for j in range(len(first))]
        tables = []
        for j, i0 in enumerate(reps):
            ZF, L, EA, w = (float(a[i0]) for a in (model.ZF, model.L, model.EA, model.w))
            mine = line_table == j
            lo = max(float(np.min(XF0[mine] - reach[mine])), 0.0)
            hi = float(np.max(XF0[mine] + reach[mine]))
            if not np.isfinite(EA):  # an inextensible line cannot reach beyond its straight length
                hi = min(hi, math.sqrt(max(L * L - ZF * ZF, 0.0)) * (1.0 - 1e-9))
            H_ref = float(np.max(H0[mine])) or w * L or 1.0
            if hi <= lo:  # nothing to tabulate: every pose goes to the exact model
                tables.append(_LineTable(X=np.array([lo, lo + 1.0]), H=np.zeros(2), K=np.zeros(2),
                                         T=np.zeros(2), KT=np.zeros(2), ok=np.zeros(1, bool),
                                         err=np.full(1, np.inf)))
                continue
            tables.append(_shared_line_table(model, i0, lo, hi, rtol=self.rtol, H_ref=H_ref))
        self._tables = tuple(tables)
        self._line_table = line_table
        self._members = tuple(np.flatnonzero(line_table == j) for j in range(len(tables)))
        self.max_error = float(max(np.max(t.err[t.ok], initial=0.0) for t in tables))
        # packed arrays of the compiled kernel (private, writable, contiguous)
        self._par = np.array([model.p_cot_B[0], model.p_cot_B[1], model.turret_angle,
                              1.0 if model.turret_mode == "free" else 0.0])
        self._geo = np.ascontiguousarray(np.column_stack([model.anchors, model.p_T, line_table.astype(float)]))
        sizes = np.array([t.X.size for t in tables])
        stops = np.cumsum(sizes)
        self._seg = np.ascontiguousarray(np.column_stack([stops - sizes, stops]).astype(np.int64))
        self._tab = np.ascontiguousarray(np.concatenate(
            [np.column_stack([t.X, t.H, t.K, np.r_[t.ok, False].astype(float)]) for t in tables]))
        k = _compiled_kernel() if kernel in ("auto", "numba") else None
        if kernel == "numba" and k is None:
            raise ModelError("kernel = 'numba' but numba cannot be imported; use 'numpy' or 'auto'")
        self.kernel = "numba" if k is not None else "numpy"
        self._k = k
        if k is not None:  # compile (or load from the disk cache) now, not in the first control step
            k(eta0, self._par, self._geo, self._seg, self._tab, np.empty(3))

    # -- information ----------------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        """Total number of table nodes (all line configurations)."""
        return int(self._tab.shape[0])

    @property
    def xf_ranges(self) -> np.ndarray:
        """(n_lines, 2) distance range [m] each line's table covers."""
        return np.array([[self._tables[j].X[0], self._tables[j].X[-1]] for j in self._line_table])

    def horizontal_tensions(self, XF) -> np.ndarray:
        """Tabulated ``HF`` [N] of every line at horizontal distances ``XF`` (n_lines,) [m]; NaN
        outside a table or in an unusable interval (numpy, for checks and plots)."""
        XF = np.asarray(XF, dtype=float)
        if XF.shape != (self.model.n_lines,):
            raise ModelError(f"XF must have shape ({self.model.n_lines},), got {XF.shape}")
        H = np.full(XF.shape, np.nan)
        for j, tb in enumerate(self._tables):
            mine = np.flatnonzero(self._line_table == j)
            x = XF[mine]
            inside = (x >= tb.X[0]) & (x <= tb.X[-1])
            a = np.clip(np.searchsorted(tb.X, x, side="right") - 1, 0, tb.X.size - 2)
            h = _hermite(tb.X[a], tb.X[a + 1], tb.H[a], tb.H[a + 1], tb.K[a], tb.K[a + 1], x)
            H[mine] = np.where(inside & tb.ok[a], np.maximum(h, 0.0), np.nan)
        return H

    def characteristics(self, eta) -> np.ndarray:
        """Every line's characteristic about the pose ``eta`` from the tables: the rows of
        :meth:`MooringModel.characteristics <tapm_opt.models.mooring.MooringModel.characteristics>`
        (survey eq. 26–28) — H0 [N], dH/dXF [N/m], XF0 [m], T0 [N], dT/dXF [N/m] — shape (5, n).

        H0 and T0 are the tables' values (within ``rtol`` of the catenary, class docstring), the
        slopes the derivatives of the same cubics (their error is larger, of the order of
        ``rtol * max(HF, H_0)`` over the node spacing: below 1e-5 of the exact slope's scale on
        fpso, ``tests/test_mooring_fast.py``). A pose with a line beyond its table is computed by
        the exact model (counted in :attr:`exact_calls`)."""
        e = np.asarray(eta, dtype=float)
        if e.shape != (3,) or not np.all(np.isfinite(e)):
            return self.model.characteristics(e)  # raises ModelError naming the values
        _, _, XF = self.model.spans(e)
        out = np.empty((5, XF.size))
        out[2] = XF
        for j, tb in enumerate(self._tables):
            mine = self._members[j]
            x = XF[mine]
            if not (np.all(x >= tb.X[0]) and np.all(x <= tb.X[-1])):
                break
            a = np.minimum(np.searchsorted(tb.X, x, side="right") - 1, tb.X.size - 2)
            if not np.all(tb.ok[a]):
                break
            x0, x1 = tb.X[a], tb.X[a + 1]
            args = (x0, x1, tb.H[a], tb.H[a + 1], tb.K[a], tb.K[a + 1], x)
            argsT = (x0, x1, tb.T[a], tb.T[a + 1], tb.KT[a], tb.KT[a + 1], x)
            out[0, mine] = np.maximum(_hermite(*args), 0.0)
            out[1, mine] = _hermite_slope(*args)
            out[3, mine] = _hermite(*argsT)
            out[4, mine] = _hermite_slope(*argsT)
        else:
            return out
        self.exact_calls += 1
        return self.model.characteristics(e)

    # -- evaluation -------------------------------------------------------------------------
    def force(self, eta) -> np.ndarray:
        """Mooring load ``tau_moor`` (3,) in {B} [N, N, N m] at pose ``eta`` (class docstring)."""
        e = eta
        if type(e) is not np.ndarray or e.dtype != np.float64 or not (e.flags.c_contiguous and e.flags.writeable):
            e = np.array(eta, dtype=float)
        if e.shape != (3,):
            return self.model.force(e)  # raises ModelError naming the shape
        if self._k is not None:
            out = np.empty(3)
            status = self._k(e, self._par, self._geo, self._seg, self._tab, out)
            if status == 0:
                return out
        else:
            if not np.all(np.isfinite(e)):
                status = 1
            else:
                _, _, XF = self.model.spans(e)
                H = self.horizontal_tensions(XF)
                if np.all(np.isfinite(H)):
                    return self.model.tau_from_H(e, H)
                status = 2
        if status == 1:
            return self.model.force(e)  # raises ModelError naming the values
        self.exact_calls += 1
        return self.model.force(e)

    __call__ = force

    def __repr__(self) -> str:
        return (f"TabulatedMooringLoad({self.model.n_lines} lines, {len(self._tables)} table(s), "
                f"{self.n_nodes} nodes, max_offset={self.max_offset:g} m, rtol={self.rtol:g}, "
                f"kernel={self.kernel!r})")


def tension_source(solve, lo: float, hi: float, T_ref: float, *, rtol: float = 1e-9):
    """A line's fairlead tension from an adaptive table: ``x -> (TF, dTF/dXF)`` [N, N/m] as a
    namespace with attributes ``TF`` and ``dTF_dXF`` (the fields of a ``CatenarySolution`` a
    tension table reads), over [lo, hi] [m].

    The table is :func:`_line_table`'s (node pairs at every regime change, checked to ``rtol``
    against ``solve``, the line's quasi-static solution, ``MooringModel.line_solver``); the exact
    ``solve`` answers outside it or in an interval it marks unusable. For callers that need many
    evaluations of a line whose exact solve is expensive (a composite line) and whose curve has
    kinks a uniform grid resolves only with many nodes (where a joint meets the seabed)."""
    from types import SimpleNamespace

    tb = _line_table(solve, lo, hi, rtol=rtol, H_ref=T_ref)

    def tf(x):
        x = np.asarray(x, dtype=float)
        j = np.clip(np.searchsorted(tb.X, x, side="right") - 1, 0, tb.X.size - 2)
        T = _hermite(tb.X[j], tb.X[j + 1], tb.T[j], tb.T[j + 1], tb.KT[j], tb.KT[j + 1], x)
        K = _hermite_slope(tb.X[j], tb.X[j + 1], tb.T[j], tb.T[j + 1], tb.KT[j], tb.KT[j + 1], x)
        bad = ~tb.ok[j] | (x < tb.X[0]) | (x > tb.X[-1])
        if np.any(bad):
            ex = solve(x[bad])
            T[bad], K[bad] = ex.TF, ex.dTF_dXF
        return SimpleNamespace(TF=T, dTF_dXF=K)

    return tf
