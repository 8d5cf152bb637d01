"""Capability envelopes (``tapm capability``, ``docs/capability.md``): the properties the method
promises, one direction against a static balance computed by hand, the files and the CLI."""

from __future__ import annotations

import csv
import dataclasses
import itertools
import json
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.config import scenario_from_dict, scenario_to_dict
from tapm_opt.control.allocation import ThrustAllocator
from tapm_opt.design.capability import (
    BEAUFORT_TABLE,
    DYNAMIC_ALLOWANCE,
    QUASI_STATIC_FACTORS,
    SLACK_TOL,
    CapabilityError,
    CapabilityOptions,
    _Engine,
    capability,
)
from tapm_opt.design.loads import mean_environmental_load
from tapm_opt.errors import TapmError
from tapm_opt.geometry import body_from_turret, turret_offset
from tapm_opt.models.mooring import MooringModel
from tapm_opt.studies.kpis import DNV_CAPACITY_FACTOR

TOL = 0.1  # the default bisection tolerance on the wind speed [m/s]


def _weak_aamo4():
    """aamo4 (4 lines at 90 deg, thrusters symmetric about the centre line) with a quarter of its
    thrust, so that the thrust cases end inside the Beaufort table."""
    d = scenario_to_dict(tapm_opt.load_scenario("aamo4"))
    for t in d["thrusters"]:
        t["max_thrust"] *= 0.25
        t["max_reverse_thrust"] *= 0.25
    return scenario_from_dict(d)


@pytest.fixture(scope="module")
def weak():
    return _weak_aamo4()


@pytest.fixture(scope="module")
def fixed_all(weak):
    """Every case of the weak aamo4 at a fixed heading, every 45 deg."""
    return capability(weak, heading="fixed", directions_deg=tuple(range(0, 360, 45)))


def _env(V: float):
    """Hs, Tp and current of the Beaufort table at wind speed V, interpolated by hand."""
    rows = BEAUFORT_TABLE
    for r0, r1 in itertools.pairwise(rows):
        if r0.wind_speed <= V <= r1.wind_speed:
            t = (V - r0.wind_speed) / (r1.wind_speed - r0.wind_speed)
            return V, r0.Hs + t * (r1.Hs - r0.Hs), r0.Tp + t * (r1.Tp - r0.Tp), \
                r0.current_speed + t * (r1.current_speed - r0.current_speed)
    raise AssertionError(V)


def _sea_state(sc, V: float, going_to: float):
    V, Hs, Tp, Vc = _env(V)
    return dataclasses.replace(sc.sea_state(), Hs=Hs, Tp=Tp, wind_speed=V, current_speed=Vc,
                               wave_direction=going_to, wind_direction=going_to, current_direction=going_to)


# -- properties ---------------------------------------------------------------------------------------

def test_thrusters_never_below_mooring_alone(weak):
    res = capability(weak, condition="intact", directions_deg=tuple(range(0, 360, 30)))
    moor, intact = res.case("mooring"), res.case("intact")
    assert np.all(intact.wind_speed >= moor.wind_speed - 1e-9), (moor.wind_speed, intact.wind_speed)
    assert np.all(intact.beaufort >= moor.beaufort)
    assert np.any(intact.wind_speed > moor.wind_speed + 1.0)     # the thrusters add something
    assert np.all(intact.wind_speed < BEAUFORT_TABLE[-1].wind_speed)  # ... inside the table
    assert res.numbers["A"] >= res.numbers["mooring_A"] and res.numbers["B"] >= res.numbers["mooring_B"]


def test_intact_never_below_any_single_failure(fixed_all):
    res = fixed_all
    intact = res.case("intact")
    failures = [c for c in (*res.cases, *res.thruster_cases) if c.kind in ("line", "thruster")]
    assert {c.name for c in failures} >= {"line 1", "line 2", "line 3", "line 4", "thruster A1", "thruster T2"}
    for c in failures:
        assert np.all(c.wind_speed <= intact.wind_speed + 1e-9), (c.name, c.wind_speed, intact.wind_speed)
        assert np.all(c.beaufort <= intact.beaufort), c.name
    assert res.numbers["C"] <= res.numbers["A"] and res.numbers["D"] <= res.numbers["B"]
    # the worst thruster reported is the one with the lowest envelope
    worst = res.cases[-1]
    assert worst.kind == "thruster"
    assert min(c.wind_speed.min() for c in res.thruster_cases) == worst.wind_speed.min()


