"""Issue 28, point 5: Gazebo worlds as they are shipped.

* Fuel URIs (every current turtlebot3 world) are read from the local Fuel cache in the layout Gazebo's fuel
  tools write (`~/.gz/fuel/<server>/<owner>/models/<name>/<version>/`, the older `~/.ignition/fuel`; the highest
  version unless the URI names one), or from the model path by the model's name; the well-known `Ground Plane`
  and `Sun` work when they are not cached; a missing Fuel model says how to get it.
* Bare include names (`<uri>x500</uri>`) are found through the model path, as Gazebo's resource path finds them.
* A link and a joint of the same name are allowed before SDF 1.7, as libsdformat allows them.
* `<cone>` is a shape; a misspelt geometry (`<bx>`) is an error, not a collision silently dropped.
* `--skip-unsupported` also drops a model whose mesh cannot be read, with its warning line.

tests/test_sdf_sdformat.py checks the same worlds against libsdformat where it is installed.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from pytest_ddenv import World, sdf
from pytest_ddenv.cli import main as cli
from pytest_ddenv.errors import WorldError
from pytest_ddenv.sdf import UnsupportedSdfError, load_sdf, parse_sdf

CONE_URL = "https://fuel.gazebosim.org/1.0/OpenRobotics/models/Construction Cone"
BOX = '<collision name="c"><geometry><box><size>{}</size></box></geometry></collision>'
GROUND = '<include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Ground Plane</uri></include>'
SUN = '<include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Sun</uri></include>'


@pytest.fixture(autouse=True)
def home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty home folder: no Fuel cache and no model path but what a test lays out."""
    folder = tmp_path / "home"
    folder.mkdir()
    monkeypatch.setenv("HOME", str(folder))
    for variable in (*sdf.MODEL_PATH_VARIABLES, *sdf.FUEL_CACHE_VARIABLES):
        monkeypatch.delenv(variable, raising=False)
    return folder


def model_folder(folder: Path, name: str, size: str, *, version: str = "1.6", mesh: str = "") -> Path:
    """A Gazebo model folder (model.config and model.sdf) holding one static box of `size`."""
    folder.mkdir(parents=True)
    geometry = BOX.format(size) if not mesh else (
        f'<collision name="c"><geometry><mesh><uri>{mesh}</uri></mesh></geometry></collision>')
    (folder / "model.sdf").write_text(f'<?xml version="1.0"?>\n<sdf version="{version}"><model name="{name}">'
                                      f'<static>true</static><link name="link">{geometry}</link></model></sdf>\n')
    (folder / "model.config").write_text(f'<?xml version="1.0"?>\n<model><name>{name}</name>'
                                         f'<sdf version="{version}">model.sdf</sdf></model>\n')
    return folder


def fuel_cache(root: Path, name: str = "Construction Cone", *, server: str = "fuel.gazebosim.org",
               versions: dict[str, str] | None = None) -> Path:
    """`gz fuel download`'s layout: owner and name lowercased, one folder per version."""
    models = root / server / "openrobotics" / "models" / name.lower()
    for version, size in (versions or {"1": "1 1 1", "3": "0.4 0.4 0.8"}).items():
        model_folder(models / version, "construction_cone", size)
    return models


def world(*includes: str, version: str = "1.6") -> str:
    return f'<?xml version="1.0"?>\n<sdf version="{version}"><world name="w">{"".join(includes)}</world></sdf>\n'


def include(uri: str, name: str = "", pose: str = "2 0 0 0 0 0") -> str:
    return f"<include><uri>{uri}</uri>{f'<name>{name}</name>' if name else ''}<pose>{pose}</pose></include>"


# -- Fuel -----------------------------------------------------------------------------------------------------------
def test_a_fuel_uri_is_read_from_the_fuel_cache_at_its_highest_version(home: Path, tmp_path: Path) -> None:
    fuel_cache(home / ".gz" / "fuel")
    path = tmp_path / "turtlebot3.world"
    path.write_text(world(GROUND, SUN, include(CONE_URL, "cone")))
    loaded = load_sdf(path)
    assert loaded.names == ("cone",) and loaded.ground is not None
    assert loaded.model("cone").shapes[0].size == (0.4, 0.4, 0.8)  # version 3, not 1
    assert loaded.model("cone").pose.x == 2.0


