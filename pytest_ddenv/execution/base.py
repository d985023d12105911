"""The `Pool` protocol every probe pool satisfies, and its statistics."""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, Protocol, Self, TypeVar, runtime_checkable

from pytest_ddenv.validation import expected, is_finite_number

if TYPE_CHECKING:
    from pytest_ddenv.execution.request import Job
    from pytest_ddenv.world.model import World

DEFAULT_WATCHDOG_FLOOR = 60.0
"""Seconds: the automatic watchdog never fires earlier than this."""
DEFAULT_WATCHDOG_FACTOR = 10.0
"""The automatic watchdog is this many times the longest of: the original run (`expect`) and the slowest probe
seen so far (or the floor)."""
DEFAULT_RUN_CAP = 300.0
"""Seconds: the wall-clock cap of one run when the pool's job does not say its own (`max_wall_time`); the same
as `robot_world.DEFAULT_MAX_WALL_TIME` (the execution layer does not import the scenario layer)."""
FIRST_RUN_MARGIN = 60.0
"""Seconds past the run's own wall-clock cap the automatic watchdog allows while no run has been timed: a run
that is merely slow ends at its cap (`ControllerTimeout`, an error of the run); the watchdog is for one that
hangs where the cap cannot stop it."""
WATCHDOG_ENV = "DDENV_PROBE_TIMEOUT"
"""The watchdog of pools created without an explicit ``watchdog=``: seconds (e.g. ``30``), ``auto`` (the
default) or ``none``. The pytest plugin and ``ddenv reduce`` create their pools that way."""


class _Default:
    def __repr__(self) -> str:
        return "DEFAULT"


DEFAULT: Any = _Default()
"""`watchdog=DEFAULT`: $DDENV_PROBE_TIMEOUT if set, else 'auto'."""


@dataclass(frozen=True)
class PoolStats:
    """A snapshot of a pool's counters.

    `probes`: probes completed (the test's result, or the handler's own exception, came back); `simulations`:
    tries started (every probe, a retry after a crash counted again); `errors`: calls that raised
    `WorkerError` (crashed twice, hung, could not start, pool closed, cluster lost them); `crashes`: worker
    deaths seen; `timeouts`: watchdog kills; `cancelled`: probes stopped at their caller's deadline;
    `retries`: probes re-run after a crash; `restarts`: worker processes started to replace dead or killed
    ones; `mean_overhead`: seconds per completed probe spent outside the probe itself (queueing excluded:
    transfer, pickling, dispatch); `slowest`: the longest probe (s); `cpu_seconds`: CPU time the completed
    probes used where they ran (the thread that ran each probe; a probe killed mid-run is not counted).
    """

    workers: int
    probes: int = 0
    simulations: int = 0
    errors: int = 0
    crashes: int = 0
    timeouts: int = 0
    cancelled: int = 0
    retries: int = 0
    restarts: int = 0
    mean_overhead: float = 0.0
    slowest: float = 0.0
    cpu_seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class StatsBook:
    """Thread-safe counters behind `PoolStats`."""

    def __init__(self, workers: int) -> None:
        self._lock = threading.Lock()
        self.workers = workers
        self._counts = {"probes": 0, "simulations": 0, "errors": 0, "crashes": 0, "timeouts": 0, "cancelled": 0,
                        "retries": 0, "restarts": 0}
        self._overhead = 0.0
        self._slowest = 0.0
        self._expected = 0.0
        self._cpu = 0.0
        self._largest = (0, 0.0)  # (size, seconds) of the largest world timed (`world_size`)

    def add(self, name: str, amount: int = 1) -> None:
        with self._lock:
            self._counts[name] += amount

    def completed(self, overhead: float, seconds: float, cpu_seconds: float = 0.0, size: int = 0) -> None:
        """A probe of a world of `size` (`world_size`; 0: unknown) came back after `seconds`."""
        with self._lock:
            self._counts["probes"] += 1
            self._overhead += max(0.0, overhead)
            self._slowest = max(self._slowest, seconds)
            self._cpu += max(0.0, cpu_seconds)
            self._timed(size, seconds)

    def expect(self, seconds: float, size: int = 0) -> None:
        """The original run (a world of `size`, 0: unknown) took `seconds`: the automatic watchdog is at least
        `factor` times that."""
        with self._lock:
            if math.isfinite(seconds) and seconds > 0:
                self._expected = max(self._expected, float(seconds))
                self._timed(size, float(seconds))

    def _timed(self, size: int, seconds: float) -> None:
        if size > 0 and (size, seconds) > self._largest:
            self._largest = (size, seconds)

    @property
    def slowest(self) -> float:
        with self._lock:
            return self._slowest

    def watchdog(self, floor: float, factor: float, size: int = 0, run_cap: float | None = None) -> float:
        """The automatic watchdog of a probe of a world of `size` (`world_size`; 0: unknown), see
        `automatic_watchdog`."""
        with self._lock:
            return automatic_watchdog(floor, factor, max(self._slowest, self._expected), self._largest, size,
                                      run_cap)

    def snapshot(self) -> PoolStats:
        with self._lock:
            probes = self._counts["probes"]
            return PoolStats(
                workers=self.workers,
                mean_overhead=self._overhead / probes if probes else 0.0,
                slowest=self._slowest,
                cpu_seconds=round(self._cpu, 6),
                **self._counts,
            )


