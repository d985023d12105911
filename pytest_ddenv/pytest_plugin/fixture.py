"""The world a test's `robot_world` fixture runs in: `--ddenv-world`, else an indirect parameter (a path or a
`World`), else `@pytest.mark.ddenv(world=...)`, loaded and checked against the test's markers, in the engine
`--ddenv-engine`, else `ddenv(engine=...)`, else the world names."""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.errors import DdenvError, shown
from pytest_ddenv.pytest_plugin.options import expand_home, options_of
from pytest_ddenv.validation import expected
from pytest_ddenv.world.files import is_file, regular_file_problem

if TYPE_CHECKING:
    from pytest_ddenv.oracle.predicates import PredicateSpec
    from pytest_ddenv.world.model import World


def _world_path(item: pytest.Item, raw: str | os.PathLike[str]) -> Path:
    """A world path as given: absolute, else relative to the test file, else to the rootdir."""
    path = expand_home(str(raw), "world")
    if path.is_absolute():
        return path
    candidates = [Path(str(item.path)).parent / path, Path(str(item.config.rootpath)) / path]
    for candidate in candidates:
        if is_file(candidate):
            return candidate
    for candidate in candidates:  # there, but not a file to read: say what it is (a folder, a FIFO, a loop)
        problem = regular_file_problem(candidate, "world file")
        if problem is not None and not problem.startswith("world file not found"):
            raise DdenvError(problem)
    folders = dict.fromkeys(str(candidate.parent) for candidate in candidates)
    raise DdenvError(f"world file not found: {raw} (looked in {', '.join(folders)})")


def load_test_world(request: pytest.FixtureRequest, spec: ReductionSpec,
                    predicates: tuple[PredicateSpec, ...]) -> World:
    """The world a test runs in, checked against its markers (DdenvError naming the file and field)."""
    from pytest_ddenv.oracle.predicates import check_predicate_models
    from pytest_ddenv.pytest_plugin.given_example import inner_test
    from pytest_ddenv.scenario.robot_world import NO_WORLD_YET
    from pytest_ddenv.world.model import World

    item = request.node
    options: dict[str, Any] = {"model_paths": list(options_of(request.config).model_paths),
                               "skip_unsupported": spec.skip_unsupported}
    override = options_of(request.config).world
    param = getattr(request, "param", None)
    if override:
        world = World.load(override, **options)
    elif isinstance(param, World):
        world = param
    elif param is not None:
        if not isinstance(param, (str, os.PathLike)):
            raise DdenvError(expected("a world file path or a World", param, "robot_world's indirect parameter"))
        world = World.load(_world_path(item, param), **options)
    elif spec.world is not None:
        world = World.load(_world_path(item, spec.world), **options)
    elif inner_test(item) is not None:  # a @given test draws its worlds: robot_world.rebound(world)
        return NO_WORLD_YET
    else:
        raise DdenvError(
            "robot_world needs a world: @pytest.mark.ddenv(world='worlds/x.yaml'), an indirect parameter, or "
            "--ddenv-world PATH"
        )
    engine = options_of(request.config).engine or spec.engine  # --ddenv-engine, else engine=, else the world's
    if engine is not None:
        world = world.with_engine(engine)
    where = world.source or world.name or "the world"
    if world.source is not None and Path(world.source).is_relative_to(request.config.invocation_params.dir):
        where = str(Path(world.source).relative_to(request.config.invocation_params.dir))
    if not isinstance(param, World) or override:  # loaded here: say what skip_unsupported dropped
        _warn_dropped(item, world, where)
    unknown = sorted(set(spec.keep) - set(world.names))
    if unknown:
        raise DdenvError(f"ddenv(keep=...) names model(s) not in {where}: {', '.join(map(shown, unknown))}")
    if not override:  # a reduced world (--ddenv-world minimal.yaml) may lack models the predicates name
        check_predicate_models(predicates, world.names, where)
    if world.scenario is not None:  # a robot that does not fit its URDF: an error at setup, not a failure
        from pytest_ddenv.errors import ScenarioError
        from pytest_ddenv.oracle.predicates import check_predicates_for_robot
        from pytest_ddenv.sim.arm.robot import robot_kind
        from pytest_ddenv.sim.robot import check_robot

        robot = world.scenario.robot
        check_robot(robot, world.source)
        try:  # a mobile robot's predicate on an arm's world, or the other way round
            check_predicates_for_robot(predicates, robot_kind(robot, world.source),
                                       robot if isinstance(robot, str) else robot.label)
        except ScenarioError as error:
            raise ScenarioError(error.reason, source=where, field="robot_failure") from None
    return world


class DroppedModelsWarning(UserWarning):
    """A test's world was loaded with `ddenv(skip_unsupported=True)` and models that cannot be simulated were
    dropped from it (`-W ignore::pytest_ddenv.pytest_plugin.hooks.DroppedModelsWarning` to silence it)."""


def _warn_dropped(item: pytest.Item, world: World, where: str) -> None:
    """One warning naming each model that skip_unsupported dropped from the test's world (none if none)."""
    from pytest_ddenv.cli.world_options import dropped_warning

    text = dropped_warning(world, where)
    if text is not None:
        warnings.warn(DroppedModelsWarning(f"{item.nodeid}: {text}"), stacklevel=1)


