"""Pictures, animations and the 3D recording of an arm's run: a real Franka Panda run of the smoke world
(tests/data/arm_smoke.yaml) in PyBullet, drawn by matplotlib, pybullet's TinyRenderer and rerun, and read
back from the files written."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv.detail import recording_detail
from pytest_ddenv.media.animate import HEIGHT, MIN_STEP, WIDTH, render_frames, write_animation
from pytest_ddenv.media.table_camera import LIFT, table_camera
from pytest_ddenv.oracle.arm_state import ArmState
from pytest_ddenv.oracle.predicates import FailureSignature, signature
from pytest_ddenv.render import draw_reduction, draw_world, plot_reduction, plot_world
from pytest_ddenv.render.canvas import pyplot
from pytest_ddenv.sim import Run, simulate
from pytest_ddenv.world import World

pytestmark = pytest.mark.pybullet  # the arm runs in PyBullet (MuJoCo's arm: tests/sim_mujoco)

DATA = Path(__file__).resolve().parent / "data"
SMOKE = DATA / "arm_smoke.yaml"
FAR_SHED = "  - {name: far_shed, pose: [40.0, 30.0, 0.5], box: [2.0, 2.0, 1.0]}\n"
"""A model 50 m from the table: a picture of the whole world would be 50 m wide."""


@dataclass
class Lifted:
    """Fails as soon as the target is 5 cm above where it started: a real failure in the middle of the run,
    with the end effector at the cube."""

    name: str = field(default="lifted", init=False)

    def reset(self) -> None:
        pass

    def check(self, state: ArmState) -> FailureSignature | None:
        assert state.target is not None
        if state.objects[state.target][2] > state.start_objects[state.target][2] + 0.05:
            return signature(self.name, state, "the cube left the table")
        return None


@pytest.fixture(scope="module")
def world() -> World:
    return World.from_yaml(SMOKE.read_text() + FAR_SHED, source=str(SMOKE))


@pytest.fixture(scope="module")
def placed(world: World) -> Run:
    """The default controller picks the cube and places it (no failure), with the run's full detail."""
    with recording_detail():
        run = simulate(world, seed=0)
    assert run.robot_kind == "arm" and run.reached_goal and run.detail is not None
    return run


@pytest.fixture(scope="module")
def lifted(world: World) -> Run:
    """The same run stopped by `Lifted` when the cube leaves the table."""
    with recording_detail():
        run = simulate(world, seed=0, predicates=[Lifted()])
    assert run.failure is not None and run.failure.predicate == "lifted"
    return run


def table_box(world: World) -> np.ndarray:
    return world.bounds("table")[:, :2]


# -- the top-down pictures ---------------------------------------------------------------------------------
def test_the_picture_of_an_arm_run_is_zoomed_to_its_table(world: World, placed: Run) -> None:
    figure = draw_world(world, [placed])
    try:
        axes = figure.axes[0]
        (x0, x1), (y0, y1) = axes.get_xlim(), axes.get_ylim()
        table = table_box(world)
        assert x0 <= table[0, 0] and table[1, 0] <= x1 and y0 <= table[0, 1] and table[1, 1] <= y1
        assert max(x1 - x0, y1 - y0) < 2.0, "the view is the table's, not the 50 m world's"
        labels = [line.get_label() for line in axes.get_lines()]
        assert any("end effector" in label for label in labels) and any("target" in label for label in labels)
        assert "arm base" in labels and "place region" in labels
        target = next(line for line in axes.get_lines() if line.get_label() == "seed 0: target")
        xs, ys = target.get_data()
        assert np.allclose([xs[-1], ys[-1]], placed.target_path[-1, :2])
    finally:
        pyplot().close(figure)


def test_a_world_of_an_arm_without_runs_is_drawn_as_an_arm_s() -> None:
    """No run, no table, no target: the scenario's robot says it is an arm; a Husky's world stays as it was."""
    arm_world = World.from_yaml("""
format: 1
scenario: {robot: panda, start: {x: 0, y: 0, z: 0.4}, goal: {x: 0.4, y: 0.3}, goal_tolerance: 0.05, timeout: 10}
models:
  - {name: crate, pose: [0.5, 0, 0.2], box: [0.1, 0.1, 0.4]}
  - {name: far_shed, pose: [40.0, 30.0, 0.5], box: [2.0, 2.0, 1.0]}
""")
    husky_world = World.from_yaml(
        "format: 1\nscenario: {start: {x: 0, y: 0}, goal: {x: 5, y: 0}, timeout: 10}\nmodels:\n"
        "  - {name: crate, pose: [2, 0, 0.2], box: [0.4, 0.4, 0.4]}\n")
    for world, arm in ((arm_world, True), (husky_world, False)):
        figure = draw_world(world)
        try:
            axes = figure.axes[0]
            labels = [line.get_label() for line in axes.get_lines()]
            assert ("arm base" in labels) == arm and ("start" in labels) == (not arm)
            if arm:
                assert axes.get_xlim()[1] < 2.0, "the shed 40 m away is out of the view"
        finally:
            pyplot().close(figure)


