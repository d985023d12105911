"""A small, fast robot world for plugin tests: a wall across the path to the goal and distant distractors."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

# The plugin tests run pytest in a subprocess (runpytest_subprocess): pytester's in-process runs restore
# sys.modules afterwards, and C extensions that a reduction imports lazily (numpy.fft, ...) cannot be
# imported twice in one process.

WALL_WORLD = (Path(__file__).resolve().parents[1] / "data" / "wall.yaml").read_text(encoding="utf-8")

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
