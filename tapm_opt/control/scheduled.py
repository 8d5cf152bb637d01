"""Gain-scheduled TAPM PID: one :class:`~tapm_opt.control.pid.TAPMPID` per operating condition.

The gains come from a gain table (``docs/gains.md``), read with
:mod:`tapm_opt.control.gain_table` — the one reader and writer of the format
``tapm_opt.gains/1``, which the design code (``tapm_opt.design.gains``) writes with — so the
import direction stays config -> models -> control -> design. A supervisor (sea-state detection,
line-break detection, [S] §4.5 Fig. 9) calls :meth:`GainScheduledPID.select` when the condition
changes; the controller switches to that condition's gains and to the mode set of its sea-state
class ([S] Table 3).

Switching is bumpless in the integral: the integral load ``K_i R(psi)^T xi`` in {B} that the old
controller applied is handed to the new one (its xi is rescaled to its own K_i) for every
component the new mode set integrates; components it does not integrate start at zero, as in
:meth:`TAPMPID.set_modes`. The proportional and damping terms change with the gains at the
switch (a step of (K_p,new - K_p,old) e), which is small while the vessel is near its setpoint.

``[S]`` = seed survey-tapm-modeling-and-control.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..geometry import rot_z, ssa
from ..interfaces import ControllerStep, Estimate, Setpoint
from ..models.system import as_system
from .gain_table import FORMAT as TABLE_FORMAT
from .gain_table import Condition, GainTable, load_gain_table
from .pid import H_PSI, H_XY, MODE_SETS, ControlError, TAPMPID

__all__ = ["GainScheduledPID", "ScheduledCondition", "TABLE_FORMAT"]

#: One operating condition of the schedule: the table's
#: :class:`~tapm_opt.control.gain_table.Condition` (sea_state, sea_class, mode_set, broken,
#: heading [rad], weathervane).
ScheduledCondition = Condition


class _ScheduledTAPMPID(TAPMPID):
    """A TAPMPID whose integral state can be handed over at a switch (bumpless transfer)."""

    def _adopt(self, xi: np.ndarray, t_prev: float | None, psi: float,
               saturated: np.ndarray, tau_prev: np.ndarray) -> None:
        # TAPMPID has no public setter for its state; this subclass is the one place that
        # writes it (a TAPMPID.set_state in pid.py would make this unnecessary).
        self._xi = np.where(self._mask, xi, 0.0)
        self._t_prev = t_prev
        self._psi = float(psi)
        self._sat = np.array(saturated, dtype=bool)
        self._tau_unsat = np.array(tau_prev, dtype=float)


def _as_table(table: Any) -> GainTable:
    if isinstance(table, GainTable):
        return table
    if isinstance(table, Mapping):
        return GainTable.from_dict(table)
    raise ControlError(f"table must be a gain table (GainTable or its JSON dict), got "
                       f"{type(table).__name__}")


class GainScheduledPID:
    """TAPM PID with gains and mode set switched by operating condition.

    ``update(t, estimate, setpoint) -> tau`` runs the active condition's
    :class:`~tapm_opt.control.pid.TAPMPID`; :meth:`select` switches the condition.

    Parameters
    ----------
    table : GainTable or mapping
        A :class:`~tapm_opt.control.gain_table.GainTable` or its JSON dict
        (``GainTable.to_dict()``, the content of ``gains.json``).
    scenario : Scenario or System, optional
        If given, the table must have been made for it (same name) and its broken-line ids must
        be line ids of the scenario; it also gives the defaults of ``tau_limit`` (the thrusters'
        capacity box, ``models.system.ThrusterSet.capacity_box``) and ``reference_point`` (the
        centre of turret, so positions are turret offsets).
    tau_limit, integral_limit, anti_windup, env_feedforward, reference_point
        Passed to every :class:`~tapm_opt.control.pid.TAPMPID`. Without a scenario the defaults are
        no saturation and the body origin.
    period : float or None
        Update period [s] for the closed-loop runner (None: the runner's control period).

    Notes
    -----
    The first row of the table is active until :meth:`select` is called. A table row's heading
    is the heading its gains were designed at; :meth:`select` takes the row nearest to the
    requested heading.
    """

    def __init__(self, table: Any, *, scenario: Any = None, tau_limit: Any = None,
                 integral_limit: Any = None, anti_windup: bool = True,
                 env_feedforward: bool = False, reference_point: Any = None,
                 period: float | None = None) -> None:
        tab = _as_table(table)
        system = None if scenario is None else as_system(scenario)
        scenario = None if system is None else system.scenario
        if reference_point is None:
            reference_point = (0.0, 0.0) if system is None else system.p_cot_B
        if tau_limit is None and system is not None and system.thrusters.n:
            tau_limit = system.thrusters.capacity_box()
        if not tab.rows:
            raise ControlError("the gain table has no rows")
        self._meta = dict(tab.meta)
        conds: list[Condition] = []
        ctrls: list[_ScheduledTAPMPID] = []
        for i, row in enumerate(tab.rows):
            cond = row.condition
            if cond.mode_set not in MODE_SETS:
                raise ControlError(f"rows[{i}].condition.mode_set={cond.mode_set!r} is not one "
                                   f"of {tuple(MODE_SETS)}")
            conds.append(cond)
            ctrls.append(_ScheduledTAPMPID(row.pid.gains, modes=cond.mode_set, tau_limit=tau_limit,
                                           integral_limit=integral_limit,
                                           anti_windup=anti_windup,
                                           env_feedforward=env_feedforward,
                                           reference_point=reference_point, period=period))
        if scenario is not None:
            name = self._meta.get("scenario")
            if name != scenario.name:
                raise ControlError(f"the gain table was made for scenario {name!r}, not "
                                   f"{scenario.name!r}")
            ids = {ln.id for ln in scenario.lines}
            bad = sorted({c.broken for c in conds} - ids - {"intact"})
            if bad:
                raise ControlError(f"the gain table has broken line(s) {bad} that scenario "
                                   f"{scenario.name!r} does not have (lines {sorted(ids)})")
        self._conds = tuple(conds)
        self._ctrls = tuple(ctrls)
        self._active = 0
        c0 = conds[0]
        self._request: dict[str, Any] = {"sea_state": c0.sea_state, "broken": c0.broken,
                                         "heading": "weathervane" if c0.weathervane
                                         else c0.heading}
        self._t: float | None = None
        self._psi = 0.0
        self._tau = np.zeros(3)
        self.period = ctrls[0].period

    @classmethod
    def from_json(cls, path: str | Path, **kwargs: Any) -> GainScheduledPID:
        """Controller from ``gains.json`` (or a folder holding it); ``kwargs`` as for the
        constructor (e.g. ``scenario=``, ``tau_limit=``).

        Raises
        ------
        GainTableError
            (a :class:`~tapm_opt.control.pid.ControlError`) Missing or unreadable file, or not a
            gain table.
        """
        return cls(load_gain_table(path), **kwargs)

    # -- schedule ------------------------------------------------------------------------
    @property
    def conditions(self) -> tuple[ScheduledCondition, ...]:
        """Every condition of the table, in table order."""
        return self._conds

    @property
    def active(self) -> ScheduledCondition:
        """The active condition."""
        return self._conds[self._active]

    @property
    def controller(self) -> TAPMPID:
        """The active condition's controller."""
        return self._ctrls[self._active]

    @property
    def modes(self) -> tuple[str, ...]:
        return self.controller.modes

    @property
    def meta(self) -> dict:
        """The table's metadata (scenario, settings, units)."""
        return dict(self._meta)

    def _lookup(self, sea_state: str, broken: str, heading: float | str) -> int:
        cands = [i for i, c in enumerate(self._conds)
                 if c.sea_state == sea_state and c.broken == broken]
        if not cands:
            raise ControlError(
                f"no gains for sea_state={sea_state!r}, broken={broken!r}: the table has sea "
                f"states {sorted({c.sea_state for c in self._conds})} and mooring states "
                f"{sorted({c.broken for c in self._conds})}")
        if heading == "weathervane":
            wv = [i for i in cands if self._conds[i].weathervane]
            if not wv:
                raise ControlError(f"no weathervane gains for sea_state={sea_state!r}, "
                                   f"broken={broken!r}")
            return wv[0]
        return min(cands, key=lambda i: abs(ssa(self._conds[i].heading - float(heading))))

    def select(self, *, sea_state: str | None = None, broken: Any = None,
               heading: float | str | None = None) -> ScheduledCondition:
        """Switch to the condition (bumpless in the integral, see the module docstring).

        Parameters
        ----------
        sea_state : str, optional
            Sea-state id; None keeps the current one.
        broken : str or sequence of str, optional
            ``"intact"``, an empty sequence (intact), a line id or a one-element sequence; None
            keeps the current mooring state.
        heading : float or "weathervane", optional
            Heading [rad]: the row designed nearest to it is used; None keeps the last request.

        Returns
        -------
        ScheduledCondition
            The active condition.

        Raises
        ------
        ControlError
            No row for the request (the active condition is then unchanged).
        """
        req = dict(self._request)
        if sea_state is not None:
            req["sea_state"] = str(sea_state)
        if broken is not None:
            if isinstance(broken, (str, int)):
                req["broken"] = str(broken) if str(broken) else "intact"
            else:
                ids = [str(b) for b in broken]
                if len(ids) > 1:
                    raise ControlError(f"broken={ids}: the gain table holds single-line failures "
                                       f"only")
                req["broken"] = ids[0] if ids else "intact"
        if heading is not None:
            if heading != "weathervane":
                try:
                    heading = float(heading)
                except (TypeError, ValueError):
                    raise ControlError(f"heading={heading!r} must be a heading [rad] or "
                                       f"'weathervane'") from None
                if not math.isfinite(heading):
                    raise ControlError(f"heading={heading!r} must be finite [rad]")
            req["heading"] = heading
        new = self._lookup(req["sea_state"], req["broken"], req["heading"])
        self._request = req
        if new != self._active:
            self._hand_over(self._ctrls[self._active], self._ctrls[new])
            self._active = new
        return self.active

    def _hand_over(self, old: TAPMPID, new: _ScheduledTAPMPID) -> None:
        """Give ``new`` the integral load of ``old`` for the components it integrates."""
        if self._t is None:
            new.reset()
            return
        q = -np.asarray(old.integral_load)  # K_i,old R^T xi_old in {B} (its used rows)
        H_I = np.zeros((3, 3))  # rows of K_i the new mode set uses ([S] Table 2)
        if "heading" in new.modes:
            H_I = H_I + H_PSI
        if "mean" in new.modes:
            H_I = H_I + H_XY
        xi_B = np.linalg.pinv(H_I @ new.gains.Ki) @ q
        new._adopt(rot_z(self._psi) @ xi_B, self._t, self._psi, old.saturated, self._tau)

    # -- control -------------------------------------------------------------------------
    def reset(self) -> None:
        """Reset every controller (integral, clock); the active condition is kept."""
        for c in self._ctrls:
            c.reset()
        self._t = None
        self._tau = np.zeros(3)

    def update(self, t: float, estimate: Estimate, setpoint: Setpoint) -> np.ndarray:
        """Command of the active condition's controller, see :meth:`TAPMPID.update`.

        Returns
        -------
        tau : ndarray, shape (3,)
            Commanded load in {B} (X [N], Y [N], N [N m]).
        """
        tau = self.controller.update(t, estimate, setpoint)
        self._t = float(t)
        self._psi = float(np.asarray(estimate.eta, dtype=float)[2])
        self._tau = np.array(tau, dtype=float)
        return tau

    def last_step(self) -> ControllerStep | None:
        """Diagnostics of the active controller's latest update."""
        return self.controller.last_step()

    @property
    def integral_load(self) -> np.ndarray:
        """Integral part of the last command in {B} [N, N, N m] (active controller)."""
        return self.controller.integral_load
