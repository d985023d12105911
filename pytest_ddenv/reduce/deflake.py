"""Deflake policies: from the outcomes of a candidate's runs so far, decide f / not f / run again.

`FixedReruns(n)` is the paper's rule: a candidate whose first run is not f is re-run up to n more times
and reproduces f as soon as one run does. A world that fails once in four runs therefore "reproduces f"
under this rule (the rule is biased toward accepting reductions; the final failure rate tells).

`SequentialTest` (``deflake="adaptive"``) is Wald's sequential probability ratio test of
H0: P(f) <= 0.05 ("f is not reproduced, only noise") against H1: P(f) >= 0.5 ("f is reproduced"), with
both error probabilities 1 - confidence. It stops as soon as the evidence is conclusive, and it also
confirms accepted candidates: at confidence 0.95 one f is not enough (two are), and five runs without f
reject. After `max_runs` runs without a conclusion it decides on the observed rate.

`CalibratedReruns` (``deflake="auto"``) measures how often the original world reproduces f before the
first round (3 extra runs, 5 unless all 3 reproduce f) and then decides candidates by a `ConfirmedRuns`
rule sized from that rate: a failure that reproduces at least half of the time must be confirmed by 2 f
runs (so a world that fails only by luck is seldom accepted), with just enough runs that a candidate
failing as often as the original is rejected with probability at most 1 - confidence.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.rates import Rate, chance_at_most, estimated
from pytest_ddenv.reduce.types import Outcome
from pytest_ddenv.validation import expected, is_integer, is_number

DEFLAKE_POLICIES: tuple[str, ...] = ("adaptive", "auto")
"""Named policies; `deflake` also accepts a non-negative int (fixed re-runs, at most `MAX_DEFLAKE`)."""
MAX_DEFLAKE = 100
"""The most fixed re-runs per candidate `deflake=N` accepts (101 runs; the adaptive test stops after 30, auto
after 10): more re-runs say nothing new about a failure and a typo such as 10**12 would never end."""


class DeflakePolicy(Protocol):
    """Decides from the outcomes so far: True (reproduces f), False (does not), None (run again)."""

    def verdict(self, outcomes: Sequence[Outcome]) -> bool | None: ...

    @property
    def label(self) -> int | str: ...


@dataclass(frozen=True)
class FixedReruns:
    """The paper's rule: f on any of 1 + reruns runs; stop at the first f."""

    reruns: int

    @property
    def label(self) -> int:
        return self.reruns

    @property
    def max_runs(self) -> int:
        return self.reruns + 1

    def verdict(self, outcomes: Sequence[Outcome]) -> bool | None:
        if Outcome.FAIL in outcomes:
            return True
        if len(outcomes) >= self.reruns + 1:
            return False
        return None


@dataclass(frozen=True)
class SequentialTest:
    """Wald's SPRT on the rate of f; ERROR, PASS and OTHER all count as "not f"."""

    confidence: float = 0.95
    noise_rate: float = 0.05
    """P(f) under H0: a world that does not reproduce f."""
    reproduce_rate: float = 0.5
    """P(f) under H1: a world that reproduces f."""
    max_runs: int = 30

    @property
    def label(self) -> str:
        return "adaptive"

    def verdict(self, outcomes: Sequence[Outcome]) -> bool | None:
        fails = sum(1 for outcome in outcomes if outcome is Outcome.FAIL)
        others = len(outcomes) - fails
        error = 1.0 - self.confidence
        upper = math.log((1.0 - error) / error)
        lower = math.log(error / (1.0 - error))
        ratio = fails * math.log(self.reproduce_rate / self.noise_rate) + others * math.log(
            (1.0 - self.reproduce_rate) / (1.0 - self.noise_rate)
        )
        if ratio >= upper:
            return True
        if ratio <= lower:
            return False
        if len(outcomes) >= self.max_runs:
            return fails / len(outcomes) >= (self.noise_rate + self.reproduce_rate) / 2.0
        return None


@dataclass(frozen=True)
class ConfirmedRuns:
    """f on at least `confirm` of at most `max_runs` runs; stops as soon as the verdict is certain.

    `ConfirmedRuns(n + 1, 1)` is `FixedReruns(n)`. With `confirm=2` one lucky f is not enough, so a world that
    reproduces f only rarely is seldom accepted.
    """

    max_runs: int
    confirm: int = 1

    @property
    def label(self) -> str:
        return f"{self.confirm}-of-{self.max_runs}"

    def verdict(self, outcomes: Sequence[Outcome]) -> bool | None:
        fails = sum(1 for outcome in outcomes if outcome is Outcome.FAIL)
        if fails >= self.confirm:
            return True
        if fails + self.max_runs - len(outcomes) < self.confirm:
            return False
        return None


