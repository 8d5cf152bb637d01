"""The report's document model: blocks (headings, paragraphs, tables, figures, ...) rendered once
to Markdown and once to self-contained HTML, and the number format of the tables."""

from __future__ import annotations

import base64
import html
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

from ..studies.kpis import format_number

__all__ = ["json_section", "BEST_MARK", "Cell", "Table", "Fig", "Heading", "Para", "Pre", "Details", "RawMarkdown",
           "render_markdown", "render_html"]

#: Mark of the better value in the side-by-side KPI tables.
BEST_MARK = "✓"


@dataclass
class Cell:
    text: str
    best: bool = False
    code: bool = False


@dataclass
class Table:
    header: list[str]
    rows: list[list[Cell]]
    align: list[str] = field(default_factory=list)  # "l" or "r" per column
    css: str = ""


@dataclass
class Fig:
    name: str
    png: bytes
    caption: str


@dataclass
class Heading:
    level: int
    text: str
    anchor: str = ""


@dataclass
class Para:
    text: str  # plain text; inline markup: **bold** only
    css: str = ""


@dataclass
class Pre:
    text: str


@dataclass
class Details:
    summary: str
    text: str


@dataclass
class RawMarkdown:
    """Markdown from a file of the study (gain tables): copied into report.md, converted for HTML."""

    text: str


def _fmt(v: Any) -> str:
    """The KPI tables' number format (one definition: :func:`tapm_opt.studies.kpis.format_number`)."""
    return format_number(v)


def _fmt_text(s: str) -> str:
    """A CSV cell: numbers formatted like :func:`_fmt`, text unchanged."""
    try:
        f = float(s)
    except (TypeError, ValueError):
        return s
    if re.fullmatch(r"[+-]?\d+", s.strip()):
        return str(int(s))
    return _fmt(f)


# Markdown rendering

def _md_html(s: str) -> str:
    """``&``, ``<`` and ``>`` as character references outside code spans: text from the study
    (study, case and condition names, descriptions, error messages) shows as written and never
    becomes HTML in report.md, as report.html escapes it too; a code span shows its text as is."""
    parts = s.split("`")   # odd parts are code spans (Markdown shows them verbatim): not escaped
    if len(parts) % 2 == 0:   # an unpaired backtick is literal text: escape everything
        return html.escape(s, quote=False)
    return "`".join(p if i % 2 else html.escape(p, quote=False) for i, p in enumerate(parts))


def _md_line(s: str) -> str:
    """Text that must stay on one line (a heading, a caption): HTML escaped, line breaks as spaces."""
    return _md_html(" ".join(s.splitlines()))


def _md_escape(s: str) -> str:
    """A table cell or header: one line, pipes and backslashes escaped, HTML escaped."""
    return _md_html(s.replace("\\", "\\\\").replace("|", "\\|").replace("\r", " ").replace("\n", " "))


def _md_cell(c: Cell) -> str:
    s = _md_escape(c.text)
    if c.code and s:
        s = f"`{s}`"
    if c.best and s:
        s = f"**{s}** {BEST_MARK}"
    return s


def _md_table(t: Table) -> str:
    al = t.align or ["l"] * len(t.header)
    lines = ["| " + " | ".join(_md_escape(h) for h in t.header) + " |",
             "|" + "|".join("---:" if a == "r" else "---" for a in al) + "|"]
    for r in t.rows:
        lines.append("| " + " | ".join(_md_cell(c) for c in r) + " |")
    return "\n".join(lines)


