"""Capability in the time domain (Level 3, ``tapm capability --level 3``), the Level 1 thrust losses and
the table that does not saturate (``docs/capability.md``).

The Level 3 runs here are short (150 s after a 30 s warm-up) on aamo4 with 6 FEM segments per line
and a coarse table, so that the search, the limits and the files are checked in seconds; the
documented fpso envelopes are the 3-hour runs of the docs.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.cli import main
from tapm_opt.config import scenario_from_dict, scenario_to_dict
from tapm_opt.design.capability import (
    BEAUFORT_TABLE,
    EXTENDED_TABLE,
    EXTENSION_ROWS,
    CapabilityError,
    CapabilityOptions,
    capability,
)
from tapm_opt.design.thrust_losses import (
    BETA_MISC,
    apply_level1_losses,
    default_diameter,
)
from tapm_opt.errors import TapmError
from tapm_opt.geometry import body_from_turret, ssa, turret_offset
from tapm_opt.models.system import System, ThrusterSet
from tapm_opt.studies.capability_level3 import Level3Options, capability_level3, run_row

COARSE = tuple(r for r in EXTENDED_TABLE if r.number in (0, 3, 4, 6, 8, 9, 10, 11, 12, 13, 15))
FAST = {"duration": 150.0, "warmup": 30.0, "segments": 6, "table": COARSE, "heading": "fixed"}


@pytest.fixture(scope="module")
def aamo4():
    return tapm_opt.load_scenario("aamo4")


@pytest.fixture(scope="module")
def level3(aamo4):
    """PID on aamo4 at the heading 0 from three directions: ahead, quartering, on the beam."""
    return capability_level3(aamo4, controller="pid", directions_deg=(0.0, 45.0, 90.0), workers=2, **FAST)


# -- Level 3 ---------------------------------------------------------------------------------------

def test_level3_never_above_level1_without_losses_at_the_same_limits(aamo4, level3):
    """Level 1 without losses, with the limits Level 3 checks (offset, the scenario's
    tension_utilisation x MBS, no riser) and the dynamic allowance 1, is the static relaxation of the
    time-domain check: Level 3 may not exceed it in any direction."""
    res = level3
    same = capability(aamo4, CapabilityOptions(condition="intact", directions_deg=(0.0, 45.0, 90.0), table=COARSE,
                                               heading="fixed", riser=False, dynamic_allowance=1.0,
                                               tension_utilisation=aamo4.limits.tension_utilisation))
    bound = same.case("intact").beaufort
    assert np.array_equal(bound, res.level1_bound.case("intact").beaufort)
    assert np.all(res.beaufort <= bound), (res.beaufort, bound)
    # the search found a limit inside the table, not the table's top or bottom: the comparison says something
    assert np.all(res.beaufort >= 0) and all(d.limit != "table" for d in res.directions)
    # every direction's deciding runs and the row above: the reported limits hold and are broken
    R, util = aamo4.limits.safe_radius, aamo4.limits.tension_utilisation
    for d in res.directions:
        assert d.decided.passed and d.decided.offset_max <= R and d.decided.util_max <= util
        assert not d.above.passed and d.above.number == COARSE[[r.number for r in COARSE].index(d.beaufort) + 1].number
        lim = d.above.limit
        assert (d.above.offset_max > R if lim == "offset" else
                d.above.util_max > util if lim.startswith("tension") else
                d.above.heading_error_max > 5.0 if lim == "heading" else lim.startswith(("line break", "diverged")))
        assert d.decided.heading_error_max <= 5.0


def _by_hand(sc, row, direction_deg: float, seed: int = 1) -> tuple[float, float, float]:
    """The closed loop of a Level 3 run built by hand: the row's environment coming from
    ``direction_deg``, PID, the FEM plant started at the field zero point at the heading 0;
    the largest LF turret offset [m], the largest fairlead tension over MBS and the largest heading
    error [deg] after the warm-up."""
    from tapm_opt.plant.simulator import Plant
    from tapm_opt.studies.closed_loop import ClosedLoopSettings, run_closed_loop
    from tapm_opt.studies.controllers import build_controller

    to = math.radians(direction_deg) + math.pi
    ss = dataclasses.replace(sc.sea_state(), id="by-hand", Hs=row.Hs, Tp=row.Tp, wind_speed=row.wind_speed,
                             current_speed=row.current_speed, wave_direction=float(ssa(to)),
                             wind_direction=float(ssa(to)), current_direction=float(ssa(to)))
    system = System.from_scenario(dataclasses.replace(sc, sea_states=(ss, *sc.sea_states), faults=()))
    psi = 0.0                                     # the fixed heading
    bx, by = body_from_turret((0.0, 0.0), psi, sc.turret.position)
    plant = Plant(system, sea_state="by-hand", seed=seed, segments=FAST["segments"], eta0=(bx, by, psi), faults=())
    settings = ClosedLoopSettings(duration=FAST["warmup"] + FAST["duration"], eta_d=(0.0, 0.0, psi))
    res = run_closed_loop(plant, build_controller(system, "pid"), settings, system=system)
    keep = res.time >= FAST["warmup"] - 1e-9
    eta = np.column_stack([res["x"], res["y"], res["psi"]])[keep]
    px, py = turret_offset(eta, sc.turret.position)
    mbs = {ln.id: sc.line_type(ln).MBS for ln in sc.lines}
    util = max(float(np.max(res[f"T_fairlead[{i}]"][keep])) / m for i, m in mbs.items())
    head = float(np.degrees(np.max(np.abs(ssa(res["psi"][keep] - psi)))))
    return float(np.max(np.hypot(px, py))), util, head


def test_a_direction_checked_by_a_closed_loop_run_at_the_envelope_and_one_row_above(aamo4, level3):
    d = level3.directions[0]                       # ahead: one row up a line is over its limit
    rows = {r.number: r for r in COARSE}
    above = COARSE[[r.number for r in COARSE].index(d.beaufort) + 1]
    R, util = aamo4.limits.safe_radius, aamo4.limits.tension_utilisation
    off, u, head = _by_hand(aamo4, rows[d.beaufort], d.direction_deg)
    assert off <= R and u <= util and head <= 5.0, (off, u, head)   # held at the envelope ...
    assert off == pytest.approx(d.decided.offset_max, rel=1e-9) and u == pytest.approx(d.decided.util_max, rel=1e-9)
    off2, u2, head2 = _by_hand(aamo4, above, d.direction_deg)
    assert off2 > R or u2 > util or head2 > 5.0, (off2, u2, head2)   # ... not one row above
    # (a line that breaks counts at its breaking tension in the KPI, above the logged samples)
    assert off2 == pytest.approx(d.above.offset_max, rel=1e-9) and u2 <= d.above.util_max + 1e-12
    # run_row repeats the search's run of one row
    again = run_row(aamo4, Level3Options(controller="pid", directions_deg=(d.direction_deg,), **FAST),
                    d.direction_deg, d.beaufort)
    assert again.passed and again.offset_max == d.decided.offset_max


def test_a_row_with_several_seeds_reports_each_seeds_maxima(aamo4, level3):
    """``seeds = 3``: the row at the envelope runs seeds 1, 2, 3 (all pass), reports each seed's
    largest offset and tension — the first seed's is the one-seed search's run, the seeds are
    different realisations, the row's figures are their maxima — and writes them to the JSON."""
    d = level3.directions[0]
    r = run_row(aamo4, Level3Options(controller="pid", directions_deg=(d.direction_deg,), seeds=3, **FAST),
                d.direction_deg, d.beaufort)
    assert r.seeds == (1, 2, 3) and len(r.offset_by_seed) == 3 and len(r.util_by_seed) == 3
    assert r.offset_by_seed[0] == d.decided.offset_max and r.util_by_seed[0] == d.decided.util_max
    assert r.offset_max == max(r.offset_by_seed) and r.util_max == max(r.util_by_seed)
    assert len(set(r.offset_by_seed)) == 3                     # three realisations, three maxima
    js = r.as_json()
    assert js["offset_max_by_seed_m"] == list(r.offset_by_seed) and js["util_max_by_seed"] == list(r.util_by_seed)


