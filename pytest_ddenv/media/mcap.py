"""The 3D recording of runs as an MCAP file (https://mcap.dev) in Foxglove's well-known schemas, for Foxglove,
Lichtblick and Rerun: the same content as the Rerun recording (`recording.py`, from `content.py`).

One file holds every run given to `write_mcap`, each under its own topics `/<label>/...` and coordinate frames
`<label>...` (a run's frames are a tree of their own: a 3D panel per run, its display frame `<label>`, shows
the runs side by side); message times are simulated times (nanoseconds from t = 0). Per run:

    /<label>/tf            foxglove.FrameTransforms: `<label>/robot` (the robot's base; an arm's end effector)
                           and `<label>/models/<name>` in `<label>`, at every sample (a static model's once)
    /<label>/scene         foxglove.SceneUpdate at the first time, kept: the ground, the goal and its tolerance
                           circle, each model's shapes in its frame (cubes, cylinders, spheres, a capsule as a
                           cylinder and two spheres, triangle lists for meshes), the robot's footprint and
                           heading (an arm's gripper and base), the trajectory, an arm's target path
    /<label>/robot/pose    foxglove.PoseInFrame: the robot's pose in `<label>` at every sample
    /<label>/scan          foxglove.PointCloud: the laser's hits (x y z float32, world frame) at every sample
    /<label>/contacts      foxglove.SceneUpdate: a sphere per contact point (size growing with the force) at
                           every sample, the models touched in the entity's metadata
    /<label>/arm/links     foxglove.SceneUpdate: an arm's links as segments at every sample (pybullet)
    /<label>/target        foxglove.SceneUpdate: an arm's target at every sample
    /<label>/failure       foxglove.SceneUpdate: a red sphere and its words at the failure pose and time
    /<label>/log           foxglove.Log: the run at its first time, the failure (ERROR) or the end

foxglove-sdk is an optional dependency (`pip install 'pytest-ddenv[mcap]'`), imported only when a file is
written. See docs/recording.md.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pytest_ddenv.media import content
from pytest_ddenv.media.content import FOOTPRINT_HEIGHT, GRIPPER_HALF_SIZE, FloatArray, quaternion, quaternions
from pytest_ddenv.media.palette import (
    CONTACT_RGBA,
    FAILURE_RGBA,
    GOAL_RGBA,
    GROUND_RGBA,
    HEADING_RGBA,
    ROBOT_RGBA,
    TARGET_RGBA,
    TRAJECTORY_RGBA,
    model_rgba,
)
from pytest_ddenv.world.model import Model, Pose, World

if TYPE_CHECKING:
    from pytest_ddenv.sim.run import Run

INSTALL_HINT = "the MCAP recording needs foxglove-sdk: pip install 'pytest-ddenv[mcap]'"
PROFILE = "pytest-ddenv"
"""The profile written in the file's header."""


class McapUnavailable(ImportError):
    """foxglove-sdk is not installed: the MCAP recording cannot be written."""


def mcap_available() -> bool:
    """Whether foxglove-sdk can be imported (the `mcap` extra is installed)."""
    try:
        _foxglove()
    except McapUnavailable:
        return False
    return True


def _foxglove() -> tuple[Any, Any, Any]:
    """(foxglove, its channels, its messages), or `McapUnavailable`."""
    try:
        import foxglove
        import foxglove.channels as channels
        import foxglove.messages as messages
    except ImportError as error:
        raise McapUnavailable(INSTALL_HINT) from error
    return foxglove, channels, messages


@dataclass(frozen=True)
class McapInfo:
    """What `write_mcap` made: the file, its topics, the messages written, the simulated time range covered
    (first, last) in seconds, the bytes written and the seconds spent."""

    path: Path
    topics: tuple[str, ...]
    messages: int
    time_range: tuple[float, float]
    size_bytes: int
    seconds: float

    def to_dict(self) -> dict[str, Any]:
        return {"file": self.path.name, "topics": len(self.topics), "messages": self.messages,
                "first_time": self.time_range[0], "last_time": self.time_range[1], "bytes": self.size_bytes,
                "seconds": round(self.seconds, 3)}


