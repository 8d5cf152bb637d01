"""Gain tables for gain scheduling: PID (pole placement) and LQR per operating condition.

The public surface of the gain design (guide: ``docs/gains.md``), gathered from its modules:

* :mod:`tapm_opt.design.loads` — the mean environmental load of a condition
  (:func:`mean_environmental_load`, :class:`MeanLoad`);
* :mod:`tapm_opt.design.tables` — conditions (sea-state classes, mooring states, headings,
  :func:`weathervane_heading`), the design of each condition and :func:`gain_table`;
* :mod:`tapm_opt.design.margins` — closed-loop poles and loop-at-a-time stability margins with
  the thrust lag and estimator low-pass (:data:`ESTIMATOR_CUTOFF`);
* :mod:`tapm_opt.control.gain_table` — the rows (:class:`GainTable`, :class:`GainRow`, ...) and
  the file format ``tapm_opt.gains/1`` (:func:`write_gain_tables`, :func:`load_gain_table`),
  which the scheduled controller reads without the design code.
"""

from __future__ import annotations

from ..control.gain_table import (
    FORMAT,
    Condition,
    GainRow,
    GainTable,
    GainTableError,
    LQRRow,
    PIDRow,
    load_gain_table,
    write_gain_tables,
)
from .loads import MeanLoad, mean_environmental_load
from .margins import ESTIMATOR_CUTOFF
from .tables import (
    CLASS_MODE_SETS,
    DEFAULT_DAMPING,
    DEFAULT_INTEGRAL_RATIO,
    DEFAULT_LQR,
    DEFAULT_PERIODS,
    SEA_CLASSES,
    LQRWeights,
    gain_table,
    sea_state_class,
    weathervane_heading,
)

__all__ = [
    "FORMAT",
    "GainTableError",
    "SEA_CLASSES",
    "CLASS_MODE_SETS",
    "DEFAULT_PERIODS",
    "DEFAULT_DAMPING",
    "DEFAULT_INTEGRAL_RATIO",
    "DEFAULT_LQR",
    "ESTIMATOR_CUTOFF",
    "LQRWeights",
    "MeanLoad",
    "Condition",
    "PIDRow",
    "LQRRow",
    "GainRow",
    "GainTable",
    "mean_environmental_load",
    "weathervane_heading",
    "sea_state_class",
    "gain_table",
    "write_gain_tables",
    "load_gain_table",
]
