"""Hypothesis draws cluttered tables until the default pick-and-place controller's arm hits an object on its
way; `pytest --ddenv-reduce` then reduces the falsifying table to the object it hits.

`tabletop_worlds()` puts the Panda at the table's edge, a target and a place region within its reach, and 8
to 16 objects (boxes, cylinders and spheres, 10 to 35 cm tall) standing on the table, at least 2 cm from
each other, the target and the place region. The default controller (`PickAndPlace`) approaches the target
from 20 cm above it and carries it 20 cm high: a tall object next to the target or on the way is hit (with
20 N or more: a graze by an object that rolled against the base is not this failure). Any place of the hit
on the same object is the same failure (`same_failure="touched"`): the arm meets a tall box at slightly
different points from run to run. Hypothesis's own shrinking is off (`phases` without `Phase.shrink`), as in
examples/test_generated_worlds.py: ddenv's reduction keeps the failure Hypothesis found while removing
objects (docs/generating-worlds.md, "Tabletop clutter").
"""

import pytest
from hypothesis import HealthCheck, Phase, given, settings

from pytest_ddenv.strategies import tabletop_worlds


@pytest.mark.ddenv(partition="model2model", priority="avg-trajectory", same_failure="touched")
@pytest.mark.robot_failure("arm_collision", min_force=20.0)
@settings(max_examples=30, deadline=None, derandomize=True, database=None, report_multiple_bugs=False,
          phases=[Phase.explicit, Phase.generate], suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(world=tabletop_worlds(count=(8, 16), size=(0.03, 0.1), height=(0.1, 0.35), clearance=0.02))
def test_panda_picks_and_places_without_hitting_the_clutter(robot_world, world):
    robot_world.rebound(world).run()
