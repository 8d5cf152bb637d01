"""Make ``catenary_reference.csv``: elastic catenary solutions from MoorPy (independent code).

Run with a Python environment that has MoorPy installed (not a tapm_opt dependency)::

    python tests/data/make_catenary_reference.py            # writes next to this script

MoorPy's ``moorpy.Catenary.catenary(XF, ZF, L, EA, W, CB=..., Tol=...)`` returns
``(fAH, fAV, fBH, fBV, info)``: end A is the anchor (on the seabed for CB >= 0), end B the
fairlead; ``fAH = HA``, ``fAV = VA`` (the anchor's horizontal tension and uplift, >= 0 here) and
``fBH = -HF``, ``fBV = -VF`` (the force the line exerts at the fairlead, pointing down and back to
the anchor, so negative). The CSV stores them in tapm_opt's convention, all >= 0:
``HF = -fBH, VF = -fBV, HA = fAH, VA = fAV``, plus MoorPy's ``info['ProfileType']`` (1 fully
suspended, 2 touching down with anchor tension, 3 touching down with zero anchor tension (friction),
4 slack: hanging vertically from the fairlead with the rest on the seabed, 6 vertical, fully suspended).

The configurations cover touchdown without and with seabed friction (both anchor-loaded and the
zero-anchor-tension case), slack lines, fully suspended lines, vertical lines and taut lines
stretched beyond their length, on three line types (chain-like, wire, polyester). Only
configurations that MoorPy solves exactly (profile types 1–4 and 6, none of its last-resort
approximations) are written.
"""

from __future__ import annotations

import csv
import datetime
import math
import platform
from pathlib import Path

import moorpy
import numpy as np
from moorpy.Catenary import catenary

TOL = 1e-10  # MoorPy's Newton tolerance: absolute span error [m]

#             name        L [m]   EA [N]   w [N/m]
LINE_TYPES = [("chain", 1000.0, 5.0e8, 1000.0),
              ("wire", 2250.0, 2.3e8, 220.3),
              ("polyester", 1500.0, 1.0e8, 60.0)]


def configurations():
    """(line type, XF, ZF, CB) rows spanning the regimes."""
    rows = []
    for name, L, EA, w in LINE_TYPES:
        for ZF_frac in (0.1, 0.3, 0.5):
            ZF = ZF_frac * L
            d_taut = math.sqrt(max(L**2 - ZF**2, 0.0))   # horizontal reach of the straight line
            for x_frac in (0.80, 0.93, 0.985, 1.0005):    # touchdown ... suspended ... taut
                XF = x_frac * d_taut
                for CB in (0.0, 0.6):
                    rows.append((name, L, EA, w, XF, ZF, CB))
        # steep, fully suspended and near-vertical
        rows.append((name, L, EA, w, 0.3 * L, 0.97 * L, 0.0))
        rows.append((name, L, EA, w, 0.1 * L, 0.999 * L, 0.0))
        # vertical and fully suspended (stretched 0.5 %)
        rows.append((name, L, EA, w, 0.0, 1.005 * L, 0.0))
    return rows


def main() -> None:
    out = Path(__file__).with_name("catenary_reference.csv")
    written = skipped = 0
    with out.open("w", newline="") as fh:
        fh.write(f"# Elastic catenary reference solutions made by tests/data/make_catenary_reference.py\n")
        fh.write(f"# with MoorPy {moorpy.__version__ if hasattr(moorpy, '__version__') else _dist_version()} "
                 f"(moorpy.Catenary.catenary, Tol={TOL:g} m), numpy {np.__version__}, "
                 f"Python {platform.python_version()}, on {datetime.date.today().isoformat()}.\n")
        fh.write("# Units: m, N, N/m. HF, VF: fairlead tension components; HA, VA: anchor horizontal tension\n")
        fh.write("# and uplift (tapm_opt convention, all >= 0; HF = -fBH, VF = -fBV, HA = fAH, VA = fAV).\n")
        wr = csv.writer(fh, lineterminator="\n")
        wr.writerow(["line", "XF", "ZF", "L", "EA", "w", "CB", "HF", "VF", "HA", "VA", "profile_type"])
        for name, L, EA, w, XF, ZF, CB in configurations():
            fAH, fAV, fBH, fBV, info = catenary(XF, ZF, L, EA, w, CB=CB, Tol=TOL, MaxIter=200)
            ptype = info.get("ProfileType")
            if ptype not in (1, 2, 3, 4, 6) or info.get("error"):
                skipped += 1
                continue
            wr.writerow([name] + [repr(float(v)) for v in (XF, ZF, L, EA, w, CB, -fBH, -fBV, fAH, fAV)]
                        + [ptype])
            written += 1
    print(f"wrote {written} configurations to {out} ({skipped} skipped: MoorPy fallback approximations)")


def _dist_version() -> str:
    from importlib.metadata import version
    return version("moorpy")


if __name__ == "__main__":
    main()
