"""The curtailed rate comparison (issue 33): the original's runs a look cannot need are not started, every
fresh run is one attempt counted once, and the decisions are exactly those of the full test."""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import pytest

from pytest_ddenv.reduce import Outcome, ProbeLog, ProbeObservation, reduce
from pytest_ddenv.reduce.rates import LOOKS, Rate, compare, settled

from .conftest import SetOracle

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
ELEMENTS = ("a", "b", "c", "d", "e", "f")


# -- the rule on synthetic outcomes ----------------------------------------------------------------------


def test_a_minimal_world_failing_every_run_holds_without_any_run_of_the_original() -> None:
    early = settled(Rate(0, 0), 5, Rate(5, 5))
    assert early is not None and early.decision == "holds" and early.skipped == 5
    assert early.original == Rate(0, 0) and early.p_value == 1.0
    assert "5 more runs of the original skipped" in early.describe() and "p >= 1" in early.describe()


def test_the_original_runs_when_its_outcomes_could_change_the_decision() -> None:
    assert settled(Rate(3, 3), 5, Rate(4, 5)) is None  # 5/5 would continue, 3/5 would hold
    assert settled(Rate(4, 4), 5, Rate(0, 5)) is None  # 5/5: below (p = 0.004); 4/5: continue (p = 0.024)
    assert settled(Rate(5, 5), 5, Rate(4, 5)) is None  # nothing left to skip
    assert settled(Rate(0, 0), 5, Rate(3, 4)) is None  # the minimal world's look is not complete


def test_a_decided_below_and_a_deferred_look() -> None:
    below = settled(Rate(9, 9), 10, Rate(0, 10))
    assert below is not None and below.decision == "below" and below.skipped == 1
    assert below.p_value == max(compare(Rate(f, 10), Rate(0, 10)).p_value for f in (9, 10)) < LEVEL_PER_LOOK
    deferred = settled(Rate(4, 4), 5, Rate(3, 5))  # 4/5 or 5/5 against 3/5: undecided either way
    assert deferred is not None and deferred.decision == "continue" and deferred.skipped == 1
    assert deferred.p_value == min(compare(Rate(f, 5), Rate(3, 5)).p_value for f in (4, 5))
    assert "p <= " in below.describe() and "p >= " in deferred.describe()


LEVEL_PER_LOOK = 0.05 / len(LOOKS)


def test_settled_agrees_with_every_outcome_of_the_skipped_runs() -> None:
    for look in LOOKS:
        for made in range(look):
            for known_fails, reduced_fails in itertools.product(range(made + 1), range(look + 1)):
                early = settled(Rate(known_fails, made), look, Rate(reduced_fails, look))
                decisions = {compare(Rate(known_fails + more, look), Rate(reduced_fails, look)).decision
                             for more in range(look - made + 1)}
                assert (early is None) == (len(decisions) > 1)
                assert early is None or {early.decision} == decisions


# -- the script's operating characteristics --------------------------------------------------------------


@pytest.fixture(scope="module")
def design():  # type: ignore[no-untyped-def]
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import bench_rate_design

        yield bench_rate_design
    finally:
        sys.path.remove(str(BENCHMARKS))


def test_the_scripts_exact_characteristics_are_the_documented_ones(design) -> None:  # type: ignore[no-untyped-def]
    # both worlds always fail: the first look holds; 5 runs of the minimal world, none of the original
    old, new = design.old_design(1.0, 1.0, 0), design.curtailed_design(1.0, 1.0, 0)
    assert (old.below, old.reduced_runs, old.original_runs) == (0.0, 5.0, 5.0)
    assert (new.below, new.reduced_runs, new.original_runs) == (0.0, 5.0, 0.0)
    # a minimal world failing half as often as a solid original is caught 95.30 % of the time (docs/algorithm.md)
    power_old, power_new = design.old_design(1.0, 0.5, 3), design.curtailed_design(1.0, 0.5, 3)
    assert power_old.below == pytest.approx(power_new.below, abs=1e-12)
    assert round(power_new.below, 4) == 0.9530
    assert power_new.original_runs < power_old.original_runs
    # equal rates of 80 %: called "below" 0.79 % of the time, by both
    assert round(design.curtailed_design(0.8, 0.8, 3).below, 4) == round(design.old_design(0.8, 0.8, 3).below, 4)
    assert round(design.old_design(0.8, 0.8, 3).below, 4) == 0.0079
    for case in (design.old_design(0.6, 0.3, 5), design.curtailed_design(0.6, 0.3, 5)):
        assert case.below + case.holds == pytest.approx(1.0)


# -- in the engine -----------------------------------------------------------------------------------------


def test_a_solid_failure_costs_five_runs_of_the_minimal_world_and_none_more_of_the_original() -> None:
    oracle = SetOracle(frozenset({"a"}))
    result = reduce(ELEMENTS, oracle, deflake="auto", partition="even", priority="sequential")
    assert result.minimal == ("a",) and result.calibration == (3, 3)
    assert result.rate_check is not None and result.rate_check.decision == "holds"
    assert result.rate_check.reduced == Rate(5, 5) and result.rate_check.original == Rate(3, 3)
    assert result.rate_check.skipped == 2 and result.original_failure_rate == (3, 3)
    original_attempts = [attempt for candidate, attempt in oracle.calls if candidate == ELEMENTS]
    assert sorted(original_attempts) == [1, 2, 3]  # the calibration runs, and nothing for the comparison
    assert len(oracle.calls) == len(set(oracle.calls)) == result.simulations


def flaky_minimal(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
    """f iff 'a' is present, except the minimal world ('a',) passes its attempts 3, 9 and 15."""
    fails = "a" in candidate and not (candidate == ("a",) and attempt in (3, 9, 15))
    return ProbeObservation(Outcome.FAIL if fails else Outcome.PASS, signature={"kind": "stuck"}, seed=attempt)


def test_a_shared_calibration_run_is_one_fresh_run_of_the_original_counted_once(tmp_path: Path) -> None:
    calls: list[tuple[tuple[str, ...], int]] = []

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        calls.append((candidate, attempt))
        return flaky_minimal(candidate, attempt)

    log = tmp_path / "runs.jsonl"
    result = reduce(ELEMENTS, probe, deflake="auto", partition="even", priority="sequential", log=log)
    check = result.rate_check
    assert result.minimal == ("a",) and result.calibration == (3, 3)
    # 4/5 and 8/10 of the minimal world (accepted on attempts 0-1) against 5/5 and 10/10: undecided; at the
    # last look 17/20 holds whatever the original's last 10 runs give (p <= 0.115 > 0.05 / 3): not started.
    # The original's fresh runs are its attempts 1-10, the calibration's 1-3 among them, each made once.
    assert check is not None and check.decision == "holds" and check.skipped == 10
    assert check.reduced == Rate(17, 20) and check.original == Rate(10, 10)
    assert check.p_value == pytest.approx(1140 / 9880)
    original_attempts = sorted(attempt for candidate, attempt in calls if candidate == ELEMENTS)
    assert original_attempts == list(range(1, 11))
    assert len(calls) == len(set(calls)) == result.simulations
    # resumed from its log: the logged fresh runs answer, nothing is simulated again, the same comparison
    calls.clear()
    again = reduce(ELEMENTS, probe, deflake="auto", partition="even", priority="sequential",
                   log=ProbeLog.load(log))
    assert calls == [] and again.rate_check == check and again.minimal == ("a",)
