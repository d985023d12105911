"""A scrubbable 3D recording of runs in Rerun's `.rrd` format (https://rerun.io), for the failing run and its
reduced counterpart side by side.

One file holds every run given to `write_recording`, each under its own entity subtree `/<label>/...`, all on
one timeline `sim_time` (simulated seconds), so that the runs scrub together in the viewer
(`rerun recording.rrd`). Per run:

    /<label>                    view coordinates (right-handed, z up)
    /<label>/ground             the ground: a flat box under the scene (static)
    /<label>/goal               the goal point; /<label>/goal/tolerance: the tolerance circle (static)
    /<label>/models/<name>      the model's pose: static, or over time for a moving model with `Run.detail`
    /<label>/models/<name>/...  its shapes in the model's frame (boxes, cylinders, capsules, spheres, mesh<i>)
    /<label>/robot              the robot base's pose over time
    /<label>/robot/footprint    the robot's footprint box and /<label>/robot/heading its +x arrow (robot frame)
    /<label>/trajectory/path    the whole trajectory as a line strip (static)
    /<label>/trajectory/position  the robot's position at each time
    /<label>/scan               the laser's hits in the world frame at each time (with `Run.detail`)
    /<label>/contacts           where the robot touches something at each time, radius growing with the force

An arm's run (`Run.robot_kind == "arm"`) has, instead of /<label>/robot's footprint and heading:

    /<label>/robot              the end effector's pose over time; /<label>/robot/gripper a small box in it
    /<label>/arm/base           the arm's base at the scenario's start (static)
    /<label>/arm/links          the arm's links as segments from each link's parent, at each time (with
                                `Run.detail` and pybullet: media/arm_links.py)
    /<label>/trajectory/...     the end effector's path and position
    /<label>/target/path        the target's path (static); /<label>/target/position: where it is at each time

and the rest as above (/<label>/goal is the place region).
    /<label>/failure            a red point and label at the failure pose, from the failure time on
    /<label>/log                text log: the run at t = 0, the failure (or the end) later

rerun-sdk is an optional dependency (`pip install 'pytest-ddenv[viewer]'`), imported only when a recording is
written. See docs/recording.md.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pytest_ddenv.media import content
from pytest_ddenv.media.content import (
    FOOTPRINT_HEIGHT,
    GRIPPER_HALF_SIZE,
    FloatArray,
    quaternion,
    quaternions,
    scan_points,
)
from pytest_ddenv.media.palette import (
    CONTACT_RGBA,
    FAILURE_RGBA,
    GOAL_RGBA,
    GROUND_RGBA,
    HEADING_RGBA,
    ROBOT_RGBA,
    SCAN_RGBA,
    TARGET_RGBA,
    TRAJECTORY_RGBA,
    model_rgba,
)
from pytest_ddenv.world.model import Model, Shape, World

if TYPE_CHECKING:
    from pytest_ddenv.sim.run import Run, RunDetail

TIMELINE = "sim_time"
"""The one timeline of a recording: simulated seconds (a duration timeline)."""
INSTALL_HINT = "the 3D recording needs rerun-sdk: pip install 'pytest-ddenv[viewer]'"


class RecordingUnavailable(ImportError):
    """rerun-sdk is not installed: the 3D recording cannot be written."""


def recording_available() -> bool:
    """Whether rerun-sdk can be imported (the `viewer` extra is installed)."""
    try:
        import rerun  # noqa: F401
    except ImportError:
        return False
    return True


def _rerun() -> Any:
    """The `rerun` module, or `RecordingUnavailable`."""
    try:
        import rerun
    except ImportError as error:
        raise RecordingUnavailable(INSTALL_HINT) from error
    return rerun


@dataclass(frozen=True)
class RecordingInfo:
    """What `write_recording` made: the file, the entity paths written, the simulated time range covered
    (first, last) in seconds, the bytes written and the seconds spent."""

    path: Path
    entities: tuple[str, ...]
    time_range: tuple[float, float]
    size_bytes: int
    seconds: float

    def to_dict(self) -> dict[str, Any]:
        return {"file": self.path.name, "entities": len(self.entities), "first_time": self.time_range[0],
                "last_time": self.time_range[1], "bytes": self.size_bytes, "seconds": round(self.seconds, 3)}


def write_recording(path: Path, runs: Sequence[tuple[str, World, Run]], *,
                    application_id: str = "pytest-ddenv") -> RecordingInfo:
    """Write every `(label, world, run)` into one Rerun `.rrd` file at `path`, each run under `/<label>`, all
    on the `sim_time` timeline; atomically (a temporary file, then renamed). Labels must be distinct and
    not empty. Raises `RecordingUnavailable` without rerun-sdk."""
    rr = _rerun()
    content.validate_labels(runs)
    labels = [label for label, _, _ in runs]
    started = time.perf_counter()
    path = Path(path)
    temporary = path.with_name(f".{path.name}.tmp{os.getpid()}")
    stream = rr.RecordingStream(application_id)
    writer = _Writer(rr, stream)
    try:
        stream.save(temporary, default_blueprint=_blueprint(rr, labels))
        stream.send_recording_name(" vs ".join(labels))
        for label, world, run in runs:
            _log_run(writer, "/" + rr.escape_entity_path_part(label), world, run)
        stream.flush()
        stream.disconnect()
        os.replace(temporary, path)
    except BaseException:
        stream.disconnect()
        temporary.unlink(missing_ok=True)
        raise
    return RecordingInfo(path, tuple(writer.entities), content.time_range(runs), path.stat().st_size,
                         time.perf_counter() - started)


def _blueprint(rr: Any, labels: Sequence[str]) -> Any:
    """The viewer's layout: one 3D view per run side by side, the text log under them."""
    import rerun.blueprint as rrb

    views = [rrb.Spatial3DView(origin="/" + rr.escape_entity_path_part(label), name=label) for label in labels]
    return rrb.Blueprint(
        rrb.Vertical(rrb.Horizontal(*views), rrb.TextLogView(origin="/", name="log"), row_shares=[5, 1]),
        rrb.TimePanel(timeline=TIMELINE),
    )


