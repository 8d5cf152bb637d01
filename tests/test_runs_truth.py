"""Every run says what happened: a service that is not a Dask scheduler, study size limits, a
result file too large to read, user text in the Markdown report, a full disk."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest

import tapm_opt._io as io_mod
from tapm_opt.cli import main
from tapm_opt.errors import TapmError
from tapm_opt.results import Result

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "studies" / "tiny.toml"


def run(capsys, *args: str):
    code = main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


def _small_result(n: int = 50) -> Result:
    t = np.arange(n, dtype=float)
    return Result(time=t, data=np.column_stack([np.sin(t), np.cos(t)]), channels=("x", "y"), units=("m", "m"),
                  meta={"scenario": "fpso"})


# -- a full disk: the error names the file being written -----------------------------------------


@pytest.fixture
def full_disk(monkeypatch):
    """Every atomic write fails as on a full disk (the data cannot be flushed to it)."""
    def no_space(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(io_mod.os, "fsync", no_space)


def test_full_disk_names_the_file_and_keeps_the_old_one(tmp_path, full_disk):
    target = tmp_path / "out" / "kpis.json"
    target.parent.mkdir()
    target.write_text("old")
    with pytest.raises(TapmError) as ei:
        io_mod.atomic_write_text(target, "new")
    exc = ei.value
    assert str(target) in str(exc) and "No space left on device" in str(exc) and "disk is full" in str(exc)
    assert isinstance(exc, OSError) and exc.errno == errno.ENOSPC and exc.filename == str(target)
    assert target.read_text() == "old"
    assert sorted(p.name for p in target.parent.iterdir()) == ["kpis.json"]   # no temporary file left


def test_full_disk_saving_a_result_names_the_npz(tmp_path, full_disk):
    with pytest.raises(TapmError, match=r"cannot write .*result\.npz: No space left on device"):
        _small_result().save(tmp_path / "case" / "result.npz")


def test_write_error_survives_the_trip_from_a_worker_process():
    import pickle

    exc = io_mod.write_error("/data/run/cases/abc/result.npz", OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is type(exc) and str(back) == str(exc) and back.errno == errno.ENOSPC


def test_study_run_on_a_full_disk_exits_2_naming_the_path(capsys, tmp_path, full_disk):
    out = tmp_path / "run"
    code, _, err = run(capsys, "study", "run", str(TINY), "--out", str(out), "--workers", "0", "--no-progress")
    assert code == 2
    assert "No space left on device" in err and str(out / "study.toml") in err, err
