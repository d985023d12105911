"""End to end through pytest: a failing robot test is reduced to its culprit (real simulation)."""

from __future__ import annotations

import importlib.util
import json
import shlex
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from burners import every_core_busy
from engines import engine_option

from pytest_ddenv import World

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only

OPEN_WORLD = (Path(__file__).resolve().parents[1] / "data" / "open.yaml").read_text(encoding="utf-8")


def summary_of(pytester: pytest.Pytester) -> dict:
    (summary,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    return json.loads(summary.read_text())


def test_failing_robot_test_fails_normally_without_the_option(wall_project: pytest.Pytester) -> None:
    result = wall_project.runpytest_subprocess()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*RobotFailure*stuck*"])
    assert not Path(wall_project.path, "ddenv-artifacts").exists()


def test_failing_robot_test_is_reduced_to_the_wall(wall_project: pytest.Pytester, physics_engine: str) -> None:
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "-o", "junit_logging=system-out", "--junitxml=junit.xml",
                                               *engine_option(physics_engine))
    result.assert_outcomes(failed=1)
    # the reported failure is still the original one
    result.stdout.fnmatch_lines(["*RobotFailure*stuck*", "*ddenv reduction*", "*reduced 6 -> 1 models*"])
    result.stdout.fnmatch_lines(["*ddenv reductions*", "*test_reaches_goal: 6 -> 1 models (83%)*probes*fails*"])
    summary = summary_of(wall_project)
    assert summary["minimal_models"] == ["wall"] and summary["engine"]["name"] == physics_engine
    assert summary["one_minimal"] is True and summary["complete"] is True
    assert summary["original_size"] == 6 and summary["probes"] > 0
    assert summary["failure_rate"]["fails"] >= 1
    folder = Path(summary["files"]["summary"]).parent
    assert World.load(folder / "minimal.yaml").names == ("wall",)
    log_lines = (folder / "runs.jsonl").read_text().splitlines()
    assert log_lines and all(json.loads(line) for line in log_lines)
    assert "--ddenv-world" in summary["replay"]
    system_out = "".join(e.text or "" for e in ET.parse(wall_project.path / "junit.xml").iter("system-out"))
    assert f"[[ATTACHMENT|{folder / 'minimal.yaml'}]]" in system_out


def test_auto_deflake_calibrates_on_the_original_world(wall_project: pytest.Pytester) -> None:
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-deflake", "auto")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*reduced 6 -> 1 models*"])
    summary = summary_of(wall_project)
    assert summary["minimal_models"] == ["wall"] and summary["one_minimal"] is True
    # 3 calibration runs; the rate comparison's first look does not top them up to 5: the minimal world failed
    # 5 of 5, so no run of the original could change its decision
    assert summary["original_failure_rate"] == {"fails": 3, "runs": 3}, "the wall stops the robot every time"
    assert summary["rate_check"]["decision"] == "holds" and summary["rate_check"]["backoffs"] == 0
    assert summary["rate_check"]["original_runs_skipped"] == 2
    assert summary["schemas"]["deflake"] == "auto:2-of-3", "a solid failure: confirmed by 2 of at most 3 runs"
    records = [json.loads(line) for line in Path(summary["files"]["log"]).read_text().splitlines()]
    assert [r["attempt"] for r in records if r.get("purpose") == "calibration"] == [1, 2, 3]
    assert max(r["attempt"] for r in records if r.get("purpose") == "reduce") <= 2, "3 runs at most"


def probed(log: Path) -> list[tuple[frozenset[str], int]]:
    """(candidate, attempt) of every reduction simulation in a run log, in log order."""
    records = [json.loads(line) for line in log.read_text().splitlines()]
    return [
        (frozenset(r["candidate"]), r["attempt"])
        for r in records
        if r.get("event") == "probe" and r.get("purpose") == "reduce"
    ]


def test_replaying_the_minimal_world_fails_the_same_way(wall_project: pytest.Pytester) -> None:
    wall_project.runpytest_subprocess("--ddenv-reduce").assert_outcomes(failed=1)
    command = shlex.split(summary_of(wall_project)["replay"])  # exactly what summary.json tells the user
    assert command[0] == "pytest" and "--ddenv-world" in command
    result = wall_project.runpytest_subprocess(*command[1:])
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*RobotFailure*stuck*"])


