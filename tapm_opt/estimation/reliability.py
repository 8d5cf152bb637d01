"""Causal (online) structural reliability index of several response signals at once.

The index of [R] §2.2 (seed ``reliability-setpoint-riser-mooring``), the survey's eq. (32) for a
mooring line ([S], ``survey-tapm-modeling-and-control``)::

    delta(t) = (r_t - r_ex(t)) / sigma_t,     r_ex = r_m + k sigma_r,
    k = sqrt(2 ln n) + gamma_E / sqrt(2 ln n)                          (Gumbel, [R] §2.2)

for every signal at once: a line's fairlead tension (``r_t`` = T_b, the mean breaking strength;
``sigma_t`` = sigma_b, its standard deviation: survey eq. 32) or a riser end's angle magnitude
(``r_t`` = the mean critical angle, ``sigma_t`` its standard deviation: delta_t, delta_b of [R]
§2.2). Everything is computed from the past only, at the rate the samples arrive, with O(1)
amortised work per sample and signal (running integrals and pointers into a buffer that holds just
the windows; nothing is re-scanned). It is the on-line counterpart of the offline index
:func:`tapm_opt.studies.kpis.reliability_index`, which sees the whole record (centred low-pass,
one sigma per record) and serves as its cross-check.

The three estimates
-------------------
``r_m`` -- the low-frequency mean ``x_lf(t)``: the **trailing moving average** of width
``lp_window`` (default 100 s) of the piecewise-linear signal, i.e. the offline centred average
shifted by half a window: ``x_lf(t) = offline x_lf(t - lp_window/2)`` exactly (same kernel). Why
this rather than a second-order low-pass: the delay is a pure, known lp_window/2 = 50 s at every
frequency (linear phase; a slow ramp of slope b is read b lp_window/2 low), the causal and offline
indices differ only by that shift and by their sigma window, so the offline index checks the
on-line one exactly; and the box kernel's zeros at periods lp_window/j null 10 s waves outright.
A critically damped second-order filter with the same low-frequency delay (omega_c = 2 /
(lp_window / 2) = 0.04 rad/s) attenuates wave-frequency ripple more (0.7 % instead of <= 4 % at
13 s) but its delay and gain depend on frequency and nothing offline matches it. Before the first
full window has passed ``x_lf`` is the mean of the record so far.

``sigma_r`` -- the standard deviation of the wave-frequency part over a trailing ``sigma_window``
(default 600 s: about 60 peak periods of a 10 s sea; over such a window the estimate of sigma of a
sea with a +-25 % band scatters by some 6-9 % (one standard deviation), over 3600 s by ~3 %: a
longer window is steadier, a shorter one follows a changing sea sooner).
The wave-frequency part is the *centred* residual ``w(t - lp_window/2) = x(t - lp_window/2) -
x_lf(t)``, available lp_window/2 late: the residual against the trailing mean, ``x(t) - x_lf(t)``,
would also carry the lag error ``x_LF(t) - x_LF(t - lp_window/2)`` of the slow motion (1.2 times
the amplitude of a 200 s oscillation against 0.36 times for the centred residual), counting the
low-frequency response twice (in r_m and in k sigma). sigma is time-weighted (trapezoid) over the
window, exactly as offline, so the two sigmas agree where their windows do.

``n`` -- the number of maxima in the exposure period: the zero up-crossings of ``w`` counted in the
sigma window (a narrow-band process has one maximum per up-crossing; level 0 because ``w`` is a
residual about a moving mean), scaled to ``exposure`` (default ``sigma_window``):
``n = count * exposure / span`` with ``span`` the time the window covers. ``k`` is
:func:`gumbel_k` of max(n, 2).

``delta = (r_t - x_lf - k sigma) / sigma_t``. ``ready`` is False until the sigma window has been
filled (``lp_window + sigma_window`` = 700 s after the first sample with the defaults); before that
the numbers are computed from what there is (sigma = 0 and n = 0 while no residual exists, k from
max(n, 2) = 2, never NaN) but flagged.

Sampling may be irregular (the integrals are exact for the piecewise-linear signal); samples should
resolve the wave periods (>= ~5 samples per period) or the up-crossings are under-counted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .._checks import positive
from .._io import readonly
from ..errors import TapmError

__all__ = ["ReliabilityError", "ReliabilityMonitor", "ReliabilityState", "ReliabilityRecord",
           "causal_reliability", "gumbel_k", "monitor_for", "monitor_signals", "line_signal", "RISER_TOP",
           "RISER_BOTTOM", "LP_WINDOW_DEFAULT",
           "SIGMA_WINDOW_DEFAULT", "N_MAXIMA_FLOOR"]

#: Width of the moving average that defines the low-frequency mean r_m [s].
LP_WINDOW_DEFAULT = 100.0
#: Trailing window of the wave-frequency standard deviation and up-crossing count [s].
SIGMA_WINDOW_DEFAULT = 600.0
#: Fewest maxima the Gumbel factor is evaluated for (k(2) = 1.67).
N_MAXIMA_FLOOR = 2.0

_REL_EPS = 1e-9       # relative time tolerance (window edges on a float grid)
_ZERO_REL = 1e-10     # |w| below this fraction of |x| counts as 0 when looking for up-crossings


class ReliabilityError(TapmError, ValueError):
    """Bad settings or samples of the reliability estimator."""


def gumbel_k(n: float | np.ndarray) -> float | np.ndarray:
    """Extreme-value factor ``k = sqrt(2 ln n) + gamma_E / sqrt(2 ln n)`` of a narrow-band Gaussian
    process with ``n`` individual maxima in the considered period (Gumbel asymptote, [R] §2.2;
    gamma_E = 0.5772157 the Euler-Mascheroni constant). n = 1000 gives k = 3.872.

    Parameters
    ----------
    n : float or ndarray
        Number(s) of maxima, each > 1 and finite.

    Returns
    -------
    float or ndarray
        k [-], a float for a scalar ``n``.
    """
    a = np.asarray(n, dtype=float)
    if not np.all(np.isfinite(a) & (a > 1)):
        bad = a[~(np.isfinite(a) & (a > 1))].ravel()[0] if a.ndim else a
        raise ReliabilityError(f"gumbel_k needs more than one maximum, got n = {float(bad)!r}")
    k = _k_unchecked(a)
    return float(k) if k.ndim == 0 else k


def _k_unchecked(n: np.ndarray) -> np.ndarray:
    s = np.sqrt(2.0 * np.log(n))
    return s + float(np.euler_gamma) / s


# -- state objects ------------------------------------------------------------------------------

@dataclass(frozen=True, kw_only=True)
class ReliabilityState:
    """The estimate after one :meth:`ReliabilityMonitor.update`; arrays are read-only, shape (m,).

    Attributes
    ----------
    t : float
        Time of the latest sample [s].
    names : tuple of str
        Signal names.
    x_lf : ndarray
        Low-frequency mean r_m (trailing average) [unit of the signal].
    sigma : ndarray
        Standard deviation of the wave-frequency part over the sigma window [unit of the signal].
    n : ndarray
        Maxima in the exposure period (up-crossings scaled to it) [-]; 0 while none is known.
    k : ndarray
        Gumbel factor for max(n, 2) maxima [-].
    delta : ndarray
        Reliability index (r_t - x_lf - k sigma) / sigma_t [-].
    span : float
        Time the sigma window covers so far [s] (= sigma_window once filled on a regular grid).
    ready : bool
        True once the sigma window has been filled; before that the numbers rest on less data.
    """

    t: float
    names: tuple[str, ...]
    x_lf: np.ndarray
    sigma: np.ndarray
    n: np.ndarray
    k: np.ndarray
    delta: np.ndarray
    span: float
    ready: bool

    def __post_init__(self) -> None:
        for f in ("x_lf", "sigma", "n", "k", "delta"):
            object.__setattr__(self, f, readonly(getattr(self, f)))

    @property
    def delta_min(self) -> float:
        """The smallest index over the signals [-] (survey eq. 33)."""
        return float(self.delta.min())

    def allowance(self) -> dict[str, float]:
        """The extreme allowance ``k sigma`` of every signal by name [unit of the signal]: what the
        setpoint optimisation and the MPC's reliability constraints subtract from the threshold."""
        return {nm: float(v) for nm, v in zip(self.names, np.nan_to_num(self.k * self.sigma))}

    @property
    def worst(self) -> str:
        """Name of the signal with the smallest index."""
        return self.names[int(np.argmin(self.delta))]


