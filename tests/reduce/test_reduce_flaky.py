"""Nondeterministic failures: deflaking keeps the culprits, and the deflake policies behave as documented."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import Outcome, reduce
from pytest_ddenv.reduce.deflake import FixedReruns, SequentialTest, make_policy

from .conftest import SetOracle, names

CULPRITS = frozenset({"m0003", "m0011", "m0012"})


@pytest.mark.parametrize("deflake", [3, "adaptive"])
def test_flaky_culprits_survive_in_at_least_95_of_100_seeds(
    deflake: int | str, record_property: Callable[[str, object], None]
) -> None:
    elements = names(16)
    contained = exact = 0
    rates = []
    for seed in range(100):
        oracle = SetOracle(CULPRITS, rate=0.7, salt=seed)
        result = reduce(elements, oracle, deflake=deflake, seed=seed, partition="even", priority="random")
        contained += set(result.minimal) >= CULPRITS
        exact += set(result.minimal) == CULPRITS
        rates.append(result.failure_rate[0] / result.failure_rate[1])
    record_property(f"flaky_{deflake}_contained", contained)
    record_property(f"flaky_{deflake}_exact", exact)
    print(f"deflake={deflake}: culprits kept in {contained}/100, result exactly the culprits in {exact}/100")
    assert contained >= 95
    assert exact >= 80
    assert 0.5 < sum(rates) / len(rates) < 0.9, "the measured failure rate of the minimal world is ~0.7"


def test_without_deflaking_flaky_culprits_leave_extra_elements() -> None:
    elements = names(16)
    exact = sum(
        set(reduce(elements, SetOracle(CULPRITS, rate=0.7, salt=seed), deflake=0, seed=seed).minimal) == CULPRITS
        for seed in range(30)
    )
    assert exact < 25, "deflaking must matter on this oracle, or the test above proves nothing"


def test_fixed_reruns_is_the_papers_rule() -> None:
    policy = FixedReruns(3)
    assert policy.verdict([Outcome.FAIL]) is True
    assert policy.verdict([Outcome.PASS]) is None
    assert policy.verdict([Outcome.PASS, Outcome.OTHER, Outcome.ERROR, Outcome.FAIL]) is True  # 1 of 4 is enough
    assert policy.verdict([Outcome.PASS, Outcome.OTHER, Outcome.ERROR, Outcome.PASS]) is False
    assert FixedReruns(0).verdict([Outcome.PASS]) is False


def test_sequential_test_confirms_and_rejects() -> None:
    policy = SequentialTest(confidence=0.95)
    assert policy.verdict([Outcome.FAIL]) is None, "one f is not conclusive at 95 %"
    assert policy.verdict([Outcome.FAIL, Outcome.FAIL]) is True
    assert policy.verdict([Outcome.PASS] * 4) is None
    assert policy.verdict([Outcome.PASS] * 5) is False
    assert policy.verdict([Outcome.ERROR] * 5) is False, "errors are never f"
    assert policy.verdict([Outcome.FAIL, Outcome.PASS, Outcome.FAIL]) is True
    mixed = [Outcome.FAIL, Outcome.PASS] * 20
    assert policy.verdict(mixed[: policy.max_runs]) in (True, False)


def test_deflake_validation() -> None:
    assert make_policy("2", 0.9) == FixedReruns(2)
    for bad in (-1, "sometimes", 1.5, True):
        with pytest.raises(ReductionError, match="adaptive"):
            make_policy(bad, 0.95)  # type: ignore[arg-type]
    with pytest.raises(ReductionError, match="confidence"):
        make_policy("adaptive", 1.0)


def test_reruns_get_their_own_attempt_numbers() -> None:
    oracle = SetOracle(frozenset({"m0001"}), rate=0.0)  # never fails again: every candidate is re-run
    reduce(names(4), oracle, deflake=2, failure_rate_runs=3)
    attempts: dict[tuple[str, ...], list[int]] = {}
    for candidate, attempt in oracle.calls:
        attempts.setdefault(candidate, []).append(attempt)
    original = names(4)
    assert attempts.pop(original) == [1, 2, 3], "failure-rate runs of the original start after its attempt 0"
    assert all(runs == [0, 1, 2] for runs in attempts.values())
