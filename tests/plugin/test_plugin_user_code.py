"""The user's software under test, in every worker: a controller, a predicate and a helper defined in the test
module, a URDF robot registered by a conftest. The reduction finds the same minimal world however the probes
run, and errors inside a worker are reported as what they are."""

from __future__ import annotations

import importlib.util
import json
import textwrap
from pathlib import Path

import pytest

from .conftest import WALL_WORLD

MY_ROBOT_CONFTEST = textwrap.dedent(
    """\
    from pytest_ddenv import RobotDescription, register_robot
    from pytest_ddenv.sim.robot import husky_urdf

    register_robot("my_husky", RobotDescription(
        urdf=husky_urdf(), drive="skid-steer",
        left_wheels=("front_left_wheel", "rear_left_wheel"), right_wheels=("front_right_wheel", "rear_right_wheel"),
        max_wheel_torque=100.0,
    ))
    """
)

USER_CODE_TEST = textwrap.dedent(
    """\
    import math
    import signal
    import threading

    import pytest

    from pytest_ddenv import Command
    from pytest_ddenv.oracle import signature


    def heading_to_goal(observation):
        \"\"\"A helper of the test module.\"\"\"
        return observation.goal_bearing


    def cautious(observation):
        \"\"\"The controller under test: steady 0.6 m/s, gentle turns toward the goal.\"\"\"
        return Command(linear=0.6, angular=max(-0.5, min(0.5, 1.5 * heading_to_goal(observation))))


    class Blocked:
        \"\"\"The test's own predicate: nearly still for 1 s (after the first second).\"\"\"

        name = "blocked"

        def reset(self):
            self.since = None

        def check(self, state):
            if state.time < 1.0 or math.hypot(*state.velocity[:2]) > 0.05:
                self.since = None
                return None
            self.since = state.time if self.since is None else self.since
            return signature(self.name, state, "still for 1 s") if state.time - self.since >= 1.0 else None


    @pytest.mark.ddenv(world="wall.yaml", deflake=1)
    @pytest.mark.robot_failure(Blocked())
    def test_reaches_goal(robot_world):
        # Every way of running probes runs the test in the main thread of its process: signals work.
        assert threading.current_thread() is threading.main_thread()
        signal.signal(signal.SIGUSR1, signal.getsignal(signal.SIGUSR1))
        assert robot_world.run(controller=cautious).reached_goal
    """
)


@pytest.fixture
def user_project(pytester: pytest.Pytester) -> pytest.Pytester:
    pytester.makefile(".yaml", wall=WALL_WORLD.replace("scenario:\n", "scenario:\n  robot: my_husky\n"))
    pytester.makeconftest(MY_ROBOT_CONFTEST)
    pytester.makepyfile(test_scenario=USER_CODE_TEST)
    return pytester


def summary_of(project: pytest.Pytester) -> dict:
    (summary,) = Path(project.path, "ddenv-artifacts").glob("*/summary.json")
    return json.loads(summary.read_text())


@pytest.mark.slow
@pytest.mark.parametrize(
    "how",
    [
        pytest.param([], id="default-workers"),
        pytest.param(["--ddenv-workers", "1"], id="in-process"),
        pytest.param(["-n", "2"], id="xdist"),
        pytest.param(["--ddenv-executor", "dask", "--ddenv-workers", "2"], id="dask"),
    ],
)
def test_user_code_reduces_to_the_same_minimal_world_however_probes_run(user_project: pytest.Pytester,
                                                                        how: list[str]) -> None:
    if "dask" in how and importlib.util.find_spec("distributed") is None:  # not imported here: see conftest.py
        pytest.skip("dask.distributed is not installed")
    result = user_project.runpytest_subprocess("--ddenv-reduce", *how)
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*'blocked' predicate fired*", "*reduced 6 -> 1 models*"])
    summary = summary_of(user_project)
    assert summary["minimal_models"] == ["wall"] and summary["one_minimal"]
    assert summary["errors"] == 0
    assert summary["predicates"] == [{"name": "blocked", "params": {}, "object": summary["predicates"][0]["object"]}]


@pytest.mark.slow  # a reduction in a subprocess: the full tier only
def test_user_code_that_does_not_import_in_a_worker_is_named(user_project: pytest.Pytester) -> None:
    user_project.makeconftest(MY_ROBOT_CONFTEST + textwrap.dedent(
        """\
        import multiprocessing

        if multiprocessing.parent_process() is not None:  # only in worker processes
            import lab_driver_only_on_the_ci_host
        """
    ))
    result = user_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-workers", "2")
    result.assert_outcomes(failed=1)
    # The one-line summary of the reduction names the module (not only the worker's stderr, which no longer
    # leaks into the test's captured output).
    result.stdout.fnmatch_lines([
        "*= ddenv reductions =*",
        "test_scenario.py::test_reaches_goal: the test could not be run in a probe worker*"
        "ModuleNotFoundError: No module named 'lab_driver_only_on_the_ci_host'*",
    ])
    assert "not reproducible" not in result.stdout.str()
    assert "Captured stderr" not in result.stdout.str()
    assert not Path(user_project.path, "ddenv-artifacts").exists()