def _state_of_new_arrays(**fields: Any) -> ReliabilityState:
    """The :class:`ReliabilityState` of ``fields`` whose arrays (``x_lf``, ``sigma``, ``n``, ``k``,
    ``delta``: float64, made here and held by nobody else) are made read-only in place instead of
    copied: the same state the constructor gives, without its five copies per update."""
    st = object.__new__(ReliabilityState)
    for name in _STATE_ARRAYS:
        fields[name].flags.writeable = False
    for name, v in fields.items():
        object.__setattr__(st, name, v)
    return st


_STATE_ARRAYS = ("x_lf", "sigma", "n", "k", "delta")


@dataclass(frozen=True, kw_only=True)
class ReliabilityRecord:
    """:func:`causal_reliability` over a record: the :class:`ReliabilityState` fields at every
    sample. Arrays are read-only; ``t``, ``span``, ``ready`` have shape (N,), the others (N, m)."""

    t: np.ndarray
    names: tuple[str, ...]
    x_lf: np.ndarray
    sigma: np.ndarray
    n: np.ndarray
    k: np.ndarray
    delta: np.ndarray
    span: np.ndarray
    ready: np.ndarray

    def __post_init__(self) -> None:
        for f in ("t", "x_lf", "sigma", "n", "k", "delta", "span"):
            object.__setattr__(self, f, readonly(getattr(self, f)))
        object.__setattr__(self, "ready", readonly(self.ready, dtype=bool))

    def __getitem__(self, name: str) -> np.ndarray:
        """delta (N,) of the signal called ``name``."""
        try:
            return self.delta[:, self.names.index(name)]
        except ValueError:
            raise ReliabilityError(f"no signal {name!r}; signals are {', '.join(self.names)}") from None


