"""The controller designs shipped with the package, and the designs ``tapm compare`` runs.

A built-in scenario may ship the designs ``tapm tune`` selected for it on the default study
(``tapm_opt/studies/builtin/tuned/<scenario>/<controller>.toml``, the ``tuned/<controller>.toml``
files of the tuning run, each headed by the command that produced it). They are rerun whenever the
plant changes: a test reruns each shipped design on its tuning case and checks the KPIs the file
records (``docs/tuning.md``, "The shipped designs").

``tapm compare --designs`` chooses what the main job runs:

- ``shipped`` (default): the scenario's shipped designs; a scenario with none runs the registry's
  defaults, and says so;
- ``defaults``: the registry's defaults (:mod:`tapm_opt.design.registry`), as before tuning;
- a ``tapm tune`` output directory: its ``tuned/<controller>.toml``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

__all__ = ["SHIPPED_DIR", "shipped_designs", "compare_designs", "DesignChoiceError"]

#: Where the shipped designs live: one directory per built-in scenario.
SHIPPED_DIR = Path(__file__).parent / "builtin" / "tuned"


class DesignChoiceError(ValueError):
    """``--designs`` names neither ``shipped``, ``defaults`` nor a tuning run's directory."""


def shipped_designs(scenario: str) -> dict[str, Path]:
    """``{controller name: design file}`` shipped for the built-in ``scenario`` (empty if none)."""
    d = SHIPPED_DIR / str(scenario)
    if not d.is_dir():
        return {}
    return {p.stem: p for p in sorted(d.glob("*.toml"))}


def compare_designs(choice: str, scenario: str, names: Sequence[str]) -> tuple[dict[str, Path], str]:
    """The design file of each controller of ``names`` that the main job runs, and a sentence
    saying where the designs come from.

    Parameters
    ----------
    choice : str
        ``"shipped"``, ``"defaults"`` or the directory of a ``tapm tune`` run.
    scenario : str
        The scenario's name (the shipped designs are per built-in scenario).
    names : sequence of str
        The study's controller names (``PID``, ``MPC``, ``NMPC`` in the default study).

    Raises
    ------
    DesignChoiceError
        A directory that holds no ``tuned/`` designs for any of ``names``.
    """
    if choice == "defaults":
        return {}, "controllers at the registry's default tunings (--designs defaults)"
    if choice == "shipped":
        ship = shipped_designs(scenario)
        found = {n: ship[n] for n in names if n in ship}
        if not found:
            return {}, (f"no designs tuned for scenario {scenario!r} are shipped: the controllers run at the "
                        "registry's default tunings (tune them: tapm tune studies/mpc_vs_pid.toml --out DIR, then "
                        "--designs DIR)")
        return found, (f"controllers at the designs tuned for {scenario} shipped in the package "
                       f"({_listing(found)})")
    d = Path(choice)
    if not (d / "tuned").is_dir():
        raise DesignChoiceError(f"--designs = {choice!r} must be 'shipped', 'defaults' or the directory of a tapm tune "
                                "run (with a tuned/ folder)")
    found = {n: d / "tuned" / f"{n}.toml" for n in names if (d / "tuned" / f"{n}.toml").is_file()}
    if not found:
        raise DesignChoiceError(f"--designs = {choice!r}: tuned/ holds no design for {', '.join(names)} "
                                f"(files named <controller>.toml)")
    missing = [n for n in names if n not in found]
    note = f"controllers at the designs of {choice} ({_listing(found)})"
    if missing:
        note += f"; {', '.join(missing)} at the registry's default tuning (no design in {choice})"
    return found, note


def _listing(found: Mapping[str, Path]) -> str:
    return ", ".join(f"{n}: {p.name}" for n, p in found.items())
