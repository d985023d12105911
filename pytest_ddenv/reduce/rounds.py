"""What one ddmin round tries: its plan (the parts in priority and removal order), its trials (subsets, then
complements, likely failures last), the grown removal of a carried round, and the next round's granularity.

Pure functions of the current world, the settings and the learner's context: the engine (`engine.py`) plays
the round and adopts what it finds. See docs/algorithm.md.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.context import Context
from pytest_ddenv.reduce.settings import Settings
from pytest_ddenv.reduce.trial import Trial
from pytest_ddenv.reduce.types import Candidate

GROWN_MIN_PARTS = 8
"""The fewest parts a carried round needs for a grown removal (`grown_removal`)."""

Part = tuple[str, ...]
FullWorld = Callable[[Sequence[str]], Candidate]
"""The candidate of some reducible elements: them and the `keep` elements, in the original order."""


@dataclass(frozen=True)
class Plan:
    """The parts of one round: `ordered` by priority (subsets), `removal` the order complements are tried."""

    ordered: list[Part]
    removal: list[Part]
    subsets: bool
    """False when every part alone is already known not to reproduce f (a carried-over round)."""

    def without(self, removed: Sequence[Part]) -> Plan:
        """The next round after removing the parts `removed` (one, or the next few in removal order: a grown
        removal): same parts and order, continuing after the first removed one (picire's complement offset),
        subsets not tried again (they all failed in this round)."""
        at, gone = self.removal.index(removed[0]), set(removed)
        return Plan(
            ordered=[part for part in self.ordered if part not in gone],
            removal=[part for part in self.removal[at + 1 :] + self.removal[:at] if part not in gone],
            subsets=False,
        )


def fresh_plan(settings: Settings, current: tuple[str, ...], granularity: int, context: Context,
               round_index: int) -> Plan:
    """The parts of a new round of the `current` world (partition schema), in priority order."""
    parts = settings.partitioner(current, granularity, context)
    check_parts(settings, current, parts)
    ordered = list(settings.prioritizer(parts, context, round_index))
    removal = ordered[::-1] if settings.complement_order == "reverse" else ordered
    return Plan(ordered=ordered, removal=removal, subsets=True)


def check_parts(settings: Settings, current: Sequence[str], parts: Sequence[Sequence[str]]) -> None:
    flat = [name for part in parts for name in part]
    if any(len(part) == 0 for part in parts) or sorted(flat) != sorted(current):
        raise ReductionError(
            f"partition schema {settings.partitioner.name!r} must return non-empty, disjoint parts "
            f"covering the current world, got {[list(part) for part in parts]!r}"
        )


def trials_of(plan: Plan, current: Sequence[str], full: FullWorld, *, keep: frozenset[str],
              below: Sequence[frozenset[str]], context: Context) -> list[tuple[Trial, tuple[Part, ...]]]:
    """Subsets in priority order, then complements in removal order, without repeats or no-ops. Those inside
    a world that failed significantly less often (`below`) or inside a rejected candidate go last."""
    members_now = set(current)
    seen = {frozenset(current)}
    trials: list[tuple[Trial, tuple[Part, ...]]] = []
    for kind, parts in (("subset", plan.ordered if plan.subsets else []), ("complement", plan.removal)):
        for part in parts:
            members = frozenset(part) if kind == "subset" else frozenset(members_now - set(part))
            if members in seen:
                continue
            seen.add(members)
            trials.append((Trial(full(tuple(members)), kind), (part,)))
    rejected = [verdict.members for verdict in context.history if not (verdict.reproduces or verdict.errored)]
    if below or rejected:  # likely not to reproduce f: tried last (reordered, never skipped)
        trials.sort(key=lambda entry: dominated(frozenset(entry[0].candidate), keep, below, rejected))
    return trials


def dominated(candidate: frozenset[str], keep: frozenset[str], below: Sequence[frozenset[str]],
              rejected: Sequence[frozenset[str]]) -> tuple[bool, bool]:
    """(inside a world that failed significantly less often: likely the same drift; inside a candidate
    that did not reproduce f: a monotone failure would not either), the sort key of `trials_of`."""
    members = candidate - keep
    return (any(candidate <= world for world in below), any(members <= world for world in rejected))


def grown_removal(plan: Plan, streak: int, granularity: str, current: Sequence[str],
                  full: FullWorld) -> tuple[Trial, tuple[Part, ...]] | None:
    """After `streak` carried rounds in a row adopted their first candidate (the parts being removed one by
    one do not matter), the next 2**streak parts in removal order removed at once, tried before the
    round's own candidates (ddmin's one part a round costs a probe per part; this, about log2 of them).
    Never more than half of the other parts, and only from GROWN_MIN_PARTS parts on: a wrong guess costs
    a rejection (with `deflake=N`, N + 1 runs), more than ddmin's one part a probe saves in a small round.
    None before a streak and with the paper's `granularity`."""
    if streak == 0 or granularity != "ddmin" or len(plan.removal) < GROWN_MIN_PARTS:
        return None
    count = min(2**streak, (len(plan.removal) - 1) // 2)
    if count < 2:
        return None
    parts = tuple(plan.removal[:count])
    removed = {name for part in parts for name in part}
    return Trial(full(tuple(name for name in current if name not in removed)), "complement"), parts


def next_granularity(settings: Settings, n: int, size: int, progress: str | None, removed: int = 1) -> int:
    """The granularity after a round of `n` parts that adopted a subset, a complement (of `removed` parts),
    or nothing (None), the current world having `size` elements."""
    if settings.granularity == "paper":
        return max(1, min(n + 1, size))
    if progress == "subset":
        return max(1, min(settings.n_partitions, size))
    if progress == "complement":
        return max(1, min(max(n - removed, 2), size))
    return max(1, min(2 * n, size))