def test_the_older_ignition_cache_a_pinned_version_and_an_encoded_name(home: Path, tmp_path: Path) -> None:
    fuel_cache(home / ".ignition" / "fuel", server="fuel.ignitionrobotics.org",
               versions={"1": "1 1 1", "2": "0.5 0.5 0.5", "3": "0.4 0.4 0.8"})
    uri = "https://fuel.ignitionrobotics.org/1.0/OpenRobotics/models/Construction%20Cone/2"
    loaded = parse_sdf(world(include(uri)), source=str(tmp_path / "w.world"))
    assert loaded.names == ("construction_cone",)  # the included model's own name
    assert loaded.model("construction_cone").shapes[0].size == (0.5, 0.5, 0.5)


def test_the_fuel_cache_variable_replaces_the_default_cache(home: Path, tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    fuel_cache(home / ".gz" / "fuel", versions={"1": "1 1 1"})
    fuel_cache(tmp_path / "cache", versions={"1": "0.2 0.2 0.2"})
    monkeypatch.setenv("GZ_FUEL_CACHE_PATH", str(tmp_path / "cache"))
    loaded = parse_sdf(world(include(CONE_URL, "cone")), source=str(tmp_path / "w.world"))
    assert loaded.model("cone").shapes[0].size == (0.2, 0.2, 0.2)


def test_a_fuel_mesh_uri_is_read_from_the_cached_model(home: Path, tmp_path: Path) -> None:
    cached = home / ".gz" / "fuel" / "fuel.gazebosim.org" / "openrobotics" / "models" / "construction cone" / "2"
    mesh_uri = f"{CONE_URL}/tip/files/meshes/cone.stl"
    model_folder(cached, "construction_cone", "", mesh=mesh_uri)
    (cached / "meshes").mkdir()
    (cached / "meshes" / "cone.stl").write_text(STL_TETRAHEDRON)
    loaded = parse_sdf(world(include(CONE_URL, "cone")), source=str(tmp_path / "w.world"))
    assert Path(loaded.model("cone").shapes[0].mesh or "") == cached / "meshes" / "cone.stl"


def test_a_fuel_uri_is_found_on_the_model_path_by_its_name(tmp_path: Path) -> None:
    model_folder(tmp_path / "models" / "construction_cone", "construction_cone", "0.3 0.3 0.6")
    loaded = parse_sdf(world(include(CONE_URL, "cone")), source=str(tmp_path / "w.world"),
                       model_paths=[tmp_path / "models"])
    assert loaded.model("cone").shapes[0].size == (0.3, 0.3, 0.6)


def test_fuel_ground_plane_and_sun_work_when_not_cached(tmp_path: Path) -> None:
    loaded = parse_sdf(world(GROUND, SUN), source=str(tmp_path / "w.world"))
    assert loaded.ground is not None and loaded.ground.z == 0.0 and loaded.names == ()
    assert any(note.startswith("lights: sun;") for note in loaded.notes), loaded.notes


def test_a_missing_fuel_model_says_how_to_get_it(home: Path, tmp_path: Path) -> None:
    text = world(GROUND, include(CONE_URL, "cone"), '<model name="kept"><static>1</static><link name="l">'
                 + BOX.format("1 1 1") + "</link></model>")
    with pytest.raises(UnsupportedSdfError) as caught:
        parse_sdf(text, source=str(tmp_path / "w.world"), model_paths=[tmp_path])
    message = str(caught.value)
    assert caught.value.model == "cone" and caught.value.field == "include/uri"
    caches = f"{home / '.gz' / 'fuel'}, {home / '.ignition' / 'fuel'}"
    assert f"not in the Fuel cache ({caches}: fuel.gazebosim.org/openrobotics/models/construction cone/VERSION)" in message
    assert f"nor on the model path ({tmp_path}) as a folder 'Construction Cone' or 'construction_cone'" in message
    assert f"; get it with: gz fuel download -u '{CONE_URL}'; to load the world without" in message
    assert "unsupported <" not in message and "never fetched" not in message
    skipped = parse_sdf(text, source=str(tmp_path / "w.world"), skip_unsupported=True)
    assert skipped.names == ("kept",)
    assert skipped.notes[0].startswith("dropped cone: Gazebo Fuel model OpenRobotics/Construction Cone is not "
                                       "here")


def test_a_remote_uri_that_is_not_fuel_says_so(tmp_path: Path) -> None:
    with pytest.raises(UnsupportedSdfError, match="is not a Gazebo Fuel model URL; remote files are never "
                                                  "downloaded: download it and name it by its local path"):
        parse_sdf(world(include("https://example.com/crate.sdf")), source=str(tmp_path / "w.world"))


# -- bare include names -----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("variable", ["GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "GAZEBO_MODEL_PATH", None])
def test_a_bare_include_name_is_found_through_the_resource_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                variable: str | None) -> None:
    model_folder(tmp_path / "models" / "x500", "x500", "0.5 0.5 0.2", version="1.9")
    if variable is not None:
        monkeypatch.setenv(variable, str(tmp_path / "models"))
    paths = [tmp_path / "models"] if variable is None else []
    loaded = parse_sdf(world(include("x500", pose="1 2 0 0 0 0"), version="1.9"), source=str(tmp_path / "w.world"),
                       model_paths=paths)
    assert loaded.names == ("x500",) and (loaded.model("x500").pose.x, loaded.model("x500").pose.y) == (1.0, 2.0)


