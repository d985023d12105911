"""The `Simulator`: runs worlds one after another, deterministically, in the physics engine each names."""

from __future__ import annotations

import importlib.util
import math
import time
from collections.abc import Sequence
from typing import Any, Self

from pytest_ddenv.alarm import Alarm
from pytest_ddenv.errors import ControllerTimeout, ScenarioError
from pytest_ddenv.oracle.predicates import GROUND, Predicate, check_predicates_for_robot
from pytest_ddenv.sim.arm.control import ArmCommand, ArmController, ArmObservation, check_arm_command
from pytest_ddenv.sim.arm.episode import ArmEpisode
from pytest_ddenv.sim.arm.robot import ArmRobot
from pytest_ddenv.sim.builder import GROUND_BODY_NAME
from pytest_ddenv.sim.control import (
    AnyCommand,
    Command,
    ControllerLike,
    Observation,
    check_command,
    check_controller,
    controller_name,
)
from pytest_ddenv.sim.engine_choice import make_physics
from pytest_ddenv.sim.episode import Episode, noise_streams
from pytest_ddenv.sim.physics import PhysicsEngine
from pytest_ddenv.sim.robot import ROBOTS, Robot, make_robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.validation import expected, is_finite_number, is_integral, is_number
from pytest_ddenv.world.model import ArmDescription, RobotDescription, Scenario, World

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""

START_CLEARANCE = 0.01
"""Spawn height above the support surface (m); the robot settles from there."""
MAX_START_PENETRATION = 0.02
"""A start pose whose robot overlaps a model by more than this (m) is 'inside an object'."""


