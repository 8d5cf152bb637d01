"""Elastic catenary of a mooring line with seabed contact and friction, numeric and symbolic.

A line of unstretched length ``L`` [m], axial stiffness ``EA`` [N] and submerged weight ``w``
[N/m] runs from its lower end A (the anchor) to its fairlead, which lies ``XF`` [m] away
horizontally and ``ZF`` [m] above A. A lies ``h_A`` [m] above a flat seabed (default 0: an anchor
on the seabed; ``h_A > 0``: an anchor on a slope or a pile head, a clump weight, a line to a buoy).
The unknowns are the fairlead tension components ``HF`` (horizontal) and ``VF`` (vertical), both
>= 0; the line's force on the vessel points from the fairlead toward A along the line.

Closure equations (Irvine 1981; in the form used by FAST/MAP, Jonkman 2007, eq. 2-2 to 2-5),
with ``VA = VF - w L`` the vertical tension at A if no part of the line rests on the seabed:

fully suspended (``VA >= -V1``, see below; ``VA < 0`` is a line that leaves an elevated A
downward and sags, its lowest point still above the seabed)::

    XF = HF/w [asinh(VF/HF) - asinh(VA/HF)] + HF L/EA
    ZF = HF/w [sqrt(1 + (VF/HF)^2) - sqrt(1 + (VA/HF)^2)] + (VF L - w L^2/2)/EA

touching down (``VA < -V1``): the line rests on the seabed over ``LB = L - (VF + V1)/w``. The
part from the seabed up to the fairlead has length ``VF/w`` and zero vertical tension where it
leaves the seabed; the part from A down to the seabed (only for ``h_A > 0``) is a catenary with
the same ``HF`` that meets the seabed horizontally, over a length ``V1/w``, where ``V1`` >= 0 is the
downward vertical tension at A that makes such a catenary drop exactly ``h_A``::

    h_A = HF/w [sqrt(1 + (V1/HF)^2) - 1] + V1^2/(2 EA w)
    =>  V1^2 = 2 h_A w (h_A w + 2 HF) / (1 + 2 B k + sqrt(1 + 4 B k + 4 k^2 HF^2)),
        B = h_A w + HF, k = 1/(2 EA)                  (the root with h_A w + HF - k V1^2 >= 0)

(``V1 = 0`` for ``h_A = 0``; ``V1^2 = h_A w (h_A w + 2 HF)`` for an inextensible line.) With seabed
friction ``CB`` (only for ``h_A = 0``, below)::

    XF = LB + HF/w [asinh(VF/HF) + asinh(V1/HF)] + HF L/EA
         + CB w/(2 EA) [-LB^2 + (LB - HF/(CB w)) max(LB - HF/(CB w), 0)]
    ZF = HF/w [sqrt(1 + (VF/HF)^2) - 1] + VF^2/(2 EA w) - h_A

Derivation of the touching-down form: on the (frictionless, below) seabed the line carries no
vertical tension and the same horizontal tension ``HF`` as its suspended parts. The fairlead's part
is the anchored touchdown catenary that rises ``ZF + h_A`` over ``VF/w``; A's part, read from where
it leaves the seabed, is the same catenary rising ``h_A`` over ``V1/w``. The spans add:
``XF = LB (1 + HF/EA) + [HF/w asinh(VF/HF) + HF VF/(w EA)] + [HF/w asinh(V1/HF) + HF V1/(w EA)]``
(the form above) and ``ZF = (ZF + h_A) - h_A``. ``V1`` follows from
``sqrt(HF^2 + V1^2) = h_A w + HF - k V1^2``: squared, a quadratic in ``V1^2``, whose smaller root,
written above without cancellation, keeps the right-hand side positive. ``V1`` grows with ``HF``
at fixed ``h_A`` (``dV1/dHF = V1 / ((h1 + HF)(1 + h1/EA))``, ``h1 = sqrt(HF^2 + V1^2)``), which
enters the touchdown Jacobian. For ``h_A = 0`` every equation reduces to the anchored one.

The regime boundary ``VF + V1 = w L`` is where the sagging suspended line's lowest point just
reaches the seabed (``LB = 0``, ``VA = -V1``): both forms give the same spans there. For
``h_A = 0`` they are also C¹ there; for ``h_A > 0`` their derivatives differ (the seabed starts to
carry the sag, a one-sided contact), so the line's stiffness has a kink where the sag touches the
seabed while the tensions stay continuous.

Seabed friction with an elevated lower end: not applied. The grounded stretch then lies between
two suspended parts that both pull on it, and how friction shares the load between them depends
on the history of the motion; tapm_opt takes the grounded stretch frictionless (``HF`` constant
along the whole line, ``HA = HF``), as MoorPy does (its ``CB`` argument carries either the friction
coefficient or, negative, the height of end A, never both). Friction only takes load off the
anchor, so this errs toward a higher anchor load and, at a given offset, a slightly lower fairlead
tension than a rough seabed would give. ``CB`` is ignored where ``h_A > 0`` (so the answer jumps
from ``h_A = 0`` to ``h_A > 0`` by the friction effect alone, when ``CB > 0``).

Both regimes are written once in :func:`closure` with numerically stable forms (no cancellation
as ``w -> 0`` or ``HF -> 0``, nor for a symmetric U-shaped line, ``VA = -VF``) and serve the
vectorised numeric solver (:func:`solve`) and the symbolic CasADi path (:func:`symbolic_function`).
Degenerate regimes have closed forms, with ``hang(z)`` the length of a line hanging vertically
over a height ``z``, root of ``z = Ls + w Ls^2/(2 EA)``:

* slack: the line hangs vertically from the fairlead over ``L2 = hang(ZF + h_A)`` and from A over
  ``L1 = hang(h_A)``, and the rest lies on the seabed without tension (``L - L1 - L2 >= XF``):
  ``HF = 0, VF = w L2, VA = -w L1``;
* vertical and fully suspended (``XF = 0``): taut, ``VA >= 0`` when ``ZF >= L (1 + w L/(2 EA))``:
  ``HF = 0, VF = EA (ZF - L)/L + w L/2``; otherwise (only for ``h_A > 0``) the line hangs doubled,
  down from A and up to the fairlead, its fold above the seabed:
  ``VF = w (L + ZF/(1 + w L/(2 EA)))/2``, ``VA = VF - w L < 0``;
* both ends on the seabed (``ZF = 0``, ``h_A = 0``, ``XF > L``): ``VF = 0`` and ``HF`` from the
  seabed stretch with friction;
* weightless (``w = 0``): a straight elastic bar, ``T = EA max(l/L - 1, 0)``.

Conventions: tensions in N, lengths in m; ``HA`` is the horizontal tension at A (reduced by seabed
friction), ``VA`` the vertical tension at A, positive when the line pulls A up (anchor uplift), 0
when the line touches down from an anchor on the seabed, negative when the line leaves an
elevated A downward; ``TF`` the fairlead tension magnitude ``sqrt(HF^2 + VF^2)`` — this is the
"fairlead tension" everywhere in tapm_opt.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from .. import _backend as bk
from ..errors import CatenaryError
from ..strain_table import StrainTable, StrainTableError

#: The smallest normal float64: a product below it has lost bits (or is 0).
_TINY = float(np.finfo(np.float64).tiny)

__all__ = [
    "REGIMES",
    "CatenarySolution",
    "regime_name",
    "closure",
    "hanging_length",
    "solve",
    "line_profile",
    "symbolic_function",
]

#: Names of the regime codes in :attr:`CatenarySolution.regime`.
REGIMES = ("slack", "touchdown", "suspended", "vertical", "seabed", "weightless")
SLACK, TOUCHDOWN, SUSPENDED, VERTICAL, SEABED, WEIGHTLESS = range(6)


# ------------------------------------------------------------------------------------------
# the one set of closure equations (numpy or CasADi)
# ------------------------------------------------------------------------------------------


def _elevated(h_A, *xs) -> bool:
    """False only on the numeric path with every lower end on the seabed (``h_A = 0``): the
    elevated-end terms then vanish and are skipped (same numbers, less work)."""
    return bk.is_symbolic(h_A, *xs) or bool(np.any(np.asarray(h_A) > 0))


def _seabed_reach(HF, h_A, EA, w):
    """``V1`` [N]: downward vertical tension at a lower end ``h_A`` above the seabed of a catenary
    with horizontal tension ``HF`` that meets the seabed horizontally (module docstring); 0 for
    ``h_A = 0``. Works on numpy arrays and CasADi symbols."""
    up = h_A > 0
    hw = bk.where(up, h_A * w, 1.0)  # a dummy height where h_A = 0: sqrt stays differentiable
    k = 0.5 / EA
    B = hw + HF
    q = 2.0 * hw * (hw + 2.0 * HF) / (1.0 + 2.0 * B * k + bk.sqrt(1.0 + 4.0 * B * k + 4.0 * k * k * HF * HF))
    return bk.where(up, bk.sqrt(q), 0.0)


def closure(HF, VF, L, EA, w, CB=0.0, h_A=0.0, table=None, *, _V1=None):
    """Horizontal and vertical span (X, Z) [m] reached by a line with fairlead tension (HF, VF).

    Implements the elastic catenary closure equations with seabed contact and friction (module
    docstring) in numerically stable form. Works elementwise on numpy arrays and on CasADi
    symbols; requires ``HF > 0`` and ``w > 0``.

    Parameters
    ----------
    HF, VF : array_like or CasADi
        Horizontal and vertical fairlead tension [N].
    L : array_like
        Unstretched length [m].
    EA : array_like
        Axial stiffness [N] (``inf`` for an inextensible line, numeric path only).
    w : array_like
        Submerged weight per unit length [N/m], > 0.
    CB : array_like
        Seabed friction coefficient [-], >= 0 (not applied where ``h_A > 0``).
    h_A : array_like
        Height of the lower end A above the seabed [m], >= 0.
    table : StrainTable, optional
        A nonlinear axial law (:class:`tapm_opt.strain_table.StrainTable`) instead of ``EA``
        (numeric path only; section "Nonlinear axial stiffness" of the module docstring).

    Returns
    -------
    X, Z : spans [m] of the same shape; Z is the fairlead's height above A.
    """
    if table is not None:
        return _table_closure(HF, VF, L, w, CB, h_A, table)[:2]
    VA = VF - w * L
    hF = bk.hypot(HF, VF)
    hA = bk.hypot(HF, VA)
    # fully suspended, S = asinh(a) - asinh(b), a = VF/HF, b = VA/HF: for VA >= 0 as
    # asinh((a-b)(a+b)/(a sqrt(1+b^2) + b sqrt(1+a^2))); for VA < 0 (a sag below an elevated A) as
    # asinh(a) + asinh(-b), a sum of positive terms. Touching down, St: the fairlead's part rises
    # from the seabed over VF/w, A's part (elevated A) reaches it over V1/w.
    if _elevated(h_A, HF, VF):
        up = VA >= 0
        den = bk.where(up, VF * hA + VA * hF, 1.0)
        S = bk.where(up, bk.asinh(w * L * (VF + VA) / den), bk.asinh(VF / HF) + bk.asinh(-VA / HF))
        V1 = _seabed_reach(HF, h_A, EA, w) if _V1 is None else _V1
        St = bk.asinh(VF / HF) + bk.asinh(V1 / HF)
        cb = bk.where(h_A > 0, 0.0, CB)  # no friction with an elevated lower end (module docstring)
    else:  # every lower end on the seabed (numeric): V1 = 0, and VA >= 0 wherever suspended
        S = bk.asinh(w * L * (VF + VA) / (VF * hA + VA * hF))
        V1, St, cb = 0.0, bk.asinh(VF / HF), CB
    Xs = HF / w * S + HF * L / EA
    Zs = L * (VF + VA) / (hF + hA) + (VF * L - 0.5 * w * L * L) / EA
    LB = L - (VF + V1) / w
    Xt = LB + HF / w * St + HF * L / EA
    Zt = VF * VF / (w * (hF + HF)) + VF * VF / (2.0 * EA * w) - h_A
    has_cb = cb > 0
    cbw = bk.where(has_cb, cb * w, 1.0)
    xs = LB - HF / cbw
    Xt = Xt + bk.where(has_cb, cbw / (2.0 * EA) * (-LB * LB + xs * bk.fmax(xs, 0.0)), 0.0)
    susp = VF + V1 >= w * L
    return bk.where(susp, Xs, Xt), bk.where(susp, Zs, Zt)


def _closure_jacobian(HF, VF, L, EA, w, CB, h_A=0.0, table=None, *, _V1=None, _dV1=None):
    """Analytic d(X, Z)/d(HF, VF) of :func:`closure` (numpy only), for the Newton iteration
    (``_V1``, ``_dV1``: the elevated end's ``V1`` and ``dV1/dHF`` of another axial law)."""
    if table is not None:
        return _table_closure(HF, VF, L, w, CB, h_A, table, jacobian=True)[2]
    VA = VF - w * L
    hF = np.hypot(HF, VF)
    hA = np.hypot(HF, VA)
    elevated = _elevated(h_A)
    if elevated:
        up = VA >= 0
        den = np.where(up, VF * hA + VA * hF, 1.0)
        S = np.where(up, np.arcsinh(w * L * (VF + VA) / den), np.arcsinh(VF / HF) + np.arcsinh(-VA / HF))
        # G = (VF/hF - VA/hA)/w, written without cancellation for either sign of VA
        G = np.where(up, HF * HF * (L * (VF + VA) / (den * hA * hF)), (VF * hA - VA * hF) / (w * hF * hA))
    else:  # VA >= 0 wherever suspended
        den = VF * hA + VA * hF
        S = np.arcsinh(w * L * (VF + VA) / den)
        G = HF * HF * (L * (VF + VA) / (den * hA * hF))
    off_s = -HF * L * (VF + VA) / (hF * hA * (hF + hA))
    Xh_s = S / w - G + L / EA
    Zv_s = G + L / EA
    # touchdown
    a = VF / HF
    off_t = -VF * VF / (w * hF * (hF + HF))
    Xh_t = (np.arcsinh(a) - VF / hF) / w + L / EA
    Zv_t = VF / (w * hF) + VF / (EA * w)
    Xv_t = off_t.copy()
    if elevated:  # the part from an elevated A down to the seabed: V1(HF)
        V1 = _seabed_reach(HF, h_A, EA, w) if _V1 is None else _V1
        h1 = np.hypot(HF, V1)
        dV1 = V1 / ((h1 + HF) * (1.0 + h1 / EA)) if _dV1 is None else _dV1
        Xh_t = Xh_t + (np.arcsinh(V1 / HF) - V1 / h1 - dV1 * V1 * V1 / (h1 * (h1 + HF))) / w
        cb = np.where(h_A > 0, 0.0, CB)
    else:
        V1, cb = 0.0, CB
    has_cb = cb > 0
    cbw = np.where(has_cb, cb * w, 1.0)
    LB = L - (VF + V1) / w
    xs_pos = np.maximum(LB - HF / cbw, 0.0)
    Xh_t = Xh_t + np.where(has_cb, -xs_pos / EA, 0.0)
    Xv_t = Xv_t + np.where(has_cb, cb / EA * (LB - xs_pos), 0.0)
    susp = VF + V1 >= w * L
    return (
        np.where(susp, Xh_s, Xh_t),
        np.where(susp, off_s, Xv_t),
        np.where(susp, off_s, off_t),
        np.where(susp, Zv_s, Zv_t),
    )


# ------------------------------------------------------------------------------------------
# nonlinear axial law: the elastic terms of a tension-strain table (numpy only)
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Run:
    """Integrals along a suspended run of line (horizontal tension H, vertical tension V = V0 + w s
    over its unstretched length s in [0, sig]) of a tension-strain table, ``eps = a_k + c_k T`` on
    each table segment: ``QX = int eps/T ds``, ``QZ = int eps V/T ds``, ``QC = int c ds``,
    ``Q5 = H^2 int a/T^3 ds``, ``Q6 = int a V/T^3 ds``. Elastic spans of the run: ``H QX``
    horizontally, ``QZ`` vertically."""

    QX: np.ndarray
    QZ: np.ndarray
    QC: np.ndarray
    Q5: np.ndarray
    Q6: np.ndarray


def _stack_last(*parts):
    """The arrays ``parts`` (..., n_i) joined on their last axis, their leading axes broadcast."""
    lead = np.broadcast_shapes(*(p.shape[:-1] for p in parts))
    return np.concatenate([np.broadcast_to(p, lead + p.shape[-1:]) for p in parts], axis=-1)


def _run(H, V0, sig, w, tab) -> _Run:
    """:class:`_Run` of a table ``tab``, exact for the piecewise-linear law: the run is cut where
    its tension crosses a row of the table (``V = +-sqrt(T_k^2 - H^2)``) and where ``V = 0``, and on
    each piece of unstretched length ``ds`` between vertical tensions ``Va < Vb`` (one sign)::

        int ds/T   = asinh(w ds (Va + Vb) / (Vb Ta + Va Tb)) / w
        int V/T ds = ds (Va + Vb) / (Ta + Tb)            int V ds = ds (Va + Vb) / 2
        H^2 int ds/T^3 = H^2 ds (Va + Vb) / (Ta Tb (Vb Ta + Va Tb))
        int V/T^3 ds   = ds (Va + Vb) / ((Ta + Tb) Ta Tb)

    (``T = sqrt(H^2 + V^2)``), all without cancellation as ``w ds -> 0``. Requires ``w > 0``; the
    pieces of every configuration are evaluated at once (arrays with a last axis of pieces)."""
    H, V0, sig, w = (a[..., None] for a in np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (H, V0, sig, w))))
    knots = tab.tension[1:-1]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        Vk = np.sqrt(np.maximum(knots * knots - H * H, 0.0))
        cand = _stack_last(0.0 * H, sig, -V0 / w, (Vk - V0) / w, (-Vk - V0) / w)
        S = np.sort(np.clip(cand, 0.0, sig), axis=-1)
        S[..., 0] = 0.0
        S[..., -1] = sig[..., 0]
        sa, sb = S[..., :-1], S[..., 1:]
        ds = sb - sa
        on = ds > 0
        Va = V0 + w * sa
        Vb = V0 + w * sb
        Ta, Tb = np.hypot(H, Va), np.hypot(H, Vb)
        sV = Va + Vb
        den = Vb * Ta + Va * Tb
        k = tab.segment_of_tension(np.hypot(H, 0.5 * sV))
        a, c = tab.intercept[k], tab.compliance[k]
        ha = on & (a != 0)
        cds = np.where(on, c * ds, 0.0)
        aP2 = np.where(ha, a * (np.arcsinh(w * ds * sV / den) / w), 0.0)
        aP3 = np.where(ha, a * (ds * sV / (Ta + Tb)), 0.0)
        cP4 = np.where(on, c * (0.5 * ds * sV), 0.0)
        aP5 = np.where(ha & (H > 0), a * (H * H * ds * sV / (Ta * Tb * den)), 0.0)
        aP6 = np.where(ha, a * (ds * sV / ((Ta + Tb) * Ta * Tb)), 0.0)
    return _Run(QX=np.sum(cds + aP2, axis=-1), QZ=np.sum(cP4 + aP3, axis=-1), QC=np.sum(cds, axis=-1),
                Q5=np.sum(aP5, axis=-1), Q6=np.sum(aP6, axis=-1))


