"""The `Simulator`: one pybullet DIRECT client that runs worlds one after another, deterministically."""

from __future__ import annotations

import math
import time as _time
from collections.abc import Sequence
from typing import Any

import numpy as np

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.oracle import (
    GROUND,
    Contact,
    FailureSignature,
    History,
    Predicate,
    RobotState,
)
from pytest_ddenv.sim.builder import GROUND_BODY_NAME, build_world
from pytest_ddenv.sim.robot import ROBOTS, Robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.world import Scenario, World

GOAL_STOP_DISTANCE = 0.05
"""The controller stops when its own position estimate is this close to the goal (m)."""
START_CLEARANCE = 0.01
"""Spawn height above the support surface (m); the robot settles from there."""
MAX_START_PENETRATION = 0.02
"""A start pose whose robot overlaps a model by more than this (m) is 'inside an object'."""
_NOISE_STREAMS = ("start", "actuation", "odometry", "imu", "laser")


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class Simulator:
    """Owns one pybullet DIRECT client; `run` rebuilds the world (resetSimulation) for every run.

    Use it as a context manager, or call `close()`. Not thread-safe; use one per process or thread.
    """

    def __init__(self) -> None:
        from pytest_ddenv.sim.quiet import silenced

        with silenced():  # importing pybullet prints its build time on the C-level stdout
            import pybullet as p

            self._client = p.connect(p.DIRECT)
        self._p = p
        if self._client < 0:  # pragma: no cover
            raise RuntimeError("could not start a pybullet DIRECT client")
        self.pybullet_version = str(p.getAPIVersion())
        try:
            from importlib.metadata import version

            self.pybullet_version = version("pybullet")
        except Exception:  # pragma: no cover
            pass
        self.runs = 0

    # -- lifecycle -------------------------------------------------------------------------------------
    def close(self) -> None:
        if self._client >= 0:
            try:
                self._p.disconnect(physicsClientId=self._client)
            except Exception:  # pragma: no cover - already gone
                pass
            self._client = -1

    def __enter__(self) -> Simulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
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
        if scenario.robot not in ROBOTS:
            raise ScenarioError(
                f"unknown robot {scenario.robot!r}; registered robots: {', '.join(sorted(ROBOTS))}",
                source=world.source, field="scenario.robot",
            )
        limit = scenario.timeout if timeout is None else timeout
        if isinstance(limit, bool) or not isinstance(limit, (int, float)) or not math.isfinite(limit) or limit <= 0:
            field = "scenario.timeout" if timeout is None else "timeout"
            raise ScenarioError(f"the time limit must be a finite number of seconds > 0, got {limit!r}",
                                source=world.source, field=field)
        values = [*scenario.start.as_list(), scenario.goal[0], scenario.goal[1]]
        if not all(math.isfinite(v) for v in values):
            raise ScenarioError("start and goal must be finite numbers", source=world.source, field="scenario")
        if not (scenario.goal_tolerance > 0):
            raise ScenarioError("goal_tolerance must be > 0", source=world.source, field="scenario.goal_tolerance")
        return scenario

    # -- running ---------------------------------------------------------------------------------------
    def run(
        self,
        world: World,
        *,
        seed: int = 0,
        predicates: Sequence[Predicate] = (),
        settings: RunSettings = RunSettings(),
        timeout: float | None = None,
    ) -> Run:
        """Simulate `world`'s scenario with noise seed `seed`; `timeout` overrides the scenario's limit."""
        if self._client < 0:
            raise RuntimeError("this Simulator is closed")
        scenario = self.check_scenario(world, timeout)
        limit = float(scenario.timeout if timeout is None else timeout)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ScenarioError(f"the seed must be an integer >= 0, got {seed!r}", field="seed")
        for predicate in predicates:
            if not isinstance(predicate, Predicate):
                raise ScenarioError(f"{predicate!r} is not a failure predicate (needs name, reset, check)",
                                    field="predicates")
        started = _time.perf_counter()
        p, client = self._p, self._client
        streams = [np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(len(_NOISE_STREAMS))]
        rng_start, rng_act, rng_odo, rng_imu, rng_laser = streams
        noise = settings.noise

        # -- build ---------------------------------------------------------------------------------
        p.resetSimulation(physicsClientId=client)
        physics = world.physics
        dt = float(physics.timestep)
        p.setGravity(*physics.gravity, physicsClientId=client)
        p.setPhysicsEngineParameter(
            fixedTimeStep=dt, numSolverIterations=int(physics.solver_iterations),
            deterministicOverlappingPairs=1, physicsClientId=client,
        )
        bodies = build_world(p, client, world, settings.friction)
        jitter = rng_start.standard_normal(3)
        start_x = scenario.start.x + noise.start_xy * jitter[0]
        start_y = scenario.start.y + noise.start_xy * jitter[1]
        start_yaw = scenario.start.yaw + noise.start_yaw * jitter[2]
        robot: Robot = ROBOTS[scenario.robot]()
        start_z = self._start_height(world, scenario, robot, start_x, start_y, start_yaw)
        body = robot.spawn(client, (start_x, start_y, start_z), start_yaw)
        self._check_start_clear(world, body, bodies)
        self.runs += 1

        # -- run -----------------------------------------------------------------------------------
        for predicate in predicates:
            predicate.reset()
        steps_per_tick = max(1, round(1.0 / (settings.control_rate * dt)))
        tick_dt = steps_per_tick * dt
        ticks = math.ceil(limit / tick_dt - 1e-9)
        laser_every = max(1, round(settings.control_rate / settings.laser_rate))
        record_every = max(1, round(settings.control_rate / settings.record_rate))
        wheels = robot.wheel_links
        wheel_index = {link: i for i, link in enumerate(wheels)}
        link_names = robot.link_names
        weight = robot.mass * float(np.linalg.norm(physics.gravity))
        goal = scenario.goal
        goal_3d = goal[2] is not None
        laser = _Laser(p, client, settings, robot, bodies) if settings.laser_rays > 0 else None

        history = History()
        times: list[float] = []
        poses: list[list[float]] = []
        velocities: list[list[float]] = []
        wheel_loads_log: list[list[float]] = []
        first_touch: dict[str, float] = {}
        last_touch: dict[str, float] = {}
        first_sensed: dict[str, float] = {}
        failure: FailureSignature | None = None
        reached = False
        goal_time: float | None = None
        estimate = [scenario.start.x, scenario.start.y]
        start_pose: tuple[float, ...] | None = None
        steps = 0
        tick = 0
        while True:
            now = steps * dt
            position, orientation = p.getBasePositionAndOrientation(body, physicsClientId=client)
            roll, pitch, yaw = p.getEulerFromQuaternion(orientation)
            linear, angular = p.getBaseVelocity(body, physicsClientId=client)
            pose = (position[0], position[1], position[2], roll, pitch, yaw)
            velocity = (*linear, *angular)
            if start_pose is None:
                start_pose = pose
            # contacts
            per_pair: dict[tuple[int, int], float] = {}
            for point in p.getContactPoints(bodyA=body, physicsClientId=client):
                key = (point[3], point[2])
                per_pair[key] = per_pair.get(key, 0.0) + point[9]
            contacts = []
            loads = [0.0] * len(wheels)
            for (link, other), force in per_pair.items():
                name = bodies.get(other)
                if name is None:
                    continue
                is_wheel = link in wheel_index
                if is_wheel:
                    loads[wheel_index[link]] += force
                model = GROUND if name == GROUND_BODY_NAME else name
                contacts.append(Contact(model, link_names.get(link, str(link)), is_wheel, force))
                if model != GROUND:
                    first_touch.setdefault(model, now)
                    last_touch[model] = now
            contacts.sort(key=lambda c: (c.model, c.link))
            # laser (a fixed number of noise draws per scan; scans at fixed ticks)
            if laser is not None and tick % laser_every == 0:
                laser.scan(position, yaw, rng_laser.standard_normal(settings.laser_rays) * noise.laser,
                           now, first_sensed)
            history.append(now, (position[0], position[1], position[2]))
            if goal_3d:
                distance = math.dist(position, (goal[0], goal[1], goal[2]))  # type: ignore[arg-type]
            else:
                distance = math.hypot(position[0] - goal[0], position[1] - goal[1])
            if tick % record_every == 0:
                times.append(now)
                poses.append(list(pose))
                velocities.append(list(velocity))
                wheel_loads_log.append(loads)
            decided = reached or failure is not None
            if not decided:
                if distance <= scenario.goal_tolerance:
                    reached, goal_time = True, now
                elif predicates:
                    state = RobotState(
                        time=now, timeout=limit, pose=pose, velocity=velocity, start=start_pose,  # type: ignore[arg-type]
                        goal=goal, goal_distance=distance, contacts=tuple(contacts), wheel_loads=tuple(loads),
                        weight=weight, history=history,
                    )
                    for predicate in predicates:
                        failure = predicate.check(state)
                        if failure is not None:
                            break
            finished = tick >= ticks or ((reached or failure is not None) and settings.stop_early)
            if finished:
                if tick % record_every != 0:
                    times.append(now)
                    poses.append(list(pose))
                    velocities.append(list(velocity))
                    wheel_loads_log.append(loads)
                break
            # localisation: dead reckoning from the wheel encoders, yaw from a noisy IMU/compass
            odo = rng_odo.standard_normal(2)
            imu = rng_imu.standard_normal(1)
            act = rng_act.standard_normal(2)
            v_meas, _ = robot.measured_velocity()
            yaw_est = _wrap(yaw + noise.imu_yaw * float(imu[0]))
            v_meas *= 1.0 + noise.odometry * float(odo[0])
            estimate[0] += v_meas * math.cos(yaw_est) * tick_dt
            estimate[1] += v_meas * math.sin(yaw_est) * tick_dt
            # go-to-goal control on the estimate
            if reached:
                v_cmd = w_cmd = 0.0
            else:
                v_cmd, w_cmd = _go_to_goal(estimate, yaw_est, goal, settings)
                if laser is not None and settings.avoid_obstacles:
                    v_cmd, w_cmd = laser.avoid(v_cmd, w_cmd, settings)
            robot.drive(v_cmd, w_cmd, 1.0 + noise.actuation * float(act[0]), 1.0 + noise.actuation * float(act[1]))
            for _ in range(steps_per_tick):
                p.stepSimulation(physicsClientId=client)
            steps += steps_per_tick
            tick += 1

        wall = _time.perf_counter() - started
        return Run(
            seed=int(seed),
            settings=settings,
            world_name=world.name,
            model_names=world.names,
            robot=scenario.robot,
            times=np.asarray(times, dtype=np.float64),
            poses=np.asarray(poses, dtype=np.float64).reshape(-1, 6),
            velocities=np.asarray(velocities, dtype=np.float64).reshape(-1, 6),
            wheel_contacts=np.asarray(wheel_loads_log, dtype=np.float64).reshape(-1, len(wheels)),
            first_touch=first_touch,
            last_touch=last_touch,
            first_sensed=first_sensed,
            reached_goal=reached,
            goal_time=goal_time,
            failure=failure,
            sim_time=steps * dt,
            wall_time=wall,
            steps=steps,
            pybullet_version=self.pybullet_version,
        )

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
        heights = [hit[3][2] for hit in hits if hit[0] >= 0]
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
            names = ", ".join(f"{GROUND if n == GROUND_BODY_NAME else n} ({-d:.2f} m deep)" for n, d in sorted(inside.items()))
            raise ScenarioError(f"the robot's start pose is inside {names}; move the start or the model(s)",
                                source=world.source, field="scenario.start")