def test_a_bare_include_name_that_is_nowhere_lists_where_it_was_looked_for(tmp_path: Path) -> None:
    with pytest.raises(WorldError) as caught:
        parse_sdf(world(include("x500")), source=str(tmp_path / "w.world"), model_paths=[tmp_path])
    assert "cannot resolve include 'x500'" in str(caught.value) and str(tmp_path) in str(caught.value)


# -- same-named link and joint before SDF 1.7 -------------------------------------------------------------------------
def arm(version: str) -> str:
    return (f'<sdf version="{version}"><world name="w"><model name="arm"><pose>1 0 0 0 0 0</pose>'
            '<link name="base"><pose>0 0 0.5 0 0 0</pose>' + BOX.format("1 1 1") + "</link>"
            '<link name="attachment"><pose>0 2 0.5 0 0 0</pose>' + BOX.format("0.5 0.5 0.5") + "</link>"
            '<joint name="attachment" type="fixed"><parent>base</parent><child>attachment</child></joint>'
            "</model></world></sdf>")


@pytest.mark.parametrize("version", ["1.4", "1.5", "1.6"])
def test_a_link_and_a_joint_of_the_same_name_are_allowed_before_sdf_1_7(version: str) -> None:
    loaded = parse_sdf(arm(version), source="arm.world")
    shapes = loaded.model("arm").shapes
    assert len(shapes) == 2 and shapes[1].pose.y == 2.0
    assert any(note.startswith("joints: arm (1 joint)") for note in loaded.notes)


def test_a_link_and_a_joint_of_the_same_name_are_an_error_from_sdf_1_7() -> None:
    with pytest.raises(WorldError, match="two frames, links, joints or models named 'attachment'"):
        parse_sdf(arm("1.7"), source="arm.world")


# -- cones and misspelt geometry ----------------------------------------------------------------------------------------
def cone_world(geometry: str = "<cone><radius>0.5</radius><length>1.2</length></cone>", *,
               static: str = "true") -> str:
    return (f'<?xml version="1.0"?>\n<sdf version="1.11"><world name="w">\n<model name="cone">'
            f"<static>{static}</static><pose>2 0 0.6 0 0 0</pose>\n<link name=\"l\">\n<collision name=\"c\">"
            f"<geometry>\n{geometry}\n</geometry></collision></link></model></world></sdf>\n")


def test_a_cone_is_a_shape() -> None:
    loaded = parse_sdf(cone_world(), source="cone.world")
    shape = loaded.model("cone").shapes[0]
    assert (shape.kind, shape.radius, shape.length) == ("cone", 0.5, 1.2)
    defaults = parse_sdf(cone_world("<cone/>"), source="cone.world").model("cone").shapes[0]
    assert (defaults.radius, defaults.length) == (1.0, 1.0)  # SDF 1.11's defaults


def built(world: World, seconds: float = 0.0) -> tuple[int, dict[str, int]]:
    """`world` built in a new pybullet client (and simulated `seconds`): the client and each model's body."""
    import pybullet

    from pytest_ddenv.sim.builder import build_world

    client = pybullet.connect(pybullet.DIRECT)
    pybullet.setGravity(0, 0, -9.81, physicsClientId=client)
    bodies = build_world(pybullet, client, world)
    for _ in range(round(seconds * 240)):
        pybullet.stepSimulation(physicsClientId=client)
    return client, {name: body for body, name in bodies.items()}


