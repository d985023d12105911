"""Gazebo SDF import (as Gazebo simulates it) and export (issue 8), with hand-written fixtures in tests/data/sdf."""

from __future__ import annotations

import dataclasses
import functools
import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pytest_ddenv import sdf
from pytest_ddenv.errors import WorldError
from pytest_ddenv.sdf import _xml, dump_sdf, load_sdf, model_search_paths, parse_sdf
from pytest_ddenv.world import Ground, Model, Pose, Scenario, Shape, World

DATA = Path(__file__).resolve().parent / "data" / "sdf"
MODELS = DATA / "models"
WORLDS = Path(__file__).resolve().parent.parent / "worlds"
SHIPPED = sorted(path.stem for path in WORLDS.glob("*.yaml"))
SCENARIOS = ("ditch", "rubble", "friction")


@pytest.fixture(autouse=True)
def no_model_path_from_the_environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for variable in sdf.MODEL_PATH_VARIABLES:
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv("GZ_FUEL_CACHE_PATH", str(tmp_path / "empty-fuel-cache"))  # whatever this machine caches


@functools.cache
def yaml_world(name: str) -> World:
    return World.load(WORLDS / f"{name}.yaml")


def features() -> World:
    return load_sdf(DATA / "features.world", model_paths=[MODELS])


def assert_close(a: Any, b: Any, path: str = "world") -> None:
    """Structural equality with floats compared to 1e-9."""
    if isinstance(a, float) or isinstance(b, float):
        assert isinstance(a, (int, float)) and isinstance(b, (int, float)), path
        assert math.isclose(a, b, rel_tol=0, abs_tol=1e-9), f"{path}: {a} != {b}"
    elif dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), path
        for item in dataclasses.fields(a):
            if item.compare:
                assert_close(getattr(a, item.name), getattr(b, item.name), f"{path}.{item.name}")
    elif isinstance(a, (tuple, list)):
        assert isinstance(b, (tuple, list)) and len(a) == len(b), f"{path}: length {len(a)} != {len(b)}"
        for index, (x, y) in enumerate(zip(a, b)):
            assert_close(x, y, f"{path}[{index}]")
    elif isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), path
        for key in a:
            assert_close(a[key], b[key], f"{path}.{key}")
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"


def world_xyz(world: World, name: str, shape: int = 0) -> np.ndarray:
    model = world.model(name)
    return model.pose.compose(model.shapes[shape].pose).position


# -- a world saved from Gazebo's GUI: <state> wins -------------------------------------------------------
class TestGuiSavedWorld:
    world = staticmethod(functools.cache(lambda: load_sdf(DATA / "gui_saved.world")))

    def test_models_and_ground(self) -> None:
        world = self.world()
        assert world.name == "default"
        assert world.names == ("asphalt_plane", "grey_wall", "ball")  # ground plane is a setting
        assert world.ground == Ground(z=0.0, mu=100.0, mu2=50.0)
        assert world.physics.gravity == (0.0, 0.0, -9.8)
        assert world.scenario is None

    def test_state_model_pose_and_scale_replace_the_stale_body(self) -> None:
        world = self.world()
        plane = world.model("asphalt_plane")
        assert plane.pose == Pose(-8.53833, 2.29833, 0.165376)  # body pose said (1.524, 0.68, 0)
        assert plane.shapes[0].size == pytest.approx((20.0, 20.0, 1.4296))  # <scale>1 1 14.296</scale>
        assert world.bounds("asphalt_plane")[1, 2] == pytest.approx(0.8802, abs=1e-4)
        assert world.bounds("asphalt_plane")[1, 0] == pytest.approx(1.46167)

    def test_state_link_pose_wins_over_an_inconsistent_state_model_pose(self) -> None:
        wall = self.world().model("grey_wall")
        assert wall.pose == Pose(-1.014, 0.6, 0.141, 1.576, 0.0, 0.0)
        assert (wall.mu, wall.mu2) == (1000.0, 500.0)
        assert wall.color == (1.0, 0.1, 0.1, 1.0)  # the ambient colour

    def test_state_scale_of_sphere_and_cylinder_as_gazebo(self) -> None:
        ball = self.world().model("ball")
        assert ball.pose == Pose(2.0, 1.0, 0.0, 0.0, 0.0, 0.5)  # link follows the state model pose
        sphere, axle = ball.shapes
        assert sphere.radius == pytest.approx(0.4)  # 0.1 * max(2, 3, 4)
        assert axle.radius == pytest.approx(0.06) and axle.length == pytest.approx(1.6)  # r * max(sx, sy), l * sz
        assert axle.pose.roll == pytest.approx(math.pi / 2)  # offsets are not scaled
        assert ball.dynamic and ball.mass == 2.0

    def test_only_the_first_state_block_counts_and_removed_models_are_ignored(self) -> None:
        world = self.world()
        assert world.model("asphalt_plane").pose.x == -8.53833
        assert "removed_long_ago" not in world

    def test_export_leaves_no_state(self) -> None:
        text = dump_sdf(self.world())
        assert "<state" not in text and "removed_long_ago" not in text
        assert_close(parse_sdf(text), self.world())


