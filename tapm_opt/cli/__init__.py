"""The ``tapm`` command (a package: the shared helpers in :mod:`._common`, one module per
group of commands).

User mistakes (a bad scenario, a missing file, an impossible option) end with a one-line
``error: ...`` message and a non-zero exit code; ``--verbose`` adds the traceback.
"""

from __future__ import annotations

import sys
import traceback
import warnings
from pathlib import Path

import click

from ..errors import TapmError
from . import analysis, scenario, simulate, study, tune  # noqa: F401  (each registers its commands)
from ._common import EXIT_USER_ERROR, State, cli
from .capability import capability as _capability_command
from .estimate import estimate as _estimate_group
from .study import _compare_sea_state  # noqa: F401  (tests use it)

__all__ = ["cli", "main", "EXIT_USER_ERROR"]

cli.add_command(_capability_command)
cli.add_command(_estimate_group)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``tapm`` console script.

    Warnings raised on the way (e.g. numpy's on non-finite arithmetic) are held back: a failed
    command ends with its one-line error only (``--verbose`` shows them too); a command that
    succeeds prints each as one ``warning: ...`` line after its output.
    """
    with warnings.catch_warnings(record=True) as caught:
        code = _main(argv)
    if code == 0 or State.verbose:
        for w in caught:
            click.echo(f"warning: {w.category.__name__}: {w.message} ({Path(w.filename).name}:{w.lineno})", err=True)
    return code


def _main(argv: list[str] | None) -> int:
    try:
        cli.main(args=argv, prog_name="tapm", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        return 130
    except click.exceptions.NoArgsIsHelpError as exc:
        exc.show()
        return exc.exit_code
    except click.UsageError as exc:  # one line naming the option and the value; --help has the usage
        where = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
        click.echo(f"error: {exc.format_message()}{where}", err=True)
        return exc.exit_code
    except click.ClickException as exc:
        exc.show()
        return exc.exit_code
    except TapmError as exc:
        if State.verbose:
            traceback.print_exc()
        msg = str(exc)
        click.echo(f"error: {msg}", err=True)
        return EXIT_USER_ERROR
    except OSError as exc:
        if State.verbose:
            traceback.print_exc()
        click.echo(f"error: {exc}", err=True)
        return EXIT_USER_ERROR
    except MemoryError as exc:
        if State.verbose:
            traceback.print_exc()
        click.echo(f"error: out of memory ({exc or 'MemoryError'}): ask for a shorter run or fewer FEM segments",
                   err=True)
        return EXIT_USER_ERROR
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

