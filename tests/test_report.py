"""The study report (tapm report): self-contained HTML + Markdown from a study directory's saved files."""

from __future__ import annotations

import hashlib
import json
import re

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import load_scenario, scenario_to_dict
from tapm_opt.errors import TapmError
from tapm_opt.report import BEST_MARK, ReportError, kpi_direction, write_report
from tapm_opt.geometry import body_from_turret
from tapm_opt.report.figures import decimate, motion_figure
from tapm_opt.report.series import turret_position_of, turret_track
from tapm_opt.results import Result

SC = load_scenario("fpso")
LINES = [ln.id for ln in SC.lines]
THR = [t.id for t in SC.thrusters]

# Known KPI numbers (exact in 4 significant digits so the rounded table reproduces them).
KPIS = {
    "PID": {"duration": 1200.0, "offset_max": 23.5, "offset_mean": 11.25, "time_outside_safe": 0.0,
            "T_max": 5.25e6, "util_max": 0.309, "delta_min": 4.125, "lines_broken": 1,
            "thrust_energy": 2.25e9, "fuel": 125.0,
            **{f"delta_min[{i}]": 4.125 + 0.5 * k for k, i in enumerate(LINES)}},
    "MPC": {"duration": 1200.0, "offset_max": 18.75, "offset_mean": 12.5, "time_outside_safe": 0.0,
            "T_max": 4.875e6, "util_max": 0.287, "delta_min": 5.5, "lines_broken": 1,
            "thrust_energy": 1.5e9, "fuel": 83.33, "solver_time_median": 0.0125,
            **{f"delta_min[{i}]": 5.5 + 0.25 * k for k, i in enumerate(LINES)}},
}
GAINS_MD = ("# Gain table — fpso\n\nOne row per condition.\n\n| sea state | broken | Kp x, y [kN/m] |\n"
            "|---|---|---|\n| storm (extreme) | intact | 210, 547 |\n")
FAIL_MSG = "QP solver returned NaN at t = 812 s (status 'primal infeasible')"


def _case_id(inputs: dict) -> str:
    return hashlib.sha256(json.dumps(inputs, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:12]


def _result(controller: str, seed: int, *, duration: float = 1200.0, t_break: float = 600.0) -> Result:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 0.5, 0.5)
    amp = 20.0 if controller == "PID" else 15.0
    x = amp * np.sin(2 * np.pi * t / 400.0) + 0.3 * rng.standard_normal(len(t))
    y = 0.6 * amp * np.sin(2 * np.pi * t / 300.0 + 0.5)
    psi = np.radians(10.0 + 5.0 * np.sin(2 * np.pi * t / 500.0))
    ch: list[tuple[str, str, np.ndarray]] = [
        ("x", "m", x), ("y", "m", y), ("psi", "rad", psi),
        ("x_d", "m", np.zeros_like(t)), ("y_d", "m", np.zeros_like(t)), ("psi_d", "rad", np.radians(8.0) + 0 * t)]
    for k, lid in enumerate(LINES):
        T = 2.0e6 + 0.5e5 * k + 1.5e6 * x / 40.0 * np.cos(np.radians(30 * k)) + 1e5 * np.sin(2 * np.pi * t / 11.0)
        if lid == "7":
            T = np.where(t > t_break, 0.0, T)
        ch.append((f"T_fairlead[{lid}]", "N", np.maximum(T, 0.0)))
    for k, tid in enumerate(THR):
        f = 3e5 + 2e5 * np.sin(2 * np.pi * t / 200.0 + k)
        ch.append((f"f[{tid}]", "N", f))
        ch.append((f"P[{tid}]", "W", 1e6 * (f / 1e6) ** 1.5))
    meta = {"scenario": "fpso", "events": [[t_break, "line 7 broke"]],
            "diagnostics": {"solver_time_median": 0.0125} if controller == "MPC" else {},
            "estimator_log": [{"t": t_break + 3.0, "line": "7", "event": "line break detected"}]}
    if controller == "MPC":
        meta["controller_log"] = [{"t": t_break + 5.0, "event": "mode switch", "from": "intact", "to": "damaged",
                                   "radius": 22.5, "broken": ["7"]}]
    return Result(time=t, data=np.column_stack([c[2] for c in ch]), channels=tuple(c[0] for c in ch),
                  units=tuple(c[1] for c in ch), meta=meta)


def _kpis_of(controller: str, condition_index: int) -> dict:
    """KPIS for the first condition; scaled copies (all but duration and lines_broken) for the others."""
    f = 1.0 + 0.25 * condition_index
    return {k: (v if k in ("duration", "lines_broken") else v * f) for k, v in KPIS[controller].items()}


