"""The study-level limit-state verification (``[verification]``, ``verification.csv``): the table's
checks name the field and the value; the CSV's rows and columns on a small study; T_mpm, T_c and
the fatigue damage recomputed from the stored ``result.npz`` by independent code (numpy's own
reader, scipy's Gumbel fit, a rainflow counter written here); the ALS rows leave the broken line
out; warnings for too few seeds and a coarse dt_log; the report section; ``tapm study verify``.

One small run (about 30 s on two idle cores): fpso at 10 segments, PID, 300 s records in its storm
intact and with line 1 broken at 150 s (seeds 1-3), and 120 s records in a short-period sea state
intact (seeds 1 and 2: too few seeds, and dt_log = 1 s coarser than its Tp / 10).
"""

from __future__ import annotations

import csv
import json
import math
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.stats import gumbel_r

from tapm_opt.cli import cli
from tapm_opt.report.document import render_markdown
from tapm_opt.report.verification import study_verification_section, verification_blocks
from tapm_opt.studies import verification_study as vs
from tapm_opt.studies.store import StudyError
from tapm_opt.studies.study import load_study, run_study

SPY = 365.25 * 24 * 3600.0

STUDY = """
[study]
name = "vstudy"
scenario = "fpso"
duration = 300.0
segments = 10
dt_log = 1.0
seeds = [1, 2, 3]
mode = "list"

[[sea_states]]
id = "storm"

[[sea_states]]
id = "choppy"            # dt_log = 1 s is coarser than its Tp / 10 = 0.6 s
Hs = 2.0
Tp = 6.0

[[controllers]]
name = "PID"
type = "pid"

[[conditions]]
name = "intact"

[[conditions]]
name = "line 1 broken"
line_break = { line = "1", time = 150.0 }

[verification]
standard = "DNV-OS-E301"
consequence_class = 1
design_fatigue_factor = 5.0
design_life = 20.0
probabilities = { storm = 0.01, choppy = 0.2 }
sections = true

[verification.line_types.chain137]
component = "studless_chain"
nominal_diameter = 0.137
""" + "".join(f"""
[[cases]]
sea_state = "{ss}"
condition = "{cond}"
seed = {seed}
""" + ("duration = 120.0\n" if ss == "choppy" else "")
    for ss, cond, seeds in (("storm", "intact", (1, 2, 3)), ("storm", "line 1 broken", (1, 2, 3)),
                            ("choppy", "intact", (1, 2))) for seed in seeds)

PROBS = {"storm": 0.01, "choppy": 0.2}


def _write(tmp: Path, text: str, name: str = "s.toml") -> Path:
    f = tmp / name
    f.write_text(text)
    return f


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("vstudy")
    st = load_study(_write(d, STUDY))
    out = d / "run"
    summary = run_study(st, out, workers=2, progress=False)
    assert summary.success, summary.errors
    return out


@pytest.fixture(scope="module")
def rows(run):
    with open(run / "verification.csv", newline="") as fh:
        return list(csv.DictReader(fh))


# -- the [verification] table's checks -------------------------------------------------------