def automatic_watchdog(floor: float, factor: float, longest: float, largest: tuple[int, float], size: int,
                       run_cap: float | None) -> float:
    """Seconds a probe may run under the automatic watchdog.

    No run timed yet (`longest` 0: the original and the confirmation runs of `ddenv reduce`): max(`floor`, the
    run's own wall-clock cap `run_cap` (None: `DEFAULT_RUN_CAP`) + `FIRST_RUN_MARGIN`). Else max(`floor`,
    `factor` x the longest run timed), where a world bigger than the largest timed one (`largest`: its size and
    seconds) counts as that run's seconds scaled by the size ratio: a world of 10 times the shapes of any timed
    one may take 10 times as long."""
    if longest <= 0:
        return max(floor, (DEFAULT_RUN_CAP if run_cap is None else run_cap) + FIRST_RUN_MARGIN)
    largest_size, largest_seconds = largest
    if 0 < largest_size < size:
        longest = max(longest, largest_seconds * size / largest_size)
    return max(floor, factor * longest)


def world_size(world: World) -> int:
    """What a run's time grows with, for the watchdog: the world's collision shapes (1 per mesh shape)."""
    return sum(len(model.shapes) for model in world)


def run_cap_of(job: object) -> float | None:
    """The wall-clock cap of one run of `job` (its `max_wall_time`, as `ScenarioJob` has it), else None."""
    cap = getattr(job, "max_wall_time", None)
    return float(cap) if is_finite_number(cap) and cap > 0 else None


ResultT_co = TypeVar("ResultT_co", covariant=True)
"""What a pool's job returns from a probe: the driver's pools return a `ProbeResult` (`Pool[ProbeResult]`)."""


@runtime_checkable
class Pool(Protocol[ResultT_co]):
    """Runs probes of one `Job` somewhere else; `call` is thread-safe and blocks until the result is back."""

    @property
    def job(self) -> Job: ...

    @property
    def size(self) -> int:
        """How many probes can run at once (use it as the probe thread count)."""
        ...

    @property
    def in_process(self) -> bool:
        """The probes run in the calling process, one at a time (no worker process to wait for)."""
        ...

    @property
    def stats(self) -> PoolStats: ...

    @property
    def notes(self) -> Sequence[str]:
        """What the pool changed on its own while it ran that a report should say (a probe moved to a worker)."""
        ...

    def expect(self, seconds: float, size: int = 0) -> None:
        """The original run of the test, a world of `size` (`world_size`; 0: unknown), took `seconds` (wall):
        the automatic watchdog scales with it."""
        ...

    def call(self, world: World, attempt: int, *, timeout: float | None = None, record: bool = False) -> ResultT_co:
        """`timeout`: seconds this probe may take before it is stopped (`ProbeDeadline`), e.g. the rest of a
        reduction's time budget; the watchdog applies as well. `record`: the probe's runs record their full
        detail (`Run.detail`)."""
        ...

    def close(self) -> None: ...

    def __enter__(self) -> Self: ...

    def __exit__(self, *exc: object) -> None: ...


def check_watchdog(watchdog: float | str | None) -> float | str | None:
    """`watchdog` as seconds, 'auto' or None; `DEFAULT` reads $DDENV_PROBE_TIMEOUT (else 'auto')."""
    from pytest_ddenv.execution.errors import PoolConfigError

    where = "watchdog"
    if watchdog is DEFAULT:
        text = os.environ.get(WATCHDOG_ENV, "").strip().lower()
        if text in ("", "auto"):
            return "auto"
        if text in ("none", "off", "0"):
            return None
        where = f"${WATCHDOG_ENV}"
        try:
            watchdog = float(text)
        except ValueError:
            watchdog = math.nan
        if not math.isfinite(watchdog) or not watchdog > 0:
            raise PoolConfigError(expected("a number of seconds > 0, 'auto' or 'none'", text, where))
    if watchdog is None or watchdog == "auto":
        return watchdog
    if not is_finite_number(watchdog) or not watchdog > 0:
        raise PoolConfigError(expected("a number of seconds > 0, 'auto' or None", watchdog, where))
    return float(watchdog)


def limit_of(watchdog: float | None, deadline: float | None, now: float) -> tuple[float | None, bool]:
    """(seconds a probe may run, whether the caller's `deadline` (monotonic time) is what limits it)."""
    left = None if deadline is None else max(0.0, deadline - now)
    if left is not None and (watchdog is None or left < watchdog):
        return left, True
    return watchdog, False


class ClusterPoolBase:
    """What a pool on a distributed cluster (`DaskPool`, `RayPool`) keeps of the `Pool` API: its size, its
    statistics and its watchdog (`watchdog` as `check_watchdog` takes it; 'auto' is max(`floor`, `factor` x
    the longest run so far)). Its probes never run in this process."""

    def __init__(self, size: int, watchdog: float | str | None, floor: float, factor: float) -> None:
        self._size = size
        self._watchdog = check_watchdog(watchdog)
        self._floor, self._factor = float(floor), float(factor)
        self._stats = StatsBook(size)

    @property
    def size(self) -> int:
        return self._size

    @property
    def in_process(self) -> bool:
        return False

    @property
    def stats(self) -> PoolStats:
        return self._stats.snapshot()

    def watchdog_seconds(self, size: int = 0) -> float | None:
        """See `LocalPool.watchdog_seconds`."""
        if self._watchdog == "auto":
            return self._stats.watchdog(self._floor, self._factor, size, run_cap_of(getattr(self, "job", None)))
        return self._watchdog  # type: ignore[return-value]

    def expect(self, seconds: float, size: int = 0) -> None:
        """See `LocalPool.expect`."""
        self._stats.expect(seconds, size)