# -- compiled arithmetic of the monitor's step (numba; the numpy expressions' operations in their
# order, element by element: the same numbers) ------------------------------------------------------

def _integral_py(C, X, ts, j, n_hi, tau):
    """:meth:`ReliabilityMonitor._integral` on the raw buffer's storage (``j``, ``n_hi``: storage
    rows of the segment and of one past the newest sample)."""
    m = C.shape[1]
    out = np.empty(m)
    if j + 1 >= n_hi:
        for k in range(m):
            out[k] = C[j, k]
        return out
    tj = ts[j]
    h = ts[j + 1] - tj
    if h <= 0:
        for k in range(m):
            out[k] = C[j, k]
        return out
    s = tau - tj            # min(max(tau - tj, 0.0), h)
    if 0.0 > s:
        s = 0.0
    if h < s:
        s = h
    ss = s * s
    for k in range(m):
        xj = X[j, k]
        slope = (X[j + 1, k] - xj) / h
        out[k] = (C[j, k] + xj * s) + (0.5 * slope) * ss
    return out


def _lf_py(C, X, ts, c_new, j, n_hi, tau, W):
    """``(C_new - integral) / W``: the trailing average."""
    I = _integral_k(C, X, ts, j, n_hi, tau)
    out = np.empty(I.shape[0])
    for k in range(I.shape[0]):
        out[k] = (C[c_new, k] - I[k]) / W
    return out


def _residual_py(C, X, ts, j_hi, tau_hi, j_lo, tau_lo, n_hi, q, W, zero_rel):
    """The centred residual ``w = x_q - c`` and its zero scale ``zero_rel max(|x_q|, |c|)``."""
    I_hi = _integral_k(C, X, ts, j_hi, n_hi, tau_hi)
    I_lo = _integral_k(C, X, ts, j_lo, n_hi, tau_lo)
    m = I_hi.shape[0]
    w = np.empty(m)
    scale = np.empty(m)
    for k in range(m):
        c = (I_hi[k] - I_lo[k]) / W
        xq = X[q, k]
        w[k] = xq - c
        a, b = abs(xq), abs(c)
        scale[k] = zero_rel * (a if (a >= b or a != a) else b)   # np.maximum (nan propagates)
    return w, scale


def _wf_terms_py(wp, w, h, negp, scale, S1, S2, cnt):
    """:meth:`ReliabilityMonitor._push_wf`'s segment terms after the first residual; the window
    sums updated in place."""
    m = w.shape[0]
    neg = np.empty(m, np.bool_)
    up = np.empty(m, np.bool_)
    a1 = np.empty(m)
    a2 = np.empty(m)
    for k in range(m):
        ng = w[k] < -scale[k]
        neg[k] = ng
        a1[k] = 0.5 * (wp[k] + w[k]) * h
        a2[k] = 0.5 * (wp[k] * wp[k] + w[k] * w[k]) * h
        u = negp[k] and not ng
        up[k] = u
        S1[k] += a1[k]
        S2[k] += a2[k]
        if u:
            cnt[k] += 1
    return neg, a1, a2, up


def _stats_py(S1, S2, cnt, span, q, floor):
    """sigma, n and max(n, floor) of the window sums (``q = exposure / span``)."""
    m = S1.shape[0]
    sig = np.empty(m)
    n = np.empty(m)
    nf = np.empty(m)
    for k in range(m):
        mean = S1[k] / span
        v = S2[k] / span - mean * mean
        sig[k] = math.sqrt(v if (v >= 0.0 or v != v) else 0.0)
        nk = cnt[k] * q
        n[k] = nk
        nf[k] = nk if (nk >= floor or nk != nk) else floor
    return sig, n, nf


