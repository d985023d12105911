"""`ScenarioJob`: a world's scenario as the test a probe runs, without pytest (`ddenv run/reduce/replay`, the
benchmarks and user scripts).

The "test" is what the simplest scenario test does: `robot_world.run()` with the failure predicates (and a
controller), raising `RobotFailure` when one fires. The job is plain data: every worker imports the user's
code it names (`imports`, `controller`) before its first probe, so robots, predicates and controllers that
code registers exist there too.
"""

from __future__ import annotations

import os
import sys
import uuid
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from pytest_ddenv.driver.user_code import (
    UserCodeExit,
    exit_error,
    exit_message,
    exits_raised,
    import_user_code,
    load_attribute,
)
from pytest_ddenv.execution import Channel, Handler, serve_requests
from pytest_ddenv.oracle.predicates import PredicateSpec
from pytest_ddenv.scenario.probe import ProbeResult, describe_error
from pytest_ddenv.scenario.robot_world import DEFAULT_MAX_WALL_TIME, RobotWorld
from pytest_ddenv.sim import ControllerLike, Run, RunSettings
from pytest_ddenv.world.model import World


@dataclass(frozen=True)
class ScenarioJob:
    """Simulate the candidate world's scenario with `predicates`, base seed `seed` and `controller` (an
    object, a "module:attribute" reference, or None for the built-in go-to-goal law), after importing
    `imports` (module names or .py files). `sys_path` and `cwd` (default: this process's) are restored
    in every worker first."""

    predicates: tuple[PredicateSpec, ...]
    seed: int = 0
    timeout: float | None = None
    controller: str | ControllerLike | None = None
    imports: tuple[str, ...] = ()
    settings: RunSettings | None = None
    max_wall_time: float | None = DEFAULT_MAX_WALL_TIME
    sys_path: tuple[str, ...] = field(default_factory=lambda: tuple(sys.path))
    cwd: str = field(default_factory=os.getcwd)
    key: str = field(default_factory=lambda: uuid.uuid4().hex)

    @property
    def label(self) -> str:
        return "the world's scenario"

    def handler(self) -> Handler:
        """Load the user's code now and return `handle(world, attempt) -> ProbeResult`."""
        for spec in self.imports:
            import_user_code(spec)
        controller = self.controller
        if isinstance(controller, str):
            controller = load_attribute(controller)

        def handle(world: World, attempt: int) -> ProbeResult:
            robot_world = RobotWorld(world, predicates=self.predicates, seed=self.seed, attempt=attempt,
                                     max_wall_time=self.max_wall_time)
            try:
                with exits_raised():
                    robot_world.run(timeout=self.timeout, settings=self.settings, controller=controller)
            except SystemExit as error:  # the user's code exited: an error of the probe, never a pass
                return ProbeResult(exit_error(error, "the run"), robot_world.runs[-1] if robot_world.runs else None)
            except Exception as error:  # noqa: BLE001 - every exception is an outcome to classify
                return ProbeResult(describe_error(error, None), robot_world.runs[-1] if robot_world.runs else None)
            return ProbeResult(None, robot_world.runs[-1])

        return handle

    def serve(self, channel: Channel) -> None:
        sys.path[:] = [entry for entry in self.sys_path if entry] + [e for e in sys.path if e not in self.sys_path]
        if self.cwd and Path(self.cwd).is_dir():
            os.chdir(self.cwd)
        serve_requests(channel, self.handler())


def run_scenario(world: World, predicates: Sequence[PredicateSpec], *, seed: int = 0, attempt: int = 0,
                 timeout: float | None = None, controller: ControllerLike | None = None,
                 max_wall_time: float | None = DEFAULT_MAX_WALL_TIME) -> Run:
    """Simulate the world's scenario once in this process (never raises for a predicate failure; raises
    `UserCodeExit` when the controller or other code under test exits)."""
    robot_world = RobotWorld(world, predicates=predicates, seed=seed, attempt=attempt, max_wall_time=max_wall_time)
    try:
        with exits_raised():
            return robot_world.run(timeout=timeout, controller=controller, raise_on_failure=False)
    except SystemExit as error:
        raise UserCodeExit(f"{world.source or world.name or 'the world'}: {exit_message(error, 'the run')}") from None
