"""The KPI catalogue (tapm_opt.studies.kpi_catalogue): every KPI a case writes is in it with a
unit and a direction, nothing else is, docs/kpis.md's tables agree with it, and the tension KPIs
see the tension of an overload break that falls between the logged samples."""

from __future__ import annotations

import ast
import dataclasses
import math
import pathlib
import re
import sys

import numpy as np
import pytest

import tapm_opt
from tapm_opt.errors import TapmError
from tapm_opt.results import Result
from tapm_opt.studies import kpi_catalogue as cat
from tapm_opt.studies.kpi_catalogue import DIRECTIONS, KINDS, KPIS, UnknownKpiError, kpi
from tapm_opt.studies.kpis import basic_kpis, case_kpis, kpi_order, kpi_unit

ROOT = pathlib.Path(__file__).resolve().parents[1]
FPSO = tapm_opt.load_scenario("fpso")   # 12 lines with winches, a riser, MBS_std > 0
UNITS = {"s", "m", "m/s", "deg", "N", "J", "W", "kg", "-", "lines"}


# -- the table itself --------------------------------------------------------------------------

def test_every_kpi_has_a_unit_a_direction_a_kind_and_a_one_line_meaning():
    assert len(KPIS) >= 50
    for name, e in KPIS.items():
        assert e.name == name
        assert e.unit in UNITS, (name, e.unit)
        assert e.direction in DIRECTIONS and e.direction in ("minimise", "maximise", "none"), name
        assert e.kind in KINDS, name
        assert e.meaning and "\n" not in e.meaning and len(e.meaning) < 200, name
    assert cat.directions() == {n: e.direction for n, e in KPIS.items()}
    assert cat.units() == {n: e.unit for n, e in KPIS.items()}
    with pytest.raises(TypeError):
        KPIS["offset_max"] = KPIS["duration"]           # read-only
    with pytest.raises(dataclasses.FrozenInstanceError):
        KPIS["offset_max"].unit = "km"


def test_directions_of_the_kpis_without_an_obvious_one():
    want = {"delta_min": "maximise", "delta_min_offline": "maximise", "riser_delta_min": "maximise",
            "detection_delay": "minimise", "false_alarms": "minimise", "break_isolated": "maximise",
            "winch_energy": "minimise", "lines_broken": "minimise", "dnv_uls_pass": "maximise",
            "dnv_als_fail": "minimise", "mode_switches": "none", "break_detected_at": "none",
            "break_isolated_line": "none", "thrust_to_command_ratio": "none", "duration": "none",
            "delta_frac_below": "minimise", "util_max": "minimise", "utilisation_max": "minimise"}
    assert {n: kpi(n).direction for n in want} == want
    assert kpi("break_isolated_line").kind == "text" and kpi("false_alarms").kind == "count"


def test_per_line_kpis_are_pattern_entries():
    e = kpi("T_max[3]")
    assert e is kpi("T_max[<id>]") is KPIS["T_max[<id>]"]
    assert (e.per, e.base, e.unit, e.direction) == ("line", "T_max", "N", "minimise")
    assert e.matches("T_max[SW-2]") and not e.matches("T_max") and not e.matches("T_mean[3]")
    assert e.pattern.match("T_max[12]").group("id") == "12" and e.name_for("7") == "T_max[7]"
    assert kpi("T_max").per == "" and kpi("T_max").pattern is None
    assert kpi("delta_min[7]").direction == "maximise" and kpi("dnv_als[2]").unit == "-"
    assert [e.base for e in cat.per_line_kpis()] == ["T_max", "T_mean", "util_max", "delta_min", "delta_frac_below",
                                                      "delta_min_offline", "fatigue_damage", "dnv_uls", "dnv_als"]
    with pytest.raises(ValueError, match="not built per line"):
        kpi("T_max").name_for("3")


