"""Key performance indicators of a closed-loop result (computed from saved results only)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..results import Result

__all__ = ["basic_kpis"]


def basic_kpis(result: Result, scenario: Any) -> dict[str, float]:
    """Offsets, heading error, tensions, thrust energy and solver statistics of one run.

    Returns a flat dict: ``offset_max``/``offset_mean``/``offset_std`` [m] (horizontal distance of the
    LF position from the field zero point), ``time_outside_safe``/``time_outside_alert`` [s],
    ``heading_error_max`` [deg] (from the logged setpoint when present), ``T_max`` [N] and
    ``utilisation_max`` (T/MBS) over all lines, ``thrust_energy`` [J] (integral of the summed
    thruster power), and the controller's solve-time statistics when the result carries them.
    """
    t = result.time
    off = np.hypot(result["x"], result["y"])
    dt = np.diff(t, append=t[-1])
    lim = scenario.limits
    out: dict[str, float] = {
        "duration": float(t[-1] - t[0]),
        "offset_max": float(off.max()),
        "offset_mean": float(off.mean()),
        "offset_std": float(off.std()),
        "time_outside_safe": float(np.sum(dt[off > lim.safe_radius])) if lim.safe_radius else 0.0,
        "time_outside_alert": float(np.sum(dt[off > lim.alert_radius])) if lim.alert_radius else 0.0,
    }
    psi_d = result["psi_d"] if "psi_d" in result else np.zeros_like(t)
    err = (result["psi"] - psi_d + np.pi) % (2 * np.pi) - np.pi
    out["heading_error_max"] = float(np.degrees(np.abs(err).max()))
    T = result.group("T_fairlead")
    ids = result.group_names("T_fairlead")
    mbs = np.array([scenario.line_arrays["MBS"][scenario.line_index(i)] for i in ids])
    out["T_max"] = float(T.max())
    out["utilisation_max"] = float((T / mbs).max())
    P = result.group("P").sum(axis=1)
    out["thrust_energy"] = float(np.trapezoid(P, t))
    diag = result.meta.get("diagnostics", {})
    for k in ("solver_time_median", "solver_time_max", "solver_failures", "solver_fallbacks", "allocation_fallbacks"):
        if k in diag:
            out[k] = float(diag[k])
    return out
