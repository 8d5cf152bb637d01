"""MoorDyn-C as a reference for the FEM plant: the forced-motion analysis run through MoorDyn.

The scenario is written as a MoorDyn v2 file (:func:`tapm_opt.config.moordyn.moordyn_text`: one
coupled body at the centre of turret, the fairleads on it, the anchors fixed) and run with the
``moordyn`` Python wheel (imported only here, when a run starts), under the protocol of
:func:`tapm_opt.plant.forced_motion.forced_motion`:

1. **settle** with the vessel at the field zero point: MoorDyn's own initial condition (its
   stationary solver, ``TmaxIC`` 600 s, ``threshIC`` 1e-3), then the body held still until every
   fairlead tension changes by less than ``settle_tol`` over ``check_every`` seconds (MoorDyn has
   no settling damping to add, so the remaining oscillation, ~1e-4 of the tension, sets the
   tolerance);
2. **move** from t = 0 as ``eta_dof(t) = A sin(2 pi t / T)`` (full speed at t = 0): the body is
   given the centre-of-turret pose at the start of each coupling step and the secant velocity
   over it (MoorDyn moves coupled bodies linearly within a step and takes their acceleration
   as the change of that velocity).

Outputs match :class:`~tapm_opt.plant.forced_motion.ForcedMotionResult`:

* ``T``: fairlead tension as tapm_opt defines it, ``|top segment tension (with internal damping)
  + the fairlead node's submerged weight|`` (``GetLineNodeTen`` and ``GetLineNodeWeight`` of the
  end node); ``T_moordyn`` is MoorDyn's own ``GetLineFairTen``, the top segment alone;
* ``force``: MoorDyn's force on the coupled body, in {E} (NED): ``(F_x, F_y, M_z about the body
  origin)`` — the moment about the centre of turret is dropped for a free turret (its bearing
  transmits none) and the lever arm of the turret added. MoorDyn-C's coupled-body force is the
  sum over its points of the end nodes' net force (tension and internal damping of the top
  segment, the node's submerged weight, drag and seabed contact) **minus the end nodes' mass and
  added mass times the body's acceleration** (``Body::getFnet``: ``F6net - M a6``); a coupled
  *point* reports no inertia (``Point::getFnet``). See ``docs/moordyn.md``.
* ``damping``: the equivalent linear damping from the energy dissipated per cycle over the cycles
  after the first, ``b = W / (pi omega A^2)``, as in ``forced_motion``.

Timing: MoorDyn's explicit schemes leave the forces and tensions of their last stage: with RK2
the midpoint ``t + h/2`` of a step, with RK4 its end. Samples are stamped with that time; output
values at ``t = k dt_out`` are interpolated between the two stages around it, and the dissipated
power uses the vessel velocity at each stamp.
"""

from __future__ import annotations

import math
import os
import re
import sys
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Literal

import numpy as np

from ..errors import ModelError, TapmError

__all__ = [
    "MoorDynUnavailable",
    "MoorDynRunError",
    "MoorDynForcedMotionResult",
    "MoorDynMooring",
    "moordyn_forced_motion",
    "moordyn_module",
]

DOFS = ("surge", "sway", "yaw")
#: Time within a step [fraction of the step] at which a scheme's last stage evaluates the forces.
STAGE_OFFSET = {"RK2": 0.5, "RK4": 1.0}


class MoorDynUnavailable(TapmError, ImportError):
    """The ``moordyn`` Python package (MoorDyn-C) is not installed."""


class MoorDynRunError(TapmError, RuntimeError):
    """MoorDyn failed to read, initialise or step the model (``log`` holds its console output)."""

    def __init__(self, message: str, log: str = ""):
        self.log = log
        tail = " | ".join(ln.strip() for ln in log.strip().splitlines()[-3:] if ln.strip())
        super().__init__(f"{message}{'; MoorDyn said: ' + tail if tail else ''}")


