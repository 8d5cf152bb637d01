"""Gain-scheduled TAPM PID: one :class:`~tapm_opt.control.pid.TAPMPID` per operating condition.

The gains come from a gain table (``tapm_opt.design.gains``, ``docs/gains.md``), read from its
JSON file without the code that made it: this module knows the file format
(``tapm_opt.gains/1``), not the design code, so the import direction stays config -> models ->
control -> design. A supervisor (sea-state detection, line-break detection, [S] §4.5 Fig. 9)
calls :meth:`GainScheduledPID.select` when the condition changes; the controller switches to that
condition's gains and to the mode set of its sea-state class ([S] Table 3).

Switching is bumpless in the integral: the integral load ``K_i R(psi)^T xi`` in {B} that the old
controller applied is handed to the new one (its xi is rescaled to its own K_i) for every
component the new mode set integrates; components it does not integrate start at zero, as in
:meth:`TAPMPID.set_modes`. The proportional and damping terms change with the gains at the
switch (a step of (K_p,new - K_p,old) e), which is small while the vessel is near its setpoint.

``[S]`` = seed survey-tapm-modeling-and-control.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..geometry import rot_z, ssa
from .estimate import Estimate, Setpoint
from .pid import H_PSI, H_XY, MODE_SETS, ControlError, PIDGains, TAPMPID

__all__ = ["GainScheduledPID", "ScheduledCondition", "TABLE_FORMAT"]

#: Gain-table file format this module reads.
TABLE_FORMAT = "tapm_opt.gains/1"


@dataclass(frozen=True, kw_only=True)
class ScheduledCondition:
    """One operating condition of the schedule.

    Attributes
    ----------
    sea_state : str
        Sea-state id.
    sea_class : str
        ``"calm"``, ``"normal"`` or ``"extreme"``.
    mode_set : str
        Key of :data:`~tapm_opt.control.pid.MODE_SETS` used in this condition.
    broken : str
        ``"intact"`` or the id of the broken line.
    heading : float
        Heading the gains were designed at [rad].
    weathervane : bool
        The heading is the condition's weathervane heading.
    """

    sea_state: str
    sea_class: str
    mode_set: str
    broken: str
    heading: float
    weathervane: bool = False


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


def _gain(row: Mapping[str, Any], name: str, where: str) -> np.ndarray:
    try:
        arr = np.asarray(row[name], dtype=float)
    except (KeyError, TypeError, ValueError):
        raise ControlError(f"{where}.pid.{name} is missing or not numeric") from None
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ControlError(f"{where}.pid.{name} must be 3 finite numbers, got {arr.tolist()}")
    return arr


def _table_dict(table: Any) -> dict:
    if hasattr(table, "to_dict"):
        table = table.to_dict()
    if not isinstance(table, Mapping):
        raise ControlError(f"table must be a gain table (GainTable or its JSON dict), got "
                           f"{type(table).__name__}")
    meta = table.get("meta", {})
    if not isinstance(meta, Mapping) or meta.get("format") != TABLE_FORMAT:
        raise ControlError(f"not a gain table: meta.format="
                           f"{meta.get('format') if isinstance(meta, Mapping) else None!r}, "
                           f"expected {TABLE_FORMAT!r}")
    rows = table.get("rows")
    if not isinstance(rows, Sequence) or not rows:
        raise ControlError("the gain table has no rows")
    return dict(table)


class GainScheduledPID:
    """TAPM PID with gains and mode set switched by operating condition.

    ``update(t, estimate, setpoint) -> tau`` runs the active condition's
    :class:`~tapm_opt.control.pid.TAPMPID`; :meth:`select` switches the condition.

    Parameters
    ----------
    table : GainTable or mapping
        A ``tapm_opt.design.gains.GainTable`` or its JSON dict (``GainTable.to_dict()``, the
        content of ``gains.json``).
    scenario : Scenario, optional
        If given, the table must have been made for it (same name) and its broken-line ids must
        be line ids of the scenario.
    tau_limit, integral_limit, anti_windup, env_feedforward
        Passed to every :class:`~tapm_opt.control.pid.TAPMPID`.

    Notes
    -----
    The first row of the table is active until :meth:`select` is called. A table row's heading
    is the heading its gains were designed at; :meth:`select` takes the row nearest to the
    requested heading.
    """

    def __init__(self, table: Any, *, scenario: Any = None, tau_limit: Any = None,
                 integral_limit: Any = None, anti_windup: bool = True,
                 env_feedforward: bool = False) -> None:
        data = _table_dict(table)
        self._meta = dict(data["meta"])
        conds: list[ScheduledCondition] = []
        ctrls: list[_ScheduledTAPMPID] = []
        for i, row in enumerate(data["rows"]):
            where = f"rows[{i}]"
            try:
                c = row["condition"]
                cond = ScheduledCondition(
                    sea_state=str(c["sea_state"]), sea_class=str(c["sea_class"]),
                    mode_set=str(c["mode_set"]), broken=str(c["broken"]),
                    heading=float(c["heading"]), weathervane=bool(c.get("weathervane", False)))
                pid = row["pid"]
            except (KeyError, TypeError, ValueError) as exc:
                raise ControlError(f"{where}: malformed condition ({type(exc).__name__}: "
                                   f"{exc})") from None
            if cond.mode_set not in MODE_SETS:
                raise ControlError(f"{where}.condition.mode_set={cond.mode_set!r} is not one of "
                                   f"{tuple(MODE_SETS)}")
            gains = PIDGains(Kp=_gain(pid, "Kp", where), Ki=_gain(pid, "Ki", where),
                             Kd=_gain(pid, "Kd", where))
            conds.append(cond)
            ctrls.append(_ScheduledTAPMPID(gains, modes=cond.mode_set, tau_limit=tau_limit,
                                           integral_limit=integral_limit,
                                           anti_windup=anti_windup,
                                           env_feedforward=env_feedforward))
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

    @classmethod
    def from_json(cls, path: str | Path, **kwargs: Any) -> GainScheduledPID:
        """Controller from ``gains.json`` (or a folder holding it); ``kwargs`` as for the
        constructor (e.g. ``scenario=``, ``tau_limit=``)."""
        p = Path(path)
        if p.is_dir():
            p = p / "gains.json"
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ControlError(f"no gain table at {p}") from None
        except (OSError, json.JSONDecodeError) as exc:
            raise ControlError(f"cannot read the gain table {p}: {exc}") from None
        return cls(data, **kwargs)

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

    @property
    def integral_load(self) -> np.ndarray:
        """Integral part of the last command in {B} [N, N, N m] (active controller)."""
        return self.controller.integral_load
