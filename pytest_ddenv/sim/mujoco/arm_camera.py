"""An arm's declared camera in MuJoCo (`ArmObservation.image`): one ray per pixel, cast by `mj_multiRay`.

MuJoCo's own renderer needs an OpenGL context, which the test's process may not have (the media draw in a
helper process, media/gl_helper.py), and a picture every control tick cannot wait on one. So the picture is
ray cast, in the camera model of pybullet's (`PybulletArm.camera_image`): at `position`, looking at
`look_at`, the image's up the world's z (x when looking straight up or down), `fov` the vertical field of
view, each pixel sampled where TinyRenderer samples it. A depth picture is each pixel's distance along the
view axis (m; `CAMERA_FAR` where nothing is hit), as exact as MuJoCo's geometry; an RGB picture is the colour
of the model hit (the world's colours; the arm's and the ground's as MuJoCo has them), lit from the camera
(`AMBIENT` plus the rest times the cosine of the angle of incidence), on `BACKGROUND`. It reads the state
only: the run is unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.sim.arm.driven import CAMERA_FAR
from pytest_ddenv.world.model import Camera

AMBIENT = 0.4
BACKGROUND = (178, 178, 204)
"""The RGB of a pixel that sees nothing."""


def ray_picture(model: mujoco.MjModel, data: mujoco.MjData, camera: Camera,
                colors: Mapping[int, Sequence[float]]) -> NDArray[np.generic]:
    """`camera`'s picture of the state in `data`: (H, W, 3) uint8 RGB or (H, W) float32 depth (m). `colors`:
    body id -> RGBA (0-1) of the world's models."""
    directions, forward = _rays(camera)
    count = len(directions)
    hit = np.zeros(count, dtype=np.int32)
    distance = np.zeros(count)
    normal = np.zeros(3 * count)
    mujoco.mj_multiRay(model, data, np.asarray(camera.position, dtype=np.float64), directions.reshape(-1), None, True,
                       -1, hit, distance, normal, count, CAMERA_FAR)
    seen = hit >= 0
    if camera.kind == "depth":
        depth = np.full(count, CAMERA_FAR)
        depth[seen] = distance[seen] * (directions[seen] @ forward)
        picture: NDArray[np.generic] = np.minimum(depth, CAMERA_FAR).astype(np.float32)
        return picture.reshape(camera.height, camera.width)
    palette = np.asarray(model.geom_rgba[:, :3], dtype=np.float64).copy()
    for geom in range(model.ngeom):
        color = colors.get(int(model.geom_bodyid[geom]))
        if color is not None:
            palette[geom] = np.asarray(color[:3], dtype=np.float64)
    light = AMBIENT + (1.0 - AMBIENT) * np.abs(np.einsum("ij,ij->i", normal.reshape(-1, 3), directions))
    rgb = np.tile(np.asarray(BACKGROUND, dtype=np.float64) / 255.0, (count, 1))
    rgb[seen] = palette[hit[seen]] * light[seen, None]
    return np.round(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8).reshape(camera.height, camera.width, 3)


def _rays(camera: Camera) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The unit direction of each pixel's ray (row by row, from the top left) and the view axis."""
    position = np.asarray(camera.position, dtype=np.float64)
    forward = np.asarray(camera.look_at, dtype=np.float64) - position
    forward /= np.linalg.norm(forward)
    hint = np.array([1.0, 0.0, 0.0]) if abs(forward[2]) > 0.99 else np.array([0.0, 0.0, 1.0])
    right = np.cross(forward, hint)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    half = math.tan(math.radians(camera.fov) / 2.0)
    # each pixel sampled at its lower left corner, as pybullet's TinyRenderer samples it (measured: its pictures
    # and these agree pixel for pixel, where pixel centres put every row half a pixel off)
    columns = (2.0 * np.arange(camera.width) / camera.width - 1.0) * half * camera.width / camera.height
    rows = (1.0 - 2.0 * (np.arange(camera.height) + 1.0) / camera.height) * half
    y, x = np.meshgrid(rows, columns, indexing="ij")
    directions = forward + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up
    return directions / np.linalg.norm(directions, axis=1, keepdims=True), forward