def _bed(HF, LB, cbw, tab, s1=None, s2=None):
    """Stretch ``int eps(T(s)) ds`` [m] of the grounded stretch between ``s1`` and ``s2`` (default
    the whole ``[0, LB]``, s from where it starts on the seabed) and ``int c ds`` [m/N] over its
    tensioned part: the tension rises by friction ``cbw = CB w`` [N/m] toward the suspended part,
    ``T(s) = max(HF - cbw (LB - s), 0)`` (``HF`` all along for ``cbw = 0``). Exact for the table:
    cut at the table's rows and where the tension vanishes, each piece a trapezoid in strain."""
    if s1 is None:
        s1 = 0.0
    if s2 is None:
        s2 = LB
    if not np.any(np.asarray(cbw) > 0):  # no friction: the tension HF all along
        ds = np.maximum(np.asarray(s2, dtype=float) - s1, 0.0)
        return ds * tab.strain_at(HF), ds * tab.compliance_at(HF)
    HF, LB, cbw, s1, s2 = (a[..., None] for a in np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (HF, LB, cbw, s1, s2))))
    fr = cbw > 0
    cs = np.where(fr, cbw, 1.0)
    knots = np.r_[0.0, tab.tension[1:-1]]
    cand = _stack_last(s1, s2, np.where(fr, LB - (HF - knots) / cs, s1))
    S = np.sort(np.clip(cand, s1, s2), axis=-1)
    sa, sb = S[..., :-1], S[..., 1:]
    ds = sb - sa
    Ta = np.maximum(HF - cbw * (LB - sa), 0.0)
    Tb = np.maximum(HF - cbw * (LB - sb), 0.0)
    Tm = HF - cbw * (LB - 0.5 * (sa + sb))  # > 0 on a tensioned piece (its ends may round to 0)
    on = (ds > 0) & (Tm > 0)
    B = np.sum(np.where(on, 0.5 * ds * (tab.strain_at(Ta) + tab.strain_at(Tb)), 0.0), axis=-1)
    QC = np.sum(np.where(on, ds * tab.compliance_at(Tm), 0.0), axis=-1)
    return B, QC


