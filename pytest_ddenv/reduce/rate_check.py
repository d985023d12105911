"""The end of a reduction: does the reduced world still fail as often as the original?

Both worlds are run on fresh attempts (the original's after its reference run, a reduced world's after the
runs it was accepted on: runs selected for failing are never counted) and compared look by look with
`rates.compare` (a one-sided group-sequential Fisher test, see rates.py and docs/algorithm.md): this module
runs and logs, the statistics are rates.py's. Every run is
logged with purpose "failure-rate", so a resumed reduction reuses them; the original world's calibration
runs (deflake="auto") count as its first fresh runs, once: they are the original's attempts 1, 2, ... and a
fresh run is one attempt, whatever made it. At each look the reduced world runs first; the original's runs
of the look that no outcome could make matter are not started (`rates.settled`).

Drift is watched during the reduction too (`DriftWatch`): an accepted world that showed a non-failing run
while being decided, or whose confirming fresh runs (its first fresh attempts up to attempt 2, made at the
first rejection of a new candidate after it was accepted) do not all fail, is tested there, while the
original has failed every fresh run so far: a search decision on the comparison's first look (and its
second, when the first held on a non-failing run) at `rates.SEARCH_LEVEL` (`rates.search_below`), not the
guarantee; "below" ends the round (`Drift`) and the
engine backs off, before a whole reduction is built on it. The end-of-run comparison of the minimal world is
unchanged and makes the guarantee.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.extra_runs import ExtraRuns
from pytest_ddenv.reduce.log import ProbeLog
from pytest_ddenv.reduce.rates import SEARCH_LEVEL, Rate, RateComparison, compare, looks_up_to, search_below, settled
from pytest_ddenv.reduce.types import Candidate, Decision, Outcome


class Drift(Exception):
    """An accepted world's rate compared "below" the original's during the reduction (`DriftWatch`)."""

    def __init__(self, comparison: RateComparison) -> None:
        super().__init__(comparison.describe())
        self.comparison = comparison


class RateChecker:
    """Runs worlds on fresh attempts and compares each with the original world (whose runs are shared)."""

    def __init__(self, extra_runs: ExtraRuns, log: ProbeLog | None, original: Candidate, max_runs: int,
                 write: Callable[[events.Event], None]) -> None:
        self.extra_runs = extra_runs
        self.log = log
        self.original = original
        self.looks = looks_up_to(max_runs)
        self.write = write
        self.below: list[frozenset[str]] = []
        """Worlds this reduction's comparisons called "below"."""
        self.outcomes: dict[frozenset[str], dict[int, Outcome]] = {}
        """world -> attempt -> outcome of its fresh runs so far (ERROR runs included; they are not counted)."""

    def record_of(self, world: Candidate) -> dict[int, Outcome]:
        """The outcomes of `world`'s fresh runs, to be filled by ExtraRuns.measure(into=...)."""
        return self.outcomes.setdefault(frozenset(world), {})

    def rate(self, world: Candidate, first: int, target: int) -> Rate:
        """`world`'s failures among `target` fresh runs (attempts from `first`; an ERROR run is replaced by
        one more attempt, once); fewer runs when the budget runs out."""
        outcomes = self.record_of(world)
        end = first + target
        for _ in range(2):
            known = {**self._logged(world), **outcomes}
            self.extra_runs.measure(world, first, end - first, known=known, into=outcomes)
            present = [outcome for attempt, outcome in outcomes.items() if first <= attempt < end]
            counted = [outcome for outcome in present if outcome is not Outcome.ERROR]
            if len(counted) >= target or len(present) < end - first:
                break
            end += target - len(counted)
        counted = [o for a, o in sorted(outcomes.items()) if first <= a < end and o is not Outcome.ERROR][:target]
        return Rate(sum(outcome is Outcome.FAIL for outcome in counted), len(counted))

    def original_rate(self, target: int) -> Rate:
        return self.rate(self.original, 1, target)

    def known_original(self, look: int) -> Rate:
        """The original's fresh runs already made (this run's or a resumed log's), from attempt 1 up to the
        first one not made: the first of those `original_rate(look)` would count (an ERROR run is not)."""
        known = {**self._logged(self.original), **self.record_of(self.original)}
        counted: list[Outcome] = []
        attempt = 1
        while attempt in known and len(counted) < look:
            if known[attempt] is not Outcome.ERROR:
                counted.append(known[attempt])
            attempt += 1
        return Rate(sum(outcome is Outcome.FAIL for outcome in counted), len(counted))

    def compare(self, world: Candidate, first: int) -> RateComparison | None:
        """Compare `world` (fresh attempts from `first`) with the original, look by look; None when the
        comparison is switched off (max_runs 0). The decision is "continue" when the budget stopped it.
        Logged as a "rate-check" record."""
        comparison: RateComparison | None = None
        for look in self.looks:
            reduced = self.rate(world, first, look)  # the reduced world first: its rate is the one reported
            if reduced.runs == look and (early := settled(self.known_original(look), look, reduced, self.looks)):
                comparison = early
                if early.decision != "continue":
                    break
                continue
            original = self.original_rate(look)
            comparison = compare(original, reduced, self.looks)
            if reduced.runs < look or original.runs < look:  # the budget ran out: no verdict on so few runs
                comparison = replace(comparison, decision="continue")
                break
            if comparison.decision != "continue":
                break
        if comparison is not None:
            if comparison.decision == "below":
                self.below.append(frozenset(world))
            self.write(events.RateCheck(
                candidate=tuple(world), original=(comparison.original.fails, comparison.original.runs),
                reduced=(comparison.reduced.fails, comparison.reduced.runs), p_value=comparison.p_value,
                decision=comparison.decision))
        return comparison

    def below_worlds(self) -> list[frozenset[str]]:
        """The worlds this reduction's comparisons called "below" so far (a resumed one makes the same
        comparisons at the same points, from its log, so it knows them at the same points too)."""
        return self.below

    def _logged(self, world: Candidate) -> dict[int, Outcome]:
        if self.log is None:
            return {}
        logged = self.log.measured("failure-rate", world)
        if frozenset(world) == frozenset(self.original):
            logged = {**self.log.measured("calibration", world), **logged}
        return logged


