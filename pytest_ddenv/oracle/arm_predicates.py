"""The arm's failure predicates: what the simulation checks every control tick on an `ArmState`.

Each is a dataclass like the mobile ones (`name`, `reset`, `check`), registered by name in
`predicates.PREDICATES` when the oracle package loads, with `robots = "arm"`. `ARM_DEFAULTS` are the
predicates an arm's run checks when the test names none. A signature's pose is the end effector's; its
`touched` are the models the arm touches other than the target and the table (those two are touched in every
pick, so they would make any two failures "touch the same model"), and for `knocked_over` the model knocked.
Parameters and details are documented in docs/oracle.md ("Arm predicates").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.oracle.arm_state import GRIPPER_CLOSE, ArmState, Pose6
from pytest_ddenv.oracle.predicates import (
    GROUND,
    TIME_LIMIT_CHECKS,
    FailureSignature,
    Predicate,
    PredicateSpec,
    add_built_in,
    signature,
)

__all__ = [
    "ARM_DEFAULTS",
    "ARM_PREDICATES",
    "ArmCollision",
    "GraspFailed",
    "JointLimit",
    "KnockedOver",
    "NotPlaced",
    "ObjectDropped",
    "SelfCollision",
    "arm_signature",
    "default_predicates",
    "placement_problem",
]

_EPSILON = 1e-9


def arm_signature(name: str, state: ArmState, detail: str, also: Sequence[str] = ()) -> FailureSignature:
    """The signature of an arm's failure now: where the end effector is, and the models the arm touches
    other than the target and the table (plus `also`, e.g. the model knocked over), sorted."""
    ignored = {state.target, state.table}
    touched = tuple(sorted({model for model in (*state.touched, *also) if model not in ignored}))
    return replace(signature(name, state, detail), touched=touched)


def _named(model: str) -> str:
    return "the ground" if model == GROUND else f"'{model}'"


@dataclass
class ArmCollision:
    """An arm link (the fingers included) touches, with at least `min_force` N, a model other than the target
    and the table, or the ground; with `models`, only one of the named models."""

    models: tuple[str, ...] | None = None
    min_force: float = 1.0
    robots: ClassVar[str] = "arm"
    name: str = field(default="arm_collision", init=False)

    def __post_init__(self) -> None:
        if self.models is not None:
            self.models = tuple(self.models)

    def reset(self) -> None:
        pass

    def check(self, state: ArmState) -> FailureSignature | None:
        for contact in state.contacts:
            if contact.normal_force < self.min_force:
                continue
            if self.models is not None:
                hit = contact.model in self.models
            else:
                hit = contact.model not in (state.target, state.table)
            if hit:
                return arm_signature(self.name, state, f"Link {contact.link} hit {_named(contact.model)} "
                                     f"({contact.normal_force:.0f} N).")
        return None


@dataclass
class GraspFailed:
    """`settle` s after the gripper was commanded "close", the target is not held (both fingers on it), or the
    fingers closed to under `min_opening` m. Each close is judged once, at its first tick `settle` s after the
    command; the predicate fires at most once a run, never before a close. Without a target: the opening only.
    """

    settle: float = 0.6
    min_opening: float = 0.003
    robots: ClassVar[str] = "arm"
    name: str = field(default="grasp_failed", init=False)
    _judged: float | None = field(default=None, init=False, repr=False)
    _fired: bool = field(default=False, init=False, repr=False)

    def reset(self) -> None:
        self._judged = None
        self._fired = False

    def check(self, state: ArmState) -> FailureSignature | None:
        if (self._fired or state.gripper_command != GRIPPER_CLOSE or self._judged == state.gripper_since
                or state.time - state.gripper_since < self.settle - _EPSILON):
            return None
        self._judged = state.gripper_since  # this close is judged now, once
        detail = self._failure(state)
        if detail is None:
            return None
        self._fired = True
        return arm_signature(self.name, state, detail)

    def _failure(self, state: ArmState) -> str | None:
        opening = state.gripper_opening
        target = f"the target '{state.target}'"
        if opening < self.min_opening:
            return f"The fingers closed to {opening:.3f} m without {target if state.target else 'an object'}."
        if state.target is None or state.target_held:
            return None
        on_target = sorted({c.link for c in state.contacts if c.finger and c.model == state.target})
        others = sorted({c.model for c in state.contacts if c.finger and c.model != state.target})
        if on_target:
            text = f"Only finger {on_target[0]} touches {target} {self.settle:g} s after closing"
        else:
            text = f"No finger touches {target} {self.settle:g} s after closing"
        between = f", the fingers touch {', '.join(_named(m) for m in others)}" if others else ""
        return f"{text} (fingers {opening:.3f} m apart{between})."


@dataclass
class ObjectDropped:
    """The target was held and lifted more than `min_lift` m above its start height, the gripper is still
    commanded "close", and the target has not been held for `duration` s: it left the gripper before the place
    phase (the default controller opens the gripper only over the place region)."""

    min_lift: float = 0.03
    duration: float = 0.2
    robots: ClassVar[str] = "arm"
    name: str = field(default="object_dropped", init=False)
    _lifted: bool = field(default=False, init=False, repr=False)
    _last_held: float = field(default=0.0, init=False, repr=False)
    _left_at: float = field(default=0.0, init=False, repr=False)

    def reset(self) -> None:
        self._lifted = False
        self._last_held = 0.0
        self._left_at = 0.0

    def check(self, state: ArmState) -> FailureSignature | None:
        target = state.target_pose
        start = None if state.target is None else state.start_objects.get(state.target)
        if target is None or start is None or state.gripper_command != GRIPPER_CLOSE:
            self._lifted = False  # an open gripper releases the target on purpose
            return None
        if state.target_held:
            self._last_held = state.time
            self._left_at = target[2]
            self._lifted = self._lifted or target[2] - start[2] > self.min_lift
            return None
        if not self._lifted or state.time - self._last_held < self.duration - _EPSILON:
            return None
        if state.table_top is not None:
            where = f"{self._left_at - state.table_top:.2f} m above the table"
        else:
            where = f"{self._left_at - start[2]:.2f} m above its start height"
        return arm_signature(self.name, state, f"'{state.target}' left the gripper {where} "
                             f"(not held for {state.time - self._last_held:.2f} s, gripper still closed).")


def placement_problem(state: ArmState, place_tolerance: float | None = None,
                      height_tolerance: float = 0.02) -> str | None:
    """Why the target is not placed now (None: it is): farther than `place_tolerance` m (planar; None: the
    scenario's) from the centre of the place region, still held, or not resting: its height more than
    `height_tolerance` m from the place region's z (its start height when the region has none)."""
    if state.target is None:
        raise ScenarioError("the scenario names no target, so there is nothing to place: name one "
                            "(scenario.target) or leave the placement predicates out", field="predicate")
    pose = state.target_pose
    if pose is None:
        return f"the target '{state.target}' is not in the world"
    tolerance = state.place_tolerance if place_tolerance is None else place_tolerance
    distance = state.place_distance(state.target)
    if distance > tolerance:
        return (f"'{state.target}' is {distance:.2f} m from the centre of the place region "
                f"(tolerance {tolerance:g} m)")
    if state.target_held:
        return f"'{state.target}' is in the place region but still in the gripper"
    start = state.start_objects.get(state.target, pose)
    resting = start[2] if state.place[2] is None else state.place[2]
    if abs(pose[2] - resting) > height_tolerance:
        return (f"'{state.target}' is in the place region but not resting on the table "
                f"({pose[2] - resting:+.2f} m from its resting height)")
    return None


@dataclass
class NotPlaced:
    """At the time limit (or at `at` s), the target is not placed: farther than `place_tolerance` m (planar;
    None: the scenario's goal tolerance) from the centre of the place region, still in the gripper, or more than
    `height_tolerance` m above or below its resting height (the place region's z, else its start height)."""

    at: float | None = None
    place_tolerance: float | None = None
    height_tolerance: float = 0.02
    robots: ClassVar[str] = "arm"
    name: str = field(default="not_placed", init=False)
    _done: bool = field(default=False, init=False, repr=False)

    def reset(self) -> None:
        self._done = False

    def check(self, state: ArmState) -> FailureSignature | None:
        limit = state.timeout if self.at is None else self.at
        if self._done or state.time < limit - _EPSILON:
            return None
        self._done = True
        problem = placement_problem(state, self.place_tolerance, self.height_tolerance)
        if problem is None:
            return None
        return arm_signature(self.name, state, f"At t = {state.time:.2f} s {problem}.")


def _up_axes(poses: Sequence[Pose6]) -> np.ndarray:
    """The up axes (unit vectors, world frame) of bodies at `poses`, one row each."""
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_euler("xyz", [pose[3:6] for pose in poses]).apply((0.0, 0.0, 1.0)))


