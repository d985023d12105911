"""Failure predicates and failure signatures: what the simulation checks every control tick.

Predicates are evaluated online by the simulator once per control tick on a `RobotState` snapshot. The
first predicate that returns a `FailureSignature` decides the run (it stops early unless asked not to).
The built-in predicates, the registry of a user's (`register_predicate`, `@predicate`) and `PredicateSpec`
(a predicate as plain data, for markers, the command line and worker processes) are here too. Whether a
signature is *the* failure being reduced is the verdict's (`verdict.py`, beside this module).

Nothing of the simulation (which imports this module), pybullet or pytest. Parameters are documented in docs/oracle.md.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from pytest_ddenv.errors import ScenarioError, shown
from pytest_ddenv.validation import expected, is_finite_number

__all__ = [
    "PREDICATES",
    "ROBOT_KINDS",
    "Collided",
    "Contact",
    "FailureSignature",
    "Fell",
    "Flipped",
    "FunctionPredicate",
    "HighCentered",
    "History",
    "Predicate",
    "PredicateSpec",
    "RobotState",
    "Stuck",
    "Timeout",
    "check_predicate",
    "check_predicate_models",
    "check_predicates_for_robot",
    "make_predicate",
    "predicate",
    "predicate_spec",
    "predicates_for",
    "register_predicate",
    "robots_of",
    "signature",
]

GROUND = "<ground>"
"""The name contacts with the world's ground plane carry (the ground is never a model)."""


# -- the per-tick snapshot ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Contact:
    """One contact of the robot with something, summed over the contact points of one (link, body) pair.

    `model` is the model name, or `GROUND` for the ground plane. `link` is the robot link's name, `wheel`
    whether that link is a wheel, `normal_force` the summed normal force in newtons; `finger` whether the
    link is one of an arm's gripper fingers.
    """

    model: str
    link: str
    wheel: bool
    normal_force: float
    finger: bool = False


class History:
    """The robot's past positions, one sample per control tick (read-only for predicates)."""

    def __init__(self) -> None:
        self._times: list[float] = []
        self._positions: list[tuple[float, float, float]] = []

    def append(self, time: float, position: tuple[float, float, float]) -> None:
        self._times.append(time)
        self._positions.append(position)

    def __len__(self) -> int:
        return len(self._times)

    @property
    def times(self) -> Sequence[float]:
        return self._times

    @property
    def positions(self) -> Sequence[tuple[float, float, float]]:
        return self._positions

    def position_at(self, time: float) -> tuple[float, float, float] | None:
        """The latest recorded position at or before `time`, or None if there is none."""
        import bisect

        index = bisect.bisect_right(self._times, time + 1e-9) - 1
        return self._positions[index] if index >= 0 else None


@dataclass(frozen=True)
class RobotState:
    """What a predicate sees at one control tick (all in the world frame, SI units).

    - `time`: simulated seconds since the robot was spawned; `timeout`: the run's time limit.
    - `pose`: (x, y, z, roll, pitch, yaw) of the robot base; `velocity`: linear xyz + angular xyz.
    - `start`: the pose the robot was spawned at (after start jitter).
    - `goal`: the goal position (z may be None), `goal_distance`: planar distance to it (3D if goal z given).
    - `contacts`: every (robot link, touched body) pair in contact now, with normal forces.
    - `wheel_loads`: normal force on each wheel (FL, FR, RL, RR) from everything it touches.
    - `weight`: the robot's weight in newtons (mass x gravity), to normalise loads.
    - `history`: positions at every earlier control tick (and this one).
    """

    time: float
    timeout: float
    pose: tuple[float, float, float, float, float, float]
    velocity: tuple[float, float, float, float, float, float]
    start: tuple[float, float, float, float, float, float]
    goal: tuple[float, float, float | None]
    goal_distance: float
    contacts: tuple[Contact, ...]
    wheel_loads: tuple[float, ...]
    weight: float
    history: History

    @property
    def position(self) -> tuple[float, float, float]:
        return self.pose[0], self.pose[1], self.pose[2]

    @property
    def tilt(self) -> float:
        """Angle between the robot's up axis and the world's up axis (radians, 0 = level, pi = upside down)."""
        roll, pitch = self.pose[3], self.pose[4]
        return math.acos(max(-1.0, min(1.0, math.cos(roll) * math.cos(pitch))))

    @property
    def touched(self) -> tuple[str, ...]:
        """Models (not the ground) in contact with any robot link now, sorted."""
        return tuple(sorted({c.model for c in self.contacts if c.model != GROUND}))

    @property
    def chassis_contacts(self) -> tuple[Contact, ...]:
        return tuple(c for c in self.contacts if not c.wheel)

    @property
    def chassis_load(self) -> float:
        """Summed normal force on the non-wheel links (N)."""
        return sum(c.normal_force for c in self.contacts if not c.wheel)


