"""The ``tapm estimate`` commands (registered in :mod:`tapm_opt.cli`).

``tapm estimate anchors SCENARIO --virtual-vessels N --duration T --out DIR [--json]``: tension-based
position and anchor estimation (EKF-SLAM, :mod:`tapm_opt.estimation.anchor_slam`; method
``docs/anchor_slam.md``).
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import click
import numpy as np

__all__ = ["estimate", "anchors"]


def _out_dir(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """``--out``: the output-directory check of every ``tapm`` command (``cli._out_path``)."""
    from ._common import out_path

    return out_path("dir")(ctx, param, value)


def _read_initial(path: str, line_ids: tuple[str, ...]) -> np.ndarray:
    """Initial anchor guesses from a CSV with a header ``id,x,y`` [m] (one row per line id; an
    optional ``z`` column is ignored: the filter is 2-D, §4.1)."""
    from ..estimation.anchor_slam import AnchorSlamError

    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = [r for r in csv.DictReader(line for line in fh if not line.lstrip().startswith("#"))]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise AnchorSlamError(f"--initial {path!r} cannot be read: {exc}") from None
    if not rows or not {"id", "x", "y"} <= set(rows[0]):
        raise AnchorSlamError(f"--initial {path!r} needs a header with columns id, x, y [m]")
    got: dict[str, np.ndarray] = {}
    for k, r in enumerate(rows, start=2):
        lid = str(r["id"]).strip()
        try:
            xy = np.array([float(r["x"]), float(r["y"])])
        except (TypeError, ValueError):
            raise AnchorSlamError(f"--initial {path!r} line {k}: x = {r.get('x')!r}, y = {r.get('y')!r} must be "
                                  "numbers [m]") from None
        if not np.all(np.isfinite(xy)):
            raise AnchorSlamError(f"--initial {path!r} line {k}: x = {r['x']!r}, y = {r['y']!r} must be finite [m]")
        if lid not in line_ids:
            raise AnchorSlamError(f"--initial {path!r} line {k}: id = {lid!r} is not a line of the scenario; lines "
                                  f"are {list(line_ids)}")
        if lid in got:
            raise AnchorSlamError(f"--initial {path!r} line {k}: id = {lid!r} is given twice")
        got[lid] = xy
    missing = [i for i in line_ids if i not in got]
    if missing:
        raise AnchorSlamError(f"--initial {path!r} gives no anchor for line(s) {missing}")
    return np.array([got[i] for i in line_ids])


@click.group("estimate")
def estimate() -> None:
    """Estimation from the vessel's sensors (tension-based positioning and anchor mapping)."""


@estimate.command("anchors")
@click.argument("scenario_name", metavar="SCENARIO")
@click.option("--virtual-vessels", "n_virtual", type=click.IntRange(1, 50), default=4, show_default=True,
              help="Number N of virtual vessels (stored equilibria) in the sensor network.")
@click.option("--duration", type=float, default=1200.0, show_default=True,
              help="Length of the stored records and of the estimation run [s].")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), required=True, callback=_out_dir,
              help="Directory for estimates.csv, anchors.csv, summary.json and network.npz.")
@click.option("--initial", "initial", type=click.Path(dir_okay=False), default=None,
              help="CSV of initial anchor guesses (columns id, x, y [m]); default: the scenario's anchors "
                   "perturbed as in the seed's Table 4.")
@click.option("--network", "network", type=click.Path(dir_okay=False), default=None,
              help="A network.npz written by an earlier run: reuse its stored records (its first N vessels) "
                   "instead of simulating.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of the random environments and the plant (not used with --network).")
@click.option("--settle", type=float, default=200.0, show_default=True,
              help="Settling chunk before each record [s] (repeated until the LF position moves < 1 m, "
                   "at most 1200 s).")
@click.option("--offsets", "offsets", type=click.FloatRange(min=0.0), nargs=2, default=(25.0, 60.0),
              show_default=True, metavar="MIN MAX",
              help="Distance of the virtual vessels' quasi-static equilibria from the field zero point [m] "
                   "(the live vessel's: 0 to MAX); the random environments are drawn until they give it. A stiff "
                   "mooring needs less: on the taut fpso_deep they put the vessel at most about 20 m away (--offsets 5 20).")
@click.option("--workers", type=click.IntRange(1, 64), default=None,
              help="Processes for the plant runs (default: 2, or 1 on a single CPU).")
@click.option("--line-correction/--no-line-correction", default=True, show_default=True,
              help="Correct each record's ranges by the line model (the seed's Delta T_c and Delta T_v of eq. 8): "
                   "a stored record's mean range error along its own track under its sea state, the live "
                   "record's tensions less the share its current puts on the lines.")