def _delta_py(r_t, lf, k_, sig, sigma_t):
    m = lf.shape[0]
    out = np.empty(m)
    for k in range(m):
        out[k] = ((r_t[k] - lf[k]) - k_[k] * sig[k]) / sigma_t[k]
    return out


def _compiled_kernels() -> Any:
    from .._jit import jit

    global _integral_k
    ik = jit(_integral_py, fallback=None)
    if ik is None:
        return None
    _integral_k = ik
    return (ik, jit(_lf_py), jit(_residual_py), jit(_wf_terms_py), jit(_stats_py), jit(_delta_py))


_integral_k: Any = _integral_py
_KERNELS: Any = False   # built on first use (None: no numba, the numpy expressions)


def _kernels() -> Any:
    global _KERNELS
    if _KERNELS is False:
        _KERNELS = _compiled_kernels()
    return _KERNELS


# -- a first-in first-out row store --------------------------------------------------------------

class _Fifo:
    """Rows addressed by absolute index; push at the end, drop from the front, amortised O(1).

    When the storage is full it either slides the kept rows to the front (when at most half of it
    is in use) or doubles; ``push`` returns True when rows moved, so the owner can refresh what it
    derives from them."""

    def __init__(self, fields: dict[str, tuple[tuple[int, ...], Any]], cap: int = 64):
        self._fields = fields
        self.cap = cap
        self.a = {k: np.empty((cap, *shape), dtype) for k, (shape, dtype) in fields.items()}
        self.base = 0  # absolute index of storage row 0
        self.lo = 0    # oldest kept row
        self.hi = 0    # one past the newest
        self.moved = 0  # rows copied by compaction so far

    def __len__(self) -> int:
        return self.hi - self.lo

    def push(self, **row: Any) -> bool:
        moved = False
        if self.hi - self.base == self.cap:
            n = self.hi - self.lo
            if 2 * n > self.cap:
                self.cap *= 2
            src = slice(self.lo - self.base, self.hi - self.base)
            for k, (shape, dtype) in self._fields.items():
                new = np.empty((self.cap, *shape), dtype)
                new[:n] = self.a[k][src]
                self.a[k] = new
            self.base = self.lo
            self.moved += n
            moved = True
        i = self.hi - self.base
        for k, v in row.items():
            self.a[k][i] = v
        self.hi += 1
        return moved

    def view(self, name: str, i: int) -> Any:
        return self.a[name][i - self.base]

    def kept(self, name: str) -> np.ndarray:
        return self.a[name][self.lo - self.base:self.hi - self.base]


# -- the estimator -------------------------------------------------------------------------------

def _positive(name: str, v: Any) -> float:
    return positive(name, v, unit="s", error=ReliabilityError)


