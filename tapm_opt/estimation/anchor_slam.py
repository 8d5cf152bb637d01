"""Tension-based positioning and anchor estimation: EKF-SLAM of a moored vessel and its anchors.

Seed *tension-based-anchor-slam* (Ren & Skjetne 2016), §3–§5, eq. (8)–(16); method, conventions
and the §6 reproduction in ``docs/anchor_slam.md``.

Frames and units: NED {E} (x north, y east, z down), SI throughout (m, N, rad, s); degrees only in
the sea-state tables a caller reads.

Pieces
------
* :class:`TensionRangeMap` -- the tension-to-range map of the line model. ``f_i(X)`` (eq. 8–9) is
  the fairlead tension magnitude ``TF`` of line i's elastic catenary
  (:func:`tapm_opt.models.catenary.solve`) at horizontal anchor-fairlead distance ``X`` with the
  fairlead at its design depth (the seed's ``z = 0``). It is strictly increasing on its domain
  ``[X_lo, X_hi]`` (from where the line stops lying slack to where ``TF`` reaches the line's MBS),
  so ``X = f_i^-1(T)`` is found by Newton's method on the catenary with the exact slope
  ``k_i = dTF/dX`` (eq. 12's generalised stiffness). Eq. (10): a measured tension is corrected for a
  loading change ``dW`` [N] (the sinkage ``dW / (A_w rho_w g)`` [m]) with ``k_T = dTF/dz`` (fairlead
  depth, z down). Eq. (13): the range from anchor i to the centre of turret (COT) is
  ``d_i = f_i^-1(T_i) + r_i``, ``r_i`` the distance of fairlead i from the COT (the COT lies on the
  extension of the anchor -> fairlead line; exact when the fairlead points at its anchor, an error
  ``r_i (1 - cos dpsi_i)`` otherwise). Eq. (12): range variance
  ``sigma_d^2 = (sigma_Tn^2 + sigma_Td^2) / k^2 + sigma_GPS^2``.
* :class:`VirtualVessel`, :class:`VirtualVesselNetwork`, :func:`generate_network` -- the sensor
  network of §4: the vessel is run on the plant (closed loop, heading-only PID, §6.1) in random
  environments until its LF position settles; then the observer's LF position and the measured
  fairlead tensions are stored over a record. Replayed, each record is a "virtual vessel" ``TP_j``:
  a landmark at a known position ``p_j^t`` with ranges ``d_ij`` to every anchor. The network also
  stores the record of the live vessel (the real-time vessel whose position is to be found).
* :class:`AnchorSLAM` -- the EKF of §5 (Table 1; eq. 15–16) on the state
  ``x = (xi (6), eta (3), b (3), nu (3), p^a (2M), p^t (2N))`` with the measurement
  ``y = (psi + xi_6, p^t, d_I, d_IJ)``.
* :class:`TensionPositionEstimator` -- the same filter without virtual vessels, a redundant
  position reference from tensions (and the heading) when GNSS drops out (anchors known, or the
  SLAM's estimates with their covariance).
* :func:`run_anchor_slam` -- replays a network through the EKF and scores it against the truth.

Size: one module on purpose — the seed's §3–§5 are one estimator: the tension-to-range map, the
virtual-vessel records and the EKF-SLAM over them share the line model and its corrections.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import expm

from .._checks import finite
from .._io import atomic_write_bytes
from ..errors import TapmError
from ..models import catenary
from ..models.mooring import MooringModel, tension_depth_sensitivity

__all__ = ["AnchorSlamError", "TensionRangeMap", "VirtualVessel", "VirtualVesselNetwork", "AnchorSLAM",
           "SlamSettings", "SlamResult", "PositionFix", "TensionPositionEstimator", "run_anchor_slam", "survey_anchors",
           "table4_initial_anchors", "TABLE4_TRUE", "TABLE4_INITIAL", "NETWORK_FORMAT"]

#: Table 4 of the seed: anchor positions (x, y) [m] as printed (z = 1000 m down for all).
TABLE4_TRUE = np.array([[2030.0, 0.0], [1385.9, 1385.9], [0.0, 2030.0], [-1385.9, 1385.9],
                        [-2030.0, 0.0], [-1385.9, -1385.9], [0.0, -2030.0], [1385.9, -1385.9]])
#: Table 4 of the seed: the initial anchor estimates (x, y) [m].
TABLE4_INITIAL = np.array([[1931.5, 148.2], [1734.6, 1520.8], [-101.3, 2234.2], [-1601.6, 1568.6],
                           [-2176.4, -262.7], [-1621.5, -1298.5], [125.3, -2359.0], [1355.8, -1596.0]])

#: Format tag of a stored network (``VirtualVesselNetwork.save``).
NETWORK_FORMAT = "tapm-anchor-slam-network/1"


class AnchorSlamError(TapmError, ValueError):
    """Bad input to the tension-based position and anchor estimation (names the field and value)."""


def _finite(name: str, v: Any, *, lo: float | None = None, strict: bool = True, unit: str = "") -> float:
    return finite(name, v, lo=lo, strict=strict, unit=unit, error=AnchorSlamError)


def table4_initial_anchors(anchors: np.ndarray) -> np.ndarray:
    """Initial anchor guesses "perturbed as in Table 4": each anchor (M, 2) [m] moved by the seed's
    offset ``TABLE4_INITIAL - TABLE4_TRUE`` of the same index (needs M = 8). For ``ren8``, whose
    cardinal anchors sit on the corrected 1960 m circle, this keeps Table 4's errors (98-370 m)."""
    a = np.asarray(anchors, dtype=float)
    if a.shape != (8, 2):
        raise AnchorSlamError(f"anchors have shape {a.shape}: Table 4's perturbation is for 8 anchors (8, 2); "
                              "give the initial guesses instead")
    return a + (TABLE4_INITIAL - TABLE4_TRUE)


# ------------------------------------------------------------------------------------------
# tension -> range map (eq. 8-10, 12, 13)
# ------------------------------------------------------------------------------------------


