"""The report's reliability and setpoint figures on a real (tiny) closed-loop study: fpso in the
'normal' sea for 900 s (the causal index is ready from 700 s), PID with a fixed setpoint and PID
with the reliability-optimal setpoint; about 25 s to run the study, 10 s per report."""

from __future__ import annotations

import re

import numpy as np
import pytest

from tapm_opt.errors import TapmError
from tapm_opt.estimation.reliability import causal_reliability
from tapm_opt.report import BEST_MARK, write_report
from tapm_opt.report import figures as report_figures
from tapm_opt.report import report as report_mod
from tapm_opt.report.data import read_study
from tapm_opt.report.series import turret_position_of, turret_track
from tapm_opt.studies.kpis import DELTA_S_DEFAULT, format_number
from tapm_opt.studies.study import load_study, run_study

STUDY = """
[study]
name = "reliability-report"
description = "PID fixed vs PID with the reliability setpoint, 900 s of the normal sea"
scenario = "fpso"
duration = 900.0
segments = 4
dt_control = 1.0
dt_log = 1.0
heading = "chasing"
setpoint = "fixed"
seeds = [1]

[[sea_states]]
id = "normal"

[[controllers]]
name = "PID fixed"
type = "pid"
setpoint = "fixed"

[[controllers]]
name = "PID reliability"
type = "pid"
setpoint = "reliability"
setpoint_options = { warmup = 100.0, period = 60.0 }

[[conditions]]
name = "intact"
"""
LABELS = ("PID fixed", "PID reliability")


def _record(monkeypatch):
    """Keep what the report's reliability figure and tension figures return while it is written."""
    seen = {"reliability": [], "lines": {}}
    real_rel, real_lines = report_mod.reliability_figure, report_figures.tension_figure

    def rel(*a, **k):
        out = real_rel(*a, **k)
        seen["reliability"].append(out)
        return out

    def lines(result, scenario, *, title, **k):
        out = real_lines(result, scenario, title=title, **k)
        seen["lines"][title.split(": ", 1)[0]] = out
        return out

    monkeypatch.setattr(report_mod, "reliability_figure", rel)
    monkeypatch.setattr(report_figures, "tension_figure", lines)
    return seen


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """The study run once (two worker processes) and its report written once, figures recorded."""
    root = tmp_path_factory.mktemp("relrep")
    (root / "s.toml").write_text(STUDY)
    out = root / "out"
    summary = run_study(load_study(root / "s.toml"), out, workers=2, progress=False)
    assert not summary.failed and len(summary.finished) == 2
    mp = pytest.MonkeyPatch()
    try:
        seen = _record(mp)
        html_path, md_path = write_report(out)
    finally:
        mp.undo()
    data = read_study(out)
    cases = {c.controller: c for c in data.cases}
    assert sorted(cases) == sorted(LABELS)
    return out, cases, html_path, md_path, seen


def _figure(study):
    *_, seen = study
    (rf,) = seen["reliability"]
    return rf


