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
"""(robot link, other body id, the midpoint between the nearest points of their geoms)."""


class NearContacts:
    """The robot's near pairs in one compiled model: `robot_geoms` with the robot link of each, `other_geoms`
    (geom ids) with the body of each in the model."""

    def __init__(self, model: mujoco.MjModel, robot_geoms: list[int], links: list[int],
                 other_geoms: list[int]) -> None:
        self.model = model
        self.robot_geoms = np.asarray(robot_geoms, dtype=np.int64)
        self.links = [int(link) for link in links]
        self.other_geoms = np.asarray(other_geoms, dtype=np.int64)
        self.bodies = [int(model.geom_bodyid[geom]) for geom in other_geoms]
        self._reach = (model.geom_rbound[self.robot_geoms][:, None] + model.geom_rbound[self.other_geoms][None, :]
                       + NEAR_DISTANCE)
        self._fromto = np.zeros(6)

    def pairs(self, data: mujoco.MjData, listed: set[tuple[int, int]]) -> list[NearPair]:
        """One near pair per (robot link, body) closer than `NEAR_DISTANCE`, leaving out the pairs `listed`
        (MuJoCo's contacts)."""
        if self.other_geoms.size == 0:
            return []
        robot = data.geom_xpos[self.robot_geoms]
        other = data.geom_xpos[self.other_geoms]
        apart = np.linalg.norm(robot[:, None, :] - other[None, :, :], axis=2)
        seen = set(listed)
        found: list[NearPair] = []
        for i, j in zip(*np.nonzero(apart < self._reach), strict=True):
            key = (self.links[i], self.bodies[j])
            if key in seen:
                continue
            distance = mujoco.mj_geomDistance(self.model, data, int(self.robot_geoms[i]), int(self.other_geoms[j]),
                                              NEAR_DISTANCE, self._fromto)
            if 0.0 <= distance < NEAR_DISTANCE:
                seen.add(key)
                x, y, z = ((self._fromto[:3] + self._fromto[3:]) / 2.0).tolist()
                found.append((key[0], key[1], (float(x), float(y), float(z))))
        return found
