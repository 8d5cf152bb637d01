"""KPIs of a case on synthetic results with answers computed by hand (tapm_opt.studies.kpis)."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import re

import numpy as np
import pytest

import tapm_opt
from tapm_opt.estimation.reliability import ReliabilityError
from tapm_opt.results import Result
from tapm_opt.studies.kpis import (KpiError, basic_kpis, case_kpis, gumbel_k, kpi_order, kpi_table, kpi_unit,
                                   low_pass, reliability_index)

BASE = tapm_opt.load_scenario("aamo4")  # lines 1..4, thrusters A1 A2 F1 T1 T2, safe 50 m, alert 80 m
LINES = [ln.id for ln in BASE.lines]
THRUSTERS = [th.id for th in BASE.thrusters]
EULER = 0.5772156649015329


def scenario(MBS=10e6, MBS_std=0.5e6, **limits):
    sc = dataclasses.replace(BASE, line_types=tuple(dataclasses.replace(lt, MBS=MBS, MBS_std=MBS_std)
                                                    for lt in BASE.line_types))
    if limits:
        sc = dataclasses.replace(sc, limits=dataclasses.replace(sc.limits, **limits))
    return sc


def grid(T_end=1000.0, dt=0.1):
    return np.round(np.arange(int(round(T_end / dt)) + 1) * dt, 9)


def make_result(t, *, T=None, x=None, y=None, psi=None, psi_d=None, P=None, events=(), diagnostics=None,
                drop=()):
    n = len(t)
    z = np.zeros(n)
    T = T or {}
    P = P or {}
    cols = {"x": z if x is None else x, "y": z if y is None else y, "psi": z if psi is None else psi,
            "psi_d": z if psi_d is None else psi_d}
    for lid in LINES:
        cols[f"T_fairlead[{lid}]"] = T.get(lid, np.full(n, 1e6))
    for tid in THRUSTERS:
        cols[f"P[{tid}]"] = P.get(tid, z)
    cols = {k: np.broadcast_to(np.asarray(v, float), (n,)) for k, v in cols.items() if k not in drop}
    units = tuple("N" if k.startswith("T_") else "W" if k.startswith("P[") else "-" for k in cols)
    meta = {"events": [list(e) for e in events]}
    if diagnostics is not None:
        meta["diagnostics"] = diagnostics
    return Result(time=t, data=np.column_stack(list(cols.values())), channels=tuple(cols), units=units, meta=meta)


# -- reliability index -------------------------------------------------------------------------

def test_gumbel_k_by_hand():
    s = math.sqrt(2 * math.log(1000))  # 3.716922
    assert gumbel_k(1000) == pytest.approx(s + EULER / s, rel=1e-12)
    assert gumbel_k(1000) == pytest.approx(3.87221, abs=1e-5)
    with pytest.raises(ReliabilityError, match="more than one maximum"):
        gumbel_k(1)


def test_reliability_index_of_a_sinusoid_equals_the_hand_value():
    t = grid(1000.0, 0.1)
    T0, a, MBS, sb = 3e6, 4e5, 10e6, 0.5e6
    T = T0 + a * np.sin(2 * np.pi * t / 10.0 + 0.3)
    tr = reliability_index(t, T, MBS, sb, window=100.0)
    # evaluated where the 100 s window fits: 50..950 s = 90 periods -> 90 up-crossings
    assert tr.time[0] == pytest.approx(50.0) and tr.time[-1] == pytest.approx(950.0)
    assert tr.n == 90
    assert tr.sigma == pytest.approx(a / math.sqrt(2), rel=1e-9)
    np.testing.assert_allclose(tr.T_LF, T0, rtol=1e-9)
    s = math.sqrt(2 * math.log(90))
    k = s + EULER / s
    delta = (MBS - k * a / math.sqrt(2) - T0) / sb
    assert tr.k == pytest.approx(k, rel=1e-12)
    np.testing.assert_allclose(tr.delta, delta, rtol=1e-9)
    # the same through case_kpis (delta_min_offline); the causal delta_min is evaluated from
    # 700 s (100 s low-pass + 600 s sigma window): 60 up-crossings in the 600 s window, exposure 600 s
    kp = case_kpis(make_result(t, T={lid: T for lid in LINES}), scenario(MBS, sb))
    s60 = math.sqrt(2 * math.log(60))
    delta_causal = (MBS - (s60 + EULER / s60) * a / math.sqrt(2) - T0) / sb
    for lid in LINES:
        assert kp[f"delta_min_offline[{lid}]"] == pytest.approx(delta, rel=1e-9)
        assert kp[f"delta_min[{lid}]"] == pytest.approx(delta_causal, rel=1e-9)
        assert kp[f"delta_frac_below[{lid}]"] == 0.0
    assert kp["delta_min_offline"] == pytest.approx(delta, rel=1e-9)
    assert kp["delta_min"] == pytest.approx(delta_causal, rel=1e-9)


def test_reliability_index_follows_the_low_frequency_tension():
    t = grid(1000.0, 0.1)
    T0, b, a, MBS, sb = 2e6, 8e3, 3e5, 10e6, 0.5e6
    T = T0 + b * t + a * np.sin(2 * np.pi * t / 10.0 + 0.3)
    tr = reliability_index(t, T, MBS, sb)
    np.testing.assert_allclose(tr.T_LF, T0 + b * tr.time, rtol=1e-9)  # a centred average keeps a ramp
    s = math.sqrt(2 * math.log(90))
    kσ = (s + EULER / s) * a / math.sqrt(2)
    assert tr.delta.min() == pytest.approx((MBS - kσ - T0 - b * 950.0) / sb, rel=1e-9)
    kp = case_kpis(make_result(t, T={lid: T for lid in LINES}), scenario(MBS, sb))
    assert kp["delta_min_offline[1]"] == pytest.approx(tr.delta.min(), rel=1e-12)
    # causal: the trailing average reads the ramp 50 s late, T_LF(t) = T0 + b (t - 50); the centred
    # residual is the sine alone (sigma = a/sqrt 2, 60 up-crossings in 600 s); evaluated 700..1000 s
    s60 = math.sqrt(2 * math.log(60))
    kσ60 = (s60 + EULER / s60) * a / math.sqrt(2)
    assert kp["delta_min[1]"] == pytest.approx((MBS - kσ60 - T0 - b * 950.0) / sb, rel=1e-9)
    # delta < 2 after t* (hand): fraction of the evaluated 300 s
    t_star = (MBS - kσ60 - T0 - 2.0 * sb) / b + 50.0
    assert 710 < t_star < 990
    assert kp["delta_frac_below[1]"] == pytest.approx((1000.0 - t_star) / 300.0, abs=0.2 / 300)
    assert kp["delta_frac_below"] == kp["delta_frac_below[4]"]


def test_low_pass_of_a_short_record_is_its_mean():
    t = grid(50.0, 1.0)
    mask, lf = low_pass(t, 5.0 + t, window=100.0)
    assert mask.all() and np.allclose(lf, 30.0)


def test_lines_without_breaking_strength_scatter_have_no_delta():
    t = grid(200.0, 1.0)
    kp = case_kpis(make_result(t), scenario(10e6, 0.0))
    assert not any(k.startswith("delta") for k in kp)


# -- offsets and heading -----------------------------------------------------------------------

def test_constant_offset_has_zero_std_and_max_equals_mean():
    t = grid(300.0, 0.5)
    kp = case_kpis(make_result(t, x=np.full(len(t), 30.0), y=np.full(len(t), -40.0)), scenario())
    assert kp["offset_max"] == pytest.approx(50.0) and kp["offset_mean"] == pytest.approx(50.0)
    assert kp["offset_std"] == pytest.approx(0.0, abs=1e-9)
    assert kp["time_outside_safe"] == 0.0  # 50 m is on the safe circle, not outside


def test_time_outside_the_circles_of_a_piecewise_offset():
    t = grid(500.0, 1.0)
    x = np.where(t < 100, 20.0, np.where(t < 300, 60.0, 90.0))
    kp = case_kpis(make_result(t, x=x), scenario())  # safe 50 m, alert 80 m
    assert kp["time_outside_safe"] == pytest.approx(400.0)
    assert kp["time_outside_alert"] == pytest.approx(200.0)
    kp0 = case_kpis(make_result(t, x=x), scenario(safe_radius=None, alert_radius=None))
    assert kp0["time_outside_safe"] == 0.0 and kp0["time_outside_alert"] == 0.0
    # t_start leaves the first 150 s out of every statistic
    kp1 = case_kpis(make_result(t, x=x), scenario(), t_start=150.0)
    assert kp1["duration"] == pytest.approx(350.0)
    assert kp1["time_outside_safe"] == pytest.approx(350.0)
    assert kp1["offset_mean"] == pytest.approx((150 * 60 + 200 * 90) / 350, rel=1e-3)


def test_heading_error_wraps():
    t = grid(10.0, 1.0)
    kp = case_kpis(make_result(t, psi=np.full(len(t), math.radians(359.0)), psi_d=np.full(len(t), math.radians(1.0))),
                   scenario())
    assert kp["heading_error_max"] == pytest.approx(2.0, abs=1e-9)
    kp = case_kpis(make_result(t, psi=np.full(len(t), math.radians(1.0)), psi_d=np.full(len(t), math.radians(359.0))),
                   scenario())
    assert kp["heading_error_max"] == pytest.approx(2.0, abs=1e-9)


# -- tensions and DNV-OS-E301 ------------------------------------------------------------------

def test_dnv_uls_check_by_hand():
    t = grid(1000.0, 0.1)
    T = 2e6 + 1e6 * np.sin(2 * np.pi * t / 10.0)  # mean 2 MN, max 3 MN
    res = make_result(t, T={lid: T for lid in LINES})
    # by default the class-1 common factor applies: mean 2 MN > 2/3 of the dynamic 1 MN -> 1.3 (2 + 1)
    assert case_kpis(res, scenario(MBS=10e6))["dnv_uls[1]"] == pytest.approx(1.3 * 3 / 9.5, rel=1e-9)
    kp = case_kpis(res, scenario(MBS=10e6), dnv_class1_common_factor=False)
    ratio = (1.1 * 2e6 + 1.5 * 1e6) / (0.95 * 10e6)  # 3.7 / 9.5
    assert ratio == pytest.approx(0.3895, abs=1e-4)
    for lid in LINES:
        assert kp[f"dnv_uls[{lid}]"] == pytest.approx(ratio, rel=1e-9)
        assert kp[f"T_max[{lid}]"] == pytest.approx(3e6, rel=1e-12)
        assert kp[f"T_mean[{lid}]"] == pytest.approx(2e6, rel=1e-9)
        assert kp[f"util_max[{lid}]"] == pytest.approx(0.3, rel=1e-12)
    assert kp["dnv_uls_max"] == pytest.approx(ratio, rel=1e-9)
    assert (kp["dnv_uls_pass"], kp["dnv_uls_fail"]) == (4, 0)
    assert "dnv_als_max" not in kp and (kp["dnv_als_pass"], kp["dnv_als_fail"]) == (0, 0)
    assert kp["T_max"] == pytest.approx(3e6) and kp["util_max"] == pytest.approx(0.3)
    # consequence class 2, and the class-1 common factor 1.3 (mean 2 > 2/3 of dyn 1)
    assert case_kpis(res, scenario(MBS=10e6), consequence_class=2)["dnv_uls[1]"] == pytest.approx(
        (1.4 * 2 + 2.1 * 1) / 9.5, rel=1e-9)
    assert case_kpis(res, scenario(MBS=10e6), dnv_class1_common_factor=True)["dnv_uls[1]"] == pytest.approx(
        1.3 * 3 / 9.5, rel=1e-9)
    # a weak line fails
    kp_weak = case_kpis(res, scenario(MBS=3.5e6), dnv_class1_common_factor=False)
    assert kp_weak["dnv_uls_max"] == pytest.approx(3.7 / (0.95 * 3.5), rel=1e-9) and kp_weak["dnv_uls_fail"] == 4


def test_dnv_als_after_a_line_break_excludes_the_broken_line():
    t = grid(1000.0, 0.1)
    tb = 500.0
    intact = 2e6 + 1e6 * np.sin(2 * np.pi * t / 10.0)            # [0, 500]: mean 2, max 3 MN
    P = (1000.0 - 500.1) / 10                                     # 10 periods in (500, 1000]
    after = 6e6 + 0.5e6 * np.cos(2 * np.pi * (t - 500.1) / P)     # (500, 1000]: mean 6, max 6.5 MN
    T = {lid: np.where(t <= tb, intact, after) for lid in LINES}
    T["1"] = np.where(t <= tb, intact, 0.0)                       # line 1 slack after its break
    res = make_result(t, T=T, events=[(tb, "line 1 broke"), (700.0, "thruster F1 failed")])
    kp = case_kpis(res, scenario(MBS=10e6), dnv_class1_common_factor=False)
    uls = 3.7 / 9.5
    als = (1.0 * 6e6 + 1.1 * 0.5e6) / 9.5e6
    for lid in LINES:
        assert kp[f"dnv_uls[{lid}]"] == pytest.approx(uls, rel=1e-9)
    assert "dnv_als[1]" not in kp
    for lid in ("2", "3", "4"):
        assert kp[f"dnv_als[{lid}]"] == pytest.approx(als, rel=1e-9)
    assert (kp["dnv_uls_pass"], kp["dnv_als_pass"], kp["dnv_als_fail"]) == (4, 3, 0)
    assert kp["dnv_als_max"] == pytest.approx(als, rel=1e-9)
    assert kp["lines_broken"] == 1
    # the broken line's statistics stop at its break (no zeros averaged in)
    assert kp["T_mean[1]"] == pytest.approx(2e6, rel=1e-9) and kp["T_max[1]"] == pytest.approx(3e6)
    assert kp["T_max[2]"] == pytest.approx(6.5e6)
    # reliability index per segment: line 1 only before its break (50..450 s: 40 periods);
    # line 2 is worst after the break (T_LF = 6 MN, sigma = 0.5 MN/sqrt 2, 8 periods of 49.99 s in 550..950 s)
    def k(n):
        s = math.sqrt(2 * math.log(n))
        return s + EULER / s
    assert kp["delta_min_offline[1]"] == pytest.approx((10e6 - k(40) * 1e6 / math.sqrt(2) - 2e6) / 0.5e6, rel=1e-9)
    lo, hi = ((10e6 - k(n) * 0.5e6 / math.sqrt(2) - 6e6) / 0.5e6 for n in (9, 7))
    assert lo - 1e-3 <= kp["delta_min_offline[2]"] <= hi + 1e-3
    assert kp["delta_min_offline"] == kp["delta_min_offline[2]"]
    # the causal index needs 700 s of a segment (low-pass + sigma window): neither the 500 s intact
    # part nor the 500 s damaged part fills it, so there is none
    assert not any(k.startswith(("delta_min[", "delta_frac_below")) for k in kp) and "delta_min" not in kp
    # a break before t_start: the broken line has no per-line KPIs, the rest is ALS only
    kp2 = case_kpis(res, scenario(MBS=10e6), t_start=600.0)
    assert not any(k.endswith("[1]") for k in kp2)
    assert "dnv_uls_max" not in kp2 and kp2["dnv_als_pass"] == 3
    json.dumps(kp, allow_nan=False)


def test_an_overload_break_counts_and_its_tension_enters_the_maxima():
    """A line breaks at 101 % of its MBS between two 1 s samples: the samples peak at 99.8 %, the
    plant's event carries the 101 %; the overload event splits the record like a prescribed break."""
    t = grid(100.0, 1.0)
    tb = 50.4
    T = {lid: np.full(len(t), 4e6) for lid in LINES}
    T["2"] = np.where(t <= 50.0, 4e6 + 5.98e6 * (t / 50.0) ** 4, 0.0)  # 9.98 MN at 50 s, broken at 51 s
    ev = (tb, "line 2 broke: overload, tension 10.1 MN = 101 % MBS >= strength 10 MN")
    res = make_result(t, T=T, events=[ev])
    kp = case_kpis(res, scenario(MBS=10e6, MBS_std=0.0), dnv_class1_common_factor=False)
    assert kp["lines_broken"] == 1
    assert kp["T_max[2]"] == pytest.approx(10.1e6) and kp["T_max"] == pytest.approx(10.1e6)
    assert kp["util_max[2]"] == pytest.approx(1.01) and kp["util_max"] == pytest.approx(1.01)
    assert kp["T_mean[2]"] < 9.98e6  # the mean is of the samples, up to the break
    # the broken line's ULS check sees the tension that broke it; the others have an ALS check
    mean2 = float(np.trapezoid(T["2"][:51], t[:51]) / 50.0)
    assert kp["dnv_uls[2]"] == pytest.approx((1.1 * mean2 + 1.5 * (10.1e6 - mean2)) / 9.5e6, rel=1e-9)
    assert "dnv_als[2]" not in kp and kp["dnv_als_pass"] == 3
    assert basic_kpis(res, scenario(MBS=10e6))["utilisation_max"] == pytest.approx(1.01)
    # without the tension in the event only the samples are known
    plain = make_result(t, T=T, events=[(tb, "line 2 broke")])
    assert case_kpis(plain, scenario(MBS=10e6))["util_max"] == pytest.approx(0.998)
    # in the plant's 'mbs' mode a line breaks at its MBS at least: the event's rounding cannot read lower
    low = make_result(t, T=T, events=[(tb, "line 2 broke: overload, tension 9.99 MN = 100 % MBS >= strength 10 MN")])
    assert case_kpis(low, scenario(MBS=10e6))["util_max"] == pytest.approx(1.0)
    low.meta["break_on_overload"] = "mbs"
    assert case_kpis(low, scenario(MBS=10.02e6))["util_max"] == pytest.approx(1.0)