def make_study(root, *, with_failed: bool = True, with_csv: bool = True, controllers=("PID", "MPC"),
               conditions=("line 7 broken at 600 s",)):
    """A study directory following the shared contract: the controllers (PID and MPC by default)
    in every condition, same labels otherwise, and optionally a failed third case (LMPC) in the
    first condition. A condition "line <id> broken at <t> s" has that line break at that time."""
    root.mkdir(parents=True, exist_ok=True)
    cases = []
    all_specs = {"PID": {"type": "pid"}, "MPC": {"type": "mpc", "horizon": 20}}
    for ci, condition in enumerate(conditions):
        sc_dict = scenario_to_dict(SC)
        brk = re.fullmatch(r"line (\S+) broken at ([\d.]+) s", condition)
        sc_dict["faults"] = [{"kind": "line_break", "line": brk[1], "time": float(brk[2])}] if brk else []
        specs = [(name, all_specs[name]) for name in controllers]
        if with_failed and ci == 0:
            specs.append(("LMPC", {"type": "lmpc"}))
        for name, ctrl in specs:
            inputs = {"scenario": sc_dict, "scenario_name": "fpso", "sea_state": "operational", "controller": ctrl,
                      "seed": 1, "duration": 1200.0, "segments": None,
                      "closed_loop": {"dt_control": 1.0, "dt_log": 0.5, "setpoint": "fixed", "heading": "chasing",
                                      "true_state": False}}
            cid = _case_id(inputs)
            labels = {"scenario": "fpso", "sea_state": "operational", "controller": name,
                      "condition": condition, "seed": 1}
            entry = {"id": cid, "name": f"fpso-operational-{name.lower()}" + (f"-c{ci}" if ci else ""),
                     "labels": labels, "inputs": inputs}
            cases.append(entry)
            d = root / "cases" / cid
            d.mkdir(parents=True)
            cj = {**entry, "tapm_opt_version": tapm_opt.__version__, "started": "2024-01-01T00:00:00"}
            if name in KPIS:
                _result(name, seed=len(cases)).save(d / "result.npz")
                entry["_kpis"] = _kpis_of(name, ci)
                (d / "kpis.json").write_text(json.dumps(entry["_kpis"]))
                cj.update(finished="2024-01-01T00:10:00", wall_time=600.0)
            else:
                (d / "error.json").write_text(json.dumps({"type": "SolverError", "message": FAIL_MSG,
                                                          "traceback": "Traceback (most recent call last):\n  ..."}))
            (d / "case.json").write_text(json.dumps({k: v for k, v in cj.items() if k != "_kpis"}))
    listed = [{k: v for k, v in c.items() if k != "_kpis"} for c in cases]
    (root / "study.json").write_text(json.dumps({"name": "controller-comparison", "description": "PID vs MPC after a "
                                                 "line break", "study_file": "cmp.toml", "cases": listed,
                                                 "tapm_opt_version": tapm_opt.__version__}))
    (root / "study.toml").write_text('name = "controller-comparison"\n# compare <PID> & MPC\n'
                                     'controllers = ["pid", "mpc"]\n')
    (root / "gains").mkdir()
    (root / "gains" / "gains.md").write_text(GAINS_MD)
    if with_csv:
        keys = sorted({k for v in KPIS.values() for k in v})
        lines = ["id,name,scenario,sea_state,controller,condition,seed," + ",".join(keys)]
        for c in cases:
            k = c.get("_kpis")
            if k is None:
                continue
            lines.append(",".join([c["id"], c["name"], "fpso", "operational", c["labels"]["controller"],
                                   c["labels"]["condition"], "1"] + [repr(k[n]) if n in k else "" for n in keys]))
        (root / "kpis.csv").write_text("\n".join(lines) + "\n")
    return root, cases


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root, cases = make_study(tmp_path_factory.mktemp("study") / "out")
    html_path, md_path = write_report(root)
    return root, cases, html_path, md_path


def _side_by_side(md: str) -> dict[str, dict[str, str]]:
    """Parse the first side-by-side KPI table of report.md back: {kpi: {controller: cell}}."""
    lines = md.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("### Side by side"))
    while not lines[i].startswith("|"):
        i += 1
    rows = []
    while i < len(lines) and lines[i].startswith("|"):
        rows.append([c.strip() for c in lines[i].strip().strip("|").split("|")])
        i += 1
    head = rows[0]
    out = {}
    for r in rows[2:]:
        out[r[0].strip("`")] = dict(zip(head[3:], r[3:]))
    return out


def _value(cell: str) -> float:
    return float(cell.replace("**", "").replace(BEST_MARK, "").strip())


def test_report_files_exist_and_html_is_self_contained(report):
    root, cases, html_path, md_path = report
    assert html_path == root / "report.html" and md_path == root / "report.md"
    page = html_path.read_text()
    imgs = re.findall(r"<img\b[^>]*>", page)
    assert len(imgs) >= 1 + 3 * 2  # layout + 3 figures per finished case
    for tag in imgs:
        src = re.search(r'src="([^"]*)"', tag).group(1)
        assert src.startswith("data:image/png;base64,")
    assert 'src="http' not in page and "href=\"http" not in page and "<link" not in page and "<script" not in page
    assert 'id="fig-layout"' in page
    for c in cases[:2]:
        for kind in ("motion", "lines", "thrusters"):
            assert f'id="fig-case_{c["id"]}_{kind}"' in page
    assert html_path.stat().st_size < 5e6
    # the study file verbatim (escaped) in a <pre>, and the case list with labels
    assert "# compare &lt;PID&gt; &amp; MPC" in page
    assert "line 7 broken at 600 s" in page
    # what the estimator and controller decided, per case, in time order
    md = md_path.read_text()
    assert ("Decisions: t = 603 s: estimator: line 7 break detected; t = 605 s: controller: mode switch "
            "intact → damaged, dead band 22.5 m") in md
    assert "Decisions: t = 603 s: estimator: line 7 break detected\n" in md       # the PID keeps no log


