"""The user's pytest test as a probe job: every worker is a pytest session of its own that collected the
failing test the way the pytest process did (same arguments, ini file, rootdir, conftests, import mode,
plugins, `sys.path` and environment), and runs the *whole test* for each probe: `runtestprotocol`, with
its function-scoped fixtures set up and torn down per probe, and `robot_world` bound to the candidate
world. Whatever the test module, its conftests and the user's packages define (robots, controllers,
predicates, helpers) therefore exists in every worker exactly as in the pytest process.

`ItemHandler` is the in-process variant (`--ddenv-workers 1`): it calls the test function again in the
pytest process with the fixture values of the failing call.
"""

from __future__ import annotations

import inspect
import io
import os
import sys
import uuid
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import pytest

from pytest_ddenv.driver.user_code import exit_error, exits_raised
from pytest_ddenv.execution import Channel, serve_requests
from pytest_ddenv.pytest_plugin.given_example import GivenExample
from pytest_ddenv.scenario.probe import ProbeResult, describe_error
from pytest_ddenv.scenario.robot_world import FIXTURE, RobotWorld
from pytest_ddenv.world.model import World

OUTCOME_EXCEPTIONS: tuple[type[BaseException], ...] = (
    Exception, pytest.fail.Exception, pytest.skip.Exception, pytest.xfail.Exception,
)
"""What a probe's test call may raise and still be an outcome (pytest.fail/skip are BaseExceptions)."""
NEUTRALIZED_OPTIONS: Mapping[str, Any] = {
    # outputs that belong to the pytest process: a worker must not overwrite them
    "xmlpath": None, "htmlpath": None, "report_log": None, "resultlog": None,
    # test selection and stopping rules of the pytest process
    "lf": False, "failedfirst": False, "newfirst": False, "stepwise": False, "stepwise_skip": False,
    "exitfirst": False, "maxfail": 0, "collectonly": False,
    # pytest-xdist: a worker is one process
    "numprocesses": None, "maxprocesses": None, "dist": "no", "distload": False, "looponfail": False,
    # debugging needs a terminal a worker does not have
    "usepdb": False, "trace": False,
}
STARTUP_STDERR_LIMIT = 4000
"""Characters of what a worker's pytest said on stderr before it failed to collect the test (its end)."""


@dataclass
class ProbeBinding:
    """The candidate world and attempt of the probe running now in this worker (read by the fixture)."""

    world: World
    attempt: int
    robot_world: RobotWorld | None = None


PROBE_BINDING = pytest.StashKey[ProbeBinding]()
WORKER = pytest.StashKey[bool]()


@dataclass(frozen=True)
class PytestJob:
    """The failing test `nodeid` (in `test_file`) as a probe job; `PytestJob.of(item)` builds it."""

    nodeid: str
    test_file: str
    args: tuple[str, ...]
    invocation_dir: str
    sys_path: tuple[str, ...]
    environ: Mapping[str, str]
    basetemp: str | None = None
    capture: str | None = None
    example: GivenExample | None = None
    """A `@given` test's falsifying example: each probe calls the test once with it (`given_example`)."""
    key: str = field(default_factory=lambda: uuid.uuid4().hex)

    @classmethod
    def of(cls, item: pytest.Item, *, capture: str | None = None, example: GivenExample | None = None,
           seed: int | None = None) -> PytestJob:
        """`seed`: the workers' `--ddenv-seed` (None: the session's), so that attempt a runs with seed + a *
        ATTEMPT_SEED_STRIDE (a failure-rate run's seed being reduced)."""
        config = item.config
        factory = getattr(config, "_tmp_path_factory", None)  # as pytest-xdist does for its workers
        basetemp = None if factory is None else str(factory.getbasetemp() / "ddenv-probes")
        args = tuple(str(a) for a in config.invocation_params.args)
        if seed is not None:  # the last --ddenv-seed given wins
            args = (*args, "--ddenv-seed", str(seed))
        return cls(
            nodeid=item.nodeid, test_file=str(item.path), args=args,
            invocation_dir=str(config.invocation_params.dir), sys_path=tuple(sys.path), environ=dict(os.environ),
            basetemp=basetemp, capture=capture, example=example,
        )

    @property
    def label(self) -> str:
        return self.nodeid

    def serve(self, channel: Channel) -> None:
        """Start a pytest session that collects the test and serves probes from its run-test loop."""
        os.chdir(self.invocation_dir)
        sys.path[:] = list(self.sys_path) + [entry for entry in sys.path if entry not in self.sys_path]
        os.environ.update(self.environ)
        server = ProbeServer(self, channel)
        try:
            code = pytest.main(list(self.args), plugins=[server])
        finally:
            server.stop_holding_stderr()
        if not server.started:
            channel.failed(server.failure(code))


