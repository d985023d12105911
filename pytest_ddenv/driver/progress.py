"""Progress of a reduction for people and CI logs: a live one-line bar on a terminal; otherwise a line per
note, at the start, at each accepted step, at verification and at the end, and at least one line every
HEARTBEAT_SECONDS (a `Heartbeat` thread), also while a single long probe runs. Used by `ddenv reduce`
(`ProgressLine`) and by the plugin (`Heartbeat` beside pytest's terminal writer)."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from typing import IO, TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.reduce import ProgressEvent

HEARTBEAT_SECONDS = 30.0
"""Longest silence of a reduction's progress in a log that is not a terminal (CI)."""
LABELS = {"end": "models done"}
"""How a CI log's line names the engine event it shows (its kind, unless renamed here): after "end" come the
stages, the files and the pictures."""


def label_of(kind: str) -> str:
    """The name of an engine event's kind in a progress line."""
    return LABELS.get(kind, kind)


def heartbeat_label(done: bool) -> str:
    """The name of a heartbeat's line: "running" while the models are reduced, "finishing" once they are done
    (`done`: the stages after the models, the files and the pictures)."""
    return "finishing" if done else "running"


class Heartbeat:
    """Calls `beat()` from a daemon thread whenever nothing was written for `interval` seconds, until closed,
    so that a CI log gets a line at least that often even while one long probe runs. Writers call `wrote()`
    after each line, holding `lock` (which `beat` is called with) so that lines never interleave."""

    def __init__(self, beat: Callable[[], None], interval: float | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.lock = threading.RLock()
        self.interval = HEARTBEAT_SECONDS if interval is None else interval
        self._beat = beat
        self._clock = clock
        self._last = clock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        if self._thread is None and not self._stop.is_set():
            self._thread = threading.Thread(target=self._run, name="ddenv-heartbeat", daemon=True)
            self._thread.start()

    def wrote(self) -> None:
        self._last = self._clock()

    def due(self) -> bool:
        return self._clock() - self._last >= self.interval

    def _run(self) -> None:
        while not self._stop.wait(max(0.01, self.interval - (self._clock() - self._last))):
            with self.lock:
                if self.due() and not self._stop.is_set():
                    self._beat()
                    self.wrote()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)


class ProgressLine:
    """A one-line progress bar on a terminal (probes, current size, elapsed). Otherwise (a CI log): a line
    at the start, at each accepted step (a smaller world), at verification and at the end, and at least
    one line every HEARTBEAT_SECONDS."""

    WIDTH = 24

    def __init__(self, stream: IO[str], *, quiet: bool = False, heartbeat: float | None = None) -> None:
        self.stream = stream
        self.quiet = quiet
        self.live = not quiet and stream.isatty() and os.environ.get("TERM") != "dumb"
        self.original: int | None = None
        self.started = time.perf_counter()
        self._width = 0
        self._last: tuple[ProgressEvent, float] | None = None
        self._note = ""
        self.heartbeat = Heartbeat(self._beat, heartbeat)
        if not quiet and not self.live:
            self.heartbeat.start()

    def note(self, text: str) -> None:
        if not self.quiet:
            with self.heartbeat.lock:
                self._clear()
                self._note = text
                self._print(f"ddenv: {text}")

    def update(self, event: ProgressEvent) -> None:
        if self.quiet:
            return
        with self.heartbeat.lock:
            if self.original is None:
                self.original = event.size
            self._last = (event, time.perf_counter())
            line = self._line(event, event.elapsed, label_of(event.kind))
            if self.live:
                self.stream.write("\r" + line.ljust(self._width))
                self.stream.flush()
                self._width = len(line)
            elif event.kind in ("start", "step", "verify", "end") or self.heartbeat.due():
                self._print(line)

    def _beat(self) -> None:
        """The heartbeat's line: the latest progress with the time now, or the latest note."""
        if self._last is None:
            self._print(f"ddenv: {self._note or 'working'} ({time.perf_counter() - self.started:.0f} s)")
            return
        event, seen = self._last
        self._print(self._line(event, event.elapsed + time.perf_counter() - seen, heartbeat_label(event.kind == "end")))

    def _print(self, line: str) -> None:
        print(line, file=self.stream, flush=True)
        self.heartbeat.wrote()

    def _line(self, event: ProgressEvent, elapsed: float, kind: str) -> str:
        original = max(self.original or event.size, 1)
        done = (original - event.size) / max(original - 1, 1)
        filled = round(self.WIDTH * min(max(done, 0.0), 1.0))
        minutes, seconds = divmod(int(elapsed), 60)
        bar = "#" * filled + "-" * (self.WIDTH - filled)
        return (f"[{bar}] {original} -> {event.size} models | {event.probes} probes | "
                f"{minutes:02d}:{seconds:02d} | {kind}")

    def _clear(self) -> None:
        if self.live and self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self._width = 0

    def close(self) -> None:
        self.heartbeat.close()
        with self.heartbeat.lock:
            if self.live and self._width:
                self.stream.write("\n")
                self.stream.flush()
                self._width = 0
