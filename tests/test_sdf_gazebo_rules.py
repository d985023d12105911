"""Issue 15: SDF read as Gazebo reads it. Static and include rules at nesting depth 1-3, frames across nesting,
merged includes, libsdformat's leniency (and strictness), capsules, polylines, heightmaps, planes, unsupported
elements with `skip_unsupported`, the per-world notes, model-path errors, textured meshes.

The corpus is tests/data/sdf/corpus (models in tests/data/sdf/models); tests/test_sdf_sdformat.py checks the
same files against libsdformat where it is installed. Expected poses marked "libsdformat" were printed by
tests/data/sdf/sdformat_dump.cc (libsdformat 12.3).
"""

from __future__ import annotations

import logging
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv import sdf
from pytest_ddenv.errors import WorldError
from pytest_ddenv.sdf import UnsupportedSdfError, load_sdf, parse_sdf
from pytest_ddenv.world import Pose, World

DATA = Path(__file__).resolve().parent / "data" / "sdf"
CORPUS = DATA / "corpus"
MODELS = DATA / "models"


@pytest.fixture(autouse=True)
def no_model_path_from_the_environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for variable in sdf.MODEL_PATH_VARIABLES:
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv("GZ_FUEL_CACHE_PATH", str(tmp_path / "empty-fuel-cache"))  # whatever this machine caches


def corpus(name: str, *, skip: bool = False) -> World:
    return load_sdf(CORPUS / f"{name}.world", model_paths=[MODELS], skip_unsupported=skip)


def shape_xyz(world: World, name: str, index: int = 0) -> np.ndarray:
    model = world.model(name)
    return model.pose.compose(model.shapes[index].pose).position


def world_xml(body: str, version: str = "1.7") -> str:
    return f'<sdf version="{version}"><world name="w">{body}</world></sdf>'


BOX = '<collision name="c"><geometry><box><size>1 1 1</size></box></geometry></collision>'


# -- 1. static, at nesting depth 1, 2 and 3 ----------------------------------------------------------------------
@pytest.mark.parametrize("depth", [1, 2, 3])
def test_a_static_nested_model_makes_its_links_static(depth: int) -> None:
    model = corpus("static_nesting").model(f"nested_static_{depth}")
    assert model.static and model.mass is None


@pytest.mark.parametrize("depth", [1, 2, 3])
def test_a_static_parent_makes_every_link_below_it_static(depth: int) -> None:
    model = corpus("static_nesting").model(f"static_parent_{depth}")
    assert model.static  # static_parent_2's nested <static>false</static> does not undo it


def test_nested_positions_and_a_dynamic_tree() -> None:
    world = corpus("static_nesting")
    assert shape_xyz(world, "nested_static_3") == pytest.approx([0.0, 7.0, 0.0])  # libsdformat
    dynamic = world.model("dynamic_3")
    assert dynamic.dynamic and dynamic.mass == 4.0 and shape_xyz(world, "dynamic_3", 1) == pytest.approx([10, 0, 1])


@pytest.mark.parametrize("name", ["wrapped_1", "wrapped_2", "wrapped_3", "tower"])
def test_a_wrapped_static_include_is_static(name: str) -> None:
    """The warehouse case: a model without <static> wrapping an include of a static model, 1-4 includes deep."""
    model = corpus("static_includes").model(name)
    assert model.static and model.mass == 5.0


@pytest.mark.parametrize(("depth", "z"), [(1, 0.25), (2, 1.25), (3, 2.25)])
def test_include_static_true_overrides_a_dynamic_model(depth: int, z: float) -> None:
    world = corpus("static_includes")
    assert world.model(f"override_static_{depth}").static
    assert shape_xyz(world, f"override_static_{depth}")[2] == pytest.approx(z)  # the include's <pose>


def test_include_static_false_overrides_a_static_model() -> None:
    unfrozen = corpus("static_includes").model("unfrozen")
    assert unfrozen.dynamic and unfrozen.mass == 5.0 and unfrozen.pose == Pose(8.0, 0.0, 0.5)


def test_wrapped_include_without_a_pose_keeps_the_included_models_pose() -> None:
    assert corpus("static_includes").model("wrapped_1").pose == Pose(0.0, 0.0, 0.75)  # 0.25 + link 0.5


@pytest.mark.parametrize(
    ("name", "beside", "block"),
    [  # libsdformat: the link placed relative_to the renamed include, and the included block
        ("renamed_1", [13.755165123780746, 0.95885107720840601, 1.0], [12.0, 0.0, 1.5]),
        ("renamed_2", [13.0, 5.0, 3.0], [13.0, 5.0, 0.5]),
        ("renamed_3", [13.651924443610106, 7.2780958286562951, 3.0], [13.651924443610106, 7.2780958286562951, 0.5]),
    ],
)
def test_include_name_and_pose_overrides_at_depth(name: str, beside: list[float], block: list[float]) -> None:
    world = corpus("static_includes")
    assert shape_xyz(world, name, 0) == pytest.approx(beside, abs=1e-9)
    assert shape_xyz(world, name, 1) == pytest.approx(block, abs=1e-9)