def test_contour_figure_exists_and_the_field_zero_point_is_safe(study):
    out, cases, html_path, md_path, seen = study
    md = md_path.read_text()
    part = md.split("## 3 Controllers compared", 1)[1].split("## 4 Cases", 1)[0]
    assert "report_files/reliability_1.png" in part
    assert (out / "report_files" / "reliability_1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert 'id="fig-reliability_1"' in html_path.read_text()
    rf = _figure(study)
    (reg,) = rf.regions                      # intact only: no line breaks
    m = reg.map
    assert m is not None and not reg.error and reg.inputs.state == "intact" and reg.inputs.broken == ()
    ix, iy = int(np.argmin(np.abs(m.x))), int(np.argmin(np.abs(m.y)))
    assert m.x[ix] == 0.0 and m.y[iy] == 0.0
    assert m.safe[iy, ix] and m.delta_min[iy, ix] >= DELTA_S_DEFAULT
    assert not m.safe.all()                  # the region has a boundary inside the map
    # the drawn contour is min delta = delta_s, and the filled safe region contains the origin
    assert list(rf.contours["intact"].levels) == [DELTA_S_DEFAULT]
    assert any(p.contains_point((0.0, 0.0)) for p in rf.filled.get_paths())
    far = (float(m.y[0]), float(m.x[0]))     # a corner of the map is not safe there
    assert not m.safe[0, 0] and not any(p.contains_point(far) for p in rf.filled.get_paths())


def test_map_inputs_are_the_runs_mean_conditions_and_the_monitors_k_sigma(study):
    """heading: circular mean of psi and tau_env: mean of tau_env_hat over the ready part (700 s on),
    k sigma: median over the ready part of causal_reliability's k * sigma, pooled over both cases."""
    _, cases, *_ = study
    inp = _figure(study).regions[0].inputs
    res = [cases[lab].load_result() for lab in LABELS]
    sc = cases[LABELS[0]].scenario()
    win = [r.time >= 700.0 - 1e-9 for r in res]
    psi = np.concatenate([r["psi"][w] for r, w in zip(res, win)])
    assert inp.heading == pytest.approx(np.arctan2(np.sin(psi).sum(), np.cos(psi).sum()), abs=1e-12)
    tau = np.concatenate([np.column_stack([r[f"tau_env_hat[{a}]"] for a in "XYN"])[w] for r, w in zip(res, win)])
    np.testing.assert_allclose(inp.tau_env, tau.mean(axis=0), rtol=1e-9)
    j = [ln.id for ln in sc.lines].index("1")
    ks = []
    for r in res:
        rec = causal_reliability(r.time, r["T_fairlead[1]"], [sc.line_arrays["MBS"][j]], [sc.line_arrays["MBS_std"][j]])
        ks.append((rec.k * rec.sigma)[rec.ready, 0])
    assert inp.ksigma_lines["1"] == pytest.approx(float(np.median(np.concatenate(ks))), rel=1e-12)
    assert sorted(inp.ksigma_lines, key=int) == [ln.id for ln in sc.lines]
    assert np.all(inp.ksigma_riser > 0) and inp.cases == 2
    assert "median of the causal monitor's k·σ over the ready part" in inp.source


def test_the_setpoint_trajectory_drawn_is_the_setpoint_channels(study):
    _, cases, *_ = study
    rf = _figure(study)
    ax = rf.figure.axes[0]
    for lab in LABELS:
        res = cases[lab].load_result()
        np.testing.assert_array_equal(rf.setpoints[lab][0], res["y_d"])    # east along the horizontal axis
        np.testing.assert_array_equal(rf.setpoints[lab][1], res["x_d"])
        tr = turret_track(res, turret_position_of(res, cases[lab].scenario()))
        np.testing.assert_array_equal(rf.tracks[lab][0], tr.y)
        np.testing.assert_array_equal(rf.tracks[lab][1], tr.x)
        (line,) = [ln for ln in ax.lines if ln.get_gid() == f"setpoint:{lab}"]
        if lab == "PID fixed":   # fixed at the field zero point: one marker
            np.testing.assert_array_equal(res["x_d"], 0.0)
            assert list(line.get_xdata()) == [0.0] and list(line.get_ydata()) == [0.0]
        else:                    # the optimal layer moves it: the dashed path is the channels
            assert np.ptp(res["x_d"]) > 1.0
            np.testing.assert_array_equal(line.get_xdata(), res["y_d"])
            np.testing.assert_array_equal(line.get_ydata(), res["x_d"])
            log = res.meta["setpoint_log"]
            (tg,) = [ln for ln in ax.lines if ln.get_gid() == f"targets:{lab}"]
            np.testing.assert_array_equal(tg.get_xdata(), [e["target"][1] for e in log])
            np.testing.assert_array_equal(tg.get_ydata(), [e["target"][0] for e in log])


def test_delta_figures_minima_equal_the_kpis(study):
    """The causal delta(t) drawn (case tension figure: lowest lines and riser ends; condition figure:
    lowest over lines and riser per controller) has the KPIs' minima."""
    _, cases, _, _, seen = study
    rf = _figure(study)
    for lab in LABELS:
        k = cases[lab].kpis
        assert min(float(np.min(d)) for _, d in rf.delta_lines[lab]) == k["delta_min"]
        assert min(float(np.min(d)) for _, d in rf.delta_riser[lab]) == k["riser_delta_min"]
        assert all(float(np.min(t)) >= 700.0 for t, _ in rf.delta_lines[lab])   # ready only
        fig = seen["lines"][f"{cases[lab].name} ({lab})"]
        axd = fig.axes[1]
        lines = [ln for ln in axd.lines if (ln.get_gid() or "").startswith("delta:line ")]
        assert 1 <= len({ln.get_gid() for ln in lines}) <= 4
        assert min(float(np.min(ln.get_ydata())) for ln in lines) == k["delta_min"]
        for end in ("top", "bottom"):
            (ln,) = [ln for ln in axd.lines if ln.get_gid() == f"delta:riser {end}"]
            assert float(np.min(ln.get_ydata())) == k[f"riser_delta_{end}_min"]
        assert any(ln.get_label().startswith("threshold δ_s") and float(ln.get_ydata()[0]) == DELTA_S_DEFAULT
                   for ln in axd.lines)


def _side_by_side(md: str) -> dict[str, list[str]]:
    lines = md.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("### Side by side"))
    while not lines[i].startswith("|"):
        i += 1
    rows = []
    while i < len(lines) and lines[i].startswith("|"):
        rows.append([c.strip() for c in lines[i].strip().strip("|").split("|")])
        i += 1
    head = rows[0]
    return {r[0].strip("`"): dict(zip(head, r)) for r in rows[2:]}