def moordyn_module():
    """The ``moordyn`` package, imported on first use."""
    try:
        import moordyn  # noqa: PLC0415
    except ImportError as exc:
        raise MoorDynUnavailable(
            f"the MoorDyn reference needs the 'moordyn' package (MoorDyn-C), which cannot be imported ({exc}); "
            "install it with: python -m pip install 'moordyn>=2.7,<3' (it is in the test extra, .[test])") from None
    return moordyn


def moordyn_version() -> str:
    try:
        from importlib.metadata import version

        return version("moordyn")
    except Exception:  # pragma: no cover - metadata missing
        return "unknown"


@contextmanager
def _console_to(path: Path) -> Iterator[None]:
    """Send the process's stdout and stderr (file descriptors 1 and 2: MoorDyn-C writes there) to
    ``path`` for the duration."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    try:
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for f in (fd, *saved):
            os.close(f)


class MoorDynMooring:
    """A scenario's mooring in MoorDyn-C, driven through its coupled turret body.

    Parameters
    ----------
    scenario : Scenario
    segments : int, optional
        Segments of every line (default: each line's own).
    workdir : path, optional
        Folder for the input file, MoorDyn's output and its console log (default: a temporary
        folder removed by :meth:`close`).
    dtM, scheme : optional
        Override the time step and scheme chosen by the export.
    """

    def __init__(self, scenario: Any, *, segments: int | None = None, workdir: str | Path | None = None,
                 dtM: float | None = None, scheme: str | None = None):
        from ..config.moordyn import moordyn_text

        self.md = moordyn_module()
        self.scenario = scenario
        self._tmp = None
        if workdir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="tapm_moordyn_")
            workdir = self._tmp.name
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.text, self.info = moordyn_text(scenario, segments=segments, dtM=dtM, scheme=scheme, outputs=False,
                                            extra_options={"disableOutput": 1})
        if self.info.scheme not in STAGE_OFFSET:
            raise ModelError(f"scheme = {self.info.scheme!r}: the reference driver runs RK2 or RK4")
        self.dtM = self.info.dtM
        self.scheme = self.info.scheme
        self.path = self.workdir / "mooring.dat"
        self.path.write_text(self.text, encoding="utf-8")
        self.log_path = self.workdir / "moordyn_console.log"
        self.log_path.write_text("", encoding="utf-8")
        tur = scenario.turret
        self.p_cot = np.array(tur.position, dtype=float)
        self.alpha_t = float(tur.angle)
        self.locked = tur.mode == "locked"
        self.n_lines = len(scenario.lines)
        self.sys = None
        self.t = 0.0
        self.ic_time = 0.0
        with self._console():
            try:
                self.sys = self.md.Create(str(self.path))
            except RuntimeError:
                pass
        if self.sys is None:
            raise MoorDynRunError("MoorDyn could not read the exported model", self.log())
        self.lines = [self.md.GetLine(self.sys, i + 1) for i in range(self.n_lines)]

    # -- plumbing --------------------------------------------------------------------------
    def _console(self):
        return _console_to(self.log_path)

    def log(self) -> str:
        try:
            return self.log_path.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return ""

    def close(self) -> None:
        if self.sys is not None:
            with self._console():
                self.md.Close(self.sys)
            self.sys = None
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> "MoorDynMooring":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -- kinematics ------------------------------------------------------------------------
    def body_pose(self, eta: np.ndarray) -> np.ndarray:
        """MoorDyn state (x, y, z, roll, pitch, yaw) of the turret body for the vessel pose ``eta``."""
        x, y, psi = float(eta[0]), float(eta[1]), float(eta[2])
        c, s = math.cos(psi), math.sin(psi)
        cx = x + c * self.p_cot[0] - s * self.p_cot[1]
        cy = y + s * self.p_cot[0] + c * self.p_cot[1]
        heading = psi + self.alpha_t if self.locked else self.alpha_t
        return np.array([cx, -cy, 0.0, 0.0, 0.0, -heading])

    def load_E(self, f6: Any, eta: np.ndarray) -> np.ndarray:
        """MoorDyn's 6-DOF body force (MoorDyn frame, about the COT) as the load on the vessel in
        {E}: (F_x [N], F_y [N], M_z about the body origin [N m])."""
        Fx, Fy = float(f6[0]), -float(f6[1])
        psi = float(eta[2])
        c, s = math.cos(psi), math.sin(psi)
        rx = c * self.p_cot[0] - s * self.p_cot[1]
        ry = s * self.p_cot[0] + c * self.p_cot[1]
        Mz = rx * Fy - ry * Fx
        if self.locked:
            Mz += -float(f6[5])
        return np.array([Fx, Fy, Mz])

    # -- running ---------------------------------------------------------------------------
    def init(self, eta0: np.ndarray) -> None:
        x = self.body_pose(eta0)
        with self._console():
            err = self.md.Init(self.sys, list(x), [0.0] * 6)
        if err:
            raise MoorDynRunError(f"MoorDyn's initial condition failed (error code {err})", self.log())
        m = re.findall(r"Remaining error after ([0-9.eE+-]+) s", self.log())
        self.ic_time = float(m[-1]) if m else 0.0
        self._x, self._t = x, 0.0

    def step(self, x: np.ndarray, xd: np.ndarray, h: float) -> np.ndarray:
        """One coupling step of length ``h`` from body state ``x`` moving at ``xd``; the body
        force (6, MoorDyn frame) at the scheme's last stage."""
        try:
            f = self.md.Step(self.sys, list(x), list(xd), self.t, h)
        except Exception as exc:  # the wheel raises RuntimeError on a failed step
            raise MoorDynRunError(f"MoorDyn failed at t = {self.t:.3f} s: {exc}", self.log()) from None
        self.t += h
        f = np.asarray(f, dtype=float)
        if not np.all(np.isfinite(f)):
            raise MoorDynRunError(f"MoorDyn's body force became non-finite at t = {self.t:.3f} s (dtM "
                                  f"{self.dtM:g} s, {self.scheme})", self.log())
        return f

    def fairlead_tensions(self) -> tuple[np.ndarray, np.ndarray]:
        """(tapm_opt fairlead tension, MoorDyn FairTen) of every line [N], at the last stage."""
        md = self.md
        T = np.empty(self.n_lines)
        Tm = np.empty(self.n_lines)
        for i, ln in enumerate(self.lines):
            n = md.GetLineN(ln)
            ten = np.asarray(md.GetLineNodeTen(ln, n), dtype=float)
            wgt = np.asarray(md.GetLineNodeWeight(ln, n), dtype=float)
            T[i] = math.sqrt(float(np.sum((wgt - ten) ** 2)))
            Tm[i] = math.sqrt(float(np.sum(ten * ten)))
        return T, Tm