@pytest.mark.parametrize(("name", "part", "line"), [
    ("door_1", "frame", 19), ("door_2", "a::frame", 31), ("door_3", "a::b::frame", 44),
    ("cart_on_wall", "static_block", 54),
])
def test_a_model_mixing_static_and_dynamic_links_is_unsupported(name: str, part: str, line: int) -> None:
    path = CORPUS / "mixed_static.world"
    world = corpus("mixed_static", skip=True)
    assert world.names == ("crate",)
    note = next(note for note in world.notes if note.startswith(f"dropped {name}:"))
    assert f"'{part}'" in note and "<model>" in note and f"{path}:{line}" in note
    with pytest.raises(UnsupportedSdfError) as error:
        load_sdf(path, model_paths=[MODELS])
    assert error.value.model == "door_1" and error.value.element == "model" and error.value.line == 19


# -- 1. frames across nesting, merged includes -----------------------------------------------------------------
@pytest.mark.parametrize(("name", "index", "expected"), [  # libsdformat
    ("rig", 0, [0.84196432036572988, 2.3539532882432215, 0.5]),  # model relative_to a world frame
    ("rig", 1, [1.1852264784084534, 2.5512841280395269, 2.9535984936842525]),  # relative_to a joint (child link)
    ("rig", 2, [1.3656852060665527, 2.7517413034671612, 2.484821821449386]),  # relative_to arm::hand::palm
    ("rig", 3, [1.1051659936099194, 2.4977410176675741, 1.9975020826390129]),  # model relative_to a frame attached_to
    ("rig", 4, [1.1851945880165313, 2.4961843388532841, 2.6900382307183888]),  # collision relative_to __model__, depth 2
    ("rig", 5, [0.66954648777731263, 3.3992549243312489, 2.4950041652780257]),  # include pose relative_to arm::upper
    ("rig", 6, [2.5971294441464763, 3.3128043654516279, 0.0]),  # include placement_frame
    ("neighbour", 0, [1.4118082230110927, 2.6652604310806858, 5.4800166611121046]),  # world model, placement_frame
])
def test_relative_to_across_nesting(name: str, index: int, expected: list[float]) -> None:
    assert shape_xyz(corpus("relative_to"), name, index) == pytest.approx(expected, abs=1e-9)


def test_frame_attribute_of_sdf_1_6_at_depth_2() -> None:
    text = world_xml(f"""<model name="m"><static>1</static><pose>1 0 0 0 0 0</pose>
      <model name="a"><pose frame="m">0 1 0 0 0 0</pose><link name="x"><pose>0 0 0 0 0 0</pose></link>
        <model name="b"><pose frame="x">0 0 1 0 0 0</pose><link name="l">{BOX}</link></model></model></model>""", "1.6")
    assert parse_sdf(text).model("m").pose == Pose(1.0, 1.0, 1.0)


def test_unknown_scoped_frame_is_an_error() -> None:
    text = world_xml(f'<model name="m"><static>1</static><link name="l"><pose relative_to="a::nothing"/>{BOX}'
                     '</link><model name="a"><link name="k"/></model></model>', "1.8")
    with pytest.raises(WorldError, match=r"unknown frame 'a::nothing' .*there are: a::k\)"):
        parse_sdf(text, source="x.world")


@pytest.mark.parametrize(("index", "expected"), [  # libsdformat
    (0, [10.0, 0.0, 0.0]), (1, [5.0, 1.0, 0.0]), (2, [4.5, 0.5, 1.0]), (3, [5.0, 1.0, 3.0]), (4, [3.0, 1.0, 0.0]),
])
def test_merged_include_links_become_the_parents(index: int, expected: list[float]) -> None:
    world = corpus("merge_include")
    parent = world.model("parent")
    assert parent.dynamic and parent.mass == 7.0 and len(parent.shapes) == 5
    assert shape_xyz(world, "parent", index) == pytest.approx(expected, abs=1e-9)


def test_merged_include_name_static_and_depth() -> None:
    world = corpus("merge_include")
    assert shape_xyz(world, "renamed", 2) == pytest.approx([0.0, -5.0, 3.0])  # attached_to the proxy frame
    assert world.model("merged_static_is_dropped").dynamic  # as libsdformat 12: the parent's <static> rules
    assert world.model("include_static_is_dropped").dynamic
    assert world.model("static_parent").static and shape_xyz(world, "static_parent") == pytest.approx([6, 10, 1])
    assert any(note.startswith("joints: parent (1 joint)") for note in world.notes)


def test_merged_include_in_a_world_is_an_error() -> None:
    with pytest.raises(WorldError, match="needs a model around it") as error:
        corpus("merge_in_world")
    assert error.value.line == 5


# -- 2. leniency as libsdformat's, strictness as libsdformat's ---------------------------------------------------
def test_comments_with_double_dashes_load() -> None:
    world = corpus("comment_dashes")
    assert world.names == ("box",) and world.ground is not None and world.model("box").mass == 1.0


def test_lenient_text() -> None:
    world = corpus("lenient_text")
    assert world.name == "lenient_text" and world.model("block").static
    assert world.model("block").pose == Pose(1.0, 2.0, 0.5)
    assert world.notes == ("plugins: libexample_plugin.so (world); plugins do not run",)


