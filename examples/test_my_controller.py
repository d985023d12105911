"""Your controller in the loop: a small obstacle-avoiding controller, written here, drives the Husky.

It uses the laser: when something is within 1 m ahead it turns on the spot toward the freer side (left
unless the right is clearly freer) and drives that way for 2 s before heading for the goal again. That
gets it around a wall, but not out of the cul-de-sac of worlds/cul_de_sac.yaml: it bounces inside the U
and never gets closer to the goal. The failure is this test's own predicate (`no_progress`, a plain
function of the state made a predicate with `@predicate`). It fails on purpose: `pytest examples --ddenv-reduce` reduces its world to the
three walls of the U. The built-in go-to-goal law fails differently in the same world: it drives into the
back wall and gets stuck there, and that failure needs the back wall only (see docs/writing-tests.md).
"""

import math

import numpy as np
import pytest

from pytest_ddenv import Command, Observation, RobotState, predicate


class Avoider:
    """Head for the goal; detour around what the laser sees ahead."""

    def reset(self, observation: Observation) -> None:
        self.detour_until = -1.0
        self.turn = 0.0

    def __call__(self, observation: Observation) -> Command:
        scan = observation.scan
        ahead = np.abs(scan.angles) < 0.5
        if np.min(scan.ranges[ahead]) < 1.0:
            if observation.time >= self.detour_until:  # a new obstacle: choose a side once
                self.turn = 0.8 if free_space(scan, 1.0) >= 0.9 * free_space(scan, -1.0) else -0.8
            self.detour_until = observation.time + 2.0
            return Command(linear=0.0, angular=self.turn)
        if observation.time < self.detour_until:
            return Command(linear=0.5, angular=0.0)
        bearing = observation.goal_bearing
        speed = min(0.8, observation.goal_distance) * max(0.0, math.cos(bearing)) ** 2
        return Command(linear=speed, angular=max(-0.8, min(0.8, 2.0 * bearing)))


def free_space(scan, side: float) -> float:
    """Summed laser ranges (capped at 4 m) on one side (+1 left, -1 right) of the robot."""
    rays = (side * scan.angles > 0.5) & (side * scan.angles < 1.8)
    return float(np.sum(np.minimum(scan.ranges[rays], 4.0)))


@predicate
def no_progress(state: RobotState) -> str | None:
    """Fails when the robot got less than 0.5 m closer to the goal in the last 15 s."""
    before = state.history.position_at(state.time - 15.0)
    if before is None:
        return None
    was = math.hypot(state.goal[0] - before[0], state.goal[1] - before[1])
    if was - state.goal_distance < 0.5:
        return f"{was:.1f} m from the goal 15 s ago, {state.goal_distance:.1f} m now"
    return None


@pytest.mark.ddenv(world="worlds/cul_de_sac.yaml")
@pytest.mark.robot_failure(no_progress)
def test_my_controller_finds_a_way_to_the_goal(robot_world):
    run = robot_world.run(controller=Avoider())
    assert run.reached_goal
