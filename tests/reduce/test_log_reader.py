"""The read-only reader of JSON-lines run logs shared by the pictures, `ddenv replay` and `ddenv show`."""

from __future__ import annotations

import json
from pathlib import Path

from pytest_ddenv.reduce import ProbeLog, events
from pytest_ddenv.reduce.log import numbered_records, parse_record, read_events


def test_a_line_is_a_record_only_when_it_holds_a_json_object() -> None:
    assert parse_record('{"event": "start"}') == {"event": "start"}
    assert parse_record('{"event": "start"}\r') == {"event": "start"}  # a file written on Windows
    for line in ("", "   ", '{"event": "pro', "[1, 2]", "42", '"text"', "null", "not json"):
        assert parse_record(line) is None, line


def test_blank_and_damaged_lines_are_skipped_and_numbered(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    probe = '{"event": "probe", "candidate": ["a"], "attempt": 0, "outcome": "fail"}'
    data = (b'{"event": "start"}\n\n[1]\n' + probe.encode() + b'\n\xff\xfe broken\n{"event": "probe"}\n'
            b'{"event": "step", "candidate": []}\n{"event": "pro')  # the last line is torn: a writer is writing it
    path.write_bytes(data)
    assert list(numbered_records(path)) == [(1, {"event": "start"}), (3, None), (4, json.loads(probe)), (5, None),
                                            (6, {"event": "probe"}), (7, {"event": "step", "candidate": []}),
                                            (8, None)]
    assert read_events(path) == [events.Start(), events.Probe(candidate=("a",), attempt=0, outcome="fail"),
                                 events.Step(candidate=())]  # a probe without its candidate is no event
    assert path.read_bytes() == data  # reading never repairs: cutting the torn line off is ProbeLog's job


def test_a_missing_or_unreadable_log_reads_as_empty(tmp_path: Path) -> None:
    assert read_events(tmp_path / "missing.jsonl") == []
    assert read_events(tmp_path) == []  # a folder


def test_the_reader_and_the_probe_log_read_the_same_events(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    with ProbeLog(path) as log:
        log.write(events.Start(elements=("a", "b")))
        log.write(events.Probe(candidate=("a",), attempt=0, outcome="fail", sim_time=float("inf")))
    with path.open("a", encoding="utf-8") as handle:
        handle.write(json.dumps({"event": "end"})[:7])
    assert read_events(path) == log.events
    assert ProbeLog(path).events == log.events  # which cuts the torn line off
    assert path.read_text(encoding="utf-8").endswith("\n")
