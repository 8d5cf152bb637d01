"""The vessel–mooring–thruster system of a scenario, built once and handed to every consumer.

:class:`System` gathers what the plant, the controllers, the estimators and the design code
need of a scenario: the vessel parameters (:class:`~tapm_opt.models.vessel.VesselParams`), the
line system (:class:`~tapm_opt.models.mooring.MooringModel`: fairlead geometry of eq. 2–5,
numeric and symbolic catenary line characteristics through one path), the thrusters
(:class:`ThrusterSet`: configuration matrix and the **one** capacity model), the turret and the
safety limits. Build it with :meth:`System.from_scenario`; derive a condition (broken lines,
buoys lost, failed thrusters) with :meth:`System.with_broken`, :meth:`System.with_lost_points` /
:meth:`ThrusterSet.without`.

Thrust capacity (one model, used by allocation bounds, PID saturation, the MPC's thrust box and the
LQR weights): :meth:`ThrusterSet.max_tau` is, for each of X, Y and N, the largest magnitude the
thrusters can produce in that degree of freedom *alone* (the other two held at zero), in both
signs, over the convex hull of each thruster's attainable forces (an azimuth's disk less its
forbidden sectors; a fixed or tunnel thruster's segment ``[-max_reverse, max]`` along its axis).
It is a linear programme (``scipy.optimize.linprog``, HiGHS) on the 128-gon inscribed in each disk
(at most 0.03 % below the true capacity).
:meth:`ThrusterSet.capacity_box` scales it by :data:`CAPACITY_FRACTION` so that the three
components can be demanded together (a box of 0.6 of each single-DOF maximum).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np

from .._io import readonly
from ..errors import ModelError
from ..geometry import turret_offset
from .mooring import MooringModel
from .thrust import configuration_matrix, extended_columns, merge_sectors
from .vessel import VesselParams

__all__ = ["System", "ThrusterSet", "CAPACITY_FRACTION", "ATTAINABLE_DIRECTIONS", "Limits", "as_system"]

#: Fraction of each single-DOF thrust maximum that the capacity box allows in X, Y and N at once.
CAPACITY_FRACTION = 0.6

_DISK_SIDES = 128  # polygon inscribed in an azimuth's thrust disk in the capacity LP

#: Directions of the support points of :meth:`ThrusterSet.attainable_polytope` (the MPC's thrust set).
ATTAINABLE_DIRECTIONS = 32


@dataclass(frozen=True, eq=False)
class ThrusterSet:
    """The thrusters of a vessel: geometry, limits, configuration matrix and capacity.

    Attributes
    ----------
    specs : tuple of schema.Thruster
        The scenario's thruster entries (angles in rad), in order.
    failed : frozenset of str
        Ids of thrusters known to have failed (left out of the capacity).
    """

    specs: tuple
    failed: frozenset = frozenset()
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        ids = [t.id for t in self.specs]
        unknown = sorted(set(self.failed) - set(ids))
        if unknown:
            raise ModelError(f"failed thruster id(s) {unknown} not among the thrusters {ids}")

    @classmethod
    def from_scenario(cls, scenario: Any) -> "ThrusterSet":
        return cls(specs=tuple(scenario.thrusters))

    # -- plain per-thruster arrays ----------------------------------------------------------
    @property
    def n(self) -> int:
        return len(self.specs)

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(t.id for t in self.specs)

    @property
    def x(self) -> np.ndarray:
        return readonly([t.position[0] for t in self.specs])

    @property
    def y(self) -> np.ndarray:
        return readonly([t.position[1] for t in self.specs])

    @property
    def f_max(self) -> np.ndarray:
        """Largest thrust along +alpha [N], shape (n,)."""
        return readonly([t.max_thrust for t in self.specs])

    @property
    def f_min(self) -> np.ndarray:
        """Smallest (most reverse) thrust along alpha [N], shape (n,): 0 for azimuths."""
        return readonly([0.0 if t.kind == "azimuth" else -t.max_reverse_thrust for t in self.specs])

    @property
    def rate(self) -> np.ndarray:
        """Largest rate of change of thrust [N/s], shape (n,)."""
        return readonly([t.max_thrust_rate for t in self.specs])

    @property
    def azimuth(self) -> np.ndarray:
        """True for azimuth thrusters, shape (n,)."""
        return readonly([t.kind == "azimuth" for t in self.specs], dtype=bool)

    @property
    def alive(self) -> np.ndarray:
        """False for failed thrusters, shape (n,)."""
        return readonly([t.id not in self.failed for t in self.specs], dtype=bool)

    def index(self, thruster: int | str) -> int:
        """Position of a thruster given by its id (str) or its index (int, not bool)."""
        ids = self.ids
        if isinstance(thruster, str) and thruster in ids:
            return ids.index(thruster)
        if isinstance(thruster, (int, np.integer)) and not isinstance(thruster, (bool, np.bool_)) \
                and 0 <= int(thruster) < len(ids):
            return int(thruster)
        raise ModelError(f"thruster {thruster!r} is neither an id in {list(ids)} nor an index 0..{len(ids) - 1}")

    def without(self, failed: Iterable[str | int]) -> "ThrusterSet":
        """The same thrusters with ``failed`` (ids or indices) added to the failed ones."""
        add = {self.ids[self.index(f)] for f in failed}
        return ThrusterSet(specs=self.specs, failed=frozenset(self.failed | add))

    # -- geometry ----------------------------------------------------------------------------
    def configuration_matrix(self, alpha: Any) -> Any:
        """T(alpha), shape (3, n): tau = T(alpha) f (``models.thrust.configuration_matrix``)."""
        return configuration_matrix(alpha, self.x, self.y)

    def extended(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...], np.ndarray]:
        """Extended-thrust form ``tau = B u``: an azimuth contributes its force components
        (f_x, f_y), a fixed or tunnel thruster its thrust along its axis.

        Returns
        -------
        B : ndarray, shape (3, n_u)
        lo, hi : ndarray, shape (n_u,) — box bounds of u [N] (a failed thruster: 0)
        kinds : tuple of str, ``"az"`` (two entries per azimuth) or ``"fixed"``
        owner : ndarray of int, shape (n_u,) — thruster index of each column
        """
        cols, lo, hi, kinds, owner = [], [], [], [], []
        for i, t in enumerate(self.specs):
            on = t.id not in self.failed
            if t.kind == "azimuth":
                cols.append(extended_columns(*t.position))
                kinds += ["az", "az"]
                lo += [-t.max_thrust * on] * 2
                hi += [t.max_thrust * on] * 2
                owner += [i, i]
            else:
                cols.append(configuration_matrix(np.array([t.angle]), [t.position[0]], [t.position[1]]))
                kinds.append("fixed")
                lo.append(-t.max_reverse_thrust * on)
                hi.append(t.max_thrust * on)
                owner.append(i)
        if not cols:
            return np.zeros((3, 0)), np.zeros(0), np.zeros(0), (), np.zeros(0, int)
        return np.hstack(cols), np.array(lo, float), np.array(hi, float), tuple(kinds), np.array(owner)

    # -- capacity (the one model) ------------------------------------------------------------
    def _hull_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Inequalities ``A u <= b`` of the convex hull of every thruster's attainable forces in
        the extended-thrust variables (u of :meth:`extended`)."""
        B, lo, hi, kinds, owner = self.extended()
        n_u = B.shape[1]
        rows, rhs = [], []
        a = 2.0 * np.pi * np.arange(_DISK_SIDES) / _DISK_SIDES
        j = 0
        while j < n_u:
            if kinds[j] != "az":
                j += 1
                continue
            t = self.specs[owner[j]]
            fmax = hi[j]
            for ak in a:  # inscribed polygon of the disk: what is claimed is attainable
                r = np.zeros(n_u)
                r[j], r[j + 1] = math.cos(ak), math.sin(ak)
                rows.append(r)
                rhs.append(fmax * math.cos(math.pi / _DISK_SIDES))
            starts, widths = merge_sectors(t.forbidden_sectors, f"thrusters[{owner[j]}] ({t.id!r})")
            for s0, w in zip(starts, widths):
                mid = s0 + 0.5 * w
                if w < math.pi:  # the chord across the forbidden wedge
                    r = np.zeros(n_u)
                    r[j], r[j + 1] = math.cos(mid), math.sin(mid)
                    rows.append(r)
                    rhs.append(fmax * math.cos(0.5 * w))
                else:  # the allowed region is a sector narrower than pi, from s0 + w to s0 + 2 pi
                    # (counter-clockwise): u must lie counter-clockwise of the ray s0 + w and
                    # clockwise of the ray s0; each row is the normal pointing out of it
                    for edge, sgn in ((s0, -1.0), (s0 + w, 1.0)):
                        r = np.zeros(n_u)
                        r[j], r[j + 1] = sgn * math.sin(edge), -sgn * math.cos(edge)
                        rows.append(r)
                        rhs.append(0.0)
            j += 2
        A = np.array(rows) if rows else np.zeros((0, n_u))
        return A, np.array(rhs, float)

    def max_tau(self) -> np.ndarray:
        """Largest |X| [N], |Y| [N], |N| [N m] each attainable alone (the other two zero), the
        smaller of the two signs; failed thrusters excluded. Shape (3,), read-only."""
        key = ("max_tau",)
        if key not in self._cache:
            B, lo, hi, _, _ = self.extended()
            out = np.zeros(3)
            if B.shape[1]:
                import scipy.optimize  # loaded on first use (process start-up)

                A, b = self._hull_rows()
                for d in range(3):
                    others = [k for k in range(3) if k != d]
                    best = math.inf
                    for sgn in (1.0, -1.0):
                        res = scipy.optimize.linprog(-sgn * B[d], A_ub=A if len(A) else None, b_ub=b if len(A) else None,
                                                     A_eq=B[others], b_eq=np.zeros(2), bounds=list(zip(lo, hi)),
                                                     method="highs")
                        if res.status != 0:
                            raise ModelError(f"thrust capacity LP for DOF {'XYN'[d]} failed: {res.message}")
                        best = min(best, max(0.0, -res.fun))
                    out[d] = best
            self._cache[key] = readonly(out)
        return self._cache[key]

    def attainable_polytope(self, n_directions: int = ATTAINABLE_DIRECTIONS) -> tuple[np.ndarray, np.ndarray]:
        """Half-spaces ``A tau <= b`` of a polytope inside the set of generalised thrusts the
        thrusters can deliver together (failed ones excluded), ``tau`` = (X [N], Y [N], N [N m]).

        The attainable set is the image ``B u`` of the convex hull of every thruster's forces
        (the rows of the capacity LP, :meth:`max_tau`): convex. Its support points in
        ``n_directions`` directions spread evenly over the sphere (in tau scaled by
        :meth:`max_tau`, so that the set is about round) are found by LP; their convex hull is
        attainable (convex combinations of attainable thrusts are attainable) and is returned,
        with each row scaled so that ``b`` holds the distance of the facet from the origin in the
        scaled thrust (``A`` has the dimensions 1/N, 1/N, 1/(N m)). Cached; shapes (m, 3), (m,).
        """
        if not (isinstance(n_directions, int) and n_directions >= 8):
            raise ModelError(f"n_directions = {n_directions!r} must be a whole number >= 8")
        key = ("polytope", n_directions)
        if key not in self._cache:
            import scipy.optimize  # loaded on first use (process start-up)
            from scipy.spatial import ConvexHull

            B, lo, hi, _, _ = self.extended()
            scale = self.max_tau()
            if not np.all(scale > 0):
                raise ModelError(f"the thrusters (failed: {sorted(self.failed)}) cannot deliver thrust in every "
                                 f"DOF (largest X, Y, N alone: {scale.tolist()}): no attainable polytope")
            Bs = B / scale[:, None]
            A_u, b_u = self._hull_rows()
            k = np.arange(n_directions) + 0.5  # Fibonacci lattice on the unit sphere
            z = 1.0 - 2.0 * k / n_directions
            phi = math.pi * (1.0 + math.sqrt(5.0)) * k
            d = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], axis=1)
            pts = []
            for dk in d:
                res = scipy.optimize.linprog(-(dk @ Bs), A_ub=A_u if len(A_u) else None, b_ub=b_u if len(A_u) else None,
                                             bounds=list(zip(lo, hi)), method="highs")
                if res.status != 0:
                    raise ModelError(f"attainable-thrust LP in direction {dk.tolist()} failed: {res.message}")
                pts.append(Bs @ res.x)
            hull = ConvexHull(np.array(pts))
            nrm, off = hull.equations[:, :3], -hull.equations[:, 3]  # nrm . tau_s <= off, |nrm| = 1
            # merge coplanar triangles (one row per facet plane)
            keyed = {}
            for n_, o_ in zip(nrm, off):
                keyed.setdefault(tuple(np.round(np.append(n_, o_), 9)), (n_, o_))
            nrm = np.array([v[0] for v in keyed.values()])
            off = np.array([v[1] for v in keyed.values()])
            self._cache[key] = (readonly(nrm / scale[None, :]), readonly(off))
        return self._cache[key]

    def capacity_box(self, fraction: float = CAPACITY_FRACTION) -> np.ndarray:
        """Box ``|tau_j| <= fraction * max_tau()[j]`` the thrusters can deliver in X, Y and N at
        once [N, N, N m]. Shape (3,)."""
        if not (math.isfinite(fraction) and 0.0 < fraction <= 1.0):
            raise ModelError(f"capacity fraction = {fraction!r} must be in (0, 1]")
        return readonly(fraction * self.max_tau())

    def rate_ratio(self) -> float:
        """The slowest thruster's ratio of thrust rate to maximum thrust [1/s] (failed ones
        excluded; 0 when none is left): the fraction of any attainable thrust the set can change
        by per second."""
        alive = self.alive
        return min((self.rate[i] / self.f_max[i] for i in range(self.n) if alive[i]), default=0.0)

    def rate_box(self, fraction: float = CAPACITY_FRACTION) -> np.ndarray:
        """Rate of change of tau the thrusters can follow in X, Y and N at once [N/s, N/s, N m/s]:
        the capacity box scaled by :meth:`rate_ratio`."""
        return readonly(self.capacity_box(fraction) * self.rate_ratio())