def test_decisions_are_ordered_and_bad_records_left_out():
    from tapm_opt.report.series import decisions_of

    r = _result("PID", 0, duration=10.0, t_break=5.0)
    r.meta["controller_log"] = [{"t": 7.0, "event": "sea state", "from": "normal", "to": "storm"},
                                {"t": float("nan"), "event": "mode switch"}, "not a record",
                                {"t": 2.0, "event": "dead band", "radius": 25.04, "broken": ["1"]}]
    assert decisions_of(r) == [[2.0, "controller: dead band 25.0 m"],
                               [7.0, "controller: sea state normal → storm"],
                               [8.0, "estimator: line 7 break detected"]]
    r.meta.pop("controller_log")
    r.meta["estimator_log"] = None
    assert decisions_of(r) == []


def test_markdown_links_figures_relatively(report):
    root, cases, _, md_path = report
    md = md_path.read_text()
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert "report_files/layout.png" in links
    assert f"report_files/case_{cases[0]['id']}_motion.png" in links
    for ln in links:
        p = md_path.parent / ln
        assert p.is_file() and p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_side_by_side_numbers_equal_kpis_json_and_better_is_marked(report):
    _, _, _, md_path = report
    tab = _side_by_side(md_path.read_text())
    for kpi in ("offset_max", "offset_mean", "T_max", "util_max", "delta_min", "thrust_energy", "fuel"):
        for ctrl in ("PID", "MPC"):
            assert _value(tab[kpi][ctrl]) == pytest.approx(KPIS[ctrl][kpi], rel=1e-12), (kpi, ctrl)
    # lower is better: offset_max (MPC 18.75 < PID 23.5); also offset_mean where PID is better
    assert BEST_MARK in tab["offset_max"]["MPC"] and BEST_MARK not in tab["offset_max"]["PID"]
    assert BEST_MARK in tab["offset_mean"]["PID"] and BEST_MARK not in tab["offset_mean"]["MPC"]
    # higher is better: delta_min (MPC 5.5 > PID 4.125)
    assert BEST_MARK in tab["delta_min"]["MPC"] and BEST_MARK not in tab["delta_min"]["PID"]
    # equal values and neutral KPIs are not marked
    assert BEST_MARK not in tab["duration"]["PID"] + tab["duration"]["MPC"]
    assert BEST_MARK not in tab["time_outside_safe"]["PID"] + tab["time_outside_safe"]["MPC"]
    # a KPI only one controller has is shown but not marked
    assert tab["solver_time_median"]["PID"] == "" and BEST_MARK not in tab["solver_time_median"]["MPC"]


def test_better_convention():
    for k in ("offset_max", "time_outside_alert", "T_max", "util_max", "thrust_energy", "fuel",
              "solver_time_p95", "solver_failures", "T_max[3]"):
        assert kpi_direction(k) == -1, k
    for k in ("delta_min", "delta_min[7]", "delta_min_offline", "delta_min_offline[7]", "riser_delta_min",
              "riser_delta_top_min", "riser_delta_bottom_min"):
        assert kpi_direction(k) == 1, k
    for k in ("riser_top_angle_max_deg", "riser_bottom_angle_max_deg", "riser_delta_frac_below", "delta_frac_below"):
        assert kpi_direction(k) == -1, k
    assert kpi_direction("duration") == 0 and kpi_direction("mode_switches") == 0
    assert kpi_direction("lines_broken") == -1 and kpi_direction("false_alarms") == -1


def test_full_kpi_table_and_per_line_delta(report):
    _, _, html_path, md_path = report
    md = md_path.read_text()
    assert "### All KPIs" in md
    full = md.split("### All KPIs", 1)[1]
    assert "`offset_max [m]`" in full and "`delta_min[12] [-]`" in full
    # per-line delta_min table of the PID case (from kpis.json): line 12 = 4.125 + 0.5 * 11
    assert "Per-line KPIs" in md
    assert re.search(r"\| 12 \|(?:[^\n]*\|)? 9\.625 \|", md)


def test_failed_case_is_listed_with_its_message(report):
    _, cases, html_path, md_path = report
    md = md_path.read_text()
    failed = md.split("## 7 Failed cases", 1)[1]
    assert cases[2]["id"] in failed and FAIL_MSG in failed and "SolverError" in failed
    page = html_path.read_text()
    assert "primal infeasible" in page.split('id="failed"', 1)[1]
    assert "No case failed" not in failed


def test_missing_study_dir_raises_naming_the_path(tmp_path):
    missing = tmp_path / "nope"
    with pytest.raises(ReportError, match=re.escape(str(missing))) as ei:
        write_report(missing)
    assert isinstance(ei.value, TapmError)
    assert not missing.exists()


@pytest.mark.parametrize("content", [None, "{not json", json.dumps({"name": "x"}),
                                     json.dumps({"cases": [{"id": "../evil"}]})])
def test_invalid_study_dir_raises_and_writes_nothing(tmp_path, content):
    d = tmp_path / "study"
    d.mkdir()
    if content is not None:
        (d / "study.json").write_text(content)
    before = sorted(p.name for p in d.iterdir())
    with pytest.raises(ReportError, match=re.escape(str(d))):
        write_report(d)
    assert sorted(p.name for p in d.iterdir()) == before  # no report.html/.md, no report_files/


