"""Read a study output directory (the shared study contract) for the report, from saved files only.

Layout read (see ``docs/report.md``)::

    DIR/study.json, DIR/study.toml
    DIR/cases/<id>/case.json, result.npz, kpis.json, error.json
    DIR/kpis.csv
    DIR/gains/gains.md | gains.csv

Nothing here simulates; results are loaded one case at a time by the caller
(:meth:`CaseInfo.load_result`) so a large study does not sit in memory all at once.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import TapmError
from ..results import Result

__all__ = ["ReportError", "StudyData", "CaseInfo", "read_study"]

_ID_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")

#: Most bytes the report reads from one case's ``result.npz`` (all its arrays, decompressed):
#: 256 MiB, about four days of an fpso log at ``dt_log = 1`` s. A larger result is refused before
#: it is decompressed and named under the report's problems; the other cases are drawn.
MAX_RESULT_BYTES = 256 * 2**20


class ReportError(TapmError, ValueError):
    """The study directory is missing or invalid, so no report can be written."""


@dataclass
class CaseInfo:
    """One case of the study as listed in ``study.json`` plus what its folder holds.

    ``status`` is ``"finished"`` (case.json has "finished", result.npz and kpis.json exist),
    ``"failed"`` (error.json exists) or ``"incomplete"`` (neither: not run or interrupted).
    """

    id: str
    name: str
    labels: dict
    inputs: dict
    folder: Path
    status: str
    case_json: dict = field(default_factory=dict)
    kpis: dict | None = None
    error: dict | None = None
    problems: list[str] = field(default_factory=list)

    @property
    def controller(self) -> str:
        c = self.labels.get("controller")
        if c is None:
            spec = self.inputs.get("controller") or {}
            c = spec.get("type", "?") if isinstance(spec, dict) else str(spec)
        return str(c)

    def load_result(self) -> Result:
        """The saved closed-loop :class:`Result` (raises ``ResultError`` if unreadable, or if its
        arrays would hold more than :data:`MAX_RESULT_BYTES`)."""
        return Result.load(self.folder / "result.npz", max_bytes=MAX_RESULT_BYTES)

    def scenario(self):
        """The case's scenario rebuilt from ``inputs["scenario"]`` (raises ``ScenarioError``)."""
        from ..config import scenario_from_dict

        sc = self.inputs.get("scenario")
        if not isinstance(sc, dict):
            raise ReportError(f"case {self.id}: inputs has no 'scenario' dictionary")
        return scenario_from_dict(sc, source=f"of case {self.id}")


@dataclass
class StudyData:
    """Everything the report reads from a study directory (results excepted)."""

    path: Path
    study: dict
    study_toml: str | None
    cases: list[CaseInfo]
    kpi_csv: tuple[list[str], list[list[str]]] | None
    gains_md: str | None
    gains_csv: tuple[list[str], list[list[str]]] | None
    problems: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return str(self.study.get("name") or self.path.name)

    @property
    def description(self) -> str:
        return str(self.study.get("description") or "")


def _read_json(path: Path) -> Any:
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def _read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    text = path.read_text(encoding="utf-8")
    rows = list(csv.reader(io.StringIO("".join(ln for ln in text.splitlines(True) if not ln.startswith("#")))))
    rows = [r for r in rows if r]
    if not rows:
        raise ValueError("empty CSV file")
    return rows[0], rows[1:]