@pytest.mark.parametrize("old, new, message", [
    ("consequence_class = 1", "consequence_class = 3",
     "verification.consequence_class = 3 is not one of 1, 2"),
    ("consequence_class = 1", "consequence_class = true",
     "verification.consequence_class = True is not one of 1, 2"),
    ("consequence_class = 1", "", "verification.consequence_class: missing required field"),
    ('standard = "DNV-OS-E301"', 'standard = "API RP 2SK"',
     "verification.standard = 'API RP 2SK' is not one of DNV-OS-E301"),
    ('standard = "DNV-OS-E301"', 'mpm_method = "median"', "verification.mpm_method = 'median' is not one of mle"),
    ("design_fatigue_factor = 5.0", "design_fatigue_factor = 0.5",
     "verification.design_fatigue_factor = 0.5 must be >= 1"),
    ("design_life = 20.0", "design_life = -20.0", "verification.design_life = -20 years must be > 0"),
    ("design_life = 20.0", "t_start = 300.0", "verification.t_start = 300 s must be below the study's duration"),
    ("storm = 0.01", "storm = 1.5", "verification.probabilities.storm = 1.5 must be <= 1"),
    ("storm = 0.01", "storm = 0.5, calm = 0.1", "verification.probabilities.calm: is not a sea state of the study"),
    ("storm = 0.01, choppy = 0.2", "storm = 0.01",
     "verification.probabilities: no probability for sea state(s) 'choppy'"),
    ("choppy = 0.2", "choppy = 0.995", "verification.probabilities: sum to 1.005, more than 1"),
    ("sections = true", 'sections = "yes"', "verification.sections"),
    ('component = "studless_chain"', 'component = "studlss_chain"',
     "verification.line_types.chain137.component = 'studlss_chain' is not one of"),
    ('component = "studless_chain"', 'component = "custom"',
     "verification.line_types.chain137: component = 'custom' needs a_D, m, area"),
    ("nominal_diameter = 0.137", "nominal_diameter = 137",
     "verification.line_types.chain137.nominal_diameter = 137 m is larger than any chain"),
    ("nominal_diameter = 0.137", "a_D = -6e10", "verification.line_types.chain137.a_D = -6e+10 must be > 0"),
    ("[verification.line_types.chain137]", "[verification.line_types.chain_137]",
     "verification.line_types.chain_137: is not a line type of scenario 'fpso'"),
    ("design_life = 20.0", "design_lif = 20.0", "verification.design_lif: unknown key; did you mean 'design_life'?"),
])
def test_bad_verification_values_name_field_and_value(tmp_path, old, new, message):
    assert old in STUDY
    out = tmp_path / "out"
    with pytest.raises(StudyError) as info:
        run_study(load_study(_write(tmp_path, STUDY.replace(old, new, 1))), out, progress=False)
    assert message in str(info.value), str(info.value)
    assert not out.exists()


def test_settings_and_defaults(tmp_path):
    st = load_study(_write(tmp_path, STUDY))
    assert st.verification["consequence_class"] == 1
    s = vs.verification_settings({"consequence_class": 2})
    assert (s.standard, s.mpm_method, s.common_factor, s.t_start, s.design_fatigue_factor, s.probabilities) == \
        ("DNV-OS-E301", "mle", True, 0.0, vs.DEFAULT_DESIGN_FATIGUE_FACTOR, None)
    # the defaults of fpso's fairlead chain: studless, nominal d = hydrodynamic 0.2466 m / 1.8
    from tapm_opt.config import load_scenario

    c = vs.line_type_curves(s, load_scenario("fpso"))["chain137"]
    assert c.component == "studless_chain" and c.nominal_diameter == pytest.approx(0.137)
    assert (c.a_D, c.m) == (6.0e10, 3.0) and c.area == pytest.approx(2 * math.pi * 0.137 ** 2 / 4)
    assert set(c.inferred) == {"component", "nominal_diameter"}


def test_dt_log_criterion():
    class SS:
        id, Hs, Tp = "s", 5.0, 10.0

    assert vs.dt_log_warning(1.0, SS) is None            # Tp / 10 exactly
    assert "coarser than Tp/10" in vs.dt_log_warning(1.5, SS)
    SS.Hs = 0.0
    assert vs.dt_log_warning(5.0, SS) is None            # no waves, no wave cycles


# -- verification.csv ---------------------------------------------------------------------------


