"""Compiled (numba) kernel of the lumped-mass FEM lines: accelerations and symplectic-Euler steps.

One function, :func:`advance`, runs ``n_steps`` steps of :meth:`FEMLines.step
<tapm_opt.plant.fem.FEMLines.step>` in one call: the same forces (axial tension-only elasticity
with internal damping, submerged weight, Morison drag normal and tangential to the node tangent
on the velocity relative to the current, seabed spring-damper), the same closed-form inverse of
the node mass + added-mass matrix, the same joints of composite lines (each adjacent half segment's
drag and added mass with its own factors, the point's isotropic drag and added mass), the same
update (with the implicit Coulomb seabed friction of ``FEMLines._friction``)
(``v += dt a``, anchors fixed, attached fairleads prescribed, ``r += dt v``), evaluated in the same
floating-point order as the numpy reference path, so the two agree to round-off (checked in
``tests/test_fem_kernel.py``).

The plant's outer step (:meth:`Plant._outer_step <tapm_opt.plant.simulator.Plant._outer_step>`)
has three more kernels, each the compiled counterpart of a numpy path it must match bit for bit
(``tests/test_plant_speed_equivalence.py``): :func:`thruster_step` (``ThrusterBank.step`` and
``tau``), :func:`vessel_step` (the rich ``vessel_rhs`` and the semi-implicit Euler update) and
:func:`mooring_step` (the fairlead path, :func:`advance`, the fairlead accelerations, the
overload and health flags and the load on the vessel); :func:`plant_pre_step` runs the rest of an
outer step (thrusters, wind and drift loads, vessel, wave-frequency pose, riser angles, current
at the nodes) in one call before :func:`mooring_step`; :func:`plant_steps` runs the two for several
outer steps in one call, the state passed from step to step in arrays.

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

__all__ = ["AVAILABLE", "advance", "thruster_step", "vessel_step", "mooring_step", "plant_pre_step", "plant_steps",
           "end_tensions"]

from .._jit import jit as _jit, numba_available

AVAILABLE = numba_available()
if not AVAILABLE:
    warnings.warn("numba is not available; the FEM mooring lines use the numpy path, which is "
                  "several times slower per step (install numba to restore the compiled kernel)",
                  RuntimeWarning, stacklevel=2)


@_jit
def _table_tension(tab, j0, j1, strain):  # pragma: no cover - compiled
    """Tension [N] of a tension-strain table (rows ``tab[j0:j1]``: strain, tension, slope of the
    segment from the row) at ``strain``: ``T_j + s_j (e - e_j)`` on the last row j <= j1 - 2 with
    ``e_j <= e`` (j0 below the table), as ``FEMLines._table_tension`` (numpy's searchsorted)."""
    lo = j0
    hi = j1 - 2
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if tab[mid, 0] <= strain:
            lo = mid
        else:
            hi = mid - 1
    return tab[lo, 1] + tab[lo, 2] * (strain - tab[lo, 0])


@_jit
def _bond(r, v, i, l0, EA, c_int, has_int_damping):  # pragma: no cover - compiled
    """Bond i (node i to node i + 1): vector (lx, ly, lz) [m], stretched length e [m] and tension
    t [N] (tension only, with internal damping), as :meth:`FEMLines.segment_state
    <tapm_opt.plant.fem.FEMLines.segment_state>` (the 3-term sums in numpy's order)."""
    lx = r[i + 1, 0] - r[i, 0]
    ly = r[i + 1, 1] - r[i, 1]
    lz = r[i + 1, 2] - r[i, 2]
    e = math.sqrt(0.0 + lx * lx + ly * ly + lz * lz)
    strain = e / l0[i] - 1.0
    t = EA[i] * strain
    if has_int_damping:
        dx = v[i + 1, 0] - v[i, 0]
        dy = v[i + 1, 1] - v[i, 1]
        dz = v[i + 1, 2] - v[i, 2]
        t += c_int[i] * (0.0 + dx * lx + dy * ly + dz * lz) / (e * l0[i])
    if strain <= 0.0:
        t = 0.0
    elif t < 0.0:  # NaN and -0.0 kept, as np.maximum(t, 0.0)
        t = 0.0
    return lx, ly, lz, e, t


@_jit
def _bond_any(r, v, i, l0, EA, tabi, tab, c_int, has_int_damping):  # pragma: no cover - compiled
    """:func:`_bond` where a bond may be of a tension-strain table (``tabi[i] = (start, stop)`` rows
    of ``tab``, else (-1, -1)): its elastic tension read from the table (:func:`_table_tension`)."""
    if tab.shape[0] == 0 or tabi[i, 0] < 0:
        return _bond(r, v, i, l0, EA, c_int, has_int_damping)
    lx = r[i + 1, 0] - r[i, 0]
    ly = r[i + 1, 1] - r[i, 1]
    lz = r[i + 1, 2] - r[i, 2]
    e = math.sqrt(0.0 + lx * lx + ly * ly + lz * lz)
    strain = e / l0[i] - 1.0
    t = _table_tension(tab, tabi[i, 0], tabi[i, 1], strain)
    if has_int_damping:
        dx = v[i + 1, 0] - v[i, 0]
        dy = v[i + 1, 1] - v[i, 1]
        dz = v[i + 1, 2] - v[i, 2]
        t += c_int[i] * (0.0 + dx * lx + dy * ly + dz * lz) / (e * l0[i])
    if strain <= 0.0:
        t = 0.0
    elif t < 0.0:  # NaN and -0.0 kept, as np.maximum(t, 0.0)
        t = 0.0
    return lx, ly, lz, e, t


@_jit
def _keep_bond(i, lx, ly, lz, e, t, bond_ok, T, qp, tvp, epsp):  # pragma: no cover - compiled
    """Bond i's tension into T, its tangent, tension vector and stretched length into the padded
    buffers (0 on a non-segment bond)."""
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


@_jit
def _joints(r, v, vc, dt, extra_damping, node_weight, node_mass, joint, joint_c, kb, cb, mu, depth, has_friction,
            qp, tvp, epsp, r_out, v_out, F_node):  # pragma: no cover - compiled
    """The joint nodes ``joint`` (ascending) of composite lines in :func:`_step`: the force and
    update of every other node with the joint's drag and added mass (``joint_c``: each adjacent
    half segment with its own factors and stretched length, the point's isotropic drag and added
    mass). Apart, so that the loop over the other nodes stays the homogeneous line's (no test per
    node)."""
    for i in range(joint.shape[0]):
        k = joint[i]
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
        el = epsp[k]  # the stretched lengths of the segments below and above
        eh = epsp[k + 1]
        cs_n = joint_c[i, 0] * el + joint_c[i, 1] * eh
        cs_t = joint_c[i, 2] * el + joint_c[i, 3] * eh
        mn = node_mass[k] + (joint_c[i, 4] * el + joint_c[i, 5] * eh) + joint_c[i, 9]
        mt = node_mass[k] + (joint_c[i, 6] * el + joint_c[i, 7] * eh) + joint_c[i, 9]
        vrx = v[k, 0] - vc[k, 0]
        vry = v[k, 1] - vc[k, 1]
        vrz = v[k, 2] - vc[k, 2]
        vt = vrx * qx + vry * qy + vrz * qz
        vnx = vrx - vt * qx
        vny = vry - vt * qy
        vnz = vrz - vt * qz
        vn_mag = math.sqrt(vnx * vnx + vny * vny + vnz * vnz)
        cn = cs_n * vn_mag
        Fx -= cn * vnx
        Fy -= cn * vny
        Fz -= cn * vnz
        ct = cs_t * abs(vt) * vt
        Fx -= ct * qx
        Fy -= ct * qy
        Fz -= ct * qz
        # the point's isotropic drag 1/2 rho CdA |v_r| v_r
        cp = joint_c[i, 8] * math.sqrt(vrx * vrx + vry * vry + vrz * vrz)
        Fx -= cp * vrx
        Fy -= cp * vry
        Fz -= cp * vrz
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
        inv_n = 1.0 / mn
        at = Ft / mt
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
            dv = dt * mu[k] * Fn / mt
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


@_jit
def _step(r, v, vc, dt, extra_damping, fl_r, fl_v,
          l0, EA, tabi, tab, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half, joint, joint_c,
          kb, cb, mu, depth, has_int_damping, has_friction,
          anchor_idx, anchors, fairlead_idx, attached,
          r_out, v_out, T, qp, tvp, epsp, F_node):  # pragma: no cover - compiled
    """One step from (r, v) into (r_out, v_out); bond tensions at the start of the step into T
    and the net force on every node (before the mass inversion) into ``F_node`` (n_nodes, 3).

    ``qp``, ``tvp`` (n_nodes + 1, 3) and ``epsp`` (n_nodes + 1,) are the padded bond buffers of
    the numpy path (row i + 1 holds bond i; rows 0 and n_nodes stay zero).
    """
    n = r.shape[0]
    # bonds: tangent, tension vector and stretched length (0 on the non-segment bonds); without a
    # tension-strain table the loop of constant EA alone
    if tab.shape[0] == 0:
        for i in range(n - 1):
            lx, ly, lz, e, t = _bond(r, v, i, l0, EA, c_int, has_int_damping)
            _keep_bond(i, lx, ly, lz, e, t, bond_ok, T, qp, tvp, epsp)
    else:
        for i in range(n - 1):
            lx, ly, lz, e, t = _bond_any(r, v, i, l0, EA, tabi, tab, c_int, has_int_damping)
            _keep_bond(i, lx, ly, lz, e, t, bond_ok, T, qp, tvp, epsp)
    # nodes: forces, accelerations, velocity and position updates, in the runs of ordinary
    # nodes between the joints of composite lines (one run over all nodes without joints)
    start = 0
    for j in range(joint.shape[0] + 1):
        stop = joint[j] if j < joint.shape[0] else n
        for k in range(start, stop):
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
        start = stop + 1
    if joint.shape[0]:  # the joints
        _joints(r, v, vc, dt, extra_damping, node_weight, node_mass, joint, joint_c, kb, cb, mu, depth, has_friction,
                qp, tvp, epsp, r_out, v_out, F_node)
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
            l0, EA, tabi, tab, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half, joint, joint_c,
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
        The constants of :class:`~tapm_opt.plant.fem.FEMLines` (bond and node arrays, the rows of
        the tension-strain tables and each bond's, the joint
        nodes of composite lines and their drag and added-mass factors, seabed depth, flags,
        anchor and fairlead node indices, the attached lines).
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
              l0, EA, tabi, tab, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half, joint, joint_c,
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


# -- the plant's outer step ------------------------------------------------------------------
# Compiled pieces of :meth:`tapm_opt.plant.simulator.Plant._outer_step`, each evaluated in the
# floating-point order of its numpy counterpart (the fallback when numba is absent), so that the
# two paths give the same bits (``tests/test_plant_speed_equivalence.py``): elementwise
# operations left to right as numpy applies them, ``sum(axis=1)`` of 3-vectors as numpy's
# sequential reduction from 0.0, ``np.sum`` of a vector as numpy's pairwise sum
# (:func:`_pairwise_sum`), matrix-vector products with ``np.dot`` (the BLAS call numpy's ``@``
# makes), ``np.clip``/``np.maximum`` with numpy's NaN and signed-zero rules.


@_jit
def _pairwise_sum(a):  # pragma: no cover - compiled
    """``np.sum`` of the 1-D array ``a`` in numpy's order (pairwise summation, 8 accumulators,
    blocks of 128)."""
    n = a.shape[0]
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[i]
        return res
    if n <= 128:
        r0, r1, r2, r3 = a[0], a[1], a[2], a[3]
        r4, r5, r6, r7 = a[4], a[5], a[6], a[7]
        i = 8
        while i < n - (n % 8):
            r0 += a[i]
            r1 += a[i + 1]
            r2 += a[i + 2]
            r3 += a[i + 3]
            r4 += a[i + 4]
            r5 += a[i + 5]
            r6 += a[i + 6]
            r7 += a[i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise_sum(a[:n2]) + _pairwise_sum(a[n2:])


@_jit
def _clip(x, lo, hi):  # pragma: no cover - compiled
    """``np.clip(x, lo, hi)`` of one value (numpy's max-then-min, NaN kept)."""
    if not (math.isnan(x) or x > lo):
        x = lo
    if not (math.isnan(x) or x < hi):
        x = hi
    return x


@_jit
def _ssa(a):  # pragma: no cover - compiled
    """:func:`tapm_opt.geometry.ssa` of one angle [rad]."""
    return a - 2.0 * np.pi * math.floor((a + np.pi) / (2.0 * np.pi))


@_jit
def thruster_step(f, alpha, failed, f_cmd, alpha_cmd, has_alpha_cmd, f_min, f_max, decay, rate_dt,
                  alpha_rate_dt, azimuth, x, y):  # pragma: no cover - compiled
    """:meth:`ThrusterBank.step <tapm_opt.plant.thrusters.ThrusterBank.step>` on checked
    commands, in place on ``f`` [N] and ``alpha`` [rad], and the new generalised thrust
    :meth:`~tapm_opt.plant.thrusters.ThrusterBank.tau` (3,) [N, N, N m] in {B}.

    ``decay = exp(-dt / T)``, ``rate_dt = max_thrust_rate dt`` [N] and ``alpha_rate_dt =
    max_azimuth_rate dt`` [rad] per thruster.
    """
    n = f.shape[0]
    for i in range(n):
        f_sat = _clip(f_cmd[i], f_min[i], f_max[i])
        f_lag = f_sat + (f[i] - f_sat) * decay[i]
        fi = f[i] + _clip(f_lag - f[i], -rate_dt[i], rate_dt[i])
        f[i] = 0.0 if failed[i] else fi
        if has_alpha_cmd and azimuth[i]:
            da = _clip(_ssa(alpha_cmd[i] - alpha[i]), -alpha_rate_dt[i], alpha_rate_dt[i])
            alpha[i] = _ssa(alpha[i] + da)
    T = np.empty((3, n))
    for i in range(n):
        c = math.cos(alpha[i])
        s = math.sin(alpha[i])
        T[0, i] = c
        T[1, i] = s
        T[2, i] = x[i] * s - y[i] * c
    return np.dot(T, f)


@_jit
def _rot_z(psi):  # pragma: no cover - compiled
    """:func:`tapm_opt.geometry.rot_z` (3, 3)."""
    c = math.cos(psi)
    s = math.sin(psi)
    R = np.zeros((3, 3))
    R[0, 0] = c
    R[0, 1] = -s
    R[1, 0] = s
    R[1, 1] = c
    R[2, 2] = 1.0
    return R


@_jit
def _coriolis(M, nu):  # pragma: no cover - compiled
    """:func:`tapm_opt.models.vessel.coriolis` (3, 3)."""
    p = np.dot(M, nu)
    C = np.zeros((3, 3))
    C[0, 2] = -p[1]
    C[1, 2] = p[0]
    C[2, 0] = p[1]
    C[2, 1] = -p[0]
    return C


@_jit
def vessel_step(eta, nu, tau, v_c, M, M_A, M_inv, D_lin, d_quad, h):  # pragma: no cover - compiled
    """One semi-implicit Euler step of the rich LF vessel (:func:`tapm_opt.models.vessel.vessel_rhs`,
    ``form="rich"``): ``nu + h nu_dot`` then ``eta + h R(psi) nu`` with the new ``nu``.

    The equation is defined once, symbolically, in :func:`~tapm_opt.models.vessel.vessel_rhs` (the
    CasADi function the design models and the MPC use); this is its numeric evaluation in the same
    floating-point order, for the plant's inner loop. ``tests/test_plant_speed_equivalence.py``
    holds the plant's two paths to the bit (``Plant.compiled`` against the numeric evaluation of
    ``vessel_rhs``; to round-off on a machine whose numpy has its own float64 sin/cos): a change to
    one that is not made to the other fails there.

    Parameters
    ----------
    eta, nu, tau : ndarray (3,)
        Pose [m, m, rad] in {E}, velocity [m/s, m/s, rad/s] in {B}, total load [N, N, N m] in {B}.
    v_c : ndarray (2,)
        Current (V_x, V_y) in {E} [m/s].
    M, M_A, M_inv, D_lin : ndarray (3, 3); d_quad : ndarray (3,)
        The vessel's :class:`~tapm_opt.models.vessel.VesselParams`.
    h : float
        Step [s].

    Returns
    -------
    eta, nu : ndarray (3,)
        The new pose and velocity.
    finite : bool
        Both are finite.
    """
    c = math.cos(-eta[2])
    s = math.sin(-eta[2])
    u_c = c * v_c[0] - s * v_c[1]
    v_cb = s * v_c[0] + c * v_c[1]
    nu_r = np.empty(3)
    nu_r[0] = nu[0] - u_c
    nu_r[1] = nu[1] - v_cb
    nu_r[2] = nu[2] - 0.0
    damping = np.dot(D_lin, nu_r)
    for i in range(3):
        damping[i] = damping[i] + d_quad[i] * abs(nu_r[i]) * nu_r[i]
    cor = np.dot(_coriolis(M - M_A, nu_r) + _coriolis(M_A, nu_r), nu_r)
    rhs = np.empty(3)
    for i in range(3):
        rhs[i] = tau[i] - cor[i] - damping[i]
    nu_r_dot = np.dot(M_inv, rhs)
    r = nu[2]
    nu_new = np.empty(3)
    nu_new[0] = nu[0] + h * (nu_r_dot[0] + r * v_cb)
    nu_new[1] = nu[1] + h * (nu_r_dot[1] + -r * u_c)
    nu_new[2] = nu[2] + h * (nu_r_dot[2] + 0.0)
    e_dot = np.dot(_rot_z(eta[2]), nu_new)
    eta_new = np.empty(3)
    finite = True
    for i in range(3):
        eta_new[i] = eta[i] + h * e_dot[i]
        finite = finite and math.isfinite(eta_new[i]) and math.isfinite(nu_new[i])
    return eta_new, nu_new, finite


@_jit
def _fairleads(eta, p_cot, p_T, turret_angle, locked, fx, fy, rx, ry):  # pragma: no cover - compiled
    """Fairlead positions (fx, fy) in {E} [m] at pose ``eta`` (eq. 5,
    :meth:`MooringModel.fairleads <tapm_opt.models.mooring.MooringModel.fairleads>`) and the
    lever arms (rx, ry) of :meth:`MooringFEM._levers <tapm_opt.plant.mooring_fem.MooringFEM._levers>`."""
    psi = eta[2]
    alpha_t = turret_angle if locked else turret_angle - psi
    c = math.cos(psi)
    s = math.sin(psi)
    cx = c * p_cot[0] - s * p_cot[1]
    cy = s * p_cot[0] + c * p_cot[1]
    ang = psi + alpha_t
    ct = math.cos(ang)
    st = math.sin(ang)
    for j in range(p_T.shape[0]):
        fx[j] = eta[0] + cx + (ct * p_T[j, 0] - st * p_T[j, 1])
        fy[j] = eta[1] + cy + (st * p_T[j, 0] + ct * p_T[j, 1])
        if locked:
            rx[j] = fx[j] - eta[0]
            ry[j] = fy[j] - eta[1]
        else:
            rx[j] = cx
            ry[j] = cy


@_jit
def _vertical_offset(hz, ph, th, dx, dy, z_fl, c, s):  # pragma: no cover - compiled
    """Displacement (x, y, z) in {E} [m] of a fairlead by the hull's heave ``hz`` [m, down], roll
    ``ph`` [rad, starboard down] and pitch ``th`` [rad, bow up] (small rotations about the body
    origin on the water line): ``(th z, -ph z, hz + ph y - th x)`` in {B} for the fairlead at
    ``(x, y, z)`` in {B} — ``(dx, dy)`` its horizontal offset from the body origin in {E},
    ``z = z_fl`` its depth — turned to {E} by the heading (``c, s`` its cosine and sine). Linear
    in ``(hz, ph, th)``: rates and accelerations give the fairlead's velocity and acceleration
    (the levers' own change, second order, left out). :meth:`MooringFEM.fairlead_state
    <tapm_opt.plant.mooring_fem.MooringFEM.fairlead_state>` is the numpy twin."""
    bx = c * dx + s * dy
    by = c * dy - s * dx
    ox = th * z_fl
    oy = -(ph * z_fl)
    oz = (hz + ph * by) - th * bx
    return c * ox - s * oy, s * ox + c * oy, oz


@_jit
def mooring_step(pose0, pose1, vert0, vert1, rate_prev, h, n_sub, p_cot, p_T, turret_angle, locked, z_fl,
                 r, v, vc, l0, EA, tabi, tab, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half,
                 joint, joint_c, kb, cb, mu, depth, has_int_damping, has_friction,
                 anchor_idx, anchors, fairlead_idx, attached, fairlead_seg, anchor_seg, active,
                 near_tension, max_speed):  # pragma: no cover - compiled
    """The mooring part of the plant's outer step of ``h`` seconds in ``n_sub`` FEM substeps.

    The fairleads follow the total pose interpolated linearly from ``pose0`` to ``pose1`` (each
    (3,) [m, m, rad]) at the constant rate ``(pose1 - pose0) / h``, and the hull's heave, roll
    and pitch from ``vert0`` to ``vert1`` (each (3,) [m, rad, rad]; zeros: none) likewise
    (:func:`_vertical_offset`) (:meth:`MooringFEM.advance
    <tapm_opt.plant.mooring_fem.MooringFEM.advance>`); then, at ``pose1``, the fairlead
    accelerations from the change of rate since ``rate_prev`` (:meth:`MooringFEM.fairlead_acceleration
    <tapm_opt.plant.mooring_fem.MooringFEM.fairlead_acceleration>`) and the load of the lines on
    the vessel (:meth:`MooringFEM.tau <tapm_opt.plant.mooring_fem.MooringFEM.tau>`).

    Returns
    -------
    r, v : ndarray (n_nodes, 3)
        Node positions [m] and velocities [m/s] after the substeps (new arrays).
    T : ndarray (n_nodes - 1,)
        Bond tensions at the start of the last substep [N].
    r_fl : ndarray (n_lines, 3)
        Fairlead positions of the last substep [m].
    rate : ndarray (6,)
        The pose rate over the step [m/s, m/s, rad/s], then the heave, roll and pitch rates
        [m/s, rad/s, rad/s] (``rate_prev`` the same of the step before).
    a_fl : ndarray (n_lines, 3)
        Fairlead accelerations [m/s^2].
    tau : ndarray (3,)
        Load of the lines on the vessel in {B} [N, N, N m].
    near : bool
        Some intact line's fairlead or anchor tension bound reached its ``near_tension`` [N]
        (``Plant._check_overload`` must look).
    suspect : bool
        Some node state is non-finite or faster than ``max_speed`` [m/s] (``FEMLines.check_health``
        reports it).
    """
    nl = p_T.shape[0]
    rate = np.empty(6)
    d = np.empty(6)
    six = False
    for c in range(3):
        d[c] = pose1[c] - pose0[c]
        rate[c] = d[c] / h
        d[3 + c] = vert1[c] - vert0[c]
        rate[3 + c] = d[3 + c] / h
        if vert0[c] != 0.0 or vert1[c] != 0.0 or rate_prev[3 + c] != 0.0:
            six = True
    fl_r = np.empty((n_sub, nl, 3))
    fl_v = np.empty((n_sub, nl, 3))
    fx = np.empty(nl)
    fy = np.empty(nl)
    rx = np.empty(nl)
    ry = np.empty(nl)
    e = np.empty(3)
    ev = np.empty(3)
    for s in range(n_sub):
        frac = (s + 1) / n_sub
        for c in range(3):
            e[c] = pose0[c] + frac * d[c]
            ev[c] = vert0[c] + frac * d[3 + c]
        _fairleads(e, p_cot, p_T, turret_angle, locked, fx, fy, rx, ry)
        for j in range(nl):
            fl_r[s, j, 0] = fx[j]
            fl_r[s, j, 1] = fy[j]
            fl_r[s, j, 2] = z_fl
            fl_v[s, j, 0] = rate[0] - rate[2] * ry[j]
            fl_v[s, j, 1] = rate[1] + rate[2] * rx[j]
            fl_v[s, j, 2] = 0.0
        if six:
            cp = math.cos(e[2])
            sp = math.sin(e[2])
            for j in range(nl):
                ox, oy, oz = _vertical_offset(ev[0], ev[1], ev[2], fx[j] - e[0], fy[j] - e[1], z_fl, cp, sp)
                vx, vy, vz = _vertical_offset(rate[3], rate[4], rate[5], fx[j] - e[0], fy[j] - e[1], z_fl, cp, sp)
                fl_r[s, j, 0] += ox
                fl_r[s, j, 1] += oy
                fl_r[s, j, 2] += oz
                fl_v[s, j, 0] += vx
                fl_v[s, j, 1] += vy
                fl_v[s, j, 2] += vz
    r, v, T = advance(r, v, vc, h / n_sub, 0.0, fl_r, fl_v,
                      l0, EA, tabi, tab, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half, joint, joint_c,
                      kb, cb, mu, depth, has_int_damping, has_friction,
                      anchor_idx, anchors, fairlead_idx, attached, np.zeros((0, nl, 3)))
    # fairlead accelerations at pose1 (rigid body)
    _fairleads(pose1, p_cot, p_T, turret_angle, locked, fx, fy, rx, ry)
    rd = rate[2]
    rdd = (rate[2] - rate_prev[2]) / h
    a0 = (rate[0] - rate_prev[0]) / h
    a1 = (rate[1] - rate_prev[1]) / h
    a_fl = np.zeros((nl, 3))
    for j in range(nl):
        a_fl[j, 0] = a0 - rdd * ry[j] - rd * rd * rx[j]
        a_fl[j, 1] = a1 + rdd * rx[j] - rd * rd * ry[j]
    if six:
        cp = math.cos(pose1[2])
        sp = math.sin(pose1[2])
        for j in range(nl):
            ax, ay, az = _vertical_offset((rate[3] - rate_prev[3]) / h, (rate[4] - rate_prev[4]) / h,
                                          (rate[5] - rate_prev[5]) / h, fx[j] - pose1[0], fy[j] - pose1[1], z_fl,
                                          cp, sp)
            a_fl[j, 0] += ax
            a_fl[j, 1] += ay
            a_fl[j, 2] += az
    # overload bound (Plant._check_overload) and health (FEMLines.check_health) flags
    near = False
    for j in range(nl):
        b_fl = T[fairlead_seg[j]] + node_weight[fairlead_idx[j]]
        b_an = T[anchor_seg[j]]
        if active[j] and not (math.isnan(b_fl) or math.isnan(b_an)):
            if max(b_fl, b_an) >= near_tension[j]:
                near = True
    suspect = False
    for k in range(r.shape[0]):
        sp = v[k, 0] * v[k, 0] + v[k, 1] * v[k, 1] + v[k, 2] * v[k, 2]
        if not (sp <= max_speed * max_speed) or not (math.isfinite(r[k, 0]) and math.isfinite(r[k, 1])
                                           and math.isfinite(r[k, 2])):
            suspect = True
    # fairlead forces (FEMLines.fairlead_forces with the current and the accelerations)
    f_x = np.zeros(nl)
    f_y = np.zeros(nl)
    for j in range(nl):
        if not active[j]:
            continue
        fl = fairlead_idx[j]
        lx, ly, lz, eps, t = _bond_any(r, v, fairlead_seg[j], l0, EA, tabi, tab, c_int, has_int_damping)
        qx = lx / eps
        qy = ly / eps
        qz = lz / eps
        Fx = -t * qx  # the vertical component (weight, drag) does not load the vessel's 3 DOF
        Fy = -t * qy
        vrx = v[fl, 0] - vc[fl, 0]
        vry = v[fl, 1] - vc[fl, 1]
        vrz = v[fl, 2] - vc[fl, 2]
        vt = 0.0 + vrx * qx + vry * qy + vrz * qz
        vnx = vrx - vt * qx
        vny = vry - vt * qy
        vnz = vrz - vt * qz
        cn = cdn[fl] * eps * math.sqrt(0.0 + vnx * vnx + vny * vny + vnz * vnz)
        Fx -= cn * vnx
        Fy -= cn * vny
        ct = cdt[fl] * eps * abs(vt) * vt
        Fx -= ct * qx
        Fy -= ct * qy
        at = 0.0 + a_fl[j, 0] * qx + a_fl[j, 1] * qy + a_fl[j, 2] * qz
        mn = node_mass[fl] + can_half[fl] * eps
        Fx -= mn * (a_fl[j, 0] - at * qx)
        Fy -= mn * (a_fl[j, 1] - at * qy)
        mt = (node_mass[fl] + cat_half[fl] * eps) * at
        f_x[j] = Fx - mt * qx
        f_y[j] = Fy - mt * qy
    # load on the vessel (MooringModel.tau_from_forces) at pose1, the fairleads of the last substep
    psi = pose1[2]
    Fxs = _pairwise_sum(f_x)
    Fys = _pairwise_sum(f_y)
    r_fl = fl_r[n_sub - 1].copy()
    if locked:
        m = np.empty(nl)
        for j in range(nl):
            m[j] = (r_fl[j, 0] - pose1[0]) * f_y[j] - (r_fl[j, 1] - pose1[1]) * f_x[j]
        Nz = _pairwise_sum(m)
    else:
        c = math.cos(psi)
        s = math.sin(psi)
        Nz = (c * p_cot[0] - s * p_cot[1]) * Fys - (s * p_cot[0] + c * p_cot[1]) * Fxs
    F = np.empty(3)
    F[0] = Fxs
    F[1] = Fys
    F[2] = Nz
    tau = np.dot(_rot_z(psi).T, F)
    return r, v, T, r_fl, rate, a_fl, tau, near, suspect


# -- the fused outer step ----------------------------------------------------------------------
# Two calls per plant outer step (Plant._outer_step when its inputs allow, Plant._fused_step):
# :func:`plant_pre_step` (the thrusters, the wind and drift loads from the block sums of the
# environment, the vessel, the wave-frequency pose, the riser angles and the current at the
# nodes), then :func:`mooring_step` (the lines). Each is the same floating-point operations as
# the plant's numpy path (which calls the environment's and the riser's float paths,
# ``HullWindLoad.tau``, ``WaveField._dirs``, ``CurrentProfile.factor``, ``RiserModel.angles_at``),
# so that the two paths keep giving the same bits.

#: Layout of the packed float output of :func:`plant_pre_step`: slices of eta, nu, eta_wf,
#: tau_thr, tau_wind, tau_drift, the total poses at the start and the end of the step, the riser
#: angles, the hull's heave, roll and pitch at the end of the step.
OUT_ETA, OUT_NU, OUT_WF, OUT_THR, OUT_WIND, OUT_DRIFT, OUT_POSE0, OUT_POSE1, OUT_RISER, OUT_VERT = (
    slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15), slice(15, 18), slice(18, 21),
    slice(21, 24), slice(24, 28), slice(28, 31))
OUT_SIZE = 31

#: Relative wave headings of the hull's motion sums on the heading grid (``vgrid`` of
#: :func:`plant_pre_step`): :data:`tapm_opt.plant.environment.N_HEADINGS` (a test checks they agree).
N_HEADINGS = 72

#: Kinds of the current at the nodes of :func:`plant_pre_step`: held (none: ``vc`` untouched),
#: uniform, linear, piecewise (``CurrentProfile.kind``).
CURRENT_HELD, CURRENT_UNIFORM, CURRENT_LINEAR, CURRENT_PIECEWISE = 0, 1, 2, 3


@_jit
def _interp(x, xp, fp):  # pragma: no cover - compiled
    """``np.interp(x, xp, fp)`` of one finite value (numpy's arithmetic: the slope of the bracket,
    ``slope (x - xp[j]) + fp[j]``, the end values held outside, the knot's value on a knot)."""
    n = xp.shape[0]
    if n == 1:
        return fp[0]
    if x < xp[0]:
        return fp[0]
    if x > xp[n - 1]:
        return fp[n - 1]
    if x == xp[n - 1]:
        return fp[n - 1]
    j = 0
    while j < n - 2 and xp[j + 1] <= x:
        j += 1
    if xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    res = slope * (x - xp[j]) + fp[j]
    if math.isnan(res):
        res = slope * (x - xp[j + 1]) + fp[j + 1]
        if math.isnan(res) and fp[j] == fp[j + 1]:
            res = fp[j]
    return res


@_jit
def _current_at_nodes(r, vc, kind, clamps, depths, factors, water_depth, surface):  # pragma: no cover - compiled
    """:meth:`CurrentProfile.velocity_unchecked <tapm_opt.models.environment.CurrentProfile.velocity_unchecked>`
    at the node depths ``r[:, 2]`` into ``vc`` (n_nodes, 3) [m/s]; False (``vc`` untouched) when a
    depth is not finite."""
    n = r.shape[0]
    for k in range(n):
        if not math.isfinite(r[k, 2]):
            return False
    for k in range(n):
        z = r[k, 2]
        if kind == CURRENT_PIECEWISE and clamps:
            phi = _interp(z, depths, factors)
        else:
            if not z > 0.0:  # np.maximum(z, 0.0), then np.minimum(., water_depth)
                z = 0.0
            if not z < water_depth:
                z = water_depth
            if kind == CURRENT_UNIFORM:
                phi = 1.0
            elif kind == CURRENT_LINEAR:
                phi = 1.0 + (factors[0] - 1.0) * (z / water_depth)
            else:
                phi = _interp(z, depths, factors)
        for c in range(3):
            vc[k, c] = phi * surface[c]
    return True


@_jit
def _heading_bracket(direction, psi):  # pragma: no cover - compiled
    """:func:`tapm_opt.plant.environment.heading_bracket`: the two grid headings about ``beta =
    direction - psi`` and the fraction between them, the same operations."""
    G = N_HEADINGS
    b = direction - psi
    b = b - 2.0 * math.pi * math.floor(b / (2.0 * math.pi))
    x = b * (G / (2.0 * math.pi))
    g0 = min(int(x), G - 1)
    f = x - g0
    g1 = 0 if g0 == G - 1 else g0 + 1
    return g0, g1, f


@_jit
def _heading_interp(grid, direction, psi, out, o):  # pragma: no cover - compiled
    """:func:`tapm_opt.plant.environment.heading_interp` into ``out[o:o + K]``: the same operations."""
    K = grid.shape[0] // N_HEADINGS
    g0, g1, f = _heading_bracket(direction, psi)
    for d in range(K):
        v0 = grid[K * g0 + d]
        out[o + d] = v0 + f * (grid[K * g1 + d] - v0)


@_jit
def _drift_interp(dq, sign, direction, psi, out, o):  # pragma: no cover - compiled
    """:meth:`WaveField.drift_of <tapm_opt.plant.environment.WaveField.drift_of>` into ``out[o:o +
    3]``: ``2 q q s`` of the drift sums ``dq`` and signs ``sign`` on the heading grid (3 G,) at the
    two grid headings about ``beta = direction - psi``, interpolated linearly (the operations of
    :func:`tapm_opt.plant.environment.heading_interp` on ``2 q q s``)."""
    g0, g1, f = _heading_bracket(direction, psi)
    for d in range(3):
        qa = dq[3 * g0 + d]
        qb = dq[3 * g1 + d]
        v0 = 2.0 * qa * qa * sign[3 * g0 + d]
        v1 = 2.0 * qb * qb * sign[3 * g1 + d]
        out[o + d] = v0 + f * (v1 - v0)


@_jit
def plant_pre_step(h, f, alpha, f_cmd, alpha_cmd, decay, rate_dt, alpha_rate_dt, V0, q0, S0, S1, C0, vgrid, dq,
                   eta, nu, eta_wf_prev, tau_moor_prev, r, vc,
                   failed, f_min, f_max, azimuth, x_thr, y_thr, has_env, wind_dir, hull_k, wave_dir, drift_c, drift_grid,
                   drift_sign, wf,
                   v_c, M, M_A, M_inv, D_lin, d_quad, has_riser, riser_c,
                   cur_kind, cur_clamps, cur_depths, cur_factors, cur_depth, cur_surface):  # pragma: no cover - compiled
    """The plant's outer step of ``h`` [s] up to its lines (``Plant._outer_step``, no winch, a
    steady current) in one call: :func:`thruster_step` (``f`` and ``alpha`` in place), the wind
    load (``HullWindLoad.tau`` at the wind speed ``V0`` [m/s] going to ``wind_dir`` [rad], the
    coefficients ``hull_k``) and the wave drift (``2 q0^2`` times the drift factor of the heading,
    ``drift_c`` the constants of ``WaveField._dirs``; with the user's drift coefficients, non-empty
    ``drift_sign``, :func:`_drift_interp` of the sums ``dq`` on the heading grid) at the start of
    the step (zero unless ``has_env``), :func:`vessel_step` on their sum with the thrust and ``tau_moor_prev``, the
    wave-frequency pose at the end (the sums ``S0, S1, C0`` of ``WaveField._motion`` there; zero
    unless ``wf``; and the heave, roll and pitch from ``vgrid``, the sums on the heading grid of
    ``WaveField.vertical_block``, empty: none), the total poses ``eta + eta_wf_prev`` and the new one, the riser angles at the
    new (``riser_c``: hang-off (x, y) in {B}, wellhead (x, y), c_t, c_b, h_t, h_b, g(v_c) (x, y)
    of ``RiserModel._affine``) and the current at the nodes ``r`` (into ``vc`` unless ``cur_kind``
    is :data:`CURRENT_HELD`, :func:`_current_at_nodes`). The arguments that change from step to
    step come first (up to ``vc``), the plant's constants after them.

    Returns
    -------
    status : int
        0 done; 1 the vessel state became unphysical (non-finite or 100 km off; ``out`` holds the
        new eta and nu, nothing else was evaluated); 2 a node depth is not finite (``vc`` untouched).
    out : ndarray (:data:`OUT_SIZE`,)
        The packed floats (:data:`OUT_ETA` ... :data:`OUT_RISER`).
    """
    out = np.zeros(OUT_SIZE)
    tau_thr = thruster_step(f, alpha, failed, f_cmd, alpha_cmd, True, f_min, f_max, decay, rate_dt,
                            alpha_rate_dt, azimuth, x_thr, y_thr)
    tau = np.empty(3)
    psi = eta[2]
    if has_env:
        b = wind_dir - psi  # HullWindLoad.tau, float path
        u_rw = nu[0] - V0 * math.cos(b)
        v_rw = nu[1] - V0 * math.sin(b)
        V_rw = math.hypot(u_rw, v_rw)
        out[12] = hull_k[0] * (V_rw * u_rw)
        out[13] = hull_k[1] * (V_rw * v_rw)
        out[14] = hull_k[2] * (u_rw * v_rw)
        beta = wave_dir - psi  # WaveField._dirs and tau_drift
        cbt = math.cos(beta)
        sbt = math.sin(beta)
        q2 = 2.0 * q0 * q0
        if drift_sign.shape[0] > 0:   # the user's drift coefficients on the heading grid (WaveField.drift_of)
            _drift_interp(dq, drift_sign, wave_dir, psi, out, 15)
        elif drift_grid.shape[0] > 0:   # short-crested: the drift factor on the heading grid (WaveField.drift_factor)
            _heading_interp(drift_grid, wave_dir, psi, out, 15)
            for i in range(3):
                out[15 + i] = q2 * out[15 + i]
        else:
            out[15] = q2 * (drift_c[0] * (cbt * abs(cbt)))
            out[16] = q2 * (drift_c[1] * (sbt * abs(sbt)))
            out[17] = q2 * (drift_c[2] * -math.sin(2.0 * beta))
    for i in range(3):
        out[9 + i] = tau_thr[i]
        tau[i] = tau_thr[i] + out[12 + i] + out[15 + i] + tau_moor_prev[i]
    eta1, nu1, finite = vessel_step(eta, nu, tau, v_c, M, M_A, M_inv, D_lin, d_quad, h)
    for i in range(3):
        out[i] = eta1[i]
        out[3 + i] = nu1[i]
    if not (finite and math.hypot(eta1[0], eta1[1]) < 1e5):
        return 1, out
    if wf:  # WaveField._motion at the new heading
        psi1 = eta1[2]
        beta = wave_dir - psi1
        cbt = math.cos(beta)
        sbt = math.sin(beta)
        s2b = math.sin(2.0 * beta)
        xb = cbt * S0
        yb = sbt * S1
        c = math.cos(psi1)
        s = math.sin(psi1)
        out[6] = c * xb - s * yb
        out[7] = s * xb + c * yb
        out[8] = s2b * C0
        if vgrid.shape[0] == 3 * N_HEADINGS:  # heave, roll and pitch at the new heading (WaveField.vertical_of)
            _heading_interp(vgrid, wave_dir, psi1, out, 28)
        elif vgrid.shape[0] > 0:   # and surge, sway and yaw of a user's table (WaveField.horizontal_of)
            v = np.empty(6)
            _heading_interp(vgrid, wave_dir, psi1, v, 0)
            for d in range(3):
                out[28 + d] = v[d]
            out[6] = c * v[3] - s * v[4]
            out[7] = s * v[3] + c * v[4]
            out[8] = v[5]
    for i in range(3):
        out[18 + i] = eta[i] + eta_wf_prev[i]
        out[21 + i] = eta1[i] + out[6 + i]
    if has_riser:  # RiserModel.angles_at(pose1): the hang-off in {E}, then the affine map
        c = math.cos(out[23])
        s = math.sin(out[23])
        dx = out[21] + c * riser_c[0] - s * riser_c[1] - riser_c[2]
        dy = out[22] + s * riser_c[0] + c * riser_c[1] - riser_c[3]
        out[24] = riser_c[4] * dx + riser_c[6] * riser_c[8]
        out[25] = riser_c[4] * dy + riser_c[6] * riser_c[9]
        out[26] = riser_c[5] * dx + riser_c[7] * riser_c[8]
        out[27] = riser_c[5] * dy + riser_c[7] * riser_c[9]
    if cur_kind != CURRENT_HELD:
        if not _current_at_nodes(r, vc, cur_kind, cur_clamps, cur_depths, cur_factors, cur_depth, cur_surface):
            return 2, out
    return 0, out


@_jit
def end_tensions(r, v, l0, EA, tabi, tab, c_int, has_int_damping, node_weight, fairlead_seg, fairlead_idx, anchor_seg,
                 active):  # pragma: no cover - compiled
    """Fairlead and anchor tension of every line [N], each (n_lines,): :meth:`FEMLines.fairlead_tension
    <tapm_opt.plant.fem.FEMLines.fairlead_tension>` (the top segment's tension vector plus the
    fairlead node's weight, 0 for a broken line) and :meth:`~tapm_opt.plant.fem.FEMLines.anchor_tension`
    (the bottom segment's tension), in the numpy path's order."""
    nl = fairlead_seg.shape[0]
    T_fl = np.empty(nl)
    T_an = np.empty(nl)
    for j in range(nl):
        lx, ly, lz, e, t = _bond_any(r, v, fairlead_seg[j], l0, EA, tabi, tab, c_int, has_int_damping)
        s = -(t / e)
        fx = s * lx
        fy = s * ly
        fz = s * lz + node_weight[fairlead_idx[j]]
        T_fl[j] = math.sqrt(0.0 + fx * fx + fy * fy + fz * fz) if active[j] else 0.0
        T_an[j] = _bond_any(r, v, anchor_seg[j], l0, EA, tabi, tab, c_int, has_int_damping)[4]
    return T_fl, T_an


@_jit
def section_tensions(r, v, l0, EA, tabi, tab, c_int, has_int_damping, w, bonds, lines, active):  # pragma: no cover - compiled
    """Tension at the upper end of sections [N] (:meth:`FEMLines.section_tension
    <tapm_opt.plant.fem.FEMLines.section_tension>`): each top segment ``bonds[i]``'s tension
    vector plus the submerged weight of its upper half ``w l0 / 2``, 0 on a broken line
    ``lines[i]``; the numpy path's operations in its order."""
    n = bonds.shape[0]
    out = np.empty(n)
    for i in range(n):
        b = bonds[i]
        lx, ly, lz, e, t = _bond_any(r, v, b, l0, EA, tabi, tab, c_int, has_int_damping)
        s = -(t / e)
        fx = s * lx
        fy = s * ly
        fz = s * lz + 0.5 * w[b] * l0[b]
        out[i] = math.sqrt(0.0 + fx * fx + fy * fy + fz * fz) if active[lines[i]] else 0.0
    return out


# plant_steps calls the step functions through these names: a test or a benchmark that wraps the
# public ones in Python (to count or time the per-step path's calls) leaves its compilation alone
_plant_pre_step, _mooring_step = plant_pre_step, mooring_step


@_jit
def plant_steps(h, n_sub, steps0, t_fem, sums, f, alpha, f_cmd, alpha_cmd, decay, rate_dt, alpha_rate_dt,
                eta, nu, eta_wf, vert, tau_moor, rate, r, v, vc,
                failed, f_min, f_max, azimuth, x_thr, y_thr, has_env, wind_dir, hull_k, wave_dir, drift_c, drift_grid,
                drift_sign, wf, v_c, M, M_A, M_inv, D_lin, d_quad, has_riser, riser_c,
                cur_kind, cur_clamps, cur_depths, cur_factors, cur_depth, cur_surface,
                p_cot, p_T, turret_angle, locked, z_fl,
                l0, EA, tabi, tab, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half,
                joint, joint_c, kb, cb, mu, depth, has_int_damping, has_friction,
                anchor_idx, anchors, fairlead_idx, attached, fairlead_seg, anchor_seg, active,
                near_tension, max_speed):  # pragma: no cover - compiled
    """Up to ``sums.shape[0]`` plant outer steps of ``h`` [s] in one call (``Plant._fused_steps``):
    each :func:`plant_pre_step`, then :func:`mooring_step` in ``n_sub`` substeps, the functions and
    arguments of the plant's per-step fused path (``Plant._fused_step``), so the same numbers. Row
    ``i`` of ``sums`` is step i's environment sums ``(V0, q0, S0, S1, C0)``, the heave, roll and
    pitch sums on the heading grid (none without them) and the drift sums on the heading grid at
    the step's start (its last ``drift_sign.shape[0]`` columns; none without the user's drift
    coefficients); ``vert`` the heave, roll and pitch at the start. The state passes from
    step to step as the plant passes it: the pose, velocity, wave-frequency pose and riser angles
    from the packed output, the mooring load and the pose rate, the node positions and velocities;
    ``f``, ``alpha`` (thrusters) and ``vc`` (current at the nodes) are written in place;
    ``t_fem`` gains ``h / n_sub`` per substep, as ``FEMLines`` adds it. ``steps0`` is the plant's
    outer-step count before the first step.

    The loop stops after a step that needs the plant's Python: its mooring step found a line
    near its strength (``near``), or a suspect node state on a step whose count is a multiple of 20
    (the plant's health check), or before a step whose :func:`plant_pre_step` reports a status.

    Returns
    -------
    k : int
        Outer steps completed.
    status : int
        0, or the status of :func:`plant_pre_step` at step ``k`` (not completed; ``outs[k]`` its
        output).
    outs : ndarray (n, :data:`OUT_SIZE`)
        Each step's packed output of :func:`plant_pre_step` (rows beyond the last step: zero).
    r, v, T, r_fl, rate, a_fl, tau, near, suspect
        :func:`mooring_step`'s outputs of step ``k - 1`` (``r``, ``v``, ``rate``, ``tau`` the
        inputs when ``k = 0``).
    tau_prev : ndarray (3,)
        The mooring load step ``k - 1`` started from (the plant's, should its health check on
        that step raise).
    t_fem : float
        The FEM time after the ``k`` steps.
    """
    n = sums.shape[0]
    nv = sums.shape[1] - drift_sign.shape[0]   # the heave, roll and pitch sums end there, the drift sums follow
    outs = np.zeros((n, OUT_SIZE))
    eta_c = eta.copy()
    nu_c = nu.copy()
    wf_c = eta_wf.copy()
    vert_c = vert.copy()
    tau_c = tau_moor.copy()
    tau_prev = tau_c
    rate_c = rate.copy()
    T = np.empty(0)
    r_fl = np.empty((0, 3))
    a_fl = np.empty((0, 3))
    near = False
    suspect = False
    dt = h / n_sub
    for i in range(n):
        status, out = _plant_pre_step(h, f, alpha, f_cmd, alpha_cmd, decay, rate_dt, alpha_rate_dt,
                                     sums[i, 0], sums[i, 1], sums[i, 2], sums[i, 3], sums[i, 4], sums[i, 5:nv],
                                     sums[i, nv:], eta_c, nu_c, wf_c, tau_c, r, vc,
                                     failed, f_min, f_max, azimuth, x_thr, y_thr, has_env, wind_dir, hull_k, wave_dir,
                                     drift_c, drift_grid, drift_sign, wf, v_c, M, M_A, M_inv, D_lin, d_quad, has_riser, riser_c,
                                     cur_kind, cur_clamps, cur_depths, cur_factors, cur_depth, cur_surface)
        outs[i, :] = out
        if status != 0:
            return i, status, outs, r, v, T, r_fl, rate_c, a_fl, tau_c, near, suspect, tau_prev, t_fem
        tau_prev = tau_c
        r, v, T, r_fl, rate_c, a_fl, tau_c, near, suspect = _mooring_step(
            out[18:21], out[21:24], vert_c, out[28:31], rate_c, h, n_sub, p_cot, p_T, turret_angle, locked, z_fl,
            r, v, vc, l0, EA, tabi, tab, c_int, bond_ok, node_weight, node_mass, cdn, cdt, can_half, cat_half,
            joint, joint_c, kb, cb, mu, depth, has_int_damping, has_friction,
            anchor_idx, anchors, fairlead_idx, attached, fairlead_seg, anchor_seg, active,
            near_tension, max_speed)
        for _ in range(n_sub):  # the same sum as n single steps (FEMLines._advance_compiled)
            t_fem += dt
        if near or (suspect and (steps0 + i + 1) % 20 == 0):
            return i + 1, 0, outs, r, v, T, r_fl, rate_c, a_fl, tau_c, near, suspect, tau_prev, t_fem
        for c in range(3):
            eta_c[c] = out[c]
            nu_c[c] = out[3 + c]
            wf_c[c] = out[6 + c]
            vert_c[c] = out[28 + c]
    return n, 0, outs, r, v, T, r_fl, rate_c, a_fl, tau_c, near, suspect, tau_prev, t_fem