def write_mcap(path: Path, runs: Sequence[tuple[str, World, Run]]) -> McapInfo:
    """Write every `(label, world, run)` into one MCAP file at `path`, each run on topics `/<label>/...` in
    frames `<label>...`; atomically (a temporary file, then renamed). Labels must be distinct and not empty.
    Raises `McapUnavailable` without foxglove-sdk."""
    foxglove, channels, messages = _foxglove()
    content.validate_labels(runs)
    started = time.perf_counter()
    path = Path(path)
    temporary = path.with_name(f".{path.name}.tmp{os.getpid()}")
    context = foxglove.Context()
    from foxglove.mcap import MCAPWriteOptions

    writer = foxglove.open_mcap(temporary, allow_overwrite=True, context=context,
                                writer_options=MCAPWriteOptions(profile=PROFILE, compression_threads=0))
    log = _Log(channels, messages, context)
    try:
        for label, world, run in runs:
            _log_run(log, label, world, run)
        writer.close()
        os.replace(temporary, path)
    except BaseException:
        writer.close()
        temporary.unlink(missing_ok=True)
        raise
    return McapInfo(path, tuple(log.channels), log.count, content.time_range(runs), path.stat().st_size,
                    time.perf_counter() - started)


@dataclass
class _Log:
    """Logs messages to typed channels of one context, a channel per topic, at simulated times."""

    channels_module: Any
    m: Any
    context: Any
    channels: dict[str, Any] = field(default_factory=dict)
    count: int = 0

    def __call__(self, topic: str, kind: str, message: Any, seconds: float) -> None:
        channel = self.channels.get(topic)
        if channel is None:
            channel = getattr(self.channels_module, f"{kind}Channel")(topic, context=self.context)
            self.channels[topic] = channel
        channel.log(message, log_time=nanoseconds(seconds))
        self.count += 1

    # -- message parts --------------------------------------------------------------------------------------
    def stamp(self, seconds: float) -> Any:
        sec, nsec = divmod(nanoseconds(seconds), 1_000_000_000)
        return self.m.Timestamp(sec=sec, nsec=nsec)

    def vector(self, xyz: Sequence[float] | FloatArray) -> Any:
        return self.m.Vector3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))

    def point(self, xyz: Sequence[float] | FloatArray) -> Any:
        return self.m.Point3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))

    def rotation(self, xyzw: Sequence[float] | FloatArray) -> Any:
        return self.m.Quaternion(x=float(xyzw[0]), y=float(xyzw[1]), z=float(xyzw[2]), w=float(xyzw[3]))

    def pose(self, position: Sequence[float] | FloatArray, xyzw: Sequence[float] | FloatArray = (0, 0, 0, 1)) -> Any:
        return self.m.Pose(position=self.vector(position), orientation=self.rotation(xyzw))

    def color(self, rgba: Sequence[float]) -> Any:
        return self.m.Color(r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3]))

    def entity(self, seconds: float, frame: str, name: str, **primitives: Any) -> Any:
        return self.m.SceneEntity(timestamp=self.stamp(seconds), frame_id=frame, id=name, frame_locked=True,
                                  **primitives)

    def line(self, points: FloatArray, thickness: float, rgba: Sequence[float], kind: str = "LineStrip") -> Any:
        return self.m.LinePrimitive(type=getattr(self.m.LinePrimitiveLineType, kind), pose=self.pose((0, 0, 0)),
                                    thickness=thickness, points=[self.point(p) for p in points],
                                    color=self.color(rgba))

    def sphere(self, position: Sequence[float] | FloatArray, diameter: float, rgba: Sequence[float]) -> Any:
        return self.m.SpherePrimitive(pose=self.pose(position), size=self.vector([diameter] * 3),
                                      color=self.color(rgba))


