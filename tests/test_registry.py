"""The controller-kind registry: one table of kinds read by the builder, the study parser and the
CLI; kinds added in a test and through an installed entry point; the defaults equal what ``tapm
simulate`` builds; the fast default paths give the reference paths' KPIs."""

from __future__ import annotations

import dataclasses
import json
import sys
import textwrap
from dataclasses import dataclass

import numpy as np
import pytest

from tapm_opt.cli import main
from tapm_opt.design import registry
from tapm_opt.design.registry import (ControllerKind, ControllerSpecError, Dimension, auto_move_blocks, build, kind,
                                       register, unregister)
from tapm_opt.interfaces import ControllerStep
from tapm_opt.models.system import System


@pytest.fixture(scope="module")
def fpso_system():
    import tapm_opt

    return System.from_scenario(tapm_opt.load_scenario("fpso"))


# -- a kind written in a test: a PD law on the turret offset -------------------------------------


@dataclass(frozen=True)
class HoldOptions:
    """A proportional-derivative hold of the body origin (test kind)."""

    kp: float = dataclasses.field(default=2e5, metadata={"unit": "N/m", "doc": "stiffness"})
    kd: float = dataclasses.field(default=5e6, metadata={"unit": "N s/m", "doc": "damping"})


class Hold:
    period = None

    def __init__(self, kp: float, kd: float):
        if not kp > 0:
            raise ValueError(f"kp = {kp!r} must be > 0")
        self.kp, self.kd, self._last = kp, kd, None

    def update(self, t, estimate, setpoint):
        c, s = np.cos(estimate.eta[2]), np.sin(estimate.eta[2])
        err_E = np.asarray(estimate.eta[:2]) - np.asarray(setpoint.eta_d[:2])
        err_B = np.array([c * err_E[0] + s * err_E[1], -s * err_E[0] + c * err_E[1]])
        tau = np.array([*(-self.kp * err_B - self.kd * np.asarray(estimate.nu[:2])), 0.0])
        self._last = ControllerStep(t=t, success=True, status="ok", solve_time=None, iterations=0)
        return tau

    def reset(self):
        self._last = None

    def last_step(self):
        return self._last


def _build_hold(system, o, ctx):
    return Hold(float(o.kp), float(o.kd))


HOLD = ControllerKind("hold", "PD hold of the body origin (test)", "Hold", HoldOptions, _build_hold,
                      {"kp": Dimension(1e4, 1e7, log=True)})


@pytest.fixture
def hold_kind():
    register(HOLD, replace=True)
    yield HOLD
    unregister("hold")


def test_builtin_kinds_are_complete():
    ks = registry.kinds()
    assert {"pid", "mpc", "lmpc"} <= set(ks)
    for k in ks.values():
        for d in k.describe():
            assert isinstance(d["doc"], str) and d["doc"], (k.name, d["name"])   # every option says what it is
        for name, dim in k.search_space.items():
            assert name in k.option_names()
            if dim.choices is None:
                assert dim.low <= dim.high


def test_unknown_kind_and_option_are_named():
    with pytest.raises(ControllerSpecError, match=r"lmpcc.*did you mean 'lmpc'"):
        kind("lmpcc")
    with pytest.raises(ControllerSpecError, match=r"controller\.w_thrst: unknown option of lmpc; did you mean 'w_thrust'"):
        registry.options_from_spec({"type": "lmpc", "w_thrst": 3.0})
    with pytest.raises(ControllerSpecError, match="registered already"):
        register(ControllerKind("pid", "again", "PID", HoldOptions, _build_hold))
    with pytest.raises(ControllerSpecError, match="built in"):
        unregister("pid")
    with pytest.raises(ControllerSpecError, match="search_space.kq is not an option"):
        ControllerKind("x", "x", "X", HoldOptions, _build_hold, {"kq": Dimension(0, 1)})
    with pytest.raises(ControllerSpecError, match="log scale needs low > 0"):
        Dimension(0.0, 1.0, log=True)


def test_auto_move_blocks_sum_to_the_horizon_and_grow():
    assert auto_move_blocks(20) is None and auto_move_blocks(5) is None
    for n in (21, 30, 50, 77, 200, 500):
        b = auto_move_blocks(n)
        assert sum(b) == n and len(b) == registry.AUTO_MOVES and min(b) >= 1
        assert b[0] <= b[-1]
    assert auto_move_blocks(50) == (1, 2, 4, 5, 8, 8, 10, 12)


