"""`PickAndPlace`: the default controller of an arm, a scripted pick and place of the scenario's target.

Phases (`PickAndPlace.phase`, in order): "approach" (above the target at its yaw, gripper open), "descend"
(to the target's centre), "close", "lift", "carry" (above the centre of the place region), "lower",
"release" (open), "retreat" (straight up), "done". A move's end-effector target travels in a straight line
at `speed`; the phase ends when the end effector is within `tolerance` of the move's end, or after
`move_time` seconds (the arm was blocked: the next phase starts anyway, as a scripted controller does).
The gripper phases last `grip_time` seconds. Until the gripper closes, the controller aims at the mean of
every observation of the target so far (each is noisy, as a perception system's), not at the first alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pytest_ddenv.oracle.arm_state import GRIPPER_CLOSE, GRIPPER_OPEN
from pytest_ddenv.sim.arm.control import ArmCommand, ArmObservation, EndEffectorTarget, GripperCommand

PHASES = ("approach", "descend", "close", "lift", "carry", "lower", "release", "retreat", "done")
Point = tuple[float, float, float]


@dataclass
class PickAndPlace:
    """The scripted pick and place (see the module docstring). Heights in metres; `clearance` is how far above
    the target's centre the approach and the carry go, `place_height` how far above the place region's z
    (default: the target's starting height) the target's centre is lowered to before release."""

    speed: float = 0.25
    """m/s of the end-effector target along a move."""
    tolerance: float = 0.01
    clearance: float = 0.2
    place_height: float = 0.01
    move_time: float = 6.0
    grip_time: float = 1.0
    phase: str = field(default="approach", init=False)
    """The phase now (one of `PHASES`)."""
    _since: float = field(default=0.0, init=False)
    _start: Point = field(default=(0.0, 0.0, 0.0), init=False)
    _goal: Point = field(default=(0.0, 0.0, 0.0), init=False)
    _yaw: float = field(default=0.0, init=False)
    _pick: Point = field(default=(0.0, 0.0, 0.0), init=False)
    _seen: list[tuple[float, float]] = field(default_factory=list, init=False)
    _ready: bool = field(default=False, init=False)

    def reset(self, observation: ArmObservation) -> None:
        """Start over: aim at the target as it is observed now."""
        target = observation.target_pose
        here = observation.end_effector[:3]
        self._pick = (target[0], target[1], target[2]) if target is not None else (here[0], here[1], here[2])
        self._yaw = _grasp_yaw(target[5] if target is not None else 0.0)
        self._seen = []
        self._ready = True
        self._enter("approach", observation)

    def __call__(self, observation: ArmObservation) -> ArmCommand:
        if not self._ready:
            self.reset(observation)
        self._aim(observation)
        while True:
            command = self._command(observation)
            if command is not None:
                return command

    def _aim(self, observation: ArmObservation) -> None:
        """Before the gripper closes: aim at the mean of the target's observed positions so far."""
        target = observation.target_pose
        if target is None or self.phase not in ("approach", "descend"):
            return
        self._seen.append((target[0], target[1]))
        count = len(self._seen)
        x, y = sum(p[0] for p in self._seen) / count, sum(p[1] for p in self._seen) / count
        self._pick = (x, y, self._pick[2])
        self._goal = (x, y, self._goal[2])

    # -- phases ---------------------------------------------------------------------------------------
    def _command(self, observation: ArmObservation) -> ArmCommand | None:
        """This phase's command, or None after moving on to the next phase."""
        elapsed = observation.time - self._since
        if self.phase in ("close", "release"):
            if elapsed >= self.grip_time:
                self._enter(PHASES[PHASES.index(self.phase) + 1], observation)
                return None
            return GripperCommand(GRIPPER_CLOSE if self.phase == "close" else GRIPPER_OPEN)
        if self.phase == "done":
            return EndEffectorTarget(self._goal, self._yaw)
        here = observation.end_effector[:3]
        if math.dist(here, self._goal) <= self.tolerance or elapsed >= self.move_time:
            self._enter(PHASES[PHASES.index(self.phase) + 1], observation)
            return None
        travelled = min(self.speed * elapsed, math.dist(self._start, self._goal))
        length = math.dist(self._start, self._goal)
        fraction = 1.0 if length == 0.0 else travelled / length
        point = tuple(a + (b - a) * fraction for a, b in zip(self._start, self._goal, strict=True))
        gripper = GRIPPER_OPEN if self.phase in ("approach", "descend") else None
        return EndEffectorTarget((point[0], point[1], point[2]), self._yaw, gripper)

    def _enter(self, phase: str, observation: ArmObservation) -> None:
        self.phase, self._since = phase, observation.time
        here = observation.end_effector[:3]
        self._start = (here[0], here[1], here[2]) if phase == "approach" else self._goal
        x, y, z = self._pick
        place_x, place_y, place_z = observation.place
        drop_z = (z if place_z is None else place_z) + self.place_height
        goals: dict[str, Point] = {
            "approach": (x, y, z + self.clearance),
            "descend": (x, y, z),
            "lift": (x, y, z + self.clearance),
            "carry": (place_x, place_y, drop_z + self.clearance),
            "lower": (place_x, place_y, drop_z),
            "retreat": (place_x, place_y, drop_z + self.clearance),
        }
        if phase in goals:
            self._goal = goals[phase]
        if phase in ("close", "release", "done"):
            self._start = self._goal


def _grasp_yaw(yaw: float) -> float:
    """The gripper's yaw for a box turned by `yaw`: the same faces, within +-45 degrees of straight."""
    quarter = math.pi / 2.0
    return (yaw + quarter / 2.0) % quarter - quarter / 2.0
