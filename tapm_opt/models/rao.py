"""First-order wave-frequency motion transfer functions (RAOs): closed-form heave, roll and pitch
of a ship-shaped hull (Jensen, Mansour & Olsen 2004), and RAO tables a user brings (CSV or
WAMIT ``.4``).

Conventions
-----------
Frames and degrees of freedom
    NED body frame {B}: x forward, y starboard, z down. Degrees of freedom in the order surge,
    sway, heave, roll, pitch, yaw (index 0..5, :data:`DOFS`). Heave is positive DOWN, roll
    positive starboard side down, pitch positive bow UP, yaw positive bow to starboard.
    Translations in m, rotations in rad, about the motion reference point: the hull's body origin
    at the waterline (midships for the closed form).
Wave and motion
    The wave elevation (positive up) at the reference point is ``zeta(t) = Re(a exp(i theta))``,
    ``theta = omega t + phi``. A motion is ``x_j(t) = Re(H_j(omega, beta) a exp(i theta))``: ``H``
    is complex per unit wave amplitude [m/m or rad/m]. Deep water, ``k = omega^2 / g``.
Heading
    ``beta`` is the direction the waves GO TO relative to the bow, measured from x (bow) toward y
    (starboard): ``beta = 0`` following seas, ``beta = pi`` head seas, ``beta = pi/2`` waves
    travelling toward starboard (coming from port). The elevation at a point (x, y) of {B} is
    ``Re(a exp(i (theta - k x cos(beta) - k y sin(beta))))``.
Long-wave limits (the hull follows the surface)
    The surface slope along x at the reference point is ``a k cos(beta) sin(theta)`` and along y
    ``a k sin(beta) sin(theta)``. A hull that follows the surface has heave ``-zeta`` (z down):
    ``H_heave -> -1``; its bow rises with a positive x slope (pitch bow up = +slope):
    ``H_pitch -> -i k cos(beta)`` (``sin(theta) = Re(-i exp(i theta))``); its starboard side rises
    with a positive y slope (roll starboard down = -slope): ``H_roll -> +i k sin(beta)``, for
    frequencies well below the roll resonance.

Closed form (:func:`closed_form_rao`)
-------------------------------------
J.J. Jensen, A.E. Mansour, A.S. Olsen, "Estimation of ship motions using closed-form
expressions", Ocean Engineering 31 (2004) 61-85 ("JMO" below). Heave and pitch are those of a
homogeneously loaded box of length ``L``, draught ``T`` and equivalent breadth ``B = C_B B_0``
(the block coefficient ``C_B`` times the moulded breadth ``B_0``, which keeps the displacement),
in strip theory with the sectional added mass ``rho B T`` and the sectional wave damping from the
radiated-wave amplitude ratio ``A``::

    alpha = 1 - Fn sqrt(k L) cos(beta) = omega_e / omega,  omega_e = omega - k U cos(beta)
    k_e   = |k cos(beta)|                   effective wave number along the hull
    A     = 2 sin(k B alpha^2 / 2) exp(-k T alpha^2)
    f     = sqrt((1 - k T)^2 + (A^2 / (k B alpha^3))^2)
    kappa = exp(-k_e T)                     Smith correction
    F     = kappa f (2 / (k_e L)) sin(k_e L / 2)
    G     = kappa f (24 / ((k_e L)^2 L)) (sin(k_e L / 2) - (k_e L / 2) cos(k_e L / 2))
    eta   = 1 / sqrt((1 - 2 k T alpha^2)^2 + (A^2 / (k B alpha^2))^2)   resonance factor
    |heave| = eta |F| [m/m],  |pitch| = eta |G| [rad/m]

The natural frequency ``omega_e^2 = g / (2 T)`` and the damping of ``eta`` are those of the box
(mass plus added mass ``2 rho B T``, restoring ``rho g B`` per unit length).

Sources: the formulas above are JMO's closed-form box model; equation numbers are not quoted
because they could not be checked against the printed paper. They agree term by term with two
public transcriptions: Fossen's MSS ``waveresponse345`` (whose documented example the tests
reproduce, heave 2.2193 m and pitch 1.3411 deg for a 2 m wave) and NetSSE's ``heaveCF`` /
``pitchCF`` (Mounet & Nielsen, DTU), which differ only in taking ``kappa = exp(-k T)``; this
module follows MSS in ``kappa = exp(-k_e T)``.

Phase (the paper gives amplitudes only). ASSUMPTION: the complex value is the one-degree-of-
freedom strip-theory form whose modulus is the amplitude above: the relative-motion exciting
force ``kappa (1 - k T + i A^2 / (k B alpha^3))`` per unit length and unit wave, integrated with
the wave ``exp(-i k cos(beta) x)`` along the hull, over the impedance
``1 - 2 k T alpha^2 + i A^2 / (k B alpha^2)`` (time factor ``exp(i omega_e t)``)::

    H_heave = -kappa ftilde etatilde sinc(k_c L / 2)
    H_pitch = -i kappa ftilde etatilde k_c J(k_c L / 2)
    ftilde = 1 - k T + i A^2 / (k B alpha^3),  etatilde = 1 / (1 - 2 k T alpha^2 + i A^2 / (k B alpha^2))
    k_c = k cos(beta),  sinc(s) = sin(s) / s,  J(s) = 3 (sin s - s cos s) / s^3

``|H_heave| = eta |F|`` and ``|H_pitch| = eta |G|`` exactly (``k_c J(k_c L / 2) = G / (kappa f)``
with the sign of ``cos(beta)``). The leading minus of heave is z down; the ``-i`` of pitch is the
x slope of the wave integrated with the lever arm ``x`` (bow up positive).

Roll. ASSUMPTION, NOT the paper's roll: JMO (as transcribed in NetSSE's ``rollCF``) derive the
roll exciting moment from the wave radiation damping of box sections through the Haskind
relation, with a damping fitted as ``a exp(b omega^-1.3) omega^d`` (b < 0) that vanishes
exponentially in long waves, so their roll tends to 0, not to the wave slope, as
``omega -> 0``. Here roll keeps JMO's one-degree-of-freedom roll equation (restoring
``C44 = rho g nabla GM_T``, natural period ``T_4``, total damping ``2 zeta_4`` of critical, i.e.
the denominator ``(1 - (omega_e T_4 / 2 pi)^2) C44 + i omega_e B44``) and drives it with the
restoring moment of the wave slope averaged over the waterplane::

    H_roll = i k sin(beta) sinc(k_c L / 2) J(k_s B_w / 2) / (1 - (omega_e/omega_4)^2 + 2 i zeta_4 omega_e/omega_4)
    k_s = k sin(beta),  B_w = C_WP B_0 (mean waterline breadth),  omega_4 = 2 pi / T_4

``zeta_4`` is the total equivalent linear roll damping ratio at resonance (wave radiation
included); the wave-slope moment is not reduced with depth (conservative). The roll long-wave
limit is ``+i k sin(beta)`` and the peak at ``omega_e = omega_4`` is ``k sin(beta) .../(2 zeta_4)``.

Known limitation of the paper's heave in beam seas: with ``k_e = 0`` the Smith factor is 1 and no
length averaging applies, so ``|H_heave| -> 1/2`` in short beam waves (it tends to 0 at every
other heading).

Tables (:class:`RAOTable`, :func:`read_rao_csv`, :func:`write_rao_csv`, :func:`read_wamit4`)
---------------------------------------------------------------------------------------------
CSV format. One header line, exactly these five columns (any order)::

    omega_rad_s,beta_deg,dof,amplitude,phase_deg

then one row per (frequency, heading, degree of freedom): ``omega_rad_s`` the wave frequency
[rad/s] > 0; ``beta_deg`` the heading [deg] in the convention above (taken modulo 360);
``dof`` one of ``surge, sway, heave, roll, pitch, yaw``; ``amplitude`` >= 0 in m/m for
translations and rad/m (radians per metre of wave amplitude) for rotations; ``phase_deg`` [deg],
with ``motion = amplitude a cos(theta + phase)``, i.e. ``H = amplitude exp(i phase)``. Every
(omega, beta) pair of the full omega x beta grid must have all six dofs: a missing dof is
refused, naming the pair and the dof. Blank lines are ignored; rows may come in any order.

WAMIT ``.4`` (motion RAO output): whitespace-separated rows ``PER BETA I Mod Pha Re Im``, with
``PER`` the wave period [s] (``PER <= 0`` are WAMIT's codes for zero and infinite period and are
refused), ``BETA`` the wave heading [deg], ``I`` the mode 1..6, and the nondimensional motion
``xi_I / A`` (translations) or ``xi_I / (A / ULEN)`` (rotations), in WAMIT's convention
``Re((Re + i Im) exp(i omega t))`` with the incident elevation ``Re(A exp(i omega t))`` at the
origin (WAMIT User Manual, ch. 3, eqs. 3.1-3.2). WAMIT's body frame is x forward, y to PORT,
z UP, rotations right-handed about those axes, and ``BETA`` is measured from x toward y (port).
Our frame is WAMIT's turned by pi about x (y and z reversed), so, with the same time factor and
phase reference:

======  ==========================================================  ======
mode    reason                                                      sign
======  ==========================================================  ======
surge   x is the same                                               +1
sway    y to starboard = -y to port                                 -1
heave   z down = -z up                                              -1
roll    about x: WAMIT's roll lifts the port side = starboard down  +1
pitch   about y (port): WAMIT's positive pitch puts the bow down    -1
yaw     about z up: WAMIT's positive yaw turns the bow to port      -1
======  ==========================================================  ======

and ``beta = -BETA`` (mod 360 deg): a wave going to port in WAMIT goes to -starboard here.
Rotations are divided by ``ULEN`` to rad/m.

Interpolation (:meth:`RAOTable.evaluate`)
    Real and imaginary parts are linear in omega between the table frequencies. Below the first
    frequency the first row is held: long waves change the response slowly and the hull follows
    the surface (rotations, proportional to ``k``, are small there). Above the last frequency the
    RAO is 0: a hull filters waves much shorter than itself, and the table does not say more, so
    a table should reach the frequency where its RAO has decayed. In beta the interpolation is
    linear and 2 pi periodic (between the last heading and the first + 2 pi); port/starboard
    symmetry is not assumed. A table with a single heading applies it to every heading.

Mean drift coefficients (:class:`DriftTable`, :func:`read_drift_csv`, :func:`write_drift_csv`, :func:`read_wamit_drift`)
-------------------------------------------------------------------------------------------------------------------------
The hull's mean (second-order) wave drift force in regular waves, per unit wave amplitude
squared: ``D_i(omega, beta)`` for surge, sway and yaw (:data:`DRIFT_DOFS`), in {B} and positive
along its axes (surge forward, sway to starboard [N/m^2], yaw bow to starboard [N m/m^2]), with
``beta`` in the heading convention above. A regular wave of amplitude ``a`` pushes the hull with
the constant force ``D_i a^2``.

CSV format. One header line, exactly these four columns (any order)::

    omega_rad_s,beta_deg,dof,D

then one row per (frequency, heading, degree of freedom): ``omega_rad_s`` > 0 [rad/s];
``beta_deg`` [deg] taken modulo 360; ``dof`` one of ``surge, sway, yaw``; ``D`` any finite
number [N/m^2 or N m/m^2]. Every (omega, beta) pair of the full omega x beta grid must have the
three dofs. Blank lines are ignored; rows may come in any order.

WAMIT ``.8`` (momentum conservation) and ``.9`` (pressure integration) mean drift output:
whitespace-separated rows ``PER BETA1 BETA2 I Mod Pha Re Im``, the mean drift of the wave pair
(BETA1, BETA2) nondimensional by ``rho g A^2 ULEN`` (forces) or ``rho g A^2 ULEN^2`` (moments).
Only the diagonal rows (BETA1 = BETA2, the mean drift of one wave train; its value is real, the
``Re`` column) of modes 1 (surge), 2 (sway) and 6 (yaw) are read; other modes (heave, roll,
pitch; WAMIT's negative, body-axes modes) and the off-diagonal pairs are skipped. The frame
change is that of the ``.4`` file: signs +1, -1, -1 for surge, sway, yaw, and ``beta = -BETA``.

Interpolation (:meth:`DriftTable.evaluate`) as :meth:`RAOTable.evaluate`: linear in omega,
the first row held below the table and 0 above it, linear and 2 pi periodic in beta.

Imports only numpy and the standard library (models layer; nothing from the plant or control).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ModelError

__all__ = [
    "DOFS",
    "DRIFT_DOFS",
    "DriftTable",
    "HullMotionParams",
    "RAOTable",
    "closed_form_rao",
    "read_drift_csv",
    "read_rao_csv",
    "read_wamit4",
    "read_wamit_drift",
    "write_drift_csv",
    "write_rao_csv",
]

#: Degrees of freedom, in the order of the last axis of a 6-dof RAO.
DOFS: tuple[str, ...] = ("surge", "sway", "heave", "roll", "pitch", "yaw")

#: Degrees of freedom of a mean drift table (:class:`DriftTable`), in the order of its last axis.
DRIFT_DOFS: tuple[str, ...] = ("surge", "sway", "yaw")

#: Sign that turns a WAMIT mode (x fwd, y port, z up) into ours (x fwd, y stbd, z down).
_WAMIT_SIGN = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])

_CSV_COLUMNS = ("omega_rad_s", "beta_deg", "dof", "amplitude", "phase_deg")
_TWO_PI = 2.0 * math.pi


# ----------------------------------------------------------------------------- checks


def _number(name: str, value: Any, unit: str, *, lo: float | None = None, hi: float | None = None,
            lo_open: bool = False, hi_open: bool = False) -> float:
    """``value`` as a finite float within the bounds, else ModelError naming the field and value."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{name} = {value!r} must be a finite number [{unit}]") from None
    bad = not math.isfinite(v)
    bad = bad or (lo is not None and (v <= lo if lo_open else v < lo))
    bad = bad or (hi is not None and (v >= hi if hi_open else v > hi))
    if bad:
        lo_s = "" if lo is None else f"{'(' if lo_open else '['}{lo:g}"
        hi_s = "" if hi is None else f"{hi:g}{')' if hi_open else ']'}"
        rng = f" in {lo_s or '(-inf'}, {hi_s or 'inf)'}" if (lo is not None or hi is not None) else ""
        raise ModelError(f"{name} = {value!r} must be a finite number{rng} [{unit}]")
    return v


