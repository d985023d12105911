"""Three tabletop scenarios: a Franka Panda on a cluttered table picks an object and places it on its left,
with the built-in pick-and-place controller. Each world has 18 models (the table, the target, 15 objects of
clutter, and one object that makes the task fail its own way; docs/scenarios.md, "Tabletop scenarios").

They fail on purpose: `pytest examples --ddenv-reduce` reduces each world to the table, the target and the
object that causes the failure. The reduction keeps the table and the target (an arm's scenario needs them).
"""

import pytest


@pytest.mark.ddenv(world="worlds/tabletop_tall_box.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("arm_collision")
def test_panda_picks_the_mug_behind_the_cereal_box(robot_world):
    run = robot_world.run()
    assert run.reached_goal


@pytest.mark.ddenv(world="worlds/tabletop_tight_grasp.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("grasp_failed")
def test_panda_grasps_the_block_beside_the_juice_box(robot_world):
    run = robot_world.run()
    assert run.reached_goal


@pytest.mark.ddenv(world="worlds/tabletop_carry.yaml", partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("object_dropped")
def test_panda_carries_the_bottle_over_the_divider(robot_world):
    run = robot_world.run()
    assert run.reached_goal
