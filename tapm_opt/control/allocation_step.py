"""Thrust allocation: the QP data of one step — sector arithmetic, direction intervals, local
frames and bounds — and the post-processing of a QP solution, shared by the DAQP and OSQP paths
of the allocator and by the cvxpy reference.

Rates and sectors are linearised about the previous command ``(f_p, alpha_p)``. The allowed
direction interval is ``[-Da, Da]`` (``Da = max_azimuth_rate dt``) intersected with the allowed
arc that contains alpha_p (forbidden sectors); b_i is its bisector, hw its half-width:

* narrow (hw < pi/2): the plant can reach the annular sector |Delta f| <= r dt,
  |Delta alpha| <= Da (r = max_thrust_rate), whose convex part is the wedge |v| <= tan(hw) p cut
  by the band ``f_p - r dt <= p <= (f_p + r dt) cos(hw)``. The QP uses the rectangle inscribed in
  it: ``p0 <= p <= (f_p + r dt) cos(hw)``, ``|v| <= tan(hw) p0`` with
  ``p0 = max(f_p - r dt, f_p / 2)``. (The wedge's two half-planes are exact but made OSQP crawl:
  a thin wedge is badly conditioned in any scaling. Keeping half the thrust for a step below
  2 r dt leaves a low-thrust thruster room to turn.)
* half (pi <= width < 2 pi: Da >= pi/2, or a sector-bounded arc): ``p >= 0`` (the half-plane
  inside the interval closest to alpha_p) and the box ``|u - u_p| <= r dt / sqrt(2)`` per
  component of the local frame (inscribed in the disc |Delta u| <= r dt);
* free (no sector and Da >= pi, or no azimuth-rate limit): the box only;
* empty (failed; or alpha_p inside a forbidden sector with no allowed direction within Da):
  u = 0, and a live thruster turns toward the nearest allowed direction.

A narrow rectangle with hw <= 2 pi / m (m = polygon_sides) only holds directions within one
polygon side of b_i, so of the inscribed m-gon only the two sides at its vertex on b_i can bind.
:func:`step_kernel` reports whether that holds for every live azimuth (the usual case in a
control loop), and the DAQP path then solves a QP with those two rows per azimuth instead of m.

Both kernels are scalar loops over the thrusters, compiled with numba (``cache=True``, numpy
floating-point semantics; plain Python when numba is missing). They work on arrays the allocator
builds once, one column per thruster in the allocator's order, rows indexed by the ``C_*``,
``S_*`` and ``G_*`` constants below:

* ``C`` (constants): kind (1 azimuth, 0 tunnel/fixed), the QP columns of p and v (of f for a
  tunnel/fixed thruster), scaled thrust rate ``max_thrust_rate / F_ref`` [1/s], azimuth rate
  [rad/s] (inf: none), scaled thrust bounds (azimuth: 0 and the capacity R) and the polygon
  apothem, position (x, y) [m], scaled power weight, the balance columns ``S B_i`` of f_x and
  f_y (``S = diag(1, 1, 1/L_ref)``), the same times F_ref (tau in N, N m; a tunnel/fixed
  thruster: its configuration-matrix column times F_ref), the fixed angle, the number of
  forbidden sectors;
* ``Sec`` (forbidden sectors, merged, one row per thruster): starts [rad] in columns
  ``0..K-1``, widths in ``K..2K-1``;
* ``S`` (state, written in place): the previous command (scaled thrust, alpha), the failed flag
  and the frame b_i last written to the DAQP matrix;
* ``G`` (the step data, written in place): b, the reported direction range offset from b, the
  bounds of p and v (tunnel/fixed: of f, as p) and of the reported magnitude.
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np
import osqp

from .._jit import jit as _jit

TWO_PI = 2.0 * math.pi
HALF_PI = 0.5 * math.pi
_SQRT1_2 = math.sqrt(0.5)
#: In a narrow interval an azimuth keeps at least this fraction of its thrust for one step (when
#: that is more than the thrust rate allows), so that it can still turn (module docstring).
_KEEP = 0.5
_INF = math.inf
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    _BIG = float(osqp.constant("OSQP_INFTY"))  # OSQP's infinity (1e30, also DAQP's): no clipping in update()

# rows of C (constants)
C_KIND, C_IP, C_IV, C_RATE, C_ARATE, C_FMIN, C_FMAX, C_RIN, C_X, C_Y, C_W = range(11)
C_BX, C_BY = 11, 14         # 3 rows each: S B_i e_x, S B_i e_y (scaled balance rows; azimuths)
C_TX, C_TY = 17, 20         # 3 rows each: F_ref B_i e_x, F_ref B_i e_y (tau in N, N m; tunnel/fixed: C_TX)
C_ANGLE, C_NSEC = 23, 24
N_C = 25
# rows of S (state)
S_F, S_ALPHA, S_FAILED, S_B = range(4)
N_S = 4
# rows of G (step data; tunnel/fixed: the bounds of f in G_LP, G_HP)
G_B, G_OLO, G_OHI, G_LP, G_HP, G_LV, G_HV, G_LM, G_HM = range(9)
N_G = 9
#: step_kernel's return code: bit 0 (value 1) set when the full polygon is needed (else its two
#: sides at b_i suffice), bit 1 (value 2) when a frame b_i moved (the DAQP matrix was rewritten);
#: -1 when tau is not finite (nothing written).
CODE_FULL, CODE_MOVED, CODE_BAD_TAU = 1, 2, -1

# -- sectors -----------------------------------------------------------------------------------------

@_jit
def _ssa(a):  # pragma: no cover - compiled
    """Smallest signed angle in [-pi, pi) (as :func:`tapm_opt.geometry.ssa`)."""
    return a - TWO_PI * math.floor((a + math.pi) / TWO_PI)


@_jit
def arc(alpha, sec, K):  # pragma: no cover - compiled
    """Allowed arc relative to alpha, ``(lo, hi)`` [rad]: the arc containing alpha (lo <= 0 <= hi),
    or, when alpha lies in a forbidden sector, the nearest allowed arc (lo > 0 or hi < 0).

    ``sec``: the K merged forbidden sectors, starts in ``sec[:K]`` and widths in
    ``sec[n:n + K]`` with ``n = len(sec) // 2`` (K >= 1)."""
    n = sec.shape[0] // 2
    for k in range(K):
        t = (alpha - sec[k]) % TWO_PI
        w = sec[n + k]
        if 0.0 < t < w:
            t2 = w - t
            if t <= t2:  # leave clockwise: the allowed arc ending at the start of sector k
                kp = k - 1 if k > 0 else K - 1
                w_prev = (sec[k] - sec[kp] - sec[n + kp]) % TWO_PI
                if w_prev == 0.0:
                    w_prev = TWO_PI - w
                return -t - w_prev, -t
            k1 = k + 1 if k + 1 < K else 0
            w_next = (sec[k1] - sec[k] - w) % TWO_PI
            if w_next == 0.0:
                w_next = TWO_PI - w
            return t2, t2 + w_next
    hi = _INF
    lo = _INF
    for k in range(K):
        hi = min(hi, (sec[k] - alpha) % TWO_PI)
        lo = min(lo, (alpha - sec[k] - sec[n + k]) % TWO_PI)
    return -lo, hi


