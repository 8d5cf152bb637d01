"""The EKF's compiled predict and correct (``tapm_opt.estimation.ekf_kernel``) against the
observer's numpy path, which writes the same equations (EKF3–EKF6) as numpy operations: the two
paths are independent codings of one filter and must agree to rounding, step by step and over a
closed loop; a singular innovation covariance is refused by both."""

from __future__ import annotations

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.estimation import observer as observer_module
from tapm_opt.estimation.ekf_kernel import kernels
from tapm_opt.estimation.lowpass import EstimationError
from tapm_opt.estimation.observer import EKFObserver
from tapm_opt.interfaces import Measurement
from tapm_opt.models.system import System

pytestmark = pytest.mark.skipif(kernels() is None, reason="numba not installed: the numpy path is the only one")


@pytest.fixture(scope="module")
def system():
    return System.from_scenario(load_scenario("fpso"))


def _measurements(n: int, *, heading_every: int = 1, seed: int = 0) -> list[Measurement]:
    """A vessel drifting on a slow circle with noise, through the heading's wrap at +-pi; thrust
    on; the heading sampled every ``heading_every`` steps (held between: partial corrections)."""
    rng = np.random.default_rng(seed)
    ms = []
    for k in range(n):
        t = float(k)
        pos = np.array([8.0 * np.cos(0.01 * t), 5.0 * np.sin(0.013 * t)]) + rng.normal(0, 0.4, 2)
        th = float(k - k % heading_every)
        hdg = float(np.angle(np.exp(1j * (np.pi - 0.02 + 0.001 * th + rng.normal(0, 2e-3)))))
        ms.append(Measurement(t=t, position=pos, heading=hdg, tensions=np.zeros(12), t_position=t,
                              t_heading=th, t_tensions=t,
                              tau_thr=np.array([4e5 * np.sin(0.05 * t), -2e5, 3e6 * np.cos(0.03 * t)])))
    return ms


def _run(system, ms, monkeypatch, compiled: bool):
    with monkeypatch.context() as mp:
        if not compiled:
            mp.setattr(observer_module, "ekf_kernels", lambda: None)
        obs = EKFObserver.from_scenario(system)
        states = []
        for m in ms:
            obs.update(m.t, m)
            states.append((obs.x.copy(), obs.P.copy(), obs.innovation.copy(), obs.innovation_cov.copy()))
    return states


@pytest.mark.parametrize("heading_every", [1, 3])
def test_compiled_steps_match_the_numpy_path(system, monkeypatch, heading_every):
    """Step by step over 200 s (every correction full, or every third with the heading held — the
    numpy path's partial correction in between): state, covariance, innovation and its covariance
    of the compiled filter within 1e-9 of each quantity's scale of the numpy filter's; the
    covariance stays symmetric."""
    ms = _measurements(200, heading_every=heading_every)
    a = _run(system, ms, monkeypatch, compiled=True)
    b = _run(system, ms, monkeypatch, compiled=False)
    for (xa, Pa, ia, Sa), (xb, Pb, ib, Sb) in zip(a, b):
        scale_x = np.maximum(np.abs(xb), np.sqrt(np.abs(np.diag(Pb))))
        assert np.all(np.abs(xa - xb) <= 1e-9 * scale_x + 1e-300)
        d = np.sqrt(np.abs(np.outer(np.diag(Pb), np.diag(Pb))))
        assert np.all(np.abs(Pa - Pb) <= 1e-9 * d + 1e-300)
        assert np.allclose(ia, ib, rtol=0, atol=1e-9) and np.allclose(Sa, Sb, rtol=1e-9, atol=0)
        assert np.array_equal(Pa, Pa.T)
    # the filter did something: its heading crossed the wrap and the bias moved off its start
    assert abs(a[-1][0][8]) > 3.0 and np.linalg.norm(a[-1][0][12:14] - a[1][0][12:14]) > 1e3


def test_singular_innovation_covariance_is_refused_by_both_paths(system, monkeypatch):
    """A covariance gone non-finite makes S singular: both paths raise EstimationError naming S."""
    ms = _measurements(3)
    for compiled in (True, False):
        with monkeypatch.context() as mp:
            if not compiled:
                mp.setattr(observer_module, "ekf_kernels", lambda: None)
            obs = EKFObserver.from_scenario(system)
            obs.update(ms[0].t, ms[0])
            obs.P = np.full((15, 15), np.nan)
            with pytest.raises(EstimationError, match="innovation covariance S"):
                obs.update(ms[1].t, ms[1])


def test_closed_loop_with_the_compiled_filter_is_the_numpy_filters(system, monkeypatch):
    """fpso's storm, PID, 120 s on the FEM plant: the logged estimate and the vessel's path with the
    compiled filter within 1e-6 m / 1e-8 rad of the numpy filter's (rounding, carried through the
    closed loop)."""
    from tapm_opt.design import build
    from tapm_opt.plant.simulator import Plant
    from tapm_opt.studies import ClosedLoopSettings, run_closed_loop

    out = {}
    for compiled in (True, False):
        with monkeypatch.context() as mp:
            if not compiled:
                mp.setattr(observer_module, "ekf_kernels", lambda: None)
            plant = Plant(system, sea_state="storm", seed=1, segments=4)
            res = run_closed_loop(plant, build(system, "pid", dt_control=1.0),
                                  ClosedLoopSettings(duration=120.0, heading="chasing"), system=system)
            out[compiled] = res
    for ch, tol in (("x_hat", 1e-6), ("y_hat", 1e-6), ("psi_hat", 1e-8), ("x", 1e-6), ("y", 1e-6)):
        d = np.max(np.abs(np.asarray(out[True][ch]) - np.asarray(out[False][ch])))
        assert d < tol, (ch, d)
    assert np.ptp(np.asarray(out[True]["x_hat"])) > 0.5   # the estimate moved
