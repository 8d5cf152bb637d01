"""DNV-ST-0111 Level 1 thrust losses applied to a scenario's thrusters (``tapm capability --losses``).

The losses of the standard's Level 1 that the scenario's data allow (``docs/capability.md``,
"Thrust losses"), DNV-ST-0111 (December 2021 edition) as transcribed from a secondary source
(section numbers of that edition; **not checked against the standard itself**):

* **[3.9.3] miscellaneous losses**: every thruster's thrust is multiplied by the constant
  ``beta_misc = 0.9`` (:data:`BETA_MISC`, "a constant 10 % thrust loss" in the transcription). The
  transcription has no separate Level 1 model of thruster-hull interaction or current inflow; that
  this constant stands for them is the project's reading, unchecked.
* **[3.11.3] thruster-thruster interaction**: a thruster ``i`` may not flush a *working* thruster
  ``j`` closer than ``15 D_i`` (:data:`FLUSHING_DISTANCE_D`) unless ``j`` is a tunnel thruster:
  ``i``'s thrust direction must not lie within ``atan(0.1 + D_i / s)`` of the direction of the
  vector from ``j`` to ``i`` (pushing away from ``j`` sends the race onto it), ``s`` the
  horizontal distance, ``D_i`` the flushing thruster's diameter. These become forbidden sectors of
  the azimuth thrusters (merged with the scenario's own), which the thrust allocator and the
  attainable polytope already honour.

Not applied, for want of data in the scenario schema (no propeller depth, no skeg): the
ventilation loss [3.9.4] (the submergence of each propeller and its load) and the skeg loss
[3.11.5]. The loss for flushing a *dead* thruster [3.11.4] is not applied either: with a thruster
failed, the forbidden sectors toward it are kept, a wider exclusion than the standard's notch
(conservative). A tunnel or fixed thruster whose axis points into another thruster's interaction
sector keeps its thrust (noted in :attr:`ThrustLosses.notes`).

Diameters: the scenario gives none, so a thruster's diameter is by default that of the disk of the
plant's power model, ``D = sqrt(4 A / pi)`` with ``A = max_thrust / q`` and the bollard thrust
loading ``q`` of :data:`tapm_opt.plant.thrusters.THRUST_LOADING` (one assumption shared with the
thrusters' power; fpso: 1.2 MN, D = 5.5 m), or one diameter given for all.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from ..errors import TapmError
from ..geometry import merge_sectors, ssa

__all__ = [
    "BETA_MISC",
    "FLUSHING_DISTANCE_D",
    "ThrustLossError",
    "ThrustLosses",
    "apply_level1_losses",
    "default_diameter",
    "interaction_sectors",
]

#: DNV-ST-0111 (2021) [3.9.3]: constant thrust loss factor of Level 1 (secondary transcription).
BETA_MISC = 0.9
#: DNV-ST-0111 (2021) [3.11.3]: a thruster may not flush a working thruster closer than this many
#: of its own diameters (unless the flushed thruster is a tunnel thruster).
FLUSHING_DISTANCE_D = 15.0


class ThrustLossError(TapmError, ValueError):
    """Bad thrust-loss input (the message names it)."""


@dataclass(frozen=True)
class ThrustLosses:
    """The Level 1 losses applied to a scenario's thrusters.

    Attributes
    ----------
    beta_misc : float
        Factor on every thruster's thrust [-] ([3.9.3]).
    diameters : dict
        Diameter used per thruster id [m].
    pairs : tuple of dict
        Every interaction sector: ``flushing``, ``flushed`` (ids), ``distance`` [m],
        ``centre_deg`` (the flushing thruster's forbidden thrust direction, from x^B toward y^B)
        and ``half_width_deg``.
    sectors : dict
        The sectors added per azimuth thruster id, ``(from, to)`` [rad] counter-clockwise.
    notes : tuple of str
        What was not applied and why.
    """

    beta_misc: float
    diameters: dict
    pairs: tuple = ()
    sectors: dict = field(default_factory=dict)
    notes: tuple = ()

    def as_json(self) -> dict:
        return {"standard": "DNV-ST-0111 (December 2021) Level 1, secondary transcription: [3.9.3] beta_misc, "
                            "[3.11.3] thruster-thruster interaction sectors",
                "beta_misc": self.beta_misc, "diameters_m": dict(self.diameters), "pairs": [dict(p) for p in self.pairs],
                "notes": list(self.notes)}


def default_diameter(max_thrust: float) -> float:
    """Diameter [m] of the disk of the plant's thruster power model for a thrust of
    ``max_thrust`` [N]: ``sqrt(4 max_thrust / (pi q))``, ``q`` the assumed bollard thrust loading
    :data:`tapm_opt.plant.thrusters.THRUST_LOADING`."""
    from ..plant.thrusters import THRUST_LOADING

    return math.sqrt(4.0 * float(max_thrust) / (math.pi * THRUST_LOADING))


def _diameters(thrusters: Any, diameter: float | None) -> dict[str, float]:
    if diameter is not None:
        if isinstance(diameter, bool) or not isinstance(diameter, (int, float)) or not (
                math.isfinite(diameter) and diameter > 0):
            raise ThrustLossError(f"thruster_diameter = {diameter!r} must be a positive number of metres")
        return {t.id: float(diameter) for t in thrusters}
    return {t.id: default_diameter(t.max_thrust) for t in thrusters}


def interaction_sectors(thrusters: Any, diameters: dict[str, float]) -> tuple[list[dict], list[str]]:
    """The [3.11.3] sectors of ``thrusters`` (scenario thrusters: ``id``, ``kind``, ``position``
    in {B}) with the diameters ``{id: D}``: one dict per (flushing, flushed) pair closer than
    ``15 D`` of the flushing one (``flushing``, ``flushed``, ``distance``, ``centre`` [rad],
    ``half_width`` [rad]), and notes on sectors that cannot be applied (tunnel and fixed
    thrusters cannot steer away). Two thrusters at one position raise :class:`ThrustLossError`."""
    pairs: list[dict] = []
    notes: list[str] = []
    for ti in thrusters:
        Di = float(diameters[ti.id])
        for tj in thrusters:
            if tj is ti or tj.kind == "tunnel":      # a tunnel thruster may be flushed
                continue
            dx = float(ti.position[0]) - float(tj.position[0])
            dy = float(ti.position[1]) - float(tj.position[1])
            s = math.hypot(dx, dy)
            if s == 0.0:
                raise ThrustLossError(f"thrusters {ti.id!r} and {tj.id!r} share the position {tuple(ti.position)}: "
                                      "no interaction sector can be drawn")
            if s >= FLUSHING_DISTANCE_D * Di:
                continue
            p = {"flushing": ti.id, "flushed": tj.id, "distance": s, "centre": math.atan2(dy, dx),
                 "half_width": math.atan(0.1 + Di / s)}
            if ti.kind != "azimuth":
                for sign in (1.0, -1.0):
                    axis = ti.angle if sign > 0 else ti.angle + math.pi
                    limit = ti.max_thrust if sign > 0 else ti.max_reverse_thrust
                    if limit > 0 and abs(float(ssa(axis - p["centre"]))) < p["half_width"]:
                        notes.append(f"{ti.kind} thruster {ti.id!r} pushes into its interaction sector toward "
                                     f"{tj.id!r}: a fixed axis cannot steer away; not applied")
                continue
            pairs.append(p)
    return pairs, notes


def apply_level1_losses(scenario: Any, *, diameter: float | None = None,
                        beta_misc: float = BETA_MISC) -> tuple[Any, ThrustLosses]:
    """The scenario with the Level 1 losses applied to its thrusters (module docstring): every
    ``max_thrust`` and ``max_reverse_thrust`` times ``beta_misc``, and each azimuth's interaction
    sectors added to its ``forbidden_sectors``. Returns ``(scenario, ThrustLosses)``; the input is
    not changed (``dataclasses.replace``).

    ``diameter``: one diameter [m] for every thruster (default: :func:`default_diameter` of each).
    """
    if isinstance(beta_misc, bool) or not isinstance(beta_misc, (int, float)) or not (0.0 < beta_misc <= 1.0):
        raise ThrustLossError(f"beta_misc = {beta_misc!r} must be a number in (0, 1]")
    ths = tuple(scenario.thrusters)
    diam = _diameters(ths, diameter)
    pairs, notes = interaction_sectors(ths, diam)
    added: dict[str, list[tuple[float, float]]] = {}
    for p in pairs:
        added.setdefault(p["flushing"], []).append((p["centre"] - p["half_width"], p["centre"] + p["half_width"]))
    new = []
    for t in ths:
        sectors = tuple(tuple(s) for s in t.forbidden_sectors) + tuple(added.get(t.id, ()))
        if t.id in added:
            try:
                merge_sectors(sectors, f"thrusters[{t.id!r}]", error=ThrustLossError)
            except ThrustLossError as exc:
                raise ThrustLossError(f"{exc} once the interaction sectors are added") from None
        new.append(dataclasses.replace(t, max_thrust=beta_misc * t.max_thrust,
                                       max_reverse_thrust=beta_misc * t.max_reverse_thrust,
                                       forbidden_sectors=sectors))
    out = dataclasses.replace(scenario, thrusters=tuple(new))
    info = ThrustLosses(beta_misc=float(beta_misc), diameters=diam,
                        pairs=tuple({"flushing": p["flushing"], "flushed": p["flushed"], "distance": p["distance"],
                                     "centre_deg": math.degrees(p["centre"]),
                                     "half_width_deg": math.degrees(p["half_width"])} for p in pairs),
                        sectors={k: tuple(v) for k, v in added.items()}, notes=tuple(notes))
    return out, info
