"""Frames and kinematics of a turret-moored vessel (survey §3.1, eq. 1–6).

Every function here works on numpy arrays and on CasADi symbols (SX/MX), so the control-design
models and the numpy plant share one definition of each relation.

Frames (NED): {E} earth-fixed at the field zero point, x north, y east, z down; {B} body-fixed,
x forward, y starboard, z down; {T} turret-fixed at the centre of turret (COT), rotated by the
turret angle ``alpha_t`` about z^B.
"""

from __future__ import annotations

import math
from typing import Sequence

import casadi as ca
import numpy as np

from . import _backend as bk

__all__ = [
    "rot_z",
    "R",
    "R2",
    "rot2_apply",
    "ssa",
    "fairleads_T",
    "fairleads_B",
    "fairleads_E",
    "turret_position",
    "turret_offset",
    "body_from_turret",
    "merge_sectors",
]


def rot_z(psi):
    """3-DOF rotation matrix R(psi) of eq. (1): eta_dot = R(psi) nu.

    Parameters
    ----------
    psi : float, ndarray or CasADi scalar
        Heading [rad]. A numpy array of shape (...) gives matrices of shape (..., 3, 3).

    Returns
    -------
    ndarray, shape (3, 3) or (..., 3, 3), or CasADi 3x3
    """
    c, s = bk.cos(psi), bk.sin(psi)
    if bk.is_symbolic(psi):
        return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))
    c = np.asarray(c, dtype=float)
    out = np.zeros(c.shape + (3, 3))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    out[..., 2, 2] = 1.0
    return out


#: Alias in the survey's notation, R(psi) of eq. (1).
R = rot_z


def R2(angle):
    """2x2 rotation matrix of eq. (4).

    Parameters
    ----------
    angle : float, ndarray or CasADi scalar
        Rotation angle [rad]; numpy arrays of shape (...) give (..., 2, 2).
    """
    c, s = bk.cos(angle), bk.sin(angle)
    if bk.is_symbolic(angle):
        return ca.vertcat(ca.horzcat(c, -s), ca.horzcat(s, c))
    c = np.asarray(c, dtype=float)
    out = np.empty(c.shape + (2, 2))
    out[..., 0, 0] = c
    out[..., 0, 1] = -s
    out[..., 1, 0] = s
    out[..., 1, 1] = c
    return out


def rot2_apply(angle, x, y):
    """Rotate the planar vector(s) (x, y) by ``angle``: returns R2(angle) @ (x, y).

    Works elementwise on numpy arrays (broadcasting) and on CasADi column vectors.
    """
    c, s = bk.cos(angle), bk.sin(angle)
    return c * x - s * y, s * x + c * y


def ssa(angle):
    """Smallest signed angle: wrap ``angle`` [rad] to the interval [-pi, pi).

    Works on floats, numpy arrays and CasADi symbols.
    """
    return angle - 2.0 * np.pi * bk.floor((angle + np.pi) / (2.0 * np.pi))


def fairleads_T(radius, gamma):
    """Fairlead (terminal point) positions in the turret frame {T}, eq. (2).

    Parameters
    ----------
    radius : array_like, shape (n,)
        Radius r_i of the fairlead circle [m].
    gamma : array_like, shape (n,)
        Fairlead angle gamma_i in {T} [rad].

    Returns
    -------
    ndarray, shape (n, 2)
        (x, y) of each fairlead in {T} [m].
    """
    radius = np.asarray(radius, dtype=float)
    gamma = np.asarray(gamma, dtype=float)
    return np.stack([radius * np.cos(gamma), radius * np.sin(gamma)], axis=-1)


def fairleads_B(p_cot_B, p_T, alpha_t):
    """Fairlead positions in {B}, eq. (3): p^B = p_cot^B + R2(alpha_t) p^T.

    Parameters
    ----------
    p_cot_B : array_like, shape (2,)
        Centre of turret in {B} [m].
    p_T : array_like, shape (n, 2)
        Fairleads in {T} [m].
    alpha_t : float or CasADi scalar
        Turret angle relative to the hull x-axis [rad].

    Returns
    -------
    (x, y) : tuple of ndarray shape (n,) or CasADi columns — fairleads in {B} [m].
    """
    p_T = np.asarray(p_T, dtype=float)
    xr, yr = rot2_apply(alpha_t, p_T[:, 0], p_T[:, 1])
    return p_cot_B[0] + xr, p_cot_B[1] + yr


