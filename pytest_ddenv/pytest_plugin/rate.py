"""`--ddenv-rate N`: a robot test run N times and judged by its failure rate (`rate_runs.RateVerdict`).

`RatePlugin` is registered when a collected test asks for a rate (the option, the ini key or `ddenv(rate=N)`).
Its `pytest_pyfunc_call` wrapper runs the test's own call (run 0), then runs 1..N-1 on the probe pool, and
fails the test with `FailureRateExceeded` when the rate is significantly above `max_failure_rate` (chained to
run 0's own exception when run 0 failed), otherwise lets it pass, even when run 0 failed. It is the innermost
wrapper (`trylast`), so that `--ddenv-reduce`'s wrapper sees the verdict. The records (a report section, JUnit
properties and flakyFailure elements, pytest-html extras, the terminal line) are `rate_records.py`'s.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Generator
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.errors import raised_by_ddenv
from pytest_ddenv.pytest_plugin.marks import spec_of
from pytest_ddenv.pytest_plugin.options import options_of
from pytest_ddenv.pytest_plugin.rate_records import with_rate
from pytest_ddenv.pytest_plugin.rate_runs import (
    FailureRateExceeded,
    FailureRateUnknown,
    RateRun,
    RateVerdict,
    pool_runs,
    run_seed,
)
from pytest_ddenv.scenario.robot_world import FIXTURE

if TYPE_CHECKING:
    from pytest_ddenv.pytest_plugin.progress import PytestProgress
    from pytest_ddenv.world.model import World

_verdict_key = pytest.StashKey[RateVerdict]()


def rate_of(item: pytest.Item) -> tuple[int, float]:
    """The test's runs and allowed failure rate: the option over the marker's argument, else 1 and 0."""
    spec, _ = spec_of(item)
    options = options_of(item.config)
    runs = options.rate if options.rate is not None else spec.rate
    allowed = options.max_failure_rate if options.max_failure_rate is not None else spec.max_failure_rate
    return runs, allowed


def wants_rate(config: pytest.Config, items: list[pytest.Item]) -> bool:
    """Whether a collected test asks for more than one run."""
    return options_of(config).rate not in (None, 1) or any(spec_of(item)[0].rate > 1 for item in items)


def verdict_of(item: pytest.Item) -> RateVerdict | None:
    """The test's failure-rate verdict, once its call has run with a rate."""
    return item.stash.get(_verdict_key, None)


class RatePlugin:
    """Run each robot test that has a rate N > 1 N times and judge it by its failure rate."""

    @pytest.hookimpl(wrapper=True, trylast=True)
    def pytest_pyfunc_call(self, pyfuncitem: pytest.Function) -> Generator[None, object, object]:
        __tracebackhide__ = True  # the verdict's traceback is the test's, not this wrapper's
        runs, allowed = rate_of(pyfuncitem)
        if runs <= 1:
            return (yield)
        reason = _not_rated(pyfuncitem)
        if reason is not None:
            warnings.warn(pytest.PytestWarning(f"{pyfuncitem.nodeid}: ddenv rate={runs} ignored: {reason}; the "
                                               "test runs once"), stacklevel=1)
            return (yield)
        try:
            result = yield
        except (Exception, pytest.fail.Exception) as error:  # pytest.fail() is a failure too
            if isinstance(error, pytest.xfail.Exception) or raised_by_ddenv(error) \
                    or pyfuncitem.config.getoption("usepdb", False):
                raise  # pytest.xfail() is no run, a broken setup no verdict; --pdb: the debugger opens on run 0's
            verdict = _judge(pyfuncitem, error, runs, allowed)
            if verdict.failed:
                raise FailureRateExceeded(verdict) from error
            if verdict.erred_mostly:
                raise FailureRateUnknown(verdict) from error
            return True  # run 0's failure is swallowed: the rate is the verdict (its run is a flaky failure)
        verdict = _judge(pyfuncitem, None, runs, allowed)
        if verdict.failed:
            raise FailureRateExceeded(verdict)
        if verdict.erred_mostly:
            raise FailureRateUnknown(verdict)
        return result

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_makereport(self, item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, Any, Any]:
        report = yield
        verdict = verdict_of(item)
        if call.when == "call" and verdict is not None:
            with_rate(item, report, verdict)
        return report


def _not_rated(item: pytest.Function) -> str | None:
    """Why a test with a rate runs once (None: it does not)."""
    from pytest_ddenv.pytest_plugin.given_example import inner_test

    if FIXTURE not in item.fixturenames:
        return "the test does not use robot_world"
    if inner_test(item) is not None:
        return "a @given test draws its own worlds (Hypothesis decides how often it runs)"
    return None


def _judge(item: pytest.Function, error: BaseException | None, runs: int, allowed: float) -> RateVerdict:
    """Run 0 is the call that just ended (`error`: what it raised); runs 1..`runs`-1 are made on the pool."""
    from pytest_ddenv.pytest_plugin.progress import PytestProgress
    from pytest_ddenv.scenario.probe import ProbeResult, describe_error
    from pytest_ddenv.scenario.robot_world import RobotWorld

    robot_world = item.funcargs[FIXTURE]
    assert isinstance(robot_world, RobotWorld)
    latest = robot_world.latest
    info = None if error is None else describe_error(error, item.path)
    first = RateRun.of(0, latest.run_seed, ProbeResult(info, latest.runs[-1] if latest.runs else None))
    progress = PytestProgress(item.config, item.nodeid, doing="measuring the failure rate of")
    made = [first]

    def done(run: RateRun) -> None:
        made.append(run)
        failed = sum(one.outcome == "failed" for one in made)
        progress(f"rate {item.name}: {len(made)} of {runs} runs, {failed} failed", probe_line=run.describe())

    try:
        others = _pool_runs(item, latest.world, robot_world.seed, runs, done, progress)
    finally:
        progress.close()
    verdict = RateVerdict((first, *others), allowed)
    progress(f"{item.nodeid}: {verdict.headline()}", final=True)
    item.stash[_verdict_key] = verdict
    for name, value in verdict.properties():
        item.user_properties.append((name, value))
    return verdict


def _pool_runs(item: pytest.Function, world: World, seed: int, runs: int, done: Callable[[RateRun], None],
               progress: PytestProgress) -> list[RateRun]:
    """Runs 1..`runs`-1 on the test's probe pool; every one an error when the pool cannot start."""
    from pytest_ddenv.errors import DdenvError
    from pytest_ddenv.pytest_plugin.pools import probe_pool, warn_about_shared_fixtures
    from pytest_ddenv.pytest_plugin.rate_runs import error_run

    indices = range(1, runs)
    try:
        with probe_pool(item, warn=lambda text: progress(text, final=True)) as pool:
            if pool.in_process:
                warn_about_shared_fixtures(item)
            return pool_runs(pool, world, seed, indices, done)
    except DdenvError as error:  # no pool (a dask scheduler that does not answer): no verdict from them
        progress(f"{item.nodeid}: the runs could not start: {error}", final=True)
        return [error_run(index, run_seed(seed, index), error) for index in indices]
