"""Controllers from a plain specification, for ``tapm simulate`` and study files.

The kinds, their options, tuned defaults and search spaces are defined once, in
:mod:`tapm_opt.design.registry` (``docs/controllers.md`` lists them); this module gives the
study side its entry point, :func:`build_controller`, with the closed loop's context (control
period, estimator, winch control) as keywords.
"""

from __future__ import annotations

from typing import Any, Mapping

from ..design.registry import (DEAD_BAND_DAMAGED_FRACTION, DEAD_BAND_FRACTION, ControllerSpecError, build, kind,
                                kind_names)

__all__ = ["build_controller", "controller_types", "ControllerSpecError", "MPC_DEFAULTS", "MPC_DEAD_BAND",
           "MPC_DEAD_BAND_DAMAGED"]

#: The MPCs' tuned weights (the registry's defaults of the kinds ``mpc`` and ``lmpc`` that differ
#: from ``MPCSettings``'), for code that builds ``MPCSettings`` by hand.
MPC_DEFAULTS = {k: kind("lmpc").defaults()[k] for k in ("w_thrust", "w_rate", "w_velocity")}
#: The MPCs' dead band as a fraction of the safe radius (``registry.DEAD_BAND_FRACTION``).
MPC_DEAD_BAND = DEAD_BAND_FRACTION
#: The MPCs' dead band after a reported break, as a fraction of the dead band.
MPC_DEAD_BAND_DAMAGED = DEAD_BAND_DAMAGED_FRACTION


def controller_types() -> tuple[str, ...]:
    """The registered controller kinds' names (built-in, registered and installed)."""
    return kind_names()


def build_controller(system: Any, spec: Mapping[str, Any] | str, *, where: str = "controller",
                     dt_control: float = 1.0, estimator: str | None = None,
                     winch: Mapping[str, Any] | None = None) -> Any:
    """A :class:`~tapm_opt.interfaces.Controller` from a specification
    (:func:`tapm_opt.design.registry.build`).

    Parameters
    ----------
    system : System or Scenario
        The system the controller is designed on (a scenario is built into its System).
    spec : mapping or str
        ``{"type": kind, option: value, ...}`` or just the kind.
    where : str
        Prefix of error messages (``--option``, ``controllers[1]``).
    dt_control : float
        The loop's control period [s]: a sea-state supervisor samples the estimate at it.
    estimator : {"lowpass", "passive", "ekf"}, optional
        The loop's estimator (default :data:`~tapm_opt.estimation.DEFAULT_ESTIMATOR`).
    winch : mapping or None
        The loop's winch (line-tension) control options when ``winch = "tension"``, else None.

    Raises
    ------
    ControllerSpecError
        Unknown kind or option, or an invalid value (the message names ``where.option``).
    """
    return build(system, spec, where=where, dt_control=dt_control, estimator=estimator, winch=winch)