def fairleads_E(eta, p_cot_B, p_T, alpha_t):
    """Fairlead positions in {E}, eq. (5): p^E = p + R2(psi) p_cot^B + R2(psi + alpha_t) p^T.

    Parameters
    ----------
    eta : array_like shape (3,) or CasADi 3-vector
        Vessel position and heading (x [m], y [m], psi [rad]) in {E}.
    p_cot_B : array_like, shape (2,)
        Centre of turret in {B} [m].
    p_T : array_like, shape (n, 2)
        Fairleads in {T} [m].
    alpha_t : float or CasADi scalar
        Turret angle relative to the hull [rad]. A turret held at a fixed orientation in {E}
        (free, weathervaning hull) has ``alpha_t = psi_t - psi`` with psi_t its heading in {E}.

    Returns
    -------
    (x, y) : tuple of ndarray shape (n,) or CasADi columns — fairleads in {E} [m].
    """
    p_T = np.asarray(p_T, dtype=float)
    x, y, psi = eta[0], eta[1], eta[2]
    cx, cy = rot2_apply(psi, p_cot_B[0], p_cot_B[1])
    tx, ty = rot2_apply(psi + alpha_t, p_T[:, 0], p_T[:, 1])
    return x + cx + tx, y + cy + ty


def turret_position(eta, p_cot_B):
    """Horizontal position of the centre of turret (COT) in {E}: p + R2(psi) p_cot^B (eq. 5 with
    r = 0).

    Parameters
    ----------
    eta : array_like, shape (3,) or (..., 3), or CasADi 3-vector
        Body-origin pose (x [m], y [m], psi [rad]) in {E}; a numpy array of shape (..., 3) gives
        one turret position per row.
    p_cot_B : array_like, shape (2,)
        Centre of turret in {B} [m].

    Returns
    -------
    (x, y) : floats, ndarrays of shape (...), or CasADi scalars — the COT in {E} [m].
    """
    if bk.is_symbolic(eta):
        x, y, psi = eta[0], eta[1], eta[2]
    else:
        eta = np.asarray(eta, dtype=float)
        if eta.ndim == 0 or eta.shape[-1] != 3:
            raise ValueError(f"eta must have 3 components (x, y, psi) along its last axis, got shape {eta.shape}")
        x, y, psi = eta[..., 0], eta[..., 1], eta[..., 2]
    cx, cy = rot2_apply(psi, float(p_cot_B[0]), float(p_cot_B[1]))
    return x + cx, y + cy


def turret_offset(eta, p_cot_B):
    """Turret-referenced offset: the COT's horizontal position relative to where it rests at the
    field zero point (eta = 0), ``p + R2(psi) p_cot^B - p_cot^B`` [m].

    This is the position every safety measure of tapm_opt refers to (offsets, safe and alert
    circles, position setpoints and errors): the mooring acts at the turret, and a pure rotation
    of the hull about the turret has offset zero. Same arguments and shapes as
    :func:`turret_position`.
    """
    x, y = turret_position(eta, p_cot_B)
    return x - float(p_cot_B[0]), y - float(p_cot_B[1])


def body_from_turret(p_turret_offset, psi, p_cot_B):
    """Body-origin position (x, y) [m] that puts the turret at ``p_turret_offset`` (relative to its
    field-zero-point position) with heading ``psi`` [rad]: the inverse of :func:`turret_offset`."""
    cx, cy = rot2_apply(psi, float(p_cot_B[0]), float(p_cot_B[1]))
    return (p_turret_offset[0] + float(p_cot_B[0]) - cx, p_turret_offset[1] + float(p_cot_B[1]) - cy)


_TWO_PI = 2.0 * np.pi


def merge_sectors(sectors: Sequence[Sequence[float]], where: str, *,
                  error: type[Exception] = ValueError) -> tuple[tuple[float, ...], tuple[float, ...]]:
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
