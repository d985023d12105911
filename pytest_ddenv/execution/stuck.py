"""The watchdog of a probe that runs in this process (`--ddenv-workers 1`), where no worker can be killed.

First a SIGALRM timer (`alarm.Alarm`) raises `ProbeTimeout` in the probe's thread when the probe runs past its
limit, and again every second. A probe can defeat it: it replaces or ignores the SIGALRM handler, stops the
timer, catches `BaseException` and goes on, or another tool holds SIGALRM. A watcher thread sees the probe still
running `ESCALATE_AFTER` seconds past the limit and interrupts it harder, every `RETRY_EVERY` seconds, with a
signal of this module's own (it wakes a `time.sleep` or a blocking call whatever SIGALRM's handler is): its
handler raises `ProbeTimeout` and traces the probe's code (`sys.settrace`, as a debugger does) so that the
interrupt is raised again at every line of the probe's code that catches it, until it leaves the probe (the
code of the standard library and of pytest-ddenv is left alone, so their cleanups run). A probe that survives
that too for `ESCALATION` seconds (it blocks every signal, or hangs in C code) cannot be stopped in this
process: the watcher says so and ends the process (exit status `LAST_RESORT_STATUS`) rather than hang forever;
the run log holds every record before it. (A probe called off the main thread, through the Python API, can
be neither interrupted nor stopped: the watcher only warns.)

The pool then reports the probe as an error (never a verdict) and runs the later probes in a worker process.
"""

from __future__ import annotations

import os
import signal
import sys
import sysconfig
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any, Self

from pytest_ddenv.alarm import Alarm

ESCALATE_AFTER = 2.0
"""Seconds past the limit after which a probe still running has defeated the alarm (it fires every second)."""
RETRY_EVERY = 0.1
ESCALATION = 30.0
"""Seconds of interrupting a probe that defeated the alarm before the last resort (ending this process)."""
LAST_RESORT_STATUS = 70
Warn = Callable[[str], None]


class ProbeTimeout(BaseException):
    """Raised in the probe's thread by the in-process watchdog to stop a probe that runs too long. A
    BaseException, so that a test's ``except Exception`` does not take it for the test's own error."""


_LEFT_ALONE = tuple(str(Path(folder).resolve()) + os.sep for folder in (
    sysconfig.get_paths()["stdlib"], sysconfig.get_paths()["platstdlib"], Path(__file__).resolve().parents[1]))
"""Code the harder interrupt never raises in: the standard library's and pytest-ddenv's own."""


def _probes_code(frame: FrameType) -> bool:
    name = frame.f_code.co_filename
    return not name.startswith("<") and not os.path.realpath(name).startswith(_LEFT_ALONE)


def _free_signal() -> int | None:
    """A real-time signal nobody handles (this module's second interrupt), or None."""
    low, high = getattr(signal, "SIGRTMIN", None), getattr(signal, "SIGRTMAX", None)
    if low is None or high is None:
        return None
    for number in range(high - 4, low + 4, -1):
        if signal.getsignal(number) == signal.SIG_DFL:
            return number
    return None