def test_passing_robot_test_is_not_reduced(wall_project: pytest.Pytester) -> None:
    wall_project.makefile(".yaml", open=OPEN_WORLD)
    wall_project.makepyfile(test_scenario=(
        "import pytest\n"
        "@pytest.mark.ddenv(world='open.yaml')\n"
        "@pytest.mark.robot_failure('stuck', window=2.0)\n"
        "def test_reaches_goal(robot_world):\n"
        "    assert robot_world.run().reached_goal\n"
    ))
    result = wall_project.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(passed=1)
    assert "ddenv reductions" not in result.stdout.str()


def test_failing_test_without_robot_world_is_not_reduced(pytester: pytest.Pytester) -> None:
    pytester.makepyfile("def test_plain():\n    assert 1 == 2\n")
    result = pytester.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1)
    assert "ddenv" not in result.stdout.str().split("short test summary")[0].split("FAILURES")[-1]


def test_failure_that_does_not_reproduce_is_reported(wall_project: pytest.Pytester) -> None:
    wall_project.makepyfile(test_scenario=(
        "import pathlib, pytest\n"
        "@pytest.mark.ddenv(world='wall.yaml', deflake=2)\n"
        "def test_flaky_outside_the_world(robot_world):\n"
        "    robot_world.run(timeout=1.0)\n"
        "    flag = pathlib.Path('ran-once')\n"
        "    first = not flag.exists()\n"
        "    flag.touch()\n"
        "    assert not first, 'fails only the first time'\n"
    ))
    result = wall_project.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*not reproducible: 0 of 3 re-runs failed the same way*they gave: pass, pass, "
                                 "pass*"])


def test_reduction_works_under_xdist(wall_project: pytest.Pytester) -> None:
    result = wall_project.runpytest_subprocess("-n", "2", "--ddenv-reduce")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*ddenv reductions*", "*6 -> 1 models*"])
    assert summary_of(wall_project)["minimal_models"] == ["wall"]


def test_interrupted_reduction_keeps_its_best_world_and_resumes_without_reprobing(
    wall_project: pytest.Pytester,
) -> None:
    # 3 simulations: the confirmation, the world without its models (it passes), one probe of the reduction
    partial = wall_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-max-probes", "3")
    partial.assert_outcomes(failed=1)
    partial.stdout.fnmatch_lines(["*6 -> * models*probes*incomplete (budget: max_probes)*"])
    first = summary_of(wall_project)
    assert first["complete"] is False and first["incomplete_reason"] == "budget: max_probes"
    assert set(first["minimal_models"]) >= {"wall"}
    assert World.load(first["files"]["minimal_yaml"]).names == tuple(first["minimal_models"])

    log = Path(first["files"]["log"])
    first_probes = probed(log)
    first_log = log.read_text()
    assert 1 <= len(first_probes) <= 2
    resumed = wall_project.runpytest_subprocess("--ddenv-reduce")  # without the budget: the same problem
    resumed.assert_outcomes(failed=1)
    assert log.read_text().startswith(first_log), "the resumed run continues the log, it does not start over"
    second = summary_of(wall_project)
    assert second["complete"] is True and second["minimal_models"] == ["wall"]
    new_probes = probed(log)[len(first_probes):]
    assert not set(new_probes) & set(first_probes)  # nothing the interrupted run simulated is simulated again


def test_a_crash_inside_the_reduction_never_replaces_the_tests_own_failure(wall_project: pytest.Pytester) -> None:
    wall_project.makeconftest(
        "import pytest_ddenv.driver.run as driver\n"
        "def broken(*args, **kwargs):\n"
        "    raise RuntimeError('engine exploded')\n"
        "driver.reduce = broken\n"
    )
    result = wall_project.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "*RobotFailure: The 'stuck' predicate fired*",
        "*the reduction itself crashed; the test's failure above is unchanged.*",
        "*test_reaches_goal: reduction crashed: RuntimeError: engine exploded*",
    ])