@dataclass(frozen=True)
class Limits:
    """Safety limits (turret-referenced radii)."""

    safe_radius: float | None
    alert_radius: float | None
    tension_utilisation: float


@dataclass(frozen=True, eq=False)
class System:
    """A moored vessel built once from a scenario (module docstring).

    Attributes
    ----------
    scenario : Scenario
        The validated scenario the system was built from (the plant builds its truth from it).
    vessel : VesselParams
        Design-model parameters (survey eq. 14–15).
    lines : MooringModel
        The intact line system (catenary lines on the turret).
    thrusters : ThrusterSet
    p_cot_B : ndarray, shape (2,)
        Centre of turret in {B} [m]: the reference point of every safety measure.
    limits : Limits
    broken : tuple of str
        Lines left out of ``lines`` (see :meth:`with_broken`).
    lost_points : tuple of (str, int)
        Points (buoys, clumps) gone from composite lines, (line id, joint) (see
        :meth:`with_lost_points`).
    """

    scenario: Any
    vessel: VesselParams
    lines: MooringModel
    thrusters: ThrusterSet
    p_cot_B: np.ndarray
    limits: Limits
    broken: tuple[str, ...] = ()
    lost_points: tuple[tuple[str, int], ...] = ()
    _risers: dict = field(default_factory=dict, repr=False, compare=False)

    def riser(self, sea_state: Any = None) -> Any:
        """The quasi-static riser model (``models.riser.RiserModel``) in ``sea_state``'s current
        (a SeaState, an id of the scenario, or None for still water), built once per sea state and
        shared by the plant, the closed loop's setpoint layer and the MPC; None without a riser."""
        if self.scenario.riser is None:
            return None
        key = getattr(sea_state, "id", sea_state)
        if key not in self._risers:
            from .riser import RiserModel

            self._risers[key] = RiserModel.from_scenario(self.scenario, sea_state)
        return self._risers[key]

    @classmethod
    def from_scenario(cls, scenario: Any) -> "System":
        lim = scenario.limits
        return cls(scenario=scenario, vessel=VesselParams.from_scenario(scenario),
                   lines=MooringModel.from_scenario(scenario), thrusters=ThrusterSet.from_scenario(scenario),
                   p_cot_B=readonly(scenario.turret.position),
                   limits=Limits(safe_radius=lim.safe_radius, alert_radius=lim.alert_radius,
                                 tension_utilisation=float(lim.tension_utilisation)))

    @property
    def name(self) -> str:
        return str(self.scenario.name)

    def with_broken(self, broken: Iterable[str | int]) -> "System":
        """The system with the lines ``broken`` (line ids, as in the scenario) removed from its line
        system. Unknown ids raise :class:`~tapm_opt.errors.ModelError`."""
        ids = [ln.id for ln in self.scenario.lines]
        if isinstance(broken, (str, bytes)):
            broken = [broken]
        b = []
        for k in broken:
            s = str(k)
            if isinstance(k, (bool, np.bool_)) or s not in ids:
                raise ModelError(f"broken line {k!r} is not a line id; lines are {ids}")
            if s not in b:
                b.append(s)
        allb = tuple(dict.fromkeys((*self.broken, *b)))
        if not allb:
            return self
        return System(scenario=self.scenario, vessel=self.vessel,
                      lines=MooringModel.from_scenario(self.scenario, broken=allb, lost_points=self.lost_points),
                      thrusters=self.thrusters, p_cot_B=self.p_cot_B, limits=self.limits, broken=allb,
                      lost_points=self.lost_points, _risers=self._risers)

    def with_lost_points(self, points: Iterable[tuple[str, int]]) -> "System":
        """The system with the points ``points`` ((line id, joint index from the anchor up): buoys
        or clumps of composite lines) gone from its line system
        (:meth:`MooringModel.with_points_lost <tapm_opt.models.mooring.MooringModel.with_points_lost>`;
        points on broken lines are ignored). Unknown lines, homogeneous lines and joints without a
        point raise :class:`~tapm_opt.errors.ModelError`."""
        pts = [(str(lid), j) for lid, j in points]
        ids = [ln.id for ln in self.scenario.lines]
        for lid, _ in pts:
            if lid not in ids:
                raise ModelError(f"lost point on line {lid!r}, which is not a line id; lines are {ids}")
        allp = tuple(dict.fromkeys((*self.lost_points, *((lid, j) for lid, j in pts if lid not in self.broken))))
        if allp == self.lost_points:
            return self
        return System(scenario=self.scenario, vessel=self.vessel,
                      lines=MooringModel.from_scenario(self.scenario, broken=self.broken, lost_points=allp),
                      thrusters=self.thrusters, p_cot_B=self.p_cot_B, limits=self.limits, broken=self.broken,
                      lost_points=allp, _risers=self._risers)

    def with_failed_thrusters(self, failed: Iterable[str | int]) -> "System":
        return System(scenario=self.scenario, vessel=self.vessel, lines=self.lines,
                      thrusters=self.thrusters.without(failed), p_cot_B=self.p_cot_B, limits=self.limits,
                      broken=self.broken, lost_points=self.lost_points, _risers=self._risers)

    def turret_offset(self, eta: Any) -> Any:
        """Turret-referenced offset (x, y) [m] of pose(s) ``eta`` (``geometry.turret_offset``)."""
        return turret_offset(eta, self.p_cot_B)


def as_system(system_or_scenario: Any) -> System:
    """``system_or_scenario`` as a :class:`System` (a scenario is built into one)."""
    if isinstance(system_or_scenario, System):
        return system_or_scenario
    return System.from_scenario(system_or_scenario)