# -- the step data ---------------------------------------------------------------------------------

@_jit
def step_kernel(dt, tau, C, Sec, S, m, tau_scale, G, write, A, bu, bl):  # pragma: no cover - compiled
    """The step data (module docstring) into ``G``; returns a ``CODE_*`` bit set.

    With ``write``, also the DAQP data: bounds of p, v, f (``bl``, ``bu`` entries ``0..nv-1``),
    the scaled tau of the balance rows (entries ``nv..nv+2``) and, for the frames b_i that moved
    since the last write (``S[S_B]``), the balance entries of the (p_i, v_i) columns of ``A``.
    """
    n = G.shape[1]
    t0, t1, t2 = tau[0], tau[1], tau[2]
    if not math.isfinite(t0 + t1 + t2):
        return CODE_BAD_TAU
    side = TWO_PI / m
    full = False
    moved = False
    nv = 0
    for i in range(n):
        fa = S[S_F, i]
        dead = S[S_FAILED, i] != 0.0
        rdt = C[C_RATE, i] * dt
        ip = int(C[C_IP, i])
        if C[C_KIND, i] == 0.0:  # tunnel/fixed: the thrust rate and its bounds
            lf = max(C[C_FMIN, i], fa - rdt)
            hf = min(C[C_FMAX, i], fa + rdt)
            if dead:
                lf = hf = 0.0
            G[G_LP, i] = lf
            G[G_HP, i] = hf
            if write:
                bl[ip] = lf
                bu[ip] = hf
            nv += 1
            continue
        nv += 2
        aa = S[S_ALPHA, i]
        D = C[C_ARATE, i] * dt
        if D >= math.pi:
            D = _INF                             # can point anywhere within dt
        R = C[C_FMAX, i]
        lm = max(fa - rdt, 0.0)
        hm = min(fa + rdt, R)
        lo = -D
        hi = D
        empty = dead
        K = int(C[C_NSEC, i])
        if K > 0 and not dead:
            slo, shi = arc(aa, Sec[i], K)
            if slo > D or shi < -D:  # out of its allowed arc and out of reach: empty, turn toward it
                empty = True
                hi = min(max(slo if slo > 0.0 else shi, -D), D)
            else:
                lo = max(slo, -D)
                hi = min(shi, D)
        restricted = (not empty) and math.isfinite(lo)
        narrow = restricted and hi - lo < math.pi
        half = restricted and not narrow
        if narrow:
            mid = 0.5 * (lo + hi)
            hw = 0.5 * (hi - lo)
        elif half:
            mid = min(max(0.0, lo + HALF_PI), hi - HALF_PI)   # half-plane direction, closest to alpha_p
            hw = HALF_PI
        else:
            mid = 0.0
            hw = HALF_PI
        if restricted:
            olo = -hw
            ohi = hw
        elif empty:
            olo = ohi = 0.0 if dead else hi         # relative to b = alpha_p (mid = 0)
        else:
            olo = -_INF
            ohi = _INF
        if empty:
            lp = hp = lv = hv = lm = hm = 0.0
        elif narrow:                                # the rectangle
            pp = fa * math.cos(mid)                 # u_p in the local frame
            lp = max(min(fa - rdt, pp), _KEEP * max(pp, 0.0))
            hp = max((fa + rdt) * math.cos(hw), pp)
            hv = lp * math.tan(hw)
            lv = -hv
            if hw > side:
                full = True
        else:  # box |Delta u| <= r dt / sqrt(2) about u_p (moved into the polygon)
            fb = min(fa, C[C_RIN, i] / math.cos((-mid) % side - math.pi / m))
            pb = fb * math.cos(mid)
            vb = -fb * math.sin(mid)
            h = rdt * _SQRT1_2
            lp = max(max(-R, pb - h), 0.0 if half else -R)
            hp = min(R, pb + h)
            lv = max(-R, vb - h)
            hv = min(R, vb + h)
            full = True
        b = aa + mid
        G[G_B, i] = b
        G[G_OLO, i] = olo
        G[G_OHI, i] = ohi
        G[G_LP, i] = lp
        G[G_HP, i] = hp
        G[G_LV, i] = lv
        G[G_HV, i] = hv
        G[G_LM, i] = lm
        G[G_HM, i] = hm
        if write:
            iv = int(C[C_IV, i])
            bl[ip] = lp
            bu[ip] = hp
            bl[iv] = lv
            bu[iv] = hv
            if b != S[S_B, i]:
                moved = True
                S[S_B, i] = b
                cb = math.cos(b)
                sb = math.sin(b)
                for r in range(3):
                    bx = C[C_BX + r, i]
                    by = C[C_BY + r, i]
                    A[r, ip] = bx * cb + by * sb         # p column: B_i e(b)
                    A[r, iv] = by * cb - bx * sb         # v column: B_i e(b + pi/2)
    if write:
        for r in range(3):
            bu[nv + r] = bl[nv + r] = tau[r] * tau_scale[r]
    return (CODE_FULL if full else 0) + (CODE_MOVED if moved else 0)