def test_post_failure_alone_can_exceed_intact_when_a_leeward_line_breaks(weak):
    """Why a failure case also needs the intact system (the default): after the break alone, a
    broken leeward line (line 4, anchor to the west, weather from 60 deg) no longer pulls the
    vessel downwind and the ALS factor is lower than the ULS one."""
    dirs = (60.0,)
    kw = {"heading": "fixed", "condition": "all-single-line", "directions_deg": dirs}
    post = capability(weak, post_failure_only=True, **kw)
    held = capability(weak, **kw)
    assert post.case("line 4").wind_speed[0] > post.case("intact").wind_speed[0] + 1.0
    assert held.case("line 4").wind_speed[0] <= held.case("intact").wind_speed[0] + 1e-9


def test_symmetric_mooring_and_thrusters_give_a_symmetric_envelope(weak):
    """aamo4: lines at 0/90/180/270 deg, hull and thrusters symmetric about the centre line; at the
    fixed heading 0 the directions d and -d mirror each other."""
    pairs = ((30.0, 330.0), (60.0, 300.0), (120.0, 240.0))
    dirs = tuple(d for p in pairs for d in p)
    res = capability(weak, heading="fixed", condition="intact", directions_deg=dirs)
    for c in res.cases:
        w = dict(zip(dirs, c.wind_speed))
        for a, b in pairs:
            assert abs(w[a] - w[b]) <= TOL + 1e-9, (c.name, a, w[a], b, w[b])
    # not symmetric about the east-west axis (bow and stern differ): the test can tell
    intact = dict(zip(dirs, res.case("intact").wind_speed))
    assert abs(intact[60.0] - intact[120.0]) > TOL


def test_fpso_envelope_is_symmetric_about_its_mooring_axis():
    """fpso: three 4-line bundles at 0/120/240 deg, riser under the turret, thrusters symmetric."""
    sc = tapm_opt.load_scenario("fpso")
    res = capability(sc, heading="fixed", condition="intact", directions_deg=(50.0, 310.0))
    for c in res.cases:
        assert abs(c.wind_speed[0] - c.wind_speed[1]) <= TOL + 1e-9, (c.name, c.wind_speed)
        assert c.limit[0] == c.limit[1]


# -- against a static balance computed by hand --------------------------------------------------------

def test_mooring_alone_against_a_hand_computed_balance():
    """aamo4, weather from the north, bow into it: at the reported limiting wind speed the catenary
    equilibrium under 1.25 x the mean load has its turret offset and every tension within the limits;
    a tolerance above, the named constraint is exceeded."""
    sc = tapm_opt.load_scenario("aamo4")
    res = capability(sc, condition="intact", directions_deg=(0.0,))
    moor = res.case("mooring")
    V, limit = float(moor.wind_speed[0]), moor.limit[0]
    assert 10.0 < V < BEAUFORT_TABLE[-1].wind_speed
    model = MooringModel.from_scenario(sc)
    T_lim = DNV_CAPACITY_FACTOR * model.MBS / QUASI_STATIC_FACTORS[("ULS", 1)]   # 0.95 MBS / 1.7
    assert np.allclose(T_lim, 0.95 * 5.0e6 / 1.70)

    def ratios(wind: float) -> dict:
        ss = _sea_state(sc, wind, math.pi)            # coming from north = going to south
        tau = 1.25 * mean_environmental_load(sc, ss, 0.0).total
        assert abs(tau[1]) < 1e-6 * abs(tau[0]) and tau[0] < 0      # head on: pure surge, pushing south
        eta = model.equilibrium(tau, psi=0.0)                        # tau_moor(eta) + 1.25 tau_env = 0
        assert np.allclose(model.force(eta)[:2], -tau[:2], atol=1e-3 * abs(tau[0]))
        p = np.array(turret_offset(eta, sc.turret.position))
        out = {"offset": float(np.hypot(*p)) / sc.limits.safe_radius}
        T = model.tensions(eta)
        out.update({f"tension {i}": float(t / tl) for i, t, tl in zip(model.line_ids, T, T_lim)})
        return out

    at = ratios(V)
    assert max(at.values()) <= 1.0 + 1e-6, at
    above = ratios(V + 1.5 * TOL)
    assert above[limit] > 1.0, (limit, above)
    assert max(above, key=above.get) == limit
    assert np.allclose(moor.offset[0], [-at["offset"] * sc.limits.safe_radius, 0.0], atol=0.05)