@pytest.mark.parametrize("variant", ["bom", "crlf", "cr", "latin1", "bom+crlf"])
def test_byte_order_mark_line_ends_and_latin1(tmp_path: Path, variant: str) -> None:
    data = (CORPUS / "lenient_text.world").read_bytes()
    if "crlf" in variant:
        data = data.replace(b"\n", b"\r\n")
    if variant == "cr":
        data = data.replace(b"\n", b"\r")
    if "bom" in variant:
        data = b"\xef\xbb\xbf" + data
    if variant == "latin1":
        data = data.replace(b"cafe", b"caf\xe9")
    path = tmp_path / "variant.world"
    path.write_bytes(data)
    assert load_sdf(path).model("block").pose == Pose(1.0, 2.0, 0.5)


@pytest.mark.parametrize("version", [" 1.6 ", "1.6\t", "1. 6", "1.3", "1.2", "1.10", "2.0"])
def test_versions_libsdformat_reads(version: str) -> None:
    world = parse_sdf(world_xml(f'<model name="m"><static>1</static><link name="l">{BOX}</link></model>', version))
    assert world.names == ("m",)


@pytest.mark.parametrize(("version", "message"), [("1.1", "not supported"), ("abc", "unreadable SDF version")])
def test_versions_libsdformat_refuses(version: str, message: str) -> None:
    with pytest.raises(WorldError, match=message):
        parse_sdf(world_xml("", version))


def test_lines_stay_right_after_every_rewrite() -> None:
    text = ('\n  <?xml version="1.0"?>\n<sdf version="1.7">\n<!-- a -- b\n -- c -->\n<world name="w">\n'
            '<plugin name="p" filename="f"><u>a&b &nbsp;</u></plugin>\n<model name="m"><static>1</static>\n'
            '<link name="l"><collision name="c"><geometry><box><size>1 x 1</size></box>\n'
            '</geometry></collision></link></model></world></sdf>')
    with pytest.raises(WorldError, match="expected numbers") as error:
        parse_sdf(text, source="lines.world")
    line = next(number for number, text_line in enumerate(text.split("\n"), 1) if "1 x 1" in text_line)
    assert line == 9 and error.value.line == line and str(error.value).startswith("lines.world:9")


def test_malformed_xml_after_a_rewritten_comment_names_its_line() -> None:
    with pytest.raises(WorldError, match="malformed XML") as error:
        parse_sdf('<sdf version="1.7">\n<!-- -- -->\n<world name="w">\n</sdf>', source="bad.world")
    assert error.value.line == 4


def test_elements_after_the_root_are_ignored_text_is_not() -> None:
    body = world_xml(f'<model name="m"><static>1</static><link name="l">{BOX}</link></model>')
    assert parse_sdf(body + "\n<extra/>\n<!-- end -->\n</sdf>").names == ("m",)  # as tinyxml2
    with pytest.raises(WorldError, match="malformed XML"):
        parse_sdf(body + "\ngarbage")  # tinyxml2 refuses text there too


def test_cdata_and_processing_instructions_are_kept_as_they_are() -> None:
    assert sdf._xml.lenient_text("<a><![CDATA[x -- & y]]><?pi a -- & b?><!-- & -- --></a>") == (
        "<a><![CDATA[x -- & y]]><?pi a -- & b?><!-- &    --></a>")


@pytest.mark.parametrize(("geometry", "expected"), [
    ("<box/>", ("box", (1.0, 1.0, 1.0), None, None)),
    ("<sphere/>", ("sphere", None, 1.0, None)),
    ("<cylinder><radius>0.5</radius></cylinder>", ("cylinder", None, 0.5, 1.0)),
    ("<capsule/>", ("capsule", None, 0.5, 1.0)),
])
def test_missing_size_elements_take_the_sdf_default_as_libsdformat_does(
    geometry: str, expected: tuple[object, ...]
) -> None:
    text = world_xml(f'<model name="m"><static>1</static><link name="l"><collision name="c"><geometry>{geometry}'
                     "</geometry></collision></link></model>", "1.8")
    shape = parse_sdf(text).model("m").shapes[0]
    assert (shape.kind, shape.size, shape.radius, shape.length) == expected


def test_empty_geometry_is_no_collision() -> None:
    text = world_xml('<model name="m"><static>1</static><link name="l"><collision name="c"><geometry><empty/>'
                     f'</geometry></collision><collision name="d"/>{BOX}</link></model>')
    assert len(parse_sdf(text).model("m").shapes) == 1


@pytest.mark.parametrize(("body", "message", "line"), [  # each refused by libsdformat too
    (f'<model><static>1</static><link name="l">{BOX}</link></model>', "a model needs a name", 2),
    (('<model name="m"><static>1</static>\n<link name="l"><collision name="c"><geometry><box><size></size></box>'
      "</geometry></collision></link></model>"), "expected 3 numbers, got 0", 3),
    (f'<model name="m"><static>1</static>\n<pose>1 2 3</pose><link name="l">{BOX}</link></model>',
     "expected 6 numbers, got 3", 3),
    (f'<model name="m"><static>yes</static><link name="l">{BOX}</link></model>', "true/false", 2),
    ('<include>\n<uri> </uri></include>', "needs a <uri>", 2),
])
def test_strict_where_libsdformat_is_strict(body: str, message: str, line: int) -> None:
    with pytest.raises(WorldError, match=message) as error:
        parse_sdf(f'<sdf version="1.7">\n<world name="w">{body}</world></sdf>', source="strict.world")
    assert error.value.line == line