def _finite_array(name: str, x: Any, unit: str, *, lo: float | None = None) -> np.ndarray:
    """``x`` as a float array, every element finite (and >= ``lo``), else ModelError naming the
    first bad element."""
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be finite numbers [{unit}], got {x!r}") from None
    ok = np.isfinite(a) if lo is None else np.isfinite(a) & (a >= lo)
    if not ok.all():
        i = int(np.flatnonzero(~ok.ravel())[0])
        rule = "finite" if lo is None else f"finite and >= {lo:g}"
        raise ModelError(f"{name}[{i}] = {float(a.ravel()[i])!r} {unit} must be {rule}")
    return a


# ----------------------------------------------------------------------------- closed form


@dataclass(frozen=True)
class HullMotionParams:
    """Main particulars of a ship-shaped hull for :func:`closed_form_rao` (SI units).

    Attributes
    ----------
    length_pp : float
        Length between perpendiculars L [m], > 0.
    breadth : float
        Moulded breadth B_0 [m], > 0.
    draught : float
        Draught T [m], > 0.
    block_coefficient : float
        C_B [-], in (0, 1]. The heave/pitch box has breadth C_B B_0 (JMO).
    waterplane_coefficient : float
        C_WP [-], in [C_B, 1]. The roll excitation averages the wave slope over the mean
        waterline breadth C_WP B_0.
    GM_T : float
        Transverse metacentric height [m], > 0 (roll restoring ``rho g nabla GM_T``).
    roll_period : float
        Natural roll period T_4 [s], > 0.
    roll_damping : float
        Total equivalent linear roll damping ratio zeta_4 [-] (fraction of critical), in [0, 1).

    Raises
    ------
    ModelError
        A field that is not a finite number or is out of range (the message names the field and
        its value).
    """

    length_pp: float
    breadth: float
    draught: float
    block_coefficient: float
    waterplane_coefficient: float
    GM_T: float
    roll_period: float
    roll_damping: float

    def __post_init__(self) -> None:
        pos = {"length_pp": "m", "breadth": "m", "draught": "m", "GM_T": "m", "roll_period": "s"}
        for name, unit in pos.items():
            object.__setattr__(self, name, _number(f"hull.{name}", getattr(self, name), unit, lo=0.0, lo_open=True))
        cb = _number("hull.block_coefficient", self.block_coefficient, "-", lo=0.0, hi=1.0, lo_open=True)
        object.__setattr__(self, "block_coefficient", cb)
        cw = _number("hull.waterplane_coefficient", self.waterplane_coefficient, "-", lo=cb, hi=1.0)
        object.__setattr__(self, "waterplane_coefficient", cw)
        z = _number("hull.roll_damping", self.roll_damping, "-", lo=0.0, hi=1.0, hi_open=True)
        object.__setattr__(self, "roll_damping", z)