class TensionRangeMap:
    """The inverse of each line's tension-distance characteristic, with eq. (10), (12), (13).

    Parameters
    ----------
    model : MooringModel
        The line model (``ZF``, ``L``, ``EA``, ``w``, ``CB``, ``h_A``, ``MBS`` per line; fairleads
        ``p_T`` in the turret frame).
    fairlead_radius : float or (M,), optional
        ``r_i`` of eq. (13) [m], default ``|p_T,i|`` (distance of fairlead i from the COT).
    x_max_tension : float
        Upper end of the domain as a fraction of each line's MBS [-] (default 1: ``TF = MBS``).

    Attributes
    ----------
    X_lo, X_hi : ndarray (M,)
        Domain of ``f_i`` [m]: ``f_i`` is strictly increasing on it.
    T_lo, T_hi : ndarray (M,)
        ``f_i(X_lo)``, ``f_i(X_hi)`` [N]: the tensions the map inverts.
    r : ndarray (M,)
        Fairlead radius of eq. (13) [m].
    """

    def __init__(self, model: MooringModel, *, fairlead_radius: Any = None, x_max_tension: float = 1.0):
        if not isinstance(model, MooringModel):
            raise AnchorSlamError(f"model = {model!r} must be a MooringModel")
        self.model = model
        self.line_ids = model.line_ids
        M = model.n_lines
        if fairlead_radius is None:
            r = np.hypot(model.p_T[:, 0], model.p_T[:, 1])
        else:
            r = np.broadcast_to(np.asarray(fairlead_radius, dtype=float), (M,)).copy()
            if not np.all(np.isfinite(r) & (r >= 0)):
                raise AnchorSlamError(f"fairlead_radius = {np.ravel(fairlead_radius).tolist()} m must be finite and >= 0")
        self.r = r
        frac = _finite("x_max_tension", x_max_tension, lo=0.0)
        self._par = (model.ZF, model.L, model.EA, model.w, model.CB, model.h_A)
        # domain: the slack limit (a line lying slack has TF independent of X) .. TF = frac * MBS
        L2 = catenary.hanging_length(model.ZF + model.h_A, model.w, model.EA)
        L1 = catenary.hanging_length(model.h_A, model.w, model.EA)
        X_slack = np.maximum(model.L - L1 - L2, 0.0)
        self.X_lo = X_slack + 1e-6 * model.L + 1e-3
        T_cap = frac * np.asarray(model.MBS, float)
        lo = self.X_lo.copy()
        # upper bound: the straight reach of the line stretched by T_cap everywhere (a section of a
        # tension-strain table by its own strain at T_cap, which its secant EA may understate)
        strain = T_cap / model.EA
        for i, c in enumerate(model.composite or ()):
            if c is not None and c.has_tables:
                strain[i] = max(float(t.strain_at(T_cap[i])) if t is not None else T_cap[i] / ea
                                for t, ea in zip(c.tables, c.EA))
        hi = np.sqrt(np.maximum((model.L * (1 + strain)) ** 2 - model.ZF ** 2, 0.0))
        if np.any(self._T(lo) >= T_cap):
            i = int(np.argmax(self._T(lo) >= T_cap))
            raise AnchorSlamError(f"line {self.line_ids[i]!r}: the tension at the slack limit already reaches "
                                  f"{frac:g} MBS; nothing to invert")
        for _ in range(80):  # bisection for TF(X_hi) = T_cap (vectorised)
            mid = 0.5 * (lo + hi)
            up = self._T(mid) < T_cap
            lo, hi = np.where(up, mid, lo), np.where(up, hi, mid)
        self.X_hi = lo
        self.T_lo = self._T(self.X_lo)
        self.T_hi = self._T(self.X_hi)
        grid = np.linspace(0.0, 1.0, 257)
        self._Xg = self.X_lo[:, None] + grid[None, :] * (self.X_hi - self.X_lo)[:, None]
        self._Tg = self._T(self._Xg)

    @classmethod
    def from_scenario(cls, scenario: Any, **kw: Any) -> "TensionRangeMap":
        """The map of a scenario's (intact) lines."""
        return cls(MooringModel.from_scenario(scenario), **kw)

    # -- forward map f_i and its slopes ----------------------------------------------------
    def _solve(self, X: np.ndarray, idx: np.ndarray | None = None) -> catenary.CatenarySolution:
        ZF, L, EA, w, CB, hA = self._par
        X = np.asarray(X, dtype=float)
        shape = X.shape
        if self.model.has_composite:  # through the model's one solver of each line
            li = (np.broadcast_to(np.arange(len(ZF)).reshape((-1,) + (1,) * (X.ndim - 1)), shape) if idx is None
                  else np.broadcast_to(idx, shape))
            return self.model.solve_at(np.maximum(X, 0.0), li)
        if idx is None:
            pars = [np.broadcast_to(p.reshape((-1,) + (1,) * (X.ndim - 1)) if X.ndim > 1 else p, shape)
                    for p in (ZF, L, EA, w, CB, hA)]
        else:
            pars = [np.broadcast_to(p[idx], shape) for p in (ZF, L, EA, w, CB, hA)]
        return catenary.solve(np.maximum(X, 0.0), pars[0], pars[1], pars[2], pars[3], CB=pars[4], h_A=pars[5])

    def _T(self, X: np.ndarray, idx: np.ndarray | None = None) -> np.ndarray:
        return self._solve(X, idx).TF

    def _line_index(self, T: np.ndarray, lines: Any) -> np.ndarray:
        M = len(self.line_ids)
        if lines is None:
            if T.shape[-1:] != (M,):
                raise AnchorSlamError(f"tensions have shape {T.shape}: the last axis must hold the {M} lines "
                                      f"{list(self.line_ids)} (or give lines=)")
            return np.broadcast_to(np.arange(M), T.shape)
        idx = np.asarray(lines, dtype=int)
        if np.any((idx < 0) | (idx >= M)):
            raise AnchorSlamError(f"lines = {np.ravel(lines).tolist()} must index the {M} lines (0..{M - 1})")
        return np.broadcast_to(idx, T.shape)

    def tension(self, X: Any, *, lines: Any = None) -> np.ndarray:
        """``f_i(X)`` (eq. 9): fairlead tension ``TF`` [N] at horizontal anchor-fairlead distance
        ``X`` [m]; last axis = lines (or ``lines`` gives the line index of each entry)."""
        return self._at(X, lines).TF

    def _at(self, X: Any, lines: Any) -> catenary.CatenarySolution:
        X = np.asarray(X, dtype=float)
        return self._solve(X, self._line_index(X, lines))

    def slope(self, X: Any, *, lines: Any = None) -> np.ndarray:
        """``k_i = dTF/dX`` [N/m] at ``X`` [m] (eq. 12's generalised stiffness), exact from the
        catenary's sensitivities: ``(HF dHF/dX + VF dVF/dX) / TF``."""
        s = self._at(X, lines)
        return s.dTF_dXF

    def heave_sensitivity(self, X: Any, *, lines: Any = None) -> np.ndarray:
        """``k_T = dTF/dz`` [N/m] (eq. 10) at ``X`` [m]: the tension change per metre the fairlead
        sinks (z down, so ``ZF`` shrinks): ``-(HF dHF/dZF + VF dVF/dZF) / TF``
        (:func:`~tapm_opt.models.mooring.tension_depth_sensitivity`)."""
        return tension_depth_sensitivity(self._at(X, lines))

    # -- inverse ---------------------------------------------------------------------------
    def distance(self, T: Any, *, lines: Any = None, clip: bool = False, tol: float = 1e-9) -> np.ndarray:
        """``X = f_i^-1(T)`` [m] (eq. 9, 11): the horizontal anchor-fairlead distance at which line i's
        catenary has fairlead tension ``T`` [N]. Newton on the catenary with the exact slope from
        a monotone table, to ``|dX| < tol`` [m].

        ``clip``: tensions outside ``[T_lo, T_hi]`` give the domain's end instead of an error.

        Raises
        ------
        AnchorSlamError
            A non-finite tension, or (without ``clip``) one outside the invertible range, naming the
            line and the value.
        """
        T = np.asarray(T, dtype=float)
        idx = self._line_index(T, lines)
        if not np.all(np.isfinite(T)):
            j = np.unravel_index(int(np.argmax(~np.isfinite(T))), T.shape)
            raise AnchorSlamError(f"tension of line {self.line_ids[int(idx[j])]!r} = {float(T[j])!r} N must be finite")
        lo, hi = self.T_lo[idx], self.T_hi[idx]
        out = (T < lo) | (T > hi)
        if np.any(out) and not clip:
            j = np.unravel_index(int(np.argmax(out)), T.shape)
            i = int(idx[j])
            raise AnchorSlamError(
                f"tension of line {self.line_ids[i]!r} = {T[j]:.6g} N is outside the range the line model "
                f"inverts, [{self.T_lo[i]:.6g}, {self.T_hi[i]:.6g}] N (slack limit .. MBS)")
        Tc = np.clip(T, lo, hi)
        flat_T, flat_i = Tc.ravel(), idx.ravel()
        X = np.empty_like(flat_T)
        for i in np.unique(flat_i):
            m = flat_i == i
            X[m] = np.interp(flat_T[m], self._Tg[i], self._Xg[i])
        Xlo, Xhi = self.X_lo[flat_i], self.X_hi[flat_i]
        for _ in range(30):
            s = self._solve(X, flat_i)
            k = s.dTF_dXF
            dX = (s.TF - flat_T) / k
            X = np.clip(X - dX, Xlo, Xhi)
            if np.max(np.abs(dX)) < tol:
                break
        return X.reshape(T.shape)

    def loading_correction(self, T: Any, delta_W: float, A_w: float, *, rho_w: float = 1025.0,
                           g: float = 9.81, lines: Any = None) -> np.ndarray:
        """Eq. (10) solved for the tension at the design draught: ``T^0 = T - k_T dW / (A_w rho_w g)``
        [N], with ``dW`` the loading change [N] (> 0 heavier: the vessel sinks ``dW / (A_w rho_w
        g)`` [m]), ``A_w`` the water-plane area [m^2] and ``k_T`` (:meth:`heave_sensitivity`) at the
        uncorrected distance."""
        T = np.asarray(T, dtype=float)
        dW = _finite("delta_W", delta_W, unit="N")
        if dW == 0.0:
            return T.copy()
        A = _finite("A_w", A_w, lo=0.0, unit="m^2")
        X = self.distance(T, lines=lines, clip=True)
        return T - self.heave_sensitivity(X, lines=lines) * dW / (A * _finite("rho_w", rho_w, lo=0.0) * g)

    def ranges(self, T: Any, *, lines: Any = None, clip: bool = False, delta_W: float = 0.0,
               A_w: float | None = None, rho_w: float = 1025.0) -> tuple[np.ndarray, np.ndarray]:
        """Eq. (13): ranges ``d = f^-1(T^0) + r`` [m] from each anchor to the COT, and the mapped
        distances ``X`` [m] (for :meth:`range_variance`); ``T^0`` is ``T`` after the loading
        correction of eq. (10) when ``delta_W`` [N] is non-zero (then ``A_w`` [m^2] is needed)."""
        T = np.asarray(T, dtype=float)
        if delta_W:
            if A_w is None:
                raise AnchorSlamError(f"delta_W = {delta_W!r} N needs the water-plane area A_w [m^2]")
            T = self.loading_correction(T, delta_W, A_w, rho_w=rho_w, lines=lines)
        X = self.distance(T, lines=lines, clip=clip)
        idx = self._line_index(T, lines)
        return X + self.r[idx], X

    def range_variance(self, X: Any, sigma_Tn: Any, *, sigma_Td: Any = 0.0, sigma_gps: float = 0.0,
                       lines: Any = None) -> np.ndarray:
        """Eq. (12): ``sigma_d^2 = (sigma_Tn^2 + sigma_Td^2) / k^2 + sigma_GPS^2`` [m^2] with the
        local slope ``k = dTF/dX`` at the mapped distance ``X`` [m]; ``sigma_Tn``, ``sigma_Td`` [N]
        the tension cells' and the dynamic tension's standard deviations, ``sigma_gps`` [m]."""
        X = np.asarray(X, dtype=float)
        idx = self._line_index(X, lines)
        k = self.slope(X, lines=idx)
        sn = np.broadcast_to(np.asarray(sigma_Tn, float), (len(self.line_ids),))[idx] if np.ndim(sigma_Tn) else sigma_Tn
        sd = np.broadcast_to(np.asarray(sigma_Td, float), (len(self.line_ids),))[idx] if np.ndim(sigma_Td) else sigma_Td
        return (np.square(sn) + np.square(sd)) / np.square(k) + float(sigma_gps) ** 2