def test_kpis_take_a_system_as_well_as_a_scenario():
    from tapm_opt.models.system import System

    t = grid(100.0, 0.5)
    res = make_result(t, x=10 + np.sin(t), T={"1": np.full(len(t), 2e6)}, drop=("psi_d",))
    sc = scenario()
    system = System.from_scenario(sc)
    assert basic_kpis(res, system) == basic_kpis(res, sc)
    full = make_result(t, x=10 + np.sin(t), T={"1": np.full(len(t), 2e6)}, events=[(60.0, "line 3 broke")])
    assert case_kpis(full, system) == case_kpis(full, sc)
    # a system of the damaged condition still carries the whole scenario: every line's KPIs
    damaged = system.with_broken(["3"])
    assert case_kpis(full, damaged) == case_kpis(full, sc)


def test_a_break_event_naming_an_unknown_line_is_an_error():
    t = grid(10.0, 1.0)
    with pytest.raises(KpiError, match=r"T_fairlead\[9\]"):
        case_kpis(make_result(t, events=[(5.0, "line 9 broke")]), scenario())


# -- energy, fuel and solver statistics --------------------------------------------------------

def test_energy_of_constant_power_and_fuel_proxy():
    t = grid(1000.0, 0.5)
    P0 = 5e6
    res = make_result(t, P={tid: np.full(len(t), P0 / len(THRUSTERS)) for tid in THRUSTERS})
    kp = case_kpis(res, scenario())
    assert kp["thrust_energy"] == pytest.approx(P0 * 1000.0, rel=1e-12)
    assert kp["thrust_power_mean"] == pytest.approx(P0, rel=1e-12)
    kwh = P0 * 1000.0 / 3.6e6
    assert kp["fuel"] == pytest.approx(0.2 * kwh, rel=1e-12)
    assert case_kpis(res, scenario(), sfc=0.18)["fuel"] == pytest.approx(0.18 * kwh, rel=1e-12)
    assert case_kpis(res, scenario(), t_start=200.0)["thrust_energy"] == pytest.approx(P0 * 800.0, rel=1e-12)


