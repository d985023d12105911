"""Bring your own simulator: the test runs `rover_sim.py`, a separate program that is not PyBullet, on the
world pytest-ddenv gives it, and reports what happened so that the reduction is trajectory-guided.

`robot_world.world` is the world of this test (the candidate world during a reduction): the test writes it
as SDF, runs the simulator in a subprocess, reads its JSON, and tells pytest-ddenv the rover's trajectory,
where it got blocked and what it touched with `robot_world.report(...)`. `robot_world.check()` then fails
the test with a "reported" failure matched by position, like a predicate's. The test fails on purpose: the
crate in the aisle would be easy to sidestep, but the pallet stack next to it is in the way.
`pytest examples --ddenv-reduce` reduces the warehouse to those two.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

SIMULATOR = Path(__file__).with_name("rover_sim.py")


@pytest.mark.ddenv(world="warehouse.yaml", partition="model2model", priority="failure-proximal")
def test_rover_reaches_the_dock(robot_world, tmp_path):
    world_file = tmp_path / "world.sdf"
    robot_world.world.save(world_file)
    scenario = robot_world.world.scenario
    command = [sys.executable, str(SIMULATOR), str(world_file), "--start", str(scenario.start.x),
               str(scenario.start.y), "--goal", str(scenario.goal[0]), str(scenario.goal[1])]
    result = json.loads(subprocess.run(command, capture_output=True, text=True, check=True).stdout)
    robot_world.report(result["times"], result["poses"], failure_pose=result["blocked_at"],
                       touched=result["touched"], reached_goal=result["reached"])
    robot_world.check()  # RobotFailure when the rover was blocked
    assert result["reached"]
