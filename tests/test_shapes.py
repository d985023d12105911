"""Capsules, polylines and heightmaps in the world model, the YAML format, pictures and SDF exports; meshes
read for their geometry only (issue 15)."""

from __future__ import annotations

import logging
import math
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from pytest_ddenv import World, WorldError, render
from pytest_ddenv.world import Model, Pose, Shape
from pytest_ddenv.world.values import check_shape
from pytest_ddenv.world.meshes import heightmap_mesh, load_heightmap, load_mesh, polyline_mesh

ROOT = Path(__file__).resolve().parent.parent
TEXTURED_DAE = ROOT / "tests" / "data" / "meshes" / "textured_box.dae"
U_OUTLINE = ((0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (1.6, 2.0), (1.6, 0.4), (0.4, 0.4), (0.4, 2.0), (0.0, 2.0))
"""A U opening towards +y: arms 0.4 m thick, the notch 1.2 m wide and 1.6 m deep."""


def ramp_image(path: Path, *, columns: int = 9, rows: int = 5, bits: int = 8) -> Path:
    """Black at the left (-x) edge to white at the right (+x) edge."""
    top = 255 if bits == 8 else 65535
    row = np.linspace(0, top, columns)
    data = np.tile(row, (rows, 1)).astype(np.uint8 if bits == 8 else np.uint16)
    Image.fromarray(data).save(path)
    return path


def write_world(tmp_path: Path, models: str, name: str = "shapes.yaml") -> Path:
    path = tmp_path / name
    path.write_text(f"format: 1\nmodels:\n{models}")
    return path


def error_of(tmp_path: Path, models: str) -> WorldError:
    with pytest.raises(WorldError) as caught:
        World.load(write_world(tmp_path, models))
    assert "shapes.yaml" in str(caught.value)
    return caught.value


# -- YAML ---------------------------------------------------------------------------------------------------
def test_the_three_kinds_parse_and_round_trip(tmp_path: Path) -> None:
    ramp_image(tmp_path / "ramp.png")
    path = write_world(tmp_path, """\
  - {name: pole, pose: [0, 0, 0.2, 1.5707963, 0, 0], capsule: {radius: 0.2, length: 3}}
  - {name: u, pose: [5, 0, 0], polyline: {points: [[0, 0], [2, 0], [2, 2], [1.6, 2], [1.6, 0.4], [0.4, 0.4], [0.4, 2], [0, 2]], height: 0.8}}
  - name: terrain
    shapes:
      - heightmap: {file: ramp.png, size: [8, 4, 1]}
        pose: [0, 0, 0.1, 0, 0, 0.5]
  - {name: dynamic_u, polyline: {points: [[0, 0], [1, 0], [0, 1]], height: 0.5}, mass: 2}
""")
    world = World.load(path)
    assert world.model("pole").shapes[0] == Shape("capsule", radius=0.2, length=3.0)
    assert world.model("u").shapes[0] == Shape("polyline", points=U_OUTLINE, height=0.8)
    terrain = world.model("terrain").shapes[0]
    assert terrain.kind == "heightmap" and terrain.mesh == "ramp.png" and terrain.size == (8.0, 4.0, 1.0)
    assert terrain.pose == Pose(0, 0, 0.1, 0, 0, 0.5)
    assert world.model("dynamic_u").dynamic
    assert World.from_yaml(world.to_yaml(), source=path) == world
    assert "capsule: {radius: 0.2, length: 3.0}" in world.to_yaml()


def test_a_saved_heightmap_still_finds_its_image(tmp_path: Path) -> None:
    (tmp_path / "terrain").mkdir()
    ramp_image(tmp_path / "terrain" / "ramp.png")
    world = World.load(write_world(tmp_path, "  - {name: hill, heightmap: {file: terrain/ramp.png, size: [8, 4, 1]}}\n"))
    (tmp_path / "out" / "deeper").mkdir(parents=True)
    saved = tmp_path / "out" / "deeper" / "minimal.yaml"
    world.save(saved)
    assert "file: ../../terrain/ramp.png" in saved.read_text()
    again = World.load(saved)
    assert np.allclose(again.bounds("hill"), world.bounds("hill"))


@pytest.mark.parametrize(
    ("models", "field", "message"),
    [
        ("  - {name: m, capsule: {radius: 0.2}}\n", "capsule.length", "missing"),
        ("  - {name: m, capsule: {radius: 0, length: 1}}\n", "capsule.radius", "positive"),
        ("  - {name: m, capsule: {radius: 0.1, length: -1}}\n", "capsule.length", "positive"),
        ("  - {name: m, capsule: {radius: 0.1, length: 1, height: 2}}\n", "capsule.height", "unknown key"),
        ("  - {name: m, polyline: {points: [[0, 0], [1, 0]], height: 1}}\n", "polyline.points", "at least 3 points"),
        ("  - {name: m, polyline: {points: [[0, 0], [1, 1], [2, 2]], height: 1}}\n", "polyline.points", "collinear"),
        ("  - {name: m, polyline: {points: [[0, 0], [1, 1], [1, 0], [0, 1]], height: 1}}\n", "polyline.points",
         "crosses or touches itself"),
        ("  - {name: m, polyline: {points: [[0, 0], [1, 0, 2], [0, 1]], height: 1}}\n", "polyline.points[1]",
         "2 numbers"),
        ("  - {name: m, polyline: {points: [[0, 0], [1, 0], [0, 1]], height: 0}}\n", "polyline.height", "positive"),
        ("  - {name: m, polyline: {points: [[0, 0], [1, 0], [0, 1]]}}\n", "polyline.height", "missing"),
        ("  - {name: m, heightmap: {file: nowhere.png, size: [1, 1, 1]}}\n", "heightmap.file", "not found"),
        ("  - {name: m, heightmap: {file: ramp.png, size: [1, 0, 1]}}\n", "heightmap.size[1]", "positive"),
        ("  - {name: m, heightmap: {file: ramp.png}}\n", "heightmap.size", "missing"),
        ("  - {name: m, heightmap: {file: not_an_image.png, size: [1, 1, 1]}}\n", "heightmap.file",
         "cannot read the heightmap image"),
        ("  - {name: m, heightmap: {file: pixel.png, size: [1, 1, 1]}}\n", "heightmap.file", "at least 2 x 2"),
        ("  - {name: m, heightmap: {file: ramp.png, size: [1, 1, 1]}, mass: 3}\n", "mass", "must be static"),
        (("  - {name: m, shapes: [{box: [1, 1, 1]}, {heightmap: {file: ramp.png, size: [1, 1, 1]}}], static: false,"
          " mass: 1}\n"), "static", "must be static"),
    ],
)
def test_bad_new_shapes_name_file_model_and_field(tmp_path: Path, models: str, field: str, message: str) -> None:
    ramp_image(tmp_path / "ramp.png")
    Image.new("L", (1, 1)).save(tmp_path / "pixel.png")
    (tmp_path / "not_an_image.png").write_text("hello")
    error = error_of(tmp_path, models)
    assert error.model == "'m' (#0)"
    assert error.field is not None and error.field.endswith(field), error.field
    assert message in error.reason


def test_check_shape_speaks_the_callers_field_names(tmp_path: Path) -> None:
    """What an SDF reader calls it to validate the shapes it makes."""
    bad = Shape("polyline", points=((0.0, 0.0), (1.0, 0.0)), height=1.0)
    with pytest.raises(WorldError) as caught:
        check_shape(bad, source="w.sdf", model="wall", field="link/collision/geometry/polyline",
                    keys={"points": "point", "file": "uri"})
    assert caught.value.field == "link/collision/geometry/polyline.point"
    assert str(caught.value).startswith("w.sdf, model wall, field 'link/collision/geometry/polyline.point':")
    with pytest.raises(WorldError, match="must be static"):
        check_shape(Shape("heightmap", mesh=str(ramp_image(tmp_path / "r.png")), size=(1.0, 1.0, 1.0)),
                    static=False)
    check_shape(Shape("capsule", radius=0.1, length=0.5))


def test_docs_example_loads_and_round_trips(tmp_path: Path) -> None:
    text = (ROOT / "docs" / "world-format.md").read_text()
    (example,) = re.findall(r"~~~yaml\n(format: 1\nmodels:\n  - \{name: fallen_pole.*?)~~~", text, flags=re.DOTALL)
    (tmp_path / "terrain").mkdir()
    ramp_image(tmp_path / "terrain" / "hill.png", columns=33, rows=33)
    path = tmp_path / "example.yaml"
    path.write_text(example)
    world = World.load(path)
    assert [m.shapes[0].kind for m in world] == ["capsule", "polyline", "heightmap"]
    low, high = world.bounds("fallen_pole")
    assert low == pytest.approx([3.85, -1.65, 0.0], abs=1e-4) and high == pytest.approx([4.15, 1.65, 0.3], abs=1e-4)
    assert World.from_yaml(world.to_yaml(), source=path) == world


# -- bounds and distances ---------------------------------------------------------------------------------
def test_capsule_bounds_and_distances_are_exact() -> None:
    lying = Model("pole", (Shape("capsule", radius=0.2, length=2.0),), pose=Pose(1, 2, 0.2, 0, math.pi / 2, 0))
    world = World(models=(lying,))
    low, high = world.bounds("pole")
    assert low == pytest.approx([-0.2, 1.8, 0.0]) and high == pytest.approx([2.2, 2.2, 0.4])
    points = np.array([[1, 2, 0.2], [2.1, 2, 0.2], [2.5, 2, 0.2], [1, 2, 1.2], [3.2, 2, 1.2]])
    expected = [0.0, 0.0, 0.3, 0.8, math.hypot(1.2, 1.0) - 0.2]
    assert world.distances(points)[:, 0] == pytest.approx(expected)


def test_polyline_distances_see_the_concave_notch() -> None:
    world = World(models=(Model("u", (Shape("polyline", points=U_OUTLINE, height=1.0),), pose=Pose(10, 0, 0)),))
    low, high = world.bounds("u")
    assert low == pytest.approx([10, 0, 0]) and high == pytest.approx([12, 2, 1])
    points = np.array([
        [10.2, 1.0, 0.5],   # inside the left arm
        [11.0, 1.5, 0.5],   # in the notch: 0.6 m from either arm, 1.1 m above the bottom of the U
        [11.0, 0.2, 0.5],   # inside the bottom
        [11.0, 0.2, 1.3],   # above the bottom
        [13.0, 1.0, 1.5],   # off the right arm, above it
    ])
    expected = [0.0, 0.6, 0.0, 0.3, math.hypot(1.0, 0.5)]
    assert world.distances(points)[:, 0] == pytest.approx(expected)
    assert world.centroid("u") == pytest.approx([11, 1, 0.5])


def test_heightmap_bounds_and_distances_follow_the_image(tmp_path: Path) -> None:
    image = ramp_image(tmp_path / "ramp.png")  # 0 m at x = -4, 1 m at x = +4 (local)
    hill = Model("hill", (Shape("heightmap", mesh=str(image), size=(8.0, 4.0, 1.0)),), pose=Pose(10, 0, 0))
    world = World(models=(hill,))
    low, high = world.bounds("hill")
    assert low == pytest.approx([6, -2, 0]) and high == pytest.approx([14, 2, 1])
    slope = math.cos(math.atan(32 / 255))  # columns 3, 4, 5 (1 m apart) are 95, 127, 159 of 255
    points = np.array([[10, 0, 0.3], [10, 0, 0.6], [14, 1, 0.99], [15, 0, 0.5], [10, 0, -1], [6, 0, 0.0]])
    expected = [0.0, (0.6 - 127 / 255) * slope, 0.0, 1.0, 1.0, 0.0]  # the middle column is 127 of 255
    assert world.distances(points)[:, 0] == pytest.approx(expected, abs=1e-6)


def test_heightmap_image_top_row_is_the_positive_y_edge(tmp_path: Path) -> None:
    data = np.zeros((3, 2), dtype=np.uint8)
    data[0, :] = 255  # the image's top row is white
    Image.fromarray(data).save(tmp_path / "north.png")
    world = World(models=(Model("m", (Shape("heightmap", mesh=str(tmp_path / "north.png"), size=(2.0, 2.0, 1.0)),)),))
    north, south = world.distances(np.array([[0.0, 1.0, 0.5], [0.0, -1.0, 0.5]]))[:, 0]
    assert north == 0.0 and south == pytest.approx(0.5)


def test_heightmaps_of_16_bit_and_colour_images(tmp_path: Path) -> None:
    sixteen = load_heightmap(ramp_image(tmp_path / "ramp16.png", bits=16))
    assert sixteen.shape == (5, 9) and sixteen[0, 0] == 0.0 and sixteen[0, -1] == 1.0
    assert sixteen[0, 4] == pytest.approx(0.5, abs=1e-4)
    Image.new("RGB", (4, 3), (255, 255, 255)).save(tmp_path / "white.png")
    assert np.all(load_heightmap(tmp_path / "white.png") == 1.0)


def test_meshes_of_polylines_and_heightmaps_are_made_once(tmp_path: Path) -> None:
    image = ramp_image(tmp_path / "ramp.png")
    assert heightmap_mesh(image, (8.0, 4.0, 1.0)) is heightmap_mesh(image, (8.0, 4.0, 1.0))
    assert load_heightmap(image) is load_heightmap(image)
    assert not load_heightmap(image).flags.writeable
    mesh = polyline_mesh(U_OUTLINE, 1.0)
    assert mesh is polyline_mesh(U_OUTLINE, 1.0)
    assert mesh.is_watertight and mesh.volume == pytest.approx(4.0 - 1.2 * 1.6)  # type: ignore[attr-defined]


# -- textured meshes -------------------------------------------------------------------------------------------
def test_a_textured_collada_mesh_with_a_missing_texture_loads_quietly(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, capfd: pytest.CaptureFixture[str]
) -> None:
    assert not (TEXTURED_DAE.parent / "textures" / "missing_crate.png").exists()
    mesh_file = tmp_path / "crate.dae"
    shutil.copy(TEXTURED_DAE, mesh_file)  # a new path: nothing cached
    path = write_world(tmp_path, "  - {name: crate, pose: [0, 0, 0.5], mesh: {file: crate.dae}}\n")
    capfd.readouterr()
    with caplog.at_level(logging.DEBUG):
        world = World.load(path)
        low, high = world.bounds("crate")
        above, inside = world.distances(np.array([[0.0, 0.0, 2.0], [0.1, 0.2, 0.5]]))[:, 0]
        render.footprints(world)
    assert low == pytest.approx([-0.5, -0.5, 0.0]) and high == pytest.approx([0.5, 0.5, 1.0])
    assert above == pytest.approx(1.0)
    assert inside == 0.0  # the geometry alone is a closed cube (texture seams would split its vertices)
    noisy = [r for r in caplog.records if r.exc_info or r.levelno >= logging.WARNING or "texture" in r.getMessage()]
    assert noisy == []
    captured = capfd.readouterr()
    assert "Traceback" not in captured.err + captured.out and "texture" not in captured.err


def test_stl_and_obj_meshes_still_load(tmp_path: Path) -> None:
    box = load_mesh(TEXTURED_DAE, (1.0, 1.0, 1.0))
    for suffix in ("stl", "obj"):
        target = tmp_path / f"box.{suffix}"
        box.export(target)  # type: ignore[attr-defined]
        loaded = load_mesh(target, (2.0, 1.0, 1.0))
        bounds = np.asarray(loaded.bounds).ravel()  # type: ignore[attr-defined]
        assert bounds == pytest.approx([-1, -0.5, -0.5, 1, 0.5, 0.5])


# -- pictures ----------------------------------------------------------------------------------------------------
def test_footprints_of_the_new_shapes(tmp_path: Path) -> None:
    image = ramp_image(tmp_path / "ramp.png")
    world = World(models=(
        Model("pole", (Shape("capsule", radius=0.2, length=2.0),), pose=Pose(0, 0, 0.2, 0, math.pi / 2, 0)),
        Model("post", (Shape("capsule", radius=0.2, length=2.0),), pose=Pose(5, 5, 1.2)),
        Model("u", (Shape("polyline", points=U_OUTLINE, height=1.0),), pose=Pose(10, 0, 0, 0, 0, math.pi / 2)),
        Model("hill", (Shape("heightmap", mesh=str(image), size=(8.0, 4.0, 1.0)),), pose=Pose(0, 10, 0)),
    ))
    pole, post, u, hill = render.footprints(world)
    assert pole.area == pytest.approx(2.0 * 0.4 + math.pi * 0.04, rel=0.01)  # a stadium
    assert pole.low == pytest.approx([-1.2, -0.2], abs=1e-3) and pole.top == pytest.approx(0.4)
    assert post.area == pytest.approx(math.pi * 0.04, rel=0.01) and post.top == pytest.approx(2.4)
    assert u.area == pytest.approx(4.0 - 1.2 * 1.6) and len(u.polygons[0]) == len(U_OUTLINE)  # concave
    assert u.low == pytest.approx([8, 0]) and u.high == pytest.approx([10, 2]) and u.top == pytest.approx(1.0)
    assert hill.area == pytest.approx(32.0) and hill.top == pytest.approx(1.0)
    (shading,) = hill.shading
    assert shading.size == (8.0, 4.0) and shading.center == (0.0, 10.0) and shading.heights.shape == (5, 9)
    picture = render.plot_world(world, path=tmp_path / "shapes.png")
    assert picture.stat().st_size > 10_000


# -- SDF export ----------------------------------------------------------------------------------------------------
def test_sdf_export_writes_the_new_elements(tmp_path: Path) -> None:
    image = ramp_image(tmp_path / "ramp.png")
    world = World(models=(
        Model("u", (Shape("polyline", points=U_OUTLINE, height=1.0),)),
        Model("hill", (Shape("heightmap", mesh="ramp.png", size=(8.0, 4.0, 1.0)),), pose=Pose(0, 10, 0)),
    ), source=str(tmp_path / "w.yaml"))
    root = ET.fromstring(world.to_sdf())
    assert root.get("version") == "1.6"
    polyline = root.find("world/model[@name='u']/link/collision/geometry/polyline")
    assert polyline is not None
    assert [p.text for p in polyline.findall("point")][:2] == ["0.0 0.0", "2.0 0.0"]
    assert polyline.findtext("height") == "1.0"
    heightmap = root.find("world/model[@name='hill']/link/collision/geometry/heightmap")
    assert heightmap is not None
    assert heightmap.findtext("uri") == image.resolve().as_uri() and heightmap.findtext("size") == "8.0 4.0 1.0"
    with_capsule = World(models=world.models + (Model("pole", (Shape("capsule", radius=0.1, length=1.0),)),),
                         source=world.source)
    root = ET.fromstring(with_capsule.to_sdf())
    assert root.get("version") == "1.8"  # the first SDF version with <capsule>
    capsule = root.find("world/model[@name='pole']/link/collision/geometry/capsule")
    assert capsule is not None and capsule.findtext("radius") == "0.1" and capsule.findtext("length") == "1.0"


def test_sdf_exports_with_the_new_shapes_load_in_libsdformat(sdformat_check: Path, tmp_path: Path) -> None:
    ramp_image(tmp_path / "ramp.png")
    world = World(models=(
        Model("pole", (Shape("capsule", radius=0.1, length=1.0),), pose=Pose(0, 0, 1), mass=2.0, static=False),
        Model("u", (Shape("polyline", points=U_OUTLINE, height=1.0),), pose=Pose(5, 0, 0)),
        Model("hill", (Shape("heightmap", mesh="ramp.png", size=(8.0, 4.0, 1.0)),), pose=Pose(0, 10, 0)),
        Model("crate", (Shape("box", size=(1.0, 1.0, 1.0)),), pose=Pose(-5, 0, 0.5)),
    ), source=str(tmp_path / "w.yaml"))
    world.save(tmp_path / "all.world")
    world.without(["pole"]).save(tmp_path / "no_capsule.world")
    result = subprocess.run([str(sdformat_check), str(tmp_path / "all.world"), str(tmp_path / "no_capsule.world")],
                            capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "ok, 5 models" in result.stdout and "ok, 4 models" in result.stdout


def test_a_mesh_file_edited_or_read_from_another_folder_is_read_again(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """The mesh cache is per content of the file: the edit-and-rerun loop in one process (a notebook, a long
    pytest-xdist worker) sees the edited mesh, and the same relative name in another folder is another file."""
    triangle = ("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex {x} 0 0\nvertex 0 1 0\nendloop\n"
                "endfacet\nendsolid t\n")
    for folder, x in (("a", 1), ("b", 3)):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "part.stl").write_text(triangle.format(x=x))
    monkeypatch.chdir(tmp_path / "a")
    assert load_mesh(Path("part.stl"), (1.0, 1.0, 1.0)).bounds[1][0] == 1.0  # type: ignore[attr-defined]
    monkeypatch.chdir(tmp_path / "b")
    assert load_mesh(Path("part.stl"), (1.0, 1.0, 1.0)).bounds[1][0] == 3.0  # type: ignore[attr-defined]
    (tmp_path / "b" / "part.stl").write_text(triangle.format(x=5.5))
    assert load_mesh(Path("part.stl"), (1.0, 1.0, 1.0)).bounds[1][0] == 5.5  # type: ignore[attr-defined]
