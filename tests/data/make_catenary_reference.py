"""Make ``catenary_reference.csv`` and ``catenary_reference_elevated.csv``: elastic catenary solutions
from MoorPy (independent code).

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

``catenary_reference_elevated.csv`` holds lines whose lower end A hangs ``h_A`` above the seabed,
which MoorPy encodes as a negative ``CB = -h_A`` (its friction is then 0): fully suspended lines
with and without a sag below A (profile type 1), lines whose sag reaches the seabed so that part of
them lies on it (MoorPy's ``'U'``: it solves the two suspended parts separately and balances their
horizontal tensions), slack lines hanging from both ends with the rest on the seabed (5), vertical
lines hanging doubled from A (6), taut lines, and the elevated cases of MoorPy's own test suite
(``tests/test_catenary.py``: the two ``CB = -372.7`` configurations and the symmetric U-shaped
line, ``CB = -20``). Its columns add ``h_A`` and MoorPy's ``info['LBot']``, the length resting on
the seabed. Two corrections: MoorPy's vertical doubled line (profile type 6, slack branch) reports
``fAV = w LA``, the magnitude of the vertical tension at A, though the line leaves A downward:
the CSV stores ``VA = -fAV`` there (tapm_opt's sign). And MoorPy's U-shaped solve can stop at a
non-solution without flagging an error (seen for nearly taut lines); such rows break the line's
vertical force balance ``VF - VA = w (L - LBot)`` (by a large factor, where the good ones hold it to
round-off) and are skipped.

    python tests/data/make_catenary_reference.py elevated   # only the elevated-end file
"""

from __future__ import annotations

import csv
import datetime
import math
import platform
import sys
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


def elevated_configurations():
    """(line type, XF, ZF, h_A) rows with the lower end above the seabed, spanning the regimes."""
    rows = []
    for name, L, EA, w in LINE_TYPES:
        for h_frac in (0.005, 0.05, 0.2):
            h_A = h_frac * L
            for ZF_frac in (0.0, 0.1, 0.3):
                ZF = ZF_frac * L
                d_taut = math.sqrt(L**2 - ZF**2)
                for x_frac in (0.5, 0.8, 0.88, 0.93, 0.96, 0.985, 1.0005):  # slack ... sag on the seabed ... taut
                    rows.append((name, L, EA, w, x_frac * d_taut, ZF, h_A))
        rows.append((name, L, EA, w, 0.3 * L, 0.97 * L, 0.1 * L))   # steep, anchor uplift
        rows.append((name, L, EA, w, 0.0, 0.3 * L, 0.45 * L))       # vertical, hanging doubled
        rows.append((name, L, EA, w, 0.0, 1.005 * L, 0.1 * L))      # vertical, taut
        rows.append((name, L, EA, w, 0.2 * L, 0.2 * L, 0.3 * L))    # slack, both ends hanging
    # MoorPy's own test cases with the lower end off the seabed (CB < 0)
    rows.append(("moorpy-test", 500.0, 7510000000000.0, 200.0, 400.0, 200.0, 372.7))
    rows.append(("moorpy-test", 130.0, 751000000.0, 881.05, 89.9, 59.2, 372.7))
    rows.append(("moorpy-test-U", 130.0, 1e12, 100.0, 100.0, 0.0, 20.0))
    return rows


def _header(fh, what: str) -> None:
    fh.write(f"# {what} made by tests/data/make_catenary_reference.py\n")
    fh.write(f"# with MoorPy {moorpy.__version__ if hasattr(moorpy, '__version__') else _dist_version()} "
             f"(moorpy.Catenary.catenary, Tol={TOL:g} m), numpy {np.__version__}, "
             f"Python {platform.python_version()}, on {datetime.date.today().isoformat()}.\n")


def write_seabed() -> None:
    out = Path(__file__).with_name("catenary_reference.csv")
    written = skipped = 0
    with out.open("w", newline="") as fh:
        _header(fh, "Elastic catenary reference solutions")
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


def write_elevated() -> None:
    out = Path(__file__).with_name("catenary_reference_elevated.csv")
    written = skipped = unbalanced = 0
    with out.open("w", newline="") as fh:
        _header(fh, "Elastic catenary reference solutions, lower end h_A above the seabed (MoorPy CB = -h_A),")
        fh.write("# Units: m, N, N/m. HF, VF: fairlead tension components; HA, VA: horizontal and vertical tension\n")
        fh.write("# at the lower end (tapm_opt convention: VA < 0 where the line leaves it downward; HF = -fBH,\n")
        fh.write("# VF = -fBV, HA = fAH, VA = fAV, or -fAV for MoorPy's vertical doubled line, which gives |VA|);\n")
        fh.write("# LBot: unstretched length on the seabed (info['LBot']).\n")
        wr = csv.writer(fh, lineterminator="\n")
        wr.writerow(["line", "XF", "ZF", "L", "EA", "w", "h_A", "HF", "VF", "HA", "VA", "LBot", "profile_type"])
        for name, L, EA, w, XF, ZF, h_A in elevated_configurations():
            fAH, fAV, fBH, fBV, info = catenary(XF, ZF, L, EA, w, CB=-h_A, Tol=TOL, MaxIter=200)
            ptype = info.get("ProfileType")
            HF, VF, HA, VA, LBot = -fBH, -fBV, fAH, fAV, info["LBot"]
            if ptype == 6 and VF < w * L:  # hanging doubled: MoorPy gives |VA|
                VA = -fAV
            if ptype not in (1, "U", 5, 6) or info.get("error"):
                skipped += 1
                continue
            if ptype == "U" and abs(VF - VA - w * (L - LBot)) > 1e-9 * w * L:
                unbalanced += 1
                continue
            wr.writerow([name] + [repr(float(v)) for v in (XF, ZF, L, EA, w, h_A, HF, VF, HA, VA, LBot)]
                        + [ptype])
            written += 1
    print(f"wrote {written} configurations to {out} ({skipped} skipped: MoorPy fallback approximations; "
          f"{unbalanced} skipped: U-shaped solve out of vertical balance)")


def main(which: str = "all") -> None:
    if which not in ("all", "seabed", "elevated"):
        raise SystemExit(f"usage: make_catenary_reference.py [all|seabed|elevated], not {which!r}")
    if which in ("all", "seabed"):
        write_seabed()
    if which in ("all", "elevated"):
        write_elevated()


def _dist_version() -> str:
    from importlib.metadata import version
    return version("moorpy")


if __name__ == "__main__":
    main(*sys.argv[1:2])