def test_kpi_table_has_the_riser_columns_with_their_direction(study):
    _, cases, html_path, md_path, _ = study
    tab = _side_by_side(md_path.read_text())
    fixed, rel = cases["PID fixed"].kpis, cases["PID reliability"].kpis
    for name, unit, better in (("riser_delta_min", "-", "higher"), ("riser_delta_top_min", "-", "higher"),
                               ("riser_delta_bottom_min", "-", "higher"), ("delta_min_offline", "-", "higher"),
                               ("riser_top_angle_max_deg", "deg", "lower"),
                               ("riser_bottom_angle_max_deg", "deg", "lower"),
                               ("riser_delta_frac_below", "-", "lower")):
        row = tab[name]
        assert row["unit"] == unit and row["better"] == better, name
        a, b = fixed[name], rel[name]
        if a == b:
            assert BEST_MARK not in row["PID fixed"] + row["PID reliability"], name
            continue
        win = "PID fixed" if (a > b) == (better == "higher") else "PID reliability"
        lose = "PID reliability" if win == "PID fixed" else "PID fixed"
        assert BEST_MARK in row[win] and BEST_MARK not in row[lose], name
    # the setpoint layers differ, so the riser indices differ and the loop above checked a mark
    assert fixed["riser_delta_min"] != rel["riser_delta_min"]
    page = html_path.read_text()
    row = re.search(r"<tr><td><code>riser_delta_min</code></td>.*?</tr>", page).group(0)
    assert row.count('class="r best"') == 1


def test_condition_paragraph_names_the_lowest_indices_and_the_setpoint_layers(study):
    _, cases, _, md_path, _ = study
    part = md_path.read_text().split("## 3 Controllers compared", 1)[1].split("## 4 Cases", 1)[0]
    para = next(ln for ln in part.splitlines() if ln.startswith("Lowest causal reliability index"))
    for lab, layer in (("PID fixed", "fixed"), ("PID reliability", "reliability, warmup = 100, period = 60")):
        k = cases[lab].kpis
        assert (f"**{lab}** (setpoint {layer}): lines {format_number(k['delta_min'])}, "
                f"riser {format_number(k['riser_delta_min'])}") in para


def test_a_map_that_cannot_be_computed_is_noted_not_fatal(study, tmp_path, monkeypatch):
    import shutil

    from tapm_opt.design import setpoint as design_setpoint

    out, *_ = study
    copy = tmp_path / "out"
    shutil.copytree(out, copy)

    def broken_map(*a, **k):
        raise design_setpoint.SetpointOptError("the catenary has no solution anywhere on the grid")

    assert issubclass(design_setpoint.SetpointOptError, TapmError)
    monkeypatch.setattr(design_setpoint, "reliability_map", broken_map)
    seen = _record(monkeypatch)
    _, md_path = write_report(copy)
    md = md_path.read_text()
    assert "report_files/reliability_1.png" in md
    assert "not computed:** SetpointOptError: the catenary has no solution anywhere on the grid" in md
    (rf,) = seen["reliability"]
    assert rf.filled is None and rf.contours == {} and rf.regions[0].map is None
    assert sorted(rf.setpoints) == sorted(LABELS)   # tracks and setpoints are still drawn
    assert "Problems met while writing this report" not in md