# -- 3. geometry -------------------------------------------------------------------------------------------------
def test_capsules() -> None:
    world = corpus("capsule")
    bollard, pill = world.model("bollard"), world.model("pill")
    assert (bollard.shapes[0].kind, bollard.shapes[0].radius, bollard.shapes[0].length) == ("capsule", 0.25, 1.0)
    assert bollard.static and pill.dynamic and pill.mass == 0.5
    assert pill.shapes[0].length == 1.0 and pill.shapes[0].pose == Pose(0.0, 0.0, 0.1)
    assert shape_xyz(world, "pill") == pytest.approx([0.1, 2.0, 0.2])  # libsdformat


def test_polylines_one_shape_each_and_holes_noted() -> None:
    world = corpus("polyline")
    wedge = world.model("wedge").shapes
    assert len(wedge) == 1 and wedge[0].kind == "polyline" and wedge[0].height == 0.5
    assert wedge[0].points == ((0.0, 0.0), (2.0, 0.0), (0.0, 1.0))  # the closing point is not repeated
    courtyard = world.model("courtyard").shapes
    assert [len(shape.points or ()) for shape in courtyard] == [4, 4, 3] and courtyard[2].height == 1.0
    assert world.notes == (("polyline holes filled: courtyard::l::c (1); Gazebo cuts outlines inside another one "
                            "out of the extrusion"),)


def test_a_polyline_needs_three_points() -> None:
    text = world_xml('<model name="m"><static>1</static><link name="l"><collision name="c"><geometry><polyline>'
                     "<point>0 0</point><point>1 0</point></polyline></geometry></collision></link></model>")
    with pytest.raises(WorldError, match="at least 3 points"):
        parse_sdf(text)


def test_heightmap_is_resolved_like_a_mesh_and_placed_at_pos() -> None:
    world = corpus("heightmap")
    hill = world.model("hill")
    (shape,) = hill.shapes
    assert hill.static and shape.kind == "heightmap" and shape.mesh == str((CORPUS / "media" / "hill.png").resolve())
    assert shape.size == (16.0, 16.0, 2.0) and shape.pose == Pose(4.0, 0.0, -0.5)
    assert world.notes == ("lights: sun; lights do not take part in the simulation",)


def test_heightmap_from_a_generated_image_through_model_uri(tmp_path: Path) -> None:
    from PIL import Image

    (tmp_path / "terrain" / "materials").mkdir(parents=True)
    Image.new("L", (9, 9), 128).save(tmp_path / "terrain" / "materials" / "flat.png")
    text = world_xml('<model name="t"><static>1</static><link name="l"><collision name="c"><geometry><heightmap>'
                     "<uri>model://terrain/materials/flat.png</uri></heightmap></geometry></collision></link></model>")
    (shape,) = parse_sdf(text, model_paths=[tmp_path]).model("t").shapes
    assert shape.size == (1.0, 1.0, 1.0) and Path(shape.mesh or "").name == "flat.png"


def test_heightmap_dem_files_are_unsupported(tmp_path: Path) -> None:
    (tmp_path / "dem.tif").write_bytes(b"II*\x00")
    path = tmp_path / "dem.world"
    path.write_text(world_xml('<model name="t"><static>1</static><link name="l"><collision name="c"><geometry>'
                              "<heightmap><uri>dem.tif</uri></heightmap></geometry></collision></link></model>"))
    with pytest.raises(UnsupportedSdfError, match="unsupported <heightmap>: format '.tif'"):
        load_sdf(path)


def test_tilted_planes_of_static_models_are_thin_boxes_under_the_surface() -> None:
    world = corpus("tilted_plane")
    assert world.ground is not None and world.ground.mu == 100.0 and world.names == ("ramp", "wall")
    for name, normal in (("ramp", np.array([-0.5, 0.0, 1.0])), ("wall", np.array([0.0, -1.0, 0.0]))):
        model = world.model(name)
        (box,) = model.shapes
        assert box.kind == "box" and box.size is not None and box.size[2] == pytest.approx(0.1)
        placed = model.pose.compose(box.pose)
        unit = normal / np.linalg.norm(normal)
        assert placed.rotation[:, 2] == pytest.approx(unit)  # the box's z axis is the plane's normal
        top_centre = placed.position + placed.rotation @ np.array([0.0, 0.0, 0.05])
        assert top_centre == pytest.approx(model.pose.compose(Pose(roll=math.pi / 2 if name == "wall" else 0.0))
                                           .position)  # the top face is on the plane
    assert world.model("ramp").shapes[0].size == pytest.approx((4.0, 2.0, 0.1))
    assert world.notes == (("planes as 0.1 m thick boxes of their <size>: ramp, wall; Gazebo's collision planes "
                            "are infinite"),)


def test_state_scale_of_capsules_and_polylines() -> None:
    text = world_xml('<model name="m"><static>1</static><link name="l"><collision name="c"><geometry><capsule>'
                     "<radius>0.5</radius><length>2</length></capsule></geometry></collision>"
                     '<collision name="p"><geometry><polyline><point>0 0</point><point>1 0</point><point>0 1</point>'
                     "<height>1</height></polyline></geometry></collision></link></model>"
                     '<state world_name="w"><model name="m"><scale>2 3 4</scale></model></state>', "1.8")
    capsule, polyline = parse_sdf(text).model("m").shapes
    assert (capsule.radius, capsule.length) == (1.5, 8.0)
    assert polyline.points == ((0.0, 0.0), (2.0, 0.0), (0.0, 3.0)) and polyline.height == 4.0


