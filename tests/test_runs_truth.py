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


# -- the report: user text in report.md, result files too large to read --------------------------


def _study_dir(root: Path, *, name: str = "s", description: str = "", case_names=("a", "b"),
               controllers=("PID", "MPC")) -> Path:
    """A study directory with finished cases of small results, written by hand (no simulation)."""
    root.mkdir(parents=True)
    cases = []
    for k, (cname, ctrl) in enumerate(zip(case_names, controllers)):
        cid = f"c{k:011d}"
        labels = {"scenario": "fpso", "sea_state": "storm", "controller": ctrl, "condition": "intact", "seed": 1}
        entry = {"id": cid, "name": cname, "labels": labels, "inputs": {"sea_state": "storm", "seed": 1}}
        cases.append(entry)
        d = root / "cases" / cid
        d.mkdir(parents=True)
        t = np.arange(0.0, 120.0)
        Result(time=t, data=np.column_stack([np.sin(t / 9), np.cos(t / 7), 0.01 * t]), channels=("x", "y", "psi"),
               units=("m", "m", "rad"), meta={}).save(d / "result.npz")
        (d / "kpis.json").write_text(json.dumps({"offset_max": 1.0 + k, "duration": 120.0}))
        (d / "case.json").write_text(json.dumps({**entry, "started": "2024-01-01T00:00:00",
                                                 "finished": "2024-01-01T00:01:00", "wall_time": 1.0}))
    (root / "study.json").write_text(json.dumps({"name": name, "description": description, "cases": cases}))
    return root


def test_markdown_report_escapes_user_text(tmp_path):
    from tapm_opt.report import write_report

    d = _study_dir(tmp_path / "s", name="<script>alert(1)</script>", description="see <img src=x onerror=alert(2)>",
                   case_names=("<img src=x onerror=alert(3)> | col\nnext", "B & <b>C</b>"),
                   controllers=("PID<script>", "MPC"))
    html_path, md_path = write_report(d)
    md = md_path.read_text()
    for raw in ("<script", "<img", "<b>"):
        assert raw not in md, raw
    assert "# Study report: &lt;script&gt;alert(1)&lt;/script&gt;" in md
    assert "see &lt;img src=x onerror=alert(2)&gt;" in md and "B &amp; &lt;b&gt;C&lt;/b&gt;" in md
    # the case list keeps its columns: the pipe and the line break of a name do not split the row
    header = next(ln for ln in md.splitlines() if ln.startswith("| id | name |"))
    row = next(ln for ln in md.splitlines() if ln.startswith("| `c00000000000` |"))
    cells = lambda ln: len(ln.replace("\\|", "").split("|"))  # noqa: E731
    assert cells(row) == cells(header) and "\\| col next" in row
    assert "<script" not in html_path.read_text()   # the HTML report escapes it too


def _inflating_result(path: Path, nbytes: int) -> None:
    """A result.npz of zeros: small on disk, ``nbytes`` once decompressed."""
    n = nbytes // 8 // 3
    np.savez_compressed(path, time=np.zeros(n), data=np.zeros((n, 3)), channels=np.array(["x", "y", "psi"]),
                        units=np.array(["m", "m", "rad"]), meta=np.array(json.dumps({"format": "tapm_opt.result/1"})))


def test_result_load_refuses_arrays_beyond_the_limit_before_decompressing(tmp_path, monkeypatch):
    from tapm_opt.results import ResultError

    f = tmp_path / "result.npz"
    _inflating_result(f, 48 * 2**20)
    assert f.stat().st_size < 2**20
    inflated = []
    import numpy.lib.format as npy

    real = npy.read_array
    monkeypatch.setattr(npy, "read_array", lambda *a, **k: inflated.append(1) or real(*a, **k))
    with pytest.raises(ResultError) as ei:
        Result.load(f, max_bytes=32 * 2**20)      # time: 16 MiB, data: 48 MiB
    msg = str(ei.value)
    assert str(f) in msg and "array 'data'" in msg and "48 MiB" in msg and "limit of 32 MiB" in msg, msg
    assert not inflated                                    # nothing was decompressed
    assert len(Result.load(f, max_bytes=128 * 2**20)) == 48 * 2**20 // 24   # within the limit: read


