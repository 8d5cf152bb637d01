"""Small file helpers: outputs are written atomically (never half-written). Text from input
files is printed through :func:`terminal_text` (from :mod:`tapm_opt._text`, re-exported here)."""

from __future__ import annotations

import csv
import io
import json
import os
import tempfile

from ._text import terminal_text  # noqa: F401 - re-exported for printing input text


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def publish(tmp: str | Path, path: str | Path) -> None:
    """Give a temporary file the permissions of a normally created file and move it into place."""
    os.chmod(tmp, 0o666 & ~_umask())
    os.replace(tmp, path)
from pathlib import Path
from typing import Iterable, Sequence


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    A reader (or a crash, even ``kill -9``) never sees a partly written file; the file gets the
    permissions of a normally created one.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def csv_text(header: Sequence[str], rows: Iterable[Sequence[object]], *, comments: Sequence[str] = ()) -> str:
    """CSV text with optional leading ``# comment`` lines; floats written with full precision."""
    buf = io.StringIO()
    for c in comments:
        buf.write(f"# {c}\n")
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([repr(float(v)) if isinstance(v, float) else v for v in row])
    return buf.getvalue()


def readonly(value: object, dtype: object = float):
    """A read-only numpy copy of ``value`` (callers keep their arrays; frozen objects stay frozen)."""
    import numpy as np

    arr = np.array(value, dtype=dtype)
    arr.flags.writeable = False
    return arr


def toml_key(k: str) -> str:
    """A TOML key: bare when it can be, else quoted."""
    k = str(k)
    return k if k and all(c.isascii() and (c.isalnum() or c in "_-") for c in k) else json.dumps(k)


def toml_value(v: object) -> str:
    """A TOML value for a bool, int, float, str, list/tuple or mapping (inline table).

    Floats are written so they read back to the same number: ``repr`` between 1e-4 and 1e6, the
    shortest round-trip scientific form outside it, ``nan``/``inf``/``-inf`` for the non-finite.
    Anything else raises ``TypeError``.
    """
    import math
    from collections.abc import Mapping

    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        v = float(v) + 0.0
        if v != 0.0 and not 1e-4 <= abs(v) < 1e6:
            import numpy as np

            return np.format_float_scientific(v, unique=True, trim="-")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")
