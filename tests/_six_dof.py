"""A scenario with the hull's six-degree-of-freedom wave-frequency motion (shared by the tests)."""

from __future__ import annotations

import dataclasses
from typing import Any


def six_dof(sc: Any, **kw: Any) -> Any:
    """``sc`` with ``vessel.wave_motion.model = "six_dof"`` and any other ``wave_motion`` fields ``kw``."""
    wm = dataclasses.replace(sc.vessel.wave_motion, model="six_dof", **kw)
    return dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, wave_motion=wm))


def horizontal(sc: Any) -> Any:
    """``sc`` with ``vessel.wave_motion.model = "horizontal"``: surge, sway and yaw only (the plant
    before six-degree-of-freedom motion; the built-in fpso moves in six)."""
    wm = dataclasses.replace(sc.vessel.wave_motion, model="horizontal")
    return dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, wave_motion=wm))
