"""`RobotWorld`: what a scenario test gets from the `robot_world` fixture, and `RobotFailure`.

No pytest import: the same object serves the pytest fixture, the `ddenv` command and user scripts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from os import PathLike
from typing import TYPE_CHECKING, Any

import numpy as np

from pytest_ddenv.errors import DdenvError, ScenarioError, WorldError, shown
from pytest_ddenv.validation import expected, is_flag, is_integral, is_real
from pytest_ddenv.world.model import World

if TYPE_CHECKING:
    from pytest_ddenv.oracle.predicates import FailureSignature, Predicate, PredicateSpec
    from pytest_ddenv.scenario.gym_env import RobotEnv
    from pytest_ddenv.sim import ControllerLike, Run, RunSettings

FIXTURE = "robot_world"
"""The name of the pytest fixture that gives a test its `RobotWorld`."""
ATTEMPT_SEED_STRIDE = 1_000_003
"""Re-run k of a probe uses seed + k * stride, so deflaking re-runs never collide with a test's own seeds."""
DEFAULT_MAX_WALL_TIME = 300.0
"""Wall-clock seconds one `run()` may take before it fails with `ControllerTimeout` (`--ddenv-run-timeout`)."""
NO_WORLD_YET = World(name="no world yet: a @given test binds each drawn world with robot_world.rebound(world)")
"""The fixture's world in a `@given` test without a world marker: the test draws its worlds."""


def _hidden_in_tracebacks(excinfo: object) -> bool:
    """`sim.tracebacks.hidden_in_tracebacks`, imported when pytest asks (loading the plugin loads no simulation)."""
    from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks

    return hidden_in_tracebacks(excinfo)


__tracebackhide__ = _hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""


class RobotFailure(AssertionError):
    """A failure predicate fired while the robot ran. Carries the failure signature and the run."""

    def __init__(self, signature: FailureSignature, run: Run) -> None:
        self.signature = signature
        self.run = run
        super().__init__(signature.explain())


def failure_predicates(values: Sequence[PredicateSpec | str | Predicate] | str | None) -> tuple[PredicateSpec, ...]:
    """`PredicateSpec`s from what `RobotWorld(predicates=...)` is given: specs, registered names (with their
    default parameters, built as the `robot_failure` marker builds them), predicate objects or functions of
    the state. `ScenarioError` naming the entry otherwise."""
    from pytest_ddenv.oracle.predicates import PredicateSpec, predicate_spec

    if values is None:
        return ()
    if isinstance(values, str):
        values = (values,)
    if not isinstance(values, (Sequence, set, frozenset)):
        raise ScenarioError(expected("a list of predicates (names, predicate objects or PredicateSpecs)", values,
                                     "RobotWorld(predicates=...)"))
    specs = []
    for index, value in enumerate(values):
        if isinstance(value, PredicateSpec):
            specs.append(value)
            continue
        try:
            specs.append(predicate_spec(value))
        except DdenvError as error:
            raise ScenarioError(f"RobotWorld(predicates=...)[{index}]: {error}") from None
    return tuple(specs)


def checked_world(world: World, where: str) -> World:
    """`world`, if it is a `World` whose values the simulator takes (`world.values.check_world_values`);
    a `WorldError` saying so at `where` otherwise (a path is no world: `World.load(path)` reads one)."""
    from pytest_ddenv.world.values import check_world_values

    if not isinstance(world, World):
        hint = f"; read a world file with World.load({shown(str(world))})" if isinstance(world, (str, PathLike)) else ""
        raise WorldError(expected("a World", world, where) + hint)
    check_world_values(world)
    return world


