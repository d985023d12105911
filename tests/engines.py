"""The physics engines in the suite: which are installed, the `pybullet` and `mujoco` markers that skip a test
where its engine is not (tests/conftest.py applies them), and the `physics_engine` fixture's parameters.

A test that asserts what only one engine does (pybullet's API, bit-identical trajectories, the paper's numbers,
the exact minimal world of a pybullet run) carries that engine's marker: `@pytest.mark.pybullet`, or
`pytestmark = pytest.mark.pybullet` for a module. An engine-neutral test where the engine matters asks for
`physics_engine` and runs once per engine ("pybullet", "mujoco"), the one not installed skipped with a reason;
it puts the engine into its world with `in_engine`, into a pytest run with `engine_option`, or into a `ddenv`
command with `engine_flag`.

An engine-neutral test that fails in MuJoCo because of a known weakness of the MuJoCo engine carries
`@pytest.mark.mujoco_gap("what MuJoCo does differently")`: where it runs in MuJoCo (its `physics_engine` is
"mujoco", or it has none and pybullet is not installed) it is a strict xfail naming the gap, so the suite says
which gaps are open and fails when one closes (then remove the marker).
"""

from __future__ import annotations

import importlib.util

import pytest

from pytest_ddenv.world import World
from pytest_ddenv.world.limits import default_engine

ENGINES = ("pybullet", "mujoco")
NOT_INSTALLED = {
    "pybullet": "needs pybullet (the PyBullet engine): pip install pybullet; runs on Python <= 3.11",
    "mujoco": 'needs mujoco (the MuJoCo engine): pip install "pytest-ddenv[mujoco]"',
}
"""The skip reason of a test of each engine where that engine is not installed."""

PYBULLET_MODULES = ("test_paper_regression.py",)
"""Modules that are pybullet's as a whole and are marked `pybullet` by place (tests/conftest.py): the paper
regression's recorded minimal worlds are pybullet runs, and the file stays unchanged."""

# -- the MuJoCo engine's known gaps: the reasons of `mujoco_gap` markers ------------------------------------------
WHEELS_HOP_AT_A_WALL = ("a Husky pushing its nose against a wall hops: in MuJoCo its wheels lose the ground on some "
                        "samples (wheel_contacts 0) where pybullet's rest on it throughout")


def installed(engine: str) -> bool:
    """Whether `engine`'s Python package can be imported here."""
    return importlib.util.find_spec(engine) is not None


ENGINE_PARAMS = [pytest.param(engine, marks=getattr(pytest.mark, engine), id=engine) for engine in ENGINES]
"""`physics_engine`'s parameters: each engine with its marker."""


def skip_reason(item: pytest.Item) -> str | None:
    """Why `item` cannot run here (it carries the marker of an engine that is not installed), or None."""
    for engine in ENGINES:
        if item.get_closest_marker(engine) is not None and not installed(engine):
            return NOT_INSTALLED[engine]
    return None


def engine_of(item: pytest.Item) -> str:
    """The engine `item` runs its worlds in: its `physics_engine` parameter, else the default engine."""
    callspec = getattr(item, "callspec", None)
    if callspec is not None and "physics_engine" in callspec.params:
        return str(callspec.params["physics_engine"])
    return default_engine()


def known_gap(item: pytest.Item) -> pytest.MarkDecorator | None:
    """A strict xfail naming the MuJoCo engine's gap when `item` has a `mujoco_gap` marker and runs in MuJoCo."""
    marker = item.get_closest_marker("mujoco_gap")
    if marker is None or engine_of(item) != "mujoco":
        return None
    return pytest.mark.xfail(strict=True, reason=f"a gap of the MuJoCo engine: {marker.args[0]}")


def in_engine(world: World, engine: str) -> World:
    """`world` simulated by `engine` (its `physics.engine`)."""
    return world.with_engine(engine)


def engine_option(engine: str) -> list[str]:
    """The pytest arguments that run a pytester project's tests in `engine`."""
    return ["--ddenv-engine", engine]


def engine_flag(engine: str) -> list[str]:
    """The `ddenv run|reduce|replay` arguments that simulate in `engine`."""
    return ["--engine", engine]
