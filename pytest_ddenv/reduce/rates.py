"""Failure-rate statistics, all of them: the reduction's end-of-run comparison, the stages' "does the rate
drop", the deflake rule's sizing, `ddenv replay`'s confidence interval and the cross-engine confirmation's
flag (`clearly_below`). `rate_check.py` runs the worlds and logs the comparison; the numbers are decided
here.

Does a reduced world still fail as often as the original? A group-sequential one-sided test.

A deflake rule such as "2 of 3 runs" accepts a candidate that fails 40 % of its runs about a third of the
time; after dozens of candidates, the accepted minimal world can fail far less often than the original, and
calling it "the failure, minimal" would overstate. So at the end of a reduction both worlds are re-run with
fresh seeds and their failure rates compared:

- H0: the reduced world fails at least as often as the original; H1: less often.
- Fisher's exact test (one-sided, ``alternative="less"``) on the 2x2 table of fails and passes.
- Looks after `LOOKS` runs of each world (5, 10, then 20); the overall level `LEVEL` (5 %) is split evenly
  over the looks (Bonferroni), so the chance of calling an equally failing world "below" is at most 5 %.
- Stop early when the reduced world's observed rate is at least the original's (it cannot then be
  significantly below on these runs), or when the test rejects H0; after the last look, "holds".
- Curtailed (`settled`): at each look the reduced world runs first; the original's runs of that look that are
  not made yet (calibration runs count) are skipped when no outcome of theirs could change the look's
  decision. The decisions are exactly those of the full test, so are its level and power; only the cost
  falls (a reduced world failing 5 of 5 holds with no run of the original at all).

Only the runs made for this comparison count; the original's first failing run is excluded, because it was
selected for failing.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

LEVEL = 0.05
"""The overall one-sided level of the test, split evenly over the looks."""

LOOKS = (5, 10, 20)
"""After how many runs of each world the test looks (the last one is the most a comparison runs)."""

NOISE = 0.2
"""`rate_drops`: a world whose failures on its fresh runs would be this unlikely at the reference world's rate
(about one standard deviation, one-sided) fails less often beyond the noise of those runs (a stage's world
against the minimal world's: the stage is reverted)."""

Decision = Literal["holds", "below", "continue"]


@dataclass(frozen=True)
class Rate:
    fails: int
    runs: int

    def __post_init__(self) -> None:
        if not 0 <= self.fails <= self.runs:
            raise ValueError(f"a failure rate needs 0 <= fails <= runs, got {self.fails}/{self.runs}")

    @property
    def value(self) -> float:
        return self.fails / self.runs if self.runs else 0.0

    def __str__(self) -> str:
        return f"{self.fails}/{self.runs}"


@dataclass(frozen=True)
class RateComparison:
    """The outcome of one look: the two rates, the test's p-value and what to do next."""

    original: Rate
    reduced: Rate
    p_value: float
    decision: Decision
    level: float
    """The level this look tested at (`LEVEL` divided by the number of looks)."""
    skipped: int = 0
    """Runs of the original this look did not need (`settled`): `p_value` is then the bound that decided,
    over every outcome they could have had (the largest for "below", the smallest otherwise)."""
    search: bool = False
    """The drift watch's search decision (`search_below`, at `level` on one look), not the end-of-run test."""

    def describe(self) -> str:
        verdict = {
            "holds": "not significantly below the original's",
            "below": "significantly below the original's",
            "continue": "undecided",
        }[self.decision]
        bound = "=" if not self.skipped else "<=" if self.decision == "below" else ">="
        p_value = f"p {bound} {self.p_value:.3g}"
        if self.search:
            verdict = {"holds": "not below the original's", "below": "below the original's",
                       "continue": "undecided"}[self.decision]
            return (f"fails {self.reduced} fresh runs vs the original's {self.original}: {verdict} at the drift "
                    f"watch's search level (one-sided Fisher exact {p_value}, level {self.level:.3g}; a search "
                    "decision: the end-of-run comparison decides the minimal world)")
        skipped = (f"; {self.skipped} more runs of the original skipped: none could change the decision"
                   if self.skipped else "")
        return (f"fails {self.reduced} fresh runs vs the original's {self.original}: {verdict} "
                f"(one-sided Fisher exact {p_value}, level {self.level:.3g} per look{skipped})")


def next_look(runs: int, looks: Sequence[int] = LOOKS) -> int:
    """How many runs of each world the next look needs, given `runs` made so far (0 when none is left)."""
    return next((look for look in looks if look > runs), 0)


def looks_up_to(max_runs: int) -> tuple[int, ...]:
    """The looks of a comparison that runs each world at most `max_runs` times: LOOKS below it, then it."""
    return (*(look for look in LOOKS if look < max_runs), max_runs) if max_runs > 0 else ()


def compare(original: Rate, reduced: Rate, looks: Sequence[int] = LOOKS, level: float = LEVEL) -> RateComparison:
    """Decide at this look. `reduced.runs` is the number of runs made; it is the last look when no further
    look is left. The original's runs may be more than the reduced world's (reused calibration runs)."""
    if not looks or list(looks) != sorted(set(looks)) or looks[0] < 1:
        raise ValueError(f"looks must be increasing positive run counts, got {list(looks)}")
    per_look = level / len(looks)
    if original.runs == 0 or reduced.runs == 0:
        return RateComparison(original, reduced, 1.0, "continue" if next_look(reduced.runs, looks) else "holds",
                              per_look)
    p_value = p_below(reduced, original)
    decision: Decision
    if p_value < per_look:
        decision = "below"
    elif reduced.value >= original.value or not next_look(reduced.runs, looks):
        decision = "holds"
    else:
        decision = "continue"
    return RateComparison(original, reduced, p_value, decision, per_look)


def settled(original: Rate, look: int, reduced: Rate, looks: Sequence[int] = LOOKS,
            level: float = LEVEL) -> RateComparison | None:
    """The decision at `look` when the original has made only `original.runs` of its `look` runs and no
    outcome of the others could change it (a comparison with `skipped` set and, over those outcomes, the
    largest p-value for "below", the smallest otherwise); None when they are needed. A look of "continue"
    whatever they give defers them to the next look, which makes them anyway."""
    missing = look - original.runs
    if missing <= 0 or reduced.runs != look:
        return None
    completions = [compare(Rate(original.fails + more, look), reduced, looks, level)
                   for more in range(missing + 1)]
    if len({completion.decision for completion in completions}) != 1:
        return None
    bound = max if completions[0].decision == "below" else min
    worst = bound(completions, key=lambda completion: completion.p_value)
    return RateComparison(original, reduced, worst.p_value, worst.decision, worst.level, skipped=missing)


SEARCH_LEVEL = 0.1
"""The drift watch's level (`search_below`). A search decision: backing off a world wrongly costs minimality,
never honesty (the end-of-run comparison is unchanged). On 5 fresh runs of a world against the original's
5/5 it backs off at 2 failures or fewer (p = 0.083; 3 of 5: p = 0.22), on 10 against 10/10 at 6 or fewer
(p = 0.043; 7 of 10: p = 0.105). With the watch's two looks (`rate_check.SEARCH_LOOKS`), a world failing 80 %
is backed off 13.5 % of the time once tested, one failing 40 % caught 95 % of the time (one look: 5.8 % and
68 %; benchmarks/bench_rate_design.py)."""


def search_below(original: Rate, reduced: Rate, look: int, level: float = SEARCH_LEVEL) -> RateComparison | None:
    """The drift watch's search decision on `reduced`'s `look` fresh runs against the original's first `look`
    ones: one look, one-sided Fisher exact at `level`, "below" or "holds" ("continue" when `reduced` has fewer
    runs: the budget stopped them). When the original has made fewer than `look`, the decision its missing
    runs cannot change (`settled`), else None: they are needed."""
    if reduced.runs < look:
        return RateComparison(original, reduced, 1.0, "continue", level, search=True)
    if original.runs >= look:
        return replace(compare(original, reduced, (look,), level), search=True)
    early = settled(original, look, reduced, (look,), level)
    return None if early is None else replace(early, search=True)


def p_below(rate: Rate, reference: Rate) -> float:
    """The one-sided p-value of "`rate` fails less often than `reference`" (Fisher's exact test on the 2x2
    table of fails and passes, ``alternative="less"``)."""
    from scipy.stats import fisher_exact

    table = [[rate.fails, rate.runs - rate.fails], [reference.fails, reference.runs - reference.fails]]
    return float(fisher_exact(table, alternative="less").pvalue)


def clearly_below(rate: Rate, reference: Rate, level: float = LEVEL) -> bool:
    """`rate` is significantly below `reference`: the end-of-run comparison's test (`p_below`, one-sided Fisher
    exact) at `level` (5 %) on a single look. Used for another physics engine's rate of a world against the
    reduction's engine's (`driver/cross_engine.py`); False when either has no runs."""
    return rate.runs > 0 and reference.runs > 0 and p_below(rate, reference) < level


def estimated(rate: Rate) -> float:
    """A failure rate estimated from few runs, never 0 or 1: (fails + 0.5) / (runs + 1)."""
    return (rate.fails + 0.5) / (rate.runs + 1.0)


def chance_at_most(fails: int, runs: int, rate: float) -> float:
    """The chance that a world failing at `rate` fails at most `fails` times in `runs` runs (binomial tail)."""
    return sum(math.comb(runs, k) * rate**k * (1.0 - rate) ** (runs - k) for k in range(fails + 1))


def rate_drops(rate: tuple[int, int], reference: tuple[int, int], noise: float = NOISE) -> bool:
    """(fails, runs) `rate` is below the `reference` rate beyond the noise of its runs: at the reference's
    estimated rate (`estimated`), `rate`'s runs would show as few failures with a chance below `noise`
    (binomial tail), or it is significantly below the reference's (Fisher, one-sided, 5 %)."""
    if rate[1] == 0 or reference[1] == 0:
        return False
    measured, expected = Rate(*rate), Rate(*reference)
    return chance_at_most(measured.fails, measured.runs, estimated(expected)) < noise or \
        p_below(measured, expected) < LEVEL


def wilson_interval(rate: Rate, confidence: float) -> tuple[float, float]:
    """The failure rate's `confidence` interval (Wilson score); (0, 1) without runs."""
    from scipy.stats import binomtest

    if rate.runs == 0:
        return 0.0, 1.0
    low, high = binomtest(rate.fails, rate.runs).proportion_ci(confidence, method="wilson")
    return float(low), float(high)


VERDICT_CONFIDENCE = 0.95
"""The confidence of a failure-rate verdict's Wilson interval (`--ddenv-rate`)."""


def significantly_above(rate: Rate, threshold: float, confidence: float = VERDICT_CONFIDENCE) -> bool:
    """`rate` is significantly above `threshold`: the lower end of its Wilson interval at `confidence` is above
    it (so with a threshold of 0, any failure is); False without runs."""
    return rate.runs > 0 and wilson_interval(rate, confidence)[0] > threshold