# -- failure signatures ------------------------------------------------------------------------------
@dataclass(frozen=True)
class FailureSignature:
    """What failed, when, where and touching what: the identity of a failure for the oracle."""

    predicate: str
    time: float
    pose: tuple[float, ...]
    touched: tuple[str, ...] = ()
    detail: str = ""

    @property
    def position(self) -> tuple[float, float, float]:
        return float(self.pose[0]), float(self.pose[1]), float(self.pose[2])

    def to_dict(self) -> dict[str, Any]:
        return {
            "predicate": self.predicate,
            "time": float(self.time),
            "pose": [float(v) for v in self.pose],
            "touched": list(self.touched),
            "detail": self.detail,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> FailureSignature:
        return cls(
            predicate=str(data["predicate"]),
            time=float(data["time"]),
            pose=tuple(float(v) for v in data["pose"]),
            touched=tuple(str(v) for v in data.get("touched", ())),
            detail=str(data.get("detail", "")),
        )

    def explain(self) -> str:
        x, y, z = (round(v, 2) + 0.0 for v in self.position)  # + 0.0: never "-0.00"
        roll, pitch, yaw = (round(math.degrees(v)) for v in self.pose[3:6])  # whole degrees, never "-0"
        factory = PREDICATES.get(self.predicate)
        if factory is not None and getattr(factory, "robots", "any") == "arm":  # oracle/arm_predicates.py
            where = "the end effector"
            touching = (", ".join(self.touched) if self.touched else "no model") + " besides the target and the table"
        else:
            where = "the robot"
            touching = ", ".join(self.touched) if self.touched else "no model (only the ground, or nothing)"
        text = (
            f"The '{self.predicate}' predicate fired at t = {self.time:.2f} s with {where} at "
            f"({x:.2f}, {y:.2f}, {z:.2f}) m, roll {roll} deg, pitch {pitch} deg, yaw {yaw} deg, "
            f"touching {touching}."
        )
        if self.detail:
            text += f" {self.detail}"
        return text


# -- predicates --------------------------------------------------------------------------------------
@runtime_checkable
class Predicate(Protocol):
    """A failure predicate: `reset()` before each run, `check(state)` once per control tick.

    `state` is a `RobotState` for a mobile robot, an `ArmState` (oracle/arm_state.py) for an arm. Return a
    `FailureSignature` (see `signature()`) to declare the failure, else None. Predicates may keep state
    between ticks; `reset` must clear it so one instance can serve many runs. An optional `robots` attribute
    says which robots it is for ("mobile", "arm" or "any"; "any" without it): `check_predicates_for_robot`.
    """

    name: str

    def reset(self) -> None: ...

    def check(self, state: Any) -> FailureSignature | None: ...


class PredicateState(Protocol):
    """What `signature()` reads of a state: a `RobotState` or an `ArmState` (where: the end effector)."""

    @property
    def time(self) -> float: ...

    @property
    def pose(self) -> tuple[float, ...]: ...

    @property
    def touched(self) -> tuple[str, ...]: ...


def signature(name: str, state: PredicateState, detail: str = "") -> FailureSignature:
    """The signature of a failure detected now (helper for predicate authors)."""
    return FailureSignature(name, float(state.time), tuple(float(v) for v in state.pose), state.touched, detail)


@dataclass
class Stuck:
    """Less than `min_progress` m of planar displacement over the last `window` s (the paper's failure).

    Ignores the first `window` seconds of the run, so the robot's start-up is never "stuck".
    """

    robots: ClassVar[str] = "mobile"
    window: float = 5.0
    min_progress: float = 0.2
    name: str = field(default="stuck", init=False)

    def reset(self) -> None:
        pass

    def check(self, state: RobotState) -> FailureSignature | None:
        if state.time < self.window - 1e-9:
            return None
        before = state.history.position_at(state.time - self.window)
        if before is None:
            return None
        moved = math.hypot(state.pose[0] - before[0], state.pose[1] - before[1])
        if moved < self.min_progress:
            return signature(self.name, state, f"Moved {moved:.3f} m in the last {self.window:g} s "
                             f"(less than {self.min_progress:g} m).")
        return None


@dataclass
class Flipped:
    """Tilt (angle of the robot's up axis from vertical) above `max_tilt` rad for `duration` s."""

    robots: ClassVar[str] = "mobile"
    max_tilt: float = math.radians(60.0)
    duration: float = 0.5
    name: str = field(default="flipped", init=False)
    _since: float | None = field(default=None, init=False, repr=False)

    def reset(self) -> None:
        self._since = None

    def check(self, state: RobotState) -> FailureSignature | None:
        if state.tilt <= self.max_tilt:
            self._since = None
            return None
        if self._since is None:
            self._since = state.time
        if state.time - self._since >= self.duration - 1e-9:
            return signature(self.name, state, f"Tilted {math.degrees(state.tilt):.0f} deg "
                             f"(limit {math.degrees(self.max_tilt):.0f} deg).")
        return None


@dataclass
class HighCentered:
    """Chassis resting on something while the wheels carry too little of the robot's weight.

    Fires when the non-wheel links carry at least `min_chassis_load` N and the four wheels together carry
    less than `max_wheel_load` (a fraction of the robot's weight), continuously for `duration` s.
    """

    robots: ClassVar[str] = "mobile"
    max_wheel_load: float = 0.5
    min_chassis_load: float = 20.0
    duration: float = 2.0
    name: str = field(default="high_centered", init=False)
    _since: float | None = field(default=None, init=False, repr=False)

    def reset(self) -> None:
        self._since = None

    def check(self, state: RobotState) -> FailureSignature | None:
        wheels = sum(state.wheel_loads)
        chassis = state.chassis_load
        if not (chassis >= self.min_chassis_load and wheels < self.max_wheel_load * state.weight):
            self._since = None
            return None
        if self._since is None:
            self._since = state.time
        if state.time - self._since >= self.duration - 1e-9:
            resting = ", ".join(sorted({c.model for c in state.chassis_contacts})) or "nothing"
            return signature(self.name, state, f"Chassis carries {chassis:.0f} N (resting on {resting}); "
                             f"wheels carry {wheels:.0f} N of {state.weight:.0f} N.")
        return None


@dataclass
class Fell:
    """The robot dropped more than `max_drop` m below its start height, or below the height `min_z`."""

    robots: ClassVar[str] = "mobile"
    max_drop: float = 0.5
    min_z: float | None = None
    name: str = field(default="fell", init=False)

    def reset(self) -> None:
        pass

    def check(self, state: RobotState) -> FailureSignature | None:
        z = state.pose[2]
        drop = state.start[2] - z
        if drop > self.max_drop:
            return signature(self.name, state, f"Dropped {drop:.2f} m below its start height.")
        if self.min_z is not None and z < self.min_z:
            return signature(self.name, state, f"Below the height limit {self.min_z:g} m (z = {z:.2f}).")
        return None


@dataclass
class Collided:
    """Contact with a model: by default any model touching a non-wheel link (bumper, chassis).

    With `models`, any contact (wheels included) with one of the named models. Contacts under
    `min_force` N are ignored.
    """

    robots: ClassVar[str] = "mobile"
    models: tuple[str, ...] | None = None
    min_force: float = 1.0
    name: str = field(default="collided", init=False)

    def __post_init__(self) -> None:
        if self.models is not None:
            self.models = tuple(self.models)

    def reset(self) -> None:
        pass

    def check(self, state: RobotState) -> FailureSignature | None:
        for contact in state.contacts:
            if contact.normal_force < self.min_force or contact.model == GROUND:
                continue
            if ((self.models is None and not contact.wheel)
                    or (self.models is not None and contact.model in self.models)):
                return signature(self.name, state, f"Link {contact.link} hit {contact.model} "
                                 f"({contact.normal_force:.0f} N).")
        return None


TimeLimitCheck = Callable[[str, Any], FailureSignature | None]
"""What `timeout` does at the time limit for one kind of state: (predicate name, state) -> signature or None."""

TIME_LIMIT_CHECKS: dict[type, TimeLimitCheck] = {}
"""`timeout`'s check at the limit by the state's type, for states other than `RobotState` (the arm's
`ArmState`: oracle/arm_predicates.py registers "the target is not placed")."""


@dataclass
class Timeout:
    """The goal was not reached within the run's time limit (an arm: the target is not placed at the limit)."""

    robots: ClassVar[str] = "any"
    name: str = field(default="timeout", init=False)

    def reset(self) -> None:
        pass

    def check(self, state: Any) -> FailureSignature | None:
        if state.time < state.timeout - 1e-9:
            return None
        at_limit = TIME_LIMIT_CHECKS.get(type(state))
        if at_limit is not None:
            return at_limit(self.name, state)
        return signature(self.name, state, f"Goal still {state.goal_distance:.2f} m away after "
                         f"{state.timeout:g} s.")


PREDICATES: dict[str, Callable[..., Predicate]] = {
    "stuck": Stuck,
    "flipped": Flipped,
    "high_centered": HighCentered,
    "fell": Fell,
    "collided": Collided,
    "timeout": Timeout,
}
"""Predicates by name: the built-in ones (the arm's are added by oracle/arm_predicates.py, which the oracle
package imports) and those added with `register_predicate`."""
BUILT_IN: set[str] = set(PREDICATES)
"""The names of the built-in predicates (mobile and arm)."""

ROBOT_KINDS = ("mobile", "arm", "any")
"""What a predicate's `robots` attribute may say: the robots it is for."""

_NON_NEGATIVE = {"min_progress", "min_chassis_load", "min_force", "duration", "margin", "min_opening",
                 "min_lift", "settle", "at", "height_tolerance"}
_POSITIVE = {"window", "max_tilt", "max_drop", "place_tolerance"}
_FRACTIONS = {"max_wheel_load"}
_MAY_BE_NONE = {"min_z", "at", "place_tolerance"}


def add_built_in(factories: Mapping[str, Callable[..., Predicate]]) -> None:
    """Register more built-in predicates (oracle/arm_predicates.py's); not for users (`register_predicate`)."""
    PREDICATES.update(factories)
    BUILT_IN.update(factories)


def register_predicate(name: str, factory: Callable[..., Predicate], *, replace: bool = False) -> None:
    """Make `factory(**params)` available by name: `@pytest.mark.robot_failure(name, **params)`, the
    `ddenv` command's `--predicate name:k=v` and `ddenv replay`. Register it in a module the test (or
    `ddenv --import`) imports, so that every probe worker has it too."""
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(expected("an identifier", name, "register_predicate(name=...)"))
    if name in BUILT_IN or (name in PREDICATES and not replace):
        raise ValueError(f"a predicate named {shown(name)} is already registered"
                         + ("" if name in BUILT_IN else " (pass replace=True)"))
    if not callable(factory):
        raise TypeError(expected("a callable factory", factory, f"register_predicate({shown(name)}, ...)"))
    PREDICATES[name] = factory


def make_predicate(name: str, /, **params: Any) -> Predicate:
    """Build the predicate `name` with `params`, validating both eagerly (`ScenarioError` if wrong)."""
    try:
        factory = PREDICATES[name]
    except (KeyError, TypeError):
        raise ScenarioError(
            f"unknown failure predicate {shown(name)}; valid predicates: {', '.join(sorted(PREDICATES))} (register "
            "your own with pytest_ddenv.register_predicate)",
            field="predicate",
        ) from None
    try:
        signature_ = inspect.signature(factory)
    except (TypeError, ValueError):  # a builtin or C callable: accept any keyword
        signature_ = None
    accepted = [] if signature_ is None else [p.name for p in signature_.parameters.values() if p.name != "name"]
    takes_any = signature_ is None or any(p.kind is p.VAR_KEYWORD for p in signature_.parameters.values())
    for key, value in params.items():
        where = f"{name}.{key}"
        if key not in accepted and not takes_any:
            raise ScenarioError(
                f"predicate {shown(name)} has no parameter {shown(key)}; valid parameters: "
                f"{', '.join(accepted) or '(none)'}",
                field=where,
            )
        if name in BUILT_IN:
            _check_built_in_parameter(key, value, where)
    if "models" in params and params["models"] is not None and name in BUILT_IN:
        params = {**params, "models": tuple(params["models"])}
    try:
        predicate = factory(**params)
    except (TypeError, ValueError) as error:
        raise ScenarioError(f"predicate {shown(name)} could not be built: {error}", field=name) from None
    check_predicate(predicate, f"the factory of predicate {shown(name)} returned {shown(predicate)}, which")
    return predicate


def _check_built_in_parameter(key: str, value: Any, where: str) -> None:
    if key == "models":
        if value is not None and (isinstance(value, str) or not all(isinstance(v, str) for v in value)):
            raise ScenarioError(expected("a list of model names or None", value), field=where)
        if value is not None and not list(value):  # it would never fire
            raise ScenarioError(expected("at least one model name (leave models out for a collision with any "
                                         "model)", value), field=where)
        return
    if key in _MAY_BE_NONE and value is None:
        return
    if not is_finite_number(value):
        raise ScenarioError(expected("a finite number", value), field=where)
    if key in _POSITIVE and value <= 0:
        raise ScenarioError(expected("a number > 0", value), field=where)
    if key in _NON_NEGATIVE and value < 0:
        raise ScenarioError(expected("a number >= 0", value), field=where)
    if key in _FRACTIONS and not 0 <= value <= 1:
        raise ScenarioError(expected("a fraction between 0 and 1", value), field=where)


def check_predicate(value: Any, what: str = "") -> None:
    """ScenarioError unless `value` follows the `Predicate` protocol (a str `name`, `reset()`, `check(state)`)."""
    problems = []
    if not isinstance(getattr(value, "name", None), str) or not getattr(value, "name", ""):
        problems.append("a non-empty str attribute 'name'")
    for method in ("reset", "check"):
        if not callable(getattr(value, method, None)):
            problems.append(f"a method {method}()")
    if problems:
        raise ScenarioError(f"{what or shown(value)} is not a failure predicate: it needs {', '.join(problems)}",
                            field="predicate")


@dataclass
class FunctionPredicate:
    """A plain function of the state as a predicate: it fails the run when it returns True (or a message, or
    a `FailureSignature`), and passes on False or None. Named after the function."""

    function: Callable[[Any], Any]
    """Called with the `RobotState` (a mobile robot) or the `ArmState` (an arm)."""
    name: str = ""
    robots: str = field(default="any", repr=False)
    """The robots it is for: "mobile", "arm" or "any" (`check_predicates_for_robot`)."""

    def __post_init__(self) -> None:
        self.name = self.name or getattr(self.function, "__name__", "") or type(self.function).__name__
        if self.robots not in ROBOT_KINDS:
            raise ScenarioError(expected(f"one of {', '.join(ROBOT_KINDS)}", self.robots,
                                         f"predicate {shown(self.name)}: robots"), field="predicate")

    def reset(self) -> None:
        pass

    def check(self, state: Any) -> FailureSignature | None:
        result = self.function(state)
        if result is None or result is False or result is np.False_:
            return None
        if isinstance(result, FailureSignature):
            return result
        if result is True or result is np.True_:
            return signature(self.name, state)
        if isinstance(result, str):
            return signature(self.name, state, result)
        raise ScenarioError(f"predicate function {self.name} returned {type(result).__name__} {shown(result)} at "
                            f"t = {state.time:.2f} s; expected True/False, a message, or a FailureSignature",
                            field="predicate")


def predicate(function: Callable[[Any], Any] | None = None, *, name: str = "", robots: str = "any") -> Any:
    """Decorator: make a plain function of the state (a `RobotState`, an arm's `ArmState`) a failure predicate
    (a `FunctionPredicate`).

    Use it for functions given to the marker, `@pytest.mark.robot_failure(no_progress)`: pytest takes a bare
    function passed alone to a marker for the function to decorate, so the marker needs the predicate
    object. `@predicate(name="trapped")` names the failure (default: the function's name);
    `@predicate(robots="arm")` says it is for arms only (default: any robot).
    """
    if function is None:
        return lambda given: FunctionPredicate(given, name, robots)
    return FunctionPredicate(function, name, robots)


@dataclass(frozen=True)
class PredicateSpec:
    """A failure predicate as a test declares it: a registered `name` with `params`, or a ready predicate
    object or function (`instance`, used as is). Specs by name travel between processes as plain data."""

    name: str
    params: Mapping[str, Any] = field(default_factory=dict)
    instance: Predicate | None = field(default=None, compare=False)
    same_failure: str | None = None
    """The predicate's own same-failure match ("all", "place", "touched", "module:qualname"; None: the test's),
    from `robot_failure(..., same_failure=...)`; the oracle applies it (`oracle.SameFailureRule`)."""

    def build(self) -> Predicate:
        return self.instance if self.instance is not None else make_predicate(self.name, **dict(self.params))

    def to_json(self) -> dict[str, Any]:
        """As recorded in summary.json: {"name", "params"}, plus "object" (its repr) for an instance and
        "same_failure" when the predicate has its own."""
        data: dict[str, Any] = {"name": self.name, "params": dict(self.params)}
        if self.instance is not None:
            data["object"] = repr(self.instance)[:300]
        if self.same_failure is not None:
            data["same_failure"] = self.same_failure
        return data


def predicate_spec(value: Any, params: Mapping[str, Any] | None = None) -> PredicateSpec:
    """A `PredicateSpec` from what a marker or a caller gives: a registered name (with `params`), a
    `Predicate` object, or a function of the `RobotState`. Validated now (`ScenarioError` if wrong)."""
    params = dict(params or {})
    if isinstance(value, str):
        make_predicate(value, **params)
        return PredicateSpec(value, params)
    if params:
        raise ScenarioError(f"parameters {', '.join(params)} are only for a predicate given by name; build "
                            f"{shown(value)} with them instead", field="predicate")
    if inspect.isclass(value):
        raise ScenarioError(f"{value.__name__} is a class; pass an instance, e.g. {value.__name__}(...)",
                            field="predicate")
    if hasattr(value, "check"):
        check_predicate(value)
        return PredicateSpec(value.name, {}, instance=value)
    if callable(value):
        wrapped = FunctionPredicate(value)
        return PredicateSpec(wrapped.name, {}, instance=wrapped)
    raise ScenarioError(f"{shown(value)} is not a failure predicate: expected a registered name "
                        f"({', '.join(sorted(PREDICATES))}), an object with name, reset() and check(state), or "
                        "a function of the state", field="predicate")


def check_predicate_models(predicates: Sequence[PredicateSpec], names: Sequence[str], where: str) -> None:
    """ScenarioError when a built-in predicate's `models=[...]` (`collided`, `arm_collision`, `knocked_over`)
    names a model that `names` (the world's models, `where` its file) does not hold: a typo would otherwise
    make the predicate silently never fire."""
    known = set(names)
    for spec in predicates:
        if spec.instance is not None:
            built_in = any(isinstance(spec.instance, factory) for name, factory in PREDICATES.items()
                           if name in BUILT_IN and isinstance(factory, type))
            models = getattr(spec.instance, "models", None) if built_in else None
        else:
            models = spec.params.get("models") if spec.name in BUILT_IN else None
        unknown = [name for name in models or () if name not in known]
        if unknown:
            listing = ", ".join(list(names)[:12]) + (", ..." if len(names) > 12 else "")
            what = "is not a model" if len(unknown) == 1 else "are not models"
            raise ScenarioError(
                f"the '{spec.name}' predicate names {', '.join(shown(n) for n in unknown[:5])}, which {what} of "
                f"{where} (its models: {listing or 'none'})"
            )


# -- which robots a predicate is for -----------------------------------------------------------------
def robots_of(value: Any) -> str:
    """The robots a predicate (or a predicate's factory, or a `PredicateSpec`) is for: its `robots`
    attribute, "any" without one. ScenarioError for a value that is not one of `ROBOT_KINDS`."""
    if isinstance(value, PredicateSpec):
        value = value.instance if value.instance is not None else PREDICATES.get(value.name)
    kind = getattr(value, "robots", "any")
    if kind not in ROBOT_KINDS:
        raise ScenarioError(expected(f"one of {', '.join(ROBOT_KINDS)}", kind,
                                     f"the robots attribute of predicate {shown(getattr(value, 'name', value))}"),
                            field="predicate")
    return str(kind)


def predicates_for(kind: str) -> list[str]:
    """The registered predicates' names that a robot of `kind` ("mobile" or "arm") can use, sorted."""
    return sorted(name for name, factory in PREDICATES.items() if robots_of(factory) in (kind, "any"))


_KIND_WORDS = {"mobile": "a mobile robot", "arm": "an arm"}
_FOR_WORDS = {"mobile": "mobile robots", "arm": "arms"}


def check_predicates_for_robot(predicates: Sequence[Predicate | PredicateSpec], kind: str, robot: str) -> None:
    """ScenarioError for the first predicate that is not for a robot of `kind` ("mobile" or "arm"; `robot` its
    name): "predicate 'stuck' is for mobile robots; the world's robot 'panda' is an arm; arm predicates: ..."
    The simulation calls it before a run; predicates that say nothing (a user's) are for any robot."""
    if kind not in _KIND_WORDS:
        raise ValueError(expected("'mobile' or 'arm'", kind, "check_predicates_for_robot(kind=...)"))
    for value in predicates:
        robots = robots_of(value)
        if robots not in (kind, "any"):
            raise ScenarioError(
                f"predicate {shown(value.name)} is for {_FOR_WORDS[robots]}; the world's robot {shown(robot)} is "
                f"{_KIND_WORDS[kind]}; {kind} predicates: {', '.join(predicates_for(kind))}"
            )
