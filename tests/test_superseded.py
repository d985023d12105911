"""`driver.superseded`: which folders are a test's earlier reductions, and the mark in their summary.json."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pytest_ddenv.driver.artifacts import FolderLock, artifact_dir_name
from pytest_ddenv.driver.superseded import SUPERSEDED_REASON, earlier_reductions, mark_superseded

TEST = "tests/test_x.py::test_y[a-1]"


def _folder(root: Path, name: str, summary: object = None) -> Path:
    folder = root / name
    folder.mkdir()
    if summary is not None:
        (folder / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    return folder


def test_earlier_reductions_are_the_test_s_own_folders_of_any_seed_with_a_summary(tmp_path: Path) -> None:
    mine = [_folder(tmp_path, artifact_dir_name(TEST, seed), {"test": TEST}) for seed in (0, 7, -3)]
    _folder(tmp_path, artifact_dir_name(TEST, 9))  # no summary.json: nothing a user would read as a result
    _folder(tmp_path, artifact_dir_name(TEST + "x", 0), {})  # another test whose id starts the same
    _folder(tmp_path, artifact_dir_name(TEST, 0).replace("-seed0-", "-seed1-"), {})  # a digest of another id
    assert earlier_reductions(tmp_path, TEST) == sorted(mine)
    assert earlier_reductions(tmp_path / "missing", TEST) == []


def test_the_mark_is_added_once_and_nothing_else_changes(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "f", {"test": TEST, "minimal": ["wall"]})
    assert mark_superseded(folder)
    first = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    assert first["superseded"]["reason"] == SUPERSEDED_REASON
    assert {key: value for key, value in first.items() if key != "superseded"} == {"test": TEST, "minimal": ["wall"]}
    assert mark_superseded(folder)
    assert json.loads((folder / "summary.json").read_text(encoding="utf-8")) == first


@pytest.mark.parametrize("content", ["[1, 2]", "{not json", ""])
def test_a_summary_that_is_not_a_json_object_is_left_as_it_is(tmp_path: Path, content: str) -> None:
    folder = _folder(tmp_path, "f")
    (folder / "summary.json").write_text(content, encoding="utf-8")
    assert not mark_superseded(folder)
    assert (folder / "summary.json").read_text(encoding="utf-8") == content


def test_a_folder_another_reduction_holds_is_not_marked(tmp_path: Path) -> None:
    folder = _folder(tmp_path, "f", {"test": TEST})
    with FolderLock(folder):
        assert not mark_superseded(folder)
    assert "superseded" not in json.loads((folder / "summary.json").read_text(encoding="utf-8"))
