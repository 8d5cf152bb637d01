"""Statistics for a class society's mooring-line limit-state checks (DNV-OS-E301).

Pure numpy/scipy functions, no study machinery: the characteristic tension from several
realisations (Gumbel most probable maximum), the partial safety factors of the line strength
check (ULS/ALS), the utilisation against the characteristic capacity, and the fatigue damage of
a tension record (rainflow counting, T-N curves, Miner's sum) with its annual value and the
fatigue life.

Units: tensions and tension ranges in N, diameters in m, areas in m², stresses in MPa,
durations in s, lives in years.

Sources and what is unchecked
-----------------------------
Every number of a standard below (partial safety factors, capacity factor 0.95, T-N curves,
nominal areas) is transcribed from the project's standards notes, which were themselves read
from **secondary transcriptions** of DNV-OS-E301 (October 2008 edition for the strength check;
"as commonly transcribed" for the fatigue curves). None has been checked against the standard
itself; the wire-rope T-N curves in particular come from secondary sources. The safety factors
and the capacity factor are the ones of :mod:`tapm_opt.standards` (one definition, shared with
the KPIs' line check and the capability envelopes). See ``docs/verification.md``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .._checks import finite
from ..models.fatigue import (TN_CURVES, TNCurve, VerificationError, finite_series, miner_damage, nominal_area,
                              rainflow_ranges)
from ..standards import (DNV_CAPACITY_FACTOR, DNV_CLASS1_COMMON_FACTOR, DNV_E301_2008_FACTORS,
                         DNV_E301_QUASI_STATIC_FACTORS)

__all__ = [
    "VerificationError",
    "GumbelFit",
    "gumbel_mpm",
    "MIN_REALISATIONS",
    "RECOMMENDED_REALISATIONS",
    "recommended_realisations",
    "partial_safety_factors",
    "characteristic_tension",
    "utilisation",
    "TNCurve",
    "TN_CURVES",
    "nominal_area",
    "rainflow_ranges",
    "miner_damage",
    "SECONDS_PER_YEAR",
    "annual_damage",
    "fatigue_life",
    "DFF_ADJACENT_KNEE",
    "DFF_ADJACENT_BASE",
    "DFF_ADJACENT_RISE",
    "adjacent_fatigue_factor",
    "damage_ratio",
    "line_neighbours",
]


# -- helpers -------------------------------------------------------------------------------------

_finite_array = finite_series


def _finite(name: str, x: object, *, positive: bool = False, nonnegative: bool = False) -> float:
    """``x`` as a finite float (> 0 with ``positive``, >= 0 with ``nonnegative``), else a
    :class:`VerificationError` naming ``name`` and the value (:func:`tapm_opt._checks.finite`)."""
    return finite(name, x, lo=0.0 if (positive or nonnegative) else None, strict=positive, error=VerificationError)


# -- characteristic tension: Gumbel most probable maximum -----------------------------------------

#: The Euler-Mascheroni constant.
EULER_GAMMA = 0.5772156649015329


class GumbelFit(NamedTuple):
    """A Gumbel (type I, maxima) fit to per-realisation maxima.

    ``mpm`` [N] is the most probable maximum, the mode of the fitted distribution, which for the
    Gumbel is its location ``mu`` [N]; ``beta`` [N] is the scale; ``method`` "moments" or "mle";
    ``n`` the number of maxima fitted.
    """

    mpm: float
    mu: float
    beta: float
    method: str
    n: int


def gumbel_mpm(maxima: Sequence[float] | np.ndarray, method: str = "moments") -> GumbelFit:
    """Most probable maximum [N] of the per-realisation maxima, from a fitted Gumbel distribution.

    Parameters
    ----------
    maxima : sequence of float
        The maximum tension [N] of each realisation (one storm record per seed, e.g. 3 h). At
        least 2, all finite.
    method : {"moments", "mle"}
        ``"moments"``: method of moments, ``beta = s sqrt(6) / pi`` and ``mu = mean - gamma beta``
        with ``s`` the sample standard deviation (ddof = 1) and ``gamma`` the Euler-Mascheroni
        constant (Gumbel mean ``mu + gamma beta``, variance ``pi^2 beta^2 / 6``).
        ``"mle"``: maximum likelihood, :func:`scipy.stats.gumbel_r.fit`.

    Returns
    -------
    GumbelFit
        ``(mpm, mu, beta, method, n)``; ``mpm == mu``, the mode of the Gumbel density
        ``f(x) = exp(-(z + exp(-z))) / beta``, ``z = (x - mu) / beta``. With all maxima equal the
        fit is degenerate: ``beta = 0`` and ``mu`` the common value (both methods).

    Source: the characteristic dynamic tension is the most probable maximum of the storm, estimated
    from several realisations as the mode of a Gumbel fitted to their maxima (the project's notes on
    DNV-OS-E301, secondary transcription). The moment formulas are the standard Gumbel moments; the
    recommendation of ten 3-hour records fitted by maximum likelihood is the SNAME bulletin's as
    quoted by Bai, *Marine Structural Design* (secondary). See :func:`recommended_realisations`.
    """
    x = _finite_array("maxima", maxima, min_len=2)
    if method not in ("moments", "mle"):
        raise VerificationError(f"method = {method!r}: expected 'moments' or 'mle'")
    n = int(x.size)
    if float(np.ptp(x)) == 0.0:
        v = float(x[0])
        return GumbelFit(v, v, 0.0, method, n)
    if method == "moments":
        beta = float(np.std(x, ddof=1)) * math.sqrt(6.0) / math.pi
        mu = float(np.mean(x)) - EULER_GAMMA * beta
    else:
        from scipy.stats import gumbel_r

        # scale the data to order 1 so the optimiser's tolerances do not depend on N vs kN
        c, s = float(np.mean(x)), float(np.std(x))
        loc, scale = gumbel_r.fit((x - c) / s)
        mu, beta = c + s * float(loc), s * float(scale)
    return GumbelFit(mu, mu, beta, method, n)


#: Fewest realisations accepted without a warning of "below the floor" (the project's requirement;
#: not a number from a standard).
MIN_REALISATIONS = 3
#: Realisations recommended: ten 3-hour records (SNAME bulletin, as quoted by Bai, Marine
#: Structural Design; a secondary source). The number DNV-OS-E301 (October 2008) asks for is
#: unsourced here.
RECOMMENDED_REALISATIONS = 10


def recommended_realisations(n_given: int) -> tuple[int, str | None]:
    """How many realisations (seeds) are recommended for the Gumbel fit, and a warning if fewer
    were given.

    Returns ``(RECOMMENDED_REALISATIONS, warning)``; ``warning`` is ``None`` when
    ``n_given >= RECOMMENDED_REALISATIONS``, else a sentence saying which threshold is not met and
    where it comes from: below :data:`MIN_REALISATIONS` (3, the project's floor) the estimate is
    flagged as not usable for a check; between 3 and 9 as fewer than recommended. The 10 is the
    SNAME bulletin's ten 3-hour records as quoted by Bai, *Marine Structural Design* (secondary);
    the number the DNV-OS-E301 edition asks for is **unsourced** in this project.
    """
    if isinstance(n_given, bool) or not isinstance(n_given, (int, np.integer)) or n_given < 0:
        raise VerificationError(f"n_given = {n_given!r}: expected a non-negative integer")
    n = int(n_given)
    rec = RECOMMENDED_REALISATIONS
    if n >= rec:
        return rec, None
    src = ("10 per the SNAME bulletin as quoted by Bai, Marine Structural Design (secondary source); "
           "the number DNV-OS-E301 asks for is unsourced here")
    if n < MIN_REALISATIONS:
        return rec, (f"only {n} realisation(s): below the floor of {MIN_REALISATIONS}; the most probable "
                     f"maximum is not fit for a limit-state check (recommended: {src})")
    return rec, f"only {n} realisations: fewer than recommended ({src})"


# -- strength check: partial safety factors (DNV-OS-E301, October 2008) ---------------------------

def _class_and_state(consequence_class: object, limit_state: object) -> tuple[int, str]:
    if isinstance(consequence_class, bool) or consequence_class not in (1, 2):
        raise VerificationError(f"consequence_class = {consequence_class!r}: expected 1 or 2")
    ls = limit_state.upper() if isinstance(limit_state, str) else limit_state
    if ls not in ("ULS", "ALS"):
        raise VerificationError(f"limit_state = {limit_state!r}: expected 'ULS' or 'ALS'")
    return int(consequence_class), str(ls)  # type: ignore[arg-type]


def partial_safety_factors(consequence_class: int, limit_state: str,
                           analysis: str = "dynamic") -> tuple[float, float]:
    """Partial safety factors ``(gamma_mean, gamma_dyn)`` of the DNV-OS-E301 line strength check.

    ``consequence_class`` 1 or 2; ``limit_state`` "ULS" (intact) or "ALS" (one line broken);
    ``analysis`` "dynamic" or "quasi-static". For a quasi-static analysis the standard gives one
    factor on the whole tension; it is returned twice, ``(gamma, gamma)``, so that
    :func:`characteristic_tension` applies it to ``T_mean + T_dyn``.

    ==========  ============  =============  =============
    limit state analysis      class 1        class 2
    ==========  ============  =============  =============
    ULS         dynamic       1.10 / 1.50    1.40 / 2.10
    ALS         dynamic       1.00 / 1.10    1.00 / 1.25
    ULS         quasi-static  1.70           2.50
    ALS         quasi-static  1.10           1.35
    ==========  ============  =============  =============

    Source: DNV-OS-E301, October 2008 edition, as transcribed in the project's standards notes
    from secondary sources; **unchecked** against the standard. The values are those of
    :data:`tapm_opt.standards.DNV_E301_2008_FACTORS` and ``DNV_E301_QUASI_STATIC_FACTORS``. Not
    applied here: the class-1 common factor 1.3 (see :func:`characteristic_tension`) and the factor
    1.2 on all factors for non-redundant single-point moorings.
    """
    cc, ls = _class_and_state(consequence_class, limit_state)
    if analysis == "dynamic":
        return DNV_E301_2008_FACTORS[(ls, cc)]
    if analysis == "quasi-static":
        g = DNV_E301_QUASI_STATIC_FACTORS[(ls, cc)]
        return g, g
    raise VerificationError(f"analysis = {analysis!r}: expected 'dynamic' or 'quasi-static'")


def characteristic_tension(T_mean: float, T_dyn: float, consequence_class: int, limit_state: str,
                           analysis: str = "dynamic", *, common_factor: bool = True) -> float:
    """Design line tension [N] of the strength check, ``gamma_mean T_mean + gamma_dyn T_dyn``.

    ``T_mean`` [N] is the characteristic mean tension (>= 0) and ``T_dyn`` [N] the characteristic
    dynamic tension (>= 0), ``T_dyn = T_mpm - T_mean`` with ``T_mpm`` the most probable maximum
    (:func:`gumbel_mpm`). The factors are :func:`partial_safety_factors`; the check is
    ``S_C >= characteristic_tension(...)``, i.e. :func:`utilisation` <= 1.

    ``common_factor`` (default True): in ULS, consequence class 1, dynamic analysis, with
    ``T_mean > 2/3 T_dyn`` the design tension is ``1.3 (T_mean + T_dyn)``
    (:data:`~tapm_opt.standards.DNV_CLASS1_COMMON_FACTOR`), read as replacing the two factors: the
    table note of DNV-OS-E301 (2008) as transcribed ("a common factor 1.3 applies"). Between
    ``2/3 T_dyn`` and ``T_dyn`` of mean tension that gives a design tension up to 0.2 (T_dyn -
    T_mean) lower than 1.10/1.50; pass False for the two factors throughout. The KPIs' line check
    (:mod:`tapm_opt.studies.kpis`, ``dnv_class1_common_factor``) is this function.

    Source: DNV-OS-E301 (October 2008), secondary transcription, unchecked.
    """
    tm = _finite("T_mean", T_mean, nonnegative=True)
    td = _finite("T_dyn", T_dyn, nonnegative=True)
    cc, ls = _class_and_state(consequence_class, limit_state)
    g_mean, g_dyn = partial_safety_factors(cc, ls, analysis)
    if common_factor and analysis == "dynamic" and ls == "ULS" and cc == 1 and tm > 2.0 / 3.0 * td:
        return DNV_CLASS1_COMMON_FACTOR * (tm + td)
    return g_mean * tm + g_dyn * td


def utilisation(T_c: float, MBS: float, capacity_factor: float = DNV_CAPACITY_FACTOR) -> float:
    """Utilisation of the strength check, ``T_c / S_C`` with ``S_C = capacity_factor * MBS``.

    ``T_c`` [N] the design tension (:func:`characteristic_tension`, >= 0), ``MBS`` [N] the minimum
    breaking strength (> 0). ``capacity_factor`` defaults to 0.95, the characteristic capacity of
    chain ``S_C = 0.95 MBS`` (DNV-OS-E301 definition, October 2008, secondary transcription,
    unchecked); pass the factor of the component's own definition for wire or fibre rope
    (0 < factor <= 1). A value <= 1 passes.
    """
    tc = _finite("T_c", T_c, nonnegative=True)
    mbs = _finite("MBS", MBS, positive=True)
    cf = _finite("capacity_factor", capacity_factor, positive=True)
    if cf > 1.0:
        raise VerificationError(f"capacity_factor = {cf!r} must be in (0, 1]")
    return tc / (cf * mbs)


# -- fatigue: T-N curves, rainflow, Miner ---------------------------------------------------------

# T-N curves, nominal areas, rainflow counting and Miner's sum: :mod:`tapm_opt.models.fatigue`
# (one definition, shared with the fatigue-aware setpoint layer), re-exported here.


#: Seconds in a year (365.25 days).
SECONDS_PER_YEAR = 365.25 * 24.0 * 3600.0


def annual_damage(damages: Sequence[float] | np.ndarray, probabilities: Sequence[float] | np.ndarray,
                  record_duration: float) -> float:
    """Annual fatigue damage [1/year] from the damage of one record per sea state.

    ``D_year = (SECONDS_PER_YEAR / record_duration) * sum_i p_i D_i``, with ``D_i`` the damage of a
    record of ``record_duration`` [s] in sea state ``i`` (:func:`miner_damage`, >= 0) and ``p_i``
    its probability of occurrence (the share of the year, each in [0, 1], summing to at most 1; a
    sum below 1 leaves the rest of the year undamaged). Source: damage summed over the sea states
    weighted by their occurrence (DNV-OS-E301 FLS, project standards notes).
    """
    D = _finite_array("damages", damages, min_len=1)
    p = _finite_array("probabilities", probabilities, min_len=1)
    if D.size != p.size:
        raise VerificationError(f"probabilities: {p.size} values for {D.size} damages; give one per sea state")
    if np.any(D < 0):
        i = int(np.flatnonzero(D < 0)[0])
        raise VerificationError(f"damages[{i}] = {float(D[i])!r} must be >= 0")
    if np.any((p < 0) | (p > 1)):
        i = int(np.flatnonzero((p < 0) | (p > 1))[0])
        raise VerificationError(f"probabilities[{i}] = {float(p[i])!r} must be in [0, 1]")
    if p.sum() > 1.0 + 1e-9:
        raise VerificationError(f"probabilities sum to {float(p.sum())!r}, more than 1")
    T = _finite("record_duration", record_duration, positive=True)
    return float(np.dot(p, D)) * SECONDS_PER_YEAR / T


def fatigue_life(annual_damage: float, design_fatigue_factor: float) -> float:
    """Fatigue life [years], ``1 / (DFF * D_year)``; ``inf`` for zero damage.

    ``annual_damage`` [1/year] (:func:`annual_damage`, >= 0); ``design_fatigue_factor`` (DFF,
    >= 1) multiplies the damage (values of 5-10 are quoted where the line cannot be inspected;
    project standards notes, secondary). The line passes when the life is at least the design life.
    """
    D = _finite("annual_damage", annual_damage, nonnegative=True)
    dff = _finite("design_fatigue_factor", design_fatigue_factor, positive=True)
    if dff < 1.0:
        raise VerificationError(f"design_fatigue_factor = {dff!r} must be >= 1")
    return math.inf if D == 0.0 else 1.0 / (dff * D)


# -- design fatigue factor from the adjacent line ------------------------------------------------

#: ``d_F`` at and below which DNV-OS-E301's design fatigue factor is its base value (as read,
#: secondary, unchecked): :func:`adjacent_fatigue_factor`.
DFF_ADJACENT_KNEE = 0.8
#: The design fatigue factor for ``d_F <= DFF_ADJACENT_KNEE`` and its rise to ``d_F = 1``.
DFF_ADJACENT_BASE = 5.0
DFF_ADJACENT_RISE = 3.0


def adjacent_fatigue_factor(d_F: float) -> float:
    """DNV-OS-E301's design fatigue factor ``gamma_F`` from the adjacent lines' damage ratio
    (Ch. 2 Sec. 2, FLS design equation ``1 - d_c gamma_F >= 0``, as commonly read; a **secondary
    reading, unchecked against the standard**):

    ``gamma_F = 5`` for ``d_F <= 0.8``, ``gamma_F = 5 + 3 (d_F - 0.8) / 0.2`` for ``d_F > 0.8``
    (8 at ``d_F = 1``, two adjacent lines equally damaged), ``d_F`` the ratio of the smaller to the
    larger characteristic fatigue damage of the two adjacent lines with the largest damage
    (:func:`damage_ratio`), in [0, 1]. :class:`VerificationError` outside [0, 1] or not finite.
    """
    d = _finite("d_F", d_F, nonnegative=True)
    if d > 1.0:
        raise VerificationError(f"d_F = {d_F!r} must be in [0, 1] (the smaller damage over the larger)")
    if d <= DFF_ADJACENT_KNEE:
        return DFF_ADJACENT_BASE
    return DFF_ADJACENT_BASE + DFF_ADJACENT_RISE * (d - DFF_ADJACENT_KNEE) / (1.0 - DFF_ADJACENT_KNEE)


def damage_ratio(D_a: float, D_b: float) -> float:
    """``d_F`` of two adjacent lines' fatigue damages (each >= 0): the smaller over the larger, in
    [0, 1]; 1 when both are 0 (equally damaged). :class:`VerificationError` for a negative or
    non-finite damage."""
    a = _finite("D_a", D_a, nonnegative=True)
    b = _finite("D_b", D_b, nonnegative=True)
    hi = max(a, b)
    return 1.0 if hi == 0.0 else min(a, b) / hi


def line_neighbours(azimuths: Sequence[float] | np.ndarray) -> list[tuple[int, int]]:
    """The two neighbours of each line around the vessel: ``azimuths`` [rad] the lines' directions
    about the turret (e.g. their fairlead angles), one per line; returns per line the indices of
    ``(the line at the next lower azimuth, the line at the next higher)`` in the cyclic order of
    the azimuths (taken modulo 2 pi; equal azimuths keep the given order). One line: its own index twice (no neighbour); two
    lines: each other twice. :class:`VerificationError` for an empty or non-finite input."""
    a = _finite_array("azimuths", azimuths, min_len=1)
    n = a.size
    order = np.argsort(np.mod(a, 2.0 * math.pi), kind="stable")
    pos = np.empty(n, dtype=int)
    pos[order] = np.arange(n)
    return [(int(order[(pos[i] - 1) % n]), int(order[(pos[i] + 1) % n])) for i in range(n)]