def _sinc(s: np.ndarray) -> np.ndarray:
    """sin(s) / s, 1 at s = 0."""
    return np.sinc(s / math.pi)


def _jfun(s: np.ndarray) -> np.ndarray:
    """J(s) = 3 (sin s - s cos s) / s^3 (even, 1 at s = 0): the lever-arm weighted average of a
    wave over a length 2 s / k, relative to its long-wave value."""
    s = np.asarray(s, dtype=float)
    small = np.abs(s) < 1e-2
    ss = np.where(small, 1.0, s)
    exact = 3.0 * (np.sin(ss) - ss * np.cos(ss)) / ss**3
    s2 = s * s
    series = 1.0 - s2 / 10.0 + s2 * s2 / 280.0
    return np.where(small, series, exact)


def closed_form_rao(omega: Any, beta: Any, hull: HullMotionParams, *, speed: float = 0.0,
                    g: float = 9.80665) -> np.ndarray:
    """Heave, roll and pitch RAOs of a ship-shaped hull in closed form (JMO 2004; roll see the
    module docstring).

    Parameters
    ----------
    omega : array_like
        Wave frequency [rad/s], >= 0 (0 gives the long-wave limits).
    beta : array_like
        Wave heading [rad]: direction the waves go to, from the bow toward starboard
        (pi = head seas). Broadcast against ``omega``.
    hull : HullMotionParams
    speed : float, optional
        Forward speed U [m/s], >= 0 (default 0, station keeping). With ``U > 0`` the phase refers
        to the wave at the moving reference point, whose frequency is the encounter frequency
        ``omega_e = omega - k U cos(beta)``, which must stay > 0.
    g : float, optional
        Gravity [m/s^2], > 0.

    Returns
    -------
    numpy.ndarray
        Complex, shape ``broadcast(omega, beta).shape + (3,)``: heave [m/m] (z down), roll [rad/m]
        (starboard down), pitch [rad/m] (bow up), per unit wave amplitude at the reference point.

    Raises
    ------
    ModelError
        ``hull`` not a :class:`HullMotionParams`, a negative or non-finite frequency, a
        non-finite heading, a bad speed or gravity, or an encounter frequency <= 0.
    """
    if not isinstance(hull, HullMotionParams):
        raise ModelError(f"hull must be a HullMotionParams, got {type(hull).__name__}")
    g = _number("g", g, "m/s^2", lo=0.0, lo_open=True)
    U = _number("speed", speed, "m/s", lo=0.0)
    w = _finite_array("omega", omega, "rad/s", lo=0.0)
    b = _finite_array("beta", beta, "rad")
    w, b = np.broadcast_arrays(w, b)
    L, T = hull.length_pp, hull.draught
    B = hull.block_coefficient * hull.breadth
    Bw = hull.waterplane_coefficient * hull.breadth
    cb, sb = np.cos(b), np.sin(b)
    k = w * w / g
    alpha = 1.0 - U * w * cb / g  # = 1 - Fn sqrt(kL) cos(beta) = omega_e / omega
    if np.any(alpha <= 0.0):
        i = int(np.flatnonzero((alpha <= 0.0).ravel())[0])
        raise ModelError(f"encounter frequency <= 0 at omega = {float(w.ravel()[i])!r} rad/s, beta = "
                         f"{float(b.ravel()[i])!r} rad, speed = {U!r} m/s: the closed form needs omega_e > 0")
    a2 = alpha * alpha
    A = 2.0 * np.sin(k * B * a2 / 2.0) * np.exp(-k * T * a2)
    # A^2 / (k B alpha^n) = A * sinc(k B alpha^2 / 2) * alpha^(2 - n) * exp(-k T alpha^2): finite at k = 0
    A2_kB = A * _sinc(k * B * a2 / 2.0) * np.exp(-k * T * a2)  # A^2 / (k B alpha^2)
    ftilde = (1.0 - k * T) + 1j * A2_kB / alpha
    etatilde = 1.0 / ((1.0 - 2.0 * k * T * a2) + 1j * A2_kB)
    kc, ks = k * cb, k * sb
    kappa = np.exp(-np.abs(kc) * T)
    common = kappa * ftilde * etatilde
    heave = -common * _sinc(kc * L / 2.0)
    pitch = -1j * common * kc * _jfun(kc * L / 2.0)
    w4 = _TWO_PI / hull.roll_period
    r = alpha * w / w4
    z4 = hull.roll_damping
    roll = 1j * ks * _sinc(kc * L / 2.0) * _jfun(ks * Bw / 2.0) / ((1.0 - r * r) + 2j * z4 * r)
    return np.stack([heave, roll, pitch], axis=-1)


