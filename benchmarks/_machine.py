"""Machine description printed at the top of every benchmark (one definition for all scripts)."""

from __future__ import annotations

import os
import platform

import casadi
import numpy as np


def machine_info(extra: str = "") -> str:
    """CPU, CPU count, OS, and the Python, numpy and CasADi versions (plus ``extra``)."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(line.split(":", 1)[1].strip() for line in fh if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    try:
        load = ", load average %.2f" % os.getloadavg()[0]
    except OSError:
        load = ""
    return (f"machine: {cpu}, {os.cpu_count()} CPUs, {platform.system()} {platform.release()}{load}\n"
            f"python {platform.python_version()}, numpy {np.__version__}, casadi {casadi.__version__}"
            + (f", {extra}" if extra else ""))
