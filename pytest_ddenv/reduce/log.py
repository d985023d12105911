"""The probe log: one event per line, per probe and per decision, written and flushed as it happens.

The events are the typed records of `events` (``start``, ``round``, ``probe``, ``accept`` when the candidate
reproduces f, ``reject`` when it does not, ``skip`` when a precondition refused it, ``cache-hit`` when its
verdict was already known, ``step`` when a smaller world was adopted, ``calibration``, ``failure-rate``,
``end``, and the driver's and the stages' own); `events.encode` writes each line and `events.decode` reads it
back. Candidates are element names in original order. The fields in `VOLATILE_FIELDS` hold wall-clock
measurements; everything else is identical for two reductions with the same inputs and seed.

A log is also a cache: `ProbeLog.load(path)` (or ``reduce(..., log=path)`` on an existing file) reads the
verdicts it holds, and the new reduction appends to the same file without simulating those candidates
again. Runs of a candidate that was being decided when the reduction stopped are reused too. To read a log
without changing it (the pictures, ``ddenv replay --recorded``): `read_events`; ``ddenv show --runs``
reads any JSON-lines file with `numbered_records`, to name the damaged lines.

A log survives a crash at any moment: each line is written with one `write` on a file opened for appending
and fsynced before the reduction goes on, so after a `kill -9`, an out-of-memory kill or a power cut the file
holds every record up to the last one or two, plus at most one incomplete last line. Opening the log cuts
that line off (and says so in `ProbeLog.notes`) instead of appending after it. A write that fails (a full
disk) is undone with `ftruncate`, so the file never holds half a record, and raises `ReductionError`.

Errors are not verdicts: a candidate rejected only because of ERROR runs is logged as ``errored`` (not
``reject``), its ERROR runs are not reused, and a resumed reduction tries it again.
"""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import json
import os
import threading
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import Any, Self

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.events import Event
from pytest_ddenv.reduce.records import json_value, read_regular
from pytest_ddenv.reduce.types import Decision, Outcome, Trace

VOLATILE_FIELDS: tuple[str, ...] = ("elapsed", "wall_time")


