"""The animations drawn by MuJoCo's renderer (media/mujoco_scene.py) in a helper process (media/gl_helper.py):
real MuJoCo runs replayed, real OpenGL frames (EGL or OSMesa), read back from the GIF. Skipped with the
reason when no OpenGL backend starts here."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="the MuJoCo engine is the mujoco extra: pip install 'pytest-ddenv[mujoco]'")

from pytest_ddenv.detail import recording_detail
from pytest_ddenv.media import gl_helper
from pytest_ddenv.media.animate import FPS, HEIGHT, MAX_FRAMES, WIDTH, AnimationInfo, draw_animation, frame_times
from pytest_ddenv.sim import Run, Simulator
from pytest_ddenv.sim.urdf_geometry import pybullet_installed
from pytest_ddenv.world import World

pytestmark = pytest.mark.slow  # each test starts the media helper process

WALL_PATH = Path(__file__).resolve().parents[1] / "data" / "wall.yaml"
BLOCK_PYBULLET = 'import sys; sys.modules["pybullet"] = None; sys.modules["pybullet_data"] = None\n'
"""What `import pybullet` sees where it is not installed (Python >= 3.12: no wheel)."""
PUSHED_CRATE = """\
format: 1
name: crate
physics: {engine: mujoco}
scenario:
  start: {x: 0.0, y: 0.0, yaw: 0.0}
  goal: {x: 8.0, y: 0.0}
  timeout: 10
models:
  - {name: crate, pose: [1.3, 0, 0.2], box: [0.4, 0.8, 0.4], static: false, mass: 2, mu: 0.3, color: [0.8, 0.1, 0.1, 1]}
