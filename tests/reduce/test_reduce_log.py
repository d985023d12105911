"""The JSON-lines probe log: content, flushing, resuming without re-probing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import Observation, Outcome, ProbeLog, ReductionInterrupted, reduce

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
    assert {"round", "probe", "accept", "reject", "step", "failure-rate"} <= set(events)
    probes = [record for record in records if record["event"] == "probe"]
    assert len(probes) == result.probes + result.failure_rate[1] == len(oracle.calls)
    for record in probes:
        assert set(record) >= {"candidate", "attempt", "seed", "outcome", "signature", "sim_time", "wall_time"}
        assert record["seed"] == record["attempt"]
    assert records[-1]["minimal"] == list(result.minimal)
    assert records[-1]["failure_rate"] == list(result.failure_rate)


def test_log_is_flushed_as_it_happens(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    seen: list[int] = []

    def probe(candidate: tuple[str, ...], attempt: int) -> Observation:
        seen.append(len(path.read_text().splitlines()) if path.exists() else 0)
        return SetOracle(CULPRITS)(candidate, attempt)

    reduce(names(12), probe, log=path, deflake=0)
    assert seen == sorted(seen) and seen[-1] > seen[0] > 0


def test_signatures_and_seeds_become_json(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"

    def probe(candidate: tuple[str, ...], attempt: int) -> Observation:
        fails = "m0001" in candidate
        signature = {"where": np.array([1.5, 2.0]), "count": np.int64(3), "names": {"a", "b"}, "nan": float("nan")}
        return Observation(Outcome.FAIL if fails else Outcome.PASS, signature=signature, seed=np.int64(7))

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
    assert resumed.probes + partial.probes == fresh.probes
    assert resumed.cache_hits > 0
    starts = [record for record in read_lines(path) if record["event"] == "start"]
    assert [record["resumed"] for record in starts] == [False, True]


def test_resume_after_an_interrupt(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    calls = 0

    def interrupted(candidate: tuple[str, ...], attempt: int) -> Observation:
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
    assert len(oracle.calls) + 8 == reduce(names(30), SetOracle(CULPRITS), deflake=0).probes + 5


def test_a_log_of_another_world_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    reduce(names(5), SetOracle(frozenset({"m0001"})), log=path, deflake=0)
    with pytest.raises(ReductionError, match="different world"):
        reduce(names(6), SetOracle(frozenset({"m0001"})), log=path, deflake=0)
    fresh = ProbeLog(path, resume=False)
    assert fresh.records == [] and path.read_text() == ""


def test_a_line_cut_short_by_a_crash_is_ignored(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    reduce(names(8), SetOracle(frozenset({"m0001"})), log=path, deflake=0)
    text = path.read_text()
    path.write_text(text + '{"event": "probe", "cand')
    assert len(ProbeLog.load(path).records) == len(text.splitlines())
    path.write_text('{"event": "start"}\nnot json\n{"event": "end"}\n')
    with pytest.raises(ReductionError, match=":2: not a probe-log line"):
        ProbeLog.load(path)
    with pytest.raises(ReductionError, match="no probe log"):
        ProbeLog.load(tmp_path / "missing.jsonl")
