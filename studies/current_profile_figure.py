"""The figure of docs/current_estimation.md from a run of studies/current_profile.toml.

    tapm study run studies/current_profile.toml --out runs/current_profile
    python studies/current_profile_figure.py runs/current_profile docs/images/current_estimation.png

Per sea state (columns): the estimated surface speed, direction and seabed factor of every case
that estimates the current (the "current estimate" events of its estimator log), against the
plant's current (``Environment.current_surface`` of the case's sea state; the seabed factor of its
profile).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def main(out: str, png: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tapm_opt.config.loader import scenario_from_dict
    from tapm_opt.estimation.current_profile import profile_shape
    from tapm_opt.plant.environment import Environment
    from tapm_opt.results import Result

    cases = []
    for d in sorted(Path(out, "cases").iterdir()):
        if not (d / "result.npz").exists():
            continue
        c = json.loads((d / "case.json").read_text())
        cases.append((c, d))
    seas = sorted({c["labels"]["sea_state"] for c, _ in cases})
    fig, axes = plt.subplots(3, len(seas), figsize=(5.5 * len(seas), 8), sharex=True, squeeze=False)
    for j, sid in enumerate(seas):
        truth_done = False
        for c, d in cases:
            if c["labels"]["sea_state"] != sid:
                continue
            r = Result.load(d / "result.npz")
            est = [e for e in r.meta.get("estimator_log", []) if e.get("event") == "current estimate"]
            sc = scenario_from_dict(c["inputs"]["scenario"])
            if not truth_done:
                env = Environment(sc, sid)
                t = np.linspace(0.0, float(r.time[-1]), 400)
                u = np.array([env.current_surface(ti)[:2] for ti in t])
                f_b = profile_shape(sc.sea_state(sid), sc.environment.water_depth)[1]
                axes[0, j].plot(t, np.hypot(u[:, 0], u[:, 1]), "k-", lw=2, label="plant")
                axes[1, j].plot(t, np.degrees(np.arctan2(u[:, 1], u[:, 0])) % 360, "k-", lw=2, label="plant")
                axes[2, j].plot(t, np.full_like(t, f_b), "k-", lw=2, label="plant")
                truth_done = True
            if not est:
                continue
            te = np.array([e["t"] for e in est])
            lab = c["labels"]["controller"]
            axes[0, j].plot(te, [e["speed"] for e in est], ".-", label=lab)
            axes[1, j].plot(te, np.degrees([e["direction"] for e in est]) % 360, ".-", label=lab)
            axes[2, j].plot(te, [e["seabed_factor"] for e in est], ".-", label=lab)
        axes[0, j].set_title(f"sea state '{sid}'")
        axes[0, j].set_ylabel("surface speed [m/s]")
        axes[1, j].set_ylabel("direction, going to [deg]")
        axes[2, j].set_ylabel("seabed factor f_b [-]")
        axes[2, j].set_xlabel("t [s]")
        for a in axes[:, j]:
            a.grid(True, alpha=0.3)
        axes[0, j].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=90)
    print(f"wrote {png}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python studies/current_profile_figure.py STUDY_OUT FIGURE.png")
    main(sys.argv[1], sys.argv[2])
