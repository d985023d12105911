"""What a world file holds that is not simulated, and why: the short lines of `World.notes`.

One line per kind (joints, plugins, sensors, lights, approximations, models without collisions) listing at
most MAX_NAMES names, and one line per model dropped by `skip_unsupported`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from pytest_ddenv.sdf._shapes import PLANE_THICKNESS
from pytest_ddenv.sdf._values import UnsupportedSdfError

MAX_NAMES = 6


@dataclass
class Notes:
    dropped: list[str] = field(default_factory=list)
    joints: list[tuple[str, int]] = field(default_factory=list)
    plugins: list[str] = field(default_factory=list)
    sensors: list[str] = field(default_factory=list)
    lights: list[str] = field(default_factory=list)
    planes: list[str] = field(default_factory=list)
    holes: list[tuple[str, int]] = field(default_factory=list)
    without_collisions: list[str] = field(default_factory=list)
    insertions: list[str] = field(default_factory=list)

    def drop(self, name: str, error: UnsupportedSdfError) -> None:
        where = f" ({error.where})" if error.where else ""
        self.dropped.append(f"dropped {name}: {error.summary}{where}")

    def lines(self) -> tuple[str, ...]:
        joints = [f"{name} ({count} joint{'s' if count != 1 else ''})" for name, count in self.joints]
        holes = [f"{name} ({count})" for name, count in self.holes]
        kinds = [
            ("joints", joints, "each articulated model is simulated as one rigid body"),
            ("plugins", self.plugins, "plugins do not run"),
            ("sensors", self.sensors, "sensors in the world do not run (the robot's come from the scenario)"),
            ("lights", self.lights, "lights do not take part in the simulation"),
            (f"planes as {PLANE_THICKNESS:g} m thick boxes of their <size>", self.planes,
             "Gazebo's collision planes are infinite"),
            ("polyline holes filled", holes, "Gazebo cuts outlines inside another one out of the extrusion"),
            ("models without collisions", self.without_collisions, "nothing to touch: skipped"),
            ("<state> insertions", self.insertions,
             "Gazebo inserts them when it loads the world, pytest-ddenv does not read them: write them as models"),
        ]
        return (*self.dropped, *(f"{kind}: {listing(names)}; {why}" for kind, names, why in kinds if names))


def listing(names: Sequence[str]) -> str:
    """`names` joined by commas, at most MAX_NAMES of them."""
    shown = ", ".join(names[:MAX_NAMES])
    return shown if len(names) <= MAX_NAMES else f"{shown} and {len(names) - MAX_NAMES} more"
