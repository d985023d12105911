"""A failure rate's runs and its verdict (`--ddenv-rate N`), as plain values: no hooks here.

Run i (0 <= i < N) of a test runs with the seed `seed + i * ATTEMPT_SEED_STRIDE`: run 0 is the test's own
call, runs 1..N-1 are probes with attempt i on the worker pool. Each is passed, failed or error (a worker that
crashed twice, a watchdog kill, a run past its wall-clock cap, an error of pytest-ddenv itself, a skip: never
a verdict); the verdict is computed from (failures, runs with a verdict) by `reduce.rates`.
"""

from __future__ import annotations

import concurrent.futures
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.reduce.rates import VERDICT_CONFIDENCE, Rate, significantly_above, wilson_interval
from pytest_ddenv.scenario.robot_world import ATTEMPT_SEED_STRIDE

if TYPE_CHECKING:
    from pytest_ddenv.execution import Pool
    from pytest_ddenv.oracle.verdict import ErrorInfo
    from pytest_ddenv.scenario.probe import ProbeResult
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World

RunOutcome = Literal["passed", "failed", "error"]
MESSAGE_LIMIT = 200
"""Characters of a run's first message line kept in its record."""
NOT_VERDICTS = ("Skipped", "XFailed", "Exit")
"""Exception types of pytest's that end a run without saying whether it passes: errors of that run."""


def run_seed(seed: int, index: int) -> int:
    """The seed of run `index` of a test whose seed is `seed` (`pytest ID --ddenv-seed <it>` reproduces it)."""
    return seed + index * ATTEMPT_SEED_STRIDE


@dataclass(frozen=True)
class RateRun:
    """One run: its index, seed and outcome, what it raised (None: it passed) and its last `Run` (kept in
    this process only, for a reduction of its failure)."""

    index: int
    seed: int
    outcome: RunOutcome
    error: ErrorInfo | None = None
    run: Run | None = field(default=None, compare=False, repr=False)

    @classmethod
    def of(cls, index: int, seed: int, result: ProbeResult) -> RateRun:
        return cls(index, seed, outcome_of(result.error), result.error, result.run)

    @property
    def first_line(self) -> str | None:
        """The first line of what it raised (at most `MESSAGE_LIMIT` characters); None when it passed."""
        if self.error is None:
            return None
        return (self.error.message.strip().splitlines() or [""])[0][:MESSAGE_LIMIT]

    def to_json(self) -> dict[str, Any]:
        """The record of the run (the JUnit property `ddenv_run_<i>`'s value, docs/writing-tests.md)."""
        error = self.error
        return {
            "run": self.index,
            "seed": self.seed,
            "outcome": self.outcome,
            "type": None if error is None else error.type_name,
            "predicate": None if error is None or error.signature is None else error.signature.predicate,
            "signature": None if error is None or error.signature is None else error.signature.to_dict(),
            "location": None if error is None else error.location,
            "message": self.first_line,
        }

    def describe(self) -> str:
        """"run 3 (seed 3000009): failed: RobotFailure: the 'stuck' predicate fired ... at test_x.py:12"."""
        what: str = self.outcome
        if self.error is not None:
            what += f": {self.error.type_name}: {self.first_line} at {self.error.location}"
        return f"run {self.index} (seed {self.seed}): {what}"


def outcome_of(error: ErrorInfo | None) -> RunOutcome:
    """Passed (nothing raised), error (pytest-ddenv's own error, a broken setup or teardown, a run stopped by its
    wall-clock cap, a skip), or failed."""
    from pytest_ddenv.oracle.verdict import is_run_error

    if error is None:
        return "passed"
    if is_run_error(error) or error.type_name in NOT_VERDICTS:
        return "error"
    return "failed"


def error_run(index: int, seed: int, error: BaseException) -> RateRun:
    """A run the pool could not make (a worker that died twice, a watchdog kill): an error, with its reason."""
    from pytest_ddenv.oracle.verdict import ErrorInfo

    return RateRun(index, seed, "error", ErrorInfo(type(error).__name__, str(error), "?", ddenv_error=True))


def pool_runs(pool: Pool[ProbeResult], world: World, seed: int, indices: Sequence[int],
              done: Callable[[RateRun], None]) -> list[RateRun]:
    """Runs `indices` of the test on `world`, as probes with attempt i, as many at a time as the pool has
    workers; `done` is called with each as it ends (in the order they end). In index order."""

    def one(index: int) -> RateRun:
        try:
            return RateRun.of(index, run_seed(seed, index), pool.call(world, index))
        except Exception as error:  # noqa: BLE001 - the pool could not run it: an error, never a verdict
            return error_run(index, run_seed(seed, index), error)

    runs: list[RateRun] = []
    if pool.in_process or pool.size <= 1:  # in this process: on this (the main) thread, one after another
        for index in indices:
            runs.append(one(index))
            done(runs[-1])
        return runs
    threads = concurrent.futures.ThreadPoolExecutor(max_workers=min(pool.size, len(indices)))
    try:
        futures = [threads.submit(one, index) for index in indices]
        for future in concurrent.futures.as_completed(futures):
            runs.append(future.result())
            done(runs[-1])
    finally:  # Ctrl-C: no new run starts; closing the pool ends the running ones
        threads.shutdown(wait=False, cancel_futures=True)
    return sorted(runs, key=lambda run: run.index)