class ReliabilityMonitor:
    """Streaming reliability index of ``m`` response signals (module docstring).

    Parameters
    ----------
    r_t : array_like, shape (m,)
        Thresholds: the mean breaking strength T_b of a line [N], the mean critical angle of a riser
        end [rad], ... (survey eq. 32; [R] §2.2), in the unit of the signal.
    sigma_t : array_like, shape (m,)
        Standard deviations of the thresholds (sigma_b of the breaking strength [N], of the critical
        angle [rad]), each > 0.
    names : sequence of str, optional
        Signal names (default ``"0"``, ``"1"``, ...), unique.
    lp_window : float
        Width of the moving average defining the low-frequency mean [s] (default 100).
    sigma_window : float
        Trailing window of sigma and of the up-crossing count [s] (default 600).
    exposure : float, optional
        Period the maxima are counted for [s] (default ``sigma_window``): n = count * exposure / span.

    Raises
    ------
    ReliabilityError
        A setting is not finite or out of range, or the shapes disagree.

    Notes
    -----
    Cost: each :meth:`update` does O(m) numpy work plus pointer moves and row pushes/drops whose
    number, amortised, is bounded independently of the windows (:attr:`inner_steps`); the buffers
    hold only the samples of the windows (:attr:`held_samples`, :attr:`held_wf_samples`).
    """

    def __init__(self, r_t: Sequence[float] | np.ndarray, sigma_t: Sequence[float] | np.ndarray, *,
                 names: Sequence[str] | None = None, lp_window: float = LP_WINDOW_DEFAULT,
                 sigma_window: float = SIGMA_WINDOW_DEFAULT, exposure: float | None = None):
        r = np.array(r_t, dtype=float, ndmin=1)
        s = np.array(sigma_t, dtype=float, ndmin=1)
        if r.ndim != 1 or r.size == 0:
            raise ReliabilityError(f"r_t must be a non-empty vector (m,), got shape {r.shape}")
        if s.shape != r.shape:
            raise ReliabilityError(f"sigma_t has shape {s.shape}, r_t {r.shape}: one per signal")
        m = r.size
        if names is None:
            names = [str(j) for j in range(m)]
        names = tuple(str(nm) for nm in names)
        if len(names) != m:
            raise ReliabilityError(f"names has {len(names)} entries for {m} signals")
        if len(set(names)) != m:
            raise ReliabilityError(f"names must be unique, got {list(names)}")
        for j in range(m):
            if not math.isfinite(r[j]):
                raise ReliabilityError(f"r_t[{j}] ({names[j]!r}) = {float(r[j])!r} must be finite")
            if not (math.isfinite(s[j]) and s[j] > 0):
                raise ReliabilityError(f"sigma_t[{j}] ({names[j]!r}) = {float(s[j])!r} must be a positive number "
                                       "(the index divides by it)")
        self.names: tuple[str, ...] = names
        self.m = m
        self.r_t = readonly(r)
        self.sigma_t = readonly(s)
        self.lp_window = _positive("lp_window", lp_window)
        self.sigma_window = _positive("sigma_window", sigma_window)
        self.exposure = self.sigma_window if exposure is None else _positive("exposure", exposure)
        self.reset()

    # -- public ---------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget every sample (the next :meth:`update` starts a new record)."""
        m = self.m
        self._raw = _Fifo({"t": ((), float), "x": ((m,), float), "C": ((m,), float)})
        self._wf = _Fifo({"t": ((), float), "w": ((m,), float), "neg": ((m,), bool),
                          "a1": ((m,), float), "a2": ((m,), float), "up": ((m,), bool)})
        self._t0 = math.nan
        self._t_last = -math.inf
        self._C0 = np.zeros(m)
        self._p_tail = 0   # raw segment holding t - lp_window
        self._q = 0        # next raw sample whose centred residual is pending
        self._p_lo = 0     # raw segment holding t_q - lp_window/2
        self._p_hi = 0     # raw segment holding t_q + lp_window/2
        self._S1 = np.zeros(m)  # integral of w over the sigma window
        self._S2 = np.zeros(m)  # integral of w^2
        self._cnt = np.zeros(m, np.int64)  # up-crossings in the window
        self._t_wf_first = math.nan
        self._steps = 0
        self._updates = 0

    def update(self, t: float, x: Sequence[float] | np.ndarray) -> ReliabilityState:
        """Feed the latest sample; returns the estimate at ``t``.

        Parameters
        ----------
        t : float
            Time [s], not before the previous sample's (equal times are a zero-length step).
        x : array_like, shape (m,)
            Latest measured values of the signals, finite.

        Raises
        ------
        ReliabilityError
            ``t`` is not finite or goes backwards, ``x`` has the wrong shape or a non-finite value.
        """
        t, xv = self._check(t, x)
        lf, sig, n, k, delta, span, ready = self._step(t, xv)
        return _state_of_new_arrays(t=t, names=self.names, x_lf=lf, sigma=sig, n=n, k=k, delta=delta,
                                    span=span, ready=ready)

    @property
    def inner_steps(self) -> int:
        """Work units done since :meth:`reset`: pointer moves, residual rows pushed and dropped, rows
        copied when a buffer is compacted or its sums refreshed. Bounded by a constant times the
        number of updates, whatever the windows (the cost is O(1) amortised per update)."""
        return self._steps + self._raw.moved + self._wf.moved

    @property
    def updates(self) -> int:
        """Samples fed since :meth:`reset`."""
        return self._updates

    @property
    def held_samples(self) -> int:
        """Raw samples buffered (those the moving averages still need, ~ lp_window / dt + 2)."""
        return len(self._raw)

    @property
    def held_wf_samples(self) -> int:
        """Wave-frequency residuals in the sigma window (~ sigma_window / dt + 1)."""
        return len(self._wf)

    # -- internals ------------------------------------------------------------------------------
    def _check(self, t: Any, x: Any) -> tuple[float, np.ndarray]:
        try:
            tf = float(t)
        except (TypeError, ValueError):
            raise ReliabilityError(f"t = {t!r} must be a time in seconds") from None
        if not math.isfinite(tf):
            raise ReliabilityError(f"t = {t!r} s must be finite")
        if tf < self._t_last:
            raise ReliabilityError(f"t = {tf!r} s goes back before the previous sample at {self._t_last!r} s")
        try:
            xv = np.asarray(x, dtype=float)
        except (TypeError, ValueError):
            raise ReliabilityError(f"x = {x!r} at t = {tf:g} s must be {self.m} number(s)") from None
        if xv.ndim == 0 and self.m == 1:
            xv = xv.reshape(1)
        if xv.shape != (self.m,):
            raise ReliabilityError(f"x has shape {xv.shape} at t = {tf:g} s; expected ({self.m},), one value per "
                                   f"signal ({', '.join(self.names)})")
        if not (math.isfinite(float(xv.sum())) or np.isfinite(xv).all()):   # a finite sum: all finite
            j = int(np.flatnonzero(~np.isfinite(xv))[0])
            raise ReliabilityError(f"x[{j}] ({self.names[j]!r}) = {float(xv[j])!r} at t = {tf:g} s is not finite")
        return tf, xv

    def _advance(self, j: int, tau: float) -> int:
        """Last raw sample index >= j with t_j <= tau (monotone pointer)."""
        R = self._raw
        ts = R.a["t"]
        b = R.base
        while j + 1 < R.hi and ts[j + 1 - b] <= tau:
            j += 1
            self._steps += 1
        return j

    def _integral(self, j: int, tau: float) -> np.ndarray:
        """Integral (m,) from the buffer origin to tau of the piecewise-linear signal, tau in segment j."""
        R = self._raw
        b = R.base
        tj = R.a["t"][j - b]
        Cj = R.a["C"][j - b]
        if j + 1 >= R.hi:
            return Cj.copy()
        h = R.a["t"][j + 1 - b] - tj
        if h <= 0:
            return Cj.copy()
        s = min(max(tau - tj, 0.0), h)
        xj = R.a["x"][j - b]
        slope = (R.a["x"][j + 1 - b] - xj) / h
        return Cj + xj * s + 0.5 * slope * (s * s)

    def _push_wf(self, tw: float, w: np.ndarray, scale: np.ndarray) -> None:
        F = self._wf
        kern = _kernels()
        if len(F) and kern is not None:   # the compiled terms, the window sums updated in place
            i = F.hi - 1 - F.base
            h = tw - F.a["t"][i]
            neg, a1, a2, up = kern[3](F.a["w"][i], w, h, F.a["neg"][i], scale, self._S1, self._S2, self._cnt)
        else:
            neg = w < -scale  # |w| <= scale counts as 0 (rounding of a residual that is exactly 0)
            if len(F):
                i = F.hi - 1 - F.base
                tp, wp = F.a["t"][i], F.a["w"][i]
                h = tw - tp
                a1 = 0.5 * (wp + w) * h
                a2 = 0.5 * (wp * wp + w * w) * h
                up = F.a["neg"][i] & ~neg
            else:
                self._t_wf_first = tw
                a1 = a2 = np.zeros(self.m)
                up = np.zeros(self.m, bool)
            self._S1 += a1
            self._S2 += a2
            self._cnt += up
        self._steps += 1
        if F.push(t=tw, w=w, neg=neg, a1=a1, a2=a2, up=up):
            self._refresh_sums()
        # drop residuals older than the window; row i holds the segment (i-1, i)
        lim = tw - self.sigma_window - _REL_EPS * max(1.0, abs(tw))
        ts = F.a["t"]
        while F.hi - F.lo > 1 and ts[F.lo - F.base] < lim:
            F.lo += 1
            i = F.lo - F.base
            self._S1 -= F.a["a1"][i]
            self._S2 -= F.a["a2"][i]
            self._cnt -= F.a["up"][i]
            self._steps += 1

    def _refresh_sums(self) -> None:
        """Recompute the window sums from the kept rows (removes the drift of running sums)."""
        F = self._wf
        seg = slice(F.lo + 1 - F.base, F.hi - F.base)
        self._S1 = F.a["a1"][seg].sum(axis=0)
        self._S2 = F.a["a2"][seg].sum(axis=0)
        self._cnt = F.a["up"][seg].sum(axis=0)
        self._steps += F.hi - F.lo

    def _rebase(self) -> None:
        """Make the cumulative integrals relative to the oldest kept sample (bounded magnitudes)."""
        R = self._raw
        c = R.a["C"][R.lo - R.base].copy()
        R.kept("C")[:] -= c
        self._C0 = self._C0 - c
        self._steps += len(R)

    def _step(self, t: float, x: np.ndarray):
        R = self._raw
        W = self.lp_window
        half = 0.5 * W
        self._updates += 1
        if R.hi == R.lo:  # first sample of the record
            self._t0 = t
            R.push(t=t, x=x, C=np.zeros(self.m))
            self._C0 = np.zeros(self.m)
            j0 = R.lo
            self._p_tail = self._q = self._p_lo = self._p_hi = j0
            C_new = self._C0
        else:
            i = R.hi - 1 - R.base
            C_new = R.a["C"][i] + 0.5 * (R.a["x"][i] + x) * (t - R.a["t"][i])
            if R.push(t=t, x=x, C=C_new):
                self._rebase()
            C_new = R.a["C"][R.hi - 1 - R.base]
        self._t_last = t
        t0 = self._t0
        eps = _REL_EPS * max(1.0, abs(t))
        kern = _kernels()

        # r_m: trailing average over [t - W, t] (the record so far until it spans W)
        if t - t0 >= W - eps:
            tau = t - W
            self._p_tail = self._advance(self._p_tail, tau)
            if kern is not None:
                lf = kern[1](R.a["C"], R.a["x"], R.a["t"], R.hi - 1 - R.base, self._p_tail - R.base, R.hi - R.base,
                             max(tau, t0), W)
            else:
                lf = (C_new - self._integral(self._p_tail, max(tau, t0))) / W
        elif t > t0:
            lf = (C_new - self._C0) / (t - t0)
        else:
            lf = x.copy()

        # centred residuals that have become computable: t_q + W/2 <= t
        ts = R.a["t"]
        while self._q < R.hi:
            tq = float(ts[self._q - R.base])
            if tq + half > t + eps:
                break
            if tq - half >= t0 - eps:
                self._p_lo = self._advance(self._p_lo, tq - half)
                self._p_hi = self._advance(max(self._p_hi, self._p_lo), tq + half)
                if kern is not None:
                    b = R.base
                    w, scale = kern[2](R.a["C"], R.a["x"], R.a["t"], self._p_hi - b, min(tq + half, t),
                                       self._p_lo - b, max(tq - half, t0), R.hi - b, self._q - b, W, _ZERO_REL)
                    self._push_wf(tq, w, scale)
                else:
                    c = (self._integral(self._p_hi, min(tq + half, t))
                         - self._integral(self._p_lo, max(tq - half, t0))) / W
                    xq = R.a["x"][self._q - R.base]
                    self._push_wf(tq, xq - c, _ZERO_REL * np.maximum(np.abs(xq), np.abs(c)))
            self._q += 1
            self._steps += 1
        # keep only what the averages still need (t0 until the first full window)
        R.lo = max(R.lo, min(self._p_tail, self._p_lo, self._q))

        # statistics of the sigma window
        F = self._wf
        if len(F) >= 2:
            span = float(F.a["t"][F.hi - 1 - F.base] - F.a["t"][F.lo - F.base])
        else:
            span = 0.0
        if span > 0 and kern is not None:
            sig, n, n_floor = kern[4](self._S1, self._S2, self._cnt, span, self.exposure / span, N_MAXIMA_FLOOR)
            k = _k_unchecked(n_floor)
            delta = kern[5](self.r_t, lf, k, sig, self.sigma_t)
        else:
            if span > 0:
                mean = self._S1 / span
                sig = np.sqrt(np.maximum(self._S2 / span - mean * mean, 0.0))
                n = self._cnt * (self.exposure / span)
            else:
                sig = np.zeros(self.m)
                n = np.zeros(self.m)
            k = _k_unchecked(np.maximum(n, N_MAXIMA_FLOOR))  # gumbel_k; the floor keeps n > 1
            delta = (self.r_t - lf - k * sig) / self.sigma_t
        ready = bool(len(F) and (F.a["t"][F.hi - 1 - F.base] - self._t_wf_first
                                 >= self.sigma_window - _REL_EPS * max(1.0, abs(t))))
        return lf, sig, n, k, delta, span, ready