def test_thrust_case_against_a_hand_computed_balance(weak, fixed_all):
    """At the limiting environment of a thrust-limited direction: the reported turret offset, the
    catenary load there and the allocator (a fresh one) balance 1.25 x the mean load."""
    res = fixed_all
    intact = res.case("intact")
    i = intact.limit.index("thrust")
    d, V = res.directions_deg[i], float(intact.wind_speed[i])
    psi = float(intact.heading[i])
    assert psi == 0.0                                             # the fixed heading
    beta_to = math.radians(d) + math.pi
    tau_env = mean_environmental_load(weak, _sea_state(weak, V, beta_to), psi).total
    bx, by = body_from_turret(intact.offset[i], psi, weak.turret.position)
    eta = np.array([bx, by, psi])
    model = MooringModel.from_scenario(weak)
    tau_T = -(model.force(eta) + DYNAMIC_ALLOWANCE * tau_env)
    alloc = ThrustAllocator(weak.thrusters, dt=1e6)
    alloc.allocate(tau_T)
    r = alloc.allocate(tau_T)
    assert not r.fallback
    assert np.all(np.abs(r.slack[:2]) <= SLACK_TOL * alloc.F_ref)
    assert abs(r.slack[2]) <= SLACK_TOL * alloc.F_ref * alloc.L_ref
    assert np.all(np.abs(r.f) <= alloc.f_max + 1e-6)
    assert np.hypot(*intact.offset[i]) <= weak.limits.safe_radius + 1e-9
    T_lim = DNV_CAPACITY_FACTOR * model.MBS / 1.70
    assert np.all(model.tensions(eta) <= T_lim * (1 + 1e-6))
    assert np.max(model.tensions(eta) / T_lim) == pytest.approx(intact.tension[i], rel=1e-6)


def test_free_turret_table_and_cached_loads_match_the_models():
    """The grid's mooring load rotated to a heading equals MooringModel.force there (fpso: turret
    91 m ahead of the body origin), and the load cached by relative direction equals a direct
    mean_environmental_load at the actual heading."""
    sc = tapm_opt.load_scenario("fpso")
    eng = _Engine(sc, CapabilityOptions(condition="intact"))
    psi = 0.7
    tab = eng.table("3", psi)
    model = MooringModel.from_scenario(sc, broken=["3"])
    for j in (0, 17, 400, len(eng.P) - 1):
        bx, by = body_from_turret(eng.P[j], psi, sc.turret.position)
        eta = np.array([bx, by, psi])
        assert np.allclose(tab.tau[j], model.force(eta), rtol=1e-7, atol=1.0)
        T = model.tensions(eta)
        _, T_lim = eng.mooring("3")
        assert tab.r_T[j] == pytest.approx(np.max(T / T_lim), rel=1e-9)
    e = eng.env_at(18.0)
    beta_from = math.radians(130.0)
    got = eng.load(e, beta_from, psi)
    ss = dataclasses.replace(sc.sea_state(), Hs=e.Hs, Tp=e.Tp, wind_speed=e.wind_speed, current_speed=e.current_speed,
                             wave_direction=beta_from + math.pi, wind_direction=beta_from + math.pi,
                             current_direction=beta_from + math.pi)
    assert np.allclose(got, mean_environmental_load(sc, ss, psi).total, rtol=1e-9, atol=1e-3)


def test_level_2_weathervane_balances_the_yaw_moment_about_the_turret():
    sc = tapm_opt.load_scenario("fpso")
    eng = _Engine(sc, CapabilityOptions(level=2, sea_state="storm", condition="intact"))
    assert eng.rel_wind != 0.0 and eng.rel_current != 0.0        # storm: wind 15, current 30 deg off
    for V in (BEAUFORT_TABLE[8].wind_speed, 19.0):
        rel = eng.weathervane(V)
        assert rel != 0.0
        m, _ = eng._moment_about_turret(eng.env_at(V), rel)
        load = eng.load(eng.env_at(V), rel, 0.0)
        assert abs(m) <= 1e-6 * np.hypot(load[0], load[1]) * 100.0


# -- options, files, CLI, report ----------------------------------------------------------------------

