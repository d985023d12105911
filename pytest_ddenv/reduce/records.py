"""What a file read back must be: a regular file, and JSON nested within a bound.

A file that pytest-ddenv wrote and reads again (`runs.jsonl`, `summary.json`, a `ddenv run --record` file)
may have been damaged or edited since. `json_value` refuses text nested deeper than `MAX_JSON_NESTING` before
parsing it (the parser would recurse once per level); what a run-log record must hold besides is
`events.decode`'s business.
"""

from __future__ import annotations

import errno
import itertools
import json
import os
import re
import stat
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
