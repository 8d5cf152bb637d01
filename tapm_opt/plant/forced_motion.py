"""Forced-motion analysis of the FEM mooring (no vessel dynamics).

The lines are settled with the vessel at the field zero point; from t = 0 the vessel moves as
``eta_dof(t) = A sin(2 pi t / T)`` (full speed at t = 0) in one degree of freedom. From the
fairlead tensions and the line forces on the vessel we estimate

* the equivalent linear mooring damping of that degree of freedom, from the energy the lines
  dissipate per cycle (survey eq. 30, §3.2.2): for ``eta = A sin(w t)`` a linear damper ``b``
  dissipates ``W = pi b w A^2`` per cycle, so ``b_eq = W / (pi w A^2)``, where
  ``W = -integral over whole cycles of F_dof * eta_dot_dof dt / n_cycles`` and ``F_dof`` is the
  mooring load on the vessel along that DOF in {E} (force for surge/sway, moment for yaw);
* the dynamic-to-quasi-static tension amplification of each line: the range (max - min) of its
  FEM fairlead tension over the analysed cycles divided by the range of its quasi-static catenary
  tension at the same vessel positions.

The first cycle is left out of both estimates and of the tension range (start-up transient); the
tension range of the first cycle is reported separately (``T_startup``).

The load on the vessel includes the fairlead nodes' drag and inertia (their half segments move with
the vessel, :meth:`~tapm_opt.plant.fem.FEMLines.fairlead_forces`); the inertia is conservative and
drops out of the dissipated energy over whole cycles.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ..errors import ModelError
from ..geometry import rot2_apply, rot_z
from .mooring_fem import MooringFEM, SettleInfo

__all__ = ["ForcedMotionResult", "forced_motion", "identify_mooring_damping", "DOFS"]

DOFS = ("surge", "sway", "yaw")


@dataclass(frozen=True)
class ForcedMotionResult:
    """Result of :func:`forced_motion`.

    Attributes
    ----------
    t : ndarray (n_out,)
        Output times [s].
    eta : ndarray (n_out, 3)
        Prescribed vessel pose (x [m], y [m], psi [rad]).
    T : ndarray (n_out, n_lines)
        FEM fairlead tension of each line [N].
    T_quasi_static : ndarray (n_out, n_lines)
        Catenary fairlead tension at the same poses [N].
    force : ndarray (n_out, 3)
        Mooring load on the vessel in {E}: (F_x [N], F_y [N], M_z [N m]).
    damping : float
        Equivalent linear damping of the DOF [N s/m] (surge, sway) or [N m s/rad] (yaw).
    energy_per_cycle : float
        Energy dissipated by the lines per cycle [J].
    amplification : ndarray (n_lines,)
        Dynamic / quasi-static fairlead tension range of each line [-].
    dt : float
        FEM time step used [s].
    T_range : ndarray (n_lines, 2)
        (min, max) FEM fairlead tension over the analysed cycles [N] (whole run if fewer than 2 cycles).
    T_startup : ndarray (n_lines, 2)
        (min, max) FEM fairlead tension over the first cycle (start-up) [N].
    sea_state : str or None
        Sea state whose current acts on the lines (None: still water).
    wall_time : float
        Wall time of the whole analysis, settling included [s].
    """

    line_ids: tuple[str, ...]
    dof: str
    amplitude: float
    period: float
    t: np.ndarray
    eta: np.ndarray
    T: np.ndarray
    T_quasi_static: np.ndarray
    force: np.ndarray
    damping: float
    energy_per_cycle: float
    amplification: np.ndarray
    dt: float
    segments: int | None
    settle: SettleInfo
    cycles_analysed: int
    T_range: np.ndarray = None  # type: ignore[assignment]
    T_startup: np.ndarray = None  # type: ignore[assignment]
    sea_state: str | None = None
    wall_time: float = 0.0
    meta: dict = field(default_factory=dict)

    def table(self) -> tuple[list[str], np.ndarray]:
        """Columns ``t, x, y, psi, T1..Tn`` (s, m, m, rad, N) and the data (n_out, 4 + n_lines)."""
        header = ["t", "x", "y", "psi", *[f"T{i + 1}" for i in range(len(self.line_ids))]]
        return header, np.column_stack([self.t, self.eta, self.T])


def forced_motion(scenario: Any, *, dof: Literal["surge", "sway", "yaw"] = "surge", amplitude: float,
                  period: float, duration: float, segments: int | None = None, dt_out: float = 1.0,
                  current: Any = None, sea_state: Any = None, safety: float = 0.9, waves: bool = False,
                  seed: int = 0, _sign: float = 1.0) -> ForcedMotionResult:
    """Drive the fairleads with a sinusoidal vessel motion and record the line response.

    Parameters
    ----------
    scenario : Scenario
    dof : {"surge", "sway", "yaw"}
        Degree of freedom moved (surge = x, sway = y in {E}, the heading stays 0).
    amplitude : float
        Motion amplitude [m] (surge, sway) or [rad] (yaw), > 0.
    period : float
        Motion period [s], > 0.
    duration : float
        Simulated time after settling [s], > 0.
    segments : int, optional
        FEM segments per line (default: the scenario's).
    dt_out : float
        Output interval [s]; the FEM step is the largest stable step that divides it.
    current : callable, optional
        ``current(z) -> (n, 3)`` current velocity in {E} on the line nodes (default: still water).
    sea_state : str or SeaState, optional
        Take the current profile of this sea state of the scenario (instead of ``current``); its
        wind does not act (the vessel motion is prescribed), its waves only with ``waves``.
    safety : float
        Fraction of the FEM stability limit used as step.
    waves : bool
        Add the sea state's wave-frequency motion of the hull to the forced one (needs
        ``sea_state``): surge, sway and yaw, and with the scenario's ``vessel.wave_motion.model =
        "six_dof"`` heave, roll and pitch (:class:`tapm_opt.plant.environment.WaveField`, the
        plant's, at heading 0 and the realisation of ``seed``, brought in over the first peak
        period, :meth:`~tapm_opt.plant.environment.WaveField.ramp`). The damping is still the
        energy the lines dissipate against the forced motion's velocity, so it is the
        low-frequency damping with the wave-frequency motion acting on the lines (survey §2.4).
        The waves alone make a slowly varying line force too, which projects onto that velocity
        over a few cycles (up to 7 % of fpso's damping in the storm): the damping and energy are
        the mean of the run with the motion ``+A sin`` and one with ``-A sin`` in the same waves,
        in which that part cancels (the time series are the first run's; twice the cost).
    seed : int
        Seed of the wave realisation (``waves``), as the plant's: the same waves as a
        :class:`~tapm_opt.plant.simulator.Plant` of that seed.

    Raises
    ------
    SettlingNotConverged
        The lines did not come to rest before the motion starts.
    """
    if dof not in DOFS:
        raise ModelError(f"dof = {dof!r} is not one of {', '.join(DOFS)}")
    for name, val in (("amplitude", amplitude), ("period", period), ("duration", duration), ("dt_out", dt_out)):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
            raise ModelError(f"{name} = {val!r} must be a positive number")
    if dt_out > period / 10.0:
        raise ModelError(f"dt_out = {dt_out:g} s must be at most period / 10 = {period / 10.0:g} s: the tension "
                         "range and amplification are read from the output samples, ten or more per cycle")
    k = DOFS.index(dof)
    A = float(amplitude) * _sign   # the motion A sin(omega t); _sign = -1 the mirrored run of waves=True
    w0 = time.perf_counter()
    ss_id = None
    if isinstance(sea_state, str) and sea_state == "none":
        sea_state = None  # still water, as for the plant
    if sea_state is not None:
        if current is not None:
            raise ModelError("give either current or sea_state, not both")
        from .environment import CurrentProfile, PlantError

        try:
            ss = sea_state if not isinstance(sea_state, str) else scenario.sea_state(sea_state)
        except KeyError as exc:
            raise PlantError(f"sea_state = {sea_state!r}: {str(exc).strip(chr(39) + chr(34))}") from None
        ss_id = ss.id
        if ss.current_speed > 0:
            current = CurrentProfile(ss, scenario.environment.water_depth).velocity
    wf = None
    if waves:
        if sea_state is None:
            raise ModelError("waves = True needs a sea_state (whose waves move the hull)")
        from .environment import Environment

        ss_seed = int(np.random.SeedSequence(seed).spawn(3)[0].generate_state(1)[0])   # the plant's waves
        wf = Environment(scenario, ss, seed=ss_seed).waves
        if wf.Hs <= 0:
            wf = None
    plant = MooringFEM(scenario, segments=segments, current=current, safety=safety)
    # a whole number of FEM steps per output interval, each no longer than the stable step
    every = int(math.ceil(dt_out / plant.dt - 1e-9))
    plant.dt = dt = dt_out / every
    def wave_pose(ts: np.ndarray):
        """The hull's wave-frequency pose and rate (n, 6) at the times ts [s] (zeros without waves)."""
        e, ed = np.zeros((ts.size, 6)), np.zeros((ts.size, 6))
        if wf is not None:
            e[:, :3], ed[:, :3] = wf.eta_wf(ts, 0.0), wf.eta_wf_dot(ts, 0.0)
            e[:, 3:], ed[:, 3:] = wf.vertical(ts, 0.0), wf.vertical_dot(ts, 0.0)
        return e, ed

    eta0 = wave_pose(np.zeros(1))[0][0]
    plant.initialise(eta0)
    info = plant.settle(eta0)
    omega = 2.0 * math.pi / period
    n_out = int(math.floor(duration / dt_out + 1e-9)) + 1
    n_steps = (n_out - 1) * every
    t_out = np.zeros(n_out)
    eta_out = np.zeros((n_out, 3))
    T_out = np.zeros((n_out, plant.fem.n_lines))
    F_out = np.zeros((n_out, 3))
    # dissipated power -F.eta_dot at the start of every FEM step (trapezoidal rule), from the
    # fairlead forces the kernel returns (tension, weight, drag; the nodes' inertia is conservative
    # and left out of the power)
    power = np.zeros(n_steps + 1)
    g = plant.geometry

    def pose(t: float):
        e, ed = (q[0] for q in wave_pose(np.array([t])))
        e[k] += A * math.sin(omega * t)
        ed[k] += A * omega * math.cos(omega * t)
        return e, ed

    def load_E(eta, eta_dot, t):
        edd = np.zeros(6)   # the forced motion's acceleration (the waves' is left out of the inertia)
        edd[k] = -A * omega * omega * math.sin(omega * t)
        tau_b = plant.tau(eta, plant.fairlead_acceleration(eta, eta_dot, edd))
        return rot_z(eta[2]) @ tau_b

    def load_dof(f_seq, e_seq):
        """The DOF's load component in {E} for fairlead forces (n, n_lines, 3) at poses (n, 3)."""
        if k < 2:
            return f_seq[:, :, k].sum(axis=1)
        fx, fy = f_seq[:, :, 0], f_seq[:, :, 1]
        e = e_seq.T[:, :, None]
        if g.turret_mode == "locked":
            px, py = g.fairleads(e)
            return ((px - e[0]) * fy - (py - e[1]) * fx).sum(axis=1)
        cx, cy = rot2_apply(e[2][:, 0], g.p_cot_B[0], g.p_cot_B[1])
        return cx * fy.sum(axis=1) - cy * fx.sum(axis=1)

    j = 0
    e, ed = pose(0.0)
    F = load_E(e, ed, 0.0)
    t_out[0], eta_out[0], T_out[0], F_out[0] = 0.0, e[:3], plant.fairlead_tension(), F
    # the steps run in blocks (MooringFEM.advance) that end where the loop looks at the state (an
    # output, a health check) and, with a current, at least every 0.1 s: the current is evaluated
    # at the start of a block and held over it
    every_c = max(1, int(0.1 / dt + 1e-9)) if plant.current is not None else n_steps + 1
    f_buf = np.zeros((min(n_steps, every, 200, every_c) if n_steps else 1, plant.fem.n_lines, 3))
    i = 0
    while i < n_steps:
        i0 = i
        i = min(n_steps, (i0 // every + 1) * every, (i0 // 200 + 1) * 200, (i0 // every_c + 1) * every_c)
        nb = i - i0
        ts = np.arange(i0, i + 1) * dt           # start of each step, then the end of the block
        e_seq, ed_seq = wave_pose(ts)
        v_forced = A * omega * np.cos(omega * ts)
        e_seq[:, k] += A * np.sin(omega * ts)
        ed_seq[:, k] += v_forced
        f_seq = f_buf[:nb]
        plant.advance(e_seq[1:], ed_seq[1:], fairlead_force_out=f_seq)
        power[i0:i] = -load_dof(f_seq, e_seq[:-1, :3]) * v_forced[:-1]
        t = i * dt
        e, ed = pose(t)
        if i % 200 == 0:
            plant.fem.check_health()
        if i % every == 0:
            j += 1
            F = load_E(e, ed, t)
            t_out[j], eta_out[j], T_out[j], F_out[j] = t, e[:3], plant.fairlead_tension(), F
    plant.fem.check_health()
    if n_steps:  # the last instant, from the same forces as the others (no inertia)
        vc = plant._vc[plant.fem.fairlead_idx] if plant.current is not None else None
        power[n_steps] = -load_dof(plant.fem.fairlead_forces(vc)[None], e[None, :3])[0] * (
            A * omega * math.cos(omega * n_steps * dt))
    power_t = np.arange(n_steps + 1) * dt
    t_out, eta_out, T_out, F_out = t_out[: j + 1], eta_out[: j + 1], T_out[: j + 1], F_out[: j + 1]

    # quasi-static reference at the output poses
    moor = plant.geometry
    XF = np.array([moor.spans(e)[2] for e in eta_out])
    T_qs = moor.solve_xf(XF).TF

    # whole cycles after the first one, within the simulated time (a whole number of dt_out)
    n_cyc = int(math.floor(n_steps * dt / period + 1e-9)) - 1
    if n_cyc >= 1:
        t0, t1 = period, period * (1 + n_cyc)
        m = (power_t >= t0 - 1e-9) & (power_t <= t1 + 1e-9)
        W = float(np.trapezoid(power[m], power_t[m])) / n_cyc
        b_eq = W / (math.pi * omega * amplitude**2)
        mo = (t_out >= t0 - 1e-9) & (t_out <= t1 + 1e-9)
        rng_dyn = T_out[mo].max(axis=0) - T_out[mo].min(axis=0)
        rng_qs = T_qs[mo].max(axis=0) - T_qs[mo].min(axis=0)
        amp = np.where(rng_qs > 1e-9 * np.maximum(T_qs[mo].max(axis=0), 1.0), rng_dyn / np.where(rng_qs > 0, rng_qs, 1.0), np.nan)
        T_range = np.column_stack([T_out[mo].min(axis=0), T_out[mo].max(axis=0)])
    else:
        W, b_eq = math.nan, math.nan
        amp = np.full(plant.fem.n_lines, np.nan)
        T_range = np.column_stack([T_out.min(axis=0), T_out.max(axis=0)])
    if wf is not None and _sign > 0 and n_cyc >= 1:   # the waves-only part cancels in the mean of +A and -A
        mirrored = forced_motion(scenario, dof=dof, amplitude=amplitude, period=period, duration=duration,
                                 segments=segments, dt_out=dt_out, current=None if sea_state is not None else current,
                                 sea_state=sea_state, safety=safety, waves=True, seed=seed, _sign=-1.0)
        W = 0.5 * (W + mirrored.energy_per_cycle)
        b_eq = W / (math.pi * omega * amplitude**2)
    first = t_out <= min(period, duration) + 1e-9
    T_startup = np.column_stack([T_out[first].min(axis=0), T_out[first].max(axis=0)])
    return ForcedMotionResult(
        line_ids=plant.line_ids, dof=dof, amplitude=float(amplitude), period=float(period), t=t_out, eta=eta_out,
        T=T_out, T_quasi_static=T_qs, force=F_out, damping=b_eq, energy_per_cycle=W, amplification=amp, dt=dt,
        segments=segments, settle=info, cycles_analysed=max(n_cyc, 0), T_range=T_range, T_startup=T_startup,
        sea_state=ss_id, wall_time=time.perf_counter() - w0, meta={"scenario": scenario.name},
    )


def identify_mooring_damping(scenario: Any, *, amplitudes: tuple[float, float, float] = (10.0, 10.0, math.radians(5.0)),
                             period: float = 100.0, cycles: int = 3, segments: int | None = None,
                             current: Any = None) -> np.ndarray:
    """Diagonal linear mooring damping D_mo (survey eq. 30) identified from forced-motion runs.

    One :func:`forced_motion` run per degree of freedom at the given amplitude and period; the
    equivalent linear damping of each becomes the diagonal of D_mo. The result depends on the
    amplitude and period (drag is nonlinear): choose those of the expected low-frequency motion.

    Parameters
    ----------
    amplitudes : (surge [m], sway [m], yaw [rad])
    period : float
        Motion period [s], e.g. the surge natural period.
    cycles : int
        Cycles simulated (the first is discarded), >= 2.

    Returns
    -------
    ndarray (3, 3)
        diag(b_surge [N s/m], b_sway [N s/m], b_yaw [N m s/rad]).
    """
    if not isinstance(cycles, int) or cycles < 2:
        raise ModelError(f"cycles = {cycles!r} must be a whole number >= 2")
    b = [forced_motion(scenario, dof=dof, amplitude=a, period=period, duration=cycles * period, segments=segments,
                       dt_out=period / 100.0, current=current).damping
         for dof, a in zip(DOFS, amplitudes)]
    return np.diag(b)
