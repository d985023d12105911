"""An arm's policy in the loop through gymnasium: `robot_world.make_env()` of an arm's world is an `ArmEnv`.

`ReachingPolicy` stands for a trained policy (its `predict(observation)` mimics stable-baselines3's): a
proportional controller of the tool through the env's end-effector actions (`make_env(actions=
"end_effector")`: moves of the tool's target, then the gripper). It goes straight from one waypoint to the
next: to the target, close, lift, carry, lower, release. On an empty table that picks and places the target,
but reaching straight for it from above and behind, its wrist hits the tall box that stands in front of the
target in worlds/arm_policy_table.yaml (18 objects on the table). Each finished episode lands in
`robot_world.runs`, so `robot_world.check()` raises the `arm_collision` failure like `robot_world.run()`
would, and `pytest examples --ddenv-reduce` reduces the table to the tall box (the reduction keeps the table
and the target). It fails on purpose (needs the `gym` extra: `pip install 'pytest-ddenv[gym]'`).
"""

import numpy as np
import pytest

pytest.importorskip("gymnasium")


class ReachingPolicy:
    """A proportional controller of the tool: straight to each waypoint (reached, or after `patience`
    ticks), the gripper as the waypoint says."""

    gain = 0.5
    patience = 60
    grip_ticks = 20

    def __init__(self, action_space):
        self.low, self.high = action_space.low, action_space.high
        self.waypoints, self.stage, self.ticks = None, 0, 0

    def plan(self, observation):
        x, y, z, _, _, self.yaw = observation["target"]
        place_x, place_y, _ = observation["place"]
        return [((x, y, z), -1.0),                      # straight at the target, gripper open
                ((x, y, z), 1.0),                       # close on it
                ((x, y, z + 0.15), 1.0),                # lift
                ((place_x, place_y, z + 0.15), 1.0),    # carry
                ((place_x, place_y, z + 0.01), 1.0),    # lower
                ((place_x, place_y, z + 0.01), -1.0),   # release
                ((place_x, place_y, z + 0.2), -1.0)]    # retreat

    def predict(self, observation, deterministic=True):
        if self.waypoints is None:
            self.waypoints = self.plan(observation)
        goal, gripper = self.waypoints[self.stage]
        tool = observation["end_effector"]
        error = np.array(goal) - tool[:3]
        self.ticks += 1
        gripping = self.stage > 0 and gripper != self.waypoints[self.stage - 1][1]
        if gripping:
            done = self.ticks >= self.grip_ticks
        else:
            done = self.ticks >= self.patience or np.linalg.norm(error) < 0.01
        if done and self.stage < len(self.waypoints) - 1:
            self.stage, self.ticks = self.stage + 1, 0
        turn = (self.yaw - tool[5] + np.pi / 4) % (np.pi / 2) - np.pi / 4  # a box is grasped at any quarter turn
        action = np.array([*(self.gain * error), self.gain * turn, gripper])
        return np.clip(action, self.low, self.high).astype(np.float32), None


@pytest.mark.ddenv(world="worlds/arm_policy_table.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("arm_collision")
def test_policy_picks_and_places_the_target(robot_world):
    env = robot_world.make_env(actions="end_effector")
    policy = ReachingPolicy(env.action_space)
    observation, info = env.reset()
    done = False
    while not done:
        action, _ = policy.predict(observation)
        observation, reward, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    env.close()
    robot_world.check()  # raises RobotFailure when the arm hit something
    assert info["reached_goal"]
