"""The MPC's QPs condensed for a dense active-set solver (DAQP).

:class:`~tapm_opt.control.mpc.LinearMPC` evaluates one sparse QP per step (``build_problem(...,
linear=True)``), and :class:`~tapm_opt.control.mpc.NonlinearMPC`'s real-time iteration one
Gauss–Newton QP of the same problem linearised along the shifted previous plan: states ``X``,
thrust moves ``U`` and one slack per step and soft-constraint family ``S`` (dead band, safe circle,
tensions, riser), the dynamics as equality rows. With ``qp_solver="daqp"`` that QP is condensed
here, each step, from the same sparse data, and solved by DAQP:

* **States eliminated.** The equality rows ``A_X X + A_U U + g_eq(0) = b_eq`` have ``A_X`` unit
  lower triangular (the initial state, then ``X_k+1 - A_k X_k``), so ``X = Phi U + x_c`` by forward
  substitution; the cost and every other row are written in ``U`` alone (``T = [Phi; I]``,
  ``H_c = T' H T``, ``f_c = T'(H t_0 + q)``).
* **Slacks as soft rows.** The sparse QP has one slack per step and soft family, below which all
  of that step's rows of the family must stay (``a_r'z - S_k <= u_r``: the faces of the dead band's
  and the safe circle's polygons, the lines' tensions, the riser's octagons) and whose cost charges
  the largest violation once. DAQP's soft rows carry a slack each, ``a_r'z <= u_r`` violated by
  ``s_r`` at the cost ``w s_r + s_r^2 / (2 rho)``, with ``w`` and ``1 / rho`` the gradient and the
  curvature of ``S_k`` in the sparse QP (``soft_l1`` and ``2 soft_l2`` for the safe circle, tensions
  and riser; ``2 w_position`` — times ``w_terminal`` at the last step — for the dead band). To charge
  each step's violation once, as the sparse QP does, only one row of each slack's group enters the
  QP: the one the predicted plan (the previous plan shifted by a step) violates most — the polygon
  face the turret is predicted to cross, the line predicted to be loaded most. If the solution
  violates another row of a group more, the rows are chosen again on it and the QP solved again
  (:class:`CondensedDAQP`, up to ``passes`` solves; the plan of lowest sparse cost is kept). Where
  the chosen rows are the largest at the optimum, the condensed QP has the sparse QP's solution;
  where the optimum sits on a polygon's corner (two rows of a group equally violated), one row
  cannot express the maximum and the plan is the best of the passes (``tests/test_mpc_condensed.py``:
  never cheaper than the sparse optimum, within 1 %). The plan's reported slacks and cost are the
  sparse QP's at that plan (every row counted).

The result has ``3 M`` variables (``M`` thrust moves) instead of ``6 (N + 1) + 3 M + 4 N``, and as
rows the hard ones (the thrust polytope and its rate rows) plus one per soft group: at N = 50 with 8
moves 24 variables and 1174 rows, at N = 20 unblocked 60 variables and 2620 rows. DAQP's set-up and
update cost about rows x moves^2, and nearly all hard rows are far from the plan, so only the hard
rows the predicted plan comes near enter DAQP; the solution is checked against all of them and
solved again with any it violates, so the plan is the full QP's (:class:`CondensedDAQP`; at fpso's
default, about 2 of 2560 rows a step, a third of the solve time). While the rows stay, DAQP is
updated in place and its working set carries over from step to step (a hot start). The plan is
expanded back to the sparse QP's variables (``X`` from ``U``, each ``S_k`` the largest violation of
its rows), so the controller's diagnostics, shift and cost are those of the sparse problem. The
sparse kernels run compiled (numba, ``tapm_opt._jit``).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from .._jit import jit
from .mpc_problem import MPCError, _Problem

__all__ = ["CondensedQP", "CondensedDAQP", "DAQP_INF", "SCREEN_MARGIN"]

#: DAQP's infinity for one-sided rows.
DAQP_INF = 1e30
#: Hard rows enter the condensed QP when the predicted plan comes within this distance of their
#: face, in the scaled moves (the row's value over its norm): :class:`CondensedDAQP`.
SCREEN_MARGIN = 0.1


def _forward_unit_lower(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, n: int, B: np.ndarray) -> None:
    """Solve ``L Y = B`` in place for the unit lower triangular ``L``, the first ``n`` columns of a
    CSC matrix (rows < n; its diagonal entries are skipped, taken as 1)."""
    for j in range(n):
        for p in range(indptr[j], indptr[j + 1]):
            i = indices[p]
            if i > j:
                d = data[p]
                for c in range(B.shape[1]):
                    B[i, c] -= d * B[j, c]


def _scatter_columns(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, c0: int, out: np.ndarray,
                     sign: float) -> None:
    """``out[:, k] = sign * M[:, c0 + k]`` for the CSC matrix M (``out`` zeroed by the caller)."""
    for k in range(out.shape[1]):
        for p in range(indptr[c0 + k], indptr[c0 + k + 1]):
            out[indices[p], k] = sign * data[p]


def _sym_matmul_cols(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, ncols: int, T: np.ndarray,
                     out: np.ndarray) -> None:
    """``out += S[:ncols, :ncols] @ T`` for the symmetric S whose upper triangle is the CSC matrix."""
    for c in range(ncols):
        for p in range(indptr[c], indptr[c + 1]):
            r = indices[p]
            if r >= ncols:
                continue
            d = data[p]
            for k in range(T.shape[1]):
                out[r, k] += d * T[c, k]
            if r != c:
                for k in range(T.shape[1]):
                    out[c, k] += d * T[r, k]


def _quad_upper(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, z: np.ndarray) -> float:
    """``z' S z`` for the symmetric S whose upper triangle is the CSC matrix."""
    s = 0.0
    for c in range(z.shape[0]):
        for p in range(indptr[c], indptr[c + 1]):
            r = indices[p]
            v = data[p] * z[r] * z[c]
            s += v if r == c else 2.0 * v
    return s


