"""What a 3D recording of a run shows, as plain numbers: the work the Rerun recording (`recording.py`) and the
MCAP recording (`mcap.py`) share. Each function takes the world and the run and returns arrays and words; the
writers only put them into their format."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.world import geometry
from pytest_ddenv.world.files import resolve_mesh_path
from pytest_ddenv.world.meshes import cone_mesh, load_heightmap, load_mesh, polyline_mesh
from pytest_ddenv.world.model import Model, Pose, Shape, World

if TYPE_CHECKING:
    from pytest_ddenv.sim.run import Run, RunDetail

FloatArray = NDArray[np.float64]

FOOTPRINT_HEIGHT = 0.3
"""Height (m) of the robot's footprint box, centred on the robot's base frame."""
GROUND_MARGIN = 3.0
"""The ground box reaches this far (m) beyond the models, the trajectory and the goal."""
GROUND_THICKNESS = 0.02
MAX_HEIGHTMAP_SAMPLES = 257
"""A heightmap image is drawn with at most this many samples a side (a 1025 x 1025 image would be 2 M
triangles)."""
GRIPPER_HALF_SIZE = (0.02, 0.1, 0.03)
"""Half sizes (m) of the box drawn for an arm's gripper in the end effector's frame (a Franka hand's)."""
GOAL_CIRCLE_POINTS = 65


@dataclass(frozen=True)
class Box:
    """An axis-aligned box: its centre and half sizes (m)."""

    centre: FloatArray
    half_sizes: FloatArray


@dataclass(frozen=True)
class Goal:
    """The goal point (an arm's place region on its table's top), its tolerance circle (N, 3) and whether it
    is an arm's (drawn smaller)."""

    position: FloatArray
    circle: FloatArray
    arm: bool

    @property
    def label(self) -> str:
        return "place region" if self.arm else "goal"


@dataclass(frozen=True)
class TriangleMesh:
    """A mesh placed at its shape's pose (in the model's frame): vertices (V, 3), faces (F, 3), normals (V, 3)."""

    vertices: FloatArray
    faces: NDArray[np.uint32]
    normals: FloatArray


@dataclass(frozen=True)
class Contacts:
    """The contact points of a run: all of them (N, 3), a radius growing with the normal force (N,), the model
    touched (N,), and how many belong to each sample (T,)."""

    positions: FloatArray
    radii: FloatArray
    models: tuple[str, ...]
    counts: tuple[int, ...]


@dataclass(frozen=True)
class LogLine:
    time: float
    level: str
    text: str


@dataclass(frozen=True)
class FailureMark:
    """Where and when the run failed, and the words on the marker."""

    time: float
    position: FloatArray
    words: str


def ground_box(world: World, run: Run) -> Box | None:
    """A flat box whose top is the ground plane, under the models, the trajectory and the goal."""
    if world.ground is None:
        return None
    points = [run.positions[:, :2]]
    points += [world.bounds(model.name)[:, :2] for model in world.models]
    if world.scenario is not None:
        points.append(np.array([world.scenario.goal[:2]], dtype=np.float64))
    flat = np.concatenate(points)
    low, high = flat.min(axis=0) - GROUND_MARGIN, flat.max(axis=0) + GROUND_MARGIN
    centre = np.array([*((low + high) / 2.0), world.ground.z - GROUND_THICKNESS / 2.0])
    return Box(centre, np.array([*((high - low) / 2.0), GROUND_THICKNESS / 2.0]))


def goal(world: World) -> Goal | None:
    """The goal point (on the ground unless it has a z; an arm's place region lies on its table) and its
    tolerance circle, 1 cm above it."""
    scenario = world.scenario
    if scenario is None:
        return None
    x, y, z = scenario.goal
    height = z if z is not None else (world.ground.z if world.ground is not None else 0.0)
    arm = scenario.table is not None or scenario.target is not None
    if z is None and scenario.table in world.names:
        height = float(world.bounds(scenario.table)[1, 2])
    angles = np.linspace(0.0, 2.0 * math.pi, GOAL_CIRCLE_POINTS)
    radius = scenario.goal_tolerance
    circle = np.stack([x + radius * np.cos(angles), y + radius * np.sin(angles),
                       np.full(GOAL_CIRCLE_POINTS, height + 0.01)], 1)
    return Goal(np.array([x, y, height], dtype=np.float64), circle, arm)


def body_frame(model: Model) -> tuple[Pose, tuple[Shape, ...]]:
    """The pose of the model's simulated body (what `RunDetail.bodies` records) and the shapes in its frame:
    the model's pose and shapes, except for a moving model of one polyline, whose body frame is the
    polyline's centre of mass (see `pytest_ddenv.sim.builder`)."""
    shapes = model.shapes
    if len(shapes) == 1 and shapes[0].kind == "polyline" and model.dynamic:
        from pytest_ddenv.sim.builder import moved_shape, polyline_centre

        centre = polyline_centre(shapes[0])
        return model.pose.compose(centre), (moved_shape(shapes[0], centre),)
    return model.pose, shapes


def model_poses(model: Model, run: Run) -> FloatArray | None:
    """(T, 7) x y z qx qy qz qw of a moving model's body at every sample of a run with detail, else None (the
    model stays at `body_frame(model)[0]`)."""
    poses = None if run.detail is None else run.detail.bodies.get(model.name)
    if poses is not None and len(poses) == len(run.times):
        return np.asarray(poses, dtype=np.float64)
    return None


MESH_KINDS = ("mesh", "polyline", "heightmap", "cone")


def triangle_mesh(shape: Shape, source: str | None) -> TriangleMesh:
    """The triangles of a mesh, polyline (extruded), cone or heightmap shape, placed at the shape's pose."""
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
    return TriangleMesh(np.asarray(mesh.vertices, dtype=np.float64) @ rotation.T + shape.pose.position,
                        np.asarray(mesh.faces, dtype=np.uint32),
                        np.asarray(mesh.vertex_normals, dtype=np.float64) @ rotation.T)


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


def contacts(run: Run, detail: RunDetail) -> Contacts:
    """The contact points at each sample, with the model touched and a radius growing with the force."""
    samples = detail.contacts[: len(run.times)]
    flat = [contact for sample in samples for contact in sample]
    positions = np.array([contact[1:4] for contact in flat], dtype=np.float64).reshape(-1, 3)
    forces = np.array([contact[4] for contact in flat], dtype=np.float64)
    radii = np.clip(0.02 + 0.004 * np.sqrt(np.maximum(forces, 0.0)), 0.02, 0.2)
    return Contacts(positions, radii, tuple(str(contact[0]) for contact in flat),
                    tuple(len(sample) for sample in samples))


def failure_mark(run: Run) -> FailureMark | None:
    """The failure marker: at the failure pose, from the failure time, with the predicate and the time."""
    failure = run.failure
    if failure is None:
        return None
    return FailureMark(float(failure.time), np.asarray(failure.pose[:3], dtype=np.float64),
                       f"{failure.predicate} at t = {failure.time:.2f} s")


def log_lines(world: World, run: Run) -> list[LogLine]:
    """The text log: the run at its first time (INFO); the failure (ERROR), or how the run ended (INFO)."""
    first = float(run.times[0]) if len(run.times) else 0.0
    lines = [LogLine(first, "INFO",
                     f"{world.name or run.world_name}: {len(world.models)} models, robot {run.robot}, seed {run.seed}"
                     + (f", {run.engine} {run.engine_version}" if run.engine_version else ""))]
    failure = run.failure
    if failure is not None:
        lines.append(LogLine(float(failure.time), "ERROR", f"FAILED: {failure.explain()}"
                             + (f" {failure.detail}" if failure.detail else "")))
    elif len(run.times):
        ending = f"reached the goal at t = {run.goal_time:.2f} s" if run.reached_goal and run.goal_time is not None \
            else f"ended at t = {float(run.times[-1]):.2f} s without a failure"
        lines.append(LogLine(float(run.times[-1]), "INFO", ending))
    return lines


def time_range(runs: Sequence[tuple[str, World, Run]]) -> tuple[float, float]:
    """The first and last simulated time of all runs (their samples and failure times)."""
    times = [float(t) for _, _, run in runs for t in (run.times[:1].tolist() + run.times[-1:].tolist())]
    times += [float(run.failure.time) for _, _, run in runs if run.failure is not None]
    return (min(times), max(times)) if times else (0.0, 0.0)


def quaternions(rpy: FloatArray) -> FloatArray:
    """(N, 4) x y z w quaternions of (N, 3) fixed-axis roll, pitch, yaw (rotation Rz @ Ry @ Rx, as
    `pytest_ddenv.world.geometry.rotation_matrix` and pybullet's getQuaternionFromEuler)."""
    half = np.asarray(rpy, dtype=np.float64).reshape(-1, 3) / 2.0
    cr, cp, cy = np.cos(half).T
    sr, sp, sy = np.sin(half).T
    result: FloatArray = np.stack([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                                   cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy], axis=1)
    return result


def quaternion(pose: Pose) -> FloatArray:
    """The x y z w quaternion of a pose's roll, pitch, yaw."""
    one: FloatArray = quaternions(np.array([[pose.roll, pose.pitch, pose.yaw]]))[0]
    return one


def validate_labels(runs: Sequence[tuple[str, World, Run]]) -> None:
    """Labels must be distinct and not empty (each names a run's part of a recording)."""
    labels = [label for label, _, _ in runs]
    if not runs or any(not label for label in labels) or len(set(labels)) != len(labels):
        raise ValueError(f"expected one or more distinct, non-empty labels, got {labels}")