def _table_reach(HF, h_A, w, tab):
    """``V1`` [N] of a table (module docstring, "Nonlinear axial stiffness"): the downward vertical
    tension at a lower end ``h_A`` above the seabed of a catenary with horizontal tension ``HF``
    that meets the seabed horizontally, from ``w h_A = (T1 - HF) + E(T1) - E(HF)``."""
    up = h_A > 0
    d1 = tab.rise(HF, np.where(up, w * h_A, 0.0))
    return np.where(up, np.sqrt(d1 * (d1 + 2.0 * HF)), 0.0)


def _reach_terms_table(HF, V1, w, tab):
    """For a line of a table touching down from an elevated lower end (``V1 > 0``): ``dV1/dHF``,
    ``dV1/dh_A`` and ``dX/dV1`` [m/N] (the span's change with ``V1`` at fixed fairlead tensions)."""
    T1 = np.hypot(HF, V1)
    A = _run(HF, -V1, V1 / w, w, tab)
    e1 = tab.strain_at(T1)
    with np.errstate(invalid="ignore", divide="ignore"):
        dV1 = np.where(V1 > 0, (V1 * V1 / (T1 + HF) - HF * T1 * w * A.Q6) / ((1.0 + e1) * V1), 0.0)
        dV1h = w * T1 / ((1.0 + e1) * V1)
    dXdV1 = -(V1 * V1 / (T1 + HF)) / (w * T1) + HF * A.Q6
    return dV1, dV1h, dXdV1


def _table_closure(HF, VF, L, w, CB, h_A, tab, jacobian: bool = False):
    """:func:`closure` (and, with ``jacobian``, :func:`_closure_jacobian`) of a line whose axial law
    is the table ``tab``: the inextensible catenary (``EA = inf``, with the table's ``V1`` for an
    elevated lower end) plus the exact elastic spans of its suspended runs and grounded stretch
    (module docstring, "Nonlinear axial stiffness"). Returns ``(X, Z, jacobian or None)``."""
    if bk.is_symbolic(HF, VF, L, w, CB, h_A):
        raise CatenaryError("a tension-strain table (nonlinear EA) has no symbolic catenary in tapm_opt")
    HF, VF, L, w, CB, h_A = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (HF, VF, L, w, CB, h_A)))
    shape = HF.shape
    HF, VF, L, w, CB, h_A = (a.ravel() for a in (HF, VF, L, w, CB, h_A))
    elevated = _elevated(h_A)
    el = [np.zeros(HF.size) for _ in range(6)]  # elastic X, Z and their d/d(HF, VF)
    dV1 = np.zeros(HF.size)
    with np.errstate(all="ignore"):
        V1 = _table_reach(HF, h_A, w, tab) if elevated else np.zeros(HF.size)
        X, Z = closure(HF, VF, L, np.inf, w, CB, h_A, _V1=V1)
        susp = VF + V1 >= w * L
        i = np.flatnonzero(susp)
        if i.size:  # suspended: one run from VA to VF
            H = HF[i]
            S = _run(H, VF[i] - w[i] * L[i], L[i], w[i], tab)
            for k, v in enumerate((H * S.QX, S.QZ, S.QX - S.Q5, -H * S.Q6, -H * S.Q6, S.Q5 + S.QC)):
                el[k][i] = v
        i = np.flatnonzero(~susp)
        if i.size:  # touching down: A's part down to the seabed, the grounded stretch, the run to the fairlead
            H, V, Li, wi, V1i = HF[i], VF[i], L[i], w[i], V1[i]
            F = _run(H, 0.0, np.minimum(V / wi, Li), wi, tab)
            cb = np.where(h_A[i] > 0, 0.0, CB[i])
            B, QCb = _bed(H, np.maximum(Li - (V + V1i) / wi, 0.0), cb * wi, tab)
            Xt = B + H * F.QX
            a_t = QCb + F.QX - F.Q5
            if elevated:
                A = _run(H, -V1i, V1i / wi, wi, tab)
                T1 = np.hypot(H, V1i)
                dV1[i] = np.where(V1i > 0, (V1i * V1i / (T1 + H) - H * T1 * wi * A.Q6)
                                  / ((1.0 + tab.strain_at(T1)) * V1i), 0.0)
                Xt = Xt + H * A.QX
                a_t = a_t + A.QX - A.Q5 + dV1[i] * H * A.Q6
            for k, v in enumerate((Xt, F.QZ, a_t, -H * F.Q6 + cb * QCb, -H * F.Q6, F.Q5 + F.QC)):
                el[k][i] = v
        X = (X + el[0]).reshape(shape)
        Z = (Z + el[1]).reshape(shape)
        if not jacobian:
            return X, Z, None
        a, b, c, d = _closure_jacobian(HF, VF, L, np.inf, w, CB, h_A, _V1=V1, _dV1=dV1)
    return X, Z, tuple((g + e).reshape(shape) for g, e in zip((a, b, c, d), el[2:]))