# -- 3. unsupported elements and the notes -----------------------------------------------------------------------
def test_actor_is_unsupported_and_dropped_with_skip_unsupported() -> None:
    path = CORPUS / "actor.world"
    with pytest.raises(UnsupportedSdfError) as error:
        load_sdf(path)
    message = str(error.value)
    assert message.startswith(f"{path}:11, model walker: unsupported <actor>")
    assert "--skip-unsupported" in message and "skip_unsupported=True" in message
    world = World.load(path, skip_unsupported=True)
    assert world.names == ("table",)
    assert world.notes == (f"dropped walker: unsupported <actor>: animated actors are not simulated ({path}:11)",)


def test_each_unsupported_model_is_named_once() -> None:
    world = corpus("unsupported", skip=True)
    assert world.names == ("kept",)
    dropped = [note.split(":")[0] for note in world.notes]
    assert dropped == ["dropped egg", "dropped part_of_a_mesh", "dropped rolling_hill", "dropped falling_floor"]
    assert [note.split("unsupported ")[1].split(":")[0] for note in world.notes] == [
        "<ellipsoid>", "<submesh>", "<heightmap>", "<plane>"]


def test_fuel_include_is_unsupported_and_dropped() -> None:
    with pytest.raises(UnsupportedSdfError, match="Gazebo Fuel model OpenRobotics/Construction Cone is not "
                                                  "here") as error:
        corpus("fuel_include")
    assert error.value.model == "cone" and error.value.line == 11 and "gz fuel download -u" in str(error.value)
    world = corpus("fuel_include", skip=True)
    assert world.names == ("kept",) and world.notes[0].startswith("dropped cone: Gazebo Fuel model")


def test_population_is_unsupported() -> None:
    text = world_xml('<population name="crowd"><model name="m"><link name="l"/></model></population>')
    with pytest.raises(UnsupportedSdfError, match="unsupported <population>"):
        parse_sdf(text)
    assert parse_sdf(text, skip_unsupported=True).notes[0].startswith("dropped crowd: unsupported <population>")


def test_notes_say_once_what_is_not_simulated() -> None:
    world = corpus("not_simulated")
    assert world.names == ("cabinet", "camera_pole")
    assert world.notes == (
        "joints: cabinet (2 joints); each articulated model is simulated as one rigid body",
        "plugins: libgazebo_ros_state.so (world), libcabinet_controller.so (cabinet); plugins do not run",
        "sensors: camera_pole::pole::camera; sensors in the world do not run (the robot's come from the scenario)",
        "lights: sun, lamp, camera_pole::pole::spot; lights do not take part in the simulation",
        "models without collisions: marker; nothing to touch: skipped",
    )
    cabinet = world.model("cabinet")
    assert cabinet.dynamic and cabinet.mass == 23.0 and len(cabinet.shapes) == 3


def test_notes_are_capped() -> None:
    lights = "".join(f'<light type="point" name="l{index}"/>' for index in range(9))
    assert parse_sdf(world_xml(lights)).notes == (
        "lights: l0, l1, l2, l3, l4, l5 and 3 more; lights do not take part in the simulation",)


def test_notes_are_not_part_of_world_equality() -> None:
    world = corpus("not_simulated")
    assert world.notes and World(models=world.models, ground=world.ground, name=world.name) == world


# -- 4. model path errors ----------------------------------------------------------------------------------------
def test_missing_include_lists_the_folders_searched_in_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GAZEBO_MODEL_PATH", str(tmp_path / "from_env"))
    path = tmp_path / "w.world"
    path.write_text(world_xml("\n<include><uri>model://warehouse_shelf</uri></include>"))
    with pytest.raises(WorldError) as error:
        load_sdf(path, model_paths=[MODELS, tmp_path / "more"])
    message = str(error.value)
    assert message.startswith(f"{path}:2, model warehouse_shelf, field 'include/uri'")
    assert f"searched, in order: {MODELS}, {tmp_path / 'more'}, {tmp_path / 'from_env'}." in message
    assert "`ddenv ... --model-path DIRS`" in message and "`--ddenv-model-path DIRS`" in message
    assert "GAZEBO_MODEL_PATH / GZ_SIM_RESOURCE_PATH / IGN_GAZEBO_RESOURCE_PATH / SDF_PATH" in message


def test_missing_mesh_lists_the_folders_searched(tmp_path: Path) -> None:
    text = world_xml('<model name="rock"><static>1</static><link name="l"><collision name="c"><geometry><mesh>'
                     "<uri>model://rocks/meshes/rock.dae</uri></mesh></geometry></collision></link></model>")
    with pytest.raises(WorldError, match="missing mesh file 'model://rocks/meshes/rock.dae'") as error:
        parse_sdf(text, source="w.world", model_paths=[tmp_path])
    assert f"searched, in order: {tmp_path}." in str(error.value) and "--model-path" in str(error.value)
    with pytest.raises(WorldError, match="no folders: no model path is set"):
        parse_sdf(text, source="w.world")


