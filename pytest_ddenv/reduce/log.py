"""The probe log: one JSON object per line, per probe and per decision, written and flushed as it happens.

Events (the ``"event"`` key): ``start``, ``round``, ``probe``, ``accept`` (the candidate reproduces f),
``reject`` (it does not), ``skip`` (a precondition refused it), ``cache-hit`` (its verdict was already
known), ``step`` (a smaller world was adopted), ``calibration`` (deflake="auto": the original world's
failure rate and the re-runs chosen from it), ``failure-rate``, ``end``. Candidates are lists of element
names in original order. The fields in `VOLATILE_FIELDS` hold wall-clock measurements; everything else is
identical for two reductions with the same inputs and seed.

A log is also a cache: `ProbeLog.load(path)` (or ``reduce(..., log=path)`` on an existing file) reads the
verdicts it holds, and the new reduction appends to the same file without simulating those candidates
again. Runs of a candidate that was being decided when the reduction stopped are reused too.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.types import Decision, Outcome

LOG_FORMAT = 1
VOLATILE_FIELDS: tuple[str, ...] = ("elapsed", "wall_time")


def jsonable(value: Any) -> Any:
    """A JSON-compatible copy of `value` (numpy scalars and arrays, tuples, sets, enums, paths ...)."""
    if isinstance(value, Outcome):
        return value.value
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value)
        return number if math.isfinite(number) else str(number)
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, Mapping):
        return {str(key): jsonable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(item) for item in value]
    if isinstance(value, (set, frozenset)):
        return sorted((jsonable(item) for item in value), key=str)
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return repr(value)


class ProbeLog:
    """A JSON-lines log of a reduction; also the source of verdicts when resuming.

    ``ProbeLog(path)`` appends to `path` and reads what it already holds (``resume=False`` truncates it
    instead). ``ProbeLog(None)`` keeps the records in memory only. `records` holds every record read or
    written, as parsed from its JSON line.
    """

    def __init__(self, path: str | os.PathLike[str] | None = None, *, resume: bool = True) -> None:
        self.path: Path | None = Path(path) if path is not None else None
        self.records: list[dict[str, Any]] = []
        self._file: IO[str] | None = None
        if self.path is None:
            return
        if self.path.is_dir():
            raise ReductionError(f"log path {self.path} is a directory; pass a file path such as runs.jsonl")
        if resume and self.path.exists():
            self.records = self._read(self.path)
        elif self.path.exists():
            self.path.write_text("")

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> ProbeLog:
        """Read an existing log (for inspection, or to resume by passing it as ``reduce(log=...)``)."""
        if not Path(path).is_file():
            raise ReductionError(f"no probe log at {path}; a log is created by reduce(..., log=path)")
        return cls(path, resume=True)

    # -- writing ------------------------------------------------------------------------------------------

    def write(self, record: Mapping[str, Any]) -> None:
        """Append one record and flush it to disk."""
        line = json.dumps(jsonable(record), allow_nan=False)
        self.records.append(json.loads(line))
        if self.path is None:
            return
        if self._file is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = self.path.open("a", encoding="utf-8")
        self._file.write(line + "\n")
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> ProbeLog:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- reading ------------------------------------------------------------------------------------------

    def started_with(self) -> tuple[tuple[str, ...], tuple[str, ...]] | None:
        """(elements, keep) of the first reduction recorded in this log, or None if it has none."""
        for record in self.records:
            if record.get("event") == "start":
                return tuple(record.get("elements", ())), tuple(record.get("keep", ()))
        return None

    def calibration(self) -> tuple[int, int] | None:
        """(fails, runs) of the first deflake calibration recorded in this log, or None."""
        for record in self.records:
            if record.get("event") == "calibration":
                return int(record["fails"]), int(record["runs"])
        return None

    def decisions(self) -> dict[frozenset[str], Decision]:
        """The verdict on every candidate this log decided (the latest one if several)."""
        decided: dict[frozenset[str], Decision] = {}
        for record in self.records:
            if record.get("event") in ("accept", "reject", "cache-hit"):
                decided[frozenset(record["candidate"])] = Decision(
                    reproduces=bool(record["reproduces"]), fails=int(record["fails"]), runs=int(record["runs"])
                )
        return decided

    def partial_runs(self) -> dict[frozenset[str], list[Outcome]]:
        """Outcomes of attempts 0, 1, ... of candidates whose runs were logged but not yet decided."""
        runs: dict[frozenset[str], dict[int, Outcome]] = {}
        for record in self.records:
            if record.get("event") == "probe" and record.get("purpose", "reduce") == "reduce":
                runs.setdefault(frozenset(record["candidate"]), {})[int(record["attempt"])] = Outcome(record["outcome"])
        decided = self.decisions()
        partial: dict[frozenset[str], list[Outcome]] = {}
        for key, by_attempt in runs.items():
            if key in decided:
                continue
            outcomes: list[Outcome] = []
            while len(outcomes) in by_attempt:
                outcomes.append(by_attempt[len(outcomes)])
            if outcomes:
                partial[key] = outcomes
        return partial

    @staticmethod
    def _read(path: Path) -> list[dict[str, Any]]:
        lines = path.read_text(encoding="utf-8").splitlines()
        records: list[dict[str, Any]] = []
        for number, line in enumerate(lines, start=1):
            if not line.strip():
                continue
            try:
                record = json.loads(line)
            except json.JSONDecodeError as error:
                if number == len(lines):  # a line cut short by a crash: everything before it is good
                    break
                raise ReductionError(
                    f"{path}:{number}: not a probe-log line ({error}); delete the file to start over"
                ) from error
            if not isinstance(record, dict) or "event" not in record:
                raise ReductionError(f"{path}:{number}: not a probe-log record; delete the file to start over")
            records.append(record)
        return records
