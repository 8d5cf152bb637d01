"""The scenario field reference, rendered from the schema metadata.

``docs/scenarios.md`` embeds :func:`field_reference_markdown` between the markers
:data:`BEGIN_MARKER` and :data:`END_MARKER`; a test checks that the two agree, so the document
follows the code. Regenerate it with::

    python -m tapm_opt.config.reference docs/scenarios.md
"""

from __future__ import annotations

import dataclasses
import math
import sys
import types
import typing
from pathlib import Path
from typing import Any, Literal, get_args, get_origin, get_type_hints

from . import schema
from .loader import file_key

__all__ = ["BEGIN_MARKER", "END_MARKER", "SECTIONS", "field_reference_markdown", "update_document"]

BEGIN_MARKER = "<!-- BEGIN FIELD REFERENCE -->"
END_MARKER = "<!-- END FIELD REFERENCE -->"

def _sections() -> tuple[tuple[str, str, type], ...]:
    """(file key, how it appears in TOML, dataclass) of every section of :class:`schema.Scenario`,
    and of the tables within them (``[vessel.wave_motion]``, ``[[lines.sections]]``)."""
    out = []

    def walk(cls: type, prefix: str) -> None:
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            tp = hints[f.name]
            args = [a for a in typing.get_args(tp) if a is not type(None)]
            key = f"{prefix}{f.name}"
            if typing.get_origin(tp) is tuple and args and dataclasses.is_dataclass(args[0]):
                out.append((key, f"[[{key}]]", args[0]))
                walk(args[0], f"{key}.")
            elif dataclasses.is_dataclass(args[0] if args else tp):
                sub = args[0] if args else tp
                out.append((key, f"[{key}]", sub))
                walk(sub, f"{key}.")

    walk(schema.Scenario, "")
    return tuple(out)


#: Section headings of the reference, derived from the Scenario dataclass.
SECTIONS: tuple[tuple[str, str, type], ...] = _sections()

_HEADER = ("file key", "type", "unit", "default", "allowed", "description")


def _cell(text: str) -> str:
    """Escape a table cell (pipes would split the cell; newlines end the row)."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _unwrap_optional(tp: Any) -> tuple[Any, bool]:
    if get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in get_args(tp) if a is not type(None)]
        if len(args) == 1:
            return args[0], True
    return tp, False


def _shape_text(shape: tuple[int, ...] | None) -> str:
    if not shape:
        return ""
    return " × ".join("n" if s == -1 else str(s) for s in shape)


def _type_text(tp: Any, meta: Any) -> str:
    tp, optional = _unwrap_optional(tp)
    origin = get_origin(tp)
    if dataclasses.is_dataclass(tp):
        out = "table"
    elif origin is tuple and get_args(tp) and dataclasses.is_dataclass(get_args(tp)[0]):
        out = "array of tables"
    elif origin is Literal:
        out = " or ".join(f"`{a!r}`".replace("'", '"') for a in get_args(tp))
    elif tp is str:
        out = "text or integer" if meta.get("id_like") else "text"
    elif tp is bool:
        out = "true/false"
    elif tp is int:
        out = "integer"
    elif tp is float:
        out = "number"
    elif origin is tuple:
        inner = get_args(tp)[0]
        if inner is str:
            out = "list of text"
        else:
            shape = _shape_text(meta.get("shape"))
            kind = "matrix" if get_origin(inner) is tuple else "list of numbers"
            out = f"{kind} ({shape})" if shape else kind
    else:  # pragma: no cover - a schema type this renderer does not know yet
        raise TypeError(f"cannot describe schema type {tp!r}")
    return f"{out}, optional" if optional else out


def _value_text(v: Any) -> str:
    if isinstance(v, tuple):
        return "[" + ", ".join(_value_text(x) for x in v) + "]"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:g}"
    if isinstance(v, str):
        return f'"{v}"'
    return str(v)


def _to_file_units(v: Any, unit: str) -> Any:
    if unit not in ("deg", "deg/s"):
        return v
    if isinstance(v, tuple):
        return tuple(_to_file_units(x, unit) for x in v)
    return math.degrees(v) if isinstance(v, (int, float)) else v


def _default_text(f: dataclasses.Field) -> str:
    if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
        return "required"
    default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
    if default is None:
        return "absent"
    if dataclasses.is_dataclass(default):
        return "all defaults"
    return f"`{_value_text(_to_file_units(default, f.metadata.get('unit', '')))}`"


def _row(cells: tuple[str, ...] | list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def _table(cls: type) -> list[str]:
    hints = get_type_hints(cls)
    lines = [_row(_HEADER), _row(["---"] * len(_HEADER))]
    for f in dataclasses.fields(cls):
        meta = f.metadata
        check = meta.get("check")
        allowed = (check.__doc__ or "").strip() if check is not None else ""
        lines.append(_row([
            f"`{file_key(f)}`",
            _cell(_type_text(hints[f.name], meta)),
            _cell(meta.get("unit", "")),
            _cell(_default_text(f)),
            _cell(allowed),
            _cell(meta.get("doc", "")),
        ]))
    return lines


def field_reference_markdown() -> str:
    """Markdown reference of every scenario field, one table per section.

    Rendered from the dataclass metadata of :mod:`tapm_opt.config.schema` (``doc``, ``unit``,
    ``check``, ``shape``, defaults) and the loader's file keys, so it cannot drift from the code.

    Returns
    -------
    str
        Markdown text without leading or trailing blank lines.
    """
    out = ["### Sections", ""]
    out += _table(schema.Scenario)
    for key, toml_name, cls in SECTIONS:
        doc = " ".join((cls.__doc__ or "").split())
        out += ["", f"### `{toml_name}`", "", f"{doc}", ""]
        out += _table(cls)
    return "\n".join(out)


def update_document(path: str | Path) -> bool:
    """Replace the text between the reference markers in ``path`` with the current reference.

    Returns
    -------
    bool
        True if the file changed.

    Raises
    ------
    ValueError
        If the file lacks either marker.
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    start, end = text.find(BEGIN_MARKER), text.find(END_MARKER)
    if start < 0 or end < start:
        raise ValueError(f"{path} must contain {BEGIN_MARKER} followed by {END_MARKER}")
    new = text[: start + len(BEGIN_MARKER)] + "\n\n" + field_reference_markdown() + "\n\n" + text[end:]
    if new != text:
        path.write_text(new, encoding="utf-8")
    return new != text


if __name__ == "__main__":  # pragma: no cover - maintenance helper
    for p in sys.argv[1:] or ["docs/scenarios.md"]:
        print(f"{p}: {'updated' if update_document(p) else 'up to date'}")
