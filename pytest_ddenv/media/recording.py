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

import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.media.palette import GROUND_RGBA, ROBOT_RGBA, model_rgba
from pytest_ddenv.world import geometry
from pytest_ddenv.world.files import resolve_mesh_path
from pytest_ddenv.world.meshes import cone_mesh, load_heightmap, load_mesh, polyline_mesh
from pytest_ddenv.world.model import Model, Pose, Shape, World

if TYPE_CHECKING:
    from pytest_ddenv.sim.run import Run, RunDetail

FloatArray = NDArray[np.float64]

TIMELINE = "sim_time"
"""The one timeline of a recording: simulated seconds (a duration timeline)."""
INSTALL_HINT = "the 3D recording needs rerun-sdk: pip install 'pytest-ddenv[viewer]'"
FOOTPRINT_HEIGHT = 0.3
"""Height (m) of the robot's footprint box, centred on the robot's base frame."""
GROUND_MARGIN = 3.0
"""The ground box reaches this far (m) beyond the models, the trajectory and the goal."""
MAX_HEIGHTMAP_SAMPLES = 257
"""A heightmap image is drawn with at most this many samples a side (a 1025 x 1025 image would be 2 M
triangles)."""
HEADING_RGBA = (0.15, 0.15, 0.15, 1.0)
TRAJECTORY_RGBA = (0.12, 0.47, 0.71, 1.0)
SCAN_RGBA = (0.17, 0.63, 0.17, 1.0)
CONTACT_RGBA = (1.0, 0.5, 0.05, 1.0)
FAILURE_RGBA = (0.84, 0.15, 0.16, 1.0)
GOAL_RGBA = (0.2, 0.7, 0.3, 1.0)
TARGET_RGBA = (0.58, 0.25, 0.75, 1.0)
GRIPPER_HALF_SIZE = (0.02, 0.1, 0.03)
"""Half sizes (m) of the box drawn for an arm's gripper in the end effector's frame (a Franka hand's)."""


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
    labels = [label for label, _, _ in runs]
    if not runs or any(not label for label in labels) or len(set(labels)) != len(labels):
        raise ValueError(f"expected one or more distinct, non-empty labels, got {labels}")
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
    return RecordingInfo(path, tuple(writer.entities), _time_range(runs), path.stat().st_size,
                         time.perf_counter() - started)


def _time_range(runs: Sequence[tuple[str, World, Run]]) -> tuple[float, float]:
    """The first and last simulated time of all runs (their samples and failure times)."""
    times = [float(t) for _, _, run in runs for t in (run.times[:1].tolist() + run.times[-1:].tolist())]
    times += [float(run.failure.time) for _, _, run in runs if run.failure is not None]
    return (min(times), max(times)) if times else (0.0, 0.0)


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
    if world.ground is None:
        return
    points = [run.positions[:, :2]]
    points += [world.bounds(model.name)[:, :2] for model in world.models]
    if world.scenario is not None:
        points.append(np.array([world.scenario.goal[:2]], dtype=np.float64))
    flat = np.concatenate(points)
    low, high = flat.min(axis=0) - GROUND_MARGIN, flat.max(axis=0) + GROUND_MARGIN
    thickness = 0.02
    centre = [*((low + high) / 2.0), world.ground.z - thickness / 2.0]
    writer.static(f"{root}/ground", writer.rr.Boxes3D(
        centers=[centre], half_sizes=[[*((high - low) / 2.0), thickness / 2.0]], colors=[GROUND_RGBA],
        fill_mode="solid"))


def _log_goal(writer: _Writer, root: str, world: World) -> None:
    """The goal point (on the ground unless it has a z; an arm's place region on its table) and its tolerance
    circle."""
    scenario = world.scenario
    if scenario is None:
        return
    x, y, z = scenario.goal
    height = z if z is not None else (world.ground.z if world.ground is not None else 0.0)
    arm = scenario.table is not None or scenario.target is not None
    if z is None and scenario.table in world.names:  # an arm's place region lies on its table
        height = float(world.bounds(scenario.table)[1, 2])
    rr = writer.rr
    writer.static(f"{root}/goal", rr.Points3D([[x, y, height]], radii=0.03 if arm else 0.08, colors=[GOAL_RGBA],
                                              labels=["place region" if arm else "goal"]))
    angles = np.linspace(0.0, 2.0 * math.pi, 65)
    radius = scenario.goal_tolerance
    circle = np.stack([x + radius * np.cos(angles), y + radius * np.sin(angles), np.full(65, height + 0.01)], 1)
    writer.static(f"{root}/goal/tolerance", rr.LineStrips3D([circle], radii=0.004 if arm else 0.015,
                                                            colors=[GOAL_RGBA]))