class ProbeServer:
    """The pytest plugin of a worker session (see the module docstring)."""

    def __init__(self, job: PytestJob, channel: Channel) -> None:
        self.job = job
        self.channel = channel
        self.started = False
        self.collect_errors: list[str] = []
        self.raised: dict[str, BaseException] = {}
        # What pytest writes to stderr before the test is collected (a conftest that does not import, a
        # usage error) is the reason the worker cannot serve: held, and sent with the failure.
        self.startup_stderr = io.StringIO()
        self._stderr: TextIO | None = sys.stderr
        sys.stderr = self.startup_stderr

    def stop_holding_stderr(self) -> None:
        if self._stderr is not None:
            sys.stderr, self._stderr = self._stderr, None

    def failure(self, code: object) -> str:
        if self.collect_errors:
            return f"collecting {self.job.test_file} failed:\n" + "\n".join(self.collect_errors)
        said = self.startup_stderr.getvalue().strip()[-STARTUP_STDERR_LIMIT:]
        last = said.splitlines()[-1].removeprefix("E").strip() if said else ""
        return (f"pytest (exit code {code}) did not collect {self.job.nodeid} from {self.job.test_file}"
                + (f": {last}; pytest said:\n{said}" if said else ""))

    @pytest.hookimpl(tryfirst=True)
    def pytest_cmdline_main(self, config: pytest.Config) -> None:
        config.args = [self.job.test_file]
        for name, value in NEUTRALIZED_OPTIONS.items():
            if hasattr(config.option, name):
                setattr(config.option, name, value)
        if self.job.basetemp is not None:  # the pytest process's basetemp, one folder per worker
            Path(self.job.basetemp).mkdir(parents=True, exist_ok=True)
            config.option.basetemp = str(Path(self.job.basetemp) / f"worker-{os.getpid()}")
        if self.job.capture is not None:
            config.option.capture = self.job.capture
        config.stash[WORKER] = True
        # Nobody reads a worker's terminal: without a reporter, no header, summary or terminal-summary hooks
        # (some plugins import heavy modules there: hypothesis's takes a second at every worker's exit).
        config.pluginmanager.set_blocked("terminalreporter")

    @pytest.hookimpl(tryfirst=True)
    def pytest_collection_modifyitems(self, config: pytest.Config, items: list[pytest.Item]) -> None:
        others = [item for item in items if item.nodeid != self.job.nodeid]
        items[:] = [item for item in items if item.nodeid == self.job.nodeid]
        if others:
            config.hook.pytest_deselected(items=others)

    def pytest_collectreport(self, report: pytest.CollectReport) -> None:
        if report.failed:
            self.collect_errors.append(f"{report.nodeid or self.job.test_file}: {report.longreprtext}")

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtestloop(self, session: pytest.Session) -> bool:
        found = [item for item in session.items if item.nodeid == self.job.nodeid]
        if not found:
            return True  # serve() reports the failure
        item = found[0]
        self.started = True
        self.stop_holding_stderr()
        serve_requests(self.channel, lambda world, attempt: self.run_item(item, world, attempt))
        return True

    @pytest.hookimpl(tryfirst=True)
    def pytest_pyfunc_call(self, pyfuncitem: pytest.Function) -> bool | None:
        """The test gets the candidate world, even from an overridden fixture; a `@given` test runs once on its
        falsifying example with the candidate world (no Hypothesis)."""
        binding = pyfuncitem.config.stash.get(PROBE_BINDING, None)
        if binding is not None:
            bind_probe(pyfuncitem, binding)
        if self.job.example is None or binding is None:
            return None
        self.job.example.call(pyfuncitem, fixture_arguments(pyfuncitem), binding.world)
        return True

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_makereport(self, item: pytest.Item, call: pytest.CallInfo[None]) -> Any:
        report = yield
        if call.excinfo is not None:
            self.raised.setdefault(call.when, call.excinfo.value)
        return report

    def run_item(self, item: pytest.Item, world: World, attempt: int) -> ProbeResult:
        """One probe: the test's setup, call and teardown with `robot_world` bound to `world`."""
        from _pytest.runner import runtestprotocol

        binding = ProbeBinding(world, attempt)
        item.config.stash[PROBE_BINDING] = binding
        self.raised.clear()
        try:
            # Tear down only the function's fixtures afterwards: module, class and session fixtures stay up
            # for the next probe, as for the next test of a normal session.
            with exits_raised():  # os._exit(0) in the test: reported as the exit it is, not a dead worker
                runtestprotocol(item, log=False, nextitem=item.parent)  # type: ignore[arg-type]
        finally:
            del item.config.stash[PROBE_BINDING]
        error = None
        for phase in ("setup", "call", "teardown"):
            if phase in self.raised:
                raised = self.raised[phase]
                error = (exit_error(raised, f"the probe's {phase}") if isinstance(raised, SystemExit)
                         else describe_error(raised, self.job.test_file, phase=phase))
                break
        robot_world = None if binding.robot_world is None else binding.robot_world.latest
        run = robot_world.runs[-1] if robot_world is not None and robot_world.runs else None
        return ProbeResult(error, run)


