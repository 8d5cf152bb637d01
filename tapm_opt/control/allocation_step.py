"""Thrust allocation: the QP data of one step — sector arithmetic, direction intervals, local
frames and bounds — shared by the OSQP allocator and the cvxpy reference.

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

:class:`_StepBounds` is a base class of :class:`~tapm_opt.control.allocation.ThrustAllocator`; its
methods read the thruster data the allocator sets up (``F_ref``, ``polygon_sides``, ``_R``,
``_Rin``, ``_rate``, ``_arate``, ``_iaz``, ``_ifx``, ``_nfx``, ``_ffmin``, ``_ffmax``,
``_sectors``, ``_jsec``) and its rate-limit state (``_fa_prev``, ``_aa_prev``, ``_ff_prev``,
``_failed``, ``_any_failed``), and cache the per-dt constants in ``_dtd``.
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np
import osqp

TWO_PI = 2.0 * math.pi
HALF_PI = 0.5 * math.pi
_SQRT1_2 = math.sqrt(0.5)
#: In a narrow interval an azimuth keeps at least this fraction of its thrust for one step (when
#: that is more than the thrust rate allows), so that it can still turn (module docstring).
_KEEP = 0.5
_INF = math.inf
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    _BIG = float(osqp.constant("OSQP_INFTY"))  # OSQP's infinity (1e30): no clipping in update()


# -- sectors -----------------------------------------------------------------------------------------

def _arc(alpha: float, starts: tuple[float, ...], widths: tuple[float, ...]) -> tuple[float, float]:
    """Allowed arc relative to alpha, ``(lo, hi)`` [rad]: the arc containing alpha (lo <= 0 <= hi),
    or, when alpha lies in a forbidden sector, the nearest allowed arc (lo > 0 or hi < 0)."""
    K = len(starts)
    for k in range(K):
        t = (alpha - starts[k]) % TWO_PI
        if 0.0 < t < widths[k]:
            t2 = widths[k] - t
            if t <= t2:  # leave clockwise: the allowed arc ending at starts[k]
                w_prev = (starts[k] - starts[k - 1] - widths[k - 1]) % TWO_PI or TWO_PI - widths[k]
                return -t - w_prev, -t
            k1 = (k + 1) % K
            w_next = (starts[k1] - starts[k] - widths[k]) % TWO_PI or TWO_PI - widths[k]
            return t2, t2 + w_next
    hi = min((s - alpha) % TWO_PI for s in starts)
    lo = -min((alpha - s - w) % TWO_PI for s, w in zip(starts, widths))
    return lo, hi


class _Step(NamedTuple):
    """Data of one step, scaled units; arrays (naz,) over the azimuths unless noted."""

    b: np.ndarray        # local frame direction (bisector of the allowed interval) [rad]
    olo: np.ndarray      # range of the reported direction, offset from b [rad]
    ohi: np.ndarray
    lp: np.ndarray       # bounds of the radial force p and the tangential force v
    hp: np.ndarray
    lv: np.ndarray
    hv: np.ndarray
    lm: np.ndarray       # bounds of the reported magnitude |u| (thrust rate, capacity)
    hm: np.ndarray
    lf: np.ndarray       # bounds of the tunnel/fixed thrusts, shape (nfx,)
    hf: np.ndarray


class _DtData(NamedTuple):
    """Per-dt constants (cached)."""

    dt: float
    rdt_a: np.ndarray    # max_thrust_rate dt / F_ref of the azimuths
    rdt_f: np.ndarray    # ... of the tunnel/fixed thrusters
    D: np.ndarray        # max_azimuth_rate dt [rad] (inf: can point anywhere)
    h: np.ndarray        # half-width of the box, rdt / sqrt(2)
    simple: tuple        # fast-path constants (no azimuth has a sector or has failed)


class _StepBounds:
    """The QP data of one allocation step (module docstring); a base class of ThrustAllocator."""

    def _dt_data(self, dt: float) -> _DtData:
        d = self._dtd
        if d is not None and d.dt == dt:
            return d
        F, R = self.F_ref, self._R
        rdt = self._rate * dt / F
        rdt_a, rdt_f = rdt[self._iaz], rdt[self._ifx]
        D = self._arate * dt
        D = np.where(D >= math.pi, _INF, D)          # can point anywhere within dt
        h = rdt_a * _SQRT1_2
        narrow = D < HALF_PI
        half = ~narrow & np.isfinite(D)
        hw = np.where(narrow, D, HALF_PI)
        olo = np.where(narrow | half, -hw, -_INF)
        # without sectors (b = alpha_p): lp = max(fa - a0, fa a8 + a1); hp = max(min((fa + a2) a3, a4), fa a5);
        # hv = max(lp a6, a7): the narrow rectangle or the box (module docstring)
        simple = (olo, -olo, np.where(narrow, rdt_a, h), np.where(narrow, 0.0, np.where(half, 0.0, -R)),
                  np.where(narrow, rdt_a, h), np.where(narrow, np.cos(hw), 1.0), np.where(narrow, _BIG, R),
                  narrow.astype(float), np.where(narrow, np.tan(hw), 0.0), np.where(narrow, 0.0, np.minimum(R, h)),
                  np.where(narrow, _KEEP, 0.0))
        d = self._dtd = _DtData(dt, rdt_a, rdt_f, D, h, simple)
        return d

    def _geometry(self, dt: float) -> _Step:
        """Direction intervals, local frames and bounds of one step (shared by OSQP and cvxpy)."""
        d = self._dt_data(dt)
        fa = self._fa_prev
        if self._nfx:
            lf = np.maximum(self._ffmin, self._ff_prev - d.rdt_f)
            hf = np.minimum(self._ffmax, self._ff_prev + d.rdt_f)
            if self._any_failed:
                dead = self._failed[self._ifx]
                lf[dead] = hf[dead] = 0.0
        else:
            lf = hf = fa[:0]
        lm = np.maximum(fa - d.rdt_a, 0.0)
        hm = np.minimum(fa + d.rdt_a, self._R)
        if not (self._jsec or self._any_failed):  # fast path: b = alpha_p, modes fixed by dt
            olo, ohi, a0, a1, a2, a3, a4, a5, a6, a7, a8 = d.simple
            lp = np.maximum(fa - a0, fa * a8 + a1)
            hp = np.maximum(np.minimum((fa + a2) * a3, a4), fa * a5)
            hv = np.maximum(lp * a6, a7)
            return _Step(self._aa_prev, olo, ohi, lp, hp, -hv, hv, lm, hm, lf, hf)
        return self._geometry_general(d, fa, lm, hm, lf, hf)

    def _geometry_general(self, d: _DtData, fa, lm, hm, lf, hf) -> _Step:
        D, R = d.D, self._R
        lo, hi = -D, D.copy()
        aa = self._aa_prev
        for j in self._jsec:
            slo, shi = _arc(float(aa[j]), *self._sectors[j])
            Dj = float(D[j])
            if slo > Dj or shi < -Dj:  # out of its allowed arc and out of reach: empty, turn toward it
                lo[j], hi[j] = math.nan, min(max(slo if slo > 0.0 else shi, -Dj), Dj)
            else:
                lo[j], hi[j] = max(slo, -Dj), min(shi, Dj)
        dead = self._failed[self._iaz]
        empty = dead | np.isnan(lo)
        restricted = np.isfinite(lo) & ~dead
        lo0, hi0 = np.where(restricted, lo, 0.0), np.where(restricted, hi, 0.0)
        narrow = restricted & (hi0 - lo0 < math.pi)
        half = restricted & ~narrow
        c = np.clip(0.0, lo0 + HALF_PI, hi0 - HALF_PI)      # half-plane direction, closest to alpha_p
        mid = np.where(narrow, 0.5 * (lo0 + hi0), np.where(half, c, 0.0))
        hw = np.where(narrow, 0.5 * (hi0 - lo0), HALF_PI)
        olo = np.where(restricted, -hw, -_INF)
        ohi = -olo
        e = empty & ~dead
        olo[e] = ohi[e] = hi[e]                               # relative to b = alpha_p (mid = 0)
        olo[dead] = ohi[dead] = 0.0
        pp = fa * np.cos(mid)                                 # u_p in the local frame
        lp = np.maximum(np.minimum(fa - d.rdt_a, pp), _KEEP * np.maximum(pp, 0.0))  # narrow: rectangle
        hp = np.maximum((fa + d.rdt_a) * np.cos(hw), pp)
        hv = lp * np.tan(np.where(narrow, hw, 0.0))
        lv = -hv
        box = ~(narrow | empty)
        if box.any():  # box |Delta u| <= r dt / sqrt(2) about u_p (moved into the polygon)
            m = self.polygon_sides
            fb = np.minimum(fa, self._Rin / np.cos(np.mod(-mid, TWO_PI / m) - math.pi / m))
            pb, vb = fb * np.cos(mid), -fb * np.sin(mid)
            lp = np.where(box, np.maximum(np.maximum(-R, pb - d.h), np.where(half, 0.0, -R)), lp)
            hp = np.where(box, np.minimum(R, pb + d.h), hp)
            lv = np.where(box, np.maximum(-R, vb - d.h), lv)
            hv = np.where(box, np.minimum(R, vb + d.h), hv)
        if empty.any():
            lp, hp, lv, hv, lm, hm = (np.where(empty, 0.0, v) for v in (lp, hp, lv, hv, lm, hm))
        return _Step(aa + mid, olo, ohi, lp, hp, lv, hv, lm, hm, lf, hf)