def _log_model(writer: _Writer, entity: str, model: Model, world: World, run: Run) -> None:
    """The model's pose (over time if it moves and the run has its poses) and its shapes in its frame."""
    rr = writer.rr
    body_pose, shapes = _body_frame(model)
    poses = None if run.detail is None else run.detail.bodies.get(model.name)
    if poses is not None and len(poses) == len(run.times):
        writer.columns(entity, run.times, rr.Transform3D.columns(translation=poses[:, :3], quaternion=poses[:, 3:]))
    else:
        writer.static(entity, rr.Transform3D(translation=body_pose.position, quaternion=_quaternion(body_pose)))
    rgba = model_rgba(model)
    for kind, archetype in _primitives(rr, shapes, rgba):
        writer.static(f"{entity}/{kind}", archetype)
    for index, shape in enumerate(shapes):
        if shape.kind in ("mesh", "polyline", "heightmap", "cone"):
            writer.static(f"{entity}/mesh{index}", _mesh(rr, shape, world.source, rgba))


def _body_frame(model: Model) -> tuple[Pose, tuple[Shape, ...]]:
    """The pose of the model's simulated body (what `RunDetail.bodies` records) and the shapes in its frame:
    the model's pose and shapes, except for a moving model of one polyline, whose body frame is the
    polyline's centre of mass (see `pytest_ddenv.sim.builder`)."""
    shapes = model.shapes
    if len(shapes) == 1 and shapes[0].kind == "polyline" and model.dynamic:
        from pytest_ddenv.sim.builder import moved_shape, polyline_centre

        centre = polyline_centre(shapes[0])
        return model.pose.compose(centre), (moved_shape(shapes[0], centre),)
    return model.pose, shapes


def _primitives(rr: Any, shapes: Sequence[Shape], rgba: Sequence[float]) -> list[tuple[str, Any]]:
    """(entity name, archetype) of the model's boxes, cylinders, capsules and spheres, one batch per kind."""
    found: list[tuple[str, Any]] = []
    boxes = [s for s in shapes if s.kind == "box"]
    if boxes:
        found.append(("boxes", rr.Boxes3D(
            half_sizes=[[v / 2.0 for v in s.size or (0.0, 0.0, 0.0)] for s in boxes],
            centers=[s.pose.position for s in boxes], quaternions=[_quaternion(s.pose) for s in boxes],
            colors=[rgba], fill_mode="solid")))
    cylinders = [s for s in shapes if s.kind == "cylinder"]
    if cylinders:
        found.append(("cylinders", rr.Cylinders3D(
            lengths=[s.length for s in cylinders], radii=[s.radius for s in cylinders],
            centers=[s.pose.position for s in cylinders], quaternions=[_quaternion(s.pose) for s in cylinders],
            colors=[rgba], fill_mode="solid")))
    capsules = [s for s in shapes if s.kind == "capsule"]
    if capsules:  # rerun's capsule runs from its origin along +z: start it half a length below the centre
        starts = [s.pose.position - s.pose.rotation[:, 2] * float(s.length or 0.0) / 2.0 for s in capsules]
        found.append(("capsules", rr.Capsules3D(
            lengths=[s.length for s in capsules], radii=[s.radius for s in capsules], translations=starts,
            quaternions=[_quaternion(s.pose) for s in capsules], colors=[rgba], fill_mode="solid")))
    spheres = [s for s in shapes if s.kind == "sphere"]
    if spheres:
        found.append(("spheres", rr.Ellipsoids3D(
            half_sizes=[[s.radius] * 3 for s in spheres], centers=[s.pose.position for s in spheres],
            colors=[rgba], fill_mode="solid")))
    return found


def _mesh(rr: Any, shape: Shape, source: str | None, rgba: Sequence[float]) -> Any:
    """A `Mesh3D` of a mesh, polyline or heightmap shape, its vertices placed at the shape's pose."""
    import trimesh

    if shape.kind == "polyline":
        assert shape.points is not None and shape.height is not None
        mesh: Any = polyline_mesh(shape.points, shape.height)
    elif shape.kind == "cone":
        assert shape.radius is not None and shape.length is not None
        mesh = cone_mesh(shape.radius, shape.length)
    elif shape.kind == "heightmap":
        assert shape.size is not None
        heights = load_heightmap(resolve_mesh_path(shape.mesh, source))
        rows, columns = (np.unique(np.linspace(0, n - 1, min(n, MAX_HEIGHTMAP_SAMPLES)).round().astype(int))
                         for n in heights.shape)
        vertices, faces = geometry.heightmap_solid(heights[np.ix_(rows, columns)], shape.size)
        mesh = trimesh.Trimesh(vertices, faces, process=False)
    else:
        mesh = load_mesh(resolve_mesh_path(shape.mesh, source), shape.scale)
    rotation = shape.pose.rotation
    vertices = np.asarray(mesh.vertices, dtype=np.float64) @ rotation.T + shape.pose.position
    normals = np.asarray(mesh.vertex_normals, dtype=np.float64) @ rotation.T
    return rr.Mesh3D(vertex_positions=vertices, triangle_indices=np.asarray(mesh.faces, dtype=np.uint32),
                     vertex_normals=normals, albedo_factor=rgba)


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


