"""Prefetched probes: the engine's next probes, started on workers the current round leaves idle.

Near the end of a round the last undecided candidates often need fewer workers than there are. The
engine then names the probes it will start next if the round ends without a reproducing candidate (the
next round's first attempts, the verification pass, or the failure-rate runs), and they start at once.
A later request for the same (candidate, attempt) takes the running or finished future instead of
probing again. A probe is a function of (candidate, attempt), so using a prefetched result changes
nothing but the wall time; a guess that turns out wrong costs only an idle worker's time. Probes a
decided round no longer needs are kept here too, so no (candidate, attempt) is ever simulated twice.
"""

from __future__ import annotations

import concurrent.futures
from collections.abc import Callable, Collection
from typing import Any

from pytest_ddenv.reduce.types import Candidate

Key = tuple[frozenset[str], int]


class Prefetch:
    """Futures of probes started ahead of need, by (candidate as a set, attempt)."""

    def __init__(self) -> None:
        self.futures: dict[Key, concurrent.futures.Future[Any]] = {}

    def __contains__(self, key: Key) -> bool:
        return key in self.futures

    def start(self, key: Key, submit: Callable[[], concurrent.futures.Future[Any]]) -> None:
        self.futures[key] = submit()

    def adopt(self, candidate: Candidate, attempt: int, future: concurrent.futures.Future[Any]) -> None:
        """Keep a probe a decided round no longer needs (running or done): a later step may."""
        self.futures.setdefault((frozenset(candidate), attempt), future)

    def keep(self, candidate: Candidate, attempt: int, result: Any) -> None:
        """Keep the result of a probe that arrived after its candidate was decided (e.g. for the
        failure-rate runs of the minimal world, which continue its attempts)."""
        future: concurrent.futures.Future[Any] = concurrent.futures.Future()
        future.set_result(result)
        self.adopt(candidate, attempt, future)

    def take(self, candidate: Candidate, attempt: int) -> concurrent.futures.Future[Any] | None:
        """The prefetched future of this probe (removed from the store), or None."""
        return self.futures.pop((frozenset(candidate), attempt), None)

    def running(self) -> int:
        """Prefetched probes not finished yet (each holds a worker or waits for one)."""
        return sum(1 for future in self.futures.values() if not future.done())

    def cancel_except(self, wanted: Collection[frozenset[str]]) -> int:
        """Cancel the prefetched probes not started yet whose candidate is not `wanted`; how many were."""
        cancelled = [key for key, future in self.futures.items() if key[0] not in wanted and future.cancel()]
        for key in cancelled:
            del self.futures[key]
        return len(cancelled)

    def close(self) -> int:
        """Cancel what has not started and forget everything; the number of probes that ran in vain."""
        unused = sum(1 for future in self.futures.values() if not future.cancel())
        self.futures.clear()
        return unused
