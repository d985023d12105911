"""A failure-rate verdict's words, numbers and JUnit properties (`pytest_plugin/rate_runs.py`), without pytest
sessions: the runs are given."""

from __future__ import annotations

import concurrent.futures
import json
import multiprocessing
from pathlib import Path

from pytest_ddenv.driver.artifacts import folder_problem
from pytest_ddenv.oracle.verdict import ErrorInfo
from pytest_ddenv.pytest_plugin.rate_runs import FailureRateUnknown, RateRun, RateVerdict, outcome_of, run_seed
from pytest_ddenv.reduce.rates import Rate, significantly_above


def runs(failures: int, count: int, errors: int = 0) -> tuple[RateRun, ...]:
    failed = ErrorInfo("AssertionError", "the robot ended right\nsecond line", "test_x.py:6")
    broken = ErrorInfo("WorkerError", "the worker died twice", "?", ddenv_error=True)
    made = [RateRun(index, run_seed(0, index), "failed", failed) for index in range(failures)]
    made += [RateRun(index, run_seed(0, index), "error", broken) for index in range(failures, failures + errors)]
    made += [RateRun(index, run_seed(0, index), "passed") for index in range(failures + errors, count)]
    return tuple(made)


def test_the_verdict_says_the_rate_and_its_wilson_interval() -> None:
    verdict = RateVerdict(runs(3, 20))
    assert verdict.headline() == "failed 3 of 20 runs, 15 % [5 %, 36 %]"
    assert verdict.failed, "with the default max_failure_rate 0 any failure fails the test"
    assert RateVerdict(runs(3, 20), 0.1).headline() == \
        "failed 3 of 20 runs, 15 % [5 %, 36 %], not significantly above the allowed 10 %"
    assert not RateVerdict(runs(3, 20), 0.1).failed
    assert RateVerdict(runs(10, 20), 0.1).failed
    assert not RateVerdict(runs(0, 20)).failed


def test_erring_runs_are_left_out_of_the_rate_and_counted() -> None:
    verdict = RateVerdict(runs(1, 10, errors=2))
    assert verdict.rate == Rate(1, 8) and verdict.errors == 2
    assert verdict.headline().endswith("(2 runs erred: not counted)")
    props = dict(verdict.properties())
    assert (props["ddenv_rate_runs"], props["ddenv_rate_failures"], props["ddenv_rate_errors"]) == (8, 1, 2)
    assert json.loads(str(props["ddenv_run_1"]))["outcome"] == "error"
    assert outcome_of(ErrorInfo("Failed", "", "x.py:1", phase="setup")) == "error"
    assert outcome_of(ErrorInfo("Skipped", "", "x.py:1")) == "error"
    assert outcome_of(ErrorInfo("ControllerTimeout", "took 301 s", "x.py:1")) == "error"  # the run's wall-clock cap
    assert outcome_of(ErrorInfo("ControllerError", "controller raised", "x.py:1")) == "failed"


def test_the_run_records_have_the_contracts_keys() -> None:
    verdict = RateVerdict(runs(1, 2))
    props = dict(verdict.properties())
    assert props["ddenv_rate_interval"] == "0.095,0.905" and props["ddenv_rate_verdict"] == "failed"
    assert json.loads(str(props["ddenv_run_0"])) == {
        "run": 0, "seed": 0, "outcome": "failed", "type": "AssertionError", "predicate": None, "signature": None,
        "location": "test_x.py:6", "message": "the robot ended right"}
    assert json.loads(str(props["ddenv_run_1"]))["seed"] == 1_000_003
    assert verdict.reduced_run() == verdict.runs[0]
    assert "run 0 (seed 0): failed: AssertionError: the robot ended right at test_x.py:6" in verdict.failure_text()


def test_significantly_above_is_the_lower_end_of_the_interval() -> None:
    assert significantly_above(Rate(1, 20), 0.0) and not significantly_above(Rate(0, 20), 0.0)
    assert not significantly_above(Rate(0, 0), 0.0)
    assert significantly_above(Rate(5, 10), 0.2) and not significantly_above(Rate(2, 10), 0.2)


def test_a_verdict_on_runs_that_mostly_erred_is_an_error_not_a_pass() -> None:
    verdict = RateVerdict(runs(0, 20, errors=18), 0.5)  # 2 passing runs left: no verdict on the test
    assert verdict.erred_mostly and not verdict.failed and verdict.word == "error"
    assert verdict.headline().startswith("no verdict: 18 of 20 runs erred; failed 0 of 2 runs")
    assert dict(verdict.properties())["ddenv_rate_verdict"] == "error"
    message = str(FailureRateUnknown(verdict))
    assert "the worker died twice" in message and message.count("\n  run ") == 5 and "... and 13 more" in message
    assert RateVerdict(runs(2, 20, errors=18)).word == "failed", "failing runs that are significant still fail it"
    assert RateVerdict(runs(0, 20, errors=10)).word == "passed", "half the runs erring still leaves a verdict"


def check_often(folder: Path) -> set[str | None]:
    return {folder_problem(folder) for _ in range(300)}


def test_the_artifacts_folder_check_of_processes_at_once_never_collides(tmp_path: Path) -> None:
    """Probe workers start at once and each checks --ddenv-artifacts: a folder that does not exist yet was made
    and removed under its own name by each, so one saw the other's and its pytest stopped (exit code 4)."""
    folder = tmp_path / "missing" / "artifacts"
    with concurrent.futures.ProcessPoolExecutor(4, mp_context=multiprocessing.get_context("fork")) as pool:
        problems = set().union(*pool.map(check_often, [folder] * 4))
    assert problems == {None}
    assert not (tmp_path / "missing").exists(), "the check leaves nothing behind"