def test_solver_statistics_come_from_the_diagnostics():
    t = grid(10.0, 1.0)
    diag = {"solver_time_median": 0.01, "solver_time_p95": 0.02, "solver_time_max": 0.05, "solver_failures": 2,
            "solver_fallbacks": 1, "allocation_fallbacks": 3, "statuses": ["ok"]}
    kp = case_kpis(make_result(t, diagnostics=diag), scenario())
    assert kp["solver_time_p95"] == 0.02 and kp["solver_failures"] == 2 and kp["allocation_fallbacks"] == 3
    assert "statuses" not in kp
    assert "solver_time_median" not in case_kpis(make_result(t), scenario())


# -- tables ------------------------------------------------------------------------------------

def test_kpi_table_round_trips_and_has_one_markdown_row_per_case():
    t = grid(300.0, 0.5)
    rows = []
    for i, (xv, ctrl) in enumerate([(10.0, "PID"), (math.pi * 10, "MPC")]):
        res = make_result(t, x=np.full(len(t), xv), T={lid: 1.234567891e6 + 1e5 * np.sin(t / 3 + i) for lid in LINES},
                          P={"A1": np.full(len(t), 1.1e5)})
        rows.append({"id": f"abc{i}", "name": f"case {i}", "labels": {"scenario": "aamo4", "sea_state": "storm",
                     "controller": ctrl, "condition": "intact", "seed": i}, "kpis": case_kpis(res, scenario())})
    rows.append({"id": "failed", "name": "failed case", "labels": {"controller": "MPC"}, "kpis": {}})
    csv_text, md = kpi_table(rows)
    parsed = list(csv.DictReader(io.StringIO(csv_text)))
    header = next(csv.reader(io.StringIO(csv_text)))
    assert header[:7] == ["id", "name", "scenario", "sea_state", "controller", "condition", "seed"]
    assert header[7:] == kpi_order(rows[0]["kpis"])
    assert len(parsed) == 3
    for row, got in zip(rows, parsed):
        assert got["id"] == row["id"] and got["controller"] == row["labels"]["controller"]
        for k, v in row["kpis"].items():
            assert float(got[k]) == v  # full precision
    assert parsed[2]["offset_max"] == ""
    md_lines = [ln for ln in md.splitlines() if ln.startswith("|")]
    assert len(md_lines) == 2 + len(rows)
    assert "offset_max [m]" in md_lines[0] and "T_max[1] [N]" in md_lines[0]
    assert md_lines[3].startswith("| abc1 | case 1 | aamo4 | storm | MPC | intact | 1 |")
    assert "| 31.42 |" in md_lines[3]  # offset pi*10 m to 4 significant digits


