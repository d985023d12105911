"""Budgets, interrupts, preconditions, keep, outcomes, progress and argument validation."""

from __future__ import annotations

import re
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.errors import DdenvError, ReductionError
from pytest_ddenv.reduce import (
    DEFLAKE_POLICIES,
    PARTITIONS,
    PRIORITIES,
    Outcome,
    ProbeCancelled,
    ProbeLog,
    ProbeObservation,
    ProgressEvent,
    ReductionInterrupted,
    reduce,
)

from .conftest import FunctionOracle, SetOracle, names

CULPRITS = frozenset({"m0004", "m0017"})


def reproduces(candidate: tuple[str, ...]) -> bool:
    return set(candidate) >= CULPRITS


# -- budgets ----------------------------------------------------------------------------------------------


def test_a_zero_probe_budget_returns_the_original() -> None:
    """With verdicts to reuse (a cache, a log): without any, a budget of 0 would do nothing and is refused."""
    with pytest.raises(ReductionError, match="max_probes: expected an integer >= 1"):
        reduce(names(20), SetOracle(CULPRITS), max_probes=0, failure_rate_runs=0)
    result = reduce(names(20), SetOracle(CULPRITS), max_probes=0, failure_rate_runs=0, cache={})
    assert result.minimal == names(20)
    assert result.incomplete_reason == "budget: max_probes" and not result.one_minimal
    assert result.probes == 0


@pytest.mark.parametrize("budget", [1, 3, 7, 15])
def test_a_probe_budget_gives_the_best_world_so_far(budget: int) -> None:
    oracle = SetOracle(CULPRITS)
    result = reduce(names(64), oracle, max_probes=budget, deflake=0, failure_rate_runs=2)
    assert result.simulations == len(oracle.calls) == budget, "the drift watch's confirming runs included"
    assert result.probes <= budget
    assert result.incomplete_reason == "budget: max_probes" and not result.one_minimal
    assert reproduces(result.minimal)
    fresh = result.simulations - result.probes  # the drift watch's confirming runs, within the budget
    assert result.failure_rate[0] == result.failure_rate[1] <= fresh, (
        "the failure-rate runs are simulations too: none left but the confirming runs already made")
    assert len(result.minimal) == result.steps[-1][1]


def test_the_budget_covers_the_failure_rate_and_calibration_runs() -> None:
    log = ProbeLog()
    complete = reduce(names(64), SetOracle(CULPRITS), deflake="auto", failure_rate_runs=5, log=log)
    assert complete.one_minimal and complete.calibration == (3, 3) and complete.rate_check is not None
    assert complete.rate_check.decision == "holds" and complete.failure_rate == (5, 5)
    # 5 fresh runs of the minimal world; the original's 3 calibration runs are not topped up to 5: with the
    # minimal world failing 5/5 no outcome of theirs could change the decision; the drift watch's confirming
    # runs (attempt 2 of accepted worlds, 2-of-3 accepted them on attempts 0 and 1) besides
    fresh = log.probes("failure-rate")
    confirming = [probe for probe in fresh if probe.candidate != complete.minimal]
    assert {probe.attempt for probe in confirming} == {2} and len(fresh) - len(confirming) == 5
    assert complete.simulations == complete.probes + len(fresh) and complete.rate_check.skipped == 2
    oracle = SetOracle(CULPRITS)
    budget = complete.simulations - 3  # all but the minimal world's last 3 fresh runs
    result = reduce(names(64), oracle, max_probes=budget, deflake="auto", failure_rate_runs=5)
    assert result.one_minimal and result.minimal == complete.minimal and result.incomplete_reason is None
    assert result.failure_rate == (2, 2), "measured with what the budget left"
    assert result.rate_check is not None and result.rate_check.decision == "continue", "no verdict on 2 runs"
    assert len(oracle.calls) == result.simulations == budget
    early = reduce(names(64), SetOracle(CULPRITS), max_probes=2, deflake="auto")
    assert early.incomplete_reason == "budget: max_probes" and early.simulations == 2
    assert early.minimal == names(64) and early.calibration is None, "the budget ran out while calibrating"


def test_a_time_budget() -> None:
    oracle = SetOracle(CULPRITS)
    result = reduce(names(200), oracle, max_seconds=0, deflake=0, failure_rate_runs=3)
    assert result.incomplete_reason == "budget: max_seconds" and not result.one_minimal
    assert result.minimal == names(200) and oracle.calls == [] and result.failure_rate == (0, 0)


