"""`check_independence`: before reducing, does the world without its reducible elements (those the
preconditions allow to remove) reproduce f in one run? Then the failure does not depend on the elements
and the reduction ends at once ("world-independent")."""

from __future__ import annotations

from collections.abc import Sequence

from pytest_ddenv.reduce.extra_runs import ExtraRuns
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.refusals import refused
from pytest_ddenv.reduce.rounds import FullWorld
from pytest_ddenv.reduce.types import Candidate, Precondition

INDEPENDENCE = "independence"
"""The log's purpose of the run of the world without its reducible elements (`check_independence`)."""
WORLD_INDEPENDENT = "world-independent"
"""The incomplete reason of a reduction that found the failure independent of the elements."""


def without_removable(preconditions: Sequence[Precondition], current: Sequence[str], keep: frozenset[str],
                      full: FullWorld) -> Candidate | None:
    """The world without every element of `current` the preconditions allow to remove (when they refuse the
    world without all of them, each element whose single removal they refuse stays, N checks); None when
    that world is refused too or keeps every element."""
    empty = full(())
    needed: tuple[str, ...] = ()
    if refused(preconditions, empty) is not None:  # only then look for the elements the preconditions need
        whole = full(current)
        needed = tuple(name for at, name in enumerate(whole) if name not in keep
                       and refused(preconditions, whole[:at] + whole[at + 1:]) is not None)
        empty = full(needed)
    if len(needed) == len(current) or refused(preconditions, empty) is not None:
        return None
    return empty


def reproduces_without_elements(preconditions: Sequence[Precondition], current: Sequence[str],
                                keep: frozenset[str], full: FullWorld, *, log: ProbeLog | None,
                                extra_runs: ExtraRuns) -> bool:
    """Whether the world without every reducible element the preconditions allow to remove reproduces f
    in one run (attempt 0, the reference's). Logged with purpose "independence" (a resumed `log` answers
    without a simulation)."""
    empty = without_removable(preconditions, current, keep, full)
    if empty is None:
        return False
    known = log.measured(INDEPENDENCE, empty) if log is not None else {}
    fails, runs = extra_runs.measure(empty, 0, 1, purpose=INDEPENDENCE, known=known, strict=True)
    return runs == 1 and fails == 1
