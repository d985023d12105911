"""The `Simulator`: one pybullet DIRECT client that runs worlds one after another, deterministically."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any, Self

from pytest_ddenv.alarm import Alarm
from pytest_ddenv.errors import ControllerTimeout, ScenarioError
from pytest_ddenv.oracle.predicates import GROUND, Predicate
from pytest_ddenv.sim.builder import GROUND_BODY_NAME, build_world
from pytest_ddenv.sim.control import (
    AnyCommand,
    Command,
    ControllerLike,
    Observation,
    check_command,
    check_controller,
    controller_name,
)
from pytest_ddenv.sim.episode import Episode, noise_streams
from pytest_ddenv.sim.robot import ROBOTS, Robot, make_robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.validation import expected, is_finite_number, is_integral, is_number
from pytest_ddenv.world.model import RobotDescription, Scenario, World

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""

START_CLEARANCE = 0.01
"""Spawn height above the support surface (m); the robot settles from there."""
MAX_START_PENETRATION = 0.02
"""A start pose whose robot overlaps a model by more than this (m) is 'inside an object'."""


class Simulator:
    """Owns one pybullet DIRECT client; `run` rebuilds the world (resetSimulation) for every run.

    Use it as a context manager, or call `close()`. Not thread-safe; use one per process or thread.
    """

    def __init__(self) -> None:
        from pytest_ddenv.sim.quiet import silenced

        with silenced():  # importing pybullet prints its build time on the C-level stdout
            import pybullet as p

            self._client: int = p.connect(p.DIRECT)
        self._p = p
        if self._client < 0:  # pragma: no cover
            raise RuntimeError("could not start a pybullet DIRECT client")
        self.pybullet_version = str(p.getAPIVersion())
        try:
            from importlib.metadata import version

            self.pybullet_version = version("pybullet")
        except Exception:  # noqa: BLE001, S110 - any failure keeps getAPIVersion()  # pragma: no cover
            pass

    # -- lifecycle -------------------------------------------------------------------------------------
    def close(self) -> None:
        if self._client >= 0:
            try:
                self._p.disconnect(physicsClientId=self._client)
            except Exception:  # noqa: BLE001, S110 - the client is already gone  # pragma: no cover
                pass
            self._client = -1

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
    def client(self) -> int:
        return self._client

    # -- validation ------------------------------------------------------------------------------------
    @staticmethod
    def check_scenario(world: World, timeout: float | None = None) -> Scenario:
        """Validate what can be checked without physics; return the scenario."""
        scenario = world.scenario
        if scenario is None:
            raise ScenarioError("the world has no scenario; add a 'scenario:' block (robot, start, goal, timeout)",
                                source=world.source, field="scenario")
        if not isinstance(scenario.robot, RobotDescription) and scenario.robot not in ROBOTS:
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
    ) -> Episode:
        """Build `world`, spawn its scenario's robot (seed `seed`) and return the episode at its first tick.

        `Simulator.run` drives it with a controller; `robot_world.make_env()` with a policy's actions.
        """
        if self._client < 0:
            raise RuntimeError("this Simulator is closed")
        scenario = self.check_scenario(world, timeout)
        limit = float(scenario.timeout if timeout is None else timeout)
        if not is_integral(seed) or seed < 0:
            raise ScenarioError(expected("an integer >= 0", seed), field="seed")
        for predicate in predicates:
            if not isinstance(predicate, Predicate):
                raise ScenarioError(f"{predicate!r} is not a failure predicate (needs name, reset, check)",
                                    field="predicates")
        p, client = self._p, self._client
        streams = noise_streams(int(seed))
        noise = settings.noise
        robot = make_robot(scenario.robot, world.source)
        p.resetSimulation(physicsClientId=client)
        physics = world.physics
        p.setGravity(*physics.gravity, physicsClientId=client)
        p.setPhysicsEngineParameter(
            fixedTimeStep=float(physics.timestep), numSolverIterations=int(physics.solver_iterations),
            deterministicOverlappingPairs=1, physicsClientId=client,
        )
        bodies = build_world(p, client, world, settings.friction)
        jitter = streams[0].standard_normal(3)
        start_x = scenario.start.x + noise.start_xy * jitter[0]
        start_y = scenario.start.y + noise.start_xy * jitter[1]
        start_yaw = scenario.start.yaw + noise.start_yaw * jitter[2]
        start_z = self._start_height(world, scenario, robot, start_x, start_y, start_yaw)
        body = robot.spawn(client, (start_x, start_y, start_z), start_yaw)
        self._check_start_clear(world, body, bodies)
        for predicate in predicates:
            predicate.reset()
        return Episode(
            p, client, world=world, scenario=scenario, robot=robot, body=body, bodies=bodies, seed=int(seed),
            streams=streams, predicates=predicates, settings=settings, limit=limit,
            pybullet_version=self.pybullet_version,
        )

    def run(
        self,
        world: World,
        *,
        seed: int = 0,
        predicates: Sequence[Predicate] = (),
        settings: RunSettings = RunSettings(),
        timeout: float | None = None,
        controller: ControllerLike | None = None,
        max_wall_time: float | None = None,
    ) -> Run:
        """Simulate `world`'s scenario with noise seed `seed`; `timeout` overrides the scenario's limit.

        `controller(observation) -> Command` drives the robot every control tick (default: `GoToGoal` with
        the settings' gains). What it raises propagates (with a note saying when); a command that is not a
        `Command`/`WheelCommand` or holds a NaN raises `ControllerError`; a run longer than
        `max_wall_time` wall-clock seconds raises `ControllerTimeout`.
        """
        if controller is None:
            from pytest_ddenv.sim.controllers import default_controller

            controller = default_controller(settings)
        check_controller(controller)
        max_wall_time = wall_limit(max_wall_time)
        episode = self.start(world, seed=seed, predicates=predicates, settings=settings, timeout=timeout)
        drive_loop(episode, controller, max_wall_time)
        return episode.result()

    # -- start pose ------------------------------------------------------------------------------------
    def _start_height(self, world: World, scenario: Scenario, robot: Robot, x: float, y: float, yaw: float) -> float:
        """z of the robot base: given, or on top of the highest support under the footprint."""
        p, client = self._p, self._client
        length, width = robot.footprint
        c, s = math.cos(yaw), math.sin(yaw)
        points = [(0.0, 0.0)] + [(sx * length / 2.0, sy * width / 2.0) for sx in (-1, 1) for sy in (-1, 1)]
        top = 1000.0 if not scenario.start_z_given else scenario.start.z + 0.05
        rays_from = [[x + c * a - s * b, y + s * a + c * b, top] for a, b in points]
        rays_to = [[fx, fy, -1000.0] for fx, fy, _ in rays_from]
        hits = p.rayTestBatch(rays_from, rays_to, numThreads=1, physicsClientId=client)
        heights: list[float] = [hit[3][2] for hit in hits if hit[0] >= 0]
        if not heights:
            where = f"({scenario.start.x:g}, {scenario.start.y:g})"
            raise ScenarioError(
                f"nothing supports the robot's start {where}: no model and no ground plane under it",
                source=world.source, field="scenario.start",
            )
        if scenario.start_z_given:
            return scenario.start.z
        return max(heights) + robot.base_height + START_CLEARANCE

    def _check_start_clear(self, world: World, body: int, bodies: dict[int, str]) -> None:
        p, client = self._p, self._client
        p.performCollisionDetection(physicsClientId=client)
        inside: dict[str, float] = {}
        for point in p.getContactPoints(bodyA=body, physicsClientId=client):
            name = bodies.get(point[2])
            if name is None or point[8] > -MAX_START_PENETRATION:
                continue
            inside[name] = min(inside.get(name, 0.0), point[8])
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


def drive_loop(episode: Episode, controller: ControllerLike, max_wall_time: float | None) -> None:
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
            if episode.reached:  # reached without stopping early: the robot is told to stand still
                command: AnyCommand = Command(0.0, 0.0)
            else:
                command = check_command(_call(controller, controller, observation), controller, observation.time)
            episode.act(command)
            if max_wall_time is not None and time.perf_counter() - episode.started > max_wall_time:
                raise _too_slow(episode, controller, max_wall_time)


def _too_slow(episode: Episode, controller: ControllerLike, max_wall_time: float | None) -> ControllerTimeout:
    return ControllerTimeout(
        f"the run took more than its wall-clock limit of {max_wall_time:g} s (at t = {episode.time:.2f} s "
        f"simulated of {episode.limit:g} s): the controller {controller_name(controller)} or the world is "
        "too slow; raise the limit (robot_world.run(max_wall_time=...), --ddenv-run-timeout)"
    )


def _call(function: Any, controller: object, observation: Observation) -> Any:
    try:
        return function(observation)
    except Exception as error:
        error.add_note(f"(raised by the controller {controller_name(controller)} at t = {observation.time:.2f} s "
                       "simulated)")
        raise
