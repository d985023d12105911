"""`Episode`: one run of a world's scenario advanced one control tick at a time.

`Simulator.run` drives it with a controller; the gymnasium environment drives it with a policy's actions.
Per tick: `sense()` reads the robot's true state (contacts, laser, goal and predicates), `observe()` draws
the tick's noise and returns what the robot's own sensors say, `act(command)` applies a command and steps
the physics to the next tick. The noise draws per tick are fixed (2 actuation, 2 odometry, 1 IMU, and
`laser_rays` per scan), so removing a model never shifts the noise sequence.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np

from pytest_ddenv.detail import detail_requested
from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.oracle.predicates import GROUND, Contact, FailureSignature, History, Predicate, RobotState
from pytest_ddenv.sim.builder import GROUND_BODY_NAME
from pytest_ddenv.sim.control import AnyCommand, Command, LaserScan, Observation, wrap_angle
from pytest_ddenv.sim.detail_recorder import DetailRecorder
from pytest_ddenv.sim.laser import Laser
from pytest_ddenv.sim.physics import PhysicsEngine
from pytest_ddenv.sim.robot import Robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.world.model import Scenario, World

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""

NOISE_STREAMS = ("start", "actuation", "odometry", "imu", "laser")


def noise_streams(seed: int) -> list[np.random.Generator]:
    """The run's independent noise generators, in `NOISE_STREAMS` order."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(len(NOISE_STREAMS))]


