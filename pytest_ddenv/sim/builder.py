"""Build a `World`'s ground and models as pybullet bodies, in the world's canonical order."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import Any

import numpy as np

from pytest_ddenv.errors import WorldError
from pytest_ddenv.sim.tracebacks import hidden_in_tracebacks
from pytest_ddenv.world.files import regular_file_problem, resolve_mesh_path
from pytest_ddenv.world.meshes import cone_mesh, load_heightmap, load_mesh, polyline_mesh, polyline_polygon
from pytest_ddenv.world.model import Model, Pose, Shape, World

__tracebackhide__ = hidden_in_tracebacks
"""pytest leaves this module's frames out of a failing test's traceback (see sim/tracebacks.py)."""

GROUND_BODY_NAME = "<ground>"
_NATIVE_MESH_SUFFIXES = (".obj", ".stl")
_OWN_LINK_KINDS = ("mesh", "polyline", "heightmap", "cone")
"""Shapes that `createCollisionShapeArray` cannot hold: a compound with one of them has a link per shape."""


WHEEL_MU = 1.0
"""The robot wheels' friction coefficient (the Husky URDF's lateral_friction)."""


def effective_mu(mu: float, friction: str) -> float:
    """pybullet lateralFriction for a world mu: min(mu, wheel mu) under "min", mu under "product"."""
    return min(mu, WHEEL_MU) if friction == "min" else mu


def build_world(p: Any, client: int, world: World, friction: str = "min") -> dict[int, str]:
    """Create the ground (if any) and every model; return body id -> model name (ground: '<ground>')."""
    bodies: dict[int, str] = {}
    if world.ground is not None:
        ground = world.ground
        shape = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=client)
        body = p.createMultiBody(0.0, shape, -1, [0.0, 0.0, ground.z], physicsClientId=client)
        p.changeDynamics(body, -1, lateralFriction=effective_mu(ground.mu, friction), restitution=ground.restitution,
                         physicsClientId=client)
        bodies[body] = GROUND_BODY_NAME
    for model in world.models:
        bodies[_build_model(p, client, model, world.source, friction)] = model.name
    return bodies


def _quaternion(p: Any, roll: float, pitch: float, yaw: float) -> list[float]:
    return list(p.getQuaternionFromEuler([roll, pitch, yaw]))


def _build_model(p: Any, client: int, model: Model, source: str | None, friction: str = "min") -> int:
    shapes = model.shapes
    if not model.static and any(s.kind == "heightmap" for s in shapes):
        raise WorldError("a heightmap is terrain and must be static", source=source, model=model.name,
                         field="static")
    if len(shapes) == 1 or not any(s.kind in _OWN_LINK_KINDS for s in shapes):
        pose = model.pose
        if len(shapes) == 1 and shapes[0].kind == "heightmap":  # a heightfield ignores its collision frame
            pose = model.pose.compose(_heightfield_frame(shapes[0], source))
        if len(shapes) == 1 and shapes[0].kind == "polyline" and not model.static:
            # the body's frame is its centre of mass (pybullet's rayTest misses parts of bodies whose inertial
            # frame is offset with baseInertialFramePosition)
            centre = polyline_centre(shapes[0])
            pose = model.pose.compose(centre)
            collision = _single_shape(p, client, moved_shape(shapes[0], centre), model, source)
        else:
            collision = _collision_shape(p, client, model, source)
        mass = 0.0 if model.static else float(model.mass if model.mass is not None else 1.0)
        body = p.createMultiBody(
            baseMass=mass,
            baseCollisionShapeIndex=collision,
            baseVisualShapeIndex=-1,
            basePosition=[pose.x, pose.y, pose.z],
            baseOrientation=_quaternion(p, pose.roll, pose.pitch, pose.yaw),
            useMaximalCoordinates=True,  # a rigid body: Bullet's cheaper solver path (docs/simulation.md)
            physicsClientId=client,
        )
        links: list[int] = [-1]
    else:  # compounds with meshes, polylines or heightmaps: one fixed link per shape
        body, links = _build_linked(p, client, model, source)
    for link in links:
        p.changeDynamics(
            body, link,
            lateralFriction=effective_mu(model.mu, friction),
            restitution=model.restitution,
            anisotropicFriction=_anisotropy(model),
            physicsClientId=client,
        )
    if not model.static:
        p.changeDynamics(body, -1, activationState=p.ACTIVATION_STATE_ENABLE_SLEEPING, physicsClientId=client)
    return int(body)


def _anisotropy(model: Model) -> list[float]:
    """mu2 mapping: isotropic. See docs/simulation.md ("Friction")."""
    return [1.0, 1.0, 1.0]


def _collision_shape(p: Any, client: int, model: Model, source: str | None) -> int:
    if len(model.shapes) == 1:
        return _single_shape(p, client, model.shapes[0], model, source)
    kinds, half_extents, radii, lengths, positions, orientations = [], [], [], [], [], []
    for shape in model.shapes:
        if shape.kind == "box":
            assert shape.size is not None
            kinds.append(p.GEOM_BOX)
            half_extents.append([v / 2.0 for v in shape.size])
            radii.append(0.0)
            lengths.append(0.0)
        elif shape.kind == "cylinder":
            kinds.append(p.GEOM_CYLINDER)
            half_extents.append([0.0, 0.0, 0.0])
            radii.append(float(shape.radius or 0.0))
            lengths.append(float(shape.length or 0.0))
        elif shape.kind == "capsule":  # `lengths`: the cylinder part, as SDF's <length>
            kinds.append(p.GEOM_CAPSULE)
            half_extents.append([0.0, 0.0, 0.0])
            radii.append(float(shape.radius or 0.0))
            lengths.append(float(shape.length or 0.0))
        else:  # sphere
            kinds.append(p.GEOM_SPHERE)
            half_extents.append([0.0, 0.0, 0.0])
            radii.append(float(shape.radius or 0.0))
            lengths.append(0.0)
        positions.append([shape.pose.x, shape.pose.y, shape.pose.z])
        orientations.append(_quaternion(p, shape.pose.roll, shape.pose.pitch, shape.pose.yaw))
    return int(p.createCollisionShapeArray(
        shapeTypes=kinds, radii=radii, halfExtents=half_extents, lengths=lengths,
        collisionFramePositions=positions, collisionFrameOrientations=orientations,
        physicsClientId=client,
    ))


def _single_shape(p: Any, client: int, shape: Shape, model: Model, source: str | None) -> int:
    frame = {
        "collisionFramePosition": [shape.pose.x, shape.pose.y, shape.pose.z],
        "collisionFrameOrientation": _quaternion(p, shape.pose.roll, shape.pose.pitch, shape.pose.yaw),
        "physicsClientId": client,
    }
    if shape.kind == "box":
        assert shape.size is not None
        return int(p.createCollisionShape(p.GEOM_BOX, halfExtents=[v / 2.0 for v in shape.size], **frame))
    if shape.kind == "cylinder":
        return int(p.createCollisionShape(p.GEOM_CYLINDER, radius=shape.radius, height=shape.length, **frame))
    if shape.kind == "sphere":
        return int(p.createCollisionShape(p.GEOM_SPHERE, radius=shape.radius, **frame))
    if shape.kind == "capsule":  # pybullet's height is the cylinder part, as SDF's <length>
        return int(p.createCollisionShape(p.GEOM_CAPSULE, radius=shape.radius, height=shape.length, **frame))
    if shape.kind == "polyline":
        return _polyline_shape(p, shape, model, source, frame)
    if shape.kind == "cone":  # pybullet has no cone: a convex mesh (the centre of mass at its mid-height)
        assert shape.radius is not None and shape.length is not None
        mesh: Any = cone_mesh(shape.radius, shape.length)
        return int(p.createCollisionShape(p.GEOM_MESH, vertices=np.asarray(mesh.vertices).tolist(), **frame))
    if shape.kind == "heightmap":
        return _heightfield_shape(p, client, shape, model, source)
    return _mesh_shape(p, client, shape, model, source, frame)


def _polyline_shape(p: Any, shape: Shape, model: Model, source: str | None, frame: dict[str, Any]) -> int:
    """The extruded outline: a concave triangle mesh when static, its convex hull when dynamic."""
    assert shape.points is not None and shape.height is not None
    mesh = polyline_mesh(shape.points, shape.height)
    vertices = np.asarray(mesh.vertices, dtype=float).tolist()  # type: ignore[attr-defined,type-var]
    if model.static:
        indices = np.asarray(mesh.faces, dtype=int).reshape(-1).tolist()  # type: ignore[attr-defined,type-var]
        index = p.createCollisionShape(p.GEOM_MESH, vertices=vertices, indices=indices,
                                       flags=p.GEOM_FORCE_CONCAVE_TRIMESH, **frame)
    else:
        index = p.createCollisionShape(p.GEOM_MESH, vertices=vertices, **frame)
    if index < 0:
        raise WorldError("pybullet could not build the polyline", source=source, model=model.name, field="points")
    return int(index)


def polyline_centre(shape: Shape) -> Pose:
    """The centre of mass of a uniform polyline prism in its model's frame (unrotated)."""
    assert shape.points is not None and shape.height is not None
    centroid = polyline_polygon(shape.points).centroid
    centre = shape.pose.compose(Pose(float(centroid.x), float(centroid.y), shape.height / 2.0))
    return Pose(centre.x, centre.y, centre.z)


