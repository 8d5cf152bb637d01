"""Test options: ``--known-defects`` runs the tests of named, known defects (marker
``known_defect``); without it they are reported as skipped with the defect's name, so the README's
test command passes on any machine while the defect stays visible."""

from __future__ import annotations

import pytest

from tapm_opt.cli import cli, main


def pytest_addoption(parser):
    parser.addoption("--known-defects", action="store_true", default=False,
                     help="also run the tests marked known_defect (expected to fail until fixed)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--known-defects"):
        return
    for item in items:
        mark = item.get_closest_marker("known_defect")
        if mark is not None:
            item.add_marker(pytest.mark.skip(reason=f"known defect: {mark.kwargs.get('reason', mark.args[0] if mark.args else '')}"))


@pytest.fixture()
def tapm():
    """``tapm capability ...`` run in-process: ``tapm(capsys, *args)`` -> (exit code, stdout,
    stderr) (the command registered on the CLI group if it is not yet)."""
    from tapm_opt.cli.capability import capability as command

    if "capability" not in cli.commands:
        cli.add_command(command)

    def run(capsys, *args):
        code = main(list(args))
        out = capsys.readouterr()
        return code, out.out, out.err

    return run