def test_kpi_order_is_stable_and_natural():
    names = ["fuel", "T_max[10]", "zzz", "T_max[2]", "dnv_uls[2]", "offset_max", "T_mean[1]", "T_max"]
    assert kpi_order(names) == ["offset_max", "T_max", "fuel", "T_max[2]", "T_max[10]", "T_mean[1]",
                                "dnv_uls[2]", "zzz"]
    assert kpi_unit("T_max[7]") == "N" and kpi_unit("offset_max") == "m" and kpi_unit("fuel") == "kg"


# -- bad input and the legacy subset -----------------------------------------------------------

@pytest.mark.parametrize("channel", ["psi_d", "x", "T_fairlead[3]", "P[F1]"])
def test_missing_channel_is_named(channel):
    t = grid(10.0, 1.0)
    with pytest.raises(KpiError, match=re.escape(repr(channel))):
        case_kpis(make_result(t, drop=(channel,)), scenario())


def test_bad_options_and_non_finite_values():
    t = grid(10.0, 1.0)
    res = make_result(t)
    with pytest.raises(KpiError, match="t_start"):
        case_kpis(res, scenario(), t_start=10.0)
    with pytest.raises(KpiError, match="consequence_class"):
        case_kpis(res, scenario(), consequence_class=3)
    bad = make_result(t, T={"2": np.where(t > 5, np.nan, 1e6)})
    with pytest.raises(KpiError, match=r"T_fairlead\[2\].*not finite at t = 6"):
        case_kpis(bad, scenario())


def test_basic_kpis_is_the_legacy_subset():
    t = grid(100.0, 0.5)
    res = make_result(t, x=10 + np.sin(t), T={"1": np.full(len(t), 2e6)}, drop=("psi_d",),
                      psi=np.full(len(t), 0.1))
    b = basic_kpis(res, scenario())  # tolerates a result without psi_d (error against 0)
    assert set(b) == {"duration", "offset_max", "offset_mean", "offset_std", "time_outside_safe",
                      "time_outside_alert", "heading_error_max", "T_max", "utilisation_max", "thrust_energy"}
    assert b["utilisation_max"] == pytest.approx(0.2) and b["heading_error_max"] == pytest.approx(math.degrees(0.1))
    full = case_kpis(make_result(t, x=10 + np.sin(t), T={"1": np.full(len(t), 2e6)}), scenario())
    assert b["offset_max"] == full["offset_max"] and b["offset_std"] == full["offset_std"]



