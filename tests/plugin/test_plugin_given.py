"""Hypothesis scenario tests under --ddenv-reduce: the falsifying example's world is reduced, each probe runs
the test once on that example, and the replay command runs it once on the minimal world."""

from __future__ import annotations

import json
import shlex
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

GIVEN_TEST = textwrap.dedent(
    """\
    import pytest
    from hypothesis import HealthCheck, given, settings, strategies as st
    from pytest_ddenv.world import World

    BASE = World.load("wall.yaml")


    @st.composite
    def subworlds(draw):
        names = set(draw(st.lists(st.sampled_from(BASE.names), unique=True, min_size=1)))
        return BASE.select(tuple(name for name in BASE.names if name in names))


    @pytest.mark.ddenv(partition="model2model", priority="avg-trajectory", deflake=1)
    @pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
    @settings(max_examples=30, deadline=None, database=None, derandomize=True,
              phases=[{phases}], suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(world=subworlds(), gain={gain})
    def test_reaches_goal(robot_world, world, gain):
        run = robot_world.rebound(world).run()
        assert run.reached_goal
    """
)


def given_project(pytester: pytest.Pytester, *, shrink: bool = True, gain: str = "st.integers(1, 3)") -> Path:
    """The wall world (the `wall_project` fixture's, requested by each test) with a @given test instead."""
    (pytester.path / "test_scenario.py").unlink()
    phases = "Phase.generate" + (", Phase.shrink" if shrink else "")
    source = GIVEN_TEST.replace("{phases}", phases).replace("{gain}", gain)
    pytester.makepyfile(test_given=source.replace("import HealthCheck,", "import HealthCheck, Phase,"))
    return pytester.path


def summary_of(folder: Path) -> dict:
    (path,) = folder.glob("ddenv-artifacts/*/summary.json")
    return json.loads(path.read_text())


@pytest.mark.parametrize("workers", ["2", "1"])
def test_the_falsifying_world_is_reduced_and_each_probe_runs_that_example_once(wall_project: pytest.Pytester,
                                                                                  workers: str) -> None:
    pytester = wall_project
    folder = given_project(pytester, shrink=False)  # Hypothesis does not shrink: ddenv's reduction does it
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", "--ddenv-workers", workers,
                                           "--ddenv-stages", "models", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    summary = summary_of(folder)
    assert summary["minimal_models"] == ["wall"]
    assert summary["one_minimal"] is True
    hypothesis = summary["hypothesis"]
    assert hypothesis["world_argument"] == "world"
    assert set(hypothesis["arguments"]) == {"gain"} and hypothesis["arguments"]["gain"] in (1, 2, 3)
    # each probe is one simulation of the example, not a Hypothesis search of 30 examples (with 2 workers a
    # few speculative runs are cancelled before they are logged; they count as simulations all the same)
    records = [json.loads(line) for line in Path(summary["files"]["log"]).read_text().splitlines()]
    logged = sum(1 for record in records if record.get("event") == "probe")
    assert logged <= summary["simulations"] <= logged + 2 * int(workers)
    assert "Failing test case: test_reaches_goal(" in result.stdout.str()  # Hypothesis names the test
    result.stdout.fnmatch_lines(["*ddenv reductions*", "*test_reaches_goal: * -> 1 models*"])


def test_the_replay_command_runs_the_test_once_on_the_minimal_world(wall_project: pytest.Pytester) -> None:
    pytester = wall_project
    folder = given_project(pytester)
    pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", "--ddenv-workers", "1",
                                  "--ddenv-stages", "models", "-p", "no:cacheprovider")
    command = shlex.split(summary_of(folder)["replay"])
    assert command[0] == "pytest" and "--ddenv-world" in command
    replay = pytester.runpytest_subprocess(*command[1:], "-p", "no:cacheprovider")
    replay.assert_outcomes(failed=1)
    replay.stdout.fnmatch_lines(["*RobotFailure*stuck*"])
    assert "Falsifying example" not in replay.stdout.str()  # one run on the file, not a Hypothesis search


def test_a_drawn_value_that_is_not_plain_data_is_named_and_the_failure_kept(wall_project: pytest.Pytester) -> None:
    pytester = wall_project
    given_project(pytester, gain="st.builds(object)")
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", "--ddenv-workers", "1",
                                           "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*no reduction: @given argument 'gain' = <object object at *> is not plain data*"])


def test_running_the_fixture_instead_of_the_drawn_world_says_what_to_do(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_forgot="""
        from hypothesis import HealthCheck, given, settings
        from pytest_ddenv.strategies import worlds

        @settings(max_examples=2, deadline=None, database=None,
                  suppress_health_check=[HealthCheck.function_scoped_fixture])
        @given(world=worlds(count=1))
        def test_forgot_rebound(robot_world, world):
            robot_world.run()
        """)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*robot_world has no world in a @given test: run the drawn one, "
                                 "robot_world.rebound(world).run()*"])