# -- every import feature ----------------------------------------------------------------------------------
def test_includes_resolve_through_explicit_model_paths() -> None:
    world = features()
    assert world.names == ("crate_a", "cone_barrel", "crate_b", "frames", "stacked", "meshes", "outer")
    crate = world.model("crate_a")
    assert crate.pose == Pose(1.0, 2.0, 0.0, 0.0, 0.0, math.pi / 2)  # <include><pose> replaces the model pose
    assert crate.dynamic and crate.mass == 12.5 and (crate.mu, crate.mu2) == (0.7, 0.6)
    mesh = crate.shapes[0]
    assert mesh.kind == "mesh" and Path(mesh.mesh or "") == (MODELS / "crate" / "meshes" / "crate.obj").resolve()
    assert mesh.scale == (2.0, 1.0, 1.0)
    other = world.model("crate_b")
    assert other.static and other.pose == Pose(0.0, 0.0, 0.5)  # <static> override; the model's own pose


def test_stock_sun_and_ground_plane_includes_work_without_gazebo_installed() -> None:
    assert features().ground == Ground(z=0.25, mu=100.0, mu2=50.0)


@pytest.mark.parametrize("variable", ["GAZEBO_MODEL_PATH", "GZ_SIM_RESOURCE_PATH", "SDF_PATH"])
def test_includes_resolve_through_the_environment(monkeypatch: pytest.MonkeyPatch, variable: str) -> None:
    monkeypatch.setenv(variable, f"/nonexistent/models{__import__('os').pathsep}{MODELS}")
    world = load_sdf(DATA / "features.world")
    assert "crate_a" in world
    assert World.load(DATA / "features.world").names == world.names  # World.load dispatches by extension


def test_model_search_path_order() -> None:
    paths = model_search_paths(["/extra"], {"GAZEBO_MODEL_PATH": "/g1:/g2", "SDF_PATH": "/s", "GZ_SIM_RESOURCE_PATH": ""})
    assert paths == (Path("/extra"), Path("/g1"), Path("/g2"), Path("/s"))


def test_model_config_picks_the_newest_supported_sdf() -> None:
    # crate/model.config lists 1.5, 1.6 and 1.9 files; only model.sdf (1.6) exists and is the one chosen
    assert features().model("crate_a").mass == 12.5


def test_relative_to_frames_and_links() -> None:
    frames = features().model("frames")
    assert frames.pose.position == pytest.approx([10.0, 0.0, 1.0]) and frames.pose.yaw == pytest.approx(math.pi / 2)
    base, top, side = frames.shapes
    assert base.pose == Pose()
    assert top.pose.position == pytest.approx([0.0, 0.0, 1.0])  # relative_to="base"
    assert side.pose.position == pytest.approx([0.0, 1.0, 0.0])  # collision relative_to another link
    assert world_xyz(features(), "frames", 2) == pytest.approx([9.0, 0.0, 1.0])


def test_model_pose_relative_to_another_model() -> None:
    stacked = features().model("stacked")
    assert stacked.pose.position == pytest.approx([10.0, 0.0, 3.0])
    assert stacked.pose.yaw == pytest.approx(math.pi / 2)