@pytest.mark.pybullet
def test_a_cone_is_simulated_as_a_cone_not_a_cylinder() -> None:
    """A ray straight down at 0.4 m from the axis meets the cone's slanted side low (a cylinder of the same size
    would be met at its top, 1.2 m up); its bounds and distances are the cone's."""
    import pybullet

    loaded = parse_sdf(cone_world(), source="cone.world")
    client, _ = built(loaded)
    try:
        hit = pybullet.rayTest([2.4, 0.0, 5.0], [2.4, 0.0, -1.0], physicsClientId=client)[0]
    finally:
        pybullet.disconnect(client)
    slant = 1.2 * (1.0 - 0.4 / 0.5)  # the side's height at 0.4 m from the axis: 0.24 m
    assert hit[0] >= 0 and abs(hit[3][2] - slant) < 0.03, hit
    low, high = loaded.bounds("cone")
    assert low.tolist() == pytest.approx([1.5, -0.5, 0.0]) and high.tolist() == pytest.approx([2.5, 0.5, 1.2])
    above_the_tip, beside_the_rim, inside = [[2.0, 0.0, 2.0]], [[3.0, 0.0, 0.0]], [[2.1, 0.0, 0.3]]
    assert loaded.distances(above_the_tip)[0, 0] == pytest.approx(0.8)
    assert loaded.distances(beside_the_rim)[0, 0] == pytest.approx(0.5)
    assert loaded.distances(inside)[0, 0] == 0.0


@pytest.mark.pybullet
def test_a_dynamic_cone_falls_and_stands_on_its_base() -> None:
    import pybullet

    loaded = World.from_yaml("format: 1\nground: {}\nmodels:\n  - {name: cone, pose: [0, 0, 1.0], mass: 2, "
                             "static: false, cone: {radius: 0.3, length: 0.8}}\n")
    client, bodies = built(loaded, 3.0)
    try:
        low, high = pybullet.getAABB(bodies["cone"], physicsClientId=client)
        _, orientation = pybullet.getBasePositionAndOrientation(bodies["cone"], physicsClientId=client)
    finally:
        pybullet.disconnect(client)
    assert low[2] == pytest.approx(0.0, abs=0.02) and high[2] == pytest.approx(0.8, abs=0.02)
    axis = pybullet.getMatrixFromQuaternion(orientation)[8]  # the z axis's z: upright
    assert axis > 0.999


def test_a_cone_is_scaled_by_the_state_as_a_cylinder_is() -> None:
    text = cone_world().replace("</model></world>", '</model><state world_name="w"><model name="cone">'
                                                    "<scale>2 2 0.5</scale></model></state></world>")
    shape = parse_sdf(text, source="cone.world").model("cone").shapes[0]
    assert (shape.kind, shape.radius, shape.length) == ("cone", 1.0, 0.6)


def test_a_cone_round_trips_through_yaml_and_sdf(tmp_path: Path) -> None:
    loaded = parse_sdf(cone_world(), source=str(tmp_path / "cone.world"))
    assert World.from_yaml(loaded.to_yaml()).models == loaded.models
    loaded.save(tmp_path / "again.world")
    text = (tmp_path / "again.world").read_text()
    assert 'version="1.11"' in text and "<cone>" in text
    assert load_sdf(tmp_path / "again.world").models == loaded.models


@pytest.mark.parametrize(("geometry", "message"), [
    ("<bx><size>1 1 1</size></bx>", "unknown geometry <bx>; expected one of: box, cylinder, sphere, capsule, cone"),
    ("<box><size>1 1 1</size></box><sphre/>", "unknown geometry <sphre>"),
    ("<cone><radius>-1</radius></cone>", "expected a positive number, got -1.0"),
])
def test_a_misspelt_or_bad_geometry_is_an_error_not_a_silent_drop(geometry: str, message: str) -> None:
    with pytest.raises(WorldError) as caught:
        parse_sdf(cone_world(geometry), source="cone.world")
    assert message in str(caught.value) and caught.value.model == "cone" and caught.value.line == 6
    assert not isinstance(caught.value, UnsupportedSdfError)