# ----------------------------------------------------------------------------- tables


def _table_axes(omega: Any, beta: Any) -> tuple[np.ndarray, np.ndarray]:
    """A table's frequencies and headings as checked float copies: each 1-D and not empty, finite,
    strictly increasing, the frequencies > 0, the headings in [0, 2 pi) (ModelError naming the
    field, index and value)."""
    w = _finite_array("table.omega", omega, "rad/s").copy()
    b = _finite_array("table.beta", beta, "rad").copy()
    if w.ndim != 1 or w.size < 1:
        raise ModelError(f"table.omega must have shape (nw,), nw >= 1, got shape {w.shape}")
    if b.ndim != 1 or b.size < 1:
        raise ModelError(f"table.beta must have shape (nb,), nb >= 1, got shape {b.shape}")
    if np.any(w <= 0.0):
        i = int(np.flatnonzero(w <= 0.0)[0])
        raise ModelError(f"table.omega[{i}] = {float(w[i])!r} rad/s must be > 0")
    for name, a, unit in (("table.omega", w, "rad/s"), ("table.beta", b, "rad")):
        d = np.diff(a)
        if np.any(d <= 0.0):
            i = int(np.flatnonzero(d <= 0.0)[0]) + 1
            raise ModelError(f"{name}[{i}] = {float(a[i])!r} {unit} must be > {name}[{i - 1}] = "
                             f"{float(a[i - 1])!r} (strictly increasing)")
    out = (b < 0.0) | (b >= _TWO_PI)
    if np.any(out):
        i = int(np.flatnonzero(out)[0])
        raise ModelError(f"table.beta[{i}] = {float(b[i])!r} rad must be in [0, 2 pi)")
    return w, b


