"""Labelled time series: time x channel, with units and metadata, saved without the code.

A :class:`Result` is what every simulation returns. It saves to one ``.npz`` file holding plain
arrays (``time``, ``data``, ``channels``, ``units``) and the metadata as a JSON string, readable
with numpy alone::

    z = numpy.load("run.npz"); z["data"][:, list(z["channels"]).index("x")]
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ._io import atomic_write_bytes, atomic_write_text, csv_text
from .errors import TapmError

__all__ = ["Result", "ResultError", "ResultBuilder"]

FORMAT = "tapm_opt.result/1"

#: Most bytes :meth:`Result.load` reads from one file by default, all its arrays together: the
#: largest log a run may write (``tapm_opt.config.loader.MAX_LOG_BYTES``, 1 GiB) and its time,
#: names and metadata. Larger arrays are refused before anything is decompressed.
MAX_LOAD_BYTES = 2**31


class ResultError(TapmError, ValueError):
    """A result file is missing, unreadable or inconsistent, or a channel does not exist."""


@dataclass(frozen=True, eq=False)
class Result:
    """Time series of named channels.

    Attributes
    ----------
    time : ndarray, shape (n,)
        Sample times [s].
    data : ndarray, shape (n, m)
        Channel values, column j is ``channels[j]``.
    channels : tuple of str
        Channel names (e.g. ``"x"``, ``"T_fairlead[3]"``).
    units : tuple of str
        Unit of each channel.
    meta : dict
        JSON-serialisable metadata (scenario, seed, code version, settings, diagnostics).
    """

    time: np.ndarray
    data: np.ndarray
    channels: tuple[str, ...]
    units: tuple[str, ...]
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        t = np.asarray(self.time, dtype=float)
        d = np.asarray(self.data, dtype=float)
        if d.ndim != 2 or d.shape[0] != t.shape[0] or d.shape[1] != len(self.channels) or len(self.units) != len(self.channels):
            raise ResultError(f"inconsistent result: time {t.shape}, data {d.shape}, "
                              f"{len(self.channels)} channels, {len(self.units)} units")
        if len(set(self.channels)) != len(self.channels):
            raise ResultError("channel names must be unique")
        t.setflags(write=False)
        d.setflags(write=False)
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "data", d)

    # -- access ----------------------------------------------------------------------------
    def __getitem__(self, name: str) -> np.ndarray:
        """Values of channel ``name``, shape (n,)."""
        return self.data[:, self._index(name)]

    def __contains__(self, name: object) -> bool:
        return name in self.channels

    def _index(self, name: str) -> int:
        try:
            return self.channels.index(name)
        except ValueError:
            raise ResultError(f"no channel {name!r}; channels are {', '.join(self.channels)}") from None

    def unit(self, name: str) -> str:
        """Unit of channel ``name``."""
        return self.units[self._index(name)]

    def group(self, prefix: str) -> np.ndarray:
        """All channels named ``prefix[...]`` stacked as columns, shape (n, k), in channel order."""
        idx = [i for i, c in enumerate(self.channels) if c.startswith(prefix + "[")]
        if not idx:
            raise ResultError(f"no channels '{prefix}[...]'")
        return self.data[:, idx]

    def group_names(self, prefix: str) -> list[str]:
        """The labels inside the brackets of the channels ``prefix[...]``."""
        return [c[len(prefix) + 1:-1] for c in self.channels if c.startswith(prefix + "[")]

    def __len__(self) -> int:
        return self.time.shape[0]

    # -- persistence -----------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the result to ``path`` (``.npz`` appended if missing), atomically.

        Raises
        ------
        WriteError
            The file cannot be written (a full disk, ...); the message names it.
        """
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        buf = io.BytesIO()
        np.savez_compressed(buf, time=self.time, data=self.data, channels=np.array(self.channels, dtype=str),
                            units=np.array(self.units, dtype=str),
                            meta=np.array(json.dumps({"format": FORMAT, **self.meta}, default=_json_default)))
        atomic_write_bytes(path, buf.getvalue())
        return path

    @classmethod
    def load(cls, path: str | Path, *, max_bytes: int = MAX_LOAD_BYTES) -> "Result":
        """Read a result written by :meth:`save`.

        Parameters
        ----------
        path : path
            The ``.npz`` file (``.npz`` appended if missing).
        max_bytes : int
            Most bytes the file's arrays may hold together once decompressed
            (:data:`MAX_LOAD_BYTES` by default). Each array's size is read from its ``.npy``
            header (shape and dtype) and from the zip member's size before any data is
            decompressed, so a small file that would inflate beyond it costs neither time nor
            memory.

        Raises
        ------
        ResultError
            The file is missing, unreadable or not a tapm_opt result, or its arrays would hold
            more than ``max_bytes`` (the message names the file, the array and the limit).
        """
        path = Path(path)
        if not path.exists() and path.with_name(path.name + ".npz").exists():
            path = path.with_name(path.name + ".npz")
        _check_npz_size(path, max_bytes)
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                fmt = meta.pop("format", None)
                if fmt != FORMAT:
                    raise ResultError(f"{path} is not a tapm_opt result (format {fmt!r})")
                return cls(time=z["time"], data=z["data"], channels=tuple(str(c) for c in z["channels"]),
                           units=tuple(str(u) for u in z["units"]), meta=meta)
        except (OSError, KeyError, ValueError) as exc:
            if isinstance(exc, ResultError):
                raise
            raise ResultError(f"cannot read result {path}: {exc}") from None

    def to_csv(self, path: str | Path, channels: Sequence[str] | None = None) -> Path:
        """Write time and channels (all by default) as CSV with a units comment line."""
        names = list(self.channels if channels is None else channels)
        cols = [self._index(n) for n in names]
        header = ["t", *names]
        rows = (tuple(map(float, (t, *self.data[i, cols]))) for i, t in enumerate(self.time))
        units = "units: s, " + ", ".join(self.units[c] for c in cols)
        return atomic_write_text(path, csv_text(header, rows, comments=[units]))


