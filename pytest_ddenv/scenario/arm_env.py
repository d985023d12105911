"""`ArmEnv`: an arm's scenario as a `gymnasium.Env`, what `robot_world.make_env()` gives for an arm's world.

The same design as the mobile robots' `RobotEnv` (scenario/gym_env.py, whose `TickEnv` both share): the same
simulation as `robot_world.run()`, `reset()` starts an `ArmEpisode` with the test's world, predicates and
seed, each `step(action)` is one control tick, finished episodes land in `robot_world.runs` (so
`robot_world.check()` raises `RobotFailure` and the test is reduced like any other), one episode per process
at a time, and `env.last_observation` is the full `ArmObservation` (contacts, every watched object's pose).

Action space, `actions="joints"` (the default): `Box(-step, step)` of n + 1 float32 values for an arm of n
joints: the first n are joint position changes (rad; m for a prismatic joint) added to the joints' targets,
which start at the joints' positions when the episode starts and stay within the URDF's limits; `step` is
`max_joint_step` (0.05 rad per tick by default: 1 rad/s at the default 20 Hz control rate). Each step sends
`JointTargets(targets, gripper)`. With `actions="end_effector"`: 5 values, changes of the tool's target
position x, y, z (m, at most `max_tool_step`, 0.02 m per tick) and of its yaw (rad, at most 0.1), the tool
pointing down; the target starts at the end effector's pose, and each step sends `EndEffectorTarget`
(inverse kinematics by the engine). The last value is the gripper in both: above 0 closes it, otherwise it
opens. Actions are used as given (not clipped to the box); a NaN or infinite one raises `ControllerError`,
a wrong shape `ValueError`.

Observation space (a `gymnasium.spaces.Dict` of float32 `Box`es from the `ArmObservation`: the joints and the
target with the seeded noise): `"joint_positions"` (n,), `"joint_velocities"` (n,), `"end_effector"` (6,): x,
y, z, roll, pitch, yaw; `"gripper"` (2,): the opening (m) and the fingers' summed force (N); `"target"` (6,):
the target's pose as perceived (zeros when the scenario names no target); `"place"` (3,): the place region's
centre x, y and its radius; `"time"` (1,): simulated seconds, in [0, time limit + one tick]; `"image"`, when
the scenario declares a camera: its picture, (H, W, 3) uint8 RGB or (H, W) float32 depth (m).

Reward: the decrease since the previous step of the true distance from the end effector to the target plus
the target's planar distance to the place region's centre (m), minus 10 on the step a failure predicate
fires, plus 10 on the step the target is placed. `terminated` when a predicate fired or the target was
placed, `truncated` at the time limit; `info` holds `"failure"`, `"reached_goal"`, `"time"`,
`"place_distance"` (the target's, true, m) and `"target_held"`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike

from pytest_ddenv.errors import ControllerError, ScenarioError
from pytest_ddenv.oracle.arm_state import GRIPPER_CLOSE, GRIPPER_OPEN
from pytest_ddenv.scenario.gym_env import ObsDict, RobotEnv, RobotWorldLike, TickEnv, _box
from pytest_ddenv.sim.arm.control import ArmCommand, ArmObservation, EndEffectorTarget, JointTargets
from pytest_ddenv.sim.arm.episode import ArmEpisode
from pytest_ddenv.sim.arm.robot import robot_kind
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.validation import expected, is_real

__all__ = ["ACTIONS", "DEFAULT_JOINT_STEP", "DEFAULT_TOOL_STEP", "TOOL_TURN_STEP", "ArmEnv", "environment_for"]

ACTIONS = ("joints", "end_effector")
DEFAULT_JOINT_STEP = 0.05
"""The largest joint position change (rad) an action asks for in one tick, by default."""
DEFAULT_TOOL_STEP = 0.02
"""The largest move (m) of the tool's target along an axis an action asks for in one tick, by default."""
TOOL_TURN_STEP = 0.1
"""The largest turn (rad) of the tool's target about the vertical an action asks for in one tick."""


