"""The oracle: whether a run's failure, or what a test raised, is the failure being reduced (`classify_result`,
and `classify` for a run; `same_failure`).

A run ends in the reference failure f (FAIL), another failure (OTHER), no failure (PASS) or an error
(ERROR). The predicates that produce failure signatures are `oracle.predicates` (the simulation checks them
every tick); the verdict knows a run only by its `failure`. The meaning of "same failure" is documented in
docs/oracle.md.

What "same" means is the user's to choose (`SameFailureRule`): the default rule (same predicate, same place,
touching one of the models the reference touched), the place only, the touched models only, or a module-level
function `same_failure(reference, signature) -> bool` of their own, for the test or per predicate.
`why_other` says which part of the rule a failure missed. An arm's failure is "at the same place"
within `ARM_TOLERANCE` (0.15 m) unless the user chose a tolerance (`tolerance_for`). The verdict is always
taken in the process that drives the reduction, never in a probe worker: a user's function is called there
only.
"""

from __future__ import annotations

import importlib
import inspect
import sys
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from pytest_ddenv import defaults
from pytest_ddenv.errors import DdenvError, shown
from pytest_ddenv.oracle.predicates import PREDICATES, FailureSignature, robots_of
from pytest_ddenv.outcome import Outcome
from pytest_ddenv.validation import expected, is_finite_number


class HasFailure(Protocol):
    """A run as the verdict sees it (a `sim.Run` is one): its failure signature, None if it did not fail."""

    @property
    def failure(self) -> FailureSignature | None: ...


# -- the oracle --------------------------------------------------------------------------------------
MATCHES = ("all", "place", "touched")
"""The built-in ways to match a failure with the reference: "all" (the default: the same predicate, within the
tolerance, touching one of the models the reference touched), "place" (the same predicate within the tolerance,
whatever it touches) and "touched" (the same predicate touching one of the models the reference touched,
wherever it is). A rule may name a user's function instead ("module:qualname")."""

SameFailureFunction = Callable[[FailureSignature, FailureSignature], Any]
"""A user's rule: `same_failure(reference, signature) -> bool` (True: `signature` is the reference failure)."""


class SameFailureError(DdenvError):
    """A same-failure rule that cannot be used: an unknown match, a function that is not module-level or does
    not import, or one that raised or returned something else than True or False."""


ARM_TOLERANCE = 0.15
"""Metres of "the same place" for an arm's failure when the tolerance is the default (`defaults.TOLERANCE`,
0.5 m, the length of a mobile robot, is half a table): see `tolerance_for`. The shipped tabletop scenarios'
failures spread over at most 0.025 m (a grasp, a collision on the way down) and 0.11 m (the target lost
while carried, the end effector moving) across 8-10 seeds."""


def tolerance_for(predicate: str, tolerance: float) -> float:
    """The tolerance that applies to a reference failure of `predicate`: `ARM_TOLERANCE` for an arm's predicate
    (a registered one whose `robots` is "arm") when `tolerance` is the default, else `tolerance` as given (a
    tolerance chosen by the user applies to arms as given; `timeout` and unregistered predicates, which may be
    any robot's, keep it too)."""
    if tolerance == defaults.TOLERANCE and predicate in PREDICATES and robots_of(PREDICATES[predicate]) == "arm":
        return ARM_TOLERANCE
    return tolerance


def same_failure(failure: FailureSignature, reference: FailureSignature,
                 tolerance: float = defaults.TOLERANCE, *, match: str = defaults.SAME_FAILURE) -> bool:
    """Whether `failure` is the reference failure f by one of the built-in `MATCHES` (see `classify`)."""
    return not _differences(failure, reference, tolerance, match)


def _distance(failure: FailureSignature, reference: FailureSignature) -> float:
    return float(np.linalg.norm(np.subtract(failure.position, reference.position)))


def _touches_as_reference(failure: FailureSignature, reference: FailureSignature, match: str) -> bool:
    """The contact part of a rule: one of the reference's models touched (any contact, when it touched none;
    with match "touched", no contact either)."""
    if not reference.touched:
        return match != "touched" or not failure.touched
    return bool(set(reference.touched) & set(failure.touched))