@click.option("--survey/--no-survey", default=True, show_default=True,
              help="Fit the anchors to the stored records in batch (least squares from the initial guesses) "
                   "and start the EKF from that fit; without it the EKF starts from the initial guesses.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of text.")
def anchors(scenario_name: str, n_virtual: int, duration: float, out_dir: str, initial: str | None,
            network: str | None, seed: int, settle: float, offsets: tuple[float, float], workers: int | None,
            line_correction: bool, survey: bool, as_json: bool) -> None:
    """Estimate SCENARIO's anchors and the vessel's position from the line tensions (EKF-SLAM).

    Generates N virtual vessels -- the vessel settled at equilibria in random environments, heading-only
    control, records of the observer's LF position and the measured tensions -- and the live
    vessel's record on the plant, fits the anchors to the stored records in batch from the initial
    anchor guesses, then runs the EKF of eq. 15-16 from that fit; every record's ranges corrected by
    the line model (eq. 8's Delta T_c and Delta T_v).
    Writes OUT/estimates.csv (position and anchors over time), anchors.csv, summary.json and
    network.npz (the stored records, for --network). Errors are horizontal, in metres.
    """
    from .._io import atomic_write_text, csv_text
    from ._common import load
    from ..estimation.anchor_slam import (AnchorSlamError, VirtualVesselNetwork, run_anchor_slam,
                                         table4_initial_anchors)
    from ..models.mooring import MooringModel

    sc = load(scenario_name)
    if not (math.isfinite(duration) and 10.0 <= duration <= 86400.0):
        raise click.BadParameter(f"{duration!r} s must be a finite number in [10, 86400] s", param_hint="'--duration'")
    if not (math.isfinite(settle) and settle > 0):
        raise click.BadParameter(f"{settle!r} s must be a positive number", param_hint="'--settle'")
    if not offsets[0] < offsets[1]:
        raise click.BadParameter(f"{offsets[0]:g} {offsets[1]:g}: MIN must be below MAX", param_hint="'--offsets'")
    model = MooringModel.from_scenario(sc)
    if initial is not None:
        a0 = _read_initial(initial, model.line_ids)
    elif model.n_lines == 8:
        a0 = table4_initial_anchors(model.anchors)
    else:
        raise click.BadParameter(f"scenario {sc.name!r} has {model.n_lines} lines: Table 4's perturbation is for 8; "
                                 "give --initial FILE.csv", param_hint="'--initial'")
    if network is not None:
        net = VirtualVesselNetwork.load(network)
        if net.scenario != sc.name:
            raise AnchorSlamError(f"--network {network!r} was stored for scenario {net.scenario!r}, not {sc.name!r}")
        if net.n < n_virtual:
            raise AnchorSlamError(f"--network {network!r} holds {net.n} virtual vessels; --virtual-vessels = "
                                  f"{n_virtual} needs at least as many")
    else:
        from ..studies.anchor_network import generate_network

        net = generate_network(sc, n_virtual, duration=duration, seed=seed, settle=settle,
                               workers=workers or min(2, os.cpu_count() or 1),
                               env_kw=None if tuple(offsets) == (25.0, 60.0) else
                               {"min_offset": float(offsets[0]), "max_offset": float(offsets[1])})
    res = run_anchor_slam(sc, net, n_virtual=n_virtual, duration=duration, anchors0=a0,
                          line_correction=line_correction, survey=survey)
    summary = {"scenario": sc.name, **res.summary(),
               "virtual_vessel_equilibria": [[float(v) for v in vv.cot.mean(axis=0)] for vv in net.vessels[:n_virtual]]}
    # compute everything first, then write: no half-written output on a failure
    texts = {name: csv_text(h, rows) for name, (h, rows) in res.csv_tables().items()}
    texts["summary.json"] = json.dumps(summary, indent=2) + "\n"
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [atomic_write_text(out / name, text) for name, text in texts.items()]
    if network is None:
        paths.append(net.save(out / "network.npz"))
    if as_json:
        click.echo(json.dumps({"anchors": summary["anchors"], "position_rms_error": summary["position_rms_error"]},
                              indent=2))
        return
    click.echo(f"{sc.name}: anchor EKF-SLAM, N = {n_virtual} virtual vessels, {res.t[-1] - res.t[0]:g} s")
    for a in summary["anchors"]:
        click.echo(f"  anchor {a['id']:>4s}: estimate ({a['estimate'][0]:9.1f}, {a['estimate'][1]:9.1f}) m, "
                   f"true ({a['true'][0]:9.1f}, {a['true'][1]:9.1f}) m, error {a['error']:6.1f} m")
    click.echo(f"  tension-only position: RMS error {summary['position_rms_error']:.2f} m "
               f"(after {res.burn_in:g} s)")
    for p in paths:
        click.echo(f"wrote {p}")
