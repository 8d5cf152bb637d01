"""The MoorDyn importer on a directory of MoorDyn input files: which import, and their statics against MoorPy's.

Printed figures, not a timed test::

    python benchmarks/moordyn_corpus.py DIR [--vessel fpso] [--csv rows.csv] [--no-moorpy]

Every file under DIR (recursively) with a MoorDyn line-type section (a line with ``---`` and
``LINE TYPES`` or ``LINE DICTIONARY``) is imported as ``tapm scenario import-moordyn`` would
(``docs/moordyn.md``, "Measured on the files MoorDyn and MoorPy ship"). Source files and notebooks
that only quote a MoorDyn file (``.py``, ``.ipynb``, ``.md``, ``.rst``) are left out and counted.

How a file is imported, first success wins:

* the vessel ``--vessel`` (default fpso) with the default ``--riser auto``, and
  ``--mbs NAME=1e7`` for every line type of the file (MoorDyn files carry no breaking strength;
  statics do not depend on it);
* retried with ``--fixed-as-fairleads`` when the refusal names that option;
* a placeholder MBS that the scenario's unit check refuses (``MBS/EA`` outside ``[1e-4, 0.5]``: a
  light line, e.g. EA 7.5 MN) is retried as 1 % of that type's EA, said in the row's options;
* where the refusal names the vessel scenario (its hull, riser or limits do not fit the file's
  water depth or lines), the other built-in vessels, each with every ``--riser`` choice.

Refusals are sorted into classes by what their message says (:data:`CLASSES`; a file may be in
several: the reason lists every problem of the file).

For each import, MoorPy (an optional dependency; ``--no-moorpy`` skips it) reads the same file,
``moorpy.System(file=..., depth, rho, g)`` with the imported water depth, density and gravity,
solves its free points (``solveEquilibrium(tol=1e-10)``), and is compared with
``MooringModel.from_scenario(imported)`` at rest and with the vessel 2 % of the water depth off in
surge and in sway. MoorPy's vessel body or points (and, with ``--fixed-as-fairleads``, the fixed
points taken as fairleads) are moved by the same displacement, turned into the file's frame where
the import turned the mooring (a rigid fit of the file's anchors and fairleads onto the
scenario's). Per file the worst over the three poses of

* the fairlead tension, ``max_k |T_k - T_k,MoorPy| / T_k,MoorPy``;
* the horizontal mooring force on the vessel, ``|F - F_MoorPy| / max(|F_MoorPy|, 0.01 sum_k H_k)``
  (``H_k`` MoorPy's horizontal fairlead tensions: where the lines' forces nearly cancel, as for a
  symmetric spread at rest, the difference is taken relative to 1 % of their sum; where every line
  hangs vertically, ``H = 0``, relative to the sum of the fairlead tensions).

Nothing is written but ``--csv``.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import math
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tapm_opt._io import atomic_write_text, csv_text
from tapm_opt.config.loader import BUILTIN_DIR
from tapm_opt.config.moordyn import RISER_CHOICES, MoorDynModel, read_moordyn
from tapm_opt.errors import TapmError
from tapm_opt.geometry import fairleads_B
from tapm_opt.models.moordyn_import import import_moordyn
from tapm_opt.models.mooring import MooringModel

#: The placeholder breaking strength of every line type [N] (the doc's shell loop).
MBS_PLACEHOLDER = 1e7
#: Files that only quote a MoorDyn input file.
NOT_INPUT = {".py", ".ipynb", ".md", ".rst"}
#: Vessel offset of the compared poses, as a fraction of the water depth.
OFFSET = 0.02

#: Refusal classes: (name, what it is, pattern found in the refusal message).
CLASSES = (
    ("rods", "rods, or lines attached to rod ends", r"rods are not supported|attached to rod ends"),
    ("body", "a free, pinned or second body", r"body \d+ is attached as|only one coupled body"),
    ("syrope", "the Syrope polyester model", r"Syrope"),
    ("free end", "a free point at one line's end (a hanging line, a weight or buoy on a line's end)",
     r"at the end of line \d+ alone"),
    ("bridle", "a free point joining three or more lines", r"bridle or Y-connection"),
    ("fixed ends level", "a line between two fixed points at one depth (neither can be the fairlead)",
     r"neither (?:end is the upper one|could be taken as the fairlead)"),
    ("fixed ends", "a line between two fixed points, in a file with a vessel",
     (r"between two fixed points \(\d+ and \d+\)(?: through free points? [\d, ]+)?; every line must run from a fixed "
      r"anchor to the vessel(?! \(both at z)")),
    ("hull points", "lines between two points on the vessel", r"between two vessel points"),
    ("bending", "a bending stiffness EI that matters", r"EI = \S+ N m\^2 matters"),
    ("one segment", "a line of one segment", r"NumSegs = 1: "),
    ("weightless", "g = 0", r"option g = 0 "),
    ("vessel fit", "no built-in vessel fits (hull, riser or limits against the water depth or lines)",
     r"vessel\.draught|limits\.\w+_radius|riser\.\w+"),
)
_OTHER = "other"
#: A refusal naming the vessel scenario: another vessel or riser choice may import.
_VESSEL_FIELD = re.compile(r"\b(?:vessel|riser|limits|thrusters|turret|sea_states|sensors)(?:\[\d+\])?\.\w+")
#: The scenario's unit check of a placeholder MBS: the type and its EA.
_MBS_CHECK = re.compile(r"line type '([^']+)' \(file line \d+\): EA = (\S+) gives tapm_opt's EA = \S+ N with "
                        r"MBS = \S+ N gives a strain at MBS")


def line_type_names(text: str) -> list[str] | None:
    """The line-type names of a MoorDyn file (the first word of every row of its LINE TYPES /
    LINE DICTIONARY section after the two column-title lines, as the doc's shell loop reads
    them); None if it has no such section."""
    names, inside, seen, n = [], False, False, 0
    for raw in text.splitlines():
        if "---" in raw:
            inside = bool(re.search(r"LINE TYPES|LINE DICTIONARY", raw.upper()))
            seen, n = seen or inside, 0
            continue
        if inside:
            n += 1
            tok = raw.split()
            if n > 2 and tok and not tok[0].startswith("#"):
                names.append(tok[0])
    return names if seen else None


def vessel_in_file(text: str) -> bool:
    """Whether a MoorDyn file has a vessel: a coupled body (``Coupled``, ``CoupledPinned``,
    ``Vessel``) or a coupled point (``Coupled``, ``Vessel``, ``Fairlead``, ``CPLD``, ``Ves``), as
    opposed to a test rig of fixed and free points and free bodies."""
    section, n, found = "", 0, False
    for raw in text.splitlines():
        if "---" in raw:
            up = raw.upper()
            section = "bodies" if "BOD" in up else "points" if re.search(r"POINT|CONNECTION|NODE PROP", up) else ""
            n = 0
            continue
        tok = raw.split("#", 1)[0].split()
        n += 1
        if section and n > 2 and len(tok) > 2:
            word = re.sub(r"\d+$", "", tok[1].upper())
            found = found or word.startswith(("COUPLED", "VESSEL", "FAIRLEAD", "CPLD")) or word == "VES"
    return found


def classes_of(reason: str) -> list[str]:
    """The refusal classes a reason names (:data:`CLASSES`), or ``["other"]``."""
    got = [name for name, _, pat in CLASSES if re.search(pat, reason)]
    return got or [_OTHER]


@dataclass
class Row:
    file: str
    ok: bool = False
    vessel: str = ""
    options: list[str] = field(default_factory=list)
    reason: str = ""
    classes: list[str] = field(default_factory=list)
    vessel_in_file: bool = True
    tried: list[str] = field(default_factory=list)
    dT: float = math.nan
    dF: float = math.nan
    friction: float = 0.0
    dT0: float = math.nan
    dF0: float = math.nan
    compared: str = ""


def _attempt(path: Path, vessel: str, riser: str, mbs: dict[str, float], ffl: bool):
    """(ImportResult, "", "") or (None, the refusal as the command prints it, its text without the
    file and line)."""
    try:
        return import_moordyn(path, vessel, mbs=mbs, riser=riser, fixed_as_fairleads=ffl), "", ""
    except TapmError as exc:
        return None, str(exc), str(getattr(exc, "detail", exc))


def import_file(path: Path, names: list[str], vessels: list[str]) -> tuple[Row, object]:
    """Import ``path`` as the module docstring says; the row and the ImportResult (or None)."""
    row = Row(str(path))
    mbs = {n: MBS_PLACEHOLDER for n in names}
    ffl = False
    first = first_detail = why = ""
    for vessel in vessels:
        for riser in RISER_CHOICES:
            while True:
                res, said, why = _attempt(path, vessel, riser, mbs, ffl)
                if res is not None:
                    break
                if not ffl and "--fixed-as-fairleads" in why:
                    ffl = True
                    continue
                light = [(t, float(ea)) for t, ea in _MBS_CHECK.findall(why) if mbs.get(t) == MBS_PLACEHOLDER]
                if light:
                    for t, ea in light:
                        mbs[t] = 0.01 * ea
                    continue
                break
            opts = (["--fixed-as-fairleads"] if ffl else []) + (["--riser " + riser] if riser != "auto" else []) + [
                f"--mbs {t}={v:g}" for t, v in mbs.items() if v != MBS_PLACEHOLDER]
            row.tried.append(" ".join([vessel, *opts]))
            if res is not None:
                row.ok, row.vessel, row.options = True, vessel, opts
                return row, res
            first, first_detail = first or said, first_detail or why
            if not _VESSEL_FIELD.search(why):
                break   # nothing of the vessel scenario in the way: another riser choice or vessel changes nothing
        if not _VESSEL_FIELD.search(why):
            break
    row.reason = first
    row.classes = classes_of(first_detail)
    return row, None


# --------------------------------------------------------------------------------------------
# MoorPy
# --------------------------------------------------------------------------------------------


def _rigid_fit(src: np.ndarray, dst: np.ndarray) -> tuple[float, float]:
    """Angle theta of the rotation (and the residual [m]) taking points ``src`` onto ``dst``
    (both (n, 2), north-east) up to a shift."""
    a, b = src - src.mean(axis=0), dst - dst.mean(axis=0)
    theta = math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), float(np.sum(a * b)))
    c, s = math.cos(theta), math.sin(theta)
    resid = float(np.max(np.abs(a @ np.array([[c, s], [-s, c]]) - b), initial=0.0))
    return theta, resid


def compare_moorpy(path: Path, res, ffl: bool) -> tuple[float, float, float, float, str]:
    """Worst fairlead-tension and horizontal-force differences against MoorPy (module docstring),
    then the same with the scenario's seabed friction set to 0 (MoorPy's lines have none; NaN where
    the scenario has none either), and a remark (empty when compared)."""
    import moorpy

    sc = res.scenario
    model: MoorDynModel = read_moordyn(path, fixed_as_fairleads=ffl)
    env = sc.environment
    depth, rho, g = float(env.water_depth), float(env.water_density), float(env.gravity)
    # the file's anchors and fairleads (NED) against the scenario's: the import's shift and turn
    src = np.array([model.global_position(model.point(p))[:2] * (1.0, -1.0)   # MoorDyn x, y -> north, east
                    for ch in model.chains for p in (ch.anchor, ch.fairlead)])
    fx, fy = fairleads_B(sc.turret.position, sc.fairleads_T, sc.turret.angle)
    dst = np.array([q for k in range(len(sc.lines)) for q in (np.asarray(sc.anchors[k], float)[:2],
                                                              (float(fx[k]), float(fy[k])))])
    theta, resid = _rigid_fit(src, dst)
    if resid > 1e-6 * max(1.0, float(np.max(np.abs(dst)))):
        return (math.nan,) * 4 + (f"the import's anchors and fairleads are no rigid move of the file's ({resid:.3g} m)",)
    c, s = math.cos(theta), math.sin(theta)
    R = np.array([[c, -s], [s, c]])
    with contextlib.redirect_stdout(io.StringIO()):
        ms = moorpy.System(file=str(path), depth=depth, rho=rho, g=g)
        ms.depth, ms.rho, ms.g = depth, rho, g
        ms.initialize()
    bodies = [ms.bodyList[b.id - 1] for b in model.bodies]
    pts = [ms.pointList[p.id - 1] for p in model.points if p.kind == "coupled" or p.id in model.fixed_fairleads]
    r6 = [np.array(b.r6, dtype=float) for b in bodies]
    r3 = [np.array(p.r, dtype=float) for p in pts]
    models = [MooringModel.from_scenario(sc)]
    if any(lt.seabed_friction for lt in sc.line_types):
        models.append(MooringModel.from_scenario(dataclasses.replace(
            sc, line_types=tuple(dataclasses.replace(lt, seabed_friction=0.0) for lt in sc.line_types))))
    worst = np.zeros((2, 2))   # (with the friction, without) x (tension, force)
    for d in (np.zeros(2), np.array([OFFSET * depth, 0.0]), np.array([0.0, OFFSET * depth])):
        d_file = R.T @ d                                  # the displacement in the file's north-east
        d_md = np.array([d_file[0], -d_file[1]])          # ... in MoorDyn's x, y
        with contextlib.redirect_stdout(io.StringIO()):
            for b, r in zip(bodies, r6):
                b.setPosition(r + np.r_[d_md, 0.0, 0.0, 0.0, 0.0])
            for p, r in zip(pts, r3):
                p.setPosition(r + np.r_[d_md, 0.0])
            ms.solveEquilibrium(tol=1e-10, maxIter=5000)
        T_mp, H = [], 0.0
        for ch in model.chains:
            ln = ms.lineList[ch.top.id - 1]
            at_b = ch.top.b == ch.fairlead
            T_mp.append(ln.TB if at_b else ln.TA)
            f = np.asarray(ln.fB if at_b else ln.fA, dtype=float)
            H += math.hypot(f[0], f[1])
        F_md = sum((np.asarray(b.getForces(lines_only=True), float)[:2] for b in bodies), np.zeros(2))
        F_md = F_md + sum((np.asarray(p.getForces(lines_only=True, xyz=True), float)[:2] for p in pts), np.zeros(2))
        F_mp = R @ np.array([F_md[0], -F_md[1]])         # north, east of the scenario
        eta = np.array([d[0], d[1], 0.0])
        scale = max(float(np.linalg.norm(F_mp)), 0.01 * H) or float(np.sum(T_mp))   # (vertical lines: H = 0)
        for k, tapm in enumerate(models):
            T = np.asarray(tapm.tensions(eta), float)
            F = np.asarray(tapm.force(eta), float)[:2]
            worst[k, 0] = max(worst[k, 0], float(np.max(np.abs(T - np.array(T_mp)) / np.array(T_mp))))
            worst[k, 1] = max(worst[k, 1], float(np.linalg.norm(F - F_mp)) / scale)
    if len(models) == 1:
        worst[1] = math.nan
    return float(worst[0, 0]), float(worst[0, 1]), float(worst[1, 0]), float(worst[1, 1]), ""


# --------------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------------


def _pct(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{100 * v:.2g} %" if v >= 1e-4 else f"{v:.1e}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", help="directory of MoorDyn input files (searched recursively)")
    ap.add_argument("--vessel", default="fpso", help="built-in vessel tried first (default fpso)")
    ap.add_argument("--csv", help="write one row per file to this CSV file")
    ap.add_argument("--no-moorpy", action="store_true", help="import only, no comparison with MoorPy")
    args = ap.parse_args(argv)
    root = Path(args.dir)
    if not root.is_dir():
        ap.error(f"{root} is not a directory")
    compare = not args.no_moorpy
    if compare:
        try:
            import moorpy  # noqa: F401
        except ImportError:
            print("MoorPy is not installed (pip install moorpy==1.3.0); run with --no-moorpy to import only",
                  file=sys.stderr)
            return 2
    builtins = sorted(p.stem for p in BUILTIN_DIR.glob("*.toml"))
    if args.vessel not in builtins:
        ap.error(f"--vessel {args.vessel}: not a built-in ({', '.join(builtins)})")
    vessels = [args.vessel] + [v for v in builtins if v != args.vessel]
    files, quoted = [], []
    for p in sorted(q for q in root.rglob("*") if q.is_file()):
        names = line_type_names(p.read_text(encoding="utf-8", errors="replace"))
        if names is None:
            continue
        (quoted if p.suffix.lower() in NOT_INPUT else files).append((p, names))
    rows: list[Row] = []
    print(f"{'file':54s} {'vessel':6s} {'result':8s} {'tension':>9s} {'force':>9s}  options / reason")
    for p, names in files:
        row, res = import_file(p, names, vessels)
        row.file = str(p.relative_to(root))
        row.vessel_in_file = vessel_in_file(p.read_text(encoding="utf-8", errors="replace"))
        if res is not None and compare:
            try:
                row.dT, row.dF, row.dT0, row.dF0, row.compared = compare_moorpy(p, res, "--fixed-as-fairleads" in
                                                                                 row.options)
                row.friction = max(lt.seabed_friction for lt in res.scenario.line_types)
            except Exception as exc:  # noqa: BLE001  (MoorPy's own failures are reported, not raised)
                row.compared = f"MoorPy: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
        rows.append(row)
        if row.ok:
            what = " ".join(row.options) + (f" ({row.compared})" if row.compared else "") + (
                f" [seabed friction {row.friction:g}; without it {_pct(row.dT0)}, {_pct(row.dF0)}]"
                if math.isfinite(row.dT0) else "")
            print(f"{row.file:54s} {row.vessel:6s} {'OK':8s} {_pct(row.dT):>9s} {_pct(row.dF):>9s}  {what}")
        else:
            reason = row.reason.split(": ", 1)[-1] if row.reason.startswith(p.name) else row.reason
            print(f"{row.file:54s} {'-':6s} {'refused':8s} {'':>9s} {'':>9s}  "
                  f"[{', '.join(row.classes)}{'' if row.vessel_in_file else '; no vessel'}] "
                  f"{reason[:150]}{'...' if len(reason) > 150 else ''}")
    ok = [r for r in rows if r.ok]
    print()
    print(f"{len(files)} files with a line-type table ({len(quoted)} source files or notebooks quoting one left out): "
          f"{len(ok)} import, {len(rows) - len(ok)} refused")
    for v in vessels:
        n = sum(r.vessel == v for r in ok)
        if n:
            print(f"  onto {v}: {n}")
    for opt in ("--fixed-as-fairleads", "--riser", "--mbs"):
        n = sum(any(o.startswith(opt) for o in r.options) for r in ok)
        if n:
            print(f"  with {opt}: {n}")
    if compare:
        both = [max(r.dT, r.dF) for r in ok]
        fin = [v for v in both if math.isfinite(v)]
        print(f"against MoorPy: {sum(v <= 0.01 for v in fin)} of {len(ok)} within 1 % (tension and force), "
              f"{sum(v <= 1e-9 for v in fin)} within 1e-9; worst {_pct(max(fin, default=math.nan))}; "
              f"{len(ok) - len(fin)} not compared")
        fric = [r for r in ok if math.isfinite(r.dT0)]
        if fric:
            print(f"  {len(fric)} with seabed friction (MoorPy has none): worst {_pct(max(max(r.dT, r.dF) for r in fric))}"
                  f", without tapm_opt's friction {_pct(max(max(r.dT0, r.dF0) for r in fric))}")
    refused = [r for r in rows if not r.ok]
    print(f"refused: {sum(not r.vessel_in_file for r in refused)} of the {len(refused)} have no vessel (no coupled "
          f"body or point; {sum(not r.vessel_in_file for r in ok)} such files import with --fixed-as-fairleads)")
    print("refusal classes (files with it / with it alone):")
    for name, what, _ in (*CLASSES, (_OTHER, "none of the above", "")):
        n = sum(name in r.classes for r in refused)
        if n:
            alone = sum(r.classes == [name] for r in refused)
            print(f"  {name:17s} {n:3d} {alone:3d}  {what}")
    if args.csv:
        header = ["file", "result", "vessel", "options", "tension_diff", "force_diff", "seabed_friction",
                  "tension_diff_no_friction", "force_diff_no_friction", "vessel_in_file", "classes", "reason",
                  "tried"]
        body = [[r.file, "OK" if r.ok else "refused", r.vessel, " ".join(r.options), r.dT, r.dF, r.friction, r.dT0, r.dF0,
                 int(r.vessel_in_file),
                 ", ".join(r.classes), r.reason or r.compared, "; ".join(r.tried)] for r in rows]
        atomic_write_text(args.csv, csv_text(header, body))
    return 0


if __name__ == "__main__":
    sys.exit(main())
