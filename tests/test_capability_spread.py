"""Capability of a spread-moored vessel (a locked turret; ``docs/capability.md`` "Spread
moorings"): mooring alone is the static equilibrium in x, y and psi with the yaw held by the lines,
the default heading follows the turret, and weathervaning a locked turret is refused."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.design.capability import (
    DYNAMIC_ALLOWANCE,
    CapabilityError,
    CapabilityOptions,
    _Engine,
    capability,
    default_heading,
    resolve_options,
)
from tapm_opt.design.loads import mean_environmental_load
from tapm_opt.geometry import ssa


@pytest.fixture(scope="module")
def semi():
    return tapm_opt.load_scenario("semi")


@pytest.fixture(scope="module")
def engine(semi):
    return _Engine(semi, CapabilityOptions(condition="intact"))


@pytest.fixture(scope="module")
def envelope(semi):
    """semi's mooring alone and intact at the default options, a few directions."""
    return capability(semi, condition="intact", directions_deg=(0.0, 40.0, 90.0, 120.0, 240.0))


def test_mooring_alone_at_zero_environment_is_the_field_zero_point(semi, engine):
    """Beaufort 0 (no wind, waves or current): the equilibrium is eta = 0 from every direction's
    start (the heading held at 0, not at the environment's direction), and it passes."""
    e0 = engine.env_at(0.0)
    for d in range(0, 360, 30):
        beta = math.radians(d)
        out = engine.evaluate_mooring(e0, beta, engine.heading("mooring", beta, 0.0), None)
        assert out.ok, (d, out.limit)
        assert np.allclose(out.eta, 0.0, atol=1e-6), (d, out.eta)
        assert math.hypot(*out.offset) < 1e-6


def test_mooring_alone_balances_the_exact_loads_at_its_own_heading(semi, engine):
    """Beaufort 8 from 40 deg: the equilibrium balances the exact catenary (MooringModel.force,
    not the tabulated load the solver uses) and 1.25 x the mean load computed afresh at the
    equilibrium's heading; the same equilibrium from a cold start and continued from calm."""
    model = engine.intact
    beta = math.radians(40.0)
    V = 20.7
    e = engine.env_at(V)
    cold = engine.evaluate_mooring(e, beta, 0.0, None)
    assert cold.ok and cold.eta is not None
    eta = cold.eta
    assert 0.1 < abs(math.degrees(eta[2])) < 15.0                 # the lines yield, a few degrees
    ss = engine.sea_state(e, beta + math.pi)
    tau_env = DYNAMIC_ALLOWANCE * np.asarray(mean_environmental_load(semi, ss, float(eta[2])).total, float)
    res = model.force(eta) + tau_env
    assert np.all(np.abs(res[:2]) <= 1e-5 * np.hypot(*tau_env[:2])), res
    assert abs(res[2]) <= 1e-5 * np.hypot(*tau_env[:2]) * 50.0, res
    guess = None
    for w in np.linspace(0.0, V, 8):                                # continued in the environment
        out = engine.evaluate_mooring(engine.env_at(float(w)), beta, 0.0, guess)
        guess = out.eta
    assert np.allclose(guess, eta, atol=1e-6)


def test_mooring_alone_offset_grows_with_the_environment(engine):
    """Monotone: along the table from calm, the turret offset never decreases and the heading
    stays bounded (on one branch), up to the reported limit."""
    beta = math.radians(120.0)
    last, guess = -1.0, None
    for w in np.linspace(0.0, 32.0, 17):
        out = engine.evaluate_mooring(engine.env_at(float(w)), beta, 0.0, guess)
        assert out.ok, (w, out.limit)
        r = math.hypot(*out.offset)
        assert r >= last - 1e-9, (w, r, last)
        assert abs(out.psi) < math.radians(15.0)
        last, guess = r, out.eta
    assert last > 20.0                                              # near the 25 m circle by then


def test_semi_envelope_is_sane_and_symmetric(semi, envelope):
    """The default envelope: heading fixed at 0; mooring alone holds Beaufort 10-12 (limits at
    the safe circle or a windward line's tension), its heading within +-15 deg; the thrusters never
    below it; the hull's port-starboard symmetry mirrors 120 and 240 deg."""
    res = envelope
    assert res.options.heading == "fixed" and res.options.settings()["heading"] == "fixed"
    moor, intact = res.case("mooring"), res.case("intact")
    assert np.all(moor.beaufort >= 10) and np.all(moor.beaufort <= 12), moor.beaufort
    assert np.all(np.abs(np.degrees(moor.heading)) < 15.0), np.degrees(moor.heading)
    assert all(lim == "offset" or lim.startswith("tension") for lim in moor.limit)
    assert np.all(np.hypot(*moor.offset.T) <= semi.limits.safe_radius + 1e-9)
    assert np.all(intact.wind_speed >= moor.wind_speed) and np.all(intact.heading == 0.0)
    # measured (docs/capability.md): 37.6 m/s head-on, 30.5 m/s on the beam, 32.4 m/s at 120 deg
    assert moor.wind_speed[0] == pytest.approx(37.6, abs=0.2) and moor.beaufort[0] == 12
    assert moor.wind_speed[2] == pytest.approx(30.5, abs=0.2) and moor.beaufort[2] == 10
    i, j = 3, 4                                                     # 120 and 240 deg
    assert moor.beaufort[i] == moor.beaufort[j] and moor.wind_speed[i] == pytest.approx(moor.wind_speed[j], abs=1e-9)
    assert moor.heading[i] == pytest.approx(-moor.heading[j], abs=1e-6)
    assert np.allclose(moor.offset[i], moor.offset[j] * [1.0, -1.0], atol=1e-6)
    assert float(ssa(moor.heading[0])) == pytest.approx(0.0, abs=1e-9)   # head-on: no yaw