def test_level3_files_and_report_section(aamo4, level3, tmp_path):
    from tapm_opt.report.capability import study_capability_section, write_level3
    from tapm_opt.report.document import render_markdown

    paths = write_level3(level3, tmp_path / "capability")
    assert sorted(p.name for p in paths) == ["capability_level3_pid.csv", "capability_level3_pid.json",
                                             "capability_level3_pid.png"]
    data = json.loads((tmp_path / "capability" / "capability_level3_pid.json").read_text())
    assert data["format"] == "tapm-capability-level3/1" and data["beaufort"] == [int(b) for b in level3.beaufort]
    assert data["settings"]["duration_s"] == 150.0 and data["directions"][0]["above"]["limit"]
    csv = (tmp_path / "capability" / "capability_level3_pid.csv").read_text().splitlines()
    assert csv[0].startswith("direction_deg,controller,beaufort") and len(csv) == 4
    blocks, figs = study_capability_section(tmp_path)
    md = render_markdown(blocks, "files")
    assert "Level 3" in md and "PID" in md and len(figs) == 1


def test_level3_after_a_line_loss_holds_no_more_than_intact_and_its_static_bound(aamo4, level3, tmp_path):
    """``failed_line``: the system after the loss of line 1 from the start (aamo4's 4 lines: 3 left).
    It holds no more than the intact system in any direction, nor more than Level 1's case
    ``line 1`` after the failure with the allowance 1; its files carry the line in their name and
    the report draws the two cases apart."""
    from tapm_opt.report.capability import study_capability_section, write_level3
    from tapm_opt.report.document import render_markdown

    res = capability_level3(aamo4, controller="pid", directions_deg=(0.0, 45.0, 90.0), workers=2,
                            failed_line="1", **FAST)
    assert res.options.case == "line 1"
    assert np.all(res.beaufort <= level3.beaufort), (res.beaufort, level3.beaufort)
    assert np.any(res.beaufort < level3.beaufort)                  # one line of four does matter somewhere
    bound = res.level1_bound.case("line 1")
    assert bound.failed == "1" and np.all(res.beaufort <= bound.beaufort)
    assert res.level1.options.post_failure_only and res.level1.options.condition == "line 1"
    assert [c.name for c in res.level1.cases] == ["mooring", "intact", "line 1"]   # that case alone
    d = res.directions[0].decided or res.directions[0].above
    assert d is not None
    write_level3(level3, tmp_path / "capability")
    paths = write_level3(res, tmp_path / "capability")
    assert sorted(p.name for p in paths) == ["capability_level3_pid_line1.csv", "capability_level3_pid_line1.json",
                                             "capability_level3_pid_line1.png"]
    data = json.loads((tmp_path / "capability" / "capability_level3_pid_line1.json").read_text())
    assert data["settings"]["failed_line"] == "1"
    blocks, figs = study_capability_section(tmp_path)
    md = render_markdown(blocks, "files")
    assert "after the loss of line 1" in md and len(figs) == 2
    with pytest.raises(CapabilityError, match="failed_line = '7' is not a line of scenario"):
        capability_level3(aamo4, controller="pid", directions_deg=(0.0,), failed_line="7", **FAST)