class _Writer:
    """Logs to one recording stream and remembers the entity paths written."""

    def __init__(self, rr: Any, stream: Any) -> None:
        self.rr, self.stream = rr, stream
        self.entities: list[str] = []

    def static(self, entity: str, *archetypes: Any) -> None:
        """Log data that holds at every time."""
        self.stream.log(entity, *archetypes, static=True)
        self._seen(entity)

    def columns(self, entity: str, times: Sequence[float] | FloatArray, columns: Any) -> None:
        """Log one row per time (`columns`: an archetype's `.columns(...)`, partitioned to match)."""
        index = self.rr.TimeColumn(TIMELINE, duration=np.asarray(times, dtype=np.float64))
        self.stream.send_columns(entity, indexes=[index], columns=columns)
        self._seen(entity)

    def _seen(self, entity: str) -> None:
        if entity not in self.entities:
            self.entities.append(entity)


def _log_run(writer: _Writer, root: str, world: World, run: Run) -> None:
    """Everything of one run under `root`."""
    writer.static(root, writer.rr.ViewCoordinates.RIGHT_HAND_Z_UP)
    _log_ground(writer, root, world, run)
    _log_goal(writer, root, world)
    for model in world.models:
        _log_model(writer, f"{root}/models/{writer.rr.escape_entity_path_part(model.name)}", model, world, run)
    if run.robot_kind == "arm":
        _log_arm(writer, root, world, run)
    else:
        _log_robot(writer, root, run)
    _log_trajectory(writer, root, run)
    detail = run.detail
    if detail is not None and detail.scan_angles is not None and detail.scan_ranges is not None:
        _log_scan(writer, f"{root}/scan", run, detail)
    if detail is not None:
        _log_contacts(writer, f"{root}/contacts", run, detail)
    _log_events(writer, root, world, run)


# -- the scene ------------------------------------------------------------------------------------------------
def _log_ground(writer: _Writer, root: str, world: World, run: Run) -> None:
    """A flat box whose top is the ground plane, under the models, the trajectory and the goal."""
    box = content.ground_box(world, run)
    if box is not None:
        writer.static(f"{root}/ground", writer.rr.Boxes3D(centers=[box.centre], half_sizes=[box.half_sizes],
                                                          colors=[GROUND_RGBA], fill_mode="solid"))


def _log_goal(writer: _Writer, root: str, world: World) -> None:
    """The goal point (an arm's place region on its table) and its tolerance circle."""
    goal = content.goal(world)
    if goal is None:
        return
    rr = writer.rr
    writer.static(f"{root}/goal", rr.Points3D([goal.position], radii=0.03 if goal.arm else 0.08, colors=[GOAL_RGBA],
                                              labels=[goal.label]))
    writer.static(f"{root}/goal/tolerance", rr.LineStrips3D([goal.circle], radii=0.004 if goal.arm else 0.015,
                                                            colors=[GOAL_RGBA]))