# ------------------------------------------------------------------------------------------
# the sensor network of virtual vessels (§4, §6.1)
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class VirtualVessel:
    """One stored record of the vessel at an equilibrium (or the live vessel's record).

    Attributes
    ----------
    t : ndarray (n,)
        Sample times [s] from the start of the record.
    position : ndarray (n, 2)
        Observer (GNSS-based EKF) LF position of the body origin in {E} [m] (the landmark
        ``p_j^t`` when the COT is the body origin).
    heading : ndarray (n,)
        Measured heading [rad].
    tensions : ndarray (n, M)
        Measured fairlead tensions [N] (tension cells, with their noise).
    tau_thr : ndarray (n, 3)
        Delivered thrust in {B} [N, N, N m].
    truth : ndarray (n, 3)
        True LF pose (x [m], y [m], psi [rad]) -- for scoring only.
    cot : ndarray (n, 2)
        Observer LF position of the centre of turret in {E} [m].
    sea_state : dict
        The environment (Hs [m], Tp [s], directions [deg], speeds [m/s]).
    settle_time : float
        Simulated time before the record [s] (the vessel started at the quasi-static equilibrium of
        the mean load).
    current_tension : ndarray (M,) or None
        The share of each fairlead tension [N] that the record's current puts on the lines, the
        seed's ``Delta T_c`` of eq. (8): the line model settled under the measured current minus
        settled without it, at the record's mean LF pose
        (``studies.anchor_network.current_tension_share``). Subtracted from the tensions before the
        tension -> range map (:meth:`mapped_tensions`); None: not known, no correction.
    range_bias : ndarray (M,) or None
        The mean error of the tension -> range map along this record [m] (eq. 8's ``Delta T_c``
        and ``Delta T_v`` together, as range): the line model driven along the record's observer
        track plus the wave-frequency motion of its sea state (with the scenario's
        six-degree-of-freedom hull, its heave, roll and pitch at the fairleads too), under its
        current (``studies.anchor_network.range_bias_along``). Subtracted from the record's ranges where
        known (:meth:`ranges`), in place of ``current_tension``. None for the live vessel, whose
        track is what is sought.
    """

    t: np.ndarray
    position: np.ndarray
    heading: np.ndarray
    tensions: np.ndarray
    tau_thr: np.ndarray
    truth: np.ndarray
    cot: np.ndarray
    sea_state: dict
    settle_time: float
    current_tension: np.ndarray | None = None
    range_bias: np.ndarray | None = None

    def mapped_tensions(self, line_correction: bool = True) -> np.ndarray:
        """The tensions the range map reads [N] (n, M): the measured ones less the current's share
        ``current_tension`` (eq. 8's ``Delta T_c``) when it is known and ``line_correction``."""
        if line_correction and self.current_tension is not None:
            return self.tensions - np.asarray(self.current_tension, float)[None, :]
        return self.tensions

    def ranges(self, range_map: "TensionRangeMap", line_correction: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """``(d, X)`` of :meth:`TensionRangeMap.ranges` for this record's tensions (clipped to the
        map's domain), with ``line_correction`` the line model's correction: the record's range
        bias subtracted where it is known, else the current's share of the tensions."""
        if line_correction and self.range_bias is not None:
            d, X = range_map.ranges(self.tensions, clip=True)
            return d - np.asarray(self.range_bias, float)[None, :], X
        return range_map.ranges(self.mapped_tensions(line_correction), clip=True)

    def head(self, n: int) -> "VirtualVessel":
        """The first ``n`` samples."""
        return replace(self, t=self.t[:n], position=self.position[:n], heading=self.heading[:n],
                       tensions=self.tensions[:n], tau_thr=self.tau_thr[:n], truth=self.truth[:n], cot=self.cot[:n])


@dataclass(frozen=True, eq=False)
class VirtualVesselNetwork:
    """``N`` virtual vessels and the live vessel, all recorded on the same time grid.

    ``save``/``load`` keep it as one ``.npz`` file (arrays) with its metadata as JSON inside.
    """

    scenario: str
    vessels: tuple[VirtualVessel, ...]
    live: VirtualVessel
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.vessels)

    @property
    def duration(self) -> float:
        return float(self.live.t[-1] - self.live.t[0])

    def subset(self, n: int, duration: float | None = None) -> "VirtualVesselNetwork":
        """The first ``n`` virtual vessels, each record (and the live one) cut to ``duration`` [s]."""
        if not isinstance(n, (int, np.integer)) or not 1 <= n <= self.n:
            raise AnchorSlamError(f"virtual vessels = {n!r}: the network holds {self.n}; give 1..{self.n}")
        vs, live = self.vessels[:n], self.live
        if duration is not None:
            d = _finite("duration", duration, lo=0.0, unit="s")
            if d > self.duration + 1e-9:
                raise AnchorSlamError(f"duration = {d:g} s is longer than the stored records ({self.duration:g} s)")
            k = int(np.searchsorted(live.t, live.t[0] + d + 1e-9))
            vs, live = tuple(v.head(k) for v in vs), live.head(k)
        return replace(self, vessels=tuple(vs), live=live)

    def save(self, path: str | Path) -> Path:
        """Write the network to ``path`` (``.npz``) atomically."""
        import io

        arrays: dict[str, np.ndarray] = {}
        metas = []
        for k, v in enumerate((self.live, *self.vessels)):
            for name in ("t", "position", "heading", "tensions", "tau_thr", "truth", "cot"):
                arrays[f"{k}_{name}"] = np.asarray(getattr(v, name))
            for name in ("current_tension", "range_bias"):
                if getattr(v, name) is not None:
                    arrays[f"{k}_{name}"] = np.asarray(getattr(v, name), float)
            metas.append({"sea_state": v.sea_state, "settle_time": v.settle_time})
        head = {"format": NETWORK_FORMAT, "scenario": self.scenario, "records": metas, "meta": self.meta}
        arrays["header"] = np.frombuffer(json.dumps(head).encode("utf-8"), dtype=np.uint8)
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        return atomic_write_bytes(path, buf.getvalue())

    @classmethod
    def load(cls, path: str | Path) -> "VirtualVesselNetwork":
        """Read a network written by :meth:`save`; a missing or foreign file raises AnchorSlamError."""
        try:
            with np.load(path, allow_pickle=False) as z:
                head = json.loads(bytes(z["header"]).decode("utf-8"))
                if head.get("format") != NETWORK_FORMAT:
                    raise AnchorSlamError(f"network file {str(path)!r} has format {head.get('format')!r}, "
                                          f"not {NETWORK_FORMAT!r}")
                recs = []
                for k, m in enumerate(head["records"]):
                    opt = {n: (np.array(z[f"{k}_{n}"]) if f"{k}_{n}" in z.files else None)
                           for n in ("current_tension", "range_bias")}
                    recs.append(VirtualVessel(**{n: np.array(z[f"{k}_{n}"]) for n in
                                                 ("t", "position", "heading", "tensions", "tau_thr", "truth", "cot")},
                                              sea_state=m["sea_state"], settle_time=float(m["settle_time"]), **opt))
        except AnchorSlamError:
            raise
        except (OSError, KeyError, ValueError) as exc:
            raise AnchorSlamError(f"network file {str(path)!r} cannot be read: {exc}") from None
        return cls(scenario=head["scenario"], vessels=tuple(recs[1:]), live=recs[0], meta=head.get("meta", {}))


