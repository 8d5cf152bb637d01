"""Argument checks shared by every layer: a number, a bounded number, a vector.

Each check returns the value converted (``float``, or a new float ``ndarray``) or raises the
caller's own exception type (``error=``), with a message that names the field, shows the value
and says what is allowed::

    dt = -1.0 s must be a positive number
    kc = 'fast' must be a finite number >= 0 [1/s]
    eta = [1.0, nan, 0.0] must be 3 finite numbers (x [m], y [m], psi [rad])
    estimate.eta must have shape (3,), got shape (2,): estimate.eta = [0.0, 0.0] must be 3 finite numbers

``eq`` is how the field and the value are joined: ``" = "`` (default) or ``"="``, the compact
form some modules' messages have always used (tests and users match on them).

Also the two small predicates the scenario and study checks share: :func:`is_number` (an ``int``
or ``float``, not a ``bool``) and :func:`fmt` (a value as a message shows it).

Top layer: imports nothing from tapm_opt, so any module may use it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["finite", "fmt", "is_number", "positive", "rule", "vector"]


def is_number(v: Any) -> bool:
    """Whether ``v`` is an ``int`` or a ``float`` (a ``bool`` is not a number here)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def fmt(v: Any) -> str:
    """``v`` as a message shows it: a float by ``:g``, a string quoted, anything else by ``str``."""
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, str):
        return repr(v)
    return str(v)


def rule(*, lo: float | None = None, hi: float | None = None, strict: bool = False, plural: bool = False) -> str:
    """What a check allows, as the end of ``"... must be "``: ``"a finite number >= 0"``,
    ``"a positive number"`` (``lo=0, strict=True``), ``"finite numbers in [0, 1]"`` (plural)..."""
    s = "s" if plural else ""
    art = "" if plural else "a "
    if lo == 0.0 and strict and hi is None:
        return f"{art}positive number{s}"
    parts = []
    if lo is not None and lo > -math.inf:
        parts.append(f"{'>' if strict else '>='} {lo:g}")
    if hi is not None and hi < math.inf:
        parts.append(f"<= {hi:g}")
    return f"{art}finite number{s}" + (" " + " and ".join(parts) if parts else "")


def _unit_after(unit: str) -> str:
    return f" [{unit}]" if unit else ""


def finite(name: str, v: Any, *, lo: float | None = None, hi: float | None = None, strict: bool = False,
           unit: str = "", error: type[Exception] = ValueError, eq: str = " = ",
           numbers_only: bool = False) -> float:
    """``v`` as a finite float, within the bounds, else ``error`` naming ``name`` and the value.

    Parameters
    ----------
    name : str
        The field as the user knows it (``"dt"``, ``"settings.sigma_T"``, ``"lines[2].EA"``).
    v : any
        The value; anything ``float()`` takes (with ``numbers_only``: an ``int`` or ``float``,
        not a ``bool`` or a string).
    lo, hi : float, optional
        Bounds: ``v >= lo`` (``v > lo`` with ``strict``) and ``v <= hi``.
    strict : bool
        Whether ``lo`` itself is excluded.
    unit : str
        Unit shown after the value (``"dt = -1.0 s must be ..."``).
    error : exception type
        What to raise: the caller's own typed error.
    eq : str
        How the field and the value are joined in the message (``" = "`` or ``"="``).
    numbers_only : bool
        Reject anything that is not an ``int`` or ``float`` (:func:`is_number`).

    Returns
    -------
    float

    Raises
    ------
    error
        ``v`` is not a number, not finite, or out of bounds.
    """
    try:
        x = float(v)
        if numbers_only and not is_number(v):
            raise TypeError
    except (TypeError, ValueError):
        raise error(f"{name}{eq}{v!r} must be {rule(lo=lo, hi=hi, strict=strict)}{_unit_after(unit)}") from None
    if (not math.isfinite(x) or (lo is not None and (x <= lo if strict else x < lo))
            or (hi is not None and x > hi)):
        raise error(f"{name}{eq}{v!r}{' ' + unit if unit else ''} must be {rule(lo=lo, hi=hi, strict=strict)}")
    return x


def positive(name: str, v: Any, *, unit: str = "", error: type[Exception] = ValueError, eq: str = " = ",
             numbers_only: bool = False) -> float:
    """``v`` as a finite float > 0: :func:`finite` with ``lo=0, strict=True``."""
    return finite(name, v, lo=0.0, strict=True, unit=unit, error=error, eq=eq, numbers_only=numbers_only)


def vector(name: str, v: Any, n: int, *, lo: float | None = None, hi: float | None = None, strict: bool = False,
           unit: str = "", what: str = "", broadcast: bool = False, error: type[Exception] = ValueError,
           eq: str = " = ", note: str = "") -> np.ndarray:
    """``v`` as a new float array of shape ``(n,)``, every entry finite and within the bounds.

    Parameters
    ----------
    name, lo, hi, strict, error, eq
        As for :func:`finite` (the bounds apply to every entry).
    n : int
        Number of entries.
    unit : str
        Unit of every entry, shown in brackets at the end of the message.
    what : str
        What the entries are, shown after the count (``"(x [m], y [m], psi [rad])"``).
    broadcast : bool
        Also take one number (or a one-entry sequence) for all ``n`` entries.
    note : str
        Appended to the message of a non-finite or out-of-bounds entry (what the caller will not
        do with it, where to look).

    Raises
    ------
    error
        Not numeric, another shape, or an entry that is not finite or out of bounds (the message
        shows the whole vector and the first bad entry).
    """
    def allowed() -> str:  # built only for a message
        count = f"one or {n}" if broadcast else f"{n}"
        return (f"{count} {rule(lo=lo, hi=hi, strict=strict, plural=True)}" + (f" {what}" if what else "")
                + _unit_after(unit))

    try:
        a = np.array(v, dtype=float)
    except (TypeError, ValueError):
        raise error(f"{name}{eq}{v!r} must be {allowed()}") from None
    if broadcast and a.shape != (n,) and a.size == 1 and a.ndim <= 1:
        a = np.full(n, float(a.reshape(())))  # as numpy broadcasts () and (1,) to (n,)
    if a.shape != (n,):
        shown = a.tolist() if a.ndim else v
        raise error(f"{name} must have shape ({n},), got shape {a.shape}: {name}{eq}{shown!r} must be {allowed()}")
    ok = np.isfinite(a)
    if lo is not None:
        ok &= (a > lo) if strict else (a >= lo)
    if hi is not None:
        ok &= a <= hi
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        raise error(f"{name}{eq}{a.tolist()!r} must be {allowed()} ({name}[{i}] is not)" + (f"; {note}" if note else ""))
    return a
