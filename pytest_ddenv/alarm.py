"""A wall-clock alarm that interrupts the main thread: what stops a probe or a run that never returns (a
controller stuck in a loop) in this process, where a worker process would simply be killed."""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from typing import Any, Self


class Alarm:
    """Raise `make_error()` in this (main) thread after `seconds`, then every second until disarmed (code
    that swallows it is interrupted again). Inactive off the main thread, without `seconds`, or when someone
    else (pytest-timeout's signal method, the test itself, an outer alarm) uses SIGALRM."""

    def __init__(self, seconds: float | None, make_error: Callable[[], BaseException]) -> None:
        self.seconds = seconds
        self.make_error = make_error
        self.active = False
        self.armed = False
        self.previous: Any = None
        self.fired = 0
        """How many times the alarm raised its error (more than once: the code caught it and went on)."""

    def usable(self) -> bool:
        if self.seconds is None or not hasattr(signal, "setitimer"):
            return False
        if threading.current_thread() is not threading.main_thread():
            return False
        handler = signal.getsignal(signal.SIGALRM)
        return handler in (signal.SIG_DFL, signal.SIG_IGN, None) and signal.getitimer(signal.ITIMER_REAL)[0] == 0

    @property
    def handler(self) -> Callable[[int, Any], None]:
        """The SIGALRM handler while the alarm is active (code that replaced it defeats the alarm)."""
        return self._fire

    def _fire(self, signum: int, frame: object) -> None:
        if self.armed:
            self.fired += 1
            raise self.make_error()

    def __enter__(self) -> Self:
        if not self.usable():
            return self
        assert self.seconds is not None
        self.previous = signal.signal(signal.SIGALRM, self._fire)
        self.active = self.armed = True
        signal.setitimer(signal.ITIMER_REAL, max(self.seconds, 1e-3), 1.0)
        return self

    def __exit__(self, *exc: object) -> None:
        while self.active:
            try:
                self.armed = False
                signal.setitimer(signal.ITIMER_REAL, 0)
                signal.signal(signal.SIGALRM, self.previous)
                self.active = False
            except BaseException:  # noqa: BLE001 - the alarm's own error, delivered just before it was disarmed
                continue
