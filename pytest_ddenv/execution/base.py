"""The `Pool` protocol every probe pool satisfies, and its statistics."""

from __future__ import annotations

import threading
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, Protocol, Self, runtime_checkable

if TYPE_CHECKING:
    from pytest_ddenv.execution.request import Job
    from pytest_ddenv.world import World

DEFAULT_WATCHDOG_FLOOR = 60.0
"""Seconds: the automatic watchdog never fires earlier than this."""
DEFAULT_WATCHDOG_FACTOR = 10.0
"""The automatic watchdog is this many times the slowest simulation seen so far (or the floor)."""


@dataclass(frozen=True)
class PoolStats:
    """A snapshot of a pool's counters.

    `probes`: probes completed (the test's result, or the handler's own exception, came back); `errors`:
    calls that raised `WorkerError` (crashed twice, hung, could not start, pool closed, cluster lost them);
    `crashes`: worker deaths seen; `timeouts`: watchdog kills; `retries`: probes re-run after a crash;
    `restarts`: worker processes started to replace dead or killed ones; `mean_overhead`: seconds per
    completed probe spent outside the probe itself (queueing excluded: transfer, pickling, dispatch);
    `slowest`: the longest probe (s).
    """

    workers: int
    probes: int = 0
    errors: int = 0
    crashes: int = 0
    timeouts: int = 0
    retries: int = 0
    restarts: int = 0
    mean_overhead: float = 0.0
    slowest: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class StatsBook:
    """Thread-safe counters behind `PoolStats`."""

    def __init__(self, workers: int) -> None:
        self._lock = threading.Lock()
        self.workers = workers
        self._counts = {"probes": 0, "errors": 0, "crashes": 0, "timeouts": 0, "retries": 0, "restarts": 0}
        self._overhead = 0.0
        self._slowest = 0.0

    def add(self, name: str, amount: int = 1) -> None:
        with self._lock:
            self._counts[name] += amount

    def completed(self, overhead: float, seconds: float) -> None:
        with self._lock:
            self._counts["probes"] += 1
            self._overhead += max(0.0, overhead)
            self._slowest = max(self._slowest, seconds)

    @property
    def slowest(self) -> float:
        with self._lock:
            return self._slowest

    def watchdog(self, floor: float, factor: float) -> float:
        """The automatic watchdog: max(floor, factor x the slowest simulation so far)."""
        return max(floor, factor * self.slowest)

    def snapshot(self) -> PoolStats:
        with self._lock:
            probes = self._counts["probes"]
            return PoolStats(
                workers=self.workers,
                mean_overhead=self._overhead / probes if probes else 0.0,
                slowest=self._slowest,
                **self._counts,
            )


@runtime_checkable
class Pool(Protocol):
    """Runs probes of one `Job` somewhere else; `call` is thread-safe and blocks until the result is back."""

    @property
    def job(self) -> Job: ...

    @property
    def size(self) -> int:
        """How many probes can run at once (use it as the probe thread count)."""
        ...

    @property
    def stats(self) -> PoolStats: ...

    def call(self, world: World, attempt: int) -> Any: ...

    def close(self) -> None: ...

    def __enter__(self) -> Self: ...

    def __exit__(self, *exc: object) -> None: ...


def check_watchdog(watchdog: float | str | None) -> float | str | None:
    from pytest_ddenv.execution.errors import PoolConfigError

    if watchdog is None or watchdog == "auto":
        return watchdog
    if isinstance(watchdog, bool) or not isinstance(watchdog, (int, float)) or not watchdog > 0:
        raise PoolConfigError(f"watchdog must be a number of seconds > 0, 'auto' or None, got {watchdog!r}")
    return float(watchdog)