def test_a_file_instead_of_a_directory(tmp_path):
    f = tmp_path / "study.json"
    f.write_text("{}")
    with pytest.raises(ReportError, match="not a study directory"):
        write_report(f)


def test_explicit_outputs_and_missing_csv(tmp_path):
    root, cases = make_study(tmp_path / "s", with_failed=False, with_csv=False)
    h, m = write_report(root, out_html=tmp_path / "o" / "r.html", out_md=tmp_path / "o" / "r.md")
    assert h.is_file() and m.is_file()
    md = m.read_text()
    assert "r_files/layout.png" in md and (tmp_path / "o" / "r_files" / "layout.png").is_file()
    assert "kpis.csv` is missing" in md and "No case failed" in md
    assert not (root / "report.html").exists()


def test_decimate_keeps_extremes_and_bounds_points():
    t = np.linspace(0, 100, 100_001)
    y = np.sin(t) + (t == t[54321]) * 10.0 - (t == t[7]) * 5.0
    td, yd = decimate(t, y, 2000)
    assert len(td) <= 2000 and np.all(np.diff(td) > 0)
    assert yd.max() == y.max() and yd.min() == y.min()
    assert td[0] == t[0] and td[-1] == t[-1]


def test_reliability_trace_matches_the_kpi_definition():
    """The delta(t) curves of the tension figure are the causal index evaluated as case_kpis does
    (restarted at the first break, a broken line only while alive, values where the estimate is
    ready), so their minima equal the per-line delta_min and the lowest-line curve's minimum the
    aggregate delta_min; the lowest lines are always drawn."""
    from tapm_opt.report.figures import tension_figure
    from tapm_opt.report.series import causal_traces
    from tapm_opt.studies import kpis

    res = _result("PID", seed=3, duration=2200.0, t_break=900.0)   # both segments > 700 s
    tr = causal_traces(res, SC)
    ref = kpis.case_kpis(res, SC)
    assert tr.delta_s == kpis.DELTA_S_DEFAULT
    assert set(tr.lines) == set(LINES) and tr.riser == {} and tr.riser_min == []
    assert tr.t_break == 900.0 and tr.broken == ("7",)
    assert tr.ready_from == [700.0, pytest.approx(900.5 + 700.0)]
    for lid, runs in tr.lines.items():
        assert min(float(r.delta.min()) for r in runs) == ref[f"delta_min[{lid}]"]
        assert all(r.t[0] >= tr.ready_from[r.segment] for r in runs)
    assert max(float(r.t.max()) for r in tr.lines["7"]) <= 900.0   # line 7 broke at 900 s
    assert [r.segment for r in tr.lines["7"]] == [0] and [r.segment for r in tr.lines["1"]] == [0, 1]
    assert min(float(r.delta.min()) for r in tr.lines_min) == ref["delta_min"]
    # k sigma is the monitor's: positive where the waves act
    assert all(np.all(r.ksigma > 0) for runs in tr.lines.values() for r in runs)
    fig = tension_figure(res, SC, title="t", traces=tr)
    drawn = [ln for ln in fig.axes[1].lines if (ln.get_gid() or "").startswith("delta:line ")]
    assert 0 < len({ln.get_gid() for ln in drawn}) <= 4
    assert min(float(np.min(ln.get_ydata())) for ln in drawn) == ref["delta_min"]


def test_a_record_too_short_for_the_causal_index_has_empty_runs():
    res = _result("PID", seed=3)   # 1200 s, break at 600 s: neither segment fills 700 s
    tr = causal_traces_of(res)
    assert tr.lines == {} and tr.lines_min == [] and tr.ready_from == [None, None]
    assert tr.segments == [(0.0, 600.0), (600.5, 1200.0)]
    from tapm_opt.report.figures import tension_figure

    fig = tension_figure(res, SC, title="t", traces=tr)
    assert any("no causal index" in t.get_text() for t in fig.axes[1].texts)


def causal_traces_of(res):
    from tapm_opt.report.series import causal_traces

    return causal_traces(res, SC)


def test_gain_tables_are_included(report):
    _, _, html_path, md_path = report
    md = md_path.read_text().split("## 6 Gains", 1)[1].split("## 7", 1)[0]
    assert "| storm (extreme) | intact | 210, 547 |" in md and "### Gain table — fpso" in md
    page = html_path.read_text().split('id="gains"', 1)[1].split('id="failed"', 1)[0]
    assert "<th>Kp x, y [kN/m]</th>" in page and "<td>210, 547</td>" in page


def test_an_unreadable_result_is_reported_not_fatal(tmp_path):
    root, cases = make_study(tmp_path / "s", with_failed=False)
    (root / "cases" / cases[1]["id"] / "result.npz").write_bytes(b"not a zip file")
    _, m = write_report(root)
    md = m.read_text()
    assert "Problems met while writing this report" in md
    assert f"case {cases[1]['id']}: cannot read" in md
    assert f"report_files/case_{cases[0]['id']}_motion.png" in md  # the other case is still drawn
    # its KPIs (kpis.json) are still compared side by side
    assert "| `offset_max` | m | lower |" in md


def _pose_result(psi, x, y, *, meta=None, setpoint=None) -> Result:
    t = np.arange(len(psi), dtype=float)
    ch = [("x", "m", x), ("y", "m", y), ("psi", "rad", psi)]
    if setpoint is not None:
        ch += [("x_d", "m", np.full(len(t), setpoint[0])), ("y_d", "m", np.full(len(t), setpoint[1]))]
    return Result(time=t, data=np.column_stack([c[2] for c in ch]), channels=tuple(c[0] for c in ch),
                  units=tuple(c[1] for c in ch), meta=meta or {})


