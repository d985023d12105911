"""A reduction's progress beside pytest's own output: one updating line on a terminal (a line per probe with
-v); in a CI log a line for each note, at the start, at each accepted step, at verification and when the
models are done, then at least one line every HEARTBEAT_SECONDS; in a pytest-xdist worker one line when the
reduction starts and its result line when it ends, on the terminal's stderr (xdist shows nothing else of its
workers). Every line's seconds and the result line's are on one clock: since the reduction started."""

from __future__ import annotations

import contextlib
import os
import sys
import time
from typing import TYPE_CHECKING, Any, TextIO

import pytest

from pytest_ddenv.driver.progress import Heartbeat, heartbeat_label, label_of

if TYPE_CHECKING:
    from pytest_ddenv.reduce import ProgressEvent

LOG = pytest.StashKey[TextIO]()
"""A text stream on the terminal, past pytest's output capture: pytest's stdout when it is not a terminal
(a CI log), or, in a pytest-xdist worker, the stderr the worker shares with the pytest process."""


def open_log(config: pytest.Config) -> None:
    """Make the `LOG` stream (called in `pytest_configure`, while output capture is suspended)."""
    worker = hasattr(config, "workerinput")
    if LOG in config.stash:  # already open (a reduction's and a failure rate's plugins both ask for it)
        return
    try:
        if not worker and sys.stdout.isatty():
            return
        descriptor = os.dup((sys.stderr if worker else sys.stdout).fileno())
    except (AttributeError, OSError, ValueError):  # no file descriptor (an in-process pytester run, ...)
        return
    config.stash[LOG] = os.fdopen(descriptor, "w", encoding=sys.stdout.encoding or "utf-8", errors="replace")


def close_log(config: pytest.Config) -> None:
    log = config.stash.get(LOG, None)
    if log is not None:
        log.close()
        del config.stash[LOG]


class PytestProgress:
    """The progress of one test's reduction (see the module docstring); `started` is its clock's zero."""

    def __init__(self, config: pytest.Config, test_id: str, doing: str = "reducing") -> None:
        self.config = config
        self.reporter = config.pluginmanager.getplugin("terminalreporter")
        self.capture = config.pluginmanager.getplugin("capturemanager")
        self.verbose = config.get_verbosity() > 0
        self.started = time.monotonic()
        self.worker: str | None = getattr(config, "workerinput", {}).get("workerid")
        self.log = config.stash.get(LOG, None)
        if self.worker is not None:  # no terminal reporter of its own: the log on the shared stderr, or nothing
            self.silent, self.live = self.log is None, False
        else:
            self.silent = self.reporter is None
            self.live = not self.silent and bool(self.reporter.isatty)
            if self.live:
                self.log = None
        self.heartbeat = Heartbeat(self._beat)
        self._text = ""
        self._done = False
        """The models are reduced: what comes is the stages, the files and the pictures."""
        self._said_result = False
        if self.worker is not None:
            self._write(f"ddenv: {doing} {test_id}")
        elif self.log is not None:  # lines go past pytest, after what pytest has written so far
            with self._suspended():
                self.reporter.ensure_newline()
                self.reporter.flush()
            self.heartbeat.start()

    def seconds(self) -> float:
        """Seconds since the reduction started."""
        return time.monotonic() - self.started

    def __call__(self, text: str, *, final: bool = False, probe_line: str | None = None,
                 event: ProgressEvent | None = None) -> None:
        """`event`: the engine event this line words, if any (a CI log needs to know which are steps)."""
        if self.silent or (self.worker is not None and not final):
            return
        line = f"ddenv: {text}" if final else f"ddenv: {text}, {self.seconds():.0f} s"
        with self.heartbeat.lock:
            self._text = text
            self._done = self._done or (event is not None and event.kind == "end")
            if self.verbose and probe_line:
                self._write(f"    {probe_line}")
            elif final:
                self._write(line)
                self._said_result = True
            elif self.live:
                self._rewrite(line)
            elif event is None or event.kind in ("start", "step", "verify", "end") or self.heartbeat.due():
                self._write(line if event is None else f"{line} ({label_of(event.kind)})")

    def _beat(self) -> None:
        """The heartbeat's line: the latest progress with the time now (none after the result line)."""
        if not self._said_result:
            self._write(f"ddenv: {self._text or 'reducing'}, {self.seconds():.0f} s "
                        f"({heartbeat_label(self._done)})")

    def _write(self, line: str) -> None:
        if self.worker is not None:
            line = f"[{self.worker}] {line}"
        if self.log is not None:
            self.log.write(line + "\n")
            self.log.flush()
        else:
            with self._suspended():
                self.reporter.write_line(line)
        self.heartbeat.wrote()

    def _rewrite(self, line: str) -> None:
        with self._suspended():
            self.reporter.rewrite(line, erase=True)

    def _suspended(self) -> contextlib.AbstractContextManager[Any]:
        if self.capture is None:
            return contextlib.nullcontext()
        return self.capture.global_and_fixture_disabled()  # type: ignore[no-any-return]

    def close(self) -> None:
        self.heartbeat.close()