def _differences(failure: FailureSignature, reference: FailureSignature, tolerance: float,
                 match: str) -> list[str]:
    """What the built-in rule `match` finds different: "predicate", "place", "touched" (none: the same)."""
    if match not in MATCHES:
        raise SameFailureError(f"unknown same-failure match {shown(match)}; valid: {', '.join(MATCHES)}")
    if failure.predicate != reference.predicate:
        return ["predicate"]
    found = []
    if match != "touched" and _distance(failure, reference) > tolerance_for(reference.predicate, tolerance):
        found.append("place")
    if match != "place" and not _touches_as_reference(failure, reference, match):
        found.append("touched")
    return found


@dataclass(frozen=True)
class OtherReason:
    """Why a failure is not the reference failure, under a rule.

    `text`: this failure's reason ("the same predicate fired at the same place (0.08 m away) but touching no
    model (the reference touched wall)"); `summary`: its kind, the same for every failure missed the same way
    (counted by `most_common_reason`); `context`: what the reference was, when it helps; `advice`: what rule
    would count it ("consider same_failure='place'"), when one would."""

    text: str
    summary: str
    context: str = ""
    advice: str = ""


def _touched_text(models: Sequence[str]) -> str:
    return ", ".join(models) if models else "no model"


def why_other(failure: FailureSignature, reference: FailureSignature,
              rule: SameFailureRule | None = None) -> OtherReason | None:
    """Why `failure` is not the `reference` failure under `rule` (default: the default rule); None when it is."""
    rule = rule or SameFailureRule()
    match = rule.match_for(reference.predicate)
    if match not in MATCHES:
        if rule.same(failure, reference):
            return None
        return OtherReason(f"{match} returned False", f"the same-failure function {match} said another failure")
    found = _differences(failure, reference, rule.tolerance, match)
    if not found:
        return None
    if found == ["predicate"]:
        return OtherReason(f"another predicate fired: {failure.predicate} (the reference: {reference.predicate})",
                           f"another predicate fired ({failure.predicate})", f"the reference: {reference.predicate}")
    distance = _distance(failure, reference)
    tolerance = tolerance_for(reference.predicate, rule.tolerance)
    touched = f"the reference touched {_touched_text(reference.touched)}"
    if "place" in found:
        far = f"{distance:.2f} m from the reference failure (more than {tolerance:g} m)"
        if "touched" in found:
            return OtherReason(f"the same predicate fired {far} and touching {_touched_text(failure.touched)} "
                               f"({touched})", "the same predicate fired elsewhere, touching other models")
        return OtherReason(f"the same predicate fired {far}",
                           f"the same predicate fired farther than {tolerance:g} m from the reference failure",
                           advice="consider a larger tolerance"
                           + (" or same_failure='touched'" if match == "all" and reference.touched else ""))
    where = "at the same place " if match == "all" else ""
    near = f"({distance:.2f} m away) " if match == "all" else ""
    advice = "consider same_failure='place'" if distance <= tolerance else ""
    if failure.touched and reference.touched:
        return OtherReason(f"the same predicate fired {where}{near}but touching {_touched_text(failure.touched)}, "
                           f"not {_touched_text(reference.touched)}",
                           f"the same predicate fired {where}but touching other models", touched, advice)
    return OtherReason(f"the same predicate fired {where}{near}but touching {_touched_text(failure.touched)} "
                       f"({touched})", f"the same predicate fired {where}but touching "
                       f"{'no model' if not failure.touched else 'a model'}", touched, advice)


def most_common_reason(reasons: Sequence[OtherReason], runs: int) -> str:
    """The reason seen most among `reasons` (of `runs` runs), worded with its count, context and advice:
    "the same predicate fired at the same place but touching no model in 5 of 5 runs (the reference touched
    wall); consider same_failure='place'". "" when there is none."""
    if not reasons:
        return ""
    counts = Counter(reason.summary for reason in reasons)
    summary, count = counts.most_common(1)[0]
    first = next(reason for reason in reasons if reason.summary == summary)
    text = f"{summary} in {count} of {runs} run{'s' if runs != 1 else ''}"
    if first.context:
        text += f" ({first.context})"
    if first.advice:
        text += f"; {first.advice}"
    return text


