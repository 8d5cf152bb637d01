"""A scenario with the hull's six-degree-of-freedom wave-frequency motion, and fpso's pair of
fixtures (shared by the tests: ``from _six_dof import fpso, fpso6``)."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

import tapm_opt


def _with_model(sc: Any, model: str, **kw: Any) -> Any:
    wm = dataclasses.replace(sc.vessel.wave_motion, model=model, **kw)
    return dataclasses.replace(sc, vessel=dataclasses.replace(sc.vessel, wave_motion=wm))


def six_dof(sc: Any, **kw: Any) -> Any:
    """``sc`` with ``vessel.wave_motion.model = "six_dof"`` and any other ``wave_motion`` fields ``kw``."""
    return _with_model(sc, "six_dof", **kw)


def horizontal(sc: Any) -> Any:
    """``sc`` with ``vessel.wave_motion.model = "horizontal"``: surge, sway and yaw only (the plant
    before six-degree-of-freedom motion; the built-in fpso moves in six)."""
    return _with_model(sc, "horizontal")


@pytest.fixture(scope="module")
def fpso():
    """fpso with surge, sway and yaw only (the built-in moves in six degrees of freedom)."""
    return horizontal(tapm_opt.load_scenario("fpso"))


@pytest.fixture(scope="module")
def fpso6(fpso):
    """fpso with the closed form's heave, roll and pitch (its built-in hull fields)."""
    return six_dof(fpso)