def test_a_hull_rotating_about_a_fixed_turret_has_turret_offset_zero():
    """The body origin swings on a 91 m arm about the turret, which stays where it rests: every
    plotted offset (trajectory, offset curve, max-offset marker) is zero."""
    p_cot = np.array(SC.turret.position, dtype=float)
    assert np.hypot(*p_cot) > 50.0
    psi = np.radians(np.linspace(-120.0, 150.0, 541))
    x, y = body_from_turret((0.0, 0.0), psi, p_cot)
    res = _pose_result(psi, x, y)
    assert np.hypot(x, y).max() > 150.0           # the body origin moves far ...
    track = turret_track(res, turret_position_of(res, SC))
    np.testing.assert_allclose(track.x, 0.0, atol=1e-9)   # ... the turret does not
    np.testing.assert_allclose(track.y, 0.0, atol=1e-9)
    np.testing.assert_allclose(track.offset, 0.0, atol=1e-9)
    fig = motion_figure(res, SC, title="rotation about the turret")
    plan, offset_axes = fig.axes[0], fig.axes[1]
    traj = plan.lines[0]
    np.testing.assert_allclose(traj.get_xdata(), 0.0, atol=1e-9)
    np.testing.assert_allclose(traj.get_ydata(), 0.0, atol=1e-9)
    np.testing.assert_allclose(offset_axes.lines[0].get_ydata(), 0.0, atol=1e-9)
    assert offset_axes.get_ylabel() == "turret offset [m]"
    assert plan.get_xlabel().startswith("turret offset") and plan.get_ylabel().startswith("turret offset")


def test_turret_offsets_of_translation_and_half_turn():
    """A translation moves the turret with the body; a half turn about the body origin puts the
    turret 2 |p_cot| behind its rest position. The setpoint channels are turret offsets already."""
    p_cot = np.array([91.44, 0.0])
    n = 5
    x, y = np.linspace(0.0, 20.0, n), np.linspace(0.0, -10.0, n)
    tr = turret_track(_pose_result(np.zeros(n), x, y, setpoint=(3.0, -4.0)), p_cot)
    np.testing.assert_allclose(tr.x, x, atol=1e-12)
    np.testing.assert_allclose(tr.y, y, atol=1e-12)
    np.testing.assert_allclose(tr.offset, np.hypot(x, y), atol=1e-12)
    np.testing.assert_array_equal(tr.x_d, 3.0)
    np.testing.assert_array_equal(tr.y_d, -4.0)
    half = turret_track(_pose_result(np.full(n, np.pi), np.zeros(n), np.zeros(n)), p_cot)
    np.testing.assert_allclose(half.x, -2.0 * p_cot[0], atol=1e-9)
    np.testing.assert_allclose(half.offset, 2.0 * p_cot[0], atol=1e-9)
    assert half.x_d is None and half.y_d is None


def test_turret_position_comes_from_the_result_then_the_scenario():
    z = np.zeros(3)
    saved = _pose_result(z, z, z, meta={"turret_position_B": [12.0, -3.0]})
    np.testing.assert_array_equal(turret_position_of(saved, SC), [12.0, -3.0])  # what the run used
    plain = _pose_result(z, z, z)
    np.testing.assert_array_equal(turret_position_of(plain, SC), SC.turret.position)
    with pytest.raises(ReportError, match="turret position is unknown"):
        turret_position_of(plain, None)
    with pytest.raises(ReportError, match="turret_position_B"):
        turret_position_of(_pose_result(z, z, z, meta={"turret_position_B": [1.0]}), SC)


# -- controllers compared: overlay figures and KPI charts -------------------------------------

from matplotlib.colors import to_rgba  # noqa: E402

from tapm_opt.report import figures as report_figures  # noqa: E402
from tapm_opt.report.figures import PANELS, comparison_figure, controller_styles  # noqa: E402
from tapm_opt.report.series import comparison_series  # noqa: E402

CONDITIONS = ("intact", "line 7 broken at 600 s")


def _capture(monkeypatch):
    """Record what the report's overlay and bar-chart functions return while it is written."""
    seen = {"overlay": [], "bars": []}
    real_overlay, real_bars = report_figures.comparison_figure, report_figures.kpi_bar_figure

    def overlay(*a, **k):
        out = real_overlay(*a, **k)
        seen["overlay"].append((k.get("title", ""), out))
        return out

    def bars(*a, **k):
        out = real_bars(*a, **k)
        seen["bars"].append(out)
        return out

    monkeypatch.setattr(report_figures, "comparison_figure", overlay)
    monkeypatch.setattr(report_figures, "kpi_bar_figure", bars)
    return seen


def _controller_lines(ax) -> dict:
    return {ln.get_gid().split(":", 1)[1]: ln for ln in ax.lines if (ln.get_gid() or "").startswith("controller:")}


def _data_axes(fig):
    """The four panels of an overlay figure (the controller legend row has no visible axis)."""
    return [ax for ax in fig.axes if ax.axison]


