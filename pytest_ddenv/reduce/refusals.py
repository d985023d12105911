"""What the preconditions refuse: the reason for one candidate, the elements of the minimal world that only
a precondition kept, and whether the minimal world still fails without them (a few runs, preconditions
bypassed: information for the reader, not part of the verdict)."""

from __future__ import annotations

from collections.abc import Callable, Sequence

from pytest_ddenv.reduce.rate_check import RateChecker
from pytest_ddenv.reduce.rates import Rate
from pytest_ddenv.reduce.rounds import FullWorld
from pytest_ddenv.reduce.types import Candidate, Precondition


def refused(preconditions: Sequence[Precondition], candidate: Candidate) -> str | None:
    """Why a precondition refuses `candidate` (None: none does)."""
    return next((str(reason) for check in preconditions if (reason := check(candidate)) is not None), None)


def precondition_kept(preconditions: Sequence[Precondition], current: Sequence[str],
                      full: FullWorld) -> tuple[tuple[str, str], ...]:
    """(element, reason) for each element of the `current` world whose removal a precondition refused (it
    was not shown needed for the failure, only for the scenario to be valid)."""
    kept: list[tuple[str, str]] = []
    for name in current:
        reason = refused(preconditions, full(tuple(other for other in current if other != name)))
        if reason is not None:
            kept.append((name, reason))
    return tuple(kept)


def rate_without_kept(preconditions: Sequence[Precondition], current: Sequence[str], full: FullWorld,
                      rates: RateChecker, exhausted: Callable[[], str | None]) -> tuple[Candidate, Rate] | None:
    """The `current` (minimal) world without its precondition-kept elements and its rate on attempts 0, 1
    and 2 (at most the first look); None when there are none, the rate comparison is off or the budget is
    `exhausted`."""
    kept = {name for name, _ in precondition_kept(preconditions, current, full)}
    if not kept or not rates.looks or exhausted():
        return None
    world = full(tuple(name for name in current if name not in kept))
    return world, rates.rate(world, 0, min(3, rates.looks[0]))
