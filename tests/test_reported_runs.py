"""`robot_world.report(...)`: what a simulator of your own did, as a Run the reduction and the pictures use."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pytest_ddenv import RobotWorld, World
from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.scenario.probe import trace_of
from pytest_ddenv.scenario.robot_world import RobotFailure

WORLD = World.load(Path(__file__).resolve().parent / "data" / "wall_and_crate.yaml")


def test_a_reported_trajectory_becomes_a_run() -> None:
    robot_world = RobotWorld(WORLD, seed=4)
    times = [0.0, 0.5, 1.0, 1.5]
    run = robot_world.report(times, [[0, 0, 0], [0.5, 0, 0.1], [1.0, 0.05, 0.3], [1.4, 0.1, 0.3]],
                             sensed={"wall": 0.5})
    assert robot_world.runs == [run] and run.failure is None and not run.reached_goal
    assert run.poses.shape == (4, 6) and run.poses[2, 5] == 0.3 and run.poses[:, 2].tolist() == [0.0] * 4
    assert run.velocities[2, 5] == pytest.approx(0.4) and run.velocities[1, 0] == pytest.approx(1.0)
    assert run.sim_time == 1.5 and run.seed == 4 and dict(run.first_sensed) == {"wall": 0.5}
    assert (run.engine, run.engine_version) == ("reported", "")  # your simulator ran it, not pybullet
    trace = trace_of(run)
    assert trace.failure_position is None and len(trace) == 4
    robot_world.check()  # no failure reported: nothing raised


def test_a_reported_failure_fails_the_test_like_a_predicate() -> None:
    robot_world = RobotWorld(WORLD)
    robot_world.report([0.0, 1.0], [[0, 0], [1.7, 0]], failure_pose=(1.7, 0.0), touched=["wall"],
                       detail="bumper pressed")
    with pytest.raises(RobotFailure, match=r"'reported' predicate fired at t = 1\.00 s.*touching wall.*bumper") as raised:
        robot_world.check()
    assert raised.value.signature.position == (1.7, 0.0, 0.0)
    assert trace_of(raised.value.run).failure_position.tolist() == [1.7, 0.0, 0.0]


@pytest.mark.parametrize(
    ("times", "poses", "options", "field", "fragment"),
    [
        ([], [], {}, "times", r"report\(times=...\): expected at least one sample, got \[\]"),
        ([0.0, 1.0, 0.5], [[0, 0]] * 3, {}, "times",
         r"report\(times=...\): expected times that do not decrease, got \[0\.0, 1\.0, 0\.5\]"),
        ([0.0, 1.0], [[0, 0], [np.nan, 0]], {}, "poses",
         r"report\(poses=...\): expected finite numbers, got NaN or infinite values"),
        ([0.0, 1.0], [[0, 0, 0, 0]] * 2, {}, "poses",
         r"report\(poses=...\): expected shape \(2, 2\), \(2, 3\) or \(2, 6\) to match times, got shape \(2, 4\)"),
        ([0.0, 1.0], [[0, 0]] * 2, {"touched": ["shelf"]}, "touched",
         r"report\(touched=...\): model\(s\) not in the world: shelf"),
        ([0.0, 1.0], [[0, 0]] * 2, {"touched": "wall"}, "touched",
         r"report\(touched=...\): expected a list of model names \(or name -> time\), not a string, got 'wall'"),
        ([0.0, 1.0], [[0, 0]] * 2, {"failure_pose": [1.0]}, "failure_pose",
         r"report\(failure_pose=...\): expected 2, 3 or 6 numbers \(x, y\[, z ...\]\), got \[1\.0\]"),
        ([0.0, 1.0], "fast", {}, "poses", r"report\(poses=...\): expected numbers, got 'fast'"),
    ],
)
def test_bad_reports_are_clear_errors(times: Any, poses: Any, options: dict[str, Any], field: str,
                                      fragment: str) -> None:
    with pytest.raises(ScenarioError, match=fragment) as raised:
        RobotWorld(WORLD).report(times, poses, **options)
    assert raised.value.field == field
