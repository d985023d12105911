"""Does a reduced world still fail as often as the original? A group-sequential one-sided test.

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

Only the runs made for this comparison count; the original's first failing run is excluded, because it was
selected for failing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

LEVEL = 0.05
"""The overall one-sided level of the test, split evenly over the looks."""

LOOKS = (5, 10, 20)
"""After how many runs of each world the test looks (the last one is the most a comparison runs)."""

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

    def describe(self) -> str:
        verdict = {
            "holds": "not significantly below the original's",
            "below": "significantly below the original's",
            "continue": "undecided",
        }[self.decision]
        return (f"fails {self.reduced} fresh runs vs the original's {self.original}: {verdict} "
                f"(one-sided Fisher exact p = {self.p_value:.3g}, level {self.level:.3g} per look)")


def next_look(runs: int, looks: Sequence[int] = LOOKS) -> int:
    """How many runs of each world the next look needs, given `runs` made so far (0 when none is left)."""
    return next((look for look in looks if look > runs), 0)


def compare(original: Rate, reduced: Rate, looks: Sequence[int] = LOOKS, level: float = LEVEL) -> RateComparison:
    """Decide at this look. `reduced.runs` is the number of runs made; it is the last look when no further
    look is left. The original's runs may be more than the reduced world's (reused calibration runs)."""
    from scipy.stats import fisher_exact

    if not looks or list(looks) != sorted(set(looks)) or looks[0] < 1:
        raise ValueError(f"looks must be increasing positive run counts, got {list(looks)}")
    per_look = level / len(looks)
    if original.runs == 0 or reduced.runs == 0:
        return RateComparison(original, reduced, 1.0, "continue" if next_look(reduced.runs, looks) else "holds",
                              per_look)
    table = [[reduced.fails, reduced.runs - reduced.fails], [original.fails, original.runs - original.fails]]
    p_value = float(fisher_exact(table, alternative="less").pvalue)
    decision: Decision
    if p_value < per_look:
        decision = "below"
    elif reduced.value >= original.value or not next_look(reduced.runs, looks):
        decision = "holds"
    else:
        decision = "continue"
    return RateComparison(original, reduced, p_value, decision, per_look)