def as_table(table) -> Any:
    """``table`` as a :class:`~tapm_opt.strain_table.StrainTable` (rows ``[[strain, tension], ...]``
    are read as one; None stays None); an invalid table raises :class:`CatenaryError`."""
    if table is None or isinstance(table, StrainTable):
        return table
    try:
        return StrainTable.from_rows(table)
    except StrainTableError as exc:
        raise CatenaryError(str(exc)) from None


# ------------------------------------------------------------------------------------------
# numeric, vectorised solver
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CatenarySolution:
    """Solution of :func:`solve`; every array has the broadcast shape of the inputs.

    Attributes
    ----------
    HF, VF : ndarray
        Horizontal and vertical tension at the fairlead [N], >= 0.
    HA, VA : ndarray
        Horizontal and vertical tension at the lower end A [N]. ``VA > 0``: the line lifts A
        (anchor uplift); ``VA = 0``: touching down from an anchor on the seabed; ``VA < 0``: the
        line leaves an elevated A downward (a sag, or the part that runs down to the seabed).
    TF, TA : ndarray
        Tension magnitude at the fairlead and at the anchor [N].
    LBot : ndarray
        Unstretched length resting on the seabed [m].
    regime : ndarray of int
        Index into :data:`REGIMES`.
    dHF_dXF, dHF_dZF, dVF_dXF, dVF_dZF : ndarray
        Exact sensitivities of the fairlead tensions to the spans [N/m] (implicit function
        theorem on the closure equations; the line's stiffness). ``dVF_dZF`` is +inf for a line
        lying straight on the seabed (ZF = 0), which lifts off with infinite vertical stiffness.
    iterations : int
        Newton iterations used (the largest over all configurations).
    """

    HF: np.ndarray
    VF: np.ndarray
    HA: np.ndarray
    VA: np.ndarray
    TF: np.ndarray
    TA: np.ndarray
    LBot: np.ndarray
    regime: np.ndarray
    dHF_dXF: np.ndarray
    dHF_dZF: np.ndarray
    dVF_dXF: np.ndarray
    dVF_dZF: np.ndarray
    iterations: int

    @property
    def dTF_dXF(self) -> np.ndarray:
        """Sensitivity of the fairlead tension magnitude to the horizontal span [N/m]:
        ``(HF dHF/dXF + VF dVF/dXF) / TF`` (0 where ``TF`` is 0)."""
        return (self.HF * self.dHF_dXF + self.VF * self.dVF_dXF) / np.maximum(self.TF, 1e-300)

    def regime_names(self) -> np.ndarray:
        """Regime names as a string array of the same shape (a composite line's code reads
        "composite")."""
        return np.vectorize(regime_name, otypes=[object])(self.regime)


def regime_name(code: int) -> str:
    """Name of a regime code: one of :data:`REGIMES`, or "composite" for the combined code of a
    composite line's sections (:func:`tapm_opt.models.composite.solve`)."""
    code = int(code)
    return REGIMES[code] if 0 <= code < len(REGIMES) else "composite"


def _check_inputs(**arrays: np.ndarray) -> None:
    rules = {
        "XF": ("must be >= 0 (horizontal fairlead distance)", lambda a: a >= 0),
        "ZF": ("must be >= 0 (fairlead at or above the anchor)", lambda a: a >= 0),
        "L": ("must be > 0 (unstretched length)", lambda a: a > 0),
        "EA": ("must be > 0 (axial stiffness)", lambda a: a > 0),
        "w": ("must be >= 0 (submerged weight; buoyant lines are not supported)", lambda a: a >= 0),
        "CB": ("must be >= 0 (seabed friction coefficient; for a lower end above the seabed, MoorPy's "
               "negative CB, give its height as h_A = -CB instead)", lambda a: a >= 0),
        "h_A": ("must be >= 0 (height of the lower end above the seabed [m]; the lower end cannot lie "
                "below the seabed)", lambda a: a >= 0),
    }
    for name, arr in arrays.items():
        finite_ok = np.isfinite(arr) | ((name == "EA") & (arr == np.inf))
        msg, rule = rules[name]
        with np.errstate(invalid="ignore"):
            bad = ~(finite_ok & rule(arr))
        if np.any(bad):
            idx = tuple(int(i) for i in np.argwhere(bad)[0])
            where = f" at index {idx}" if arr.ndim else ""
            what = "must be finite" if not finite_ok[idx] else msg
            raise CatenaryError(f"{name} = {float(arr[idx])!r}{where} {what}")


def hanging_length(ZF, w, EA, table=None):
    """Unstretched length [m] of a line hanging vertically with no horizontal tension over a
    height ZF [m] (submerged weight w [N/m], axial stiffness EA [N]; floats or arrays): the root
    of ZF = Ls + w Ls^2 / (2 EA), in a form without cancellation. With a tension-strain ``table``
    (instead of EA): the root of ``w ZF = w Ls + E(w Ls)``, ``E`` the table's complementary energy."""
    if table is not None:
        tab = as_table(table)
        ZF, w = np.broadcast_arrays(np.asarray(ZF, dtype=float), np.asarray(w, dtype=float))
        top = tab.rise(0.0, w * ZF)
        return np.where(w > 0, top / np.where(w > 0, w, 1.0), ZF)
    return 2.0 * ZF / (1.0 + np.sqrt(1.0 + 2.0 * w * ZF / EA))


def _initial_guess(XF, ZF, L, EA, w):
    """Peyrot & Goulois (1979) starting point, raised for lines stretched beyond their length."""
    d = np.hypot(XF, ZF)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(d >= L, 0.2, np.sqrt(np.maximum(3.0 * ((L * L - ZF * ZF) / (XF * XF) - 1.0), 0.0)))
        lam = np.where(XF <= 0, 1e6, np.maximum(lam, 0.2))
        HF = np.maximum(np.abs(0.5 * w * XF / lam), 1e-3 * w * L)
        VF = 0.5 * w * (ZF / np.tanh(lam) + L)
        T0 = np.where(d > L, EA * (d / L - 1.0), 0.0)
        T0 = np.where(np.isfinite(T0), T0, 0.0)
        HF = np.maximum(HF, T0 * XF / d)
        VF = np.maximum(VF, T0 * ZF / d + 0.5 * w * L)
    return HF, VF