"""
"""The robot drives into a light red crate and pushes it ahead."""
TITLE_ROWS = 17
"""The white title bar on top of every frame (time and title), left out when frames are compared."""


def wall_run() -> tuple[World, Run]:
    world = World.load(WALL_PATH).with_engine("mujoco")
    with recording_detail(), Simulator() as sim:
        return world, sim.run(world, timeout=6.0)


def mujoco_animation(path: Path, world: World, run: Run) -> AnimationInfo:
    try:
        return gl_helper.in_gl_helper(draw_animation, path, world, run, "wall", FPS, MAX_FRAMES, "", "mujoco")
    except gl_helper.AnimationUnavailable as error:
        pytest.skip(f"MuJoCo's renderer cannot start here: {error}")


def read_frames(path: Path) -> np.ndarray:
    import imageio.v3 as iio

    return np.asarray(iio.imread(path, index=None), dtype=int)


def robot_mask(frames: np.ndarray) -> np.ndarray:
    """Pixels of the robot's yellow (palette.ROBOT_RGBA, pybullet's Husky) below the title bar."""
    body = frames[:, TITLE_ROWS:, :]
    return (body[..., 0] > 150) & (body[..., 1] > 100) & (body[..., 2] < 80)


def centroid(mask: np.ndarray) -> tuple[float, float]:
    rows, columns = np.nonzero(mask)
    return float(columns.mean()), float(rows.mean())


def test_mujoco_draws_every_frame_of_the_replay_with_the_robot_in_view(tmp_path: Path) -> None:
    world, run = wall_run()
    assert run.engine == "mujoco" and run.detail is not None
    info = mujoco_animation(tmp_path / "wall.gif", world, run)
    frames = read_frames(tmp_path / "wall.gif")
    assert frames.shape == (len(frame_times(run)), HEIGHT, WIDTH, 3)
    assert info.frames == len(frames)
    robot = robot_mask(frames)
    assert robot.sum(axis=(1, 2)).min() > 200  # the chase camera keeps the robot in every frame
    body = frames[:, TITLE_ROWS:, :]
    assert all(np.abs(body[i] - body[i + 1]).sum() > 0 for i in range(len(frames) - 1))
    # the robot drove 1.3 m towards the blue wall: the coloured models (not the grey ground, not the robot) fill
    # more of the last frame than of the first (measured: 15 % more, in both renderers)
    coloured = ((body.max(axis=-1) - body.min(axis=-1)) > 30) & ~robot
    assert coloured[-1].sum() > 1.1 * coloured[0].sum()


@pytest.mark.skipif(not pybullet_installed(), reason="compares with pybullet's TinyRenderer")
def test_both_renderers_put_the_robot_at_the_same_place_in_the_frame(tmp_path: Path) -> None:
    world, run = wall_run()
    mujoco_animation(tmp_path / "mujoco.gif", world, run)
    draw_animation(tmp_path / "pybullet.gif", world, run, "wall", FPS, MAX_FRAMES, "", "pybullet")
    in_mujoco, in_pybullet = read_frames(tmp_path / "mujoco.gif"), read_frames(tmp_path / "pybullet.gif")
    assert in_mujoco.shape == in_pybullet.shape
    for index in (0, len(in_mujoco) // 2, len(in_mujoco) - 1):
        (x1, y1), (x2, y2) = centroid(robot_mask(in_mujoco)[index]), centroid(robot_mask(in_pybullet)[index])
        assert abs(x1 - x2) < 6 and abs(y1 - y2) < 6


def test_a_pushed_model_is_drawn_where_the_run_recorded_it(tmp_path: Path) -> None:
    """A crate in the robot's way is pushed along: drawn from the run's detail it is ahead of the robot (higher
    in the chase camera's frame); without the detail it stays at its start, left behind between the camera
    and the robot (lower in the frame)."""
    world = World.from_yaml(PUSHED_CRATE, source="crate.yaml")
    with recording_detail(), Simulator() as sim:
        run = sim.run(world, timeout=4.0)
    assert run.detail is not None and run.detail.bodies["crate"][-1][0] > 2.5  # pushed 1 m and more
    mujoco_animation(tmp_path / "detail.gif", world, run)
    mujoco_animation(tmp_path / "start.gif", world, dataclasses.replace(run, detail=None))
    with_detail, without = read_frames(tmp_path / "detail.gif"), read_frames(tmp_path / "start.gif")
    robot_row = centroid(robot_mask(with_detail)[-1])[1]
    assert centroid(crate_mask(with_detail[-1]))[1] < robot_row - 5  # ahead of the robot
    assert centroid(crate_mask(without[-1]))[1] > robot_row + 30  # left behind at its start
    assert np.array_equal(with_detail[0], without[0])  # the same first frame: the crate has not moved yet


def crate_mask(frame: np.ndarray) -> np.ndarray:
    """Pixels of the crate's red (its colour in the world file) below the title bar."""
    body = frame[TITLE_ROWS:, :, :]
    return (body[..., 0] > 120) & (body[..., 1] < 60) & (body[..., 2] < 60)


def test_an_opengl_backend_that_does_not_start_is_noted_and_the_next_one_draws(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    if sys.platform != "linux":
        pytest.skip("the EGL/OSMesa fallback is Linux's")
    world, run = wall_run()
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(gl_helper, "LINUX_BACKENDS", ("no-such-backend",))
    with pytest.raises(gl_helper.AnimationUnavailable) as raised:
        gl_helper.in_gl_helper(draw_animation, tmp_path / "none.gif", world, run, "", FPS, 4, "", "mujoco")
    message = str(raised.value)
    assert "MUJOCO_GL=no-such-backend: import mujoco: RuntimeError: invalid value" in message
    assert "--ddenv-media pictures" in message and "set in your environment" not in message
    assert not (tmp_path / "none.gif").exists()
    monkeypatch.setattr(gl_helper, "LINUX_BACKENDS", ("no-such-backend", "egl", "osmesa"))
    mujoco_animation(tmp_path / "second.gif", world, run)
    assert len(read_frames(tmp_path / "second.gif")) == len(frame_times(run))


def test_a_renderer_process_that_dies_is_noted_for_each_backend_and_the_reduction_goes_on(
        monkeypatch: pytest.MonkeyPatch) -> None:
    if sys.platform != "linux":
        pytest.skip("the EGL/OSMesa fallback is Linux's")
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    with pytest.raises(gl_helper.AnimationUnavailable) as raised:
        gl_helper.in_gl_helper(os._exit, 3)  # the helper process ends as a crashing GL driver would end it
    message = str(raised.value)
    assert "MUJOCO_GL=egl: the renderer's process died; MUJOCO_GL=osmesa: the renderer's process died" in message


def run_without_pybullet(tmp_path: Path, code: str, *arguments: str) -> subprocess.CompletedProcess[str]:
    """`code` in a Python where `import pybullet` fails and MUJOCO_GL is not set, `arguments` in its sys.argv."""
    (tmp_path / "wall.yaml").write_text(WALL_PATH.read_text(encoding="utf-8"))
    env = {key: value for key, value in os.environ.items() if key != "MUJOCO_GL"}
    return subprocess.run([sys.executable, "-c", BLOCK_PYBULLET + textwrap.dedent(code), *arguments], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=600)


REDUCTION_MEDIA = """\
    import os
    import warnings
    from pathlib import Path
    from pytest_ddenv.detail import recording_detail
    from pytest_ddenv.media.writer import PendingMedia, Shown
    from pytest_ddenv.sim import Simulator
    from pytest_ddenv.world import World

    world = World.load("wall.yaml")
    with recording_detail(), Simulator() as sim:
        run = sim.run(world, timeout=2.0)
    os.environ.update(argument.split("=", 1) for argument in sys.argv[1:] if "=" in argument)  # after the run
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        shown = [Shown("original", world, run, False), Shown("minimal", world.without(["ball"]), run, False)]
        written = PendingMedia(Path("."), shown, helper="--in-finish" not in sys.argv).finish()
    print("RAN", run.engine, "WRITTEN", sorted(path.name for path in written.paths))
    print("WARNINGS", [str(warning.message) for warning in caught])
    """
"""A reduction's media of a MuJoCo run: `NAME=VALUE` arguments set after the run (the user's MUJOCO_GL);
`--in-finish`: the animations start in `finish()` (a reduction in one process), else at once (`helper=True`)."""


def test_without_pybullet_a_reductions_animations_are_drawn_by_mujoco(tmp_path: Path) -> None:
    done = run_without_pybullet(tmp_path, REDUCTION_MEDIA)
    assert done.returncode == 0, done.stderr
    if "no renderer can draw" in done.stdout:
        pytest.skip(f"MuJoCo's renderer cannot start here: {done.stdout}")
    assert "RAN mujoco WRITTEN ['minimal.gif', 'original.gif'" in done.stdout, done.stdout
    assert "WARNINGS []" in done.stdout
    original, minimal = read_frames(tmp_path / "original.gif"), read_frames(tmp_path / "minimal.gif")
    assert original.shape[1:] == (HEIGHT, WIDTH, 3) and robot_mask(original).sum(axis=(1, 2)).min() > 200
    assert minimal.shape == original.shape


def test_without_pybullet_a_gl_backend_that_does_not_start_is_one_warning_naming_it(tmp_path: Path) -> None:
    done = run_without_pybullet(tmp_path, REDUCTION_MEDIA, "MUJOCO_GL=no-such-backend", "--in-finish")
    assert done.returncode == 0, done.stderr
    assert "RAN mujoco WRITTEN" in done.stdout and ".gif" not in done.stdout.partition("WARNINGS")[0]
    (warnings_line,) = [line for line in done.stdout.splitlines() if line.startswith("WARNINGS")]
    assert warnings_line.count("not written") == 1 and "original.gif, minimal.gif not written" in warnings_line
    assert "tried MUJOCO_GL=no-such-backend" in warnings_line and "set in your environment" in warnings_line
    assert not list(tmp_path.glob("*.gif"))


def test_without_pybullet_ddenv_show_animates_a_run_with_mujoco(tmp_path: Path) -> None:
    done = run_without_pybullet(tmp_path, 'from pytest_ddenv.cli.main import main\n'
                                          'sys.exit(main(["show", "wall.yaml", "--animate", "wall.gif"]))')
    if "no renderer can draw" in done.stderr:
        pytest.skip(f"MuJoCo's renderer cannot start here: {done.stderr}")
    assert done.returncode == 0, done.stdout + done.stderr
    frames = read_frames(tmp_path / "wall.gif")
    robot_pixels = robot_mask(frames).sum(axis=(1, 2))  # at the wall MuJoCo's Husky hops (tests/engines.py):
    assert frames.shape[1:] == (HEIGHT, WIDTH, 3)  # the chase camera sees little of it for a few frames
    assert (robot_pixels > 0).all() and np.median(robot_pixels) > 200


def test_without_pybullet_or_an_opengl_backend_ddenv_show_animate_is_one_error(tmp_path: Path) -> None:
    done = run_without_pybullet(tmp_path, 'from pytest_ddenv.media import gl_helper\n'
                                          'gl_helper.LINUX_BACKENDS = ("no-such-backend",)\n'
                                          'from pytest_ddenv.cli.main import main\n'
                                          'sys.exit(main(["show", "wall.yaml", "--animate", "wall.gif"]))')
    assert done.returncode == 2, done.stdout + done.stderr
    assert "ddenv: error: no renderer can draw the animations here: pybullet is not installed" in done.stderr
    assert "tried MUJOCO_GL=no-such-backend" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "wall.gif").exists()