# -- --skip-unsupported drops a model whose mesh cannot be read ---------------------------------------------------------
STL_TETRAHEDRON = """solid t
facet normal 0 0 -1
 outer loop
  vertex 0 0 0
  vertex 0 1 0
  vertex 1 0 0
 endloop
endfacet
facet normal 0 -1 0
 outer loop
  vertex 0 0 0
  vertex 1 0 0
  vertex 0 0 1
 endloop
endfacet
facet normal -1 0 0
 outer loop
  vertex 0 0 0
  vertex 0 0 1
  vertex 0 1 0
 endloop
endfacet
facet normal 1 1 1
 outer loop
  vertex 1 0 0
  vertex 0 1 0
  vertex 0 0 1
 endloop
endfacet
endsolid t
"""


def mesh_model(name: str, uri: str) -> str:
    return (f'<model name="{name}"><static>true</static><link name="l"><collision name="c"><geometry><mesh>'
            f"<uri>{uri}</uri></mesh></geometry></collision></link></model>")


@pytest.mark.parametrize(("mesh", "content", "reason"), [
    ("rock.stl", b"\x00\xff" * 500, "not a mesh file"),
    ("rock.stl", None, "missing mesh file"),
    ("rock.obj", b"just some text\n", "not a mesh file"),
])
def test_skip_unsupported_drops_a_model_whose_mesh_cannot_be_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], mesh: str,
    content: bytes | None, reason: str,
) -> None:
    if content is not None:
        (tmp_path / mesh).write_bytes(content)
    (tmp_path / "good.stl").write_text(STL_TETRAHEDRON)
    (tmp_path / "site.world").write_text(world(mesh_model("rock", mesh), mesh_model("hut", "good.stl")))
    monkeypatch.chdir(tmp_path)
    code = cli.main(["check", "site.world"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_USAGE and reason in err and "--skip-unsupported" in err and len(err.splitlines()) == 1
    code = cli.main(["check", "site.world", "--skip-unsupported"])
    out = capsys.readouterr().out
    assert code == 0 and out.startswith("site.world: 1 model (1 reducible)")
    assert f"\nnot simulated: dropped rock: {reason}" in out
    code = cli.main(["convert", "site.world", "site.yaml", "--skip-unsupported"])
    warning = capsys.readouterr().err.strip()
    assert code == 0 and World.load(tmp_path / "site.yaml").names == ("hut",)
    assert warning.startswith("ddenv: warning: site.world: skip_unsupported dropped 1 model that cannot be simulated: "
                              f"rock: {reason}"), warning
    assert len(warning.splitlines()) == 1


def test_a_fuel_world_is_checked_by_ddenv_with_the_cache_in_home(home: Path, tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    fuel_cache(home / ".gz" / "fuel")
    (tmp_path / "tb3.world").write_text(world(GROUND, SUN, include(CONE_URL, "cone")))
    monkeypatch.chdir(tmp_path)
    assert os.environ["HOME"] == str(home)
    code = cli.main(["check", "tb3.world", "--json"])
    assert code == 0 and json.loads(capsys.readouterr().out)["models"] == 1


def test_a_cached_fuel_include_is_cut_by_its_model_name(home: Path, tmp_path: Path) -> None:
    from pytest_ddenv.sdf import cut_models

    fuel_cache(home / ".gz" / "fuel")
    path = tmp_path / "tb3.world"
    path.write_text(world(GROUND, include(CONE_URL), '<model name="kept"><static>1</static><link name="l">'
                          + BOX.format("1 1 1") + "</link></model>"))
    loaded = load_sdf(path)
    assert loaded.names == ("construction_cone", "kept")
    cut = cut_models(path, {"construction_cone"})
    assert "Construction Cone" not in cut and "Ground Plane" in cut
    assert parse_sdf(cut, source=path) == loaded.without(["construction_cone"])


# -- a scenario for a Gazebo world on the command line: negative coordinates ------------------------------------------
@pytest.mark.parametrize("form", [["--start", "-5,-1", "--goal", "-3,-1"], ["--start", "-5,-1,-0.1", "--goal=-3,-1"]])
def test_start_and_goal_may_be_negative(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                        capsys: pytest.CaptureFixture[str], form: list[str]) -> None:
    (tmp_path / "yard.world").write_text(world(GROUND, '<model name="far"><static>1</static><pose>9 9 0.5 0 0 0</pose>'
                                               '<link name="l">' + BOX.format("1 1 1") + "</link></model>"))
    monkeypatch.chdir(tmp_path)
    code = cli.main(["run", "yard.world", *form, "--timeout", "10", "--no-picture", "--json"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert json.loads(captured.out)["reached_goal"] is True
