"""The MPC's reliability constraints (``MPCSettings(reliability=True)``): the tension limits and
riser-angle limits the on-line indices give, the current's share of the riser angles learnt from
the measured angles, and plans that keep the riser inside its limit when the plain MPC does not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tapm_opt.config import load_scenario
from tapm_opt.control.mpc import LinearMPC, MPCSettings, NonlinearMPC
from tapm_opt.interfaces import Estimate, Setpoint
from tapm_opt.models.riser import RiserModel
from tapm_opt.models.system import System


@pytest.fixture(scope="module")
def fpso():
    return load_scenario("fpso")


class _Stats:
    def __init__(self, ks, ready=True):
        self.ks, self.ready = ks, ready

    def allowance(self):
        return self.ks


# distinct per line, so a mix-up of line ids and indices shows
KS = {**{f"line {i}": 1e5 * i for i in range(1, 13)}, "riser top": math.radians(0.2), "riser bottom": math.radians(0.4)}


def _estimate(fpso, eta, tau_env=np.zeros(3), *, current=True, ks=KS, ready=True):
    riser = RiserModel.from_scenario(fpso, "normal" if current else None)
    return Estimate(t=0.0, eta=np.asarray(eta, float), nu=np.zeros(3), tau_env=tau_env,
                    tensions=np.full(12, 3e6), riser_angles=riser.angles_at(np.asarray(eta, float)),
                    reliability=_Stats(ks, ready))


@pytest.mark.parametrize("cls", [NonlinearMPC, LinearMPC])
def test_limits_follow_the_indices(fpso, cls):
    """T_lim = min(utilisation x MBS, T_b - k sigma - delta_s sigma_b) per line, the design limit
    until the monitor is ready; the riser limits r - k sigma - delta_s sigma_r; the current's share
    is the measured angle less the hang-off part, i.e. what the current alone does to the riser."""
    util = 0.86  # between the reliability limits of the lines with small and large allowances
    ctrl = cls(System.from_scenario(fpso), MPCSettings(reliability=True, delta_s=2.0, tension_utilisation=util))
    eta = np.array([-20.0, 5.0, 0.1])
    est = _estimate(fpso, eta)
    T_lim = ctrl._tension_limits(est)
    mbs, std = fpso.line_arrays["MBS"], fpso.line_arrays["MBS_std"]
    rel = mbs - 1e5 * np.arange(1, 13) - 2.0 * std
    np.testing.assert_allclose(T_lim, np.minimum(util * mbs, rel))
    assert np.any(rel < util * mbs) and np.any(rel > util * mbs)      # both limits bind somewhere
    np.testing.assert_allclose(ctrl._tension_limits(_estimate(fpso, eta, ready=False)), util * mbs)
    rp = ctrl._riser_parameters(est)
    rs = fpso.riser
    np.testing.assert_allclose(rp[:2], [rs.critical_top_angle - math.radians(0.2) - 2 * rs.critical_top_angle_std,
                                        rs.critical_bottom_angle - math.radians(0.4) - 2 * rs.critical_bottom_angle_std])
    wet = RiserModel.from_scenario(fpso, "normal").angles_at(eta)
    dry = RiserModel.from_scenario(fpso, None).angles_at(eta)
    np.testing.assert_allclose(rp[2:], wet - dry, atol=1e-9)
    assert np.abs(rp[2:]).max() > math.radians(0.5)   # the current matters on fpso


def test_without_reliability_the_utilisation_limit_holds(fpso):
    ctrl = NonlinearMPC(System.from_scenario(fpso), MPCSettings())
    est = _estimate(fpso, np.zeros(3))
    np.testing.assert_allclose(ctrl._tension_limits(est), fpso.limits.tension_utilisation * fpso.line_arrays["MBS"])
    assert ctrl._prob.p_idx["riser"].stop == ctrl._prob.p_idx["riser"].start


@pytest.mark.parametrize("cls", [NonlinearMPC, LinearMPC])
def test_riser_limit_shapes_the_plan(fpso, cls):
    """The vessel sits 40 m south, where the current and the offset put the riser's bottom angle
    past the limit its index gives: the reliability MPC plans to bring the hang-off back until the
    predicted bottom angle is inside (soft constraint active), the plain MPC plans a slower return."""
    system = System.from_scenario(fpso)
    eta = np.array([-40.0, 0.0, 0.0])
    ks = {**KS, "riser bottom": math.radians(1.5)}
    est = _estimate(fpso, eta, ks=ks)
    sp = Setpoint(eta_d=np.array([-40.0, 0.0, 0.0]))   # the plain MPC would stay
    wet = RiserModel.from_scenario(fpso, "normal")
    rs = fpso.riser
    lim_b = rs.critical_bottom_angle - ks["riser bottom"] - 2 * rs.critical_bottom_angle_std
    assert np.hypot(*wet.angles_at(eta)[2:]) > lim_b
    finals = {}
    for rel in (False, True):
        ctrl = cls(system, MPCSettings(reliability=rel, horizon=20, dt=10.0))
        ctrl.update(0.0, est, sp)
        step = ctrl.last_step()
        X = ctrl._z[ctrl._prob.idx["X"]].reshape(-1, 6) * ctrl._prob.scale["x"]
        finals[rel] = np.hypot(*wet.angles_at(X[-1, :3])[2:])
        if rel:
            assert "riser" in step.active
    assert finals[True] <= lim_b * 1.02
    assert finals[False] > lim_b
