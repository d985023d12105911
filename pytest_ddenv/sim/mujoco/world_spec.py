"""A `World` and its robot as one MuJoCo `MjSpec`: the robot's bodies first (its degrees of freedom then have
the same indices in every candidate world), the ground plane, then one body per model in world order.

- a static model is a body without a joint (welded to the world); a dynamic one has a free joint and the
  world file's mass (1 kg when absent), with pybullet's inertia: a primitive's exact inertia, a compound of
  primitives with its centre of mass at the model origin and its bounding box's inertia (Bullet's
  btCompoundShape), the mass split equally between the shapes of a compound with a mesh, polyline, cone or
  heightmap (one pybullet link each);
- box, cylinder, sphere, capsule: MuJoCo's geoms (half sizes; cylinder and capsule along the local z axis,
  `length` the cylinder part, as ours); cone, mesh and polyline: convex mesh pieces (pieces.py); heightmap:
  an `hfield`.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from pytest_ddenv.errors import WorldError
from pytest_ddenv.sim.builder import GROUND_BODY_NAME
from pytest_ddenv.sim.mujoco.contacts import set_contact
from pytest_ddenv.sim.mujoco.pieces import Piece, dynamic_mesh_pieces, polyline_pieces, static_mesh_pieces
from pytest_ddenv.world.files import regular_file_problem, resolve_mesh_path
from pytest_ddenv.world.geometry import rotation_matrix
from pytest_ddenv.world.meshes import cone_mesh, load_heightmap
from pytest_ddenv.world.model import Model, Pose, Shape, World

_PRIMITIVES = ("box", "cylinder", "sphere", "capsule")


def world_spec(world: World, robot: mujoco.MjSpec, robot_prefix: str, friction: str) -> mujoco.MjSpec:
    """The spec of `robot` (attached with `robot_prefix`) in `world`, with MuJoCo's options set for
    deterministic runs (warm start off, constraint islands on: removing a far body leaves a run identical)."""
    spec = mujoco.MjSpec()
    spec.modelname = "world"
    physics = world.physics
    spec.option.timestep = float(physics.timestep)
    spec.option.gravity = list(physics.gravity)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST  # a velocity servo at 240 Hz needs it
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_WARMSTART
    spec.compiler.autolimits = True
    spec.worldbody.add_frame().attach_body(robot.worldbody.first_body(), robot_prefix, "")
    if world.ground is not None:
        ground = world.ground
        plane = spec.worldbody.add_geom(name=GROUND_BODY_NAME, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1],
                                        pos=[0, 0, ground.z])
        set_contact(plane, ground.mu, ground.restitution, friction)
    for model in world.models:
        _add_model(spec, model, world.source, friction)
    return spec


def _quaternion(pose: Pose) -> list[float]:
    quaternion = np.zeros(4)
    rotation = np.ascontiguousarray(rotation_matrix(pose.roll, pose.pitch, pose.yaw), dtype=np.float64)
    mujoco.mju_mat2Quat(quaternion, rotation.reshape(9))
    return quaternion.tolist()


def _add_model(spec: mujoco.MjSpec, model: Model, source: str | None, friction: str) -> None:
    if not model.static and any(shape.kind == "heightmap" for shape in model.shapes):
        raise WorldError("a heightmap is terrain and must be static", source=source, model=model.name,
                         field="static")
    body = spec.worldbody.add_body(name=model.name, pos=[model.pose.x, model.pose.y, model.pose.z],
                                   quat=_quaternion(model.pose))
    if not model.static:
        body.add_freejoint()
    per_shape = [_shape_geoms(spec, body, model, index, shape, source) for index, shape in enumerate(model.shapes)]
    for geom in (geom for geoms in per_shape for geom in geoms):
        set_contact(geom, model.mu, model.restitution, friction)
        geom.rgba = list(model.color)
    if model.static:
        return
    mass = float(model.mass if model.mass is not None else 1.0)
    if len(model.shapes) > 1 and all(shape.kind in _PRIMITIVES for shape in model.shapes):
        _compound_inertia(body, model, mass)
        return
    for geoms in per_shape:
        for geom in geoms:
            geom.mass = mass / len(per_shape) / len(geoms)


def _compound_inertia(body: mujoco.MjsBody, model: Model, mass: float) -> None:
    """Bullet's btCompoundShape: the centre of mass at the model origin, the inertia of its bounding box."""
    alone = World(models=(dataclasses.replace(model, pose=Pose()),))
    low, high = alone.bounds(model.name)
    x, y, z = (np.asarray(high, dtype=np.float64) - np.asarray(low, dtype=np.float64)).tolist()
    body.explicitinertial = True
    body.mass = mass
    body.ipos = [0.0, 0.0, 0.0]
    body.inertia = [mass / 12 * (y**2 + z**2), mass / 12 * (x**2 + z**2), mass / 12 * (x**2 + y**2)]