def test_the_failure_point_of_an_arm_is_marked_at_the_end_effector(world: World, lifted: Run) -> None:
    assert lifted.failure is not None
    figure = draw_reduction(world, ["table", "cube"], original_run=lifted, minimal_run=lifted)
    try:
        axes = figure.axes[0]
        crosses = [line for line in axes.get_lines() if line.get_marker() == "X"]
        assert crosses and all(np.allclose(np.column_stack(line.get_data())[0], lifted.failure.pose[:2])
                               for line in crosses)
        halos = {collection.get_gid() for collection in axes.collections if collection.get_gid()}
        assert halos == {"needed:table", "needed:cube"}
        legend = [text.get_text() for text in axes.get_legend().get_texts()]
        assert "failure point (end effector)" in legend
        assert not any("robot outline" in text for text in legend)
    finally:
        pyplot().close(figure)


def test_arm_pictures_are_written(world: World, placed: Run, lifted: Run, tmp_path: Path) -> None:
    assert lifted.failure is not None
    written = [plot_world(world, [placed], path=tmp_path / "run.png"),
               plot_reduction(world, ["table", "cube"], path=tmp_path / "reduction.png",
                              failure_pose=lifted.failure.pose)]
    assert all(path.stat().st_size > 10_000 for path in written)


# -- the animations ----------------------------------------------------------------------------------------
def test_the_camera_looks_at_the_table_from_above_the_arm(world: World, placed: Run) -> None:
    eye, look = table_camera(world, placed)
    assert world.scenario is not None
    table = table_box(world)
    assert table[0, 0] <= look[0] <= table[1, 0] and table[0, 1] <= look[1] <= table[1, 1]
    assert look[2] == pytest.approx(placed.target_path[0, 2] + LIFT)
    assert eye[2] > look[2] + 0.5, "from above"
    base = (world.scenario.start.x, world.scenario.start.y)
    assert math.dist(eye[:2], base) < math.dist(eye[:2], look[:2]), "from the arm's side of the table"


def test_the_gif_shows_the_arm_moving_over_a_still_table(world: World, placed: Run, tmp_path: Path) -> None:
    frames = [frame for _, frame in render_frames(world, placed, max_frames=12)]
    assert all(frame.shape == (HEIGHT, WIDTH, 3) for frame in frames)
    assert all(frame[20:-20].std() > 10 for frame in frames), "not an empty picture"
    rgb = frames[0].astype(int)
    green = (rgb[..., 1] > rgb[..., 0] + 60) & (rgb[..., 1] > rgb[..., 2] + 60)
    assert green.sum() > 50, "the place region's green disc is on the table"
    changed = [float((np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 40)[20:-20].mean())
               for a, b in zip(frames, frames[1:])]
    assert max(changed) < 0.25, "the camera stands still: only the arm and the cube change the picture"
    assert sum(fraction > 0.01 for fraction in changed) >= len(changed) // 2, "the arm moves"
    info = write_animation(tmp_path / "placed.gif", world, placed, title="arm_smoke")
    assert info.path.stat().st_size > 0 and info.times[-1] == placed.times[-1]
    assert info.frames > placed.times[-1] / MIN_STEP + 2, "an arm's seconds get more frames than a Husky's"


