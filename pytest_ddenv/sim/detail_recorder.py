"""`DetailRecorder`: what an episode records for `Run.detail` when a run's full detail is asked for."""

from __future__ import annotations

import numpy as np

from pytest_ddenv.sim.builder import GROUND_BODY_NAME
from pytest_ddenv.sim.laser import Laser
from pytest_ddenv.sim.physics import PhysicsEngine
from pytest_ddenv.sim.run import RunDetail
from pytest_ddenv.world.model import World

ContactPoint = tuple[str, float, float, float, float]


class DetailRecorder:
    """Samples the moving models' poses, the robot's joints, the latest laser scan and the contact points
    each time the episode records the robot's pose."""

    def __init__(self, physics: PhysicsEngine, world: World, wheel_links: frozenset[int], laser: Laser | None,
                 laser_height: float) -> None:
        self._physics = physics
        bodies = physics.bodies
        moving = {model.name for model in world.models if model.dynamic}
        self._moving = [(body, name) for body, name in bodies.items() if name in moving]
        self._bodies = bodies
        self._wheels = wheel_links
        self._laser = laser
        self._laser_height = laser_height
        self._joint_count = len(physics.joint_positions())
        self._poses: dict[str, list[list[float]]] = {name: [] for _, name in self._moving}
        self._joints: list[list[float]] = []
        self._scans: list[np.ndarray] = []
        self._contacts: list[tuple[ContactPoint, ...]] = []

    def sample(self) -> None:
        for body, name in self._moving:
            position, orientation = self._physics.body_pose(body)
            self._poses[name].append([*position, *orientation])
        self._joints.append(self._physics.joint_positions())
        if self._laser is not None:
            self._scans.append(np.array(self._laser.latest.ranges, dtype=np.float64))
        self._contacts.append(self._contact_points())

    def _contact_points(self) -> tuple[ContactPoint, ...]:
        points = []
        for link, other, (x, y, z), force in self._physics.contact_positions():
            name = self._bodies.get(other)
            if name is None or (name == GROUND_BODY_NAME and link in self._wheels):
                continue
            points.append((name, float(x), float(y), float(z), float(force)))
        return tuple(points)

    def result(self) -> RunDetail:
        samples = len(self._joints)
        laser = self._laser
        return RunDetail(
            bodies={name: np.asarray(poses, dtype=np.float64).reshape(-1, 7) for name, poses in self._poses.items()},
            joints=np.asarray(self._joints, dtype=np.float64).reshape(samples, self._joint_count),
            scan_angles=None if laser is None else np.array(laser.angles, dtype=np.float64),
            scan_ranges=None if laser is None else np.asarray(self._scans, dtype=np.float64).reshape(samples, -1),
            scan_height=self._laser_height,
            contacts=tuple(self._contacts),
            scan_origin=(0.0, 0.0) if laser is None else laser.origin,
        )