def test_an_unknown_name_is_a_typed_error_with_a_hint():
    with pytest.raises(UnknownKpiError) as info:
        kpi("utilization_max")
    err = info.value
    assert isinstance(err, TapmError) and isinstance(err, KeyError)
    assert err.name == "utilization_max" and "utilisation_max" in err.suggestions
    assert str(err).startswith("unknown KPI 'utilization_max'; did you mean 'utilisation_max'")
    with pytest.raises(UnknownKpiError, match=re.escape("did you mean 'T_max[3]'")):
        kpi("T_maxx[3]")
    with pytest.raises(UnknownKpiError, match="unknown KPI 'zzz'; the KPIs are listed"):
        kpi("zzz")
    with pytest.raises(KeyError):
        kpi("offset_min[")
    # the tolerant helpers of the tables: no unit and no direction for a column that is not a KPI
    assert cat.find_kpi("zzz") is None and not cat.is_kpi("zzz") and cat.is_kpi("dnv_uls[4]")
    assert kpi_unit("zzz") == "" and cat.kpi_sign("zzz") == 0
    assert cat.kpi_sign("offset_max") == -1 and cat.kpi_sign("delta_min[2]") == 1 and cat.kpi_sign("duration") == 0


def test_the_catalogue_module_imports_the_standard_library_only():
    tree = ast.parse((ROOT / "tapm_opt" / "studies" / "kpi_catalogue.py").read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            mods = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:   # the package's error base class, nothing else of the package
                assert (node.level, node.module) == (2, "errors"), ast.dump(node)
                continue
            mods = [node.module]
        else:
            continue
        for m in mods:
            assert m.split(".")[0] in sys.stdlib_module_names or m == "__future__", m


def test_column_order_is_the_catalogues():
    fixed = [n for n, e in KPIS.items() if not e.per]
    assert kpi_order(reversed(fixed)) == fixed
    assert kpi_order(["zzz", "T_mean[10]", "T_max[2]", "T_mean[2]", "utilisation_max", "T_max"]) == \
        ["T_max", "utilisation_max", "T_max[2]", "T_mean[2]", "T_mean[10]", "zzz"]


# -- the catalogue against what the cases write ------------------------------------------------

def _overload_case(mbs: float = 3.7e6, line: str = "4") -> tuple[Result, object]:
    """fpso_equivalent (fpso's homogeneous-line mooring, so one line type makes a weak line) in the
    storm with one line's MBS lowered so that it breaks from overload about 35 s in (PID, 60 s, 1 s
    logging, 6 segments: ~3 s)."""
    from tapm_opt.plant.simulator import Plant
    from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller

    base = tapm_opt.load_scenario("fpso_equivalent")
    weak = dataclasses.replace(base.line_types[0], id="weak", MBS=mbs)
    lines = tuple(dataclasses.replace(ln, type="weak") if ln.id == line else ln for ln in base.lines)
    sc = dataclasses.replace(base, line_types=base.line_types + (weak,), lines=lines,
                             plant=dataclasses.replace(base.plant, break_on_overload="mbs"))
    plant = Plant(sc, sea_state="storm", seed=1, segments=6)
    res = run_closed_loop(plant, build_controller(sc, {"type": "pid"}), ClosedLoopSettings(duration=60.0, dt_log=1.0))
    return res, sc


@pytest.fixture(scope="module")
def overload():
    return _overload_case()


def test_a_line_broken_by_overload_reads_at_least_its_mbs(overload):
    """The break's peak falls between the 1 s samples (the samples read below the MBS); the plant's
    event carries it and the tension KPIs take it."""
    res, sc = overload
    (t_b, text), = res.meta["events"]
    assert text.startswith("line 4 broke: overload") and 30.0 < t_b < 60.0
    mbs = 3.7e6
    T4 = res["T_fairlead[4]"]
    assert T4.max() < mbs and T4[res.time > t_b].max() == 0.0   # the samples miss the peak
    k = case_kpis(res, sc)
    assert k["util_max[4]"] >= 1.0 and k["util_max"] >= 1.0 and k["T_max[4]"] >= mbs and k["T_max"] >= mbs
    assert k["lines_broken"] == 1 and "dnv_als[4]" not in k and k["dnv_uls[4]"] > 1.0 and k["dnv_uls_fail"] >= 1
    assert basic_kpis(res, sc)["utilisation_max"] >= 1.0
    # the detector found the broken line after its break: no false alarm
    assert k["false_alarms"] == 0 and k["break_isolated_line"] == "4" and 0 < k["detection_delay"] < 20.0


def test_every_kpi_a_closed_loop_case_writes_is_in_the_catalogue(overload):
    res, sc = overload
    written = {**case_kpis(res, sc), **basic_kpis(res, sc)}
    assert {"detection_delay", "false_alarms", "winch_energy", "thrust_to_command_ratio", "dnv_als_max",
            "allocation_fallbacks"} <= set(written)
    missing = [n for n in written if not cat.is_kpi(n)]
    assert not missing, missing
    for n, v in written.items():
        e = kpi(n)
        if e.kind == "text":
            assert isinstance(v, str), n
        elif e.kind == "count":
            assert isinstance(v, (int, float)) and float(v).is_integer(), (n, v)
        else:
            assert isinstance(v, (int, float)) and math.isfinite(v), (n, v)


def _full_result() -> Result:
    """A synthetic fpso record with every channel and log a KPI reads: 2000 s, line 1 broken at
    800 s (both segments longer than the causal index's 700 s), riser angles, winch lengths, the DP
    command, the estimator's and the controller's logs and an MPC's diagnostics."""
    t = np.arange(2001.0)
    n = len(t)
    c = np.cos(2 * np.pi * t / 10.0)
    cols = {"x": 5 + np.sin(t / 50), "y": np.zeros(n), "psi": np.zeros(n), "psi_d": np.zeros(n)}
    for ln in FPSO.lines:
        T = 3e6 + 2e5 * c
        cols[f"T_fairlead[{ln.id}]"] = np.where(t <= 800.0, T, 0.0) if ln.id == "1" else T
        cols[f"L[{ln.id}]"] = 1000.0 - 0.01 * np.minimum(t, 100.0)
    for th in FPSO.thrusters:
        cols[f"P[{th.id}]"] = np.full(n, 1e5)
    cols.update({"riser_top_angle": np.radians(2 + 0.5 * c), "riser_bottom_angle": np.radians(1 + 0.3 * c),
                 "tau_cmd[X]": np.full(n, 1e6), "tau_cmd[Y]": np.zeros(n), "tau_thr[X]": np.full(n, 2e5),
                 "tau_thr[Y]": np.zeros(n), "roll": np.radians(1 + 0.5 * c), "pitch": np.radians(-0.3 * c),
                 "x_hat": 5 + np.sin(t / 50) + 0.5, "y_hat": np.zeros(n), "psi_hat": np.zeros(n)})
    meta = {"events": [[800.0, "line 1 broke"], [1200.0, "line 3 lost its buoy at joint 0"]],
            "estimator_log": [{"t": 300.0, "line": "5", "event": "line break detected"},
                              {"t": 808.0, "line": "1", "event": "line break detected"},
                              {"t": 1240.0, "line": "3", "joint": 0, "event": "buoy loss detected"},
                              {"t": 900.0, "event": "current estimate", "speed": 0.7, "direction": np.radians(170.0),
                               "seabed_factor": 0.2, "std": [0.01, 0.01, 0.01]},
                              {"t": 1530.0, "event": "sensor fault detected", "sensor": "gnss", "fault": "drift"}],
            "sea_state": "normal", "redundancy": "vote",
            "controller_log": [{"t": 810.0, "event": "mode switch"}],
            "diagnostics": {"solver_time_median": 0.01, "solver_time_p95": 0.02, "solver_time_max": 0.05,
                            "solver_failures": 0, "solver_fallbacks": 0, "allocation_fallbacks": 1}}
    return Result(time=t, data=np.column_stack(list(cols.values())), channels=tuple(cols),
                  units=tuple("-" for _ in cols), meta=meta)


def test_the_catalogue_holds_what_the_kpi_functions_write_and_nothing_else():
    """Both ways: every name case_kpis and basic_kpis write is a catalogue KPI, and every catalogue
    KPI is written by one of them on a record that has every channel."""
    res = _full_result()
    from tapm_opt.config.schema import Fault

    fpso = dataclasses.replace(FPSO, faults=(Fault(kind="gnss_drift", time=1500.0, speed=0.1, direction=0.0),))
    written = {**case_kpis(res, fpso), **basic_kpis(res, fpso)}
    assert not [n for n in written if not cat.is_kpi(n)]
    covered = {kpi(n).name for n in written}
    assert [n for n in KPIS if n not in covered] == []
    assert written["false_alarms"] == 1 and written["mode_switches"] == 1 and written["detection_delay"] == 8.0
    assert written["buoys_lost"] == 1 and written["buoy_loss_detection_delay"] == 40.0
    assert written["roll_max_deg"] == pytest.approx(1.5) and written["pitch_max_deg"] == pytest.approx(0.3)
    c = np.cos(2 * np.pi * res.time / 10.0)
    assert written["roll_std_deg"] == pytest.approx(0.5 * np.std(c))
    assert written["pitch_std_deg"] == pytest.approx(0.3 * np.std(c))
    assert written["buoy_loss_isolated"] == 1.0 and written["buoy_loss_detected_at"] == 1240.0
    # fpso 'normal': 0.8 m/s going 180 deg, seabed factor 0.15
    assert written["current_speed_error"] == pytest.approx(0.1)
    assert written["current_direction_error"] == pytest.approx(10.0)
    assert written["current_seabed_factor_error"] == pytest.approx(0.05)
    assert written["sensor_fault_detection_delay"] == 30.0 and written["sensor_false_alarms"] == 0
    assert abs(written["turret_error_fault_max"] - 0.5) < 1e-9


# -- the catalogue against docs/kpis.md ----------------------------------------------------------

def _doc_rows() -> dict[str, tuple[str, str]]:
    """``{name: (unit, direction)}`` of every row of the KPI tables of docs/kpis.md (the tables
    headed ``| name | unit | direction | definition |``; a row may name several KPIs)."""
    text = (ROOT / "docs" / "kpis.md").read_text(encoding="utf-8")
    out: dict[str, tuple[str, str]] = {}
    tables = 0
    in_table = False
    for ln in text.splitlines():
        if ln.strip() == "| name | unit | direction | definition |":
            in_table, tables = True, tables + 1
            continue
        if not in_table:
            continue
        if not ln.startswith("|"):
            in_table = False
            continue
        if set(ln) <= set("|-: "):
            continue
        cells = [c.strip() for c in ln.strip().strip("|").split(" | ")]
        names = re.findall(r"`([^`]+)`", cells[0])
        assert names and re.fullmatch(r"(`[^`]+`(, )?)+", cells[0]), ln
        for n in names:
            assert n not in out, f"{n} documented twice"
            out[n] = (cells[1], cells[2])
    assert tables >= 8, "docs/kpis.md lost its KPI tables"
    return out


def test_the_docs_kpi_tables_agree_with_the_catalogue_both_ways():
    doc = _doc_rows()
    assert [n for n in doc if n not in KPIS] == []                 # documented names are catalogue names
    assert [n for n in KPIS if n not in doc] == []                 # every catalogue KPI is documented
    wrong = {n: (doc[n], (e.unit, e.direction)) for n, e in KPIS.items() if doc[n] != (e.unit, e.direction)}
    assert not wrong, wrong


def test_the_docs_column_order_is_the_catalogues():
    text = (ROOT / "docs" / "kpis.md").read_text(encoding="utf-8")
    part = text.split("## Tables", 1)[1].split("\n2. ", 1)[0]
    listed = re.search(r"1\. `([^`]+)`", part, re.S).group(1)
    names = [n.strip() for n in listed.replace("\n", " ").split(",")]
    assert names == [n for n, e in KPIS.items() if not e.per]