def _log_model(writer: _Writer, entity: str, model: Model, world: World, run: Run) -> None:
    """The model's pose (over time if it moves and the run has its poses) and its shapes in its frame."""
    rr = writer.rr
    body_pose, shapes = content.body_frame(model)
    poses = content.model_poses(model, run)
    if poses is not None:
        writer.columns(entity, run.times, rr.Transform3D.columns(translation=poses[:, :3], quaternion=poses[:, 3:]))
    else:
        writer.static(entity, rr.Transform3D(translation=body_pose.position, quaternion=quaternion(body_pose)))
    rgba = model_rgba(model)
    for kind, archetype in _primitives(rr, shapes, rgba):
        writer.static(f"{entity}/{kind}", archetype)
    for index, shape in enumerate(shapes):
        if shape.kind in content.MESH_KINDS:
            mesh = content.triangle_mesh(shape, world.source)
            writer.static(f"{entity}/mesh{index}", rr.Mesh3D(
                vertex_positions=mesh.vertices, triangle_indices=mesh.faces, vertex_normals=mesh.normals,
                albedo_factor=rgba))


def _primitives(rr: Any, shapes: Sequence[Shape], rgba: Sequence[float]) -> list[tuple[str, Any]]:
    """(entity name, archetype) of the model's boxes, cylinders, capsules and spheres, one batch per kind."""
    found: list[tuple[str, Any]] = []
    boxes = [s for s in shapes if s.kind == "box"]
    if boxes:
        found.append(("boxes", rr.Boxes3D(
            half_sizes=[[v / 2.0 for v in s.size or (0.0, 0.0, 0.0)] for s in boxes],
            centers=[s.pose.position for s in boxes], quaternions=[quaternion(s.pose) for s in boxes],
            colors=[rgba], fill_mode="solid")))
    cylinders = [s for s in shapes if s.kind == "cylinder"]
    if cylinders:
        found.append(("cylinders", rr.Cylinders3D(
            lengths=[s.length for s in cylinders], radii=[s.radius for s in cylinders],
            centers=[s.pose.position for s in cylinders], quaternions=[quaternion(s.pose) for s in cylinders],
            colors=[rgba], fill_mode="solid")))
    capsules = [s for s in shapes if s.kind == "capsule"]
    if capsules:  # rerun's capsule runs from its origin along +z: start it half a length below the centre
        starts = [s.pose.position - s.pose.rotation[:, 2] * float(s.length or 0.0) / 2.0 for s in capsules]
        found.append(("capsules", rr.Capsules3D(
            lengths=[s.length for s in capsules], radii=[s.radius for s in capsules], translations=starts,
            quaternions=[quaternion(s.pose) for s in capsules], colors=[rgba], fill_mode="solid")))
    spheres = [s for s in shapes if s.kind == "sphere"]
    if spheres:
        found.append(("spheres", rr.Ellipsoids3D(
            half_sizes=[[s.radius] * 3 for s in spheres], centers=[s.pose.position for s in spheres],
            colors=[rgba], fill_mode="solid")))
    return found


# -- the robot and what it sensed ---------------------------------------------------------------------------
def _log_robot(writer: _Writer, root: str, run: Run) -> None:
    """The base's pose over time, its footprint and heading (robot frame)."""
    rr = writer.rr
    poses = np.asarray(run.poses, dtype=np.float64)
    writer.columns(f"{root}/robot", run.times, rr.Transform3D.columns(
        translation=poses[:, :3], quaternion=quaternions(poses[:, 3:6])))
    length, width = run.footprint
    writer.static(f"{root}/robot/footprint", rr.Boxes3D(
        half_sizes=[[length / 2.0, width / 2.0, FOOTPRINT_HEIGHT / 2.0]], colors=[ROBOT_RGBA], labels=[run.robot],
        fill_mode="solid"))
    writer.static(f"{root}/robot/heading", rr.Arrows3D(
        origins=[[0.0, 0.0, FOOTPRINT_HEIGHT / 2.0]], vectors=[[length * 0.75, 0.0, 0.0]], colors=[HEADING_RGBA],
        radii=0.02))


