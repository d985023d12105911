"""`ddenv(skip_unsupported=True)`: the models dropped from a test's world are named in one warning per world
load, in pytest's warnings summary (with and without --ddenv-reduce)."""

from __future__ import annotations

import textwrap

import pytest

YARD = textwrap.dedent(
    """\
    <?xml version="1.0"?>
    <sdf version="1.7" xmlns:ddenv="https://github.com/pytest-ddenv/pytest-ddenv/sdf">
      <world name="yard">
        <ddenv:scenario robot="husky" timeout="20">
          <ddenv:start x="0" y="0" yaw="0"/>
          <ddenv:goal x="4" y="0"/>
        </ddenv:scenario>
        <include><uri>model://ground_plane</uri></include>
        <model name="wall"><static>true</static><pose>2 0 0.5 0 0 0</pose>
          <link name="l"><collision name="c"><geometry><box><size>0.3 4 1</size></box></geometry></collision></link>
        </model>
        <actor name="walker"><skin><filename>walk.dae</filename></skin></actor>
        <actor name="jogger"><skin><filename>run.dae</filename></skin></actor>
      </world>
    </sdf>
    """
)
TEST = textwrap.dedent(
    """\
    import pytest

    @pytest.mark.ddenv(world="yard.world", skip_unsupported={skip}, deflake=1)
    @pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
    def test_reaches_goal(robot_world):
        assert robot_world.run().reached_goal
    """
)


@pytest.mark.parametrize("options", [
    pytest.param([], id="plain"),
    pytest.param(["--ddenv-reduce", "--ddenv-media", "none", "--ddenv-workers", "1"], id="reduce",
                 marks=pytest.mark.slow),  # a real reduction in a subprocess: the full tier only
])
def test_one_warning_names_each_dropped_model(pytester: pytest.Pytester, options: list[str]) -> None:
    pytester.makefile(".world", yard=YARD)
    pytester.makepyfile(test_yard=TEST.format(skip=True))
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", *options)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "*warnings summary*",
        ("*DroppedModelsWarning: test_yard.py::test_reaches_goal: yard.world: skip_unsupported dropped 2 models "
         "that cannot be simulated: walker: unsupported <actor>*; jogger: unsupported <actor>*"),
    ])
    assert result.stdout.str().count("DroppedModelsWarning:") == 1


def test_no_warning_when_nothing_is_dropped(pytester: pytest.Pytester) -> None:
    pytester.makefile(".world", yard=YARD.replace("<actor", "<!-- actor").replace("</actor>", "</actor -->"))
    pytester.makepyfile(test_yard=TEST.format(skip=True))
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    assert "DroppedModelsWarning" not in result.stdout.str()