def test_the_arm_stands_at_its_start_not_at_the_end_effector(world: World, placed: Run) -> None:
    """Drawn with its joints at a different time, the arm changes the picture where it is: the frames of
    the first and the middle time differ (the arm moved), and the arm's base does not move between them."""
    from pytest_ddenv.media.animate import _PybulletScene

    scene = _PybulletScene(world, placed)
    try:
        import pybullet as p

        bases = []
        for index in (0, len(placed.times) // 2):
            scene.place(placed, index)
            bases.append(p.getBasePositionAndOrientation(scene.robot, physicsClientId=scene.client)[0])
        assert world.scenario is not None
        start = world.scenario.start
        assert bases[0] == bases[1] and math.dist(bases[0][:2], (start.x, start.y)) < 1e-6
        assert math.dist(bases[0], placed.poses[len(placed.times) // 2, :3]) > 0.3
        assert placed.detail is not None
        angles = [p.getJointState(scene.robot, j, physicsClientId=scene.client)[0] for j in range(scene.joints)]
        assert np.allclose(angles, placed.detail.joints[len(placed.times) // 2])
    finally:
        scene.close()


# -- the 3D recording --------------------------------------------------------------------------------------
def test_the_recording_holds_the_arm_its_paths_and_the_failure(world: World, lifted: Run, tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    from pytest_ddenv.media.recording import write_recording

    info = write_recording(tmp_path / "recording.rrd", [("lifted", world, lifted)])
    rows: dict[str, int] = {}
    for chunk in RrdReader(info.path).stream().to_chunks():
        rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    for entity in ("/lifted/robot/gripper", "/lifted/arm/base", "/lifted/trajectory/path", "/lifted/target/path",
                   "/lifted/failure", "/lifted/models/cube", "/lifted/models/far_shed"):
        assert entity in rows, entity
    samples = len(lifted.times)
    assert rows["/lifted/arm/links"] == samples + 1  # the style, then one row of bones per sample
    assert rows["/lifted/target/position"] == samples + 1
    assert rows["/lifted/robot"] == samples
    assert "/lifted/robot/footprint" not in rows and "/lifted/robot/heading" not in rows


def test_the_links_replayed_from_the_joints_put_the_gripper_where_the_run_recorded_it(world: World,
                                                                                      placed: Run) -> None:
    from pytest_ddenv.media.arm_links import arm_links

    links = arm_links(world, placed)
    assert links is not None and links.positions.shape == (len(placed.times), len(links.names) + 1, 3)
    tool = links.names.index("panda_grasptarget") + 1
    assert np.abs(links.positions[:, tool] - placed.poses[:, :3]).max() < 1e-3
    assert world.scenario is not None
    start = world.scenario.start
    assert np.allclose(links.positions[:, 0], (start.x, start.y, start.z))
    assert links.bones(0).shape == (len(links.names), 2, 3)


# -- a MuJoCo run, in both renderers -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def in_mujoco() -> tuple[World, Run]:
    pytest.importorskip("mujoco")
    world = World.load(SMOKE).with_engine("mujoco")
    with recording_detail():
        run = simulate(world, seed=0)
    assert run.engine == "mujoco" and run.robot_kind == "arm" and run.detail is not None
    return world, run


def test_a_mujoco_run_moves_the_arm_in_pybullets_renderer_by_joint_name(in_mujoco: tuple[World, Run]) -> None:
    """MuJoCo records the arm and finger joints only (9 for the Panda), pybullet every joint (12)."""
    import pybullet as p

    from pytest_ddenv.media.animate import _PybulletScene

    world, run = in_mujoco
    assert run.detail is not None and run.detail.joints.shape[1] == 9
    scene = _PybulletScene(world, run)
    try:
        middle = len(run.times) // 2
        scene.place(run, middle)
        names = {p.getJointInfo(scene.robot, j, physicsClientId=scene.client)[1].decode(): j
                 for j in range(scene.joints)}
        recorded = dict(zip([f"panda_joint{i}" for i in range(1, 8)] + ["panda_finger_joint1", "panda_finger_joint2"],
                            run.detail.joints[middle], strict=True))
        for name, angle in recorded.items():
            assert p.getJointState(scene.robot, names[name], physicsClientId=scene.client)[0] == pytest.approx(angle)
    finally:
        scene.close()


def arm_centroids(frames: np.ndarray) -> list[tuple[float, float]]:
    """The centre of the arm's yellow (palette.ROBOT_RGBA: blue under a quarter of red, unlike the brown table)
    below the title bar, per frame."""
    body = frames[:, 17:, :, :3].astype(int)
    mask = (body[..., 0] > 120) & (body[..., 1] > 0.6 * body[..., 0]) & (body[..., 2] < 0.25 * body[..., 0])
    return [(float(np.nonzero(m)[1].mean()), float(np.nonzero(m)[0].mean())) for m in mask]


@pytest.mark.slow  # the media helper process
@pytest.mark.mujoco
def test_both_renderers_draw_the_arm_at_the_same_place(in_mujoco: tuple[World, Run], tmp_path: Path) -> None:
    import imageio.v3 as iio

    from pytest_ddenv.media import gl_helper
    from pytest_ddenv.media.animate import FPS, MAX_FRAMES, draw_animation

    world, run = in_mujoco
    try:
        gl_helper.in_gl_helper(draw_animation, tmp_path / "mujoco.gif", world, run, "", FPS, MAX_FRAMES, "", "mujoco")
    except gl_helper.AnimationUnavailable as error:
        pytest.skip(f"MuJoCo's renderer cannot start here: {error}")
    draw_animation(tmp_path / "pybullet.gif", world, run, "", FPS, MAX_FRAMES, "", "pybullet")
    mujoco_frames, pybullet_frames = (iio.imread(tmp_path / name, index=None) for name in ("mujoco.gif", "pybullet.gif"))
    assert mujoco_frames.shape == pybullet_frames.shape
    centres = list(zip(arm_centroids(mujoco_frames), arm_centroids(pybullet_frames), strict=True))
    assert all(math.dist(a, b) < 6 for a, b in centres), centres
    assert math.dist(centres[0][0], centres[len(centres) // 2][0]) > 5, "the arm moved in the picture"
