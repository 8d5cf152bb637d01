"""The tension-residual CUSUM line-break detector: its statistics on synthetic residuals, its
settings and measurements checks, its tabulated line model, and detection, isolation and false
alarms in closed loop on the fpso FEM plant in the design storm."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.config.schema import Fault
from tapm_opt.estimation.detection import (FALSE_ALARM_TIME_DEFAULT, DetectionError, TensionDropDetector,
                                           TensionResidualDetector, _TensionTable)
from tapm_opt.estimation.lowpass import LowPassEstimator
from tapm_opt.interfaces import Measurement
from tapm_opt.models.system import System
from tapm_opt.plant.simulator import Plant
from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
from tapm_opt.studies.controllers import build_controller
from tapm_opt.studies.kpis import break_times

FPSO = load_scenario("fpso")
ETA = np.array([12.0, -7.0, 0.05])   # a pose off the field zero point


@pytest.fixture(scope="module")
def model():
    return System.from_scenario(FPSO).lines


@pytest.fixture(scope="module")
def T_eta(model):
    return np.asarray(model.tensions(ETA), float)


def _feed(det, T_rows, eta=ETA, t0=0.0, dt=1.0):
    """Feed rows of tensions at t0, t0 + dt, ...; returns the time of the first detection (or None)."""
    first = None
    for k, T in enumerate(T_rows):
        if det.update(t0 + k * dt, T, eta) and first is None:
            first = t0 + k * dt
    return first


# -- synthetic residuals -------------------------------------------------------------------------

def test_threshold_follows_the_false_alarm_design(model):
    det = TensionResidualDetector(model)
    assert det.threshold == pytest.approx(math.log(12 * FALSE_ALARM_TIME_DEFAULT * 1.0))
    assert det.threshold == pytest.approx(19.75, abs=0.01)
    slow = TensionResidualDetector(model, false_alarm_time=3600.0, rate=2.0)
    assert slow.threshold == pytest.approx(math.log(12 * 3600.0 * 2.0))


def test_no_alarm_on_zero_mean_noise_and_the_running_estimates_converge(model, T_eta):
    """Cell noise of 35 kN (fpso's 0.2 % of MBS) plus a 40 kN bias, 20 000 samples: no alarm, the
    statistic never leaves zero, and the robust running estimates find the bias and the standard
    deviation."""
    det = TensionResidualDetector(model)
    rng = np.random.default_rng(0)
    sd = 35e3
    rows = T_eta + 40e3 + sd * rng.standard_normal((20000, 12))
    assert _feed(det, rows) is None
    assert det.events == [] and det.samples == 20000
    assert np.max(det.peak) == 0.0
    assert np.nanmax(det.worst_drop) < 0.2            # deepest noise dip: < 20 % of the design shift
    np.testing.assert_allclose(det.bias, 40e3, atol=6e3)
    np.testing.assert_allclose(det.sigma, sd, rtol=0.08)


@pytest.fixture(scope="module")
def statistical(model):
    """Settings where the CUSUM works in its statistical range: cell noise 3 % of MBS (510 kN) and
    a fixed scale (adapt=False), so that the design shift is about 3 standard deviations; a
    3-sample confirmation, whose cap h / 3 per sample the mean step stays below (with the default
    16 samples the cap clips most steps and the delay is no longer Wald's)."""
    det = TensionResidualDetector(model, noise_rel=0.03, dynamic_rel=0.05, adapt=False, min_samples=3)
    return det, det.sigma_design


def test_no_false_alarm_in_the_statistical_range(statistical, T_eta):
    """20 000 samples x 12 lines of Gaussian residuals at the design scale: the CUSUM's mean time
    between false alarms is at least e^h = 3.8e8 samples per line, so an alarm here would have a
    probability below 1e-3."""
    det, sd = statistical
    det.reset()
    d = det.shift * T_eta / sd
    assert np.all((2.5 < d) & (d < 3.5))
    rows = T_eta + sd * np.random.default_rng(1).standard_normal((20000, 12))
    assert _feed(det, rows) is None
    # P(g_k > x) <= e^-x at any sample (Lorden), so over 2.4e5 line-samples the largest statistic
    # is about ln(2.4e5) = 12.4 and exceeds h - 4 = 15.75 with probability below 4 %
    assert 5.0 < np.max(det.peak) < det.threshold - 4.0


def test_a_step_is_detected_within_the_cusums_expected_delay_and_isolated(statistical, T_eta):
    """A loss of 35 % of line 3's tension (above the reference of half the design shift), from a
    zero start: the mean delay over 200 runs is the Wald approximation h / E[l] within 15 % (the
    overshoot over h adds to it, the reflection at zero takes from it; 200 runs give the mean to
    about +-0.4 samples; measured 12.1 against 11.6), and every run isolates line 3."""
    det, sds = statistical
    i = 2
    sd = sds[i]
    D = 0.35 * T_eta[i]
    d = det.shift * T_eta[i] / sd
    El = d * (D / sd - d / 2)                          # mean log-likelihood-ratio step after the change
    assert El < det.threshold / det.min_samples       # not clipped: the statistical regime
    wald = det.threshold / El
    delays = []
    rng = np.random.default_rng(2)
    for _ in range(200):
        det.reset()
        rows = T_eta + sds * rng.standard_normal((100, 12))
        rows[:, i] -= D
        k = next(k for k, T in enumerate(rows) if det.update(float(k), T, ETA))
        assert det.broken == frozenset({"3"})
        delays.append(k + 1.0)                         # samples from the change to the alarm
    assert abs(np.mean(delays) - wald) <= 0.15 * wald
    assert np.min(delays) >= det.min_samples


def test_a_break_is_confirmed_by_min_samples_then_latched_and_the_model_reduced(model, T_eta):
    det = TensionResidualDetector(model)
    rng = np.random.default_rng(3)
    rows = T_eta + 35e3 * rng.standard_normal((400, 12))
    rows[300:, 6] = 35e3 * rng.standard_normal(100)    # line 7 breaks at its fairlead at t = 300 s
    s_before = None
    for k, T in enumerate(rows):
        if k == 300:
            s_before = det.sigma[6], det.bias[6]
        det.update(float(k), T, ETA)
        if k < 315:
            assert det.broken == frozenset(), k
    assert det.min_samples == 16                         # BREAK_CONFIRMATION_TIME 16 s at 1 Hz
    assert det.broken == frozenset({"7"})
    (ev,) = det.events
    assert ev["t"] == 315.0 and ev["line"] == "7" and ev["event"] == "line break detected"
    assert ev["statistic"] >= det.threshold * (1 - 1e-12)     # sixteen capped steps of h / 16
    assert (det.sigma[6], det.bias[6]) == s_before      # frozen while the alarm was building
    # latched: intact readings again change nothing; the other lines are predicted without line 7
    assert _feed(det, [T_eta] * 5, t0=500.0) == 500.0 and len(det.events) == 1
    assert det.active_model.line_ids == tuple(lid for lid in model.line_ids if lid != "7")
    np.testing.assert_allclose(det.predicted(ETA), model.without(["7"]).tensions(ETA), rtol=1e-6)
    det.reset()
    assert det.broken == frozenset() and det.events == [] and det.samples == 0
    assert det.active_model is model and np.all(det.statistic == 0)
    np.testing.assert_array_equal(det.sigma, det.sigma_design)


def test_isolation_picks_the_largest_normalised_shift(model, T_eta):
    """Lines 2 (to zero) and 5 (to 40 % of its tension) cross at the same sample: line 2 is
    isolated there, line 5 at the next sample."""
    det = TensionResidualDetector(model)
    rows = np.tile(T_eta, (20, 1))
    rows[:, 1] = 0.0
    rows[:, 4] *= 0.4
    _feed(det, rows)
    assert [(e["t"], e["line"]) for e in det.events] == [(15.0, "2"), (16.0, "5")]


def test_a_break_below_the_fairlead_is_found_where_the_drop_detector_sees_nothing(model, T_eta):
    """A line broken at its anchor hangs from the fairlead: its cell reads the weight of the
    water-depth length, w x 982 m = 1.3 MN, 40 % of the pretension, above the drop detector's 20 %."""
    hang = float(model.w[0] * model.ZF[0])
    assert 0.35 < hang / T_eta[0] < 0.45
    rows = np.tile(T_eta, (30, 1))
    rows[:, 0] = hang
    res, drop = TensionResidualDetector(model), TensionDropDetector(model)
    assert _feed(res, rows) == 15.0 and res.broken == frozenset({"1"})
    assert _feed(drop, rows) is None


def test_no_test_before_the_first_pose(model, T_eta):
    det = TensionResidualDetector(model)
    rows = np.tile(T_eta, (30, 1))
    rows[:, 3] = 0.0
    for k in range(10):
        assert det.update(float(k), rows[k], None) == frozenset()
    assert det.samples == 0
    assert _feed(det, rows[10:], t0=10.0) == 25.0


def test_a_held_sample_is_counted_once(model, T_eta):
    """Control steps of 0.25 s with 1 Hz tension cells: sixteen samples take 15 s, not 3.75 s."""
    det = TensionResidualDetector(model)
    rows = np.tile(T_eta, (64, 1))
    rows[:, 8] = 0.0
    assert _feed(det, rows, dt=0.25) == 15.0 and det.samples == 16


def test_estimator_with_the_residual_detector(model, T_eta):
    """The low-pass estimator feeds the detector its previous LF pose (None at the first update)
    and leaves the detected line out of its load balance."""
    est = LowPassEstimator(model, detector=TensionResidualDetector(model))
    T = T_eta.copy()
    T[4] = 0.0

    def m(t):
        return Measurement(t=t, position=ETA[:2], heading=float(ETA[2]), tensions=T, t_position=t, t_heading=t,
                           t_tensions=t, tau_thr=np.zeros(3))

    seen = [est.update(float(t), m(float(t))).broken_lines for t in range(18)]
    assert seen == [frozenset()] * 16 + [frozenset({"5"})] * 2     # no pose at t = 0; samples 1 to 16
    assert "5" not in est.model.line_ids
    assert est.log()[0]["t"] == 16.0 and est.log()[0]["line"] == "5"


# -- the tabulated line model ------------------------------------------------------------------

def test_tabulated_tensions_match_the_catenary(model):
    table = _TensionTable(model)
    rng = np.random.default_rng(4)
    T0 = np.asarray(model.tensions(np.zeros(3)))
    worst = 0.0
    for _ in range(300):
        r, a = 100.0 * math.sqrt(rng.random()), rng.uniform(-math.pi, math.pi)
        eta = np.array([r * math.cos(a), r * math.sin(a), rng.uniform(-math.pi, math.pi)])
        ex = np.asarray(model.tensions(eta))
        worst = max(worst, float(np.max(np.abs(table(eta) - ex) / np.maximum(ex, T0))))
    assert worst < 1e-6 and table.exact_calls == 0
    # beyond the tables: the exact model answers
    near = _TensionTable(model, max_offset=0.0)
    eta = np.array([250.0, 0.0, 0.0])
    np.testing.assert_array_equal(near(eta), model.tensions(eta))
    assert near.exact_calls == 1


def test_tension_tables_are_built_once_per_process(model, monkeypatch):
    """A second detector on an equal model (another run of a study) reads the tables the first
    built: no table is built again (a composite model still solves its lines once at rest for the
    pretension that scales the tables' accuracy), the nodes are the same read-only arrays, the
    tensions equal."""
    from tapm_opt.estimation import detection

    first = _TensionTable(model, max_offset=37.0)
    calls = []
    orig = _TensionTable._table
    monkeypatch.setattr(_TensionTable, "_table", staticmethod(lambda *a, **kw: calls.append(a[1:3]) or orig(*a, **kw)))
    again = _TensionTable(model, max_offset=37.0)
    assert calls == []
    np.testing.assert_array_equal(again._tab, first._tab)
    assert all(not a.flags.writeable for tab in detection._PROCESS_TABLES.values() for a in tab[2:])
    eta = np.array([12.0, -7.0, 0.2])
    np.testing.assert_array_equal(again(eta), first(eta))
    other = _TensionTable(model, max_offset=38.0)          # another range: its own tables
    assert len(calls) > 0 and other._tab.shape[0] > 0


# -- settings and measurements -----------------------------------------------------------------

@pytest.mark.parametrize("kw, field", [
    ({"shift": 0.0}, "shift"), ({"shift": 1.5}, "shift"), ({"shift": float("nan")}, "shift"),
    ({"false_alarm_time": -1.0}, "false_alarm_time"), ({"false_alarm_time": 0.01}, "false_alarm_time"),
    ({"rate": 0.0}, "rate"), ({"rate": float("inf")}, "rate"),
    ({"min_samples": 0}, "min_samples"), ({"min_samples": 2.5}, "min_samples"), ({"min_samples": True}, "min_samples"),
    ({"noise_rel": 0.0}, "noise_rel"), ({"dynamic_rel": -0.1}, "dynamic_rel"), ({"adapt": "yes"}, "adapt"),
    ({"tau": 0.0}, "tau"), ({"clip": -3.0}, "clip"), ({"shift": "0.5"}, "shift"),
])
def test_bad_settings_name_the_field(model, kw, field):
    with pytest.raises(DetectionError, match=rf"^{field} = "):
        TensionResidualDetector(model, **kw)


def test_bad_measurements_name_the_field(model, T_eta):
    det = TensionResidualDetector(model)
    with pytest.raises(DetectionError, match=r"tensions has shape \(3,\), expected \(12,\)"):
        det.update(0.0, np.zeros(3), ETA)
    bad = T_eta.copy()
    bad[2] = np.nan
    with pytest.raises(DetectionError, match=r"tensions\[2\] \(line '3'\) = nan N must be finite"):
        det.update(0.0, bad, ETA)
    with pytest.raises(DetectionError, match=r"tensions\[2\]"):
        det.update(0.0, bad, None)          # checked also before the first pose
    with pytest.raises(DetectionError, match=r"eta = \[1.0, nan, 0.0\] must be 3 finite"):
        det.update(0.0, T_eta, [1.0, np.nan, 0.0])
    with pytest.raises(DetectionError, match=r"eta = \[1.0, 2.0\] must be 3 finite"):
        det.update(0.0, T_eta, [1.0, 2.0])
    with pytest.raises(DetectionError, match=r"t = nan s must be a finite number"):
        det.update(float("nan"), T_eta, ETA)
    det.update(5.0, T_eta, ETA)
    with pytest.raises(DetectionError, match=r"t = 4.0 s is before the previous update 5.0 s"):
        det.update(4.0, T_eta, ETA)


# -- closed loop on the FEM plant: fpso design storm, PID, low-pass estimator -------------------

class _Alongside:
    """The residual detector as the estimator's, the drop detector fed the same measurements."""

    def __init__(self, primary, other):
        self.primary, self.other = primary, other

    events = property(lambda self: self.primary.events)

    def reset(self):
        self.primary.reset()
        self.other.reset()

    def update(self, t, tensions, eta=None):
        self.other.update(t, tensions, eta)
        return self.primary.update(t, tensions, eta)


def _storm(detector, duration, faults=(), seed=3):
    system = System.from_scenario(FPSO)
    plant = Plant(FPSO, sea_state="storm", seed=seed, faults=list(faults))
    return run_closed_loop(plant, build_controller(FPSO, {"type": "pid"}), ClosedLoopSettings(duration=duration),
                           system=system, estimator=LowPassEstimator(system.lines, detector=detector))


@pytest.fixture(scope="module")
def intact_storm(model):
    res, drop = TensionResidualDetector(model), TensionDropDetector(model)
    r = _storm(_Alongside(res, drop), 1800.0)
    return r, res, drop


@pytest.mark.slow
def test_intact_storm_half_hour_has_no_false_alarm(intact_storm):
    """Measured (seed 3, the hull's heave, roll and pitch at the fairleads): the deepest intact
    residuals, of the lee bundles' lines 5-12, reach 47-59 % of the design shift in their wave
    dips (14 % on line 10 with surge, sway and yaw only), so the statistic leaves zero there, to
    2.7 (h = 19.75); the weather bundle's lines 1-4 stay at 17-18 %."""
    r, res, drop = intact_storm
    assert break_times(r) == {}
    assert res.events == [] and drop.events == [] and r.meta["estimator_log"] == []
    assert res.samples >= 1790
    assert np.max(res.peak) < 0.25 * res.threshold
    assert np.nanmax(res.worst_drop) < 0.8
    assert np.nanmax(res.worst_drop[:4]) < 0.3


@pytest.fixture(scope="module")
def loaded_lines(intact_storm):
    r = intact_storm[0]
    mean = r.group("T_fairlead").mean(axis=0)
    ids = r.group_names("T_fairlead")
    return {"most": ids[int(np.argmax(mean))], "least": ids[int(np.argmin(mean))]}


@pytest.fixture(scope="module")
def break_runs(model, loaded_lines):
    out = {}
    for which, line in loaded_lines.items():
        for kind in ("residual", "drop"):
            det = TensionResidualDetector(model) if kind == "residual" else TensionDropDetector(model)
            r = _storm(det, 700.0, [Fault(kind="line_break", line=line, time=600.0)])
            out[which, kind] = (line, r)
    return out


@pytest.mark.slow
def test_the_most_and_least_loaded_lines_are_bundle_1_and_3(loaded_lines):
    assert loaded_lines == {"most": "4", "least": "9"}


@pytest.mark.slow
@pytest.mark.parametrize("which", ["most", "least"])
def test_storm_break_is_detected_and_isolated_by_both_detectors(break_runs, which):
    """Measured: the residual test declares the break 16 s after it (its sixteen confirming tension
    samples, ``BREAK_CONFIRMATION_TIME``), the drop detector 6 s after it (its 5 s hold), both
    isolate the line, no other line is declared."""
    delays = {}
    for kind in ("residual", "drop"):
        line, r = break_runs[which, kind]
        assert break_times(r) == {line: 600.0}
        log = r.meta["estimator_log"]
        assert [e["line"] for e in log] == [line], (kind, log)
        delays[kind] = log[0]["t"] - 600.0
    assert delays["residual"] == 16.0
    assert 0 < delays["drop"] <= 30.0
    assert break_runs[which, "residual"][1].meta["estimator_log"][0]["statistic"] >= 19.75