def _level3_study(tmp_path, capability_toml: str):
    from tapm_opt.studies.spec import load_study

    f = tmp_path / "s.toml"
    f.write_text('[study]\nname = "s"\nscenario = "aamo4"\nduration = 4.0\nsegments = 6\n[[sea_states]]\nid = "tidal"\n'
                 '[[controllers]]\nname = "PID"\ntype = "pid"\n[capability]\n' + capability_toml)
    return load_study(f)


def test_a_study_asks_for_level3_and_gets_each_controllers_files_once(tmp_path, level3, monkeypatch):
    """``[capability]`` with ``level = 3``: one computation per controller kind into
    DIR/capability (the options the same as ``tapm capability --level 3``), not repeated while the
    options stay, and an earlier table's files removed when the table changes."""
    import tapm_opt.studies.capability_level3 as lv3_mod
    from tapm_opt.report.capability import study_capability_section
    from tapm_opt.report.document import render_markdown
    from tapm_opt.studies.runner import write_study_capability

    table = ('level = 3\ncontrollers = ["pid"]\nduration = 150.0\nwarmup = 30.0\nsegments = 6\nheading = "fixed"\n'
             'directions_deg = [0.0, 45.0, 90.0]\n')
    study = _level3_study(tmp_path, table)
    calls = []
    real = lv3_mod.capability_level3

    def counted(sc, opt, **kw):
        calls.append(opt)
        assert dataclasses.replace(opt, table=COARSE, workers=2) == Level3Options(
            controller="pid", directions_deg=(0.0, 45.0, 90.0), workers=2, **FAST)
        return level3                     # the module's run of the same options on the coarse table

    monkeypatch.setattr(lv3_mod, "capability_level3", counted)
    out = tmp_path / "run"
    d = write_study_capability(study, out, workers=2)
    assert len(calls) == 1 and calls[0].table == EXTENDED_TABLE      # the study's default table
    assert sorted(p.name for p in d.iterdir()) == ["capability_level3_pid.csv", "capability_level3_pid.json",
                                                    "study_capability_level3_pid.json"]
    write_study_capability(study, out, workers=2)
    assert len(calls) == 1                                              # the same options: kept
    blocks, figs = study_capability_section(out)
    assert "Level 3" in render_markdown(blocks, "files") and len(figs) == 1
    # another controller added: only its computation runs
    two = _level3_study(tmp_path, table.replace('["pid"]', '["pid", "lmpc"]'))
    monkeypatch.setattr(lv3_mod, "capability_level3",
                        lambda sc, opt, **kw: calls.append(opt) or dataclasses.replace(level3, options=opt))
    write_study_capability(two, out, workers=2)
    assert [c.controller for c in calls] == ["pid", "lmpc"]
    assert (d / "capability_level3_lmpc.json").is_file()
    # back to Level 1: the Level 3 files go, the Level 1 ones come
    monkeypatch.setattr(lv3_mod, "capability_level3", real)
    import tapm_opt.design.capability as cap_mod

    class _Result:
        def data_files(self):
            return {"capability.json": b"{}\n", "capability.csv": b"direction_deg\n"}

    monkeypatch.setattr(cap_mod, "capability", lambda sc, opt: _Result())
    write_study_capability(_level3_study(tmp_path, 'condition = "intact"\n'), out)
    assert sorted(p.name for p in d.iterdir()) == ["capability.csv", "capability.json", "study_capability.json"]
    # no [capability] any more: the study's own files go, a file it did not write stays
    (d / "notes.txt").write_text("mine")
    none = dataclasses.replace(_level3_study(tmp_path, 'condition = "intact"\n'), capability=None)
    assert write_study_capability(none, out) is None
    assert sorted(p.name for p in d.iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("table, text", [
    ('level = 3\ncontrollers = "pid"\n', "capability.controllers = 'pid' must be a non-empty list"),
    ('level = 3\ncontrollers = ["pid", "lqr"]\n', "'lqr' is not a controller kind"),
    ('level = 3\nduration = -5.0\n', "capability.duration = -5.0 must be a number > 0"),
    ('level = 3\ncondition = "intact"\n', "capability.condition: unknown option with level = 3"),
    ('level = 3\nsea_state = "storm"\n', "capability.sea_state = 'storm' is not a sea state"),
    ('controllers = ["pid"]\n', "capability.controllers: unknown option"),
    ('condition = "line 9"\n', "capability.condition = 'line 9': '9' is not a line of scenario 'aamo4'"),
    ('level = 3\nfailed_line = "9"\n', "capability.failed_line = '9' is not a line of scenario 'aamo4'"),
])
def test_a_bad_level3_study_table_is_refused_naming_the_option(tmp_path, table, text):
    from tapm_opt.studies.store import StudyError

    with pytest.raises(StudyError, match=text.replace("(", r"\(").replace("[", r"\[")):
        _level3_study(tmp_path, table)


# -- bad input ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("kw, text", [
    ({"controller": "lqr"}, "controller = 'lqr'"), ({"duration": 0.0}, "duration = 0.0"),
    ({"warmup": -1.0}, "warmup = -1.0"), ({"seeds": 0}, "seeds = 0"), ({"segments": 0}, "segments = 0"),
    ({"heading": "north"}, "heading = 'north'"), ({"directions_deg": (0.0, 360.0)}, "must not repeat"),
    ({"heading_tolerance": 0.0}, "heading_tolerance = 0.0"),
    ({"tension_utilisation": 1.5}, "tension_utilisation = 1.5"), ({"table": "big"}, "table = 'big'"),
    ({"losses": "no"}, "losses = 'no'"), ({"thruster_diameter": math.nan}, "thruster_diameter = nan"),
    ({"failed_line": ""}, "failed_line = ''"),
])
def test_bad_level3_options_are_typed_errors_naming_the_option(kw, text):
    with pytest.raises(CapabilityError, match=text) as exc:
        Level3Options(**kw)
    assert isinstance(exc.value, TapmError)