class ProbeWatchdog:
    """The watchdog of one in-process probe (see the module docstring): use it around the probe's call.

    `defeat` says how the probe defeated the alarm, when it did (None: it did not); `interrupted` whether the
    watcher had to interrupt it harder."""

    def __init__(self, limit: float | None, what: str, warn: Warn, *, escalate_after: float = ESCALATE_AFTER,
                 escalation: float = ESCALATION) -> None:
        self.limit = limit
        self.what = what
        self.warn = warn
        self.escalate_after = escalate_after
        self.escalation = escalation
        self.alarm = Alarm(limit, self._error)
        self.defeat: str | None = None
        self.started = 0.0
        self.ended: float | None = None
        self._finished = threading.Event()
        self._lock = threading.Lock()
        self._done = False
        self._armed = False
        self._thread_id = 0
        self._owner: FrameType | None = None
        self._previous_trace: Any = None
        self._backup: int | None = None
        self._backup_previous: Any = None

    def _error(self) -> ProbeTimeout:
        return ProbeTimeout(f"the probe ran past {self.limit:g} s")

    def __enter__(self) -> Self:
        self.started = time.monotonic()
        self.alarm.__enter__()
        if self.limit is None:
            return self
        self._armed = True
        if threading.current_thread() is threading.main_thread():
            self._thread_id = threading.get_ident()
            self._owner = sys._getframe(1)
            self._previous_trace = sys.gettrace()
            self._backup = _free_signal()
            if self._backup is not None:
                self._backup_previous = signal.signal(self._backup, self._interrupt_harder)
        threading.Thread(target=self._watch, name="ddenv-probe-watchdog", daemon=True).start()
        return self

    def ran_past_limit(self) -> bool:
        """The probe ran (or runs) longer than its limit."""
        end = self.ended if self.ended is not None else time.monotonic()
        return self.limit is not None and end - self.started > self.limit

    def handler_replaced(self) -> bool:
        """The probe replaced (or ignored) SIGALRM's handler: the alarm cannot interrupt it."""
        return self.alarm.active and signal.getsignal(signal.SIGALRM) != self.alarm.handler

    def _interrupt_harder(self, signum: int, frame: FrameType | None) -> None:
        """The second signal's handler, in the probe's thread: trace the probe's code, raise the interrupt."""
        if not self._armed:
            return
        while frame is not None and frame is not self._owner:
            frame.f_trace = self._trace
            frame.f_trace_lines = True
            frame = frame.f_back
        sys.settrace(self._trace)
        raise self._error()

    def _trace(self, frame: FrameType, event: str, arg: object) -> Any:
        if self._armed and event in ("call", "line") and _probes_code(frame):
            raise self._error()
        return self._trace

    def _why(self) -> str:
        if self.handler_replaced():
            return "it replaced the SIGALRM handler"
        if self.alarm.fired:
            return "it caught the watchdog's interrupt (ProbeTimeout, a BaseException) and went on"
        if not self.alarm.active:
            return "the SIGALRM timer could not be used (another tool holds SIGALRM, or not the main thread)"
        return "it stopped the SIGALRM timer"

    def _watch(self) -> None:
        assert self.limit is not None
        if self._finished.wait(self.limit + self.escalate_after):
            return
        self.defeat = self._why()
        if self._backup is None:  # not in the main thread (or no signal free): it cannot be interrupted
            self.warn(f"ddenv: warning: the probe of {self.what} runs past its {self.limit:g} s watchdog and cannot "
                      "be interrupted here (it does not run in the main thread); use worker processes")
            return
        self.warn(f"ddenv: the probe of {self.what} runs past its {self.limit:g} s watchdog in this process and "
                  f"did not stop ({self.defeat}); interrupting it harder")
        last_resort = time.monotonic() + self.escalation
        while not self._finished.wait(RETRY_EVERY):
            with self._lock:
                if self._done:
                    return
                signal.pthread_kill(self._thread_id, self._backup)
                if time.monotonic() > last_resort:
                    self.warn(f"ddenv: error: the probe of {self.what} cannot be stopped in this process "
                              f"({self.defeat}; it went on for {self.escalation:g} s of interrupts); ending this "
                              f"process (exit status {LAST_RESORT_STATUS}). The run log holds every record before "
                              "this probe: run again with --ddenv-workers 2 (or ddenv reduce --workers 2), where a "
                              "hung probe's worker is killed, to resume")
                    os._exit(LAST_RESORT_STATUS)

    def __exit__(self, *exc: object) -> None:
        self.ended = time.monotonic()
        self._armed = False
        self._finished.set()
        if self._owner is not None:
            sys.settrace(self._previous_trace)
            self._owner = None
        if self.limit is not None and self.defeat is None and self.handler_replaced():
            self.defeat = "it replaced the SIGALRM handler"
        while True:  # an interrupt delivered meanwhile is not the probe's any more: clean up again
            try:
                with self._lock:
                    self._done = True
                if self._backup is not None:
                    signal.signal(self._backup, signal.SIG_IGN)  # a signal still pending is dropped
                    signal.signal(self._backup, self._backup_previous)
                    self._backup = None
                self.alarm.__exit__()
                break
            except ProbeTimeout:
                continue
