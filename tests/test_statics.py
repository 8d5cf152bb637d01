"""Tests of the one equilibrium solver (tapm_opt.models.statics) and its users: the catenary
mooring balance (MooringModel.equilibrium, heading free or held), the CasADi vessel rest point
(models.vessel.equilibrium) and the PID design on a scenario."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import tapm_opt
from tapm_opt.control.pid import ControlError
from tapm_opt.control.pid_design import design_from_scenario
from tapm_opt.errors import ModelError
from tapm_opt.models.mooring import MooringModel
from tapm_opt.models.statics import EquilibriumError, solve_equilibrium
from tapm_opt.models.vessel import VesselParams, equilibrium, moored_function


@pytest.fixture(scope="module")
def fpso():
    return tapm_opt.load_scenario("fpso")


def test_continuation_reaches_a_root_the_direct_solve_cannot():
    """f = x - 10 s, defined only within 5 of the root (a line beyond its reach raises): from
    x = 0 the full load is out of the domain; load steps of 1 stay inside it."""
    calls = []

    def residual(x, s):
        calls.append(s)
        if abs(x[0] - 10.0 * s) > 5.0:
            raise ModelError("beyond reach")
        return np.array([x[0] - 10.0 * s])

    x = solve_equilibrium(residual, lambda x, s: np.eye(1), np.zeros(1), tol=1e-12)
    assert x[0] == pytest.approx(10.0, abs=1e-12)
    assert calls[0] == 1.0 and 0.0 in calls  # tried directly, then from s = 0
    with pytest.raises(EquilibriumError, match="left the model's domain"):
        solve_equilibrium(residual, lambda x, s: np.eye(1), np.zeros(1), tol=1e-12, steps=0)


def test_no_root_raises_with_the_residual():
    with pytest.raises(EquilibriumError) as info:
        solve_equilibrium(lambda x, s: x**2 + 1.0, lambda x, s: np.diag(2 * x), np.ones(1),
                          tol=1e-9)
    assert info.value.residual >= 1.0 and "residual" in info.value.reason


def test_held_heading_balances_x_y_and_keeps_psi(fpso):
    moor = MooringModel.from_scenario(fpso)
    tau = np.array([-2.5e6, 8.0e5, 3.0e7])
    psi = 0.2
    eta = moor.equilibrium(tau, psi=psi)
    assert eta[2] == psi
    np.testing.assert_allclose(moor.force(eta)[:2], -tau[:2], rtol=0, atol=1e-6 * 2.5e6)
    assert math.hypot(eta[0], eta[1]) > 10.0
    # the yaw moment the mooring leaves is the heading controller's; a locked turret that is
    # given that moment too rests at the same pose with its heading free
    locked = dataclasses.replace(fpso, turret=dataclasses.replace(fpso.turret, mode="locked"))
    m_l = MooringModel.from_scenario(locked)
    eta_l = m_l.equilibrium(tau, psi=psi)
    tau_thr = -(m_l.force(eta_l)[2] + tau[2])
    free = m_l.equilibrium(tau + [0.0, 0.0, tau_thr], eta_guess=eta_l + [2.0, -2.0, 0.02])
    np.testing.assert_allclose(free, eta_l, atol=1e-7)


def test_free_turret_with_free_heading_has_no_rest_under_a_yaw_moment(fpso):
    """A free turret passes only the line force through the turret centre: with the heading
    free, a body-fixed moment other than x_cot Y has no equilibrium (the hull weathervanes);
    with the heading held the same load has one."""
    moor = MooringModel.from_scenario(fpso, broken=("1",))
    tau = [-2.0e6, 5.0e5, 1.0e7]
    with pytest.raises(EquilibriumError, match=r"lines \['2', .*weathervanes"):
        moor.equilibrium(tau)
    assert moor.equilibrium(tau, psi=0.0)[2] == 0.0
    with pytest.raises(ModelError, match="3 finite numbers"):
        moor.equilibrium([1.0, float("nan"), 0.0])


def test_design_from_scenario_uses_the_mooring_equilibrium(fpso):
    """design_from_scenario rests where MooringModel.equilibrium puts the vessel; its errors are
    ControlErrors."""
    x_cot = fpso.turret.position[0]
    tau = np.array([-2.0e6, 1.0e5, x_cot * 1.0e5])
    d = design_from_scenario(fpso, periods=150.0, damping=0.7, tau_env=tau)
    np.testing.assert_array_equal(d.eta_op, MooringModel.from_scenario(fpso).equilibrium(tau))
    with pytest.raises(ControlError, match="weathervanes"):
        design_from_scenario(fpso, periods=150.0, damping=0.7, tau_env=[-2e6, 5e5, 1e7])


def test_vessel_equilibrium_agrees_with_the_mooring_balance(fpso):
    """Independent path: the CasADi design model with the catenary restoring load at rest
    (nu_dot = 0) against the numeric catenary balance."""
    locked = dataclasses.replace(fpso, turret=dataclasses.replace(fpso.turret, mode="locked"))
    moor = MooringModel.from_scenario(locked)
    tau = np.array([-1.5e6, 4.0e5, 2.0e7])
    eta_m = moor.equilibrium(tau)
    fn = moored_function(VesselParams.from_scenario(locked),
                         moor.force_function("catenary", eta0=eta_m + [3.0, -3.0, 0.01]))
    eta_v = equilibrium(fn, tau, eta_guess=eta_m + [3.0, -3.0, 0.01], tol=1e-12)
    np.testing.assert_allclose(eta_v, eta_m, atol=1e-6)
