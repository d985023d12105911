"""The processes a probe starts (a `subprocess.Popen`, with `start_new_session=True` or not, an `os.fork()` child,
a daemon that forked twice), found under the process that ran the probe and ended with it.

A worker process is made a child subreaper (Linux), so that every process its probes start stays its descendant
even when the process between them exits; when the worker ends (the end of the reduction, or the watchdog
kills it) its descendants are ended first. An in-process probe (`--ddenv-workers 1`) ends the processes it
started, and that are still running, when it returns. Processes are found in `/proc` by their parent, and
told apart from a later process that got the same pid by their start time. Elsewhere than Linux, nothing is
found and nothing is ended.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import signal
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import NamedTuple

PROC = Path("/proc")
PR_SET_CHILD_SUBREAPER = 36
TERM_GRACE = 0.5
"""Seconds the processes being ended get after SIGTERM before SIGKILL."""


class Process(NamedTuple):
    pid: int
    started: int
    """Start time in clock ticks since boot (`/proc/PID/stat` field 22): tells a process from a later one with
    the same pid."""


def _table() -> dict[int, tuple[int, int]]:
    """pid -> (parent pid, start time) of every live process (zombies left out)."""
    found: dict[int, tuple[int, int]] = {}
    try:
        entries = list(os.scandir(PROC))
    except OSError:
        return found
    for entry in entries:
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/stat", "rb") as handle:
                fields = handle.read().rsplit(b")", 1)[1].split()
        except (OSError, IndexError):
            continue  # gone meanwhile
        if fields[0] != b"Z":
            found[int(entry.name)] = (int(fields[1]), int(fields[19]))
    return found


def descendants(pid: int) -> list[Process]:
    """Every live process under `pid` (children, grandchildren, ...), parents before their children."""
    children: dict[int, list[int]] = {}
    table = _table()
    for child, (parent, _) in table.items():
        children.setdefault(parent, []).append(child)
    found: list[Process] = []
    queue = list(children.get(pid, ()))
    while queue:
        child = queue.pop(0)
        found.append(Process(child, table[child][1]))
        queue.extend(children.get(child, ()))
    return found


def _alive(process: Process) -> bool:
    try:
        with open(f"/proc/{process.pid}/stat", "rb") as handle:
            fields = handle.read().rsplit(b")", 1)[1].split()
    except (OSError, IndexError):
        return False
    return fields[0] != b"Z" and int(fields[19]) == process.started


def _signal(processes: Iterable[Process], number: int) -> None:
    for process in processes:
        if _alive(process):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(process.pid, number)


def end_processes(processes: Iterable[Process], grace: float = TERM_GRACE) -> int:
    """End `processes`: SIGTERM, then SIGKILL to those still running after `grace` seconds; our own children
    among them are reaped. Returns how many were running."""
    chosen = [process for process in processes if _alive(process)]
    if not chosen:
        return 0
    _signal(chosen, signal.SIGTERM)
    deadline = time.monotonic() + grace
    while any(_alive(process) for process in chosen) and time.monotonic() < deadline:
        _reap(chosen)
        time.sleep(0.02)
    _signal(chosen, signal.SIGKILL)
    _reap(chosen)
    return len(chosen)


def _reap(processes: Iterable[Process]) -> None:
    """Collect the exit status of those of `processes` that are this process's children (no zombies left)."""
    for process in processes:
        with contextlib.suppress(ChildProcessError, OSError):
            os.waitpid(process.pid, os.WNOHANG)


def become_subreaper(on: bool = True) -> bool:
    """Make this process adopt the orphans among its descendants (Linux `PR_SET_CHILD_SUBREAPER`), or stop
    (`on=False`); False when the system does not offer it."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True)
        return bool(libc.prctl(PR_SET_CHILD_SUBREAPER, int(on), 0, 0, 0) == 0)
    except (OSError, AttributeError):
        return False


@contextlib.contextmanager
def processes_ended(exclude: Iterable[int] = ()) -> Iterator[list[Process]]:
    """Around an in-process probe: the processes it starts under this process (`exclude`: pids that are not
    its, e.g. the pool's own workers), and their orphans, are ended when it returns; the list yields those
    ended (filled at the end)."""
    before = {process.pid for process in descendants(os.getpid())}
    adopting = become_subreaper(True)
    ended: list[Process] = []
    try:
        yield ended
    finally:
        skip = before | set(exclude)
        started = [process for process in descendants(os.getpid()) if process.pid not in skip]
        if started:
            end_processes(started)
            ended.extend(started)
        if adopting:
            become_subreaper(False)
