"""Near contacts: the robot's geoms within `NEAR_DISTANCE` of a model's geom but not touching it.

pybullet lists contact points up to its contact breaking threshold (0.02 m) apart, with force 0, so a model
the robot nearly touches counts as touched there (a failure's `touched`, `first_touch`, `last_touch`).
MuJoCo's `data.contact` holds only the pairs in contact; a contact margin would list the others but changes
the contacts MuJoCo computes and with them the run (measured: the ditch's robot then ends 0.6 m further in
one seed of three). So the near pairs are found apart, after the step, with `mj_geomDistance`, for the
geoms whose bounding spheres come within the distance: the physics is unchanged, only the listing.
"""

from __future__ import annotations

import mujoco
import numpy as np

NEAR_DISTANCE = 0.02
"""pybullet's contact breaking threshold (m): how far apart a listed contact point may be."""

NearPair = tuple[int, int, tuple[float, float, float]]
"""(robot geom, other geom, the midpoint between their nearest points)."""


class NearContacts:
    """The robot's near pairs in one compiled model; `robot_geoms` and `other_geoms` are geom ids."""

    def __init__(self, model: mujoco.MjModel, robot_geoms: list[int], other_geoms: list[int]) -> None:
        self.model = model
        self.robot_geoms = np.asarray(robot_geoms, dtype=np.int64)
        self.other_geoms = np.asarray(other_geoms, dtype=np.int64)
        self._reach = (model.geom_rbound[self.robot_geoms][:, None] + model.geom_rbound[self.other_geoms][None, :]
                       + NEAR_DISTANCE)
        self._fromto = np.zeros(6)

    def pairs(self, data: mujoco.MjData) -> list[NearPair]:
        """Every (robot geom, other geom) pair closer than `NEAR_DISTANCE` with no contact between them."""
        if self.other_geoms.size == 0:
            return []
        robot = data.geom_xpos[self.robot_geoms]
        other = data.geom_xpos[self.other_geoms]
        apart = np.linalg.norm(robot[:, None, :] - other[None, :, :], axis=2)
        found: list[NearPair] = []
        for i, j in zip(*np.nonzero(apart < self._reach), strict=True):
            geom1, geom2 = int(self.robot_geoms[i]), int(self.other_geoms[j])
            distance = mujoco.mj_geomDistance(self.model, data, geom1, geom2, NEAR_DISTANCE, self._fromto)
            if 0.0 <= distance < NEAR_DISTANCE:
                x, y, z = ((self._fromto[:3] + self._fromto[3:]) / 2.0).tolist()
                found.append((geom1, geom2, (float(x), float(y), float(z))))
        return found
