"""The wave-frequency allowance ``k sigma`` and the anchor estimation's ``Delta T_v`` with the hull's
heave, roll and pitch (``vessel.wave_motion.model = "six_dof"``).

* The horizontal model's ``k sigma`` is the formula it was, to the bit, and ``tapm setpoint`` hands
  it no vertical motion.
* ``dT/dz`` of the line model (:meth:`MooringModel.depth_sensitivity`) against finite differences
  of the catenary in the fairlead's height, on fpso's composite and ren8's homogeneous lines.
* A hull that only heaves gives ``k sigma = k |dT/dz| sigma_heave`` for every line.
* The six-degree-of-freedom ``k sigma`` against the FEM plant's fairlead tension in the storm: the
  quasi-static allowance is far below the dynamic tension in 1000 m of water either way, but with
  heave, roll and pitch it follows the FEM's line-to-line pattern and its largest line.
* The anchor estimation's range bias along a record moves the FEM lines with the heave, roll and
  pitch when the scenario has them.
"""

from __future__ import annotations

import math

import _six_dof
import numpy as np
import pytest
from _six_dof import six_dof

import tapm_opt
from tapm_opt.control.setpoint_opt import SetpointProblem, WorkingPoint
from tapm_opt.design import setpoint as spm
from tapm_opt.design.tables import weathervane_heading
from tapm_opt.estimation.reliability import gumbel_k
from tapm_opt.geometry import body_from_turret
from tapm_opt.models.system import System
from tapm_opt.plant.environment import Environment, WaveField
from tapm_opt.plant.mooring_fem import MooringFEM

fpso, fpso6 = _six_dof.fpso, _six_dof.fpso6   # fixtures: fpso horizontal, fpso6 in six degrees of freedom


def _problem(sc, broken=()):
    system = System.from_scenario(sc)
    return SetpointProblem(system.with_broken(broken) if broken else system, None, "unified")


def _wp(prob, psi, p):
    return WorkingPoint(p=np.asarray(p, float), psi=psi, tau_env=np.zeros(3),
                        ksigma_lines=np.zeros(len(prob.line_ids)))


def _old_ksigma(prob, wp, p, motion):
    """The line allowance as it was computed before the vertical motion (lines only, no riser)."""
    _, G = prob.linearise(wp.at(p))
    scale = prob.sigma_b[prob.has_index]
    Gs = -(G * scale[:, None])
    m = int(np.sum(prob.has_index))
    resp = np.hstack([motion @ Gs[:m].T, motion @ Gs[m:].T])
    sigma = resp.std(axis=0)
    wd = resp - resp.mean(axis=0)
    n = np.sum((wd[:-1] < 0) & (wd[1:] >= 0), axis=0) * 1.0
    k = np.array([gumbel_k(max(v, 2.0)) for v in n])
    out = np.zeros(len(prob.line_ids))
    out[prob.has_index] = (k * sigma)[:m]
    return out


# --- the horizontal model: unchanged --------------------------------------------------------------

def test_horizontal_ksigma_is_the_old_formula_to_the_bit(fpso):
    ss = fpso.sea_state("storm")
    psi, p = 0.4, np.array([-12.0, 5.0])
    prob = _problem(fpso, ("2",))
    motions, vert = spm._hull_wf(fpso, ss, psi, 1200.0, 0.5, 3, [fpso.turret.position])
    assert vert is None                                        # horizontal: no heave, roll or pitch
    ks, _, _ = spm.wave_frequency_ksigma(prob, _wp(prob, psi, p), p, motions[0], 1200.0)
    assert np.array_equal(ks, _old_ksigma(prob, _wp(prob, psi, p), p, motions[0]))
    assert np.all(ks > 0)


def test_static_setpoint_passes_the_vertical_motion_only_with_six_dof(fpso, fpso6, monkeypatch):
    seen = []

    def spy(*args, **kw):
        seen.append(args[6] if len(args) > 6 else kw.get("vertical"))
        raise RuntimeError("stop")

    monkeypatch.setattr(spm, "wave_frequency_ksigma", spy)
    for sc in (fpso, fpso6):
        with pytest.raises(RuntimeError, match="stop"):
            spm.static_setpoint(sc, "normal", "quadratic", exposure=600.0)
    assert seen[0] is None
    assert seen[1] is not None and seen[1].shape == (int(600.0 / 0.5), 3) and np.std(seen[1][:, 0]) > 0.1


# --- dT/dz of the line model -----------------------------------------------------------------------

@pytest.mark.parametrize("name", ["fpso", "ren8"])
def test_depth_sensitivity_is_the_finite_difference_of_the_catenary(name):
    sc = tapm_opt.load_scenario(name)
    lines = System.from_scenario(sc).lines
    h = 0.01
    for eta in (np.zeros(3), np.array([25.0, -15.0, 0.3])):
        _, _, XF = lines.spans(eta)
        kz = lines.depth_sensitivity(eta)
        fd = np.array([(lines.line_solver(i, ZF=float(lines.ZF[i]) - h)(np.array([XF[i]])).TF[0]
                        - lines.line_solver(i, ZF=float(lines.ZF[i]) + h)(np.array([XF[i]])).TF[0]) / (2 * h)
                       for i in range(lines.n_lines)])          # a fairlead h deeper: ZF - h
        assert np.allclose(kz, fd, rtol=1e-5, atol=0.0), (kz, fd)
        assert np.all(kz < 0)                                   # a deeper fairlead slackens a hanging line


