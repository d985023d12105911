"""A small, fast robot world for plugin tests: a wall across the path to the goal and distant distractors."""

from __future__ import annotations

import textwrap

import pytest

# The plugin tests run pytest in a subprocess (runpytest_subprocess): pytester's in-process runs restore
# sys.modules afterwards, and C extensions that a reduction imports lazily (numpy.fft, ...) cannot be
# imported twice in one process.

WALL_WORLD = textwrap.dedent(
    """\
    format: 1
    name: wall
    scenario:
      start: {x: 0.0, y: 0.0, yaw: 0.0}
      goal: {x: 4.0, y: 0.0}
      timeout: 20
    models:
      - {name: far_box_a, pose: [-4, 4, 0.25], box: [0.5, 0.5, 0.5]}
      - {name: far_box_b, pose: [-4, -4, 0.25], box: [0.5, 0.5, 0.5]}
      - {name: wall, pose: [2.0, 0, 0.5], box: [0.3, 4.0, 1.0]}
      - {name: side_post, pose: [2, 5, 0.5], cylinder: {radius: 0.2, length: 1.0}}
      - {name: far_box_c, pose: [8, 6, 0.25], box: [0.5, 0.5, 0.5]}
      - {name: ball, pose: [-3, 0, 0.2], sphere: {radius: 0.2}}
    """
)

SCENARIO_TEST = textwrap.dedent(
    """\
    import pytest

    @pytest.mark.ddenv(world="wall.yaml", partition="model2model", priority="avg-trajectory", deflake=1)
    @pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
    def test_reaches_goal(robot_world):
        run = robot_world.run()
        assert run.reached_goal
    """
)


@pytest.fixture
def wall_project(pytester: pytest.Pytester) -> pytest.Pytester:
    pytester.makefile(".yaml", wall=WALL_WORLD)
    pytester.makepyfile(test_scenario=SCENARIO_TEST)
    return pytester
