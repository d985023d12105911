"""`pytest --ddenv-reduce` on an arm's world: the tall box beside the cube is what the hand hits (a quick
end-to-end check; the shipped tabletop scenarios are reduced in tests/test_tabletop_scenarios.py)."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from pytest_ddenv import World

pytestmark = [pytest.mark.slow, pytest.mark.pybullet]

BLOCKED = (Path(__file__).resolve().parents[1] / "data" / "arm_blocked.yaml").read_text(encoding="utf-8")

ARM_TEST = textwrap.dedent(
    """\
    import pytest

    @pytest.mark.ddenv(world="arm_blocked.yaml", deflake=1)
    def test_places_the_cube(robot_world):
        run = robot_world.run()
        assert run.reached_goal
    """
)


def test_the_reduction_keeps_the_box_the_hand_hits(pytester: pytest.Pytester) -> None:
    pytester.makefile(".yaml", arm_blocked=BLOCKED)
    pytester.makepyfile(test_arm=ARM_TEST)
    result = pytester.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*RobotFailure*arm_collision*tall_box*", "*reduced 6 -> 3 models*"])
    (summary_file,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    summary = json.loads(summary_file.read_text())
    assert sorted(summary["minimal_models"]) == ["cube", "table", "tall_box"]
    assert summary["one_minimal"] is True
    minimal = World.load(summary_file.parent / "minimal.yaml")
    assert minimal.scenario is not None and minimal.scenario.target == "cube" and minimal.scenario.watch == ()


def test_a_mobile_robots_predicate_on_an_arm_world_is_an_error_at_setup(pytester: pytest.Pytester) -> None:
    pytester.makefile(".yaml", arm_blocked=BLOCKED)
    pytester.makepyfile(test_arm=ARM_TEST.replace("def test_", '@pytest.mark.robot_failure("stuck")\ndef test_'))
    result = pytester.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(errors=1)
    refused = ("*arm_blocked.yaml, field 'robot_failure': predicate 'stuck' is for mobile robots; the world's robot "
               "'panda' is an arm; arm predicates: *")
    result.stdout.fnmatch_lines(["*ERROR at setup*", refused])
    assert not Path(pytester.path, "ddenv-artifacts").exists()
