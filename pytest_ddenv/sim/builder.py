"""Build a `World`'s ground and models as pybullet bodies, in the world's canonical order."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pytest_ddenv.errors import WorldError
from pytest_ddenv.world import Model, Shape, World, load_mesh, resolve_mesh_path

GROUND_BODY_NAME = "<ground>"
_NATIVE_MESH_SUFFIXES = (".obj", ".stl")


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
    if len(shapes) == 1 or not any(s.kind == "mesh" for s in shapes):
        collision = _collision_shape(p, client, model, source)
        mass = 0.0 if model.static else float(model.mass if model.mass is not None else 1.0)
        body = p.createMultiBody(
            baseMass=mass,
            baseCollisionShapeIndex=collision,
            baseVisualShapeIndex=-1,
            basePosition=[model.pose.x, model.pose.y, model.pose.z],
            baseOrientation=_quaternion(p, model.pose.roll, model.pose.pitch, model.pose.yaw),
            physicsClientId=client,
        )
        links: list[int] = [-1]
    else:  # compounds with meshes: one fixed link per shape (createCollisionShapeArray has no vertices)
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
    return body


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
        else:  # sphere
            kinds.append(p.GEOM_SPHERE)
            half_extents.append([0.0, 0.0, 0.0])
            radii.append(float(shape.radius or 0.0))
            lengths.append(0.0)
        positions.append([shape.pose.x, shape.pose.y, shape.pose.z])
        orientations.append(_quaternion(p, shape.pose.roll, shape.pose.pitch, shape.pose.yaw))
    return p.createCollisionShapeArray(
        shapeTypes=kinds, radii=radii, halfExtents=half_extents, lengths=lengths,
        collisionFramePositions=positions, collisionFrameOrientations=orientations,
        physicsClientId=client,
    )


def _single_shape(p: Any, client: int, shape: Shape, model: Model, source: str | None) -> int:
    frame = {
        "collisionFramePosition": [shape.pose.x, shape.pose.y, shape.pose.z],
        "collisionFrameOrientation": _quaternion(p, shape.pose.roll, shape.pose.pitch, shape.pose.yaw),
        "physicsClientId": client,
    }
    if shape.kind == "box":
        assert shape.size is not None
        return p.createCollisionShape(p.GEOM_BOX, halfExtents=[v / 2.0 for v in shape.size], **frame)
    if shape.kind == "cylinder":
        return p.createCollisionShape(p.GEOM_CYLINDER, radius=shape.radius, height=shape.length, **frame)
    if shape.kind == "sphere":
        return p.createCollisionShape(p.GEOM_SPHERE, radius=shape.radius, **frame)
    return _mesh_shape(p, client, shape, model, source, frame)


def _mesh_shape(p: Any, client: int, shape: Shape, model: Model, source: str | None, frame: dict[str, Any]) -> int:
    path: Path = resolve_mesh_path(shape.mesh, source)
    if not path.exists():
        raise WorldError(f"mesh file not found: {path}", source=source, model=model.name, field="mesh")
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
    return index


def _build_linked(p: Any, client: int, model: Model, source: str | None) -> tuple[int, list[int]]:
    first, rest = model.shapes[0], model.shapes[1:]
    base_shape = _single_shape(p, client, first, model, source)
    shape_ids = [_single_shape(p, client, shape, model, source) for shape in rest]
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
        linkPositions=[[0.0, 0.0, 0.0]] * count,
        linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * count,
        linkInertialFramePositions=[[0.0, 0.0, 0.0]] * count,
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * count,
        linkParentIndices=[0] * count,
        linkJointTypes=[p.JOINT_FIXED] * count,
        linkJointAxis=[[0.0, 0.0, 1.0]] * count,
        physicsClientId=client,
    )
    return body, [-1, *range(count)]
