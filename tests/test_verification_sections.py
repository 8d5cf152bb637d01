"""The verification of every section of a composite line (docs/verification.md) and DNV-OS-E301's
design fatigue factor from the adjacent line, on a small fpso_deep study: its chain-polyester-chain
lines give each line three checked sections, the polyester rope's against its own curve and MBS.

One small run (about 20 s): fpso_deep's storm, PID, 150 s records, seeds 1 and 2, intact.
The polyester rope's damage is recomputed from its stored channel with the ``rainflow`` package
and numpy's npz reader; the design fatigue factors from the rows' annual damages with the
neighbours written out here.
"""

from __future__ import annotations

import csv
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import rainflow

from tapm_opt.config import load_scenario
from tapm_opt.report.document import render_markdown
from tapm_opt.report.verification import study_verification_section
from tapm_opt.studies import verification_study as vs
from tapm_opt.studies.store import StudyError
from tapm_opt.studies.study import load_study, run_study

STUDY = """
[study]
name = "vdeep"
scenario = "fpso_deep"
duration = 150.0
dt_log = 1.0
heading = "chasing"
seeds = [1, 2]

[[sea_states]]
id = "storm"

[[controllers]]
name = "PID"
type = "pid"

[[conditions]]
name = "intact"

[verification]
consequence_class = 1
design_fatigue_factor = "adjacent"
design_life = 25.0
probabilities = { storm = 0.01 }
sections = true

[verification.line_types.chain137]
component = "studless_chain"
nominal_diameter = 0.137
"""


def _write(tmp: Path, text: str, name: str = "s.toml") -> Path:
    f = tmp / name
    f.write_text(text)
    return f


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("vdeep")
    out = d / "run"
    summary = run_study(load_study(_write(d, STUDY)), out, workers=1, progress=False)
    assert summary.success, summary.errors
    return out