def test_the_time_budget_interrupts_running_probes() -> None:
    """The deadline passes while a probe is still running: the reduction ends without waiting for it (a
    hang guard of 60 s lets the test finish if it does not)."""
    release = threading.Event()
    waited: list[bool] = []

    def blocking(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if len(candidate) < 64:
            waited.append(release.wait(60))
        return SetOracle(CULPRITS)(candidate, attempt)

    executor = ThreadPoolExecutor(max_workers=2)
    try:
        result = reduce(names(64), blocking, max_seconds=0.5, deflake=0, executor=executor, workers=2)
        assert waited == [], "returned while the probes were still running"
    finally:
        release.set()
        executor.shutdown(wait=True)
    assert result.incomplete_reason == "budget: max_seconds" and result.minimal == names(64)
    assert result.probes == 0 and result.simulations == 2 and result.errors == 0


def test_a_probe_cancelled_by_its_caller_ends_the_reduction_without_a_verdict(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"

    def cancelled_later(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if len(cancelled_later.calls) == 3:  # type: ignore[attr-defined]
            raise ProbeCancelled("budget: max_seconds")
        cancelled_later.calls.append(candidate)  # type: ignore[attr-defined]
        return SetOracle(CULPRITS)(candidate, attempt)

    cancelled_later.calls = []  # type: ignore[attr-defined]
    result = reduce(names(64), cancelled_later, deflake=0, log=path, failure_rate_runs=2)
    assert result.incomplete_reason == "budget: max_seconds" and result.errors == 0
    assert result.simulations == 4 and result.failure_rate in ((0, 0), (1, 1))
    assert sum(1 for line in path.read_text().splitlines() if '"event": "probe"' in line) == 3
    assert result.probes == 3 - sum(1 for line in path.read_text().splitlines()
                                    if '"event": "probe"' in line and '"failure-rate"' in line)


def test_budgets_with_an_executor() -> None:
    with ThreadPoolExecutor(max_workers=2) as executor:
        result = reduce(names(64), SetOracle(CULPRITS), max_probes=6, deflake=0, executor=executor, workers=2)
    assert result.incomplete_reason == "budget: max_probes"
    assert reproduces(result.minimal) and result.probes <= 6


# -- interrupt --------------------------------------------------------------------------------------------


def test_keyboard_interrupt_raises_with_the_partial_result(tmp_path: Path) -> None:
    path = tmp_path / "runs.jsonl"
    calls = 0

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        nonlocal calls
        calls += 1
        if calls == 12:
            raise KeyboardInterrupt
        return SetOracle(CULPRITS)(candidate, attempt)

    with pytest.raises(ReductionInterrupted) as caught:
        reduce(names(64), probe, log=path, deflake=0)
    assert isinstance(caught.value, KeyboardInterrupt) and isinstance(caught.value, DdenvError)
    partial = caught.value.reduction
    assert partial.incomplete_reason == "interrupted" and not partial.one_minimal
    assert partial.simulations == 12 and partial.probes <= 11, "the drift watch's confirming runs are no probes"
    assert reproduces(partial.minimal) and len(partial.minimal) < 64
    last = path.read_text().splitlines()[-1]
    assert '"event": "end"' in last and '"interrupted"' in last


def test_interrupt_from_progress_callback_while_parallel() -> None:
    def stop(event: ProgressEvent) -> None:
        if event.kind == "probe" and event.probes >= 5:
            raise KeyboardInterrupt

    with ThreadPoolExecutor(max_workers=2) as executor, pytest.raises(ReductionInterrupted) as caught:
        reduce(names(64), SetOracle(CULPRITS), deflake=0, executor=executor, workers=2, on_progress=stop)
    assert reproduces(caught.value.reduction.minimal)


# -- preconditions, keep, outcomes ------------------------------------------------------------------------


def test_preconditions_skip_candidates_without_probing() -> None:
    ground = "m0000"

    def needs_ground(candidate: tuple[str, ...]) -> str | None:
        return None if ground in candidate else "the robot spawns on m0000"

    oracle = SetOracle(CULPRITS)
    result = reduce(names(24), oracle, preconditions=[needs_ground], deflake=0, precondition_check=True)
    without_ground = [(candidate, attempt) for candidate, attempt in oracle.calls if ground not in candidate]
    assert without_ground == [(tuple(sorted(CULPRITS)), attempt) for attempt in range(3)], (
        "only the check of the minimal world without what a precondition kept")
    assert result.skipped > 0
    assert set(result.minimal) == CULPRITS | {ground}
    assert result.one_minimal, "1-minimal relative to the preconditions"
    assert result.precondition_kept == ((ground, "the robot spawns on m0000"),)
    assert set(result.needed) == CULPRITS
    assert result.without_precondition_kept == (3, 3), "the failure reproduces without the ground too"


def test_the_precondition_bypass_check_is_off_by_default_and_the_report_says_not_checked() -> None:
    """Issue 33: information only, so a reduction does not pay for it unless asked (`precondition_check`)."""
    from pytest_ddenv.driver.report_text import needed_lines
    from pytest_ddenv.stages.explain import _why_not_run

    ground = "m0000"
    oracle = SetOracle(CULPRITS)
    result = reduce(names(24), oracle, preconditions=[lambda c: None if ground in c else "spawns on m0000"], deflake=0)
    assert not [candidate for candidate, _ in oracle.calls if ground not in candidate], "no run without the ground"
    assert result.precondition_kept == ((ground, "spawns on m0000"),)
    assert result.without_precondition_kept is None
    assert result.simulations == len(oracle.calls)
    assert needed_lines(result)[-1].startswith("without them: not checked (the explain stage")
    assert "not simulated without it (the explain stage does" in _why_not_run(result, ground)


def test_a_precondition_bypass_check_whose_runs_all_errored_says_it_could_not_run() -> None:
    """Issue 28: "the failure reproduced in 0/0 runs" when the bypass runs could not start; now "could not run"."""
    from pytest_ddenv.driver.report_text import needed_lines

    ground = "m0000"
    oracle = SetOracle(CULPRITS)

    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if ground not in candidate:  # a world without the ground cannot even start
            return ProbeObservation(Outcome.ERROR, seed=attempt)
        return oracle(candidate, attempt)

    result = reduce(names(24), probe, preconditions=[lambda c: None if ground in c else "spawns on m0000"], deflake=0,
                    precondition_check=True)
    assert result.without_precondition_kept == (0, 0)
    lines = needed_lines(result)
    assert lines[-1] == "without them (precondition bypassed) the check could not run (none of its runs finished)"
    assert not any("0/0" in line for line in lines)
    from pytest_ddenv.stages.explain import _why_not_run  # the explain stage's "without m0000" says the same

    assert _why_not_run(result, ground).endswith("the check could not run (none of its runs finished)")


def test_keep_elements_stay_in_every_candidate() -> None:
    keep = {"m0001", "m0010"}
    oracle = SetOracle(CULPRITS)
    result = reduce(names(24), oracle, keep=keep, deflake=0)
    assert all(keep <= set(candidate) for candidate, _ in oracle.calls)
    assert set(result.minimal) == CULPRITS | keep
    assert result.kept == ("m0001", "m0010")
    assert result.minimal == tuple(sorted(result.minimal)), "original order"


def test_only_kept_elements() -> None:
    oracle = SetOracle(frozenset())
    result = reduce(names(3), oracle, keep=names(3), failure_rate_runs=0)
    assert result.minimal == names(3) and result.one_minimal and result.probes == 0


def test_empty_world_and_failure_without_any_element() -> None:
    assert reduce((), SetOracle(frozenset()), failure_rate_runs=0).minimal == ()
    result = reduce(names(9), SetOracle(frozenset()), deflake=0)
    assert result.minimal == () and result.one_minimal


@pytest.mark.parametrize("outcome", [Outcome.OTHER, Outcome.ERROR, Outcome.PASS])
def test_only_the_same_failure_counts(outcome: Outcome) -> None:
    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if reproduces(candidate):
            return ProbeObservation(Outcome.FAIL)
        return ProbeObservation(outcome if len(candidate) < 10 else Outcome.PASS)

    result = reduce(names(32), probe, deflake=1)
    assert set(result.minimal) == CULPRITS
    assert (result.errors > 0) == (outcome is Outcome.ERROR)


def test_a_probe_that_raises_is_an_error_outcome() -> None:
    def probe(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        if len(candidate) == 1:
            raise RuntimeError("simulator crashed")
        return FunctionOracle(lambda c: reproduces(tuple(c)))(candidate, attempt)

    result = reduce(names(20), probe, deflake=0)
    assert set(result.minimal) == CULPRITS and result.errors > 0


def test_a_probe_that_returns_garbage_is_reported() -> None:
    with pytest.raises(ReductionError, match="must return an ProbeObservation"):
        reduce(names(4), lambda candidate, attempt: True, deflake=0)  # type: ignore[arg-type,return-value]
    with pytest.raises(ReductionError, match="outcome must be one of fail, other, pass, error"):
        reduce(names(4), lambda candidate, attempt: ProbeObservation("boom"), deflake=0)  # type: ignore[arg-type]
    result = reduce(names(4), lambda candidate, attempt: ProbeObservation("fail"), deflake=0)  # type: ignore[arg-type]
    assert result.minimal == ()


def test_progress_events() -> None:
    events: list[ProgressEvent] = []
    result = reduce(names(20), SetOracle(CULPRITS), deflake=0, on_progress=events.append)
    kinds = [event.kind for event in events]
    assert kinds[0] == "start" and kinds[-1] == "end"
    assert {"round", "probe", "step", "verify"} <= set(kinds)
    assert kinds.count("probe") == result.probes
    assert kinds.count("step") == len(result.steps) - 1


def test_paper_granularity_also_ends_one_minimal() -> None:
    result = reduce(names(40), SetOracle(CULPRITS), granularity="paper", deflake=0)
    assert set(result.minimal) == CULPRITS and result.one_minimal and result.granularity == "paper"


def test_reduction_records_the_schemas() -> None:
    result = reduce(
        names(5),
        SetOracle(CULPRITS & set(names(5))),
        partition="timeseg",
        priority="timestep",
        deflake="adaptive",
        seed=4,
    )
    assert (result.partition, result.priority, result.deflake, result.seed) == ("timeseg", "timestep", "adaptive", 4)
    assert result.removed == tuple(name for name in names(5) if name not in result.minimal)


# -- validation -------------------------------------------------------------------------------------------

VALID: dict[str, Any] = {}


@pytest.mark.parametrize(
    "arguments, message",
    [
        ({"partition": "kmeans"}, "valid choices: " + ", ".join(PARTITIONS)),
        ({"priority": "nearest"}, "valid choices: " + ", ".join(PRIORITIES)),
        ({"granularity": "fast"}, "granularity: expected one of ddmin, paper, got 'fast'"),
        ({"deflake": "maybe"}, "one of " + ", ".join(DEFLAKE_POLICIES)),
        ({"n_partitions": 1}, "n_partitions: expected an integer >= 2, got 1"),
        ({"max_probes": -1}, "max_probes: expected an integer >= 0, got -1"),
        ({"max_seconds": "1s"}, "max_seconds: expected None or a number >= 0, got '1s'"),
        ({"max_seconds": float("nan")}, "max_seconds: expected None or a number >= 0, got nan"),
        ({"deflake": 10**12}, "deflake: expected at most 100 re-runs per candidate, got 1000000000000"),
        ({"deflake": 10**100}, "deflake: expected at most 100 re-runs per candidate, got a 333-bit number"),
        ({"deflake": "9" * 5000}, "deflake: expected at most 100 re-runs per candidate, got a 5000-digit number"),
        ({"keep": ["nope"]}, "keep names elements that are not in the world: nope"),
        ({"keep": "m0001"}, "keep: expected a collection of element names, not a string, got 'm0001'"),
        ({"confidence": 0.3}, "confidence: expected a number strictly between 0.5 and 1, got 0.3"),
        ({"seed": -1}, "seed: expected an integer >= 0, got -1"),
        ({"failure_rate_runs": 1.5}, "failure_rate_runs: expected an integer >= 0, got 1.5"),
        ({"cache": []}, "cache: expected None or a MutableMapping, got []"),
        ({"executor": object()}, "executor: expected None or a concurrent.futures.Executor, got <object object"),
        ({"log": 3}, "log: expected None, a path or a ProbeLog, got 3"),
        ({"preconditions": [3]}, "preconditions: expected callables check(candidate) -> str | None, got 3"),
        ({"reference": [1, 2]}, "reference: expected a Trace or None, got [1, 2]"),
        ({"geometry": object()}, "geometry: expected None or an object with centroids(names) and distances(points, names), got <object object"),
        ({"complement_order": "sideways"}, "complement_order: expected one of reverse, priority, got 'sideways'"),
    ],
)
def test_invalid_arguments_are_named(arguments: dict[str, Any], message: str) -> None:
    with pytest.raises(ReductionError, match=re.escape(message)):
        reduce(names(4), SetOracle(frozenset({"m0001"})), **arguments)


@pytest.mark.parametrize(
    "elements, message",
    [
        (["a", "b", "a"], "elements: expected distinct element names, got a more than once"),
        (["a", ""], "elements: expected non-empty str names, got ''"),
        ("abc", "elements: expected a sequence of element names, got 'abc'"),
    ],
)
def test_invalid_elements(elements: Any, message: str) -> None:
    with pytest.raises(ReductionError, match=message):
        reduce(elements, SetOracle(frozenset()))


def test_invalid_probe() -> None:
    with pytest.raises(ReductionError, match=r"probe: expected a callable probe\(candidate, attempt\) -> ProbeObservation, "
                                             "got 'probe'"):
        reduce(names(3), "probe")  # type: ignore[arg-type]
