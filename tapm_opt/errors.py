"""Typed exceptions of tapm_opt.

Every error a user can cause derives from :class:`TapmError`; the ``tapm`` command prints its
message on one line and exits non-zero instead of showing a traceback.
"""

from __future__ import annotations

from dataclasses import dataclass


class TapmError(Exception):
    """Base class of every user-facing error in tapm_opt."""


@dataclass(frozen=True)
class ScenarioIssue:
    """One problem found in a scenario.

    Attributes
    ----------
    path : str
        Field path in the scenario file, e.g. ``lines[3].length``.
    message : str
        What is wrong and what is allowed, naming the bad value.
    """

    path: str
    message: str

    def __str__(self) -> str:
        if not self.path:
            return self.message
        sep = " " if self.message.startswith("= ") else ": "
        return f"{self.path}{sep}{self.message}"


class IssuesError(TapmError, ValueError):
    """An input with one or more problems, each naming its field path (``issues``).

    Subclasses set ``what``, the kind of input, used in the message ("invalid <what>: ...").
    """

    what = "input"

    def __init__(self, issues: list[ScenarioIssue] | ScenarioIssue | str, *, source: str = ""):
        if isinstance(issues, str):
            issues = [ScenarioIssue("", issues)]
        elif isinstance(issues, ScenarioIssue):
            issues = [issues]
        self.issues: tuple[ScenarioIssue, ...] = tuple(issues)
        self.source = source
        head = f"invalid {self.what} {source}" if source else f"invalid {self.what}"
        if len(self.issues) == 1:
            msg = f"{head}: {self.issues[0]}"
        else:
            body = "\n".join(f"  - {i}" for i in self.issues)
            msg = f"{head}: {len(self.issues)} problems\n{body}"
        super().__init__(msg)


class ScenarioError(IssuesError):
    """A scenario file or dictionary is invalid.

    Carries *all* problems found (``issues``), not only the first one.
    """

    what = "scenario"


class CatenaryError(TapmError, ValueError):
    """A catenary problem has invalid input or no solution."""


class ModelError(TapmError, ValueError):
    """A model was asked something it cannot answer (bad argument, unknown option)."""