@pytest.mark.parametrize("kw, text", [
    ({"level": 3}, "level = 3"), ({"heading": "north"}, "heading = 'north'"),
    ({"condition": "every"}, "condition = 'every'"), ({"directions_deg": (0, 360)}, "must not repeat"),
    ({"dynamic_allowance": 0.5}, "dynamic_allowance = 0.5"), ({"wind_tol": 0.0}, "wind_tol = 0.0"),
    ({"workers": 0}, "workers = 0"), ({"bogus": 1}, "unknown option"),
])
def test_bad_options_are_typed_errors_naming_the_field(kw, text):
    sc = tapm_opt.load_scenario("aamo4")
    with pytest.raises(CapabilityError, match=text) as exc:
        capability(sc, **kw)
    assert isinstance(exc.value, TapmError)


def test_scenario_without_safe_radius_is_refused():
    d = scenario_to_dict(tapm_opt.load_scenario("aamo4"))
    d["limits"].pop("safe_radius", None)
    d["limits"].pop("alert_radius", None)
    with pytest.raises(CapabilityError, match="safe_radius"):
        capability(scenario_from_dict(d), condition="intact", directions_deg=(0.0,))



def test_cli_writes_the_envelopes_and_plots(tapm, capsys, tmp_path):
    out = tmp_path / "cap"
    code, text, err = tapm(capsys, "capability", "aamo4", "--out", str(out), "--condition", "thruster-failure",
                           "--directions", "0,90,180,270", "--workers", "1", "--json")
    assert code == 0, err
    summary = json.loads(text)
    assert set(summary["numbers"]) >= {"A", "B", "C", "D"}
    for name in ("capability.csv", "capability.json", "capability.png", "capability_cases.png"):
        assert (out / name).stat().st_size > 0
    with open(out / "capability.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["direction_deg", "case", "beaufort", "wind_speed", "limit"]
    cases = {r[1] for r in rows[1:]}
    assert {"mooring", "intact"} <= cases and len([c for c in cases if c.startswith("thruster ")]) == 1
    assert len(rows) == 1 + 4 * 3
    data = json.loads((out / "capability.json").read_text())
    assert data["numbers"]["C"] is not None and len(data["thruster_failures"]) == 5
    assert data["settings"]["dynamic_allowance"] == 1.25
    assert (out / "capability.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("args, text", [
    (("--level", "4"), "--level"), (("--sea-state", "nope"), "'nope' is not a sea state"),
    (("--directions", "0,0"), "repeats a direction"), (("--directions", "north"), "--directions"),
    (("--condition", "some"), "--condition"), (("--heading", "north"), "--heading"),
])
def test_cli_bad_options_exit_2_and_write_nothing(tapm, capsys, tmp_path, args, text):
    out = tmp_path / "cap"
    code, _, err = tapm(capsys, "capability", "aamo4", "--out", str(out), *args)
    assert code == 2
    assert text in err
    assert not out.exists()


def test_report_section_from_a_study_directory(tmp_path):
    from tapm_opt.report.capability import study_capability_section, write_capability
    from tapm_opt.report.document import Fig, Table, render_markdown

    assert study_capability_section(tmp_path) is None
    res = capability(tapm_opt.load_scenario("aamo4"), condition="intact", directions_deg=(0.0, 120.0, 240.0))
    write_capability(res, tmp_path / "capability")
    blocks, figs = study_capability_section(tmp_path)
    assert len(figs) == 2 and all(isinstance(f, Fig) and f.png[:4] == b"\x89PNG" for f in figs)
    md = render_markdown(blocks, "files")
    assert "## 8 Capability" in md and "| A |" in md and "intact" in md
    assert any(isinstance(b, Table) for b in blocks)
    (tmp_path / "capability" / "capability.json").write_text("{not json")
    problems: list[str] = []
    blocks, figs = study_capability_section(tmp_path, problems)
    assert not figs and problems and "capability.json" in problems[0]


def test_one_lines_condition_is_that_case_of_every_single_line():
    """``condition = "line <id>"`` computes that line's case alone: the same envelope as the case of
    ``all-single-line``; an id the scenario does not have is refused by name."""
    sc = tapm_opt.load_scenario("aamo4")
    kw = {"directions_deg": [0.0, 90.0], "heading": "fixed"}
    one = capability(sc, {"condition": "line 2", **kw})
    every = capability(sc, {"condition": "all-single-line", **kw})
    assert [c.name for c in one.cases] == ["mooring", "intact", "line 2"]
    assert np.array_equal(one.case("line 2").beaufort, every.case("line 2").beaufort)
    assert np.array_equal(one.case("line 2").wind_speed, every.case("line 2").wind_speed)
    assert one.numbers["D_case"] == "line 2"
    with pytest.raises(CapabilityError, match="condition = 'line 9': '9' is not a line of scenario 'aamo4'"):
        capability(sc, {"condition": "line 9", **kw})
    with pytest.raises(CapabilityError, match="condition = 'lines' must be one of"):
        CapabilityOptions(condition="lines")