@dataclass(frozen=True)
class MoorDynForcedMotionResult:
    """Result of :func:`moordyn_forced_motion` (fields as in ``ForcedMotionResult``).

    Attributes
    ----------
    t, eta : ndarray
        Output times [s] and the prescribed vessel pose (n_out, 3).
    T : ndarray (n_out, n_lines)
        Fairlead tension, tapm_opt's definition (top segment + fairlead node weight) [N].
    T_moordyn : ndarray (n_out, n_lines)
        MoorDyn's ``FairTen`` (top segment tension with internal damping) [N].
    force : ndarray (n_out, 3)
        Load on the vessel in {E}: (F_x [N], F_y [N], M_z [N m]), inertia of the end nodes included.
    damping, energy_per_cycle : float
        Equivalent linear damping [N s/m or N m s/rad] and energy dissipated per cycle [J].
    dtM, scheme : float, str
        MoorDyn time step [s] and scheme; the coupling step is ``dt``.
    settle_time : float
        Simulated settling: MoorDyn's initial-condition pseudo-time plus the hold [s].
    settle_converged : bool
        Whether the hold met ``settle_tol``; ``settle_change`` the last relative change.
    wall_time, settle_wall_time : float
        Wall time of the whole call (export, MoorDyn set-up, settling, motion) and of the
        set-up and settling [s].
    """

    line_ids: tuple[str, ...]
    dof: str
    amplitude: float
    period: float
    t: np.ndarray
    eta: np.ndarray
    T: np.ndarray
    T_moordyn: np.ndarray
    force: np.ndarray
    damping: float
    energy_per_cycle: float
    dtM: float
    scheme: str
    dt: float
    segments: int | None
    cycles_analysed: int
    settle_time: float
    settle_converged: bool
    settle_change: float
    wall_time: float
    settle_wall_time: float
    moordyn_version: str
    input_text: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def real_time_factor(self) -> float:
        """(settling + motion) simulated seconds per wall second, whole call."""
        return (self.settle_time + float(self.t[-1])) / self.wall_time if self.wall_time > 0 else math.nan


