"""The plant: truth vessel + FEM mooring + environment + thrusters + sensors + faults.

Time stepping (multirate, all explicit):

* an **outer step** ``h <= outer_dt`` (default 0.1 s) advances the thrusters, the environmental
  loads and the low-frequency (LF) vessel. The vessel is the *rich* form of
  :func:`tapm_opt.models.vessel.vessel_rhs` (Coriolis, quadratic damping on the velocity relative
  to the current) — the same CasADi Function the design models use, called numerically — driven by
  thrust, wind, wave drift and the FEM mooring load from the end of the previous outer step
  (semi-implicit Euler: ``nu`` first, then ``eta`` with the new ``nu``);
* inside it, **FEM substeps** at the largest stable step that divides ``h`` move the lines, with
  the fairleads following the *total* motion (LF + wave-frequency), interpolated linearly over the
  outer step.

A vessel with low-frequency roll and pitch (``vessel.roll_pitch``, :attr:`Plant.roll_pitch`;
``docs/semi.md``) integrates them in the per-outer-step path with the same semi-implicit Euler, from
the thrust, wind and drift moments at the start of the step and the lines' moments at the end of the
previous one; they add to the pose's roll and pitch, so the fairleads follow them (the fused
multi-step path is not used then). Without it the plant is the 3-DOF one, to the bit.

A scenario with a riser also gets its quasi-static end angles
(:class:`tapm_opt.models.riser.RiserModel`, the affine map of the tensioned beam) at the
instantaneous hang-off (LF + wave-frequency pose) and the sea state's current, at the end of
every outer step; the riser does not load the vessel ([R] §2.1).

The environment's random sums (the wave-frequency motion and drift sums of
:class:`~tapm_opt.plant.environment.WaveField`, the gusts of
:class:`~tapm_opt.plant.environment.Wind`) are functions of time alone: the plant evaluates them for
a block of its coming outer-step times at once (:meth:`WaveField.block
<tapm_opt.plant.environment.WaveField.block>`, :meth:`Wind.block
<tapm_opt.plant.environment.Wind.block>`, up to
:data:`~tapm_opt.plant.environment.BLOCK_MAX` steps) and applies the heading per step; they equal
the scalar-time sums to a few units in the last place of the phases.

With numba, an outer step without a winch or a turning current is two compiled calls
(:mod:`tapm_opt.plant.fem_kernel`, :attr:`Plant.compiled`): ``plant_pre_step`` (thrusters, wind
and drift loads, vessel, wave-frequency pose, riser angles, current at the nodes) and
``mooring_step`` (the lines); otherwise the thrusters, the vessel and the lines are compiled
apart. Either way the kernels repeat the numpy path's operations in its order, so both give the
same numbers. :meth:`Plant.step` runs its fused outer steps in one compiled call
(``plant_steps``: the two calls of each step in a loop, the same numbers), up to a step at whose
start a fault is due or where the plant's Python must look (a line near its strength, a health
check, a failed step), which then finishes as the single fused step does.

The controller sees the plant only through :meth:`Plant.measure` (sensors), as a real one would.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Callable, Sequence

import numpy as np

from ._kernels import fem_kernel as _fem_kernel
from .._checks import vector
from ..config.schema import SENSOR_FAULT_KINDS, FaultTargetError, buoy_of_fault, sensor_fault_issues
from ..geometry import rot_z
from ..interfaces import Measurement, ThrusterCommand, Truth, _frozen, _trusted
from ..models.system import System
from ..models.vessel import roll_pitch_moments, roll_pitch_rhs, vessel_rhs
from ..results import Result, ResultBuilder
from .environment import BLOCK_MAX, Environment, PlantError
from .fem import MAX_NODE_SPEED, SimulationDiverged, _as_f64
from .mooring_fem import MooringFEM, SettleInfo
from .sensors import Sensors
from .thrusters import ThrusterBank

#: Fraction of a line's strength at which the plant evaluates its exact fairlead and anchor
#: tensions for a break (``Plant._check_overload``: the bounds from the segment tensions come first).
OVERLOAD_NEAR = 0.98

#: Four units in the last place (relative): how far an outer-step time may lie from ``t0 + i h`` for
#: the block sums of the environment (:meth:`Plant._env_block`).
_ULP4 = 4.0 * 2.220446049250313e-16
_EMPTY = np.zeros(1)
_NO_SUMS = (0.0, 0.0, 0.0, 0.0, 0.0, np.zeros(0), np.zeros(0))

__all__ = ["Plant", "ThrusterCommand", "run_open_loop", "PlantError", "SimulationDiverged", "section_channel"]


def section_channel(line_id: str, k: int) -> str:
    """The logged channel of the tension [N] at the upper end of section ``k`` (from the anchor
    up, from 0: the scenario's ``sections`` order) of line ``line_id``: ``T_section[<line>/<k>]``
    (:meth:`FEMLines.section_tension <tapm_opt.plant.fem.FEMLines.section_tension>`). Logged for
    every section below the fairlead section of a line of several sections."""
    return f"T_section[{line_id}/{int(k)}]"


class Plant:
    """The simulated moored vessel, stepped by the closed-loop runner.

    Parameters
    ----------
    scenario : Scenario or System
        The scenario (a :class:`~tapm_opt.models.system.System` stands for its scenario).
    sea_state : str, SeaState or None
        Sea state (id or object); default the scenario's first one; ``"none"`` for no environment
        (still water, no wind, no waves).
    seed : int
        Seed of every random process (waves, wind, sensor noise).
    segments : int, optional
        FEM segments per line (default: each line's own).
    wave_frequency : bool
        Superpose first-order wave-frequency motion on the fairleads and the measurements.
    faults : sequence of Fault, optional
        Faults to inject (default: the scenario's).
    outer_dt : float
        Longest outer step [s] for vessel, thrusters and environment.
    eta0 : array_like (3,), optional
        Initial LF pose [m, m, rad] (default the field zero point); the lines are settled there.
    break_on_overload : {"mbs", "sampled", "never"}, optional
        When a line breaks from overload (default the scenario's ``plant.break_on_overload``):
        a line whose fairlead or anchor tension reaches its strength breaks at its fairlead and
        the break is logged as an event. The strength is the MBS ('mbs'), a draw from
        N(MBS, MBS_std) per line with this plant's seed ('sampled'), or infinite ('never').

    Attributes
    ----------
    compiled : bool
        Run the outer step's thrusters, vessel and lines as compiled kernels
        (:mod:`tapm_opt.plant.fem_kernel`: :func:`~tapm_opt.plant.fem_kernel.thruster_step`,
        :func:`~tapm_opt.plant.fem_kernel.vessel_step`, :func:`~tapm_opt.plant.fem_kernel.mooring_step`)
        when numba is available and the FEM kernel is "numba" (default True); False: the numpy
        path. Both give the same numbers (``tests/test_plant_speed_equivalence.py``).
    """

    compiled: bool = True
    #: Run the fused outer steps of a :meth:`step` in one compiled call (:meth:`_fused_steps`,
    #: :func:`~tapm_opt.plant.fem_kernel.plant_steps`); False: one :meth:`_fused_step` per outer
    #: step. The same numbers either way (``tests/test_plant_multistep.py``); the switch is for the
    #: tests and the benchmarks.
    _multi_step: bool = True

    def __init__(self, scenario: Any, *, sea_state: Any = None, seed: int = 0, segments: int | None = None,
                 wave_frequency: bool = True, faults: Sequence[Any] | None = None, outer_dt: float = 0.1,
                 eta0: Any = None, safety: float = 0.9, break_on_overload: str | None = None):
        if not (math.isfinite(outer_dt) and outer_dt > 0):
            raise PlantError(f"outer_dt = {outer_dt!r} s must be a positive number")
        system = scenario if isinstance(scenario, System) else System.from_scenario(scenario)
        #: The system the plant was built from (its truth is intact: broken lines come from faults).
        self.system = system if not system.broken else System.from_scenario(system.scenario)
        scenario = system.scenario
        self.scenario = scenario
        self.outer_dt = float(outer_dt)
        ss = _sea_state(scenario, sea_state)
        ss_seed, noise_seed, strength_seed = (int(c.generate_state(1)[0])
                                              for c in np.random.SeedSequence(seed).spawn(3))
        self.sea_state = ss
        self.env = Environment(scenario, ss, seed=ss_seed) if ss is not None else None
        self.wave_frequency = bool(wave_frequency) and self.env is not None and ss.Hs > 0
        # the FEM checks its nodes' depths itself each step: the profile's unchecked velocity
        dev = self.env.development if self.env is not None else None
        has_current = self.env is not None and (ss.current_speed > 0 or (
            dev is not None and dev.extremes("current_speed")[1] > 0))
        current = self.env.current.velocity_unchecked if has_current else None
        #: The sea state develops within the run (``sea_state.development``): the outer steps take
        #: the environment of their start from Python (not the fused compiled steps).
        self._developing = self.env is not None and self.env.develops
        self.mooring = MooringFEM(scenario, segments=segments, current=current, safety=safety,
                                  geometry=self.system.lines)
        self.thrusters = ThrusterBank.from_scenario(scenario)
        self.sensors = Sensors.from_scenario(scenario, seed=noise_seed)
        #: Quasi-static riser model (None without a riser), in the sea state's current.
        self.riser = self.system.riser(ss)
        self.vessel = self.system.vessel
        self._v_c = np.zeros(2) if current is None else np.asarray(self.env.current_surface(0.0)[:2], dtype=float)
        #: True when the current changes in time (``sea_state.current_turn_rate``, a developing
        #: current): vessel and lines then see the current of the start of each outer step.
        self._current_turns = current is not None and self.env.current_varies
        self.line_ids = tuple(ln.id for ln in scenario.lines)
        #: The sections below the fairlead section of each line of several sections, as
        #: ``(line j, section k, top bond)`` (:meth:`FEMLines.section_top_bonds`): logged as
        #: ``T_section[<line id>/<k>]`` (:meth:`channels`); empty without composite lines.
        self.section_tops = self.mooring.fem.section_top_bonds()
        self._sec_bonds = np.array([b for _, _, b in self.section_tops], dtype=np.int64)
        self._sec_lines = np.array([j for j, _, _ in self.section_tops], dtype=np.int64)
        self._winch_rate_max = np.array([ln.winch_max_rate for ln in scenario.lines])
        self._L_limits = np.array([ln.length_limits for ln in scenario.lines])
        self._faults = sorted(scenario.faults if faults is None else faults, key=lambda f: f.time)
        #: The joint of each buoy_loss fault, by its position in the time-sorted faults.
        self._buoy_joint: dict[int, int] = {}
        for k, f in enumerate(self._faults):
            if f.kind == "buoy_loss":
                try:
                    self._buoy_joint[k] = buoy_of_fault(scenario, f.line, getattr(f, "joint", None),
                                                        getattr(f, "point", None))[1]
                except FaultTargetError as exc:
                    sep = " " if str(exc).startswith("= ") else ": "
                    raise PlantError(f"fault buoy_loss at t = {f.time:g} s: {exc.field}{sep}{exc}") from None
                continue
            if f.kind in SENSOR_FAULT_KINDS:
                bad = sensor_fault_issues(f, self.line_ids)
                if bad:
                    raise PlantError(f"fault {f.kind} at t = {f.time!r} s: {bad[0][0]} {bad[0][1]}")
                continue
            if f.kind not in ("line_break", "thruster_failure"):
                raise PlantError(f"fault at t = {f.time:g} s has kind {f.kind!r}; kinds are 'line_break', "
                                 f"'thruster_failure', 'buoy_loss', {', '.join(map(repr, SENSOR_FAULT_KINDS))}")
            if f.kind == "line_break" and str(f.line) not in self.line_ids:
                raise PlantError(f"fault line_break at t = {f.time:g} s names line {f.line!r}, which does not "
                                 f"exist; lines are {list(self.line_ids)}")
            if f.kind == "thruster_failure" and str(f.thruster) not in self.thrusters.ids:
                raise PlantError(f"fault thruster_failure at t = {f.time:g} s names thruster {f.thruster!r}, which "
                                 f"does not exist; thrusters are {list(self.thrusters.ids)}")
        self._fault_i = 0
        self.events: list[tuple[float, str]] = []
        mode = scenario.plant.break_on_overload if break_on_overload is None else break_on_overload
        if mode not in ("mbs", "sampled", "never"):
            raise PlantError(f"break_on_overload = {mode!r} must be one of 'mbs', 'sampled', 'never'")
        self.break_on_overload = mode
        types = [scenario.line_type(ln) for ln in scenario.lines]
        mbs = np.array([t.MBS for t in types])
        if mode == "sampled":
            std = np.array([t.MBS_std for t in types])
            draw = np.random.default_rng(strength_seed).standard_normal(len(types))
            mbs = np.maximum(mbs + std * draw, 0.0)
        #: Breaking strength of each line [N] (inf: never breaks from overload).
        self.strength = np.full(len(types), np.inf) if mode == "never" else mbs
        self.t = 0.0
        self.eta = np.zeros(3) if eta0 is None else _vec3("eta0", eta0)
        self.nu = np.zeros(3)
        self._cmd = ThrusterCommand(np.zeros(self.thrusters.n), self.thrusters.alpha.copy())
        self._winch = np.zeros(len(self.line_ids))
        self._winching = False   # any(self._winch), set with it
        self._eta_wf = self._wf(0.0)
        #: The hull's wave-frequency heave, roll and pitch move the fairleads (the scenario's
        #: ``vessel.wave_motion.model = "six_dof"``; :meth:`WaveField.vertical`).
        self.six_dof = self.wave_frequency and self.env.waves.six_dof
        self._vert = self.env.waves.vertical(0.0, float(self.eta[2])) if self.six_dof else np.zeros(3)
        #: Low-frequency roll and pitch of the hull (``vessel.roll_pitch``; None: 3-DOF): the state
        #: ``rp = (phi, theta, p, q)`` [rad, rad, rad/s, rad/s] (:func:`~tapm_opt.models.vessel.roll_pitch_rhs`),
        #: integrated in the per-outer-step path; the fairleads follow it (it adds to the wave-frequency
        #: roll and pitch of the pose).
        self.roll_pitch = self.vessel.roll_pitch
        self.rp = np.zeros(4)
        self._M_lines = np.zeros(2)
        pose = np.concatenate([self.eta + self._eta_wf, self._vert])
        self.mooring.initialise(pose)
        self.settle_info: SettleInfo = self.mooring.settle(pose)
        self._tau_moor = self.mooring.tau(pose)
        if self.roll_pitch is not None:   # start at the static heel and trim the lines give
            self._M_lines = self._line_moments(pose, None)
            C = self.roll_pitch.C
            self.rp[:2] = self._M_lines / np.array(C)
            if np.max(np.abs(self.rp[:2])) > 1e-5:
                pose = np.concatenate([self.eta + self._eta_wf, self._vert + self._rp_pose()])
                self.mooring.initialise(pose)
                self.settle_info = self.mooring.settle(pose)
                self._tau_moor = self.mooring.tau(pose)
                self._M_lines = self._line_moments(pose, None)
        self._riser_angles = (None if self.riser is None else
                              self.riser.angles_at(pose[:3], self._v_c if self._current_turns else None))
        self._rate = np.zeros(6)   # the pose rate, then the heave, roll and pitch rates
        if self.wave_frequency:
            self._rate[:3] = self.env.eta_wf_dot(0.0, self.eta[2])
        if self.six_dof:
            self._rate[3:] = self.env.waves.vertical_dot(0.0, float(self.eta[2]))
        self._loads: Any = {"tau_wind": np.zeros(3), "tau_drift": np.zeros(3), "tau_moor": self._tau_moor.copy(),
                            "tau_thr": np.zeros(3)}
        # the environment's sums over blocks of outer steps (_env_sums) and the fused step's constants
        self._blk: tuple | None = None
        self._blk_j = -1
        self._blk_h, self._blk_n = math.nan, 0
        self._fused: tuple | None = None
        self._r_last = self._v_last = None
        self._steps = 0
        self._tension_cache: tuple | None = None
        self._T_alloc_cache: tuple | None = None
        self._dt_stable: float | None = None
        self._h_last = -1.0
        self._n_sub = 1

    # -- helpers ---------------------------------------------------------------------------
    def _rp_pose(self) -> np.ndarray:
        """The low-frequency (heave, roll, pitch) = (0, phi, theta) added to the pose's last three."""
        return np.array([0.0, self.rp[0], self.rp[1]])

    def _line_moments(self, pose: np.ndarray, a_fl: np.ndarray | None) -> np.ndarray:
        """Roll and pitch moments (K, M) [N m] of the lines about the centre of gravity (docs/semi.md
        eq. RP5): each fairlead force f in {E} (:meth:`FEMLines.fairlead_forces`, the load on the
        vessel, z down) at its fairlead r (of the last FEM step), turned to {B}, with the lever
        ``(b_x, b_y, z - z_G)`` from the centre of gravity: ``K = sum(b_y f_z - (z - z_G) f_y)``,
        ``M = sum((z - z_G) f_x - b_x f_z)``."""
        m = self.mooring
        fem = m.fem
        vc = m._vc[fem.fairlead_idx] if m.current is not None else None
        f = fem.fairlead_forces(vc, a_fl)
        r = m._r_fl
        c, s = math.cos(pose[2]), math.sin(pose[2])
        dx, dy = r[:, 0] - pose[0], r[:, 1] - pose[1]
        bx, by = c * dx + s * dy, c * dy - s * dx
        fx, fy = c * f[:, 0] + s * f[:, 1], c * f[:, 1] - s * f[:, 0]
        lz = r[:, 2] - self.roll_pitch.cg_depth
        return np.array([float(np.sum(by * f[:, 2] - lz * fy)), float(np.sum(lz * fx - bx * f[:, 2]))])

    def _roll_pitch_step(self, h: float, tau_thr: np.ndarray, tau_wind: np.ndarray, tau_drift: np.ndarray) -> None:
        """Advance the roll–pitch state over ``h`` [s] (semi-implicit Euler, as the vessel) under the
        thrust, wind and drift moments at the start of the step and the lines' moments of the end of
        the previous one (docs/semi.md eq. RP1, RP4, RP5)."""
        rp = self.roll_pitch
        moment = roll_pitch_moments(rp, tau_thr, tau_wind, tau_drift) + self._M_lines
        x = self.rp
        xd = roll_pitch_rhs(x, moment, rp)
        rates = x[2:] + h * xd[2:]
        self.rp = np.concatenate([x[:2] + h * rates, rates])
        if not np.isfinite(self.rp).all():
            raise SimulationDiverged(f"roll and pitch became non-finite at t = {self.t:.2f} s "
                                     f"(roll, pitch, rates = {self.rp.tolist()})", time=self.t)

    def _wf(self, t: float) -> np.ndarray:
        if not self.wave_frequency:
            return np.zeros(3)
        return np.asarray(self.env.eta_wf(t, self.eta[2]), dtype=float)

    def _end_tensions(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`MooringFEM.fairlead_tension` and :meth:`~MooringFEM.anchor_tension` [N], evaluated
        once per outer step (``measure`` and ``sample_row`` at the same instant share them; one
        pass, :meth:`FEMLines.end_tensions`); not to be changed in place."""
        fem = self.mooring.fem
        c = self._tension_cache
        # a break between steps replaces _attached; a state set from outside, r or v
        if c is None or c[0] != self._steps or c[1] is not fem.r or c[2] is not fem.v or c[3] is not fem._attached:
            c = self._tension_cache = (self._steps, fem.r, fem.v, fem._attached, fem.end_tensions())
        return c[4]

    def _fairlead_tension(self) -> np.ndarray:
        """:meth:`MooringFEM.fairlead_tension` [N] of this outer step (:meth:`_end_tensions`); a copy."""
        return self._end_tensions()[0].copy()

    @property
    def eta_total(self) -> np.ndarray:
        """LF plus wave-frequency pose (x [m], y [m], psi [rad])."""
        return self.eta + self._eta_wf

    @property
    def attitude(self) -> np.ndarray:
        """True roll, pitch and their rates (4,) [rad, rad, rad/s, rad/s] the MRU measures: the
        low-frequency state plus the wave-frequency roll and pitch (with ``six_dof``); zeros without
        ``vessel.roll_pitch``."""
        a = self.rp.copy()
        if self.six_dof:
            a[:2] += self._vert[1:]
            a[2:] += self._rate[4:]
        return a

    @property
    def fem_dt(self) -> float:
        """FEM step in use [s]."""
        return self.mooring.dt

    # -- interface -------------------------------------------------------------------------
    def step(self, dt: float, thruster_cmd: ThrusterCommand | None = None, winch_cmd: Any = None) -> None:
        """Advance the plant by ``dt`` seconds holding the commands.

        Parameters
        ----------
        dt : float
            Time to advance [s], > 0.
        thruster_cmd : ThrusterCommand, optional
            New thruster commands (kept until the next command); saturation and rate limits apply.
        winch_cmd : array_like (n_lines,), optional
            Winch speed of each line [m/s] (+ pays out, - hauls in), limited to each line's
            ``winch_max_rate`` and length limits. Non-zero on a line without a winch is an error.
        """
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise PlantError(f"dt = {dt!r} s must be a positive number")
        if thruster_cmd is not None:
            self._cmd = self._check_cmd(thruster_cmd)
        if winch_cmd is not None:
            self._winch = self._check_winch(winch_cmd)
            self._winching = bool(self._winch.any())
        n = max(1, int(math.ceil(dt / self.outer_dt - 1e-9)))
        h = dt / n
        if (self._multi_step and self.compiled and not self._winching and not self._current_turns
                and not self._developing and self.mooring.fem._kernel_fn is not None):
            k = 0
            while k < n:   # runs of fused steps in one call; a step it cannot take, on its own
                done = self._fused_steps(h, n - k)
                if not done:
                    self._outer_step(h)
                    done = 1
                k += done
            return
        for _ in range(n):
            self._outer_step(h)

    def measure(self, *, truth: bool = False) -> Measurement:
        """Sensor readings at the current time (GNSS, heading, tension cells, riser inclinometers
        if the scenario has a riser) and the thruster feedback (delivered thrust and azimuth,
        failure flags, the generalised thrust they give); with ``truth=True`` also the true LF
        state (:class:`~tapm_opt.interfaces.Truth`), for validation estimators only."""
        # the sensors only read the tensions (their held sample is a new array): no copy
        m = self.sensors._fields(self.t, self.eta + self._eta_wf, self._end_tensions()[0], self._riser_angles,
                                 self.attitude if self.roll_pitch is not None else None)
        th = self.thrusters
        tr = Truth(eta=self.eta, nu=self.nu, tau_env=self.loads["tau_wind"] + self.loads["tau_drift"]) if truth else None
        f, alpha = th._f.copy(), th._alpha.copy()
        # tau_thr = T(alpha) f, as ThrusterBank.tau computes it; T(alpha) kept while the azimuths stay
        c = self._T_alloc_cache
        if c is None or not np.array_equal(c[0], alpha):
            c = self._T_alloc_cache = (alpha.copy(), th.T_alloc())
        tau = c[1] @ th._f
        return _trusted(Measurement, **m, thruster_f=_frozen(f), thruster_alpha=_frozen(alpha),
                        thruster_failed=_frozen(th._failed.copy()), tau_thr=_frozen(tau), truth=tr)

    # -- checks ----------------------------------------------------------------------------
    def _check_cmd(self, cmd: Any) -> ThrusterCommand:
        if not isinstance(cmd, ThrusterCommand):
            if isinstance(cmd, tuple) and len(cmd) == 2:
                cmd = ThrusterCommand(*cmd)
            else:
                raise PlantError(f"thruster command must be a ThrusterCommand or (f, alpha), got {type(cmd).__name__}")
        n = self.thrusters.n
        f = np.asarray(cmd.f, dtype=float)
        alpha = self.thrusters.alpha if cmd.alpha is None else np.asarray(cmd.alpha, dtype=float)
        for name, v in (("thruster_cmd.f", f), ("thruster_cmd.alpha", alpha)):
            if v.shape != (n,):
                raise PlantError(f"{name} has shape {v.shape}, expected ({n},) for thrusters {list(self.thrusters.ids)}")
            if math.isfinite(float(v.sum())):   # a finite sum: every value is finite
                continue
            bad = np.flatnonzero(~np.isfinite(v))
            if bad.size:
                i = int(bad[0])
                raise PlantError(f"{name}[{i}] (thruster {self.thrusters.ids[i]!r}) = {float(v[i])!r} must be finite")
        return ThrusterCommand(f.copy(), alpha.copy())

    def _check_winch(self, cmd: Any) -> np.ndarray:
        w = np.asarray(cmd, dtype=float)
        if w.shape != (len(self.line_ids),):
            raise PlantError(f"winch_cmd has shape {w.shape}, expected ({len(self.line_ids)},) for lines {list(self.line_ids)}")
        bad = np.flatnonzero(~np.isfinite(w))
        if bad.size:
            i = int(bad[0])
            raise PlantError(f"winch_cmd[{i}] (line {self.line_ids[i]!r}) = {float(w[i])!r} m/s must be finite")
        no_winch = np.flatnonzero((self._winch_rate_max == 0) & (w != 0))
        if no_winch.size:
            i = int(no_winch[0])
            raise PlantError(f"winch_cmd[{i}] = {w[i]:g} m/s on line {self.line_ids[i]!r}, which has no winch "
                             "(lines[].winch_max_rate = 0)")
        return np.clip(w, -self._winch_rate_max, self._winch_rate_max)

    # -- the outer step --------------------------------------------------------------------
    def _apply_faults(self) -> None:
        while self._fault_i < len(self._faults) and self._faults[self._fault_i].time <= self.t + 1e-9:
            f = self._faults[self._fault_i]
            if f.kind == "line_break":
                self.mooring.break_line(str(f.line))
                self.events.append((self.t, f"line {f.line} broke"))
            elif f.kind == "buoy_loss":
                joint = self._buoy_joint[self._fault_i]
                self.mooring.lose_point(str(f.line), joint)
                self._dt_stable = None   # a lighter joint node: the stable step again
                self._h_last = -1.0
                self.events.append((self.t, f"line {f.line} lost its buoy at joint {joint}"))
            elif f.kind in SENSOR_FAULT_KINDS:   # the sensors corrupt their samples from f.time on
                line = self.line_ids.index(str(f.line)) if f.kind.startswith("cell_") else None
                self.sensors.inject(f, line)
                what = {"gnss_dropout": "GNSS dropout", "gnss_drift": "GNSS drift",
                        "cell_stuck": f"tension cell {f.line} stuck", "cell_drift": f"tension cell {f.line} drift",
                        "cell_noisy": f"tension cell {f.line} noisy",
                        "gyro_stuck": f"gyro {f.gyro or 1} stuck", "gyro_drift": f"gyro {f.gyro or 1} drift"}[f.kind]
                end = "" if f.end_time is None else f" until {f.end_time:g} s"
                self.events.append((float(f.time), f"sensor fault: {what}{end}"))
            else:
                self.thrusters.fail(str(f.thruster))
                self.events.append((self.t, f"thruster {f.thruster} failed"))
            self._fault_i += 1

    def _check_overload(self, T_bonds: np.ndarray) -> None:
        """Break every intact line whose fairlead or anchor tension reached its strength.

        ``T_bonds`` are the segment tensions of the last FEM substep. The fairlead tension is at
        most the top segment's tension plus the fairlead node's weight, the anchor tension is the
        bottom segment's: only when one of these bounds comes within 2 % of a line's strength are
        its exact fairlead and anchor tensions (at the end of the step) evaluated and compared.
        """
        if self.break_on_overload == "never":
            return
        m = self.mooring
        fem = m.fem
        bound = np.maximum(T_bonds[fem.fairlead_seg] + fem.node_weight[fem.fairlead_idx], T_bonds[fem.anchor_seg])
        near = bound >= OVERLOAD_NEAR * self.strength
        if not np.any(near & fem.active):
            return
        T = np.maximum(m.fairlead_tension(), m.anchor_tension())
        over = np.flatnonzero(m.fem.active & (T >= self.strength))
        for j in over:
            lid = self.line_ids[j]
            m.break_line(lid)
            mbs = self.scenario.line_type(self.scenario.lines[j]).MBS
            self.events.append((self.t, f"line {lid} broke: overload, tension {T[j] / 1e6:.3g} MN = "
                                        f"{100 * T[j] / mbs:.0f} % MBS >= strength {self.strength[j] / 1e6:.3g} MN"))

    def _env_block(self, t0: float, h: float) -> None:
        """A new block of environment sums (``self._blk``) from ``t0`` [s] on: the plant's next
        outer-step times ``t_i = round(t_{i-1} + h, 9)`` while they stay within a few units in the
        last place of ``t0 + i h`` (:meth:`WaveField.block`, :meth:`Wind.block` evaluate there),
        at least ``t0`` and the next time. Blocks of one step length grow from 16 to
        :data:`~tapm_opt.plant.environment.BLOCK_MAX` steps, so outer steps of changing length
        compute few sums they do not use."""
        n = min(2 * self._blk_n, BLOCK_MAX) if h == self._blk_h else 16
        self._blk_h, self._blk_n = h, n
        times = [t0]
        t = t0
        for i in range(1, n):
            t = round(t + h, 9)
            if abs(t - (t0 + i * h)) > _ULP4 * max(abs(t), 1.0):
                break
            times.append(t)
        env = self.env
        if len(times) >= 2:
            S, C = env.waves.block(t0, h, len(times))
            Vg = env.waves.vertical_block(t0, h, len(times))
            Dq = env.waves.drift_block(t0, h, len(times))
            V = env.wind.block(t0, h, len(times))
        else:  # the next time is off the grid of h (rounding drift): the two times on their own
            times.append(round(t0 + h, 9))
            rows = [env.waves.block(t, h, 1) for t in times]
            S, C = np.concatenate([r[0] for r in rows]), np.concatenate([r[1] for r in rows])
            Vg = np.concatenate([env.waves.vertical_block(t, h, 1) for t in times])
            Dq = np.concatenate([env.waves.drift_block(t, h, 1) for t in times])
            V = env.wind.block(times[0], h, 1) + env.wind.block(times[1], h, 1)
        # the sums of each step from the block's time i to i + 1, packed for the compiled steps
        # (Plant._fused_steps): V and q at i, S[0], S[1], C[0] and the heave, roll and pitch sums
        # on the heading grid at i + 1, the drift sums on the heading grid at i (the user's drift
        # coefficients), as _env_sums gives them
        nv = Vg.shape[1]
        packed = np.empty((len(times) - 1, 5 + nv + Dq.shape[1]))
        packed[:, 0] = V[:-1]
        packed[:, 1] = C[:-1, 1]
        packed[:, 2] = S[1:, 0]
        packed[:, 3] = S[1:, 1]
        packed[:, 4] = C[1:, 0]
        packed[:, 5:5 + nv] = Vg[1:]
        packed[:, 5 + nv:] = Dq[:-1]
        self._blk = (times, V, C[:, 1].tolist(), S[:, 0].tolist(), S[:, 1].tolist(), C[:, 0].tolist(), packed, Vg,
                     Dq)
        self._blk_j = 0

    def _env_sums(self, t0: float, t1: float, h: float) -> tuple:
        """The environment's sums of the outer step from ``t0`` to ``t1`` [s]: the wind speed V [m/s]
        and the drift sum q at ``t0`` (:meth:`Wind.speed`, ``WaveField._sums``), the motion sums
        ``S[0], S[1], C[0]`` and the heave, roll and pitch sums on the heading grid (3 G,)
        (:meth:`WaveField.vertical_block`, empty without them) at ``t1``, and the drift sums on the
        heading grid (3 G,) at ``t0`` (:meth:`WaveField.drift_block`, empty without the user's
        drift coefficients), from the block (a new one when the times are not its next)."""
        j = self._blk_j
        b = self._blk
        if b is None or j + 1 >= len(b[0]) or b[0][j] != t0 or b[0][j + 1] != t1:
            self._env_block(t0, h)
            j = 0
            b = self._blk
        self._blk_j = j + 1
        return b[1][j], b[2][j], b[3][j + 1], b[4][j + 1], b[5][j + 1], b[7][j + 1], b[8][j]

    def _outer_step(self, h: float) -> None:
        if self._fault_i < len(self._faults):
            self._apply_faults()
        t0 = self.t
        t1 = round(t0 + h, 9)  # no drift from repeated addition: logged times are exact
        if self._current_turns:   # a turning current, held over the outer step
            self._v_c = self.env.current_surface(t0)[:2]
            self.mooring.current = functools.partial(self.env.current_velocity, t=t0)
        self._tension_cache = None   # the state changes below: no tension of the last instant holds
        env = self.env
        sums = self._env_sums(t0, t1, h) if env is not None else None
        m = self.mooring
        compiled = self.compiled and m.fem._kernel_fn is not None  # numba is there and the FEM uses it
        if compiled and not self._winching and not self._current_turns and not self._developing:
            f = self._fused   # the constants of the fused step, while the lines' constants and current stay
            if (f[2] is not None if f is not None and f[0] is m.fem._kernel_constants() and f[1] is m.current
                    else self._fused_ok()):
                self._fused_step(h, t0, t1, sums)
                return
        if compiled:
            fem_kernel = _fem_kernel()   # loaded with the compiled FEM (numba) already
        tau_thr = self.thrusters._advance(h, self._cmd.f, self._cmd.alpha, compiled=compiled)
        psi0 = float(self.eta[2])
        if env is not None:
            # the wind and drift loads at t0 on the plant's own state (a finite float heading and
            # velocity: the vessel step below checks them) from the block's sums
            tau_wind = env.wind.hull.tau(sums[0], env.wind.direction_at(t0), psi0, float(self.nu[0]),
                                         float(self.nu[1]))
            if env.waves.drift_table:   # the user's coefficients: the sums on the heading grid
                tau_drift = env.waves.drift_of(sums[6], psi0, t0)
            else:
                tau_drift = 2.0 * sums[1] * sums[1] * env.waves.drift_factor(psi0)
        else:
            tau_wind = tau_drift = np.zeros(3)
        tau = tau_thr + tau_wind + tau_drift + self._tau_moor
        if compiled:
            ves = self.vessel
            eta, nu, finite = fem_kernel.vessel_step(self.eta, self.nu, tau, self._v_c, ves.M, ves.M_A, ves.M_inv,
                                                     ves.D_lin, ves.d_quad, float(h))
        else:
            _, nu_dot = vessel_rhs(self.eta, self.nu, tau, self._v_c, self.vessel, form="rich")
            nu = self.nu + h * np.asarray(nu_dot, dtype=float).ravel()
            eta = self.eta + h * (rot_z(self.eta[2]) @ nu)
            finite = np.isfinite(nu).all() and np.isfinite(eta).all()
        if not (finite and math.hypot(eta[0], eta[1]) < 1e5):
            self._diverged(t0, eta, nu)
        # winches
        winching = self._winching  # new lengths change the stable step
        if winching:
            fem = self.mooring.fem
            fem.L = np.clip(fem.L + h * self._winch, self._L_limits[:, 0], self._L_limits[:, 1])
            fem._update_lengths()
        # FEM substeps with the fairleads on the interpolated total motion
        rp_on = self.roll_pitch is not None
        pose0 = np.concatenate([self.eta + self._eta_wf, self._vert + self._rp_pose() if rp_on else self._vert])
        if rp_on:
            self._roll_pitch_step(h, tau_thr, tau_wind, tau_drift)
        self.t = t1
        self.eta, self.nu = eta, nu
        if self.wave_frequency and env.waves.grid_horizontal:
            self._eta_wf = env.waves.horizontal_of(sums[5], float(eta[2]))
        elif self.wave_frequency:
            self._eta_wf = env.waves._motion_of(sums[2], sums[3], sums[4], float(eta[2]))
        else:
            self._eta_wf = np.zeros(3)
        if self.six_dof:
            self._vert = env.waves.vertical_of(sums[5], float(eta[2]))
        pose1 = np.concatenate([self.eta + self._eta_wf, self._vert + self._rp_pose() if rp_on else self._vert])
        n_sub = self._substeps(h, winching)
        self._steps += 1
        if compiled:  # substeps, fairlead accelerations and the load in one call, the same numbers
            T_bonds, rate, a_fl, tau_moor, near, suspect = m.outer_step_compiled(pose0, pose1, self._rate, h, n_sub,
                                                                                 OVERLOAD_NEAR * self.strength)
            if suspect and self._steps % 20 == 0:
                m.fem.check_health()
            self._rate = rate
            if near:  # a line may break: the load without it
                self._check_overload(T_bonds)
                tau_moor = m.tau(pose1, a_fl)
            self._tau_moor = tau_moor
        else:
            m.dt = h / n_sub
            rate = (pose1 - pose0) / h
            # all substeps in one call (the current, if any, held over the outer step: MooringFEM.advance)
            frac = np.arange(1, n_sub + 1) / n_sub
            T_bonds = m.advance(pose0 + frac[:, None] * (pose1 - pose0), np.broadcast_to(rate, (n_sub, 6)))
            if self._steps % 20 == 0:
                m.fem.check_health()
            a_fl = m.fairlead_acceleration(pose1, rate, (rate - self._rate) / h)
            self._rate = rate
            self._check_overload(T_bonds)
            self._tau_moor = m.tau(pose1, a_fl)
        if rp_on:
            self._M_lines = self._line_moments(pose1, a_fl)
        if self.riser is not None:   # in the current of the step (a turning or developing one as the hull has it)
            self._riser_angles = self.riser.angles_at(pose1[:3], self._v_c if self._current_turns else None)
        self._loads = {"tau_wind": tau_wind, "tau_drift": tau_drift, "tau_moor": self._tau_moor, "tau_thr": tau_thr}

    def _substeps(self, h: float, winching: bool) -> int:
        """FEM substeps of an outer step of ``h`` [s] (the stable step re-evaluated after a winch)."""
        m = self.mooring
        if winching or self._dt_stable is None:
            self._dt_stable = m.fem.stable_dt(m.safety)
        if winching or h != self._h_last:
            self._n_sub = max(1, int(math.ceil(h / self._dt_stable - 1e-9)))
            self._h_last = h
        return self._n_sub

    def _diverged(self, t0: float, eta: np.ndarray, nu: np.ndarray) -> None:
        raise SimulationDiverged(
            f"vessel state became unphysical at t = {t0:.2f} s (eta = {eta.tolist()}, nu = {nu.tolist()}); "
            "check the vessel mass and damping, the thruster commands and the environmental loads",
            time=t0)

    def _fused_ok(self) -> bool:
        """The fused compiled outer step applies: the lines' current is none or the sea state's
        profile (not another callable), and the per-step constants are gathered
        (``self._fused``, rebuilt when the FEM's line constants or the lines' current change)."""
        m = self.mooring
        fem = m.fem
        kc, cur_fn = fem._kernel_constants(), m.current
        f = self._fused
        if f is not None and f[0] is kc and f[1] is cur_fn:
            return f[2] is not None
        if self.roll_pitch is not None:   # roll and pitch are integrated in the per-outer-step path
            self._fused = (kc, cur_fn, None)
            return False
        env = self.env
        prof = env.current if env is not None else None
        kinds = _fem_kernel()
        if m.current is None:
            cur = (kinds.CURRENT_HELD, False, _EMPTY, _EMPTY, 1.0, np.zeros(3))
        elif prof is not None and m.current == prof.velocity_unchecked:
            kind = {"uniform": kinds.CURRENT_UNIFORM, "linear": kinds.CURRENT_LINEAR,
                    "piecewise": kinds.CURRENT_PIECEWISE}[prof.kind]
            cur = (kind, bool(prof._interp_clamps), np.ascontiguousarray(prof._depths, dtype=float),
                   np.ascontiguousarray(prof._factors, dtype=float), float(prof.water_depth),
                   np.ascontiguousarray(prof.surface, dtype=float))
        else:
            self._fused = (kc, cur_fn, None)
            return False
        g = m.geometry
        ves, th = self.vessel, self.thrusters
        lim = th.limits
        if env is not None:
            w, wv = env.wind, env.waves
            env_c = (True, float(w.direction), np.ascontiguousarray(w.hull.k, dtype=float), float(wv.direction),
                     np.ascontiguousarray(wv._drift_c, dtype=float), np.ascontiguousarray(wv._drift_grid, dtype=float),
                     np.ascontiguousarray(wv._drift_sign, dtype=float))
        else:
            env_c = (False, 0.0, np.zeros(3), 0.0, np.zeros(3), np.zeros(0), np.zeros(0))
        if self.riser is not None:
            rz = self.riser
            riser = (True, np.array(rz._hangoff_xy + rz._wellhead_xy + rz._cc + rz._hh + rz._g_default_xy, dtype=float))
        else:
            riser = (False, np.zeros(10))
        if m._vc.shape != (fem.n_nodes, 3) or not m._vc.flags.c_contiguous or m._vc.dtype != np.float64:
            m._vc = np.array(np.broadcast_to(m._vc, (fem.n_nodes, 3)), dtype=float, order="C")
        else:
            m._vc = m._vc.copy()   # the kernel writes the current into it: the plant's own array
        # plant_pre_step's constants (after vc), mooring_step's geometry (before r) and lines (after vc)
        pre = ((th._failed, lim.f_min, lim.f_max, lim.azimuth, lim.x, lim.y) + env_c + (self.wave_frequency,)
               + (np.asarray(self._v_c, dtype=float), ves.M, ves.M_A, ves.M_inv, ves.D_lin, ves.d_quad) + riser + cur)
        geo = (m._p_cot, m._p_T, float(g.turret_angle), g.turret_mode == "locked", m.fairlead_z)
        lines = kc + (fem.fairlead_seg, fem.anchor_seg, fem.active)
        self._fused = (kc, cur_fn, (pre, geo, lines))
        return True

    def _fused_prologue(self, h: float) -> tuple[int, np.ndarray, np.ndarray]:
        """What the fused paths need before their compiled calls for outer steps of ``h`` [s]: the
        thrusters' lag factors for ``h``, the FEM substeps, and the node positions and velocities
        in the kernels' layout (copied only when set from outside)."""
        th = self.thrusters
        if th._dt_decay != h:
            th._lag(h)
        n_sub = self._n_sub if h == self._h_last and self._dt_stable is not None else self._substeps(h, False)
        fem = self.mooring.fem
        r, v = fem.r, fem.v
        if r is not self._r_last or v is not self._v_last:  # set from outside: the kernel's layout
            shape = (fem.n_nodes, 3)
            r, v = _as_f64(r, shape, "r"), _as_f64(v, shape, "v")
        return n_sub, r, v

    def _fused_step(self, h: float, t0: float, t1: float, sums) -> None:
        """:meth:`_outer_step` in two compiled calls, :func:`~tapm_opt.plant.fem_kernel.plant_pre_step`
        (thrusters, loads, vessel, wave-frequency pose, riser, current at the nodes) and
        :func:`~tapm_opt.plant.fem_kernel.mooring_step` (the lines): the same operations as the
        numpy path, for outer steps without a winch or a turning current."""
        pre, geo, lines = self._fused[2]
        m = self.mooring
        fem = m.fem
        th = self.thrusters
        n_sub, r, v = self._fused_prologue(h)
        if sums is None:
            sums = _NO_SUMS
        V0, q0, S0, S1, C0, vg = sums[:6]
        dq = sums[6] if len(sums) > 6 else _NO_SUMS[6]
        kern = _fem_kernel()
        vc = m._vc
        cmd = self._cmd
        status, out = kern.plant_pre_step(h, th._f, th._alpha, cmd.f, cmd.alpha, th._decay, th._rate_dt,
                                          th._alpha_rate_dt, V0, q0, S0, S1, C0, vg, dq, self.eta, self.nu, self._eta_wf,
                                          self._tau_moor, r, vc, *pre)
        if status == 1:
            self._diverged(t0, out[0:3], out[3:6])
        self.t = t1
        self.eta, self.nu, self._eta_wf = out[0:3], out[3:6], out[6:9]
        vert0, self._vert = self._vert, out[28:31]
        if status == 2:   # a node is no longer finite: reported as diverged
            fem.check_health()
            raise SimulationDiverged(f"FEM mooring state non-finite at t = {fem.t:.3f} s", time=fem.t)
        self._steps += 1
        m.dt = dt = h / n_sub
        pose1 = out[21:24]
        r, v, T_bonds, m._r_fl, self._rate, a_fl, tau_moor, near, suspect = kern.mooring_step(
            out[18:21], pose1, vert0, self._vert, self._rate, h, n_sub, *geo, r, v, vc, *lines,
            OVERLOAD_NEAR * self.strength, MAX_NODE_SPEED)
        fem.r, fem.v = self._r_last, self._v_last = r, v
        t = fem.t
        for _ in range(n_sub):  # the same sum as n single steps (FEMLines._advance_compiled)
            t += dt
        fem.t = t
        if suspect and self._steps % 20 == 0:
            fem.check_health()
        if near:  # a line may break: the load without it
            self._check_overload(T_bonds)
            tau_moor = m.tau(pose1, a_fl)
        self._tau_moor = tau_moor
        if self.riser is not None:
            self._riser_angles = out[24:28]
        self._loads = out

    def _fused_steps(self, h: float, n: int) -> int:
        """Up to ``n`` outer steps of ``h`` [s] as :meth:`_fused_step` takes them, in one compiled
        call (:func:`~tapm_opt.plant.fem_kernel.plant_steps`); the number taken, 0 when the first
        cannot be (the fused step does not apply, or a fault is due: :meth:`_outer_step` takes it).

        The steps' times (``round(t + h, 9)`` each) and environment sums (from the block of
        :meth:`_env_block`, a new one as :meth:`_env_sums` would start it) are found here first;
        the call covers the steps up to the one at whose start a fault is due and those the block
        holds. It stops after a step that needs this method: a line near its strength (the
        overload check and the load without a broken line) or a suspect node state on a health
        check's step, which it finishes as :meth:`_fused_step` does; a step whose pre-step failed
        is reported as :meth:`_fused_step` reports it."""
        m = self.mooring
        fem = m.fem
        f = self._fused
        if not (f[2] is not None if f is not None and f[0] is fem._kernel_constants() and f[1] is m.current
                else self._fused_ok()):
            return 0
        t0 = t = self.t
        times = [t0]
        fi = self._fault_i
        t_fault = self._faults[fi].time if fi < len(self._faults) else math.inf
        for _ in range(n):
            if t_fault <= t + 1e-9:   # _apply_faults at the start of this step
                break
            t = round(t + h, 9)
            times.append(t)
        n = len(times) - 1
        if n == 0:
            return 0
        env = self.env
        j = 0
        if env is not None:   # _env_sums of each step, from one block
            j, b = self._blk_j, self._blk
            if b is None or j + 1 >= len(b[0]) or b[0][j] != t0 or b[0][j + 1] != times[1]:
                self._env_block(t0, h)
                j, b = 0, self._blk
            bt = b[0]
            c, nb = 1, len(bt)
            while c < n and j + c + 1 < nb and bt[j + c + 1] == times[c + 1]:
                c += 1
            n = c
            sums = b[6][j:j + n]
        else:
            sums = np.zeros((n, 5))
        th = self.thrusters
        n_sub, r, v = self._fused_prologue(h)
        pre, geo, lines = self._fused[2]
        cmd = self._cmd
        steps0 = self._steps
        (k, status, outs, r, v, T_bonds, r_fl, rate, a_fl, tau_moor, near, suspect, tau_prev,
         t_fem) = _fem_kernel().plant_steps(
            h, n_sub, steps0, fem.t, sums, th._f, th._alpha, cmd.f, cmd.alpha, th._decay, th._rate_dt,
            th._alpha_rate_dt, self.eta, self.nu, self._eta_wf, self._vert, self._tau_moor, self._rate, r, v, m._vc, *pre,
            *geo,
            *lines, OVERLOAD_NEAR * self.strength, MAX_NODE_SPEED)
        self._tension_cache = None
        if env is not None:
            self._blk_j = j + k + (1 if status else 0)
        if k:
            self.t = times[k]
            out = outs[k - 1]
            self.eta, self.nu, self._eta_wf, self._vert = out[0:3], out[3:6], out[6:9], out[28:31]
            self._steps = steps0 + k
            m.dt = h / n_sub
            fem.r, fem.v = self._r_last, self._v_last = r, v
            fem.t = t_fem
            m._r_fl, self._rate = r_fl, rate
            if suspect and self._steps % 20 == 0:
                if k > 1:   # should it raise: the plant of the step before, as _fused_step leaves it
                    self._tau_moor, self._loads = tau_prev, outs[k - 2]
                    if self.riser is not None:
                        self._riser_angles = outs[k - 2, 24:28]
                fem.check_health()
            if near:  # a line may break: the load without it
                self._check_overload(T_bonds)
                tau_moor = m.tau(out[21:24], a_fl)
            self._tau_moor = tau_moor
            if self.riser is not None:
                self._riser_angles = out[24:28]
            self._loads = out
        if status:   # step k's pre-step failed: reported as _fused_step reports it
            out = outs[k]
            if status == 1:
                self._diverged(times[k], out[0:3], out[3:6])
            self.t = times[k + 1]
            self.eta, self.nu, self._eta_wf, self._vert = out[0:3], out[3:6], out[6:9], out[28:31]
            fem.check_health()
            raise SimulationDiverged(f"FEM mooring state non-finite at t = {fem.t:.3f} s", time=fem.t)
        return k

    @property
    def loads(self) -> dict[str, np.ndarray]:
        """The loads of the last outer step in {B} [N, N, N m], each (3,): ``tau_wind``, ``tau_drift``
        (at its start), ``tau_moor`` (at its end), ``tau_thr``."""
        ld = self._loads
        if type(ld) is not dict:
            ld = self._loads = {"tau_wind": ld[12:15], "tau_drift": ld[15:18], "tau_moor": self._tau_moor,
                                "tau_thr": ld[9:12]}
        return ld

    # -- logging ---------------------------------------------------------------------------
    def channels(self) -> list[tuple[str, str]]:
        """Names and units of the channels of :meth:`sample_row`."""
        ch = [("x", "m"), ("y", "m"), ("psi", "rad"), ("u", "m/s"), ("v", "m/s"), ("r", "rad/s"),
              ("x_wf", "m"), ("y_wf", "m"), ("psi_wf", "rad")]
        ch += [(f"T_fairlead[{i}]", "N") for i in self.line_ids]
        ch += [(f"T_anchor[{i}]", "N") for i in self.line_ids]
        ch += [(section_channel(self.line_ids[j], k), "N") for j, k, _ in self.section_tops]
        ch += [(f"L[{i}]", "m") for i in self.line_ids]
        ch += [(f"f[{i}]", "N") for i in self.thrusters.ids]
        ch += [(f"alpha[{i}]", "rad") for i in self.thrusters.ids]
        ch += [(f"P[{i}]", "W") for i in self.thrusters.ids]
        for load in ("tau_thr", "tau_moor", "tau_wind", "tau_drift"):
            ch += [(f"{load}[X]", "N"), (f"{load}[Y]", "N"), (f"{load}[N]", "N m")]
        if self.riser is not None:
            ch += [("riser_top[x]", "rad"), ("riser_top[y]", "rad"), ("riser_bottom[x]", "rad"),
                   ("riser_bottom[y]", "rad"), ("riser_top_angle", "rad"), ("riser_bottom_angle", "rad")]
        if self.six_dof:
            ch += [("heave_wf", "m"), ("roll_wf", "rad"), ("pitch_wf", "rad")]
        if self.roll_pitch is not None:
            ch += [("roll", "rad"), ("pitch", "rad"), ("roll_rate", "rad/s"), ("pitch_rate", "rad/s")]
        return ch

    def sample_row(self) -> np.ndarray:
        """Current values of all :meth:`channels` (true states, not measurements)."""
        m = self.mooring
        T_fl, T_an = self._end_tensions()
        parts = [
            self.eta, self.nu, self._eta_wf, T_fl, T_an,
            m.fem.section_tension(self._sec_bonds, self._sec_lines), m.fem.L,
            self.thrusters.f, self.thrusters.alpha, self.thrusters.power(),
            self.loads["tau_thr"], self.loads["tau_moor"], self.loads["tau_wind"], self.loads["tau_drift"],
        ]
        if self._riser_angles is not None:
            a = self._riser_angles
            parts += [a, (math.hypot(a[0], a[1]), math.hypot(a[2], a[3]))]
        if self.six_dof:
            parts.append(self._vert)
        if self.roll_pitch is not None:
            parts.append(self.rp)
        return np.concatenate(parts)

    def metadata(self) -> dict:
        """Inputs and settings that identify a run."""
        from .. import __version__

        ss = self.sea_state
        wm = self.scenario.vessel.wave_motion
        drift = self.env is not None and self.env.waves.drift_table
        return {
            "scenario": self.scenario.name,
            "sea_state": None if ss is None else ss.id,
            "segments": [int(s) for s in self.mooring.fem.lines.segments],
            "fem_dt": self.mooring.dt,
            "outer_dt": self.outer_dt,
            "wave_frequency": self.wave_frequency,
            # the hull's wave motion as run: the model, the user's RAO and drift tables (None: not used)
            "wave_motion": wm.model if self.six_dof else "horizontal",
            "rao_file": wm.rao_file if self.six_dof and wm.model == "table" else None,
            "drift_file": wm.drift_file if drift else None,
            "settle": {"time": self.settle_info.time, "converged": self.settle_info.converged},
            "break_on_overload": self.break_on_overload,
            "events": [[t, e] for t, e in self.events],
            "tapm_opt_version": __version__,
        }


def _sea_state(scenario: Any, sea_state: Any):
    if sea_state is None:
        return scenario.sea_states[0] if scenario.sea_states else None
    if isinstance(sea_state, str):
        if sea_state == "none":
            return None
        try:
            return scenario.sea_state(sea_state)
        except KeyError as exc:
            raise PlantError(f"sea_state = {sea_state!r}: {str(exc).strip(chr(39) + chr(34))}") from None
    return sea_state


def _vec3(name: str, v: Any) -> np.ndarray:
    return vector(name, v, 3, what="(x [m], y [m], psi [rad])", error=PlantError)


def run_open_loop(plant: Plant, duration: float, *, thruster_cmd: ThrusterCommand | Callable[[float], ThrusterCommand] | None = None,
                  winch_cmd: Any = None, dt_log: float = 1.0, meta: dict | None = None) -> Result:
    """Run the plant with fixed (or time-scheduled) commands and log every ``dt_log`` seconds.

    Parameters
    ----------
    plant : Plant
    duration : float
        Simulated time [s].
    thruster_cmd : ThrusterCommand or callable t -> ThrusterCommand, optional
        Thruster commands (held between log instants when a callable).
    winch_cmd : array_like (n_lines,), optional
        Winch speeds [m/s].
    dt_log : float
        Logging interval [s].
    """
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise PlantError(f"duration = {duration!r} s must be a positive number")
    if not (isinstance(dt_log, (int, float)) and math.isfinite(dt_log) and dt_log > 0):
        raise PlantError(f"dt_log = {dt_log!r} s must be a positive number")
    n = int(math.floor(duration / dt_log + 1e-9))
    rb = ResultBuilder(plant.channels(), capacity=n + 1)
    rb.append(plant.t, plant.sample_row())
    for _ in range(n):
        cmd = thruster_cmd(plant.t) if callable(thruster_cmd) else thruster_cmd
        plant.step(dt_log, cmd, winch_cmd)
        rb.append(plant.t, plant.sample_row())
    return rb.build({**plant.metadata(), **(meta or {})})
