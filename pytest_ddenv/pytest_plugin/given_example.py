"""Hypothesis tests (`@given`) under reduction: reduce the falsifying example's world, one example per probe.

A scenario test that draws its world (``@given(world=strategies.worlds(...))``) binds it with
``robot_world.rebound(world)``. When it fails under ``--ddenv-reduce``, Hypothesis has already shrunk the
example and re-run it last; the plugin recorded the arguments of every call of the test's inner function
(`recording_calls`, through Hypothesis's public, reassignable ``test.hypothesis.inner_test``), so it knows
the falsifying example: which argument is the world (`GivenExample.world_argument`) and the other drawn
values. Each probe then calls the inner test function exactly once, with those values and the candidate
world in place of the drawn one, bypassing Hypothesis (no generation, no shrinking, no database writes in
probes). The other drawn values travel to the probe workers, so they must be plain data (JSON).
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import json
import re
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.scenario.robot_world import FIXTURE, RobotWorld
from pytest_ddenv.world.model import World

_BLOB = re.compile(r"@reproduce_failure\([^)]*\)")


def inner_test(item: pytest.Item) -> Callable[..., Any] | None:
    """The function a Hypothesis test wraps (None: not a `@given` test)."""
    handle = getattr(getattr(item, "obj", None), "hypothesis", None)
    inner = getattr(handle, "inner_test", None)
    return inner if callable(inner) else None


@contextlib.contextmanager
def recording_calls(item: pytest.Item) -> Iterator[list[dict[str, Any]]]:
    """Within the block, the keyword arguments of each call Hypothesis makes of the test (the last one kept:
    after shrinking, Hypothesis runs the falsifying example last)."""
    handle = item.obj.hypothesis  # type: ignore[attr-defined]
    original = handle.inner_test
    calls: list[dict[str, Any]] = []

    @functools.wraps(original)
    def recorded(*args: Any, **kwargs: Any) -> Any:
        calls[:] = [dict(kwargs)]
        return original(*args, **kwargs)

    handle.inner_test = recorded
    try:
        yield calls
    finally:
        handle.inner_test = original


@dataclass(frozen=True)
class GivenExample:
    """The falsifying example of a `@given` test: the argument that holds the world, and the other drawn
    arguments (plain JSON data)."""

    world_argument: str
    arguments: Mapping[str, Any]

    @classmethod
    def of(cls, call: Mapping[str, Any], world: World, fixtures: Mapping[str, Any]) -> GivenExample:
        """The example of the test call `call` (its keyword arguments) whose drawn world is `world`;
        `fixtures`: the test's fixture values (not drawn). Raises DdenvError naming the argument when the
        world is not one of the drawn arguments or another drawn argument is not plain data."""
        drawn = {name: value for name, value in call.items() if name not in fixtures}
        worlds = [name for name, value in drawn.items() if value is world or _switched_to(value, world)]
        if not worlds:
            raise DdenvError("the world the test ran is not one of its @given arguments: draw the world itself "
                             "(@given(world=strategies.worlds(...))) and run robot_world.rebound(world)")
        others = {name: value for name, value in drawn.items() if name != worlds[0]}
        for name, value in others.items():
            try:
                plain = json.loads(json.dumps(value, allow_nan=False))
            except (TypeError, ValueError):
                plain = None
            if plain != value:
                raise DdenvError(f"@given argument {name!r} = {value!r:.80} is not plain data (JSON): the probes "
                                 "run the test again in worker processes with the same drawn values; draw it as "
                                 "numbers, strings, lists or dicts, or into the world")
        return cls(worlds[0], others)

    def call(self, item: pytest.Item, fixtures: Mapping[str, Any], world: World) -> Any:
        """Run the test once on this example with `world` in place of the drawn one (no Hypothesis)."""
        inner = inner_test(item)
        if inner is None:
            raise DdenvError(f"{item.nodeid} is no longer a @given test")
        return inner(**fixtures, **self.arguments, **{self.world_argument: world})


def _switched_to(drawn: Any, world: World) -> bool:
    """Whether `world` is the `drawn` world with its physics engine switched (`robot_world.rebound` under
    `--ddenv-engine` or the marker's `engine=`)."""
    return isinstance(drawn, World) and drawn.physics.engine != world.physics.engine and \
        drawn.with_engine(world.physics.engine) == world


def reproduction(item: pytest.Item, error: BaseException, example: GivenExample) -> dict[str, Any]:
    """How to get the falsifying example back from Hypothesis: its seed (``--hypothesis-seed`` or ``@seed``),
    the ``@reproduce_failure`` decorator when Hypothesis printed one (``print_blob=True``), the drawn values
    besides the world; for `summary.json`."""
    seed = getattr(item.obj, "_hypothesis_internal_use_seed", None)  # type: ignore[attr-defined]
    if seed is None:
        with contextlib.suppress(ValueError):
            seed = item.config.getoption("hypothesis_seed", None)
    notes = [str(note) for note in getattr(error, "__notes__", ())]
    blob = next((match.group(0) for note in notes if (match := _BLOB.search(note))), None)
    return {"world_argument": example.world_argument, "arguments": dict(example.arguments),
            "seed": None if seed is None else str(seed), "reproduce_failure": blob}


class GivenReplay:
    """With ``--ddenv-world FILE``, a `@given` test runs once, on FILE, instead of drawing worlds: the
    replay of a reduction (``pytest NODEID --ddenv-world .../minimal.yaml``). The other drawn values of the
    falsifying example come from the `summary.json` beside FILE, when there is one."""

    def __init__(self, world_file: str) -> None:
        self.world_file = Path(world_file)

    @pytest.hookimpl(tryfirst=True)
    def pytest_pyfunc_call(self, pyfuncitem: pytest.Function) -> bool | None:
        inner = inner_test(pyfuncitem)
        robot_world = pyfuncitem.funcargs.get(FIXTURE)
        if inner is None or not isinstance(robot_world, RobotWorld):
            return None
        fixtures = {name: pyfuncitem.funcargs[name] for name in inspect.signature(pyfuncitem.obj).parameters
                    if name in pyfuncitem.funcargs}
        self.example(inner, fixtures).call(pyfuncitem, fixtures, robot_world.world)
        return True

    def example(self, inner: Callable[..., Any], fixtures: Mapping[str, Any]) -> GivenExample:
        recorded = self._recorded()
        if recorded is not None:
            return recorded
        drawn = [name for name in inspect.signature(inner).parameters if name not in fixtures]
        if len(drawn) != 1:
            raise DdenvError(f"--ddenv-world {self.world_file}: the test draws {', '.join(drawn) or 'nothing'} and "
                             "no summary.json beside the file says which one is the world and what the others were")
        return GivenExample(drawn[0], {})

    def _recorded(self) -> GivenExample | None:
        try:
            summary = json.loads((self.world_file.parent / "summary.json").read_text(encoding="utf-8"))
            given = summary["hypothesis"]
            return GivenExample(str(given["world_argument"]), dict(given["arguments"]))
        except (OSError, ValueError, KeyError, TypeError):
            return None