SEARCH_LOOKS = 2
"""The drift watch's test looks at most at the comparison's first SEARCH_LOOKS looks (5, then 10 runs)."""

WATCHED_RUNS = 3
"""An accepted world whose deciding runs all failed is watched until its first `WATCHED_RUNS` attempts are
made: a world failing at rate p shows a non-failing one among them with probability 1 - p^3 (78 % at 50 %,
94 % at 40 %), a world failing every run costs its confirming runs only when it is not the minimal one."""


class DriftWatch:
    """Drift during the reduction: each accepted world is watched once, at the first rejection after it was
    accepted (the engine calls `check`), while every fresh run of the original so far failed.

    - The runs that decided the world included a non-failing one (a pass or another failure; an ERROR run is
      no outcome of the world and does not count): it is tested at once (its fresh runs, never the ones that
      decided it).
    - Otherwise confirming fresh runs up to its attempt `WATCHED_RUNS` - 1 (any-of-N accepts on one failing
      run: attempts 1 and 2; `auto`'s 2-of-3 on two: attempt 2), the first fresh attempts, those the end-of-run
      comparison would make first; all failing leaves it be, any other outcome starts the test there, with
      them as its first runs.
    The test is a search decision (`rates.search_below` at `rates.SEARCH_LEVEL`): the world's fresh runs up
    to the comparison's first look against the original's first ones (calibration runs included; the
    original's runs no outcome could make matter are not started), then, when that held but the world showed a
    non-failing run and the original's first look (made then) failed every run, up to its second look
    (`SEARCH_LOOKS`). Every run is one the end-of-run comparison
    reuses if the world stays the minimal one, and it decides that world at its own level, unchanged;
    "below" raises `Drift`. Every run is logged, so a resumed reduction answers from the log."""

    def __init__(self, rates: RateChecker) -> None:
        self.rates = rates
        self.watched: set[frozenset[str]] = set()

    def check(self, world: Candidate, first: int, decision: Decision | None) -> RateComparison | None:
        """Watch `world` (fresh attempts from `first`, accepted on `decision`) unless it was already watched
        or the original has shown a non-failing fresh run; the test made, if any. Raises `Drift` when it is
        "below"."""
        key = frozenset(world)
        if key in self.watched or not self.rates.looks:
            return None
        original = self.rates.known_original(self.rates.looks[-1])
        if original.fails < original.runs:  # a flaky original: a pass says nothing; the end of the run tells
            return None
        self.watched.add(key)
        if decision is None or decision.fails == decision.runs - decision.errors:  # an ERROR says nothing
            confirming = WATCHED_RUNS - (1 if decision is None else decision.runs)
            confirmed = self.rates.rate(world, first, confirming) if confirming > 0 else Rate(0, 0)
            if confirmed.runs == 0 or confirmed.fails == confirmed.runs:
                return None
        comparison = self.test(world, first)
        if comparison.decision == "below":
            self.rates.below.append(key)
            raise Drift(comparison)
        return comparison

    def test(self, world: Candidate, first: int) -> RateComparison:
        """The search decision on `world`'s fresh runs (logged as a "rate-check" record): at the comparison's
        first look, then, when that held but the world showed a non-failing run while the original's first look
        failed every run, at its second (`SEARCH_LOOKS`); "continue" when the budget stopped the runs."""
        looks = self.rates.looks[:SEARCH_LOOKS]
        for index, look in enumerate(looks):
            decided = self.look(world, first, look)
            if decided.decision != "holds" or index == len(looks) - 1 or \
                    decided.reduced.fails == decided.reduced.runs:
                break
            original = self.rates.original_rate(look)  # made once: every later comparison reuses them
            if original.fails < original.runs:  # a flaky original: the world's passes say nothing
                break
        self.rates.write(events.RateCheck(
            candidate=tuple(world), original=(decided.original.fails, decided.original.runs),
            reduced=(decided.reduced.fails, decided.reduced.runs), p_value=decided.p_value,
            decision=decided.decision))
        return decided

    def look(self, world: Candidate, first: int, look: int) -> RateComparison:
        """One look of the search decision: `world`'s fresh runs up to `look` against the original's first
        `look` (those no outcome could make matter are not started)."""
        reduced = self.rates.rate(world, first, look)
        decided = search_below(self.rates.known_original(look), reduced, look)
        if decided is None:  # the original's missing runs could change the decision
            original = self.rates.original_rate(look)
            decided = search_below(original, reduced, look) if original.runs == look else \
                RateComparison(original, reduced, 1.0, "continue", SEARCH_LEVEL, search=True)  # the budget ran out
            assert decided is not None
        return decided