def moved_shape(shape: Shape, origin: Pose) -> Shape:
    """`shape` in the frame of `origin`, a translation of its model's frame."""
    pose = dataclasses.replace(shape.pose, x=shape.pose.x - origin.x, y=shape.pose.y - origin.y,
                               z=shape.pose.z - origin.z)
    return dataclasses.replace(shape, pose=pose)


def _heightfield_shape(p: Any, client: int, shape: Shape, model: Model, source: str | None) -> int:
    """A GEOM_HEIGHTFIELD of the image: pybullet centres it on the middle of its height range and ignores a
    collision frame, so the body (or link) is placed at `_heightfield_frame`."""
    assert shape.size is not None
    rows, columns, data = _heightfield_data(resolve_mesh_path(shape.mesh, source))
    size_x, size_y, size_z = shape.size
    index = p.createCollisionShape(
        p.GEOM_HEIGHTFIELD, meshScale=[size_x / (columns - 1), size_y / (rows - 1), size_z],
        heightfieldData=data, numHeightfieldRows=columns, numHeightfieldColumns=rows, physicsClientId=client,
    )
    if index < 0:
        raise WorldError("pybullet could not build the heightmap", source=source, model=model.name, field="file")
    return int(index)


def _heightfield_frame(shape: Shape, source: str | None) -> Pose:
    """Where a heightfield goes in its model's frame: the shape's pose, raised by the middle of the heights."""
    assert shape.size is not None
    heights = load_heightmap(resolve_mesh_path(shape.mesh, source))
    middle = (float(heights.min()) + float(heights.max())) / 2.0 * shape.size[2]
    return shape.pose.compose(Pose(z=middle))