def test_report_names_a_result_too_large_and_draws_the_others(tmp_path, monkeypatch):
    import tapm_opt.report.data as data_mod
    from tapm_opt.report import write_report

    monkeypatch.setattr(data_mod, "MAX_RESULT_BYTES", 32 * 2**20)
    d = _study_dir(tmp_path / "s")
    bomb = d / "cases" / "c00000000000" / "result.npz"
    _inflating_result(bomb, 64 * 2**20)              # time: 21 MiB, data: 64 MiB
    _, md_path = write_report(d)
    md = md_path.read_text()
    problems = md.split("Problems met while writing this report", 1)[1]
    assert f"case c00000000000: {bomb}: array 'data'" in problems and "limit of 32 MiB" in problems, problems
    assert md.count("Result not readable") == 1      # the other case is read and drawn
    assert "case c00000000001: motion figure not drawn" in problems   # read: only its figure lacks a scenario


# -- a scheduler address that is not a Dask scheduler -------------------------------------------


class _Peer:
    """A TCP service on 127.0.0.1 that is not a Dask scheduler: ``http`` answers whatever it gets
    with an HTTP error, ``silent`` accepts connections and says nothing."""

    def __init__(self, kind: str):
        import socket
        import threading

        self.kind, self.conns = kind, []
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:   # closed
                return
            self.conns.append(conn)
            if self.kind == "http":
                try:
                    conn.recv(65536)
                    conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\nConnection: close\r\n\r\n")
                finally:
                    conn.close()

    def close(self) -> None:
        self.sock.close()
        for c in self.conns:
            c.close()


@pytest.fixture(params=["http", "silent"])
def peer(request):
    p = _Peer(request.param)
    yield p
    p.close()


def _bounded(fn, limit: float = 60.0):
    """Run ``fn`` in a thread; (finished, exception). A call that hangs is reported, not waited for."""
    import threading

    got: dict = {}

    def target():
        try:
            got["value"] = fn()
        except BaseException as exc:  # noqa: BLE001
            got["exc"] = exc

    th = threading.Thread(target=target, daemon=True)
    th.start()
    th.join(limit)
    return not th.is_alive(), got.get("exc")


def test_a_service_that_is_not_a_scheduler_is_named(peer, monkeypatch):
    pytest.importorskip("dask.distributed", reason="dask[distributed] is not installed (extra 'dask')")
    from tapm_opt.studies import executors
    from tapm_opt.studies.store import StudyRunError

    monkeypatch.setattr(executors, "SCHEDULER_TIMEOUT", 1.0, raising=False)
    finished, exc = _bounded(lambda: executors.dask_client(peer.address))
    assert finished, f"connecting to a {peer.kind} service did not end"
    assert isinstance(exc, StudyRunError), repr(exc)
    msg = str(exc)
    assert peer.address in msg and "out of memory" not in msg
    if peer.kind == "http":
        assert "does not speak Dask's protocol" in msg and "impossible size" in msg, msg
    else:
        assert "accepted the connection but sent nothing within 1 s" in msg, msg


def test_study_run_at_an_http_server_exits_2_naming_the_address(capsys, tmp_path):
    pytest.importorskip("dask.distributed", reason="dask[distributed] is not installed (extra 'dask')")
    p = _Peer("http")
    try:
        code, _, err = run(capsys, "study", "run", str(TINY), "--out", str(tmp_path / "run"), "--no-progress",
                           "--scheduler", p.address)
    finally:
        p.close()
    assert code == 2
    assert f"error: Dask scheduler {p.address!r}: the service there does not speak Dask's protocol" in err, err
    assert "out of memory" not in err and "FEM" not in err
    assert not (tmp_path / "run").exists()


# -- study size: limits stated up front, the count said, the scenario stored once ----------------


def _study_file(tmp_path: Path, *, seeds, scenario: str = "fpso", name: str = "big") -> Path:
    f = tmp_path / f"{name}.toml"
    f.write_text(f'[study]\nname = "{name}"\nscenario = "{scenario}"\nduration = 60.0\nsegments = 6\n'
                 f"seeds = {list(seeds)}\n\n[[sea_states]]\nid = \"storm\"\n\n"
                 '[[controllers]]\nname = "PID"\ntype = "pid"\n\n[[controllers]]\nname = "MPC"\ntype = "lmpc"\n')
    return f


