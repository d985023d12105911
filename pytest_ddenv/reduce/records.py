"""What a record read back from a file must be: JSON nested within a bound, and, for a run-log record, the
fields its readers use of the types its writer gives them.

A file that pytest-ddenv wrote and reads again (`runs.jsonl`, `summary.json`, a `ddenv run --record` file)
may have been damaged or edited since. `json_value` refuses text nested deeper than `MAX_JSON_NESTING` before
parsing it (the parser would recurse once per level), and `record_problem` says why a run-log record cannot be
used (a field of the wrong type), so that the log's readers can ignore it as a damaged line, with a note,
instead of failing in the middle of a reduction.
"""

from __future__ import annotations

import errno
import itertools
import json
import math
import os
import re
import stat
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

MAX_JSON_NESTING = 64
"""Levels of lists and objects in a JSON value read back (a run-log record needs 4, a summary about 6)."""
_STRINGS = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)
_NOT_BRACKETS = re.compile(r"[^\[\]{}]+")


def read_regular(path: Path, limit: int | None = None) -> bytes:
    """The bytes of the regular file at `path` (a symbolic link to one is fine): OSError naming the path when it
    is a folder, a pipe or a device (opened without blocking, so a FIFO never hangs the reader), or larger than
    `limit` bytes."""
    handle = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        status = os.fstat(handle)
        if stat.S_ISDIR(status.st_mode):
            raise IsADirectoryError(errno.EISDIR, "is a folder, not a file", str(path))
        if not stat.S_ISREG(status.st_mode):
            raise OSError(errno.EINVAL, "not a regular file (a pipe or a device)", str(path))
        if limit is not None and status.st_size > limit:
            raise OSError(errno.EFBIG, f"larger than the {limit} byte limit", str(path))
        with os.fdopen(handle, "rb", closefd=False) as stream:
            return stream.read()
    finally:
        os.close(handle)


def json_value(text: str, limit: int = MAX_JSON_NESTING) -> Any:
    """`json.loads(text)`, refusing (ValueError) text whose lists and objects are nested deeper than `limit`,
    before parsing it."""
    brackets = _NOT_BRACKETS.sub("", _STRINGS.sub("", text))
    if len(brackets) > 2 * limit:
        depth = max(itertools.accumulate(1 if char in "[{" else -1 for char in brackets), default=0)
        if depth > limit:
            raise ValueError(f"lists and objects nested more than {limit} deep")
    return json.loads(text)


def _integer(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _names(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(item, str) for item in value)


def _point(value: Any) -> bool:
    return isinstance(value, list) and len(value) == 5 and all(_number(item) for item in value)


OUTCOMES = ("fail", "other", "pass", "error")
_KINDS: Mapping[str, tuple[str, Callable[[Any], bool]]] = {
    "names": ("a list of model names", _names),
    "count": ("an integer >= 0", _integer),
    "seed": ("an integer >= 0 or null", lambda value: value is None or _integer(value)),
    "outcome": (f"one of {', '.join(OUTCOMES)}", lambda value: value in OUTCOMES),
    "text": ("a string", lambda value: isinstance(value, str)),
    "flag": ("true or false", lambda value: isinstance(value, bool)),
    "number": ("a finite number", _number),
    "points": ("a list of [distance, time, x, y, yaw]", lambda value: isinstance(value, list)
               and all(_point(item) for item in value)),
    "signature": ("an object or null", lambda value: value is None or isinstance(value, dict)),
}
_VERDICT = {"candidate": "names!", "reproduces": "flag!", "fails": "count!", "runs": "count!", "errored": "flag"}
_RATE = {"candidate": "names!", "fails": "count!", "runs": "count!"}
EVENTS: Mapping[str, Mapping[str, str]] = {
    "probe": {"candidate": "names!", "attempt": "count!", "outcome": "outcome!", "purpose": "text", "seed": "seed",
              "signature": "signature"},
    "accept": _VERDICT, "reject": _VERDICT, "errored": _VERDICT, "cache-hit": _VERDICT, "rate-below": _VERDICT,
    "calibration": {"fails": "count!", "runs": "count!"},
    "failure-rate": _RATE, "precondition-check": _RATE,
    "step": {"candidate": "names"}, "back-off": {"candidate": "names"}, "skip": {"candidate": "names"},
    "start": {"elements": "names", "keep": "names"},
    "usage": {"simulations": "count", "cpu_seconds": "number", "final": "flag"},
    "path": {"points": "points!", "failure_time": "number!"},
}
"""The fields of each event that its readers use, of the kind in `_KINDS` ("!": the record must have it)."""


def record_problem(record: Mapping[str, Any]) -> str | None:
    """Why a run-log record cannot be used (a field its readers need missing, or of the wrong type), or None."""
    event = record.get("event")
    if not isinstance(event, str):
        return "no 'event' name"
    fields = {"stage": "text", **EVENTS.get(event, {})}
    for name, kind in fields.items():
        if name not in record:
            if kind.endswith("!"):
                return f"a {event!r} record without '{name}'"
            continue
        what, valid = _KINDS[kind.rstrip("!")]
        if not valid(record[name]):
            return f"'{name}' of a {event!r} record is not {what}"
    return None
