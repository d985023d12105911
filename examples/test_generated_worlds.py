"""Hypothesis draws cluttered worlds until the robot (the default go-to-goal controller, which drives blind)
collides with something; `pytest --ddenv-reduce` then reduces the falsifying world to the model it hits.

Hypothesis's own shrinking is off (`phases` without `Phase.shrink`): ddenv's reduction keeps the failure
Hypothesis found (same predicate, same place, same model touched) while removing models, and this test took
2.5 to 3.2 times fewer simulations than with Hypothesis's shrinker, which also swapped the failure for
another one (benchmarks/bench_generated.py; docs/generating-worlds.md, "Reducing what Hypothesis finds").
"""

import pytest
from hypothesis import HealthCheck, Phase, given, settings

from pytest_ddenv.strategies import worlds


@pytest.mark.ddenv(partition="model2model", priority="avg-trajectory")
@pytest.mark.robot_failure("collided")
@settings(max_examples=30, deadline=None, derandomize=True, database=None, report_multiple_bugs=False,
          phases=[Phase.explicit, Phase.generate], suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(world=worlds(count=(6, 16), size=(0.4, 1.0), static=True))
def test_husky_crosses_a_cluttered_yard_without_collision(robot_world, world):
    robot_world.rebound(world).run()
