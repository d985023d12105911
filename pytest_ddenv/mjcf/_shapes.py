"""MuJoCo geoms as the world model's shapes, read from the compiled scene (sizes, `fromto`, defaults, angle
units and mesh centring all resolved by MuJoCo) at the scene's initial configuration (`qpos0`)."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pytest_ddenv.world import geometry
from pytest_ddenv.world.geometry import FloatArray
from pytest_ddenv.world.meshes import load_heightmap
from pytest_ddenv.world.model import Pose, Shape

PLANE_THICKNESS = 0.1
"""A finite plane that is not the ground becomes a box this thick under its surface (m)."""
GEOM_TYPES = ("plane", "hfield", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh", "sdf")
"""MuJoCo's `mjtGeom` values 0-8, by name."""
UNSUPPORTED = {"ellipsoid": "the world model has no ellipsoid: write it as a sphere, capsule or box",
               "sdf": "signed-distance-field geoms (MuJoCo plugins) are not read"}


@dataclass(frozen=True)
class Frame:
    """A rigid transform: rotation matrix and position."""

    rotation: FloatArray
    position: FloatArray

    def inverse(self) -> Frame:
        return Frame(self.rotation.T, -self.rotation.T @ self.position)

    def then(self, child: Frame) -> Frame:
        """`child` (given in this frame) in this frame's parent."""
        return Frame(self.rotation @ child.rotation, self.position + self.rotation @ child.position)

    def pose(self) -> Pose:
        roll, pitch, yaw = geometry.rpy_from_matrix(self.rotation)
        x, y, z = (float(v) for v in self.position)
        return Pose(x, y, z, roll, pitch, yaw)


def quaternion_matrix(mujoco: Any, quaternion: FloatArray) -> FloatArray:
    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(quaternion, dtype=np.float64))
    return matrix.reshape(3, 3)


class GeomReader:
    """Shapes of the geoms of one compiled scene. `fail(message, geom id, field)` makes the error."""

    def __init__(self, mujoco: Any, model: Any, data: Any, spec: Any, folder: Path,
                 fail: Callable[[str, int, str], Exception]) -> None:
        self.mujoco, self.model, self.data, self.spec, self.folder, self.fail = mujoco, model, data, spec, folder, fail

    def type_name(self, geom: int) -> str:
        return GEOM_TYPES[int(self.model.geom_type[geom])]

    def frame(self, geom: int) -> Frame:
        """The geom's frame in the world (for a mesh: the mesh file's frame, before MuJoCo centred it)."""
        frame = Frame(self.data.geom_xmat[geom].reshape(3, 3).copy(), self.data.geom_xpos[geom].copy())
        if self.type_name(geom) == "mesh":
            mesh = int(self.model.geom_dataid[geom])
            centring = Frame(quaternion_matrix(self.mujoco, self.model.mesh_quat[mesh]), self.model.mesh_pos[mesh])
            frame = frame.then(centring.inverse())
        return frame

    def shape(self, geom: int, body: Frame) -> Shape:
        """The shape of `geom`, placed in the frame `body` (the model's)."""
        kind = self.type_name(geom)
        if kind in UNSUPPORTED:
            raise self.fail(f"unsupported geom type {kind}: {UNSUPPORTED[kind]}", geom, "geom/@type")
        size = [float(v) for v in self.model.geom_size[geom]]
        frame = self.frame(geom)
        if kind == "plane":  # a finite plane that is not the ground: a thin box under its surface
            if size[0] <= 0 or size[1] <= 0:
                raise self.fail("an infinite plane (size 0) inside a body, or a second or tilted ground plane: "
                                "give it a finite size, or make it the one horizontal plane in <worldbody>",
                                geom, "geom/@size")
            frame = frame.then(Frame(np.eye(3), np.array([0.0, 0.0, -PLANE_THICKNESS / 2])))
            return Shape("box", size=(2 * size[0], 2 * size[1], PLANE_THICKNESS), pose=self.placed(frame, body))
        pose = self.placed(frame, body)
        if kind == "box":
            return Shape("box", size=(2 * size[0], 2 * size[1], 2 * size[2]), pose=pose)
        if kind == "sphere":
            return Shape("sphere", radius=size[0], pose=pose)
        if kind in ("cylinder", "capsule"):  # MuJoCo's size: radius, half-length (of the cylinder part)
            return Shape("cylinder" if kind == "cylinder" else "capsule", radius=size[0], length=2 * size[1], pose=pose)
        if kind == "mesh":
            return self.mesh(geom, pose)
        return self.hfield(geom, pose)

    def placed(self, frame: Frame, body: Frame) -> Pose:
        return body.inverse().then(frame).pose()

    def mesh(self, geom: int, pose: Pose) -> Shape:
        mesh = self.spec.meshes[int(self.model.geom_dataid[geom])]
        if not mesh.file:
            raise self.fail(f"mesh {mesh.name!r} has no file (vertices written in the scene are not read)", geom,
                            "mesh/@file")
        path = self.asset_file(mesh.file, self.spec.meshdir, self.folder)
        sx, sy, sz = (float(v) for v in mesh.scale)
        return Shape("mesh", mesh=str(path), scale=(sx, sy, sz), pose=pose)

    def hfield(self, geom: int, pose: Pose) -> Shape:
        field = self.spec.hfields[int(self.model.geom_dataid[geom])]
        if not field.file:
            raise self.fail(f"height field {field.name!r} has no image file (elevation data in the scene is not "
                            "read)", geom, "hfield/@file")
        radius_x, radius_y, top, _ = (float(v) for v in field.size)
        path = self.asset_file(field.file, self.spec.meshdir, self.folder)
        # MuJoCo stretches the image's grey levels from its darkest (0) to its brightest (top); the world model
        # from black (0) to white: the same surface is a taller heightmap moved down by its darkest level
        heights = load_heightmap(path)
        low, high = float(heights.min()), float(heights.max())
        full = top / (high - low) if high > low else top
        lowered = pose.compose(Pose(z=-low * full))
        return Shape("heightmap", mesh=str(path), size=(2 * radius_x, 2 * radius_y, full), pose=lowered)

    @staticmethod
    def asset_file(file: str, meshdir: str, folder: Path) -> Path:
        """Where MuJoCo reads a mesh or height-field file: as given when absolute, else in the compiler's
        `meshdir` (which `assetdir` sets), itself relative to the main file's folder `folder`; made absolute."""
        return Path(os.path.abspath(folder / meshdir / file))  # an absolute file stays itself