def _csr_rows_times(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, rows: np.ndarray, ncols: int,
                    T: np.ndarray, out: np.ndarray) -> None:
    """``out[i] = M[rows[i], :ncols] @ T`` for the CSR matrix M and dense ``T`` (ncols x k)."""
    for i in range(rows.shape[0]):
        r = rows[i]
        for k in range(T.shape[1]):
            out[i, k] = 0.0
        for p in range(indptr[r], indptr[r + 1]):
            c = indices[p]
            if c < ncols:
                d = data[p]
                for k in range(T.shape[1]):
                    out[i, k] += d * T[c, k]


def _csr_rows_dot(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, rows: np.ndarray, ncols: int,
                  z: np.ndarray, out: np.ndarray) -> None:
    """``out[i] = M[rows[i], :ncols] @ z[:ncols]`` for the CSR matrix M."""
    for i in range(rows.shape[0]):
        r = rows[i]
        s = 0.0
        for p in range(indptr[r], indptr[r + 1]):
            c = indices[p]
            if c < ncols:
                s += data[p] * z[c]
        out[i] = s


def _first_max_per_group(v: np.ndarray, starts: np.ndarray, counts: np.ndarray, out: np.ndarray) -> bool:
    """``out[g]`` = index into ``v`` of the first largest value of group g (``v[starts[g]:starts[g] +
    counts[g]]``, each group non-empty). False (``out`` partly written) when a group holds a NaN."""
    for g in range(starts.shape[0]):
        s = starts[g]
        best = s
        bv = v[s]
        if math.isnan(bv):
            return False
        for i in range(s + 1, s + counts[g]):
            x = v[i]
            if math.isnan(x):
                return False
            if x > bv:
                bv = x
                best = i
        out[g] = best
    return True


_forward_unit_lower = jit(_forward_unit_lower)
_scatter_columns = jit(_scatter_columns)
_sym_matmul_cols = jit(_sym_matmul_cols)
_quad_upper = jit(_quad_upper)
_csr_rows_times = jit(_csr_rows_times)
_csr_rows_dot = jit(_csr_rows_dot)
_first_max_per_group = jit(_first_max_per_group)


