"""Thruster geometry: the thrust configuration matrix (one definition for plant and allocation).

A thruster i at (x_i, y_i) in {B} producing thrust f_i [N] along the direction alpha_i (measured
from x^B toward y^B) gives the generalised force in {B}

    tau = sum_i f_i (cos alpha_i, sin alpha_i, x_i sin alpha_i - y_i cos alpha_i) = T(alpha) f.

In the extended-thrust form an azimuth thruster's force components (f_x, f_y) = f (cos, sin) are
the unknowns and ``tau = B u`` with the constant columns (1, 0, -y_i) and (0, 1, x_i).
Works on numpy arrays and CasADi symbols.
"""

from __future__ import annotations

import math
from typing import Sequence

import casadi as ca
import numpy as np

from .. import _backend as bk
from ..errors import ModelError

__all__ = ["configuration_matrix", "extended_columns", "merge_sectors"]

_TWO_PI = 2.0 * math.pi


def configuration_matrix(alpha, x, y):
    """T(alpha), shape (3, n): column i = (cos a_i, sin a_i, x_i sin a_i - y_i cos a_i).

    Parameters
    ----------
    alpha : array_like (n,) or CasADi column
        Thrust directions [rad].
    x, y : array_like (n,)
        Thruster positions in {B} [m].
    """
    c, s = bk.cos(alpha), bk.sin(alpha)
    if bk.is_symbolic(alpha):
        x, y = ca.DM(np.asarray(x, float)), ca.DM(np.asarray(y, float))
        return ca.vertcat(c.T, s.T, (x * s - y * c).T)
    x, y = np.asarray(x, float), np.asarray(y, float)
    return np.stack([c, s, x * s - y * c])


def extended_columns(x: float, y: float) -> np.ndarray:
    """Columns of tau for the force components (f_x, f_y) of one thruster at (x, y): shape (3, 2)."""
    return np.array([[1.0, 0.0], [0.0, 1.0], [-float(y), float(x)]])


def merge_sectors(sectors: Sequence[Sequence[float]], where: str, *,
                  error: type[Exception] = ModelError) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Union of forbidden arcs ``(from, to)`` (counter-clockwise, i.e. increasing angle, from
    ``from`` to ``to``) as sorted disjoint ``(starts, widths)`` [rad].

    ``where`` names the thruster in error messages; ``error`` is the exception type raised for a
    malformed sector or sectors that forbid every direction."""
    ivs: list[tuple[float, float]] = []
    for k, sec in enumerate(sectors):
        if len(sec) != 2 or not all(math.isfinite(float(v)) for v in sec):
            raise error(f"{where}.forbidden_sectors[{k}]={tuple(sec)!r} must be two finite angles (from, to) [rad]")
        a, b = float(sec[0]), float(sec[1])
        w = (b - a) % _TWO_PI
        if w <= 0.0:
            continue
        a %= _TWO_PI
        if a + w > _TWO_PI:
            ivs += [(a, _TWO_PI), (0.0, a + w - _TWO_PI)]
        else:
            ivs.append((a, a + w))
    if not ivs:
        return (), ()
    ivs.sort()
    merged = [list(ivs[0])]
    for s, e in ivs[1:]:
        if s <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], e)
        else:
            merged.append([s, e])
    if len(merged) > 1 and merged[0][0] <= 0.0 and merged[-1][1] >= _TWO_PI:  # joins across 0
        last = merged.pop()
        merged[0] = [last[0], merged[0][1] + _TWO_PI]
    widths = tuple(e - s for s, e in merged)
    if sum(widths) >= _TWO_PI * (1.0 - 1e-12):
        raise error(f"{where}.forbidden_sectors forbid every direction")
    return tuple(s % _TWO_PI for s, _ in merged), widths