# -- 7. textured meshes: no third-party traceback ----------------------------------------------------------------
def test_a_textured_collada_mesh_logs_nothing(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, capfd: pytest.CaptureFixture[str]
) -> None:
    """trimesh logs a traceback for each texture it cannot open (Gazebo keeps them in ../materials/textures);
    importing and measuring a world with such a mesh logs nothing."""
    pytest.importorskip("collada", reason="trimesh reads .dae files only with pycollada installed")
    models = tmp_path / "models"
    shutil.copytree(MODELS / "textured_box", models / "textured_box")  # a new path: no cached mesh
    with caplog.at_level(logging.DEBUG):
        world = load_sdf(CORPUS / "textured_mesh.world", model_paths=[models])
        low, high = world.bounds("textured_box")
    assert high - low == pytest.approx([1.0 * (math.cos(0.5) + math.sin(0.5))] * 2 + [1.0])
    assert not [record for record in caplog.records if record.exc_info or record.name.startswith("trimesh")
                and record.levelno >= logging.WARNING]
    assert "Traceback" not in capfd.readouterr().err


def test_collada_geometry_drops_the_appearance_and_keeps_the_shape() -> None:
    trimesh = pytest.importorskip("trimesh")
    pytest.importorskip("collada")
    import io

    data = sdf.collada_geometry(MODELS / "textured_box" / "meshes" / "textured_box.dae")
    assert b"library_images" not in data and b"library_effects" not in data and b"bind_material" not in data
    mesh = trimesh.load(io.BytesIO(data), file_type="dae", force="mesh")
    assert mesh.bounds.tolist() == [[-0.5, -0.5, 0.0], [0.5, 0.5, 1.0]]


def test_collada_geometry_refuses_entities(tmp_path: Path) -> None:
    (tmp_path / "evil.dae").write_text('<?xml version="1.0"?>\n<!DOCTYPE C [<!ENTITY a "aa">]>\n<COLLADA>&a;</COLLADA>')
    with pytest.raises(WorldError, match="not allowed"):
        sdf.collada_geometry(tmp_path / "evil.dae")


def test_a_capsule_without_a_cylinder_part_is_a_sphere() -> None:
    from pytest_ddenv.sdf import parse_sdf

    world = parse_sdf('<sdf version="1.9"><world name="w"><model name="ball"><static>true</static><link name="l">'
                      '<collision name="c"><geometry><capsule><radius>0.3</radius><length>0</length></capsule>'
                      '</geometry></collision></link></model></world></sdf>')
    (shape,) = world.model("ball").shapes
    assert shape.kind == "sphere" and shape.radius == 0.3


def test_a_self_intersecting_polyline_is_refused_with_its_line() -> None:
    from pytest_ddenv.errors import WorldError
    from pytest_ddenv.sdf import parse_sdf

    bowtie = "".join(f"<point>{x} {y}</point>" for x, y in ((0, 0), (1, 1), (1, 0), (0, 1)))
    text = ('<sdf version="1.9"><world name="w">\n<model name="tie"><static>true</static><link name="l">'
            f'<collision name="c"><geometry>\n<polyline>{bowtie}<height>1</height></polyline>'
            '</geometry></collision></link></model></world></sdf>')
    with pytest.raises(WorldError, match=r"w.sdf:3, model tie, field .*polyline.*point") as raised:
        parse_sdf(text, source="w.sdf")
    assert "self" in str(raised.value).lower() or "intersect" in str(raised.value).lower()


# -- 8. undeclared namespace prefixes: lenient as libsdformat ------------------------------------------------------
def test_undeclared_namespace_prefixes_are_read_as_libsdformat_reads_them() -> None:
    world = corpus("namespaced")  # libsdformat loads it too (tests/test_sdf_sdformat.py)
    assert world.names == ("crate",) and world.model("crate").pose == Pose(1.0, 2.0, 0.25, yaw=0.5)
    assert world.notes == ("plugins: libgazebo_ros_factory.so (world), libgz_follow.so (crate); plugins do not run",)


@pytest.mark.parametrize("body", [
    '<gz:camera_follow>true</gz:camera_follow><model name="m"><static>1</static><link name="l">{BOX}</link></model>',
    ('<plugin name="p" filename="f.so"><ros:remap from="a" to="b"/></plugin><model name="m"><static>1</static>'
     '<link name="l">{BOX}</link></model>'),
    ('<model name="m"><static>1</static><pose gz:expressed_in="world">0 0 1 0 0 0</pose><link name="l">{BOX}</link>'
     "</model>"),
    '<model name="m" xmlns:gz="urn:gz"><static>1</static><link name="l">{BOX}</link></model><gz:x/>',  # inner only
])
def test_an_undeclared_prefix_is_not_an_error(body: str) -> None:
    text = f'<sdf version="1.7" xmlns:other="urn:o">\n<world name="w">{body.format(BOX=BOX)}</world></sdf>'
    assert parse_sdf(text).names == ("m",)


def test_an_undeclared_ddenv_prefix_is_still_ddenv() -> None:
    text = world_xml('<ddenv:scenario robot="husky" timeout="9"><ddenv:start x="1" y="0"/><ddenv:goal x="5" y="0"/>'
                     f'</ddenv:scenario><model name="m"><static>1</static><link name="l">{BOX}</link></model>')
    scenario = parse_sdf(text).scenario
    assert scenario is not None and scenario.timeout == 9.0 and scenario.goal[0] == 5.0