def render_markdown(blocks: Sequence[Any], fig_dir_rel: str) -> str:
    out: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            out.append("#" * b.level + " " + _md_line(b.text))
        elif isinstance(b, Para):
            out.append(_md_html(b.text))
        elif isinstance(b, Pre):
            fence = "```"
            while fence in b.text:
                fence += "`"
            out.append(f"{fence}\n{b.text.rstrip()}\n{fence}")
        elif isinstance(b, Details):
            fence = "```"
            while fence in b.text:
                fence += "`"
            out.append(f"{_md_line(b.summary)}:\n\n{fence}\n{b.text.rstrip()}\n{fence}")
        elif isinstance(b, Table):
            out.append(_md_table(b))
        elif isinstance(b, Fig):
            alt = _md_line(b.caption).replace("[", "&#91;").replace("]", "&#93;")
            out.append(f"![{alt}]({fig_dir_rel}/{b.name}.png)\n\n*{_md_line(b.caption)}*")
        elif isinstance(b, RawMarkdown):
            out.append(_demote_md_headings(_md_html_outside_fences(b.text.strip()), 2))
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _md_html_outside_fences(text: str) -> str:
    """:func:`_md_html` on every line of Markdown text except inside fenced code blocks (shown verbatim)."""
    out, fence = [], ""
    for ln in text.splitlines():
        m = re.match(r"^\s*(`{3,}|~{3,})", ln)
        if fence:
            if m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence):
                fence = ""
            out.append(ln)
        elif m:
            fence = m.group(1)
            out.append(ln)
        else:
            out.append(_md_html(ln))
    return "\n".join(out)


def _demote_md_headings(text: str, by: int) -> str:
    return "\n".join(("#" * by + ln) if re.match(r"^#{1,6}\s", ln) else ln for ln in text.splitlines())


# HTML rendering

_CSS = """
body{font-family:-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:0 auto;max-width:1400px;
padding:1em 2em;color:#222;line-height:1.4}
h1{border-bottom:2px solid #333;padding-bottom:.2em}h2{border-bottom:1px solid #bbb;margin-top:2em}
table{border-collapse:collapse;margin:.6em 0 1.2em 0;font-size:.85em}
th,td{border:1px solid #ccc;padding:.25em .6em;vertical-align:top}th{background:#f0f0f0;text-align:left}
td.r{text-align:right;font-variant-numeric:tabular-nums}td.best{background:#e3f4e3;font-weight:bold}
.wide{overflow-x:auto;max-width:100%}
pre{background:#f7f7f7;border:1px solid #ddd;padding:.6em;overflow-x:auto;font-size:.85em}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #eee}figcaption{font-size:.85em;color:#555}
p.note{color:#555;font-size:.9em}p.error{color:#a00}code{background:#f3f3f3;padding:0 .2em}
nav ul{columns:2}
"""


def _inline_html(text: str) -> str:
    s = html.escape(text)
    s = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", s)
    s = re.sub(r"`([^`]+)`", r"<code>\1</code>", s)
    return s


def _html_table(t: Table) -> str:
    al = t.align or ["l"] * len(t.header)
    h = "".join(f"<th>{html.escape(x)}</th>" for x in t.header)
    body = []
    for r in t.rows:
        tds = []
        for a, c in zip(al, r):
            cls = " ".join(x for x in ("r" if a == "r" else "", "best" if c.best else "") if x)
            txt = html.escape(c.text)
            if c.code and txt:
                txt = f"<code>{txt}</code>"
            if c.best and txt:
                txt = f"<strong>{txt}</strong> {BEST_MARK}"
            tds.append(f'<td class="{cls}">{txt}</td>' if cls else f"<td>{txt}</td>")
        body.append("<tr>" + "".join(tds) + "</tr>")
    cls = f' class="{t.css}"' if t.css else ""
    return f'<div class="wide"><table{cls}><thead><tr>{h}</tr></thead><tbody>{"".join(body)}</tbody></table></div>'