# -- the solution ---------------------------------------------------------------------------------

@_jit
def finish_kernel(x, y, iy, tau, G, C, S, F_ref, L_ref, idle_tol, steer, commit, out):  # pragma: no cover - compiled
    """Clip a scaled QP solution x (p, v, f, ...) to the exact limits of the step ``G``; returns
    1 (and writes nothing) when x is not finite, else 0.

    Writes ``out`` (2 n + 6): f [N], alpha [rad] per thruster, the tau they produce and
    ``tau - that`` [N, N, N m]. An azimuth with |u_i| <= idle_tol gets the lowest thrust the rate
    allows (0 unless it is falling from more than r dt) and keeps alpha_p or, with ``steer``,
    turns within its interval toward its preferred direction ``-W_i^-1 B_i^T y / 2`` (y = the
    multiplier of the force balance, ``y[iy:iy + 3]``, convention P x + q + A^T y = 0). With
    ``commit``, the command becomes the previous command of the next step (``S``).
    """
    n = G.shape[1]
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i]
    if not math.isfinite(s):
        return 1
    y0 = y[iy]
    y1 = y[iy + 1]
    y2 = y[iy + 2] / L_ref                      # multiplier of the scaled moment row, per N m / F_ref
    pref_ok = steer and math.isfinite(y0 + y1 + y2)
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    for i in range(n):
        ip = int(C[C_IP, i])
        if C[C_KIND, i] == 0.0:  # tunnel/fixed
            ff = min(max(x[ip], G[G_LP, i]), G[G_HP, i])
            t0 += C[C_TX, i] * ff
            t1 += C[C_TX + 1, i] * ff
            t2 += C[C_TX + 2, i] * ff
            out[i] = ff * F_ref
            out[n + i] = C[C_ANGLE, i]
            if commit:
                S[S_F, i] = ff
            continue
        b = G[G_B, i]
        olo = G[G_OLO, i]
        ohi = G[G_OHI, i]
        p = min(max(x[ip], G[G_LP, i]), G[G_HP, i])
        v = min(max(x[int(C[C_IV, i])], G[G_LV, i]), G[G_HV, i])
        mag = math.hypot(p, v)
        th = min(max(math.atan2(v, p), olo), ohi) + b   # direction kept within the interval
        fa = min(max(mag, G[G_LM, i]), G[G_HM, i])      # exact |Delta f| <= r dt and f <= max_thrust
        if mag <= idle_tol:
            fa = G[G_LM, i]
            th = S[S_ALPHA, i]
            if pref_ok:  # preferred u_i = -W_i^-1 B_i^T y / 2 (stationarity with u_i free)
                w2 = 2.0 * C[C_W, i]
                px = -(y0 - C[C_Y, i] * y2) / w2
                py = -(y1 + C[C_X, i] * y2) / w2
                pref = math.hypot(px, py) > idle_tol
                toff = _ssa(math.atan2(py, px) - b) if pref else 0.0
                if pref or olo > 0.0 or ohi < 0.0:          # also: out of a forbidden sector
                    th = b + min(max(toff, olo), ohi)
        fx = fa * math.cos(th)
        fy = fa * math.sin(th)
        t0 += C[C_TX, i] * fx + C[C_TY, i] * fy
        t1 += C[C_TX + 1, i] * fx + C[C_TY + 1, i] * fy
        t2 += C[C_TX + 2, i] * fx + C[C_TY + 2, i] * fy
        al = _ssa(th)
        out[i] = fa * F_ref
        out[n + i] = al
        if commit:
            S[S_F, i] = fa
            S[S_ALPHA, i] = al
    out[2 * n] = t0
    out[2 * n + 1] = t1
    out[2 * n + 2] = t2
    out[2 * n + 3] = tau[0] - t0
    out[2 * n + 4] = tau[1] - t1
    out[2 * n + 5] = tau[2] - t2
    return 0