class CondensedQP:
    """The condensed form of an MPC's sparse QP (module docstring): the linear MPC's, or the
    real-time iteration's Gauss–Newton QP in the step from the linearisation point.

    Parameters
    ----------
    prob : _Problem
        The MPC problem (``build_problem``) whose variables and index maps the QP has.
    H_pattern, Aeq_pattern, G_pattern : (row indices, column pointers)
        CSC sparsity of the upper triangle of the Hessian, of the equality rows and of the other
        rows, over the QP's variables z = (X, U, S).
    lb_in, ub_in : ndarray
        Bounds of the other rows (before subtracting their value at z = 0).

    After :meth:`condense` the DAQP problem is ``H`` (n x n), ``f``, ``A`` (m x n), ``bu``, ``bl``
    (n + m: the moves' bounds, then the rows), ``sense`` and the soft weights ``rho``, ``w``; its rows
    are the hard rows (``hard_rows``, rows of the sparse QP without a slack, or whose slack is held at
    0) followed by one row per soft group (``groups``: the slacks that cost something), the one
    chosen for the step (``chosen``). The dimensions are fixed at the first :meth:`condense`.
    """

    def __init__(self, prob: _Problem, H_pattern: tuple, Aeq_pattern: tuple, G_pattern: tuple,
                 lb_in: np.ndarray, ub_in: np.ndarray):
        idx = prob.idx
        self.nX = idx["X"].stop
        self.nU = idx["U"].stop - idx["U"].start
        self.nXU = self.nX + self.nU
        self.nz = len(prob.lbz)
        (self._Hr, self._Hc), (self._Ar, self._Ac), (self._Gr, self._Gc) = (
            tuple(np.asarray(a, np.int64) for a in pat) for pat in (H_pattern, Aeq_pattern, G_pattern))
        n_eq = int(self._Ar.max(initial=-1)) + 1 if len(self._Ar) else 0
        if n_eq != self.nX:
            raise MPCError(f"condensing: {n_eq} equality rows for {self.nX} states (the dynamics must be the "
                           "only equality rows)")
        # the equality rows have no slack, and the states come first and form a lower triangle
        if self._Ac[self.nz] != self._Ac[self.nXU]:
            raise MPCError("condensing: a slack appears in the dynamics")
        for j in range(self.nX):
            rows = self._Ar[self._Ac[j]:self._Ac[j + 1]]
            if j not in rows or np.any(rows < j):
                raise MPCError("condensing: the dynamics' state block is not lower triangular with a diagonal")
        self._eq_diag = np.array([self._Ac[j] + int(np.flatnonzero(self._Ar[self._Ac[j]:self._Ac[j + 1]] == j)[0])
                                  for j in range(self.nX)], np.int64)
        # the slack part of the Hessian is diagonal and uncoupled from X and U
        for c in range(self.nXU, self.nz):
            rows = self._Hr[self._Hc[c]:self._Hc[c + 1]]
            if np.any(rows != c):
                raise MPCError("condensing: a slack is coupled to other variables in the cost")
        self._diag_pos = np.full(self.nz, -1, np.int64)  # position of H[c, c] for the slacks
        for c in range(self.nXU, self.nz):
            if self._Hc[c + 1] > self._Hc[c]:
                self._diag_pos[c] = self._Hc[c]
        # each other row holds at most one slack, with the coefficient -1 (checked at each step)
        m = len(lb_in)
        self.row_slack = np.full(m, -1, np.int64)
        slack_pos = []
        for c in range(self.nXU, self.nz):
            for p in range(self._Gc[c], self._Gc[c + 1]):
                r = self._Gr[p]
                if self.row_slack[r] >= 0:
                    raise MPCError(f"condensing: row {r} holds two slacks")
                self.row_slack[r] = c
                slack_pos.append(p)
        self._slack_pos = np.array(slack_pos, np.int64)
        if np.any(np.isfinite(np.asarray(lb_in)[self.row_slack >= 0])):
            raise MPCError("condensing: a soft row has a finite lower bound")
        self.lb_in, self.ub_in = np.asarray(lb_in, float), np.asarray(ub_in, float)
        # G row by row: the CSR structure and the permutation of the CSC nonzeros into it
        perm = sp.csc_matrix((np.arange(len(self._Gr), dtype=float) + 1.0, self._Gr, self._Gc),
                             shape=(m, self.nz)).tocsr()
        perm.sort_indices()
        self._Rp, self._Ri = perm.indptr.astype(np.int64), perm.indices.astype(np.int64)
        self._perm = (perm.data - 1.0).astype(np.int64)
        self._B = np.zeros((self.nX, self.nU + 1))          # [Phi | x_c]
        self._T = np.zeros((self.nXU, self.nU + 1))         # [T | t_0]
        self._T[self.nX:, :self.nU] = np.eye(self.nU)
        self._W = np.zeros((self.nXU, self.nU + 1))
        self.H = np.zeros((self.nU, self.nU))
        self.f = np.zeros(self.nU)
        self.hard_rows: np.ndarray | None = None            # fixed at the first condense

    def _slack_curvature(self, Hx: np.ndarray) -> np.ndarray:
        """The Hessian's diagonal at each slack of ``slack_cols`` (0 where it has none)."""
        pos = self._diag_pos[self.slack_cols]
        return np.where(pos >= 0, Hx[np.maximum(pos, 0)], 0.0)

    def _structure(self, Hx: np.ndarray, q: np.ndarray, lbz: np.ndarray, ubz: np.ndarray) -> None:
        """Sort the rows (first condense): hard rows, soft groups with their weights, free rows."""
        self.slack_cols = np.unique(self.row_slack[self.row_slack >= 0])
        cols = self.slack_cols
        curv = self._slack_curvature(Hx)
        lin = q[cols]
        fixed = ubz[cols] <= lbz[cols]
        soft = ~fixed & ((curv > 0) | (lin > 0))
        hard = (self.row_slack < 0) | np.isin(self.row_slack, cols[fixed])
        self.hard_rows = np.flatnonzero(hard)
        # the hard rows' nonzeros (CSR positions); when none lies in a state's column, a hard row's
        # condensed form is its coefficients on the moves, the same at every step with the same
        # coefficients (``_rows_of_last_step``)
        Rp = self._Rp
        self._hard_nz = (np.concatenate([np.arange(Rp[r], Rp[r + 1]) for r in self.hard_rows]).astype(np.int64)
                         if len(self.hard_rows) else np.zeros(0, np.int64))
        self._hard_in_moves = bool(np.all(self._Ri[self._hard_nz] >= self.nX))
        self._hard_vals: np.ndarray | None = None
        #: Counts the times the hard rows' coefficients (``A[:nh]``) were written: equal counts,
        #: equal rows.
        self.hard_version = 0
        self._hard_bounds = (self.ub_in[self.hard_rows], self.lb_in[self.hard_rows])
        self.groups = cols[soft]
        self._grp_curv, self._grp_lin = curv[soft], lin[soft]
        srows = np.flatnonzero(np.isin(self.row_slack, self.groups))
        order = srows[np.argsort(self.row_slack[srows], kind="stable")]
        self._order = order
        self._starts = np.flatnonzero(np.r_[True, np.diff(self.row_slack[order]) != 0]) if len(order) else \
            np.zeros(0, np.int64)
        self._counts = np.diff(np.r_[self._starts, len(order)])
        self._first = np.zeros(len(self._starts), np.int64)
        nU, nh, ng = self.nU, len(self.hard_rows), len(self.groups)
        self.m = nh + ng
        self.A = np.zeros((self.m, nU))
        self._AT = np.zeros((self.m, nU + 1))
        self.bu = np.zeros(nU + self.m)
        self.bl = np.zeros(nU + self.m)
        self.sense = np.zeros(nU + self.m, dtype=np.intc)
        self.sense[nU + nh:] = 8
        self.rho = np.ones(nU + self.m)
        self.w = np.zeros(nU + self.m)
        self.rho[nU + nh:] = 1.0 / np.maximum(self._grp_curv, 1e-12)   # a pure L1 slack: a tiny quadratic
        self.w[nU + nh:] = self._grp_lin
        self.chosen = np.zeros(ng, np.int64)
        self._vals = np.zeros(len(order))
        self._slack_key = (lbz[self.nXU:].copy(), ubz[self.nXU:].copy(), curv.copy(), lin.copy())

    def condense(self, Hx: np.ndarray, Aeqx: np.ndarray, Gx: np.ndarray, q: np.ndarray, b_eq: np.ndarray,
                 g_eq: np.ndarray, g_in: np.ndarray, lbz: np.ndarray, ubz: np.ndarray,
                 u_pred: np.ndarray) -> None:
        """Condense the sparse QP with these values (the nonzeros of H's upper triangle, of the
        equality rows and of the other rows; the gradient at z = 0, the equality rows' right-hand
        side and both row blocks at z = 0; the variable bounds) into the DAQP problem (class
        docstring). Of each soft group the row kept is the one the predicted moves ``u_pred``
        (scaled) violate most (the first of the largest)."""
        nX, nU, nXU = self.nX, self.nU, self.nXU
        if np.any(Aeqx[self._eq_diag] != 1.0):
            raise MPCError("condensing: the dynamics' state block has a diagonal other than 1")
        if np.any(Gx[self._slack_pos] != -1.0):
            raise MPCError("condensing: a soft row's slack coefficient is not -1")
        if self.hard_rows is None:
            self._structure(Hx, q, lbz, ubz)
        else:
            key = self._slack_key
            if not (np.array_equal(key[0], lbz[nXU:]) and np.array_equal(key[1], ubz[nXU:])
                    and np.array_equal(key[2], self._slack_curvature(Hx))
                    and np.array_equal(key[3], q[self.slack_cols])):
                raise MPCError("condensing: the slacks' bounds or weights changed after the set-up")
        # states: X = Phi U + x_c
        B = self._B
        B[:] = 0.0
        _scatter_columns(self._Ac, self._Ar, Aeqx, nX, B[:, :nU], -1.0)
        B[:, nU] = b_eq - g_eq
        _forward_unit_lower(self._Ac, self._Ar, Aeqx, nX, B)
        T = self._T
        T[:nX] = B
        # cost
        W = self._W
        W[:] = 0.0
        _sym_matmul_cols(self._Hc, self._Hr, Hx, nXU, T, W)
        TW = T[:, :nU].T @ W
        self.H[:] = 0.5 * (TW[:, :nU] + TW[:, :nU].T)
        self.f[:] = TW[:, nU] + T[:, :nU].T @ q[:nXU]
        # rows: the hard ones, then of each soft group the row the predicted plan violates most
        self._Gr_vals, self._g_in = Gx[self._perm], g_in
        self.bu[:nU], self.bl[:nU] = ubz[nX:nXU], lbz[nX:nXU]
        self.sense[:nU] = np.where(self.bu[:nU] <= self.bl[:nU], 5, 0)   # a failed thruster's DOF: held
        nh = len(self.hard_rows)
        if self._rows_of_last_step():
            self._set_bounds(self.hard_rows, 0)
        else:
            self._set_rows(self.hard_rows, 0)
            self._hard_vals = self._Gr_vals[self._hard_nz]
            self.hard_version += 1
        if len(self._order):
            self.chosen[:] = self._largest(self._z_of(u_pred))
            self._set_rows(self.chosen, nh)

    def _rows_of_last_step(self) -> bool:
        """True when the hard rows' condensed form (``A[:nh]`` and its buffer) is that of the last
        step: they lie in the moves only (the moves' part of ``T`` is the identity and a zero
        constant, fixed) and their coefficients equal the last step's (a NaN never does)."""
        return (self._hard_in_moves and self._hard_vals is not None
                and np.array_equal(self._Gr_vals[self._hard_nz], self._hard_vals))

    def rechoose(self, u: np.ndarray, tol: float = 1e-7) -> bool:
        """Choose again, on the plan of the moves ``u``, the row of each soft group that plan
        violates by more than ``tol`` beyond the chosen row's violation (and beyond 0): the row it
        violates most. True (and those rows replaced) when any group changes, so the QP is to be
        solved again; a group whose rows the plan does not violate keeps its row."""
        if not len(self._order):
            return False
        z = self._z_of(u)
        rows = self._largest(z)
        v_best = self._excess(rows, z)
        v_now = self._excess(self.chosen, z)
        change = v_best > np.maximum(v_now, 0.0) + tol
        if not np.any(change):
            return False
        self.chosen[change] = rows[change]
        self._set_rows(self.chosen, len(self.hard_rows))
        return True

    def _excess(self, rows: np.ndarray, z: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Value of the sparse QP's ``rows`` above their upper bounds at ``z`` (``out``: a buffer
        for the rows' products)."""
        out = np.empty(len(rows)) if out is None else out
        _csr_rows_dot(self._Rp, self._Ri, self._Gr_vals, rows, self.nXU, z, out)
        return out + self._g_in[rows] - self.ub_in[rows]

    def _z_of(self, u: np.ndarray) -> np.ndarray:
        """States and moves of the prediction with the moves ``u`` (the first nX + nU variables)."""
        return self._T[:, :self.nU] @ u + self._T[:, self.nU]

    def _largest(self, z: np.ndarray) -> np.ndarray:
        """Of each soft group, the row with the largest value above its bound at ``z`` (the first of
        the largest)."""
        order = self._order
        v = self._excess(order, z, self._vals)
        if _first_max_per_group(v, self._starts, self._counts, self._first):
            return order[self._first]
        at_max = np.flatnonzero(v >= np.repeat(np.maximum.reduceat(v, self._starts), self._counts))
        group = np.searchsorted(self._starts, at_max, side="right") - 1
        return order[at_max[np.unique(group, return_index=True)[1]]]

    def _set_rows(self, rows: np.ndarray, at: int) -> None:
        """Write the sparse QP's ``rows`` in the moves into the DAQP rows from ``at`` on."""
        nU, k = self.nU, len(rows)
        AT = self._AT[at:at + k]
        _csr_rows_times(self._Rp, self._Ri, self._Gr_vals, rows, self.nXU, self._T, AT)
        self.A[at:at + k] = AT[:, :nU]
        self._set_bounds(rows, at)

    def _set_bounds(self, rows: np.ndarray, at: int) -> None:
        """The DAQP bounds of the rows from ``at`` on, written by :meth:`_set_rows` for the sparse
        QP's ``rows`` (their products with ``T`` in ``_AT``) and this step's row values."""
        nU, k = self.nU, len(rows)
        const = self._AT[at:at + k, nU] + self._g_in[rows]
        ub, lb = self._hard_bounds if rows is self.hard_rows else (self.ub_in[rows], self.lb_in[rows])
        np.minimum(ub - const, DAQP_INF, out=self.bu[nU + at:nU + at + k])
        np.maximum(lb - const, -DAQP_INF, out=self.bl[nU + at:nU + at + k])

    def expand(self, u: np.ndarray) -> np.ndarray:
        """The sparse QP's variables of the condensed solution ``u``: the states of the prediction,
        the moves, and each slack the largest violation of all its rows (0 when none)."""
        z = np.zeros(self.nz)
        z[:self.nX] = self._B[:, :self.nU] @ u + self._B[:, self.nU]
        z[self.nX:self.nXU] = u
        order = self._order
        if len(order):
            viol = self._excess(order, z, self._vals)
            z[self.groups] = np.maximum(np.maximum.reduceat(viol, self._starts), 0.0)
        return z

    def cost(self, Hx: np.ndarray, q: np.ndarray, z: np.ndarray) -> float:
        """The sparse QP's cost at ``z`` relative to z = 0: ``z' H z / 2 + q' z``."""
        return 0.5 * _quad_upper(self._Hc, self._Hr, Hx, z) + float(q @ z)


class CondensedDAQP:
    """A sparse MPC QP solved condensed by DAQP, step after step (module docstring): the condensed
    problem (:class:`CondensedQP`), solved by a ``daqp.Model``, and up to ``passes`` solves of a
    step, the soft rows chosen again on each solution, the plan of lowest sparse cost kept.

    **Hard rows screened** (``screen``, default :data:`SCREEN_MARGIN`; None: every row always).
    Most hard rows — the facets of the thrust polytope and of its rate polytope at every move — are
    far from the plan: at fpso's default (20 moves, 60 facets) 2560 rows, of which a handful bind.
    DAQP's set-up and update cost grows with rows x moves^2, so only the hard rows the predicted
    plan (``u_pred``) comes within ``screen`` of (the distance to the row's face over the row's
    norm, in the scaled moves) enter DAQP. The solution is then checked against every hard row;
    rows it violates beyond DAQP's ``primal_tol`` are added and the QP solved again, until none is.
    The screened QP is a relaxation of the full one, so a solution feasible for every row is the
    full QP's optimum (unique: the condensed Hessian is positive definite): the screening changes
    the work, not the plan (``tests/test_mpc_condensed.py``). A step whose rows are those of the last
    step updates the model in place with its working set kept (a hot start); otherwise DAQP is set
    up afresh (also when a thruster's DOF is held or freed).

    ``settings``: DAQP's settings (keys of ``daqp.Model().settings``).
    """

    def __init__(self, cq: CondensedQP, settings: dict, passes: int, screen: float | None = None):
        import daqp

        from .allocation import DAQP_STATUS

        self._daqp_module, self._status_names = daqp, DAQP_STATUS
        self.cq, self.settings, self.passes = cq, dict(settings), int(passes)
        self.screen = SCREEN_MARGIN if screen is None else float(screen)
        if not self.screen > 0.0:
            self.screen = math.inf   # every hard row
        self._tol = float(self.settings.get("primal_tol", 1e-6))
        self._model = None
        self._sense = b""
        self._keep: np.ndarray | None = None      # the hard rows in DAQP (a mask), None: all
        self._hard_cache: tuple | None = None     # (hard_version, hard rows, their norms, solve)
        self._solves = 0
        self._rows = np.zeros(0, np.int64)        # DAQP's rows among cq's
        self._cols = np.zeros(0, np.int64)        # ... and their entries of bu, bl, sense, rho, w
        #: Screening counts of the last solve: hard rows, rows in DAQP, solves that added rows.
        self.screen_stats = (0, 0, 0)

    def reset(self) -> None:
        """Set DAQP up afresh at the next solve."""
        self._model = None

    def _gap(self, u: np.ndarray) -> np.ndarray:
        """Distance of the moves ``u`` from each hard row's nearer bound (negative: violated), in
        the row's units (NaN where ``u`` gives none)."""
        cq = self.cq
        nU, nh = cq.nU, len(cq.hard_rows)
        v = self._hard()[0] @ u
        return np.minimum(cq.bu[nU:nU + nh] - v, v - cq.bl[nU:nU + nh])

    def _screened(self, u: np.ndarray) -> np.ndarray | None:
        """The hard rows within ``screen`` of the plan ``u`` (a mask; None: all of them)."""
        cq = self.cq
        if not math.isfinite(self.screen) or len(cq.hard_rows) <= cq.nU:
            return None
        return ~(self._gap(u) > self.screen * self._hard()[1])   # a NaN keeps its row

    def _hard(self) -> tuple:
        """The hard rows ``A[:nh]`` and their Euclidean norms, kept while the rows stay
        (``hard_version``); from the second step with the same rows a sparse copy (each row holds a
        move or two: the polytope and rate rows), cheaper to multiply."""
        cq = self.cq
        c = self._hard_cache
        if c is None or c[0] != cq.hard_version:
            Ah = cq.A[:len(cq.hard_rows)]
            c = self._hard_cache = (cq.hard_version, Ah, np.sqrt(np.einsum("ij,ij->i", Ah, Ah)), self._solves)
        elif not sp.issparse(c[1]) and self._solves > c[3]:
            c = self._hard_cache = (c[0], sp.csr_matrix(c[1]), c[2], c[3])
        return c[1:3]

    def _select(self, keep: np.ndarray | None) -> bool:
        """Set DAQP's rows to the kept hard rows and every soft row; True when they changed."""
        cq = self.cq
        nU, nh = cq.nU, len(cq.hard_rows)
        if keep is None:
            rows = np.arange(cq.m)
        else:
            rows = np.concatenate([np.flatnonzero(keep), np.arange(nh, cq.m)])
        prev = self._keep
        same = self._model is not None and (prev is None if keep is None
                                            else prev is not None and np.array_equal(prev, keep))
        self._keep, self._rows = keep, rows
        self._cols = np.concatenate([np.arange(nU), nU + rows])
        return not same

    def _setup(self) -> int:
        """A new DAQP model of the selected rows (cold). Returns DAQP's set-up flag."""
        cq, c = self.cq, self._cols
        model = self._daqp_module.Model()
        model.settings = dict(self.settings)
        flag, _ = model.setup(cq.H, cq.f, cq.A[self._rows], cq.bu[c], cq.bl[c], cq.sense[c])
        if flag < 0:
            self._model = None
            return flag
        model.soft_weights(rho_u=cq.rho[c], w_u=cq.w[c])
        self._model = model
        return flag

    def solve(self, Hx: np.ndarray, Aeqx: np.ndarray, Gx: np.ndarray, q: np.ndarray, b_eq: np.ndarray,
              g_eq: np.ndarray, g_in: np.ndarray, lbz: np.ndarray, ubz: np.ndarray,
              u_pred: np.ndarray) -> tuple[bool, str, int, np.ndarray]:
        """Condense and solve (arguments of :meth:`CondensedQP.condense`). Returns ``(ok, status,
        iterations, z)``: ``z`` the sparse QP's variables of the plan (NaN when no solve succeeded),
        ``status`` DAQP's (``allocation.DAQP_STATUS`` names)."""
        DAQP_STATUS = self._status_names
        cq = self.cq
        self._solves += 1
        cq.condense(Hx, Aeqx, Gx, q, b_eq, g_eq, g_in, lbz, ubz, u_pred=u_pred)
        sense = cq.sense.tobytes()
        changed = self._select(self._screened(np.asarray(u_pred, float)))
        if self._model is None or changed or sense != self._sense:
            flag = self._setup()     # new rows, or a thruster's DOF held or freed: start cold
            if flag < 0:
                self._sense = b""
                return False, f"setup: {DAQP_STATUS.get(flag, flag)}", 0, np.full(cq.nz, np.nan)
        else:                        # the same rows: DAQP keeps its working set
            c = self._cols
            self._model.update(H=cq.H, f=cq.f, A=cq.A[self._rows], bupper=cq.bu[c], blower=cq.bl[c])
        self._sense = sense
        best, it, status, added = None, 0, "", 0
        k = 0
        while k < self.passes:
            u, _, flag, info = self._model.solve()
            u = np.asarray(u, float)
            it += int(info["iterations"])
            status = DAQP_STATUS.get(flag, f"exitflag_{flag}")
            if not (flag > 0 and np.all(np.isfinite(u))):
                break
            if self._keep is not None:
                gap = self._gap(u)   # a screened-out row violated beyond DAQP's tolerance (or NaN)
                bad = ~self._keep & ~(gap >= -self._tol)
                if bad.any():        # add it, and the rows near u, and solve again
                    self._select(self._keep | bad | ~(gap > self.screen * self._hard()[1]))
                    added += 1
                    if self._setup() < 0:
                        break
                    continue
            z = cq.expand(u)
            c = cq.cost(Hx, q, z)
            if best is None or c < best[0]:
                best = (c, z, status)
            k += 1
            if k >= self.passes or not cq.rechoose(u):
                break
            cols = self._cols
            self._model.update(A=cq.A[self._rows], bupper=cq.bu[cols], blower=cq.bl[cols])
        self.screen_stats = (len(cq.hard_rows), len(self._rows) - (cq.m - len(cq.hard_rows)), added)
        if best is None:
            return False, status, it, np.full(cq.nz, np.nan)
        return True, best[2], it, best[1]