# --- a hull that only heaves -------------------------------------------------------------------------

def test_pure_heave_gives_k_times_dTdz_times_sigma_heave(fpso6, monkeypatch):
    ss = fpso6.sea_state("storm")
    psi, p = 0.2, np.array([10.0, -4.0])
    rng = np.random.default_rng(5)
    w, ph, a = rng.uniform(0.4, 0.9, 30), rng.uniform(0, 2 * math.pi, 30), rng.uniform(0.1, 0.3, 30)

    def heave_only(self, t, psi):
        t = np.asarray(t, float)
        out = np.zeros(t.shape + (3,))
        out[..., 0] = np.cos(np.multiply.outer(t, w) + ph) @ a
        return out

    monkeypatch.setattr(WaveField, "eta_wf", lambda self, t, psi: np.zeros(np.shape(t) + (3,)))
    monkeypatch.setattr(WaveField, "vertical", heave_only)
    motions, vert = spm._hull_wf(fpso6, ss, psi, 3600.0, 0.5, 0, [fpso6.turret.position])
    assert not np.any(motions[0]) and not np.any(vert[:, 1:])
    prob = _problem(fpso6)
    ks, _, n = spm.wave_frequency_ksigma(prob, _wp(prob, psi, p), p, motions[0], 3600.0, vertical=vert)
    bx, by = body_from_turret(p, psi, prob.p_cot_B)
    kz = prob.system.lines.depth_sensitivity(np.array([bx, by, psi]))
    hz = vert[:, 0]
    wd = -(hz - hz.mean())                                      # dT/dz < 0: the tension falls as the hull sinks
    n_up = float(np.sum((wd[:-1] < 0) & (wd[1:] >= 0)))
    assert np.all(n == n_up)
    expected = gumbel_k(n_up) * np.abs(kz) * hz.std()
    assert np.allclose(ks, expected, rtol=1e-12, atol=0.0)


def test_roll_and_pitch_move_the_fairleads_as_the_plant_does(fpso6):
    """The fairleads' displacement by heave, roll and pitch is the FEM plant's (its fairlead positions
    with and without them)."""
    prob = _problem(fpso6)
    psi, p = 0.7, np.array([3.0, -8.0])
    vert = np.array([[0.5, 0.02, -0.01], [-0.3, -0.015, 0.02]])
    ox, oy, oz = spm.fairlead_wf_motion(prob, psi, p, vert)
    fem = MooringFEM(fpso6, segments=4)
    bx, by = body_from_turret(p, psi, prob.p_cot_B)
    for j, v in enumerate(vert):
        r3, _ = fem.fairlead_state(np.array([bx, by, psi]), np.zeros(3))
        r6, _ = fem.fairlead_state(np.array([bx, by, psi, *v]), np.zeros(6))
        assert np.allclose(np.stack([ox[j], oy[j], oz[j]], axis=1), r6 - r3, rtol=0, atol=1e-12)


# --- against the FEM plant ---------------------------------------------------------------------------

def _fem_and_qs_sigma(sc, ss, psi, duration, *, segments=10, skip=100.0, dt_out=0.5):
    """Fairlead tension standard deviation [N] of the FEM lines (``segments`` per line, the sea
    state's current) held at the field zero point at heading ``psi`` and moved by the hull's
    wave-frequency motion (seed 0), and the quasi-static sigma (``k sigma / k``) of the same motion
    at the same instants, after ``skip`` seconds."""
    env = Environment(sc, ss, seed=0)
    prob = _problem(sc)
    p = np.zeros(2)
    bx, by = body_from_turret(p, psi, prob.p_cot_B)
    lf = np.array([bx, by, psi])
    fem = MooringFEM(sc, segments=segments, current=env.current_at)
    every = math.ceil(dt_out / fem.dt)
    fem.dt = dt_out / every
    fem.initialise(lf)
    fem.settle(lf, max_time=3000.0)
    n_out = round(duration / dt_out)
    t_all = np.arange(1, n_out * every + 1) * fem.dt
    E, Ed = np.zeros((t_all.size, 6)), np.zeros((t_all.size, 6))
    E[:, :3], Ed[:, :3] = lf + env.eta_wf(t_all, psi), env.eta_wf_dot(t_all, psi)
    if env.waves.six_dof:
        for c0 in range(0, t_all.size, 20000):
            c = slice(c0, c0 + 20000)
            E[c, 3:], Ed[c, 3:] = env.waves.vertical(t_all[c], psi), env.waves.vertical_dot(t_all[c], psi)
    T = np.empty((n_out, fem.fem.n_lines))
    for j in range(n_out):
        fem.advance(E[j * every:(j + 1) * every], Ed[j * every:(j + 1) * every])
        T[j] = fem.fairlead_tension()
    t = np.arange(1, n_out + 1) * dt_out
    keep = t >= skip
    tk = t[keep]
    wf = env.eta_wf(tk, psi)
    cx, cy = (math.cos(psi) * prob.p_cot_B[0] - math.sin(psi) * prob.p_cot_B[1],
              math.sin(psi) * prob.p_cot_B[0] + math.cos(psi) * prob.p_cot_B[1])
    motion = np.stack([wf[:, 0] - cy * wf[:, 2], wf[:, 1] + cx * wf[:, 2]], axis=1)   # as _hull_wf
    vert = env.waves.vertical(tk, psi) if env.waves.six_dof else None
    ks, _, n = spm.wave_frequency_ksigma(prob, _wp(prob, psi, p), p, motion, tk[-1] - tk[0], vertical=vert)
    return T[keep].std(axis=0), ks / np.array([gumbel_k(max(v, 2.0)) for v in n])