@pytest.mark.parametrize("args, text", [
    (("--level", "3", "--duration", "-5"), "--duration"), (("--level", "3", "--seeds", "0"), "--seeds"),
    (("--level", "3", "--controller", "lqr"), "--controller"), (("--duration", "600"), "--duration"),
    (("--level", "3", "--condition", "all"), "--condition"), (("--level", "3", "--warmup", "nan"), "--warmup"),
    (("--thruster-diameter", "4"), "--thruster-diameter"), (("--level", "4"), "--level"),
    (("--table", "huge"), "--table"), (("--level", "3", "--heading-tolerance", "0"), "--heading-tolerance"),
    (("--level", "3", "--failed-line", "9"), "--failed-line"), (("--failed-line", "1"), "--failed-line"),
])
def test_cli_refuses_bad_level3_and_loss_options_naming_them(capsys, tmp_path, args, text):
    out = tmp_path / "cap"
    code = main(["capability", "aamo4", "--out", str(out), *args])
    err = capsys.readouterr().err
    assert code == 2 and text in err, err
    assert not out.exists()


# -- Level 1 thrust losses -------------------------------------------------------------------------

def test_losses_apply_the_factor_and_the_interaction_sectors_of_the_standard():
    sc = tapm_opt.load_scenario("fpso")
    lossy, info = apply_level1_losses(sc)
    assert info.beta_misc == BETA_MISC == 0.9
    for a, b in zip(sc.thrusters, lossy.thrusters):
        assert b.max_thrust == pytest.approx(0.9 * a.max_thrust)
    D = default_diameter(1.2e6)
    assert D == pytest.approx(math.sqrt(4 * 1.2e6 / (math.pi * 5.0e4)))        # 5.53 m: 15 D = 83 m
    pairs = {(p["flushing"], p["flushed"]): p for p in info.pairs}
    # aft row y = -14, 0, 14: A1 pushing to port (-90 deg) flushes A2 14 m away and A3 28 m away
    assert pairs[("A1", "A2")]["centre_deg"] == pytest.approx(-90.0)
    assert pairs[("A1", "A2")]["half_width_deg"] == pytest.approx(math.degrees(math.atan(0.1 + D / 14.0)))
    assert pairs[("A1", "A3")]["half_width_deg"] == pytest.approx(math.degrees(math.atan(0.1 + D / 28.0)))
    assert pairs[("A2", "A1")]["centre_deg"] == pytest.approx(90.0)
    assert not any({p["flushing"][0], p["flushed"][0]} == {"A", "F"} for p in info.pairs)   # 268 m apart
    assert len(info.pairs) == 12
    # surge is untouched by the sectors (all across the beam): the capacity is the factor's
    cap0, cap1 = ThrusterSet.from_scenario(sc).max_tau(), ThrusterSet.from_scenario(lossy).max_tau()
    assert cap1[0] == pytest.approx(0.9 * cap0[0], rel=1e-6)
    assert cap1[1] < 0.9 * cap0[1] * 0.95                                         # sway loses more
    # a larger spacing than 15 D: no sector
    _, far = apply_level1_losses(sc, diameter=0.5)
    assert far.pairs == () and far.sectors == {}