def _log_trajectory(writer: _Writer, root: str, run: Run) -> None:
    """The robot's (an arm's: the end effector's) whole path, and its position at each time."""
    rr = writer.rr
    positions = np.asarray(run.poses, dtype=np.float64)[:, :3]
    thin = run.robot_kind == "arm"
    writer.static(f"{root}/trajectory/path", rr.LineStrips3D([positions], radii=0.005 if thin else 0.02,
                                                             colors=[TRAJECTORY_RGBA]))
    writer.static(f"{root}/trajectory/position", rr.Points3D.from_fields(radii=0.015 if thin else 0.05,
                                                                         colors=[TRAJECTORY_RGBA]))
    writer.columns(f"{root}/trajectory/position", run.times, rr.Points3D.columns(positions=positions))


def _log_arm(writer: _Writer, root: str, world: World, run: Run) -> None:
    """An arm: the end effector's pose and a box for its gripper, the base, the links, the target's path."""
    from pytest_ddenv.media.arm_links import arm_links

    rr = writer.rr
    poses = np.asarray(run.poses, dtype=np.float64)
    writer.columns(f"{root}/robot", run.times, rr.Transform3D.columns(
        translation=poses[:, :3], quaternion=quaternions(poses[:, 3:6])))
    writer.static(f"{root}/robot/gripper", rr.Boxes3D(half_sizes=[list(GRIPPER_HALF_SIZE)], colors=[ROBOT_RGBA],
                                                       labels=[run.robot], fill_mode="solid"))
    if world.scenario is not None:
        start = world.scenario.start
        writer.static(f"{root}/arm/base", rr.Points3D([[start.x, start.y, start.z]], radii=0.06,
                                                      colors=[ROBOT_RGBA], labels=["arm base"]))
    links = arm_links(world, run)
    if links is not None:
        count = len(links.parents)
        segments = np.concatenate([links.bones(row) for row in range(len(links.positions))])
        writer.static(f"{root}/arm/links", rr.LineStrips3D.from_fields(radii=0.02, colors=[ROBOT_RGBA]))
        writer.columns(f"{root}/arm/links", run.times[: len(links.positions)], rr.LineStrips3D.columns(
            strips=list(segments)).partition([count] * len(links.positions)))
    path = run.target_path
    if path is not None and len(path):
        target = np.asarray(path, dtype=np.float64)
        writer.static(f"{root}/target/path", rr.LineStrips3D([target], radii=0.005, colors=[TARGET_RGBA]))
        writer.static(f"{root}/target/position", rr.Points3D.from_fields(radii=0.02, colors=[TARGET_RGBA]))
        writer.columns(f"{root}/target/position", run.times[: len(target)], rr.Points3D.columns(positions=target))


def _log_scan(writer: _Writer, entity: str, run: Run, detail: RunDetail) -> None:
    """The laser hits at each sample (one row per sample, empty when nothing was hit)."""
    points, counts = scan_points(run, detail)
    rr = writer.rr
    writer.static(entity, rr.Points3D.from_fields(radii=0.025, colors=[SCAN_RGBA]))
    writer.columns(entity, run.times[: len(counts)], rr.Points3D.columns(positions=points).partition(counts))


def _log_contacts(writer: _Writer, entity: str, run: Run, detail: RunDetail) -> None:
    """The contact points at each sample, labelled with the model touched, radius growing with the force."""
    found = content.contacts(run, detail)
    rr = writer.rr
    writer.static(entity, rr.Points3D.from_fields(colors=[CONTACT_RGBA], show_labels=False))
    writer.columns(entity, run.times[: len(found.counts)], rr.Points3D.columns(
        positions=found.positions, radii=found.radii, labels=list(found.models)).partition(list(found.counts)))


def _log_events(writer: _Writer, root: str, world: World, run: Run) -> None:
    """The text log (the run at its first time; the failure, or the end) and the failure marker."""
    rr = writer.rr
    mark = content.failure_mark(run)
    if mark is not None:
        writer.columns(f"{root}/failure", [mark.time], rr.Points3D.columns(
            positions=[mark.position], radii=[0.12], colors=[FAILURE_RGBA], labels=[mark.words]))
    lines = content.log_lines(world, run)
    writer.columns(f"{root}/log", [line.time for line in lines], rr.TextLog.columns(
        text=[line.text for line in lines], level=[line.level for line in lines]))
