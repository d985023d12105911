"""The `--predicate NAME[:key=value,...]` option: its text read into `PredicateSpec`s and checked (the predicate
and its parameters exist, the models it names are in the world); `ddenv reduce`'s default for an arm."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from pytest_ddenv.cli.world_options import UsageError
from pytest_ddenv.errors import DdenvError, shown
from pytest_ddenv.oracle.predicates import PredicateSpec, check_predicate_models

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.world.model import World


def parse_predicate(text: str) -> PredicateSpec:
    """`NAME[:key=value,...]`, e.g. `stuck:window=5,min_progress=0.2` or `collided:models=[wall,barrel]`.

    Values are numbers, true/false, none, or [a,b,...] lists of names; validated by `oracle.make_predicate`.
    """
    from pytest_ddenv.oracle.predicates import make_predicate

    name, _, rest = text.partition(":")
    if not name.strip():
        raise UsageError(f"--predicate {shown(text)}: expected NAME[:key=value,...]")
    params: dict[str, Any] = {}
    for item in _split_top_level(rest):
        key, equals, value = item.partition("=")
        if not equals or not key.strip():
            raise UsageError(f"--predicate {shown(text)}: expected key=value, got {shown(item)} "
                             "(form: NAME[:key=value,...], e.g. stuck:window=5,min_progress=0.2)")
        if key.strip() in params:
            raise UsageError(f"--predicate {shown(text)}: {shown(key.strip())} is given twice; give each "
                             "parameter once")
        params[key.strip()] = _predicate_value(value.strip())
    try:
        make_predicate(name.strip(), **params)
    except DdenvError as error:
        raise UsageError(f"--predicate {shown(text)}: {error}") from None
    return PredicateSpec(name.strip(), params)


def _split_top_level(text: str) -> list[str]:
    """Split at commas that are not inside [...]."""
    items, depth, current = [], 0, ""
    for char in text:
        depth += char == "["
        depth -= char == "]"
        if char == "," and depth == 0:
            items.append(current)
            current = ""
        else:
            current += char
    if current.strip():
        items.append(current)
    return [item for item in items if item.strip()]


def _predicate_value(text: str) -> Any:
    lowered = text.lower()
    if lowered in ("none", "null"):
        return None
    if lowered in ("true", "false"):
        return lowered == "true"
    if text.startswith("[") and text.endswith("]"):
        return [item.strip() for item in text[1:-1].split(",") if item.strip()]
    for convert in (int, float):
        try:
            return convert(text)
        except ValueError:
            pass
    return text


def parsed_predicates(texts: Sequence[str]) -> tuple[PredicateSpec, ...]:
    """Every `--predicate` given, read in order."""
    return tuple(parse_predicate(text) for text in texts)


def reduce_predicates(texts: Sequence[str], world: World) -> tuple[PredicateSpec, ...]:
    """`ddenv reduce`'s predicates: those given, or for an arm's world the arm's defaults (`ARM_DEFAULTS`); a
    mobile robot's world needs at least one (its run fails no other way)."""
    predicates = parsed_predicates(texts)
    if predicates or world.scenario is None:
        return predicates
    from pytest_ddenv.oracle.arm_predicates import default_predicates
    from pytest_ddenv.sim.arm.robot import robot_kind

    if robot_kind(world.scenario.robot, world.source) == "arm":
        return default_predicates("arm")
    raise UsageError("the following arguments are required for a mobile robot's world: --predicate/-p "
                     "(e.g. -p stuck); an arm's world checks the arm's default predicates when none is given")


def check_named_models(predicates: Sequence[PredicateSpec], world: World) -> None:
    """The models the predicates name (`collided:models=[...]`) are models of `world`; UsageError otherwise."""
    try:
        check_predicate_models(predicates, world.names, world.source or world.name)
    except DdenvError as error:
        raise UsageError(f"--predicate: {error}") from None
