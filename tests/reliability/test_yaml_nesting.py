"""The nesting limit's message is the package's own whatever PyYAML is installed: PyYAML 6.0.4's libyaml refuses
nesting beyond 1000 levels while it scans ahead, before the reader has counted 64 (issue 27, point 7)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from pytest_ddenv import World, WorldError
from pytest_ddenv.world._bounded_yaml import MAX_DEPTH, load_document

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("depth", [MAX_DEPTH + 1, 999, 1000, 1001, 100_000])
@pytest.mark.parametrize(("opening", "inner", "closing", "field"), [
    ("[", "1", "]", "models[0][0][0]...[0][0]"),
    ("{a: ", "1", "}", "models.a.a.a....a.a"),
])
def test_nesting_on_one_line_gets_the_packages_message_at_any_depth(depth: int, opening: str, inner: str,
                                                                    closing: str, field: str) -> None:
    text = "format: 1\nmodels: " + opening * depth + inner + closing * depth + "\n"
    with pytest.raises(WorldError) as raised:
        load_document(text, "deep.yaml")
    assert str(raised.value) == f"deep.yaml:2, field '{field}': lists and mappings nested more than {MAX_DEPTH} deep"


def test_nesting_over_lines_gets_the_packages_message() -> None:
    text = "format: 1\nmodels:\n" + "".join(f"{'  ' * level}- \n" for level in range(2000)) + "  " * 2000 + "- 1\n"
    with pytest.raises(WorldError, match=rf"^deep.yaml:{MAX_DEPTH + 2}, field 'models\[0\].*nested more than 64"):
        load_document(text, "deep.yaml")


@pytest.mark.parametrize("path", sorted([*(ROOT / "worlds").glob("*.yaml"), *(ROOT / "examples").rglob("*.yaml")]),
                         ids=lambda path: path.name)
def test_both_readers_read_a_world_file_alike(path: Path) -> None:
    """The pure-Python reader (used again when libyaml refuses the nesting) resolves as the C one does."""
    from pytest_ddenv.world._bounded_yaml import _Loader, _PythonLoader

    text = path.read_text(encoding="utf-8")
    assert yaml.load(text, Loader=_PythonLoader) == yaml.load(text, Loader=_Loader)


def test_both_readers_read_numbers_with_an_exponent_as_numbers() -> None:
    from pytest_ddenv.world._bounded_yaml import _Loader, _PythonLoader

    text = "a: 1e3\nb: 2.5E-3\nc: '1e3'\nd: 12\n"
    expected = {"a": 1000.0, "b": 0.0025, "c": "1e3", "d": 12}
    assert yaml.load(text, Loader=_PythonLoader) == yaml.load(text, Loader=_Loader) == expected


def test_a_world_file_nested_deeper_than_libyaml_allows_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "deep.yaml"
    path.write_text("format: 1\nmodels: " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    with pytest.raises(WorldError, match=r"deep.yaml:2, field 'models\[0\]\[0\]\[0\]\.\.\.\[0\]\[0\]': lists and "
                                         r"mappings nested more than 64 deep"):
        World.load(path)


def test_nesting_after_other_models_and_wide_characters_names_its_line() -> None:
    """The pure-Python parser reads only up to where libyaml stopped: the limit is found there, past models
    and names of characters that take several bytes in UTF-8."""
    models = "".join(f"  - {{name: kiste_{i}_äöü_箱, pose: [{i}, 0, 0.5], box: [0.3, 4, 1]}}\n" for i in range(500))
    text = "format: 1\nmodels:\n" + models + "  - " + "[" * 2000 + "]" * 2000 + "\n"
    with pytest.raises(WorldError) as raised:
        load_document(text, "deep.yaml")
    assert str(raised.value) == (f"deep.yaml:{3 + 500}, field 'models[500][0][0]...[0][0]': lists and mappings "
                                 f"nested more than {MAX_DEPTH} deep")
