"""Importing a MoorDyn v2 file as a scenario (``tapm scenario import-moordyn``; docs/moordyn.md).

The file is read and mapped in :mod:`tapm_opt.config.moordyn` (its parser, the mapping of line
types, points and lines, the riser, turret and re-centring choices). This module builds the
scenario from it and adds the checks that need the mooring model: whether a line type's bending
stiffness matters (:func:`bending_notes`, the catenary's tension at rest), which is why it sits
in the ``models`` layer.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..config import scenario_from_dict
from ..config.moordyn import (RECENTRE_CHOICES, RISER_CHOICES, TURRET_CHOICES, ImportResult, MoorDynError,
                              MoorDynModel, problem_in_file_terms, read_moordyn, scenario_data_from_moordyn,
                              scenario_toml, vessel_data_of)
from ..errors import ScenarioError
from ..geometry import fairleads_B
from . import composite as _composite
from .mooring import MooringModel

__all__ = ["import_moordyn", "bending_notes", "BENDING_NEGLIGIBLE", "composite_joints", "export_moordyn"]


#: Bending stiffness is neglected where ``EI / (H l^2)`` is at most this (H the line's horizontal
#: tension at rest, l its segment length): the bending length ``sqrt(EI / H)`` is then under a tenth
#: of a segment, shorter than anything the lumped-mass line resolves.
BENDING_NEGLIGIBLE = 0.01


def bending_notes(model: MoorDynModel, sc: Any) -> list[str]:
    """Notes for the line types with ``EI > 0`` whose bending is negligible (the criterion
    :data:`BENDING_NEGLIGIBLE` on every line of the type, at rest at the field zero point); a
    :class:`MoorDynError` naming the lines where it is not."""
    stiff = {lt.name: lt for lt in model.line_types if lt.EI > 0}
    if not stiff:
        return []
    sol = MooringModel.from_scenario(sc).solve_lines(np.zeros(3))
    H = np.atleast_1d(np.asarray(sol.HF, dtype=float))
    worst: dict[str, tuple[float, str]] = {}
    for k, ln in enumerate(sc.lines):
        # every section (a MoorDyn line): the horizontal tension is the line's, the same in all
        # its suspended sections (the points between them carry vertical loads only)
        chain = model.chains[k] if k < len(model.chains) else None
        for j, (sec, nseg) in enumerate(zip(ln.parts, ln.section_segments())):
            lt = stiff.get(str(sec.type))
            if lt is None:
                continue
            seg = sec.length / nseg
            ratio = lt.EI / (H[k] * seg * seg) if H[k] > 0 else math.inf
            name = str(chain.lines[j].id) if chain is not None and len(chain.lines) == len(ln.parts) else str(ln.id)
            if ratio > worst.get(lt.name, (-1.0, ""))[0]:
                worst[lt.name] = (ratio, name)
    notes, bad = [], []
    for name, (ratio, lid) in worst.items():
        lt = stiff[name]
        if ratio <= BENDING_NEGLIGIBLE:
            notes.append(f"line type {name!r}: bending stiffness EI = {lt.EI:g} N m^2 (line {lt.lineno}) is neglected: "
                         f"EI / (H l^2) is at most {ratio:.2g} (line {lid}; H the horizontal tension at rest, l the "
                         f"segment length), under {BENDING_NEGLIGIBLE:g}: the bending length sqrt(EI/H) is under a tenth "
                         "of a segment")
        else:
            bad.append(f"line type {name!r} (file line {lt.lineno}): EI = {lt.EI:g} N m^2 matters: EI / (H l^2) = "
                       f"{ratio:.3g} on line {lid} (over {BENDING_NEGLIGIBLE:g}; H the horizontal tension at rest, l the "
                       "segment length), and tapm_opt's lines are cables without bending stiffness")
    if bad:
        raise MoorDynError("; ".join(bad), source=model.source)
    return notes



def import_moordyn(path: str | Path, vessel: str | Path, *, mbs: Mapping[str, float] | None = None,
                   mbs_cov: float = 0.05,
                   name: str | None = None, riser: str = "auto", turret: str = "auto",
                   recentre: str = "auto", fixed_as_fairleads: bool = False) -> ImportResult:
    """A scenario from a MoorDyn v2 file and a vessel scenario.

    From the MoorDyn file: line types, lines (length, segments), anchors, fairleads, water depth,
    water density and gravity (``g``, default 9.80665 as MoorDyn-C; ``rho`` or ``WtrDnsty``, or
    MoorDyn-F's ``rhoW``), seabed friction. Lines joined in series by free points, from a fixed
    point up to the vessel, become one composite line (its sections from the anchor up); a free
    point with a mass, volume, drag or added mass becomes a point type (clump weight or buoy) at
    its joint. From ``vessel`` (built-in name or TOML path):
    everything else (vessel, turret position, mode and angle, thrusters, sea states, riser,
    faults of lines that exist, sensors, limits, plant settings).

    Fairleads become turret angles and radii about the vessel's centre of turret at the field zero
    point (turret angle alpha_t removed); all fairleads must be at one depth. An anchor (a fixed
    point) lies on the seabed or above it, below the fairleads (a raised anchor keeps its z; one
    below the seabed or not below the fairleads is refused). MoorDyn files carry
    no breaking strength: ``mbs`` maps every used line type to its MBS [N]; ``MBS_std`` is
    ``mbs_cov`` times it. A file written by ``tapm scenario export-moordyn`` gives its line types'
    MBS and MBS_std (and tapm_opt's own values of what MoorDyn has no column for) in its front
    matter, so ``mbs`` may leave them out.

    ``riser`` says what becomes of the vessel scenario's riser in the file's water depth (one of
    :data:`~tapm_opt.config.moordyn.RISER_CHOICES`; docs/moordyn.md, "The riser"):

    - ``"keep"``: as it is (an error if it does not fit the depth);
    - ``"adapt"``: its length and top tension scaled by the ratio of the straight distances from
      its hang-off to its wellhead in the new and the old depth (a vertical riser from the
      fairlead depth to the seabed stays one; the top tension keeps its ratio to the riser's
      weight, the tensioners' 1.2-2x), its other properties and critical angles kept;
    - ``"drop"``: left out (the riser's reliability index and angles are then not computed);
    - ``"auto"`` (default): kept if the depth is the vessel scenario's, else adapted.

    Every choice but an unchanged ``keep`` is said in a note.

    ``turret`` (one of :data:`~tapm_opt.config.moordyn.TURRET_CHOICES`): MoorDyn has no turret, and its fairleads on a
    coupled body are fixed to the hull. ``"auto"`` (default) keeps the vessel scenario's turret
    mode when the fairleads lie on one circle about its centre of turret (a turret mooring), and
    locks the turret to the hull otherwise (a spread mooring: the mooring's yaw stiffness kept);
    ``"locked"`` and ``"free"`` choose. A mode that differs from the vessel scenario's, or a free
    turret with fairleads not on one circle, is said in a note.

    ``fixed_as_fairleads``: a file with no vessel point (no coupled point, no body) whose lines run
    between two fixed points (a test rig holding a line between a point on the seabed and one
    higher up) imports with the upper fixed point of each line, or lines in series, as a fairlead
    on the vessel, the lower one as its anchor, said in a note; ends at the same depth, or a fixed
    point that would be both a fairlead and an anchor, are refused. Off by default: a fixed point
    in MoorDyn does not move, and only the user can say that it stands for a vessel's fairlead
    (the refusal of such a file names this option).
    """
    if riser not in RISER_CHOICES:
        raise MoorDynError(f"riser = {riser!r} must be one of {', '.join(RISER_CHOICES)}")
    if turret not in TURRET_CHOICES:
        raise MoorDynError(f"turret = {turret!r} must be one of {', '.join(TURRET_CHOICES)}")
    if recentre not in RECENTRE_CHOICES:
        raise MoorDynError(f"recentre = {recentre!r} must be one of {', '.join(RECENTRE_CHOICES)}")
    model = read_moordyn(path, fixed_as_fairleads=fixed_as_fairleads)
    vdata, vname = vessel_data_of(vessel)
    data, notes, comments = scenario_data_from_moordyn(model, vdata, mbs=mbs or {}, mbs_cov=mbs_cov, name=name,
                                                       vessel_name=vname, riser=riser, turret=turret,
                                                       recentre=recentre)
    try:
        sc = scenario_from_dict(data, source=f"(imported from {model.source})")
    except ScenarioError as exc:
        said = [problem_in_file_terms(i, model, data) for i in exc.issues]
        raise MoorDynError(f"the imported scenario is invalid ({len(said)} problem{'s' * (len(said) > 1)}): "
                           + "; ".join(said), source=model.source) from None
    notes += bending_notes(model, sc)
    header = [
        f"{data['meta']['name']} — imported by tapm scenario import-moordyn",
        f"Mooring (line types, lines, anchors, fairleads, water depth, density, gravity): MoorDyn file {model.source}",
        f"Everything else (vessel, turret position/mode/angle, thrusters, sea states, ...): scenario {vname}",
        "Conventions (frames, diameter, drag, damping): tapm_opt docs/moordyn.md",
        *[f"NOTE: {n}" for n in notes],
    ]
    return ImportResult(scenario=sc, data=data, toml=scenario_toml(data, header=header, comments=comments),
                        notes=tuple(notes))


def composite_joints(sc: Any) -> dict[int, np.ndarray]:
    """Quasi-static equilibrium positions in {E} (NED) [m] of the joints of every composite line
    at the field zero point: line index -> array (sections - 1, 3) from the anchor up
    (:func:`tapm_opt.models.composite.points`), where :func:`~tapm_opt.config.moordyn.moordyn_text`
    starts MoorDyn's free points."""
    model = MooringModel.from_scenario(sc)
    if not model.has_composite:
        return {}
    fx, fy = fairleads_B(sc.turret.position, sc.fairleads_T, sc.turret.angle)
    depth = sc.environment.water_depth
    out = {}
    for i, c in enumerate(model.composite):
        if c is None or c.n_sections < 2:  # homogeneous (a line of a tension-strain table is one section)
            continue
        a = np.asarray(sc.anchors[i], dtype=float)
        d = np.array([float(fx[i]) - a[0], float(fy[i]) - a[1]])
        XF = float(np.hypot(*d))
        u = d / XF if XF > 0 else np.array([1.0, 0.0])
        px, pz = _composite.points(XF, float(model.ZF[i]), c, h_A=float(model.h_A[i]))
        px, pz = np.ravel(px), np.ravel(pz)
        out[i] = np.column_stack([a[0] + px * u[0], a[1] + px * u[1], depth - pz])
    return out


def export_moordyn(scenario: Any, path: str | Path, **kwargs: Any):
    """:func:`tapm_opt.config.moordyn.export_moordyn` with the free points of composite lines
    started at their quasi-static equilibrium (:func:`composite_joints`), so that MoorDyn's
    initial-condition solver starts at the answer; the same file otherwise."""
    from ..config import load_scenario
    from ..config.moordyn import export_moordyn as _export

    sc = scenario if not isinstance(scenario, (str, Path)) else load_scenario(scenario)
    kwargs.setdefault("joints", composite_joints(sc))
    return _export(sc, path, **kwargs)