def nanoseconds(seconds: float) -> int:
    """Simulated seconds as integer nanoseconds (MCAP's and Foxglove's times)."""
    return round(float(seconds) * 1e9)


def _log_run(log: _Log, label: str, world: World, run: Run) -> None:
    """Everything of one run on its topics and frames."""
    first = float(run.times[0]) if len(run.times) else 0.0
    _log_frames(log, label, world, run)
    entities = _scene(log, label, world, run, first)
    log(f"/{label}/scene", "SceneUpdate", log.m.SceneUpdate(entities=entities), first)
    poses = np.asarray(run.poses, dtype=np.float64)
    rotations = quaternions(poses[:, 3:6])
    for time_, position, rotation in zip(run.times, poses[:, :3], rotations, strict=True):
        log(f"/{label}/robot/pose", "PoseInFrame", log.m.PoseInFrame(
            timestamp=log.stamp(time_), frame_id=label, pose=log.pose(position, rotation)), time_)
    detail = run.detail
    if detail is not None and detail.scan_angles is not None and detail.scan_ranges is not None:
        _log_scan(log, label, run, *content.scan_points(run, detail))
    if detail is not None:
        _log_contacts(log, label, run, content.contacts(run, detail))
    if run.robot_kind == "arm":
        _log_arm_motion(log, label, world, run)
    _log_events(log, label, world, run)


def _log_frames(log: _Log, label: str, world: World, run: Run) -> None:
    """The robot's frame and every model's in the run's frame: static models' with the first sample, moving
    ones (a run with detail) at every sample."""
    m = log.m
    poses = np.asarray(run.poses, dtype=np.float64)
    rotations = quaternions(poses[:, 3:6])
    moving: list[tuple[str, FloatArray]] = []
    fixed = []
    for model in world.models:
        frame = f"{label}/models/{model.name}"
        recorded = content.model_poses(model, run)
        if recorded is not None:
            moving.append((frame, recorded))
        else:
            body_pose = content.body_frame(model)[0]
            fixed.append((frame, body_pose))
    for row, time_ in enumerate(run.times):
        stamp = log.stamp(time_)
        transforms = [m.FrameTransform(timestamp=stamp, parent_frame_id=label, child_frame_id=f"{label}/robot",
                                       translation=log.vector(poses[row, :3]), rotation=log.rotation(rotations[row]))]
        transforms += [m.FrameTransform(timestamp=stamp, parent_frame_id=label, child_frame_id=frame,
                                        translation=log.vector(recorded[row, :3]),
                                        rotation=log.rotation(recorded[row, 3:]))
                       for frame, recorded in moving]
        if row == 0:
            transforms += [m.FrameTransform(timestamp=stamp, parent_frame_id=label, child_frame_id=frame,
                                            translation=log.vector(pose.position),
                                            rotation=log.rotation(quaternion(pose)))
                           for frame, pose in fixed]
        log(f"/{label}/tf", "FrameTransforms", m.FrameTransforms(transforms=transforms), time_)


