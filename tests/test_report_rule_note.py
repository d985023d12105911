"""The report's note on a fixed deflake rule that a flaky original makes miss (`report_text.rule_lines`): real
reductions of synthetic probes (no physics), the note read from the reduction they return."""

from __future__ import annotations

from collections.abc import Callable

from pytest_ddenv.driver.report_text import rule_lines
from pytest_ddenv.reduce import Outcome, ProbeObservation, Reduction, reduce

ELEMENTS = ("a", "b", "c", "d", "e", "f")


def flaky(every: int) -> Callable[[tuple[str, ...], int], ProbeObservation]:
    """f when 'a' is there, except on attempts divisible by `every` after attempt 0 (the reference fails)."""

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        fails = "a" in candidate and (attempt == 0 or attempt % every != 0)
        return ProbeObservation(Outcome.FAIL if fails else Outcome.PASS, signature={"kind": "stuck"}, seed=attempt)

    return probe


def reduced(every: int, deflake: int | str) -> Reduction:
    return reduce(ELEMENTS, flaky(every), deflake=deflake, partition="even", priority="sequential")


def test_any_of_one_on_an_original_that_fails_half_its_runs_gets_the_note() -> None:
    result = reduced(2, 0)
    original = result.original_failure_rate
    assert original is not None and original[0] < original[1]
    lines = rule_lines(result)
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"note: the original world failed {original[0]} of {original[1]} fresh runs, and "
                               "deflake=0 judges a candidate on 1 run (any failing): a candidate that fails as often "
                               "as the original is rejected about ")
    assert "deflake=auto (the default)" in lines[0]


def test_no_note_when_the_rule_rarely_misses_or_is_calibrated_or_the_original_fails_every_run() -> None:
    assert rule_lines(reduced(2, 3)) == [], "any of 4 runs at about 50 %: misses about 6 %"
    assert rule_lines(reduced(2, "auto")) == [], "auto sizes the rule from the original's rate"
    assert rule_lines(reduced(10**6, 0)) == [], "an original failing every fresh run"
    assert rule_lines(reduced(1, 0)) == [], "an original failing none: the report's warning up front says so"
    assert rule_lines(reduced(2, 0), misses=0.99) == [], "below the threshold"