class ArmEnv(TickEnv[ArmEpisode, ArmObservation, ArmCommand]):
    """An arm's scenario as a gymnasium environment (see the module docstring for the spaces, the reward and
    termination).

    `settings`, `timeout`, `max_wall_time` and `render_mode` as for `RobotEnv`; `actions` ("joints" or
    "end_effector") what an action moves; `max_joint_step` (rad per tick) and `max_tool_step` (m per tick)
    bound the action space.
    """

    def __init__(
        self,
        robot_world: RobotWorldLike,
        *,
        settings: RunSettings | None = None,
        timeout: float | None = None,
        actions: str = "joints",
        max_joint_step: float = DEFAULT_JOINT_STEP,
        max_tool_step: float = DEFAULT_TOOL_STEP,
        max_wall_time: float | None = None,
        render_mode: str | None = None,
    ) -> None:
        super().__init__(robot_world, settings=settings, timeout=timeout, max_wall_time=max_wall_time,
                         render_mode=render_mode)
        if actions not in ACTIONS:
            raise ScenarioError(expected(" or ".join(map(repr, ACTIONS)), actions, "make_env(actions=...)"))
        for name, value in (("max_joint_step", max_joint_step), ("max_tool_step", max_tool_step)):
            if not (is_real(value) and 0.0 < value < math.inf):
                raise ScenarioError(expected("a number > 0", value, f"make_env({name}=...)"))
        self.actions = actions
        self.max_joint_step, self.max_tool_step = float(max_joint_step), float(max_tool_step)
        self._targets = np.zeros(0)
        """The joint targets, or the tool's target x, y, z, yaw."""
        self._layout(self._start(robot_world.run_seed, ()))

    def _layout(self, probe: ArmEpisode) -> None:
        """Both spaces, from a throwaway episode (the number of joints, the time limit, the camera's picture)."""
        joints = len(probe.arm.joint_names)
        image = probe.observe().image
        self._lower = np.asarray(probe.arm.lower, dtype=np.float64)
        self._upper = np.asarray(probe.arm.upper, dtype=np.float64)
        inf = np.inf
        self.observation_space = spaces.Dict({
            "joint_positions": _box(np.full(joints, -inf), np.full(joints, inf)),
            "joint_velocities": _box(np.full(joints, -inf), np.full(joints, inf)),
            "end_effector": _box(np.full(6, -inf), np.full(6, inf)),
            "gripper": _box(np.full(2, -inf), np.full(2, inf)),
            "target": _box(np.full(6, -inf), np.full(6, inf)),
            "place": _box(np.full(3, -inf), np.full(3, inf)),
            "time": _box(np.zeros(1), np.full(1, probe.limit + probe.tick_dt)),
        })
        if image is not None:
            self.observation_space.spaces["image"] = (
                spaces.Box(0, 255, image.shape, dtype=np.uint8) if image.dtype == np.uint8
                else spaces.Box(0.0, np.inf, image.shape, dtype=np.float32))
        if self.actions == "joints":
            high = np.array([*(self.max_joint_step,) * joints, 1.0])
        else:
            high = np.array([*(self.max_tool_step,) * 3, TOOL_TURN_STEP, 1.0])
        self.action_space = _box(-high, high)

    def _episode_of(self, started: object) -> ArmEpisode:
        if not isinstance(started, ArmEpisode):
            raise ScenarioError("ArmEnv drives arms; this world's robot is not one (robot_world.make_env() gives "
                                "the environment of the world's robot)", field="scenario.robot")
        state = started.state
        if state is None:
            raise RuntimeError("the arm's episode started without sensing its first tick")
        if self.actions == "joints":
            self._targets = np.asarray(state.joint_positions, dtype=np.float64)
        else:
            self._targets = np.array([*state.position, state.pose[5]], dtype=np.float64)
        return started

    def _encode(self, observation: ArmObservation) -> ObsDict:
        f32 = np.float32
        target = observation.target_pose
        encoded: ObsDict = {
            "joint_positions": np.array(observation.joint_positions, dtype=f32),
            "joint_velocities": np.array(observation.joint_velocities, dtype=f32),
            "end_effector": np.array(observation.end_effector, dtype=f32),
            "gripper": np.array([observation.gripper_opening, observation.gripper_force], dtype=f32),
            "target": np.array(target if target is not None else (0.0,) * 6, dtype=f32),
            "place": np.array([*observation.place[:2], observation.place_tolerance], dtype=f32),
            "time": np.array([observation.time], dtype=f32),
        }
        if observation.image is not None:
            encoded["image"] = np.array(observation.image)
        return encoded

    def _command(self, action: ArrayLike, episode: ArmEpisode) -> ArmCommand:
        """The targets moved by the action's changes (joints within their limits), and the gripper's command."""
        size = len(self._targets) + 1
        moved = f"{size - 1} joint changes" if self.actions == "joints" else "x, y, z and yaw changes"
        meaning = f"{size} numbers ({moved}, then the gripper)"
        try:
            values = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError) as error:
            raise ValueError(expected(meaning, action, "action")) from error
        if values.shape != (size,):
            raise ValueError(expected(meaning, action, "action", got=f"an array of shape {values.shape}"))
        if not np.all(np.isfinite(values)):
            raise ControllerError(expected("finite numbers", values.tolist(),
                                           f"the policy's action at t = {episode.time:.2f} s"))
        gripper = GRIPPER_CLOSE if values[-1] > 0.0 else GRIPPER_OPEN
        if self.actions == "end_effector":
            self._targets = self._targets + values[:-1]
            x, y, z, yaw = (float(v) for v in self._targets)
            return EndEffectorTarget((x, y, z), yaw, gripper)
        self._targets = np.clip(self._targets + values[:-1], self._lower, self._upper)
        return JointTargets(tuple(float(v) for v in self._targets), gripper)

    def _progress(self, episode: ArmEpisode) -> float:
        state = episode.state
        target = None if state is None else state.target_pose
        if state is None or target is None:
            return 0.0
        return math.dist(state.position, target[:3]) + _place_distance(episode)

    def _info(self, episode: ArmEpisode) -> dict[str, Any]:
        state = episode.state
        return {**super()._info(episode), "place_distance": _place_distance(episode),
                "target_held": bool(state is not None and state.target_held)}


def _place_distance(episode: ArmEpisode) -> float:
    """The target's true planar distance to the place region's centre (m; 0 without a target)."""
    state = episode.state
    if state is None or state.target is None or state.target not in state.objects:
        return 0.0
    return float(state.place_distance(state.target))


def environment_for(robot_world: RobotWorldLike, **options: Any) -> RobotEnv | ArmEnv:
    """`robot_world.make_env(**options)`: an `ArmEnv` when the world's robot is an arm, else a `RobotEnv`."""
    world = robot_world.world
    robot = world.scenario.robot if world.scenario is not None else "husky"
    if robot_kind(robot, world.source) == "arm":
        return ArmEnv(robot_world, **options)
    return RobotEnv(robot_world, **options)
