"""Studies: one recipe for a closed-loop case (:func:`run_case_on`), the KPIs, and study files
run in parallel, resumable.

    from tapm_opt.studies import ClosedLoopSettings, run_case_on
    run = run_case_on(system, "lmpc", ClosedLoopSettings(duration=600.0), sea_state="storm")
"""

from __future__ import annotations

from .._lazy import lazy_exports

#: Each public name and the module that defines it (imported on first use, so importing the
#: package stays cheap and free of cycles).
_EXPORTS = {
    "run_case_on": ".recipe",
    "CaseRun": ".recipe",
    "ClosedLoopSettings": ".closed_loop",
    "run_closed_loop": ".closed_loop",
    "build_controller": ".controllers",
    "case_kpis": ".kpis",
    "KPIS": ".kpi_catalogue",
    "kpi": ".kpi_catalogue",
    "load_study": ".spec",
    "study_from_dict": ".spec",
    "expand_cases": ".spec",
    "Study": ".spec",
    "Case": ".spec",
    "run_study": ".runner",
    "StudySummary": ".runner",
    "verify_study": ".verification_study",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