def test_mass_friction_bullet_and_restitution() -> None:
    stacked = features().model("stacked")
    assert stacked.mass == 4.0  # 3 kg + 1 kg Gazebo default for the link without <inertial>
    assert (stacked.mu, stacked.mu2) == (0.4, 0.3)  # SDF 1.7 <bullet> friction when <ode> is absent
    assert stacked.restitution == 0.5


def test_meshes_with_degrees_scale_and_collada_unit() -> None:
    world = features()
    meshes = world.model("meshes")
    assert meshes.pose.yaw == pytest.approx(math.pi / 2)  # <pose degrees="true">
    stl, dae = meshes.shapes
    assert Path(stl.mesh or "").name == "block.stl" and stl.scale == (1.0, 1.0, 1.0)
    assert dae.scale == pytest.approx((0.0254, 0.0254, 0.0508))  # inch unit times <scale>1 1 2</scale>


def test_collada_meshes_have_their_size_in_metres() -> None:
    pytest.importorskip("collada", reason="trimesh reads .dae files only with pycollada installed")
    world = features()
    low, high = world.bounds("meshes")
    extent = high - low
    assert extent[2] == pytest.approx(2.0 + 30 * 0.0508 / 2 + 0.1, abs=1e-6)  # dae box 30 in high, scaled 2x in z


def test_nested_models_are_merged_into_their_parent() -> None:
    outer = features().model("outer")
    assert len(outer.shapes) == 2
    assert outer.shapes[1].pose.position == pytest.approx([2.0, 0.0, 1.0])


def test_models_without_collisions_are_skipped() -> None:
    assert "visual_only" not in features()


def test_single_model_file() -> None:
    world = load_sdf(DATA / "single_model.sdf")
    assert world.names == ("cinder_block",) and world.ground is None and world.name == "single_model"
    block = world.model("cinder_block")
    assert block.pose == Pose(4.448, -1.102, 0.872, 0.0, 0.0, -0.032)
    assert block.dynamic and block.mass == 5.0 and len(block.shapes) == 2


def test_sdf_1_4_world_with_gravity_in_physics() -> None:
    world = load_sdf(DATA / "v14.world")
    assert world.physics.gravity == (0.0, 0.0, -3.7)
    assert world.model("rock").pose == Pose(1.0, 1.0, 0.5)


def test_frame_attribute_of_sdf_1_5_and_1_6() -> None:
    text = """<sdf version="1.6"><world name="w"><model name="m"><static>1</static><pose frame="">1 0 0 0 0 0</pose>
    <link name="l"><pose frame="m">0 0 2 0 0 0</pose>
    <collision name="c"><geometry><box><size>1 1 1</size></box></geometry></collision></link></model></world></sdf>"""
    assert parse_sdf(text).model("m").pose == Pose(1.0, 0.0, 2.0)


def test_quaternion_poses() -> None:
    text = """<sdf version="1.7"><world name="w"><model name="m"><static>1</static>
    <pose rotation_format="quat_xyzw">0 0 1 0 0 0.7071067811865476 0.7071067811865476</pose>
    <link name="l"><collision name="c"><geometry><box><size>1 1 1</size></box></geometry></collision></link>
    </model></world></sdf>"""
    assert parse_sdf(text).model("m").pose.yaw == pytest.approx(math.pi / 2)


# -- export -------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", SHIPPED)
def test_yaml_to_sdf_to_yaml_round_trip(name: str) -> None:
    world = yaml_world(name)
    again = parse_sdf(dump_sdf(world), source=WORLDS / f"{name}.world")
    world = dataclasses.replace(world, models=tuple(  # the export writes a mesh file's absolute path
        dataclasses.replace(m, shapes=tuple(dataclasses.replace(s, mesh=str(WORLDS / s.mesh)) if s.kind == "mesh"
                                            else s for s in m.shapes)) for m in world.models))
    if again != world:  # exact in practice; the contract is 1e-9
        assert_close(again, world)


@pytest.mark.parametrize("name", SCENARIOS)
def test_shipped_sdf_worlds_are_the_exported_yaml(name: str) -> None:
    path = WORLDS / f"{name}.world"
    assert path.read_text(encoding="utf-8") == dump_sdf(yaml_world(name)), (
        f"{path.name} is out of date: python tools/make_scenario_worlds.py --sdf")


