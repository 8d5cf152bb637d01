"""Line-break detection from the tension cells.

:class:`TensionDropDetector` is the simplest detector a vessel with tension cells has: a line whose
measured fairlead tension stays below ``fraction`` of its pretension (the design model's tension at
the field zero point) for ``hold`` seconds is declared broken, and stays so. It needs no model of
the vessel's motion: the fairlead tension of an intact catenary line cannot fall below the weight
of the line hanging between the fairlead and the seabed (on fpso the slack side keeps at least 75 % of
its pretension quasi-statically anywhere on the alert circle), while a broken line reads its cell's
noise about zero.

Detected breaks reach the setpoint layer and the controllers through ``Estimate.broken_lines``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import TapmError

__all__ = ["TensionDropDetector", "DetectionError"]


class DetectionError(TapmError, ValueError):
    """Bad detector settings or measurements."""


class TensionDropDetector:
    """Declares a line broken when its measured tension stays below ``fraction`` x pretension.

    Parameters
    ----------
    model : MooringModel
        The intact design model (its line ids and its tensions at eta = 0).
    fraction : float
        Threshold as a fraction of each line's pretension, in (0, 1) [-].
    hold : float
        Time the tension must stay below the threshold [s], >= 0.
    """

    def __init__(self, model: Any, *, fraction: float = 0.2, hold: float = 5.0):
        if not (isinstance(fraction, (int, float)) and 0 < fraction < 1):
            raise DetectionError(f"fraction = {fraction!r} must be a number in (0, 1)")
        if not (isinstance(hold, (int, float)) and math.isfinite(hold) and hold >= 0):
            raise DetectionError(f"hold = {hold!r} s must be a number >= 0")
        self.line_ids = tuple(model.line_ids)
        self.threshold = fraction * np.asarray(model.tensions(np.zeros(3)), float)
        self.fraction, self.hold = float(fraction), float(hold)
        self.reset()

    def reset(self) -> None:
        self._since = np.full(len(self.line_ids), np.nan)   # time each line fell below, NaN if above
        self.broken: frozenset[str] = frozenset()
        self.events: list[dict] = []

    def update(self, t: float, tensions: Any, eta: Any = None) -> frozenset[str]:
        """Feed the measured fairlead tensions (n,) [N] at time ``t`` [s]; returns the lines known
        broken so far. ``eta`` (the estimator's LF pose) is not used: this test needs no model of
        the motion."""
        T = np.asarray(tensions, float)
        if T.shape != self._since.shape:
            raise DetectionError(f"tensions has shape {T.shape}, expected ({len(self.line_ids)},) for lines "
                                 f"{list(self.line_ids)}")
        if not np.all(np.isfinite(T)):
            i = int(np.flatnonzero(~np.isfinite(T))[0])
            raise DetectionError(f"tensions[{i}] (line {self.line_ids[i]!r}) = {float(T[i])!r} N must be finite")
        low = T < self.threshold
        self._since = np.where(low, np.where(np.isnan(self._since), t, self._since), np.nan)
        new = [lid for lid, s in zip(self.line_ids, self._since)
               if not math.isnan(s) and t - s >= self.hold and lid not in self.broken]
        if new:
            self.broken = self.broken | frozenset(new)
            self.events += [{"t": float(t), "line": lid, "event": "line break detected"} for lid in new]
        return self.broken
