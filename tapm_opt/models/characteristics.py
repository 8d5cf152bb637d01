"""Line characteristics and system restoring curves (survey eq. 25–29), as plain tables.

These functions compute; writing files is the caller's job (see ``tapm lines``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from . import catenary
from .mooring import MooringModel

__all__ = ["LineCharacteristics", "OffsetCurves", "line_characteristics", "offset_curves"]


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


def line_characteristics(model: MooringModel, *, half_range: float, n_points: int = 41) -> LineCharacteristics:
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
    sol = catenary.solve(XF, model.ZF[:, None], model.L[:, None], model.EA[:, None], model.w[:, None],
                         CB=model.CB[:, None], h_A=model.h_A[:, None])
    return LineCharacteristics(line_ids=model.line_ids, XF0=XF0, XF=XF, H=sol.HF, V=sol.VF, T=sol.TF,
                               regime=sol.regime)


def offset_curves(model: MooringModel, directions: np.ndarray, offsets: np.ndarray) -> OffsetCurves:
    """Mooring load and tensions for the vessel displaced by ``offsets`` along ``directions``.

    Parameters
    ----------
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