class Episode:
    """The state of one run between control ticks (see the module docstring). Built by `Simulator.start`."""

    def __init__(
        self, physics: PhysicsEngine, *, world: World, scenario: Scenario, robot: Robot, body: int, seed: int,
        streams: list[np.random.Generator], predicates: Sequence[Predicate], settings: RunSettings, limit: float,
    ) -> None:
        self.physics = physics
        self.world, self.scenario, self.robot, self.body = world, scenario, robot, body
        self.bodies = physics.bodies
        self.seed, self.settings, self.limit = int(seed), settings, limit
        self.predicates = tuple(predicates)
        self.started = time.perf_counter()
        _, self._rng_act, self._rng_odo, self._rng_imu, self._rng_laser = streams
        dt = float(world.physics.timestep)
        self._dt = dt
        self._steps_per_tick = max(1, round(1.0 / (settings.control_rate * dt)))
        self.tick_dt = self._steps_per_tick * dt
        self._ticks = math.ceil(limit / self.tick_dt - 1e-9)
        self._laser_every = max(1, round(settings.control_rate / settings.laser_rate))
        self._record_every = max(1, round(settings.control_rate / settings.record_rate))
        self._wheel_index = {link: i for i, link in enumerate(robot.wheel_links)}
        self._weight = robot.mass * float(np.linalg.norm(world.physics.gravity))
        mount = robot.laser
        self.laser = Laser(physics, settings, mount) if settings.laser_rays > 0 and mount else None
        self.history = History()
        self._times: list[float] = []
        self._poses: list[list[float]] = []
        self._velocities: list[list[float]] = []
        self._loads: list[list[float]] = []
        self.first_touch: dict[str, float] = {}
        self.last_touch: dict[str, float] = {}
        self.first_sensed: dict[str, float] = {}
        self.failure: FailureSignature | None = None
        self.reached = False
        self.goal_time: float | None = None
        self.estimate = [scenario.start.x, scenario.start.y]
        self._start_pose: tuple[float, ...] | None = None
        self._steps = 0
        self.tick = 0
        self.finished = False
        self._observed = False
        self._pose: tuple[float, float, float, float, float, float] = (0.0,) * 6
        self._contacts: tuple[Contact, ...] = ()
        self._detail = DetailRecorder(physics, world, frozenset(robot.wheel_links), self.laser,
                                      mount.height if mount else 0.0) if detail_requested() else None
        self.sense()

    @property
    def time(self) -> float:
        """Simulated seconds since the robot was spawned."""
        return self._steps * self._dt

    @property
    def pose(self) -> tuple[float, float, float, float, float, float]:
        """The robot's true pose now (x, y, z, roll, pitch, yaw)."""
        return self._pose

    # -- one tick ------------------------------------------------------------------------------------
    def sense(self) -> None:
        """Read the true state at this tick, record it, and decide goal and failure."""
        now = self.time
        position, (roll, pitch, yaw), linear, angular = self.physics.base_state()
        pose = (position[0], position[1], position[2], roll, pitch, yaw)
        velocity = (*linear, *angular)
        self._pose = pose
        if self._start_pose is None:
            self._start_pose = pose
        contacts, loads = self._contacts_now(now)
        self._contacts = contacts
        if self.laser is not None and self.tick % self._laser_every == 0:
            noise = self._rng_laser.standard_normal(self.settings.laser_rays) * self.settings.noise.laser
            self.laser.scan(position, yaw, noise, now, self.first_sensed)
        self.history.append(now, (position[0], position[1], position[2]))
        goal = self.scenario.goal
        if goal[2] is not None:
            distance = math.dist(position, (goal[0], goal[1], goal[2]))
        else:
            distance = math.hypot(position[0] - goal[0], position[1] - goal[1])
        if self.tick % self._record_every == 0:
            self._record(now, pose, velocity, loads)
        if not (self.reached or self.failure is not None):
            if distance <= self.scenario.goal_tolerance:
                self.reached, self.goal_time = True, now
            elif self.predicates:
                state = RobotState(
                    time=now, timeout=self.limit, pose=pose, velocity=velocity, start=self._start_pose,  # type: ignore[arg-type]
                    goal=goal, goal_distance=distance, contacts=contacts, wheel_loads=tuple(loads),
                    weight=self._weight, history=self.history,
                )
                for predicate in self.predicates:
                    self.failure = checked_signature(predicate, predicate.check(state), now)
                    if self.failure is not None:
                        break
        decided = self.reached or self.failure is not None
        if self.tick >= self._ticks or (decided and self.settings.stop_early):
            self.finished = True
            if self.tick % self._record_every != 0:
                self._record(now, pose, velocity, loads)
        self._observed = False

    def _contacts_now(self, now: float) -> tuple[tuple[Contact, ...], list[float]]:
        per_pair: dict[tuple[int, int], float] = {}
        for link, other, force in self.physics.robot_contacts():
            key = (link, other)
            per_pair[key] = per_pair.get(key, 0.0) + force
        contacts = []
        loads = [0.0] * len(self._wheel_index)
        link_names = self.robot.link_names
        for (link, other), force in per_pair.items():
            name = self.bodies.get(other)
            if name is None:
                continue
            is_wheel = link in self._wheel_index
            if is_wheel:
                loads[self._wheel_index[link]] += force
            model = GROUND if name == GROUND_BODY_NAME else name
            contacts.append(Contact(model, link_names.get(link, str(link)), is_wheel, force))
            if model != GROUND:
                self.first_touch.setdefault(model, now)
                self.last_touch[model] = now
        contacts.sort(key=lambda c: (c.model, c.link))
        return tuple(contacts), loads

    def _record(self, now: float, pose: tuple[float, ...], velocity: tuple[float, ...], loads: list[float]) -> None:
        self._times.append(now)
        self._poses.append(list(pose))
        self._velocities.append(list(velocity))
        self._loads.append(loads)
        if self._detail is not None:
            self._detail.sample()

    def observe(self) -> Observation:
        """What the robot's sensors say at this tick. Draws the tick's noise and advances the dead-reckoning
        estimate: call it once per tick, before `act` (on a finished episode it only reports)."""
        if self._observed:
            raise RuntimeError("observe() was already called at this tick; call act(command) first")
        speeds, v_meas, w_meas = self.robot.odometry()
        yaw_est = self._pose[5]
        if not self.finished:
            noise = self.settings.noise
            odo = self._rng_odo.standard_normal(2)
            imu = self._rng_imu.standard_normal(1)
            self._act_noise = self._rng_act.standard_normal(2)
            yaw_est = wrap_angle(self._pose[5] + noise.imu_yaw * float(imu[0]))
            v_meas *= 1.0 + noise.odometry * float(odo[0])
            w_meas *= 1.0 + noise.odometry * float(odo[1])
            self.estimate[0] += v_meas * math.cos(yaw_est) * self.tick_dt
            self.estimate[1] += v_meas * math.sin(yaw_est) * self.tick_dt
            self._observed = True
        scan: LaserScan | None = None if self.laser is None else self.laser.latest
        return Observation(
            time=self.time, goal=self.scenario.goal, pose=(self.estimate[0], self.estimate[1], yaw_est),
            velocity=(v_meas, w_meas), wheel_speeds=speeds, imu=(self._pose[3], self._pose[4], yaw_est), scan=scan,
            contacts=self._contacts,
        )

    def act(self, command: AnyCommand) -> None:
        """Apply `command` (with the tick's actuation noise), step the physics to the next tick, sense."""
        if self.finished:
            raise RuntimeError("the episode is finished")
        if not self._observed:
            raise RuntimeError("call observe() before act(): it draws this tick's noise")
        scale_left = 1.0 + self.settings.noise.actuation * float(self._act_noise[0])
        scale_right = 1.0 + self.settings.noise.actuation * float(self._act_noise[1])
        if isinstance(command, Command):
            self.robot.drive(command.linear, command.angular, scale_left, scale_right)
        else:
            self.robot.drive_wheels(command.left, command.right, scale_left, scale_right)
        self.physics.step(self._steps_per_tick)
        self._steps += self._steps_per_tick
        self.tick += 1
        self.sense()

    # -- the record ----------------------------------------------------------------------------------
    def result(self) -> Run:
        """The `Run` of this episode so far (complete once `finished`)."""
        wheels = len(self._wheel_index)
        return Run(
            seed=self.seed,
            settings=self.settings,
            world_name=self.world.name,
            model_names=self.world.names,
            robot=self.scenario.robot if isinstance(self.scenario.robot, str) else self.robot.name,
            footprint=tuple(float(v) for v in self.robot.footprint),  # type: ignore[arg-type]
            times=np.asarray(self._times, dtype=np.float64),
            poses=np.asarray(self._poses, dtype=np.float64).reshape(-1, 6),
            velocities=np.asarray(self._velocities, dtype=np.float64).reshape(-1, 6),
            wheel_contacts=np.asarray(self._loads, dtype=np.float64).reshape(-1, wheels),
            first_touch=dict(self.first_touch),
            last_touch=dict(self.last_touch),
            first_sensed=dict(self.first_sensed),
            reached_goal=self.reached,
            goal_time=self.goal_time,
            failure=self.failure,
            sim_time=self.time,
            wall_time=time.perf_counter() - self.started,
            steps=self._steps,
            pybullet_version=self.physics.version if self.physics.name == "pybullet" else "",
            detail=None if self._detail is None else self._detail.result(),
            engine=self.physics.name,
            engine_version=self.physics.version,
        )


def checked_signature(predicate: Predicate, result: object, now: float) -> FailureSignature | None:
    """What a predicate's `check` returned: a signature or None; anything else is a ScenarioError naming it."""
    if result is None or isinstance(result, FailureSignature):
        return result
    raise ScenarioError(f"predicate {predicate.name!r} returned {type(result).__name__} {result!r} at t = {now:.2f} s; "
                        "check() must return a FailureSignature (see pytest_ddenv.oracle.signature) or None",
                        field="predicates")
