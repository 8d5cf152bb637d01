"""The value checks of the study-file loader: every problem collected with its field path.

Used by :mod:`tapm_opt.studies.spec`; the checks on numbers and text reuse the scenario loader's
value helpers, so a study file and a scenario file word their errors alike.
"""

from __future__ import annotations

import difflib
import math
from typing import Any, Mapping, Sequence

from .._checks import fmt as _fmt, is_number as _is_number  # the scenario loader's value checks too
from .store import StudyIssue


class Checker:
    """Collects every problem with its field path."""

    def __init__(self) -> None:
        self.issues: list[StudyIssue] = []

    def err(self, path: str, msg: str) -> None:
        self.issues.append(StudyIssue(path, msg))

    def keys(self, data: Mapping, allowed: set[str], path: str) -> None:
        for k in data:
            if k not in allowed:
                hint = difflib.get_close_matches(str(k), sorted(allowed), n=1, cutoff=0.6)
                self.err(f"{path}.{k}" if path else str(k),
                         "unknown key" + (f"; did you mean '{hint[0]}'?" if hint else
                                          f"; allowed keys: {', '.join(sorted(allowed))}"))

    def table(self, v: Any, path: str) -> dict | None:
        if not isinstance(v, dict):
            self.err(path, f"must be a table, got {type(v).__name__} {_fmt(v)}")
            return None
        return v

    def tables(self, v: Any, path: str) -> list[dict]:
        """A list of tables ([[path]]); a single table is accepted as a list of one."""
        if isinstance(v, dict):
            return [v]
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            self.err(path, f"must be a list of tables ([[{path}]]), got {type(v).__name__} {_fmt(v)}")
            return []
        return v

    def text(self, v: Any, path: str, *, id_like: bool = False) -> str | None:
        if id_like and isinstance(v, int) and not isinstance(v, bool):
            return str(v)
        if not isinstance(v, str) or not v.strip():
            self.err(path, f"must be non-empty text, got {type(v).__name__} {_fmt(v)}")
            return None
        return v

    def number(self, v: Any, path: str, *, unit: str = "", positive: bool = False, nonneg: bool = False,
               at_most: float | None = None) -> float | None:
        u = f" [{unit}]" if unit else ""
        if not _is_number(v):
            self.err(path, f"must be a number{u}, got {type(v).__name__} {_fmt(v)}")
            return None
        x = float(v)
        if not math.isfinite(x):
            self.err(path, f"= {_fmt(x)} must be a finite number")
            return None
        su = f" {unit}" if unit else ""
        if positive and x <= 0:
            self.err(path, f"= {_fmt(x)}{su} must be > 0")
            return None
        if nonneg and x < 0:
            self.err(path, f"= {_fmt(x)}{su} must be >= 0")
            return None
        if at_most is not None and x > at_most:
            self.err(path, f"= {_fmt(x)}{su} must be <= {_fmt(at_most)}")
            return None
        return x

    def integer(self, v: Any, path: str, *, at_least: int | None = None) -> int | None:
        if not (isinstance(v, int) and not isinstance(v, bool)):
            self.err(path, f"must be a whole number, got {type(v).__name__} {_fmt(v)}")
            return None
        if at_least is not None and v < at_least:
            self.err(path, f"= {v} must be >= {at_least}")
            return None
        return int(v)

    def choice(self, v: Any, allowed: Sequence[str], path: str) -> str | None:
        if v not in allowed:
            hint = difflib.get_close_matches(str(v), list(allowed), n=1)
            self.err(path, f"= {_fmt(v)} is not one of {', '.join(allowed)}"
                     + (f" (did you mean {hint[0]!r}?)" if hint else ""))
            return None
        return v

    def boolean(self, v: Any, path: str) -> bool | None:
        if not isinstance(v, bool):
            self.err(path, f"must be true or false, got {_fmt(v)}")
            return None
        return v

    def unique(self, names: list[tuple[int, str | None]], path: str, key: str) -> None:
        seen: dict[str, int] = {}
        for i, n in names:
            if n is None:
                continue
            if n in seen:
                self.err(f"{path}[{i}].{key}", f"= {n!r} is also used by {path}[{seen[n]}] ({key}s must be unique)")
            else:
                seen[n] = i
