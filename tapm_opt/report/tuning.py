"""The report of a tuning run (``tapm report TUNE_DIR`` on a ``tapm tune`` output): the answer
first — the controllers' fronts compared, front against front — then the evidence.

Read from the run's files only (``tuning.json``, ``trials.csv``, ``front.csv``, ``verify.csv``);
nothing is run again. The comparison (``docs/tuning.md``, "The report"):

- **coverage** of controller A over B: the share of B's front points for which A's front has a
  point with no more of the first objective plus a tolerance (0.5 m for an offset, 0 otherwise)
  and no more of the second; for each covered point, A's best relative saving in the second
  objective; the B points A does not cover are listed (where B is better);
- **hypervolume** of each front (the first two objectives, smaller-is-better form), against one
  reference point for all controllers: the worst value of each objective over every front, plus
  5 % of its range, so the numbers compare;
- the fronts drawn (all finished trials faint, each front as a line, the time outside the safe
  circle as colour, the selected designs starred, their held-out values as open markers).
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .._io import atomic_write_bytes, atomic_write_text
from ..studies.kpi_catalogue import KPIS
from ..studies.kpis import DELTA_S_DEFAULT
from ..studies.tuning import format_kpi, hypervolume_2d
from .data import ReportError
from .document import Cell, Fig, Heading, Para, Table, render_html, render_markdown

__all__ = ["is_tuning_dir", "write_tuning_report", "coverage", "TUNING_JSON"]

TUNING_JSON = "tuning.json"


def is_tuning_dir(path: str | Path) -> bool:
    """Whether ``path`` holds a ``tapm tune`` run."""
    return (Path(path) / TUNING_JSON).is_file()


@dataclass(frozen=True)
class _Point:
    controller: str
    trial: int
    values: dict
    params: str


def _read_csv(path: Path) -> list[dict]:
    if not path.is_file():
        return []
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _num(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _sign(objective_label: str) -> tuple[str, float]:
    """``("offset_max", +1)`` from ``"max(offset_max)"`` (-1 for a maximised KPI)."""
    name = objective_label.split("(", 1)[-1].rstrip(")")
    k = KPIS.get(name)
    return name, (-1.0 if k is not None and k.direction == "maximise" else 1.0)


def _tolerance(name: str) -> float:
    return 0.5 if name.startswith("offset") else 0.0


def coverage(a: Sequence[tuple[float, float]], b: Sequence[tuple[float, float]], tol: float = 0.5) -> dict:
    """How far front ``a`` covers front ``b`` (both as (first, second) objective pairs, smaller
    is better): ``{"covered": fraction of b's points with an a point of first <= b.first + tol and
    second <= b.second, "savings": per covered b point the best relative saving in the second
    objective (1 - a/b), "uncovered": the b points not covered}``."""
    covered, savings, uncovered = 0, [], []
    for p in b:
        ok = [q for q in a if q[0] <= p[0] + tol and q[1] <= p[1]]
        if ok:
            covered += 1
            savings.append(1.0 - min(q[1] for q in ok) / p[1] if p[1] else 0.0)
        else:
            uncovered.append(p)
    return {"covered": covered / len(b) if b else math.nan, "savings": savings, "uncovered": uncovered}


def _figure(points: dict, fronts: dict, selected: dict, held: dict, names: tuple[str, str]) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .figures import png_bytes

    fig = Figure(figsize=(8.0, 5.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    sx = 1 / 3.6e9 if KPIS.get(names[1]) is not None and KPIS[names[1]].unit == "J" else 1.0
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]
    tout = [_num(p.values.get("time_outside_safe")) for ps in points.values() for p in ps]
    vmax = max([t for t in tout if math.isfinite(t)] + [1.0])
    sc = None
    for i, (c, ps) in enumerate(points.items()):
        col = colours[i % len(colours)]
        x = [_num(p.values.get(names[0])) for p in ps]
        y = [_num(p.values.get(names[1])) * sx for p in ps]
        ax.scatter(x, y, s=10, color=col, alpha=0.25, linewidths=0)
        f = sorted(fronts.get(c, []), key=lambda p: _num(p.values.get(names[0])))
        if f:
            fx = [_num(p.values.get(names[0])) for p in f]
            fy = [_num(p.values.get(names[1])) * sx for p in f]
            ax.step(fx, fy, where="post", color=col, lw=1.5, label=f"{c} front ({len(f)})")
            sc = ax.scatter(fx, fy, c=[_num(p.values.get("time_outside_safe")) for p in f], cmap="viridis",
                            vmin=0.0, vmax=vmax, s=28, edgecolors=col, zorder=3)
        if c in selected:
            s = selected[c]
            ax.scatter([_num(s.get(names[0]))], [_num(s.get(names[1])) * sx], marker="*", s=220, color=col,
                       edgecolors="black", zorder=4, label=f"{c} selected")
        if c in held:
            h = held[c]
            ax.scatter([_num(h.get(names[0]))], [_num(h.get(names[1])) * sx], marker="o", s=90, facecolors="none",
                       edgecolors=col, linewidths=2, zorder=4, label=f"{c} held-out")
    if sc is not None:
        fig.colorbar(sc, ax=ax, label="time outside the safe circle [s]")
    ux = KPIS[names[0]].unit if names[0] in KPIS else ""
    ax.set_xlabel(f"{names[0]} [{ux}]" if ux and ux != "-" else names[0])
    ax.set_ylabel(f"{names[1]} [MWh]" if sx != 1.0 else names[1])
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    return png_bytes(fig)


def _option_text(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, tuple)):
        return "(" + ", ".join(_option_text(x) for x in v) + ")"
    return str(v)


def _verdict(a: str, b: str, cv: dict, hv: Mapping[str, float], o0: tuple, o1: tuple, tol: float, nb: int) -> str:
    """One pair's answer: does ``a``'s front cover ``b``'s, with at least its hypervolume?"""
    (n0, _), (n1, _) = o0, o1
    sav = cv["savings"]
    covers = cv["covered"] >= 1.0 - 1e-12
    txt = (f"**{a} over {b}: {'covers' if covers else 'does not cover'}.** For {100 * cv['covered']:.0f} % of "
           f"{b}'s {nb} front designs {a} has a design with no more {n0}" + (f" (+{tol:g} m)" if tol else "")
           + f" and no more {n1}")
    if sav:
        txt += (f", {100 * np.median(sav):.1f} % less {n1} at the median (range {100 * min(sav):.1f} to "
                f"{100 * max(sav):.1f} %)")
    txt += f"; hypervolume {hv[a]:.4g} against {hv[b]:.4g}"
    if covers and hv[a] >= hv[b]:
        txt += f": {a}'s front is at least as good as {b}'s everywhere {b} reaches."
    elif covers:
        txt += f": {a} covers {b}'s designs but its front spans less (smaller hypervolume)."
    else:
        txt += "."
    return txt


