"""The expected wave-frequency features of a sea state for the sea-state supervisor
(:mod:`tapm_opt.control.supervisor`), from the plant's own wave model: the hull's head-on and
abeam responses and the GNSS noise through the estimator's complement and the supervisor's wave
band. Here, in the design layer, because it runs the plant's :class:`~tapm_opt.plant.environment.Environment`;
:func:`tapm_opt.design.supervisor.sea_state_supervisor` builds the supervisor's references with it
and passes them in.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..control.supervisor import wave_band_sos
from ..estimation.lowpass import estimator_complement
from ..plant.environment import Environment

__all__ = ["wave_reference"]


def wave_reference(scenario: Any, sea_state: Any, *, dt: float, band: Any, settle: float,
                    estimator_cutoff: float | None, gnss_std: float, seed: int,
                    duration: float) -> dict:
    """The WF moments of one sea state (module docstring): m0, m2 of the head-on and abeam hull
    responses and of the GNSS noise through the estimator complement and the wave band."""
    import scipy.signal

    sos = wave_band_sos(dt, band)
    comp = estimator_complement(dt, estimator_cutoff) if estimator_cutoff is not None else None

    def chain(x: np.ndarray) -> np.ndarray:
        if comp is not None:
            x = scipy.signal.lfilter(comp[0], comp[1], x)
        return scipy.signal.sosfilt(sos, x) if len(sos) else x

    def moments(xf: np.ndarray) -> tuple[float, float]:
        return float(np.mean(xf[1:] ** 2)), float(np.mean(np.diff(xf) ** 2) / dt**2)

    n_skip = int(math.ceil(settle / dt))
    out: dict = {"wave_direction": 0.0, "m0": [0.0, 0.0], "m2": [0.0, 0.0]}
    if sea_state.Hs > 0:
        env = Environment(scenario, sea_state, seed=seed)
        d = float(env.waves.direction)
        out["wave_direction"] = d
        t = np.arange(int(round(duration / dt)) + n_skip) * dt
        e0 = np.asarray(env.eta_wf(t, d))  # beta = 0: surge response along the wave direction
        S0 = e0[:, 0] * math.cos(d) + e0[:, 1] * math.sin(d)
        p1 = d - 0.5 * math.pi
        e1 = np.asarray(env.eta_wf(t, p1))  # beta = pi/2: sway response
        S1 = -e1[:, 0] * math.sin(p1) + e1[:, 1] * math.cos(p1)
        for i, S in enumerate((S0, S1)):
            out["m0"][i], out["m2"][i] = moments(chain(S)[n_skip:])
    # white noise of std gnss_std on each axis: m0 = 2 sigma^2 sum h^2 (impulse response h)
    n_h = max(20 * n_skip, 4096)
    imp = np.zeros(n_h)
    imp[0] = 1.0
    h = chain(imp)
    out["noise_m0"] = float(2.0 * gnss_std**2 * np.sum(h**2))
    out["noise_m2"] = float(2.0 * gnss_std**2 * np.sum(np.diff(np.r_[0.0, h]) ** 2) / dt**2)
    return out
