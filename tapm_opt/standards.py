"""Numbers of the offshore standards the workbench checks against, in one place (the project's
standards notes; to be checked against the standards themselves).

Used by the KPIs' line check (:mod:`tapm_opt.studies.kpis`) and the capability envelopes
(:mod:`tapm_opt.design.capability`), which therefore share one definition of each factor.
"""

from __future__ import annotations

__all__ = ["DNV_E301_2008_FACTORS", "DNV_CAPACITY_FACTOR", "DNV_CLASS1_COMMON_FACTOR", "DNV_E301_QUASI_STATIC_FACTORS"]

#: Partial safety factors (gamma_mean, gamma_dyn) of DNV-OS-E301, October 2008 edition, dynamic
#: analysis, by limit state and consequence class. Read from secondary transcriptions
#: (the project's standards notes); to be checked against the standard itself.
DNV_E301_2008_FACTORS: dict[tuple[str, int], tuple[float, float]] = {
    ("ULS", 1): (1.10, 1.50),
    ("ULS", 2): (1.40, 2.10),
    ("ALS", 1): (1.00, 1.10),
    ("ALS", 2): (1.00, 1.25),
}
#: DNV-OS-E301 (October 2008) quasi-static safety factors on the line tension, by limit state and
#: consequence class (the project's standards notes).
DNV_E301_QUASI_STATIC_FACTORS: dict[tuple[str, int], float] = {
    ("ULS", 1): 1.70, ("ULS", 2): 2.50, ("ALS", 1): 1.10, ("ALS", 2): 1.35,
}
#: Characteristic capacity S_C = 0.95 * MBS (DNV-OS-E301 definition for chain; applied to every line).
DNV_CAPACITY_FACTOR = 0.95
#: Common factor on T_C,mean + T_C,dyn in consequence class 1 when T_C,mean > 2/3 T_C,dyn
#: (as transcribed in STANDARDS.md; applied by default, ``dnv_class1_common_factor=False`` disables it).
DNV_CLASS1_COMMON_FACTOR = 1.3