@dataclass(frozen=True, eq=False)
class RAOTable:
    """A 6-dof RAO table in the module's conventions.

    Attributes
    ----------
    omega : numpy.ndarray
        Wave frequencies [rad/s], shape (nw,), nw >= 1, finite, > 0, strictly increasing.
    beta : numpy.ndarray
        Headings [rad], shape (nb,), nb >= 1, strictly increasing within [0, 2 pi).
    H : numpy.ndarray
        Complex RAOs, shape (nw, nb, 6) [m/m for surge, sway, heave; rad/m for roll, pitch, yaw].

    The arrays are stored as read-only copies.

    Raises
    ------
    ModelError
        Shapes that do not match, non-finite values, frequencies or headings out of range or not
        strictly increasing (the message names the field, index and value).
    """

    omega: np.ndarray
    beta: np.ndarray
    H: np.ndarray

    def __post_init__(self) -> None:
        w, b = _table_axes(self.omega, self.beta)
        try:
            H = np.array(self.H, dtype=complex)
        except (TypeError, ValueError):
            raise ModelError("table.H must be complex numbers of shape (nw, nb, 6)") from None
        if H.shape != (w.size, b.size, 6):
            raise ModelError(f"table.H must have shape (nw, nb, 6) = {(w.size, b.size, 6)}, got {H.shape}")
        bad = ~(np.isfinite(H.real) & np.isfinite(H.imag))
        if bad.any():
            i, j, m = (int(v[0]) for v in np.nonzero(bad))
            raise ModelError(f"table.H[{i}, {j}, {m}] ({DOFS[m]} at omega = {float(w[i])!r} rad/s, beta = "
                             f"{float(b[j])!r} rad) = {H[i, j, m]!r} must be finite")
        for name, a in (("omega", w), ("beta", b), ("H", H)):
            a.flags.writeable = False
            object.__setattr__(self, name, a)

    def evaluate(self, omega: Any, beta: Any) -> np.ndarray:
        """The RAO at wave frequencies ``omega`` [rad/s] (>= 0) and headings ``beta`` [rad]
        (any finite value, taken modulo 2 pi), broadcast together.

        Linear in omega (real and imaginary parts), holding the first row below the first
        frequency and 0 above the last; linear and 2 pi periodic in beta (see the module
        docstring).

        Returns
        -------
        numpy.ndarray
            Complex, shape ``broadcast(omega, beta).shape + (6,)`` [m/m, rad/m].

        Raises
        ------
        ModelError
            A negative or non-finite frequency, or a non-finite heading.
        """
        return _interpolate(self.omega, self.beta, self.H, omega, beta)


def _interpolate(tw: np.ndarray, tb: np.ndarray, V: np.ndarray, omega: Any, beta: Any) -> np.ndarray:
    """The table ``V`` (nw, nb, m) on the frequencies ``tw`` and headings ``tb`` at ``omega``
    [rad/s] (>= 0) and ``beta`` [rad] (finite), broadcast together: linear in omega, the first
    row held below ``tw[0]`` and 0 above ``tw[-1]``; linear and 2 pi periodic in beta (see the
    module docstring). Shape ``broadcast(omega, beta).shape + (m,)``, the dtype of ``V``."""
    w = _finite_array("omega", omega, "rad/s", lo=0.0)
    b = _finite_array("beta", beta, "rad")
    w, b = np.broadcast_arrays(w, b)
    nw, nb = tw.size, tb.size
    # frequency: index of the left node and weight of the right one
    wc = np.clip(w, tw[0], tw[-1])
    if nw > 1:
        iw = np.clip(np.searchsorted(tw, wc, side="right") - 1, 0, nw - 2)
        tw_w = (wc - tw[iw]) / (tw[iw + 1] - tw[iw])
        iw1 = iw + 1
    else:
        iw = iw1 = np.zeros(w.shape, dtype=int)
        tw_w = np.zeros(w.shape)
    # heading: periodic, the last interval from tb[-1] to tb[0] + 2 pi
    bb = np.mod(b, _TWO_PI)
    bb = np.where(bb < tb[0], bb + _TWO_PI, bb)
    ext = np.append(tb, tb[0] + _TWO_PI)
    ib = np.clip(np.searchsorted(ext, bb, side="right") - 1, 0, nb - 1)
    tb_w = (bb - ext[ib]) / (ext[ib + 1] - ext[ib])
    ib1 = (ib + 1) % nb
    if nb == 1:
        tb_w = np.zeros(b.shape)
    tw_w, tb_w = tw_w[..., None], tb_w[..., None]
    out = ((1.0 - tw_w) * ((1.0 - tb_w) * V[iw, ib] + tb_w * V[iw, ib1])
           + tw_w * ((1.0 - tb_w) * V[iw1, ib] + tb_w * V[iw1, ib1]))
    return np.where((w > tw[-1])[..., None], np.zeros((), V.dtype), out)


def _assemble(records: dict[tuple[float, float], dict[int, tuple[complex, int]]], source: str,
              what: str) -> RAOTable:
    """An RAO table from ``{(omega, beta): {dof: (H, row)}}`` (:func:`_assemble_grid`: a full
    omega x beta product, all six dofs at every pair)."""
    omegas, betas, H = _assemble_grid(records, source, what, DOFS, "row", "all six dofs", complex)
    return RAOTable(np.array(omegas), np.array(betas), H)


