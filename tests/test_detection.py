"""The tension-drop line-break detector and the estimator's switch to the reduced line model."""

from __future__ import annotations

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.estimation.detection import DetectionError, TensionDropDetector
from tapm_opt.estimation.lowpass import LowPassEstimator
from tapm_opt.interfaces import Measurement
from tapm_opt.models.mooring import MooringModel


@pytest.fixture(scope="module")
def model():
    return MooringModel.from_scenario(load_scenario("fpso"))


def test_a_line_is_declared_broken_after_the_hold_and_stays_so(model):
    det = TensionDropDetector(model, fraction=0.2, hold=5.0)
    T = np.asarray(model.tensions(np.zeros(3)))
    for t in np.arange(0.0, 10.0, 1.0):
        assert det.update(t, T) == frozenset()
    low = T.copy()
    low[1] = 0.1 * T[1]
    seen = [det.update(t, low) for t in np.arange(10.0, 20.0, 1.0)]
    assert seen[4] == frozenset() and seen[5] == frozenset({"2"})     # at 15 s = 10 s + hold
    assert det.update(21.0, T) == frozenset({"2"})                    # latched
    assert det.events == [{"t": 15.0, "line": "2", "event": "line break detected"}]


def test_a_short_dip_is_no_break(model):
    det = TensionDropDetector(model, hold=5.0)
    T = np.asarray(model.tensions(np.zeros(3)))
    low = T.copy()
    low[0] = 0.0
    for t in range(4):
        det.update(float(t), low)
    det.update(4.0, T)
    for t in range(5, 9):
        assert det.update(float(t), low) == frozenset()


def test_slack_side_of_a_loaded_mooring_is_not_a_break(model):
    """At 80 m offset (the alert radius) the slack lines keep well above 20 % of pretension."""
    T0 = np.asarray(model.tensions(np.zeros(3)))
    for ang in np.radians(np.arange(0, 360, 30)):
        T = np.asarray(model.tensions(np.array([80 * np.cos(ang), 80 * np.sin(ang), 0.0])))
        assert np.all(T > 0.3 * T0)


def test_estimator_leaves_the_detected_line_out(model):
    est = LowPassEstimator(model, detector=TensionDropDetector(model, hold=0.0))
    T = np.asarray(model.tensions(np.zeros(3)))
    T[4] = 0.0

    def m(t):
        return Measurement(t=t, position=np.zeros(2), heading=0.0, tensions=T, t_position=t, t_heading=t,
                           t_tensions=t, tau_thr=np.zeros(3))

    e = est.update(0.0, m(0.0))
    assert e.broken_lines == frozenset({"5"})
    assert "5" not in est.model.line_ids and est.model.n_lines == 11
    np.testing.assert_allclose(est.mooring_load(np.zeros(3)), model.without(["5"]).force(np.zeros(3)), rtol=1e-6,
                               atol=1.0)
    est.reset()
    assert est.model is model


def test_without_drops_lines_and_refuses_to_drop_all(model):
    m = model.without(["1", "12", "99"])
    assert m.line_ids == tuple(str(i) for i in range(2, 12))
    np.testing.assert_allclose(m.tensions(np.zeros(3)), np.asarray(model.tensions(np.zeros(3)))[1:11])
    assert model.without([]) is model
    with pytest.raises(Exception, match="every line is broken"):
        model.without(model.line_ids)


def test_bad_settings_and_measurements(model):
    with pytest.raises(DetectionError, match="fraction"):
        TensionDropDetector(model, fraction=1.5)
    with pytest.raises(DetectionError, match="hold"):
        TensionDropDetector(model, hold=-1.0)
    det = TensionDropDetector(model)
    with pytest.raises(DetectionError, match="shape"):
        det.update(0.0, np.zeros(3))
    T = np.ones(12)
    T[2] = np.nan
    with pytest.raises(DetectionError, match=r"tensions\[2\] \(line '3'\)"):
        det.update(0.0, T)
