"""Text from input files made safe to print on a terminal.

A scenario's name, description, sources and ids are free text; printed as they are, a newline
would forge extra output lines and an ANSI escape sequence (``ESC [ 31 m``, ``ESC [ 2 J``) would
recolour or clear the user's terminal. :func:`terminal_text` replaces every such character with a
visible escape, so what is printed is what the file holds.
"""

from __future__ import annotations

import unicodedata

__all__ = ["terminal_text"]

_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t", "\x1b": "\\x1b", "\\": "\\\\"}


def _escape(ch: str) -> str:
    named = _NAMED.get(ch)
    if named is not None:
        return named
    code = ord(ch)
    if code <= 0xFF:
        return f"\\x{code:02x}"
    if code <= 0xFFFF:
        return f"\\u{code:04x}"
    return f"\\U{code:08x}"


def _unsafe(ch: str) -> bool:
    # Cc: C0/C1 control characters and DEL (ESC starts the ANSI sequences); Cf: format characters
    # such as the bidirectional overrides U+202A-U+202E that reorder what follows; Zl, Zp: line and
    # paragraph separators; Cs: lone surrogates (not printable as UTF-8).
    return unicodedata.category(ch) in ("Cc", "Cf", "Zl", "Zp", "Cs")


def terminal_text(text: object, *, limit: int | None = None) -> str:
    """``text`` (``str()`` of any object) with control characters replaced by visible escapes.

    Newlines, tabs, ESC and the other C0/C1 control characters, DEL, Unicode format characters
    (bidirectional overrides, zero-width characters), line and paragraph separators and lone
    surrogates become ``\\n``, ``\\t``, ``\\x1b``, ``\\u202e``, ...; a backslash is doubled only
    when the text needed escaping (so an escape in the output is never ambiguous), and plain text
    is returned unchanged. ``limit`` (characters, optional) cuts a longer result with
    ``... (N characters)``.

    >>> terminal_text("evil\\n\\x1b[31mred")
    'evil\\\\n\\\\x1b[31mred'
    """
    s = text if isinstance(text, str) else str(text)
    if any(_unsafe(ch) for ch in s):
        s = "".join(_escape(ch) if (ch == "\\" or _unsafe(ch)) else ch for ch in s)
    if limit is not None and len(s) > limit:
        s = f"{s[:max(limit, 0)]}... ({len(s)} characters)"
    return s