def _energy(t: np.ndarray, p: np.ndarray, t0: float, t1: float) -> float:
    """Integral of the samples ``p(t)`` over [t0, t1] (trapezoid, ends interpolated)."""
    inside = (t > t0) & (t < t1)
    tt = np.concatenate([[t0], t[inside], [t1]])
    pp = np.concatenate([[np.interp(t0, t, p)], p[inside], [np.interp(t1, t, p)]])
    return float(np.trapezoid(pp, tt))


def moordyn_forced_motion(scenario: Any, *, dof: Literal["surge", "sway", "yaw"] = "surge", amplitude: float,
                          period: float, duration: float, segments: int | None = None, dt_out: float = 1.0,
                          settle_tol: float = 1e-3, settle_max_time: float = 300.0, check_every: float = 5.0,
                          dtM: float | None = None, scheme: str | None = None,
                          workdir: str | Path | None = None) -> MoorDynForcedMotionResult:
    """Forced motion of the scenario's mooring in MoorDyn-C (the protocol of ``forced_motion``).

    Parameters as :func:`tapm_opt.plant.forced_motion.forced_motion` (still water); ``settle_*``
    and ``check_every`` control the hold after MoorDyn's initial condition; ``dtM``/``scheme``
    override the exported step; ``workdir`` keeps MoorDyn's files (default: a temporary folder).

    Raises
    ------
    MoorDynUnavailable
        The ``moordyn`` package is not installed.
    MoorDynRunError
        MoorDyn could not read, initialise or step the model.
    """
    w0 = time.perf_counter()
    if dof not in DOFS:
        raise ModelError(f"dof = {dof!r} is not one of {', '.join(DOFS)}")
    for name, val in (("amplitude", amplitude), ("period", period), ("duration", duration), ("dt_out", dt_out)):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
            raise ModelError(f"{name} = {val!r} must be a positive number")
    if segments is not None and (not isinstance(segments, (int, np.integer)) or segments < 2):
        raise ModelError(f"segments = {segments!r} must be a whole number >= 2")
    k = DOFS.index(dof)
    omega = 2.0 * math.pi / period
    with MoorDynMooring(scenario, segments=segments, workdir=workdir, dtM=dtM, scheme=scheme) as mm:
        eta0 = np.zeros(3)
        mm.init(eta0)
        # -- hold at the field zero point ------------------------------------------------------
        x0 = mm.body_pose(eta0)
        zero = np.zeros(6)
        sub = int(math.ceil(dt_out / mm.dtM - 1e-9))
        h = dt_out / sub
        n_check = max(1, int(round(check_every / h)))
        T_prev, _ = mm.fairlead_tensions()
        held, change, converged = 0.0, math.inf, False
        while held < settle_max_time - 1e-9:
            for _ in range(n_check):
                mm.step(x0, zero, h)
            held += n_check * h
            T_now, _ = mm.fairlead_tensions()
            change = float(np.max(np.abs(T_now - T_prev) / np.maximum(np.abs(T_now), 1.0)))
            T_prev = T_now
            if change < settle_tol:
                converged = True
                break
        settle_wall = time.perf_counter() - w0

        # -- forced motion ----------------------------------------------------------------------
        def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
            e, ed = np.zeros(3), np.zeros(3)
            e[k] = amplitude * math.sin(omega * t)
            ed[k] = amplitude * omega * math.cos(omega * t)
            return e, ed

        n_out = int(math.floor(duration / dt_out + 1e-9)) + 1
        n_steps = (n_out - 1) * sub
        off = STAGE_OFFSET[mm.scheme] * h
        t_out = np.arange(n_out) * dt_out
        eta_out = np.zeros((n_out, 3))
        T_out = np.zeros((n_out, mm.n_lines))
        Tm_out = np.zeros((n_out, mm.n_lines))
        F_out = np.zeros((n_out, 3))
        # t = 0: the settled state at rest (the motion starts at full speed with the first step)
        T_out[0], Tm_out[0] = mm.fairlead_tensions()
        F_out[0] = mm.load_E(mm.step(x0, zero, h), eta0)  # one more held step: the force at rest
        # with RK2 the stages sit at mid-step: an output at t_j is the mean of the stages at
        # t_j - h/2 and t_j + h/2, so one step more than the motion needs is run
        n_run = n_steps + (1 if off < h else 0)
        stamps = np.empty(n_run)
        power = np.empty(n_run)
        pending = None  # (j, T, Tm, F) of the stage just before output time t_j
        x_i = x0
        for i in range(n_run):
            t_i = i * h
            e1, _ = pose(t_i + h)
            x_n = mm.body_pose(e1)
            f6 = mm.step(x_i, (x_n - x_i) / h, h)
            ts = t_i + off
            es, eds = pose(ts)
            F = mm.load_E(f6, es)
            stamps[i] = ts
            power[i] = -F[k] * eds[k]
            T = Tm = None
            if pending is not None:
                T, Tm = mm.fairlead_tensions()
                j, T0, Tm0, F0 = pending
                T_out[j], Tm_out[j], F_out[j] = 0.5 * (T0 + T), 0.5 * (Tm0 + Tm), 0.5 * (F0 + F)
                pending = None
            j = (i + 1) // sub
            if (i + 1) % sub == 0 and j < n_out:
                eta_out[j] = e1
                if T is None:
                    T, Tm = mm.fairlead_tensions()
                if off == h:
                    T_out[j], Tm_out[j], F_out[j] = T, Tm, F
                else:
                    pending = (j, T, Tm, F)
            x_i = x_n
        text = mm.text
        dtM_used, scheme_used, ic_time = mm.dtM, mm.scheme, mm.ic_time

    n_cyc = int(math.floor(duration / period + 1e-9)) - 1
    if n_cyc >= 1:
        W = _energy(stamps, power, period, period * (1 + n_cyc)) / n_cyc
        b_eq = W / (math.pi * omega * amplitude**2)
    else:
        W, b_eq = math.nan, math.nan
    return MoorDynForcedMotionResult(
        line_ids=tuple(ln.id for ln in scenario.lines), dof=dof, amplitude=float(amplitude), period=float(period),
        t=t_out, eta=eta_out, T=T_out, T_moordyn=Tm_out, force=F_out, damping=b_eq, energy_per_cycle=W,
        dtM=dtM_used, scheme=scheme_used, dt=h, segments=segments, cycles_analysed=max(n_cyc, 0),
        settle_time=ic_time + held, settle_converged=converged, settle_change=change,
        wall_time=time.perf_counter() - w0, settle_wall_time=settle_wall, moordyn_version=moordyn_version(),
        input_text=text, meta={"scenario": scenario.name, "ic_time": ic_time, "hold_time": held},
    )