def _newton(XF, ZF, L, EA, w, CB, h_A, *, tol, max_iter, guess=None, table=None):
    """Damped Newton on (HF, VF) for the general (non-degenerate) configurations, from ``guess``
    (HF, VF) where it is positive and finite, else from :func:`_initial_guess` (with a ``table``,
    at the stiffness of the straight line's strain)."""
    if table is None:
        HF, VF = _initial_guess(XF, ZF, L, EA, w)
    else:
        e = np.maximum(np.hypot(XF, ZF) / L - 1.0, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            EAg = np.where(e > 0, table.tension_at(e) / np.where(e > 0, e, 1.0), table.initial_slope)
        HF, VF = _initial_guess(XF, ZF, L, EAg, w)
    if guess is not None:
        g_H, g_V = guess
        use = np.isfinite(g_H) & np.isfinite(g_V) & (g_H > 0) & (g_V > 0)
        HF, VF = np.where(use, g_H, HF), np.where(use, g_V, VF)
    it = 0
    J = None  # a table's Jacobian, kept from the line search (its runs are the closure's)
    with np.errstate(all="ignore"):
        X, Z = closure(HF, VF, L, EA, w, CB, h_A, table)
        rX, rZ = X - XF, Z - ZF
        err = np.abs(rX) + np.abs(rZ)
        for it in range(1, max_iter + 1):
            active = err > tol
            if it == 1 and guess is not None:  # from a nearby solution: one step anyway, to full precision
                active = err > 0
            if not np.any(active):
                it -= 1
                break
            a, b, c, d = _closure_jacobian(HF, VF, L, EA, w, CB, h_A, table) if J is None else J
            det = a * d - b * c
            dH = -(d * rX - b * rZ) / det
            dV = -(-c * rX + a * rZ) / det
            bad = ~(np.isfinite(dH) & np.isfinite(dV))
            dH = np.where(bad, 0.5 * HF, dH)
            dV = np.where(bad, 0.0, dV)
            step = np.ones_like(HF)
            for _ in range(8):  # backtracking on the residual norm, keep HF, VF positive
                Hn = np.maximum(HF + step * dH, 0.1 * HF)
                Vn = np.maximum(VF + step * dV, 0.1 * VF)
                if table is None:
                    Xn, Zn = closure(Hn, Vn, L, EA, w, CB, h_A)
                else:
                    Xn, Zn, Jn = _table_closure(Hn, Vn, L, w, CB, h_A, table, jacobian=True)
                rXn, rZn = Xn - XF, Zn - ZF
                errn = np.abs(rXn) + np.abs(rZn)
                ok = (errn < err) | ~active | ~np.isfinite(err)
                ok &= np.isfinite(errn)
                if np.all(ok):
                    break
                step = np.where(ok, step, 0.5 * step)
            take = active & np.isfinite(errn)
            if table is not None:
                J = tuple(np.where(take, jn, jo) for jn, jo in zip(Jn, (a, b, c, d)))
            HF = np.where(take, Hn, HF)
            VF = np.where(take, Vn, VF)
            rX = np.where(take, rXn, rX)
            rZ = np.where(take, rZn, rZ)
            err = np.where(take, errn, err)
    return HF, VF, err, it


def _fallback(XF, ZF, L, EA, w, CB, h_A, HF, VF, tol, table=None):
    """Per-configuration scipy solve, in log-scaled variables, for what Newton did not converge."""
    from scipy.optimize import root

    def fun(p):
        h, v = np.exp(p)
        x, z = closure(np.array(h), np.array(v), L, EA, w, CB, h_A, table)
        return [float(x - XF), float(z - ZF)]

    best = (HF, VF, np.inf)
    for h0, v0 in ((HF, VF), *(_initial_guess(np.array(XF), np.array(ZF), L, EA, w),)):
        with np.errstate(all="ignore"):
            sol = root(fun, np.log([max(float(h0), 1e-12), max(float(v0), 1e-12)]), method="hybr", tol=1e-14)
            h, v = np.exp(sol.x)
            r = np.abs(fun(sol.x)).sum()
        if np.isfinite(r) and r < best[2]:
            best = (h, v, r)
        if r <= tol:
            break
    return best


def solve(XF, ZF, L, EA, w, *, CB=0.0, h_A=0.0, tol: float = 1e-9, max_iter: int = 60,
          guess=None, table=None) -> CatenarySolution:
    """Solve the elastic catenary for arrays of line configurations at once.

    Parameters
    ----------
    XF : array_like
        Horizontal distance lower end -> fairlead [m], >= 0.
    ZF : array_like
        Height of the fairlead above the lower end [m], >= 0.
    L : array_like
        Unstretched line length [m], > 0.
    EA : array_like
        Axial stiffness [N], > 0 (``np.inf`` for an inextensible line).
    w : array_like
        Submerged weight per unit length [N/m], >= 0 (0: weightless bar).
    CB : array_like, optional
        Seabed friction coefficient [-], >= 0 (applied only where ``h_A = 0``, module docstring).
    h_A : array_like, optional
        Height of the lower end above the seabed [m], >= 0 (default 0: an anchor on the seabed).
        The seabed lies ``h_A + ZF`` below the fairlead.
    tol : float, optional
        Closure tolerance [m]: the spans reproduce ``XF`` and ``ZF`` to within ``tol``.
    max_iter : int, optional
        Newton iteration limit before the per-configuration fallback.
    guess : (HF, VF), optional
        Starting tensions [N] for the Newton iteration (arrays of the input shape, e.g. a nearby
        solution); entries that are not positive and finite use the usual start. The answer does
        not depend on it beyond the tolerance.
    table : StrainTable or rows, optional
        A nonlinear axial law, a tension-strain table (:class:`tapm_opt.strain_table.StrainTable`
        or rows ``[[strain, tension], ...]``), for every configuration: the elastic stretch is
        the exact integral of its strain along the line (module docstring, "Nonlinear axial
        stiffness"), and ``EA`` is not read but for its check (give the table's secant). Without
        it (default) the line has the constant ``EA``.

    Returns
    -------
    CatenarySolution
        Arrays of the broadcast input shape.

    Raises
    ------
    CatenaryError
        On invalid input (negative, non-finite), an inextensible line shorter than the
        anchor–fairlead distance, or a configuration that does not converge; the message names
        the input and its value. No NaN is ever returned.
    """
    tab = as_table(table)
    XF, ZF, L, EA, w, CB, hA = (np.asarray(a, dtype=float) for a in (XF, ZF, L, EA, w, CB, h_A))
    _check_inputs(XF=XF, ZF=ZF, L=L, EA=EA, w=w, CB=CB, h_A=hA)
    shape = np.broadcast_shapes(XF.shape, ZF.shape, L.shape, EA.shape, w.shape, CB.shape, hA.shape)
    XF, ZF, L, EA, w, CB, hA = (np.broadcast_to(a, shape).ravel() for a in (XF, ZF, L, EA, w, CB, hA))
    n = XF.size
    out = {k: np.zeros(n) for k in ("HF", "VF", "HA", "VA", "LBot", "dHX", "dHZ", "dVX", "dVZ")}
    regime = np.full(n, -1, dtype=np.int8)

    d = np.hypot(XF, ZF)
    inext_short = np.isinf(EA) & (d > L * (1 + 1e-12)) & (tab is None)
    if np.any(inext_short):
        i = int(np.argmax(inext_short))
        raise CatenaryError(
            f"inextensible line (EA = inf) of length L = {L[i]:g} m cannot span the anchor-fairlead "
            f"distance {d[i]:g} m (XF = {XF[i]:g} m, ZF = {ZF[i]:g} m) at index {i}")

    with np.errstate(divide="ignore", invalid="ignore"):
        # weightless straight bar
        m = w == 0
        if np.any(m):
            if tab is None:
                T = EA[m] * np.maximum(d[m] / L[m] - 1.0, 0.0)
            else:
                T = tab.tension_at(np.maximum(d[m] / L[m] - 1.0, 0.0))
            dd = np.where(d[m] > 0, d[m], 1.0)
            out["HF"][m] = T * XF[m] / dd
            out["VF"][m] = T * ZF[m] / dd
            out["HA"][m], out["VA"][m] = out["HF"][m], out["VF"][m]
            taut = d[m] > L[m]
            if tab is None:
                k0 = np.where(taut, EA[m] * (1.0 / L[m] - 1.0 / dd), 0.0)
                k1 = np.where(taut, EA[m] / dd**3, 0.0)
            else:  # F = T(d/L - 1) (X, Z)/d: k0 = T/d, k1 = (T'/L - T/d)/d^2
                k0 = np.where(taut, T / dd, 0.0)
                k1 = np.where(taut, (tab.tangent_at(d[m] / L[m] - 1.0) / L[m] - T / dd) / dd**2, 0.0)
            out["dHX"][m] = k0 + k1 * XF[m] ** 2
            out["dVZ"][m] = k0 + k1 * ZF[m] ** 2
            out["dHZ"][m] = out["dVX"][m] = k1 * XF[m] * ZF[m]
            regime[m] = WEIGHTLESS
        heavy = ~m
        # slack: hanging vertically from the fairlead (L2) and from an elevated lower end (L1)
        L1 = hanging_length(hA, w, EA, tab)
        L2 = hanging_length(ZF + hA, w, EA, tab)
        m = heavy & (L1 + L2 <= L) & (L - L1 - L2 >= XF)
        if np.any(m):
            out["VF"][m] = w[m] * L2[m]
            out["VA"][m] = -w[m] * L1[m]
            out["LBot"][m] = L[m] - L1[m] - L2[m]
            if tab is None:
                out["dVZ"][m] = w[m] / (1.0 + w[m] * L2[m] / EA[m])
            else:
                out["dVZ"][m] = w[m] / (1.0 + tab.strain_at(w[m] * L2[m]))
            regime[m] = SLACK
        # vertical, fully suspended: taut (VA >= 0) or hanging doubled from an elevated lower end
        m = heavy & (regime < 0) & (XF <= 1e-12 * L)
        if np.any(m) and tab is not None:
            _vertical_table(m, out, regime, ZF, L, w, tab)
        elif np.any(m):
            kw = 1.0 + 0.5 * w[m] * L[m] / EA[m]
            taut = ZF[m] >= L[m] * kw
            VF = np.where(taut, EA[m] * (ZF[m] - L[m]) / L[m] + 0.5 * w[m] * L[m],
                          0.5 * w[m] * (L[m] + ZF[m] / kw))
            VF = np.where(np.isfinite(VF), VF, w[m] * L[m])
            out["VF"][m] = VF
            out["VA"][m] = VF - w[m] * L[m]
            ratio = np.log(VF / np.maximum(VF - w[m] * L[m], 1e-300))
            # the doubled line swings sideways without restoring force at XF = 0 (the horizontal
            # span grows like HF log(1/HF))
            out["dHX"][m] = np.where(taut, 1.0 / (ratio / w[m] + L[m] / EA[m]), 0.0)
            out["dVZ"][m] = np.where(taut, EA[m] / L[m], 0.5 * w[m] / kw)
            regime[m] = VERTICAL
        # both ends on the seabed, line stretched
        m = heavy & (regime < 0) & (ZF <= 0) & (hA <= 0)
        if np.any(m) and tab is not None:
            _seabed_table(m, out, regime, XF, L, w, CB, tab)
        elif np.any(m):
            cbw = CB[m] * w[m]
            stretch = XF[m] - L[m]
            with np.errstate(divide="ignore", invalid="ignore"):
                H_part = np.sqrt(2.0 * EA[m] * cbw * stretch)
                part = (cbw > 0) & (H_part < cbw * L[m])
                H_full = (stretch + cbw * L[m] ** 2 / (2.0 * EA[m])) * EA[m] / L[m]
            H = np.where(part, H_part, H_full)
            out["HF"][m] = H
            out["HA"][m] = np.where(part, 0.0, np.maximum(H - cbw * L[m], 0.0))
            out["LBot"][m] = L[m]
            out["dHX"][m] = np.where(part, EA[m] * cbw / np.where(part, H, 1.0), EA[m] / L[m])
            out["dVZ"][m] = np.inf
            regime[m] = SEABED

    iterations = 0
    g = np.flatnonzero(regime < 0)
    if g.size:
        args = (XF[g], ZF[g], L[g], EA[g], w[g], CB[g], hA[g])
        gs = None
        if guess is not None:
            gs = tuple(np.broadcast_to(np.asarray(a, dtype=float), shape).ravel()[g] for a in guess)
        HF, VF, err, iterations = _newton(*args, tol=tol, max_iter=max_iter, guess=gs, table=tab)
        bad = np.flatnonzero(~(err <= tol) | ~np.isfinite(HF) | ~np.isfinite(VF))
        for j in bad:
            h, v, r = _fallback(*(a[j] for a in args), HF[j], VF[j], tol, tab)
            if not r <= tol:
                i = int(g[j])
                raise CatenaryError(
                    "catenary did not converge for XF = {:g} m, ZF = {:g} m, L = {:g} m, EA = {:g} N, "
                    "w = {:g} N/m, CB = {:g}, h_A = {:g} m (index {}); closure error {:.3g} m".format(
                        XF[i], ZF[i], L[i], EA[i], w[i], CB[i], hA[i], i, r))
            HF[j], VF[j] = h, v
        Lg, wg, EAg, CBg, hg = L[g], w[g], EA[g], CB[g], hA[g]
        if not _elevated(hg):
            V1 = np.zeros_like(HF)
        else:
            V1 = _seabed_reach(HF, hg, EAg, wg) if tab is None else _table_reach(HF, hg, wg, tab)
        susp = VF + V1 >= wg * Lg
        LB = np.where(susp, 0.0, Lg - (VF + V1) / wg)
        cbw = np.where(hg > 0, 0.0, CBg * wg)
        out["HF"][g] = HF
        out["VF"][g] = VF
        out["VA"][g] = np.where(susp, VF - wg * Lg, 0.0 - V1)  # 0.0 - 0.0: no negative zero
        out["HA"][g] = np.where(susp, HF, np.maximum(HF - cbw * LB, 0.0))
        out["LBot"][g] = LB
        a, b, c, dd = _closure_jacobian(HF, VF, Lg, EAg, wg, CBg, hg, tab)
        det = a * dd - b * c
        out["dHX"][g], out["dHZ"][g] = dd / det, -b / det
        out["dVX"][g], out["dVZ"][g] = -c / det, a / det
        regime[g] = np.where(susp, SUSPENDED, TOUCHDOWN)

    HF, VF, HA, VA = out["HF"], out["VF"], out["HA"], out["VA"]
    res = {
        "HF": HF, "VF": VF, "HA": HA, "VA": VA,
        "TF": np.hypot(HF, VF), "TA": np.hypot(HA, VA), "LBot": out["LBot"],
        "dHF_dXF": out["dHX"], "dHF_dZF": out["dHZ"], "dVF_dXF": out["dVX"], "dVF_dZF": out["dVZ"],
    }
    for k, v in res.items():
        if k != "dVF_dZF" and not np.all(np.isfinite(v)):  # pragma: no cover - guarded above
            i = int(np.argmax(~np.isfinite(v)))
            raise CatenaryError(f"non-finite {k} for XF = {XF[i]:g} m, ZF = {ZF[i]:g} m, L = {L[i]:g} m")
    shaped = {k: v.reshape(shape) for k, v in res.items()}
    return CatenarySolution(regime=regime.reshape(shape), iterations=int(iterations), **shaped)


def _vertical_table(m, out, regime, ZF, L, w, tab) -> None:
    """The vertical regime (``XF = 0``) of a line of a table, into ``out`` at the mask ``m``: taut,
    ``ZF = L + L mean_strain(VF, w L)`` (its tension falls linearly by ``w L`` to A), or hanging
    doubled from an elevated lower end over ``L1`` down and ``L2 = L - L1`` up,
    ``ZF = L2 + E(w L2)/w - L1 - E(w L1)/w``."""
    z, Lm, wm = ZF[m], L[m], w[m]
    wL = wm * Lm
    taut = z >= Lm * (1.0 + tab.mean_strain(wL, wL))
    VF = tab.solve_mean_strain(np.where(taut, (z - Lm) / Lm, 0.0), wL)
    # doubled: R(L2) = ZF, R increasing on [L/2, L] with R' = 2 + eps(w L2) + eps(w L1)
    lo, hi = 0.5 * Lm, Lm.copy()

    def R(L2):
        L1 = Lm - L2
        with np.errstate(invalid="ignore", divide="ignore"):
            return (L2 - L1 + L2 * np.where(L2 > 0, tab.mean_strain(wm * L2, wm * L2), 0.0)
                    - L1 * np.where(L1 > 0, tab.mean_strain(wm * L1, wm * L1), 0.0))

    L2 = 0.5 * (lo + hi)
    for _ in range(200):
        f = R(L2) - z
        lo, hi = np.where(f < 0, L2, lo), np.where(f > 0, L2, hi)
        dR = 2.0 + tab.strain_at(wm * L2) + tab.strain_at(wm * (Lm - L2))
        L2n = L2 - f / dR
        L2n = np.where((L2n <= lo) | (L2n >= hi) | ~np.isfinite(L2n), 0.5 * (lo + hi), L2n)
        done = (np.abs(L2n - L2) <= 4e-16 * Lm) | (f == 0) | taut
        L2 = np.where(f == 0, L2, L2n)
        if np.all(done):
            break
    VF = np.where(taut, VF, wm * L2)
    out["VF"][m] = VF
    out["VA"][m] = VF - wL
    VA = np.maximum(VF - wL, 0.0)
    run = _run(0.0, VA, Lm, wm, tab)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.log(VF / np.maximum(VA, 1e-300))
        dHX = 1.0 / (ratio / wm + run.QX)
    out["dHX"][m] = np.where(taut & np.isfinite(dHX), dHX, 0.0)
    out["dVZ"][m] = np.where(taut, 1.0 / (Lm * tab.mean_compliance(VA, VF)),
                             wm / (2.0 + tab.strain_at(wm * L2) + tab.strain_at(wm * (Lm - L2))))
    regime[m] = VERTICAL


def _seabed_table(m, out, regime, XF, L, w, CB, tab) -> None:
    """Both ends on the seabed, the line stretched by ``XF - L``, for a line of a table, into
    ``out`` at the mask ``m``: friction carries the tension to 0 over part of the line
    (``E(H) = CB w (XF - L)``, while ``H < CB w L``) or it falls by ``CB w L`` along all of it
    (``XF - L = L mean_strain(H, CB w L)``)."""
    cbw = CB[m] * w[m]
    Lm = L[m]
    stretch = XF[m] - Lm
    H_part = tab.rise(0.0, cbw * stretch, alpha=0.0)
    part = (cbw > 0) & (H_part < cbw * Lm)
    H_full = tab.solve_mean_strain(stretch / Lm, cbw * Lm)
    H = np.where(part, H_part, H_full)
    out["HF"][m] = H
    out["HA"][m] = np.where(part, 0.0, np.maximum(H - cbw * Lm, 0.0))
    out["LBot"][m] = Lm
    with np.errstate(divide="ignore", invalid="ignore"):
        out["dHX"][m] = np.where(part, cbw / tab.strain_at(H), 1.0 / (Lm * tab.mean_compliance(H - cbw * Lm, H)))
    out["dVZ"][m] = np.inf
    regime[m] = SEABED


def _hanging_piece(H, V0, sig, w, EA):
    """Spans (dx, dz) [m] and tension [N] of a suspended piece of line with horizontal tension H
    that starts with vertical tension V0 (either sign) and runs over an unstretched length sig
    (arrays), in forms without cancellation as in :func:`closure`; H = 0 gives a vertical piece."""
    H, V0, w = np.float64(H), np.float64(V0), np.float64(w)
    V = V0 + w * sig
    hV, h0 = np.hypot(H, V), np.hypot(H, V0)
    same = V * V0 >= 0
    den = np.where(same, V * h0 + V0 * hV, 1.0)  # 0 only where V = V0 = 0, i.e. sig = 0
    with np.errstate(invalid="ignore", divide="ignore", over="ignore", under="ignore"):
        d = np.where(den != 0, den, 1.0)
        a = w * sig * (V + V0)
        # a weight so small that w sig (V + V0) ~ w^2 sig^2 underflows (or goes subnormal): the same
        # quotient ordered (V + V0) / den * w sig, whose factors stay normal
        arg = np.where(np.abs(a) < _TINY, (V + V0) / d * (w * sig), a / d)
        dS = np.where(same, np.where(den != 0, np.arcsinh(arg), 0.0),
                      np.arcsinh(V / H) - np.arcsinh(V0 / H))
        dx = np.where((H > 0) & (dS != 0), H / w * dS, 0.0) + H * sig / EA  # no 0 x inf for a tiny w
        dz = np.where(hV + h0 > 0, sig * (V + V0) / np.where(hV + h0 > 0, hV + h0, 1.0), 0.0)
    dz = dz + (V0 * sig + 0.5 * w * sig**2) / EA
    return dx, dz, hV


def line_profile(XF: float, ZF: float, L: float, EA: float, w: float, *, CB: float = 0.0, h_A: float = 0.0,
                 n: int = 101, table=None):
    """Shape and tension along one line, from the lower end A (s = 0) to the fairlead (s = L).

    Parameters
    ----------
    XF, ZF, L, EA, w, CB, h_A, table : float
        As in :func:`solve` (scalars; ``table`` a tension-strain table or None).
    n : int
        Number of points along the unstretched arc length.

    Returns
    -------
    dict
        ``s`` unstretched arc length [m], ``x`` horizontal distance from A [m], ``z`` height above A
        [m] (the seabed is at ``z = -h_A``), ``T`` tension [N], each of shape (n,), plus the scalar
        solution.

    A buoyant line (``w < 0``, a buoyant section of a composite line,
    :mod:`tapm_opt.models.composite`) is the same catenary upside down: the line of weight ``|w|``
    hanging from its upper end (the fairlead, here its lower end) to A, ``ZF`` below it, read back
    from A; it arches up from its ends and never reaches the seabed (``h_A`` and ``CB`` are not
    read), nor is a sea surface above it known here (:func:`tapm_opt.models.composite.solve` keeps
    a buoyant section below it). ``solution`` is then that flipped catenary's.
    """
    if w < 0:
        # the flipped line: its lower end is the fairlead, ZF above A in the flipped frame; no
        # seabed (the surface) within its reach, even hanging doubled (the sag is at most 10 L)
        pr = line_profile(XF, ZF, L, EA, -w, CB=0.0, h_A=10.0 * L + ZF, n=n, table=table)
        return {"s": L - pr["s"][::-1], "x": XF - pr["x"][::-1], "z": ZF - pr["z"][::-1], "T": pr["T"][::-1],
                "solution": pr["solution"]}
    if table is not None:
        return _line_profile_table(XF, ZF, L, EA, w, CB, h_A, n, as_table(table))
    sol = solve(XF, ZF, L, EA, w, CB=CB, h_A=h_A)
    HF = float(sol.HF)
    reg = int(sol.regime)
    s = np.linspace(0.0, L, n)
    if reg == WEIGHTLESS:
        frac = s / L
        x, z = frac * XF, frac * ZF
        T = np.full(n, float(sol.TF))
    elif reg == SLACK:
        # hanging from A over L1, untensioned on the seabed over LB, hanging from the fairlead over L2
        L1 = float(hanging_length(h_A, w, EA))
        L2 = float(hanging_length(ZF + h_A, w, EA))  # not L - LBot: no cancellation
        LB = float(sol.LBot)
        s1 = np.minimum(s, L1)
        z1 = -(s1 + w * (L1 * s1 - 0.5 * s1 * s1) / EA)
        x = np.clip(XF * (s - L1) / max(LB, 1e-300), 0.0, XF)
        sv = np.clip(L2 - (L - s), 0.0, L2)  # hanging arc length, exact at the fairlead
        z = np.where(s <= L1, z1, -h_A + sv + w * sv * sv / (2 * EA))
        T = np.where(s <= L1, w * (L1 - s1), w * sv)
    elif reg == VERTICAL and float(sol.VA) < 0:
        # hanging doubled from an elevated A: down over L1, up over L2 (lengths without w/w)
        L2 = 0.5 * (L + ZF / (1.0 + 0.5 * w * L / EA))
        L1 = L - L2
        x = np.zeros(n)
        s1, s2 = np.minimum(s, L1), np.maximum(s - L1, 0.0)
        down = s1 + w * (L1 * s1 - 0.5 * s1 * s1) / EA  # below A, at the fold L1 + w L1^2/(2 EA)
        z = -down + s2 + w * s2 * s2 / (2.0 * EA)
        T = w * np.where(s <= L1, L1 - s1, s2)
    else:  # touchdown, suspended, taut vertical; seabed (LB = L) through the same friction integral
        LB = float(sol.LBot)
        VA = float(sol.VA)
        # touching down from an elevated A: A's part over L1 = V1/w down to the seabed
        L1 = -VA / w if (reg == TOUCHDOWN and h_A > 0) else 0.0
        V2 = 0.0 if reg in (TOUCHDOWN, SEABED) else VA  # vertical tension where the last part starts
        s1 = np.minimum(s, L1)
        x1, z1, T1 = _hanging_piece(HF, VA if L1 > 0 else 0.0, s1, w, EA)
        if L1 > 0:
            z1 = np.where(s >= L1, -h_A, z1)  # exact where it meets the seabed
        cbw = CB * w if h_A <= 0 else 0.0
        s0 = max(LB - HF / cbw, 0.0) if cbw > 0 else 0.0
        sb = np.clip(s - L1, 0.0, LB)
        tens_int = np.where(sb > s0, HF * (sb - s0) - cbw * (LB * (sb - s0) - 0.5 * (sb**2 - s0**2)), 0.0)
        x_bed = sb + tens_int / EA
        sig = np.maximum(s - L1 - LB, 0.0)
        x2, z2, T2 = _hanging_piece(HF, V2, sig, w, EA)
        x = x1 + x_bed + x2
        z = z1 + z2
        T_bed = np.maximum(HF - cbw * (LB - sb), 0.0)
        T = np.where(s < L1, T1, np.where((s <= L1 + LB) & (LB > 0), T_bed, T2))
    return {"s": s, "x": x, "z": z, "T": T, "solution": sol}


def _line_profile_table(XF, ZF, L, EA, w, CB, h_A, n, tab):
    """:func:`line_profile` of a line of a tension-strain table: the inextensible shape of each
    part plus its exact elastic stretch up to each point (:func:`_run`, :func:`_bed`); a part
    hanging vertically over ``sv`` from where its tension is 0 rises ``sv + E(w sv)/w``."""
    sol = solve(XF, ZF, L, EA, w, CB=CB, h_A=h_A, table=tab)
    HF = float(sol.HF)
    reg = int(sol.regime)
    s = np.linspace(0.0, L, n)

    def hang(sv):  # height risen over sv above a zero-tension end, hanging vertically
        return sv + np.where(sv > 0, sv * tab.mean_strain(w * sv, w * sv), 0.0)

    if reg == WEIGHTLESS:
        frac = s / L
        x, z = frac * XF, frac * ZF
        T = np.full(n, float(sol.TF))
    elif reg == SLACK or (reg == VERTICAL and float(sol.VA) < 0):
        if reg == SLACK:
            L1 = float(hanging_length(h_A, w, EA, tab))
            L2 = float(hanging_length(ZF + h_A, w, EA, tab))
            LB = float(sol.LBot)
        else:  # hanging doubled from an elevated A: down over L1, up over L2
            L2 = float(sol.VF) / w
            L1, LB = L - L2, 0.0
        s1 = np.minimum(s, L1)
        z1 = -(hang(L1) - hang(L1 - s1))  # below A
        if reg == SLACK:
            x = np.clip(XF * (s - L1) / max(LB, 1e-300), 0.0, XF)
            sv = np.clip(L2 - (L - s), 0.0, L2)
            z = np.where(s <= L1, z1, -h_A + hang(sv))
            T = np.where(s <= L1, w * (L1 - s1), w * sv)
        else:
            x = np.zeros(n)
            s2 = np.maximum(s - L1, 0.0)
            z = np.where(s <= L1, z1, -hang(L1) + hang(s2))
            T = w * np.where(s <= L1, L1 - s1, s2)
    else:  # touchdown, suspended, taut vertical, seabed
        LB = float(sol.LBot)
        VA = float(sol.VA)
        L1 = -VA / w if (reg == TOUCHDOWN and h_A > 0) else 0.0
        V2 = 0.0 if reg in (TOUCHDOWN, SEABED) else VA

        def piece(V0, sig):
            dx, dz, Tp = _hanging_piece(HF, V0, sig, w, np.inf)
            if w > 0 and np.any(sig > 0):
                r = _run(HF, V0, sig, w, tab)
                dx = dx + (HF * r.QX if HF > 0 else 0.0)
                dz = dz + r.QZ
            return dx, dz, Tp

        s1 = np.minimum(s, L1)
        x1, z1, T1 = piece(VA if L1 > 0 else 0.0, s1)
        if L1 > 0:
            z1 = np.where(s >= L1, -h_A, z1)
        cbw = CB * w if h_A <= 0 else 0.0
        sb = np.clip(s - L1, 0.0, LB)
        B, _ = _bed(HF, LB, cbw, tab, 0.0, sb)
        x_bed = sb + B
        sig = np.maximum(s - L1 - LB, 0.0)
        x2, z2, T2 = piece(V2, sig)
        x = x1 + x_bed + x2
        z = z1 + z2
        T_bed = np.maximum(HF - cbw * (LB - sb), 0.0)
        T = np.where(s < L1, T1, np.where((s <= L1 + LB) & (LB > 0), T_bed, T2))
    return {"s": s, "x": x, "z": z, "T": T, "solution": sol}


# ------------------------------------------------------------------------------------------
# symbolic path (CasADi)
# ------------------------------------------------------------------------------------------

_SYMBOLIC_CACHE: dict[Any, ca.Function] = {}


def symbolic_function(*, abstol: float = 1e-10, max_iter: int = 50) -> ca.Function:
    """CasADi Function ``catenary(XF, ZF, L, EA, w, CB, h_A, HF0, VF0) -> (HF, VF, closure_error)``.

    The fairlead tensions are the root of the same :func:`closure` residual as the numeric
    solver, found by a CasADi ``rootfinder`` (Newton with line search on log HF, log VF, which
    keeps both positive), so the Function can be embedded in an NLP with exact first and second
    derivatives (implicit function theorem). ``h_A`` is the height of the lower end above the
    seabed [m] (0: an anchor on the seabed). ``HF0, VF0`` is the initial guess [N] — e.g. the
    numeric solution at a nearby configuration (:func:`solve`).

    ``closure_error`` [m] is the largest span error of the returned tensions, recomputed from the
    closure equations (``inf`` if they are not finite). CasADi's rootfinder does not always report a
    failed solve, so **a caller must check it** (e.g. ``closure_error < 1e-6``); a poor guess can
    leave Newton far from the root.

    Every regime of :func:`solve` is covered: the regular ones (touching down and fully
    suspended) by the root, the degenerate ones by the same closed forms as :func:`solve`
    (module docstring), chosen from the inputs and evaluated instead of the root (a short-circuit
    switch, so the root is not attempted where it does not exist): weightless (``w = 0``), slack
    (``L - L1 - L2 >= XF``), vertical (``XF = 0``) and both ends on the seabed (``ZF = 0``,
    ``h_A = 0``). Their ``closure_error`` is 0; their derivatives are those of the closed forms.

    Inputs and outputs are scalars; use ``Function.map`` for several lines. At ``h_A = 0`` the
    derivative with respect to ``h_A`` is that of the anchored branch (0), not the one-sided limit
    from above (which is unbounded: the part of the line that runs down to the seabed grows like
    ``sqrt(h_A)``).
    """
    key = (abstol, max_iter)
    if key in _SYMBOLIC_CACHE:
        return _SYMBOLIC_CACHE[key]
    z = ca.SX.sym("z", 2)
    p = ca.SX.sym("p", 7)
    XF, ZF, L, EA, w, CB, h_A = (p[i] for i in range(7))
    X, Z = closure(ca.exp(z[0]), ca.exp(z[1]), L, EA, w, CB, h_A)
    g = ca.Function("catenary_residual", [z, p], [ca.vertcat(X - XF, Z - ZF)])
    rf = ca.rootfinder("catenary_rf", "newton", g,
                       {"abstol": abstol, "max_iter": max_iter, "line_search": True, "error_on_fail": False})
    names = ["XF", "ZF", "L", "EA", "w", "CB", "h_A", "HF0", "VF0"]
    syms = [ca.MX.sym(nm) for nm in names]
    sol = rf(ca.log(ca.vertcat(syms[7], syms[8])), ca.vertcat(*syms[:7]))
    HF, VF = ca.exp(sol[0]), ca.exp(sol[1])
    Xc, Zc = closure(HF, VF, *syms[2:7])
    err = ca.fmax(ca.fabs(Xc - syms[0]), ca.fabs(Zc - syms[1]))
    err = ca.if_else(err <= 1e300, err, ca.inf)  # NaN compares false: reported as inf
    root = ca.Function("catenary_root", syms, [ca.vertcat(HF, VF, err)])
    degenerate = _symbolic_degenerate()
    XF, ZF, L, EA, w, CB, h_A = syms[:7]
    code, closed = degenerate(XF, ZF, L, EA, w, CB, h_A)
    out = ca.if_else(code > 0, closed, root(*syms), True)
    fn = ca.Function("catenary", syms, [out[0], out[1], out[2]], names, ["HF", "VF", "closure_error"])
    _SYMBOLIC_CACHE[key] = fn
    return fn


def _symbolic_degenerate() -> ca.Function:
    """CasADi Function ``(XF, ZF, L, EA, w, CB, h_A) -> (code, [HF, VF, 0])``: ``code`` > 0 where
    :func:`solve` uses a closed form (1 weightless, 2 slack, 3 vertical, 4 both ends on the
    seabed; 0: the regular root), and that closed form's tensions (the same formulas as
    :func:`solve`; finite everywhere so that a switch on ``code`` keeps derivatives clean)."""
    if "degenerate" in _SYMBOLIC_CACHE:
        return _SYMBOLIC_CACHE["degenerate"]
    XF, ZF, L, EA, w, CB, h_A = (ca.SX.sym(n) for n in ("XF", "ZF", "L", "EA", "w", "CB", "h_A"))
    d = ca.sqrt(XF * XF + ZF * ZF)
    dd = ca.if_else(d > 0, d, 1.0)
    # weightless straight bar
    T0 = EA * ca.fmax(d / L - 1.0, 0.0)
    H_wl, V_wl = T0 * XF / dd, T0 * ZF / dd

    def hang(z):  # hanging_length, written for SX
        return 2.0 * z / (1.0 + ca.sqrt(1.0 + 2.0 * w * z / EA))

    L1, L2 = hang(h_A), hang(ZF + h_A)
    slack = ca.logic_and(L1 + L2 <= L, L - L1 - L2 >= XF)
    # vertical: taut, or hanging doubled from an elevated lower end
    kw = 1.0 + 0.5 * w * L / EA
    taut = ZF >= L * kw
    V_vert = ca.if_else(taut, EA * (ZF - L) / L + 0.5 * w * L, 0.5 * w * (L + ZF / kw))
    # both ends on the seabed, stretched: friction over part or all of the line
    cbw = CB * w
    stretch = ca.fmax(XF - L, 0.0)
    H_part = ca.sqrt(2.0 * EA * ca.fmax(cbw, 1e-300) * stretch)
    part = ca.logic_and(cbw > 0, H_part < cbw * L)
    H_full = (stretch + cbw * L * L / (2.0 * EA)) * EA / L
    H_bed = ca.if_else(part, H_part, H_full)
    wz = w == 0
    code = ca.if_else(wz, 1, ca.if_else(slack, 2, ca.if_else(XF <= 1e-12 * L, 3,
                      ca.if_else(ca.logic_and(ZF <= 0, h_A <= 0), 4, 0))))
    H = ca.if_else(wz, H_wl, ca.if_else(slack, 0.0, ca.if_else(code == 3, 0.0, H_bed)))
    V = ca.if_else(wz, V_wl, ca.if_else(slack, w * L2, ca.if_else(code == 3, V_vert, 0.0)))
    fn = ca.Function("catenary_degenerate", [XF, ZF, L, EA, w, CB, h_A], [code, ca.vertcat(H, V, 0.0)])
    _SYMBOLIC_CACHE["degenerate"] = fn
    return fn
