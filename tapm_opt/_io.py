"""Small file helpers: outputs are written atomically (never half-written). Text from input
files is printed through :func:`terminal_text` (from :mod:`tapm_opt._text`, re-exported here)."""

from __future__ import annotations

import csv
import errno
import io
import json
import os
import tempfile

from ._text import terminal_text  # noqa: F401 - re-exported for printing input text
from .errors import TapmError


class WriteError(TapmError, OSError):
    """An output file could not be written (a full disk, no permission, ...).

    The message names the file and the reason. What is raised is a subclass named and typed as the
    underlying error as well (``IsADirectoryError``, ``PermissionError``, ``OSError``, ...: its
    ``type`` in a case's ``error.json`` stays that name), with its ``errno`` and ``filename``, so
    ``except OSError`` (or ``PermissionError``, ...) still catches it.
    """

    def __init__(self, path: str | os.PathLike, reason: str, errno_: int | None = None):
        self.path, self.reason = str(path), str(reason)
        super().__init__(f"cannot write {self.path}: {self.reason}")
        self.errno, self.strerror, self.filename = errno_, self.reason, self.path

    def __str__(self) -> str:
        return str(self.args[0])

    def __reduce__(self):   # rebuilt from its fields when sent back from a worker process
        base = next(b for b in type(self).__mro__ if b is not WriteError and issubclass(b, OSError)
                    and not issubclass(b, WriteError))
        return (_rebuild_write_error, (base.__name__, self.path, self.reason, self.errno))


_WRITE_ERRORS: dict[type, type] = {}


def _write_error_class(base: type) -> type:
    """The :class:`WriteError` subclass that is also ``base`` (an ``OSError`` class) and has its name."""
    cls = _WRITE_ERRORS.get(base)
    if cls is None:
        cls = type(base.__name__, (WriteError, base), {"__module__": __name__, "__doc__": WriteError.__doc__})
        _WRITE_ERRORS[base] = cls
    return cls


def _rebuild_write_error(base_name: str, path: str, reason: str, errno_: int | None) -> WriteError:
    import builtins

    base = getattr(builtins, base_name, OSError)
    base = base if isinstance(base, type) and issubclass(base, OSError) else OSError
    return _write_error_class(base)(path, reason, errno_)


def write_error(path: str | os.PathLike, exc: OSError) -> WriteError:
    """The :class:`WriteError` of ``exc`` raised while writing ``path`` (of ``exc``'s own class too)."""
    if isinstance(exc, WriteError):
        return exc
    reason = exc.strerror or str(exc) or type(exc).__name__
    if exc.errno == errno.ENOSPC:
        reason += " (the disk is full: free some space, then run the same command again)"
    elif exc.errno is not None and exc.errno == getattr(errno, "EDQUOT", None):
        reason += " (over the disk quota: free some space, then run the same command again)"
    elif exc.filename is not None and str(exc.filename) != str(path) and \
            not os.path.basename(str(exc.filename)).startswith(f".{os.path.basename(str(path))}."):
        reason += f" ({exc.filename})"   # another path than the file's, nor its temporary file
    return _write_error_class(type(exc))(path, reason, exc.errno)


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

    Raises
    ------
    WriteError
        The file cannot be written (a full disk, no permission, ...): the message names ``path``
        and the reason; the old file, if any, is left as it was.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise write_error(path, exc) from exc
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        publish(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise write_error(path, exc) from exc
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