class RobotWorld:
    """A world bound to a scenario test: run the robot in it, see the runs made so far.

    `run()` simulates the world's scenario with the test's failure predicates and a controller (the
    built-in go-to-goal law unless you pass yours); when a predicate fires it raises `RobotFailure` (an
    `AssertionError`), so the test fails with a one-paragraph explanation. `make_env()` gives the same
    simulation as a gymnasium environment; `report()` records what a simulator of your own did.
    """

    def __init__(
        self,
        world: World,
        *,
        predicates: Sequence[PredicateSpec | str | Predicate] | str = (),
        seed: int = 0,
        attempt: int = 0,
        max_wall_time: float | None = DEFAULT_MAX_WALL_TIME,
        engine: str | None = None,
    ) -> None:
        self.world = checked_world(world, "RobotWorld(world=...)")
        self.engine = engine
        """The physics engine the worlds it is rebound to run in (`--ddenv-engine`, the marker's `engine=`);
        None: each world's own `physics.engine`."""
        self.predicates = failure_predicates(predicates)
        for name, value in (("seed", seed), ("attempt", attempt)):
            if not is_integral(value) or value < 0:
                raise ScenarioError(expected("an integer >= 0", value, f"RobotWorld({name}=...)"))
        if max_wall_time is not None and not (is_real(max_wall_time) and 0 < max_wall_time < math.inf):
            raise ScenarioError(expected("a number of seconds > 0 or None", max_wall_time,
                                         "RobotWorld(max_wall_time=...)"))
        self.seed = seed
        self.attempt = attempt
        self.max_wall_time = max_wall_time
        self.runs: list[Run] = []
        self.run_error: BaseException | None = None
        """What the last `run()` raised instead of returning a run (a controller that raised or returned NaN,
        a run past its wall-clock limit); None when it returned one."""
        self.rebound_to: RobotWorld | None = None
        """The last `rebound` of this one (a Hypothesis test binds each generated world with it)."""

    def __repr__(self) -> str:
        count = len(self.world)
        return (f"RobotWorld({self.world.name or self.world.source!r}, {count} model{'s' if count != 1 else ''}, "
                f"seed={self.seed})")

    def rebound(self, world: World, *, attempt: int | None = None, engine: str | None = None) -> RobotWorld:
        """The same test setup (predicates, seed, time limits, chosen engine) on another world: a world the
        test generates (``@given(world=strategies.worlds())``: ``robot_world.rebound(world).run()``), or a
        reduction probe's candidate world and attempt. `attempt` defaults to this one's; `engine` (default:
        this one's) is the engine the new one runs its worlds in (a probe's: its world's, which may be another
        engine than the test's when a reduction confirms the failure in it)."""
        world = checked_world(world, "robot_world.rebound(world=...)")
        engine = self.engine if engine is None else engine
        if engine is not None and world.physics.engine != engine:
            world = world.with_engine(engine)
        bound = RobotWorld(world, predicates=self.predicates, seed=self.seed,
                           attempt=self.attempt if attempt is None else attempt, max_wall_time=self.max_wall_time,
                           engine=engine)
        self.rebound_to = bound
        return bound

    @property
    def latest(self) -> RobotWorld:
        """The world the test ran last: this one, or the last one it was rebound to (recursively)."""
        current = self
        while current.rebound_to is not None:
            current = current.rebound_to
        return current

    @property
    def run_seed(self) -> int:
        """The seed `run()` uses by default: the test's seed, shifted per reduction re-run."""
        return self.seed + self.attempt * ATTEMPT_SEED_STRIDE

    def build_predicates(self) -> list[Predicate]:
        """The test's failure predicates, ready for one run (each is reset when the run starts); for an arm's
        world when the test names none, the arm's defaults (`oracle.default_predicates("arm")`)."""
        specs = self.predicates
        if not specs and self.world.scenario is not None:
            from pytest_ddenv.oracle import default_predicates
            from pytest_ddenv.sim.arm.robot import robot_kind

            specs = default_predicates(robot_kind(self.world.scenario.robot, self.world.source))
        return [spec.build() for spec in specs]

    def run(
        self,
        *,
        seed: int | None = None,
        timeout: float | None = None,
        settings: RunSettings | None = None,
        controller: ControllerLike | None = None,
        raise_on_failure: bool = True,
        max_wall_time: float | None = None,
    ) -> Run:
        """Simulate the scenario once; raise `RobotFailure` if a failure predicate fires.

        `seed` defaults to the test's seed; `timeout` (simulated seconds) to the world file's. `controller`
        is called every control tick with an `Observation` and returns a `Command` (default: the built-in
        `GoToGoal`). `max_wall_time` (wall-clock seconds, default the fixture's) bounds a slow controller.
        """
        from pytest_ddenv.sim import RunSettings, simulate

        if self.world is NO_WORLD_YET:
            raise ScenarioError("robot_world has no world in a @given test: run the drawn one, "
                                "robot_world.rebound(world).run()")
        if settings is not None and not isinstance(settings, RunSettings):
            raise ScenarioError(expected("a RunSettings (pytest_ddenv.RunSettings(...)) or None", settings,
                                         "RobotWorld.run(settings=...)"))
        if not is_flag(raise_on_failure):
            raise ScenarioError(expected("True or False", raise_on_failure, "RobotWorld.run(raise_on_failure=...)"))
        if seed is not None and (not is_integral(seed) or seed < 0):
            raise ScenarioError(expected("an integer >= 0 or None", seed, "RobotWorld.run(seed=...)"))
        effective_seed = (self.seed if seed is None else seed) + self.attempt * ATTEMPT_SEED_STRIDE
        self.run_error = None
        try:
            result = simulate(
                self.world, seed=effective_seed, predicates=self.build_predicates(),
                settings=settings or RunSettings(), timeout=timeout, controller=controller,
                max_wall_time=self.max_wall_time if max_wall_time is None else max_wall_time,
            )
        except Exception as error:
            self.run_error = error
            raise
        self.runs.append(result)
        if raise_on_failure:
            self.check(result)
        return result

    def check(self, run: Run | None = None) -> None:
        """Raise `RobotFailure` if `run` (default: the last run, an env episode or a report) failed."""
        if run is None:
            if not self.runs:
                raise RuntimeError("no run yet: call run(), step an env from make_env(), or report()")
            run = self.runs[-1]
        if run.failure is not None:
            raise RobotFailure(run.failure, run)

    def make_env(self, **options: Any) -> RobotEnv:
        """The scenario as a `gymnasium.Env` (needs the `gym` extra): see `pytest_ddenv.scenario.gym_env.RobotEnv`
        for the observation and action spaces and `options`. Each finished episode is added to `runs`."""
        from pytest_ddenv.scenario.gym_env import RobotEnv

        return RobotEnv(self, **options)

    def report(
        self,
        times: Sequence[float] | np.ndarray,
        poses: Sequence[Sequence[float]] | np.ndarray,
        *,
        failure_pose: Sequence[float] | None = None,
        failure_time: float | None = None,
        touched: Sequence[str] | Mapping[str, float] = (),
        sensed: Mapping[str, float] | None = None,
        reached_goal: bool = False,
        detail: str = "",
        footprint: tuple[float, float] = (0.5, 0.5),
    ) -> Run:
        """Record what a simulator of your own did, so that the reduction's trajectory-guided schemas and the
        pictures work for it. Returns the recorded `Run` (also appended to `runs`).

        `times` (T,) simulated seconds; `poses` (T, 2) x y, (T, 3) x y yaw, or (T, 6) x y z roll pitch yaw,
        world frame. `failure_pose` (x, y[, z]) where it failed, at `failure_time` (default: the last time);
        then `check()` raises a `RobotFailure` ("reported" failure) matched by position like a predicate's.
        `touched`: the models the robot touched (names, or name -> first time); `sensed`: name -> first time
        its sensors saw it (for the "timestep" priority).
        """
        from pytest_ddenv.scenario.reported import reported_run

        run = reported_run(
            self.world, times, poses, seed=self.run_seed, failure_pose=failure_pose, failure_time=failure_time,
            touched=touched, sensed=sensed or {}, reached_goal=reached_goal, detail=detail, footprint=footprint,
        )
        self.runs.append(run)
        return run