class _Step(NamedTuple):
    """Data of one step, scaled units (module docstring): ``G`` (N_G, n), the azimuth and
    tunnel/fixed columns, and whether the full polygon is needed. The attributes are arrays over
    the azimuths (lf, hf: over the tunnel/fixed thrusters)."""

    G: np.ndarray
    iaz: np.ndarray
    ifx: np.ndarray
    full: bool

    b = property(lambda s: s.G[G_B, s.iaz])      # local frame direction (bisector of the allowed interval) [rad]
    olo = property(lambda s: s.G[G_OLO, s.iaz])  # range of the reported direction, offset from b [rad]
    ohi = property(lambda s: s.G[G_OHI, s.iaz])
    lp = property(lambda s: s.G[G_LP, s.iaz])    # bounds of the radial force p and the tangential force v
    hp = property(lambda s: s.G[G_HP, s.iaz])
    lv = property(lambda s: s.G[G_LV, s.iaz])
    hv = property(lambda s: s.G[G_HV, s.iaz])
    lm = property(lambda s: s.G[G_LM, s.iaz])    # bounds of the reported magnitude |u| (thrust rate, capacity)
    hm = property(lambda s: s.G[G_HM, s.iaz])
    lf = property(lambda s: s.G[G_LP, s.ifx])    # bounds of the tunnel/fixed thrusts
    hf = property(lambda s: s.G[G_HP, s.ifx])