def _side_by_side_all(md: str) -> dict[str, dict[str, dict[str, str]]]:
    """Every side-by-side table of report.md: {condition description: {kpi: {controller: cell}}}."""
    out = {}
    lines = md.splitlines()
    for i, ln in enumerate(lines):
        if not ln.startswith("### Side by side: "):
            continue
        desc = ln[len("### Side by side: "):]
        j = i + 1
        while not lines[j].startswith("|"):
            j += 1
        rows = []
        while j < len(lines) and lines[j].startswith("|"):
            rows.append([c.strip() for c in lines[j].strip().strip("|").split("|")])
            j += 1
        out[desc] = {r[0].strip("`"): dict(zip(rows[0][3:], r[3:])) for r in rows[2:]}
    return out


@pytest.fixture(scope="module")
def two_conditions(tmp_path_factory):
    """PID and MPC in two conditions (plus the failed LMPC in the first), the report written with
    the overlay and bar-chart results recorded."""
    mp = pytest.MonkeyPatch()
    try:
        seen = _capture(mp)
        root, cases = make_study(tmp_path_factory.mktemp("cmp") / "out", conditions=CONDITIONS)
        html_path, md_path = write_report(root)
    finally:
        mp.undo()
    return root, cases, html_path, md_path, seen


def test_one_overlay_figure_per_condition_in_html_and_markdown(two_conditions):
    root, cases, html_path, md_path, seen = two_conditions
    md = md_path.read_text()
    page = html_path.read_text()
    assert "## 3 Controllers compared" in md and 'id="compare"' in page
    part = md.split("## 3 Controllers compared", 1)[1].split("## 4 Cases", 1)[0]
    for n, cond in enumerate(CONDITIONS, start=1):
        assert f"### Condition {n}: " in part and f"condition {cond}" in part
        assert f"report_files/compare_{n}.png" in part
        assert (root / "report_files" / f"compare_{n}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f'id="fig-compare_{n}"' in page
    assert not (root / "report_files" / "compare_3.png").exists()
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)  # plain image links (no brackets in the captions)
    assert {"report_files/compare_1.png", "report_files/compare_2.png", "report_files/kpi_bars.png"} <= set(links)
    # the KPI chart sits with the KPI tables, in both outputs
    kpis = md.split("## 5 KPIs", 1)[1].split("## 6 Gains", 1)[0]
    assert "### KPI charts" in kpis and "report_files/kpi_bars.png" in kpis
    assert kpis.index("kpi_bars.png") < kpis.index("### Side by side")
    assert 'id="fig-kpi_bars"' in page.split('id="kpis"', 1)[1]
    # the existing sections are still there
    for h in ("## 1 Study", "## 2 Scenario", "## 4 Cases", "### All KPIs", "## 6 Gains", "## 7 Failed cases"):
        assert h in md
    assert len(seen["overlay"]) == len(CONDITIONS) and len(seen["bars"]) == 1


def test_overlay_has_one_line_per_controller_in_each_panel(two_conditions):
    *_, seen = two_conditions
    for title, ov in seen["overlay"]:
        axes = _data_axes(ov.figure)
        assert len(axes) == 4
        assert [ax.get_ylabel() for ax in axes] == ["turret offset [m]", "heading [deg]", "max T/MBS [-]",
                                                   "thrust power [MW]"]
        assert ov.tension_quantity == "utilisation" and not ov.notes
        for ax, panel in zip(axes, PANELS):
            lines = _controller_lines(ax)
            assert sorted(lines) == ["MPC", "PID"], (title, panel)   # the failed LMPC has no curve
            assert sorted(ov.curves[panel]) == ["MPC", "PID"]
            for lab, ln in lines.items():
                np.testing.assert_array_equal(ln.get_xdata(), ov.curves[panel][lab][0])
                np.testing.assert_array_equal(ln.get_ydata(), ov.curves[panel][lab][1])
                assert len(ln.get_xdata()) <= report_figures.MAX_POINTS
        # safe and alert radii as horizontal lines on the offset panel, allowed utilisation on the tension one
        ys = {float(ln.get_ydata()[0]) for ln in axes[0].lines if (ln.get_gid() or "") == "" and
              len(set(ln.get_ydata())) == 1 and "radius" in ln.get_label()}
        assert ys == {SC.limits.safe_radius, SC.limits.alert_radius}
        assert any(ln.get_label().startswith("allowed T/MBS") and
                   float(ln.get_ydata()[0]) == pytest.approx(SC.limits.tension_utilisation) for ln in axes[2].lines)
        # the legend row names the controllers
        legend_axes = [ax for ax in ov.figure.axes if not ax.axison]
        texts = [t.get_text() for t in legend_axes[0].get_legend().get_texts()]
        assert texts == ["PID", "MPC"]


