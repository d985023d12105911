"""What identifies the code under test (`code_identity`), the problem a run log belongs to (`problem`), and
when a log is resumed (`artifacts.prepare`, `driver.same_reference`)."""

from __future__ import annotations

import importlib
import json
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from engines import installed

from pytest_ddenv import World
from pytest_ddenv.driver import artifacts
from pytest_ddenv.driver.code_identity import CodeIdentity, collected_elsewhere, identify, scripts_beside
from pytest_ddenv.driver.run import same_reference
from pytest_ddenv.oracle.predicates import FailureSignature
from pytest_ddenv.scenario.probe import FailureReference
from pytest_ddenv.driver.problem import problem_of

WORLD = World.from_yaml("format: 1\nmodels:\n  - {name: wall, pose: [2, 0, 0.5], box: [0.3, 4, 1]}\n")


@pytest.fixture
def project(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A project folder on sys.path; the modules imported from it are forgotten afterwards."""
    root = tmp_path / "project"
    root.mkdir()
    monkeypatch.syspath_prepend(str(root))
    before = set(sys.modules)
    yield root
    for name in set(sys.modules) - before:
        del sys.modules[name]


def load(root: Path, files: dict[str, str], *names: str) -> None:
    for name, text in files.items():
        (root / name).write_text(text)
    importlib.invalidate_caches()
    for name in names:
        importlib.import_module(name)


def test_the_project_files_loaded_are_identified_by_content_and_installed_packages_by_version(project: Path) -> None:
    load(project, {"ctl_a.py": "import numpy\nGAIN = 1.0\n"}, "ctl_a")
    identity = identify([project])
    assert set(identity.files) == {"ctl_a.py"}, "installed code (pytest, numpy, pytest_ddenv) is not a project file"
    assert {"numpy", "pytest-ddenv", "python"} <= set(identity.packages)
    assert ("pybullet" in identity.packages) == installed("pybullet"), "pybullet's version, where it is installed"
    (project / "ctl_a.py").write_text("import numpy\nGAIN = 2.0\n")
    edited = identify([project])
    assert edited.files["ctl_a.py"] != identity.files["ctl_a.py"]
    assert edited.changes_since(identity) == ["ctl_a.py (edited)"]
    assert identify([project]) == edited, "the same files give the same identity"


def test_excluded_files_are_left_out_unless_an_included_file_imports_them(project: Path) -> None:
    load(project, {"helper_b.py": "X = 1\n", "test_other_c.py": "Y = 2\n",
                   "test_mine_d.py": "from helper_b import X\nimport test_shared_e\n", "test_shared_e.py": "Z = 3\n"},
         "helper_b", "test_other_c", "test_shared_e", "test_mine_d")
    others = {project / "test_other_c.py", project / "test_shared_e.py"}
    identity = identify([project], exclude=others)
    assert set(identity.files) == {"helper_b.py", "test_mine_d.py", "test_shared_e.py"}


def test_other_test_files_and_conftests_of_other_folders_cannot_matter(tmp_path: Path) -> None:
    test_file = tmp_path / "tests" / "robots" / "test_mine.py"
    collected = [test_file, tmp_path / "tests" / "test_other.py"]
    elsewhere = collected_elsewhere(test_file, collected)
    assert test_file.resolve() not in elsewhere and (tmp_path / "tests" / "test_other.py").resolve() in elsewhere


def test_the_scripts_beside_the_test_file_are_code_under_test_but_not_its_test_files(tmp_path: Path) -> None:
    """A simulator the test runs as a program (`subprocess`) is never imported: it is taken by content."""
    for name in ("test_rover.py", "rover_sim.py", "conftest.py", "helper.py", "other_test.py"):
        (tmp_path / name).write_text("X = 1\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "deeper.py").write_text("X = 1\n")
    found = scripts_beside(tmp_path / "test_rover.py", ["test_*.py", "*_test.py"])
    assert [path.name for path in found] == ["helper.py", "rover_sim.py"]


def test_data_files_are_identified_by_content(project: Path) -> None:
    mesh = project / "rock.obj"
    mesh.write_text("v 0 0 0\n")
    first = identify([project], data_files=[mesh])
    mesh.write_text("v 0 0 1\n")
    assert identify([project], data_files=[mesh]).changes_since(first) == ["rock.obj (edited)"]


def test_a_recorded_identity_reads_back_and_a_malformed_one_is_none() -> None:
    identity = CodeIdentity({"a.py": "00ff"}, {"numpy": "2.0"})
    assert CodeIdentity.from_json(json.loads(json.dumps(identity.to_json()))) == identity
    for bad in (None, [], {"files": {"a.py": 1}, "packages": {}}, {"files": {}}):
        assert CodeIdentity.from_json(bad) is None
    newer = CodeIdentity({"b.py": "11"}, {"numpy": "2.1"})
    assert newer.changes_since(identity) == ["a.py (no longer imported)", "b.py (new)", "numpy 2.0 -> 2.1"]


def test_the_problem_says_what_changed() -> None:
    code = CodeIdentity({"ctl.py": "01"}, {"python": "3.11.7"})
    problem = problem_of(WORLD, {"deflake": 1}, "def test(): ...", code)
    assert problem.differences(problem.header()) == []
    edited = problem_of(WORLD, {"deflake": 1}, "def test(): ...", CodeIdentity({"ctl.py": "02"}, code.packages))
    assert edited.differences(problem.header()) == ["the code under test changed: ctl.py (edited)"]
    assert edited.fingerprint != problem.fingerprint
    other = problem_of(WORLD.without(["wall"]), {"deflake": 3}, "def test(): ...", code)
    assert other.differences(problem.header()) == ["the world changed", "the reduction settings changed"]


STUCK_AT_WALL = FailureSignature("stuck", 6.2, (2.3, 0.8, 0.15, 0.0, 0.0, 0.2), ("left_wall",))


def reference(signature: FailureSignature | None = STUCK_AT_WALL) -> FailureReference:
    return FailureReference("RobotFailure", "test_walls.py:21", signature)


def test_a_logged_reference_is_the_same_failure_only_under_the_same_failure_rule() -> None:
    logged = reference().to_dict()
    assert same_reference(logged, reference(), 0.3)
    moved = FailureSignature("stuck", 6.2, (2.3, -0.8, 0.15, 0.0, 0.0, -0.2), ("right_wall",))
    assert not same_reference(logged, reference(moved), 0.3)
    untouched = FailureSignature("stuck", 6.2, STUCK_AT_WALL.pose, ())
    assert not same_reference(logged, reference(untouched), 0.3), "the rule both ways: touching nothing now"
    assert not same_reference(reference(untouched).to_dict(), reference(), 0.3)
    assert not same_reference({"exception_type": 1}, reference(), 0.3), "malformed: not the same"
    raised = FailureReference("TypeError", "test_walls.py:21")
    assert same_reference(raised.to_dict(), raised, 0.3)
    assert not same_reference(raised.to_dict(), FailureReference("TypeError", "test_walls.py:22"), 0.3)


def test_a_log_is_resumed_only_for_the_same_problem_and_failure(tmp_path: Path) -> None:
    problem = problem_of(WORLD, {}, "", CodeIdentity(), reference=reference().to_dict())
    paths, notes = artifacts.prepare(tmp_path, problem)
    assert notes == [] and json.loads(paths.log.read_text())["reference"] == reference().to_dict()
    with paths.log.open("a") as log:
        log.write('{"event": "session"}\n')
    assert artifacts.prepare(tmp_path, problem, same_reference=lambda logged: True) == (paths, [])
    assert len(paths.log.read_text().splitlines()) == 2, "resumed: the log kept"
    _, notes = artifacts.prepare(tmp_path, problem, same_reference=lambda logged: False)
    assert notes == ["the run log of another problem (it reduced another failure) was kept as runs.previous-1.jsonl; "
                     "this reduction starts a new runs.jsonl"]
    edited = problem_of(WORLD, {}, "", CodeIdentity({"ctl.py": "02"}, {}), reference=reference().to_dict())
    _, notes = artifacts.prepare(tmp_path, edited)
    assert notes == ["the run log of another problem (the code under test changed: ctl.py (new)) was kept as "
                     "runs.previous-2.jsonl; this reduction starts a new runs.jsonl"]
