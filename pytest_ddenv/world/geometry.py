"""Rigid transforms and point-to-primitive distances, vectorised with numpy.

Conventions (the same as URDF and SDF): a pose is x y z roll pitch yaw, the rotation is
R = Rz(yaw) @ Ry(pitch) @ Rx(roll), and a point p in a frame with pose (t, R) is t + R @ p in the parent.
Cylinders have their axis along their local z.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def rotation_matrix(roll: float, pitch: float, yaw: float) -> FloatArray:
    """The 3x3 rotation of the fixed-axis roll-pitch-yaw angles (Rz @ Ry @ Rx)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def rpy_from_matrix(rotation: FloatArray) -> tuple[float, float, float]:
    """Roll, pitch, yaw of a rotation matrix (inverse of `rotation_matrix`)."""
    pitch = float(np.arcsin(np.clip(-rotation[2, 0], -1.0, 1.0)))
    if abs(rotation[2, 0]) < 1.0 - 1e-12:
        roll = float(np.arctan2(rotation[2, 1], rotation[2, 2]))
        yaw = float(np.arctan2(rotation[1, 0], rotation[0, 0]))
    else:  # gimbal lock: put everything in yaw
        roll = 0.0
        yaw = float(np.arctan2(-rotation[0, 1], rotation[1, 1]))
    return roll, pitch, yaw


def to_local(points: FloatArray, translation: FloatArray, rotation: FloatArray) -> FloatArray:
    """Express world points (N, 3) in a frame whose pose in the world is (translation, rotation)."""
    return (points - translation) @ rotation


def box_distance(local_points: FloatArray, size: FloatArray) -> FloatArray:
    """Distance from points (in the box frame) to a centred box of full `size`; 0 inside."""
    excess = np.maximum(np.abs(local_points) - size / 2.0, 0.0)
    distance: FloatArray = np.linalg.norm(excess, axis=1)
    return distance


def cylinder_distance(local_points: FloatArray, radius: float, length: float) -> FloatArray:
    """Distance from points (in the cylinder frame) to a centred z-axis cylinder; 0 inside."""
    radial = np.hypot(local_points[:, 0], local_points[:, 1]) - radius
    axial = np.abs(local_points[:, 2]) - length / 2.0
    return np.hypot(np.maximum(radial, 0.0), np.maximum(axial, 0.0))


def sphere_distance(local_points: FloatArray, radius: float) -> FloatArray:
    """Distance from points (in the sphere frame) to a centred sphere; 0 inside."""
    centre_distance: FloatArray = np.linalg.norm(local_points, axis=1)
    return np.maximum(centre_distance - radius, 0.0)