def test_six_dof_ksigma_against_the_fem_plant_in_the_storm(fpso, fpso6):
    """Quasi-static against dynamic (600 s after 100 s, 10 segments; docs/controllers.md has the
    hour with 20): the FEM's fairlead tension scatters 6.5-7.9 times the horizontal model's
    quasi-static sigma and 11.1-16.8 times the six-degree-of-freedom one's (each with its own
    motion; the bounds asserted are 5-10 and 8-20).
    With heave, roll and pitch the quasi-static sigma is nearer the FEM's on its worst line (bundle
    2, whose lines the surge moves little and the pitch a lot) and its ratio to the FEM's varies
    less from line to line."""
    ss = fpso.sea_state("storm")
    psi = float(weathervane_heading(fpso, ss))
    fem3, qs3 = _fem_and_qs_sigma(fpso, ss, psi, 700.0)
    fem6, qs6 = _fem_and_qs_sigma(fpso6, ss, psi, 700.0)
    r3, r6 = fem3 / qs3, fem6 / qs6
    assert np.all((r3 > 5.0) & (r3 < 10.0)), r3
    assert np.all((r6 > 8.0) & (r6 < 20.0)), r6
    worst = int(np.argmax(fem6))
    assert abs(math.log(fem6[worst] / qs6[worst])) < abs(math.log(fem6[worst] / qs3[worst]))
    assert r6.max() / r6.min() < (fem6 / qs3).max() / (fem6 / qs3).min()
    assert np.sum(qs6) > np.sum(qs3) and np.sum(fem6) > np.sum(fem3)   # heave adds on the whole


# --- the anchor estimation's Delta T_v ---------------------------------------------------------------

def test_range_bias_moves_the_fem_lines_with_heave_roll_and_pitch(monkeypatch):
    """``range_bias_along`` drives the FEM with the hull's heave, roll and pitch when the scenario
    has them (the same realisation as its surge, sway and yaw), with surge, sway and yaw only
    otherwise."""
    from tapm_opt.studies import anchor_network

    sc3 = tapm_opt.load_scenario("ren8")
    sc6 = six_dof(sc3, block_coefficient=0.828, GM_T=5.0, roll_period=14.7)
    ss = sc3.sea_state(sc3.sea_states[0].id)
    P = np.array([[10.0, 5.0], [10.5, 5.2], [11.0, 5.1]])
    H = np.array([0.0, 0.01, 0.02])
    poses = {}
    real = MooringFEM.advance

    def spy(self, eta, eta_dot, *a, **kw):
        poses.setdefault(self.scenario.vessel.wave_motion.model, []).append((np.array(eta), np.array(eta_dot)))
        return real(self, eta, eta_dot, *a, **kw)

    monkeypatch.setattr(MooringFEM, "advance", spy)
    b3 = anchor_network.range_bias_along(sc3, ss, P, H, seed=4, segments=6, skip=0.0)
    b6 = anchor_network.range_bias_along(sc6, ss, P, H, seed=4, segments=6, skip=0.0)
    assert all(e.shape[1] == 3 for e, _ in poses["horizontal"])
    assert all(e.shape[1] == 6 for e, _ in poses["six_dof"])
    waves = Environment(sc6, ss, seed=4).waves
    e6, ed6 = poses["six_dof"][1]
    e3, _ = poses["horizontal"][1]
    nsub = len(e6)
    t = (1 + np.arange(1, nsub + 1) / nsub) * 1.0
    assert np.array_equal(e6[:, :3], e3)
    assert np.allclose(e6[:, 3:], waves.vertical(t, float(H[1])), rtol=0, atol=1e-12)
    assert np.allclose(ed6[:, 3:], waves.vertical_dot(t, float(H[1])), rtol=0, atol=1e-12)
    assert np.any(e6[:, 3:] != 0) and not np.array_equal(b3, b6)