@dataclass(frozen=True, kw_only=True)
class SlamSettings:
    """Tuning of :class:`AnchorSLAM` (SI units).

    Attributes
    ----------
    sigma_T : float
        Tension-cell noise ``sigma_Tn`` [N] (eq. 10, 12); the seed's §6.1 uses ``sigma_T^2 = 1e8``.
    sigma_Td : float
        Dynamic tension of the live vessel not explained by the model [N] (eq. 12).
    sigma_Td_virtual : float
        The same for the stored records [N] (the LF wander about the equilibrium and the
        wave-frequency tension; eq. 12 prints only ``sigma_Tn`` for ``d_ij``, this adds it).
    sigma_gps : float
        ``sigma_GPS`` of eq. (12) [m].
    sigma_pt : float
        Noise of the stored observer positions ``p^t`` [m] (the observer's LF error).
    virtual_noise : float
        Random walk of the virtual vessels' positions, ``p^t' = E_t w_t`` [m/sqrt(s)]. The seed's
        ``p^t' = 0`` treats each landmark as fixed; a stored vessel keeps wandering about its
        equilibrium (on ren8 up to ±7 m over its 400 s surge period), and the ranges of each
        instant belong to the position of that instant, so the state follows the record.
    heading_std : float
        Heading measurement noise [rad].
    anchor_std0 : float
        Initial standard deviation of each anchor coordinate [m] (Table 4's errors: up to 370 m).
    position_std0 : float
        Initial standard deviation of the live vessel's position [m].
    anchor_noise : float
        ``E_a`` of ``p^a' = E_a w_a`` [m/sqrt(s)] (§5: "a noise is needed").
    T_b : float
        Bias time constant [s] (eq. 1b); ``bias_std`` [N, N, N m] its stationary deviation.
    force_noise : float
        White force on the kinetics [N/sqrt(Hz)].
    omega_0, lam, wf_std :
        WF model (eq. 1d-1e): peak frequency [rad/s], relative damping [-], expected WF motion
        (x, y [m], psi [rad]).
    anchor_coordinates : {"polar", "cartesian"}
        How the anchor states ``p_i^a`` are held: the seed's Cartesian ``(x_i^a, y_i^a)``, or
        ``(rho_i, theta_i)`` about the field zero point (default). With Table 4's guesses (up to
        370 m off) the Cartesian EKF is inconsistent: the range Jacobian's direction is wrong by up
        to 0.19 rad at first, far more than the 0.015 rad the landmarks' baseline resolves, so the
        range information leaks into the tangential direction and the covariance collapses there
        while the error stays (synthetic ranges, N = 10: errors up to 84 m with a reported 3 m).
        In polar coordinates a range ``rho_i - e_r(theta_i) . (p_j - 0)`` informs ``theta_i`` only
        through the landmarks' spread, whatever the current estimate. Eq. (16)'s anchor blocks
        become ``chi_i dp_i^a/d(rho_i, theta_i)``.
    """

    sigma_T: float = 1.0e4
    sigma_Td: float = 2.0e4
    sigma_Td_virtual: float = 2.0e4
    sigma_gps: float = 0.5
    sigma_pt: float = 0.25
    virtual_noise: float = 0.2
    heading_std: float = math.radians(0.1)
    anchor_std0: float = 200.0
    position_std0: float = 50.0
    anchor_noise: float = 1.0e-3
    T_b: float = 1000.0
    bias_std: tuple[float, float, float] = (1.0e6, 1.0e6, 1.0e8)
    force_noise: tuple[float, float, float] = (1.0e5, 1.0e5, 1.0e7)
    omega_0: float = 2 * math.pi / 9.0
    lam: float = 0.1
    wf_std: tuple[float, float, float] = (0.3, 0.3, 0.003)
    anchor_coordinates: str = "polar"

    def __post_init__(self) -> None:
        if self.anchor_coordinates not in ("polar", "cartesian"):
            raise AnchorSlamError(f"settings.anchor_coordinates = {self.anchor_coordinates!r} is not one of "
                                  "'polar', 'cartesian'")
        for f in ("sigma_T", "sigma_pt", "anchor_std0", "position_std0", "T_b", "omega_0", "lam", "heading_std"):
            _finite(f"settings.{f}", getattr(self, f), lo=0.0)
        for f in ("sigma_Td", "sigma_Td_virtual", "sigma_gps", "anchor_noise", "virtual_noise"):
            _finite(f"settings.{f}", getattr(self, f), lo=0.0, strict=False)
        for f in ("bias_std", "force_noise", "wf_std"):
            v = getattr(self, f)
            if len(v) != 3:
                raise AnchorSlamError(f"settings.{f} = {v!r} must be 3 numbers (x, y, psi)")
            for k, x in enumerate(v):
                _finite(f"settings.{f}[{k}]", x, lo=0.0)


