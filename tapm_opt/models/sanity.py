"""Engineering sanity of a valid scenario: checks that need the mooring and thruster models.

The loader (:mod:`tapm_opt.config.loader`) checks each field, the cross-field rules and the
plausibility bounds; a scenario that passes describes something physical. This module asks the
next question — is it a mooring that can work? — with the catenary at the field zero point and the
thrusters' capacity, which the configuration package cannot import. ``tapm scenario validate``
prints what it finds: an ``error`` makes the file invalid, a ``warning`` is printed and the file
stays valid.

Every finding names the field path, the value and what is allowed or expected
(``docs/scenarios.md``, "Engineering checks").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ..errors import ScenarioIssue, TapmError

__all__ = [
    "EngineeringIssue",
    "engineering_issues",
    "VERTICAL_LINE_FRACTION",
    "UNBALANCED_FRACTION",
    "RAISED_ANCHOR_WARNING",
]

#: A line whose horizontal anchor-fairlead span at the field zero point is under this fraction of
#: its vertical span hangs (within 3 degrees of) straight down from its fairlead.
VERTICAL_LINE_FRACTION = 0.05
#: Net horizontal mooring force at the field zero point, as a fraction of the lines' summed
#: horizontal pretension, above which the mooring is reported as not balanced there.
UNBALANCED_FRACTION = 0.01
#: An anchor more than this fraction of the water depth above the seabed is reported (a buoy, a
#: clump or a slope can put it there; a unit slip in its z can too).
RAISED_ANCHOR_WARNING = 0.25


@dataclass(frozen=True)
class EngineeringIssue(ScenarioIssue):
    """A :class:`~tapm_opt.errors.ScenarioIssue` with a severity: ``"error"`` (the scenario cannot
    work as given) or ``"warning"`` (it can, but something deserves a look)."""

    severity: Literal["error", "warning"] = "error"


def engineering_issues(scenario: Any) -> list[EngineeringIssue]:
    """Engineering checks of a loaded (valid) scenario.

    * every line's pretension at the field zero point (elastic catenary, no load) against its MBS:
      an error at or above 100 % (the line breaks at rest), a warning above
      ``limits.tension_utilisation`` (no margin left for the weather);
    * a line whose anchor lies (almost) straight under its fairlead: an error (it restrains nothing
      horizontally and the quasi-static model has no stiffness direction there);
    * a mooring that does not balance at the field zero point: a warning;
    * fairleads above the water line, anchors far above the seabed: warnings (unit slips);
    * no thrust capacity in surge, sway or yaw (no thrusters, or forbidden sectors leaving too
      little): a warning — the mooring can be analysed, but no controller can be closed.

    Returns
    -------
    list of EngineeringIssue
        Errors first, then warnings, each in the order of the file.
    """
    out: list[EngineeringIssue] = []
    _geometry(scenario, out)
    _mooring(scenario, out)
    _thrust(scenario, out)
    return sorted(out, key=lambda i: i.severity != "error")


def _err(out: list, path: str, msg: str) -> None:
    out.append(EngineeringIssue(path, msg, "error"))


def _warn(out: list, path: str, msg: str) -> None:
    out.append(EngineeringIssue(path, msg, "warning"))


def _geometry(sc: Any, out: list[EngineeringIssue]) -> None:
    env, tur = sc.environment, sc.turret
    if tur.fairlead_depth < 0:
        _warn(out, "turret.fairlead_depth", (
            f"= {tur.fairlead_depth:g} m puts the fairleads {-tur.fairlead_depth:g} m above the water line (depth is z "
            "down, 0 at the water line): the catenary and the FEM plant treat the whole line as submerged, with its "
            "submerged weight, drag and current up to the fairlead"))
    h_A = sc.line_arrays["h_A"]
    for i, ln in enumerate(sc.lines):
        if h_A[i] > RAISED_ANCHOR_WARNING * env.water_depth:
            _warn(out, f"lines[{i}].anchor[2]", (
                f"= {ln.anchor[2]:g} m puts the anchor {h_A[i]:g} m above the seabed, more than "
                f"{RAISED_ANCHOR_WARNING:g} x the water depth ({env.water_depth:g} m): the line's lower end hangs "
                "there (a buoy, a clump, a slope); if it should lie on the seabed, give its z as the water depth "
                "or leave z out"))


def _mooring(sc: Any, out: list[EngineeringIssue]) -> None:
    from .mooring import MooringModel

    try:
        model = MooringModel.from_scenario(sc)
        eta0 = np.zeros(3)
        sol = model.solve_lines(eta0)
        _, _, XF = model.spans(eta0)
        tau = model.force(eta0)
    except TapmError as exc:
        _err(out, "lines", f"the mooring has no catenary solution at the field zero point: {exc}")
        return
    limit = sc.limits.tension_utilisation
    for i, ln in enumerate(sc.lines):
        p = f"lines[{i}]"
        lt = sc.line_type(ln)
        T, mbs = float(sol.TF[i]), float(lt.MBS)
        u = T / mbs
        if u >= 1.0:
            _err(out, f"{p}.length", (
                f"= {ln.length:g} m gives a pretension at the field zero point of {T / 1e3:.4g} kN, {100 * u:.3g} % "
                f"of the MBS of line type {lt.id!r} ({mbs / 1e3:.4g} kN): the line breaks at rest; it must stay below "
                f"limits.tension_utilisation = {100 * limit:.3g} % (pretensions are usually 10-25 % of MBS): "
                "lengthen the line, move its anchor closer or check the MBS"))
        elif u > limit:
            _warn(out, f"{p}.length", (
                f"= {ln.length:g} m gives a pretension at the field zero point of {T / 1e3:.4g} kN, {100 * u:.3g} % "
                f"of the MBS of line type {lt.id!r} ({mbs / 1e3:.4g} kN), above limits.tension_utilisation = "
                f"{100 * limit:.3g} %, the allowed tension in the weather: no margin is left for the environment "
                "(pretensions are usually 10-25 % of MBS)"))
        ZF = float(model.ZF[i])
        if XF[i] < VERTICAL_LINE_FRACTION * ZF:
            a = ", ".join(f"{x:g}" for x in ln.anchor)
            _err(out, f"{p}.anchor", (
                f"= ({a}) m lies straight under the line's fairlead: horizontal span {XF[i]:.3g} m for a vertical "
                f"span of {ZF:g} m (at least {VERTICAL_LINE_FRACTION:g} x it, about 3 degrees from the vertical, is "
                "needed). A line hanging straight down restrains nothing horizontally at rest and its pull has no "
                "direction there; a mooring line runs out from the vessel toward its anchor"))
    H = np.asarray(sol.HF, dtype=float)
    net = math.hypot(float(tau[0]), float(tau[1]))
    if H.sum() > 0 and net > UNBALANCED_FRACTION * H.sum():
        # the net force in {E} (the body frame is {E} at the field zero point): where it pulls to
        bearing = math.degrees(math.atan2(float(tau[1]), float(tau[0]))) % 360.0
        _warn(out, "lines", (
            f"the mooring does not balance at the field zero point: the lines pull the vessel with a net "
            f"{net / 1e3:.4g} kN toward {bearing:.0f} deg (from north), {100 * net / H.sum():.3g} % of their summed "
            f"horizontal pretension ({H.sum() / 1e3:.4g} kN; at most {100 * UNBALANCED_FRACTION:g} % is balanced): "
            "without thrust the vessel rests elsewhere, while offsets and the setpoint are measured from the field "
            "zero point; check the anchors and lengths"))


def _thrust(sc: Any, out: list[EngineeringIssue]) -> None:
    from .system import ThrusterSet

    if not sc.thrusters:
        _warn(out, "thrusters", (
            "= [] (none): the scenario has no thrust capacity, so no controller can hold the vessel in closed loop "
            "(tapm simulate, compare and study runs need thrust in surge, sway and yaw); the mooring can still be "
            "analysed (tapm lines, scenario show, plant forced-motion)"))
        return
    try:
        box = np.asarray(ThrusterSet.from_scenario(sc).max_tau(), dtype=float)
    except TapmError as exc:
        _warn(out, "thrusters", f"the thrust capacity could not be computed: {exc}")
        return
    missing = [name for name, b in zip(("surge (X)", "sway (Y)", "yaw (N)"), box) if not b > 0]
    if missing:
        sectors = [f"thrusters[{i}].forbidden_sectors_deg" for i, t in enumerate(sc.thrusters) if t.forbidden_sectors]
        hint = f"; check {', '.join(sectors)}" if sectors else ""
        _warn(out, "thrusters", (
            f"have no usable thrust capacity in {', '.join(missing)}: the largest thrust each direction can get alone "
            f"is X {box[0]:.3g} N, Y {box[1]:.3g} N, N {box[2]:.3g} N m (with {len(sc.thrusters)} thrusters, their "
            f"limits and forbidden sectors), so no controller can hold the vessel in closed loop (tapm simulate, "
            f"compare and study runs need thrust in surge, sway and yaw){hint}"))
