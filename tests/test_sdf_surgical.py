"""Surgical export: minimal.sdf of an SDF-born world is the user's file with the removed models (and their
<state> entries) cut out, nothing else changed, and it imports as exactly the minimal world."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from pytest_ddenv import World
from pytest_ddenv.artifacts import write_minimal_sdf
from pytest_ddenv.sdf import SurgeryError, cut_models, parse_sdf

DATA = Path(__file__).resolve().parent / "data" / "sdf"
WORLD = DATA / "corpus" / "surgical.world"
MODELS = [str(DATA / "models")]


@pytest.fixture(scope="module")
def world() -> World:
    return World.load(WORLD, model_paths=MODELS)


def removed_lines(original: str, cut: str) -> list[str]:
    """The lines of `original` that are not in `cut`, checking that `cut` is `original` minus whole lines."""
    kept = iter(cut.splitlines())
    gone = []
    current = next(kept, None)
    for line in original.splitlines():
        if line == current:
            current = next(kept, None)
        else:
            gone.append(line.strip())
    assert current is None, "the cut file has a line the original does not have"
    return gone


def test_the_world_imports_with_its_models(world: World) -> None:
    assert world.names == ("block_left", "block_right", "crate", "shelf", "label_on_shelf")


def test_cutting_removes_the_models_and_their_state_and_nothing_else(world: World) -> None:
    original = WORLD.read_text()
    cut = cut_models(WORLD, {"block_right", "crate"}, model_paths=MODELS)
    gone = removed_lines(original, cut)
    assert gone[0] == "<include>" and "<name>block_right</name>" in gone and gone[4] == "</include>"
    assert '<model name="crate"><pose>4 0 0.25 0 0 0.3</pose>' in gone
    assert '<plugin filename="libcrate_tracker.so" name="tracker"/>' in gone  # the crate's own plugin goes too
    assert '<model name="crate"><pose>4 0 0.25 0 0 0.3</pose><scale>1 1 1</scale>' in gone  # its <state>
    assert not [line for line in gone if "block_left" in line or "shelf" in line or "lamp" in line]
    for kept in ("<!-- the aisle -->", "--", "<gui fullscreen", "libgazebo_ros_state.so", "model://sun",
                 "<uri>model://static_block</uri>", 'name="aisle_lamp"', "<physics name=\"1ms\""):
        assert kept in cut
    assert "Gazebo/Wood" not in cut  # the crate's material went with it


def test_the_cut_file_imports_as_the_minimal_world(world: World) -> None:
    cut = cut_models(WORLD, {"block_right", "crate"}, model_paths=MODELS)
    reread = parse_sdf(cut, source=WORLD, model_paths=MODELS)
    assert reread.models == world.without(["block_right", "crate"]).models


def test_write_minimal_sdf_cuts_when_the_result_is_exactly_the_minimal_world(world: World, tmp_path: Path) -> None:
    minimal = world.without(["block_right", "crate"])
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, minimal, ("block_right", "crate"), MODELS)
    assert how == f"cut from {WORLD}"
    assert (tmp_path / "minimal.sdf").read_text() == cut_models(WORLD, {"block_right", "crate"}, model_paths=MODELS)


def test_a_kept_model_placed_relative_to_a_removed_one_is_regenerated_with_the_reason(world: World,
                                                                                       tmp_path: Path) -> None:
    minimal = world.without(["shelf"])
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, minimal, ("shelf",), MODELS)
    assert how is not None and how.startswith("regenerated: the cut file does not load") and "shelf" in how
    assert World.load(tmp_path / "minimal.sdf").names == minimal.names  # the regenerated one is complete


def test_a_yaml_born_world_is_regenerated(tmp_path: Path) -> None:
    world = World.from_yaml("format: 1\nmodels:\n  - {name: box, pose: [0, 0, 0.5], box: [1, 1, 1]}\n",
                            source=str(tmp_path / "w.yaml"))
    assert write_minimal_sdf(tmp_path / "minimal.sdf", world, world, (), ()) == "regenerated"


def test_a_name_that_is_not_a_top_level_model_is_refused() -> None:
    with pytest.raises(SurgeryError, match="no top-level element for model"):
        cut_models(WORLD, {"nothing_by_that_name"}, model_paths=MODELS)


def test_an_include_that_no_longer_resolves_is_refused(tmp_path: Path) -> None:
    with pytest.raises(SurgeryError, match="cannot resolve an include again"):
        cut_models(WORLD, {"crate"}, model_paths=())


def test_a_copy_of_the_minimal_world_next_to_the_original_opens_there(world: World, tmp_path: Path) -> None:
    cut = cut_models(WORLD, {"crate"}, model_paths=MODELS)
    beside = WORLD.with_name("_minimal_surgical_test.world")
    beside.write_text(cut)
    try:
        reloaded = World.load(beside, model_paths=MODELS)
    finally:
        beside.unlink()
    assert dataclasses.replace(reloaded, source=None).models == world.without(["crate"]).models


def test_the_documented_scenario_block_loads() -> None:
    import re

    text = (Path(__file__).resolve().parent.parent / "docs" / "sdf.md").read_text()
    (block,) = re.findall(r"```xml\n(.*?)```", text, flags=re.DOTALL)
    world = parse_sdf(block, source="docs/sdf.md")
    assert world.scenario is not None and world.scenario.robot == "husky"
    assert world.scenario.goal == (8.0, 2.0, None) and world.scenario.timeout == 60.0
    assert world.scenario.goal_tolerance == 0.5 and len(world) == 0