def test_losses_lower_level1_by_the_factors_applied():
    """Thrust factor alone (a diameter too small for any interaction): Level 1 with losses is Level 1
    of the scenario whose thrusters were scaled by 0.9 by hand; with the sectors, lower still across
    the beam, never higher anywhere."""
    d = scenario_to_dict(tapm_opt.load_scenario("aamo4"))
    for t in d["thrusters"]:
        t["max_thrust"] *= 0.25
        t["max_reverse_thrust"] *= 0.25
    weak = scenario_from_dict(d)
    kw = {"heading": "fixed", "condition": "intact", "directions_deg": (0.0, 60.0, 90.0, 180.0)}
    base = capability(weak, **kw)
    factor = capability(weak, losses=True, thruster_diameter=0.1, **kw)
    scaled = dataclasses.replace(weak, thrusters=tuple(
        dataclasses.replace(t, max_thrust=0.9 * t.max_thrust, max_reverse_thrust=0.9 * t.max_reverse_thrust)
        for t in weak.thrusters))
    by_hand = capability(scaled, **kw)
    assert np.allclose(factor.case("intact").wind_speed, by_hand.case("intact").wind_speed)
    w0, w1 = base.case("intact").wind_speed, factor.case("intact").wind_speed
    thrust = np.array([lim == "thrust" for lim in base.case("intact").limit])
    assert thrust.any() and np.all(w1[thrust] < w0[thrust] - 0.05) and np.all(w1 <= w0 + 1e-9)
    assert factor.info["thrust_losses"]["beta_misc"] == 0.9 and base.info["thrust_losses"] is None
    full = capability(weak, losses=True, **kw)                                   # with the sectors
    w2 = full.case("intact").wind_speed
    # never above the factor alone but for the bisection's tolerance (with sectors the exact check of
    # the pieces decides where the allocator fails, and it finds a little more than the allocator)
    assert np.all(w2 <= w1 + 0.1 + 1e-9) and np.all(w2 < w0 + 1e-9)
    assert factor.case("mooring").wind_speed.tolist() == base.case("mooring").wind_speed.tolist()


