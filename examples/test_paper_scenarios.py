"""The paper's three Husky scenarios as the scenario tests a user would write.

They fail on purpose: they are the demo of `pytest examples --ddenv-reduce`, not part of the test suite.
Each uses the schema pairing that did best for its scenario in the paper (Tables II-IV) and the default
deflake rule (`auto`: calibrated on the original world's failure rate).
"""

import pytest


@pytest.mark.ddenv(world="worlds/ditch.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("stuck", window=5.0, min_progress=0.2)
def test_husky_crosses_the_ditch(robot_world):
    run = robot_world.run()
    assert run.reached_goal


@pytest.mark.ddenv(world="worlds/rubble.yaml", partition="timeseg", priority="avg-trajectory")
@pytest.mark.robot_failure("high_centered")
@pytest.mark.robot_failure("stuck", window=5.0, min_progress=0.2)
def test_husky_drives_through_the_rubble(robot_world):
    run = robot_world.run()
    assert run.reached_goal


@pytest.mark.ddenv(world="worlds/friction.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("stuck", window=5.0, min_progress=0.2)
def test_husky_crosses_the_friction_patches(robot_world):
    run = robot_world.run()
    assert run.reached_goal