@pytest.mark.slow  # a reduction in a subprocess: the full tier only
def test_an_exception_the_test_raises_only_in_probes_is_shown_as_it_is(user_project: pytest.Pytester) -> None:
    user_project.makepyfile(test_scenario=USER_CODE_TEST.replace(
        "def heading_to_goal(observation):\n",
        "def heading_to_goal(observation):\n"
        "    import multiprocessing, os\n"
        "    if multiprocessing.parent_process() is not None:  # in probe workers only\n"
        "        return float(os.environ['LAB_ONLY_IN_THE_PYTEST_PROCESS'])\n",
    ))
    result = user_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-workers", "2", "--ddenv-media", "none")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "*= ddenv reductions =*",
        "test_scenario.py::test_reaches_goal: every confirmation run of the test raised "
        "KeyError: 'LAB_ONLY_IN_THE_PYTEST_PROCESS' at test_scenario.py:* instead of failing the same way*",
    ])
    assert "not reproducible" not in result.stdout.str() and "--ddenv-deflake" not in result.stdout.str()


@pytest.mark.slow  # a reduction in a subprocess: the full tier only
def test_a_robot_registered_only_in_the_pytest_process_is_reported_as_unknown(user_project: pytest.Pytester) -> None:
    user_project.makeconftest(
        "import multiprocessing\n"
        "if multiprocessing.parent_process() is None:  # the pytest process only, not its probe workers\n"
        + textwrap.indent(MY_ROBOT_CONFTEST, "    ")
    )
    result = user_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-workers", "2")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*every confirmation run of the test raised an error*",
                                 "*ScenarioError*unknown robot 'my_husky'; registered robots: husky*"])
    assert "not reproducible" not in result.stdout.str()


@pytest.mark.slow
def test_a_controller_that_raises_is_another_failure_with_its_exception_logged(user_project: pytest.Pytester) -> None:
    docstring = '    """The controller under test: steady 0.6 m/s, gentle turns toward the goal."""\n'
    assert docstring in USER_CODE_TEST
    user_project.makepyfile(test_scenario=USER_CODE_TEST.replace(
        docstring,
        docstring + "    if observation.pose[0] > 2.5:  # past the wall: only where the wall is gone\n"
        "        raise ZeroDivisionError('lost its way')\n",
    ))
    result = user_project.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1)
    summary = summary_of(user_project)
    assert summary["minimal_models"] == ["wall"] and summary["errors"] == 0
    records = [json.loads(line) for line in Path(summary["files"]["log"]).read_text().splitlines()]
    others = [r for r in records if r.get("event") == "probe" and r["outcome"] == "other"]
    assert others and all("ZeroDivisionError: lost its way" in r["detail"] for r in others)
    assert all(r["signature"]["exception"] == "ZeroDivisionError" for r in others)


OWN_SIMULATOR_TEST = textwrap.dedent(
    """\
    import json
    import subprocess
    import sys

    import pytest

    SIMULATOR = '''
    import sys, xml.etree.ElementTree as ET
    names = [m.get("name") for m in ET.parse(sys.argv[1]).getroot().iter("model")]
    print("blocked" if "wall" in names else "arrived")
    '''


    @pytest.mark.ddenv(world="wall.yaml", partition="timeseg", priority="avg-trajectory", deflake=0)
    def test_rover_arrives(robot_world, tmp_path):
        robot_world.world.save(tmp_path / "world.sdf")
        done = subprocess.run([sys.executable, "-c", SIMULATOR, str(tmp_path / "world.sdf")],
                              capture_output=True, text=True, check=True)
        assert done.stdout.strip() == "arrived"
    """
)


@pytest.mark.slow  # a reduction in a subprocess: the full tier only
def test_a_test_with_its_own_simulator_and_no_report_is_reduced_by_model_position(pytester: pytest.Pytester) -> None:
    pytester.makefile(".yaml", wall=WALL_WORLD)
    pytester.makepyfile(test_rover=OWN_SIMULATOR_TEST)
    result = pytester.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "*reduced 6 -> 1 models*",
        "*note: the test made no robot_world.run() and no robot_world.report(), so there is no trajectory: "
        "partition timeseg -> model2model*",
        "*note: *priority avg-trajectory-proximal -> sequential*",
    ])
    summary = summary_of(pytester)
    assert summary["minimal_models"] == ["wall"] and summary["schemas"]["partition"] == "model2model"
    assert len(summary["notes"]) == 2


@pytest.mark.slow  # a reduction in a subprocess: the full tier only
def test_a_run_that_raised_is_named_in_the_fallback_note(user_project: pytest.Pytester) -> None:
    docstring = '    """The controller under test: steady 0.6 m/s, gentle turns toward the goal."""\n'
    user_project.makepyfile(test_scenario=USER_CODE_TEST.replace(  # it raises in front of the wall only
        docstring, docstring + "    if min(observation.scan.ranges) < 1.0:\n        raise ZeroDivisionError('no plan')\n"))
    result = user_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-workers", "1", "--ddenv-media", "none")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*note: robot_world.run() raised ZeroDivisionError, so there is no trajectory: "
                                 "priority avg-trajectory-proximal -> sequential*"])
    assert "made no robot_world.run()" not in result.stdout.str()