def _where_and_why(a: str, b: str, uncovered: Sequence[tuple[float, float]], front_a: Sequence[_Point],
                   trials_a: Sequence[tuple[tuple[float, float], _Point]], front_b: Sequence[_Point],
                   o0: tuple, o1: tuple, tol: float, limits: Mapping[str, Any]) -> str:
    """Where ``b``'s front is better than ``a``'s, and why, from the run's own figures: each
    uncovered design of ``b`` is one of (1) closer than any design of ``a`` came (``a``'s least
    first objective is larger), (2) cheaper than any trial of ``a`` ran (``a``'s least second
    objective over every finished trial is larger: ``a``'s search space or structure does not
    reach so little), or (3) a stretch where ``a`` reaches the first objective but spends more;
    with the time outside the safe circle those designs of ``b`` leave the turret out."""
    (n0, s0), (n1, s1) = o0, o1
    fa = sorted((s0 * _num(p.values.get(n0)), s1 * _num(p.values.get(n1))) for p in front_a)
    ta = [q for q, _ in trials_a if all(math.isfinite(x) for x in q)]
    min0_a = min(q[0] for q in fa)
    cheapest = min(ta or fa, key=lambda q: q[1])
    bpts = {(s0 * _num(p.values.get(n0)), s1 * _num(p.values.get(n1))): p for p in front_b}
    groups: dict[str, list] = {"closer": [], "cheaper": [], "more": []}
    for u in uncovered:
        if u[0] + tol < min0_a:
            groups["closer"].append(u)
        elif u[1] < cheapest[1]:
            groups["cheaper"].append(u)
        else:
            groups["more"].append(u)

    def rng(pts: list, i: int, name: str, sign: float) -> str:
        lo, hi = min(sign * p[i] for p in pts), max(sign * p[i] for p in pts)
        lo, hi = min(lo, hi), max(lo, hi)
        return format_kpi(name, lo) if lo == hi else f"{format_kpi(name, lo)} to {format_kpi(name, hi)}"

    def outside(pts: list) -> str:
        tout = [_num(bpts[p].values.get("time_outside_safe")) for p in pts if p in bpts]
        tout = [t for t in tout if math.isfinite(t)]
        r = limits.get("safe_radius")
        if not tout or max(tout) <= 0:
            return ""
        where = f"the {r:g} m safe circle" if r else "the safe circle"
        span = (f"{max(tout):.0f} s" if min(tout) == max(tout) else f"up to {max(tout):.0f} s" if min(tout) <= 0
                else f"{min(tout):.0f}–{max(tout):.0f} s")
        return f"; {b}'s designs there leave the turret outside {where} for {span} of the cases' time"

    def plural(g: list) -> str:
        return f"{len(g)} design{'s' * (len(g) > 1)}"

    parts = []
    if groups["closer"]:
        g = groups["closer"]
        parts.append(f"{b} reaches {n0} {rng(g, 0, n0, s0)} ({plural(g)}), closer than any design of {a} came "
                     f"(its least {n0} is {format_kpi(n0, s0 * min0_a)})")
    if groups["cheaper"]:
        g = groups["cheaper"]
        parts.append(f"{b} runs on {rng(g, 1, n1, s1)} at {n0} {rng(g, 0, n0, s0)} ({plural(g)}), less than any "
                     f"trial of {a} spent: {a}'s cheapest trial spent {format_kpi(n1, s1 * cheapest[1])} at "
                     f"{format_kpi(n0, s0 * cheapest[0])}, so its search space or its structure does not reach so "
                     f"little {n1}" + outside(g))
    if groups["more"]:
        g = groups["more"]
        extra = []
        for u in g:
            ok = [q for q in fa if q[0] <= u[0] + tol]
            if ok and u[1]:
                extra.append(min(q[1] for q in ok) / u[1] - 1.0)
        ex = [e for e in extra if math.isfinite(e)]
        parts.append(f"at {n0} {rng(g, 0, n0, s0)} ({plural(g)}) {a}'s front reaches the {n0} but spends more "
                     f"{n1}" + (f" ({_span(ex)} % more)" if ex else "") + outside(g))
    return f"*Where {b} is better than {a}, and why:* " + "; ".join(parts) + "."