@dataclass
class KnockedOver:
    """A named object (`models`; default: every object the run records but the target and the table, i.e. the
    scenario's `watch` models) tilted more than `max_tilt` rad from its start orientation, or fell more than
    `max_drop` m below the table top (below its start height when the table top is unknown)."""

    models: tuple[str, ...] | None = None
    max_tilt: float = math.radians(45.0)
    max_drop: float = 0.05
    robots: ClassVar[str] = "arm"
    name: str = field(default="knocked_over", init=False)
    _start_up: dict[str, tuple[Pose6, np.ndarray]] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.models is not None:
            self.models = tuple(self.models)

    def reset(self) -> None:
        self._start_up = {}

    def check(self, state: ArmState) -> FailureSignature | None:
        names = self.models if self.models is not None else sorted(
            set(state.objects) - {state.target, state.table})
        # a model not in this world (a reduction removed it) is not there to knock over
        present = [model for model in names if model in state.objects and model in state.start_objects]
        if not present:
            return None
        for model in present:
            height, start = state.objects[model][2], state.start_objects[model][2]
            reference = start if state.table_top is None else state.table_top
            if height < reference - self.max_drop:
                below = "its start height" if state.table_top is None else "the table top"
                return arm_signature(self.name, state, f"'{model}' fell off the table "
                                     f"({reference - height:.2f} m below {below}).", also=(model,))
        now = _up_axes([state.objects[model] for model in present])
        then = np.array([self._start_axis(model, state.start_objects[model]) for model in present])
        tilts = np.arccos(np.clip(np.einsum("ij,ij->i", now, then), -1.0, 1.0))
        for model, tilt in zip(present, tilts, strict=True):
            if tilt > self.max_tilt:
                return arm_signature(self.name, state, f"'{model}' was knocked over (tilted "
                                     f"{math.degrees(tilt):.0f} deg, limit {math.degrees(self.max_tilt):.0f} deg).",
                                     also=(model,))
        return None

    def _start_axis(self, model: str, start: Pose6) -> np.ndarray:
        """`model`'s up axis at the start (computed once a run)."""
        cached = self._start_up.get(model)
        if cached is None or cached[0] != start:
            cached = self._start_up[model] = (start, _up_axes([start])[0])
        return cached[1]


