"""Study runs as processes: workers end with their parent (kill -9, Ctrl-C), one run per directory.

Each test starts a study run in a child process; its cases last ten simulated hours, so they are
still running whenever the test acts, and every process started here is killed at the end.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tapm_opt.cli import main
from tapm_opt.studies import store
from tapm_opt.studies.study import StudyBusyError, load_study, run_study

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "studies" / "tiny.toml"
WAIT = 180.0   # generous bound [s] on waiting for a child process to reach a state (shared machine)

# The runner stands for a run started from a terminal: Ctrl-C raises KeyboardInterrupt. A process
# started in the background by a non-interactive shell (as a CI job may be) inherits SIGINT
# ignored, and Python then leaves it ignored; so the runner sets the terminal's disposition itself.
_RUNNER = """
import signal
import sys
signal.signal(signal.SIGINT, signal.default_int_handler)
from tapm_opt.studies import executors
from tapm_opt.studies.study import load_study, run_study
executors.USE_PDEATHSIG = sys.argv[4] == "1"
run_study(load_study(sys.argv[1]), sys.argv[2], workers=int(sys.argv[3]), progress=False)
"""


@pytest.fixture
def long_study(tmp_path):
    """The tiny study with cases of 36000 s: they do not finish while a test runs."""
    f = tmp_path / "long.toml"
    f.write_text(TINY.read_text().replace("duration = 60.0", "duration = 36000.0"))
    return f


def _alive(pid: int) -> bool:
    """True while process ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except FileNotFoundError:
        return False
    except OSError:   # no /proc
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


def _children(pid: int) -> set[int]:
    """The processes whose parent is ``pid`` (empty without /proc)."""
    kids = set()
    for d in Path("/proc").glob("[0-9]*"):
        try:
            if int((d / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                kids.add(int(d.name))
        except (OSError, ValueError, IndexError):
            continue
    return kids


def _wait_for(cond, proc: subprocess.Popen, what: str) -> None:
    deadline = time.monotonic() + WAIT
    while not cond():
        if proc.poll() is not None:
            raise AssertionError(f"the run ended before {what}: {proc.stdout.read().decode()}")
        assert time.monotonic() < deadline, f"no {what} within {WAIT:.0f} s"
        time.sleep(0.05)


def _start(study: Path, out: Path, workers: int, pdeathsig: bool = True) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", _RUNNER, str(study), str(out), str(workers), str(int(pdeathsig))],
                            start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def _worker_pids(out: Path, ids: list[str]) -> dict[str, int] | None:
    """The pid of the worker running each case (from its case.json), once all have started."""
    pids = {}
    for cid in ids:
        try:
            meta = json.loads((store.case_dir(out, cid) / store.CASE_JSON).read_text())
        except (OSError, ValueError):
            return None
        pids[cid] = meta["worker"]["pid"]
    return pids


def _cleanup(proc: subprocess.Popen, pids) -> None:
    for pid in pids or ():
        if _alive(pid):
            os.kill(pid, signal.SIGKILL)
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    proc.stdout.close()


@pytest.mark.parametrize("how", ["sigkill", "sigkill-no-pdeathsig", "sigint"])
def test_workers_end_with_their_parent(long_study, tmp_path, how):
    """kill -9 of the run (with the kernel's parent-death signal, or with the polling watcher
    alone), or Ctrl-C: no worker process is left running."""
    out = tmp_path / "run"
    ids = [c.id for c in load_study(long_study).cases]
    proc = _start(long_study, out, workers=2, pdeathsig=how != "sigkill-no-pdeathsig")
    pids = None
    try:
        _wait_for(lambda: _worker_pids(out, ids) is not None, proc, "case started in each worker")
        workers = _worker_pids(out, ids)
        assert len(set(workers.values())) == 2 and proc.pid not in workers.values()
        pids = set(workers.values()) | _children(proc.pid)   # the workers and any other child process
        assert all(_alive(p) for p in workers.values())
        os.kill(proc.pid, signal.SIGINT if how == "sigint" else signal.SIGKILL)
        proc.wait(timeout=WAIT)
        if how == "sigint":
            assert proc.returncode != 0
        else:
            assert proc.returncode == -signal.SIGKILL
        deadline = time.monotonic() + WAIT
        while any(_alive(p) for p in pids) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not [p for p in pids if _alive(p)], "processes started by the run outlived it"
        # the interrupted cases are left as started: a re-run runs them again
        assert [store.case_status(store.case_dir(out, c)) for c in ids] == ["started", "started"]
    finally:
        _cleanup(proc, pids)


def test_second_run_into_the_same_directory_is_refused(long_study, tmp_path, capsys):
    out = tmp_path / "run"
    tiny = load_study(TINY)
    proc = _start(long_study, out, workers=1)
    try:
        lock = out / store.LOCK
        first = store.case_dir(out, load_study(long_study).cases[0].id) / store.CASE_JSON
        _wait_for(lambda: first.is_file(), proc, "case started")   # study.json is written by then
        assert lock.read_text().split()[0] == str(proc.pid)
        before = (out / store.STUDY_JSON).read_bytes()

        with pytest.raises(StudyBusyError) as info:
            run_study(tiny, out, workers=1, progress=False)
        assert info.value.pid == proc.pid and info.value.directory == out
        msg = str(info.value)
        assert str(out) in msg and f"pid {proc.pid}" in msg, msg

        code = main(["study", "run", str(TINY), "--out", str(out), "--no-progress"])
        err = capsys.readouterr().err
        assert code == 2 and f"pid {proc.pid}" in err and str(out) in err and "Traceback" not in err, err
        assert (out / store.STUDY_JSON).read_bytes() == before   # the refused runs wrote nothing
        assert proc.poll() is None
    finally:
        _cleanup(proc, ())
    # the kernel released the lock of the killed run: the directory can be taken again
    with store.study_lock(out):
        assert lock.read_text().split()[0] == str(os.getpid())


def test_lock_is_exclusive_within_one_process(tmp_path):
    with store.study_lock(tmp_path):
        with pytest.raises(StudyBusyError, match=f"pid {os.getpid()}"):
            with store.study_lock(tmp_path):
                pass
    with store.study_lock(tmp_path):   # released at the end of the block
        pass