class Simulator:
    """Runs worlds one after another, deterministically, each in the physics engine its `physics.engine` names
    (one engine instance per engine, created on first use and rebuilt for every run: see sim/physics.py).

    Use it as a context manager, or call `close()`. Not thread-safe; use one per process or thread.
    """

    def __init__(self) -> None:
        self._engines: dict[str, PhysicsEngine] = {}
        self._closed = False
        if importlib.util.find_spec("pybullet") is not None:  # the default engine, started now as it always was
            self._engine("pybullet", None)

    def _engine(self, name: str, source: str | None) -> PhysicsEngine:
        engine = self._engines.get(name)
        if engine is None:
            engine = self._engines[name] = make_physics(name, source)
        return engine

    # -- lifecycle -------------------------------------------------------------------------------------
    def close(self) -> None:
        for engine in self._engines.values():
            engine.close()
        self._engines.clear()
        self._closed = True

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:  # noqa: BLE001, S110 - a finalizer must not raise (at interpreter exit pybullet may be gone)
            pass

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def client(self) -> int:
        """The pybullet client id (-1 when closed or pybullet is not installed)."""
        engine = self._engines.get("pybullet")
        return -1 if self._closed or engine is None else int(getattr(engine, "client", -1))

    @property
    def pybullet_version(self) -> str:
        engine = self._engines.get("pybullet")
        return "" if engine is None else engine.version

    # -- validation ------------------------------------------------------------------------------------
    @staticmethod
    def check_scenario(world: World, timeout: float | None = None) -> Scenario:
        """Validate what can be checked without physics; return the scenario."""
        scenario = world.scenario
        if scenario is None:
            raise ScenarioError("the world has no scenario; add a 'scenario:' block (robot, start, goal, timeout)",
                                source=world.source, field="scenario")
        if not isinstance(scenario.robot, (RobotDescription, ArmDescription)) and scenario.robot not in ROBOTS:
            raise ScenarioError(
                f"unknown robot {scenario.robot!r}; registered robots: {', '.join(sorted(ROBOTS))}",
                source=world.source, field="scenario.robot",
            )
        limit = scenario.timeout if timeout is None else timeout
        if not is_finite_number(limit) or limit <= 0:
            field = "scenario.timeout" if timeout is None else "timeout"
            raise ScenarioError(expected("a finite time limit in seconds > 0", limit),
                                source=world.source, field=field)
        values = [*scenario.start.as_list(), scenario.goal[0], scenario.goal[1]]
        if not all(math.isfinite(v) for v in values):
            raise ScenarioError(expected("a finite start and goal", values), source=world.source, field="scenario")
        if not (scenario.goal_tolerance > 0):
            raise ScenarioError(expected("a number > 0", scenario.goal_tolerance), source=world.source,
                                field="scenario.goal_tolerance")
        names = set(world.names)
        for key in ("target", "table"):
            name = getattr(scenario, key)
            if name is not None and name not in names:
                raise ScenarioError(f"the {key} {name!r} is not a model of the world", source=world.source,
                                    field=f"scenario.{key}")
        return scenario

    # -- running ---------------------------------------------------------------------------------------
    def start(
        self,
        world: World,
        *,
        seed: int = 0,
        predicates: Sequence[Predicate] = (),
        settings: RunSettings = RunSettings(),
        timeout: float | None = None,
    ) -> Episode | ArmEpisode:
        """Build `world`, spawn its scenario's robot (seed `seed`) and return the episode at its first tick: an
        `ArmEpisode` for an arm, else an `Episode`.

        `Simulator.run` drives it with a controller; `robot_world.make_env()` with a policy's actions.
        """
        if self._closed:
            raise RuntimeError("this Simulator is closed")
        scenario = self.check_scenario(world, timeout)
        limit = float(scenario.timeout if timeout is None else timeout)
        if not is_integral(seed) or seed < 0:
            raise ScenarioError(expected("an integer >= 0", seed), field="seed")
        for predicate in predicates:
            if not isinstance(predicate, Predicate):
                raise ScenarioError(f"{predicate!r} is not a failure predicate (needs name, reset, check)",
                                    field="predicates")
        physics = self._engine(world.physics.engine, world.source)
        streams = noise_streams(int(seed))
        noise = settings.noise
        robot = make_robot(scenario.robot, world.source)
        arm = isinstance(robot, ArmRobot)
        try:
            check_predicates_for_robot(predicates, "arm" if arm else "mobile", robot.name)
        except ScenarioError as error:
            raise ScenarioError(error.reason, source=world.source, field="predicates") from None
        physics.load(world, robot, settings.friction)
        jitter = streams[0].standard_normal(3)
        if arm:  # an arm is bolted where the world puts it (the draws are made all the same)
            jitter[:] = 0.0
        start_x = scenario.start.x + noise.start_xy * jitter[0]
        start_y = scenario.start.y + noise.start_xy * jitter[1]
        start_yaw = scenario.start.yaw + noise.start_yaw * jitter[2]
        start_z = self._start_height(physics, world, scenario, robot, start_x, start_y, start_yaw)
        if arm and not scenario.start_z_given:
            start_z -= START_CLEARANCE  # the arm's base stands on its support
        driven, body = physics.spawn(robot, (start_x, start_y, start_z), start_yaw)
        self._check_start_clear(physics, world)
        for predicate in predicates:
            predicate.reset()
        kind: type[Episode | ArmEpisode] = ArmEpisode if arm else Episode
        return kind(
            physics, world=world, scenario=scenario, robot=driven, body=body, seed=int(seed),
            streams=streams, predicates=predicates, settings=settings, limit=limit,
        )

    def run(
        self,
        world: World,
        *,
        seed: int = 0,
        predicates: Sequence[Predicate] = (),
        settings: RunSettings = RunSettings(),
        timeout: float | None = None,
        controller: ControllerLike | ArmController | None = None,
        max_wall_time: float | None = None,
    ) -> Run:
        """Simulate `world`'s scenario with noise seed `seed`; `timeout` overrides the scenario's limit.

        `controller(observation) -> Command` drives the robot every control tick (default: `GoToGoal` with
        the settings' gains). What it raises propagates (with a note saying when); a command that is not a
        `Command`/`WheelCommand` or holds a NaN raises `ControllerError`; a run longer than
        `max_wall_time` wall-clock seconds raises `ControllerTimeout`. An arm's controller sees an
        `ArmObservation` and returns an arm's command (sim/arm/control.py); its default is `PickAndPlace`.
        """
        if controller is not None:
            check_controller(controller)
        max_wall_time = wall_limit(max_wall_time)
        episode = self.start(world, seed=seed, predicates=predicates, settings=settings, timeout=timeout)
        if controller is None:
            from pytest_ddenv.sim.arm.pick_place import PickAndPlace
            from pytest_ddenv.sim.controllers import default_controller

            controller = PickAndPlace() if isinstance(episode, ArmEpisode) else default_controller(settings)
        drive_loop(episode, controller, max_wall_time)
        return episode.result()

    # -- start pose ------------------------------------------------------------------------------------
    @staticmethod
    def _start_height(physics: PhysicsEngine, world: World, scenario: Scenario, robot: Robot, x: float, y: float,
                      yaw: float) -> float:
        """z of the robot base: given, or on top of the highest support under the footprint."""
        length, width = robot.footprint
        c, s = math.cos(yaw), math.sin(yaw)
        points = [(0.0, 0.0)] + [(sx * length / 2.0, sy * width / 2.0) for sx in (-1, 1) for sy in (-1, 1)]
        top = 1000.0 if not scenario.start_z_given else scenario.start.z + 0.05
        rays_from = [[x + c * a - s * b, y + s * a + c * b, top] for a, b in points]
        rays_to = [[fx, fy, -1000.0] for fx, fy, _ in rays_from]
        heights = physics.support_heights(rays_from, rays_to)
        if not heights:
            where = f"({scenario.start.x:g}, {scenario.start.y:g})"
            raise ScenarioError(
                f"nothing supports the robot's start {where}: no model and no ground plane under it",
                source=world.source, field="scenario.start",
            )
        if scenario.start_z_given:
            return scenario.start.z
        return max(heights) + robot.base_height + START_CLEARANCE

    @staticmethod
    def _check_start_clear(physics: PhysicsEngine, world: World) -> None:
        inside: dict[str, float] = {}
        bodies = physics.bodies
        for other, distance in physics.start_contacts():
            name = bodies.get(other)
            if name is None or distance > -MAX_START_PENETRATION:
                continue
            inside[name] = min(inside.get(name, 0.0), distance)
        if inside:
            names = ", ".join(f"{GROUND if n == GROUND_BODY_NAME else n} ({-d:.2f} m deep)"
                              for n, d in sorted(inside.items()))
            raise ScenarioError(f"the robot's start pose is inside {names}; move the start or the model(s)",
                                source=world.source, field="scenario.start")


