"""The robot's planar laser: rays cast by the physics engine, a fixed number of noise draws."""

from __future__ import annotations

import math

import numpy as np

from pytest_ddenv.sim.builder import GROUND_BODY_NAME
from pytest_ddenv.sim.control import FloatArray, LaserScan
from pytest_ddenv.sim.physics import PhysicsEngine
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.world.model import LaserMount


class Laser:
    """A planar laser mounted on the robot, rays tilted slightly down so low clutter near the robot is seen."""

    TILT = 0.08  # rad below horizontal: from 0.35 m up, the rays reach the ground about 4 m out

    def __init__(self, physics: PhysicsEngine, settings: RunSettings, mount: LaserMount) -> None:
        self.physics = physics
        self.rays = settings.laser_rays
        self.range = settings.laser_range
        self.mount = mount
        self.bodies = physics.bodies
        fov = settings.laser_fov
        if fov >= 2 * math.pi - 1e-9:
            angles = np.arange(self.rays) * (2 * math.pi / self.rays) - math.pi
        else:
            angles = np.linspace(-fov / 2.0, fov / 2.0, self.rays)
        if mount.yaw:  # the laser is turned on the robot: its rays' angles in the robot's frame
            angles = angles + mount.yaw
        self.angles: FloatArray = np.asarray(angles, dtype=np.float64)
        self.angles.flags.writeable = False
        self.ranges = np.full(self.rays, np.inf)
        self.origin = (float(mount.x), float(mount.y))
        self.latest = LaserScan(self._frozen_ranges(), self.angles, float(self.range), 0.0, self.origin)

    def scan(self, position: tuple[float, float, float], yaw: float, noise: np.ndarray, now: float,
             first_sensed: dict[str, float]) -> LaserScan:
        """Sweep once from the robot's base `position` and `yaw`; record first sightings in `first_sensed`."""
        headings = self.angles + yaw
        cos_t, sin_t = math.cos(self.TILT), math.sin(self.TILT)
        direction = np.stack([np.cos(headings) * cos_t, np.sin(headings) * cos_t, np.full(self.rays, -sin_t)], axis=1)
        x, y = position[0], position[1]
        if any(self.origin):  # the laser's place on the robot, turned with it
            forward, left = self.origin
            cos_y, sin_y = math.cos(yaw), math.sin(yaw)
            x, y = x + forward * cos_y - left * sin_y, y + forward * sin_y + left * cos_y
        origin = np.array([x, y, position[2] + self.mount.height])
        starts = origin + direction * self.mount.min_range
        ends = origin + direction * self.range
        hits = self.physics.cast_rays(starts.tolist(), ends.tolist())
        span = self.range - self.mount.min_range
        for i, hit in enumerate(hits):
            name = self.bodies.get(hit[0]) if hit[0] >= 0 else None
            if name is None or name == GROUND_BODY_NAME:
                self.ranges[i] = np.inf
                continue
            first_sensed.setdefault(name, now)
            self.ranges[i] = self.mount.min_range + hit[1] * span + noise[i]
        self.latest = LaserScan(self._frozen_ranges(), self.angles, float(self.range), now, self.origin)
        return self.latest

    def _frozen_ranges(self) -> np.ndarray:
        ranges = self.ranges.copy()
        ranges.flags.writeable = False
        return ranges