class ProbeLog:
    """A JSON-lines log of a reduction; also the source of verdicts when resuming.

    ``ProbeLog(path)`` appends to `path` and reads what it already holds, cutting off an incomplete last line
    (``resume=False`` truncates it instead). ``ProbeLog(None)`` keeps the events in memory only. `events`
    holds every event read or written, as read back from its line; `notes` what opening the file repaired.
    `durable=False` skips the fsync after each line (faster, for throw-away logs).
    """

    stage: str | None = None
    """The stage after the model-level reduction whose records this log reads (None: the model-level one);
    see `view`."""

    def __init__(self, path: str | os.PathLike[str] | None = None, *, resume: bool = True,
                 durable: bool = True) -> None:
        self.path: Path | None = Path(path) if path is not None else None
        self.events: list[Event] = []
        self.notes: list[str] = []
        self.durable = durable
        self._fd: int | None = None
        self._lock = threading.Lock()
        if self.path is None:
            return
        if self.path.is_dir():
            raise ReductionError(f"log path {self.path} is a directory; pass a file path such as runs.jsonl")
        if resume and self.path.exists():
            self.events = self._read(self.path)
        elif self.path.exists():
            os.truncate(self.path, 0)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> ProbeLog:
        """Read an existing log (for inspection, or to resume by passing it as ``reduce(log=...)``)."""
        if not Path(path).is_file():
            raise ReductionError(f"no probe log at {path}; a log is created by reduce(..., log=path)")
        return cls(path, resume=True)

    def view(self, stage: str) -> ProbeLog:
        """The log of one stage after the model-level reduction (``--ddenv-stages``): every record it writes
        goes to this log's file with ``"stage": stage``, and its reading methods (`decisions`, `started_with`
        ...) see only that stage's records, so each stage resumes on its own. Closing a view does nothing."""
        return _StageView(self, stage)

    def own_events(self) -> list[Event]:
        """The events of this log's stage (those of no stage for the model-level log)."""
        return [event for event in self.events if event.stage == self.stage]

    @property
    def records(self) -> list[dict[str, Any]]:
        """Every event as the JSON object its line holds (to look at a log; its readers use `events`)."""
        return [json.loads(events.encode(event)) for event in self.events]

    # -- writing ------------------------------------------------------------------------------------------

    def write(self, event: Event) -> None:
        """Append one event; it is on disk (fsynced) when this returns. Raises ReductionError if it cannot be
        written (the file is left as it was: complete records only)."""
        line = events.encode(event)
        written = events.decode(line)
        if not isinstance(written, Event):  # a writer's bug: never write what the reader would refuse
            raise ReductionError(f"internal error: an unreadable {event.NAME!r} event: {written}")
        if self.path is not None:
            self._append((line + "\n").encode("utf-8"))
        self.events.append(written)

    def _append(self, data: bytes) -> None:
        assert self.path is not None
        with self._lock:
            size = 0
            try:
                if self._fd is None:
                    created = not self.path.exists()
                    self.path.parent.mkdir(parents=True, exist_ok=True)
                    self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
                    if created and self.durable:
                        sync_directory(self.path.parent)
                status = os.fstat(self._fd)
                if status.st_nlink == 0:  # deleted (its folder too?) while the reduction ran: writing is in vain
                    raise ReductionError(gone_failure(self.path))
                size = status.st_size
                view = memoryview(data)
                while view:
                    view = view[os.write(self._fd, view):]
                if self.durable:
                    os.fsync(self._fd)
            except OSError as error:
                if self._fd is not None:
                    with contextlib.suppress(OSError):
                        os.ftruncate(self._fd, size)  # never leave half a record behind
                raise ReductionError(write_failure(self.path, error)) from error

    def close(self) -> None:
        with self._lock:
            if self._fd is not None:
                with contextlib.suppress(OSError):
                    os.close(self._fd)
                self._fd = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- reading ------------------------------------------------------------------------------------------

    def started_with(self) -> tuple[tuple[str, ...], tuple[str, ...]] | None:
        """(elements, keep) of the first reduction recorded in this log, or None if it has none."""
        for event in self.own_events():
            if isinstance(event, events.Start):
                return event.elements, event.keep
        return None

    def calibration(self) -> tuple[int, int] | None:
        """(fails, runs) of the first deflake calibration recorded in this log, or None."""
        for event in self.own_events():
            if isinstance(event, events.Calibration):
                return event.fails, event.runs
        return None

    def decisions(self) -> dict[frozenset[str], Decision]:
        """The verdict on every candidate this log decided (the latest one if several). Rejections that rest
        on ERROR runs (``errored``) are not verdicts and are left out."""
        decided: dict[frozenset[str], Decision] = {}
        for event in self.own_events():
            if isinstance(event, events.VERDICTS) and not event.errored:
                key = frozenset(event.candidate)
                earlier = decided.get(key)
                trace = accepted_trace(event)
                if trace is None and earlier is not None:  # a cache hit logs no trace: keep the acceptance's
                    trace = earlier.trace
                decided[key] = Decision(reproduces=event.reproduces, fails=event.fails, runs=event.runs,
                                        errors=event.errors or 0, trace=trace if event.reproduces else None)
        return decided

    def partial_runs(self) -> dict[frozenset[str], list[Outcome]]:
        """Outcomes of attempts 0, 1, ... of candidates whose runs were logged but not yet decided, up to the
        first ERROR run or missing attempt (an ERROR is no outcome of the seed: that attempt runs again)."""
        runs: dict[frozenset[str], dict[int, Outcome]] = {}
        for event in self.own_events():
            if isinstance(event, events.Probe) and event.purpose == "reduce":
                runs.setdefault(frozenset(event.candidate), {})[event.attempt] = event.result
        decided = self.decisions()
        partial: dict[frozenset[str], list[Outcome]] = {}
        for key, by_attempt in runs.items():
            if key in decided:
                continue
            outcomes: list[Outcome] = []
            while by_attempt.get(len(outcomes), Outcome.ERROR) is not Outcome.ERROR:
                outcomes.append(by_attempt[len(outcomes)])
            if outcomes:
                partial[key] = outcomes
        return partial

    def measured(self, purpose: str, candidate: Collection[str]) -> dict[int, Outcome]:
        """attempt -> outcome of the logged `purpose` runs ("calibration", "failure-rate") of `candidate`,
        ERROR runs left out (they run again)."""
        key = frozenset(candidate)
        found: dict[int, Outcome] = {}
        for event in self.probes(purpose):
            if frozenset(event.candidate) == key and event.result is not Outcome.ERROR:
                found[event.attempt] = event.result
        return found

    def probes(self, *purposes: str) -> list[events.Probe]:
        """This log's stage's probe events with one of these purposes (any purpose when none is given)."""
        return [event for event in self.own_events()
                if isinstance(event, events.Probe) and (not purposes or event.purpose in purposes)]

    def decided_probes(self) -> int:
        """Probe runs whose result a reduction used (reduction and calibration runs), in this log so far."""
        return len(self.probes("reduce", "calibration"))

    def _read(self, path: Path) -> list[Event]:
        try:
            data = read_regular(path)
        except OSError as error:
            raise ReductionError(f"cannot read the run log {path}: {error.strerror or error}; move it away to "
                                 "start over") from None
        complete = data.rfind(b"\n") + 1
        if complete < len(data):  # a last line without its newline: cut short by a crash or a full disk
            os.truncate(path, complete)
            self.notes.append(
                f"{path.name}: its last line was incomplete ({len(data) - complete} bytes, cut short by a crash "
                "or a full disk) and was removed; every complete record before it is reused"
            )
        found: list[Event] = []
        ignored: list[int] = []
        first_problem = ""
        for number, event in _numbered_events(data[:complete].decode("utf-8", errors="replace")):
            if isinstance(event, events.Unreadable):
                if not found:
                    raise ReductionError(
                        f"{path}:{number}: not a probe-log record, so this file is not a pytest-ddenv run log; "
                        "pass another log path, or move the file away to start over"
                    )
                ignored.append(number)
                first_problem = first_problem or f"line {number}: {event.problem}"
                continue
            if not found and (later := events.later_format(event)) is not None:
                raise ReductionError(
                    f"{path}:{number}: a run log of a later pytest-ddenv (format {later}; this one reads format "
                    f"{events.SCHEMA_VERSION}); pass another log path, or move the file away to start over")
            found.append(event)
        if ignored:
            shown = ", ".join(map(str, ignored[:5])) + (f" and {len(ignored) - 5} more" if len(ignored) > 5 else "")
            self.notes.append(f"{path.name}: line(s) {shown} are not records (damaged; {first_problem}) and were "
                              "ignored; the candidates they decided are decided again")
        return found


