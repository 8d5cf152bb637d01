"""The DP observers (passive observer and EKF) against the plant's own LF truth and against the
model they are built on.

One closed loop per sea state on fpso (PID, 1200 s), shared by the module: in the ``normal`` sea the
passive observer drives the loop, in the ``storm`` the EKF; the other observer and the present
``LowPassEstimator`` are fed the same measurements alongside, so all three are compared on one run.
Figures measured with these settings and the thresholds' margins: ``docs/estimation.md``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from tapm_opt.config import Fault, load_scenario
from tapm_opt.estimation.detection import TensionDropDetector
from tapm_opt.estimation.lowpass import EstimationError, LowPassEstimator, first_order_step
from tapm_opt.estimation.observer import (DEFAULT_TP, PASSIVE_OMEGA_C_RATIO, PASSIVE_ZETA_N, EKFObserver,
                                          PassiveObserver, passive_gains, wave_filter_matrices)
from tapm_opt.geometry import rot_z, ssa
from tapm_opt.interfaces import Estimate, Estimator, Measurement, ThrusterCommand
from tapm_opt.models.system import System
from tapm_opt.models.vessel import VesselParams
from tapm_opt.plant.simulator import Plant
from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
from tapm_opt.studies.controllers import build_controller

DURATION = 1200.0
WARM = 300            # samples (s) left out of the statistics: start-up of the estimators and the loop
OBSERVERS = ("passive", "ekf")


@pytest.fixture(scope="module")
def system():
    return System.from_scenario(load_scenario("fpso"))


class Tee:
    """The estimator of the loop plus shadows fed the same measurements; every estimate kept."""

    def __init__(self, main, shadows):
        self.main, self.shadows = main, shadows
        self.measurements, self.estimates = [], {k: [] for k in ("main", *shadows)}

    def update(self, t, m):
        self.measurements.append(m)
        for k, e in self.shadows.items():
            self.estimates[k].append(e.update(t, m))
        est = self.main.update(t, m)
        self.estimates["main"].append(est)
        return est

    def reset(self):
        for e in (self.main, *self.shadows.values()):
            e.reset()


def _closed_loop(system, sea_state, driver):
    make = {"passive": PassiveObserver, "ekf": EKFObserver}
    other = "ekf" if driver == "passive" else "passive"
    tee = Tee(make[driver].from_scenario(system, sea_state),
              {other: make[other].from_scenario(system, sea_state), "lowpass": LowPassEstimator(system.lines)})
    plant = Plant(system, sea_state=sea_state, seed=1, segments=10)
    res = run_closed_loop(plant, build_controller(system, "pid"), ClosedLoopSettings(duration=DURATION, dt_control=1.0),
                          system=system, estimator=tee)
    est = {driver: tee.estimates["main"], other: tee.estimates[other], "lowpass": tee.estimates["lowpass"]}
    return {"result": res, "estimates": est, "measurements": tee.measurements,
            "omega_0": 2 * math.pi / system.scenario.sea_state(sea_state).Tp}


@pytest.fixture(scope="module")
def runs(system):
    return {"normal": _closed_loop(system, "normal", "passive"), "storm": _closed_loop(system, "storm", "ekf")}


def _eta(estimates):
    return np.array([e.eta for e in estimates])


def _rms_xy(run, name):
    res = run["result"]
    E = _eta(run["estimates"][name])
    err = E[WARM:, :2] - np.c_[res["x"], res["y"]][WARM:]
    return float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))


def _band(x, omega_0):
    """Band-pass 0.3-2 omega_0 (4th-order Butterworth, zero phase) of a 1 Hz series."""
    sos = butter(4, [0.3 * omega_0 / (2 * np.pi), 2.0 * omega_0 / (2 * np.pi)], btype="band", fs=1.0, output="sos")
    return sosfiltfilt(sos, x)


def _leakage(eta_hat, res, omega_0):
    """var(band-pass of the LF estimate's x, y) / var(true WF motion x_wf, y_wf), after the warm-up."""
    num = sum(np.var(_band(eta_hat[:, i], omega_0)[WARM:]) for i in (0, 1))
    den = np.var(res["x_wf"][WARM:]) + np.var(res["y_wf"][WARM:])
    return float(num / den)


# -- (a) LF position error against the plant's truth -----------------------------------------

@pytest.mark.parametrize("sea", ["normal", "storm"])
def test_lf_position_error_is_below_the_low_pass_estimators(runs, sea):
    run = runs[sea]
    assert run["result"].meta["estimator"] == "Tee"
    rms = {k: _rms_xy(run, k) for k in (*OBSERVERS, "lowpass")}
    # measured (1200 s, seed 1): normal lowpass 0.73, passive 0.32, ekf 0.29 m; storm 1.12, 0.42, 0.44 m
    for k in OBSERVERS:
        assert rms[k] <= 0.75 * rms["lowpass"], rms
        assert rms[k] <= 0.65, rms


def test_heading_error_is_small(runs):
    for sea, run in runs.items():
        psi = run["result"]["psi"][WARM:]
        for k in OBSERVERS:
            err = ssa(_eta(run["estimates"][k])[WARM:, 2] - psi)
            assert np.degrees(np.sqrt(np.mean(err ** 2))) < 0.1, (sea, k)   # heading noise 0.1 deg


def test_eta_wf_plus_eta_reproduces_the_measurement_on_average(runs):
    """eta + eta_wf is the observer's y_hat: its error against the measured pose is noise-sized."""
    run = runs["storm"]
    y = np.array([[m.position[0], m.position[1]] for m in run["measurements"]])[WARM:]
    for k in OBSERVERS:
        yh = np.array([e.eta[:2] + e.eta_wf[:2] for e in run["estimates"][k]])[WARM:]
        assert np.sqrt(np.mean((y - yh) ** 2)) < 0.6   # GNSS noise 0.5 m per axis
        assert abs(np.mean(y - yh)) < 0.1


# -- (b) wave-frequency leakage --------------------------------------------------------------

def _replay_clean(run, make):
    """Replay the run's measurement times with the noise-free true pose (LF + WF) measured."""
    res = run["result"]
    est = make()
    out = []
    for k, m in enumerate(run["measurements"]):
        clean = replace(m, position=np.array([res["x"][k] + res["x_wf"][k], res["y"][k] + res["y_wf"][k]]),
                        heading=float(ssa(res["psi"][k] + res["psi_wf"][k])))
        out.append(est.update(m.t, clean).eta)
    return np.array(out)


@pytest.mark.parametrize("sea", ["normal", "storm"])
def test_wave_frequency_motion_leaks_little_into_the_lf_estimate(runs, system, sea):
    """Leakage of the true WF motion alone (the run replayed without sensor noise): var of the LF
    estimate in the band 0.3-2 omega_0 over var(x_wf) + var(y_wf). Target <= 10 %; measured
    (1200 s): EKF 7.6 % (normal) / 8.8 % (storm), passive 9.4 % / 8.0 % (zeta_n = 1.1, omega_c =
    1.05 omega_0; with zeta_n = 1, omega_c = 1.2 omega_0 11.3 % / 9.6 %: that notch leaves the lower
    flank of the WF spectrum, where the surge motion has most of its energy)."""
    run = runs[sea]
    makers = {"passive": lambda: PassiveObserver.from_scenario(system, sea),
              "ekf": lambda: EKFObserver.from_scenario(system, sea)}
    leak = {k: _leakage(_replay_clean(run, mk), run["result"], run["omega_0"]) for k, mk in makers.items()}
    assert leak["ekf"] <= 0.10, leak
    assert leak["passive"] <= 0.10, leak


def test_wave_frequency_band_with_sensor_noise_is_bounded(runs):
    """The same ratio on the measured (noisy) storm run: the band then holds mostly GNSS noise
    (0.5 m against 0.4 m of WF surge). Measured: EKF 18 %, passive 18 %, low-pass 4.5 % (it filters
    everything above 2 pi / 40 s, at the price of the lag in the RMS error above)."""
    run = runs["storm"]
    leak = {k: _leakage(_eta(run["estimates"][k]), run["result"], run["omega_0"]) for k in (*OBSERVERS, "lowpass")}
    assert leak["ekf"] <= 0.30, leak
    assert leak["passive"] <= 0.35, leak
    assert leak["lowpass"] <= 0.10, leak


def test_wave_frequency_estimate_follows_the_true_wf_motion(runs):
    """In the storm the WF estimate eta_wf correlates with the true surge WF motion."""
    run = runs["storm"]
    wf = run["result"]["x_wf"][WARM:]
    for k in OBSERVERS:
        xw = np.array([e.eta_wf[0] for e in run["estimates"][k]])[WARM:]
        assert np.corrcoef(wf, xw)[0, 1] > 0.4, k


# -- (c) bias convergence --------------------------------------------------------------------

@pytest.fixture(scope="module")
def thrust_step(system):
    """Still water, a constant thrust from t = 0 (all six thrusters ahead at 40 % of capacity,
    2.9 MN surge once the thrusters have ramped up); both observers are told tau_thr = None.
    Returns times, the tau_env estimates ({B}) of each and the delivered thrust. The plant at
    fpso's own segments (3 / 16 / 1 per line): at 10 (split 1 / 8 / 1) the FEM mooring is 13 %
    stiffer than the quasi-static model the observers carry (the 300 m bottom chain in one
    segment), and that error, not the observer, would set the bias (12-15 %)."""
    plant = Plant(system, sea_state="none", seed=2)
    cmd = ThrusterCommand(0.4 * np.asarray(plant.thrusters.limits.f_max, float), np.zeros(plant.thrusters.n))
    obs = {"passive": PassiveObserver.from_scenario(system), "ekf": EKFObserver.from_scenario(system)}
    ts, tau_true, tau_hat = [], [], {k: [] for k in obs}
    for _ in range(800):
        m = plant.measure()
        tau_true.append(np.array(m.tau_thr))
        blind = replace(m, tau_thr=None)
        for k, o in obs.items():
            tau_hat[k].append(np.array(o.update(m.t, blind).tau_env))
        ts.append(m.t)
        plant.step(1.0, cmd)
    return np.array(ts), {k: np.array(v) for k, v in tau_hat.items()}, np.array(tau_true)


@pytest.mark.parametrize("kind", OBSERVERS)
def test_bias_converges_to_an_unknown_thrust_step(thrust_step, kind):
    """Told no thrust, the observer must explain the thrust as environment: tau_env -> tau_thr.
    Every 100 s mean of the estimate from 300 s on within 5 % of |tau_thr| (measured: passive
    1-3 %, EKF 1-3 %), the noise about it below 12 % rms (measured 6 % and 9 %)."""
    t, hats, true = thrust_step
    hat = hats[kind]
    ref = true[-1]
    assert ref[0] > 2e6 and abs(ref[1]) < 1e3          # the step is real: 2.9 MN ahead
    scale = np.linalg.norm(ref[:2])
    err = hat[:, :2] - true[:, :2]
    for a in range(300, 800, 100):
        w = (t >= a) & (t < a + 100)
        assert np.linalg.norm(err[w].mean(axis=0)) < 0.05 * scale, (a, err[w].mean(axis=0) / scale)
    late = t >= 300
    assert np.sqrt(np.mean(np.sum((err[late] - err[late].mean(axis=0)) ** 2, axis=1))) < 0.12 * scale
    assert np.abs(hat[late, 2].mean() - true[late, 2].mean()) < 0.05 * scale * 50.0   # yaw: 50 m lever
    early = np.linalg.norm(err[t <= 20.0], axis=1)
    assert early.max() > 0.3 * scale   # it starts far off (the thrust ramps up): convergence, not a copy


class LinearSpring:
    """A stand-in line model: tau_m = -R(psi)^T K eta (no tabulated evaluator)."""

    line_ids = ()

    def __init__(self, K):
        self.K = np.asarray(K, float)

    def force(self, eta):
        return -rot_z(eta[2]).T @ (self.K @ np.asarray(eta, float))

    def stiffness(self, eta):
        return self.K


def _simulate_model(vessel, K, omega_0, lam, b_step, *, T=1500.0, h=0.05, dt=1.0, seed=4, noise=(0.5, 0.002),
                    wf_std=(0.3, 0.3, 0.002)):
    """Eq. (1) itself: LF vessel on a linear spring, constant bias from t = 200 s ({E}), WF of
    (1d)-(1e) driven by white noise, GNSS/heading noise. Returns measurements and the truth."""
    rng = np.random.default_rng(seed)
    A, C = wave_filter_matrices(omega_0, lam)
    q = 4.0 * lam * omega_0 * np.asarray(wf_std) ** 2
    eta, nu, xi = np.zeros(3), np.zeros(3), np.zeros(6)
    Mi, D = vessel.M_inv, vessel.D_lin
    ms, truth = [], []
    n_sub = int(round(dt / h))
    for k in range(int(T / dt) + 1):
        t = k * dt
        yw = C @ xi
        y = eta + yw + np.array([noise[0] * rng.standard_normal(), noise[0] * rng.standard_normal(),
                                 noise[1] * rng.standard_normal()])
        b = b_step if t >= 200.0 else np.zeros(3)
        ms.append(Measurement(t=t, position=y[:2], heading=float(ssa(y[2])), tensions=np.zeros(0), t_position=t,
                              t_heading=t, t_tensions=t, tau_thr=np.zeros(3)))
        truth.append((eta.copy(), nu.copy(), b.copy(), yw))
        for _ in range(n_sub):
            Rt = rot_z(eta[2]).T
            tau_m = -Rt @ (K @ eta)
            nu = nu + h * (Mi @ (-D @ nu + Rt @ b + tau_m))
            eta = eta + h * (rot_z(eta[2]) @ nu)
            xi = xi + h * (A @ xi)
            xi[3:] += np.sqrt(q * h) * rng.standard_normal(3)
    return ms, truth


@pytest.fixture(scope="module")
def model_data(system):
    K = np.diag([8.6e4, 8.6e4, 7.2e8])          # fpso's mooring stiffness at the field zero point
    w0 = 2 * np.pi / 10.0
    b_step = np.array([1.5e6, -1.0e6, 2.0e7])
    ms, truth = _simulate_model(system.vessel, K, w0, 0.1, b_step)
    return K, w0, b_step, ms, truth


@pytest.mark.parametrize("kind", OBSERVERS)
def test_model_matched_bias_step_and_states(system, model_data, kind):
    """On data from the observer's own model (eq. 1, a bias step at 200 s) the estimates converge:
    the bias's mean error over 600-1500 s below 3 % of the step (x, y; measured <= 2 %) and 10 %
    (yaw), every 100 s mean from 500 s within 6 %; LF position RMS below 0.55 of the raw
    measurement's (measured: passive 0.40, EKF 0.30); the WF estimate follows the WF motion."""
    K, w0, b_step, ms, truth = model_data
    vessel = system.vessel
    if kind == "passive":
        obs = PassiveObserver(LinearSpring(K), vessel, omega_0=w0)
    else:
        obs = EKFObserver(LinearSpring(K), vessel, omega_0=w0, gnss_std=0.5, heading_std=0.002, wf_std=(0.3, 0.3, 0.002))
    est = [obs.update(m.t, m) for m in ms]
    t = np.array([m.t for m in ms])
    b_hat = np.array([rot_z(e.eta[2]) @ e.tau_env for e in est])         # back to {E}
    b_true = np.array([tr[2] for tr in truth])
    err = (b_hat - b_true) / np.array([1.5e6, 1.5e6, 2.0e7])
    late = t >= 600.0
    assert np.all(np.abs(err[late, :2].mean(axis=0)) < 0.03), err[late].mean(axis=0)
    assert abs(err[late, 2].mean()) < 0.10, err[late].mean(axis=0)
    for a in range(500, 1500, 100):
        w = (t >= a) & (t < a + 100)
        assert np.all(np.abs(err[w, :2].mean(axis=0)) < 0.06), (a, err[w].mean(axis=0))
    assert np.abs(err[(t > 200) & (t < 210), 0]).min() > 0.5   # the step is not known: it has to be found
    eta_true = np.array([tr[0] for tr in truth])[300:, :2]
    eta_hat = np.array([e.eta for e in est])[300:, :2]
    y = np.array([m.position for m in ms])[300:]
    rms = np.sqrt(np.mean(np.sum((eta_hat - eta_true) ** 2, axis=1)))
    raw = np.sqrt(np.mean(np.sum((y - eta_true) ** 2, axis=1)))
    assert rms < 0.55 * raw, (rms, raw)
    wf_true = np.array([tr[3][0] for tr in truth])[300:]
    wf_hat = np.array([e.eta_wf[0] for e in est])[300:]
    assert np.corrcoef(wf_true, wf_hat)[0, 1] > 0.5


# -- (d) still water -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def still_water(system):
    plant = Plant(system, sea_state="none", seed=5, segments=10)
    obs = {"passive": PassiveObserver.from_scenario(system), "ekf": EKFObserver.from_scenario(system)}
    est, truth = {k: [] for k in obs}, []
    for _ in range(500):
        m = plant.measure()
        for k, o in obs.items():
            est[k].append(o.update(m.t, m))
        truth.append(plant.eta.copy())
        plant.step(1.0)
    return est, np.array(truth)


@pytest.mark.parametrize("kind", OBSERVERS)
def test_still_water_estimates_stay_at_the_truth(still_water, kind):
    """No waves, no wind, no thrust: the vessel rests at the field zero point; the estimates must
    stay there (position within the filtered GNSS noise, velocity and load near zero). Measured:
    position rms 0.29 m (passive) / 0.22 m (EKF), velocity rms <= 0.02 m/s."""
    est, truth = still_water
    est = est[kind][100:]
    assert np.abs(truth[:, :2]).max() < 0.05                          # the truth did stay
    eta = np.array([e.eta for e in est])
    assert np.sqrt(np.mean(np.sum(eta[:, :2] ** 2, axis=1))) < 0.35   # GNSS 0.5 m per axis
    assert np.abs(eta[:, 2]).max() < math.radians(0.2)
    nu = np.array([e.nu for e in est])
    assert np.all(nu[:, :2].std(axis=0) < 0.03) and np.all(np.abs(nu[:, :2].mean(axis=0)) < 0.005)
    tau = np.array([e.tau_env for e in est])
    # measured: mean <= 3e3 N, rms <= 1.7e5 N (the GNSS noise through the bias gains)
    assert np.all(np.abs(tau[:, :2].mean(axis=0)) < 2e4), tau.mean(axis=0)
    assert np.all(tau[:, :2].std(axis=0) < 2.5e5), tau.std(axis=0)    # mooring: 1.8 MN at 20 m
    wf = np.array([e.eta_wf for e in est])[:, :2]
    assert np.all(np.sqrt(np.mean(wf ** 2, axis=0)) < 0.4)            # noise only: measured 0.35 / 0.20 m


# -- (e) inputs ------------------------------------------------------------------------------

def _meas(t=1.0, position=(0.0, 0.0), heading=0.0, tau_thr=None):
    return Measurement(t=t, position=np.asarray(position, float), heading=heading, tensions=np.zeros(12),
                       t_position=t, t_heading=t, t_tensions=t, tau_thr=tau_thr)


@pytest.mark.parametrize("kw, field", [
    ({"omega_0": -1.0}, "omega_0"), ({"omega_0": float("nan")}, "omega_0"), ({"lam": 0.0}, "lam"),
    ({"lam": 2.0}, "lam"), ({"zeta_n": 0.05}, "zeta_n"), ({"omega_c": 0.5}, "omega_c"),
    ({"T_b": 0.0}, "T_b"), ({"T_b": (1000.0, -1.0, 1000.0)}, "T_b[1]"), ({"K3": -1.0}, "K3"),
    ({"K3": 1e12, "K4": 1.0}, "K3[0] / K4[0]"), ({"omega_b": 1.0}, "omega_b"),
    ({"sea_state": "storm"}, "sea_state"),
])
def test_passive_observer_rejects_bad_settings(system, kw, field):
    with pytest.raises(EstimationError, match=field.replace("[", r"\[").replace("]", r"\]")):
        PassiveObserver(system.lines, system.vessel, **kw)


@pytest.mark.parametrize("kw, field", [
    ({"omega_0": 0.0}, "omega_0"), ({"lam": -0.1}, "lam"), ({"gnss_std": -0.1}, "gnss_std"),
    ({"heading_std": float("inf")}, "heading_std"), ({"wf_std": 0.0}, "wf_std"), ({"bias_std": (1.0, 2.0)}, "bias_std"),
    ({"force_noise": -1.0}, "force_noise"), ({"T_b": "long"}, "T_b"),
])
def test_ekf_rejects_bad_settings(system, kw, field):
    with pytest.raises(EstimationError, match=field):
        EKFObserver(system.lines, system.vessel, **kw)


@pytest.mark.parametrize("cls", [PassiveObserver, EKFObserver])
def test_bad_models_sea_states_and_measurements_raise(system, cls):
    with pytest.raises(EstimationError, match="model"):
        cls(object(), system.vessel)
    with pytest.raises(EstimationError, match="vessel"):
        cls(system.lines, {"M": 1.0})
    with pytest.raises(EstimationError, match="'rough'"):
        cls.from_scenario(system, "rough")
    with pytest.raises(EstimationError, match="scenario_or_system"):
        cls.from_scenario(42)
    obs = cls.from_scenario(system)
    obs.update(1.0, _meas(1.0))
    with pytest.raises(EstimationError, match=r"t = 0.5 s is before"):
        obs.update(0.5, _meas(0.5))
    with pytest.raises(EstimationError, match="nan"):
        obs.update(2.0, _meas(2.0, position=(float("nan"), 0.0)))
    with pytest.raises(EstimationError, match="tau_thr"):
        obs.update(2.0, _meas(2.0, tau_thr=np.zeros(2)))
    with pytest.raises(EstimationError, match="measurement"):
        obs.update(2.0, {"position": (0, 0)})


def test_gain_formulas_and_their_transfer_function():
    """K1, K2 of Fossen 2011 eq. 11.123-11.124 make y -> eta_hat the notch times a low-pass at
    omega_c (without the LF kinetics): check the fast subsystem's frequency response, for the
    defaults (zeta_n = 1.1, omega_c = 1.05 omega_0) and for given zeta_n, omega_c."""
    w0, lam = 0.6, 0.1
    assert (PASSIVE_ZETA_N, PASSIVE_OMEGA_C_RATIO) == (1.1, 1.05)
    gains = {(1.1, 1.05 * w0): passive_gains(w0, lam), (1.0, 1.2 * w0): passive_gains(w0, lam, 1.0, 1.2 * w0)}
    mag = {}
    for (zn, wc), (K1, K2) in gains.items():
        assert np.allclose(np.diag(K1[:3]), -2 * (zn - lam) * wc / w0)
        assert np.allclose(np.diag(K1[3:]), 2 * w0 * (zn - lam))
        assert np.allclose(K2, wc * np.eye(3))
        k1, k2 = K1[0, 0], K1[3, 0]
        A = np.array([[0, 1 - k1, -k1], [-w0 ** 2, -2 * lam * w0 - k2, -k2], [0, -wc, -wc]])
        B = np.array([k1, k2, wc])
        for w in (0.1, 0.8 * w0, w0, 1.5):
            s = 1j * w
            H = np.linalg.solve(s * np.eye(3) - A, B)[2]
            ref = (s ** 2 + 2 * lam * w0 * s + w0 ** 2) * wc / ((s ** 2 + 2 * zn * w0 * s + w0 ** 2) * (s + wc))
            assert abs(H - ref) < 1e-12
            mag[zn, w] = abs(H)
        assert abs(ref) < 1.0  # (last) above the notch: attenuated
        assert np.all(np.linalg.eigvals(A).real < 0)
    # the defaults pass less of the notch's lower flank, where a moored ship's WF surge motion lies
    assert mag[1.1, 0.8 * w0] == pytest.approx(0.174, abs=1e-3) and mag[1.0, 0.8 * w0] == pytest.approx(0.200, abs=1e-3)
    assert mag[1.1, w0] < mag[1.0, w0]


def test_defaults_and_from_scenario(system):
    sc = system.scenario
    p = PassiveObserver.from_scenario(system)
    assert p.omega_0 == pytest.approx(2 * np.pi / DEFAULT_TP)
    p = PassiveObserver.from_scenario(sc, "storm")
    assert p.omega_0 == pytest.approx(2 * np.pi / 13.0) and p.omega_c == pytest.approx(1.05 * p.omega_0)
    assert p.zeta_n == 1.1
    assert np.all(p.K3 / p.K4 > 1.0 / p.T_b) and np.all(p.K3 / p.K4 < p.omega_0)   # passivity ordering
    e = EKFObserver.from_scenario(sc, sc.sea_state("normal"), T_b=500.0)
    assert e.omega_0 == pytest.approx(2 * np.pi / 10.0) and np.all(e.T_b == 500.0)
    assert e.gnss_std == sc.sensors.gnss_std and e.heading_std == pytest.approx(math.radians(0.1))
    assert np.allclose(e.wf_std[:2], 0.04 * 7.0)
    assert isinstance(e, Estimator) and isinstance(p, Estimator)
    v = VesselParams.from_scenario(sc)
    assert np.allclose(EKFObserver(system.lines, v).vessel.M, sc.vessel.mass_matrix)


@pytest.mark.parametrize("cls", [PassiveObserver, EKFObserver])
def test_estimate_fields_heading_wrap_and_reset(system, cls):
    obs = cls.from_scenario(system)
    T0 = np.asarray(system.lines.tensions(np.zeros(3)))
    est = None
    for k in range(40):   # heading crossing +-pi
        psi = float(ssa(np.pi - 0.2 + 0.01 * k))
        m = replace(_meas(float(k), heading=psi), tensions=T0)
        est = obs.update(m.t, m)
    assert isinstance(est, Estimate) and est.eta_wf.shape == (3,) and est.tau_env.shape == (3,)
    assert -np.pi <= est.eta[2] < np.pi
    # no 2 pi jump; the model's yaw spring makes the estimate lag the ramp: the passive 0.12 rad and
    # the EKF 0.035 rad on fpso's chain-wire-chain mooring (K33 1.17e9 N m/rad), half that on the
    # softer fpso_equivalent (7.2e8 N m/rad: 0.063 and 0.019 rad)
    assert abs(ssa(est.eta[2] - (np.pi - 0.2 + 0.39))) < 0.2
    assert est.tensions is not None and np.allclose(est.tensions, T0)
    assert est.broken_lines == frozenset() and est.reliability is None
    assert obs.innovation.shape == (3,)
    if cls is EKFObserver:
        assert obs.innovation_cov.shape == (3, 3) and np.all(np.linalg.eigvalsh(obs.innovation_cov) > 0)
        assert obs.innovation_mask.all()
        assert np.allclose(obs.P, obs.P.T)
    obs.reset()
    e2 = obs.update(0.0, _meas(0.0, position=(3.0, -2.0)))
    assert np.allclose(e2.eta, [3.0, -2.0, 0.0])


def test_ekf_corrects_only_at_new_samples(system):
    obs = EKFObserver.from_scenario(system)
    obs.update(0.0, _meas(0.0))
    held = Measurement(t=0.5, position=np.array([5.0, 0.0]), heading=0.0, tensions=np.zeros(12), t_position=0.0,
                       t_heading=0.5, t_tensions=0.0)
    est = obs.update(0.5, held)     # the position is the held sample of t = 0: not used again
    assert list(obs.innovation_mask) == [False, False, True]
    assert abs(est.eta[0]) < 1e-6
    est = obs.update(1.0, _meas(1.0, position=(5.0, 0.0)))
    assert obs.innovation_mask.all() and est.eta[0] > 0.01


# -- (f) a detected break swaps the model ---------------------------------------------------

def test_detected_break_swaps_the_line_model(system):
    """Still water, line 1 breaks at 50 s: with a detector the observers drop it from the model,
    so the bias stays near the true (zero) environment; an observer without a detector has to
    explain the lost line's pull (~2 MN) as environmental load. Compared: the mean of the last 200 s."""
    plant = Plant(system, sea_state="none", seed=6, segments=10, faults=[Fault(kind="line_break", time=50.0, line="1")])
    obs = {"passive": PassiveObserver.from_scenario(system, detector=TensionDropDetector(system.lines)),
           "ekf": EKFObserver.from_scenario(system, detector=TensionDropDetector(system.lines)),
           "ekf_blind": EKFObserver.from_scenario(system)}
    est = {k: [] for k in obs}
    for _ in range(600):
        m = plant.measure()
        for k, o in obs.items():
            est[k].append(o.update(m.t, m))
        plant.step(1.0)
    lost = float(np.linalg.norm(system.lines.force(np.zeros(3))[:2] - system.lines.without({"1"}).force(np.zeros(3))[:2]))
    assert lost > 1e6
    for k in ("passive", "ekf"):
        assert est[k][-1].broken_lines == frozenset({"1"})
        assert "1" not in obs[k].model.line_ids and "1" in obs[k].intact_model.line_ids
        assert obs[k].log() and obs[k].log()[0]["line"] == "1"
        assert np.allclose(obs[k].mooring_load(np.array([2.0, 1.0, 0.01])),
                           system.lines.without({"1"}).force(np.array([2.0, 1.0, 0.01])), rtol=1e-6, atol=10.0)
        tail = np.array([e.tau_env for e in est[k][-200:]]).mean(axis=0)
        assert np.linalg.norm(tail[:2]) < 0.06 * lost, (k, tail / lost)      # measured: passive 0.05, EKF 0.03
    blind = np.array([e.tau_env for e in est["ekf_blind"][-200:]]).mean(axis=0)
    assert np.linalg.norm(blind[:2]) > 0.8 * lost, blind / lost                # measured 1.18
    obs["ekf"].reset()
    assert obs["ekf"].model is obs["ekf"].intact_model


def test_state_handed_to_another_observer_gives_its_estimate():
    """``state``/``set_state``/``estimate_now``: a fresh observer given another's state reports the
    same estimate, and then evolves as it does."""
    from tapm_opt.config import load_scenario
    from tapm_opt.estimation.observer import EKFObserver, PassiveObserver
    from tapm_opt.interfaces import Measurement
    from tapm_opt.models.system import System

    system = System.from_scenario(load_scenario("fpso"))
    rng = np.random.default_rng(0)
    for cls in (PassiveObserver, EKFObserver):
        a, b = cls.from_scenario(system), cls.from_scenario(system)
        ms = [Measurement(t=float(k), position=rng.normal(0, 1, 2), heading=0.01 * rng.normal(), tensions=np.zeros(12),
                          t_position=float(k), t_heading=float(k), t_tensions=float(k)) for k in range(40)]
        for m in ms[:30]:
            a.update(m.t, m)
        b.set_state(a.state())
        ea, eb = a.estimate_now(29.0, ms[29]), b.estimate_now(29.0, ms[29])
        assert np.array_equal(ea.eta, eb.eta) and np.array_equal(ea.tau_env, eb.tau_env)
        for m in ms[30:]:
            ea, eb = a.update(m.t, m), b.update(m.t, m)
        assert np.allclose(ea.eta, eb.eta, rtol=0, atol=1e-9) and np.allclose(ea.nu, eb.nu, rtol=0, atol=1e-12)


@pytest.mark.parametrize("psi", [0.0, 0.7, math.pi / 2, -2.5])
def test_ekf_transition_jacobian_against_central_differences(psi):
    """The EKF's F (the Jacobian of its discrete prediction, every block incl. the bias's
    d(R^T b)/db = R^T) against central differences of the same prediction at a heading off 0."""
    import copy

    from tapm_opt.config import load_scenario
    from tapm_opt.estimation.observer import EKFObserver
    from tapm_opt.models.system import System

    ekf = EKFObserver.from_scenario(System.from_scenario(load_scenario("fpso")))
    rng = np.random.default_rng(3)
    x0 = np.concatenate([rng.normal(0, 0.5, 6), [12.0, -8.0, psi], rng.normal(0, 0.3, 2), [1e-3],
                         [1.5e6, -0.8e6, 2e7]])
    tau_c = np.array([3e5, -2e5, 1e6])

    def step(x):
        f = copy.deepcopy(ekf)
        f.x, f.P = x.copy(), np.eye(15)
        f._predict(1.0, tau_c)
        return f.x, f._Phi.copy()

    _, F = step(x0)
    h = np.array([1e-4] * 6 + [1e-3, 1e-3, 1e-6, 1e-5, 1e-5, 1e-7, 10.0, 10.0, 100.0])
    num = np.empty((15, 15))
    for j in range(15):
        e = np.zeros(15)
        e[j] = h[j]
        num[:, j] = (step(x0 + e)[0] - step(x0 - e)[0]) / (2 * h[j])
    big = np.abs(num) > 1e-15            # entry by entry: the bias's entries are ~1e-9 beside 1's
    assert np.max(np.abs(F - num)[big] / np.abs(num)[big]) < 5e-3   # the mooring block: J by differences
    assert np.max(np.abs(F[~big])) < 1e-15


def test_first_order_step_is_the_exact_solution_and_composes():
    """T y' = u - y with u held: y(dt) = u + (y0 - u) exp(-dt / T); two half steps are one step;
    a step back in time holds y; arrays work element-wise."""
    T, y0, u = 40.0, np.array([3.0, -2.0]), np.array([1.0, 5.0])
    y = first_order_step(y0, u, 25.0, T)
    np.testing.assert_allclose(y, u + (y0 - u) * math.exp(-25.0 / T), rtol=1e-15)
    np.testing.assert_allclose(first_order_step(first_order_step(y0, u, 12.5, T), u, 12.5, T), y, rtol=1e-14)
    np.testing.assert_array_equal(first_order_step(y0, u, -5.0, T), y0)
    assert first_order_step(2.0, 2.0, 1e6, T) == pytest.approx(2.0) and first_order_step(0.0, 1.0, 1e9, T) == 1.0