def _go_to_goal(estimate: list[float], yaw: float, goal: tuple[float, float, float | None],
                settings: RunSettings) -> tuple[float, float]:
    dx, dy = goal[0] - estimate[0], goal[1] - estimate[1]
    distance = math.hypot(dx, dy)
    if distance < GOAL_STOP_DISTANCE:
        return 0.0, 0.0
    error = _wrap(math.atan2(dy, dx) - yaw)
    w = max(-settings.max_turn_rate, min(settings.max_turn_rate, settings.turn_gain * error))
    v = min(settings.max_speed, 0.8 * distance) * max(0.0, math.cos(error)) ** 2
    return v, w


class _Laser:
    """A planar laser on the robot, rays tilted slightly down so low clutter near the robot is seen."""

    TILT = 0.08  # rad below horizontal: the rays reach the ground about 4 m out

    def __init__(self, p: Any, client: int, settings: RunSettings, robot: Robot, bodies: dict[int, str]) -> None:
        self.p, self.client = p, client
        self.rays = settings.laser_rays
        self.range = settings.laser_range
        self.robot = robot
        self.bodies = bodies
        fov = settings.laser_fov
        if fov >= 2 * math.pi - 1e-9:
            self.angles = np.arange(self.rays) * (2 * math.pi / self.rays) - math.pi
        else:
            self.angles = np.linspace(-fov / 2.0, fov / 2.0, self.rays)
        self.ranges = np.full(self.rays, np.inf)

    def scan(self, position: tuple[float, float, float], yaw: float, noise: np.ndarray, now: float,
             first_sensed: dict[str, float]) -> None:
        headings = self.angles + yaw
        cos_t, sin_t = math.cos(self.TILT), math.sin(self.TILT)
        direction = np.stack([np.cos(headings) * cos_t, np.sin(headings) * cos_t, np.full(self.rays, -sin_t)], axis=1)
        origin = np.array([position[0], position[1], position[2] + self.robot.laser_height])
        starts = origin + direction * self.robot.laser_min_range
        ends = origin + direction * self.range
        hits = self.p.rayTestBatch(starts.tolist(), ends.tolist(), numThreads=1, physicsClientId=self.client)
        span = self.range - self.robot.laser_min_range
        for i, hit in enumerate(hits):
            name = self.bodies.get(hit[0]) if hit[0] >= 0 else None
            if name is None or name == GROUND_BODY_NAME:
                self.ranges[i] = np.inf
                continue
            first_sensed.setdefault(name, now)
            self.ranges[i] = self.robot.laser_min_range + hit[2] * span + noise[i]

    def avoid(self, v: float, w: float, settings: RunSettings) -> tuple[float, float]:
        """Reactive avoidance: stop and turn away while a laser hit lies in the robot's corridor ahead.

        The corridor is 0.8 m wide (the Husky is 0.67 m) and 1.4 m deep from the robot's centre.
        """
        finite = np.isfinite(self.ranges)
        ranges = np.where(finite, self.ranges, 0.0)
        ahead = ranges * np.cos(self.angles)
        side = ranges * np.sin(self.angles)
        blocking = finite & (ahead > 0.0) & (ahead < 1.4) & (np.abs(side) < 0.4)
        if not blocking.any():
            return v, w
        away = -1.0 if float(np.sum(side[blocking])) > 0 else 1.0  # turn away from the obstacle's side
        return 0.0, away * settings.max_turn_rate
