"""`robot_world.make_env()` of an arm's world: the `ArmEnv`, on the real simulator (no mocks)."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import shutil
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
from gymnasium.utils.env_checker import check_env  # noqa: E402

from pytest_ddenv.errors import ControllerError, ScenarioError  # noqa: E402
from pytest_ddenv.scenario.arm_env import ArmEnv  # noqa: E402
from pytest_ddenv.scenario.gym_env import FAILURE_PENALTY, GOAL_BONUS, RobotEnv  # noqa: E402
from pytest_ddenv.scenario.robot_world import RobotFailure, RobotWorld  # noqa: E402
from pytest_ddenv.sim.arm.control import EndEffectorTarget, GripperCommand  # noqa: E402
from pytest_ddenv.sim.arm.pick_place import PickAndPlace  # noqa: E402
from pytest_ddenv.world import Model, Pose, Shape, World  # noqa: E402
from pytest_ddenv.world.model import Camera  # noqa: E402

pytestmark = pytest.mark.pybullet  # the arm runs in PyBullet (w31mujoco brings it to MuJoCo)

ROOT = Path(__file__).resolve().parent.parent
SMOKE = ROOT / "tests" / "data" / "arm_smoke.yaml"
CHECK_ENV_NOTES = ("infinity", "Not able to test alternative render modes")
"""What check_env may warn about: the unbounded observation boxes, no spec."""


@pytest.fixture(scope="module")
def smoke() -> World:
    return World.load(SMOKE)


@pytest.fixture
def env(smoke: World) -> Iterator[ArmEnv]:
    made = RobotWorld(smoke).make_env()
    assert isinstance(made, ArmEnv)
    yield made
    made.close()


def check_quietly(env: gymnasium.Env) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    assert [str(w.message) for w in caught if not any(note in str(w.message) for note in CHECK_ENV_NOTES)] == []


class DefaultControllerAsActions:
    """The default controller's commands as end-effector actions (changes of the tool's aim, which this
    policy tracks as the env does: from the end effector's pose at the reset), through the env."""

    def __init__(self, env: ArmEnv) -> None:
        self.env, self.controller = env, PickAndPlace()
        self.aim: np.ndarray | None = None
        self.gripper = "open"

    def __call__(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        if self.aim is None:
            self.aim = np.array([*observation["end_effector"][:3], observation["end_effector"][5]], dtype=float)
        assert self.env.last_observation is not None
        command = self.controller(self.env.last_observation)
        if isinstance(command, EndEffectorTarget):
            wanted = np.array([*command.position, command.yaw])
            self.gripper = command.gripper or self.gripper
        else:
            assert isinstance(command, GripperCommand)
            wanted, self.gripper = self.aim, command.action
        change, self.aim = wanted - self.aim, wanted
        return np.array([*change, 1.0 if self.gripper == "close" else -1.0])


def roll_out(env: ArmEnv, policy: Any, seed: int | None = None) -> tuple[dict[str, Any], list[tuple]]:
    observation, info = env.reset(seed=seed)
    steps = []
    while True:
        step = env.step(policy(observation))
        steps.append(step)
        observation = step[0]
        if step[2] or step[3]:
            return info, steps


def still(env: ArmEnv) -> Any:
    return lambda observation: np.zeros(env.action_space.shape)


# -- the gymnasium contract ------------------------------------------------------------------------------------
@pytest.mark.parametrize("actions", ["joints", "end_effector"])
def test_check_env_passes(smoke: World, actions: str) -> None:
    env = RobotWorld(smoke).make_env(actions=actions)
    check_quietly(env)
    check_quietly(env.unwrapped)


def test_spaces(env: ArmEnv) -> None:
    assert env.action_space.shape == (8,) and env.action_space.dtype == np.float32
    assert np.allclose(env.action_space.high, [0.05] * 7 + [1.0])
    assert set(env.observation_space.spaces) == {"joint_positions", "joint_velocities", "end_effector", "gripper",
                                                 "target", "place", "time"}
    observation, info = env.reset()
    assert env.observation_space.contains(observation)
    assert np.allclose(observation["place"], [0.45, 0.3, 0.08])
    assert np.allclose(observation["target"][:3], [0.5, 0.0, 0.425], atol=0.05)  # perceived, with noise
    assert observation["gripper"][0] == pytest.approx(0.08, abs=1e-3)  # open
    assert info["seed"] == 0 and info["place_distance"] == pytest.approx(0.3, abs=0.01)
    tool = RobotWorld(World.load(SMOKE)).make_env(actions="end_effector", max_tool_step=0.01)
    assert np.allclose(tool.action_space.high, [0.01, 0.01, 0.01, 0.1, 1.0])


def test_a_mobile_robot_s_world_still_gives_a_robot_env(smoke: World) -> None:
    from plugin.conftest import WALL_WORLD

    assert type(RobotWorld(World.from_yaml(WALL_WORLD)).make_env()) is RobotEnv
    with pytest.raises(ScenarioError, match="RobotEnv drives wheeled robots; this world's robot is not one"):
        RobotEnv(RobotWorld(smoke))


@pytest.mark.parametrize(("kind", "shape", "dtype"), [("rgb", (24, 32, 3), np.uint8), ("depth", (24, 32), np.float32)])
def test_a_declared_camera_s_picture_is_observed(smoke: World, kind: str, shape: tuple, dtype: type) -> None:
    camera = Camera(position=(0.5, 0.0, 0.8), look_at=(0.5, 0.0, 0.4), width=32, height=24, kind=kind)
    assert smoke.scenario is not None
    world = dataclasses.replace(smoke, scenario=dataclasses.replace(smoke.scenario, camera=camera))
    env = RobotWorld(world).make_env()
    check_quietly(env)
    observation, _ = env.reset()
    image = observation["image"]
    assert image.shape == shape and image.dtype == dtype and image.flags.writeable
    assert env.observation_space.contains(observation)
    assert env.last_observation is not None and np.array_equal(image, env.last_observation.image)
    if kind == "depth":
        assert image[12, 16] == pytest.approx(0.8 - 0.45, abs=0.01)  # the cube's top, under the camera
    assert "image" not in RobotWorld(smoke).make_env().observation_space.spaces


# -- what the actions do -----------------------------------------------------------------------------------------
def test_joint_actions_move_the_joint_targets_within_the_limits(env: ArmEnv) -> None:
    env.reset()
    start = env._targets.copy()
    push = np.array([0.05, 0, 0, 0, 0, 0, 0, -1.0])
    for _ in range(10):
        observation, *_ = env.step(push)
    assert env._targets[0] == pytest.approx(start[0] + 0.5)
    assert observation["joint_positions"][0] == pytest.approx(start[0] + 0.5, abs=0.05)
    for _ in range(100):
        env.step(push)
    assert env._targets[0] == pytest.approx(env._upper[0])


def test_the_default_controller_through_end_effector_actions_places_the_cube(smoke: World) -> None:
    robot_world = RobotWorld(smoke)
    env = robot_world.make_env(actions="end_effector")
    assert isinstance(env, ArmEnv)
    info, steps = roll_out(env, DefaultControllerAsActions(env))
    last = steps[-1]
    assert last[2] and not last[3] and last[4]["reached_goal"] and last[4]["failure"] is None
    assert last[1] >= GOAL_BONUS - 1.0  # the step the cube was placed
    assert last[4]["place_distance"] <= 0.08
    assert robot_world.runs[-1].reached_goal and robot_world.runs[-1].robot_kind == "arm"
    rewards = sum(step[1] for step in steps)
    assert rewards > GOAL_BONUS  # the progress (tool to cube, cube to the place) was paid too
    robot_world.check()


def test_an_arm_that_hits_a_box_fails_the_test_like_run(smoke: World) -> None:
    """The arm swings its first joint into a tall box beside it: `arm_collision` ends the episode with the
    penalty, the run is recorded, and `check()` raises RobotFailure as after `robot_world.run()`."""
    tower = Model("tower", (Shape("box", size=(0.1, 0.1, 0.6)),), pose=Pose(0.0, 0.35, 0.7), static=True)
    world = World(models=(*smoke.models, tower), scenario=smoke.scenario, physics=smoke.physics, name="tower")
    robot_world = RobotWorld(world, predicates=["arm_collision"])
    env = robot_world.make_env()
    info, steps = roll_out(env, lambda observation: np.array([0.05, 0, 0, 0, 0, 0, 0, -1.0]))
    last = steps[-1]
    assert last[2] and not last[3] and last[4]["failure"]["predicate"] == "arm_collision"
    assert last[4]["failure"]["touched"] == ["tower"]
    assert last[1] <= -FAILURE_PENALTY + 0.5
    assert robot_world.runs == [last[4]["run"]]
    with pytest.raises(RobotFailure, match="arm_collision"):
        robot_world.check()


def test_standing_still_is_truncated_and_not_placed(smoke: World) -> None:
    robot_world = RobotWorld(smoke, predicates=["arm_collision"])
    env = robot_world.make_env(timeout=1.0)
    info, steps = roll_out(env, still(env))
    assert len(steps) == 20 and steps[-1][3] and not steps[-1][2]
    assert not steps[-1][4]["reached_goal"] and steps[-1][4]["failure"] is None
    assert abs(sum(step[1] for step in steps)) < 0.01  # nothing moved: no progress paid


def test_same_seed_gives_identical_observations(env: ArmEnv) -> None:
    def observations(seed: int) -> list[np.ndarray]:
        observation, _ = env.reset(seed=seed)
        seen = [observation["joint_positions"], observation["target"]]
        for _ in range(5):
            observation, *_ = env.step(np.array([0.01] * 7 + [-1.0]))
            seen += [observation["joint_positions"], observation["target"]]
        return seen

    first, again, other = observations(3), observations(3), observations(4)
    assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
    assert not all(np.array_equal(a, b) for a, b in zip(first, other, strict=True))


# -- bad input ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("action", [[0.0] * 7, [[0.0] * 8], "close"])
def test_a_bad_action_shape_is_a_clear_error(env: ArmEnv, action: Any) -> None:
    env.reset()
    with pytest.raises(ValueError, match=r"action: expected 8 numbers \(7 joint changes, then the gripper\)"):
        env.step(action)


def test_a_nan_action_fails_like_a_controller(env: ArmEnv) -> None:
    env.reset()
    with pytest.raises(ControllerError, match=r"the policy's action at t = 0.00 s: expected finite numbers"):
        env.step([np.nan] + [0.0] * 7)


@pytest.mark.parametrize(("options", "message"), [
    ({"actions": "torques"}, r"make_env\(actions=...\): expected 'joints' or 'end_effector', got 'torques'"),
    ({"max_joint_step": 0}, r"make_env\(max_joint_step=...\): expected a number > 0, got 0"),
    ({"max_tool_step": float("inf")}, r"make_env\(max_tool_step=...\): expected a number > 0"),
    ({"render_mode": "human"}, r"render_mode: expected None, got 'human'; ArmEnv renders nothing"),
])
def test_bad_options_are_one_clear_error(smoke: World, options: dict[str, Any], message: str) -> None:
    with pytest.raises((ScenarioError, ValueError), match=message):
        RobotWorld(smoke).make_env(**options)


# -- the example ---------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_arm_policy_example_is_reduced_to_the_tall_box(pytester: pytest.Pytester) -> None:
    """examples/test_arm_policy_gym.py fails (its policy's wrist hits the tall box) and is reduced to it."""
    if importlib.util.find_spec("gymnasium") is None:
        pytest.skip("gymnasium is not installed")
    shutil.copy(ROOT / "examples" / "test_arm_policy_gym.py", pytester.path)
    shutil.copytree(ROOT / "worlds", pytester.path / "worlds")
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", "test_arm_policy_gym.py")
    result.assert_outcomes(failed=1)
    (summary_file,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    summary = json.loads(summary_file.read_text())
    assert summary["original_size"] == 19 and summary["one_minimal"]
    assert summary["minimal_models"] == ["table", "target", "tall_box"]
    assert summary["reference_failure"]["signature"]["predicate"] == "arm_collision"
    assert summary["reference_failure"]["signature"]["touched"] == ["tall_box"]


@pytest.mark.slow
def test_the_docs_arm_policy_fails_and_is_reduced(pytester: pytest.Pytester) -> None:
    """docs/writing-tests.md, "An arm's policy through gymnasium": the example fails as it says and is reduced
    to the tall box."""
    import re

    text = (ROOT / "docs" / "writing-tests.md").read_text(encoding="utf-8")
    (example,) = [block for block in re.findall(r"```python\n(.*?)```", text, flags=re.DOTALL)
                  if "arm_policy_table.yaml" in block]
    pytester.makepyfile(test_arm_policy=example)
    shutil.copytree(ROOT / "worlds", pytester.path / "worlds")
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*The 'arm_collision' predicate fired*tall_box*", "*19 -> 3 models*"])
    (summary_file,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    assert json.loads(summary_file.read_text())["minimal_models"] == ["table", "target", "tall_box"]
