"""State and response estimation from measurements.

* :mod:`tapm_opt.estimation.lowpass` -- low-pass state and environmental-load estimate
  (``LowPassEstimator``, ``TrueStateEstimator``).
* :mod:`tapm_opt.estimation.observer` -- DP observers on the anchor-SLAM seed's eq. (1): the
  nonlinear passive observer and an EKF (``PassiveObserver``, ``EKFObserver``).
* :mod:`tapm_opt.estimation.detection` -- line-break detection with tension cells
  (``TensionResidualDetector``, ``TensionDropDetector``).
* :mod:`tapm_opt.estimation.bank` -- a bank of observers that detects and isolates a line break
  from the position/heading innovations (``ObserverBank``), without tension cells.
* :mod:`tapm_opt.estimation.current_profile` -- the current profile (surface speed, direction,
  seabed factor) estimated on line from the tension cells and the riser inclinometers
  (``CurrentProfileEstimator``, ``CurrentResponseModel``, ``CurrentEstimating``).
* :mod:`tapm_opt.estimation.reliability` -- the causal (on-line) structural reliability index of
  line tensions and riser angles (survey eq. 32; reliability seed §2.2), re-exported here.
"""

from .reliability import (LP_WINDOW_DEFAULT as LP_WINDOW_DEFAULT, SIGMA_WINDOW_DEFAULT as SIGMA_WINDOW_DEFAULT,
                          ReliabilityError as ReliabilityError, ReliabilityMonitor as ReliabilityMonitor,
                          ReliabilityRecord as ReliabilityRecord, ReliabilityState as ReliabilityState,
                          causal_reliability as causal_reliability, gumbel_k as gumbel_k)

#: The estimator of the closed loop, study files, ``tapm simulate`` and the controllers' build
#: context unless one is chosen: the EKF, which left the least wave-frequency motion in its LF
#: estimate (docs/estimation.md).
DEFAULT_ESTIMATOR = "ekf"

__all__ = ["DEFAULT_ESTIMATOR", "ReliabilityMonitor", "ReliabilityState", "ReliabilityRecord", "ReliabilityError", "causal_reliability",
           "gumbel_k", "LP_WINDOW_DEFAULT", "SIGMA_WINDOW_DEFAULT"]
