"""Static equilibrium of the moored vessel: the one root finder.

Every rest point in the project — the pose where the catenary mooring balances a mean load
(:meth:`~tapm_opt.models.mooring.MooringModel.equilibrium`, used by the gain design and by
:func:`~tapm_opt.control.pid_design.design_from_scenario`) and the rest state of a CasADi vessel model
(:func:`~tapm_opt.models.vessel.equilibrium`) — is found by :func:`solve_equilibrium`: Powell's
hybrid method (``scipy.optimize.root``, ``method="hybr"``) with the exact Jacobian, judged on the
residual (not on the solver's ``success`` flag), and, if the direct solve fails, continuation in
the load from the start point.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..errors import ModelError, TapmError

__all__ = ["EquilibriumError", "solve_equilibrium", "CONTINUATION_STEPS"]

#: Load steps of the continuation s = 0, 1/n, ..., 1 tried when the direct solve fails.
CONTINUATION_STEPS = 10


class EquilibriumError(ModelError):
    """No static equilibrium was found.

    Attributes
    ----------
    residual : float
        Largest |residual| of the last attempt (inf if it left the model's domain).
    reason : str
        What stopped the last attempt (solver message, or the model's error).
    """

    def __init__(self, message: str, *, residual: float = math.inf, reason: str = "") -> None:
        super().__init__(message)
        self.residual = float(residual)
        self.reason = reason


Residual = Callable[[np.ndarray, float], np.ndarray]


def _attempt(residual: Residual, jacobian: Residual, guess: np.ndarray, s: float, tol: float
             ) -> tuple[np.ndarray | None, float, str]:
    try:
        import scipy.optimize  # loaded on first use (process start-up)

        sol = scipy.optimize.root(lambda x: residual(x, s), guess, jac=lambda x: jacobian(x, s),
                                  method="hybr")
        ok = bool(np.all(np.isfinite(sol.x)))
        res = float(np.max(np.abs(residual(sol.x, s)))) if ok else math.inf
    except TapmError as exc:  # e.g. a catenary line pulled beyond its reach
        return None, math.inf, f"the search left the model's domain ({exc})"
    if res <= tol:  # NaN fails too
        return np.array(sol.x, dtype=float), res, ""
    msg = " ".join(str(sol.message).split())  # scipy's messages hold line breaks
    return None, res, f"{msg} (residual {res:.3g} > tol={tol:g})"


def solve_equilibrium(residual: Residual, jacobian: Residual, guess: np.ndarray, *, tol: float,
                      steps: int = CONTINUATION_STEPS) -> np.ndarray:
    """Root of ``residual(x, s) = 0`` at full load ``s = 1``.

    First Powell's hybrid method from ``guess`` at ``s = 1``; if that fails (residual above
    ``tol``, a non-finite point, or a :class:`~tapm_opt.errors.TapmError` raised by the model),
    continuation: ``s = 0, 1/steps, ..., 1``, each solve starting from the previous root (the
    first from ``guess``).

    Parameters
    ----------
    residual : callable ``(x, s) -> ndarray, shape (n,)``
        Balance of the loads at point ``x`` with the load scaled by ``s`` in [0, 1] (scaled to
        be O(1), the unit of ``tol``).
    jacobian : callable ``(x, s) -> ndarray, shape (n, n)``
        d residual / d x.
    guess : ndarray, shape (n,)
        Start point.
    tol : float
        Largest accepted |residual| at the root.
    steps : int
        Continuation steps; 0: direct solve only.

    Returns
    -------
    ndarray, shape (n,)

    Raises
    ------
    EquilibriumError
        Neither the direct solve nor the continuation reached ``tol``; ``residual`` and
        ``reason`` describe the last attempt.
    """
    guess = np.asarray(guess, dtype=float)
    x, res, why = _attempt(residual, jacobian, guess, 1.0, tol)
    if x is not None:
        return x
    if steps > 0:
        x_s = guess
        for s in np.linspace(0.0, 1.0, int(steps) + 1):
            step, res, why_s = _attempt(residual, jacobian, x_s, float(s), tol)
            if step is None:
                why = f"{why}; continuation stopped at load fraction {s:.2g}: {why_s}"
                break
            x_s = step
        else:
            return x_s
    raise EquilibriumError(f"no equilibrium: {why}", residual=res, reason=why)
