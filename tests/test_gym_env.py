"""`robot_world.make_env()`: the scenario as a gymnasium environment, on the real simulator (no mocks)."""

from __future__ import annotations

import importlib
import math
import sys
import textwrap
import warnings
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from engines import in_engine
from plugin.conftest import WALL_WORLD  # the same small world as the plugin tests

gymnasium = pytest.importorskip("gymnasium")
from gymnasium.utils.env_checker import check_env  # noqa: E402

from pytest_ddenv.sim.controllers import GoToGoal  # noqa: E402
from pytest_ddenv.errors import ScenarioError  # noqa: E402
from pytest_ddenv.scenario.gym_env import FAILURE_PENALTY, GOAL_BONUS, RobotEnv  # noqa: E402
from pytest_ddenv.oracle import PredicateSpec  # noqa: E402
from pytest_ddenv.scenario.robot_world import ATTEMPT_SEED_STRIDE, RobotFailure, RobotWorld  # noqa: E402
from pytest_ddenv.sim import ControllerError, ControllerTimeout, Run, RunSettings  # noqa: E402
from pytest_ddenv.world import World  # noqa: E402

STUCK = (PredicateSpec("stuck", {"window": 2.0, "min_progress": 0.2}),)
OPEN_WORLD = textwrap.dedent(
    """\
    format: 1
    name: open
    scenario:
      start: {x: 0.0, y: 0.0, yaw: 0.0}
      goal: {x: 1.5, y: 0.0}
      goal_tolerance: 0.3
      timeout: 10
    models:
      - {name: far_box, pose: [-4, 4, 0.25], box: [0.5, 0.5, 0.5]}
    """
)
CHECK_ENV_NOTES = ("infinity", "Not able to test alternative render modes", "symmetric and normalized")
"""What check_env may warn about: the unbounded pose/velocity boxes, no spec, the unnormalized wheel box."""

Step = tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]
Policy = Callable[[RobotEnv, dict[str, np.ndarray]], Any]


@pytest.fixture(scope="module")
def wall_world() -> World:
    return World.from_yaml(WALL_WORLD, source="wall.yaml")


@pytest.fixture(scope="module")
def open_world() -> World:
    return World.from_yaml(OPEN_WORLD, source="open.yaml")


@pytest.fixture
def stuck_world(wall_world: World) -> RobotWorld:
    return RobotWorld(wall_world, predicates=STUCK)


@pytest.fixture
def stuck_in_engine(wall_world: World, physics_engine: str) -> RobotWorld:
    """`stuck_world` in each physics engine."""
    return RobotWorld(in_engine(wall_world, physics_engine), predicates=STUCK)


@pytest.fixture
def env(stuck_world: RobotWorld) -> Iterator[RobotEnv]:
    made = stuck_world.make_env()
    yield made
    made.close()


def straight(env: RobotEnv, obs: dict[str, np.ndarray]) -> np.ndarray:
    return np.array([env.settings.max_speed, 0.0])


def go_to_goal(env: RobotEnv, obs: dict[str, np.ndarray]) -> np.ndarray:
    """The built-in GoToGoal law on the full observation: the very commands `robot_world.run()` gives."""
    assert env.last_observation is not None
    command = GoToGoal()(env.last_observation)
    return np.array([command.linear, command.angular])


def roll_out(env: RobotEnv, policy: Policy, seed: int | None = None) -> tuple[dict[str, Any], list[Step]]:
    """Reset `env` and step it with `policy` until the episode ends."""
    obs, info = env.reset(seed=seed)
    steps: list[Step] = []
    while True:
        step = env.step(policy(env, obs))
        steps.append(step)
        obs = step[0]
        if step[2] or step[3]:
            return info, steps