def test_a_robot_test_runs_in_a_gazebo_world_with_includes_from_the_model_path(
    wall_project: pytest.Pytester,
) -> None:
    models = wall_project.mkdir("models")
    wall_model = models / "wall_block"
    wall_model.mkdir()
    (wall_model / "model.config").write_text("<?xml version='1.0'?><model><name>wall_block</name>"
                                              "<sdf version='1.6'>model.sdf</sdf></model>")
    (wall_model / "model.sdf").write_text(
        "<?xml version='1.0'?><sdf version='1.6'><model name='wall_block'><static>true</static>"
        "<link name='link'><collision name='c'><geometry><box><size>0.3 4 1</size></box></geometry>"
        "</collision></link></model></sdf>"
    )
    World.load(wall_project.path / "wall.yaml").select(["far_box_a"]).save(wall_project.path / "base.world")
    text = (wall_project.path / "base.world").read_text().replace(
        "</world>", "<include><uri>model://wall_block</uri><name>wall</name><pose>2 0 0.5 0 0 0</pose></include></world>"
    )
    (wall_project.path / "gazebo.world").write_text(text)
    wall_project.makepyfile(test_scenario=SCENARIO_TEST_SDF)
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-model-path", str(models))
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*RobotFailure*stuck*touching wall*", "*2 -> 1 models*"])
    missing = wall_project.runpytest_subprocess()
    missing.assert_outcomes(errors=1)
    missing.stdout.fnmatch_lines(["*wall_block*"])


SCENARIO_TEST_SDF = (
    "import pytest\n"
    "@pytest.mark.ddenv(world='gazebo.world')\n"
    "@pytest.mark.robot_failure('stuck', window=2.0, min_progress=0.2)\n"
    "def test_reaches_goal(robot_world):\n"
    "    assert robot_world.run().reached_goal\n"
)


def test_ddenv_replay_reproduces_a_plugin_made_reduction(wall_project: pytest.Pytester) -> None:
    from pytest_ddenv.cli.main import main

    wall_project.runpytest_subprocess("--ddenv-reduce").assert_outcomes(failed=1)
    summary = summary_of(wall_project)
    assert summary["predicates"] == [{"name": "stuck", "params": {"window": 2.0, "min_progress": 0.2}}]
    assert summary["tolerance"] == 0.5 and summary["scenario_seed"] == 0
    folder = Path(summary["files"]["summary"]).parent
    assert (folder / "reduction.png").stat().st_size > 0 and (folder / "progress.png").stat().st_size > 0
    assert main(["replay", str(folder)]) == 0  # 0: the minimal world still fails the same way


def decisions(summary: dict) -> list[tuple[str, tuple[str, ...]]]:
    log = Path(summary["files"]["log"]).read_text().splitlines()
    records = [json.loads(line) for line in log]
    return [(r["event"], tuple(r["candidate"])) for r in records if r.get("event") in ("accept", "step")]


def test_parallel_workers_accept_exactly_what_serial_accepts(wall_project: pytest.Pytester) -> None:
    wall_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-workers", "1").assert_outcomes(failed=1)
    serial = summary_of(wall_project)
    Path(serial["files"]["log"]).unlink()
    Path(serial["files"]["summary"]).unlink()
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-workers", "2")
    result.assert_outcomes(failed=1)
    parallel = summary_of(wall_project)
    assert serial["workers"]["workers"] == 1 and parallel["workers"]["workers"] == 2
    assert parallel["minimal_models"] == serial["minimal_models"] == ["wall"]
    assert [size for _, size in parallel["steps"]] == [size for _, size in serial["steps"]]
    assert decisions(parallel) == decisions(serial)


def test_in_process_probes_warn_that_function_scoped_fixtures_are_shared(wall_project: pytest.Pytester) -> None:
    wall_project.makepyfile(test_scenario=SCENARIO_TEST_WITH_FIXTURE)
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-workers", "1", "-v")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines([
        "*probe *: * models -> *",  # -v: each probe on its own line
        "*PytestWarning: test_scenario.py::test_reaches_goal: function-scoped fixture(s) counter are not "
        "re-created for each reduction probe*",
    ])
    assert "tmp_path" not in result.stdout.str().split("PytestWarning")[1].split("\n")[0]


def test_probe_workers_run_the_whole_test_with_fresh_function_fixtures(wall_project: pytest.Pytester) -> None:
    wall_project.makepyfile(test_scenario=SCENARIO_TEST_WITH_FIXTURE.replace(
        "    counter.append(1)\n", "    counter.append(1)\n    assert counter == [1], 'a fixture value was reused'\n"))
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-workers", "2")
    result.assert_outcomes(failed=1)
    assert "PytestWarning" not in result.stdout.str()
    assert summary_of(wall_project)["minimal_models"] == ["wall"]


