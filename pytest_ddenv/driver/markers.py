"""The `ddenv` and `robot_failure` markers: parsed and validated eagerly into plain values.

No pytest import: the plugin hands over the markers' args and kwargs and turns `MarkerError` into a usage
error that names the test.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from pytest_ddenv import defaults
from pytest_ddenv.driver.settings import SETTING, SettingError, marker_settings
from pytest_ddenv.errors import DdenvError, shown

if TYPE_CHECKING:
    from pytest_ddenv.oracle.predicates import PredicateSpec
    from pytest_ddenv.oracle.verdict import SameFailureRule

DDENV_KEYWORDS = tuple(str(setting.marker) for setting in marker_settings())
"""The `ddenv(...)` marker's arguments (`driver/settings.py` declares them)."""
SAME_FAILURE_KEYWORD = "same_failure"
"""The `robot_failure` keyword that sets the predicate's own same-failure rule (not a predicate parameter)."""


class MarkerError(SettingError):
    """A marker's arguments are invalid; the message names the marker and the argument."""


@dataclass(frozen=True)
class ReductionSpec:
    """What `@pytest.mark.ddenv(...)` says about a test (defaults when the marker is absent)."""

    world: str | None = None
    engine: str | None = None
    """The physics engine chosen for the test's world (None: the world's `physics.engine`)."""
    confirm_engines: tuple[str, ...] = ()
    """The other engines the minimal and original worlds are run in after the reduction (`driver/cross_engine.py`)."""
    partition: str = defaults.PARTITION
    priority: str = defaults.PRIORITY
    n_partitions: int = defaults.N_PARTITIONS
    granularity: str = defaults.GRANULARITY
    deflake: int | str = defaults.DEFLAKE
    tolerance: float = defaults.TOLERANCE
    same_failure: str = defaults.SAME_FAILURE
    """The test's same-failure match: "all", "place", "touched" or "module:qualname" of a user function
    (`oracle.SameFailureRule`)."""
    keep: tuple[str, ...] = ()
    seed: int = defaults.SEED
    rate: int = 1
    """Runs of the test whose failure rate is its verdict (`--ddenv-rate`; 1: run once, as usual)."""
    max_failure_rate: float = 0.0
    """The failure rate the test may have (`--ddenv-max-failure-rate`): it fails when significantly above."""
    max_probes: int | None = None
    max_seconds: float | None = None
    skip_unsupported: bool = False
    stages: tuple[str, ...] | None = None
    """The model-level reduction and the stages after it that are on (None: not given, the default
    `pytest_ddenv.stages.DEFAULT_STAGES`)."""
    stage_probes: int | None = None
    """Simulations each stage after the models may start (None: all of them together at most twice the
    model-level simulations)."""

    def same_failure_rule(self, predicates: Sequence[PredicateSpec] = ()) -> SameFailureRule:
        """The rule that decides "same failure": this test's match and tolerance, and the predicates' own
        matches (`robot_failure(..., same_failure=...)`)."""
        from pytest_ddenv.oracle.verdict import SameFailureRule

        return SameFailureRule(self.same_failure, self.tolerance,
                               tuple((spec.name, spec.same_failure) for spec in predicates if spec.same_failure))


def parse_ddenv_marker(args: Sequence[Any], kwargs: Mapping[str, Any]) -> ReductionSpec:
    """The marker's arguments, each checked as `driver/settings.py` declares it (MarkerError naming it)."""
    if len(args) > 1:
        raise MarkerError("ddenv(...) takes at most one positional argument, the world file")
    values = dict(kwargs)
    if args:
        if "world" in values:
            raise MarkerError("ddenv(...): the world is given twice (positional and world=)")
        values["world"] = args[0]
    unknown = sorted(set(values) - set(DDENV_KEYWORDS))
    if unknown:
        raise MarkerError(f"ddenv(...): unknown argument '{unknown[0]}'; valid arguments: {', '.join(DDENV_KEYWORDS)}")
    updates: dict[str, Any] = {}
    for setting in marker_settings():
        if setting.marker in values:
            try:
                value = setting.check(values[setting.marker], f"ddenv({setting.marker}=...)")
            except SettingError as error:
                raise MarkerError(str(error)) from None
            updates.update(value if setting.name == "budget" else {setting.name: value})
    return replace(ReductionSpec(), **updates)


