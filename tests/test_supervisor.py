"""Tests of the sea-state supervisor and the controllers it switches
(tapm_opt.control.supervisor, survey §4.5, Fig. 9, Tables 2–3): the feature estimators on
synthetic signals, the expected features against the plant's own wave and load models,
classification on closed-loop fpso runs (calm, normal, storm, and a sea state halfway between
normal and storm), mode switching of a TAPMPID, row selection of a GainScheduledPID, a developing
sea state (replayed), and bad input."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys

import numpy as np
import pytest
import scipy.signal

import tapm_opt
from tapm_opt.control.pid import MODE_SETS, ControlError
from tapm_opt.control.scheduled import GainScheduledPID
from tapm_opt.control.supervisor import (DEFAULT_BAND, SeaStateFeatures, SeaStateReference, SeaStateSupervisor,
                                         SupervisedController, SupervisorError, WaveMotionStatistics,
                                         spectral_features, wave_band_sos)
from tapm_opt.design.supervisor import sea_state_supervisor, supervised_pid
from tapm_opt.estimation.lowpass import estimator_complement
from tapm_opt.interfaces import Controller, Estimate, FaultAware, Logged, Setpoint
from tapm_opt.models.system import System
from tapm_opt.studies.controllers import build_controller

DURATION = 1200.0  # [s] per closed-loop run: first decision at 680 s, then 520 s of hysteresis


# --- fixtures -------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


@pytest.fixture(scope="module")
def system(fpso):
    return System.from_scenario(fpso)


@pytest.fixture(scope="module")
def base(system):
    """The fpso supervisor (its references are shared by the runs' supervisors)."""
    return sea_state_supervisor(system)


def _halfway(fpso):
    """A sea state halfway between normal and storm in every parameter (Hs 8.5 m, Tp 11.5 s,
    wind 16 m/s, current 0.9 m/s, directions halfway)."""
    a, b = fpso.sea_state("normal"), fpso.sea_state("storm")
    mid = {n: 0.5 * (getattr(a, n) + getattr(b, n))
           for n in ("Hs", "Tp", "wind_speed", "wind_direction", "current_speed", "current_direction")}
    return dataclasses.replace(a, id="between", **mid)


class _Recorder:
    """Pass-through controller that records what the runner hands the controller."""

    def __init__(self, inner):
        self.inner, self.period, self.estimates = inner, inner.period, []

    def update(self, t, estimate, setpoint):
        self.estimates.append(estimate)
        return self.inner.update(t, estimate, setpoint)

    def reset(self):
        self.inner.reset()

    def last_step(self):
        return self.inner.last_step()

    def log(self):
        return self.inner.log()

    def set_failed_thrusters(self, failed):
        self.inner.set_failed_thrusters(failed)


def _run(system, base, sea_state, estimator="lowpass"):
    from tapm_opt.plant.simulator import Plant
    from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller

    sup = SeaStateSupervisor(base.references, initial="normal")
    ctrl = SupervisedController(build_controller(system, "pid"), sup)
    rec = _Recorder(ctrl)
    plant = Plant(system, sea_state=sea_state, seed=1)
    res = run_closed_loop(plant, rec, ClosedLoopSettings(duration=DURATION, estimator=estimator), estimator=None)
    return ctrl, res, rec.estimates


@pytest.fixture(scope="module")
def runs(fpso, system, base):
    return {sid: _run(system, base, fpso.sea_state(sid)) for sid in ("calm", "normal", "storm")}


@pytest.fixture(scope="module")
def between_run(fpso, system, base):
    return _run(system, base, _halfway(fpso))


# --- feature estimators on synthetic signals --------------------------------------------------

@pytest.mark.parametrize("period, dt", [(8.0, 1.0), (13.0, 1.0), (5.0, 0.5), (20.0, 2.0)])
def test_sinusoid_gives_its_period_and_sqrt2_amplitude(period, dt):
    """Unfiltered: A_s = sqrt(2) a and T_z = T exactly (the finite-difference rate inverted for a
    sinusoid); a circular motion of radius a gives A_s = 2 a."""
    a, w = 0.7, 2 * math.pi / period
    for y_of in (lambda t: 0.0, lambda t: a * math.cos(w * t)):
        st = WaveMotionStatistics(dt=dt, window=50 * period, band=None)
        for k in range(int(200 * period / dt)):
            t = k * dt
            st.update(t, a * math.sin(w * t), y_of(t))
        r = 2.0 if y_of(0.0) else math.sqrt(2.0)
        assert st.amplitude == pytest.approx(r * a, rel=2e-3)
        assert st.period == pytest.approx(period, rel=1e-3)


def test_band_pass_scales_a_sinusoid_by_its_gain_and_keeps_the_period():
    dt, a = 1.0, 1.3
    sos = wave_band_sos(dt, DEFAULT_BAND)
    for period in (7.0, 12.0, 25.0):
        w = 2 * math.pi / period
        st = WaveMotionStatistics(dt=dt, window=600.0)
        for k in range(2000):
            st.update(k * dt, a * math.sin(w * k * dt), 0.0)
        _, h = scipy.signal.sosfreqz(sos, worN=[w * dt])
        assert st.amplitude == pytest.approx(math.sqrt(2) * a * abs(h[0]), rel=0.01)
        assert st.period == pytest.approx(period, rel=0.005)


def test_narrow_band_process_amplitude_and_zero_crossing_period():
    """50 components in 0.9–1.1 w0 with random phases: the windowed estimates are within 10 % of
    2 sqrt(m0) and 2 pi sqrt(m0/m2) of the components."""
    rng = np.random.default_rng(3)
    w0, n = 2 * math.pi / 11.0, 50
    w = w0 * rng.uniform(0.9, 1.1, n)
    a = 0.05 * np.exp(-0.5 * ((w - w0) / (0.05 * w0)) ** 2)
    ph = rng.uniform(0, 2 * math.pi, n)
    m0, m2 = float(np.sum(a**2) / 2), float(np.sum(a**2 * w**2) / 2)
    st = WaveMotionStatistics(dt=1.0, window=3000.0, band=None)
    for k in range(4000):
        st.update(float(k), float(a @ np.sin(w * k + ph)), 0.0)
    A, T = spectral_features(m0, m2, 1e-9)
    assert st.amplitude == pytest.approx(A, rel=0.10)
    assert st.period == pytest.approx(T, rel=0.10)


def test_online_window_equals_the_offline_moments_and_forgets_old_samples():
    rng = np.random.default_rng(0)
    dt, window, n = 1.0, 300.0, 1500
    x, y = rng.standard_normal(n), rng.standard_normal(n)
    x[:700] *= 5.0  # a loud first part that must leave the window
    st = WaveMotionStatistics(dt=dt, window=window)
    for k in range(n):
        st.update(k * dt, x[k], y[k])
    xf, yf = scipy.signal.sosfilt(st.sos, x), scipy.signal.sosfilt(st.sos, y)
    keep = slice(n - int(window), n)  # samples with t > t_last - window
    m0 = np.mean(xf[keep] ** 2 + yf[keep] ** 2)
    m2 = np.mean(np.diff(xf)[keep.start - 1:] ** 2 + np.diff(yf)[keep.start - 1:] ** 2)
    assert st.samples == int(window)
    np.testing.assert_allclose(st.moments, (m0, m2), rtol=1e-9)


def test_estimator_complement_is_the_lowpass_estimators_eta_wf(system):
    """The expected features see eta_wf through exactly the LowPassEstimator's filter."""
    from tapm_opt.estimation.lowpass import LowPassEstimator

    est = LowPassEstimator(system.lines)
    rng = np.random.default_rng(1)
    x = rng.standard_normal(400)
    x[0] = 0.0
    wf = [x[k] - est.filter(float(k), np.array([x[k], 0.0]), 0.0, np.zeros(3))[0][0] for k in range(400)]
    b, a = estimator_complement(1.0, est.omega_c)
    np.testing.assert_allclose(scipy.signal.lfilter(b, a, x), wf, atol=1e-12)


def test_expected_wave_features_are_the_plants_motion_at_any_heading(fpso, system):
    """The head-on/abeam decomposition gives the moments of the plant's own eta_wf at an
    arbitrary heading, and the expected load is |tau_xy| of the mean load model."""
    from tapm_opt.design.loads import mean_environmental_load
    from tapm_opt.plant.environment import Environment

    sup = sea_state_supervisor(system, sea_states=["storm"], gnss_std=0.0, heading_step=1e-6)
    ref = sup.references[0]
    psi = 0.35
    env = Environment(fpso, "storm", seed=0)
    t = np.arange(3600 + 80) * 1.0
    b, a = estimator_complement(1.0, 2 * math.pi / 40.0)
    wf = np.asarray(env.eta_wf(t, psi))
    xf, yf = (scipy.signal.sosfilt(sup.wave.sos, scipy.signal.lfilter(b, a, wf[:, i]))[80:] for i in (0, 1))
    m0 = np.mean(xf[1:] ** 2 + yf[1:] ** 2)
    m2 = np.mean(np.diff(xf) ** 2 + np.diff(yf) ** 2)
    A, T = spectral_features(m0, m2, 1.0)
    e = ref.expected(psi)
    assert e.amplitude == pytest.approx(A, rel=0.01)
    assert e.period == pytest.approx(T, rel=0.01)
    tau = mean_environmental_load(fpso, "storm", psi).total
    assert e.load == pytest.approx(math.hypot(tau[0], tau[1]), rel=1e-12)
    assert ref.sea_class == "extreme" and ref.info["kind"] == "model"


def test_the_fpso_sea_states_are_well_apart_in_the_feature_space(base):
    """Each sea state is nearest to itself by far more than the margin (3–7 units apart at
    heading 0); calm and normal differ in load only (their WF motion is below the GNSS noise)."""
    ids = base.sea_states
    for i in ids:
        d = {j: base.distance(base.expected(i), j) for j in ids}
        assert d[i] == 0.0
        assert min(v for j, v in d.items() if j != i) > 3 * base.margin
    calm, normal = base.expected("calm"), base.expected("normal")
    assert normal.amplitude / calm.amplitude < 1.1 and normal.load / calm.load > 2.0


# --- classification in closed loop --------------------------------------------------------------

@pytest.mark.parametrize("sid", ["calm", "normal", "storm"])
def test_supervisor_finds_the_sea_state_of_the_run(runs, base, sid):
    ctrl, res, _ = runs[sid]
    sup = ctrl.supervisor
    assert sup.sea_state == sid
    assert sup.switches <= 1
    for ev in sup.events:  # the one switch is the first decision, right after the warm-up
        assert ev["reason"] == "first decision" and ev["t"] == pytest.approx(sup.warm_up, abs=1.0)
        assert set(ev) >= {"t", "event", "from", "to", "features"} and ev["event"] == "sea state"
    # measured features against the models (heading of the window)
    f, e = sup.features, base.expected(sid, sup.heading)
    assert f.amplitude == pytest.approx(e.amplitude, rel=0.15)
    assert f.period == pytest.approx(e.period, rel=0.10)
    assert f.load == pytest.approx(e.load, rel=0.15)
    assert res.meta["controller_log"] == ctrl.log()


@pytest.mark.parametrize("sid", ["calm", "storm"])
def test_supervisor_behind_the_ekf_finds_the_sea_state(fpso, system, sid):
    """Behind the EKF (the loop's default estimator) ``eta_wf`` is the observer's WF estimate,
    without the GNSS noise: the references of ``estimator_cutoff=None`` (noise term 0) match it,
    those with the noise term would expect 1.6x the storm's amplitude."""
    obs = sea_state_supervisor(system, estimator_cutoff=None)
    noisy = sea_state_supervisor(system, estimator_cutoff=None, gnss_std=fpso.sensors.gnss_std)
    ctrl, _, _ = _run(system, obs, fpso.sea_state(sid), estimator="ekf")
    sup = ctrl.supervisor
    assert sup.sea_state == sid and sup.switches <= 1
    f, e = sup.features, obs.expected(sid, sup.heading)
    assert f.load == pytest.approx(e.load, rel=0.15)
    if sid == "storm":   # the WF motion stands out of the noise from the storm up
        assert f.amplitude == pytest.approx(e.amplitude, rel=0.15)
        assert noisy.expected(sid, sup.heading).amplitude > 1.4 * f.amplitude


def test_switched_tapmpid_changes_its_mode_set(runs):
    """Initial sea state normal (mode set normal_restoring); calm -> heading only, storm ->
    all four modes ([S] Table 3, design.tables.CLASS_MODE_SETS)."""
    want = {"calm": ("calm", 1), "normal": ("normal_restoring", 0), "storm": ("extreme_restoring", 1)}
    for sid, (mode_set, n) in want.items():
        ctrl, res, _ = runs[sid]
        assert ctrl.modes == MODE_SETS[mode_set]
        assert ctrl.mode_switches == n
        sw = [e for e in res.meta["controller_log"] if e["event"] == "mode switch"]
        assert len(sw) == n
        for e in sw:
            assert e["from"] == "normal_restoring" and e["to"] == mode_set
            assert tuple(e["to_modes"]) == MODE_SETS[mode_set]


def test_a_sea_state_between_two_does_not_chatter(fpso, base, between_run):
    """Halfway between normal and storm the models put the sea state on the boundary (distances
    within the margin of each other); with hysteresis the supervisor switches at most once."""
    sup_b = sea_state_supervisor(dataclasses.replace(fpso, sea_states=(_halfway(fpso),)))
    e = sup_b.expected("between")
    d_normal, d_storm = base.distance(e, "normal"), base.distance(e, "storm")
    assert abs(d_normal - d_storm) < base.margin
    ctrl, _, _ = between_run
    assert ctrl.supervisor.sea_state in ("normal", "storm")
    assert ctrl.supervisor.switches <= 1
    assert ctrl.mode_switches <= 1


def test_hysteresis_stops_chatter_on_the_boundary():
    """A load wandering +-5 % about the boundary between two sea states (their geometric mean):
    without margin and dwell the supervisor switches every time it crosses; with the defaults
    (margin 1.0 = a 7.5 % load change at s = 0.15) it decides once and stays."""
    refs = [SeaStateReference.constant("normal", "normal", amplitude=1.0, period=8.0, load=3.13e6),
            SeaStateReference.constant("storm", "extreme", amplitude=1.0, period=8.0, load=7.57e6)]
    mid = math.sqrt(3.13e6 * 7.57e6)
    plain = SeaStateSupervisor(refs, features=("load",), window=60.0, warm_up=100.0, margin=0.0, dwell=0.0)
    hyst = SeaStateSupervisor(refs, features=("load",), window=60.0, warm_up=100.0)
    for k in range(4000):
        e = _estimate(float(k), mid * math.exp(0.05 * math.sin(2 * math.pi * k / 400.0)))
        plain.update(float(k), e)
        hyst.update(float(k), e)
    assert plain.switches >= 15
    assert hyst.switches <= 1


def test_a_developing_sea_state_is_followed_without_chatter(runs, base):
    """The plant's sea state is fixed for a run (Environment holds one sea state), so the
    recorded estimates of the calm, normal and storm runs are played back one after the other:
    the supervisor follows calm -> normal -> storm, one switch per change."""
    sup = SeaStateSupervisor(base.references, initial="calm")
    t = 0.0
    seen = []
    for sid in ("calm", "normal", "storm"):
        for est in runs[sid][2]:
            sup.update(t, dataclasses.replace(est, t=t))
            t += 1.0
        seen.append(sup.sea_state)
    assert seen == ["calm", "normal", "storm"]
    assert [(e["from"], e["to"]) for e in sup.events] == [("calm", "normal"), ("normal", "storm")]


# --- gain-scheduled form ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def table(fpso):
    from tapm_opt.design.gains import gain_table

    return gain_table(fpso, sea_states=("calm", "storm"), broken=("3",))


def _estimate(t, load, broken=()):
    return Estimate(t=t, eta=np.zeros(3), nu=np.zeros(3), tau_env=np.array([-load, 0.0, 0.0]),
                    eta_wf=np.zeros(3), broken_lines=frozenset(broken))


def test_gain_scheduled_pid_gets_the_row_of_the_sea_state_and_the_broken_line(system, table):
    ctrl = supervised_pid(system, gain_table=table, features=("load",), window=60.0, warm_up=60.0, dwell=30.0)
    assert isinstance(ctrl.controller, GainScheduledPID)
    assert ctrl.supervisor.sea_states == ("calm", "storm") and ctrl.sea_state == "calm"
    storm = ctrl.supervisor.expected("storm").load
    sp = Setpoint(eta_d=np.zeros(3))
    t = 0
    for t in range(0, 200):
        ctrl.update(float(t), _estimate(float(t), storm), sp)
    assert ctrl.controller.active.sea_state == "storm" and ctrl.controller.active.broken == "intact"
    assert ctrl.modes == MODE_SETS["extreme_restoring"]
    for t in range(200, 210):
        ctrl.update(float(t), _estimate(float(t), storm, {"3"}), sp)
    assert (ctrl.controller.active.sea_state, ctrl.controller.active.broken) == ("storm", "3")
    # an untabled line: the nearest available row (the active one) is kept and logged once
    for t in range(210, 220):
        ctrl.update(float(t), _estimate(float(t), storm, {"3", "7"}), sp)
    assert (ctrl.controller.active.sea_state, ctrl.controller.active.broken) == ("storm", "3")
    log = ctrl.log()
    missing = [e for e in log if e["event"] == "missing row"]
    assert len(missing) == 1 and missing[0]["requested"]["broken"] == ["3", "7"]
    assert missing[0]["used"]["broken"] == "3"
    sw = [e for e in log if e["event"] == "mode switch"]
    assert [(e["from"]["sea_state"], e["from"]["broken"], e["to"]["sea_state"], e["to"]["broken"]) for e in sw] == \
        [("calm", "intact", "storm", "intact"), ("storm", "intact", "storm", "3")]
    assert ctrl.mode_switches == 2
    assert [e["event"] for e in log if e["event"] == "sea state"] == ["sea state"]
    ctrl.reset()
    assert ctrl.log() == [] and ctrl.sea_state == "calm"


def test_missing_sea_state_row_falls_back_to_the_nearest(system, table):
    """A supervisor with a sea state the table lacks: the row of the table's sea state of the
    same class (storm for extreme) is used, and the fallback is logged."""
    sup = sea_state_supervisor(system, sea_states=["calm", "extreme"], features=("load",),
                                           window=60.0, warm_up=60.0, initial="calm")
    ctrl = SupervisedController(GainScheduledPID(table, scenario=system), sup)
    load = sup.expected("extreme").load
    for t in range(100):
        ctrl.update(float(t), _estimate(float(t), load), Setpoint(eta_d=np.zeros(3)))
    assert sup.sea_state == "extreme" and ctrl.controller.active.sea_state == "storm"
    assert [e["used"]["sea_state"] for e in ctrl.log() if e["event"] == "missing row"] == ["storm"]


def test_protocols_and_plain_form(system):
    ctrl = supervised_pid(system, pid=build_controller(system, "pid"))
    assert isinstance(ctrl, Controller) and isinstance(ctrl, Logged) and isinstance(ctrl, FaultAware)
    assert ctrl.modes == MODE_SETS["normal_restoring"] and ctrl.sea_state == "normal"
    assert ctrl.period is None and ctrl.last_step() is None
    calm = supervised_pid(system, pid=build_controller(system, "pid"), initial_sea_state="calm", modes={"calm": ("heading", "damping")})
    assert calm.modes == ("heading", "damping")


def test_supervisor_module_does_not_import_the_design_code():
    code = ("import sys, tapm_opt.control.supervisor; "
            "print(sorted(m for m in sys.modules if m.startswith('tapm_opt.design')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


# --- bad input --------------------------------------------------------------------------------

def _ref(sid="a", load=1e6):
    return SeaStateReference.constant(sid, "normal", amplitude=1.0, period=8.0, load=load)


@pytest.mark.parametrize("kwargs, match", [
    ({"window": -5.0}, "window = -5.0"),
    ({"window": 5.0}, "window = 5.0"),
    ({"band": (40.0, 5.0)}, r"band = \(40.0, 5.0\)"),
    ({"band": (1.0, 40.0)}, r"band\[0\] = 1 s"),
    ({"dt": float("nan")}, "dt = nan"),
    ({"dwell": -1.0}, "dwell = -1.0"),
    ({"margin": "x"}, "margin = 'x'"),
    ({"scales": {"height": 1.0}}, "unknown feature"),
    ({"scales": {"load": 0.0}}, r"scales\['load'\] = 0.0"),
    ({"features": ("amplitude", "colour")}, "features"),
    ({"initial": "storm"}, "initial = 'storm'"),
])
def test_bad_supervisor_settings_raise(kwargs, match):
    with pytest.raises(SupervisorError, match=match):
        SeaStateSupervisor([_ref()], **kwargs)


def test_bad_references_and_estimates_raise(system):
    assert issubclass(SupervisorError, ControlError)
    with pytest.raises(SupervisorError, match="empty"):
        SeaStateSupervisor([])
    with pytest.raises(SupervisorError, match="duplicate"):
        SeaStateSupervisor([_ref(), _ref()])
    with pytest.raises(SupervisorError, match=r"references\[0\]"):
        SeaStateSupervisor(["calm"])
    with pytest.raises(SupervisorError, match="amplitude = -1"):
        SeaStateReference.constant("a", "calm", amplitude=-1, period=8.0, load=1.0)
    sup = SeaStateSupervisor([_ref()])
    e = _estimate(0.0, 1e6)
    with pytest.raises(SupervisorError, match="eta_wf = None"):
        sup.update(0.0, dataclasses.replace(e, eta_wf=None))
    with pytest.raises(SupervisorError, match="estimate.tau_env"):
        sup.update(0.0, dataclasses.replace(e, tau_env=np.array([np.nan, 0.0, 0.0])))
    with pytest.raises(SupervisorError, match="estimate.eta_wf"):
        sup.update(0.0, dataclasses.replace(e, eta_wf=np.zeros(2)))
    with pytest.raises(SupervisorError, match="t = inf"):
        sup.update(math.inf, e)
    sup.update(0.0, e)
    with pytest.raises(SupervisorError, match="sample interval 2.5 s"):
        sup.update(2.5, e)
    sup.update(1.0, e)
    with pytest.raises(SupervisorError, match="t = 0.5 s is before"):
        sup.update(0.5, e)
    with pytest.raises(SupervisorError, match="sea_state = 'b'"):
        sup.expected("b")
    with pytest.raises(SupervisorError, match="sea_states: 'hurricane'"):
        sea_state_supervisor(system, sea_states=["hurricane"])
    with pytest.raises(SupervisorError, match="estimator_cutoff = 'fast'"):
        sea_state_supervisor(system, estimator_cutoff="fast")
    with pytest.raises(SupervisorError, match="gnss_std = -0.1"):
        sea_state_supervisor(system, gnss_std=-0.1)


def test_bad_controller_arguments_raise(system, table):
    sup = SeaStateSupervisor([_ref()])
    with pytest.raises(SupervisorError, match="GainScheduledPID or a TAPMPID, got str"):
        SupervisedController("pid", sup)
    with pytest.raises(SupervisorError, match="SeaStateSupervisor, got dict"):
        SupervisedController(GainScheduledPID(table), {})
    with pytest.raises(SupervisorError, match="heading = 'north'"):
        SupervisedController(GainScheduledPID(table), sup, heading="north")
    with pytest.raises(SupervisorError, match="modes is for a TAPMPID"):
        SupervisedController(GainScheduledPID(table), sup, modes={"calm": "calm"})
    with pytest.raises(SupervisorError, match="unknown class 'stormy'"):
        supervised_pid(system, pid=build_controller(system, "pid"), modes={"stormy": "calm"})
    with pytest.raises(SupervisorError, match=r"modes\['calm'\] = 'sideways'"):
        supervised_pid(system, pid=build_controller(system, "pid"), modes={"calm": "sideways"})
    with pytest.raises(SupervisorError, match="initial_sea_state = 'hurricane'"):
        supervised_pid(system, pid=build_controller(system, "pid"), initial_sea_state="hurricane")
    with pytest.raises(SupervisorError, match="initial_sea_state = 'normal' is not a sea state of the gain table"):
        supervised_pid(system, gain_table=table, initial_sea_state="normal")
    with pytest.raises(SupervisorError, match="gain_table = 3"):
        supervised_pid(system, gain_table=3)
    with pytest.raises(SupervisorError, match="modes is for the plain PID"):
        supervised_pid(system, gain_table=table, modes={"calm": "calm"})
    with pytest.raises(SupervisorError, match="sea_states is set by supervised_pid"):
        supervised_pid(system, pid=build_controller(system, "pid"), sea_states=["calm"])
    with pytest.raises(SupervisorError, match="pid must be a TAPMPID, got str"):
        supervised_pid(system, pid="pid")
    feats = SeaStateFeatures(1.0, 8.0, 1e6)
    assert feats.as_dict() == {"amplitude_m": 1.0, "period_s": 8.0, "load_N": 1e6}