@pytest.fixture(scope="module")
def rows(run):
    with open(run / "verification.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _npz(path: Path, name: str) -> np.ndarray:
    with np.load(path, allow_pickle=False) as z:
        ch = [str(c) for c in z["channels"]]
        return z["data"][:, ch.index(name)].copy()


def _results(run: Path) -> list[Path]:
    return sorted((run / "cases").glob("*/result.npz"))


def test_every_section_has_its_rows_and_its_channel(rows):
    sc = load_scenario("fpso_deep")
    assert list(rows[0]) == list(vs.CSV_COLUMNS)
    got = [(r["line"], r["section"], r["line_type"], r["channel"], r["limit_state"]) for r in rows]
    want = [(ln.id, k, t, ch, ls) for ln in sc.lines
            for k, t, ch in (("2", "chain137", f"T_fairlead[{ln.id}]"), ("1", "poly240", f"T_section[{ln.id}/1]"),
                             ("0", "chain137", f"T_section[{ln.id}/0]"))
            for ls in ("ULS", "FLS")]
    assert got == want and len(set(got)) == len(rows) == 72
    # the rope is checked against its own line type: its MBS, its curve in range / MBS
    poly = [r for r in rows if r["line_type"] == "poly240"]
    assert all(r["a_D"] == "0.259" and r["m"] == "13.46" and float(r["area"]) == 17.75
               for r in poly if r["limit_state"] == "FLS")
    assert all(r["verdict"] == "pass" for r in rows if r["limit_state"] == "ULS")


def test_section_strength_uses_the_section_type_and_channel(run):
    data = json.loads((run / "verification.json").read_text())
    poly = next(r for r in data["rows"] if r["limit_state"] == "ULS" and r["line"] == "1" and r["section"] == 1)
    assert poly["MBS"] == 17.75e6 and poly["channel"] == "T_section[1/1]"
    # the per-seed maxima are the stored channel's (t_start 0: the whole record)
    assert sorted(poly["maxima"]) == pytest.approx(sorted(float(_npz(p, "T_section[1/1]").max())
                                                          for p in _results(run)), rel=1e-12)
    assert poly["utilisation"] == pytest.approx(poly["T_c"] / (0.95 * 17.75e6), rel=1e-12)
    # the bottom chain at its buoy is checked against the chain's MBS
    chain = next(r for r in data["rows"] if r["limit_state"] == "ULS" and r["line"] == "1" and r["section"] == 0)
    assert chain["MBS"] == 1.699e7
    # the fairlead rows keep their channel
    top = next(r for r in data["rows"] if r["limit_state"] == "ULS" and r["line"] == "1" and r["section"] == 2)
    assert sorted(top["maxima"]) == pytest.approx(sorted(float(_npz(p, "T_fairlead[1]").max())
                                                         for p in _results(run)), rel=1e-12)
    assert "poly240" in data["line_types"] and data["line_types"]["poly240"]["component"] == "polyester_rope"


def test_polyester_damage_recomputed_with_rainflow(run, rows):
    """Miner's sum of the rope's stored channel, counted by rainflow.count_cycles (half cycles as
    0.5) and DNV's polyester curve n = 0.259 R^-13.46, R = range / MBS: the row's damage within 1e-9."""
    checked = 0
    for r in rows:
        if r["line_type"] != "poly240" or r["limit_state"] != "FLS":
            continue
        ds = []
        for p in _results(run):
            T = _npz(p, r["channel"])
            ds.append(sum(n * (R / 17.75e6) ** 13.46 / 0.259 for R, n in rainflow.count_cycles(T)))
        D = float(np.mean(ds))
        assert D > 0 and float(r["damage"]) == pytest.approx(D, rel=1e-9)
        checked += 1
    assert checked == 12


def test_adjacent_design_fatigue_factor(run, rows):
    """Per FLS row, gamma_F = 5 for d_F <= 0.8, else 5 + 3 (d_F - 0.8) / 0.2, d_F the row's annual
    damage over its more damaged neighbour's (same section), the neighbours fpso_deep's ring of
    fairlead angles; the life uses that factor."""
    sc = load_scenario("fpso_deep")
    ids = [ln.id for ln in sc.lines]
    deg = {ln.id: math.degrees(ln.fairlead_angle) % 360.0 for ln in sc.lines}
    ring = sorted(ids, key=lambda i: deg[i])
    fls = {(r["line"], r["section"]): r for r in rows if r["limit_state"] == "FLS"}
    gammas = []
    for (lid, k), r in fls.items():
        i = ring.index(lid)
        n1, n2 = ring[i - 1], ring[(i + 1) % len(ring)]
        D = float(r["annual_damage"])
        Dn = max(float(fls[n1, k]["annual_damage"]), float(fls[n2, k]["annual_damage"]))
        d_F = min(D, Dn) / max(D, Dn)
        gamma = 5.0 if d_F <= 0.8 else 5.0 + 3.0 * (d_F - 0.8) / 0.2
        assert float(r["dff"]) == pytest.approx(gamma, rel=1e-12)
        assert float(r["life_years"]) == pytest.approx(1.0 / (gamma * D), rel=1e-12)
        gammas.append(gamma)
    # the neighbours within a bundle are about equally damaged: factors above 5, up to 8
    assert max(gammas) > 6.0 and all(5.0 <= g <= 8.0 for g in gammas)
    data = json.loads((run / "verification.json").read_text())
    assert data["settings"]["design_fatigue_factor"] == "adjacent"
    one = next(r for r in data["rows"] if r["limit_state"] == "FLS" and r["line"] == "1" and r["section"] == 2)
    assert one["dff_neighbour"] in ("12", "2") and 0.0 <= one["d_F"] <= 1.0


def test_a_number_keeps_its_factor(run, tmp_path):
    d = tmp_path / "five"
    shutil.copytree(run, d)
    table = load_study(_write(tmp_path, STUDY)).verification | {"design_fatigue_factor": 5.0}
    res = vs.verify_study(d, table)
    fls = [r for r in res.rows if r["limit_state"] == "FLS"]
    assert all(r["dff"] == 5.0 and r["life_years"] == pytest.approx(1.0 / (5.0 * r["annual_damage_total"]))
               for r in fls)


def test_results_without_section_channels_warn_and_keep_the_fairlead_rows(run, tmp_path):
    """A result stored before the plant logged T_section: its sections are left out, with a warning."""
    d = tmp_path / "old"
    shutil.copytree(run, d)
    for p in _results(d):
        with np.load(p, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        keep = np.array([not str(c).startswith("T_section[") for c in arrays["channels"]])
        arrays["channels"], arrays["units"] = arrays["channels"][keep], arrays["units"][keep]
        arrays["data"] = arrays["data"][:, keep]
        np.savez(p, **arrays)
    res = vs.verify_study(d)
    assert {r["channel"] for r in res.rows} == {f"T_fairlead[{i}]" for i in range(1, 13)}
    assert any("T_section[1/1] is not in the stored results of 2 case(s)" in w for w in res.warnings)


def test_bad_tables(tmp_path):
    for old, new, message in (
            ('design_fatigue_factor = "adjacent"', 'design_fatigue_factor = "adjacnt"',
             "verification.design_fatigue_factor = 'adjacnt' is not one of adjacent"),
            ('design_fatigue_factor = "adjacent"', 'design_fatigue_factor = 0.9',
             "verification.design_fatigue_factor = 0.9 must be >= 1"),
            # a line type the scenario does not have (fpso's wire) is still an error
            ("[verification.line_types.chain137]", "[verification.line_types.wire165]",
             "verification.line_types.wire165: is not a line type of scenario 'fpso_deep'")):
        out = tmp_path / "out"
        with pytest.raises(StudyError) as info:
            run_study(load_study(_write(tmp_path, STUDY.replace(old, new, 1))), out, progress=False)
        assert message in str(info.value), str(info.value)
        assert not out.exists()


def test_report_labels_the_sections(run):
    md = render_markdown(study_verification_section(run)[0], "files")
    assert "| 1/1 poly240 |" in md and "| 1/0 chain137 |" in md
    assert "design fatigue factor from the adjacent line" in md
