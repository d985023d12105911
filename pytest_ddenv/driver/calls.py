"""The driver's way to the pool (`Calls`): every simulation of a reduction goes through it, so that it counts
them (the budget), stops them at the time budget's deadline, and keeps recent failing runs for the pictures."""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from typing import TYPE_CHECKING, Any

from pytest_ddenv.execution import Pool, ProbeDeadline
from pytest_ddenv.oracle.verdict import FailureReference, SameFailureRule, classify_result
from pytest_ddenv.reduce import Outcome, ProbeCancelled, ProbeObservation
from pytest_ddenv.scenario.probe import ProbeResult

if TYPE_CHECKING:
    from pytest_ddenv.reduce.types import Candidate, Probe
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World

PICTURE_RUNS_KEPT = 16
"""Failing runs kept in memory for the pictures (the accepted world's run is pinned at each step)."""


class Calls:
    """Runs the test on a world on `pool` (`__call__`, a `ProbeCall`): counts the probes it starts (`started`,
    for the budget), stops them at the time budget's `deadline`, and keeps recent failing runs for the
    pictures (no extra simulation for them)."""

    def __init__(self, pool: Pool[ProbeResult], reference: FailureReference, rule: SameFailureRule,
                 deadline: float | None) -> None:
        self.pool = pool
        self.reference = reference
        self.rule = rule
        self.deadline = deadline
        self.started = 0
        self._local = threading.local()
        self._lock = threading.Lock()
        self._runs: OrderedDict[frozenset[str], Run] = OrderedDict()
        self._pinned: tuple[frozenset[str], Run] | None = None

    def __call__(self, world: World, attempt: int, *, record: bool = False) -> ProbeResult:
        left = None if self.deadline is None else self.deadline - time.monotonic()
        if left is not None and left <= 0:
            self._local.cancelled = True
            raise ProbeDeadline("the reduction's time budget ran out before this probe started")
        with self._lock:
            self.started += 1
        try:
            options: dict[str, Any] = {"record": True} if record else {}
            if left is not None:
                options["timeout"] = left
            result = self.pool.call(world, attempt, **options)
        except ProbeDeadline:
            self._local.cancelled = True
            raise
        if not isinstance(result, ProbeResult):  # a job of the caller's that breaks the contract
            raise TypeError(f"the pool's job returned {type(result).__name__}, not a ProbeResult")
        if result.run is not None and classify_result(result.error, self.reference, self.rule) is Outcome.FAIL:
            with self._lock:
                key = frozenset(world.names)
                self._runs[key] = result.run
                self._runs.move_to_end(key)
                while len(self._runs) > PICTURE_RUNS_KEPT:
                    self._runs.popitem(last=False)
        return result

    def cancellable(self, probe: Probe) -> Probe:
        """`probe` (which calls this), raising `ProbeCancelled` when its simulation was stopped at the time
        budget's deadline: the engine records no outcome for it."""

        def cancellable_probe(candidate: Candidate, attempt: int) -> ProbeObservation:
            self._local.cancelled = False
            observation = probe(candidate, attempt)
            if self._local.cancelled:
                raise ProbeCancelled("budget: max_seconds")
            return observation

        return cancellable_probe

    def pin(self, candidate: tuple[str, ...]) -> None:
        """An accepted world: keep its failing run (if this process saw it) for the pictures."""
        key = frozenset(candidate)
        with self._lock:
            if key in self._runs:
                self._pinned = (key, self._runs[key])

    def run_of(self, names: tuple[str, ...], world: World, original: Run | None) -> Run | None:
        """A failing run of the world `names` seen during this reduction (the original's for no removal)."""
        key = frozenset(names)
        if key == frozenset(world.names) and original is not None:
            return original
        with self._lock:
            if self._pinned is not None and self._pinned[0] == key:
                return self._pinned[1]
            return self._runs.get(key)

    def may_start(self, max_probes: int | None) -> bool:
        """Another simulation is within the budgets."""
        if self.deadline is not None and time.monotonic() >= self.deadline:
            return False
        return max_probes is None or self.started < max_probes
