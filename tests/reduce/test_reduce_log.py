"""The JSON-lines probe log: content, flushing, resuming without re-probing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import (
    Outcome,
    ProbeLog,
    ProbeObservation,
    ReductionInterrupted,
    events,
    reduce,
)

from .conftest import SetOracle, line_trace, names

CULPRITS = frozenset({"m0002", "m0009", "m0010"})


def read_lines(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_every_probe_and_decision_is_a_json_line(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    oracle = SetOracle(CULPRITS, rate=0.8, trace=line_trace(12.0))
    result = reduce(names(12), oracle, log=path, deflake=2)
    records = read_lines(path)
    events = [record["event"] for record in records]
    assert events[0] == "start" and events[-1] == "end"
    assert {"round", "probe", "accept", "reject", "step", "rate-check", "failure-rate"} <= set(events)
    probes = [record for record in records if record["event"] == "probe"]
    fresh = [record for record in probes if record["purpose"] == "failure-rate"]
    assert len(probes) == result.probes + len(fresh) == len(oracle.calls) == result.simulations
    for record in probes:
        assert set(record) >= {"candidate", "attempt", "seed", "outcome", "signature", "sim_time", "wall_time"}
        assert record["seed"] == record["attempt"]
    assert records[-1]["minimal"] == list(result.minimal)
    assert records[-1]["failure_rate"] == list(result.failure_rate)


def test_log_is_flushed_as_it_happens(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    seen: list[int] = []

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        seen.append(len(path.read_text().splitlines()) if path.exists() else 0)
        return SetOracle(CULPRITS)(candidate, attempt)

    reduce(names(12), probe, log=path, deflake=0)
    assert seen == sorted(seen) and seen[-1] > seen[0] > 0


def test_signatures_and_seeds_become_json(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        fails = "m0001" in candidate
        signature = {"where": np.array([1.5, 2.0]), "count": np.int64(3), "names": {"a", "b"}, "nan": float("nan")}
        return ProbeObservation(Outcome.FAIL if fails else Outcome.PASS, signature=signature, seed=np.int64(7))

    reduce(names(3), probe, log=path, deflake=0)
    probe_line = next(record for record in read_lines(path) if record["event"] == "probe")
    assert probe_line["signature"] == {"where": [1.5, 2.0], "count": 3, "names": ["a", "b"], "nan": "nan"}
    assert probe_line["seed"] == 7


def test_resume_does_not_reprobe_decided_candidates(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    elements = names(40)
    first_oracle = SetOracle(CULPRITS, rate=0.7, salt=5)
    partial = reduce(elements, first_oracle, log=path, deflake=2, max_probes=25, failure_rate_runs=0)
    assert partial.incomplete_reason == "budget: max_probes"
    decided = set(ProbeLog.load(path).decisions())
    assert decided

    resumed_oracle = SetOracle(CULPRITS, rate=0.7, salt=5)
    resumed = reduce(elements, resumed_oracle, log=str(path), deflake=2, failure_rate_runs=0)
    assert not decided & {frozenset(candidate) for candidate, _ in resumed_oracle.calls}
    done_before = set(first_oracle.calls)
    assert not done_before & set(resumed_oracle.calls), "no (candidate, attempt) simulated twice"

    fresh = reduce(elements, SetOracle(CULPRITS, rate=0.7, salt=5), deflake=2, failure_rate_runs=0)
    assert resumed.minimal == fresh.minimal
    assert resumed.probes == fresh.probes, "a resumed reduction reports the whole history"
    assert resumed.resumed_probes == partial.probes == 25
    assert resumed.simulations + partial.simulations == fresh.simulations
    assert resumed.cache_hits > 0
    starts = [record for record in read_lines(path) if record["event"] == "start"]
    assert [record["resumed"] for record in starts] == [False, True]


def test_resume_after_an_interrupt(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    calls = 0

    def interrupted(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        nonlocal calls
        calls += 1
        if calls == 9:
            raise KeyboardInterrupt
        return SetOracle(CULPRITS)(candidate, attempt)

    with pytest.raises(ReductionInterrupted):
        reduce(names(30), interrupted, log=ProbeLog(path), deflake=0)
    oracle = SetOracle(CULPRITS)
    result = reduce(names(30), oracle, log=ProbeLog.load(path), deflake=0)
    assert set(result.minimal) == CULPRITS
    assert len(oracle.calls) + 8 == reduce(names(30), SetOracle(CULPRITS), deflake=0).simulations


def test_a_log_of_another_world_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    reduce(names(5), SetOracle(frozenset({"m0001"})), log=path, deflake=0)
    with pytest.raises(ReductionError, match="different world"):
        reduce(names(6), SetOracle(frozenset({"m0001"})), log=path, deflake=0)
    fresh = ProbeLog(path, resume=False)
    assert fresh.records == [] and path.read_text() == ""


def test_a_line_cut_short_by_a_crash_is_cut_off_and_said(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    reduce(names(8), SetOracle(frozenset({"m0001"})), log=path, deflake=0)
    text = path.read_text()
    path.write_text(text + '{"event": "probe", "cand')
    log = ProbeLog.load(path)
    assert len(log.records) == len(text.splitlines())
    assert path.read_text() == text, "the fragment is cut off, not appended to"
    assert "last line was incomplete (24 bytes" in log.notes[0]
    log.write(events.Session(pid=1, time="now"))
    log.close()
    assert ProbeLog.load(path).events[-1] == events.Session(pid=1, time="now") and ProbeLog.load(path).notes == []
    again = reduce(names(8), SetOracle(frozenset({"m0001"})), log=path, deflake=0)
    assert again.notes == () and again.probes > 0


def test_a_damaged_line_inside_the_log_is_ignored_and_said(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    path.write_text('{"event": "start"}\nnot json\n[1, 2]\n{"event": "step", "candidate": ["a"]}\n')
    log = ProbeLog.load(path)
    assert log.events == [events.Start(), events.Step(candidate=("a",))]
    expected = ("runs.jsonl: line(s) 2, 3 are not records (damaged; line 2: not a JSON object (or nested too deep)) "
                "and were ignored; the candidates they decided are decided again")
    assert log.notes == [expected]


def test_a_file_that_is_not_a_log_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    path.write_text("name: a world\nmodels: []\n")
    with pytest.raises(ReductionError, match=":1: not a probe-log record, so this file is not a pytest-ddenv run"):
        ProbeLog.load(path)
    assert path.read_text() == "name: a world\nmodels: []\n", "left alone"
    with pytest.raises(ReductionError, match="no probe log"):
        ProbeLog.load(tmp_path / "missing.jsonl")


def test_every_line_is_fsynced(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import os

    synced: list[int] = []
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(fd), real_fsync(fd))[1])
    log = ProbeLog(tmp_path / "runs.jsonl")
    for index in range(3):
        log.write(events.Probe(candidate=("a",), attempt=index, outcome="pass"))
    log.close()
    assert len(synced) >= 3


def test_a_write_that_fails_leaves_complete_lines_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A full disk in the middle of a line: the half line is removed and the error says what to do."""
    import errno
    import os

    path = tmp_path / "runs.jsonl"
    log = ProbeLog(path)
    log.write(events.Start())
    written = path.read_text()
    real_write = os.write

    def half_then_full(fd: int, data: bytes) -> int:
        if len(data) > 10:
            real_write(fd, bytes(data[:10]))
            return 10
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "write", half_then_full)
    with pytest.raises(ReductionError, match=r"cannot write .*runs.jsonl: No space left on device \(ENOSPC\)\. "
                                             r"Every record written before is intact.*resumes from the log"):
        log.write(events.Probe(candidate=("a",), attempt=0, outcome="fail"))
    monkeypatch.undo()
    log.close()
    assert path.read_text() == written
    assert [record["event"] for record in ProbeLog.load(path).records] == ["start"]