def read_study(study_dir: str | Path) -> StudyData:
    """Read ``study_dir`` following the study contract.

    Raises
    ------
    ReportError
        The directory does not exist, is not a directory, or has no readable ``study.json`` with
        a ``cases`` list of objects with a valid ``id``. Problems of single cases (unreadable
        kpis.json, ...) do not raise: they are collected in ``problems`` and shown in the report.
    """
    path = Path(study_dir)
    if not path.exists():
        raise ReportError(f"study directory {path} does not exist")
    if not path.is_dir():
        raise ReportError(f"{path} is not a study directory (it is not a directory)")
    sj = path / "study.json"
    if not sj.is_file():
        raise ReportError(f"{path} is not a study directory: it has no study.json "
                          f"(write one with `tapm study run STUDY.toml --out {path}`)")
    try:
        study = _read_json(sj)
    except (OSError, ValueError) as exc:
        raise ReportError(f"cannot read {sj}: {exc}") from None
    if not isinstance(study, dict) or not isinstance(study.get("cases"), list):
        raise ReportError(f"{sj} is not a study description: it needs an object with a 'cases' list")

    from ..studies.store import StudyError, study_cases

    try:
        entries = study_cases(study, where=sj)   # each case's scenario, stored once per study, put back
    except StudyError as exc:
        raise ReportError(str(exc)) from None
    problems: list[str] = []
    cases: list[CaseInfo] = []
    seen: set[str] = set()
    for i, entry in enumerate(entries):
        cid = entry.get("id") if isinstance(entry, dict) else None
        if not isinstance(cid, str) or not _ID_RE.match(cid) or cid in (".", ".."):
            raise ReportError(f"{sj}: cases[{i}] has no valid 'id' (got {cid!r})")
        if cid in seen:
            raise ReportError(f"{sj}: case id {cid!r} appears twice")
        seen.add(cid)
        folder = path / "cases" / cid
        case_json: dict = {}
        cprob: list[str] = []
        if (folder / "case.json").is_file():
            try:
                cj = _read_json(folder / "case.json")
                case_json = cj if isinstance(cj, dict) else {}
            except (OSError, ValueError) as exc:
                cprob.append(f"cannot read {folder / 'case.json'}: {exc}")
        name = entry.get("name") or case_json.get("name") or cid
        labels = entry.get("labels") or case_json.get("labels") or {}
        inputs = entry.get("inputs") or case_json.get("inputs") or {}
        info = CaseInfo(id=cid, name=str(name), labels=dict(labels) if isinstance(labels, dict) else {},
                        inputs=dict(inputs) if isinstance(inputs, dict) else {}, folder=folder,
                        status="incomplete", case_json=case_json, problems=cprob)
        if (folder / "error.json").is_file():
            info.status = "failed"
            try:
                err = _read_json(folder / "error.json")
                info.error = err if isinstance(err, dict) else {"type": "?", "message": str(err)}
            except (OSError, ValueError) as exc:
                info.error = {"type": "?", "message": f"(error.json unreadable: {exc})"}
        elif "finished" in case_json and (folder / "result.npz").is_file() and (folder / "kpis.json").is_file():
            info.status = "finished"
            try:
                k = _read_json(folder / "kpis.json")
                if not isinstance(k, dict):
                    raise ValueError("not a JSON object")
                info.kpis = {str(n): v for n, v in k.items() if _is_number(v)}
            except (OSError, ValueError) as exc:
                info.problems.append(f"cannot read {folder / 'kpis.json'}: {exc}")
        cases.append(info)

    toml_path = path / "study.toml"
    study_toml = None
    if toml_path.is_file():
        try:
            study_toml = toml_path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            problems.append(f"cannot read {toml_path}: {exc}")

    kpi_csv = None
    if (path / "kpis.csv").is_file():
        try:
            kpi_csv = _read_csv(path / "kpis.csv")
        except (OSError, ValueError, csv.Error, UnicodeDecodeError) as exc:
            problems.append(f"cannot read {path / 'kpis.csv'}: {exc}")

    gains_md = gains_csv = None
    gdir = path / "gains"
    if (gdir / "gains.md").is_file():
        try:
            gains_md = (gdir / "gains.md").read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            problems.append(f"cannot read {gdir / 'gains.md'}: {exc}")
    if gains_md is None and (gdir / "gains.csv").is_file():
        try:
            gains_csv = _read_csv(gdir / "gains.csv")
        except (OSError, ValueError, csv.Error, UnicodeDecodeError) as exc:
            problems.append(f"cannot read {gdir / 'gains.csv'}: {exc}")

    return StudyData(path=path, study=study, study_toml=study_toml, cases=cases, kpi_csv=kpi_csv,
                     gains_md=gains_md, gains_csv=gains_csv, problems=problems)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))