def test_defaults_are_the_tuned_study_defaults(fpso_system):
    lm = build(fpso_system, "lmpc")
    s = lm.settings
    assert lm.qp_solver == "daqp"
    assert (s.w_thrust, s.w_rate, s.w_velocity) == (10.0, 5.0, 5.0)
    assert s.dead_band == pytest.approx(registry.DEAD_BAND_FRACTION * fpso_system.limits.safe_radius)
    assert s.dead_band_damaged == pytest.approx(registry.DEAD_BAND_DAMAGED_FRACTION * s.dead_band)
    assert s.fault_tolerance and s.dead_band_budget and s.move_blocks is None
    nm = build(fpso_system, "mpc")
    assert nm.settings.solver == "rti" and nm.qp_solver == "daqp"
    assert build(fpso_system, {"type": "mpc", "solver": "sqp"}).qp_solver == "piqp"   # the reference path
    assert build(fpso_system, {"type": "lmpc", "horizon": 50}).settings.move_blocks == auto_move_blocks(50)
    assert build(fpso_system, {"type": "lmpc", "horizon": 50, "move_blocks": None}).settings.move_blocks is None
    cat = build(fpso_system, {"type": "mpc", "mooring": "catenary"}).settings
    assert not cat.fault_tolerance and cat.dead_band_damaged is None
    with pytest.raises(ControllerSpecError, match="dead_band_budget = False has nothing to budget"):
        build(fpso_system, {"type": "lmpc", "dead_band": 0.0, "dead_band_budget": False})
    with pytest.raises(ControllerSpecError, match="move_blocks = 'fast'"):
        build(fpso_system, {"type": "lmpc", "move_blocks": "fast"})


def _capture_built(monkeypatch):
    """Record the controller the recipe builds (tapm simulate and study cases)."""
    from tapm_opt.studies import recipe

    built = []
    orig = recipe.build_controller

    def spy(*a, **kw):
        c = orig(*a, **kw)
        built.append(c)
        return c

    monkeypatch.setattr(recipe, "build_controller", spy)
    return built


@pytest.mark.parametrize("kind_name", ["lmpc", "mpc", "pid"])
def test_registry_defaults_equal_what_simulate_builds(monkeypatch, tmp_path, capsys, fpso_system, kind_name):
    built = _capture_built(monkeypatch)
    code = main(["simulate", "fpso", "--controller", kind_name, "--duration", "4", "--sea-state", "normal",
                 "--segments", "4", "--out", str(tmp_path / "run")])
    assert code == 0, capsys.readouterr().err
    (ctrl,) = built
    ref = build(fpso_system, kind_name)
    assert type(ctrl) is type(ref)
    if kind_name == "pid":
        np.testing.assert_allclose(ctrl._tau_limit, ref._tau_limit)
        assert ctrl.modes == ref.modes
    else:
        assert ctrl.settings == ref.settings and ctrl.qp_solver == ref.qp_solver


def test_a_kind_registered_in_a_test_runs_from_simulate_and_a_study(hold_kind, monkeypatch, tmp_path, capsys):
    built = _capture_built(monkeypatch)
    code = main(["simulate", "fpso", "--controller", "hold", "--option", "kp=3e5", "--duration", "30",
                 "--sea-state", "normal", "--segments", "4", "--out", str(tmp_path / "run")])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert isinstance(built[-1], Hold) and built[-1].kp == 3e5
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["controller"] == {"type": "hold", "kp": 300000.0} and summary["kpis"]["offset_max"] > 0
    code = main(["simulate", "fpso", "--controller", "hold", "--option", "kq=1", "--duration", "30",
                 "--out", str(tmp_path / "bad")])
    assert code != 0 and "--option.kq: unknown option of hold; allowed: kp, kd" in capsys.readouterr().err
    study = tmp_path / "s.toml"
    study.write_text(textwrap.dedent("""
        [study]
        name = "hold"
        scenario = "fpso"
        duration = 20.0
        segments = 4
        [[sea_states]]
        id = "normal"
        [[controllers]]
        type = "hold"
        kd = 4e6
    """))
    code = main(["study", "run", str(study), "--out", str(tmp_path / "study"), "--workers", "0", "--no-progress"])
    assert code == 0, capsys.readouterr().err
    rows = (tmp_path / "study" / "kpis.csv").read_text().splitlines()
    assert len(rows) == 2 and ",Hold," in rows[1]   # the kind's label names the controller


