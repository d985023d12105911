"""Reductions a later session made stale: a test that passes now, after an edit of its code or world, still has
the folder of its earlier reduction (`minimal.yaml`, a `summary.json` that says "fails 5/5"). Nothing is deleted
or moved (the folder's log is what a later failure resumes from): its `summary.json` gets a ``superseded`` entry
and the session says so. A later reduction of the test rewrites `summary.json`, and the entry goes with it."""

from __future__ import annotations

import json
import re
import time
from pathlib import Path

from pytest_ddenv.driver.artifacts import ArtifactsError, FolderLock, artifact_dir_name, readable_test_id, write_json
from pytest_ddenv.reduce.records import read_regular

SUMMARY_LIMIT = 64 * 1024 * 1024
"""Bytes of a `summary.json` read at most (a folder's file is not trusted to be small)."""
SUPERSEDED_REASON = "the test passed in a later session: this reduction is of earlier code or an earlier world"


def earlier_reductions(root: Path, test_id: str) -> list[Path]:
    """The folders under `root` that `test_id`'s reductions made (one per seed reduced, named by
    `artifact_dir_name`) and that hold a `summary.json`, in name order."""
    pattern = re.compile(re.escape(readable_test_id(test_id)) + r"-seed(-?\d+)-[0-9a-f]{8}")
    try:
        entries = sorted(root.iterdir())
    except OSError:  # no artifacts folder yet, or not readable: nothing to say
        return []
    found = []
    for entry in entries:
        match = pattern.fullmatch(entry.name)
        if match is not None and artifact_dir_name(test_id, int(match.group(1))) == entry.name \
                and (entry / "summary.json").is_file():
            found.append(entry)
    return found


def mark_superseded(folder: Path) -> bool:
    """Add the ``superseded`` entry (`SUPERSEDED_REASON` and when) to `folder`'s `summary.json`, under the folder's
    lock; an entry already there is kept as it is. False when it could not be written: another reduction holds
    the folder (its own `summary.json` is about to replace this one), or the file is not a JSON object."""
    try:
        with FolderLock(folder):
            path = folder / "summary.json"
            summary = json.loads(read_regular(path, SUMMARY_LIMIT))
            if not isinstance(summary, dict):
                return False
            if "superseded" not in summary:
                summary["superseded"] = {"reason": SUPERSEDED_REASON,
                                         "at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
                write_json(path, summary)
            return True
    except (ArtifactsError, OSError, ValueError):
        return False
