"""Every kind of bad world file is a WorldError naming the file, the model and the field."""

from __future__ import annotations

from pathlib import Path

import pytest

from pytest_ddenv import DdenvError, World, WorldError

VALID_MODEL = "  - {name: box1, pose: [1, 2, 0.1], box: [0.2, 0.2, 0.2]}\n"


def load(tmp_path: Path, text: str, name: str = "bad.yaml") -> World:
    path = tmp_path / name
    path.write_text(text)
    return World.load(path)


def error_of(tmp_path: Path, text: str) -> WorldError:
    with pytest.raises(WorldError) as caught:
        load(tmp_path, text)
    assert isinstance(caught.value, DdenvError)
    assert "bad.yaml" in str(caught.value)
    return caught.value


def test_yaml_syntax_error_names_the_line(tmp_path: Path) -> None:
    error = error_of(tmp_path, "format: 1\nmodels:\n  - {name: a, box: [1, 1, 1]\n  - {name: b}\n")
    assert "YAML syntax error" in str(error)
    assert error.line == 4
    assert "bad.yaml:4" in str(error)


def test_unknown_top_level_key(tmp_path: Path) -> None:
    error = error_of(tmp_path, "format: 1\nmodles: []\n")
    assert "unknown key 'modles'" in str(error)
    assert "models" in str(error)  # lists what is expected


def test_missing_model_name(tmp_path: Path) -> None:
    error = error_of(tmp_path, "format: 1\nmodels:\n" + VALID_MODEL + "  - {box: [1, 1, 1]}\n")
    assert error.model == "#1" and error.field == "name"
    assert "model #1, field 'name': missing" in str(error)


def test_duplicate_model_name(tmp_path: Path) -> None:
    error = error_of(tmp_path, "format: 1\nmodels:\n" + VALID_MODEL + VALID_MODEL)
    assert "duplicate model name 'box1'" in str(error)
    assert error.model == "#1" and error.field == "name"


def test_unknown_shape_type(tmp_path: Path) -> None:
    error = error_of(tmp_path, "format: 1\nmodels:\n  - {name: torus1, shapes: [{torus: [1, 2]}]}\n")
    assert "model 'torus1' (#0)" in str(error)
    assert error.field == "shapes[0]"
    assert "unknown shape type 'torus'" in str(error) and "box, cylinder, sphere, mesh" in str(error)


@pytest.mark.parametrize(
    ("shape", "field"),
    [
        ("box: [0.2, 0, 0.2]", "box[1]"),
        ("box: [0.2, 0.2, -1]", "box[2]"),
        ("cylinder: {radius: 0, length: 1}", "cylinder.radius"),
        ("sphere: {radius: -0.5}", "sphere.radius"),
    ],
)
def test_zero_or_negative_size(tmp_path: Path, shape: str, field: str) -> None:
    error = error_of(tmp_path, f"format: 1\nmodels:\n  - {{name: m, {shape}}}\n")
    assert error.field == field
    assert "expected a positive number" in str(error)


@pytest.mark.parametrize("value", [".nan", ".inf", "-.inf"])
def test_nan_or_infinite_number(tmp_path: Path, value: str) -> None:
    error = error_of(tmp_path, f"format: 1\nmodels:\n  - {{name: m, pose: [0, {value}, 0], box: [1, 1, 1]}}\n")
    assert error.model == "'m' (#0)" and error.field == "pose[1]"
    assert "expected a finite number" in str(error)


def test_string_where_a_number_is_expected(tmp_path: Path) -> None:
    error = error_of(tmp_path, "format: 1\nmodels:\n  - {name: m, box: [1, 1, 1], mass: heavy}\n")
    assert error.field == "mass"
    assert "expected a number, got the string 'heavy'" in str(error)


def test_dynamic_model_without_positive_mass(tmp_path: Path) -> None:
    error = error_of(tmp_path, "format: 1\nmodels:\n  - {name: m, box: [1, 1, 1], static: false}\n")
    assert error.field == "mass"
    assert "dynamic model needs a positive mass" in str(error)
    error = error_of(tmp_path, "format: 1\nmodels:\n  - {name: m, box: [1, 1, 1], mass: 0, static: false}\n")
    assert "dynamic model needs a positive mass" in str(error)


def test_mesh_file_that_does_not_exist(tmp_path: Path) -> None:
    error = error_of(tmp_path, "format: 1\nmodels:\n  - {name: m, mesh: {file: meshes/barrel.stl}}\n")
    assert error.field == "mesh.file"
    assert "mesh file not found" in str(error)
    assert str(tmp_path / "meshes" / "barrel.stl") in str(error)


@pytest.mark.parametrize("version", ["2", "'1'", "0"])
def test_unknown_format_version(tmp_path: Path, version: str) -> None:
    error = error_of(tmp_path, f"format: {version}\nmodels: []\n")
    assert error.field == "format"
    assert "unknown format version" in str(error) and "supports 1" in str(error)


def test_missing_format_key(tmp_path: Path) -> None:
    error = error_of(tmp_path, "models: []\n")
    assert error.field == "format" and "missing" in str(error)


def test_missing_file_is_a_world_error(tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="cannot read world file"):
        World.load(tmp_path / "nowhere.yaml")


def test_world_without_reducible_models_is_valid(tmp_path: Path) -> None:
    world = load(tmp_path, "format: 1\nmodels: []\n", "empty.yaml")
    assert world.names == ()
    keep_only = load(tmp_path, "format: 1\nmodels:\n  - {name: a, box: [1, 1, 1], keep: true}\n", "keep.yaml")
    assert keep_only.reducible_names == ()


def test_select_and_without_reject_unknown_names(tmp_path: Path) -> None:
    world = load(tmp_path, "format: 1\nmodels:\n" + VALID_MODEL, "ok.yaml")
    with pytest.raises(WorldError, match="unknown model name.*'nope'.*the world has: box1"):
        world.select(["nope"])
    with pytest.raises(WorldError, match="'nope'"):
        world.without(["box1", "nope"])