def _assemble_grid(records: dict[tuple[float, float], dict[int, tuple[Any, int]]], source: str, what: str,
                   dofs: tuple[str, ...], row: str, needs: str, dtype: Any) -> tuple[list, list, np.ndarray]:
    """The frequencies, headings and values (nw, nb, len(dofs)) of ``{(omega, beta): {dof: (value,
    row)}}``, refusing no rows, a grid that is not a full omega x beta product or a pair without
    all its dofs (``row``: what the file's records are called; ``needs``: which dofs a pair needs)."""
    if not records:
        raise ModelError(f"{source}: no {what} rows")
    omegas = sorted({p[0] for p in records})
    betas = sorted({p[1] for p in records})
    for w in omegas:
        for b in betas:
            if (w, b) not in records:
                raise ModelError(f"{source}: the grid is not a full omega x beta product: no {row}s for "
                                 f"omega = {w!r} rad/s, beta = {math.degrees(b)!r} deg")
    V = np.zeros((len(omegas), len(betas), len(dofs)), dtype=dtype)
    for i, w in enumerate(omegas):
        for j, b in enumerate(betas):
            pair = records[(w, b)]
            for m, name in enumerate(dofs):
                if m not in pair:
                    raise ModelError(f"{source}: omega = {w!r} rad/s, beta = {math.degrees(b)!r} deg has no "
                                     f"{name} {row} (every pair needs {needs})")
                V[i, j, m] = pair[m][0]
    return omegas, betas, V


def _read_grid_csv(path: str | Path, columns: tuple[str, ...], numeric: tuple[str, ...], dofs: tuple[str, ...],
                   value_of: Any) -> tuple[str, dict[tuple[float, float], dict[int, tuple[Any, int]]]]:
    """The records ``{(omega, beta): {dof: (value, row)}}`` of a table in CSV (:func:`read_rao_csv`,
    :func:`read_drift_csv`): the header exactly ``columns`` (any order), every ``numeric`` column a
    finite number, ``dof`` one of ``dofs``, ``omega_rad_s`` > 0, no pair and dof twice; a row's
    value is ``value_of(vals, row_no, src)`` (which may refuse it). Each error names the file, the
    row, the column and the value."""
    path = Path(path)
    src = str(path)
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None:
            raise ModelError(f"{src}: empty file, expected the header {','.join(columns)}")
        cols = [c.strip() for c in header]
        missing = [c for c in columns if c not in cols]
        extra = [c for c in cols if c not in columns]
        dup = sorted({c for c in cols if cols.count(c) > 1})
        if missing or extra or dup:
            parts = ([f"missing column(s) {missing}"] if missing else []) + (
                [f"extra column(s) {extra}"] if extra else []) + ([f"repeated column(s) {dup}"] if dup else [])
            raise ModelError(f"{src}: header {cols}: {'; '.join(parts)}; expected {list(columns)}")
        at = {c: cols.index(c) for c in columns}
        records: dict[tuple[float, float], dict[int, tuple[Any, int]]] = {}
        for row_no, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != len(cols):
                raise ModelError(f"{src}: row {row_no} has {len(row)} values, the header has {len(cols)}")
            vals: dict[str, float] = {}
            for c in numeric:
                text = row[at[c]].strip()
                try:
                    v = float(text)
                except ValueError:
                    raise ModelError(f"{src}: row {row_no}, column {c}: {text!r} is not a number") from None
                if not math.isfinite(v):
                    raise ModelError(f"{src}: row {row_no}, column {c}: {text!r} must be finite")
                vals[c] = v
            dof = row[at["dof"]].strip().lower()
            if dof not in dofs:
                raise ModelError(f"{src}: row {row_no}, column dof: {row[at['dof']]!r} must be one of {list(dofs)}")
            if vals["omega_rad_s"] <= 0.0:
                raise ModelError(f"{src}: row {row_no}, column omega_rad_s: {vals['omega_rad_s']!r} must be > 0")
            value = value_of(vals, row_no, src)
            key = (vals["omega_rad_s"], _heading_rad(vals["beta_deg"]))
            m = dofs.index(dof)
            pair = records.setdefault(key, {})
            if m in pair:
                raise ModelError(f"{src}: row {row_no} repeats row {pair[m][1]} (omega = {key[0]!r} rad/s, "
                                 f"beta = {vals['beta_deg']!r} deg, dof {dof})")
            pair[m] = (value, row_no)
    return src, records


def _wamit_rows(path: str | Path, names: str) -> Any:
    """``(src, line_no, line, values)`` of every non-blank line of a WAMIT output file whose
    columns are ``names`` (e.g. "PER BETA I Mod Pha Re Im"): all numbers (Fortran exponents
    read), finite (but Pha), PER > 0 (WAMIT's zero and infinite period codes refused); Mod
    is left to the caller (:func:`_check_modulus`); each error names the line and value."""
    path = Path(path)
    src = str(path)
    n = len(names.split())
    with path.open() as fh:
        for line_no, line in enumerate(fh, start=1):
            parts = line.split()
            if not parts:
                continue
            try:
                vals = tuple(float(p.replace("D", "E").replace("d", "e")) for p in parts)
            except ValueError:
                vals = ()
            if len(vals) != n:
                raise ModelError(f"{src}: line {line_no}: {line.strip()!r} is not {n} numbers ({names})")
            per = vals[0]
            if not all(math.isfinite(v) for i, v in enumerate(vals) if i != n - 3):   # Pha may be anything
                raise ModelError(f"{src}: line {line_no}: {line.strip()!r} has a value that is not finite")
            if per <= 0.0:
                raise ModelError(f"{src}: line {line_no}: PER = {per!r} s: zero and infinite periods (PER <= 0, "
                                 "WAMIT's codes 0 and -1) are not supported")
            yield src, line_no, line, vals


def _check_modulus(src: str, line_no: int, mod: float, re_: float, im_: float, names: str) -> None:
    """Refuse a WAMIT line whose Mod contradicts ``|Re + i Im|`` (columns out of order)."""
    if abs(abs(complex(re_, im_)) - mod) > 1e-3 * max(1.0, mod):
        raise ModelError(f"{src}: line {line_no}: Mod = {mod!r} but |Re + i Im| = {abs(complex(re_, im_))!r} "
                         f"(columns must be {names})")


def _heading_rad(deg: float) -> float:
    """A heading in degrees as radians in [0, 2 pi)."""
    r = math.radians(deg % 360.0)
    return 0.0 if r >= _TWO_PI else r