def test_lines_stay_right_with_undeclared_prefixes() -> None:
    text = ('<?xml version="1.0"?>\n<sdf\n version="1.7">\n<world name="w">\n<gz:a/>\n<model name="m">'
            '<static>1</static>\n<link name="l"><ros:b/><collision name="c"><geometry><box><size>1 x 1</size>'
            "</box></geometry></collision></link></model></world></sdf>")
    with pytest.raises(WorldError, match="expected numbers") as error:
        parse_sdf(text, source="ns.world")
    assert error.value.line == 7
    with pytest.raises(WorldError, match="malformed XML") as error:
        parse_sdf(text.replace("</model>", ""), source="ns.world")
    assert error.value.line == 7 and error.value.model == "m"
    assert "(inside <model name='m'> opened at line 6)" in str(error.value)


@pytest.mark.parametrize("text", [
    '<?xml version="1.0"?>\n<!DOCTYPE sdf [<!ENTITY a "aaaa">]>\n<sdf version="1.7"><gz:x>&a;</gz:x></sdf>',
    '<!DOCTYPE sdf SYSTEM "http://example.com/x.dtd">\n<sdf version="1.7"><world name="w" gz:a="1"/></sdf>',
    '<sdf version="1.7"><!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]><gz:x>&e;</gz:x></sdf>',
])
def test_undeclared_prefixes_keep_dtds_and_entities_refused(text: str) -> None:
    with pytest.raises(WorldError, match=r"not allowed|malformed XML|forbidden"):
        parse_sdf(text, source="hostile.world")


# -- 9. names a joint, a frame or a pose gives must exist: strict as libsdformat --------------------------------
BAD_CORPUS = sorted(CORPUS.glob("bad_*.world"))
BAD = {  # file: line, model, field, the name not found, the names there are
    "bad_joint_child.world": (15, "arm", "joint/child", "'fore_arm' in the <child> of joint 'elbow'",
                              "base, elbow, forearm"),
    "bad_joint_parent.world": (14, "arm", "joint/parent", "'bas' in the <parent> of joint 'elbow'",
                               "base, elbow, forearm"),
    "bad_attached_to.world": (7, "shelf", "frame/@attached_to", "'bord' in the attached_to of frame 'shelf_top'",
                              "board, shelf_top"),
    "bad_world_attached_to.world": (5, None, "frame/@attached_to", "'table' in the attached_to of frame 'dock'",
                                    "desk, dock"),
    "bad_relative_to.world": (10, "cart", "frame/pose/@relative_to",
                              "'chasis' in the relative_to of frame 'handle'", "chassis, handle"),
}


def test_every_bad_corpus_file_is_described() -> None:
    assert {path.name for path in BAD_CORPUS} == set(BAD)


@pytest.mark.parametrize("path", BAD_CORPUS, ids=lambda path: path.name)
def test_a_name_that_is_no_frame_is_refused_as_libsdformat_refuses_it(path: Path) -> None:
    line, model, field, missing, there_are = BAD[path.name]
    with pytest.raises(WorldError) as error:
        load_sdf(path, model_paths=[MODELS], skip_unsupported=True)
    assert not isinstance(error.value, UnsupportedSdfError)  # not droppable: the file is wrong
    assert (error.value.line, error.value.model, error.value.field) == (line, model, field)
    message = str(error.value)
    assert message.startswith(f"{path}:{line}, ") and f"unknown frame {missing}" in message
    assert message.endswith(f"(there are: {there_are})")


@pytest.mark.parametrize("name", [*BAD, "namespaced.world"])
def test_libsdformat_agrees_on_names_and_prefixes(sdformat_check: Path, name: str) -> None:
    result = subprocess.run([str(sdformat_check), str(CORPUS / name)], capture_output=True, text=True, check=False,
                            timeout=60)
    assert (result.returncode == 0) == (name == "namespaced.world"), result.stdout + result.stderr


JOINT_MODEL = ('<model name="arm"><link name="base">{BOX}</link><link name="tip"/><frame name="fr" attached_to="tip"/>'
               '<model name="inner"><link name="il"/></model>\n<joint name="h" type="fixed">{joint}</joint></model>')


@pytest.mark.parametrize(("joint", "error"), [  # each as libsdformat 12 decides
    ("<parent>base</parent><child>tip</child>", None),
    ("<parent>world</parent><child>base</child>", None),
    ("<parent>base</parent><child>fr</child>", None),
    ("<parent>base</parent><child>inner</child>", None),
    ("<parent>base</parent><child>inner::il</child>", None),
    ("<parent>base</parent><child> tip </child>", None),
    ("<parent>base</parent><child>world</child>", "unknown frame 'world' in the <child> of joint 'h'"),
    ("<parent>__model__</parent><child>base</child>", "unknown frame '__model__' in the <parent> of joint 'h'"),
    ("<parent>base</parent><child>inner::nope</child>", r"unknown frame 'inner::nope' .*\(there are: inner::il\)"),
    ("<parent>base</parent>", "joint 'h' needs a <child>"),
    ("<parent>base</parent><child> </child>", "joint 'h' needs a <child>"),
    ("<child>tip</child>", "joint 'h' needs a <parent>"),
    ("<parent>base</parent><child>base</child>", "the same <parent> and <child>"),
])
def test_joint_parent_and_child_must_be_frames_of_the_model(joint: str, error: str | None) -> None:
    text = world_xml(JOINT_MODEL.format(BOX=BOX, joint=joint))
    if error is None:
        assert parse_sdf(text).names == ("arm",)
        return
    with pytest.raises(WorldError, match=error) as raised:
        parse_sdf(text, source="j.world")
    assert raised.value.line == 2 and raised.value.model == "arm"