def test_shipped_ditch_world_loads_through_world_load() -> None:
    world = World.load(WORLDS / "rubble.world")
    assert len(world) == 36
    assert_close(world, yaml_world("rubble"))


def test_export_is_sdf_1_6_with_collision_visual_mass_friction_and_colour() -> None:
    root = ET.fromstring(dump_sdf(yaml_world("friction")))
    assert root.tag == "sdf" and root.get("version") == "1.6"
    world = root.find("world")
    assert world is not None and world.find("state") is None
    models = {model.get("name"): model for model in world.findall("model")}
    assert "ground_plane" in models and models["ground_plane"].find("link/collision/geometry/plane") is not None
    tile = models["grey_wall"]
    assert tile.findtext("static") == "true"
    assert tile.findtext("link/collision/surface/friction/ode/mu") == "1000.0"
    assert tile.findtext("link/collision/surface/friction/ode/mu2") == "500.0"
    assert tile.findtext("link/visual/material/ambient") == "1.0 0.1 0.1 1.0"
    assert tile.find("link/visual/geometry/box") is not None
    barrel = models["Construction Barrel_2"]
    assert barrel.findtext("link/inertial/mass") == "500.0"
    assert len(barrel.findall("link/collision")) == 2 and len(barrel.findall("link/visual")) == 2
    assert world.find("light") is not None and world.find("physics") is not None


def test_export_of_a_sub_world_names_no_removed_model() -> None:
    world = yaml_world("rubble").select(["asphalt_plane", "cinder_block"])
    text = dump_sdf(world)
    assert "lumber" not in text and "cinder_block_0" not in text
    assert parse_sdf(text).names == ("asphalt_plane", "cinder_block")


def test_export_of_meshes_keeps_their_size(tmp_path: Path) -> None:
    world = features()
    path = tmp_path / "out.world"
    world.save(path)
    again = World.load(path)
    assert_close(again.model("meshes"), world.model("meshes"))
    dae_scale = ET.parse(path).getroot().find(".//model[@name='meshes']/link/collision[2]/geometry/mesh/scale")
    assert dae_scale is not None and dae_scale.text == "1.0 1.0 2.0"  # Gazebo applies the inch unit itself


def test_export_keeps_keep_and_tags() -> None:
    model = Model("m", (Shape("box", size=(1.0, 1.0, 1.0)),), keep=True, tags={"a": "x", "b": 2, "c": 0.5, "d": True})
    world = World(models=(model,), name="w", scenario=Scenario(start=Pose(1.0, 2.0, 3.0, yaw=0.5), start_z_given=True,
                                                     goal=(1.0, 2.0, 0.5)))
    assert parse_sdf(dump_sdf(world)) == world


def test_export_of_an_unnamed_world_is_named_default() -> None:
    assert parse_sdf(dump_sdf(World())).name == "default"


def test_export_without_ground_or_scenario() -> None:
    world = World(models=(Model("m", (Shape("sphere", radius=0.5),), mass=2.0, static=False),), ground=None, name="w")
    again = parse_sdf(dump_sdf(world))
    assert again.ground is None and again.scenario is None and again == world


# -- bad and hostile input ----------------------------------------------------------------------------------------
def write(tmp_path: Path, text: str, name: str = "bad.world") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def model_xml(geometry: str, name: str = "m", extra: str = "") -> str:
    return (f'<sdf version="1.6"><world name="w"><model name="{name}"><static>1</static>{extra}<link name="l">'
            f'<collision name="c"><geometry>{geometry}</geometry></collision></link></model></world></sdf>')


def test_malformed_xml_names_its_line(tmp_path: Path) -> None:
    path = write(tmp_path, '<sdf version="1.6">\n<world name="w">\n<model name="a">\n</world>\n</sdf>\n')
    with pytest.raises(WorldError, match="malformed XML") as error:
        load_sdf(path)
    assert error.value.line == 4 and error.value.source == str(path) and f"{path}:4" in str(error.value)


BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE sdf [
 <!ENTITY lol "lol">
 <!ENTITY lol1 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol2 "&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
 <!ENTITY lol9 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
]>
<sdf version="1.6"><world name="&lol9;"/></sdf>
"""
EXTERNAL_ENTITY = """<?xml version="1.0"?>
<!DOCTYPE sdf [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>
<sdf version="1.6"><world name="&xxe;"/></sdf>
"""
EXTERNAL_DTD = """<?xml version="1.0"?>
<!DOCTYPE sdf SYSTEM "http://example.invalid/sdf.dtd">
<sdf version="1.6"><world name="w"/></sdf>
"""


@pytest.mark.parametrize("text", [BILLION_LAUGHS, EXTERNAL_ENTITY, EXTERNAL_DTD], ids=["laughs", "xxe", "dtd"])
def test_entity_attacks_are_refused(tmp_path: Path, text: str) -> None:
    with pytest.raises(WorldError, match="not allowed") as error:
        load_sdf(write(tmp_path, text))
    assert error.value.line is not None


def test_hostile_collada_mesh_is_refused(tmp_path: Path) -> None:
    (tmp_path / "evil.dae").write_text(BILLION_LAUGHS.replace("sdf", "COLLADA"), encoding="utf-8")
    with pytest.raises(sdf.UnsupportedSdfError, match="not allowed") as error:  # unreadable: skip_unsupported drops it
        load_sdf(write(tmp_path, model_xml("<mesh><uri>evil.dae</uri></mesh>")))
    assert f"cannot read {tmp_path / 'evil.dae'}: XML document type declarations" in str(error.value)


def test_files_over_the_size_limit_are_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_xml, "MAX_FILE_BYTES", 1000)
    path = write(tmp_path, model_xml("<box><size>1 1 1</size></box>") + " " * 2000)
    with pytest.raises(WorldError, match="larger than the 1000 byte limit"):
        load_sdf(path)
    with pytest.raises(WorldError, match="larger than"):
        parse_sdf(path.read_text())


def test_unsupported_geometry(tmp_path: Path) -> None:
    with pytest.raises(sdf.UnsupportedSdfError, match="unsupported <ellipsoid>") as error:
        load_sdf(write(tmp_path, model_xml("<ellipsoid><radii>1 2 3</radii></ellipsoid>", name="egg")))
    assert error.value.model == "egg" and error.value.field == "link 'l'/collision 'c'/geometry/ellipsoid"
    assert error.value.element == "ellipsoid" and "--skip-unsupported" in str(error.value)


def test_missing_mesh_file(tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="missing mesh file .*nothing.stl") as error:
        load_sdf(write(tmp_path, model_xml("<mesh><uri>meshes/nothing.stl</uri></mesh>", name="rock")))
    assert error.value.model == "rock" and error.value.line == 1


def test_unsupported_mesh_format(tmp_path: Path) -> None:
    (tmp_path / "m.ply").write_text("ply\n")
    with pytest.raises(sdf.UnsupportedSdfError, match="unsupported <mesh>: format '.ply'"):
        load_sdf(write(tmp_path, model_xml("<mesh><uri>m.ply</uri></mesh>")))


def test_unresolvable_include_names_the_model_and_the_paths(tmp_path: Path) -> None:
    path = write(tmp_path, '<sdf version="1.6"><world name="w"><include><uri>model://husky_tower</uri></include>'
                           "</world></sdf>")
    with pytest.raises(WorldError, match="model://husky_tower") as error:
        load_sdf(path, model_paths=[MODELS, tmp_path / "more"])
    message = str(error.value)
    assert str(MODELS) in message and str(tmp_path / "more") in message and "--ddenv-model-path" in message


def test_remote_include_is_not_fetched(tmp_path: Path) -> None:
    path = write(tmp_path, '<sdf version="1.6"><world name="w"><include>'
                           "<uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Cone</uri></include></world></sdf>")
    with pytest.raises(sdf.UnsupportedSdfError, match="Gazebo Fuel model OpenRobotics/Cone is not here: not "
                                                      "in the Fuel cache"):
        load_sdf(path)


def test_include_cycle_is_an_error(tmp_path: Path) -> None:
    loop = tmp_path / "loop"
    loop.mkdir()
    (loop / "model.sdf").write_text('<sdf version="1.6"><model name="loop"><include><uri>model://loop</uri></include>'
                                    "</model></sdf>")
    path = write(tmp_path, '<sdf version="1.6"><world name="w"><include><uri>model://loop</uri></include>'
                           "</world></sdf>")
    with pytest.raises(WorldError, match="nested more than"):
        load_sdf(path, model_paths=[tmp_path])


BAD_DOCUMENT_IDS = [
    "root", "no-version", "old-version", "no-world", "not-a-number", "count", "negative-size", "cylinder-length",
    "static", "unknown-frame", "nan", "two-shapes", "dynamic-plane", "include-uri", "submesh",
]


@pytest.mark.parametrize(
    ("text", "message"),
    ids=BAD_DOCUMENT_IDS,
    argvalues=[
        ('<world name="w"/>', "expected an <sdf> root"),
        ('<sdf><world name="w"/></sdf>', "no version"),
        ('<sdf version="1.1"><world name="w"/></sdf>', "not supported"),
        ('<sdf version="1.6"><light name="l"/></sdf>', "neither a <world> nor a <model>"),
        (model_xml("<box><size>1 x 1</size></box>"), "expected numbers"),
        (model_xml("<box><size>1 1</size></box>"), "expected 3 numbers"),
        (model_xml("<box><size>1 -1 1</size></box>"), "must be positive"),
        (model_xml("<cylinder><radius>1</radius><length> </length></cylinder>"), "expected 1 numbers, got 0"),
        (model_xml("<box><size>1 1 1</size></box>").replace("<static>1<", "<static>maybe<"), "true/false"),
        (model_xml("<box><size>1 1 1</size></box>", extra='<pose relative_to="nowhere">0 0 0 0 0 0</pose>'),
         "unknown frame 'nowhere'"),
        (model_xml("<box><size>1 1 1</size></box>", extra="<pose>0 0 nan 0 0 0</pose>"), "finite"),
        (model_xml("<box><size>1 1 1</size></box><box><size>1 1 1</size></box>"), "exactly one shape"),
        (model_xml("<plane><normal>0 0 1</normal></plane>").replace("<static>1</static>", "<static>0</static>"),
         "unsupported <plane>: a collision plane of a dynamic model"),
        ('<sdf version="1.6"><world name="w"><include/></world></sdf>', "needs a <uri>"),
        (model_xml("<mesh><uri>x.stl</uri><submesh><name>a</name></submesh></mesh>"), "submesh"),
    ],
)
def test_bad_documents(text: str, message: str) -> None:
    with pytest.raises(WorldError, match=message):
        parse_sdf(text, source="bad.world")


def test_frame_cycle_is_an_error() -> None:
    text = """<sdf version="1.7"><world name="w"><model name="m"><static>1</static>
    <frame name="a"><pose relative_to="b"/></frame><frame name="b"><pose relative_to="a"/></frame>
    <link name="l"><pose relative_to="a"/><collision name="c"><geometry><box><size>1 1 1</size></box></geometry>
    </collision></link></model></world></sdf>"""
    with pytest.raises(WorldError, match="cycle"):
        parse_sdf(text)


def test_two_ground_planes_are_an_error() -> None:
    plane = "<plane><normal>0 0 1</normal></plane>"
    text = model_xml(plane, name="g1").replace("</world>", model_xml(plane, name="g2").split('<world name="w">')[1]
                                               .replace("</sdf>", ""))
    with pytest.raises(WorldError, match="second ground plane"):
        parse_sdf(text)


# -- simulation ----------------------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("name", SCENARIOS)
def test_import_of_exported_scenarios_reproduces_the_same_simulation(name: str) -> None:
    sim = pytest.importorskip("pytest_ddenv.sim")
    original = yaml_world(name)
    exported = load_sdf(WORLDS / f"{name}.world")
    first = sim.simulate(original, seed=3, timeout=1.5)
    second = sim.simulate(exported, seed=3, timeout=1.5)
    assert np.array_equal(first.poses, second.poses)
    assert first.reached_goal == second.reached_goal


def test_bad_ddenv_scenario_is_a_scenario_error() -> None:
    from pytest_ddenv.errors import ScenarioError

    text = (f'<sdf version="1.6" xmlns:ddenv="{sdf.DDENV_NS}"><world name="w"><ddenv:scenario timeout="-1">'
            '<ddenv:start x="0" y="0"/><ddenv:goal x="1" y="0"/></ddenv:scenario></world></sdf>')
    with pytest.raises(ScenarioError, match="timeout"):
        parse_sdf(text, source="x.world")