def causal_reliability(t: Sequence[float] | np.ndarray, X: Sequence[Sequence[float]] | np.ndarray,
                       r_t: Sequence[float] | np.ndarray, sigma_t: Sequence[float] | np.ndarray, *,
                       names: Sequence[str] | None = None, lp_window: float = LP_WINDOW_DEFAULT,
                       sigma_window: float = SIGMA_WINDOW_DEFAULT,
                       exposure: float | None = None) -> ReliabilityRecord:
    """Run :class:`ReliabilityMonitor` over a record: the on-line estimate at every sample.

    The numbers are those of feeding the samples one by one to :meth:`ReliabilityMonitor.update`
    (the same code), so the value at sample i depends on samples 0..i only.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times [s], finite and non-decreasing.
    X : array_like, shape (N, m) or (N,)
        Signal values (a 1-D ``X`` is one signal), finite.
    r_t, sigma_t, names, lp_window, sigma_window, exposure
        As for :class:`ReliabilityMonitor`.

    Returns
    -------
    ReliabilityRecord
        ``x_lf``, ``sigma``, ``n``, ``k``, ``delta`` (N, m); ``span``, ``ready`` (N,).

    Raises
    ------
    ReliabilityError
        Bad settings, shapes, non-finite values or times going backwards (naming the sample).
    """
    mon = ReliabilityMonitor(r_t, sigma_t, names=names, lp_window=lp_window, sigma_window=sigma_window,
                             exposure=exposure)
    tv = np.asarray(t, dtype=float)
    Xv = np.asarray(X, dtype=float)
    if Xv.ndim == 1:
        Xv = Xv[:, None]
    if tv.ndim != 1 or Xv.ndim != 2 or Xv.shape != (tv.size, mon.m):
        raise ReliabilityError(f"t has shape {tv.shape} and X {np.shape(X)}; expected (N,) and (N, {mon.m})")
    N, m = Xv.shape
    bad = ~np.isfinite(tv)
    back = np.zeros(N, bool)
    back[1:] = tv[1:] < tv[:-1]
    bad |= back | ~np.all(np.isfinite(Xv), axis=1)
    if bad.any():  # let the streaming check word the error of the first bad sample
        i = int(np.flatnonzero(bad)[0])
        if i:
            mon._t_last = float(tv[i - 1])
        mon._check(tv[i], Xv[i])
    out = {f: np.empty((N, m)) for f in ("x_lf", "sigma", "n", "k", "delta")}
    span = np.empty(N)
    ready = np.zeros(N, bool)
    for i in range(N):
        lf, sig, n, k, delta, sp, rd = mon._step(float(tv[i]), Xv[i])
        out["x_lf"][i], out["sigma"][i], out["n"][i], out["k"][i], out["delta"][i] = lf, sig, n, k, delta
        span[i] = sp
        ready[i] = rd
    return ReliabilityRecord(t=tv, names=mon.names, span=span, ready=ready, **out)