def test_csv_columns_and_rows(run, rows):
    with open(run / "verification.csv", newline="") as fh:
        assert next(csv.reader(fh)) == list(vs.CSV_COLUMNS)
    # the columns before the sections, in their place; the new ones at the end
    assert vs.CSV_COLUMNS == ("controller", "condition", "sea_state", "line", "limit_state", "n_seeds", "T_mpm",
                              "T_c", "utilisation", "verdict", "a_D", "m", "area", "damage", "annual_damage",
                              "life_years", "section", "line_type", "channel", "dff")
    lines = [str(i) for i in range(1, 13)]
    # the fairlead sections' rows, as before the sections were checked
    top = [r for r in rows if r["channel"].startswith("T_fairlead[")]
    keys = [(r["controller"], r["condition"], r["sea_state"], r["line"], r["limit_state"]) for r in top]
    want = ([("PID", "intact", ss, lid, ls) for ss in ("storm", "choppy") for lid in lines for ls in ("ULS", "FLS")]
            + [("PID", "line 1 broken", "storm", lid, "ALS") for lid in lines[1:]])
    assert keys == want
    assert all(r["section"] == "2" and r["line_type"] == "chain137" and r["channel"] == f"T_fairlead[{r['line']}]"
               for r in top)
    # fpso's chain-wire-chain lines (sections = true): each line's fairlead section, then its wire (1),
    # then its bottom chain (0)
    secs = [(r["sea_state"], r["condition"], r["line"], r["section"], r["line_type"], r["channel"], r["limit_state"])
            for r in rows]
    assert len(set(secs)) == len(rows) == 3 * len(want)
    assert secs[:6] == [("storm", "intact", "1", k, t, ch, ls) for k, t, ch in (
        ("2", "chain137", "T_fairlead[1]"), ("1", "wire165", "T_section[1/1]"), ("0", "chain137", "T_section[1/0]"))
        for ls in ("ULS", "FLS")]
    # without sections (the default): one row per controller, condition, sea state, line and limit
    # state, the fairlead's, with the same values as above
    table = tomllib.loads(STUDY)["verification"]
    del table["sections"]
    res = vs.verify_study(run, table, write=False)
    plain = [r for r in res.rows if r["limit_state"] != "offset"]
    assert [(r["controller"], r["condition"], r["sea_state"], r["line"], r["limit_state"]) for r in plain] == want
    assert all(r["channel"] == f"T_fairlead[{r['line']}]" for r in plain)
    for r, q in zip(top, plain):
        for c in ("T_mpm", "utilisation", "damage"):
            if r[c]:
                assert float(r[c]) == pytest.approx(float(q[c]), rel=1e-12)
    for r in rows:   # the design fatigue factor used, on the FLS rows
        assert r["dff"] == ("5.0" if r["limit_state"] == "FLS" else "")
    for r in rows:
        assert r["n_seeds"] == ("2" if r["sea_state"] == "choppy" else "3")
        strength = ("T_mpm", "T_c", "utilisation")
        fatigue = ("a_D", "m", "area", "damage", "annual_damage", "life_years")
        if r["limit_state"] in ("ULS", "ALS"):
            assert all(r[c] for c in strength) and not any(r[c] for c in fatigue), r
            assert r["verdict"] == ("pass" if float(r["utilisation"]) <= 1 else "fail")
        else:
            assert all(r[c] for c in fatigue) and not any(r[c] for c in strength), r
            assert r["verdict"] == ("pass" if float(r["life_years"]) >= 20.0 else "fail")


