"""A declared camera: the arm's controller sees its picture (pybullet's TinyRenderer), and it changes nothing
else of the run."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv import World
from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.sim import Simulator
from pytest_ddenv.sim.arm.control import ArmObservation, GripperCommand
from pytest_ddenv.world.model import Camera

pytestmark = pytest.mark.pybullet
OVERHEAD = Camera(position=(0.5, 0.0, 0.8), look_at=(0.5, 0.0, 0.4), width=48, height=32, kind="depth")


def with_camera(world: World, camera: Camera) -> World:
    assert world.scenario is not None
    return dataclasses.replace(world, scenario=dataclasses.replace(world.scenario, camera=camera))


def pictures(sim: Simulator, world: World) -> list[np.ndarray]:
    seen: list[ArmObservation] = []

    def look(observation: ArmObservation) -> GripperCommand:
        seen.append(observation)
        return GripperCommand("open")

    sim.run(world, controller=look, timeout=0.1)
    return [o.image for o in seen]  # type: ignore[misc]


def test_a_depth_camera_sees_the_cube_on_the_table(sim: Simulator, smoke: World) -> None:
    (depth, *_) = pictures(sim, with_camera(smoke, OVERHEAD))
    assert depth.shape == (32, 48) and depth.dtype == np.float32 and not depth.flags.writeable
    assert depth[15, 24] == pytest.approx(0.8 - 0.45, abs=0.01)  # the cube's top, under the camera
    assert depth[2, 2] == pytest.approx(0.8 - 0.4, abs=0.01)  # the table's top beside it


def test_an_rgb_camera_sees_the_red_cube(sim: Simulator, smoke: World) -> None:
    (rgb, *_) = pictures(sim, with_camera(smoke, dataclasses.replace(OVERHEAD, kind="rgb")))
    assert rgb.shape == (32, 48, 3) and rgb.dtype == np.uint8
    red, green, blue = (int(v) for v in rgb[15, 24])
    assert red > 2 * green and red > 2 * blue  # the cube, red in the world file
    assert len({int(v) for v in rgb[2, 2]}) == 1  # the table, grey


def test_no_camera_no_picture(sim: Simulator, smoke: World) -> None:
    assert pictures(sim, smoke)[0] is None


def test_the_camera_changes_nothing_else(sim: Simulator, smoke: World) -> None:
    assert sim.run(smoke, seed=3).same_trajectory(sim.run(with_camera(smoke, OVERHEAD), seed=3))


def test_the_camera_is_read_and_written_back(smoke: World, tmp_path: Path) -> None:
    world = with_camera(smoke, OVERHEAD)
    assert World.from_yaml(world.to_yaml()).scenario == world.scenario
    path = tmp_path / "camera.sdf"
    path.write_text(world.to_sdf(), encoding="utf-8")
    assert World.load(path).scenario == world.scenario


@pytest.mark.parametrize(("camera", "field", "message"), [
    ("{position: [0, 0, 1], look_at: [0, 0, 1]}", "scenario.camera.look_at", "its own position"),
    ("{position: [0, 0, 1], look_at: [0, 0, 0], width: 0}", "scenario.camera.width", "from 1 to 1024"),
    ("{position: [0, 0, 1], look_at: [0, 0, 0], kind: infrared}", "scenario.camera.kind", "rgb, depth"),
    ("{position: [0, 0, 1], look_at: [0, 0, 0], fov: 200}", "scenario.camera.fov", "below 180|between 0 and 180"),
    ("{position: [0, 0, 1]}", "scenario.camera.look_at", "missing"),
])
def test_a_bad_camera_says_which_field(smoke: World, camera: str, field: str, message: str) -> None:
    text = smoke.to_yaml().replace("  watch: [mug]\n", f"  watch: [mug]\n  camera: {camera}\n")
    with pytest.raises(ScenarioError, match=message) as caught:
        World.from_yaml(text)
    assert caught.value.field == field


def test_a_bad_camera_made_in_python_is_refused_before_a_run(smoke: World) -> None:
    from pytest_ddenv.scenario.robot_world import RobotWorld

    with pytest.raises(ScenarioError, match="from 1 to 1024") as caught:
        RobotWorld(with_camera(smoke, dataclasses.replace(OVERHEAD, width=4096)))
    assert caught.value.field == "scenario.camera.width"
