"""What every ``tapm`` command shares: the command group, loading a scenario argument, the
checks of ``--out`` paths and of ``KEY=VALUE`` options, and the exit code of a user error.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import click
import numpy as np

from .. import __version__
from ..config import load_scenario

__all__ = ["EXIT_USER_ERROR", "State", "ControllerKindChoice", "cli", "load", "out_path", "check_issues", "parse_floats", "key_values",
           "parse_value"]

EXIT_USER_ERROR = 2


class State:
    """Process-wide flags of the command line (``--verbose``)."""

    verbose = False


class ControllerKindChoice(click.ParamType):
    """``--controller``: a registered controller kind (:mod:`tapm_opt.design.registry`), read
    when the option is parsed, so an installed plugin's kind is a choice too."""

    name = "kind"

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        from ..design.registry import kind_names

        return "[" + "|".join(kind_names()) + "]"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        from ..design.registry import ControllerSpecError, kind

        try:
            return kind(value, where="--controller").name
        except ControllerSpecError as exc:
            self.fail(str(exc).removeprefix("--controller.type = "), param, ctx)


def load(name_or_path: str):
    """The scenario a command argument names (built-in name or TOML file)."""
    return load_scenario(name_or_path)


def out_path(kind: str, what: str | None = None):
    """Callback of an ``--out`` option naming a file (``kind="file"``) or a directory to write
    (``what`` names it in messages): the path must not be empty, and its nearest existing ancestor
    must be a writable directory."""
    what = what or ("directory" if kind == "dir" else "file")

    def check(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
        if value is None:
            return None
        if not str(value).strip():
            raise click.BadParameter(f"{value!r} is empty: give the {what} to write", ctx=ctx, param=param)
        p = Path(value)
        for anc in (p, *p.parents) if kind == "dir" else p.parents:
            if not anc.exists():
                continue
            if not anc.is_dir():
                raise click.BadParameter(f"{value!r}: cannot create the {what}: {str(anc)!r} is a file, not a "
                                         "directory", ctx=ctx, param=param)
            if not os.access(anc, os.W_OK | os.X_OK):
                raise click.BadParameter(f"{value!r}: cannot create the {what}: no write access to {str(anc)!r}",
                                         ctx=ctx, param=param)
            break
        return value

    return check


def check_issues(issues) -> None:
    """Raise the first plausibility issue of an option as a click error naming the option."""
    if issues:
        iss = issues[0]
        raise click.BadParameter(str(iss.message).removeprefix("= "), param_hint=f"'{iss.path}'")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--verbose", "-v", is_flag=True, help="Show tracebacks and extra detail.")
@click.version_option(__version__, prog_name="tapm")
def cli(verbose: bool) -> None:
    """tapm_opt — control design workbench for thruster-assisted position mooring."""
    State.verbose = verbose


def parse_floats(text: str, what: str) -> np.ndarray:
    try:
        vals = np.array([float(x) for x in text.split(",") if x.strip()])
    except ValueError:
        raise click.BadParameter(f"{what} must be comma-separated numbers, got {text!r}") from None
    if vals.size == 0 or not np.all(np.isfinite(vals)):
        raise click.BadParameter(f"{what} must be finite numbers, got {text!r}")
    return vals


def key_values(items: tuple[str, ...], flag: str) -> dict:
    """``KEY=VALUE`` options as a dict (values by :func:`_parse_value`)."""
    out: dict = {}
    for opt in items:
        if "=" not in opt:
            raise click.BadParameter(f"{flag} {opt!r} must look like KEY=VALUE")
        k, v = opt.split("=", 1)
        out[k.strip()] = parse_value(v.strip())
    return out


def parse_value(text: str):
    """A --option value: number, list of numbers (comma-separated), true/false, or text."""
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        if "," in text:
            return [float(x) for x in text.split(",")]
        val = float(text)
        return int(val) if val.is_integer() and "." not in text and "e" not in low else val
    except ValueError:
        return text