def test_under_xdist_on_a_busy_machine_a_test_with_a_function_scoped_fixture_gets_one_probe_worker_process(
    wall_project: pytest.Pytester,
) -> None:
    """An xdist worker's default is `auto`: on a busy machine one core, and a test whose fixture probes would
    share runs them in one worker process, each probe with fresh fixtures, and nothing warns."""
    wall_project.makepyfile(test_scenario=SCENARIO_TEST_WITH_FIXTURE.replace(
        "    counter.append(1)\n", "    counter.append(1)\n    assert counter == [1], 'a fixture value was reused'\n"))
    with every_core_busy():
        result = wall_project.runpytest_subprocess("-n", "1", "--ddenv-reduce")
    result.assert_outcomes(failed=1)
    assert "PytestWarning" not in result.stdout.str()
    summary = summary_of(wall_project)
    assert summary["minimal_models"] == ["wall"] and summary["workers"]["workers"] == 1


SCENARIO_TEST_WITH_FIXTURE = (
    "import pytest\n"
    "@pytest.fixture\n"
    "def counter():\n"
    "    return []\n"
    "@pytest.mark.ddenv(world='wall.yaml')\n"
    "@pytest.mark.robot_failure('stuck', window=2.0, min_progress=0.2)\n"
    "def test_reaches_goal(robot_world, counter, pytestconfig):\n"
    "    counter.append(1)\n"
    "    assert robot_world.run().reached_goal\n"
)


def test_pytest_html_report_gets_the_pictures_and_files(wall_project: pytest.Pytester) -> None:
    if importlib.util.find_spec("pytest_html") is None:  # not imported here: see tests/conftest.py
        pytest.skip("pytest-html is not installed")
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "--html=report.html", "--self-contained-html")
    result.assert_outcomes(failed=1)
    html = (wall_project.path / "report.html").read_text()
    assert "minimal.yaml" in html and "summary.json" in html
    assert "data:image/png;base64" in html  # reduction.png and progress.png embedded


def test_indirect_parametrization_gives_each_case_its_world_and_keep_is_honoured(
    wall_project: pytest.Pytester,
) -> None:
    wall_project.makefile(".yaml", open=OPEN_WORLD)
    wall_project.makepyfile(test_scenario=(
        "import pytest\n"
        "@pytest.mark.ddenv(keep=['ball'])\n"
        "@pytest.mark.robot_failure('stuck', window=2.0, min_progress=0.2)\n"
        "@pytest.mark.parametrize('robot_world', ['wall.yaml', 'open.yaml'], indirect=True)\n"
        "def test_reaches_goal(robot_world):\n"
        "    assert robot_world.run().reached_goal\n"
    ))
    result = wall_project.runpytest_subprocess("--ddenv-reduce")
    result.assert_outcomes(failed=1, errors=1)
    result.stdout.fnmatch_lines(["*ddenv(keep=...) names model(s) not in *open.yaml: *ball*"])
    assert summary_of(wall_project)["minimal_models"] == ["wall", "ball"]  # file order; ball kept on request


PID_TEST = (
    "import os\n"
    "import pytest\n"
    "@pytest.mark.ddenv(world='wall.yaml')\n"
    "@pytest.mark.robot_failure('stuck', window=2.0, min_progress=0.2)\n"
    "def test_reaches_goal(robot_world{fixture}):\n"
    "    with open('pids.txt', 'a') as pids:\n"
    "        pids.write(f'{{os.getpid()}}\\n')\n"
    "    assert robot_world.run().reached_goal\n"
)


@pytest.mark.slow  # pytest in a subprocess beside burners
@pytest.mark.parametrize("fixture", ["", ", tmp_path"])
def test_auto_on_a_busy_machine_runs_probes_here_unless_a_fixture_would_be_shared(
        wall_project: pytest.Pytester, fixture: str) -> None:
    wall_project.makepyfile(test_scenario=PID_TEST.format(fixture=fixture))
    with every_core_busy():
        result = wall_project.runpytest_subprocess("--ddenv-reduce", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    pids = (wall_project.path / "pids.txt").read_text().split()
    assert summary_of(wall_project)["minimal_models"] == ["wall"] and len(pids) > 3
    if fixture:  # tmp_path would be shared by probes in this process: one worker process runs them
        assert len(set(pids)) == 2 and "re-created" not in result.stdout.str()
    else:  # the test's own run and every probe in the pytest process (no worker to start per test)
        assert len(set(pids)) == 1