def read_rao_csv(path: str | Path) -> RAOTable:
    """Read an RAO table in the CSV format of the module docstring.

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    RAOTable

    Raises
    ------
    ModelError
        Missing or extra columns, a value that is not a number (naming the row and column), NaN
        or infinite values, a negative amplitude, an unknown dof, a frequency <= 0, duplicate
        rows, a grid that is not a full omega x beta product, or a pair without all six dofs.
    """
    def value_of(vals: dict[str, float], row_no: int, src: str) -> complex:
        if vals["amplitude"] < 0.0:
            raise ModelError(f"{src}: row {row_no}, column amplitude: {vals['amplitude']!r} must be >= 0")
        return vals["amplitude"] * complex(math.cos(math.radians(vals["phase_deg"])),
                                           math.sin(math.radians(vals["phase_deg"])))

    src, records = _read_grid_csv(path, _CSV_COLUMNS, ("omega_rad_s", "beta_deg", "amplitude", "phase_deg"), DOFS,
                                  value_of)
    return _assemble(records, src, "RAO")


def write_rao_csv(table: RAOTable, path: str | Path) -> None:
    """Write ``table`` in the CSV format of the module docstring (full float precision, so that
    :func:`read_rao_csv` gives it back to rounding).

    Parameters
    ----------
    table : RAOTable
    path : str or pathlib.Path
        File to write (replaced).

    Raises
    ------
    ModelError
        ``table`` is not an :class:`RAOTable`.
    """
    if not isinstance(table, RAOTable):
        raise ModelError(f"table must be an RAOTable, got {type(table).__name__}")
    with Path(path).open("w", newline="") as fh:
        wr = csv.writer(fh, lineterminator="\n")
        wr.writerow(_CSV_COLUMNS)
        for i, w in enumerate(table.omega):
            for j, b in enumerate(table.beta):
                for m, name in enumerate(DOFS):
                    h = complex(table.H[i, j, m])
                    wr.writerow([repr(float(w)), repr(math.degrees(float(b))), name,
                                 repr(abs(h)), repr(math.degrees(math.atan2(h.imag, h.real)))])


def read_wamit4(path: str | Path, *, ulen: float) -> RAOTable:
    """Read a WAMIT ``.4`` motion-RAO file and convert it to the module's conventions (see the
    module docstring for the format, the frame change and the signs).

    Parameters
    ----------
    path : str or pathlib.Path
    ulen : float
        WAMIT's length scale ULEN [m] (from the GDF file), > 0: rotations are divided by it.

    Returns
    -------
    RAOTable
        omega = 2 pi / PER [rad/s], beta = -BETA mod 2 pi [rad], H (nw, nb, 6).

    Raises
    ------
    ModelError
        A row without 7 numbers, PER <= 0 (WAMIT's zero/infinite-period codes), a mode that is
        not 1..6, a modulus that contradicts Re and Im, duplicate rows, a grid that is not a full
        product, or a pair without all six modes (each naming the line and value).
    """
    ulen = _number("ulen", ulen, "m", lo=0.0, lo_open=True)
    names = "PER BETA I Mod Pha Re Im"
    records: dict[tuple[float, float], dict[int, tuple[complex, int]]] = {}
    src = str(path)
    for src, line_no, _, (per, beta_w, mode, mod, _pha, re_, im_) in _wamit_rows(path, names):
        if mode != int(mode) or not 1 <= int(mode) <= 6:
            raise ModelError(f"{src}: line {line_no}: mode I = {mode!r} must be 1..6")
        m = int(mode) - 1
        _check_modulus(src, line_no, mod, re_, im_, names)
        h = _WAMIT_SIGN[m] * complex(re_, im_) / (ulen if m >= 3 else 1.0)
        key = (_TWO_PI / per, _heading_rad(-beta_w))
        pair = records.setdefault(key, {})
        if m in pair:
            raise ModelError(f"{src}: line {line_no} repeats line {pair[m][1]} (PER = {per!r} s, "
                             f"BETA = {beta_w!r} deg, mode {m + 1})")
        pair[m] = (h, line_no)
    return _assemble(records, src, "WAMIT .4")


# ----------------------------------------------------------------------------- mean drift

_DRIFT_COLUMNS = ("omega_rad_s", "beta_deg", "dof", "D")

#: WAMIT modes of the mean drift read (surge, sway, yaw) and their signs in our frame.
_WAMIT_DRIFT_MODES = {1: (0, 1.0), 2: (1, -1.0), 6: (2, -1.0)}


@dataclass(frozen=True, eq=False)
class DriftTable:
    """Mean wave drift coefficients of a hull in the module's conventions (see the module
    docstring): the mean force (moment) in regular waves per unit wave amplitude squared.

    Attributes
    ----------
    omega : numpy.ndarray
        Wave frequencies [rad/s], shape (nw,), nw >= 1, finite, > 0, strictly increasing.
    beta : numpy.ndarray
        Headings [rad] (where the waves go to, relative to the bow), shape (nb,), nb >= 1,
        strictly increasing within [0, 2 pi).
    D : numpy.ndarray
        Real coefficients, shape (nw, nb, 3): surge, sway [N/m^2], yaw [N m/m^2] in {B}.

    The arrays are stored as read-only copies.

    Raises
    ------
    ModelError
        Shapes that do not match, non-finite values, frequencies or headings out of range or not
        strictly increasing (the message names the field, index and value).
    """

    omega: np.ndarray
    beta: np.ndarray
    D: np.ndarray

    def __post_init__(self) -> None:
        w, b = _table_axes(self.omega, self.beta)
        try:
            D = np.array(self.D, dtype=float)
        except (TypeError, ValueError):
            raise ModelError("table.D must be real numbers of shape (nw, nb, 3)") from None
        if D.shape != (w.size, b.size, 3):
            raise ModelError(f"table.D must have shape (nw, nb, 3) = {(w.size, b.size, 3)}, got {D.shape}")
        bad = ~np.isfinite(D)
        if bad.any():
            i, j, m = (int(v[0]) for v in np.nonzero(bad))
            raise ModelError(f"table.D[{i}, {j}, {m}] ({DRIFT_DOFS[m]} at omega = {float(w[i])!r} rad/s, beta = "
                             f"{float(b[j])!r} rad) = {float(D[i, j, m])!r} must be finite")
        for name, a in (("omega", w), ("beta", b), ("D", D)):
            a.flags.writeable = False
            object.__setattr__(self, name, a)

    def evaluate(self, omega: Any, beta: Any) -> np.ndarray:
        """The coefficients at wave frequencies ``omega`` [rad/s] (>= 0) and headings ``beta``
        [rad] (finite, taken modulo 2 pi), broadcast together: linear in omega, the first row held
        below the first frequency and 0 above the last; linear and 2 pi periodic in beta.

        Returns
        -------
        numpy.ndarray
            Real, shape ``broadcast(omega, beta).shape + (3,)`` [N/m^2, N/m^2, N m/m^2].

        Raises
        ------
        ModelError
            A negative or non-finite frequency, or a non-finite heading.
        """
        return _interpolate(self.omega, self.beta, self.D, omega, beta)