def _scene(log: _Log, label: str, world: World, run: Run, first: float) -> list[Any]:
    """The entities that hold at every time: the ground, the goal, the models, the robot's shape, the paths."""
    m = log.m
    entities = []
    box = content.ground_box(world, run)
    if box is not None:
        entities.append(log.entity(first, label, "ground", cubes=[m.CubePrimitive(
            pose=log.pose(box.centre), size=log.vector(box.half_sizes * 2.0), color=log.color(GROUND_RGBA))]))
    goal = content.goal(world)
    if goal is not None:
        entities.append(log.entity(
            first, label, goal.label, spheres=[log.sphere(goal.position, 0.06 if goal.arm else 0.16, GOAL_RGBA)],
            lines=[log.line(goal.circle, 0.008 if goal.arm else 0.03, GOAL_RGBA)]))
    for model in world.models:
        entities.append(_model(log, f"{label}/models/{model.name}", model, world, first))
    robot = f"{label}/robot"
    if run.robot_kind == "arm":
        entities.append(log.entity(first, robot, "gripper", cubes=[m.CubePrimitive(
            pose=log.pose((0, 0, 0)), size=log.vector(np.array(GRIPPER_HALF_SIZE) * 2.0),
            color=log.color(ROBOT_RGBA))], texts=[_text(log, (0, 0, 0.08), run.robot, ROBOT_RGBA)]))
        if world.scenario is not None:
            start = world.scenario.start
            entities.append(log.entity(first, label, "arm base",
                                       spheres=[log.sphere((start.x, start.y, start.z), 0.12, ROBOT_RGBA)]))
        if run.target_path is not None and len(run.target_path):
            entities.append(log.entity(first, label, "target path", lines=[
                log.line(np.asarray(run.target_path, dtype=np.float64), 0.01, TARGET_RGBA)]))
    else:
        length, width = run.footprint
        entities.append(log.entity(
            first, robot, "footprint",
            cubes=[m.CubePrimitive(pose=log.pose((0, 0, 0)), size=log.vector((length, width, FOOTPRINT_HEIGHT)),
                                   color=log.color(ROBOT_RGBA))],
            arrows=[m.ArrowPrimitive(pose=log.pose((0, 0, FOOTPRINT_HEIGHT / 2.0)), shaft_length=length * 0.55,
                                     shaft_diameter=0.04, head_length=length * 0.2, head_diameter=0.1,
                                     color=log.color(HEADING_RGBA))],
            texts=[_text(log, (0, 0, FOOTPRINT_HEIGHT), run.robot, ROBOT_RGBA)]))
    thin = run.robot_kind == "arm"
    entities.append(log.entity(first, label, "trajectory", lines=[
        log.line(np.asarray(run.poses, dtype=np.float64)[:, :3], 0.01 if thin else 0.04, TRAJECTORY_RGBA)]))
    return entities


def _model(log: _Log, frame: str, model: Model, world: World, first: float) -> Any:
    """A model's shapes in its body frame, in its colour."""
    m = log.m
    rgba = model_rgba(model)
    color = log.color(rgba)
    cubes, cylinders, spheres, triangles = [], [], [], []
    for shape in content.body_frame(model)[1]:
        pose = shape.pose
        if shape.kind == "box":
            cubes.append(m.CubePrimitive(pose=_pose(log, pose), size=log.vector(shape.size or (0, 0, 0)), color=color))
        elif shape.kind in ("cylinder", "capsule"):
            radius, length = float(shape.radius or 0.0), float(shape.length or 0.0)
            cylinders.append(m.CylinderPrimitive(pose=_pose(log, pose),
                                                 size=log.vector((2 * radius, 2 * radius, length)),
                                                 bottom_scale=1.0, top_scale=1.0, color=color))
            if shape.kind == "capsule":  # its two caps
                axis = pose.rotation[:, 2] * length / 2.0
                spheres += [log.sphere(pose.position + sign * axis, 2 * radius, rgba) for sign in (-1.0, 1.0)]
        elif shape.kind == "sphere":
            spheres.append(log.sphere(pose.position, 2 * float(shape.radius or 0.0), rgba))
        elif shape.kind in content.MESH_KINDS:
            mesh = content.triangle_mesh(shape, world.source)
            triangles.append(m.TriangleListPrimitive(
                pose=log.pose((0, 0, 0)), points=[log.point(v) for v in mesh.vertices], color=color,
                indices=[int(i) for i in mesh.faces.reshape(-1)]))
    return log.entity(first, frame, model.name, cubes=cubes, cylinders=cylinders, spheres=spheres,
                      triangles=triangles)


