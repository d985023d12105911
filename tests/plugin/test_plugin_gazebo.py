"""A Gazebo world in a scenario test: unsupported models skipped on request, what is not simulated said in the
report, and minimal.sdf cut from the user's own file."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

GAZEBO_WORLD = textwrap.dedent(
    """\
    <?xml version="1.0"?>
    <!-- a Gazebo user's world -- with a comment libsdformat accepts and expat does not -->
    <sdf version="1.7" xmlns:ddenv="https://github.com/pytest-ddenv/pytest-ddenv/sdf">
      <world name="yard">
        <ddenv:scenario robot="husky" timeout="20">
          <ddenv:start x="0" y="0" yaw="0"/>
          <ddenv:goal x="4" y="0"/>
        </ddenv:scenario>
        <include><uri>model://sun</uri></include>
        <include><uri>model://ground_plane</uri></include>
        <plugin filename="libgazebo_ros_state.so" name="state"/>
        <model name="far_box"><static>true</static><pose>-4 4 0.25 0 0 0</pose>
          <link name="l"><collision name="c"><geometry><box><size>0.5 0.5 0.5</size></box></geometry></collision></link>
        </model>
        <model name="wall"><static>true</static><pose>2 0 0.5 0 0 0</pose>
          <link name="l"><collision name="c"><geometry><box><size>0.3 4 1</size></box></geometry></collision></link>
        </model>
        <actor name="walker"><skin><filename>walk.dae</filename></skin></actor>
        <model name="post"><static>true</static><pose>2 5 0.5 0 0 0</pose>
          <link name="l"><collision name="c"><geometry><cylinder><radius>0.2</radius><length>1</length></cylinder></geometry></collision></link>
        </model>
      </world>
    </sdf>
    """
)


def gazebo_test(marker: str) -> str:
    return textwrap.dedent(
        f"""\
        import pytest

        @pytest.mark.ddenv({marker})
        @pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
        def test_reaches_goal(robot_world):
            assert robot_world.run().reached_goal
        """
    )


def test_an_unsupported_model_is_an_error_naming_it_unless_skipped(pytester: pytest.Pytester) -> None:
    pytester.makefile(".world", yard=GAZEBO_WORLD)
    pytester.makepyfile(test_yard=gazebo_test("world='yard.world'"))
    result = pytester.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*yard.world:*unsupported <actor>*skip_unsupported=True*"])


@pytest.mark.slow  # a real reduction in a subprocess: the full tier only
def test_a_gazebo_world_is_reduced_with_its_notes_and_a_cut_minimal_sdf(pytester: pytest.Pytester) -> None:
    pytester.makefile(".world", yard=GAZEBO_WORLD)
    pytester.makepyfile(test_yard=gazebo_test("world='yard.world', skip_unsupported=True, deflake=1"))
    result = pytester.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "*reduced 3 -> 1 models*",
        "*not simulated: dropped walker: unsupported <actor>*",
        "*not simulated: plugins: libgazebo_ros_state.so (world)*",
    ])
    (summary_file,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    summary = json.loads(summary_file.read_text())
    assert summary["minimal_models"] == ["wall"]
    assert summary["minimal_sdf"] == f"cut from {pytester.path / 'yard.world'}"
    cut = Path(summary["files"]["minimal_sdf"]).read_text()
    assert "far_box" not in cut and 'name="post"' not in cut
    for kept in ('<model name="wall">', "<actor name=\"walker\">", "libgazebo_ros_state.so", "model://sun",
                 "a Gazebo user's world -- with a comment", "<ddenv:scenario"):
        assert kept in cut