def percent(value: float) -> str:
    return f"{100 * value:.0f} %"


@dataclass(frozen=True)
class RateVerdict:
    """A test's runs judged: it fails when its failure rate is significantly above `max_failure_rate`."""

    runs: tuple[RateRun, ...]
    max_failure_rate: float = 0.0

    @property
    def failures(self) -> int:
        return sum(run.outcome == "failed" for run in self.runs)

    @property
    def errors(self) -> int:
        return sum(run.outcome == "error" for run in self.runs)

    @property
    def rate(self) -> Rate:
        """(failures, runs with a verdict): errors are left out."""
        return Rate(self.failures, len(self.runs) - self.errors)

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.rate, VERDICT_CONFIDENCE)

    @property
    def failed(self) -> bool:
        return significantly_above(self.rate, self.max_failure_rate)

    @property
    def erred_mostly(self) -> bool:
        """More than half the runs erred (workers that could not start, watchdog kills): what is left is no
        verdict, and the test errs instead of passing on the few runs that ended."""
        return 2 * self.errors > len(self.runs)

    @property
    def word(self) -> str:
        """The verdict: "failed" (significantly above the allowed rate), "error" (`erred_mostly`), "passed"."""
        return "failed" if self.failed else "error" if self.erred_mostly else "passed"

    @property
    def failed_runs(self) -> tuple[RateRun, ...]:
        return tuple(run for run in self.runs if run.outcome == "failed")

    def reduced_run(self) -> RateRun | None:
        """The failing run a reduction reduces: run 0 when it failed, else the first failing run."""
        return next(iter(self.failed_runs), None)

    def headline(self) -> str:
        """"failed 3 of 20 runs, 15 % [5 %, 36 %], above the allowed 10 %" (and the errors left out)."""
        rate = self.rate
        low, high = self.interval
        text = f"failed {rate.fails} of {rate.runs} run{'s' if rate.runs != 1 else ''}"
        text += f", {percent(rate.value)} [{percent(low)}, {percent(high)}]" if rate.runs else ""
        if self.max_failure_rate > 0:
            relation = "above" if self.failed else "not significantly above"
            text += f", {relation} the allowed {percent(self.max_failure_rate)}"
        if self.errors:
            text += f" ({self.errors} run{'s' if self.errors != 1 else ''} erred: not counted)"
        if self.word == "error":
            text = f"no verdict: {self.errors} of {len(self.runs)} runs erred; {text}"
        return text

    def failure_text(self) -> str:
        """The message of a failing verdict: the headline, then each failing run's seed and first line."""
        lines = [f"ddenv failure rate: {self.headline()}"]
        lines += [f"  {run.describe()}" for run in self.failed_runs]
        return "\n".join(lines)

    def properties(self) -> list[tuple[str, object]]:
        """The JUnit properties of the verdict (pytest's `user_properties`), as docs/writing-tests.md lists them."""
        low, high = self.interval
        return [
            ("ddenv_rate_runs", self.rate.runs),
            ("ddenv_rate_failures", self.failures),
            ("ddenv_rate_errors", self.errors),
            ("ddenv_rate_interval", f"{low:.3f},{high:.3f}"),
            ("ddenv_rate_verdict", self.word),
            *((f"ddenv_run_{run.index}", json.dumps(run.to_json(), sort_keys=True)) for run in self.runs),
        ]

    def to_json(self) -> dict[str, Any]:
        """The verdict as plain data (it travels on the test's report, through pytest-xdist)."""
        low, high = self.interval
        return {
            "headline": self.headline(),
            "verdict": self.word,
            "runs": [run.to_json() for run in self.runs],
            "failures": self.failures, "errors": self.errors, "counted": self.rate.runs,
            "interval": [low, high], "max_failure_rate": self.max_failure_rate,
            "tracebacks": {str(run.index): run.error.traceback for run in self.failed_runs
                           if run.error is not None},
        }


class FailureRateUnknown(DdenvError):
    """More than half of a test's runs erred (`RateVerdict.erred_mostly`): an error of the runs, not a verdict
    on the test (never reduced), each erring run's reason listed."""

    def __init__(self, verdict: RateVerdict) -> None:
        erred = [run for run in verdict.runs if run.outcome == "error"]
        super().__init__("\n".join([f"ddenv failure rate: {verdict.headline()}",
                                     *(f"  {run.describe()}" for run in erred[:5]),
                                     *([f"  ... and {len(erred) - 5} more"] if len(erred) > 5 else [])]))
        self.verdict = verdict


class FailureRateExceeded(AssertionError):
    """A test whose failure rate is significantly above the allowed one (`--ddenv-rate`): the test's failure."""

    def __init__(self, verdict: RateVerdict) -> None:
        super().__init__(verdict.failure_text())
        self.verdict = verdict