def test_overlay_curves_are_the_logged_quantities():
    """Peaks survive the reduction: the plotted maxima are those of the full-rate series (turret
    offset, max over lines of T/MBS = KPI util_max, total power in MW)."""
    kpis = pytest.importorskip("tapm_opt.studies.kpis")
    res = _result("PID", seed=3)
    ref = kpis.case_kpis(res, SC)
    cs = comparison_series(res, SC, label="PID")
    ov = comparison_figure([cs, comparison_series(_result("MPC", seed=4), SC, label="MPC")], SC.limits, title="t")
    off = turret_track(res, turret_position_of(res, SC)).offset
    assert ov.curves["offset"]["PID"][1].max() == pytest.approx(off.max(), rel=1e-12)
    assert ov.curves["offset"]["PID"][1].max() == pytest.approx(ref["offset_max"], rel=1e-12)
    assert ov.curves["tension"]["PID"][1].max() == pytest.approx(ref["util_max"], rel=1e-12)
    P = res.group("P").sum(axis=1)
    assert ov.curves["power"]["PID"][1].max() == pytest.approx(P.max() / 1e6, rel=1e-12)
    assert np.trapezoid(P, res.time) == pytest.approx(ref["thrust_energy"], rel=1e-12)
    assert len(ov.curves["offset"]["PID"][0]) <= report_figures.MAX_POINTS < len(res.time)
    # the line-7 break is drawn once, not once per controller
    assert sum(t.get_text().startswith(" line 7 broke") for t in _data_axes(ov.figure)[0].texts) == 1


def test_bar_heights_equal_the_kpi_table_and_colours_match_the_overlay(two_conditions):
    _, cases, _, md_path, seen = two_conditions
    bars = seen["bars"][0]
    assert bars.kpis == ["offset_max", "time_outside_safe", "util_max", "delta_min", "thrust_energy"]
    assert bars.groups == list(CONDITIONS) and bars.labels == ["PID", "MPC"]
    tables = _side_by_side_all(md_path.read_text())
    descs = [next(d for d in tables if f"condition {c} " in d + " ") for c in CONDITIONS]
    by_label = {(c["labels"]["condition"], c["labels"]["controller"]): c.get("_kpis") for c in cases}
    for k in bars.kpis:
        for lab in bars.labels:
            drawn = bars.bars[k][lab]
            assert [j for j, _ in drawn] == [0, 1]  # one bar per condition
            for j, rect in drawn:
                value = rect.get_height() * bars.scale[k]
                exact = by_label[(CONDITIONS[j], lab)][k]
                assert value == pytest.approx(exact, rel=1e-12), (k, lab, j)   # kpis.json
                assert value == pytest.approx(_value(tables[descs[j]][k][lab]), rel=1e-3)  # the table cell
                assert bars.values[k][lab][j] == exact
    assert bars.units["thrust_energy"] == "GJ" and bars.scale["thrust_energy"] == 1e9
    # one colour per controller, the same in the bar chart and in every overlay figure
    styles = controller_styles(["PID", "MPC"])
    for lab in bars.labels:
        want = to_rgba(styles[lab]["color"])
        for k in bars.kpis:
            for _, rect in bars.bars[k][lab]:
                assert rect.get_facecolor() == want
        for _, ov in seen["overlay"]:
            for ax in _data_axes(ov.figure):
                assert to_rgba(_controller_lines(ax)[lab].get_color()) == want
    assert to_rgba(styles["PID"]["color"]) != to_rgba(styles["MPC"]["color"])


def test_controller_colours_follow_first_appearance_and_avoid_limit_colours():
    st = controller_styles(["MPC", "PID", "MPC", "NMPC"])
    assert list(st) == ["MPC", "PID", "NMPC"]
    colours = [to_rgba(s["color"]) for s in st.values()]
    assert len(set(colours)) == 3
    for reserved in (report_figures.SAFE_COLOR, report_figures.ALERT_COLOR, report_figures.EVENT_COLOR):
        assert to_rgba(reserved) not in colours
    many = controller_styles([f"c{i}" for i in range(12)])
    assert len({(s["color"], s["ls"]) for s in many.values()}) == 12


def test_one_controller_still_gets_its_comparison_and_chart(tmp_path, monkeypatch):
    seen = _capture(monkeypatch)
    root, cases = make_study(tmp_path / "s", controllers=("PID",), with_failed=False, conditions=CONDITIONS)
    _, m = write_report(root)
    md = m.read_text()
    assert md.count("Only one controller ran in this condition") == 2
    assert (root / "report_files" / "compare_1.png").is_file() and (root / "report_files" / "kpi_bars.png").is_file()
    for _, ov in seen["overlay"]:
        for ax in _data_axes(ov.figure):
            assert list(_controller_lines(ax)) == ["PID"]
    bars = seen["bars"][0]
    assert bars.labels == ["PID"]
    for k in bars.kpis:
        assert [j for j, _ in bars.bars[k]["PID"]] == [0, 1]
    assert "Problems met while writing this report" not in md


def _drop_channels(path, prefixes) -> None:
    res = Result.load(path)
    keep = [i for i, c in enumerate(res.channels) if not c.startswith(tuple(prefixes))]
    Result(time=res.time, data=res.data[:, keep], channels=tuple(res.channels[i] for i in keep),
           units=tuple(res.units[i] for i in keep), meta=res.meta).save(path)


def test_missing_channels_leave_a_note_not_a_crash(tmp_path, monkeypatch):
    seen = _capture(monkeypatch)
    root, cases = make_study(tmp_path / "s", with_failed=False)
    mpc = next(c for c in cases if c["labels"]["controller"] == "MPC")
    _drop_channels(root / "cases" / mpc["id"] / "result.npz", ("P[", "T_fairlead["))
    _, m = write_report(root)
    md = m.read_text()
    part = md.split("## 3 Controllers compared", 1)[1].split("## 4 Cases", 1)[0]
    note = next(ln for ln in part.splitlines() if ln.startswith("Not in the figure:"))
    assert "MPC: no line tension (no T_fairlead[...] channels)" in note
    assert "MPC: no thrust power (no P[...] channels)" in note
    assert "report_files/compare_1.png" in part
    (_, ov), = seen["overlay"]
    assert sorted(ov.curves["offset"]) == sorted(ov.curves["heading"]) == ["MPC", "PID"]
    assert list(ov.curves["tension"]) == ["PID"] and list(ov.curves["power"]) == ["PID"]
    # the KPI chart still uses both cases' kpis.json
    assert seen["bars"][0].labels == ["PID", "MPC"]


