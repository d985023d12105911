"""A scenario test for a robot declared in YAML only: the diffbot (diffbot.urdf) and its world.

The world's `scenario.robot` is a mapping (URDF, drive, wheel joints); wheel radius, track, footprint and
the laser mount are read from the URDF. The test fails on purpose: the diffbot's bumper clears the floor by
5 cm, so it cannot climb the 10 cm loading dock the goal is on. `pytest examples --ddenv-reduce` reduces the
13-model world to the dock alone. Not part of the test suite.
"""

import pytest


@pytest.mark.ddenv(world="diffbot_world.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("stuck", window=5.0, min_progress=0.2)
def test_diffbot_drives_onto_the_loading_dock(robot_world):
    run = robot_world.run()
    assert run.reached_goal