def parse_same_failure(value: Any, where: str) -> str:
    """A same-failure match: "all", "place", "touched", or a module-level function `same_failure(reference,
    signature) -> bool` (held as "module:qualname", so that `ddenv replay` can import it)."""
    try:
        return str(SETTING["same_failure"].check(value, where))
    except SettingError as error:
        raise MarkerError(str(error)) from None


def parse_failure_markers(markers: Sequence[tuple[Sequence[Any], Mapping[str, Any]]]) -> tuple[PredicateSpec, ...]:
    """Validate each robot_failure marker by building its predicate (unknown names or parameters fail here).

    A marker holds a registered predicate's name with keyword parameters, a predicate object
    (`robot_failure(OnSlope(max_pitch=0.3))`) or a plain function of the state (`robot_failure(tipped)`), and
    optionally the predicate's own same-failure rule (`same_failure="place"`, not a parameter of the predicate).
    """
    from pytest_ddenv.oracle.predicates import PREDICATES, predicate_spec

    specs = []
    for args, given in markers:
        kwargs = dict(given)
        match = kwargs.pop(SAME_FAILURE_KEYWORD, None)
        if len(args) != 1:
            raise MarkerError(
                "robot_failure(...) takes one positional argument: a predicate name, e.g. "
                "robot_failure('stuck', window=5.0), a predicate object, or a function of the state; "
                f"registered predicates: {', '.join(sorted(PREDICATES))}"
            )
        try:
            spec = predicate_spec(args[0], kwargs)
        except DdenvError as error:
            raise MarkerError(f"robot_failure({shown(args[0])}, ...): {error}") from error
        if match is not None:
            where = f"robot_failure({shown(args[0])}, same_failure=...)"
            spec = replace(spec, same_failure=parse_same_failure(match, where))
        specs.append(spec)
    return tuple(specs)


def marked_predicate(value: Any) -> Any:
    """The class or function that pytest marked with `robot_failure` when it was given alone to the marker
    (`robot_failure(OnSlope)`, `robot_failure(tipped)`): `value` itself, or its class (pytest then called the
    class with the test, making `value` an instance); None when neither carries such a mark.

    pytest takes a lone class or function given to a marker for the thing to mark: the mark lands on it with
    no arguments and the test is called with it, or replaced by what it returns."""
    for holder in (value, type(value)):
        try:  # any module attribute comes here: a proxy's __getattr__ may raise anything
            marks = vars(holder).get("pytestmark", ())
        except Exception:  # noqa: BLE001
            continue
        if isinstance(marks, (list, tuple)) and any(_is_empty_failure_mark(mark) for mark in marks):
            return holder
    return None


def _is_empty_failure_mark(mark: Any) -> bool:
    return getattr(mark, "name", None) == "robot_failure" and not getattr(mark, "args", ()) \
        and not getattr(mark, "kwargs", {})


def misplaced_predicate_message(holder: Any) -> str:
    """The usage error for `robot_failure(holder)` where pytest took the predicate for the thing to mark."""
    name = getattr(holder, "__name__", None) or shown(holder)
    if inspect.isclass(holder):
        return (f"robot_failure({name}): {name} is a class, not a predicate, so pytest marked the class instead of "
                f"the test and did not collect the test; pass an instance: robot_failure({name}())")
    return (f"robot_failure({name}): pytest takes a function given alone to a marker for the function to mark, "
            f"so it called {name} with the test as its state; decorate {name} with @predicate (from pytest_ddenv "
            f"import predicate), or write robot_failure.with_args({name})")


def find_marked_test(lines: Sequence[str], predicate_name: str) -> tuple[str, int] | None:
    """The test (its name and the marker's line, 1-based) that `robot_failure(predicate_name)` decorates in a
    module's source `lines`; None when not found."""
    usage = re.compile(rf"robot_failure\(\s*(?:[\w.]+\.)?{re.escape(predicate_name)}\s*\)")
    for number, line in enumerate(lines, start=1):
        if usage.search(line):
            test = defined_after(lines, number)
            if test is not None:
                return test, number
    return None


def defined_after(lines: Sequence[str], first: int) -> str | None:
    """The name of the first function defined on or after line `first` (1-based) of `lines`: the function
    that the decorators on that line decorate."""
    for line in lines[max(first - 1, 0):first + 40]:
        match = re.match(r"\s*(?:async\s+)?def\s+(\w+)", line)
        if match:
            return match.group(1)
    return None
