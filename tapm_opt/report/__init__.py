"""Study reports: HTML (self-contained) and Markdown from a study directory's saved results.

    from tapm_opt.report import write_report
    html_path, md_path = write_report("out/study1")

See ``docs/report.md``. This is the only part of tapm_opt that imports matplotlib.
"""

from .data import ReportError, read_study
from .report import BEST_MARK, kpi_direction, side_by_side_tables, write_report

__all__ = ["write_report", "ReportError", "read_study", "kpi_direction", "side_by_side_tables", "BEST_MARK"]
