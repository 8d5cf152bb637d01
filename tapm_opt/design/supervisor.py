"""Design-time construction of the sea-state supervisor ([S] §4.5, Fig. 9, Tables 2–3).

The run-time parts — the supervisor, the switched controller, the feature estimators — are in
:mod:`tapm_opt.control.supervisor`; they take their references as arguments. Here, in the design
layer, those references are computed from the models the plant uses (the wave model and the
mean environmental load, :mod:`tapm_opt.design.wave_reference`, :mod:`tapm_opt.design.loads`)
and passed in:

:func:`sea_state_supervisor`
    a :class:`~tapm_opt.control.supervisor.SeaStateSupervisor` for a scenario's sea states, with
    their expected features from its models;
:func:`supervised_pid`
    a :class:`~tapm_opt.control.supervisor.SupervisedController` for a system: a gain-scheduled
    PID on a gain table, or a TAPMPID whose modes switch with the sea-state class.

``[S]`` = seed survey-tapm-modeling-and-control.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping, Sequence

from .._checks import finite, positive
from ..control.gain_table import GainTable, load_gain_table
from ..control.pid import ControlError, TAPMPID
from ..control.scheduled import GainScheduledPID
from ..control.supervisor import (DEFAULT_BAND, SeaStateFeatures, SeaStateReference, SeaStateSupervisor,
                                  SupervisedController, SupervisorError, class_mode_sets, spectral_features,
                                  wave_band_sos)
from ..errors import TapmError
from ..models.system import as_system
from .loads import mean_environmental_load
from .margins import ESTIMATOR_CUTOFF  # the low-pass estimator's default cut-off
from .tables import sea_state_class
from .wave_reference import wave_reference  # runs the plant's wave model

__all__ = ["sea_state_supervisor", "supervised_pid"]


class _ModelReference:
    """``expected(psi)`` of a scenario sea state from the wave and load models."""

    def __init__(self, scenario: Any, sea_state: Any, wave: dict, *, dt: float, seed: int):
        self.scenario, self.sea_state, self.wave, self.dt, self.seed = scenario, sea_state, wave, dt, seed

    def load(self, psi: float) -> float:
        tau = mean_environmental_load(self.scenario, self.sea_state, psi, seed=self.seed).total
        return float(math.hypot(tau[0], tau[1]))

    def __call__(self, psi: float) -> SeaStateFeatures:
        w = self.wave
        beta = w["wave_direction"] - psi
        c2, s2 = math.cos(beta) ** 2, math.sin(beta) ** 2
        m0 = c2 * w["m0"][0] + s2 * w["m0"][1] + w["noise_m0"]
        m2 = c2 * w["m2"][0] + s2 * w["m2"][1] + w["noise_m2"]
        A, T = spectral_features(m0, m2, self.dt)
        return SeaStateFeatures(A, T, self.load(psi))


def sea_state_supervisor(system: Any, *, sea_states: Sequence[str] | None = None,
                         classes: Mapping[str, str] | None = None, seed: int = 0,
                         estimator_cutoff: float | None | str = "default", gnss_std: float | None = None,
                         reference_duration: float = 3600.0, dt: float = 1.0,
                         band: tuple[float, float] | None = DEFAULT_BAND, **options: Any) -> SeaStateSupervisor:
    """Supervisor for a scenario's sea states, their expected features from its models
    (module docstring of :mod:`tapm_opt.control.supervisor`, "Expected features").

    Parameters
    ----------
    system : System or Scenario
    sea_states : sequence of str, optional
        Sea-state ids to choose from (default all of the scenario's).
    classes : mapping id -> class, optional
        Class of each sea state (default ``design.tables.sea_state_class``: by id, else Hs).
    seed : int
        Seed of the wave model of the expected features (the plant's seed is unknown to the
        supervisor; the statistics depend little on it).
    estimator_cutoff : float, None or "default"
        Cut-off [rad/s] of the estimator low-pass whose complement is ``eta_wf``
        (``"default"``: that of :class:`~tapm_opt.estimation.lowpass.LowPassEstimator`,
        2 pi / 40 s; None: ``eta_wf`` is an observer's estimate of the WF motion itself).
    gnss_std : float, optional
        Position noise per axis [m] in ``eta_wf`` (default the scenario's
        ``sensors.gnss_std`` with a low-pass cut-off; 0 with ``estimator_cutoff=None``, an
        observer's WF estimate, which filters the noise out).
    reference_duration : float
        Length of the model series of the WF moments [s].
    dt, band, **options
        As for :class:`~tapm_opt.control.supervisor.SeaStateSupervisor` (``window``, ``warm_up``,
        ``dwell``, ``margin``, ``scales``, ``features``, ``initial``, ``heading_step``).

    Returns
    -------
    SeaStateSupervisor

    Raises
    ------
    SupervisorError
        Not a System or Scenario, an unknown sea state or class, bad settings (the message names
        the field and the value).
    """
    try:
        scenario = as_system(system).scenario
    except (TypeError, AttributeError, TapmError) as exc:
        raise SupervisorError(f"system = {type(system).__name__}: not a System or Scenario ({exc})") from None
    if sea_states is None:
        chosen = list(scenario.sea_states)
    else:
        if isinstance(sea_states, str):
            sea_states = [sea_states]
        chosen = []
        for sid in sea_states:
            try:
                chosen.append(scenario.sea_state(str(sid)))
            except KeyError:
                raise SupervisorError(f"sea_states: {sid!r} is not a sea state of scenario {scenario.name!r} "
                                      f"({[s.id for s in scenario.sea_states]})") from None
    if not chosen:
        raise SupervisorError(f"scenario {scenario.name!r} has no sea states")
    if isinstance(estimator_cutoff, str):
        if estimator_cutoff != "default":
            raise SupervisorError(f"estimator_cutoff = {estimator_cutoff!r} must be a cut-off [rad/s], None "
                                  f"or 'default'")
        estimator_cutoff = ESTIMATOR_CUTOFF
    elif estimator_cutoff is not None:
        estimator_cutoff = positive("estimator_cutoff", estimator_cutoff, error=SupervisorError)
    if gnss_std is None:
        gnss_std = scenario.sensors.gnss_std if estimator_cutoff is not None else 0.0
    gnss = finite("gnss_std", gnss_std, lo=0.0, error=SupervisorError)
    dt = positive("dt", dt, error=SupervisorError)
    duration = positive("reference_duration", reference_duration, error=SupervisorError)
    settle = 0.0 if band is None else 2.0 * float(band[1])
    wave_band_sos(dt, band)  # checks the band before the models run
    refs = []
    for ss in chosen:
        try:
            cls_ = sea_state_class(ss, classes)
        except ControlError as exc:
            raise SupervisorError(f"classes: {exc}") from None
        wave = wave_reference(scenario, ss, dt=dt, band=band, settle=settle,
                              estimator_cutoff=estimator_cutoff, gnss_std=gnss, seed=int(seed),
                              duration=duration)
        info = {"kind": "model", "Hs_m": float(ss.Hs), "Tp_s": float(ss.Tp), "seed": int(seed),
                "estimator_cutoff_rad_s": estimator_cutoff, "gnss_std_m": gnss, **wave}
        refs.append(SeaStateReference(sea_state=ss.id, sea_class=cls_,
                                      expected=_ModelReference(scenario, ss, wave, dt=dt, seed=int(seed)),
                                      info=info))
    return SeaStateSupervisor(refs, dt=dt, band=band, **options)


def supervised_pid(system: Any, *, gain_table: Any = None, modes: Mapping[str, Any] | None = None,
                   initial_sea_state: str | None = None, pid: TAPMPID | None = None, heading: str = "auto",
                   **supervisor_options: Any) -> SupervisedController:
    """A sea-state supervised PID for ``system``: gain-scheduled (with ``gain_table``) or a
    TAPMPID whose modes switch with the sea-state class.

    Parameters
    ----------
    system : System or Scenario
    gain_table : GainTable, mapping, str or Path, optional
        The gain table (object, its JSON dict, ``gains.json`` or its folder): a
        :class:`~tapm_opt.control.scheduled.GainScheduledPID` on it (capacity box, centre of
        turret) is switched; the supervisor chooses among the table's sea states, with the
        table's classes.
    modes : mapping class -> mode set, optional
        Without a table: the mode set of each class (default ``control.pid.CLASS_MODE_SETS``).
    initial_sea_state : str, optional
        Sea state before the first decision (default the table's first row, else the scenario's
        first sea state).
    pid : TAPMPID, optional
        Without a table: the PID to switch (required; e.g. the study PID,
        ``studies.controllers.build_controller(system, "pid")``).
    heading : "auto", "setpoint" or "weathervane"
        See :class:`SupervisedController`.
    **supervisor_options
        :func:`sea_state_supervisor` options (``window``, ``dwell``, ``margin``,
        ``warm_up``, ``scales``, ``features``, ``seed``, ``dt``, ...).

    Raises
    ------
    SupervisorError
        Bad arguments (the table's own errors are :class:`~tapm_opt.control.gain_table.GainTableError`).
    """
    for key in ("sea_states", "classes", "initial"):
        if key in supervisor_options:
            raise SupervisorError(f"{key} is set by supervised_pid (use initial_sea_state=, or build the "
                                  f"SeaStateSupervisor yourself)")
    system = as_system(system)
    if gain_table is not None:
        if modes is not None:
            raise SupervisorError("modes is for the plain PID: a gain table's rows carry their own mode sets")
        if pid is not None:
            raise SupervisorError("give either gain_table or pid, not both")
        if isinstance(gain_table, (str, Path)):
            table = load_gain_table(gain_table)
        elif isinstance(gain_table, (GainTable, Mapping)):
            table = gain_table
        else:
            raise SupervisorError(f"gain_table = {gain_table!r} must be a GainTable, its dict or a path to gains.json")
        ctrl = GainScheduledPID(table, scenario=system)
        conds = ctrl.conditions
        states = list(dict.fromkeys(c.sea_state for c in conds))
        classes = {c.sea_state: c.sea_class for c in conds}
        initial = states[0] if initial_sea_state is None else initial_sea_state
        if initial not in states:
            raise SupervisorError(f"initial_sea_state = {initial!r} is not a sea state of the gain table {states}")
        sup = sea_state_supervisor(system, sea_states=states, classes=classes, initial=initial,
                                               **supervisor_options)
        return SupervisedController(ctrl, sup, heading=heading)
    if pid is not None and not isinstance(pid, TAPMPID):
        raise SupervisorError(f"pid must be a TAPMPID, got {type(pid).__name__}")
    class_mode_sets(modes)  # check before anything is built
    ids = [s.id for s in system.scenario.sea_states]
    initial = (ids[0] if ids else None) if initial_sea_state is None else initial_sea_state
    if initial not in ids:
        raise SupervisorError(f"initial_sea_state = {initial!r} is not a sea state of scenario "
                              f"{system.scenario.name!r} ({ids})")
    if pid is None:
        raise SupervisorError("pid is missing: give the TAPMPID to switch (e.g. "
                              "tapm_opt.studies.controllers.build_controller(system, 'pid')) or a gain_table")
    sup = sea_state_supervisor(system, initial=initial, **supervisor_options)
    return SupervisedController(pid, sup, modes=modes, heading=heading)
