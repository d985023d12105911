"""`ArmEpisode`: one run of an arm's scenario, one control tick at a time (the arm's `Episode`).

The same interface as sim/episode.py's `Episode` (`sense`, `observe`, `act`, `finished`, `time`, `tick_dt`,
`result()`), so `Simulator.run`'s drive loop and the gymnasium environment drive either. Per tick: `sense()`
reads the joints, the end effector, the gripper, the arm's contacts (fingers marked) and self contacts, and
the poses of the target, the table and the `watch` models; builds an `ArmState`, decides "placed" (the goal)
and checks the predicates (the first that fires ends the run). `observe()` draws the tick's sensing noise, a
fixed number of draws per tick (one per arm joint on the joint readings, three on the target's pose), so
removing a model never shifts the noise. `act(command)` applies a `JointTargets`, `EndEffectorTarget` or
`GripperCommand` and steps the physics to the next tick.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.detail import detail_requested
from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.oracle.arm_predicates import KnockedOver
from pytest_ddenv.oracle.arm_state import GRIPPER_OPEN, ArmState, Pose6
from pytest_ddenv.oracle.predicates import GROUND, Contact, FailureSignature, History, Predicate
from pytest_ddenv.sim.arm.control import ArmCommand, ArmObservation, GripperCommand, JointTargets
from pytest_ddenv.sim.arm.driven import DrivenArm
from pytest_ddenv.sim.builder import GROUND_BODY_NAME
from pytest_ddenv.sim.detail_recorder import DetailRecorder
from pytest_ddenv.sim.episode import checked_signature
from pytest_ddenv.sim.physics import PhysicsEngine
from pytest_ddenv.sim.robot import Robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.world.model import Scenario, World

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""

JOINT_NOISE_FRACTION = 0.1
"""An arm joint's reading noise (rad) is this fraction of `noise.imu_yaw` (0.001 rad by default)."""
PLACED_SPEED = 0.02
"""m/s: the target counts as placed once it moves slower than this, released inside the place region."""


def pose6(position: Sequence[float], quaternion: Sequence[float]) -> Pose6:
    """(x, y, z, roll, pitch, yaw) of a position and an (x, y, z, w) quaternion (pybullet's Euler convention)."""
    from scipy.spatial.transform import Rotation  # here: importing scipy.spatial takes 0.2-0.5 s

    roll, pitch, yaw = Rotation.from_quat(list(quaternion)).as_euler("xyz")
    return (float(position[0]), float(position[1]), float(position[2]), float(roll), float(pitch), float(yaw))