def _span(fractions: Sequence[float]) -> str:
    lo, hi = round(100 * min(fractions)), round(100 * max(fractions))
    return f"{lo}" if lo == hi else f"{lo}–{hi}"


def _reliability_cost(ctrls: Sequence[str], info: Mapping[str, Any], points: Mapping[str, list],
                      fronts: Mapping[str, list], o0: tuple, o1: tuple, delta_s: float) -> list[str]:
    """What the riser's and the lines' reliability cost: per controller, the index over its front,
    at its selected design, and the cheapest finished trial that keeps it at ``delta_s`` or
    above (or the best any trial reached)."""
    (n0, _), (n1, s1) = o0, o1
    out = []
    for kpi, what in (("riser_delta_min", "the riser's reliability index"),
                      ("delta_min", "the lines' reliability index")):
        if not any(math.isfinite(_num(p.values.get(kpi))) for ps in points.values() for p in ps):
            continue
        for c in ctrls:
            pts = [p for p in points.get(c, []) if math.isfinite(_num(p.values.get(kpi)))]
            if not pts:
                continue
            fv = [_num(p.values.get(kpi)) for p in fronts.get(c, []) if math.isfinite(_num(p.values.get(kpi)))]
            sel = (info["controllers"][c].get("kpis") or {}).get(kpi)
            txt = f"**{c}**, {what} ({kpi}, its least over the cases):"
            if fv:
                txt += f" {min(fv):.2f} to {max(fv):.2f} over its front"
            if sel is not None and math.isfinite(_num(sel)):
                txt += f", {_num(sel):.2f} at the selected design"
            ok = [p for p in pts if _num(p.values.get(kpi)) >= delta_s]
            if ok:
                p = min(ok, key=lambda p: s1 * _num(p.values.get(n1)))
                txt += (f"; the cheapest trial keeping it at {delta_s:g} or above spends "
                        f"{format_kpi(n1, _num(p.values.get(n1)))} at {format_kpi(n0, _num(p.values.get(n0)))} "
                        f"(trial {p.trial})")
            else:
                p = max(pts, key=lambda p: _num(p.values.get(kpi)))
                txt += (f"; no trial kept it at {delta_s:g} or above: the best reached {_num(p.values.get(kpi)):.2f} "
                        f"(trial {p.trial}, {format_kpi(n0, _num(p.values.get(n0)))}, "
                        f"{format_kpi(n1, _num(p.values.get(n1)))})")
            out.append(txt + ".")
    return out


