"""Elementary functions that work on numpy arrays and on CasADi symbols alike.

One equation, one definition: kinematics and catenary residuals are written once with these
functions and evaluated either numerically (numpy, vectorised) or symbolically (CasADi SX/MX).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

_CASADI_TYPES = (ca.SX, ca.MX, ca.DM)


def is_symbolic(*xs: Any) -> bool:
    """True if any argument is a CasADi object (SX, MX or DM)."""
    for x in xs:
        if isinstance(x, _CASADI_TYPES):
            return True
    return False


def sin(x):
    return ca.sin(x) if is_symbolic(x) else np.sin(x)


def cos(x):
    return ca.cos(x) if is_symbolic(x) else np.cos(x)


def sqrt(x):
    return ca.sqrt(x) if is_symbolic(x) else np.sqrt(x)


def asinh(x):
    return ca.asinh(x) if is_symbolic(x) else np.arcsinh(x)


def atan2(y, x):
    return ca.atan2(y, x) if is_symbolic(y, x) else np.arctan2(y, x)


def hypot(x, y):
    """sqrt(x**2 + y**2) without overflow for numpy; plain form for CasADi."""
    if is_symbolic(x, y):
        return ca.sqrt(x * x + y * y)
    return np.hypot(x, y)


def fmax(a, b):
    return ca.fmax(a, b) if is_symbolic(a, b) else np.maximum(a, b)


def fabs(x):
    return ca.fabs(x) if is_symbolic(x) else np.abs(x)


def floor(x):
    return ca.floor(x) if is_symbolic(x) else np.floor(x)


def where(cond, a, b):
    """Elementwise ``a if cond else b``."""
    if is_symbolic(cond, a, b):
        return ca.if_else(cond, a, b)
    return np.where(cond, a, b)


def sum_(x):
    """Sum of all elements (CasADi column or numpy array)."""
    return ca.sum1(x) if is_symbolic(x) else np.sum(x)