#: Signal names of the riser's two ends in :func:`monitor_for`'s monitor.
RISER_TOP, RISER_BOTTOM = "riser top", "riser bottom"


def line_signal(line_id: str) -> str:
    """Signal name of a line's tension in :func:`monitor_for`'s monitor."""
    return f"line {line_id}"


def monitor_for(scenario: Any, **settings: Any) -> ReliabilityMonitor:
    """The monitor of a scenario's measured signals, in the order the estimators feed them: every
    line's fairlead tension (scenario order; ``r_t`` = MBS, ``sigma_t`` = MBS_std — a line without
    one gets ``sigma_t`` = 1 N and its index means nothing: consumers skip lines with MBS_std = 0),
    then, with a riser, the magnitudes of its top and bottom angles (``r_t`` = the mean critical
    angles, ``sigma_t`` their standard deviations). Names ``"line <id>"``, ``"riser top"``,
    ``"riser bottom"``; ``settings`` go to :class:`ReliabilityMonitor`."""
    la = scenario.line_arrays
    r_t = list(np.asarray(la["MBS"], float))
    s_t = [v if v > 0 else 1.0 for v in np.asarray(la["MBS_std"], float)]
    names = [line_signal(ln.id) for ln in scenario.lines]
    rs = scenario.riser
    if rs is not None:
        r_t += [rs.critical_top_angle, rs.critical_bottom_angle]
        s_t += [rs.critical_top_angle_std, rs.critical_bottom_angle_std]
        names += [RISER_TOP, RISER_BOTTOM]
    return ReliabilityMonitor(np.array(r_t), np.array(s_t), names=names, **settings)


def monitor_signals(tensions: Any, riser_angles: Any, m: int) -> np.ndarray:
    """The vector :func:`monitor_for`'s monitor takes: the tensions, then (when the monitor has two
    more signals) the magnitudes of the top and bottom riser angles from ``riser_angles`` =
    (top_x, top_y, bottom_x, bottom_y) [rad] (zeros if there are none)."""
    T = np.asarray(tensions, float)
    if m == T.size:
        return T
    ra = np.zeros(4) if riser_angles is None else np.asarray(riser_angles, float)
    return np.concatenate([T, [math.hypot(ra[0], ra[1]), math.hypot(ra[2], ra[3])]])