def _pose(log: _Log, pose: Pose) -> Any:
    return log.pose(pose.position, quaternion(pose))


def _text(log: _Log, position: Sequence[float], words: str, rgba: Sequence[float]) -> Any:
    return log.m.TextPrimitive(pose=log.pose(position), billboard=True, font_size=14.0, scale_invariant=True,
                               color=log.color(rgba), text=words)


def _log_scan(log: _Log, label: str, run: Run, points: FloatArray, counts: Any) -> None:
    """The laser's hits at each sample as a point cloud of x y z float32 in the run's frame."""
    m = log.m
    kind = m.PackedElementFieldNumericType.Float32
    fields = [m.PackedElementField(name=name, offset=4 * index, type=kind) for index, name in enumerate("xyz")]
    ends = np.cumsum(counts)
    for time_, end, count in zip(run.times[: len(counts)], ends, counts, strict=True):
        data = points[end - count: end].astype("<f4").tobytes()
        log(f"/{label}/scan", "PointCloud", m.PointCloud(
            timestamp=log.stamp(time_), frame_id=label, pose=log.pose((0, 0, 0)), point_stride=12, fields=fields,
            data=data), time_)


def _log_contacts(log: _Log, label: str, run: Run, found: content.Contacts) -> None:
    """A sphere per contact point at each sample (none: an empty entity), the models touched as metadata."""
    m = log.m
    start = 0
    for time_, count in zip(run.times[: len(found.counts)], found.counts, strict=True):
        models = found.models[start: start + count]
        spheres = [log.sphere(found.positions[i], 2 * float(found.radii[i]), CONTACT_RGBA)
                   for i in range(start, start + count)]
        start += count
        entity = m.SceneEntity(timestamp=log.stamp(time_), frame_id=label, id="contacts", spheres=spheres,
                               metadata=[m.KeyValuePair(key="models", value=",".join(models))])
        log(f"/{label}/contacts", "SceneUpdate", m.SceneUpdate(entities=[entity]), time_)


def _log_arm_motion(log: _Log, label: str, world: World, run: Run) -> None:
    """An arm's links (replayed through pybullet's forward kinematics) and its target, at each sample."""
    from pytest_ddenv.media.arm_links import arm_links

    links = arm_links(world, run)
    if links is not None:
        for row, time_ in enumerate(run.times[: len(links.positions)]):
            segments = links.bones(row).reshape(-1, 3)
            log(f"/{label}/arm/links", "SceneUpdate", log.m.SceneUpdate(entities=[log.entity(
                time_, label, "links", lines=[log.line(segments, 0.04, ROBOT_RGBA, "LineList")])]), time_)
    path = run.target_path
    if path is not None and len(path):
        for time_, position in zip(run.times[: len(path)], np.asarray(path, dtype=np.float64), strict=True):
            log(f"/{label}/target", "SceneUpdate", log.m.SceneUpdate(entities=[log.entity(
                time_, label, "target", spheres=[log.sphere(position, 0.04, TARGET_RGBA)])]), time_)


def _log_events(log: _Log, label: str, world: World, run: Run) -> None:
    """The failure marker at the failure time, and the text log."""
    m = log.m
    mark = content.failure_mark(run)
    if mark is not None:
        log(f"/{label}/failure", "SceneUpdate", m.SceneUpdate(entities=[log.entity(
            mark.time, label, "failure", spheres=[log.sphere(mark.position, 0.24, FAILURE_RGBA)],
            texts=[_text(log, mark.position + np.array([0.0, 0.0, 0.3]), mark.words, FAILURE_RGBA)])]), mark.time)
    levels = {"INFO": m.LogLevel.Info, "ERROR": m.LogLevel.Error}
    for line in content.log_lines(world, run):
        log(f"/{label}/log", "Log", m.Log(timestamp=log.stamp(line.time), level=levels[line.level],
                                          message=line.text, name=label), line.time)
