"""Animations of a run: frames drawn headless and written as a GIF.

Two renderers draw the same replay: PyBullet's software renderer (TinyRenderer, no OpenGL) in a render-only
pybullet client wherever pybullet is installed, whatever engine simulated the run (so existing GIFs stay
the same), and otherwise MuJoCo's OpenGL renderer (media/mujoco_scene.py) in a helper process that tries
EGL and OSMesa (media/gl_helper.py). A replay, not a re-simulation: the world is built once and every
frame puts the robot (base pose and joints) and the moving models where the run recorded them
(`Run.detail`; without it, the moving models stay at their start poses). A chase camera follows the robot
from behind and above, its heading smoothed so that the picture does not swing with every wobble. An arm
(`Run.robot_kind == "arm"`) stands at the scenario's start with its joints where the run recorded them, and a
fixed camera looks over its table (media/table_camera.py). Each
frame carries the simulated time; from the failure moment on the frame has a red border and the failure's
words.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.media.arm_links import recorded_joints
from pytest_ddenv.media.gl_helper import in_gl_helper
from pytest_ddenv.media.palette import FINGER_RGBA, GROUND_RGBA, ROBOT_RGBA, model_rgba
from pytest_ddenv.media.table_camera import PLACE_RGBA, PLACE_THICKNESS, place_disc, table_camera
from pytest_ddenv.scenario.reported import REPORTED
from pytest_ddenv.sim.builder import GROUND_BODY_NAME, build_world
from pytest_ddenv.sim.quiet import silenced
from pytest_ddenv.sim.robot import make_robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.urdf_geometry import pybullet_installed
from pytest_ddenv.world.model import World


def renderer_name() -> str:
    """The renderer that draws the animations here: "pybullet" where pybullet is installed, else "mujoco"."""
    return "pybullet" if pybullet_installed() else "mujoco"


Frame = NDArray[np.uint8]

WIDTH, HEIGHT = 240, 180
"""Frame size in pixels: TinyRenderer's cost grows with it (about 23 ms a frame at this size, 35 ms at 320 x 240
before issue 33)."""
MAX_FRAMES = 60
"""Rendered frames per animation at most (a few seconds of rendering); a long run is played faster."""
MIN_STEP = 0.4
"""Simulated seconds between frames at least (a short run is not rendered at every recorded tick): at `FPS` a
run plays at twice its speed (0.25 s at 8 frames a second before issue 33: the same speed, 60 % more frames)."""
ARM_MIN_STEP = 0.16
"""The same for an arm, whose runs last seconds, not minutes (a grasp is over in a second): 0.8 times its speed."""
FPS = 5
"""Frames per second of the GIF."""
HOLD_SECONDS = 1.5
"""The last frame (the failure) is shown this long, so that a looping GIF pauses on it."""
CHASE_DISTANCE, CHASE_HEIGHT = 4.5, 2.6
"""Camera: metres behind the robot, and above its base, for a Husky-sized robot (scaled by the robot's
length between half and twice these)."""
HUSKY_LENGTH = 0.99
_FAILURE_RED = (214, 39, 40)


@dataclass(frozen=True)
class AnimationInfo:
    """What `write_animation` made: the file, its frames, the simulated times they show, the failure time
    (None: the run did not fail), the bytes written and the seconds spent rendering and encoding."""

    path: Path
    frames: int
    times: tuple[float, ...]
    failure_time: float | None
    size_bytes: int
    seconds: float

    def to_dict(self) -> dict[str, Any]:
        return {"file": self.path.name, "frames": self.frames, "first_time": self.times[0] if self.times else None,
                "last_time": self.times[-1] if self.times else None, "failure_time": self.failure_time,
                "bytes": self.size_bytes, "seconds": round(self.seconds, 3)}


def frame_times(run: Run, *, max_frames: int = MAX_FRAMES, min_step: float = MIN_STEP) -> list[int]:
    """Indices into `run.times` of the frames to render: evenly spaced over the run (at least `min_step`
    simulated seconds apart, at most `max_frames`), always the last sample, and the sample at the failure."""
    times = np.asarray(run.times, dtype=float)
    if len(times) == 0:
        return []
    duration = float(times[-1] - times[0])
    step = max(min_step, duration / max(1, max_frames - 1))
    wanted = np.arange(float(times[0]), float(times[-1]) + 1e-9, step)
    indices = {int(np.searchsorted(times, t, side="left")) for t in wanted}
    indices.add(len(times) - 1)
    if run.failure is not None:
        indices.add(min(len(times) - 1, int(np.searchsorted(times, run.failure.time - 1e-9, side="left"))))
    return sorted(i for i in indices if i < len(times))


class _Scene(Protocol):
    def place(self, run: Run, index: int) -> None: ...
    def image(self, eye: Sequence[float], target: Sequence[float], width: int, height: int) -> Frame: ...
    def close(self) -> None: ...


class _PybulletScene:
    """A render-only pybullet client holding the world and the robot."""

    def __init__(self, world: World, run: Run) -> None:
        with silenced():
            import pybullet as p
        self.p = p
        self.client = p.connect(p.DIRECT)
        try:
            self._build(world, run)
        except BaseException:
            p.disconnect(self.client)
            raise

    def _build(self, world: World, run: Run) -> None:
        p, client = self.p, self.client
        with silenced():
            bodies = build_world(p, client, world)
        colors = {model.name: list(model_rgba(model)) for model in world.models}
        self.bodies = {name: body for body, name in bodies.items()}
        for body, name in bodies.items():
            rgba = list(GROUND_RGBA) if name == GROUND_BODY_NAME else colors[name]
            for link in range(-1, p.getNumJoints(body, physicsClientId=client)):
                p.changeVisualShape(body, link, rgbaColor=rgba, textureUniqueId=-1, physicsClientId=client)
        start = world.scenario.start if world.scenario is not None else None
        self.robot: int | None = None
        self.columns: list[int] | None = None
        """The robot's joint of each column of the run's recorded joints (None: they are not this robot's)."""
        arm = run.robot_kind == "arm"
        if world.scenario is not None and start is not None and run.robot != REPORTED:
            try:
                with silenced():
                    robot = make_robot(world.scenario.robot, world.source)
                    self.robot = robot.spawn(client, (start.x, start.y, start.z if arm else 0.5), start.yaw)
            except Exception:  # noqa: BLE001 - a robot of the user's that cannot be made here: drawn as a box
                self.robot = None
            if self.robot is not None and run.detail is not None:
                self.columns = recorded_joints(p, client, self.robot, robot, run.detail.joints.shape[1])
        self.fixed_base = arm and self.robot is not None
        """An arm stands at the scenario's start (its recorded poses are the end effector's)."""
        if self.fixed_base:
            self._paint_arm()
            self._add_place_disc(world)
        if self.robot is None:  # a run reported by a simulator of the user's, or a robot not known here
            length, width = run.footprint
            shape = p.createVisualShape(p.GEOM_BOX, halfExtents=[length / 2, width / 2, 0.15],
                                        rgbaColor=list(ROBOT_RGBA), physicsClientId=client)
            self.robot = p.createMultiBody(0.0, -1, shape, [0, 0, 0], physicsClientId=client)
        self.joints = p.getNumJoints(self.robot, physicsClientId=client)

    def _paint_arm(self) -> None:
        """The arm in the robot's colour, its fingers darker (the Panda's URDF makes it all white)."""
        p, client, robot = self.p, self.client, self.robot
        for link in range(-1, p.getNumJoints(robot, physicsClientId=client)):
            name = "" if link < 0 else p.getJointInfo(robot, link, physicsClientId=client)[12].decode()
            rgba = FINGER_RGBA if "finger" in name else ROBOT_RGBA
            p.changeVisualShape(robot, link, rgbaColor=list(rgba), textureUniqueId=-1, physicsClientId=client)

    def _add_place_disc(self, world: World) -> None:
        """An arm's place region: a thin green disc on the table, drawn only."""
        disc = place_disc(world)
        if disc is None:
            return
        p, client = self.p, self.client
        centre, radius = disc
        shape = p.createVisualShape(p.GEOM_CYLINDER, radius=radius, length=PLACE_THICKNESS,
                                    rgbaColor=list(PLACE_RGBA), physicsClientId=client)
        p.createMultiBody(0.0, -1, shape, list(centre), physicsClientId=client)

    def place(self, run: Run, index: int) -> None:
        p, client = self.p, self.client
        if not self.fixed_base:
            x, y, z, roll, pitch, yaw = (float(v) for v in run.poses[index])
            p.resetBasePositionAndOrientation(self.robot, [x, y, z], p.getQuaternionFromEuler([roll, pitch, yaw]),
                                              physicsClientId=client)
        detail = run.detail
        if detail is None:
            return
        if self.columns is not None:
            for joint, angle in zip(self.columns, detail.joints[index], strict=True):
                p.resetJointState(self.robot, joint, float(angle), physicsClientId=client)
        for name, poses in detail.bodies.items():
            body = self.bodies.get(name)
            if body is not None and index < len(poses):
                p.resetBasePositionAndOrientation(body, poses[index][:3].tolist(), poses[index][3:].tolist(),
                                                  physicsClientId=client)

    def image(self, eye: Sequence[float], target: Sequence[float], width: int, height: int) -> Frame:
        p = self.p
        view = p.computeViewMatrix(list(eye), list(target), [0.0, 0.0, 1.0])
        projection = p.computeProjectionMatrixFOV(60.0, width / height, 0.1, 80.0)
        _, _, rgba, _, _ = p.getCameraImage(width, height, view, projection, renderer=p.ER_TINY_RENDERER,
                                            lightDirection=[0.4, -0.5, 1.0], shadow=0, physicsClientId=self.client)
        return np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[:, :, :3].copy()

    def close(self) -> None:
        self.p.disconnect(self.client)


def chase_headings(run: Run, indices: Sequence[int], smoothing: float = 1.5) -> list[float]:
    """The camera's heading at each frame: the robot's yaw, unwrapped and smoothed with a time constant of
    `smoothing` simulated seconds."""
    yaws = np.unwrap(np.asarray(run.poses[:, 5], dtype=float))
    times = np.asarray(run.times, dtype=float)
    heading = float(yaws[0])
    last = float(times[0])
    result = []
    for index in range(len(times)):
        blend = 1.0 - math.exp(-(float(times[index]) - last) / smoothing)
        heading += blend * (float(yaws[index]) - heading)
        last = float(times[index])
        result.append(heading)
    return [result[i] for i in indices]


def _scene(renderer: str, world: World, run: Run, width: int, height: int) -> _Scene:
    if renderer == "pybullet":
        return _PybulletScene(world, run)
    from pytest_ddenv.media.mujoco_scene import MujocoScene

    return MujocoScene(world, run, width, height)


def render_frames(world: World, run: Run, *, title: str = "", width: int = WIDTH, height: int = HEIGHT,
                  max_frames: int = MAX_FRAMES, failure_text: str = "", renderer: str = "pybullet"
                  ) -> Iterator[tuple[float, Frame]]:
    """(simulated time, RGB frame) of the run, chase camera (an arm's: fixed over its table), with the time and
    the failure marked: from the time a failure predicate fired, else (`failure_text`: the test failed after
    the run, e.g. in an `assert`) on the last frame. `renderer`: "pybullet" or "mujoco", drawn in this
    process (MuJoCo's only in a process whose `MUJOCO_GL` is chosen: `write_animation` does that)."""
    arm = run.robot_kind == "arm"
    indices = frame_times(run, max_frames=max_frames, min_step=ARM_MIN_STEP if arm else MIN_STEP)
    headings = chase_headings(run, indices)
    failure_time = None if run.failure is None else float(run.failure.time)
    scene = _scene(renderer, world, run, width, height)
    scale = min(2.0, max(0.5, run.footprint[0] / HUSKY_LENGTH))  # a small robot is followed closer
    fixed = table_camera(world, run) if arm else None
    try:
        for index, heading in zip(indices, headings, strict=True):
            scene.place(run, index)
            if fixed is not None:
                eye, look = fixed
            else:
                x, y, z = (float(v) for v in run.poses[index][:3])
                back = CHASE_DISTANCE * scale
                eye = (x - back * math.cos(heading), y - back * math.sin(heading), z + CHASE_HEIGHT * scale)
                look = (x, y, z)
            frame = scene.image(eye, look, width, height)
            now = float(run.times[index])
            if failure_time is not None:
                words = _failure_words(run) if now >= failure_time - 1e-9 else ""
            else:
                words = f"FAILED: {failure_text}" if failure_text and index == indices[-1] else ""
            yield now, _annotate(frame, title, now, words)
    finally:
        scene.close()


def _failure_words(run: Run) -> str:
    assert run.failure is not None
    return f"FAILED: {run.failure.predicate} at t = {run.failure.time:.1f} s"


def _annotate(frame: Frame, title: str, now: float, failure_words: str) -> Frame:
    from PIL import Image, ImageDraw

    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image)
    width, height = image.size
    draw.rectangle((0, 0, width, 16), fill=(255, 255, 255))
    draw.text((4, 2), f"{title}   t = {now:5.1f} s" if title else f"t = {now:5.1f} s", fill=(0, 0, 0))
    if failure_words:
        draw.rectangle((0, 0, width - 1, height - 1), outline=_FAILURE_RED, width=4)
        draw.rectangle((0, height - 18, width, height), fill=_FAILURE_RED)
        draw.text((6, height - 15), failure_words[:(width - 12) // 6], fill=(255, 255, 255))  # 6 px a letter
    return np.asarray(image, dtype=np.uint8)


def write_animation(path: Path, world: World, run: Run, *, title: str = "", fps: int = FPS,
                    max_frames: int = MAX_FRAMES, failure_text: str = "") -> AnimationInfo:
    """Render `run` in `world` and write it as a looping GIF at `path` (atomically: a temporary file, then
    renamed), with the renderer of `renderer_name()`: pybullet's here, MuJoCo's in a helper process
    (AnimationUnavailable when no OpenGL backend starts). `failure_text`: see `render_frames`."""
    if renderer_name() == "pybullet":
        return draw_animation(path, world, run, title, fps, max_frames, failure_text, "pybullet")
    return in_gl_helper(draw_animation, path, world, run, title, fps, max_frames, failure_text, "mujoco")


def draw_animation(path: Path, world: World, run: Run, title: str, fps: int, max_frames: int, failure_text: str,
                   renderer: str) -> AnimationInfo:
    """`write_animation` with `renderer`, in this process."""
    import imageio.v3 as iio

    started = time.perf_counter()
    shown = list(render_frames(world, run, title=title, max_frames=max_frames, failure_text=failure_text,
                               renderer=renderer))
    frames = [frame for _, frame in shown] or [np.zeros((HEIGHT, WIDTH, 3), np.uint8)]
    durations = [1000.0 / fps] * (len(frames) - 1) + [1000.0 * HOLD_SECONDS]
    path = Path(path)
    temporary = path.with_name(path.name + ".tmp")
    iio.imwrite(temporary, np.stack(frames), extension=".gif", duration=durations, loop=0)
    temporary.replace(path)
    return AnimationInfo(path, len(shown), tuple(t for t, _ in shown),
                         None if run.failure is None else float(run.failure.time), path.stat().st_size,
                         time.perf_counter() - started)