def _npz_channel(path: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(time, channel) read with numpy alone (not through tapm_opt's Result)."""
    with np.load(path, allow_pickle=False) as z:
        ch = [str(c) for c in z["channels"]]
        return z["time"].copy(), z["data"][:, ch.index(name)].copy()


def _cases(run: Path) -> dict[tuple[str, str, str], list[Path]]:
    """{(controller, condition, sea state): [result.npz of each seed]} from the case folders."""
    out: dict = {}
    for d in sorted((run / "cases").iterdir()):
        meta = json.loads((d / "case.json").read_text())
        lab = meta["labels"]
        out.setdefault((lab["controller"], lab["condition"], lab["sea_state"]), []).append(
            (lab["seed"], d / "result.npz"))
    return {k: [p for _, p in sorted(v)] for k, v in out.items()}


def test_T_mpm_and_T_c_recomputed_from_the_stored_tensions(run, rows):
    cases = _cases(run)
    detail = {(r["condition"], r["sea_state"], r["line"], r["section"], r["limit_state"]): r
              for r in json.loads((run / "verification.json").read_text())["rows"]}
    from tapm_opt.config import load_scenario

    sc = load_scenario("fpso")
    checked = 0
    for r in rows:
        if r["limit_state"] == "FLS":
            continue
        mbs = sc.line_type_by_id(r["line_type"]).MBS   # the section's own type: chain137 or wire165
        assert r["channel"] == (f"T_fairlead[{r['line']}]" if r["section"] == "2"
                                else f"T_section[{r['line']}/{r['section']}]")
        maxima = [float(_npz_channel(p, r["channel"])[1].max())
                  for p in cases[("PID", r["condition"], r["sea_state"])]]
        loc, _ = gumbel_r.fit(maxima)
        assert float(r["T_mpm"]) == pytest.approx(loc, rel=1e-3), r
        # T_c by hand from the stored mean: DNV-OS-E301 (2008) class 1, ULS 1.1/1.5 with the common
        # factor 1.3 when T_mean > 2/3 T_dyn, ALS 1.0/1.1; capacity 0.95 MBS
        t_mean = detail[(r["condition"], r["sea_state"], r["line"], int(r["section"]), r["limit_state"])]["T_mean"]
        t_dyn = max(float(r["T_mpm"]) - t_mean, 0.0)
        if r["limit_state"] == "ULS":
            t_c = 1.3 * (t_mean + t_dyn) if t_mean > 2 / 3 * t_dyn else 1.1 * t_mean + 1.5 * t_dyn
        else:
            t_c = 1.0 * t_mean + 1.1 * t_dyn
        assert float(r["T_c"]) == pytest.approx(t_c, rel=1e-9)
        assert float(r["utilisation"]) == pytest.approx(t_c / (0.95 * mbs), rel=1e-9)
        checked += 1
    assert checked == 3 * 35


def _hand_rainflow(x: np.ndarray) -> list[tuple[float, float]]:
    """ASTM E1049-85 rainflow counting (5.4.4), written independently of the package: the
    reversals, then the three-point rule; the residue as half cycles."""
    rev = [float(x[0])]
    for v in map(float, x[1:]):
        if v == rev[-1]:
            continue
        if len(rev) >= 2 and (rev[-1] - rev[-2]) * (v - rev[-1]) > 0:
            rev[-1] = v          # still rising (or falling): the same half cycle
        else:
            rev.append(v)
    out, stack = [], []
    for v in rev:
        stack.append(v)
        while len(stack) >= 3:
            X, Y = abs(stack[-1] - stack[-2]), abs(stack[-2] - stack[-3])
            if X < Y:
                break
            if len(stack) == 3:
                out.append((Y, 0.5))
                stack.pop(0)
            else:
                out.append((Y, 1.0))
                last = stack.pop()
                del stack[-2:]
                stack.append(last)
    out += [(abs(b - a), 0.5) for a, b in zip(stack[:-1], stack[1:])]
    return out


def test_hand_rainflow_on_the_astm_example():
    got: dict[float, float] = {}
    for r, n in _hand_rainflow(np.array([-2, 1, -3, 5, -1, 3, -4, 4, -2.0])):
        got[r] = got.get(r, 0.0) + n
    assert got == {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}


def test_damage_annual_damage_and_life_recomputed(run, rows):
    cases = _cases(run)
    curves = {"chain137": (6.0e10, 3.0, 2 * math.pi * 0.137 ** 2 / 4),   # studless chain, as stated
              "wire165": (3.4e14, 4.0, math.pi * 0.165 ** 2 / 4)}       # six-strand wire by default
    fls = [r for r in rows if r["limit_state"] == "FLS"]
    assert len(fls) == 3 * 24
    total: dict[tuple[str, str], float] = {}
    for r in fls:
        a_D, m, area = curves[r["line_type"]]
        assert (float(r["a_D"]), float(r["m"]), float(r["area"])) == pytest.approx((a_D, m, area))
        ds, durs = [], []
        for p in cases[("PID", "intact", r["sea_state"])]:
            t, T = _npz_channel(p, r["channel"])
            ds.append(sum(n * (R / area / 1e6) ** m for R, n in _hand_rainflow(T)) / a_D)
            durs.append(t[-1] - t[0])
        D = float(np.mean(ds))
        assert D > 0 and float(r["damage"]) == pytest.approx(D, rel=1e-9)
        # this sea state's share of the year's damage: p D (seconds a year / record length)
        annual = PROBS[r["sea_state"]] * D * SPY / float(np.mean(durs))
        assert float(r["annual_damage"]) == pytest.approx(annual, rel=1e-9)
        total[r["line"], r["section"]] = total.get((r["line"], r["section"]), 0.0) + annual
    for r in fls:   # the life is the line section's, over both sea states, with DFF 5
        assert float(r["life_years"]) == pytest.approx(1.0 / (5.0 * total[r["line"], r["section"]]), rel=1e-9)


def test_als_leaves_the_broken_line_out(run, rows):
    als = [r for r in rows if r["limit_state"] == "ALS"]
    assert "1" not in {r["line"] for r in als} and len(als) == 3 * 11
    data = json.loads((run / "verification.json").read_text())
    assert [(e["condition"], e["line"]) for e in data["excluded"]] == [("line 1 broken", "1")]
    # the ALS maxima are of the whole record, the transient after the break included
    cases = _cases(run)[("PID", "line 1 broken", "storm")]
    r2 = next(r for r in data["rows"] if r["limit_state"] == "ALS" and r["line"] == "2" and r["section"] == 2)
    assert r2["maxima"] == pytest.approx([_npz_channel(p, "T_fairlead[2]")[1].max() for p in cases])
    # and its mean is the damaged record's, after the break at 150 s
    t, T = _npz_channel(cases[0], "T_fairlead[2]")
    after = t >= 150.0
    assert r2["means"][0] == pytest.approx(np.trapezoid(T[after], t[after]) / (t[after][-1] - t[after][0]), rel=1e-9)


def test_offset_against_the_safe_circle(run):
    data = json.loads((run / "verification.json").read_text())
    off = [o for o in data["offsets"] if o["quantity"] == "turret offset"]
    assert [(o["condition"], o["sea_state"], o["limit_state"]) for o in off] == [
        ("intact", "storm", "ULS"), ("intact", "choppy", "ULS"), ("line 1 broken", "storm", "ALS")]
    kp = [json.loads((p.parent / "kpis.json").read_text())["offset_max"]
          for p in _cases(run)[("PID", "intact", "storm")]]
    assert off[0]["maxima"] == pytest.approx(kp, rel=1e-12)   # the KPIs' turret offset, whole record
    assert off[0]["ratio"] == pytest.approx(off[0]["mpm"] / 50.0)


def test_few_seeds_and_coarse_dt_log_warn(run, rows):
    text = "\n".join(json.loads((run / "verification.json").read_text())["warnings"])
    assert "PID, intact, choppy: only 2 realisation(s): below the floor of 3" in text
    assert "PID, intact, storm: only 3 realisations: fewer than recommended" in text
    assert "sea state 'choppy': dt_log = 1 s is coarser than Tp/10 = 0.6 s" in text
    assert "sea state 'storm': dt_log" not in text           # Tp = 13 s: 1 s is fine
    # two seeds still give a fit (warned); the defaults of the line type are stated, not warned
    assert all(r["T_mpm"] for r in rows if r["sea_state"] == "choppy" and r["limit_state"] == "ULS")
    assert "line type 'chain137'" not in text


def test_one_seed_gives_no_fit(run, tmp_path):
    d = tmp_path / "one"
    shutil.copytree(run, d)
    for p in _cases(d)[("PID", "intact", "storm")][1:]:      # two of the three seeds gone
        shutil.rmtree(p.parent)
    res = vs.verify_study(d)
    uls = [r for r in res.rows if r["limit_state"] == "ULS" and r["sea_state"] == "storm"]
    assert len(uls) == 3 * 12 and all(r["n_seeds"] == 1 and r["T_mpm"] is None and r["verdict"] == "n/a" for r in uls)
    assert any("2 of 8 cases are not finished" in w for w in res.warnings)
    assert any("no Gumbel fit with one seed" in w for w in res.warnings)
    with open(d / "verification.csv", newline="") as fh:
        r = next(r for r in csv.DictReader(fh) if r["limit_state"] == "ULS")
    assert (r["T_mpm"], r["T_c"], r["utilisation"], r["verdict"]) == ("", "", "", "n/a")


def test_an_error_writes_nothing(run, tmp_path, monkeypatch):
    d = tmp_path / "err"
    shutil.copytree(run, d)
    for f in ("verification.csv", "verification.json"):
        (d / f).unlink()

    def boom(*a, **k):
        raise RuntimeError("rainflow failed")

    monkeypatch.setattr(vs, "miner_damage", boom)
    with pytest.raises(RuntimeError):
        vs.verify_study(d)
    assert not (d / "verification.csv").exists() and not (d / "verification.json").exists()


# -- the command and the report ---------------------------------------------------------------


def test_study_verify_command(run, tmp_path):
    d = tmp_path / "cli"
    shutil.copytree(run, d)
    (d / "verification.csv").unlink()
    other = _write(tmp_path, STUDY.replace("consequence_class = 1", "consequence_class = 2"), "class2.toml")
    r = CliRunner().invoke(cli, ["study", "verify", str(d), "--study", str(other)])
    assert r.exit_code == 0, r.output
    assert "ULS 72 rows" in r.output and "ALS 33 rows" in r.output
    with open(d / "verification.csv", newline="") as fh:
        uls = next(x for x in csv.DictReader(fh) if x["limit_state"] == "ULS")
    detail = next(x for x in json.loads((d / "verification.json").read_text())["rows"] if x["limit_state"] == "ULS")
    assert float(uls["T_c"]) == pytest.approx(1.4 * detail["T_mean"] + 2.1 * detail["T_dyn"])
    no_table = _write(tmp_path, STUDY.replace("[verification", "[off"), "none.toml")
    r = CliRunner().invoke(cli, ["study", "verify", str(d), "--study", str(no_table)])
    assert r.exit_code == 2 and "has no [verification] table" in r.output


def test_report_section(run):
    got = study_verification_section(run)
    assert got is not None
    md = render_markdown(got[0], "files")
    assert md.startswith("## 8 Verification")
    assert "### ULS: intact, sea state storm" in md and "### ALS: line 1 broken, sea state storm" in md
    assert "excluded (broken)" in md and "FLS: fatigue damage and life" in md
    assert {f.name for f in got[1]} == {"verification_strength", "verification_fatigue"}


def test_report_compares_the_controllers():
    """The comparison table on a made-up file: MPC's worst line against PID's, per limit state."""
    def row(ctrl, ls, line, **kw):
        return {"controller": ctrl, "condition": "intact" if ls != "ALS" else "broken", "sea_state": "storm",
                "line": line, "limit_state": ls, "n_seeds": 3, "verdict": "pass", **kw}

    rows = [row("PID", "ULS", "1", utilisation=0.40), row("PID", "ULS", "2", utilisation=0.50),
            row("MPC", "ULS", "1", utilisation=0.45), row("MPC", "ULS", "2", utilisation=0.30),
            row("PID", "ALS", "2", utilisation=0.60), row("MPC", "ALS", "2", utilisation=0.66),
            row("PID", "FLS", "1", damage=2e-6, life_years=100.0), row("MPC", "FLS", "1", damage=4e-6,
                                                                        life_years=50.0)]
    data = {"format": "tapm-verification/1", "settings": {"consequence_class": 1, "probabilities": {"storm": 0.1}},
            "partial_safety_factors": {"ULS": [1.1, 1.5], "ALS": [1.0, 1.1]}, "rows": rows}
    md = render_markdown(verification_blocks(data)[0], "files")
    table = md.split("Controllers against PID on the limit states", 1)[1]
    assert "| ULS | intact | storm | worst utilisation | 0.5 (2) | 0.45 (1) | **0.9** ✓ |" in table
    assert "| ALS | broken | storm | worst utilisation | 0.6 (2) | 0.66 (2) | 1.1 |" in table
    assert "| FLS | intact | storm | worst damage per record | 2.000e-06 (1) | 4.000e-06 (1) | 2 |" in table
    assert "| FLS | intact | all | shortest life [years] | 100 (1) | 50 (1) | 0.5 |" in table
