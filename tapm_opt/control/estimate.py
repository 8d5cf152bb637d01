"""What a motion controller receives: the state estimate and the setpoint.

Shared by every controller behind ``update(t, estimate, setpoint) -> tau`` (PID modes, MPC).
Both are frozen; their arrays are read-only float copies of what was passed in. They do not
validate shapes or finiteness: each controller checks its inputs and raises its own typed error
naming the bad field (a controller must never turn a NaN estimate into a NaN command).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Estimate", "Setpoint"]


def _ro(value: object) -> np.ndarray:
    arr = np.array(value, dtype=float)  # always a copy: callers keep their arrays
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class Estimate:
    """State estimate handed to controllers.

    Parameters
    ----------
    t : float
        Time of the estimate [s].
    eta : ndarray, shape (3,)
        Low-frequency position and heading in {E} (x [m], y [m], psi [rad]).
    nu : ndarray, shape (3,)
        Low-frequency velocity in {B} (u [m/s], v [m/s], r [rad/s]).
    tau_env : ndarray, shape (3,)
        Estimated slowly varying environmental load in {B} (X [N], Y [N], N [N m]); zeros if
        unknown.
    tensions : ndarray, shape (n_lines,), optional
        Measured fairlead tensions [N], if available.
    """

    t: float
    eta: np.ndarray
    nu: np.ndarray
    tau_env: np.ndarray
    tensions: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", float(self.t))
        for name in ("eta", "nu", "tau_env"):
            object.__setattr__(self, name, _ro(getattr(self, name)))
        if self.tensions is not None:
            object.__setattr__(self, "tensions", _ro(self.tensions))


@dataclass(frozen=True, eq=False)
class Setpoint:
    """Desired motion handed to controllers.

    Parameters
    ----------
    eta_d : ndarray, shape (3,)
        Desired position and heading in {E} (x [m], y [m], psi [rad]).
    nu_d : ndarray, shape (3,)
        Desired velocity in {B} (u [m/s], v [m/s], r [rad/s]); zeros by default.
    """

    eta_d: np.ndarray
    nu_d: np.ndarray = field(default_factory=lambda: _ro(np.zeros(3)))

    def __post_init__(self) -> None:
        for name in ("eta_d", "nu_d"):
            object.__setattr__(self, name, _ro(getattr(self, name)))