@functools.lru_cache(maxsize=4)  # a 1025 x 1025 image is a list of a million floats
def _heightfield_data(path: Path) -> tuple[int, int, list[float]]:
    """(rows, columns, samples) for pybullet: sample i + j * columns is column i (along +x) of row j (along
    +y, from the image's bottom row)."""
    heights = load_heightmap(path)
    rows, columns = heights.shape
    return rows, columns, heights[::-1, :].ravel().tolist()


def _mesh_shape(p: Any, client: int, shape: Shape, model: Model, source: str | None, frame: dict[str, Any]) -> int:
    path: Path = resolve_mesh_path(shape.mesh, source)
    problem = regular_file_problem(path, "mesh file")  # pybullet would wait forever on a FIFO
    if problem is not None:
        raise WorldError(problem, source=source, model=model.name, field="mesh")
    flags = p.GEOM_FORCE_CONCAVE_TRIMESH if model.static else 0
    if path.suffix.lower() in _NATIVE_MESH_SUFFIXES:
        index = p.createCollisionShape(p.GEOM_MESH, fileName=str(path), meshScale=list(shape.scale),
                                       flags=flags, **frame)
    else:
        mesh = load_mesh(path, shape.scale)
        vertices = np.asarray(mesh.vertices, dtype=float).tolist()  # type: ignore[attr-defined,type-var]
        if model.static:
            indices = np.asarray(mesh.faces, dtype=int).reshape(-1).tolist()  # type: ignore[attr-defined,type-var]
            index = p.createCollisionShape(p.GEOM_MESH, vertices=vertices, indices=indices, flags=flags, **frame)
        else:
            index = p.createCollisionShape(p.GEOM_MESH, vertices=vertices, **frame)
    if index < 0:
        raise WorldError(f"pybullet could not build the mesh {path}", source=source, model=model.name, field="mesh")
    return int(index)


def _build_linked(p: Any, client: int, model: Model, source: str | None) -> tuple[int, list[int]]:
    """The base holds the first shape and each other shape is a fixed link; with a heightmap (whose pose is its
    link's, see `_heightfield_frame`) the base holds nothing and every shape is a link."""
    if any(shape.kind == "heightmap" for shape in model.shapes):
        base_shape, linked = -1, model.shapes
    else:
        base_shape, linked = _single_shape(p, client, model.shapes[0], model, source), model.shapes[1:]
    shape_ids = [_single_shape(p, client, shape, model, source) for shape in linked]
    frames = [_heightfield_frame(shape, source) if shape.kind == "heightmap" else None for shape in linked]
    total = 0.0 if model.static else float(model.mass if model.mass is not None else 1.0)
    each = total / len(model.shapes)
    count = len(shape_ids)
    body = p.createMultiBody(
        baseMass=each,
        baseCollisionShapeIndex=base_shape,
        baseVisualShapeIndex=-1,
        basePosition=[model.pose.x, model.pose.y, model.pose.z],
        baseOrientation=_quaternion(p, model.pose.roll, model.pose.pitch, model.pose.yaw),
        linkMasses=[each] * count,
        linkCollisionShapeIndices=shape_ids,
        linkVisualShapeIndices=[-1] * count,
        linkPositions=[[0.0, 0.0, 0.0] if f is None else [f.x, f.y, f.z] for f in frames],
        linkOrientations=[[0.0, 0.0, 0.0, 1.0] if f is None else _quaternion(p, f.roll, f.pitch, f.yaw)
                          for f in frames],
        linkInertialFramePositions=[[0.0, 0.0, 0.0]] * count,
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * count,
        linkParentIndices=[0] * count,
        linkJointTypes=[p.JOINT_FIXED] * count,
        linkJointAxis=[[0.0, 0.0, 1.0]] * count,
        physicsClientId=client,
    )
    return body, [-1, *range(count)]