def test_a_kind_from_an_installed_entry_point(tmp_path, monkeypatch, capsys):
    """A plugin package: a module defining a kind and a distribution whose entry point in the
    group tapm_opt.controllers names it, found through importlib.metadata."""
    pkg = tmp_path / "site"
    pkg.mkdir()
    (pkg / "tapm_hold_plugin.py").write_text(textwrap.dedent('''
        import dataclasses
        import numpy as np
        from tapm_opt.design.registry import ControllerKind
        from tapm_opt.interfaces import ControllerStep

        @dataclasses.dataclass(frozen=True)
        class Options:
            """Zero thrust (plugin test)."""
            scale: float = dataclasses.field(default=0.0, metadata={"doc": "thrust scale", "unit": "-"})

        class Zero:
            period = None
            def __init__(self, scale): self.scale, self._last = scale, None
            def update(self, t, estimate, setpoint):
                self._last = ControllerStep(t=t, success=True, status="ok", solve_time=None, iterations=0)
                return np.zeros(3) * self.scale
            def reset(self): self._last = None
            def last_step(self): return self._last

        def kind():
            return ControllerKind("zero_plugin", "zero thrust", "Zero", Options,
                                  lambda system, o, ctx: Zero(o.scale))
    '''))
    dist = pkg / "tapm_hold_plugin-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: tapm-hold-plugin\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[tapm_opt.controllers]\nzero_plugin = tapm_hold_plugin:kind\n")
    monkeypatch.syspath_prepend(str(pkg))
    from importlib.metadata import entry_points

    assert any(ep.name == "zero_plugin" for ep in entry_points(group=registry.ENTRY_POINT_GROUP))
    try:
        registry.reload_plugins()
        assert "zero_plugin" in registry.kind_names()
        code = main(["simulate", "fpso", "--controller", "zero_plugin", "--duration", "10", "--sea-state", "calm",
                     "--segments", "4", "--out", str(tmp_path / "run")])
        assert code == 0, capsys.readouterr().err
        k = json.loads((tmp_path / "run" / "summary.json").read_text())["kpis"]
        assert k["thrust_energy"] == pytest.approx(0.0, abs=1e3)   # the plugin's zero thrust reached the plant
    finally:
        unregister("zero_plugin")
        sys.modules.pop("tapm_hold_plugin", None)


def test_docs_controller_table_is_the_registry():
    """docs/controllers.md's table of kinds and options is :func:`registry.markdown_table`."""
    from pathlib import Path

    doc = (Path(__file__).parents[1] / "docs" / "controllers.md").read_text()
    begin, end = "<!-- registry table: begin -->", "<!-- registry table: end -->"
    assert begin in doc and end in doc
    table = doc.split(begin, 1)[1].split(end, 1)[0].strip()
    assert table == registry.markdown_table().strip(), "regenerate with python -m tapm_opt.design.registry"


@pytest.mark.slow
def test_fast_defaults_give_the_reference_paths_kpis():
    """In a short storm (600 s, a line breaking at 300 s) the default paths (linear MPC on DAQP,
    nonlinear MPC's real-time iteration on DAQP) keep the reference paths' (piqp; the converged
    SQP) largest offset within 0.5 m and thrust energy within 1 %."""
    import tapm_opt
    from tapm_opt.config import Fault
    from tapm_opt.studies.closed_loop import ClosedLoopSettings
    from tapm_opt.studies.recipe import run_case_on

    sc = tapm_opt.load_scenario("fpso")
    sc = dataclasses.replace(sc, faults=(Fault(kind="line_break", time=300.0, line="1"),))
    system = System.from_scenario(sc)
    settings = ClosedLoopSettings(duration=600.0, heading="chasing")
    pairs = [("lmpc", {"type": "lmpc", "qp_solver": "piqp"}), ("mpc", {"type": "mpc", "solver": "sqp"})]
    for fast, ref in pairs:
        a = run_case_on(system, fast, settings, sea_state="storm", seed=1, segments=10).kpis
        b = run_case_on(system, ref, settings, sea_state="storm", seed=1, segments=10).kpis
        assert abs(a["offset_max"] - b["offset_max"]) <= 0.5, (fast, a["offset_max"], b["offset_max"])
        assert a["thrust_energy"] == pytest.approx(b["thrust_energy"], rel=0.01), fast
        assert a["solver_failures"] == 0


def test_pid_capacity_fraction_scales_its_command_box(fpso_system):
    """The PID's anti-windup box is ``capacity_fraction`` of the largest X, Y and N the thrusters
    make each alone (0.6 by default, as before the option); it is tunable and checked."""
    from tapm_opt.design import build
    from tapm_opt.design.registry import ControllerSpecError, kind

    top = np.asarray(fpso_system.thrusters.max_tau(), float)
    np.testing.assert_allclose(build(fpso_system, "pid")._tau_limit, 0.6 * top, rtol=1e-12)
    np.testing.assert_allclose(build(fpso_system, {"type": "pid", "capacity_fraction": 0.95})._tau_limit,
                               0.95 * top, rtol=1e-12)
    given = build(fpso_system, {"type": "pid", "capacity_fraction": 0.95, "tau_limit": [1e6, 1e6, 1e8]})
    np.testing.assert_allclose(given._tau_limit, [1e6, 1e6, 1e8])   # an explicit box wins
    for bad in (0.0, 1.2, "half"):
        with pytest.raises(ControllerSpecError, match=r"controller.capacity_fraction = .* must be a number in \(0, 1\]"):
            build(fpso_system, {"type": "pid", "capacity_fraction": bad})
    assert kind("pid").search_space["capacity_fraction"].low == 0.4