def _build(d: Path) -> tuple[list, list[Fig], str]:
    try:
        info = json.loads((d / TUNING_JSON).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ReportError(f"{str(d / TUNING_JSON)!r} cannot be read: {exc}") from None
    settings = info.get("settings", {})
    objs = [_sign(o) for o in settings.get("objectives", [])]
    if len(objs) < 2:
        raise ReportError(f"{str(d)!r}: the front comparison needs two objectives, the run has "
                          f"{settings.get('objectives')}")
    (n0, s0), (n1, s1) = objs[0], objs[1]
    trials = _read_csv(d / "trials.csv")
    front_rows = _read_csv(d / "front.csv")
    points: dict[str, list[_Point]] = {}
    for r in trials:
        if r.get("state") == "COMPLETE":
            points.setdefault(r["controller"], []).append(
                _Point(r["controller"], int(r["trial"]), {k: _num(v) for k, v in r.items()
                                                          if k not in ("controller", "trial", "state", "params",
                                                                       "feasible")}, r.get("params", "")))
    fronts: dict[str, list[_Point]] = {}
    for r in front_rows:
        fronts.setdefault(r["controller"], []).append(
            _Point(r["controller"], int(r["trial"]), {k: _num(v) for k, v in r.items()
                                                      if k not in ("controller", "trial", "state", "params",
                                                                   "feasible")}, r.get("params", "")))
    ctrls = list(info.get("controllers", {}))
    selected = {c: v.get("kpis") for c, v in info["controllers"].items() if v.get("kpis")}
    held = {c: v.get("kpis") for c, v in (info.get("verify") or {}).items()}

    def pair(p: _Point) -> tuple[float, float]:
        return (s0 * _num(p.values.get(n0)), s1 * _num(p.values.get(n1)))

    def display(name: str) -> tuple[float, str]:   # scale and unit the hypervolume is given in
        unit = KPIS[name].unit if name in KPIS else ""
        return (1 / 3.6e9, "MWh") if unit == "J" else (1.0, "" if unit in ("", "-") else unit)

    fp = {c: [pair(p) for p in fronts.get(c, [])] for c in ctrls}
    allp = [q for ps in fp.values() for q in ps]
    blocks: list = [Heading(1, f"Tuning: {info.get('study', d.name)}")]
    figs: list[Fig] = []
    if not allp:
        blocks.append(Para("No controller has a front: no finished trial met the constraints "
                           + ", ".join(settings.get("constraints", [])) + "."))
        return blocks, figs, f"Tuning {info.get('study', '')}"
    arr = np.array(allp)
    ref = arr.max(axis=0) + 0.05 * np.maximum(arr.max(axis=0) - arr.min(axis=0), 1e-12)
    (k0, u0), (k1, u1) = display(n0), display(n1)
    hv = {c: hypervolume_2d(fp[c], ref) * k0 * k1 for c in ctrls}
    tol = _tolerance(n0)
    # the verdict first
    blocks.append(Heading(2, "The answer"))
    limits = info.get("limits") or {}
    all_pts = {c: [(pair(p), p) for p in ps] for c, ps in points.items()}
    for a in ctrls:
        for b in ctrls:
            ia, ib = info["controllers"][a], info["controllers"][b]
            if a == b or not fp[a] or not fp[b] or (ia.get("group") or {}) != (ib.get("group") or {}):
                continue   # fronts compare within a sea state and condition when the run was split by them
            cv = coverage(fp[a], fp[b], tol)
            if math.isnan(cv["covered"]):
                continue
            blocks.append(Para(_verdict(a, b, cv, hv, (n0, s0), (n1, s1), tol, len(fp[b]))))
            if cv["uncovered"]:
                blocks.append(Para(_where_and_why(a, b, cv["uncovered"], fronts[a], all_pts.get(a, []),
                                                  fronts[b], (n0, s0), (n1, s1), tol, limits)))
    blocks.append(Para("Hypervolume of each front (" + f"{n0} × {n1}" + ", against the common reference "
                       f"{format_kpi(n0, s0 * ref[0])} / {format_kpi(n1, s1 * ref[1])}; larger is better): "
                       + "; ".join(f"**{c}** {hv[c]:.4g} {u0}·{u1}".rstrip("·") for c in ctrls) + "."))
    cost = _reliability_cost(ctrls, info, points, fronts, (n0, s0), (n1, s1), float(info.get("delta_s", DELTA_S_DEFAULT)))
    if cost:
        blocks.append(Heading(3, "What the riser and the lines cost"))
        blocks.extend(Para(t) for t in cost)
    png = _figure(points, fronts, selected, held, (n0, n1))
    figs.append(Fig("tuning_fronts", png, "Each controller's finished trials (faint), front (line; colour: time "
                                          "outside the safe circle), selected design (star) and its held-out "
                                          "value (circle)"))
    blocks.append(figs[-1])
    # the designs
    blocks.append(Heading(2, "The selected designs"))
    head = ["controller", "trial", n0, n1, "time outside safe", "held-out " + n0, "held-out " + n1, "file"]
    rows = []
    for c in ctrls:
        v = info["controllers"][c]
        k = v.get("kpis") or {}
        h = held.get(c) or {}
        rows.append([Cell(c), Cell(str(v.get("selected", "–"))), Cell(format_kpi(n0, _num(k.get(n0)))),
                     Cell(format_kpi(n1, _num(k.get(n1)))), Cell(format_kpi("time_outside_safe",
                                                                            _num(k.get("time_outside_safe")))),
                     Cell(format_kpi(n0, _num(h.get(n0)))), Cell(format_kpi(n1, _num(h.get(n1)))),
                     Cell(v.get("design", v.get("note", "–")), code=bool(v.get("design")))])
    blocks.append(Table(head, rows, ["l", "r", "r", "r", "r", "r", "r", "l"]))
    for c in ctrls:
        spec = info["controllers"][c].get("spec")
        if spec:
            blocks.append(Para(f"**{c}** ({spec.get('type')}): " + ", ".join(
                f"{k} = {_option_text(v)}" for k, v in spec.items() if k != "type")))
    blocks.append(Heading(2, "The run"))
    st = settings
    blocks.append(Para(f"Objectives {', '.join(st.get('objectives', []))}; constraints "
                       f"{', '.join(st.get('constraints', [])) or 'none'}; {st.get('trials')} trials per controller, "
                       f"sampler {st.get('sampler')}, seed {st.get('seed')}, selection {st.get('select')}; "
                       f"storage {info.get('storage')}."))
    rows = [[Cell(c), Cell(str(v.get("complete", 0))), Cell(str(v.get("failed", 0))),
             Cell(str(v.get("feasible", 0))), Cell(str(len(v.get("front", []))))]
            for c, v in info["controllers"].items()]
    blocks.append(Table(["controller", "finished", "failed", "meeting the constraints", "on the front"], rows,
                        ["l", "r", "r", "r", "r"]))
    if held:
        blocks.append(Heading(2, "Held-out seeds"))
        seeds = ", ".join(map(str, st.get("verify_seeds", [])))
        blocks.append(Para(f"The selected designs rerun on seeds {seeds}, which the search never used (sums such as "
                           "the energy scaled to the tuning's number of cases; worst cases over every held-out "
                           "case). A large gap says the design was tuned to the seed's particular storm."))
        vrows = []
        for c in ctrls:
            v = (info.get("verify") or {}).get(c) or {}
            k = info["controllers"][c].get("kpis") or {}
            for name in [n for n in (n0, n1, "time_outside_safe", "riser_delta_min") if n in (v.get("kpis") or {})]:
                t, h = _num(k.get(name)), _num(v["kpis"].get(name))
                per = "; ".join(f"seed {sd}: {format_kpi(name, _num(kk.get(name)))}"
                                for sd, kk in (v.get("per_seed") or {}).items())
                gap = (f"{100 * (h - t) / abs(t):+.1f} %" if t and math.isfinite(t) and math.isfinite(h)
                       and name not in ("time_outside_safe", "riser_delta_min") else format_kpi(name, h - t))
                vrows.append([Cell(c), Cell(name), Cell(format_kpi(name, t)), Cell(format_kpi(name, h)), Cell(gap),
                              Cell(per)])
        blocks.append(Table(["controller", "KPI", "tuning", "held-out", "gap", "per held-out seed"], vrows,
                            ["l", "l", "r", "r", "r", "l"]))
    return blocks, figs, f"Tuning {info.get('study', '')}"


def write_tuning_report(tune_dir: str | Path, *, out_html: str | Path | None = None,
                        out_md: str | Path | None = None) -> tuple[Path, Path]:
    """Write the tuning run's report (HTML and Markdown); returns ``(html_path, md_path)``."""
    d = Path(tune_dir)
    if not is_tuning_dir(d):
        raise ReportError(f"{str(d)!r} is not a tuning directory (no {TUNING_JSON}: run tapm tune first)")
    out_html = Path(out_html) if out_html is not None else d / "report.html"
    out_md = Path(out_md) if out_md is not None else d / "report.md"
    fig_dir = out_md.parent / f"{out_md.stem}_files"
    import os

    fig_rel = Path(os.path.relpath(fig_dir, out_md.parent)).as_posix()
    blocks, figs, title = _build(d)
    md = render_markdown(blocks, fig_rel)
    page = render_html(blocks, title)
    fig_dir.mkdir(parents=True, exist_ok=True)
    for f in figs:
        atomic_write_bytes(fig_dir / f"{f.name}.png", f.png)
    atomic_write_text(out_md, md)
    atomic_write_text(out_html, page)
    return out_html, out_md
