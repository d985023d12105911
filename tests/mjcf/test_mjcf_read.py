"""MJCF scenes read as worlds: each good scene of tests/data/mjcf/ has the top-level bodies MuJoCo itself reads,
its geoms become shapes where MuJoCo puts them, and what is not simulated is named once."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco", reason='reading MJCF needs mujoco: pip install "pytest-ddenv[mujoco]"')

from pytest_ddenv.errors import WorldError  # noqa: E402
from pytest_ddenv.mjcf import load_mjcf  # noqa: E402
from pytest_ddenv.world import World  # noqa: E402
from pytest_ddenv.world.meshes import load_heightmap, load_mesh  # noqa: E402

CORPUS = Path(__file__).resolve().parents[1] / "data" / "mjcf"
GOOD = sorted(path.name for path in CORPUS.glob("*.xml") if not path.name.startswith("bad_"))


@pytest.mark.parametrize("name", GOOD)
def test_each_good_scene_has_the_top_level_bodies_mujoco_reads(name: str) -> None:
    spec = mujoco.MjSpec.from_file(str(CORPUS / name))
    world = World.load(CORPUS / name)
    assert world.names == tuple(body.name for body in spec.worldbody.bodies)
    assert world.physics.engine == "mujoco"


def test_every_geom_type_becomes_its_shape() -> None:
    world = load_mjcf(CORPUS / "every_geom.xml")
    kinds = {model.name: [shape.kind for shape in model.shapes] for model in world.models}
    assert kinds == {"barrel": ["cylinder"], "bench": ["box", "box"], "crate": ["box"], "post": ["cylinder"],
                     "ball": ["sphere"], "pipe": ["capsule"], "rock": ["mesh"], "ramp": ["mesh"],
                     "bumps": ["heightmap"], "tile": ["box"], "cabinet": ["box", "box"]}
    post, pipe, tile = world.model("post"), world.model("pipe"), world.model("tile")
    assert (post.shapes[0].radius, post.shapes[0].length) == pytest.approx((0.1, 1.2))  # fromto, resolved
    assert post.shapes[0].pose.z == pytest.approx(0.6)
    assert (pipe.shapes[0].radius, pipe.shapes[0].length) == pytest.approx((0.15, 1.2))
    assert pipe.pose.pitch == pytest.approx(np.pi / 2)  # axisangle in degrees (compiler angle="degree")
    assert world.model("crate").shapes[0].size == pytest.approx((0.5, 0.5, 0.5))  # from the default class
    assert world.model("crate").pose.yaw == pytest.approx(np.radians(30))
    assert tile.shapes[0].size == pytest.approx((1.0, 1.0, 0.1))  # a finite plane: a 0.1 m box under it
    assert tile.shapes[0].pose.z == pytest.approx(-0.05)


def test_static_dynamic_mass_friction_colour_and_ground() -> None:
    world = load_mjcf(CORPUS / "every_geom.xml")
    ball, cabinet, crate = world.model("ball"), world.model("cabinet"), world.model("crate")
    assert (ball.static, ball.mass) == (False, pytest.approx(2.0))  # a free joint
    assert not cabinet.static  # a hinge in its subtree: one rigid body, the subtree's mass
    # MuJoCo's masses from geom volumes (density 1000), its visual-only 0.1 m cube counted, as MuJoCo counts it
    assert cabinet.mass == pytest.approx((0.6 * 0.8 * 1.0 + 0.02 * 0.8 * 1.0 + 0.1 ** 3) * 1000)
    assert crate.static and crate.mass is None
    assert len(cabinet.shapes) == 2  # its visual-only geom (contype = conaffinity = 0) is left out
    assert crate.mu == crate.mu2 == pytest.approx(0.8)  # the default class's sliding friction
    assert crate.color == pytest.approx((0.7, 0.5, 0.2, 1.0))
    assert world.model("post").color == pytest.approx((0.1, 0.2, 0.9, 1.0))  # its material's
    assert world.ground is not None and world.ground.mu == pytest.approx(0.9) and world.ground.z == 0.0


def test_shapes_are_where_mujoco_puts_its_geoms() -> None:
    """Every shape's world bounding box equals that of MuJoCo's compiled geom (meshes: their vertices, which
    MuJoCo re-centres; our shape keeps the file's frame)."""
    path = CORPUS / "every_geom.xml"
    model = mujoco.MjSpec.from_file(str(path)).compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    world = load_mjcf(path)
    for name in ("rock", "ramp"):
        ours = world.model(name)
        shape = ours.shapes[0]
        vertices = np.asarray(load_mesh(Path(shape.mesh or ""), shape.scale).vertices)
        placed = ours.pose.compose(shape.pose)
        in_world = vertices @ placed.rotation.T + placed.position
        geom = next(g for g in range(model.ngeom) if model.body(int(model.geom_bodyid[g])).name == name)
        mesh = int(model.geom_dataid[geom])
        start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        theirs = data.geom_xpos[geom] + model.mesh_vert[start:start + count] @ data.geom_xmat[geom].reshape(3, 3).T
        np.testing.assert_allclose(in_world.min(axis=0), theirs.min(axis=0), atol=1e-5)
        np.testing.assert_allclose(in_world.max(axis=0), theirs.max(axis=0), atol=1e-5)
    for name in ("crate", "post", "pipe", "barrel"):
        ours = world.model(name)
        low, high = world.bounds(name)[0], world.bounds(name)[1]
        geom = next(g for g in range(model.ngeom) if model.body(int(model.geom_bodyid[g])).name == name)
        center = ours.pose.compose(ours.shapes[0].pose).position
        np.testing.assert_allclose(center, data.geom_xpos[geom], atol=1e-9)
        assert np.all(low <= data.geom_xpos[geom]) and np.all(data.geom_xpos[geom] <= high)


def test_height_field_is_the_surface_mujoco_reads() -> None:
    """The same heights over the same rectangle: MuJoCo puts the image's top row at +y, as the world model does,
    and stretches its grey levels from the darkest to the brightest (the world model: black to white)."""
    world = load_mjcf(CORPUS / "every_geom.xml")
    model_pose, shape = world.model("bumps").pose, world.model("bumps").shapes[0]
    assert shape.size[:2] == pytest.approx((3.0, 2.0))
    model = mujoco.MjSpec.from_file(str(CORPUS / "every_geom.xml")).compile()
    rows, columns = int(model.hfield_nrow[0]), int(model.hfield_ncol[0])
    theirs = model.hfield_data[: rows * columns].reshape(rows, columns) * model.hfield_size[0][2]  # row 0 at -y
    ours = model_pose.z + shape.pose.z + load_heightmap(Path(shape.mesh or "")) * shape.size[2]  # row 0 at +y
    assert theirs.min() == 0.0 and theirs.max() == pytest.approx(0.3)
    np.testing.assert_allclose(np.flipud(ours), theirs, atol=1e-6)


def test_not_simulated_elements_are_named_once() -> None:
    world = World.load(CORPUS / "not_simulated.xml")
    notes = "\n".join(world.notes)
    for named in ("joints: arm_base (1 joint), slider (1 joint)", "actuators: shoulder_motor, rail_drive",
                  "sensors: shoulder_angle, tip_touch", "tendons: coupling", "equality constraints: lock",
                  "cameras: overview, wrist_cam", "lights: lamp", "contact excludes: no_self"):
        assert notes.count(named) == 1, named
    assert len(world.notes) == 8


def test_the_scenario_text_is_read() -> None:
    scenario = World.load(CORPUS / "wall_in_the_way.xml").scenario
    assert scenario is not None
    assert (scenario.robot, scenario.start.x, scenario.goal, scenario.timeout, scenario.goal_tolerance) == (
        "husky", 0.0, (5.0, 0.0, None), 12.0, 0.5)


def test_skip_unsupported_drops_the_body_and_says_so() -> None:
    world = World.load(CORPUS / "bad_ellipsoid.xml", skip_unsupported=True)
    assert world.names == ()
    assert world.notes[0].startswith("dropped egg: unsupported geom type ellipsoid")
    assert "bad_ellipsoid.xml:4" in world.notes[0]


def test_geoms_directly_in_worldbody_are_one_kept_model(tmp_path: Path) -> None:
    scene = tmp_path / "scene.xml"
    scene.write_text('<mujoco><worldbody><geom type="plane" size="0 0 1"/>'
                     '<geom name="kerb" type="box" size="2 0.1 0.1" pos="0 1 0.1"/>'
                     '<body name="crate" pos="2 0 0.25"><geom type="box" size="0.25 0.25 0.25"/></body>'
                     '</worldbody></mujoco>')
    world = World.load(scene)
    assert world.names == ("worldbody", "crate") and world.reducible_names == ("crate",)
    assert world.model("worldbody").keep and world.model("worldbody").shapes[0].size == pytest.approx((4, 0.2, 0.2))


def test_saving_a_world_as_mjcf_is_refused_with_what_to_do(tmp_path: Path) -> None:
    world = World.load(CORPUS / "wall_in_the_way.xml")
    with pytest.raises(WorldError, match="save it as .yaml or .sdf"):
        world.save(tmp_path / "copy.xml")


def test_the_documented_scenario_text_loads(tmp_path: Path) -> None:
    import re

    text = (Path(__file__).resolve().parents[2] / "docs" / "mjcf.md").read_text()
    (block,) = re.findall(r"```xml\n(.*?)```", text, flags=re.DOTALL)
    scene = tmp_path / "scene.xml"
    scene.write_text(f'<mujoco><worldbody><body name="crate"><geom size="0.2"/></body></worldbody>{block}</mujoco>')
    assert World.load(scene).scenario == World.load(CORPUS / "wall_in_the_way.xml").scenario


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_the_scene_of_every_geom_simulates_in_each_engine(engine: str, monkeypatch: pytest.MonkeyPatch,
                                                          tmp_path: Path) -> None:
    """Read from another folder, its mesh and image files are still found (absolute paths), and the Husky drives
    to a goal among every kind of shape in both engines."""
    import dataclasses
    import importlib.util

    if importlib.util.find_spec(engine) is None:
        pytest.skip(f"{engine} is not installed")
    from pytest_ddenv.sim import simulate
    from pytest_ddenv.world import Scenario

    monkeypatch.chdir(tmp_path)
    world = World.load(CORPUS / "every_geom.xml").with_engine(engine)
    assert all(Path(shape.mesh).is_absolute() for model in world.models for shape in model.shapes if shape.mesh)
    run = simulate(dataclasses.replace(world, scenario=Scenario(goal=(2.0, 0.0, None), timeout=6.0)))
    assert run.reached_goal and run.engine == engine