def check_quietly(env: gymnasium.Env) -> None:
    """check_env, failing on any warning but the expected notes (e.g. 'not equal although similar')."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    unexpected = [str(w.message) for w in caught if not any(note in str(w.message) for note in CHECK_ENV_NOTES)]
    assert unexpected == []


# -- the gymnasium contract ------------------------------------------------------------------------
def test_check_env_passes(stuck_in_engine: RobotWorld) -> None:
    env = stuck_in_engine.make_env()
    check_quietly(env)
    check_quietly(env.unwrapped)


def test_check_env_passes_with_wheel_actions(stuck_world: RobotWorld) -> None:
    check_quietly(stuck_world.make_env(wheel_actions=True))


def test_spaces_are_fixed_at_construction(env: RobotEnv) -> None:
    space = env.observation_space
    assert isinstance(space, gymnasium.spaces.Dict)
    shapes = {key: box.shape for key, box in space.spaces.items()}
    assert shapes == {"pose": (3,), "goal": (2,), "velocity": (2,), "wheel_speeds": (4,), "scan": (90,), "time": (1,)}
    assert all(box.dtype == np.float32 for box in space.spaces.values())
    assert env.action_space.low.tolist() == pytest.approx([-1.0, -0.8])
    assert env.action_space.high.tolist() == pytest.approx([1.0, 0.8])
    obs, _ = env.reset()
    assert obs in space
    assert obs["goal"].tolist() == [4.0, 0.0]
    assert obs["time"].tolist() == [0.0]


def test_no_scan_without_a_laser(stuck_world: RobotWorld) -> None:
    env = stuck_world.make_env(settings=RunSettings(laser_rays=0))
    assert "scan" not in env.observation_space.spaces
    obs, _ = env.reset()
    assert "scan" not in obs and obs in env.observation_space


def test_scan_reads_max_range_where_nothing_was_hit(env: RobotEnv) -> None:
    obs, _ = env.reset()
    assert env.last_observation is not None and env.last_observation.scan is not None
    ranges = env.last_observation.scan.ranges
    assert np.isinf(ranges).any() and np.isfinite(ranges).any()  # the wall ahead, nothing behind
    assert np.all(obs["scan"][np.isinf(ranges)] == np.float32(10.0))
    assert obs["scan"][np.isfinite(ranges)] == pytest.approx(ranges[np.isfinite(ranges)], abs=1e-5)


def test_same_seed_gives_bit_identical_observations(env: RobotEnv) -> None:
    def observations(seed: int) -> list[dict[str, np.ndarray]]:
        obs, _ = env.reset(seed=seed)
        seen = [obs]
        for _ in range(15):
            seen.append(env.step(np.array([0.8, 0.3]))[0])
        return seen

    first, again, other = observations(7), observations(7), observations(8)
    for a, b in zip(first, again, strict=True):
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(first[-1]["pose"], other[-1]["pose"])


# -- episodes, failures and runs ---------------------------------------------------------------------
def test_driving_into_the_wall_terminates_stuck_and_lands_in_runs(stuck_in_engine: RobotWorld) -> None:
    stuck_world = stuck_in_engine
    start_info, steps = roll_out(stuck_world.make_env(), straight)
    _, reward, terminated, truncated, info = steps[-1]
    assert terminated and not truncated
    assert info["failure"]["predicate"] == "stuck"
    assert info["reached_goal"] is False
    assert info["time"] == pytest.approx(len(steps) * 0.05)
    assert all(not (s[2] or s[3]) for s in steps[:-1])
    assert all(s[4]["failure"] is None and "run" not in s[4] for s in steps[:-1])
    # progress rewards telescope to the distance gained; the failure costs FAILURE_PENALTY once
    total = sum(s[1] for s in steps)
    gained = start_info["goal_distance"] - info["goal_distance"]
    assert total == pytest.approx(gained - FAILURE_PENALTY)
    assert reward < -FAILURE_PENALTY / 2
    assert stuck_world.runs == [info["run"]]
    run = info["run"]
    assert isinstance(run, Run) and run.failure is not None and run.failure.predicate == "stuck"
    assert "wall" in run.touched
    with pytest.raises(RobotFailure, match="'stuck' predicate fired"):
        stuck_world.check()


def test_stepping_a_finished_episode_says_reset(env: RobotEnv, stuck_world: RobotWorld) -> None:
    roll_out(env, straight)
    with pytest.raises(RuntimeError, match=r"call reset\(\)"):
        env.step(np.zeros(2))
    env.reset()
    env.close()
    assert len(stuck_world.runs) == 1  # recorded once, when it ended


def test_time_limit_truncates(wall_world: World) -> None:
    robot_world = RobotWorld(wall_world)  # no predicates
    env = robot_world.make_env(timeout=1.0)
    assert env.observation_space["time"].high.tolist() == pytest.approx([1.05])
    _, steps = roll_out(env, lambda env, obs: np.zeros(2))
    _, _, terminated, truncated, info = steps[-1]
    assert truncated and not terminated
    assert len(steps) == 20 and info["time"] == pytest.approx(1.0)
    assert info["failure"] is None and info["run"] is robot_world.runs[-1]
    assert len(robot_world.runs) == 1
    robot_world.check()  # nothing failed


def test_reaching_the_goal_terminates_with_the_bonus(open_world: World, physics_engine: str) -> None:
    robot_world = RobotWorld(in_engine(open_world, physics_engine), predicates=STUCK)
    env = robot_world.make_env()
    _, steps = roll_out(env, go_to_goal)
    _, reward, terminated, truncated, info = steps[-1]
    assert terminated and not truncated
    assert info["reached_goal"] is True and info["failure"] is None
    assert reward > GOAL_BONUS
    assert robot_world.runs[-1].reached_goal
    robot_world.check()


def test_policy_stepping_go_to_goal_gives_the_same_run_as_run(wall_world: World, physics_engine: str) -> None:
    """The env is the same simulation: GoToGoal's actions through make_env() give robot_world.run()'s Run."""
    wall_world = in_engine(wall_world, physics_engine)
    by_run = RobotWorld(wall_world, predicates=STUCK, seed=3).run(raise_on_failure=False)
    robot_world = RobotWorld(wall_world, predicates=STUCK, seed=3)
    _, steps = roll_out(robot_world.make_env(), go_to_goal)
    by_env = steps[-1][4]["run"]
    assert by_env.seed == by_run.seed == 3
    assert by_env.same_trajectory(by_run)
    assert np.array_equal(by_env.wheel_contacts, by_run.wheel_contacts)
    assert by_env.failure == by_run.failure and by_run.failure is not None
    assert (by_env.steps, by_env.reached_goal, by_env.sim_time) == (by_run.steps, by_run.reached_goal, by_run.sim_time)
    assert dict(by_env.first_touch) == dict(by_run.first_touch)
    assert dict(by_env.first_sensed) == dict(by_run.first_sensed)


def test_reset_seeds_follow_the_reduction_attempt(wall_world: World) -> None:
    robot_world = RobotWorld(wall_world, predicates=STUCK, seed=5, attempt=2)
    env = robot_world.make_env()
    assert env.reset()[1]["seed"] == 5 + 2 * ATTEMPT_SEED_STRIDE == robot_world.run_seed
    assert env.reset(seed=11)[1]["seed"] == 11 + 2 * ATTEMPT_SEED_STRIDE


def test_unfinished_episodes_are_recorded_when_dropped(stuck_world: RobotWorld) -> None:
    env = stuck_world.make_env()
    env.reset()
    env.reset()  # not stepped: nothing to record
    assert stuck_world.runs == []
    for _ in range(5):
        env.step(np.array([0.5, 0.0]))
    env.reset()  # stepped and unfinished: recorded
    assert len(stuck_world.runs) == 1 and stuck_world.runs[0].sim_time == pytest.approx(0.25)
    env.step(np.array([0.5, 0.0]))
    env.close()
    env.close()  # closing twice is fine
    assert len(stuck_world.runs) == 2 and stuck_world.runs[1].failure is None
    assert env.episode is None


# -- wheel actions --------------------------------------------------------------------------------
def test_wheel_actions_drive_the_wheels(wall_world: World, physics_engine: str) -> None:
    robot_world = RobotWorld(in_engine(wall_world, physics_engine), predicates=STUCK)
    env = robot_world.make_env(wheel_actions=True)
    bound = (1.0 + 0.8 * 0.5708 * 1.5 / 2.0) / 0.17775  # the Husky's fastest wheel within the Command box
    assert env.action_space.high.tolist() == pytest.approx([bound, bound], rel=1e-6)
    assert env.action_space.low.tolist() == pytest.approx([-bound, -bound], rel=1e-6)
    obs, _ = env.reset()
    for _ in range(20):
        obs, *_ = env.step(np.array([4.0, 4.0]))
    assert obs["pose"][0] > 0.5 and abs(obs["pose"][1]) < 0.2  # straight ahead
    assert np.all(obs["wheel_speeds"] > 2.0)
    for _ in range(20):
        obs, *_ = env.step(np.array([-3.0, 3.0]))
    assert obs["velocity"][1] > 0.2  # turning left on the spot


# -- errors ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("action", [np.zeros(3), np.zeros((2, 1)), 1.0, [[1.0, 0.0]], ["fast", "left"]])
def test_a_bad_action_shape_is_a_clear_error(env: RobotEnv, action: Any) -> None:
    env.reset()
    with pytest.raises(ValueError, match=r"action: expected 2 numbers \(linear, angular\), got "):
        env.step(action)
    env.step([0.1, 0.0])  # the episode is intact: observe/act still alternate


def test_a_nan_action_fails_like_a_controller(env: RobotEnv) -> None:
    env.reset()
    with pytest.raises(ControllerError, match=r"the policy's action at t = 0\.\d\d s: expected finite numbers, got \[nan, 0\.0\]"):
        env.step(np.array([math.nan, 0.0]))


def test_step_before_reset(env: RobotEnv) -> None:
    with pytest.raises(RuntimeError, match=r"reset\(\) before step\(\)"):
        env.step(np.zeros(2))


def test_a_second_env_takes_the_simulator_over(stuck_world: RobotWorld, wall_world: World) -> None:
    first = stuck_world.make_env()
    first.reset()
    first.step(np.zeros(2))
    second = RobotWorld(wall_world).make_env()
    with pytest.raises(RuntimeError, match="one episode at a time"):
        first.step(np.zeros(2))
    second.reset()
    second.step(np.zeros(2))


def test_wall_time_limit_raises_controller_timeout(stuck_world: RobotWorld) -> None:
    env = stuck_world.make_env(max_wall_time=1e-9)
    env.reset()
    with pytest.raises(ControllerTimeout, match="wall-clock limit"):
        env.step(np.zeros(2))
    env.close()
    assert stuck_world.runs == []  # like robot_world.run(), a timed-out run is not recorded


def test_bad_options(stuck_world: RobotWorld) -> None:
    with pytest.raises(ValueError, match="render_mode: expected None, got 'human'; RobotEnv renders nothing"):
        stuck_world.make_env(render_mode="human")
    with pytest.raises(ScenarioError, match="'max_wall_time': expected a number of seconds > 0 or None, got 0"):
        stuck_world.make_env(max_wall_time=0)
    with pytest.raises(ScenarioError, match=r"'timeout': expected a finite time limit in seconds > 0, got -1\.0"):
        stuck_world.make_env(timeout=-1.0)
    env = stuck_world.make_env()
    with pytest.raises(ValueError, match="no options"):
        env.reset(options={"timeout": 3})


def test_missing_gymnasium_is_a_clear_import_error(monkeypatch: pytest.MonkeyPatch, stuck_world: RobotWorld) -> None:
    monkeypatch.setitem(sys.modules, "gymnasium", None)
    monkeypatch.delitem(sys.modules, "pytest_ddenv.scenario.gym_env")
    with pytest.raises(ImportError, match=r"pip install 'pytest-ddenv\[gym\]'"):
        importlib.import_module("pytest_ddenv.scenario.gym_env")
    with pytest.raises(ImportError, match="make_env"):
        stuck_world.make_env()