def _size_text(n: float) -> str:
    for unit, k in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= k:
            return f"{n / k:.3g} {unit}"
    return f"{int(n)} bytes"


def _check_npz_size(path: Path, max_bytes: int) -> None:
    """Raise :class:`ResultError` when the arrays of the ``.npz`` file ``path`` would hold more
    than ``max_bytes`` once decompressed. Reads only the zip directory and each ``.npy`` header."""
    import math
    import zipfile

    from numpy.lib import format as npy

    limit = f"the limit of {_size_text(max_bytes)} for reading one result"
    try:
        zf = zipfile.ZipFile(path)
    except FileNotFoundError:
        raise ResultError(f"cannot read result {path}: no such file") from None
    except (OSError, zipfile.BadZipFile, ValueError) as exc:
        raise ResultError(f"cannot read result {path}: {exc}") from None
    total = 0
    with zf:
        for zi in zf.infolist():
            name = zi.filename.removesuffix(".npy")
            if total + zi.file_size > max_bytes:
                raise ResultError(f"{path}: array {name!r} is {_size_text(zi.file_size)} once decompressed "
                                  f"({_size_text(zi.compress_size)} in the file), above {limit}: not read")
            try:
                with zf.open(zi) as fh:
                    version = npy.read_magic(fh)
                    reader = {(1, 0): npy.read_array_header_1_0, (2, 0): npy.read_array_header_2_0}.get(version)
                    shape, _, dtype = (reader(fh) if reader is not None
                                       else npy._read_array_header(fh, version))   # a newer .npy version
            except Exception as exc:  # noqa: BLE001 - any damage of the member: not a result we read
                raise ResultError(f"cannot read result {path}: array {name!r}: {exc}") from None
            nbytes = math.prod(int(n) for n in shape) * int(dtype.itemsize)
            total += max(nbytes, zi.file_size)
            if total > max_bytes:
                raise ResultError(f"{path}: array {name!r} of shape {tuple(shape)} and dtype {dtype} holds "
                                  f"{_size_text(nbytes)}" + ("" if total == nbytes else
                                                             f" ({_size_text(total)} with the arrays before it)")
                                  + f", above {limit}: not read")


def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON-serialisable: {type(o).__name__}")


class ResultBuilder:
    """Collects samples row by row into preallocated storage; :meth:`build` returns a Result.

    Parameters
    ----------
    channels : sequence of (name, unit)
    capacity : int
        Expected number of rows (grows if exceeded).
    """

    def __init__(self, channels: Iterable[tuple[str, str]], capacity: int = 1024):
        ch = list(channels)
        self.channels = tuple(c for c, _ in ch)
        self.units = tuple(u for _, u in ch)
        self._t = np.zeros(max(capacity, 1))
        self._d = np.zeros((max(capacity, 1), len(ch)))
        self._n = 0

    def append(self, t: float, row: np.ndarray) -> None:
        """Add one sample: time [s] and the channel values in channel order."""
        self.next_row(t)[:] = row

    def next_row(self, t: float) -> np.ndarray:
        """Add one sample at time ``t`` [s] and return its row (m,) to fill in place, in channel
        order (zeros until written; a caller that fills it piece by piece saves assembling it)."""
        if self._n == self._t.shape[0]:
            self._t = np.concatenate([self._t, np.zeros_like(self._t)])
            self._d = np.vstack([self._d, np.zeros_like(self._d)])
        self._t[self._n] = t
        self._n += 1
        return self._d[self._n - 1]

    def build(self, meta: Mapping[str, Any] | None = None) -> Result:
        return Result(time=self._t[: self._n].copy(), data=self._d[: self._n].copy(), channels=self.channels,
                      units=self.units, meta=dict(meta or {}))
