"""The colours the animations and the 3D recordings share: the ground, the robot, the models, and the marks."""

from __future__ import annotations

import hashlib

from pytest_ddenv.world.model import Model

PALETTE = ((0.55, 0.42, 0.30), (0.36, 0.50, 0.63), (0.52, 0.60, 0.36), (0.66, 0.46, 0.52), (0.45, 0.45, 0.58),
            (0.70, 0.58, 0.34), (0.40, 0.58, 0.55))
"""Colours of the models left at the default grey, in the animations and the recording."""
DEFAULT_COLOR = (0.6, 0.6, 0.6, 1.0)

GROUND_RGBA = (0.78, 0.78, 0.74, 1.0)
ROBOT_RGBA = (0.95, 0.75, 0.1, 1.0)
"""The ground, and a robot drawn as its footprint box, in the animations and the recording (MuJoCo's
renderer draws a URDF robot's chassis in it too: the MuJoCo engine compiles no visual meshes)."""
WHEEL_RGBA = (0.15, 0.15, 0.15, 1.0)
"""A URDF robot's wheels in MuJoCo's renderer."""
FINGER_RGBA = WHEEL_RGBA
"""An arm's fingers in both renderers (the rest of the arm is `ROBOT_RGBA`)."""


def model_rgba(model: Model) -> tuple[float, float, float, float]:
    """The model's colour in the animations and the recording: its own, or when it is left at the default
    grey one of `PALETTE` by its name (the same model has the same colour in every world)."""
    if tuple(model.color) != DEFAULT_COLOR:
        red, green, blue, alpha = (float(v) for v in model.color)
        return red, green, blue, alpha
    index = int(hashlib.sha1(model.name.encode()).hexdigest(), 16) % len(PALETTE)
    return (*PALETTE[index], 1.0)

HEADING_RGBA = (0.15, 0.15, 0.15, 1.0)
TRAJECTORY_RGBA = (0.12, 0.47, 0.71, 1.0)
SCAN_RGBA = (0.17, 0.63, 0.17, 1.0)
CONTACT_RGBA = (1.0, 0.5, 0.05, 1.0)
FAILURE_RGBA = (0.84, 0.15, 0.16, 1.0)
GOAL_RGBA = (0.2, 0.7, 0.3, 1.0)
TARGET_RGBA = (0.58, 0.25, 0.75, 1.0)
"""The robot's heading arrow, its trajectory, the laser's hits, the contacts, the failure marker, the goal and
an arm's target, in both 3D recordings (`.rrd` and `.mcap`)."""