def test_too_many_seeds_are_refused_when_the_file_is_read(tmp_path):
    from tapm_opt.studies.study import StudyError, load_study

    f = _study_file(tmp_path, seeds=range(200_000))
    finished, exc = _bounded(lambda: load_study(f))
    assert finished, "reading a study of 200 000 seeds did not end"
    assert isinstance(exc, StudyError), repr(exc)
    assert "study.seeds: has 200000 seeds; a study holds at most 10000 cases" in str(exc), str(exc)


def test_case_count_limit_names_the_count_and_what_makes_it(tmp_path, monkeypatch):
    from tapm_opt.studies import spec
    from tapm_opt.studies.study import StudyError, load_study

    monkeypatch.setattr(spec, "MAX_CASES", 6, raising=False)
    with pytest.raises(StudyError) as ei:
        load_study(_study_file(tmp_path, seeds=[1, 2, 3, 4]))
    assert ("cases: the study has 8 cases (1 sea state x 2 controllers x 1 condition x 4 seeds); at most 6 cases "
            "are allowed in one study") in str(ei.value), str(ei.value)


def test_inputs_too_large_for_every_case_to_store_are_refused(tmp_path, monkeypatch):
    from tapm_opt.studies import spec
    from tapm_opt.studies.study import StudyError, load_study

    monkeypatch.setattr(spec, "MAX_CASE_INPUT_BYTES", 4 * 2**10, raising=False)   # fpso's inputs: about 9 kB
    with pytest.raises(StudyError) as ei:
        load_study(_study_file(tmp_path, seeds=[1]))
    msg = str(ei.value)
    assert "study.scenario: case 'storm, PID, intact, seed 1': its inputs are" in msg, msg
    assert "above the 4 KiB one case may hold" in msg and "the largest part is scenario." in msg, msg


def test_study_json_holds_the_scenario_once_and_the_count_is_said_first(tmp_path, capsys):
    from tapm_opt.report.data import read_study
    from tapm_opt.studies import store
    from tapm_opt.studies.study import load_study, run_study

    st = load_study(TINY)
    out = tmp_path / "run"
    run_study(st, out, workers=0, progress=True)
    err = capsys.readouterr().err
    assert err.startswith(f"study tiny: 2 cases, 2 to run -> {out}\n"), err[:300]

    sj = json.loads((out / "study.json").read_text())
    assert sj["n_cases"] == 2 and len(sj["scenarios"]) == 1
    key, scenario = next(iter(sj["scenarios"].items()))
    assert scenario == st.cases[0].inputs["scenario"] and scenario["meta"]["name"] == "fpso"
    assert (out / "study.json").read_text().count('"line_types"') == 1    # not once per case
    for c, e in zip(st.cases, sj["cases"]):
        assert e["scenario"] == key and "scenario" not in e["inputs"] and e["labels"] == c.labels
        cj = json.loads((out / "cases" / c.id / "case.json").read_text())   # the case folder: whole inputs
        assert cj["inputs"] == c.inputs and cj["inputs"]["scenario"] == scenario and cj["labels"] == c.labels
    # every reader gets whole inputs back
    assert [r.inputs for r in store.load_study_results(out)] == [c.inputs for c in st.cases]
    assert [c.inputs for c in read_study(out).cases] == [c.inputs for c in st.cases]
    # resuming says so, and runs nothing
    s = run_study(st, out, workers=0, progress=True)
    assert capsys.readouterr().err.startswith(f"study tiny: 2 cases, 2 already finished, 0 to run -> {out}\n")
    assert sorted(s.skipped) == sorted(c.id for c in st.cases)


def test_cases_not_run_yet_get_their_scenario_from_study_json(tmp_path):
    from tapm_opt.report.data import read_study
    from tapm_opt.studies import store
    from tapm_opt.studies.study import load_study

    st = load_study(TINY)
    out = tmp_path / "run"
    out.mkdir()
    store.write_json(out / "study.json", store.study_json(st.name, st.description, None, st.cases, "0"))
    recs = store.load_study_results(out)
    assert [r.status for r in recs] == ["missing", "missing"]
    assert [r.inputs for r in recs] == [c.inputs for c in st.cases]
    assert [c.inputs for c in read_study(out).cases] == [c.inputs for c in st.cases]
    sj = json.loads((out / "study.json").read_text())
    sj["cases"][1]["scenario"] = "sha256-0000000000000000"
    (out / "study.json").write_text(json.dumps(sj))
    from tapm_opt.report import ReportError

    with pytest.raises(ReportError, match=r"cases\[1\] .* references scenario 'sha256-0000000000000000'"):
        read_study(out)