class AnchorSLAM:
    """EKF-SLAM of §5 (Table 1; model eq. 15, Jacobian eq. 16).

    State ``x = (xi (6), eta (3), b (3), nu (3), p^a (2M), p^t (2N))`` -- WF states (``xi_4..6`` the
    WF pose), LF pose of the body origin in {E}, bias in {E}, LF velocity in {B}, the anchors and the
    virtual vessels' positions (each COT). Model (eq. 15a)::

        xi'  = A_w xi + E_w w_w,      eta' = R(psi) nu,       b' = -T_b^-1 b + E_b w_b,
        M nu' = -D nu + R^T b - R^T G eta + tau_c,            p^a' = E_a w_a,     p^t' = 0

    with ``G`` the mooring stiffness at the field zero point (:meth:`MooringModel.stiffness`) and
    ``tau_c`` the delivered thrust. Measurements (eq. 15b): the heading ``psi + xi_6``, the stored
    observer positions ``p^t``, the live ranges ``d_i = |p_i^a - c|`` with ``c`` the COT of the total
    (LF + WF) pose (``p^p + (xi_4, xi_5)`` for a COT at the body origin), and the virtual ranges
    ``d_ij = |p_i^a - p_j^t|``; their Jacobian is eq. (16) (the seed's ``A_1 A_2 A_3``, ``chi_i``,
    ``s_i``, ``theta_ij`` blocks; with a COT off the body origin the ``psi`` column gains the lever
    arm's derivative).

    Discretisation (Table 1's ``Phi = I + T df/dx`` is unstable for the WF resonator at a 1 s
    step): the WF block by its exact transition ``exp(A_w T)``, the bias by its exact decay, the
    kinetics by a semi-implicit Euler step (damping implicit, then ``eta`` with the new ``nu``), the
    covariance by the exact Jacobian of that map; the correction of Table 1, processed one scalar
    measurement at a time (the measurement noise is diagonal, so this is the batch update exactly).

    Parameters
    ----------
    range_map : TensionRangeMap
    M, D : (3, 3)
        Vessel inertia (incl. added mass) [kg, kg m^2] and linear damping [N s/m, ...].
    anchors0 : (M, 2)
        Initial anchor estimates [m].
    n_virtual : int
        Number of virtual vessels ``N`` (0: only the live vessel -- a tension-based position
        reference, :class:`TensionPositionEstimator`).
    settings : SlamSettings
    eta0 : (3,)
        Initial LF pose estimate [m, m, rad] (default the field zero point).
    p_cot_B : (2,)
        COT in {B} [m].
    anchor_cov0 : (2M, 2M), optional
        Initial anchor covariance [m^2] (default ``anchor_std0^2 I``).
    """

    def __init__(self, range_map: TensionRangeMap, M: Any, D: Any, anchors0: Any, *, n_virtual: int = 0,
                 settings: SlamSettings = SlamSettings(), eta0: Any = (0.0, 0.0, 0.0), p_cot_B: Any = (0.0, 0.0),
                 anchor_cov0: Any = None, virtual0: Any = None):
        if not isinstance(range_map, TensionRangeMap):
            raise AnchorSlamError(f"range_map = {range_map!r} must be a TensionRangeMap")
        if not isinstance(settings, SlamSettings):
            raise AnchorSlamError(f"settings = {settings!r} must be a SlamSettings")
        self.map = range_map
        self.s = s = settings
        nl = len(range_map.line_ids)
        a0 = np.asarray(anchors0, dtype=float)
        if a0.shape != (nl, 2) or not np.all(np.isfinite(a0)):
            raise AnchorSlamError(f"anchors0 has shape {a0.shape}: it must be {nl} finite (x, y) pairs [m], one per "
                                  f"line {list(range_map.line_ids)}")
        if not isinstance(n_virtual, (int, np.integer)) or n_virtual < 0:
            raise AnchorSlamError(f"n_virtual = {n_virtual!r} must be an integer >= 0")
        self.M_lines, self.N = nl, int(n_virtual)
        self._Mi = np.linalg.inv(np.asarray(M, float))
        self._D = np.asarray(D, float)
        self._G = np.asarray(range_map.model.stiffness(np.zeros(3)), float)
        self._pc = np.asarray(p_cot_B, float)
        n = 15 + 2 * nl + 2 * self.N
        self.n = n
        self.ia = slice(15, 15 + 2 * nl)
        self.it = slice(15 + 2 * nl, n)
        x = np.zeros(n)
        e0 = np.asarray(eta0, float)
        if e0.shape != (3,) or not np.all(np.isfinite(e0)):
            raise AnchorSlamError(f"eta0 = {np.ravel(eta0).tolist()} must be 3 finite numbers (x [m], y [m], psi [rad])")
        x[6:9] = e0
        self.polar = s.anchor_coordinates == "polar"
        x[self.ia] = self._to_state(a0).ravel()
        P = np.zeros((n, n))
        w0 = s.omega_0
        wf = np.asarray(s.wf_std, float)
        P[0:3, 0:3] = np.diag(wf ** 2 / w0 ** 2)
        P[3:6, 3:6] = np.diag(wf ** 2)
        P[6:8, 6:8] = np.eye(2) * s.position_std0 ** 2
        P[8, 8] = s.heading_std ** 2
        P[9:12, 9:12] = np.diag(np.asarray(s.bias_std, float) ** 2)
        P[12:15, 12:15] = np.diag([0.5 ** 2, 0.5 ** 2, 0.005 ** 2])
        if anchor_cov0 is None:
            C = np.eye(2 * nl) * s.anchor_std0 ** 2
        else:
            C = np.asarray(anchor_cov0, float)
            if C.shape != (2 * nl, 2 * nl) or not np.all(np.isfinite(C)):
                raise AnchorSlamError(f"anchor_cov0 has shape {C.shape}: it must be ({2 * nl}, {2 * nl}) [m^2]")
        Ji = np.linalg.inv(self._J(x))                     # Cartesian -> state coordinates
        P[self.ia, self.ia] = Ji @ (0.5 * (C + C.T)) @ Ji.T
        if self.N:
            P[self.it, self.it] = np.eye(2 * self.N) * 1e4  # replaced by the first stored positions
            if virtual0 is not None:
                x[self.it] = np.asarray(virtual0, float).ravel()
                P[self.it, self.it] = np.eye(2 * self.N) * s.sigma_pt ** 2
        self.x, self.P = x, P
        self._t: float | None = None
        self._disc_dt: float | None = None
        self.innovation = np.zeros(0)

    # -- anchor coordinates ------------------------------------------------------------------
    def _to_state(self, a: np.ndarray) -> np.ndarray:
        if not self.polar:
            return np.asarray(a, float).copy()
        return np.c_[np.hypot(a[:, 0], a[:, 1]), np.arctan2(a[:, 1], a[:, 0])]

    def _anchor_xy(self, x: np.ndarray) -> np.ndarray:
        q = x[self.ia].reshape(-1, 2)
        if not self.polar:
            return q
        return np.c_[q[:, 0] * np.cos(q[:, 1]), q[:, 0] * np.sin(q[:, 1])]

    def _J(self, x: np.ndarray) -> np.ndarray:
        """d(anchors, Cartesian) / d(anchor states), block diagonal (2M, 2M)."""
        nl = self.M_lines
        if not self.polar:
            return np.eye(2 * nl)
        q = x[self.ia].reshape(-1, 2)
        J = np.zeros((2 * nl, 2 * nl))
        for i, (rho, th) in enumerate(q):
            c, s_ = math.cos(th), math.sin(th)
            J[2 * i:2 * i + 2, 2 * i:2 * i + 2] = [[c, -rho * s_], [s_, rho * c]]
        return J

    # -- accessors ---------------------------------------------------------------------------
    @property
    def anchors(self) -> np.ndarray:
        """Anchor estimates (M, 2) [m], Cartesian in {E}."""
        return self._anchor_xy(self.x).copy()

    @property
    def anchor_cov(self) -> np.ndarray:
        """Anchor covariance (2M, 2M) [m^2], Cartesian (first order)."""
        J = self._J(self.x)
        return J @ self.P[self.ia, self.ia] @ J.T

    @property
    def eta(self) -> np.ndarray:
        """LF pose estimate (x [m], y [m], psi [rad])."""
        return self.x[6:9].copy()

    @property
    def position_cov(self) -> np.ndarray:
        """Covariance of the LF position (2, 2) [m^2]."""
        return self.P[6:8, 6:8].copy()

    @property
    def virtual_positions(self) -> np.ndarray:
        return self.x[self.it].reshape(-1, 2).copy()

    # -- prediction --------------------------------------------------------------------------
    def _discretise(self, dt: float) -> None:
        s = self.s
        w0, lam = s.omega_0, s.lam
        I3 = np.eye(3)
        A = np.block([[np.zeros((3, 3)), I3], [-w0 * w0 * I3, -2.0 * lam * w0 * I3]])
        q_w = 4.0 * lam * w0 * np.asarray(s.wf_std, float) ** 2
        Ew = np.zeros((6, 3))
        Ew[3:, :] = np.diag(np.sqrt(q_w))
        vl = np.zeros((12, 12))
        vl[:6, :6] = -A * dt
        vl[:6, 6:] = Ew @ Ew.T * dt
        vl[6:, 6:] = A.T * dt
        E = expm(vl)
        Phi_w = E[6:, 6:].T
        Qw = Phi_w @ E[:6, 6:]
        n = self.n
        Q = np.zeros((n, n))
        Q[:6, :6] = 0.5 * (Qw + Qw.T)
        a = math.exp(-dt / s.T_b)
        bs = np.asarray(s.bias_std, float)
        Q[9:12, 9:12] = np.diag(bs ** 2 * (1.0 - a * a))
        Fn = np.asarray(s.force_noise, float)
        self._A_nu = np.linalg.inv(np.eye(3) + dt * self._Mi @ self._D)
        Gm = dt * self._A_nu @ self._Mi
        Q[12:15, 12:15] = Gm @ np.diag(Fn ** 2 / dt) @ Gm.T
        Q[self.ia, self.ia] = np.eye(2 * self.M_lines) * s.anchor_noise ** 2 * dt   # Cartesian; mapped in predict
        if self.N:
            Q[self.it, self.it] = np.eye(2 * self.N) * max(s.virtual_noise ** 2 * dt, 1e-12)
        self._Q, self._Phi_w, self._decay, self._Gm = Q, Phi_w, a, Gm
        self._disc_dt = dt

    def predict(self, dt: float, tau_c: Any) -> None:
        """Propagate state and covariance over ``dt`` [s] with the delivered thrust ``tau_c`` (3,)
        in {B} [N, N, N m] held (Table 1, state and error propagation)."""
        dt = _finite("dt", dt, lo=0.0, unit="s")
        tau_c = np.asarray(tau_c, float)
        if self._disc_dt is None or abs(dt - self._disc_dt) > 1e-9 * max(1.0, dt):
            self._discretise(dt)
        x = self.x
        eta, b, nu = x[6:9], x[9:12], x[12:15]
        psi = float(eta[2])
        c, s_ = math.cos(psi), math.sin(psi)
        R = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
        dR = np.array([[-s_, -c, 0.0], [c, -s_, 0.0], [0.0, 0.0, 0.0]])
        g = b - self._G @ eta                               # {E}: bias minus linear mooring restoring
        nu_new = self._A_nu @ (nu + dt * (self._Mi @ (R.T @ g + tau_c)))
        xn = x.copy()
        xn[:6] = self._Phi_w @ x[:6]
        xn[6:9] = eta + dt * (R @ nu_new)
        xn[9:12] = self._decay * b
        xn[12:15] = nu_new
        # Jacobian of the discrete map (LF block)
        Jg_eta = -R.T @ self._G
        Jg_eta[:, 2] += dR.T @ g                            # d(R^T g)/d psi
        Fnu_eta = self._Gm @ Jg_eta
        Fnu_b = self._Gm @ R.T
        Fnu_nu = self._A_nu
        Feta_eta = np.eye(3) + dt * R @ Fnu_eta
        Feta_eta[:, 2] += dt * dR @ nu_new
        F = np.eye(self.n)
        F[:6, :6] = self._Phi_w
        F[6:9, 6:9], F[6:9, 9:12], F[6:9, 12:15] = Feta_eta, dt * R @ Fnu_b, dt * R @ Fnu_nu
        F[9:12, 9:12] = np.eye(3) * self._decay
        F[12:15, 6:9], F[12:15, 9:12], F[12:15, 12:15] = Fnu_eta, Fnu_b, Fnu_nu
        Q = self._Q
        if self.polar:
            Ji = np.linalg.inv(self._J(x))
            Q = Q.copy()
            Q[self.ia, self.ia] = Ji @ Q[self.ia, self.ia] @ Ji.T
        self.P = F @ self.P @ F.T + Q
        self.x = xn

    # -- correction --------------------------------------------------------------------------
    def _cot(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """COT of the total pose (2,) and its derivative with respect to psi (2,)."""
        psi = x[8] + x[5]
        c, s_ = math.cos(psi), math.sin(psi)
        px, py = self._pc
        cot = x[6:8] + x[3:5] + np.array([c * px - s_ * py, s_ * px + c * py])
        return cot, np.array([-s_ * px - c * py, c * px - s_ * py])

    def measurement_model(self, x: np.ndarray, *, heading: bool = False, live: bool = False,
                          virtual: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """``h(x)`` and its Jacobian ``H`` (eq. 15b, 16) for the chosen parts, stacked in the seed's
        order ``(psi + xi_6, p^t, d_I, d_IJ)``; ``d_IJ`` ordered anchor-major (eq. 14b)."""
        n, nl, N = self.n, self.M_lines, self.N
        anc = self._anchor_xy(x)
        Ja = self._J(x)
        hs, Hs = [], []
        if heading:
            h = np.zeros((1, n))
            h[0, 8] = h[0, 5] = 1.0                         # d psi / d eta, d psi / d xi (eq. 16)
            hs.append([x[8] + x[5]])
            Hs.append(h)
        if virtual and N:
            Hp = np.zeros((2 * N, n))
            Hp[:, self.it] = np.eye(2 * N)
            hs.append(x[self.it])
            Hs.append(Hp)
        if live:
            cot, dcot = self._cot(x)
            diff = cot[None, :] - anc                       # (M, 2): COT - anchor
            dist = np.hypot(diff[:, 0], diff[:, 1])
            u = diff / dist[:, None]                        # rows of A_1 A_2 A_3 (eq. 16)
            Hd = np.zeros((nl, n))
            Hd[:, 3:5] = u                                  # d d_i / d (xi_4, xi_5)
            Hd[:, 6:8] = u                                  # d d_i / d p^p
            Hd[:, 8] = Hd[:, 5] = u @ dcot                  # lever arm of a COT off the body origin
            for i in range(nl):                             # chi_i: d d_i / d p_i^a
                Hd[i, 15 + 2 * i:17 + 2 * i] = -u[i] @ Ja[2 * i:2 * i + 2, 2 * i:2 * i + 2]
            hs.append(dist)
            Hs.append(Hd)
        if virtual and N:
            pt = x[self.it].reshape(N, 2)
            diff = anc[:, None, :] - pt[None, :, :]          # (M, N, 2): anchor - virtual COT
            dist = np.hypot(diff[..., 0], diff[..., 1])
            u = diff / dist[..., None]                       # s_i rows; theta_ij = -u
            Hv = np.zeros((nl * N, n))
            for i in range(nl):
                r0 = i * N
                Hv[r0:r0 + N, 15 + 2 * i:17 + 2 * i] = u[i] @ Ja[2 * i:2 * i + 2, 2 * i:2 * i + 2]
                for j in range(N):
                    Hv[r0 + j, self.it.start + 2 * j:self.it.start + 2 * j + 2] = -u[i, j]
            hs.append(dist.ravel())
            Hs.append(Hv)
        if not hs:
            return np.zeros(0), np.zeros((0, n))
        return np.concatenate([np.ravel(v) for v in hs]), np.vstack(Hs)

    def correct(self, *, heading: float | None = None, d_live: Any = None, var_live: Any = None,
                p_virtual: Any = None, d_virtual: Any = None, var_virtual: Any = None) -> None:
        """Measurement update (Table 1, eq. 15b-16) with whichever parts are given.

        Parameters
        ----------
        heading : float
            Measured heading [rad] (``psi + xi_6``).
        d_live, var_live : (M,)
            Live ranges ``d_I`` [m] (eq. 13-14a) and their variances [m^2] (eq. 12).
        p_virtual : (N, 2)
            Stored observer positions of the virtual vessels' COT [m].
        d_virtual, var_virtual : (M, N)
            Virtual ranges ``d_IJ`` [m] (row i: anchor i, eq. 14b) and variances [m^2].

        The stored positions and the virtual ranges go together (both or neither).
        """
        x = self.x
        N = self.N
        virtual = N > 0 and p_virtual is not None and d_virtual is not None
        if N and (p_virtual is None) != (d_virtual is None):
            raise AnchorSlamError("give the virtual vessels' positions p_virtual and ranges d_virtual together")
        h, H = self.measurement_model(x, heading=heading is not None, live=d_live is not None, virtual=virtual)
        if not len(h):
            return
        y, r = [], []
        if heading is not None:
            y.append([float(heading)])
            r.append([self.s.heading_std ** 2])
        if virtual:
            y.append(np.asarray(p_virtual, float).reshape(N, 2).ravel())
            r.append(np.full(2 * N, self.s.sigma_pt ** 2))
        if d_live is not None:
            y.append(np.asarray(d_live, float))
            r.append(np.asarray(var_live, float))
        if virtual:
            y.append(np.asarray(d_virtual, float).ravel())
            r.append(np.asarray(var_virtual, float).ravel())
        yv = np.concatenate([np.ravel(v) for v in y])
        rv = np.concatenate([np.ravel(v) for v in r])
        if yv.shape != h.shape or rv.shape != h.shape or not np.all(np.isfinite(yv)) or not np.all(np.isfinite(rv) & (rv > 0)):
            raise AnchorSlamError(f"measurements: {yv.size} values and {rv.size} variances for {h.size} model outputs; "
                                  "every value must be finite and every variance > 0")
        v = yv - h
        if heading is not None:
            v[0] = math.remainder(float(v[0]), 2 * math.pi)
        # Table 1's update, processed one scalar measurement at a time (R is diagonal, so this is
        # the batch update exactly: every residual is taken at the prior and H is the prior's).
        # The covariance update P - k (P h)^T is Table 1's Joseph form at the optimal gain; no
        # matrix inversion (a LAPACK solve per step is slow on a busy machine).
        self.innovation = v.copy()
        xp = x.copy()
        P = self.P.copy()
        for j in range(len(v)):
            hj = H[j]
            nz = np.flatnonzero(hj)
            Ph = P[:, nz] @ hj[nz]
            sj = float(hj[nz] @ Ph[nz]) + rv[j]
            k = Ph / sj
            xp += k * (v[j] - float(hj[nz] @ (xp[nz] - x[nz])))
            P -= np.outer(k, Ph)
        self.x = xp
        self.P = 0.5 * (P + P.T)

    def step(self, t: float, *, tau_c: Any = (0.0, 0.0, 0.0), **measurements: Any) -> None:
        """Predict to ``t`` [s] (from the previous step) and correct with ``measurements``
        (:meth:`correct`'s keywords)."""
        t = _finite("t", t, unit="s")
        if self._t is not None:
            if t < self._t:
                raise AnchorSlamError(f"t = {t!r} s is before the previous step {self._t!r} s")
            if t > self._t:
                self.predict(t - self._t, tau_c)
        self._t = t
        self.correct(**measurements)


# ------------------------------------------------------------------------------------------
# replaying a network, scoring
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class SlamResult:
    """Estimates over time of one :func:`run_anchor_slam`.

    ``t`` (n,) [s]; ``position`` (n, 2) tension-only LF position estimate [m]; ``position_std``
    (n, 2) [m]; ``truth`` (n, 2) true LF position [m]; ``anchors`` (n, M, 2) estimates [m];
    ``anchor_std`` (n, M, 2) [m]; ``anchors_true`` (M, 2); ``line_ids``; ``burn_in`` [s] -- the
    start of the window of ``position_rms_error``; ``line_correction``: whether the records'
    ranges were corrected by the line model (eq. 8's ``Delta T_c``, ``Delta T_v``); ``anchors_survey``
    (M, 2) [m]: the batch estimate the filter started from (None: it started from
    ``anchors_initial``).
    """

    t: np.ndarray
    position: np.ndarray
    position_std: np.ndarray
    truth: np.ndarray
    anchors: np.ndarray
    anchor_std: np.ndarray
    anchors_true: np.ndarray
    anchors_initial: np.ndarray
    line_ids: tuple[str, ...]
    n_virtual: int
    burn_in: float
    line_correction: bool = False
    anchors_survey: np.ndarray | None = None

    @property
    def anchor_errors(self) -> np.ndarray:
        """Final horizontal error of each anchor estimate (M,) [m]."""
        return np.hypot(*(self.anchors[-1] - self.anchors_true).T)

    @property
    def position_errors(self) -> np.ndarray:
        return np.hypot(*(self.position - self.truth).T)

    @property
    def position_rms_error(self) -> float:
        """RMS of the horizontal position error from ``burn_in`` to the end [m]."""
        sel = self.t >= self.t[0] + self.burn_in
        return float(np.sqrt(np.mean(self.position_errors[sel] ** 2)))

    def summary(self) -> dict:
        """``{"anchors": [{"id", "true", "estimate", "error"}...], "position_rms_error", ...}``, metres."""
        est = self.anchors[-1]
        return {"anchors": [{"id": lid, "true": [float(v) for v in self.anchors_true[i]],
                             "estimate": [float(v) for v in est[i]], "error": float(self.anchor_errors[i])}
                            for i, lid in enumerate(self.line_ids)],
                "position_rms_error": self.position_rms_error,
                "max_anchor_error": float(self.anchor_errors.max()),
                "virtual_vessels": self.n_virtual, "duration": float(self.t[-1] - self.t[0]),
                "burn_in": self.burn_in, "line_correction": self.line_correction,
                "survey": self.anchors_survey is not None}

    def csv_tables(self) -> dict[str, tuple[list[str], list[list[float]]]]:
        """``{"estimates.csv": (header, rows), "anchors.csv": ...}`` -- the series over time and
        the final anchor table."""
        head = ["t", "x_hat", "y_hat", "x_hat_std", "y_hat_std", "x_true", "y_true", "position_error"]
        for lid in self.line_ids:
            head += [f"anchor[{lid}].x", f"anchor[{lid}].y", f"anchor[{lid}].x_std", f"anchor[{lid}].y_std"]
        rows = []
        e = self.position_errors
        for k in range(len(self.t)):
            row = [float(self.t[k]), *map(float, self.position[k]), *map(float, self.position_std[k]),
                   *map(float, self.truth[k]), float(e[k])]
            for i in range(len(self.line_ids)):
                row += [*map(float, self.anchors[k, i]), *map(float, self.anchor_std[k, i])]
            rows.append(row)
        ah = ["id", "x_true", "y_true", "x_initial", "y_initial", "x_estimate", "y_estimate", "error"]
        arows = [[lid, *map(float, self.anchors_true[i]), *map(float, self.anchors_initial[i]),
                  *map(float, self.anchors[-1, i]), float(self.anchor_errors[i])] for i, lid in enumerate(self.line_ids)]
        return {"estimates.csv": (head, rows), "anchors.csv": (ah, arows)}


def survey_anchors(range_map: TensionRangeMap, vessels: Any, anchors0: Any, *,
                   line_correction: bool = True, correlation_time: float = 200.0) -> tuple[np.ndarray, np.ndarray]:
    """Batch estimate of the anchors from stored records: for each anchor ``i`` the horizontal
    position that best fits, in least squares from ``anchors0[i]``, every sample of every record's
    range ``d_ij(t)`` (:meth:`VirtualVessel.ranges`, the line model's correction with
    ``line_correction``) as the distance to that record's observer COT ``p_j(t)``:
    ``min sum_j,t (|p_i^a - p_j(t)| - d_ij(t))^2``.

    The stored records are a batch (the seed's §4: "previously collected and stored data"), so the
    anchors need not be filtered: the EKF of eq. 15-16 treats the 1 Hz ranges as white noise, but
    their errors are correlated over a record (the landmark's slow wander, the lines' dynamics), and
    the filter then settles tens of metres off where the least-squares fit of the same ranges is
    within a few metres (``docs/anchor_slam.md``). Returns ``(anchors (M, 2) [m], covariance
    (2M, 2M) [m^2])``: block-diagonal, each block the fit's ``s^2 (J^T J)^-1`` with ``s^2`` the
    residuals' variance, times the samples in ``correlation_time`` [s] (the range errors'
    correlation: about half the stored vessels' 400 s surge period), and at least ``1 m^2`` on
    the diagonal.
    """
    from scipy.optimize import least_squares

    vs = list(vessels)
    if not vs:
        raise AnchorSlamError("the survey needs at least one stored record (virtual vessels = 0)")
    a0 = np.asarray(anchors0, dtype=float)
    M = len(range_map.line_ids)
    if a0.shape != (M, 2) or not np.all(np.isfinite(a0)):
        raise AnchorSlamError(f"anchors0 has shape {a0.shape}: it must be {M} finite (x, y) pairs [m]")
    P = np.concatenate([v.cot for v in vs])                            # (n, 2)
    D = np.concatenate([v.ranges(range_map, line_correction)[0] for v in vs])   # (n, M)
    dt = float(np.median(np.diff(vs[0].t))) if len(vs[0].t) > 1 else 1.0
    per_record = max(1.0, min(_finite("correlation_time", correlation_time, lo=0.0, unit="s") / dt,
                              len(P) / len(vs)))
    out, cov = np.zeros((M, 2)), np.zeros((2 * M, 2 * M))
    for i in range(M):
        def resid(a, d=D[:, i]):
            return np.hypot(a[0] - P[:, 0], a[1] - P[:, 1]) - d

        sol = least_squares(resid, a0[i], method="lm")
        J = sol.jac
        s2 = float(np.mean(sol.fun ** 2))
        C = s2 * per_record * np.linalg.pinv(J.T @ J)
        C[np.diag_indices(2)] = np.maximum(np.diag(C), 1.0)
        out[i] = sol.x
        cov[2 * i:2 * i + 2, 2 * i:2 * i + 2] = C
    return out, cov


def run_anchor_slam(scenario: Any, network: VirtualVesselNetwork, *, n_virtual: int | None = None,
                    duration: float | None = None, anchors0: Any = None, settings: SlamSettings | None = None,
                    burn_in: float | None = None, line_correction: bool = True, survey: bool = True) -> SlamResult:
    """Replay ``network`` (its first ``n_virtual`` vessels, ``duration`` [s]) through
    :class:`AnchorSLAM` from the initial anchors ``anchors0`` (M, 2) [m] (default: the scenario's
    anchors perturbed as in Table 4, :func:`table4_initial_anchors`).

    With ``survey`` (default) the stored records are first fitted in batch from ``anchors0``
    (:func:`survey_anchors`), and the filter starts from that fit and its covariance; without it,
    from ``anchors0`` with ``SlamSettings.anchor_std0``. Every step (the records' sample period)
    reads all records at the same instant (§6.1): the live vessel's heading, thrust and tensions
    (-> ``d_I``) and each virtual vessel's observer position and tensions (-> ``d_IJ``), mapped by
    :class:`TensionRangeMap` (clipped to its domain) with the variances of eq. (12) at the mapped
    distances; with ``line_correction`` (default) the line model's correction of each record
    (:meth:`VirtualVessel.ranges`: its range bias along its track where known, else the current's
    share of its tensions). ``burn_in`` (default a tenth of the duration) starts the window of the
    position RMS error.
    """
    from ..models.system import System

    system = System.from_scenario(scenario)
    rmap = TensionRangeMap(system.lines)
    n_virtual = network.n if n_virtual is None else n_virtual
    net = network.subset(n_virtual, duration)
    if anchors0 is None:
        anchors0 = table4_initial_anchors(system.lines.anchors)
    s = settings or SlamSettings(sigma_T=float(scenario.sensors.tension_std_rel * np.max(system.lines.MBS)),
                                 sigma_gps=float(scenario.sensors.gnss_std),
                                 heading_std=max(float(scenario.sensors.heading_std), 1e-5))
    live, vs = net.live, net.vessels
    M = len(rmap.line_ids)
    if live.tensions.shape[1] != M:
        raise AnchorSlamError(f"the network's records hold {live.tensions.shape[1]} tensions; scenario "
                              f"{scenario.name!r} has {M} lines")
    N = len(vs)
    # ranges at once (vectorised inversion): live (n, M), virtual (N, n, M)
    d_live, X_live = live.ranges(rmap, line_correction)
    var_live = rmap.range_variance(X_live, s.sigma_T, sigma_Td=s.sigma_Td, sigma_gps=s.sigma_gps)
    pv = np.stack([v.cot for v in vs])                     # (N, n, 2)
    a_start, cov0 = np.asarray(anchors0, float), None
    n_ekf = N
    if not survey:   # the filter reads the stored records' ranges (with the survey, the fit does)
        dX = [v.ranges(rmap, line_correction) for v in vs]
        d_v, X_v = np.stack([d for d, _ in dX]), np.stack([X for _, X in dX])
        var_v = rmap.range_variance(X_v, s.sigma_T, sigma_Td=s.sigma_Td_virtual)
    else:
        # the stored records fitted in batch; the filter then locates the live vessel on those
        # anchors, held (the live ranges do not move them: their errors are correlated too, and
        # with the anchors free they pulled them tens of metres off the fit)
        a_start, survey_cov = survey_anchors(rmap, vs, anchors0, line_correction=line_correction)
        s, cov0, n_ekf = replace(s, anchor_noise=0.0), np.eye(2 * M) * 1e-6, 0
    ekf = AnchorSLAM(rmap, system.vessel.M, system.vessel.D_lin, a_start, n_virtual=n_ekf, settings=s,
                     eta0=(0.0, 0.0, float(live.heading[0])), p_cot_B=system.p_cot_B,
                     virtual0=pv[:, 0, :] if n_ekf else None, anchor_cov0=cov0)
    n = len(live.t)
    pos, pos_std = np.zeros((n, 2)), np.zeros((n, 2))
    anc, anc_std = np.zeros((n, M, 2)), np.zeros((n, M, 2))
    for k in range(n):
        tau = live.tau_thr[k - 1] if k else live.tau_thr[0]
        virtual = dict(p_virtual=pv[:, k, :], d_virtual=d_v[:, k, :].T, var_virtual=var_v[:, k, :].T) if n_ekf else {}
        ekf.step(float(live.t[k]), tau_c=tau, heading=float(live.heading[k]), d_live=d_live[k], var_live=var_live[k],
                 **virtual)
        pos[k] = ekf.x[6:8]
        pos_std[k] = np.sqrt(np.diag(ekf.P)[6:8])
        anc[k] = ekf.anchors
        anc_std[k] = np.sqrt(np.diag(ekf.anchor_cov)).reshape(M, 2)
    if survey:   # the anchors' uncertainty is the fit's
        anc_std[:] = np.sqrt(np.diag(survey_cov)).reshape(M, 2)[None]
    T = float(live.t[-1] - live.t[0])
    bi = 0.1 * T if burn_in is None else _finite("burn_in", burn_in, lo=0.0, strict=False, unit="s")
    used = any(r.current_tension is not None or r.range_bias is not None for r in (live, *vs))
    return SlamResult(t=live.t.copy(), position=pos, position_std=pos_std, truth=live.truth[:, :2].copy(),
                      anchors=anc, anchor_std=anc_std, anchors_true=np.asarray(system.lines.anchors, float),
                      anchors_initial=np.asarray(anchors0, float), line_ids=rmap.line_ids, n_virtual=N, burn_in=bi,
                      line_correction=bool(line_correction and used),
                      anchors_survey=a_start.copy() if survey else None)


# ------------------------------------------------------------------------------------------
# a tension-based position reference
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PositionFix:
    """A tension-based position: ``position`` (2,) LF body origin in {E} [m], ``covariance`` (2, 2)
    [m^2], ``eta`` (3,) the LF pose [m, m, rad], ``ranges`` (M,) the mapped ranges ``d_i`` [m]."""

    t: float
    position: np.ndarray
    covariance: np.ndarray
    eta: np.ndarray
    ranges: np.ndarray


class TensionPositionEstimator:
    """A redundant position reference from the fairlead tensions and the heading (no GNSS).

    The filter of :class:`AnchorSLAM` without virtual vessels (Ren et al. 2015 with the anchor
    map of this paper): the anchors are the scenario's (fixed) or an :class:`AnchorSLAM`'s estimates
    with their covariance (``anchor_cov``: they stay uncertain states, with no process noise).
    ``update(t, measurement)`` -- a :class:`~tapm_opt.interfaces.Measurement` -- returns a
    :class:`PositionFix`; a new tension sample (``t_tensions``) corrects the ranges, the heading
    corrects every call. Tensions outside the map's domain are clipped to it.

    Parameters
    ----------
    system : System
    anchors : (M, 2), optional
        Anchor positions [m] (default the scenario's).
    anchor_cov : (2M, 2M), optional
        Their covariance [m^2] (default: known exactly -- 1 mm^2).
    eta0 : (3,)
        Initial LF pose (e.g. the last GNSS-based estimate before the drop-out).
    position_std0 : float
        Its standard deviation [m].
    settings : SlamSettings, optional
    """

    def __init__(self, system: Any, *, anchors: Any = None, anchor_cov: Any = None, eta0: Any = (0.0, 0.0, 0.0),
                 position_std0: float = 10.0, settings: SlamSettings | None = None):
        from ..models.system import System

        if not isinstance(system, System):
            raise AnchorSlamError(f"system = {system!r} must be a System (System.from_scenario(scenario))")
        sc = system.scenario
        self.map = TensionRangeMap(system.lines)
        s = settings or SlamSettings(sigma_T=float(sc.sensors.tension_std_rel * np.max(system.lines.MBS)),
                                     sigma_gps=float(sc.sensors.gnss_std),
                                     heading_std=max(float(sc.sensors.heading_std), 1e-5))
        s = replace(s, position_std0=_finite("position_std0", position_std0, lo=0.0, unit="m"), anchor_noise=0.0)
        a = system.lines.anchors if anchors is None else anchors
        M = system.lines.n_lines
        cov = np.eye(2 * M) * 1e-6 if anchor_cov is None else anchor_cov
        self._init = dict(range_map=self.map, M=system.vessel.M, D=system.vessel.D_lin, anchors0=a, settings=s,
                          eta0=eta0, p_cot_B=system.p_cot_B, anchor_cov0=cov)
        self.settings = s
        self.reset()

    def reset(self) -> None:
        self.ekf = AnchorSLAM(**self._init)
        self._t_T = -math.inf

    def update(self, t: float, measurement: Any) -> PositionFix:
        m = measurement
        if m.tensions is None or np.shape(m.tensions) != (self.ekf.M_lines,):
            raise AnchorSlamError(f"measurement.tensions = {m.tensions!r} must hold {self.ekf.M_lines} tensions [N]")
        kw: dict = {"heading": float(m.heading)}
        d = np.full(self.ekf.M_lines, np.nan)
        if float(m.t_tensions) > self._t_T:
            d, X = self.map.ranges(np.asarray(m.tensions, float), clip=True)
            kw.update(d_live=d, var_live=self.map.range_variance(X, self.settings.sigma_T,
                                                                 sigma_Td=self.settings.sigma_Td,
                                                                 sigma_gps=self.settings.sigma_gps))
            self._t_T = float(m.t_tensions)
        tau = np.zeros(3) if m.tau_thr is None else np.asarray(m.tau_thr, float)
        self.ekf.step(t, tau_c=tau, **kw)
        e = self.ekf
        return PositionFix(t=float(t), position=e.x[6:8].copy(), covariance=e.position_cov, eta=e.eta, ranges=d)