def bind_probe(item: pytest.Function, binding: ProbeBinding) -> None:
    """The test's `robot_world` is the probe's candidate world and attempt, even from an overridden fixture."""
    given = item.funcargs.get(FIXTURE)
    if not isinstance(given, RobotWorld):
        return
    if given.world is not binding.world or given.attempt != binding.attempt:
        given = given.rebound(binding.world, attempt=binding.attempt, engine=binding.world.physics.engine)
        item.funcargs[FIXTURE] = given
    binding.robot_world = given


def fixture_arguments(item: pytest.Function) -> dict[str, Any]:
    """The test function's arguments that pytest provides (its fixtures and parameters), by name."""
    parameters = inspect.signature(item.obj).parameters
    return {name: item.funcargs[name] for name in parameters if name in item.funcargs}


class ItemHandler:
    """Probes in the pytest process: call the test function again with `robot_world` rebound to the
    candidate world; the other arguments keep the values the failing call received."""

    def __init__(self, item: pytest.Function, example: GivenExample | None = None, seed: int | None = None) -> None:
        """`seed`: the base seed of the probes (None: the test's), as `PytestJob.of`'s."""
        self.item = item
        self.example = example
        self.arguments = fixture_arguments(item)
        original = item.funcargs[FIXTURE]
        assert isinstance(original, RobotWorld)
        if seed is not None and seed != original.seed:
            original = RobotWorld(original.world, predicates=original.predicates, seed=seed,
                                  max_wall_time=original.max_wall_time, engine=original.engine)
        self.original = original

    def __call__(self, world: World, attempt: int) -> ProbeResult:
        rebound = self.original.rebound(world, attempt=attempt, engine=world.physics.engine)  # the probe's
        arguments = {**self.arguments, FIXTURE: rebound}
        error = None
        try:
            with exits_raised():  # os._exit(0) in the test would end pytest without a word
                if self.example is not None:
                    self.example.call(self.item, arguments, world)
                else:
                    self.item.obj(**arguments)
        except SystemExit as exited:  # the test exited: an error of the probe, never a pass
            error = exit_error(exited, "the probe")
        except OUTCOME_EXCEPTIONS as raised:  # every exception is an outcome to classify
            error = describe_error(raised, self.item.path)
        ran = rebound.latest
        return ProbeResult(error, ran.runs[-1] if ran.runs else None)
