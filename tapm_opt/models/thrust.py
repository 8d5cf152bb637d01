"""Thruster geometry: the thrust configuration matrix (one definition for plant and allocation).

A thruster i at (x_i, y_i) in {B} producing thrust f_i [N] along the direction alpha_i (measured
from x^B toward y^B) gives the generalised force in {B}

    tau = sum_i f_i (cos alpha_i, sin alpha_i, x_i sin alpha_i - y_i cos alpha_i) = T(alpha) f.

In the extended-thrust form an azimuth thruster's force components (f_x, f_y) = f (cos, sin) are
the unknowns and ``tau = B u`` with the constant columns (1, 0, -y_i) and (0, 1, x_i).
Works on numpy arrays and CasADi symbols.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .. import _backend as bk
from ..geometry import merge_sectors  # noqa: F401  (re-exported: the thrusters' sector arithmetic)

__all__ = ["configuration_matrix", "extended_columns", "merge_sectors"]


def configuration_matrix(alpha, x, y):
    """T(alpha), shape (3, n): column i = (cos a_i, sin a_i, x_i sin a_i - y_i cos a_i).

    Parameters
    ----------
    alpha : array_like (n,) or CasADi column
        Thrust directions [rad].
    x, y : array_like (n,)
        Thruster positions in {B} [m].
    """
    if type(alpha) is np.ndarray and alpha.ndim == 1:   # the plant's and allocator's per-step call
        c, s = np.cos(alpha), np.sin(alpha)
        T = np.empty((3, alpha.shape[0]))
        T[0], T[1] = c, s
        T[2] = np.asarray(x, float) * s - np.asarray(y, float) * c
        return T
    c, s = bk.cos(alpha), bk.sin(alpha)
    if bk.is_symbolic(alpha):
        x, y = ca.DM(np.asarray(x, float)), ca.DM(np.asarray(y, float))
        return ca.vertcat(c.T, s.T, (x * s - y * c).T)
    x, y = np.asarray(x, float), np.asarray(y, float)
    return np.stack([c, s, x * s - y * c])


def extended_columns(x: float, y: float) -> np.ndarray:
    """Columns of tau for the force components (f_x, f_y) of one thruster at (x, y): shape (3, 2)."""
    return np.array([[1.0, 0.0], [0.0, 1.0], [-float(y), float(x)]])
