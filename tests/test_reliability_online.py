"""The causal (on-line) reliability index (tapm_opt.estimation.reliability) and the KPIs built on it.

Answers come from closed forms (a sinusoid's mean and RMS, the Gumbel factor, Rice's zero up-crossing
period of a sum of cosines, the trailing average of a sine), from the offline index it must reproduce
when their windows coincide, and from direct recomputation over the window.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.estimation import (ReliabilityError, ReliabilityMonitor, causal_reliability, gumbel_k,
                                 LP_WINDOW_DEFAULT, SIGMA_WINDOW_DEFAULT)
from tapm_opt.results import Result
from tapm_opt.studies import kpis
from tapm_opt.studies.kpis import case_kpis, kpi_order, kpi_table, kpi_unit, low_pass, reliability_index

EULER = 0.5772156649015329
W = LP_WINDOW_DEFAULT


def k_hand(n: float) -> float:
    s = math.sqrt(2 * math.log(n))
    return s + EULER / s


def narrow_band(t, sigma, *, seed, n_comp=200, Tp=10.0, rel_width=0.5, with_leak=False):
    """Sum of n_comp equal cosines with random phases, frequencies spread over +-rel_width/2 of
    omega_p = 2 pi / Tp: a narrow-band, nearly Gaussian process of standard deviation sigma.
    Returns (x, Tz) with Tz = 2 pi sqrt(m0 / m2) the mean zero up-crossing period (Rice), or
    (x, Tz, leak) with ``leak(W)`` the RMS of x through a W-wide moving average (gain sinc(w W / 2))
    when ``with_leak``."""
    rng = np.random.default_rng(seed)
    wp = 2 * np.pi / Tp
    w = np.linspace((1 - rel_width / 2) * wp, (1 + rel_width / 2) * wp, n_comp)
    a = np.full(n_comp, sigma * math.sqrt(2.0 / n_comp))
    ph = rng.uniform(0, 2 * np.pi, n_comp)
    x = np.zeros(len(t))
    for ai, wi, pi in zip(a, w, ph):
        x += ai * np.cos(wi * t + pi)
    m0, m2 = np.sum(a**2 / 2), np.sum(a**2 / 2 * w**2)
    Tz = 2 * np.pi * math.sqrt(m0 / m2)
    if with_leak:
        return x, Tz, lambda W: math.sqrt(np.sum(a**2 / 2 * (np.sin(w * W / 2) / (w * W / 2))**2))
    return x, Tz


# -- the estimator on a stationary record -------------------------------------------------------

@pytest.fixture(scope="module")
def sea():
    """4 h at 0.5 s: mean 3 MN + a 600 s LF sine of 0.2 MN + narrow-band WF of sigma 0.2 MN."""
    t = np.arange(0.0, 4 * 3600.0 + 0.25, 0.5)
    wf, Tz, leak = narrow_band(t, 2e5, seed=7, with_leak=True)
    T0, A, P = 3e6, 2e5, 600.0
    return dict(t=t, x=T0 + A * np.sin(2 * np.pi * t / P) + wf, Tz=Tz, sigma=2e5, T0=T0, A=A, P=P, leak=leak(W))


def test_online_sigma_n_and_delta_of_a_narrow_band_sea(sea):
    t, x, sig, Tz = sea["t"], sea["x"], sea["sigma"], sea["Tz"]
    S = 3600.0  # 360 periods: sampling error of sigma ~ 3 % (600 s gives ~ 9 %, a 1-sigma figure)
    r_t, s_t = 10e6, 0.5e6
    rec = causal_reliability(t, x, [r_t], [s_t], sigma_window=S)
    ok = rec.ready
    assert t[ok][0] == pytest.approx(W + S) and ok[np.flatnonzero(ok)[0]:].all()
    s = rec.sigma[ok, 0]
    # the centred residual passes the WF almost unchanged (1 - sinc gain: +0.05 % variance) and
    # lets 0.045 A of the 600 s sine through (+0.1 %): the true sigma within 0.1 %
    assert np.max(np.abs(s / sig - 1)) < 0.08
    assert np.mean(s**2) / sig**2 == pytest.approx(1.0, abs=0.02)
    n = rec.n[ok, 0]
    assert np.max(np.abs(n / (S / Tz) - 1)) < 0.04
    assert n.mean() == pytest.approx(S / Tz, rel=0.01)
    # r_m: the trailing 100 s average of the LF sine = A sinc(pi W / P) sin(2 pi (t - W/2) / P)
    A, P, T0 = sea["A"], sea["P"], sea["T0"]
    u = math.pi * W / P
    m_true = T0 + A * math.sin(u) / u * np.sin(2 * np.pi * (t[ok] - W / 2) / P)
    err = rec.x_lf[ok, 0] - m_true  # the WF leaking through the average: |sinc| <= 4.3 % over the band
    assert sea["leak"] < 0.03 * sig
    assert np.sqrt(np.mean(err**2)) == pytest.approx(sea["leak"], rel=0.1)
    assert np.max(np.abs(err)) < 5 * sea["leak"]
    delta_true = (r_t - m_true - k_hand(S / Tz) * sig) / s_t
    assert np.max(np.abs(rec.delta[ok, 0] - delta_true)) < 0.15  # 8 % of k sigma / s_t = 0.12, + leak
    assert np.mean(rec.delta[ok, 0] - delta_true) == pytest.approx(0.0, abs=0.02)


def test_default_windows_count_the_maxima_of_ten_minutes(sea):
    t, x, Tz = sea["t"], sea["x"], sea["Tz"]
    rec = causal_reliability(t, x, [10e6], [0.5e6])
    ok = rec.ready
    assert t[ok][0] == pytest.approx(W + SIGMA_WINDOW_DEFAULT)
    np.testing.assert_allclose(rec.span[ok], SIGMA_WINDOW_DEFAULT)
    assert rec.n[ok, 0].mean() == pytest.approx(SIGMA_WINDOW_DEFAULT / Tz, rel=0.02)
    np.testing.assert_allclose(rec.k[:, 0], gumbel_k(np.maximum(rec.n[:, 0], 2.0)), rtol=1e-15)
    # sigma over 60 periods: a spread of several per cent (one standard deviation) about the true value
    s = rec.sigma[ok, 0] / sea["sigma"]
    assert abs(s.mean() - 1) < 0.02 and 0.03 < s.std() < 0.15


def test_a_sinusoid_gives_the_closed_form_at_every_ready_instant():
    t = np.round(np.arange(12001) * 0.1, 9)
    T0, a = 3e6, 4e5
    x = T0 + a * np.cos(2 * np.pi * t / 10.0)
    rec = causal_reliability(t, x, [10e6], [0.5e6])
    ok = rec.ready
    np.testing.assert_allclose(rec.x_lf[ok, 0], T0, rtol=1e-12)
    np.testing.assert_allclose(rec.sigma[ok, 0], a / math.sqrt(2), rtol=1e-9)
    np.testing.assert_allclose(rec.n[ok, 0], 60, rtol=1e-9)  # 60 periods in 600 s, exposure = window
    np.testing.assert_allclose(rec.delta[ok, 0], (10e6 - T0 - k_hand(60) * a / math.sqrt(2)) / 0.5e6, rtol=1e-9)


# -- streaming, batch, causality ---------------------------------------------------------------

def irregular_record(seed=3, T_end=1500.0, m=3):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.2, 0.8, int(T_end / 0.5)))
    X = np.column_stack([1e6 * (j + 1) + narrow_band(t, 1e5 * (j + 1), seed=seed + j)[0] for j in range(m)])
    return t, X


def test_streaming_equals_batch_exactly():
    t, X = irregular_record()
    r_t, s_t = [5e6, 6e6, 7e6], [4e5, 5e5, 6e5]
    rec = causal_reliability(t, X, r_t, s_t, names=["a", "b", "c"], lp_window=80.0, sigma_window=300.0)
    mon = ReliabilityMonitor(r_t, s_t, names=["a", "b", "c"], lp_window=80.0, sigma_window=300.0)
    for i in range(len(t)):
        st = mon.update(t[i], X[i])
        assert st.t == t[i] and st.ready == rec.ready[i] and st.span == rec.span[i]
        for f in ("x_lf", "sigma", "n", "k", "delta"):
            assert np.array_equal(getattr(st, f), getattr(rec, f)[i]), (f, i)
    assert st.names == rec.names == ("a", "b", "c")
    assert st.delta_min == st.delta.min() and st.worst == rec.names[int(np.argmin(st.delta))]
    np.testing.assert_array_equal(rec["b"], rec.delta[:, 1])
    # reset starts a new record: the same numbers again
    mon.reset()
    again = [mon.update(t[i], X[i]).delta for i in range(200)]
    np.testing.assert_array_equal(np.array(again), rec.delta[:200])


def test_changing_the_future_does_not_change_the_past():
    t, X = irregular_record(seed=5)
    i0 = len(t) // 2
    Y = X.copy()
    Y[i0 + 1:] += 3e5 * np.sin(t[i0 + 1:, None] / 7.0) + 1e6
    a = causal_reliability(t, X, [5e6] * 3, [5e5] * 3)
    b = causal_reliability(t, Y, [5e6] * 3, [5e5] * 3)
    for f in ("x_lf", "sigma", "n", "k", "delta", "span", "ready"):
        np.testing.assert_array_equal(getattr(a, f)[:i0 + 1], getattr(b, f)[:i0 + 1])
    assert not np.array_equal(a.delta[i0 + 1:], b.delta[i0 + 1:])


def test_window_sums_equal_a_direct_recomputation_over_the_window():
    """At any instant sigma and the up-crossing count are those of the centred residuals (the
    offline low-pass of the record) whose times lie in the trailing sigma window ending at the
    newest computable residual: the running sums neither drift nor miss a sample."""
    t, X = irregular_record(seed=11, T_end=4000.0, m=2)
    lp, S = 60.0, 150.0  # short windows: many buffer compactions over the record
    rec = causal_reliability(t, X, [5e6, 5e6], [5e5, 5e5], lp_window=lp, sigma_window=S)
    rng = np.random.default_rng(0)
    for i in sorted(rng.choice(np.flatnonzero(rec.ready), 40, replace=False)):
        for j in range(2):
            mask, lf = low_pass(t[: i + 1], X[: i + 1, j], lp)
            tw, w = t[: i + 1][mask], X[: i + 1, j][mask] - lf
            keep = tw >= tw[-1] - S - 1e-9 * tw[-1]
            tw, w = tw[keep], w[keep]
            span = tw[-1] - tw[0]
            mean = np.trapezoid(w, tw) / span
            sig = math.sqrt(np.trapezoid(w**2, tw) / span - mean**2)
            assert rec.sigma[i, j] == pytest.approx(sig, rel=1e-8)
            assert rec.span[i] == pytest.approx(span, rel=1e-12)
            count = int(np.sum((w[:-1] < 0) & (w[1:] >= 0)))
            assert rec.n[i, j] * rec.span[i] / S == pytest.approx(count, abs=1e-9)


def test_work_per_update_does_not_grow_with_the_windows():
    t = np.arange(0.0, 12000.0, 1.0)
    x = np.column_stack([1e6 + 1e5 * np.sin(2 * np.pi * t / 10.3), 2e6 + 1e5 * np.cos(2 * np.pi * t / 9.1)])
    ratios = {}
    for lp, S in ((20.0, 60.0), (100.0, 600.0), (1000.0, 6000.0)):
        mon = ReliabilityMonitor([5e6, 5e6], [5e5, 5e5], lp_window=lp, sigma_window=S)
        held = []
        for ti, xi in zip(t, x):
            mon.update(ti, xi)
            held.append((mon.held_samples, mon.held_wf_samples))
        held = np.array(held)
        # the buffers hold the windows and no more
        assert held[:, 0].max() <= lp / 1.0 + 2 and held[:, 1].max() <= S / 1.0 + 1
        assert held[-1, 1] == S + 1
        ratios[S] = mon.inner_steps / mon.updates
        assert mon.updates == len(t)
    # amortised: each sample is pushed, moved and dropped a bounded number of times
    assert max(ratios.values()) < 12
    assert ratios[6000.0] < ratios[60.0] + 1.0


# -- against the offline index -----------------------------------------------------------------

def test_agrees_with_the_offline_index_when_the_windows_coincide():
    t = np.arange(0.0, 7200.0 + 0.25, 0.5)
    wf, _ = narrow_band(t, 1.5e5, seed=21)
    x = 2.5e6 + 1e5 * np.sin(2 * np.pi * t / 900.0) + wf
    tr = reliability_index(t, x, 10e6, 0.5e6)
    # a sigma window holding the whole offline evaluated range, exposure = that range
    S = t[-1] - W
    rec = causal_reliability(t, x, [10e6], [0.5e6], sigma_window=S, exposure=S)
    assert rec.ready[-1] and not rec.ready[-2]
    assert rec.sigma[-1, 0] == pytest.approx(tr.sigma, rel=1e-9)
    assert abs(rec.n[-1, 0] - tr.n) <= 1  # level 0 here, the residual's mean offline
    # same kernel: the trailing average is the centred one W/2 later, at every instant
    lag = int(round(W / 2 / 0.5))
    j = np.flatnonzero(t >= W)
    np.testing.assert_allclose(rec.x_lf[j, 0], tr.T_LF[: len(j)], rtol=1e-12)
    assert tr.time[: len(j)] == pytest.approx(t[j] - lag * 0.5)
    assert rec.delta[-1, 0] == pytest.approx(tr.delta[-1], abs=abs(gumbel_k(tr.n + 1) - tr.k) * tr.sigma / 0.5e6 + 1e-9)


def test_default_index_tracks_the_offline_one_on_a_stationary_record():
    """Default windows on a 2 h stationary record: the causal index differs from the offline one by
    its k (10 min of maxima against the whole record's) and the 10-minute sampling of sigma; with
    the offline k the mean difference is within 0.1 k sigma / sigma_t."""
    t = np.arange(0.0, 7200.0 + 0.25, 0.5)
    wf, _ = narrow_band(t, 2e5, seed=4)
    x = 3e6 + wf
    tr = reliability_index(t, x, 10e6, 0.5e6)
    rec = causal_reliability(t, x, [10e6], [0.5e6])
    ok = rec.ready
    on = rec.delta[ok, 0]
    off = np.interp(t[ok] - W / 2, tr.time, tr.delta)  # the offline index at the trailing mean's instant
    k_sig = tr.k * tr.sigma / 0.5e6
    same_k = (10e6 - rec.x_lf[ok, 0] - tr.k * rec.sigma[ok, 0]) / 0.5e6
    assert abs(np.mean(same_k - off)) < 0.1 * k_sig
    # the causal k (n ~ 60) is below the offline one (n ~ 700): a less conservative index
    assert np.all(rec.k[ok, 0] < tr.k) and np.mean(on - off) > 0


def test_a_step_in_the_mean_is_followed_within_the_low_pass_window():
    t = np.arange(0.0, 1500.0, 0.5)
    ts, a, b = 800.0, 1e6, 3e6
    x = np.where(t < ts, a, b)
    rec = causal_reliability(t, x, [10e6], [1e6])
    lf = rec.x_lf[:, 0]
    np.testing.assert_allclose(lf[t < ts], a, rtol=1e-12)
    np.testing.assert_allclose(lf[t >= ts + W], b, rtol=1e-12)
    mid = (t > ts) & (t < ts + W)
    assert np.all(np.diff(lf[mid]) > 0) and np.all((lf[mid] > a) & (lf[mid] < b))


def test_constant_signal_and_first_samples_are_nan_free():
    mon = ReliabilityMonitor([10.0], [2.0])
    st = mon.update(0.0, [4.0])
    assert (st.x_lf[0], st.sigma[0], st.n[0], st.span, st.ready) == (4.0, 0.0, 0.0, 0.0, False)
    assert st.k[0] == pytest.approx(k_hand(2)) and st.delta[0] == pytest.approx((10 - 4) / 2)
    for ti in np.arange(1.0, 800.0):
        st = mon.update(ti, 4.0)  # one signal: a scalar will do
    assert st.ready and st.sigma[0] == pytest.approx(0.0, abs=1e-12) and st.n[0] == 0.0
    assert st.delta[0] == pytest.approx((10 - 4 - 0.0) / 2)
    # partial window: mean of what there is, flagged
    mon.reset()
    for ti, xi in ((0.0, 1.0), (10.0, 3.0), (10.0, 3.0)):
        st = mon.update(ti, [xi])
    assert st.x_lf[0] == pytest.approx(2.0) and not st.ready and np.all(np.isfinite(st.delta))


def test_gumbel_k_is_one_definition():
    assert kpis.gumbel_k is gumbel_k and kpis.LP_WINDOW_DEFAULT == LP_WINDOW_DEFAULT
    assert gumbel_k(1000) == pytest.approx(k_hand(1000), rel=1e-14)
    np.testing.assert_allclose(gumbel_k(np.array([2.0, 60.0])), [k_hand(2), k_hand(60)], rtol=1e-14)
    with pytest.raises(ReliabilityError, match="more than one maximum"):
        gumbel_k(np.array([3.0, 1.0]))


@pytest.mark.parametrize("kwargs, match", [
    (dict(sigma_t=[1.0, 0.0]), r"sigma_t\[1\] \('b'\) = 0.0 must be a positive"),
    (dict(sigma_t=[1.0, -2.0]), r"sigma_t\[1\]"),
    (dict(sigma_t=[1.0]), "sigma_t has shape"),
    (dict(r_t=[1.0, math.inf]), r"r_t\[1\] \('b'\) = inf must be finite"),
    (dict(lp_window=0.0), "lp_window = 0.0 s must be a positive"),
    (dict(sigma_window=-5.0), "sigma_window = -5.0 s must be a positive"),
    (dict(sigma_window=math.nan), "sigma_window = nan"),
    (dict(exposure=0), "exposure = 0 s must be a positive"),
    (dict(names=["a"]), "names has 1 entries for 2 signals"),
    (dict(names=["a", "a"]), "names must be unique"),
])
def test_bad_settings_are_named(kwargs, match):
    args = dict(r_t=[1.0, 2.0], sigma_t=[1.0, 1.0], names=["a", "b"]) | kwargs
    with pytest.raises(ReliabilityError, match=match):
        ReliabilityMonitor(args.pop("r_t"), args.pop("sigma_t"), **args)


def test_bad_samples_are_named():
    mon = ReliabilityMonitor([1.0, 2.0], [1.0, 1.0], names=["a", "b"])
    mon.update(5.0, [0.0, 0.0])
    with pytest.raises(ReliabilityError, match=r"x\[1\] \('b'\) = nan at t = 6 s is not finite"):
        mon.update(6.0, [0.0, math.nan])
    with pytest.raises(ReliabilityError, match=r"x has shape \(3,\) at t = 6 s; expected \(2,\)"):
        mon.update(6.0, [0.0, 0.0, 0.0])
    with pytest.raises(ReliabilityError, match="t = 4.0 s goes back before the previous sample at 5.0 s"):
        mon.update(4.0, [0.0, 0.0])
    with pytest.raises(ReliabilityError, match="t = inf s must be finite"):
        mon.update(math.inf, [0.0, 0.0])
    assert mon.updates == 1  # rejected samples change nothing
    with pytest.raises(ReliabilityError, match=r"expected \(N,\) and \(N, 2\)"):
        causal_reliability([0.0, 1.0], np.zeros((3, 2)), [1.0, 2.0], [1.0, 1.0])
    with pytest.raises(ReliabilityError, match="goes back"):
        causal_reliability([0.0, 2.0, 1.0], np.zeros((3, 2)), [1.0, 2.0], [1.0, 1.0])
    with pytest.raises(ReliabilityError, match="no signal 'z'"):
        causal_reliability([0.0, 1.0], np.zeros((2, 2)), [1.0, 2.0], [1.0, 1.0], names=["a", "b"])["z"]


# -- KPIs ----------------------------------------------------------------------------------------

FPSO = tapm_opt.load_scenario("fpso")  # 12 lines (MBS 16.99 MN, MBS_std 0.85 MN), 6 thrusters, a riser
MBS, MBS_STD = 16.99e6, 0.85e6


def fpso_result(t, *, T=None, riser=None, events=()):
    n = len(t)
    cols = {"x": np.zeros(n), "y": np.zeros(n), "psi": np.zeros(n), "psi_d": np.zeros(n)}
    for ln in FPSO.lines:
        cols[f"T_fairlead[{ln.id}]"] = np.broadcast_to(T.get(ln.id, T["*"]) if T else np.full(n, 3e6), (n,))
    for th in FPSO.thrusters:
        cols[f"P[{th.id}]"] = np.zeros(n)
    for name, v in (riser or {}).items():
        cols[name] = v
    units = tuple("N" if k.startswith("T_") else "W" if k.startswith("P[") else "rad" if k.startswith("riser")
                  else "-" for k in cols)
    return Result(time=t, data=np.column_stack(list(cols.values())), channels=tuple(cols), units=units,
                  meta={"events": [list(e) for e in events]})


def test_fpso_riser_critical_angles_are_as_assumed():
    rs = FPSO.riser
    assert (math.degrees(rs.critical_top_angle), math.degrees(rs.critical_top_angle_std)) == pytest.approx((8.0, 1.0))
    assert (math.degrees(rs.critical_bottom_angle),
            math.degrees(rs.critical_bottom_angle_std)) == pytest.approx((5.0, 0.5))
    assert FPSO.line_arrays["MBS"][0] == MBS and FPSO.line_arrays["MBS_std"][0] == MBS_STD


def test_causal_offline_and_riser_kpis_by_hand():
    t = np.round(np.arange(10001) * 0.1, 9)  # 1000 s
    c = np.cos(2 * np.pi * t / 10.0)
    T0, a = 3e6, 2e5
    top = np.radians(2.0 + 0.5 * c)
    ramp = 0.003  # deg/s
    bottom = np.radians(1.0 + ramp * t + 0.3 * c)
    res = fpso_result(t, T={"*": T0 + a * c}, riser={"riser_top_angle": top, "riser_bottom_angle": bottom})
    kp = case_kpis(res, FPSO)
    # lines: causal over 700..1000 s (60 periods in the 600 s window), offline over 50..950 s (90)
    d_causal = (MBS - T0 - k_hand(60) * a / math.sqrt(2)) / MBS_STD
    d_off = (MBS - T0 - k_hand(90) * a / math.sqrt(2)) / MBS_STD
    for ln in FPSO.lines:
        assert kp[f"delta_min[{ln.id}]"] == pytest.approx(d_causal, rel=1e-9)
        assert kp[f"delta_min_offline[{ln.id}]"] == pytest.approx(d_off, rel=1e-9)
        assert kp[f"delta_frac_below[{ln.id}]"] == 0.0
    assert kp["delta_min"] == pytest.approx(d_causal, rel=1e-9)
    assert kp["delta_min_offline"] == pytest.approx(d_off, rel=1e-9)
    # riser: maxima of the magnitudes; top delta (8 deg +- 1 deg) constant, bottom (5 +- 0.5 deg)
    # falls with the trailing mean 1 deg + ramp (t - 50 s)
    assert kp["riser_top_angle_max_deg"] == pytest.approx(2.5, rel=1e-12)
    assert kp["riser_bottom_angle_max_deg"] == pytest.approx(1.0 + ramp * 1000.0 + 0.3, rel=1e-12)
    kσ_top, kσ_bot = k_hand(60) * 0.5 / math.sqrt(2), k_hand(60) * 0.3 / math.sqrt(2)
    d_top = (8.0 - 2.0 - kσ_top) / 1.0
    d_bot_end = (5.0 - 1.0 - ramp * 950.0 - kσ_bot) / 0.5
    assert kp["riser_delta_top_min"] == pytest.approx(d_top, rel=1e-9)
    assert kp["riser_delta_bottom_min"] == pytest.approx(d_bot_end, rel=1e-9)
    assert kp["riser_delta_min"] == pytest.approx(min(d_top, d_bot_end), rel=1e-9)
    t_star = (5.0 - 1.0 - kσ_bot - 2.0 * 0.5) / ramp + 50.0  # bottom delta reaches delta_s = 2
    assert 700 < t_star < 1000
    assert kp["riser_delta_frac_below"] == pytest.approx((1000.0 - t_star) / 300.0, abs=0.2 / 300)
    for name in ("delta_min_offline", "riser_delta_min", "delta_min_offline[3]"):
        assert kpi_unit(name) == "-"
    assert kpi_unit("riser_top_angle_max_deg") == "deg"


def test_without_riser_or_its_channels_the_riser_kpis_are_absent():
    t = np.round(np.arange(2001) * 0.5, 9)
    ang = {"riser_top_angle": np.full(len(t), 0.02), "riser_bottom_angle": np.full(len(t), 0.01)}
    no_riser = dataclasses.replace(FPSO, riser=None)
    kp = case_kpis(fpso_result(t, riser=ang), no_riser)
    assert kp["riser_top_angle_max_deg"] == pytest.approx(math.degrees(0.02))
    assert not any(k.startswith("riser_delta") for k in kp)
    kp_old = case_kpis(fpso_result(t), FPSO)  # a result from before the riser channels
    assert not any(k.startswith("riser") for k in kp_old)
    full = case_kpis(fpso_result(t, riser=ang), FPSO)
    assert full["riser_delta_top_min"] == pytest.approx((8.0 - math.degrees(0.02)) / 1.0, rel=1e-9)
    csv_text, md = kpi_table([{"id": "a", "kpis": full}, {"id": "b", "kpis": kp_old}])
    header = csv_text.splitlines()[0].split(",")
    assert "riser_delta_min" in header and "riser_top_angle_max_deg [deg]" in md
    assert csv_text.splitlines()[2].split(",")[header.index("riser_delta_min")] == ""


def test_kpi_order_places_the_new_names():
    names = ["riser_delta_min", "delta_min_offline[10]", "delta_min", "delta_min_offline", "riser_top_angle_max_deg",
             "delta_min_offline[2]", "delta_frac_below[2]", "thrust_energy", "dnv_uls[2]", "lines_broken"]
    assert kpi_order(names) == ["delta_min", "delta_min_offline", "lines_broken", "riser_top_angle_max_deg",
                                "riser_delta_min", "thrust_energy", "delta_frac_below[2]", "delta_min_offline[2]",
                                "delta_min_offline[10]", "dnv_uls[2]"]


def test_causal_kpis_restart_after_a_break_and_stop_at_the_broken_line():
    t = np.round(np.arange(10001) * 0.2, 9)  # 2000 s, line 1 breaks at 800 s
    tb = 800.0
    c = np.cos(2 * np.pi * t / 10.0)
    before, after = 2e6 + 1e6 * c, 6e6 + 0.5e6 * c
    T = {"*": np.where(t <= tb, before, after), "1": np.where(t <= tb, before, 0.0)}
    kp = case_kpis(fpso_result(t, T=T, events=[(tb, "line 1 broke")]), FPSO)
    d_intact = (MBS - 2e6 - k_hand(60) * 1e6 / math.sqrt(2)) / MBS_STD     # ready 700..800 s
    d_damaged = (MBS - 6e6 - k_hand(60) * 0.5e6 / math.sqrt(2)) / MBS_STD  # ready from 1500.2 s
    assert kp["delta_min[1]"] == pytest.approx(d_intact, rel=1e-9)  # its zeros after the break do not count
    for lid in ("2", "12"):
        assert kp[f"delta_min[{lid}]"] == pytest.approx(min(d_intact, d_damaged), rel=1e-9)
    assert kp["delta_min"] == pytest.approx(d_damaged, rel=1e-9)
    # t_start = 300 s: the intact part (500 s) never fills the windows; line 1 keeps its offline index
    kp2 = case_kpis(fpso_result(t, T=T, events=[(tb, "line 1 broke")]), FPSO, t_start=300.0)
    assert "delta_min[1]" not in kp2 and "delta_min_offline[1]" in kp2
    assert kp2["delta_min[2]"] == pytest.approx(d_damaged, rel=1e-9)
    # windows are options
    kp3 = case_kpis(fpso_result(t, T=T, events=[(tb, "line 1 broke")]), FPSO, sigma_window=300.0)
    assert kp3["delta_min[1]"] == pytest.approx((MBS - 2e6 - k_hand(30) * 1e6 / math.sqrt(2)) / MBS_STD, rel=1e-9)
    with pytest.raises(kpis.KpiError, match="sigma_window = 0.0 s must be a positive number"):
        case_kpis(fpso_result(t), FPSO, sigma_window=0.0)


def test_a_non_finite_riser_angle_is_named():
    t = np.round(np.arange(101) * 1.0, 9)
    ang = {"riser_top_angle": np.where(t > 50, np.nan, 0.01), "riser_bottom_angle": np.full(len(t), 0.01)}
    with pytest.raises(kpis.KpiError, match=r"'riser_top_angle' is not finite at t = 51"):
        case_kpis(fpso_result(t, riser=ang), FPSO)
