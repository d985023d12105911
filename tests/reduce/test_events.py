"""The run log's events (`pytest_ddenv.reduce.events`): one class per kind, one writer, one reader that reports
what it cannot read instead of misreading it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import ProbeLog, events

PACKAGE = Path(events.__file__).resolve().parents[1]
RUNLOGS = Path(__file__).resolve().parents[1] / "data" / "runlogs"
SAMPLES: dict[str, Any] = {
    "Names": ("a", "b"), "tuple[Names, ...]": (("a",), ("b",)), "Count": 3, "int": -2, "tuple[Count, ...]": (1, 0),
    "OutcomeName": "other", "str": "text", "str | int": "auto", "bool": True, "float": 0.25,
    "FailsOfRuns": (2, 5), "tuple[tuple[float, ...], ...]": ((1.0, 2.0, 3.0, 4.0, 5.0),),
    "JsonObject": {"predicate": "stuck", "pose": [1.0, 2.0]}, "Any": [1, "two"],
}
"""A value of each annotation a field has."""


def full(kind: type[events.Event]) -> events.Event:
    """An event of `kind` with every field set."""
    return kind(**{field.name: SAMPLES[str(field.type).removesuffix(" | None")] for field in dataclasses.fields(kind)})


@pytest.mark.parametrize("kind", events.KINDS.values(), ids=list(events.KINDS))
def test_every_kind_reads_back_as_written_with_every_field_or_only_its_required_ones(
        kind: type[events.Event]) -> None:
    event = full(kind)
    assert events.decode(events.encode(event)) == event
    required = {field.name for field in dataclasses.fields(kind) if field.default is dataclasses.MISSING}
    line = json.loads(events.encode(event))
    bare = events.from_json({key: value for key, value in line.items() if key == "event" or key in required})
    assert isinstance(bare, kind), bare
    for name in required:  # each required field is required
        missing = events.from_json({key: value for key, value in line.items() if key != name})
        assert missing == events.Unreadable(f"a {kind.NAME!r} record without {name!r}".replace('"', "'"))


@pytest.mark.parametrize("name", ["complete", "killed"])
def test_every_line_of_a_real_log_is_an_event_that_writes_back_the_same(name: str) -> None:
    for line in (RUNLOGS / name / "runs.jsonl").read_text().splitlines():
        event = events.decode(line)
        assert isinstance(event, events.Event), (event, line)
        assert events.decode(events.encode(event)) == event


@pytest.mark.parametrize(("line", "problem"), [
    ('{"event": "note", "text": "x"}', "an unknown event 'note'"),
    ('{"candidate": ["a"]}', "no 'event' name"),
    ('{"event": "probe", "candidate": ["a"], "attempt": 0, "outcome": "fa', "not a JSON object"),  # torn
    ('{"event": "step", "candidate": "wall"}', "'candidate' of a 'step' record is not a list of model names"),
    ('{"event": "probe", "candidate": ["a"], "attempt": -1, "outcome": "fail"}', "'attempt' of a 'probe' record"),
    ('{"event": "session", "pid": 1, "time": 5}', "'time' of a 'session' record is not a string"),
    ("[" * 100 + "]" * 100, "nested too deep"),
])
def test_what_is_not_an_event_is_said_never_misread(line: str, problem: str) -> None:
    found = events.decode(line)
    assert isinstance(found, events.Unreadable) and problem in found.problem, found


def test_a_log_line_this_version_does_not_know_is_a_damaged_line_with_a_note(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    start = events.encode(events.Start(elements=("a", "b")))
    path.write_text(f'{start}\n{{"event": "verdict-v2", "candidate": ["a"]}}\n')
    log = ProbeLog.load(path)
    assert log.events == [events.Start(elements=("a", "b"))]
    assert log.notes == [("runs.jsonl: line(s) 2 are not records (damaged; line 2: an unknown event 'verdict-v2') "
                          "and were ignored; the candidates they decided are decided again")]


def test_a_log_of_a_later_schema_version_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    later = events.Problem(format=events.SCHEMA_VERSION + 1, fingerprint="f", parts={})
    path.write_text(events.encode(later) + "\n")
    with pytest.raises(ReductionError, match=rf"runs.jsonl:1: a run log of a later pytest-ddenv \(format "
                                             rf"{events.SCHEMA_VERSION + 1}; this one reads format 1\)"):
        ProbeLog.load(path)


def test_the_event_key_is_spelt_in_the_run_log_module_only() -> None:
    spelt = [path.relative_to(PACKAGE).as_posix() for path in sorted(PACKAGE.rglob("*.py"))
             if '"event"' in path.read_text(encoding="utf-8")]
    assert spelt == ["reduce/events.py"]