@dataclass(frozen=True)
class CalibratedReruns:
    """`deflake="auto"`: a `ConfirmedRuns` rule sized from the original world's failure rate, measured
    before the first round (see the module docstring and docs/algorithm.md §6)."""

    confidence: float = 0.95
    runs: int = 5
    """Extra runs of the original world (attempts 1 .. runs; attempt 0 is the reference failure)."""
    sure_runs: int = 3
    """Stop after this many extra runs if every one of them reproduced f."""
    max_runs: int = 10

    @property
    def label(self) -> str:
        return "auto"

    def rule_for(self, fails: int, runs: int) -> ConfirmedRuns:
        """The rule for a failure that reproduced `fails` times in `runs` calibration runs.

        The rate is estimated as p = (fails + 0.5) / (runs + 1), never 0 or 1. A failure that reproduces at
        least half of the time must be confirmed (2 f runs); a rarer one needs 1. The number of runs is the
        smallest n such that a world failing at rate p shows fewer than `confirm` f in n runs with
        probability at most 1 - confidence (capped at `max_runs`): 3/3 or 5/5 give 2-of-3, 3/5 2-of-6,
        2/5 1-of-6, 1/5 or fewer 1-of-10.
        """
        rate = estimated(Rate(fails, runs))
        confirm = 2 if rate >= 0.5 else 1
        for count in range(confirm, self.max_runs + 1):
            if chance_at_most(confirm - 1, count, rate) <= 1.0 - self.confidence:
                return ConfirmedRuns(count, confirm)
        return ConfirmedRuns(self.max_runs, confirm)

    def verdict(self, outcomes: Sequence[Outcome]) -> bool | None:
        raise ReductionError("deflake='auto' must be calibrated on the original world before deciding candidates")


def runs_worth_starting_ahead(policy: DeflakePolicy) -> int:
    """How many runs of one candidate may be started before the earlier ones are back: a fixed-length rule's
    maximum (`FixedReruns`, `ConfirmedRuns`), else 0 (the adaptive test decides one run at a time)."""
    return policy.max_runs if isinstance(policy, (FixedReruns, ConfirmedRuns)) else 0


def make_policy(deflake: int | str | DeflakePolicy, confidence: float) -> DeflakePolicy:
    """`deflake` is a non-negative int (fixed re-runs, also as a digit string), "adaptive", "auto", or a
    decided rule (`FixedReruns`, `ConfirmedRuns`, `SequentialTest`: the stages after the model-level
    reduction reuse the rule it calibrated)."""
    if isinstance(deflake, (FixedReruns, ConfirmedRuns, SequentialTest)):
        return deflake
    if not is_number(confidence) or not 0.5 < confidence < 1.0:
        raise ReductionError(expected("a number strictly between 0.5 and 1", confidence, "confidence"))
    most = f"at most {MAX_DEFLAKE} re-runs per candidate"
    if isinstance(deflake, str) and deflake.strip().isdigit():
        digits = deflake.strip()
        if len(digits) > 20:  # int() of 5000 digits raises ValueError; it is out of bounds anyway
            raise ReductionError(expected(most, digits, "deflake", got=f"a {len(digits)}-digit number"))
        deflake = int(digits)
    if is_integer(deflake):
        if deflake < 0:
            raise ReductionError(expected("an integer >= 0 (re-runs), 'adaptive' or 'auto'", deflake, "deflake"))
        if deflake > MAX_DEFLAKE:
            size = str(deflake) if deflake.bit_length() <= 64 else f"a {deflake.bit_length()}-bit number"
            raise ReductionError(
                f"{expected(most, deflake, 'deflake', got=size)}; for a very flaky "
                "failure use deflake='auto' (calibrated on the original world) or 'adaptive'"
            )
        return FixedReruns(deflake)
    if deflake == "adaptive":
        return SequentialTest(confidence=float(confidence))
    if deflake == "auto":
        return CalibratedReruns(confidence=float(confidence))
    raise ReductionError(
        expected(f"an integer >= 0 (fixed re-runs) or one of {', '.join(DEFLAKE_POLICIES)}", deflake, "deflake")
    )