@dataclass(frozen=True)
class SameFailureRule:
    """When a failure is the reference failure f (docs/oracle.md, "The same-failure rule").

    `match` is one of `MATCHES` or "module:qualname" of a module-level function `same_failure(reference,
    signature) -> bool`; `tolerance` the metres of "the same place"; `predicates` per-predicate matches
    (predicate name, match), from `robot_failure(..., same_failure=...)`, which take precedence for a reference
    failure of that predicate. A reference failure of an arm's predicate is matched within
    `ARM_TOLERANCE` when `tolerance` is the default (`tolerance_for`). Plain data: a function is held by its
    name and imported when first used, so the rule is recorded in `summary.json` and `ddenv replay` re-applies
    it (`to_json`, `from_json`)."""

    match: str = defaults.SAME_FAILURE
    tolerance: float = defaults.TOLERANCE
    predicates: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        if not is_finite_number(self.tolerance) or self.tolerance < 0:
            raise ValueError(expected("a finite number >= 0", self.tolerance, "tolerance"))
        for name, match in (("same_failure", self.match), *self.predicates):
            if not isinstance(match, str) or (match not in MATCHES and ":" not in match):
                raise SameFailureError(expected(f"one of {', '.join(MATCHES)} or 'module:function'", match, name))

    def match_for(self, predicate: str) -> str:
        """The match that applies to a reference failure of `predicate`."""
        return dict(self.predicates).get(predicate, self.match)

    def same(self, failure: FailureSignature, reference: FailureSignature) -> bool:
        """Whether `failure` is the `reference` failure under this rule."""
        match = self.match_for(reference.predicate)
        if match in MATCHES:
            return same_failure(failure, reference, self.tolerance, match=match)
        return _call(match, reference, failure)

    def built_in(self) -> SameFailureRule:
        """This rule with "all" for every user function (for grouping other failures among themselves)."""
        return replace(self, match=self.match if self.match in MATCHES else defaults.SAME_FAILURE,
                       predicates=tuple((name, match if match in MATCHES else defaults.SAME_FAILURE)
                                        for name, match in self.predicates))

    def describe(self, reference: FailureSignature) -> str:
        """The rule as it applies to `reference`: "no_goal_progress within 0.5 m, touching one of the models
        the reference touched (the default rule)"."""
        match = self.match_for(reference.predicate)
        origin = ("the default rule" if match == defaults.SAME_FAILURE and reference.predicate not in
                  dict(self.predicates) else f"same_failure={match!r}")
        if match not in MATCHES:
            return f"when {match}(reference, signature) says so"
        place = f"within {tolerance_for(reference.predicate, self.tolerance):g} m"
        if not reference.touched:
            touching = "touching no model, as the reference" if match == "touched" else ""
        else:
            touching = "touching one of the models the reference touched"
        parts = {"all": [place, touching], "place": [place, "whatever it touches"],
                 "touched": [touching, "wherever it is"]}[match]
        return f"{reference.predicate} {', '.join(part for part in parts if part)} ({origin})"

    def to_json(self) -> dict[str, Any]:
        """As recorded in summary.json: {"match", "tolerance", "predicates": {name: match}}."""
        return {"match": self.match, "tolerance": self.tolerance, "predicates": dict(self.predicates)}

    @classmethod
    def from_json(cls, data: Any, where: str = "same_failure") -> SameFailureRule:
        """The inverse of `to_json`; a user function is imported now (`SameFailureError` naming `where`)."""
        if not isinstance(data, Mapping):
            raise SameFailureError(expected("a mapping {match, tolerance, predicates}", data, where))
        predicates = data.get("predicates") or {}
        if not isinstance(predicates, Mapping):
            raise SameFailureError(expected("a mapping {predicate: match}", predicates, f"{where}.predicates"))
        tolerance = data.get("tolerance", defaults.TOLERANCE)
        try:
            rule = cls(data.get("match", defaults.SAME_FAILURE), tolerance,
                       tuple((str(name), match) for name, match in predicates.items()))
        except ValueError as error:
            raise SameFailureError(f"{where}: {error}") from None
        for match in (rule.match, *dict(rule.predicates).values()):
            if match not in MATCHES:
                load_same_failure_function(match, where)
        return rule


def same_failure_match(value: Any, where: str) -> str:
    """A match as a rule holds it, from what a user gives: "all", "place", "touched", or a module-level function
    `same_failure(reference, signature) -> bool` (the function, or "module:qualname"), which becomes
    "module:qualname". `SameFailureError` naming `where` (the marker argument, the option) otherwise."""
    if isinstance(value, str) and value in MATCHES:
        return value
    if isinstance(value, str) and ":" in value:
        return function_reference(load_same_failure_function(value, where), where)
    if isinstance(value, str) or not callable(value):
        raise SameFailureError(expected(f"one of {', '.join(repr(m) for m in MATCHES)} or a module-level function "
                                        "same_failure(reference, signature) -> bool", value, where))
    return function_reference(value, where)


