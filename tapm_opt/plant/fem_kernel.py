"""Compiled (numba) kernel of the lumped-mass FEM lines: accelerations and symplectic-Euler steps.

One function, :func:`advance`, runs ``n_steps`` steps of :meth:`FEMLines.step
<tapm_opt.plant.fem.FEMLines.step>` in one call: the same forces (axial tension-only elasticity
with internal damping, submerged weight, Morison drag normal and tangential to the node tangent
on the velocity relative to the current, seabed spring-damper), the same closed-form inverse of
the node mass + added-mass matrix, the same update (with the implicit Coulomb seabed friction of
``FEMLines._friction``)
(``v += dt a``, anchors fixed, attached fairleads prescribed, ``r += dt v``), evaluated in the same
floating-point order as the numpy reference path, so the two agree to round-off (checked in
``tests/test_fem_kernel.py``).

The per-line constants are passed as the arrays :class:`~tapm_opt.plant.fem.FEMLines` holds (no
copies): a winch that changes the unstretched lengths (``FEMLines._update_lengths``) is seen by
the next call. The kernel keeps no state: positions and velocities come in and go out as arrays.

Floating point follows numpy (``error_model="numpy"``: a division by zero gives inf or nan, as
in the numpy path, and :meth:`~tapm_opt.plant.fem.FEMLines.check_health` reports it; no fast-math,
so the operations keep their order). The functions are compiled on first use and cached on disk
(``cache=True``, in the package's ``__pycache__``); later processes load the compiled code. If
numba cannot be imported, :data:`AVAILABLE` is False, a :class:`RuntimeWarning` says so, and
:class:`~tapm_opt.plant.fem.FEMLines` falls back to its numpy path.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

__all__ = ["AVAILABLE", "advance"]

from .._jit import jit as _jit, numba_available

AVAILABLE = numba_available()
if not AVAILABLE:
    warnings.warn("numba is not available; the FEM mooring lines use the numpy path, which is "
                  "several times slower per step (install numba to restore the compiled kernel)",
                  RuntimeWarning, stacklevel=2)


@_jit
def _step(r, v, vc, dt, extra_damping, fl_r, fl_v,
          l0, EA, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half,
          kb, cb, mu, depth, has_int_damping, has_friction,
          anchor_idx, anchors, fairlead_idx, attached,
          r_out, v_out, T, qp, tvp, epsp, F_node):  # pragma: no cover - compiled
    """One step from (r, v) into (r_out, v_out); bond tensions at the start of the step into T
    and the net force on every node (before the mass inversion) into ``F_node`` (n_nodes, 3).

    ``qp``, ``tvp`` (n_nodes + 1, 3) and ``epsp`` (n_nodes + 1,) are the padded bond buffers of
    the numpy path (row i + 1 holds bond i; rows 0 and n_nodes stay zero).
    """
    n = r.shape[0]
    # bonds: tangent, tension vector and stretched length (0 on the non-segment bonds)
    for i in range(n - 1):
        lx = r[i + 1, 0] - r[i, 0]
        ly = r[i + 1, 1] - r[i, 1]
        lz = r[i + 1, 2] - r[i, 2]
        e = math.sqrt(lx * lx + ly * ly + lz * lz)
        strain = e / l0[i] - 1.0
        t = EA[i] * strain
        if has_int_damping:
            dx = v[i + 1, 0] - v[i, 0]
            dy = v[i + 1, 1] - v[i, 1]
            dz = v[i + 1, 2] - v[i, 2]
            t += c_int[i] * (dx * lx + dy * ly + dz * lz) / (e * l0[i])
        if strain <= 0.0:
            t = 0.0
        elif t < 0.0:
            t = 0.0
        T[i] = t
        ok = 1.0 if bond_ok[i] else 0.0
        inv = ok / e
        qx = lx * inv
        qy = ly * inv
        qz = lz * inv
        qp[i + 1, 0] = qx
        qp[i + 1, 1] = qy
        qp[i + 1, 2] = qz
        tvp[i + 1, 0] = t * qx
        tvp[i + 1, 1] = t * qy
        tvp[i + 1, 2] = t * qz
        epsp[i + 1] = e * ok
    # nodes: forces, accelerations, velocity and position updates
    for k in range(n):
        Fx = tvp[k + 1, 0] - tvp[k, 0]
        Fy = tvp[k + 1, 1] - tvp[k, 1]
        Fz = tvp[k + 1, 2] - tvp[k, 2]
        Fz += node_weight[k]
        qx = qp[k + 1, 0] + qp[k, 0]
        qy = qp[k + 1, 1] + qp[k, 1]
        qz = qp[k + 1, 2] + qp[k, 2]
        nq = math.sqrt(qx * qx + qy * qy + qz * qz)
        qx /= nq
        qy /= nq
        qz /= nq
        s = epsp[k + 1] + epsp[k]  # twice the node's stretched length
        vrx = v[k, 0] - vc[k, 0]
        vry = v[k, 1] - vc[k, 1]
        vrz = v[k, 2] - vc[k, 2]
        vt = vrx * qx + vry * qy + vrz * qz
        vnx = vrx - vt * qx
        vny = vry - vt * qy
        vnz = vrz - vt * qz
        vn_mag = math.sqrt(vnx * vnx + vny * vny + vnz * vnz)
        cn = cdn[k] * s * vn_mag
        Fx -= cn * vnx
        Fy -= cn * vny
        Fz -= cn * vnz
        ct = cdt[k] * s * abs(vt) * vt
        Fx -= ct * qx
        Fy -= ct * qy
        Fz -= ct * qz
        pen = r[k, 2] - depth
        Fn = 0.0
        if pen > 0.0:
            Fn = kb[k] * pen + cb[k] * v[k, 2]
            if Fn < 0.0:
                Fn = 0.0
            Fz -= Fn
        F_node[k, 0] = Fx
        F_node[k, 1] = Fy
        F_node[k, 2] = Fz
        Ft = Fx * qx + Fy * qy + Fz * qz
        inv_n = 1.0 / (node_mass[k] + can_half[k] * s)
        at = Ft / (node_mass[k] + cat_half[k] * s)
        ax = (Fx - Ft * qx) * inv_n + at * qx
        ay = (Fy - Ft * qy) * inv_n + at * qy
        az = (Fz - Ft * qz) * inv_n + at * qz
        if extra_damping != 0.0:
            ax -= extra_damping * v[k, 0]
            ay -= extra_damping * v[k, 1]
            az -= extra_damping * v[k, 2]
        vx = v[k, 0] + dt * ax
        vy = v[k, 1] + dt * ay
        vz = v[k, 2] + dt * az
        if has_friction:  # Coulomb friction, implicit: stick or slide (FEMLines._friction)
            dv = dt * mu[k] * Fn / (node_mass[k] + cat_half[k] * s)
            if dv > 0.0:
                sp = math.sqrt(vx * vx + vy * vy)
                if sp <= dv:
                    vx = vx * 0.0
                    vy = vy * 0.0
                else:
                    f = 1.0 - dv / sp
                    vx = vx * f
                    vy = vy * f
        v_out[k, 0] = vx
        v_out[k, 1] = vy
        v_out[k, 2] = vz
        r_out[k, 0] = r[k, 0] + dt * vx
        r_out[k, 1] = r[k, 1] + dt * vy
        r_out[k, 2] = r[k, 2] + dt * vz
    # boundary conditions: anchors fixed, attached fairleads prescribed
    for j in range(anchor_idx.shape[0]):
        a = anchor_idx[j]
        for c in range(3):
            v_out[a, c] = 0.0
            r_out[a, c] = anchors[j, c]
    for m in range(attached.shape[0]):
        j = attached[m]
        f = fairlead_idx[j]
        for c in range(3):
            v_out[f, c] = fl_v[j, c]
            r_out[f, c] = fl_r[j, c]


@_jit
def advance(r, v, vc, dt, extra_damping, fl_r_seq, fl_v_seq,
            l0, EA, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half,
            kb, cb, mu, depth, has_int_damping, has_friction,
            anchor_idx, anchors, fairlead_idx, attached, F_fl_seq):  # pragma: no cover - compiled
    """``n_steps = len(fl_r_seq)`` (>= 1) symplectic-Euler steps of the FEM lines.

    Parameters
    ----------
    r, v : ndarray (n_nodes, 3)
        Positions [m] and velocities [m/s] at the start (read only).
    vc : ndarray (n_nodes, 3)
        Current velocity at each node [m/s], held over the steps.
    dt, extra_damping : float
        Step [s] and mass-proportional damping rate [1/s].
    fl_r_seq, fl_v_seq : ndarray (n_steps, n_lines, 3)
        Prescribed fairlead positions and velocities at the end of each step.
    l0 ... attached
        The constants of :class:`~tapm_opt.plant.fem.FEMLines` (bond and node arrays, seabed
        depth, flags, anchor and fairlead node indices, the attached lines).
    F_fl_seq : ndarray (n_steps, n_lines, 3) or (0, n_lines, 3)
        Filled, when not empty, with the net force of the line and the water on each fairlead
        node at the start of every step (tension, weight, drag: the load on the vessel without
        the node's inertia, as :meth:`~tapm_opt.plant.fem.FEMLines.fairlead_forces`).

    Returns
    -------
    r, v : ndarray (n_nodes, 3)
        New arrays: the state after the last step.
    T : ndarray (n_nodes - 1,)
        Bond tensions at the start of the last step [N].
    """
    n = r.shape[0]
    ra = np.empty_like(r)
    va = np.empty_like(v)
    rb = np.empty_like(r)
    vb = np.empty_like(v)
    T = np.empty(n - 1)
    qp = np.zeros((n + 1, 3))
    tvp = np.zeros((n + 1, 3))
    epsp = np.zeros(n + 1)
    F_node = np.empty((n, 3))
    keep = F_fl_seq.shape[0] > 0
    r_in, v_in = r, v
    for s in range(fl_r_seq.shape[0]):
        if s % 2 == 0:
            r_out, v_out = ra, va
        else:
            r_out, v_out = rb, vb
        _step(r_in, v_in, vc, dt, extra_damping, fl_r_seq[s], fl_v_seq[s],
              l0, EA, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half,
              kb, cb, mu, depth, has_int_damping, has_friction,
              anchor_idx, anchors, fairlead_idx, attached,
              r_out, v_out, T, qp, tvp, epsp, F_node)
        if keep:
            for j in range(fairlead_idx.shape[0]):
                f = fairlead_idx[j]
                for c in range(3):
                    F_fl_seq[s, j, c] = F_node[f, c]
        r_in, v_in = r_out, v_out
    return r_in, v_in, T
