"""The chain of accepted worlds and backing off along it: the drift watch on its last world, and, when the
minimal world (or, for the drift watch, the last accepted one) fails significantly less often than the
original, the search for the last accepted world whose rate holds, the rejection of every later one
("rate-below") and the note the result carries.

The engine (`engine.py`) goes on reducing from the world the back-off finds; the rate comparisons and the
drift watch themselves are `rate_check.py`'s. See docs/algorithm.md.
"""

from __future__ import annotations

from collections.abc import Callable, MutableMapping, Sequence
from dataclasses import dataclass
from typing import Any

from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.context import Context, Verdict
from pytest_ddenv.reduce.rate_check import DriftWatch, RateChecker
from pytest_ddenv.reduce.rates import Rate, RateComparison
from pytest_ddenv.reduce.result import plural
from pytest_ddenv.reduce.types import Candidate, Decision, Outcome, Trace

MAX_BACKOFFS = 3
"""How many times a reduction backs off from a minimal world that fails significantly less often than the
original before it reports that world with its rate as it is."""


@dataclass(frozen=True)
class Step:
    """An accepted world of the reduction (the original first), with the first attempt that was not used
    to accept it (its fresh runs start there) and the trace of the failure it was accepted on."""

    world: Candidate
    fresh_from: int
    trace: Trace | None


def last_holding(chain: Sequence[Step], rates: RateChecker, *, during: bool) -> int | None:
    """The index in `chain` of the last accepted world whose rate holds, its last world being "below": back
    from the end, 1, 2, 4 ... worlds, then a binary search. `during` (the drift watch caught the last accepted
    world): the world before it, unsearched. None when the budget stopped the search."""
    good, bad = (len(chain) - 2 if during else 0), len(chain) - 1
    end, distance = bad, 1
    while bad - good > 1:
        if distance and end - distance > good:  # first back from the end, 1, 2, 4 ... worlds: drift comes late
            middle, distance = end - distance, 2 * distance
        else:  # then a binary search between the last world that holds and the first below
            middle, distance = (good + bad) // 2, 0
        comparison = rates.compare(chain[middle].world, chain[middle].fresh_from)
        if comparison is None or comparison.decision == "continue":
            return None
        if comparison.decision == "holds":
            good, distance = middle, 0
        else:
            bad = middle
    return good


def reject_below(rejected: Sequence[Step], rates: RateChecker, cache: MutableMapping[Any, Any], context: Context,
                 keep: frozenset[str], write: Callable[[events.Event], None]) -> None:
    """Reject each of the `rejected` accepted worlds for its rate: its fresh runs become its decision (in the
    cache, the learner's history and a "rate-below" record)."""
    for step in rejected:
        outcomes = rates.record_of(step.world).values()
        fails = sum(outcome is Outcome.FAIL for outcome in outcomes)
        runs = sum(outcome is not Outcome.ERROR for outcome in outcomes)
        cache[frozenset(step.world)] = Decision(reproduces=False, fails=fails, runs=runs)
        context.history.append(Verdict(frozenset(step.world) - keep, False))
        write(events.RateBelow(candidate=step.world, reproduces=False, fails=fails, runs=runs))


def backoff_note(number: int, rejected: Sequence[Step], back: Step, below: RateComparison, *, during: bool) -> str:
    """The result's note on back-off `number`, from `rejected[-1]` (the world found below) to `back`."""
    return (
        f"back-off {number}: a {len(rejected[-1].world)}-element "
        f"{'accepted world (drift watch, during the reduction)' if during else 'minimal world'} failed "
        f"{'' if below.search else 'significantly '}less often than the original ({below.describe()}); "
        f"{plural(len(rejected), 'accepted world')} rejected for it, reduction resumed from "
        f"{len(back.world)} elements")


class AcceptedChain:
    """The accepted worlds since the original (or since the last back-off's good world), in order, the drift
    watch on the last one, and the back-offs made from them."""

    def __init__(self, original: Step, rates: RateChecker, cache: MutableMapping[Any, Any]) -> None:
        self.steps: list[Step] = [original]
        self.rates = rates
        self.cache = cache
        self.drift = DriftWatch(rates)
        self.backoffs = 0
        self.drift_backoffs = 0
        """Back-offs of the drift watch (during the reduction); the end of the run has MAX_BACKOFFS of its own."""
        self.notes: list[str] = []
        """One per back-off, for the result."""

    def watch_drift(self) -> None:
        """A round's first rejection: watch the current accepted world for drift (rate_check.DriftWatch)."""
        if len(self.steps) > 1 and self.drift_backoffs < MAX_BACKOFFS:
            step = self.steps[-1]
            decision = self.cache.get(frozenset(step.world))
            self.drift.check(step.world, step.fresh_from, decision if isinstance(decision, Decision) else None)

    def compare_last(self) -> RateComparison | None:
        """The end of the run's rate comparison of the last accepted world with the original."""
        return self.rates.compare(self.steps[-1].world, self.steps[-1].fresh_from)

    def may_back_off_at_end(self) -> bool:
        return self.backoffs - self.drift_backoffs < MAX_BACKOFFS

    def back_off(self, below: RateComparison, *, during: bool, context: Context, keep: frozenset[str],
                 write: Callable[[events.Event], None]) -> Step | None:
        """The last world (`during`: the drift watch's) is `below`: find the last accepted world whose rate
        holds (`last_holding`), reject every later one (`reject_below`), and return it, now the chain's last.
        None when the budget stopped the search."""
        good = last_holding(self.steps, self.rates, during=during)
        if good is None:
            return None
        rejected = self.steps[good + 1:]
        reject_below(rejected, self.rates, self.cache, context, keep, write)
        self.backoffs += 1
        back = self.steps[good]
        del self.steps[good + 1:]
        self.notes.append(backoff_note(self.backoffs, rejected, back, below, during=during))
        return back

    def minimal_rate(self, rate_check: RateComparison | None) -> Rate | None:
        """The last world's fresh runs: those of the rate comparison `rate_check`, or (nothing was removed, or
        no comparison was made) the first look; None when the rate comparison is off."""
        if rate_check is not None:
            return rate_check.reduced
        if not self.rates.looks:
            return None
        if len(self.steps) == 1:
            return self.rates.original_rate(self.rates.looks[0])
        return self.rates.rate(self.steps[-1].world, self.steps[-1].fresh_from, self.rates.looks[0])