def test_errored_rejections_are_not_verdicts_and_are_retried_on_resume(tmp_path: Path) -> None:
    """The smaller failing world {m0001} is never seen because its probes always error (a worker killed):
    the reduction must not claim 1-minimality, must not log a "reject" verdict for it, tries it once more
    at the end, and a resumed reduction tries it again and finds it."""
    path = tmp_path / "runs.jsonl"
    culprit = frozenset({"m0001"})

    def erroring(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if frozenset(candidate) == culprit:
            return ProbeObservation(Outcome.ERROR, detail="WorkerError: the worker was killed by SIGKILL")
        return SetOracle(culprit)(candidate, attempt)

    first = reduce(names(4), erroring, log=path, deflake=0, failure_rate_runs=0, priority="sequential")
    assert first.minimal == ("m0000", "m0001")
    assert not first.one_minimal and first.incomplete_reason == "not verified: 1 candidate errored"
    assert first.errored == 1 and first.errors == 2, "tried once more at the end"
    assert any(note.startswith("not verified: 1 single removal") for note in first.notes)
    records = read_lines(path)
    assert [r["event"] for r in records if frozenset(r.get("candidate", ())) == culprit and r["event"] != "probe"] \
        == ["errored", "errored"]
    assert culprit not in ProbeLog.load(path).decisions()

    oracle = SetOracle(culprit)
    resumed = reduce(names(4), oracle, log=path, deflake=0, failure_rate_runs=0, priority="sequential")
    assert resumed.one_minimal and resumed.minimal == ("m0001",) and resumed.incomplete_reason is None
    assert oracle.calls == [(("m0001",), 0), ((), 0)], "only the errored candidate and the new one run"


def test_a_rejection_is_errored_only_when_the_errors_made_it(tmp_path: Path) -> None:
    """deflake=1 (two runs): ERROR then PASS is no verdict (one PASS alone would ask for another run);
    PASS then PASS is a verdict."""
    path = tmp_path / "runs.jsonl"

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if candidate == ("m0000",) and attempt == 0:
            return ProbeObservation(Outcome.ERROR, detail="worker killed")
        return SetOracle(frozenset({"m0000", "m0001"}))(candidate, attempt)

    reduce(names(2), probe, log=path, deflake=1, failure_rate_runs=0, priority="sequential")
    verdicts = {tuple(r["candidate"]): r["event"] for r in read_lines(path) if r["event"] in ("reject", "errored")}
    assert verdicts == {("m0000",): "errored", ("m0001",): "reject"}