def test_default_heading_follows_the_turret(semi):
    fpso = tapm_opt.load_scenario("fpso")
    assert CapabilityOptions().heading is None
    assert default_heading(semi) == "fixed" and default_heading(fpso) == "weathervane"
    assert resolve_options(semi, CapabilityOptions()).heading == "fixed"
    assert resolve_options(fpso, CapabilityOptions()).heading == "weathervane"
    assert resolve_options(fpso, CapabilityOptions(heading="fixed")).heading == "fixed"
    assert resolve_options(semi, CapabilityOptions(heading="fixed", fixed_heading_deg=10.0)).fixed_heading_deg == 10.0


def test_weathervane_on_a_locked_turret_is_refused(semi):
    with pytest.raises(CapabilityError, match="heading = 'weathervane'.*turret.mode = 'locked'"):
        capability(semi, heading="weathervane", condition="intact", directions_deg=(0.0,))
    with pytest.raises(CapabilityError, match="heading = 'weathervane'"):
        _Engine(semi, CapabilityOptions(heading="weathervane"))



def test_cli_default_heading_and_refusal(tapm, capsys, tmp_path):
    out = tmp_path / "cap"
    code, _, err = tapm(capsys, "capability", "semi", "--out", str(out), "--heading", "weathervane")
    assert code == 2 and "--heading" in err and "locked" in err
    assert not out.exists()
    code, _, err = tapm(capsys, "capability", "semi", "--out", str(out), "--condition", "intact",
                           "--directions", "0,90", "--workers", "1", "--json")
    assert code == 0, err
    data = json.loads((out / "capability.json").read_text())
    assert data["settings"]["heading"] == "fixed"
    moor = data["cases"][0]
    assert moor["name"] == "mooring" and min(moor["beaufort"]) >= 10


def _semi_study(tmp_path, extra: str = ""):
    f = tmp_path / "s.toml"
    f.write_text('[study]\nname = "s"\nscenario = "semi"\nduration = 4.0\nsegments = 6\n[[sea_states]]\n'
                 'id = "operating"\n[[controllers]]\nname = "PID"\ntype = "pid"\n'
                 f'[capability]\ncondition = "intact"\ndirections_deg = [0.0, 90.0]\n{extra}')
    return f


def test_study_weathervane_on_a_locked_turret_is_refused(tmp_path):
    from tapm_opt.studies.spec import load_study
    from tapm_opt.studies.store import StudyError

    with pytest.raises(StudyError, match="capability.heading = 'weathervane'"):
        load_study(_semi_study(tmp_path, 'heading = "weathervane"\n'))


def test_study_stamp_holds_the_resolved_heading(tmp_path, monkeypatch):
    """The stamp holds the heading resolved by the turret ("fixed" for semi); a result stamped
    under the former default (weathervane) is recomputed."""
    import tapm_opt.design.capability as cap_module
    from tapm_opt.studies.runner import write_study_capability
    from tapm_opt.studies.spec import load_study

    study = load_study(_semi_study(tmp_path))
    calls = []

    class _Result:
        def data_files(self):
            return {"capability.json": b"{}\n", "capability.csv": b"direction_deg\n"}

    monkeypatch.setattr(cap_module, "capability", lambda sc, opt: calls.append(dict(opt)) or _Result())
    d = write_study_capability(study, tmp_path / "run")
    stamp_file = d / "study_capability.json"
    stamp = json.loads(stamp_file.read_text())
    assert stamp["options"]["heading"] == "fixed" and len(calls) == 1
    write_study_capability(study, tmp_path / "run")
    assert len(calls) == 1
    stamp_file.write_text(json.dumps({**stamp, "options": {**stamp["options"], "heading": "weathervane"}}))
    write_study_capability(study, tmp_path / "run")
    assert len(calls) == 2


def test_level3_heading_defaults_by_the_turret_and_refuses_weathervaning_a_spread_mooring(semi):
    """Level 3 (Python and studies) resolves its heading as Level 1 does: by the turret when not
    given, a weathervane on a locked turret refused naming the heading."""
    from tapm_opt.design.capability import CapabilityError
    from tapm_opt.studies.capability_level3 import Level3Options, study_level3_options

    fpso = tapm_opt.load_scenario("fpso")
    assert Level3Options().heading is None
    assert Level3Options().resolved(semi).heading == "fixed"
    assert Level3Options().resolved(fpso).heading == "weathervane"
    assert Level3Options(heading="fixed").resolved(fpso).heading == "fixed"
    with pytest.raises(CapabilityError, match="weathervane"):
        Level3Options(heading="weathervane").resolved(semi)
    with pytest.raises(CapabilityError, match="heading"):
        Level3Options(heading="bow")
    (opt,) = study_level3_options({"level": 3, "controllers": ["pid"]})
    assert opt.resolved(semi).settings()["heading"] == "fixed"