def function_reference(function: Any, where: str) -> str:
    """"module:qualname" of a module-level function of two arguments, checked to import as itself."""
    name = getattr(function, "__qualname__", None) or shown(function)
    if not inspect.isfunction(function):
        raise SameFailureError(f"{where}: {name} is not a function; give a module-level function "
                               "same_failure(reference, signature) -> bool")
    if "<" in function.__qualname__:  # "<lambda>", "outer.<locals>.inner"
        raise SameFailureError(f"{where}: {name} is not a module-level function; define it at module level "
                               "(def same_failure(reference, signature): ...) so that `ddenv replay` and `ddenv "
                               "reduce` can import it by name")
    try:
        inspect.signature(function).bind(None, None)
    except TypeError:
        raise SameFailureError(f"{where}: {name} must take two arguments, (reference, signature)") from None
    reference = f"{function.__module__}:{function.__qualname__}"
    if load_same_failure_function(reference, where) is not function:
        raise SameFailureError(f"{where}: {reference} does not import as the function given (redefined?); give "
                               "a function defined once at module level")
    return reference


def load_same_failure_function(reference: str, where: str) -> SameFailureFunction:
    """The function "module:qualname" names: from the loaded modules, else imported (`SameFailureError`)."""
    module_name, _, qualname = reference.partition(":")
    module = sys.modules.get(module_name)
    if module is None:
        try:
            module = importlib.import_module(module_name)
        except Exception as error:  # noqa: BLE001 - any import failure: said with the option or argument
            raise SameFailureError(f"{where}: the same-failure function {reference} cannot be imported: "
                                   f"{type(error).__name__}: {error} (import its module first, e.g. "
                                   "`ddenv --import MODULE_OR_FILE`)") from None
    value: Any = module
    for part in qualname.split("."):
        value = getattr(value, part, None)
        if value is None:
            raise SameFailureError(f"{where}: module {module_name} has no function {qualname!r}")
    if not callable(value):
        raise SameFailureError(f"{where}: {reference} is not a function")
    return value  # type: ignore[no-any-return]


def _call(reference: str, expected_failure: FailureSignature, failure: FailureSignature) -> bool:
    """A user's rule applied: `function(reference_signature, signature)`, checked to say True or False."""
    function = load_same_failure_function(reference, "same_failure")
    try:
        verdict = function(expected_failure, failure)
    except Exception as error:
        raise SameFailureError(f"the same-failure function {reference} raised {type(error).__name__}: {error} "
                               f"(reference {expected_failure.predicate} at t = {expected_failure.time:.2f} s, "
                               f"signature {failure.predicate} at t = {failure.time:.2f} s)") from error
    if not isinstance(verdict, (bool, np.bool_)):
        raise SameFailureError(f"the same-failure function {reference} returned {type(verdict).__name__} "
                               f"{shown(verdict)}; expected True or False")
    return bool(verdict)


def as_rule(rule: SameFailureRule | float) -> SameFailureRule:
    """A rule, from a rule or a tolerance (the default rule with that tolerance)."""
    return rule if isinstance(rule, SameFailureRule) else SameFailureRule(tolerance=rule)


def classify(
    run: HasFailure | None,
    reference: FailureSignature,
    rule: SameFailureRule | float = defaults.TOLERANCE,
    *,
    error: BaseException | None = None,
) -> Outcome:
    """Classify a run against the reference failure, by `rule` (or the default rule with this tolerance):
    `classify_result` of the run's failure.

    - ERROR: `error` is given or `run` is None (the simulation or the test broke).
    - PASS: the run has no failure signature.
    - FAIL (same failure f): by the default rule, the same predicate fired, the failure position is within
      `tolerance` m (3D) of the reference's, and, if the robot touched models at the reference failure, it
      touches at least one of those same models now. The last rule tells "trapped in the gap, wedged against
      the far plateau" from "fell off the edge onto the bare ground" at the same spot, and the 3D distance (z
      included) tells it from "blocked by the wall at ground level". Other rules: `SameFailureRule`.
    - OTHER: any other failure.
    """
    if error is not None or run is None:
        return Outcome.ERROR
    failure = run.failure
    raised = None if failure is None else ErrorInfo(ROBOT_FAILURE, "", "", signature=failure)
    return classify_result(raised, FailureReference(ROBOT_FAILURE, "", reference), rule)