def scan_points(run: Run, detail: RunDetail) -> tuple[FloatArray, NDArray[np.int64]]:
    """The laser's hits in the world frame, (N, 3), and how many belong to each sample, (T,): each ray leaves
    the laser (`scan_origin` on the robot, `scan_height` up), at the robot's yaw plus its angle, tilted down
    by `Laser.TILT` (as the laser casts it); rays without a hit are left out."""
    from pytest_ddenv.sim.laser import Laser

    assert detail.scan_angles is not None and detail.scan_ranges is not None
    ranges = np.asarray(detail.scan_ranges, dtype=np.float64)
    poses = np.asarray(run.poses, dtype=np.float64)[: len(ranges)]
    hit = np.isfinite(ranges)
    rows, rays = np.nonzero(hit)
    headings = detail.scan_angles[rays] + poses[rows, 5]
    reach = ranges[rows, rays]
    flat = reach * math.cos(Laser.TILT)
    forward, left = detail.scan_origin
    yaws = poses[rows, 5]
    x = poses[rows, 0] + forward * np.cos(yaws) - left * np.sin(yaws)
    y = poses[rows, 1] + forward * np.sin(yaws) + left * np.cos(yaws)
    points = np.stack([x + flat * np.cos(headings), y + flat * np.sin(headings),
                       poses[rows, 2] + detail.scan_height - reach * math.sin(Laser.TILT)], axis=1)
    return points, hit.sum(axis=1).astype(np.int64)


def _log_scan(writer: _Writer, entity: str, run: Run, detail: RunDetail) -> None:
    """The laser hits at each sample (one row per sample, empty when nothing was hit)."""
    points, counts = scan_points(run, detail)
    rr = writer.rr
    writer.static(entity, rr.Points3D.from_fields(radii=0.025, colors=[SCAN_RGBA]))
    writer.columns(entity, run.times[: len(counts)], rr.Points3D.columns(positions=points).partition(counts))


def _log_contacts(writer: _Writer, entity: str, run: Run, detail: RunDetail) -> None:
    """The contact points at each sample, labelled with the model touched, radius growing with the force."""
    samples = detail.contacts[: len(run.times)]
    flat = [contact for contacts in samples for contact in contacts]
    counts = [len(contacts) for contacts in samples]
    positions = np.array([contact[1:4] for contact in flat], dtype=np.float64).reshape(-1, 3)
    forces = np.array([contact[4] for contact in flat], dtype=np.float64)
    radii = np.clip(0.02 + 0.004 * np.sqrt(np.maximum(forces, 0.0)), 0.02, 0.2)
    rr = writer.rr
    writer.static(entity, rr.Points3D.from_fields(colors=[CONTACT_RGBA], show_labels=False))
    writer.columns(entity, run.times[: len(samples)], rr.Points3D.columns(
        positions=positions, radii=radii, labels=[str(contact[0]) for contact in flat]).partition(counts))


def _log_events(writer: _Writer, root: str, world: World, run: Run) -> None:
    """The text log (the run at its first time; the failure, or the end) and the failure marker."""
    rr = writer.rr
    first = float(run.times[0]) if len(run.times) else 0.0
    texts = [f"{world.name or run.world_name}: {len(world.models)} models, robot {run.robot}, seed {run.seed}"
             + (f", {run.engine} {run.engine_version}" if run.engine_version else "")]  # not for a reported run
    levels, times = ["INFO"], [first]
    failure = run.failure
    if failure is not None:
        words = f"{failure.predicate} at t = {failure.time:.2f} s"
        writer.columns(f"{root}/failure", [failure.time], rr.Points3D.columns(
            positions=[failure.pose[:3]], radii=[0.12], colors=[FAILURE_RGBA], labels=[words]))
        texts.append(f"FAILED: {failure.explain()}" + (f" {failure.detail}" if failure.detail else ""))
        levels.append("ERROR")
        times.append(float(failure.time))
    elif len(run.times):
        ending = f"reached the goal at t = {run.goal_time:.2f} s" if run.reached_goal and run.goal_time is not None \
            else f"ended at t = {float(run.times[-1]):.2f} s without a failure"
        texts.append(ending)
        levels.append("INFO")
        times.append(float(run.times[-1]))
    writer.columns(f"{root}/log", times, rr.TextLog.columns(text=texts, level=levels))


# -- numbers ----------------------------------------------------------------------------------------------
def quaternions(rpy: FloatArray) -> FloatArray:
    """(N, 4) x y z w quaternions of (N, 3) fixed-axis roll, pitch, yaw (rotation Rz @ Ry @ Rx, as
    `pytest_ddenv.world.geometry.rotation_matrix` and pybullet's getQuaternionFromEuler)."""
    half = np.asarray(rpy, dtype=np.float64).reshape(-1, 3) / 2.0
    cr, cp, cy = np.cos(half).T
    sr, sp, sy = np.sin(half).T
    result: FloatArray = np.stack([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                                   cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy], axis=1)
    return result


def _quaternion(pose: Pose) -> FloatArray:
    quaternion: FloatArray = quaternions(np.array([[pose.roll, pose.pitch, pose.yaw]]))[0]
    return quaternion