def box_corners(size: FloatArray) -> FloatArray:
    """The 8 corners (8, 3) of a centred box of full `size`."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
    return signs * (size / 2.0)


def cylinder_extent_points(radius: float, length: float, segments: int = 32) -> FloatArray:
    """Points on the rims of a z-axis cylinder, enough for tight axis-aligned bounds after rotation."""
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    ring = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    top = np.column_stack([ring, np.full(segments, length / 2.0)])
    bottom = np.column_stack([ring, np.full(segments, -length / 2.0)])
    return np.vstack([top, bottom])


def capsule_distance(local_points: FloatArray, radius: float, length: float) -> FloatArray:
    """Distance from points (in the capsule frame) to a centred z-axis capsule whose cylinder part is
    `length` long (the half-spheres add `radius` at each end); 0 inside."""
    radial = np.hypot(local_points[:, 0], local_points[:, 1])
    axial = np.maximum(np.abs(local_points[:, 2]) - length / 2.0, 0.0)
    return np.maximum(np.hypot(radial, axial) - radius, 0.0)


def capsule_bounds(translation: FloatArray, rotation: FloatArray, radius: float,
                   length: float) -> tuple[FloatArray, FloatArray]:
    """Exact axis-aligned bounds (low, high) of a capsule placed at (translation, rotation)."""
    half_axis = np.abs(rotation[:, 2]) * length / 2.0
    return translation - half_axis - radius, translation + half_axis + radius


def cone_distance(local_points: FloatArray, radius: float, length: float) -> FloatArray:
    """Distance from points (in the cone frame) to a z-axis cone whose base (of `radius`) is at z = -length/2
    and tip at z = +length/2, as SDF's `<cone>`; 0 inside. The distance in the half-plane (r, z) of each point
    to the triangle the cone turns."""
    r = np.hypot(local_points[:, 0], local_points[:, 1])
    z = local_points[:, 2]
    half = length / 2.0
    inside = (z >= -half) & (z <= half) & (r <= radius * (half - z) / length)
    base = _segment_distance(r, z, (0.0, -half), (radius, -half))
    side = _segment_distance(r, z, (radius, -half), (0.0, half))
    return np.where(inside, 0.0, np.minimum(base, side))


def cone_bounds(translation: FloatArray, rotation: FloatArray, radius: float,
                length: float) -> tuple[FloatArray, FloatArray]:
    """Exact axis-aligned bounds (low, high) of a cone placed at (translation, rotation): its base disc and tip."""
    axis = rotation[:, 2]
    base = translation - axis * length / 2.0
    tip = translation + axis * length / 2.0
    disc = radius * np.sqrt(np.clip(1.0 - axis**2, 0.0, 1.0))
    return np.minimum(base - disc, tip), np.maximum(base + disc, tip)


def _segment_distance(r: FloatArray, z: FloatArray, start: tuple[float, float],
                      end: tuple[float, float]) -> FloatArray:
    """Distance from the 2D points (r, z) to the segment from `start` to `end`."""
    (r0, z0), (r1, z1) = start, end
    dr, dz = r1 - r0, z1 - z0
    t = np.clip(((r - r0) * dr + (z - z0) * dz) / (dr * dr + dz * dz), 0.0, 1.0)
    distance: FloatArray = np.hypot(r - (r0 + t * dr), z - (z0 + t * dz))
    return distance


def prism_distance(planar_distance: FloatArray, local_z: FloatArray, height: float) -> FloatArray:
    """Distance to a prism (a planar region extruded from z = 0 to `height`), given each point's distance to
    the region in the xy plane (0 inside it) and its local z; 0 inside."""
    vertical = np.maximum(np.maximum(-local_z, local_z - height), 0.0)
    return np.hypot(planar_distance, vertical)


def heightmap_solid(heights: FloatArray, size: tuple[float, float, float]) -> tuple[FloatArray, FloatArray]:
    """Vertices (V, 3) and triangles (F, 3) of the solid under a heightmap.

    `heights` (rows, columns) are in 0..1, row 0 at the +y edge and column 0 at the -x edge (an image seen
    from above); the surface spans `size` x and y centred on the origin, heights scaled by `size` z, and the
    solid reaches down to z = 0 (four side walls and a bottom). Each grid cell is split along the diagonal
    from its (-x, +y) corner to its (+x, -y) corner, as `heightmap_height` interpolates.
    """
    rows, columns = heights.shape
    size_x, size_y, size_z = size
    xs = np.linspace(-size_x / 2.0, size_x / 2.0, columns)
    ys = np.linspace(size_y / 2.0, -size_y / 2.0, rows)
    grid_x, grid_y = np.meshgrid(xs, ys)
    top = np.column_stack([grid_x.ravel(), grid_y.ravel(), heights.ravel() * size_z])
    index = np.arange(rows * columns).reshape(rows, columns)
    a, b = index[:-1, :-1].ravel(), index[:-1, 1:].ravel()
    c, d = index[1:, 1:].ravel(), index[1:, :-1].ravel()
    faces = [np.column_stack([a, c, b]), np.column_stack([a, d, c])]  # counter-clockwise seen from above
    rim = np.concatenate([index[0, :], index[1:, -1], index[-1, -2::-1], index[-2:0:-1, 0]])  # clockwise from above
    base = top[rim] * np.array([1.0, 1.0, 0.0])
    count = len(top)
    ring = np.arange(len(rim))
    following = np.roll(ring, -1)
    faces.append(np.column_stack([rim[ring], rim[following], count + following]))
    faces.append(np.column_stack([rim[ring], count + following, count + ring]))
    corners = count + np.array([0, columns - 1, columns + rows - 2, 2 * columns + rows - 3])
    faces.append(np.array([[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]]))
    return np.vstack([top, base]), np.vstack(faces)


def heightmap_height(heights: FloatArray, size: tuple[float, float, float], xy: FloatArray) -> FloatArray:
    """The surface height of `heightmap_solid` at planar points (N, 2); NaN outside its rectangle."""
    rows, columns = heights.shape
    size_x, size_y, size_z = size
    column = (xy[:, 0] + size_x / 2.0) / size_x * (columns - 1)
    row = (size_y / 2.0 - xy[:, 1]) / size_y * (rows - 1)
    inside = (column >= 0) & (column <= columns - 1) & (row >= 0) & (row <= rows - 1)
    j = np.clip(np.floor(column), 0, columns - 2).astype(int)
    i = np.clip(np.floor(row), 0, rows - 2).astype(int)
    u, v = np.clip(column - j, 0.0, 1.0), np.clip(row - i, 0.0, 1.0)
    h_a, h_b = heights[i, j], heights[i, j + 1]
    h_c, h_d = heights[i + 1, j + 1], heights[i + 1, j]
    upper = h_a + u * (h_b - h_a) + v * (h_c - h_b)  # triangle a-b-c (u >= v)
    lower = h_a + v * (h_d - h_a) + u * (h_c - h_d)  # triangle a-c-d (u < v)
    height = np.where(u >= v, upper, lower) * size_z
    return np.where(inside, height, np.nan)
