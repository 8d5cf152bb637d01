"""The closed loop's fast paths give what the reference paths give, to the last bit: the
reliability monitor's compiled arithmetic against its numpy expressions, the plant's Measurement
and the observers' Estimate (built from their own arrays, not copied) against the constructors."""

from __future__ import annotations

import numpy as np
import pytest

import tapm_opt
from tapm_opt.estimation import reliability as rel
from tapm_opt.interfaces import Estimate, Measurement


def _record(seed: int, n: int = 1500, m: int = 5):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.3, 1.7, n))
    t[100:105] = t[100]            # zero-length steps
    base = rng.uniform(1e5, 5e6, m)
    X = base + 0.1 * base * np.sin(np.outer(t, rng.uniform(0.01, 0.5, m))) + rng.normal(0, 1e4, (n, m))
    X[:, 0] = 3.0                  # a constant signal: residuals exactly 0
    return t, X, base * 3.0, base * 0.1


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_monitor_kernels_equal_numpy(seed, monkeypatch):
    if rel._kernels() is None:
        pytest.skip("no numba: the numpy expressions are the only path")
    t, X, r_t, s_t = _record(seed)
    kw = dict(lp_window=60.0, sigma_window=300.0)
    fast = rel.causal_reliability(t, X, r_t, s_t, **kw)
    monkeypatch.setattr(rel, "_KERNELS", None)
    ref = rel.causal_reliability(t, X, r_t, s_t, **kw)
    for f in ("x_lf", "sigma", "n", "k", "delta", "span", "ready"):
        a, b = getattr(fast, f), getattr(ref, f)
        assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True), f


@pytest.fixture(scope="module")
def plant():
    from tapm_opt.models.system import System
    from tapm_opt.plant.simulator import Plant

    system = System.from_scenario(tapm_opt.load_scenario("fpso"))
    return Plant(system, sea_state="storm", seed=3, segments=4)


def _same(a, b) -> bool:
    """The same type and value; an array also read-only, as the constructor makes it."""
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and np.array_equal(a, b) and not a.flags.writeable
    return bool(a == b)


def test_measurement_fast_equals_constructor(plant):
    for _ in range(3):
        plant.step(1.0)
        m = plant.measure(truth=True)
        ref = Measurement(**{f: getattr(m, f) for f in Measurement.__dataclass_fields__})
        for f in Measurement.__dataclass_fields__:
            if f != "truth":
                assert _same(getattr(m, f), getattr(ref, f)), f
        # the measurement's arrays are its own: the plant going on leaves them as they were
        f0, tau0 = m.thruster_f.copy(), m.tau_thr.copy()
        plant.step(1.0)
        assert np.array_equal(m.thruster_f, f0) and np.array_equal(m.tau_thr, tau0)
        th = plant.thrusters
        m2 = plant.measure()
        assert np.array_equal(m2.tau_thr, th.tau())


def test_estimate_fast_equals_constructor(plant):
    from tapm_opt.studies.closed_loop import ClosedLoopSettings, default_estimator

    est = default_estimator(plant.system, ClosedLoopSettings(), plant.sea_state)
    for _ in range(3):
        plant.step(1.0)
        m = plant.measure()
        e = est.update(m.t, m)
        ref = Estimate(**{f: getattr(e, f) for f in Estimate.__dataclass_fields__})
        for f in Estimate.__dataclass_fields__:
            if f != "reliability":
                assert _same(getattr(e, f), getattr(ref, f)), f
