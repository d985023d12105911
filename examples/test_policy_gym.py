"""A policy in the loop through gymnasium: `robot_world.make_env()` is the scenario as a `gymnasium.Env`.

`LinearPolicy` stands for a trained policy (its `predict(observation)` mimics stable-baselines3's): a
linear map from features of the observation dict (the goal in the robot's frame, the measured speed) to
(linear, angular) velocity. It steers well enough on flat ground, but it drives straight at the goal over
the ditch of worlds/ditch.yaml and gets stuck in it. Each finished episode lands in `robot_world.runs`, so
`robot_world.check()` raises the `stuck` failure like `robot_world.run()` would, and the test is reduced
like any other: `pytest examples --ddenv-reduce` shrinks the 43-model ditch world to the two asphalt planes
whose gap is the ditch (about 11 probes). It fails on purpose (needs the `gym` extra:
`pip install 'pytest-ddenv[gym]'`).
"""

import math

import numpy as np
import pytest

pytest.importorskip("gymnasium")


class LinearPolicy:
    """action = clip(weights @ features + bias), features = (goal ahead, goal to the left, speed)."""

    weights = np.array([[0.35, 0.0, 0.1],
                        [0.0, 0.9, 0.0]])
    bias = np.array([0.05, 0.0])

    def __init__(self, action_space):
        self.low, self.high = action_space.low, action_space.high

    def predict(self, observation, deterministic=True):
        x, y, yaw = observation["pose"]
        dx, dy = observation["goal"][0] - x, observation["goal"][1] - y
        ahead = math.cos(yaw) * dx + math.sin(yaw) * dy
        left = -math.sin(yaw) * dx + math.cos(yaw) * dy
        features = np.array([ahead, left, observation["velocity"][0]])
        action = np.clip(self.weights @ features + self.bias, self.low, self.high)
        return action.astype(np.float32), None


@pytest.mark.ddenv(world="worlds/ditch.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("stuck", window=5.0, min_progress=0.2)
def test_policy_crosses_the_ditch(robot_world):
    env = robot_world.make_env()
    policy = LinearPolicy(env.action_space)
    observation, info = env.reset()
    done = False
    while not done:
        action, _ = policy.predict(observation)
        observation, reward, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    env.close()
    robot_world.check()  # raises RobotFailure when the episode ended stuck
    assert info["reached_goal"]
