"""Study files: many closed-loop cases from one TOML file, run in parallel, resumable.

A study compares controllers across sea states, mooring conditions (intact, a line broken at some
time, a thruster failed, a buoy lost from a composite line) and seeds. Every case is one :func:`run_case` — scenario with the
condition's faults, FEM plant, controller, :func:`~tapm_opt.studies.closed_loop.run_closed_loop`,
KPIs — and :func:`run_study` writes each to its own folder (layout: :mod:`tapm_opt.studies.store`).

Study file
----------
::

    [study]
    name = "mpc_vs_pid"              # required
    description = "..."              # optional
    scenario = "fpso"                # required: built-in name, or a path relative to this file
    duration = 3600.0                # required: simulated time of each case [s], > 0
    segments = 10                    # optional: FEM segments per line (default: each line's own)
    break_on_overload = "sampled"    # optional: "mbs", "sampled" or "never" (default: the scenario's
                                     # [plant] setting; lines break at their strength, docs/plant.md)
    dt_control = 1.0                 # control / allocation / plant period [s] (default 1)
    dt_log = 1.0                     # logging period [s], a multiple of dt_control (default 1)
    heading = "chasing"              # "chasing" (bow into the weather, default) or "fixed"
    setpoint = "fixed"               # "fixed" (default) or "chasing" (survey eq. 38)
    true_state = false               # hand the controller the true state (default false)
    seeds = [1]                      # seeds of waves, wind and sensor noise (default [1])
    mode = "product"                 # "product" (default): every sea state x controller x condition
                                     # x seed, plus the [[cases]] below; "list": only the [[cases]]

    [[sea_states]]                   # optional; default: the scenario's first sea state
    id = "storm"                     # a sea state of the scenario ...
    [[sea_states]]
    id = "storm_12m"                 # ... or a new one: every SeaState field of the scenario schema
    Hs = 12.0                        # (Hs, Tp, gamma, wave_direction_deg, wind_speed, ...), checked
    Tp = 14.0                        # as in a scenario file

    [[controllers]]                  # at least one
    name = "PID"                     # display name, unique (default: PID, MPC for lmpc, NMPC for mpc)
    type = "pid"                     # "pid", "mpc" (nonlinear MPC) or "lmpc" (linear MPC)
    periods = [250.0, 250.0, 150.0]  # any option of tapm_opt.studies.controllers.build_controller

    [[conditions]]                   # optional; default: one condition "intact"
    name = "line 1 broken at 1800 s" # display name (default: made from the faults, or "intact")
    line_break = { line = "1", time = 1800.0 }              # a table or a list of tables
    thruster_failure = { thruster = "A3", time_fraction = 0.25 }
    buoy_loss = { line = "3", joint = 0, time = 1200.0 }    # a composite line's buoy comes off: its
                                     # joint from the anchor up (or point = "<point type id>")
                                     # time [s] or time_fraction (of the case's duration), one of them

    [[cases]]                        # optional: extra (mode "product") or the only (mode "list") cases
    controller = "PID"               # controller name (default: the only controller)
    sea_state = "storm"              # sea-state id (default: the first of [[sea_states]])
    condition = "intact"             # condition name (default: the first condition)
    seed = 7                         # default: the first of study.seeds
    duration = 600.0                 # optional: overrides study.duration for this case
    name = "..."                     # optional: display name of the case

    [verification]                   # optional: DNV-OS-E301 limit-state checks after the run
    consequence_class = 1            # required: 1 or 2 (standard = "DNV-OS-E301", mpm_method,
                                     # t_start, design_fatigue_factor, design_life, probabilities,
                                     # [verification.line_types.<id>]: docs/verification.md)

Everything is checked when the file is loaded — unknown keys (with a suggestion), types, ranges,
the scenario (its own errors are passed on under ``study.scenario``), sea-state ids, controller
types, options and values (each controller is built once, which takes about a second for a
nonlinear MPC), line and thruster ids, fault times within the run — and :class:`StudyError` lists
every problem with its field path, e.g. ``controllers[1].type = 'lqr' is not one of pid, mpc,
lmpc``. Nothing is written for an invalid study.

Cases
-----
A :class:`Case` holds ``id``, ``name``, ``labels`` (``scenario``, ``sea_state``, ``controller``,
``condition``, ``seed``) and ``inputs``: everything needed to run it, with no reference to the study
file — the full scenario dictionary (:func:`~tapm_opt.config.scenario_to_dict`) with the
condition's faults added and *only the case's sea state* among its sea states (so adding a sea state
to a study does not change the ids of the other cases), the sea-state id, the controller
specification (without the display name), the seed, the duration, the FEM segments and the
closed-loop settings. The id is the hash of the inputs (:func:`~tapm_opt.studies.store.case_id`),
so two cases with the same inputs are the same case: a study that defines one twice under different
names is an error.

Running
-------
:func:`run_study` takes the study directory for itself (a second run into it, from any process,
is refused with :class:`StudyBusyError` naming the directory and the running one's pid), then
runs the cases that are not finished yet on local processes or a Dask cluster. Local workers
write each case's files themselves, atomically, so a run killed at any point (even ``kill -9``)
loses no finished case, and running the same study into the same folder again resumes it; they
end with the process that started them, however it ends. Dask workers write nothing: they send
each case back and the client stores it, so they need no shared file system. A case that raises
gets ``error.json``, the others go on, and the summary counts it as failed.

Modules
-------
This module gathers the public names. The code is in :mod:`~tapm_opt.studies.spec` (study files,
validation, cases), :mod:`~tapm_opt.studies.jobs` (one case: :func:`run_case`, storing its files),
:mod:`~tapm_opt.studies.executors` (local processes, Dask) and :mod:`~tapm_opt.studies.runner`
(:func:`run_study`, KPI tables); the directory layout is in :mod:`~tapm_opt.studies.store`.
"""

from __future__ import annotations

from .jobs import run_case
from .kpis import case_kpis as compute_kpis  # a case's KPIs (the name studies used before the recipe)
from .runner import StudySummary, run_study, write_tables
from .spec import Case, Study, expand_cases, load_study, study_from_dict
from .store import StudyBusyError, StudyError, StudyIssue, StudyRunError

__all__ = [
    "Case",
    "Study",
    "StudySummary",
    "StudyError",
    "StudyIssue",
    "StudyRunError",
    "StudyBusyError",
    "load_study",
    "study_from_dict",
    "expand_cases",
    "run_case",
    "run_study",
    "write_tables",
    "compute_kpis",
]
