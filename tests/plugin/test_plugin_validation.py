"""Markers and options are validated eagerly with errors that say what and where."""

from __future__ import annotations

import os
from typing import Any

import pytest


@pytest.mark.parametrize(
    ("marker", "message"),
    [
        ("ddenv(world='wall.yaml', partition='kmeans')", "*unknown partition 'kmeans'; valid choices: *model2model*"),
        ("ddenv(world='wall.yaml', priority='nearest')", "*unknown priority 'nearest'; valid choices:*failure-proximal*"),
        ("ddenv(world='wall.yaml', colour=3)", "*unknown argument 'colour'; valid arguments: world, engine, partition*"),
        ("ddenv(world='wall.yaml', deflake=-1)", "*deflake=...*expected an integer >= 0 and <= 100 or one of*adaptive*"),
        ("ddenv(world='wall.yaml', budget='lots')", "*budget=...*expected a probe count*"),
        ("robot_failure('wobbly')", "*robot_failure('wobbly', ...)*wobbly*stuck*"),
        ("robot_failure('stuck', windw=3)", "*robot_failure('stuck', ...)*windw*"),
    ],
)
def test_bad_marker_is_a_usage_error_naming_the_test(wall_project: pytest.Pytester, marker: str, message: str) -> None:
    wall_project.makepyfile(test_scenario=(
        "import pytest\n"
        f"@pytest.mark.{marker}\n"
        "def test_robot(robot_world):\n"
        "    robot_world.run()\n"
    ))
    result = wall_project.runpytest_subprocess()
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["ERROR: test_scenario.py::test_robot: " + message])


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--ddenv-deflake", "many"], "*--ddenv-deflake: expected an integer >= 0 and <= 100 or one of adaptive*"),
        (["--ddenv-max-probes", "0"], "*--ddenv-max-probes: expected an integer >= 1, got '0'*"),
        (["--ddenv-max-time", "soon"], "*--ddenv-max-time: expected a positive, finite number of seconds*"),
        (["--ddenv-max-time", "nan"], "*--ddenv-max-time: expected a positive, finite number of seconds, got 'nan'"),
        (["--ddenv-max-time", "inf"], "*--ddenv-max-time: expected a positive, finite number of seconds, got 'inf'"),
        (["--ddenv-max-time", "-5"], "*--ddenv-max-time: expected a positive, finite number of seconds, got '-5'"),
        (["--ddenv-executor", "tcp://scheduler"], ("*--ddenv-executor: expected 'local', 'dask' or a dask scheduler "
                                                   "address tcp://HOST:PORT*got 'tcp://scheduler'")),
        (["--ddenv-workers", "two"], "*--ddenv-workers: expected an integer >= 1*"),
        (["--ddenv-world", "nowhere.yaml"], "*--ddenv-world: no such file: nowhere.yaml*"),
    ],
)
def test_bad_option_is_a_usage_error(pytester: pytest.Pytester, option: list[str], message: str) -> None:
    pytester.makepyfile("def test_ok():\n    pass\n")
    result = pytester.runpytest_subprocess(*option)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([message])


def test_ini_errors_name_the_ini_key(pytester: pytest.Pytester) -> None:
    pytester.makeini("[pytest]\nddenv_max_probes = zero\n")
    pytester.makepyfile("def test_ok():\n    pass\n")
    result = pytester.runpytest_subprocess()
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["ERROR: ddenv_max_probes in tox.ini: expected an integer >= 1, got 'zero'"])
    result = pytester.runpytest_subprocess("--ddenv-max-probes", "0")  # the command line wins, and is named
    result.stderr.fnmatch_lines(["ERROR: --ddenv-max-probes: expected an integer >= 1, got '0'"])


def test_a_bad_ini_boolean_is_a_usage_error_before_any_test_runs(pytester: pytest.Pytester) -> None:
    pytester.makeini("[pytest]\nddenv_reduce = maybe\n")
    pytester.makepyfile("def test_fails():\n    assert False\n")
    result = pytester.runpytest_subprocess()
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["ERROR: ddenv_reduce in tox.ini: expected true or false*invalid truth value 'maybe'"])
    assert "test_fails" not in result.stdout.str()


def test_options_are_listed_in_help(pytester: pytest.Pytester) -> None:
    result = pytester.runpytest_subprocess("--help")
    result.stdout.fnmatch_lines(["robot world reduction (pytest-ddenv):", "*--ddenv-reduce*", "*--ddenv-world=PATH*"])


def test_missing_world_is_a_clear_error(pytester: pytest.Pytester) -> None:
    pytester.makepyfile("def test_robot(robot_world):\n    pass\n")
    result = pytester.runpytest_subprocess()
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(["*robot_world needs a world: @pytest.mark.ddenv(world=*"])


@pytest.mark.parametrize(("make", "message"), [
    pytest.param(lambda path: os.mkfifo(path), "*not a world file: *world.yaml is a FIFO (named pipe)*", id="fifo"),
    pytest.param(lambda path: path.symlink_to(path.name), "*not a world file: *world.yaml is a loop of symbolic links*",
                 id="loop"),
])
def test_a_world_marker_naming_what_is_not_a_file_says_what_it_is(pytester: pytest.Pytester, make: Any,
                                                                   message: str) -> None:
    make(pytester.path / "world.yaml")
    pytester.makepyfile("import pytest\n\n@pytest.mark.ddenv(world='world.yaml')\n"
                        "def test_robot(robot_world):\n    pass\n")
    result = pytester.runpytest_subprocess()
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines([message])


