"""Nondeterministic failures: deflaking keeps the culprits, and the deflake policies behave as documented."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import Outcome, ProbeObservation, reduce
from pytest_ddenv.reduce.deflake import (
    CalibratedReruns,
    ConfirmedRuns,
    FixedReruns,
    SequentialTest,
    make_policy,
)
from pytest_ddenv.reduce.log import ProbeLog

from .conftest import SetOracle, names, uniform

CULPRITS = frozenset({"m0003", "m0011", "m0012"})


@pytest.mark.parametrize("deflake", [3, "adaptive", "auto"])
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


# -- deflake="auto": re-runs calibrated on the original world ---------------------------------------------


def test_calibrated_rules_follow_the_original_failure_rate() -> None:
    policy = CalibratedReruns(confidence=0.95)
    labels = [policy.rule_for(fails, 5).label for fails in range(6)]
    assert labels == ["1-of-10", "1-of-10", "1-of-6", "2-of-6", "2-of-5", "2-of-3"]
    assert policy.rule_for(3, 3) == ConfirmedRuns(3, 2)
    assert CalibratedReruns(confidence=0.99).rule_for(3, 3).max_runs > 3
    with pytest.raises(ReductionError, match="calibrated"):
        policy.verdict([Outcome.PASS])


def test_confirmed_runs_stop_as_soon_as_the_verdict_is_certain() -> None:
    rule = ConfirmedRuns(3, confirm=2)
    F, P = Outcome.FAIL, Outcome.PASS
    assert rule.verdict([F]) is None, "one f is not enough"
    assert rule.verdict([F, F]) is True
    assert rule.verdict([P, P]) is False, "2 f are out of reach in the one run left"
    assert rule.verdict([F, P]) is None and rule.verdict([F, P, F]) is True and rule.verdict([F, P, P]) is False
    assert ConfirmedRuns(4, confirm=1).verdict([P, P, P]) is None
    assert [ConfirmedRuns(4, 1).verdict(o) for o in ([F], [P] * 4)] == [FixedReruns(3).verdict(o) for o in ([F], [P] * 4)]


@pytest.mark.parametrize("rate, salt", [(1.0, 0), (0.7, 2), (0.5, 4)])
def test_auto_deflake_runs_the_original_first_then_the_calibrated_rule(rate: float, salt: int) -> None:
    elements = names(16)
    oracle = SetOracle(CULPRITS, rate=rate, salt=salt)
    log = ProbeLog()
    result = reduce(elements, oracle, deflake="auto", partition="even", failure_rate_runs=3, log=log)
    assert result.calibration is not None
    fails, runs = result.calibration
    assert oracle.calls[:runs] == [(elements, attempt) for attempt in range(1, runs + 1)]
    rule = CalibratedReruns().rule_for(fails, runs)
    assert result.deflake == f"auto:{rule.label}"
    decided = log.probes("reduce")
    assert max(probe.attempt for probe in decided) < rule.max_runs, "every candidate gets at most max_runs runs"
    assert result.probes == len(decided) + runs, "calibration runs are counted as probes"
    assert result.simulations == len(oracle.calls) == result.probes + len(log.probes("failure-rate"))
    assert set(result.minimal) >= CULPRITS


def test_auto_deflake_seldom_accepts_a_world_that_fails_only_by_luck() -> None:
    """The culprits fail 90 % of runs; without m0012 they still fail 15 % of runs (by luck)."""

    def fails(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        present = set(candidate)
        rate = 0.9 if present >= CULPRITS else 0.15 if present >= CULPRITS - {"m0012"} else 0.0
        failed = uniform(candidate, attempt, salt) < rate
        return ProbeObservation(Outcome.FAIL if failed else Outcome.PASS, seed=attempt)

    kept: dict[int | str, int] = {"auto": 0, 1: 0, 3: 0}
    for salt in range(60):
        for deflake in kept:
            result = reduce(names(16), fails, deflake=deflake, seed=salt, partition="even", failure_rate_runs=0)
            kept[deflake] += "m0012" in result.minimal
    print(f"m0012 kept in 60 seeds: {kept}")
    assert kept["auto"] >= 40, kept
    assert kept["auto"] > max(kept[1], kept[3]) + 15, f"the paper's rule loses m0012 more often: {kept}"


def test_a_resumed_reduction_reuses_the_logged_calibration(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    elements = names(16)
    first = reduce(elements, SetOracle(CULPRITS, rate=0.7, salt=2), deflake="auto", log=path, max_probes=12)
    assert first.incomplete_reason == "budget: max_probes" and first.calibration is not None
    oracle = SetOracle(CULPRITS, rate=0.7, salt=2)
    resumed = reduce(elements, oracle, deflake="auto", log=path)
    assert resumed.calibration == first.calibration and resumed.deflake == first.deflake
    assert (elements, 1) not in oracle.calls, "the calibration runs are not repeated"
    assert ProbeLog.load(path).calibration() == first.calibration