def _shape_geoms(spec: mujoco.MjSpec, body: mujoco.MjsBody, model: Model, index: int, shape: Shape,
                 source: str | None) -> list[mujoco.MjsGeom]:
    pose = shape.pose
    frame = {"pos": [pose.x, pose.y, pose.z], "quat": _quaternion(pose)}
    kind = mujoco.mjtGeom
    if shape.kind == "box":
        assert shape.size is not None
        return [body.add_geom(type=kind.mjGEOM_BOX, size=[v / 2.0 for v in shape.size], **frame)]
    if shape.kind in ("cylinder", "capsule"):
        assert shape.radius is not None and shape.length is not None
        geom_type = kind.mjGEOM_CYLINDER if shape.kind == "cylinder" else kind.mjGEOM_CAPSULE
        return [body.add_geom(type=geom_type, size=[shape.radius, shape.length / 2.0, 0.0], **frame)]
    if shape.kind == "sphere":
        assert shape.radius is not None
        return [body.add_geom(type=kind.mjGEOM_SPHERE, size=[shape.radius, 0.0, 0.0], **frame)]
    if shape.kind == "heightmap":
        return [_hfield(spec, body, model, index, shape, source)]
    name = f"{model.name}#{index}"
    if shape.kind == "cone":
        assert shape.radius is not None and shape.length is not None
        cone: object = cone_mesh(shape.radius, shape.length)
        pieces: tuple[Piece, ...] = ((np.asarray(cone.vertices, dtype=np.float64),  # type: ignore[attr-defined]
                                      np.asarray(cone.faces, dtype=np.int64)),)  # type: ignore[attr-defined]
    elif shape.kind == "polyline":
        assert shape.points is not None and shape.height is not None
        pieces = polyline_pieces(shape.points, shape.height, model.static)
    else:
        path = resolve_mesh_path(shape.mesh, source)
        problem = regular_file_problem(path, "mesh file")
        if problem is not None:
            raise WorldError(problem, source=source, model=model.name, field="mesh")
        scale = (float(shape.scale[0]), float(shape.scale[1]), float(shape.scale[2]))
        pieces = (static_mesh_pieces if model.static else dynamic_mesh_pieces)(path, scale)
    return [_mesh_geom(spec, body, f"{name}/{k}", piece, frame) for k, piece in enumerate(pieces)]


def _mesh_geom(spec: mujoco.MjSpec, body: mujoco.MjsBody, name: str, piece: Piece,
               frame: dict[str, list[float]]) -> mujoco.MjsGeom:
    vertices, faces = piece
    mesh = spec.add_mesh(name=name)
    mesh.uservert = np.asarray(vertices, dtype=np.float32).reshape(-1).tolist()
    mesh.userface = np.asarray(faces, dtype=np.int32).reshape(-1).tolist()
    return body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name, **frame)


def _hfield(spec: mujoco.MjSpec, body: mujoco.MjsBody, model: Model, index: int, shape: Shape,
            source: str | None) -> mujoco.MjsGeom:
    """Our heightmap: image row 0 at the +y edge, a pixel's height value * size z above the shape's frame.
    MuJoCo's hfield: row 0 at the -y edge, the elevation scaled to [0, 1] times size[2] above the geom frame,
    with a solid base of size[3] below it; so the rows are flipped and the geom raised by the lowest height."""
    assert shape.size is not None
    heights = load_heightmap(resolve_mesh_path(shape.mesh, source))
    rows, columns = heights.shape
    low, high = float(heights.min()), float(heights.max())
    size_x, size_y, size_z = shape.size
    span = max(high - low, 1e-9)
    field = spec.add_hfield(name=f"{model.name}#{index}")
    field.nrow, field.ncol = rows, columns
    field.userdata = ((heights[::-1, :] - low) / span).astype(np.float32).reshape(-1).tolist()
    base = low * size_z
    field.size = [size_x / 2.0, size_y / 2.0, span * size_z if high > low else 1e-6, max(base, 1e-3)]
    pose = shape.pose
    return body.add_geom(type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=field.name,
                         pos=[pose.x, pose.y, pose.z + base], quat=_quaternion(pose))
