"""`--ddenv-stages`, ini `ddenv_stages` and the marker's `stages=`: what runs after the model-level reduction."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # real reductions (subprocesses, simulations): the full tier only


def summary_of(pytester: pytest.Pytester) -> dict:
    (summary,) = Path(pytester.path, "ddenv-artifacts").glob("*/summary.json")
    return json.loads(summary.read_text())


def test_models_only_is_the_model_level_reduction_alone(wall_project: pytest.Pytester) -> None:
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-stages", "models")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*reduced 6 -> 1 models*"])
    result.stdout.no_fnmatch_line("*stage *")
    summary = summary_of(wall_project)
    assert "stages" not in summary and summary["minimal_models"] == ["wall"]
    folder = Path(summary["files"]["summary"]).parent
    assert sorted(p.name for p in folder.glob("*.yaml")) == ["minimal.yaml"]
    assert not any("stage" in json.loads(line) for line in (folder / "runs.jsonl").read_text().splitlines())


def test_default_stages_report_the_culprit_and_the_passing_world(wall_project: pytest.Pytester) -> None:
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "-o", "junit_logging=system-out",
                                               "--junitxml=junit.xml")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*stage explain (0 simulations):*", "*without wall: passes*",
                                 "*stage passing (0 simulations):*", "*nearest passing world: without wall*"])
    summary = summary_of(wall_project)
    folder = Path(summary["files"]["summary"]).parent
    assert (folder / "passing.yaml").exists()
    assert f"[[ATTACHMENT|{folder / 'passing.yaml'}]]" in (wall_project.path / "junit.xml").read_text()


def test_the_marker_chooses_stages_and_the_command_line_overrides_it(wall_project: pytest.Pytester) -> None:
    test = (wall_project.path / "test_scenario.py").read_text().replace('deflake=1)', 'deflake=1, stages="models,time")')
    (wall_project.path / "test_scenario.py").write_text(test)
    result = wall_project.runpytest_subprocess("--ddenv-reduce")
    result.stdout.fnmatch_lines(["*stage time (*", "*time limit 20 s -> *"])
    assert summary_of(wall_project)["stages"]["stages"] == ["models", "time"]
    result = wall_project.runpytest_subprocess("--ddenv-reduce", "--ddenv-stages", "models,explain")
    assert summary_of(wall_project)["stages"]["stages"] == ["models", "explain"]


@pytest.mark.parametrize(("where", "args", "message"), [
    ("option", ("--ddenv-stages", "models,shape"),
     "*--ddenv-stages: unknown stage 'shape'; valid stages: models, shapes, attributes, time, explain, passing*"),
    ("ini", ("-o", "ddenv_stages=everything"), "*ddenv_stages*unknown stage 'everything'*"),
    ("option", ("--ddenv-stage-probes", "0"), "*--ddenv-stage-probes: expected an integer >= 1, got '0'*"),
])
def test_bad_stage_settings_are_usage_errors(wall_project: pytest.Pytester, where: str, args: tuple[str, ...],
                                             message: str) -> None:
    result = wall_project.runpytest_subprocess("--ddenv-reduce", *args)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines([message])


def test_a_bad_stages_marker_argument_names_the_test(wall_project: pytest.Pytester) -> None:
    test = (wall_project.path / "test_scenario.py").read_text().replace('deflake=1)', 'deflake=1, stages=["models", 3])')
    (wall_project.path / "test_scenario.py").write_text(test)
    result = wall_project.runpytest_subprocess("--ddenv-reduce")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*test_reaches_goal*ddenv(stages=...)*"])