def test_a_panel_no_case_can_fill_says_so():
    res = _result("PID", seed=2)
    keep = [i for i, c in enumerate(res.channels) if not c.startswith(("P[", "psi"))]
    bare = Result(time=res.time, data=res.data[:, keep], channels=tuple(res.channels[i] for i in keep),
                  units=tuple(res.units[i] for i in keep), meta={})
    cs = comparison_series(bare, None, label="PID")
    assert cs.offset is None and cs.heading is None and cs.power is None and cs.util is None
    assert cs.tension is not None  # without the scenario's MBS: the tension in MN
    ov = comparison_figure([cs], None, title="bare")
    axes = _data_axes(ov.figure)
    assert ov.tension_quantity == "tension" and axes[2].get_ylabel() == "max tension [MN]"
    assert ov.curves["tension"]["PID"][1].max() == pytest.approx(res.group("T_fairlead").max() / 1e6)
    assert any("thrust power not logged" in t.get_text() for t in axes[3].texts)
    assert any("heading not logged" in t.get_text() for t in axes[1].texts)
    assert len(ov.notes) == 3 and all(n.startswith("PID: ") for n in ov.notes)
    report_figures.png_bytes(ov.figure)  # renders


def test_after_a_break_the_safe_region_leaves_the_broken_line_out():
    """The condition's second map: line 7 left out, k sigma from the damaged record's ready part,
    drawn dashed; the intact one solid and filled."""
    from tapm_opt.report.reliability import case_reliability, reliability_figure, safe_regions

    res = _result("PID", seed=3, duration=2200.0, t_break=900.0)
    tr = causal_traces_of(res)
    cr = case_reliability(res, SC, tr, label="PID", controller="PID", setpoint="fixed")
    assert [c.segment for c in cr.conditions] == [0, 1] and all(c.ready for c in cr.conditions)
    assert cr.conditions[1].window == (pytest.approx(1600.5), 2200.0)
    regions = safe_regions([cr], SC, SC.sea_state("normal"), n=21)
    assert [r.inputs.state for r in regions] == ["intact", "after the break"]
    intact, after = regions
    assert intact.map is not None and after.map is not None
    assert intact.inputs.broken == () and after.inputs.broken == ("7",)
    assert "7" in intact.inputs.ksigma_lines and "7" not in after.inputs.ksigma_lines
    ks1 = np.median(np.concatenate([r.ksigma for r in tr.lines["1"] if r.segment == 1]))
    assert after.inputs.ksigma_lines["1"] == pytest.approx(ks1, rel=1e-12)
    assert "after the break record" in after.inputs.source
    psi = res["psi"][res.time >= 700.0 - 1e-9]
    psi = psi[res.time[res.time >= 700.0 - 1e-9] <= 900.0]
    assert intact.inputs.heading == pytest.approx(np.arctan2(np.sin(psi).sum(), np.cos(psi).sum()))
    assert intact.inputs.tau_env is None   # no tau_env_hat channels in this record
    rf = reliability_figure([cr], regions, SC.limits, title="t", delta_s=2.0)
    assert set(rf.contours) == {"intact", "after the break"}
    assert rf.contours["intact"].get_linestyle()[0][1] is None           # solid
    assert rf.contours["after the break"].get_linestyle()[0][1] is not None   # dashed
    assert rf.filled is not None
    # the break is marked on the delta(t) panel
    assert any(t.get_text().startswith(" line 7 broke") for t in rf.figure.axes[1].texts)
    report_figures.png_bytes(rf.figure)


def test_side_by_side_gives_the_worst_lines_fatigue_life_against_the_first_controller(tmp_path):
    """The life of the worst line over the first column's is the inverse ratio of their
    fatigue_damage_max (Miner: life ~ 1 / damage), the longest marked; absent without the KPI."""
    from tapm_opt.report.data import CaseInfo
    from tapm_opt.report.kpi_tables import side_by_side_tables

    def case(i, ctrl, dmg):
        k = {"offset_max": 10.0 + i}
        if dmg is not None:
            k["fatigue_damage_max"] = dmg
        return CaseInfo(id=f"c{i}", name=f"c{i}", labels={"controller": ctrl, "seed": 1}, inputs={},
                        folder=tmp_path, status="finished", kpis=k)

    (_, tab), = side_by_side_tables([case(0, "chasing", 3.0e-4), case(1, "fatigue", 2.4e-4)])
    row = [r for r in tab.rows if r[0].text.startswith("worst line's fatigue life")]
    assert len(row) == 1 and "chasing" in row[0][0].text
    assert [c.text for c in row[0][3:]] == ["1", "1.25"] and [c.best for c in row[0][3:]] == [False, True]
    (_, tab), = side_by_side_tables([case(0, "chasing", None), case(1, "fatigue", None)])
    assert not any(r[0].text.startswith("worst line's") for r in tab.rows)