def _md_to_html(text: str) -> str:
    """Minimal Markdown (headings, pipe tables, paragraphs, fenced code) to HTML for the gain tables."""
    out: list[str] = []
    lines = text.splitlines()
    i = 0
    para: list[str] = []

    def flush() -> None:
        if para:
            out.append(f"<p>{_inline_html(' '.join(para))}</p>")
            para.clear()

    while i < len(lines):
        ln = lines[i]
        if ln.strip().startswith("```"):
            flush()
            j = i + 1
            while j < len(lines) and not lines[j].strip().startswith("```"):
                j += 1
            out.append(f"<pre>{html.escape(chr(10).join(lines[i + 1:j]))}</pre>")
            i = j + 1
            continue
        m = re.match(r"^(#{1,6})\s+(.*)$", ln)
        if m:
            flush()
            lvl = min(len(m.group(1)) + 2, 6)
            out.append(f"<h{lvl}>{_inline_html(m.group(2))}</h{lvl}>")
            i += 1
            continue
        if ln.strip().startswith("|"):
            flush()
            rows = []
            while i < len(lines) and lines[i].strip().startswith("|"):
                rows.append(_split_md_row(lines[i]))
                i += 1
            header, body, align = rows[0], [], []
            for r in rows[1:]:
                if all(re.fullmatch(r":?-{1,}:?", c.strip()) for c in r if c.strip()) and not align:
                    align = ["r" if c.strip().endswith(":") else "l" for c in r]
                    continue
                body.append(r)
            tab = Table(header=[_unmd(h) for h in header],
                        rows=[[Cell(_unmd(c), best=_is_bold(c)) for c in r] for r in body],
                        align=align or ["l"] * len(header))
            out.append(_html_table(tab))
            continue
        if not ln.strip():
            flush()
        else:
            para.append(ln.strip())
        i += 1
    flush()
    return "\n".join(out)


def _split_md_row(line: str) -> list[str]:
    s = line.strip()
    if s.startswith("|"):
        s = s[1:]
    if s.endswith("|") and not s.endswith("\\|"):
        s = s[:-1]
    cells, cur, esc = [], [], False
    for ch in s:
        if esc:
            cur.append(ch)
            esc = False
        elif ch == "\\":
            esc = True
        elif ch == "|":
            cells.append("".join(cur).strip())
            cur = []
        else:
            cur.append(ch)
    cells.append("".join(cur).strip())
    return cells


def _is_bold(c: str) -> bool:
    return c.strip().startswith("**")


def _unmd(c: str) -> str:
    return c.replace("**", "").replace("`", "").strip()


def render_html(blocks: Sequence[Any], title: str) -> str:
    body: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            aid = f' id="{html.escape(b.anchor)}"' if b.anchor else ""
            body.append(f"<h{b.level}{aid}>{html.escape(b.text)}</h{b.level}>")
        elif isinstance(b, Para):
            cls = f' class="{b.css}"' if b.css else ""
            body.append(f"<p{cls}>{_inline_html(b.text)}</p>")
        elif isinstance(b, Pre):
            body.append(f"<pre>{html.escape(b.text)}</pre>")
        elif isinstance(b, Details):
            body.append(f"<details><summary>{html.escape(b.summary)}</summary><pre>{html.escape(b.text)}</pre></details>")
        elif isinstance(b, Table):
            body.append(_html_table(b))
        elif isinstance(b, Fig):
            data = base64.b64encode(b.png).decode("ascii")
            body.append(f'<figure id="fig-{html.escape(b.name)}"><img alt="{html.escape(b.caption)}" '
                        f'src="data:image/png;base64,{data}"><figcaption>{html.escape(b.caption)}</figcaption></figure>')
        elif isinstance(b, RawMarkdown):
            body.append(_md_to_html(b.text))
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
            + "\n".join(body) + "\n</body>\n</html>\n")


def json_section(path: Path, fmt: str, draw: Callable[[dict], tuple[list, list]], what: str,
                 problems: list[str] | None = None) -> tuple[list, list]:
    """The blocks and figures ``draw`` makes of the JSON file ``path`` of format ``fmt`` (its
    ``"format"`` field); a file that cannot be read or drawn gives one error paragraph instead (and
    a line in ``problems``), since a broken file must not stop the report. ``what`` names the
    section in those messages ("capability", "verification")."""
    import json

    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if data.get("format") != fmt:
            raise ValueError(f"format = {data.get('format')!r}, expected {fmt!r}")
        return draw(data)
    except Exception as exc:  # noqa: BLE001 - a broken file must not stop the report
        if problems is not None:
            problems.append(f"{what} section not drawn: {path.name}: {exc}")
        return [Para(f"**{what.capitalize()} not shown:** {exc}", css="error")], []
