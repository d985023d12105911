"""Hypothesis draws cluttered tables until the default pick-and-place controller's arm hits an object on the
way; `pytest --ddenv-reduce` then reduces the falsifying table to the object it hits.

`tabletop_worlds()` puts the Panda at the table's edge, a target and a place region within its reach, and
6 to 14 objects (boxes, cylinders, spheres up to 30 cm tall) standing on the table, at least 2 cm from each
other, the target and the place region. The default controller (`PickAndPlace`) approaches the target
from 20 cm above it and carries it 20 cm high: a tall object next to the target or on the way is hit.
Hypothesis's own shrinking is off (`phases` without `Phase.shrink`), as in examples/test_generated_worlds.py:
ddenv's reduction keeps the failure Hypothesis found while removing objects (docs/generating-worlds.md).
"""

import pytest
from hypothesis import HealthCheck, Phase, given, settings

from pytest_ddenv.strategies import tabletop_worlds


@pytest.mark.ddenv(partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("arm_collision")
@settings(max_examples=30, deadline=None, derandomize=True, database=None, report_multiple_bugs=False,
          phases=[Phase.explicit, Phase.generate], suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(world=tabletop_worlds(count=(6, 14), height=(0.05, 0.3), clearance=0.02))
def test_panda_picks_and_places_without_hitting_the_clutter(robot_world, world):
    robot_world.rebound(world).run()