def test_a_pose_relative_to_nothing_is_refused_even_when_nothing_resolves_through_it() -> None:
    text = world_xml(f'<model name="m"><link name="l">{BOX}</link><frame name="f"><pose relative_to="nope"/></frame>'
                     '</model><frame name="g" attached_to="m"/><frame name="k"><pose relative_to="ghost"/></frame>')
    with pytest.raises(WorldError, match="unknown frame 'nope' in the relative_to of frame 'f'"):
        parse_sdf(text)
    with pytest.raises(WorldError, match=r"unknown frame 'ghost' .* of the world \(there are: g, k, m\)"):
        parse_sdf(text.replace('relative_to="nope"', 'relative_to="l"'))


# -- 10. files inside found models, Gazebo-classic resource URIs ---------------------------------------------------
def test_a_missing_file_in_a_model_that_was_found_says_where_the_model_is() -> None:
    text = world_xml('<model name="w"><static>1</static><link name="l"><collision name="c"><geometry><mesh>'
                     "<uri>model://crate/meshes/nope.dae</uri></mesh></geometry></collision></link></model>")
    with pytest.raises(WorldError) as error:
        parse_sdf(text, source="w.world", model_paths=[MODELS])
    message = str(error.value)
    assert f"model 'crate' was found at {MODELS / 'crate'}, but it has no file 'meshes/nope.dae'" in message
    assert "model not found" not in message and "--model-path" not in message


@pytest.fixture
def resources(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """tmp/world/hm.world using file://media/materials/textures/hm.png; the image in tmp/share/media/..."""
    monkeypatch.delenv("GAZEBO_RESOURCE_PATH", raising=False)
    textures = tmp_path / "share" / "media" / "materials" / "textures"
    textures.mkdir(parents=True)
    shutil.copy(CORPUS / "media" / "hill.png", textures / "hm.png")
    (tmp_path / "world").mkdir()
    (tmp_path / "world" / "hm.world").write_text(world_xml(
        '<model name="hill"><static>1</static><link name="l"><collision name="c"><geometry><heightmap><uri>'
        "file://media/materials/textures/hm.png</uri><size>8 8 1</size></heightmap></geometry></collision></link>"
        "</model>"))
    return tmp_path


def test_a_gazebo_classic_media_uri_is_found_through_the_resource_path(
    resources: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.raises(WorldError) as error:
        load_sdf(resources / "world" / "hm.world", model_paths=[MODELS])
    message = str(error.value)
    assert "missing heightmap file 'file://media/materials/textures/hm.png': file not found" in message
    assert f"searched, in order: {resources / 'world'}, {MODELS}." in message
    assert "'media/' to GAZEBO_RESOURCE_PATH or to the model path" in message
    expected = resources / "share" / "media" / "materials" / "textures" / "hm.png"
    monkeypatch.setenv("GAZEBO_RESOURCE_PATH", f"{resources / 'nothing'}:{resources / 'share'}")
    assert load_sdf(resources / "world" / "hm.world").model("hill").shapes[0].mesh == str(expected.resolve())
    monkeypatch.delenv("GAZEBO_RESOURCE_PATH")
    world = load_sdf(resources / "world" / "hm.world", model_paths=[resources / "share"])  # the model path too
    assert world.model("hill").shapes[0].mesh == str(expected.resolve())


def test_a_relative_file_uri_is_relative_to_the_world_file_first(resources: Path) -> None:
    (resources / "world" / "media").symlink_to(resources / "share" / "media")
    world = load_sdf(resources / "world" / "hm.world")
    assert world.model("hill").shapes[0].mesh is not None
    absolute = resources / "share" / "media" / "materials" / "textures" / "hm.png"
    text = (resources / "world" / "hm.world").read_text()
    (resources / "other.world").write_text(text.replace("file://media", f"file://{resources / 'share' / 'media'}"))
    assert load_sdf(resources / "other.world").model("hill").shapes[0].mesh == str(absolute.resolve())  # file:///


# -- 11. a joint, a plugin, a light and an actor together ---------------------------------------------------------
def test_everything_not_simulated_is_noted_and_the_actor_dropped() -> None:
    with pytest.raises(UnsupportedSdfError, match="unsupported <actor>") as error:
        corpus("everything_not_simulated")
    assert error.value.model == "visitor" and error.value.line == 28
    world = corpus("everything_not_simulated", skip=True)
    assert world.names == ("door",) and world.model("door").mass == 15.0
    path = CORPUS / "everything_not_simulated.world"
    assert world.notes == (
        f"dropped visitor: unsupported <actor>: animated actors are not simulated ({path}:28)",
        "joints: door (1 joint); each articulated model is simulated as one rigid body",
        "plugins: libworld_stats.so (world), libdoor_opener.so (door); plugins do not run",
        "lights: sun; lights do not take part in the simulation",
    )