@pytest.mark.parametrize(
    ("marker", "message"),
    [
        ("robot_failure.with_args(Pressed)", "*Pressed is a class; pass an instance, e.g. Pressed(...)*"),
        ("robot_failure(3)", "*robot_failure(3, ...)*3 is not a failure predicate: expected a registered name*"),
        ("robot_failure(Pressed(), window=2)", "*parameters window are only for a predicate given by name*"),
    ],
)
def test_a_marker_that_holds_no_predicate_is_a_usage_error(wall_project: pytest.Pytester, marker: str,
                                                          message: str) -> None:
    wall_project.makepyfile(test_scenario=(
        "import pytest\n"
        "class Pressed:\n"
        "    name = 'pressed'\n"
        "    def reset(self): pass\n"
        "    def check(self, state): return None\n"
        f"@pytest.mark.ddenv(world='wall.yaml')\n@pytest.mark.{marker}\n"
        "def test_robot(robot_world):\n"
        "    robot_world.run()\n"
    ))
    result = wall_project.runpytest_subprocess()
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["ERROR: test_scenario.py::test_robot: " + message])


_ON_SLOPE = (
    "class OnSlope:\n"
    "    name = 'on_slope'\n"
    "    def __init__(self{init}):\n"
    "        pass\n"
    "    def reset(self): pass\n"
    "    def check(self, state): return None\n"
)


@pytest.mark.parametrize(
    ("definition", "marker", "message"),
    [
        (_ON_SLOPE.format(init=", max_pitch=0.3"), "robot_failure(OnSlope)",
         "*robot_failure(OnSlope): OnSlope is a class, not a predicate*pass an instance: robot_failure(OnSlope())"),
        (_ON_SLOPE.format(init=""), "robot_failure(OnSlope)",  # OnSlope(test) raises TypeError on import
         "*robot_failure(OnSlope): OnSlope is a class, not a predicate*pass an instance: robot_failure(OnSlope())"),
        ("def tipped(state):\n    return state.time > 3\n", "robot_failure(tipped)",  # AttributeError on import
         "*robot_failure(tipped): pytest takes a function given alone*@predicate*robot_failure.with_args(tipped)"),
        ("def tipped(state):\n    return None\n", "robot_failure(tipped)",  # the test silently became None
         "*robot_failure(tipped): pytest takes a function given alone*@predicate*robot_failure.with_args(tipped)"),
    ],
    ids=["class-with-defaults", "class-without-parameters", "function-raising", "function-returning-none"],
)
def test_a_predicate_given_alone_is_a_usage_error_naming_the_test(pytester: pytest.Pytester, definition: str,
                                                                  marker: str, message: str) -> None:
    """pytest takes a lone class or function given to a marker for the thing to mark: the test is lost (or
    the module fails to import with the predicate's own error). It must stop pytest, naming the test."""
    pytester.makepyfile(test_scenario=(
        f"import pytest\n{definition}"
        f"@pytest.mark.ddenv(world='wall.yaml')\n@pytest.mark.{marker}\n"
        "def test_robot(robot_world):\n"
        "    robot_world.run()\n"
        "def test_other():\n"
        "    pass\n"
    ))
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["ERROR: test_scenario.py::test_robot: " + message])
    assert "AttributeError" not in result.stdout.str() + result.stderr.str()


def test_a_plain_function_predicate_is_given_with_with_args(wall_project: pytest.Pytester) -> None:
    wall_project.makepyfile(test_scenario=(
        "import pytest\n"
        "def pressed(state):\n"
        "    return bool(state.chassis_contacts)\n"
        "@pytest.mark.ddenv(world='wall.yaml')\n"
        "@pytest.mark.robot_failure.with_args(pressed)\n"
        "def test_robot(robot_world):\n"
        "    robot_world.run()\n"
    ))
    result = wall_project.runpytest_subprocess()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*RobotFailure: The 'pressed' predicate fired*touching wall*"])


@pytest.mark.slow  # a real reduction in a subprocess: the full tier only
def test_ci_logs_get_progress_lines_and_relative_artifacts_follow_the_invocation_folder(
        wall_project: pytest.Pytester) -> None:
    """Not a terminal (a CI log): a line per accepted step. The tests live in suite/ with their own ini file,
    which makes suite/ pytest's rootdir; a relative --ddenv-artifacts is still relative to where pytest runs."""
    suite = wall_project.mkdir("suite")
    for name in ("wall.yaml", "test_scenario.py"):
        (wall_project.path / name).rename(suite / name)
    (suite / "pytest.ini").write_text("[pytest]\n", encoding="utf-8")
    result = wall_project.runpytest_subprocess("suite/test_scenario.py", "--ddenv-reduce", "--ddenv-artifacts",
                                               "out", "-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["ddenv: reducing test_reaches_goal: 6 models, 0 probes, * s (start)",
                                 "ddenv: reducing test_reaches_goal: * models, * probes, * s (step)",
                                 "ddenv: reducing test_reaches_goal: 1 model, * probes, * s (models done)"])
    assert (wall_project.path / "out").is_dir() and not (suite / "out").exists()
    assert list((wall_project.path / "out").glob("*/minimal.yaml"))