# -- the table that does not saturate -----------------------------------------------------------------

def test_extension_continues_the_standard_table():
    assert EXTENDED_TABLE[:12] == BEAUFORT_TABLE and [r.number for r in EXTENSION_ROWS] == [12, 13, 14, 15]
    for r in BEAUFORT_TABLE[1:]:                     # the wind relation the extension uses gives every row
        assert math.floor(10 * 0.836 * (r.number + 0.5) ** 1.5) / 10 == r.wind_speed
    top = BEAUFORT_TABLE[-1]
    for r in EXTENSION_ROWS:
        assert r.Hs == pytest.approx(top.Hs * (r.wind_speed / top.wind_speed) ** 2, abs=0.05)
        assert r.Hs <= 30.0 and r.current_speed == top.current_speed
    assert np.all(np.diff([r.wind_speed for r in EXTENDED_TABLE]) > 0)


def test_fpso_weathervaning_envelope_ends_inside_the_extended_table():
    """fpso bow into the weather holds the standard table's top row (the table is too weak for it);
    with the extension the envelope ends where the thrust runs out."""
    sc = tapm_opt.load_scenario("fpso")
    std = capability(sc, condition="intact", directions_deg=(0.0,), table="standard")
    ext = capability(sc, condition="intact", directions_deg=(0.0,))
    assert std.case("intact").beaufort[0] == 11 and std.case("intact").limit[0] == "table"
    b = int(ext.case("intact").beaufort[0])
    assert 11 < b < 15 and ext.case("intact").limit[0] == "thrust"
    assert ext.info["table"][-1]["number"] == 15 and ext.options.settings()["table_name"] == "extended"


def test_thrust_with_sectors_is_checked_exactly_where_the_allocator_gives_up():
    """fpso with the losses, pure sway: by hand the six azimuths deliver about 5.6 MN (A1 and F1
    across the beam, the others at their sector edges, 63.7/116.3 and 56.9/123.1 deg, the aft row
    turned down to balance the yaw moment); the convex hull of the capacity ends at 5.69 MN. The
    allocator from rest stops near 4.7 MN; the capability's exact check of the sector pieces does
    not."""
    from tapm_opt.design.capability import _Engine

    sc = tapm_opt.load_scenario("fpso")
    eng = _Engine(sc, CapabilityOptions(losses=True, condition="intact"))
    alloc, _ = eng.thrust(None)
    tau = np.array([0.0, 5.5e6, 0.0])
    alloc.reset()
    alloc.allocate(tau)
    assert np.abs(alloc.allocate(tau).slack[1]) > 0.1e6           # the allocator alone falls short
    assert eng.attained(None, tau) and eng.exact_calls == 1
    assert eng.thrusters.max_tau()[1] == pytest.approx(5.69e6, rel=2e-3)
    assert not eng.attained(None, np.array([0.0, 5.8e6, 0.0]))    # beyond the hull