def parse_record(line: str) -> dict[str, Any] | None:
    """The record one line of a JSON-lines file holds: its JSON object, or None when the line is blank, damaged
    (cut short, invalid JSON) or holds another JSON value."""
    try:
        record = json_value(line)
    except ValueError:  # invalid JSON, or nested too deep
        return None
    return record if isinstance(record, dict) else None


def numbered_records(path: Path) -> Iterator[tuple[int, dict[str, Any] | None]]:
    """(line number from 1, record) for every non-blank line of the JSON-lines file at `path`: a run log
    (`ProbeLog`) or a file of ``ddenv run --record`` lines. The record is None for a line that holds no JSON
    object (`parse_record`), so a caller can name the line. Read-only: a torn last line (a writer still
    writing, or a crash) is reported as None, never cut off (repairing is `ProbeLog`'s job). Bytes that are
    not UTF-8 damage their line only. Raises OSError when the file cannot be read or is not a regular file
    (a folder, a pipe, a device)."""
    return _numbered(read_regular(path).decode("utf-8", errors="replace"))


def read_events(path: Path) -> list[Event]:
    """The events of the run log at `path` in order, blank and unreadable lines (damaged, or an event this
    version does not know) skipped; [] when it is missing or cannot be read. Read-only (see
    `numbered_records`)."""
    try:
        text = read_regular(path).decode("utf-8", errors="replace")
    except OSError:
        return []
    return [event for _, event in _numbered_events(text) if isinstance(event, Event)]


def _numbered(text: str) -> Iterator[tuple[int, dict[str, Any] | None]]:
    for number, line in enumerate(text.split("\n"), start=1):
        if line.strip():
            yield number, parse_record(line)


def _numbered_events(text: str) -> Iterator[tuple[int, Event | events.Unreadable]]:
    for number, line in enumerate(text.split("\n"), start=1):
        event = events.decode(line)
        if event is not None:
            yield number, event


class _StageView(ProbeLog):
    """`ProbeLog.view`: one stage's records, written through the parent log (same file, same lock)."""

    def __init__(self, parent: ProbeLog, stage: str) -> None:
        self.path = parent.path
        self.events = parent.events
        self.notes = []
        self.durable = parent.durable
        self.stage = stage
        self._parent = parent
        self._fd = None
        self._lock = threading.Lock()

    def write(self, event: Event) -> None:
        self._parent.write(dataclasses.replace(event, stage=self.stage))

    def close(self) -> None:
        """The parent log owns the file."""


def sync_directory(directory: Path) -> None:
    """fsync a folder, so that a file just created or renamed in it survives a crash (best effort)."""
    try:
        handle = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(handle)
    except OSError:
        pass
    finally:
        os.close(handle)


def write_failure(path: Path, error: OSError) -> str:
    """The message for a file of a reduction that could not be written: why, and what became of the records
    written before (intact only when the folder still is)."""
    if not path.parent.is_dir():
        return gone_failure(path)
    code = errno.errorcode.get(error.errno or 0, "")
    why = f"{error.strerror or error}" + (f" ({code})" if code else "")
    if error.errno in (errno.ENOSPC, errno.EDQUOT):
        fix = "free some space"
    elif error.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        fix = "fix the folder's permissions"
    else:
        fix = "fix the cause"
    return (f"cannot write {path}: {why}. Every record written before is intact; {fix} and run the reduction "
            "again: it resumes from the log")


def gone_failure(path: Path) -> str:
    """The message for a reduction whose file (or folder) was deleted while it ran."""
    where = path.parent if not path.parent.is_dir() else path
    return (f"cannot write {path}: {where} was deleted while the reduction ran, and the records written before "
            "with it; run the reduction again: it starts over")


def accepted_trace(event: events.Event) -> Trace | None:
    """The trace an acceptance was logged with (None: none, or one this version cannot read: the schemas then
    read the trace before it, as a log written before traces were logged did)."""
    if not isinstance(event, events.Accept) or event.trace is None:
        return None
    try:
        return Trace.from_json(event.trace)
    except ReductionError:
        return None
