"""Surgical export: minimal.sdf of an SDF-born world is the user's file with the removed models (and their
<state> entries) cut out, nothing else changed, and it imports as exactly the minimal world."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from pytest_ddenv import World
from pytest_ddenv.driver.artifacts import write_minimal_sdf
from pytest_ddenv.sdf import SurgeryError, cut_models, parse_sdf
from pytest_ddenv.sdf._surgical import cut_file
from pytest_ddenv.world import Physics, Pose, Scenario

DATA = Path(__file__).resolve().parent / "data" / "sdf"
WORLD = DATA / "corpus" / "surgical.world"
MODELS = [str(DATA / "models")]
CORPUS = DATA / "corpus"


@pytest.fixture(autouse=True)
def no_fuel_cache(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("GZ_FUEL_CACHE_PATH", str(tmp_path / "empty-fuel-cache"))  # whatever this machine caches


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
    assert how == ("regenerated: the pose of the world's <model name=\"label_on_shelf\"> is relative_to the removed "
                   "model shelf; the cut file would not load")
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


# -- the reviewer's findings (issue 15, point 6) -------------------------------------------------------------
def test_a_world_with_fuel_includes_and_an_actor_is_cut_not_regenerated(tmp_path: Path) -> None:
    path = CORPUS / "surgical_fuel.world"
    world = World.load(path, model_paths=MODELS, skip_unsupported=True)
    assert world.names == ("wall", "block", "post")
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, world.without(["post", "block"]), ("post", "block"),
                            MODELS)
    assert how == f"cut from {path}"
    cut = (tmp_path / "minimal.sdf").read_text()
    gone = removed_lines(path.read_text(), cut)
    assert "<name>block</name>" in gone and not [line for line in gone if "fuel" in line or "walker" in line]
    assert "Construction Cone" in cut and "Construction Barrel" in cut and '<actor name="walker">' in cut


def test_state_entries_are_cut_by_their_own_names_when_insertions_come_first(tmp_path: Path) -> None:
    path = CORPUS / "surgical_insertions.world"
    world = World.load(path, model_paths=MODELS)
    assert world.model("box_a").pose.y == 4.0  # the state's pose, not the model's
    for removed in ("box_a", "box_b", "box_c"):
        cut = cut_models(path, {removed}, model_paths=MODELS)
        assert f'"{removed}"' not in cut
        assert parse_sdf(cut, source=path, model_paths=MODELS) == world.without([removed])
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, world.without(["box_b"]), ("box_b",), MODELS)
    assert how == f"cut from {path}"


@pytest.mark.parametrize(("element", "says"), [
    ('<frame name="dock" attached_to="rack"/>',
     "the world's <frame name=\"dock\"> is attached_to the removed model rack"),
    ('<frame name="dock" attached_to="rack::board"/>', "is attached_to the removed model rack"),
    ('<frame name="dock"><pose relative_to="rack::board">0 0 0 0 0 0</pose></frame>',
     "the pose of the world's <frame name=\"dock\"> is relative_to the removed model rack"),
    ('<light name="lamp" type="point"><pose relative_to="rack">0 0 1 0 0 0</pose></light>',
     "the pose of the world's <light name=\"lamp\"> is relative_to the removed model rack"),
    ('<joint name="j" type="fixed"><parent>world</parent><child>rack::board</child></joint>',
     "the world's <joint name=\"j\"> has the removed model rack as its <child>"),
])
def test_a_kept_element_that_names_a_removed_model_is_refused(tmp_path: Path, element: str, says: str) -> None:
    path = tmp_path / "dock.world"
    path.write_text(f'''<sdf version="1.8"><world name="w">
  <model name="rack"><static>true</static><link name="board"><collision name="c"><geometry><box><size>1 1 1</size>
  </box></geometry></collision></link></model>
  {element}
  <model name="crate"><static>true</static><pose>3 0 0.5 0 0 0</pose><link name="l"><collision name="c"><geometry>
  <box><size>1 1 1</size></box></geometry></collision></link></model>
</world></sdf>
''')
    with pytest.raises(SurgeryError, match="the cut file would not load") as raised:
        cut_models(path, {"rack"})
    assert says in raised.value.reason
    assert '"crate"' not in cut_models(path, {"crate"})  # a model no element names is cut as usual


def test_a_frame_attached_to_a_removed_model_gives_the_regenerated_export_with_the_reason(tmp_path: Path) -> None:
    path = CORPUS / "surgical_frames.world"
    world = World.load(path)
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, world.without(["rack"]), ("rack",), ())
    assert how == ("regenerated: the world's <frame name=\"dock\"> is attached_to the removed model rack; the cut "
                   "file would not load")
    assert World.load(tmp_path / "minimal.sdf").names == ("bin", "crate", "hill")


def test_the_cut_file_must_give_the_whole_minimal_world_not_only_its_models(world: World, tmp_path: Path) -> None:
    minimal = dataclasses.replace(world.without(["crate"]), physics=Physics(timestep=0.002))
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, minimal, ("crate",), MODELS)
    assert how == "regenerated: the cut file does not give the minimal world (its physics differ)"


GIVEN = Scenario(robot="husky", start=Pose(x=-1.0, y=0.5, yaw=0.25), goal=(7.0, 0.0, None), timeout=12.0)


def test_a_scenario_given_outside_the_file_is_written_into_the_cut_file(world: World, tmp_path: Path) -> None:
    minimal = dataclasses.replace(world.without(["crate"]), scenario=GIVEN)
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, minimal, ("crate",), MODELS)
    assert how == f"cut from {WORLD}; its ddenv:scenario written from the reduction's scenario (not the file's)"
    cut = (tmp_path / "minimal.sdf").read_text()
    assert parse_sdf(cut, source=WORLD, model_paths=MODELS) == minimal
    lines = cut.splitlines()
    at = lines.index('    <ddenv:scenario xmlns:ddenv="https://github.com/pytest-ddenv/pytest-ddenv/sdf" '
                     'robot="husky" timeout="12.0" goal_tolerance="0.3">')
    assert lines[at - 1].startswith("    <physics name=\"1ms\"")  # where the writer puts it: after the physics
    assert lines[at + 1:at + 4] == ['      <ddenv:start x="-1.0" y="0.5" yaw="0.25" />',
                                    '      <ddenv:goal x="7.0" y="0.0" />', "    </ddenv:scenario>"]
    assert removed_lines(cut, cut_models(WORLD, {"crate"}, model_paths=MODELS)) == [  # nothing else changed
        line.strip() for line in lines[at:at + 4]]


def test_a_scenario_that_overrides_the_files_replaces_it_in_place() -> None:
    path = CORPUS / "surgical_insertions.world"
    world = World.load(path)
    cut = cut_file(path, {"box_b"}, scenario=GIVEN)
    assert cut.scenario_written and cut.text.count("ddenv:scenario") == 2  # one element, opened and closed
    assert parse_sdf(cut.data, source=path) == dataclasses.replace(world.without(["box_b"]), scenario=GIVEN)
    assert cut.text.index("<ddenv:scenario") < cut.text.index("model://ground_plane")
    unchanged = cut_file(path, {"box_b"}, scenario=world.scenario)
    assert not unchanged.scenario_written and unchanged.text == cut_models(path, {"box_b"})


def test_a_stray_ampersand_does_not_prevent_the_cut(tmp_path: Path) -> None:
    path = CORPUS / "surgical_frames.world"
    world = World.load(path)
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, world.without(["crate"]), ("crate",), ())
    assert how is not None and how.startswith(f"cut from {path};")
    cut = (tmp_path / "minimal.sdf").read_text()
    first_gone = removed_lines(path.read_text(), cut)[0]
    assert first_gone == '<model name="crate"><static>true</static><pose>-2 0 0.25 0 0 0</pose>'
    assert "report?world=dock&format=json" in cut and '"crate"' not in cut


def test_a_latin1_file_is_cut_on_its_own_bytes(tmp_path: Path) -> None:
    text = WORLD.read_text().replace('<?xml version="1.0" ?>', '<?xml version="1.0" encoding="ISO-8859-1"?>')
    data = text.replace("<!-- the aisle -->", "<!-- the aisle (caf\xe9 side) -->").encode("latin-1")
    path = tmp_path / "latin1.world"
    path.write_bytes(data)
    cut = cut_file(path, {"crate"}, model_paths=MODELS)
    assert "caf\xe9".encode("latin-1") in cut.data and "caf\xe9".encode() not in cut.data
    same_in_utf8 = tmp_path / "utf8.world"
    same_in_utf8.write_text(data.decode("latin-1"), encoding="utf-8")
    assert cut.data == cut_models(same_in_utf8, {"crate"}, model_paths=MODELS).encode("latin-1")
    assert cut.data.startswith(data[:data.index(b"<model name=\"crate\">")].rstrip(b" "))
    assert parse_sdf(cut.data, source=path, model_paths=MODELS).names == ("block_left", "block_right", "shelf",
                                                                         "label_on_shelf")


def test_relative_paths_left_in_the_cut_file_are_said_with_where_to_put_it(tmp_path: Path) -> None:
    path = CORPUS / "surgical_frames.world"
    world = World.load(path)
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, world.without(["crate"]), ("crate",), ())
    assert how == (f"cut from {path}; its relative paths (media/hill.png) are relative to the original's folder "
                   f"{path.parent}: copy minimal.sdf beside the original to open it")
    how = write_minimal_sdf(tmp_path / "minimal.sdf", world, world.without(["hill"]), ("hill",), ())
    assert how == f"cut from {path}"
