"""The loop a user lives in: reduce, edit the code under test, reduce again. The second reduction answers for
the edited code (a fresh run log, never the earlier verdicts), the note says which file changed, and an
unchanged rerun still resumes. A failure that happens with no models at all is not "reduced"."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

TWO_WALLS = (Path(__file__).parents[1] / "data" / "two_walls.yaml").read_text()

STEERING = textwrap.dedent(
    """\
    def around(observation, side):
        \"\"\"Toward a waypoint beside the walls (left: side = 1, right: side = -1), then to the goal.\"\"\"
        x, y, yaw = observation.pose
        wx, wy = (4.0, side * 1.5) if x < 3.5 else (6.0, 0.0)
        bearing = math.atan2(wy - y, wx - x) - yaw
        bearing = math.atan2(math.sin(bearing), math.cos(bearing))
        return Command(linear=0.6, angular=max(-1.0, min(1.0, 2.0 * bearing)))
    """
)

TEST_HEADER = textwrap.dedent(
    """\
    import math

    import pytest

    from pytest_ddenv import Command

    """
)

TEST_BODY = textwrap.dedent(
    """\


    @pytest.mark.ddenv(world="walls.yaml", deflake=1, priority="sequential")
    @pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
    def test_goes_around(robot_world):
        assert robot_world.run(controller=controller).reached_goal
    """
)

# Each way to hold the code that decides the side: (files before the edit, the edit: file, old, new text).
LEFT_THEN_RIGHT = {
    "controller-in-the-test-module": (
        {"test_walls.py": TEST_HEADER + STEERING + "\n\ndef controller(observation):\n"
                                                   "    return around(observation, 1.0)\n" + TEST_BODY},
        ("test_walls.py", "around(observation, 1.0)", "around(observation, -1.0)"),
    ),
    "module-level-constant": (
        {"test_walls.py": TEST_HEADER + "SIDE = 1.0\n\n" + STEERING
         + "\n\ndef controller(observation):\n    return around(observation, SIDE)\n" + TEST_BODY},
        ("test_walls.py", "SIDE = 1.0", "SIDE = -1.0"),
    ),
    "helper-module": (
        {"steering.py": "import math\n\nfrom pytest_ddenv import Command\n\nSIDE = 1.0\n\n\n" + STEERING,
         "test_walls.py": TEST_HEADER + "from steering import SIDE, around\n\n\n"
                                        "def controller(observation):\n    return around(observation, SIDE)\n"
                          + TEST_BODY},
        ("steering.py", "SIDE = 1.0", "SIDE = -1.0"),
    ),
    # a program beside the test that the test runs (a simulator or planner of its own), never imported
    "script-run-as-a-program": (
        {"side.py": "print(1.0)\n",
         "test_walls.py": TEST_HEADER + "import subprocess\nimport sys\nfrom pathlib import Path\n\n"
                                        "SIDE = float(subprocess.run([sys.executable, Path(__file__).with_name("
                                        "'side.py')], capture_output=True, text=True, check=True).stdout)\n\n"
                          + STEERING + "\n\ndef controller(observation):\n    return around(observation, SIDE)\n"
                          + TEST_BODY},
        ("side.py", "print(1.0)", "print(-1.0)"),
    ),
}


def summary_of(project: pytest.Pytester) -> dict:
    (summary,) = Path(project.path, "ddenv-artifacts").glob("*/summary.json")
    return json.loads(summary.read_text())


def reduce(project: pytest.Pytester) -> tuple[pytest.RunResult, dict]:
    result = project.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    return result, summary_of(project)


@pytest.mark.parametrize("where", sorted(LEFT_THEN_RIGHT))
def test_an_edit_of_the_code_under_test_gives_the_new_answer_not_the_earlier_verdicts(
        pytester: pytest.Pytester, where: str) -> None:
    files, (edited, old, new) = LEFT_THEN_RIGHT[where]
    pytester.makefile(".yaml", walls=TWO_WALLS)
    for name, text in files.items():
        Path(pytester.path, name).write_text(text)
    _, before = reduce(pytester)
    assert before["minimal_models"] == ["left_wall"]
    assert before["reference_failure"]["signature"]["touched"] == ["left_wall"]

    path = Path(pytester.path, edited)
    path.write_text(path.read_text().replace(old, new))
    result, after = reduce(pytester)
    assert after["minimal_models"] == ["right_wall"], "the earlier run's verdicts were reused"
    assert after["reference_failure"]["signature"]["touched"] == ["right_wall"]
    assert after["resumed_runs"] == 0 and after["failure_rate"]["fails"] == after["failure_rate"]["runs"]
    result.stdout.fnmatch_lines([f"*the code under test changed: {edited} (edited)*runs.previous-1.jsonl*"])
    assert "in earlier runs" not in result.stdout.str()


def test_an_unchanged_rerun_resumes_the_log(pytester: pytest.Pytester) -> None:
    files, _ = LEFT_THEN_RIGHT["helper-module"]
    pytester.makefile(".yaml", walls=TWO_WALLS)
    for name, text in files.items():
        Path(pytester.path, name).write_text(text)
    reduce(pytester)
    result, again = reduce(pytester)
    assert again["minimal_models"] == ["left_wall"] and again["resumed_runs"] == 1
    assert "runs.previous" not in result.stdout.str()
    result.stdout.fnmatch_lines(["*in earlier runs*"])
    # the terminal line gives the whole history's simulations and this run's share: its time is this run's
    sims = again["simulations"]
    this_run = again["this_run"]["simulations"]
    assert 0 < this_run < sims
    line = f"test_walls.py::test_goes_around: 6 -> 1 models *, {sims} simulations ({this_run} in this run), * s, *"
    result.stdout.fnmatch_lines([line])


def test_a_log_of_another_failure_is_not_resumed_even_when_the_code_is_the_same(pytester: pytest.Pytester) -> None:
    """The side comes from a data file the code identity does not cover: the reference failure tells."""
    pytester.makefile(".yaml", walls=TWO_WALLS)
    pytester.makefile(".txt", side="1.0")
    Path(pytester.path, "test_walls.py").write_text(
        TEST_HEADER + STEERING + "\n\ndef controller(observation):\n"
        "    return around(observation, float(open('side.txt').read()))\n" + TEST_BODY)
    reduce(pytester)
    pytester.makefile(".txt", side="-1.0")
    result, after = reduce(pytester)
    assert after["minimal_models"] == ["right_wall"] and after["resumed_runs"] == 0
    result.stdout.fnmatch_lines(["*the run log of another problem (it reduced another failure)*"])


def test_a_failure_that_happens_without_any_model_is_not_reduced(pytester: pytest.Pytester) -> None:
    pytester.makefile(".yaml", walls=TWO_WALLS)
    pytester.makepyfile(test_walls=textwrap.dedent(
        """\
        import pytest


        def broken(observation):
            return (0.5, 0.0)  # not a Command: fails in every world


        @pytest.mark.ddenv(world="walls.yaml", deflake=1)
        @pytest.mark.robot_failure("stuck", window=2.0, min_progress=0.2)
        def test_drives(robot_world):
            assert robot_world.run(controller=broken).reached_goal
        """))
    result = pytester.runpytest_subprocess("--ddenv-reduce", "--ddenv-media", "none")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*ControllerError*",
                                 "*the failure does not depend on the world: it also happens with no models*"])
    summary = summary_of(pytester)
    assert summary["status"] == "world-independent" and summary["simulations"] == 2  # confirmation + empty world
    folder = Path(summary["files"]["summary"]).parent
    assert not (folder / "minimal.yaml").exists()
    records = [json.loads(line) for line in (folder / "runs.jsonl").read_text().splitlines()]
    (empty,) = [r for r in records if r.get("purpose") == "independence"]
    assert empty["candidate"] == [] and empty["outcome"] == "fail"