def _assemble_drift(records: dict[tuple[float, float], dict[int, tuple[float, int]]], source: str,
                    what: str, row: str) -> DriftTable:
    """A drift table from ``{(omega, beta): {dof: (D, row)}}`` (:func:`_assemble_grid`: a full
    omega x beta product, surge, sway and yaw at every pair)."""
    omegas, betas, D = _assemble_grid(records, source, what, DRIFT_DOFS, row, "surge, sway and yaw", float)
    return DriftTable(np.array(omegas), np.array(betas), D)


def read_drift_csv(path: str | Path) -> DriftTable:
    """Read a mean drift table in the CSV format of the module docstring
    (``omega_rad_s,beta_deg,dof,D``).

    Parameters
    ----------
    path : str or pathlib.Path

    Returns
    -------
    DriftTable

    Raises
    ------
    ModelError
        Missing, extra or repeated columns, a row of the wrong length, a value that is not a
        finite number, a frequency <= 0, a dof other than surge, sway, yaw (each naming the row,
        column and value), duplicate rows, a grid that is not a full omega x beta product, or a
        pair without the three dofs.
    """
    src, records = _read_grid_csv(path, _DRIFT_COLUMNS, ("omega_rad_s", "beta_deg", "D"), DRIFT_DOFS,
                                  lambda vals, row_no, src: vals["D"])
    return _assemble_drift(records, src, "drift", "row")


def write_drift_csv(table: DriftTable, path: str | Path) -> None:
    """Write ``table`` in the CSV format of the module docstring (full float precision, so that
    :func:`read_drift_csv` gives it back to rounding of the headings' degrees).

    Raises
    ------
    ModelError
        ``table`` is not a :class:`DriftTable`.
    """
    if not isinstance(table, DriftTable):
        raise ModelError(f"table must be a DriftTable, got {type(table).__name__}")
    with Path(path).open("w", newline="") as fh:
        wr = csv.writer(fh, lineterminator="\n")
        wr.writerow(_DRIFT_COLUMNS)
        for i, w in enumerate(table.omega):
            for j, b in enumerate(table.beta):
                for m, name in enumerate(DRIFT_DOFS):
                    wr.writerow([repr(float(w)), repr(math.degrees(float(b))), name, repr(float(table.D[i, j, m]))])


def read_wamit_drift(path: str | Path, *, ulen: float, rho: float, g: float) -> DriftTable:
    """Read a WAMIT ``.8`` or ``.9`` mean drift file (format, frame change and signs in the module
    docstring) into a drift table in SI units.

    Parameters
    ----------
    path : str or pathlib.Path
    ulen : float
        WAMIT's length scale ULEN [m], > 0: forces are ``rho g ULEN`` and moments ``rho g ULEN^2``
        times the file's values (per unit wave amplitude squared).
    rho, g : float
        Water density [kg/m^3] and gravity [m/s^2] of the dimensional values, > 0.

    Returns
    -------
    DriftTable
        omega = 2 pi / PER [rad/s], beta = -BETA1 mod 2 pi [rad], D (nw, nb, 3).

    Raises
    ------
    ModelError
        A row without 8 numbers, a value that is not finite, PER <= 0 (WAMIT's zero and infinite
        period codes), a mode that is not an integer, a modulus that contradicts Re and Im,
        duplicate rows (each naming the line and value), a grid that is not a full product, or a
        pair without surge, sway and yaw.
    """
    ulen = _number("ulen", ulen, "m", lo=0.0, lo_open=True)
    rho = _number("rho", rho, "kg/m^3", lo=0.0, lo_open=True)
    g = _number("g", g, "m/s^2", lo=0.0, lo_open=True)
    names = "PER BETA1 BETA2 I Mod Pha Re Im"
    records: dict[tuple[float, float], dict[int, tuple[float, int]]] = {}
    src = str(path)
    for src, line_no, _, (per, b1, b2, mode, mod, _pha, re_, im_) in _wamit_rows(path, names):
        if mode != int(mode):
            raise ModelError(f"{src}: line {line_no}: mode I = {mode!r} must be an integer")
        _check_modulus(src, line_no, mod, re_, im_, names)
        if b1 != b2 or int(mode) not in _WAMIT_DRIFT_MODES:
            continue   # a pair of wave directions, or heave, roll, pitch, body-axes modes
        m, sign = _WAMIT_DRIFT_MODES[int(mode)]
        scale = rho * g * (ulen * ulen if m == 2 else ulen)
        key = (_TWO_PI / per, _heading_rad(-b1))
        pair = records.setdefault(key, {})
        if m in pair:
            raise ModelError(f"{src}: line {line_no} repeats line {pair[m][1]} (PER = {per!r} s, "
                             f"BETA = {b1!r} deg, mode {int(mode)})")
        pair[m] = (sign * scale * re_, line_no)
    return _assemble_drift(records, src, "WAMIT mean drift (BETA1 = BETA2, modes 1, 2, 6)", "line")