@dataclass
class JointLimit:
    """An arm joint stays within `margin` rad (m for a prismatic joint) of one of its limits (the URDF's) for
    `duration` s. Joints without finite limits are never at one."""

    margin: float = 0.02
    duration: float = 0.5
    robots: ClassVar[str] = "arm"
    name: str = field(default="joint_limit", init=False)
    _since: dict[str, float] = field(default_factory=dict, init=False, repr=False)

    def reset(self) -> None:
        self._since = {}

    def check(self, state: ArmState) -> FailureSignature | None:
        for joint, position, lower, upper in zip(state.joint_names, state.joint_positions, state.joint_lower,
                                                 state.joint_upper, strict=True):
            if not (math.isfinite(lower) and math.isfinite(upper)):
                continue
            near = "lower" if position - lower < self.margin else "upper" if upper - position < self.margin else ""
            if not near:
                self._since.pop(joint, None)
                continue
            since = self._since.setdefault(joint, state.time)
            if state.time - since >= self.duration - _EPSILON:
                limit = lower if near == "lower" else upper
                return arm_signature(self.name, state, f"Joint {joint} at {position:.3f}, "
                                     f"{abs(position - limit):.3f} from its {near} limit {limit:.3f} for "
                                     f"{state.time - since:.2f} s.")
        return None


@dataclass
class SelfCollision:
    """Two of the arm's own links touch (non-adjacent links: adjacent ones always touch at their joint)."""

    robots: ClassVar[str] = "arm"
    name: str = field(default="self_collision", init=False)

    def reset(self) -> None:
        pass

    def check(self, state: ArmState) -> FailureSignature | None:
        if not state.self_contacts:
            return None
        pairs = "; ".join(f"{a} and {b}" for a, b in state.self_contacts)
        return arm_signature(self.name, state, f"The arm touches itself: links {pairs}.")


def _timeout_at_limit(name: str, state: ArmState) -> FailureSignature | None:
    """`timeout` on an arm: the target is not placed at the time limit (no target: the limit alone)."""
    if state.target is None:
        return arm_signature(name, state, f"The time limit of {state.timeout:g} s was reached.")
    problem = placement_problem(state)
    if problem is None:
        return None
    return arm_signature(name, state, f"The target is not placed after {state.timeout:g} s: {problem}.")


ARM_PREDICATES: dict[str, Callable[..., Predicate]] = {
    "arm_collision": ArmCollision,
    "grasp_failed": GraspFailed,
    "object_dropped": ObjectDropped,
    "not_placed": NotPlaced,
    "knocked_over": KnockedOver,
    "joint_limit": JointLimit,
    "self_collision": SelfCollision,
}
"""The arm's built-in predicates by name (`timeout` is the mobile robots' one, which knows arms)."""

ARM_DEFAULTS: tuple[str, ...] = ("arm_collision", "grasp_failed", "object_dropped", "knocked_over", "not_placed")
"""The predicates an arm's run checks, in this order, when the test names none: the causes first (what the
arm hit, a grasp that did not close on the target, a target lost on the way, an object knocked over), the
outcome last (the target not placed at the time limit). `joint_limit` and `self_collision` are left out:
they are the controller's own doing, not the table's, and a scripted controller may graze its limits."""



def default_predicates(kind: str) -> tuple[PredicateSpec, ...]:
    """The predicates a run of a robot of `kind` checks when the test names none: `ARM_DEFAULTS` for an arm,
    none for a mobile robot (its run ends at the goal or the time limit, and the test asserts on it)."""
    if kind not in ("mobile", "arm"):
        raise ValueError(f"kind must be 'mobile' or 'arm', not {kind!r}")
    return tuple(PredicateSpec(name) for name in ARM_DEFAULTS) if kind == "arm" else ()


add_built_in(ARM_PREDICATES)
TIME_LIMIT_CHECKS[ArmState] = _timeout_at_limit
