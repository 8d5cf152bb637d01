"""Virtual-vessel networks for the tension-based anchor EKF-SLAM, generated on the plant
(anchor-SLAM seed §4, §6.1): each virtual vessel is a closed loop of the plant with heading-only
control settled in a random environment, its LF position and tensions recorded. The filter and
the network's records are in :mod:`tapm_opt.estimation.anchor_slam`; this module runs the plant,
so it belongs to the studies layer.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from typing import Any

import numpy as np

from .._parallel import limit_threads, worker_threads
from ..errors import TapmError
from .._checks import finite
from ..estimation.anchor_slam import AnchorSlamError, VirtualVessel, VirtualVesselNetwork
from ..models.mooring import MooringModel

__all__ = ["random_sea_states", "generate_network", "current_tension_share", "range_bias_along"]


def _sea_state_dict(ss: Any) -> dict:
    return {"Hs": float(ss.Hs), "Tp": float(ss.Tp), "wave_direction_deg": math.degrees(ss.wave_direction),
            "wind_speed": float(ss.wind_speed), "wind_direction_deg": math.degrees(ss.wind_direction),
            "current_speed": float(ss.current_speed), "current_direction_deg": math.degrees(ss.current_direction)}


def random_sea_states(scenario: Any, n: int, *, seed: int = 0, min_offset: float = 25.0, max_offset: float = 60.0,
                      Hs_range: tuple[float, float] = (1.0, 4.0), wind_max: float = 15.0,
                      current_max: float = 0.2, current_spread_deg: float = 35.0,
                      heading: float = 0.0, stratify: bool = True) -> list[tuple[Any, np.ndarray]]:
    """``n`` random environments as in §6.1 and the quasi-static equilibrium of each.

    Wind speed ``U(0, wind_max)`` [m/s] and direction ``U(0, 360)`` deg; ``Hs ~ U(Hs_range)`` [m],
    ``Tp = clip(4.5 sqrt(Hs), 5, 14)`` [s], main wave direction ``U(0, 360)`` deg; current speed
    ``U(0, current_max)`` [m/s], its direction within ``±current_spread_deg`` of the waves (§6.1).
    Directions are "going to" (the scenario's convention). The draws are stratified by where they
    put the vessel: environment j is drawn again until its quasi-static equilibrium at the held
    ``heading`` [rad] lies ``min_offset``..``max_offset`` [m] from the field zero point with its
    bearing within ``180 / n`` deg of ``j`` times the golden angle (137.5 deg), so the landmarks --
    and those of every prefix, the first 4 of 10 as well -- surround the field zero point and every
    anchor sees a tangential baseline; no line above 0.6 MBS. ``stratify=False``: any bearing.

    Returns a list of ``(SeaState, eta_eq (3,))``.
    """
    from ..design.loads import mean_environmental_load
    from ..models.statics import EquilibriumError

    if not scenario.sea_states:
        raise AnchorSlamError(f"scenario {scenario.name!r} defines no sea state (the template of the random ones)")
    n = int(n)
    rng = np.random.default_rng(seed)
    base = scenario.sea_states[0]
    model = MooringModel.from_scenario(scenario)
    out = []
    for j in range(n):
        for attempt in range(2000):
            Hs = float(rng.uniform(*Hs_range))
            wave = float(rng.uniform(0.0, 2 * math.pi))
            ss = replace(base, id=f"random_{seed}_{j}", Hs=Hs, Tp=float(np.clip(4.5 * math.sqrt(Hs), 5.0, 14.0)),
                         wave_direction=wave, wind_speed=float(rng.uniform(0.0, wind_max)),
                         wind_direction=float(rng.uniform(0.0, 2 * math.pi)),
                         current_speed=float(rng.uniform(0.0, current_max)),
                         current_direction=wave + math.radians(float(rng.uniform(-1, 1)) * current_spread_deg),
                         current_profile="uniform", current_profile_depths=(), current_profile_factors=())
            try:
                tau = mean_environmental_load(scenario, ss, heading, seed=seed * 1000 + j).total
                eta = model.equilibrium(tau, psi=heading)
            except (EquilibriumError, TapmError):
                continue
            centre = j * math.pi * (3.0 - math.sqrt(5.0))          # the golden angle, 137.5 deg
            off = math.remainder(math.atan2(eta[1], eta[0]) - centre, 2 * math.pi)
            in_sector = (not stratify) or abs(off) <= math.pi / max(n, 1)
            if (in_sector and min_offset <= math.hypot(eta[0], eta[1]) <= max_offset
                    and np.all(model.tensions(eta) < 0.6 * model.MBS)):
                out.append((ss, eta))
                break
        else:  # pragma: no cover - the lower Hs of each sector always fits
            raise AnchorSlamError(f"no environment with an equilibrium {min_offset:g}..{max_offset:g} m away "
                                  f"in sector {j} of {n} after 2000 draws (a stiff mooring needs smaller offsets: "
                                  f"min_offset, max_offset; tapm estimate anchors --offsets)")
    return out


def current_tension_share(scenario: Any, sea_state: Any, eta: Any, *, segments: int | None = None) -> np.ndarray:
    """The share of each fairlead tension [N], shape (M,), that ``sea_state``'s current puts on the
    lines with the vessel held at ``eta`` (x [m], y [m], psi [rad]): the seed's ``Delta T_c`` of
    eq. (8), which its range map leaves out. The scenario's lines as the FEM of the plant
    (``plant.mooring_fem.MooringFEM``, ``segments`` per line) settled by dynamic relaxation under
    the current's profile and without it; the difference of the settled fairlead tensions. Zero
    without a current. The tensions the range map reads are the measured ones less this share
    (``estimation.anchor_slam.VirtualVessel.current_tension``)."""
    from ..plant.environment import CurrentProfile
    from .closed_loop import fem_static_tensions

    eta = np.asarray(eta, dtype=float)
    if eta.shape != (3,) or not np.all(np.isfinite(eta)):
        raise AnchorSlamError(f"eta = {eta.tolist()} must be a finite pose (x [m], y [m], psi [rad])")
    if not float(getattr(sea_state, "current_speed", 0.0)) > 0.0:
        return np.zeros(len(scenario.lines))
    profile = CurrentProfile(sea_state, scenario.environment.water_depth)
    settle = fem_static_tensions(scenario, segments)
    return settle(eta, profile.velocity) - settle(eta, None)


def range_bias_along(scenario: Any, sea_state: Any, positions: Any, headings: Any, *, seed: int = 0,
                     segments: int | None = None, skip: float = 60.0, dt: float = 1.0) -> np.ndarray:
    """The mean error of the tension -> range map along a record [m], shape (M,): the mean over the
    record of ``d_i`` from the line model's fairlead tensions minus the true distance from anchor
    ``i`` to the COT, with the lines (the plant's FEM, ``segments`` per line) settled at the first
    pose and then driven along ``positions`` (n, 2) [m] and ``headings`` (n,) [rad] (the record's
    LF track, samples ``dt`` [s] apart, linear in between) plus the wave-frequency motion of
    ``sea_state`` (the plant's wave model, realisation ``seed``: surge, sway and yaw, and with the
    scenario's six-degree-of-freedom hull its heave, roll and pitch, as the plant moves the
    fairleads), under its current; the first ``skip`` [s] are left out. The seed's eq. 8 terms
    ``Delta T_c`` (current) and ``Delta T_v`` (vessel motion) together, as range: the taut lines'
    mean wave-frequency dynamic tension shortens their mapped ranges (up to 2 m on ren8 with ``Hs``
    3 m). Subtracted from a stored record's ranges (``VirtualVessel.range_bias``)."""
    from ..estimation.anchor_slam import TensionRangeMap
    from ..geometry import rot_z
    from ..plant.environment import Environment
    from ..plant.mooring_fem import MooringFEM

    P = np.asarray(positions, dtype=float)
    psi = np.unwrap(np.asarray(headings, dtype=float))
    if P.ndim != 2 or P.shape[1] != 2 or psi.shape != (len(P),) or len(P) < 2 or not (
            np.all(np.isfinite(P)) and np.all(np.isfinite(psi))):
        raise AnchorSlamError(f"positions {P.shape} and headings {psi.shape} must be a finite track of n >= 2 "
                              "samples: (n, 2) [m] and (n,) [rad]")
    env = Environment(scenario, sea_state, seed=seed)
    fem = MooringFEM(scenario, segments=segments, current=env.current_at if sea_state.current_speed > 0 else None)
    rmap = TensionRangeMap.from_scenario(scenario)
    anchors = np.asarray(rmap.model.anchors, dtype=float)[:, :2]
    c = np.asarray(rmap.model.p_cot_B, dtype=float)
    pose0 = np.array([P[0, 0], P[0, 1], psi[0]])
    fem.initialise(pose0)
    fem.settle(pose0, max_time=3000.0)
    nsub = max(1, int(round(dt / fem.dt)))
    a = np.arange(1, nsub + 1) / nsub
    six_dof = env.waves.six_dof
    err = []
    for k in range(len(P) - 1):
        t = (k + a) * dt
        d_lf = np.concatenate([P[k + 1] - P[k], [psi[k + 1] - psi[k]]])
        lf = np.column_stack([P[k, 0] + a * d_lf[0], P[k, 1] + a * d_lf[1], psi[k] + a * d_lf[2]])
        eta = lf + env.eta_wf(t, float(psi[k]))
        eta_dot = np.repeat((d_lf / dt)[None, :], nsub, axis=0) + env.eta_wf_dot(t, float(psi[k]))
        if six_dof:   # the hull's heave, roll and pitch move the fairleads too, as on the plant
            eta = np.hstack([eta, env.waves.vertical(t, float(psi[k]))])
            eta_dot = np.hstack([eta_dot, env.waves.vertical_dot(t, float(psi[k]))])
        fem.advance(eta, eta_dot)
        if t[-1] >= skip:
            e = eta[-1]
            cot = e[:2] + rot_z(e[2])[:2, :2] @ c
            err.append(rmap.ranges(fem.fairlead_tension(), clip=True)[0] - np.linalg.norm(anchors - cot, axis=1))
    if not err:
        raise AnchorSlamError(f"the record ({(len(P) - 1) * dt:g} s) is shorter than skip = {skip:g} s")
    return np.mean(err, axis=0)


class _Recorder:
    """An Estimator that passes through the inner one and keeps what a stored record needs."""

    def __init__(self, inner: Any, plant: Any):
        self.inner, self.plant = inner, plant
        self.rows: list[tuple] = []

    def update(self, t: float, measurement: Any) -> Any:
        est = self.inner.update(t, measurement)
        m = measurement
        tau = np.zeros(3) if m.tau_thr is None else np.asarray(m.tau_thr, float)
        self.rows.append((t, est.eta[:2].copy(), m.heading, np.asarray(m.tensions, float).copy(), tau,
                          self.plant.eta.copy(), est.eta.copy()))
        return est

    def reset(self) -> None:
        self.inner.reset()


def _record(args: tuple) -> VirtualVessel:
    """Run one environment on the plant (worker of :func:`generate_network`)."""
    from ..estimation.observer import EKFObserver
    from ..geometry import rot_z
    from ..models.system import System
    from ..plant.simulator import Plant
    from .closed_loop import ClosedLoopSettings, run_closed_loop
    from .controllers import build_controller

    scenario, ss, eta0, seed, settle, settle_max, settle_tol, duration, segments, dt, live = args
    system = System.from_scenario(scenario)
    plant = Plant(system, sea_state=ss, seed=seed, eta0=eta0, segments=segments)
    ctrl = build_controller(system, {"type": "pid", "modes": "calm"})  # heading only (§6.1)
    obs = EKFObserver.from_scenario(system, sea_state=ss)
    rec = _Recorder(obs, plant)
    cfg = dict(heading="fixed", eta_d=(0.0, 0.0, float(eta0[2])), detector="none", dt_control=dt, dt_log=dt)
    # settle: in chunks until the observer's mean LF position moves less than settle_tol between chunks
    t_settle, prev = 0.0, None
    while True:
        run_closed_loop(plant, ctrl, ClosedLoopSettings(duration=settle, **cfg), estimator=rec)
        t_settle += settle
        mean = np.mean([r[1] for r in rec.rows[-int(settle / dt):]], axis=0)
        rec.rows.clear()
        if (prev is not None and float(np.hypot(*(mean - prev))) < settle_tol) or t_settle >= settle_max:
            break
        prev = mean
    run_closed_loop(plant, ctrl, ClosedLoopSettings(duration=duration, **cfg), estimator=rec)
    rows = rec.rows
    t = np.array([r[0] for r in rows])
    cot = np.array([r[6][:2] + rot_z(r[6][2])[:2, :2] @ system.p_cot_B for r in rows])
    position, heading = np.array([r[1] for r in rows]), np.array([r[2] for r in rows])
    # the current's share of the tensions (eq. 8's Delta T_c) at the record's mean pose as the
    # estimator knows it: a stored vessel's mean observer position; the live vessel's position is
    # what is sought, so the field zero point (the share changes little over tens of metres)
    psi = float(np.angle(np.mean(np.exp(1j * heading))))
    pose = np.array([0.0, 0.0, psi]) if live else np.array([*position.mean(axis=0), psi])
    # the map's range bias along a stored record's own track (its observer positions and headings;
    # another realisation of the waves): not for the live vessel, whose track is what is sought
    bias = None if live else range_bias_along(scenario, ss, position, heading, seed=seed + 7, segments=segments,
                                              dt=dt)
    return VirtualVessel(t=t - t[0], position=position, heading=heading,
                         tensions=np.array([r[3] for r in rows]), tau_thr=np.array([r[4] for r in rows]),
                         truth=np.array([r[5] for r in rows]), cot=cot, sea_state=_sea_state_dict(ss),
                         settle_time=t_settle,
                         current_tension=current_tension_share(scenario, ss, pose, segments=segments),
                         range_bias=bias)


def generate_network(scenario: Any, n: int, *, duration: float, seed: int = 0, settle: float = 200.0,
                     settle_max: float = 1200.0, settle_tol: float = 1.0, workers: int = 2,
                     segments: int | None = None, dt: float = 1.0, live_sea_state: Any = None,
                     env_kw: dict | None = None) -> VirtualVesselNetwork:
    """Generate ``n`` virtual vessels and the live vessel's record on the plant (§4, §6.1).

    Each of ``n`` random environments (:func:`random_sea_states`) and the live vessel's (one more
    draw, any bearing, unless ``live_sea_state`` gives one of the scenario's) is run in closed loop with the
    heading-only PID (``{"type": "pid", "modes": "calm"}``, heading held at 0) from the quasi-static
    equilibrium of its mean load, in chunks of ``settle`` [s] until the observer's mean LF position
    moves less than ``settle_tol`` [m] from one chunk to the next (at most ``settle_max`` [s]); then
    the observer's LF position, the measured tensions, heading and thrust are recorded every ``dt``
    [s] for ``duration`` [s]. Each record also keeps the line model's correction (eq. 8): a stored
    record its range bias along its own track (:func:`range_bias_along`), every record the
    current's share of its tensions (:func:`current_tension_share`; the live one at the field zero
    point). ``workers`` (<= 2 recommended) processes share the runs.
    """
    from ..plant.environment import PlantError

    n = int(n)
    if n < 1:
        raise AnchorSlamError(f"virtual vessels = {n!r} must be >= 1")
    duration = finite("duration", duration, lo=0.0, strict=True, unit="s", error=AnchorSlamError)
    for name, v in (("settle", settle), ("settle_max", settle_max), ("settle_tol", settle_tol), ("dt", dt)):
        finite(name, v, lo=0.0, strict=True, error=AnchorSlamError)
    envs = random_sea_states(scenario, n, seed=seed, **(env_kw or {}))
    envs += random_sea_states(scenario, 1, seed=seed + 7919, stratify=False,
                              **{**(env_kw or {}), "min_offset": 0.0})      # the live vessel: 0 to max_offset
    if live_sea_state is not None:
        from ..design.loads import mean_environmental_load

        ss = scenario.sea_state(live_sea_state) if isinstance(live_sea_state, str) else live_sea_state
        model = MooringModel.from_scenario(scenario)
        envs[-1] = (ss, model.equilibrium(mean_environmental_load(scenario, ss, 0.0, seed=seed).total, psi=0.0))
    jobs = [(scenario, ss, eta, seed * 1000 + j + 1, settle, settle_max, settle_tol, duration, segments, dt,
             j == len(envs) - 1) for j, (ss, eta) in enumerate(envs)]
    workers = max(1, min(int(workers), len(jobs), os.cpu_count() or 1))
    try:
        if workers == 1:
            recs = [_record(a) for a in jobs]
        else:
            with ProcessPoolExecutor(max_workers=workers, initializer=limit_threads,
                                     initargs=(worker_threads(workers),)) as ex:
                recs = list(ex.map(_record, jobs))
    except PlantError as exc:
        raise AnchorSlamError(f"a virtual-vessel run failed on the plant: {exc}") from None
    meta = {"seed": seed, "duration": duration, "dt": dt, "settle": settle, "settle_tol": settle_tol,
            "segments": segments, "env": env_kw or {}}
    return VirtualVesselNetwork(scenario=scenario.name, vessels=tuple(recs[:-1]), live=recs[-1], meta=meta)


# ------------------------------------------------------------------------------------------
# the EKF-SLAM (§5, eq. 15-16)
# ------------------------------------------------------------------------------------------
