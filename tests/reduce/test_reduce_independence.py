"""`check_independence`: a failure that the world without its reducible elements reproduces is not reduced."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pytest_ddenv.reduce import Outcome, ProbeObservation, ReductionInterrupted, reduce

from .conftest import SetOracle, names


def always_fails(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
    return ProbeObservation(Outcome.FAIL)


def records(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_a_failure_without_any_element_is_not_reduced(tmp_path: Path) -> None:
    log = tmp_path / "runs.jsonl"
    result = reduce(names(8), always_fails, keep=("m0003",), check_independence=True, log=log)
    assert result.independent and result.incomplete_reason == "world-independent" and not result.one_minimal
    assert result.minimal == result.original and result.simulations == 1 and result.probes == 0
    (run,) = [r for r in records(log) if r["event"] == "probe"]
    assert run["purpose"] == "independence" and run["candidate"] == ["m0003"] and run["attempt"] == 0
    resumed = reduce(names(8), always_fails, keep=("m0003",), check_independence=True, log=log)
    assert resumed.independent and resumed.simulations == 0, "the logged run answers"


def test_the_elements_a_precondition_needs_stay_in_the_world_without_elements(tmp_path: Path) -> None:
    log = tmp_path / "runs.jsonl"

    def needs_m0005(candidate: tuple[str, ...]) -> str | None:
        return None if "m0005" in candidate else "removes m0005"

    result = reduce(names(8), always_fails, preconditions=(needs_m0005,), check_independence=True, log=log)
    assert result.independent
    assert [r["candidate"] for r in records(log) if r["event"] == "probe"] == [["m0005"]]


def test_a_failure_that_needs_an_element_costs_one_run_more_and_reduces_as_before() -> None:
    culprits = frozenset({"m0002", "m0006"})
    without = reduce(names(10), SetOracle(culprits), deflake=0)
    oracle = SetOracle(culprits)
    checked = reduce(names(10), oracle, deflake=0, check_independence=True)
    assert not checked.independent and checked.minimal == without.minimal and checked.one_minimal
    assert checked.simulations == without.simulations + 1 and oracle.calls[0] == ((), 0)


def test_an_interrupt_during_the_check_keeps_the_log(tmp_path: Path) -> None:
    log = tmp_path / "runs.jsonl"

    def interrupted(candidate: tuple[str, ...], attempt: int) -> ProbeObservation:
        raise KeyboardInterrupt

    with pytest.raises(ReductionInterrupted) as stop:
        reduce(names(6), interrupted, check_independence=True, log=log)
    assert stop.value.reduction.incomplete_reason == "interrupted"
    assert records(log)[-1]["event"] == "end"


def test_check_independence_is_a_flag() -> None:
    with pytest.raises(Exception, match="check_independence: expected True or False, got 'yes'"):
        reduce(names(3), always_fails, check_independence="yes")  # type: ignore[arg-type]