def pointing_down(yaw: float) -> tuple[float, float, float, float]:
    """The (x, y, z, w) quaternion of a tool pointing down, turned by `yaw` about the vertical."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_euler("xyz", [math.pi, 0.0, yaw]).as_quat()
    return float(x), float(y), float(z), float(w)


class ArmEpisode:
    """The state of one arm run between control ticks (see the module docstring). Built by `Simulator.start`."""

    def __init__(
        self, physics: PhysicsEngine, *, world: World, scenario: Scenario, robot: Robot, body: int, seed: int,
        streams: list[np.random.Generator], predicates: Sequence[Predicate], settings: RunSettings, limit: float,
    ) -> None:
        arm: DrivenArm | None = getattr(robot, "arm", None)
        if arm is None:
            raise RuntimeError(f"the {physics.name} engine spawned the arm {robot.name!r} without its driven arm")
        self.physics, self.arm = physics, arm
        self.world, self.scenario, self.robot, self.body = world, scenario, robot, body
        self.bodies = physics.bodies
        self.seed, self.settings, self.limit = int(seed), settings, limit
        self.predicates = tuple(predicates)
        self.started = time.perf_counter()
        _, _, self._rng_joints, _, self._rng_target = streams
        dt = float(world.physics.timestep)
        self._dt = dt
        self._steps_per_tick = max(1, round(1.0 / (settings.control_rate * dt)))
        self.tick_dt = self._steps_per_tick * dt
        self._ticks = math.ceil(limit / self.tick_dt - 1e-9)
        self._record_every = max(1, round(settings.control_rate / settings.record_rate))
        self._body_of = {name: key for key, name in self.bodies.items()}
        self._models = frozenset(world.names)
        self._colors: dict[int, tuple[float, float, float, float]] | None = None
        knocked = [name for p in self.predicates if isinstance(p, KnockedOver) and p.models for name in p.models]
        named = [scenario.target, scenario.table, *scenario.watch, *knocked]  # what knocked_over(models=) names too
        self.watched = tuple(dict.fromkeys(n for n in named if n is not None and n in self._body_of))
        self.table_top = float(world.bounds(scenario.table)[1][2]) if scenario.table in self._body_of else None
        self._finger_links = tuple(sorted(arm.finger_links))
        self.history = History()
        self._times: list[float] = []
        self._poses: list[list[float]] = []
        self._velocities: list[list[float]] = []
        self._finger_forces: list[list[float]] = []
        self._target_path: list[list[float]] = []
        self.first_touch: dict[str, float] = {}
        self.last_touch: dict[str, float] = {}
        self.failure: FailureSignature | None = None
        self.reached = False
        self.goal_time: float | None = None
        self.gripper_command, self.gripper_since = GRIPPER_OPEN, 0.0
        self.start_objects: dict[str, Pose6] = {}
        self._steps = 0
        self.tick = 0
        self.finished = False
        self._observed = False
        self.state: ArmState | None = None
        """The true state at this tick (what the predicates saw)."""
        self._target_before: tuple[float, float, float] | None = None
        self._detail = DetailRecorder(physics, world, frozenset(), None, 0.0) if detail_requested() else None
        self.sense()

    @property
    def time(self) -> float:
        """Simulated seconds since the arm was spawned."""
        return self._steps * self._dt

    @property
    def pose(self) -> Pose6:
        """The end effector's true pose now."""
        return (0.0,) * 6 if self.state is None else self.state.pose

    # -- one tick ------------------------------------------------------------------------------------
    def sense(self) -> None:
        """Read the true state at this tick, record it, and decide goal and failure."""
        now = self.time
        positions, velocities = self.arm.joint_state()
        ee_position, ee_quaternion = self.arm.end_effector()
        pose = pose6(ee_position, ee_quaternion)
        self.history.append(now, (pose[0], pose[1], pose[2]))
        contacts, finger_forces = self._contacts_now(now)
        objects = {name: self._body_pose(name) for name in self.watched}
        if not self.start_objects:
            self.start_objects = dict(objects)
        target = self.scenario.target
        held = target is not None and all(
            any(c.model == target and c.link == self.arm.link_names.get(f) for c in contacts)
            for f in self._finger_links)
        names = self.arm.link_names
        state = ArmState(
            time=now, timeout=self.limit, pose=pose, history=self.history, joint_names=self.arm.joint_names,
            joint_positions=tuple(positions), joint_velocities=tuple(velocities), joint_lower=self.arm.lower,
            joint_upper=self.arm.upper, gripper_opening=self.arm.gripper_opening(),
            gripper_command=self.gripper_command, gripper_since=self.gripper_since, contacts=contacts,
            self_contacts=tuple((names.get(a, str(a)), names.get(b, str(b))) for a, b in self.arm.self_contacts()),
            target=target, target_held=held, objects=objects, start_objects=self.start_objects,
            place=self.scenario.goal, place_tolerance=self.scenario.goal_tolerance, table=self.scenario.table,
            table_top=self.table_top,
        )
        self.state = state
        if self.tick % self._record_every == 0:
            self._record(now, state, finger_forces)
        if not (self.reached or self.failure is not None):
            if self._placed(state):
                self.reached, self.goal_time = True, now
            else:
                for predicate in self.predicates:
                    self.failure = checked_signature(predicate, predicate.check(state), now)
                    if self.failure is not None:
                        break
        decided = self.reached or self.failure is not None
        if self.tick >= self._ticks or (decided and self.settings.stop_early):
            self.finished = True
            if self.tick % self._record_every != 0:
                self._record(now, state, finger_forces)
        self._observed = False

    def _placed(self, state: ArmState) -> bool:
        """The target rests in the place region, released: the gripper told to open, not held by both fingers,
        moved from where it started, and still."""
        target = state.target
        if target is None or target not in state.objects or state.gripper_command != GRIPPER_OPEN:
            return False
        position = state.objects[target][:3]
        before, self._target_before = self._target_before, (position[0], position[1], position[2])
        if before is None or math.dist(before, position) > PLACED_SPEED * self.tick_dt:
            return False
        if state.target_held:
            return False
        moved = math.dist(position, state.start_objects[target][:3]) > state.place_tolerance / 2.0
        return moved and state.place_distance(target) <= state.place_tolerance

    def _body_pose(self, name: str) -> Pose6:
        position, quaternion = self.physics.body_pose(self._body_of[name])
        return pose6(position, quaternion)

    def _contacts_now(self, now: float) -> tuple[tuple[Contact, ...], list[float]]:
        per_pair: dict[tuple[int, int], float] = {}
        for link, other, force in self.physics.robot_contacts():
            per_pair[(link, other)] = per_pair.get((link, other), 0.0) + force
        contacts = []
        fingers = [0.0] * len(self._finger_links)
        names = self.arm.link_names
        for (link, other), force in per_pair.items():
            name = self.bodies.get(other)
            if name is None:
                continue
            finger = link in self.arm.finger_links
            if finger:
                fingers[self._finger_links.index(link)] += force
            model = GROUND if name == GROUND_BODY_NAME else name
            contacts.append(Contact(model, names.get(link, str(link)), False, force, finger=finger))
            if model != GROUND:
                self.first_touch.setdefault(model, now)
                self.last_touch[model] = now
        contacts.sort(key=lambda c: (c.model, c.link))
        return tuple(contacts), fingers

    def _record(self, now: float, state: ArmState, finger_forces: list[float]) -> None:
        linear, angular = self._ee_velocity()
        self._times.append(now)
        self._poses.append(list(state.pose))
        self._velocities.append([*linear, *angular])
        self._finger_forces.append(finger_forces)
        target = state.target_pose
        if target is not None:
            self._target_path.append(list(target[:3]))
        if self._detail is not None:
            self._detail.sample()

    def _ee_velocity(self) -> tuple[Sequence[float], Sequence[float]]:
        velocity = getattr(self.arm, "end_effector_velocity", None)
        if velocity is None:  # an engine's arm that does not report it
            return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        linear, angular = velocity()
        return linear, angular

    def observe(self) -> ArmObservation:
        """What the arm's sensors say at this tick. Draws the tick's noise: call it once per tick, before `act`
        (on a finished episode it only reports)."""
        if self._observed:
            raise RuntimeError("observe() was already called at this tick; call act(command) first")
        state = self.state
        assert state is not None
        positions = np.asarray(state.joint_positions, dtype=np.float64)
        objects: dict[str, Pose6] = dict(state.objects)
        if not self.finished:
            noise = self.settings.noise
            positions = positions + self._rng_joints.standard_normal(len(positions)) * (
                noise.imu_yaw * JOINT_NOISE_FRACTION)
            seen = self._rng_target.standard_normal(3)
            target = state.target
            if target is not None and target in objects:
                x, y, z, roll, pitch, yaw = objects[target]
                objects[target] = (x + noise.laser * float(seen[0]), y + noise.laser * float(seen[1]), z, roll, pitch,
                                   yaw + noise.imu_yaw * float(seen[2]))
            self._observed = True
        return ArmObservation(
            time=state.time, joint_names=state.joint_names, joint_positions=tuple(float(v) for v in positions),
            joint_velocities=state.joint_velocities, end_effector=state.pose, gripper_opening=state.gripper_opening,
            gripper_force=sum(c.normal_force for c in state.contacts if c.finger), contacts=state.contacts,
            objects=objects, target=state.target, place=state.place, place_tolerance=state.place_tolerance,
            image=self._image(),
        )

    def _image(self) -> NDArray[np.generic] | None:
        """The scenario's camera's picture now (None: no camera)."""
        camera = self.scenario.camera
        if camera is None:
            return None
        render = getattr(self.arm, "camera_image", None)
        if render is None:
            raise ScenarioError(f"the {self.physics.name} engine's arm has no camera; remove scenario.camera",
                                source=self.world.source, field="scenario.camera")
        if self._colors is None:
            self._colors = {key: self.world.model(name).color for key, name in self.bodies.items()
                            if name in self._models}
        image: NDArray[np.generic] = render(camera, self._colors)
        image.flags.writeable = False
        return image

    def act(self, command: ArmCommand) -> None:
        """Apply `command`, step the physics to the next tick, sense."""
        if self.finished:
            raise RuntimeError("the episode is finished")
        if not self._observed:
            raise RuntimeError("call observe() before act(): it draws this tick's noise")
        gripper: str | None
        if isinstance(command, GripperCommand):
            gripper = command.action
        elif isinstance(command, JointTargets):
            self.arm.set_joint_targets(command.positions)
            gripper = command.gripper
        else:
            ee = command
            self.arm.set_joint_targets(self.arm.inverse_kinematics(ee.position, pointing_down(ee.yaw)))
            gripper = ee.gripper
        if gripper is not None and gripper != self.gripper_command:
            self.arm.set_gripper(gripper)
            self.gripper_command, self.gripper_since = gripper, self.time
        self.physics.step(self._steps_per_tick)
        self._steps += self._steps_per_tick
        self.tick += 1
        self.sense()

    # -- the record ----------------------------------------------------------------------------------
    def result(self) -> Run:
        """The `Run` of this episode so far (complete once `finished`)."""
        return Run(
            seed=self.seed,
            settings=self.settings,
            world_name=self.world.name,
            model_names=self.world.names,
            robot=self.scenario.robot if isinstance(self.scenario.robot, str) else self.robot.name,
            footprint=(float(self.robot.footprint[0]), float(self.robot.footprint[1])),
            times=np.asarray(self._times, dtype=np.float64),
            poses=np.asarray(self._poses, dtype=np.float64).reshape(-1, 6),
            velocities=np.asarray(self._velocities, dtype=np.float64).reshape(-1, 6),
            wheel_contacts=np.asarray(self._finger_forces, dtype=np.float64).reshape(-1, len(self._finger_links)),
            first_touch=dict(self.first_touch),
            last_touch=dict(self.last_touch),
            first_sensed={},
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
            robot_kind="arm",
            target_path=np.asarray(self._target_path, dtype=np.float64).reshape(-1, 3) if self._target_path else None,
        )

