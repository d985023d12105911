"""A robot test that passes after an edit: the folder of its earlier reduction is marked superseded, never
deleted, and a later failure resumes its log as before."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from .conftest import WALL_WORLD

pytestmark = pytest.mark.slow

WALL = "  - {name: wall, pose: [2.0, 0, 0.5], box: [0.3, 4.0, 1.0]}\n"


def _summary(project: pytest.Pytester) -> tuple[Path, dict[str, object]]:
    [folder] = (project.path / "ddenv-artifacts").iterdir()
    return folder, json.loads((folder / "summary.json").read_text(encoding="utf-8"))


def test_a_test_that_passes_now_marks_its_earlier_reduction_and_a_later_failure_resumes(
        wall_project: pytest.Pytester) -> None:
    wall_project.runpytest_subprocess("--ddenv-reduce").assert_outcomes(failed=1)
    folder, before = _summary(wall_project)
    assert "superseded" not in before

    assert WALL in WALL_WORLD
    wall_project.makefile(".yaml", wall=WALL_WORLD.replace(WALL, ""))  # the wall is gone: the test passes now
    passed = wall_project.runpytest_subprocess("--ddenv-reduce")
    passed.assert_outcomes(passed=1)
    passed.stdout.fnmatch_lines([
        "*ddenv reductions*",
        (f"test_scenario.py::test_reaches_goal: passes now; the earlier reduction in *{folder.name} (of earlier "
         "code or an earlier world) marked superseded in summary.json"),
    ])
    _, marked = _summary(wall_project)
    superseded = marked.pop("superseded")
    assert isinstance(superseded, dict) and superseded["reason"].startswith("the test passed in a later session")
    assert marked == before  # nothing else of the earlier reduction changed
    assert (folder / "minimal.yaml").is_file() and (folder / "runs.jsonl").is_file()

    wall_project.makefile(".yaml", wall=WALL_WORLD)  # the wall is back: the earlier log resumes
    again = wall_project.runpytest_subprocess("--ddenv-reduce")
    again.assert_outcomes(failed=1)
    again.stdout.fnmatch_lines(["*probes: * decided (* in earlier runs)*"])
    _, resumed = _summary(wall_project)
    assert "superseded" not in resumed
    assert resumed["minimal_models"] == before["minimal_models"] == ["wall"]