def wall_limit(max_wall_time: object) -> float | None:
    """`max_wall_time` checked: None (no limit) or wall-clock seconds > 0; ScenarioError otherwise."""
    if max_wall_time is None:
        return None
    if not is_number(max_wall_time) or not max_wall_time > 0:
        raise ScenarioError(expected("a number of seconds > 0 or None", max_wall_time), field="max_wall_time")
    return float(max_wall_time)


def drive_loop(episode: Episode | ArmEpisode, controller: ControllerLike | ArmController,
               max_wall_time: float | None) -> None:
    """Run `episode` to its end with `controller` called every control tick, within `max_wall_time`: checked
    every tick, and (in the main thread) an alarm that also stops a controller that never returns."""
    reset = getattr(controller, "reset", None)
    first = True
    left = None if max_wall_time is None else max(max_wall_time - (time.perf_counter() - episode.started), 0.0)
    with Alarm(left, lambda: _too_slow(episode, controller, max_wall_time)):
        while not episode.finished:
            observation = episode.observe()
            if first and reset is not None:
                _call(reset, controller, observation)
            first = False
            episode.act(_command(episode, controller, observation))  # type: ignore[arg-type]
            if max_wall_time is not None and time.perf_counter() - episode.started > max_wall_time:
                raise _too_slow(episode, controller, max_wall_time)


def _command(episode: Episode | ArmEpisode, controller: Any, observation: Observation | ArmObservation
             ) -> AnyCommand | ArmCommand:
    """This tick's command, checked. A mobile robot that reached its goal without stopping early is told to
    stand still; an arm that placed the target goes on as its controller says."""
    if isinstance(episode, ArmEpisode):
        command = _call(controller, controller, observation)
        return check_arm_command(command, controller, observation.time, len(episode.arm.joint_names))
    if episode.reached:
        return Command(0.0, 0.0)
    return check_command(_call(controller, controller, observation), controller, observation.time)


def _too_slow(episode: Episode | ArmEpisode, controller: object, max_wall_time: float | None) -> ControllerTimeout:
    return ControllerTimeout(
        f"the run took more than its wall-clock limit of {max_wall_time:g} s (at t = {episode.time:.2f} s "
        f"simulated of {episode.limit:g} s): the controller {controller_name(controller)} or the world is "
        "too slow; raise the limit (robot_world.run(max_wall_time=...), --ddenv-run-timeout)"
    )


def _call(function: Any, controller: object, observation: Observation | ArmObservation) -> Any:
    try:
        return function(observation)
    except Exception as error:
        error.add_note(f"(raised by the controller {controller_name(controller)} at t = {observation.time:.2f} s "
                       "simulated)")
        raise