ROBOT_FAILURE = "RobotFailure"
"""The exception type of a predicate's failure (`RobotFailure`), as `ErrorInfo.type_name` says it."""


@dataclass(frozen=True)
class ErrorInfo:
    """What a test raised, as plain data.

    `location` is file:line of the deepest frame inside the test file (else the deepest frame);
    `signature` is set for a `RobotFailure`; `ddenv_error` for an error of pytest-ddenv itself (a world that
    cannot be simulated, a worker that could not run the test), which is never a verdict. `phase` is
    "call" unless the test's setup or teardown broke (an error, not a verdict either).
    """

    type_name: str
    message: str
    location: str
    traceback: str = ""
    signature: FailureSignature | None = None
    ddenv_error: bool = False
    phase: str = "call"

    def describe(self) -> str:
        where = f" (in the test's {self.phase})" if self.phase != "call" else ""
        return f"{self.type_name}: {self.message} at {self.location}{where}"


@dataclass(frozen=True)
class FailureReference:
    """The original failure a probe must reproduce.

    A predicate failure (`RobotFailure`) is matched by its signature (same predicate, failure position within
    tolerance); any other exception by its type and the line of the test that raised it.
    """

    exception_type: str
    location: str
    signature: FailureSignature | None = None

    @classmethod
    def of(cls, error: ErrorInfo) -> FailureReference:
        return cls(error.type_name, error.location, error.signature)

    def describe(self) -> str:
        if self.signature is not None:
            return f"{self.signature.predicate} at t={self.signature.time:.1f} s"
        return f"{self.exception_type} at {self.location}"

    def to_dict(self) -> dict[str, Any]:
        return {
            "exception_type": self.exception_type,
            "location": self.location,
            "signature": None if self.signature is None else self.signature.to_dict(),
        }


WALL_CLOCK_CAP = "ControllerTimeout"
"""The exception type of a run stopped by its wall-clock cap (`max_wall_time`, `--ddenv-run-timeout`, `ddenv
reduce --run-timeout`): an error of the run (ERROR), never a verdict."""


def hit_wall_clock_cap(error: ErrorInfo | None) -> bool:
    """Whether `error` is a run stopped by its wall-clock cap (`WALL_CLOCK_CAP`)."""
    return error is not None and error.signature is None and error.type_name == WALL_CLOCK_CAP


def is_run_error(error: ErrorInfo | None) -> bool:
    """Whether `error` is an error of the run rather than an outcome of the test: pytest-ddenv's own error, a
    broken setup or teardown, or a run stopped by its wall-clock cap."""
    return error is not None and (error.ddenv_error or error.phase != "call" or hit_wall_clock_cap(error))


def wall_clock_cap_message(location: str) -> str:
    """Why a test whose original failure (raised at `location`) is its run's wall-clock cap is not reduced."""
    return (f"the test failed with {WALL_CLOCK_CAP} at {location}: its run went past its wall-clock cap, an error of "
            "the run (a busy machine, a slow controller or a big world), not a failure of the robot; it cannot "
            "be reduced as a failure. Raise the cap (robot_world.run(max_wall_time=...), --ddenv-run-timeout, "
            "ddenv reduce --run-timeout) or make the controller faster. No reduction was run.")


def classify_result(error: ErrorInfo | None, reference: FailureReference, rule: SameFailureRule | float) -> Outcome:
    """Compare what a probe raised with the original failure: a predicate failure by `rule` (a
    `SameFailureRule`, or the default rule with this tolerance), an exception by its type and line. An error
    of the run (`is_run_error`: a run stopped by its wall-clock cap included) is ERROR."""
    if error is None:
        return Outcome.PASS
    if is_run_error(error):
        return Outcome.ERROR
    if error.signature is not None:
        if reference.signature is None:
            return Outcome.OTHER
        return Outcome.FAIL if as_rule(rule).same(error.signature, reference.signature) else Outcome.OTHER
    if reference.signature is None and error.type_name == reference.exception_type:
        return Outcome.FAIL if error.location == reference.location else Outcome.OTHER
    return Outcome.OTHER