def test_a_study_capability_is_recomputed_when_a_default_changes(tmp_path, monkeypatch):
    """The stamp holds the resolved options: a result computed under another default (here the
    standard table, the default before the extended one) or stamped with the study's options only
    is recomputed; the same resolved options are not."""
    import tapm_opt.design.capability as cap_module
    from tapm_opt.studies.runner import write_study_capability
    from tapm_opt.studies.spec import load_study

    f = tmp_path / "s.toml"
    f.write_text('[study]\nname = "s"\nscenario = "fpso"\nduration = 4.0\nsegments = 6\n[[sea_states]]\nid = "storm"\n'
                 '[[controllers]]\nname = "PID"\ntype = "pid"\n'
                 '[capability]\ncondition = "intact"\ndirections_deg = [0.0, 90.0]\n')
    study = load_study(f)
    calls = []

    class _Result:
        def data_files(self):
            return {"capability.json": b"{}\n", "capability.csv": b"direction_deg\n"}

    monkeypatch.setattr(cap_module, "capability", lambda sc, opt: calls.append(dict(opt)) or _Result())
    d = write_study_capability(study, tmp_path / "run")
    assert len(calls) == 1 and calls[0]["directions_deg"] == [0.0, 90.0]
    write_study_capability(study, tmp_path / "run")
    assert len(calls) == 1                                        # same resolved options
    stamp_file = d / "study_capability.json"
    stamp = json.loads(stamp_file.read_text())
    assert stamp["options"]["table_name"] == "extended" and stamp["options"]["level"] == 1
    stale = {**stamp, "options": {**stamp["options"], "table_name": "standard",
                                  "table": stamp["options"]["table"][:12]}}
    stamp_file.write_text(json.dumps(stale))
    write_study_capability(study, tmp_path / "run")
    assert len(calls) == 2                                        # computed under the old default
    stamp_file.write_text(json.dumps({**stamp, "options": study.capability}))
    write_study_capability(study, tmp_path / "run")
    assert len(calls) == 3                                        # stamped with the study's options only
    assert json.loads(stamp_file.read_text()) == stamp


def test_a_study_that_asks_for_capability_gets_it_in_its_folder_and_report(tmp_path):
    from tapm_opt.report import write_report
    from tapm_opt.studies.spec import load_study
    from tapm_opt.studies.store import StudyError
    from tapm_opt.studies.study import run_study

    f = tmp_path / "s.toml"
    f.write_text('[study]\nname = "s"\nscenario = "fpso"\nduration = 4.0\nsegments = 6\n[[sea_states]]\nid = "storm"\n'
                 '[[controllers]]\nname = "PID"\ntype = "pid"\n'
                 '[capability]\ncondition = "intact"\ndirections_deg = [0.0, 90.0]\n')
    study = load_study(f)
    assert study.capability == {"condition": "intact", "directions_deg": [0.0, 90.0]}
    out = tmp_path / "run"
    run_study(study, out, workers=0, progress=False)
    data = json.loads((out / "capability" / "capability.json").read_text())
    assert [c["name"] for c in data["cases"]] == ["mooring", "intact"]
    assert data["directions_deg"] == [0.0, 90.0]
    mtime = (out / "capability" / "capability.json").stat().st_mtime_ns
    run_study(study, out, workers=0, progress=False)                  # same options: not recomputed
    assert (out / "capability" / "capability.json").stat().st_mtime_ns == mtime
    html, md = write_report(out)
    assert "8 Capability" in md.read_text() and "capability" in html.read_text()
    f.write_text(f.read_text().replace('condition = "intact"', 'condition = "everything"'))
    with pytest.raises(StudyError, match="capability"):
        load_study(f)
    f.write_text(f.read_text().replace('condition = "everything"', 'sea_state = "stormy"'))
    with pytest.raises(StudyError, match="capability.sea_state = 'stormy' is not a sea state"):
        load_study(f)
    f.write_text(f.read_text().replace('sea_state = "stormy"', 'workerz = 2'))
    with pytest.raises(StudyError, match="capability.workerz: unknown option"):
        load_study(f)
