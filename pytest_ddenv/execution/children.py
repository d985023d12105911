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


def _stat(pid: int) -> tuple[str, int, int] | None:
    """(state, parent pid, start time) of a process, None when it is gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as handle:
            fields = handle.read().rsplit(b")", 1)[1].split()
        return fields[0].decode(), int(fields[1]), int(fields[19])
    except (OSError, IndexError, ValueError):
        return None


def _children(pid: int) -> list[int] | None:
    """The children of `pid` from `/proc/PID/task/*/children` (cheap: no scan of every process); None when the
    system does not list them."""
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return []
    found: list[int] = []
    for task in tasks:
        try:
            with open(f"/proc/{pid}/task/{task}/children", "rb") as handle:
                found.extend(int(word) for word in handle.read().split())
        except FileNotFoundError:
            if not os.path.exists(f"/proc/{pid}/task/{task}"):
                continue  # the thread ended meanwhile
            return None
        except OSError:
            continue
    return found


def _children_by_scan() -> dict[int, list[int]]:
    """parent pid -> children, from every process of the system (where `_children` is not offered)."""
    children: dict[int, list[int]] = {}
    with contextlib.suppress(OSError):
        for entry in os.scandir(PROC):
            if entry.name.isdigit():
                status = _stat(int(entry.name))
                if status is not None:
                    children.setdefault(status[1], []).append(int(entry.name))
    return children


def descendants(pid: int) -> list[Process]:
    """Every live process under `pid` (children, grandchildren, ...), parents before their children."""
    scanned: dict[int, list[int]] | None = None
    found: list[Process] = []
    queue = [pid]
    while queue:
        parent = queue.pop(0)
        children = _children(parent)
        if children is None:
            scanned = scanned if scanned is not None else _children_by_scan()
            children = scanned.get(parent, [])
        for child in children:
            status = _stat(child)
            if status is not None and status[0] != "Z":
                found.append(Process(child, status[2]))
                queue.append(child)
    return found


def _alive(process: Process) -> bool:
    status = _stat(process.pid)
    return status is not None and status[0] != "Z" and status[2] == process.started


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
