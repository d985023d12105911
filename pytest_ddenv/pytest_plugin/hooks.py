"""pytest glue: the plugin pytest loads (the `pytest11` entry point): options, markers, the `robot_world`
fixture, and, under `--ddenv-reduce`, the reduction's plugin object (`reduction.ReductionPlugin`).

Hooks stay thin; the work is done in the modules beside this one (`options`, `marks`, `fixture`,
`reduction`). A project that has the plugin installed and does not use it pays for its options and
markers, a check of each collected name for a misplaced predicate, and nothing per test.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Generator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.pytest_plugin import marks
from pytest_ddenv.pytest_plugin.fixture import DroppedModelsWarning, load_test_world
from pytest_ddenv.pytest_plugin.options import add_options, options_of, read_options, stash_options
from pytest_ddenv.pytest_plugin.progress import close_log, open_log

if TYPE_CHECKING:
    from pytest_ddenv.scenario.robot_world import RobotWorld

__all__ = ["DroppedModelsWarning", "robot_world"]

MARKERS = (
    ("ddenv(world=PATH, engine='pybullet'|'mujoco', partition=..., priority=..., n_partitions=2, "
    "granularity='ddmin', deflake='auto', "
    "tolerance=0.5, same_failure='all'|'place'|'touched'|function, keep=(...), seed=0, rate=1, "
    "max_failure_rate=0, budget=N, "
    "skip_unsupported=False, stages='models,explain,passing', confirm_engines='mujoco'): "
    "the world of a robot scenario test and how to reduce it when the test fails under --ddenv-reduce."),
    ("robot_failure(NAME, **params, same_failure=...): a failure predicate checked while the robot runs "
    "(stuck, flipped, high_centered, fell, collided, timeout); stackable."),
)


def pytest_addoption(parser: pytest.Parser) -> None:
    add_options(parser)


def pytest_configure(config: pytest.Config) -> None:
    for line in MARKERS:
        config.addinivalue_line("markers", line)
    options = stash_options(config, read_options(config))
    from pytest_ddenv.pytest_plugin.worker import WORKER

    worker = config.stash.get(WORKER, False)  # a probe worker's session runs the test, and reduces nothing
    if options.reduce and not worker:
        from pytest_ddenv.pytest_plugin.reduction import ReductionPlugin

        config.pluginmanager.register(ReductionPlugin(config), "ddenv-reduction")
    if not worker and (options.rate not in (None, 1) or _xdist_controller(config)):
        _register_rate_records(config)  # the reports of tests with a rate arrive here
    if options.world and not worker:  # a @given test runs once on that world (replay)
        from pytest_ddenv.pytest_plugin.given_example import GivenReplay

        config.pluginmanager.register(GivenReplay(options.world), "ddenv-given-replay")


def pytest_report_header(config: pytest.Config) -> str | None:
    """One line to reproduce a session's reductions (as pytest-randomly prints its seed), when the plugin does
    something (reduction on, a world given) or with -v."""
    return header_line(config)


@pytest.hookimpl(tryfirst=True)
def pytest_pycollect_makeitem(collector: pytest.Module | pytest.Class, name: str, obj: object) -> list[Any] | None:
    return marks.misplaced_item(collector, name, obj)


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> Generator[None, pytest.CollectReport,
                                                                          pytest.CollectReport]:
    return marks.misplaced_report(collector, (yield))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Validate the markers of every collected robot test now, not in the middle of a run; with a test that
    asks for a failure rate (`--ddenv-rate`, `ddenv(rate=N)`), the plugin that runs it."""
    marks.check_markers(config, items)
    from pytest_ddenv.pytest_plugin.rate import RatePlugin, wants_rate
    from pytest_ddenv.pytest_plugin.worker import WORKER

    if not config.stash.get(WORKER, False) and not config.pluginmanager.has_plugin("ddenv-rate") \
            and wants_rate(config, items):
        capture = config.pluginmanager.getplugin("capturemanager")
        with capture.global_and_fixture_disabled() if capture is not None else contextlib.nullcontext():
            open_log(config)  # the progress lines' stream, past pytest's capture
        config.pluginmanager.register(RatePlugin(), "ddenv-rate")
        if not hasattr(config, "workerinput"):  # an xdist worker's reports go to its controller
            _register_rate_records(config)


def _xdist_controller(config: pytest.Config) -> bool:
    """A pytest-xdist session's controller (`-n N`): the records of its workers' tests arrive here."""
    return not hasattr(config, "workerinput") and getattr(config.option, "dist", "no") != "no"


def _register_rate_records(config: pytest.Config) -> None:
    """The hooks that write a failure-rate verdict's JUnit elements and terminal lines, once."""
    from pytest_ddenv.pytest_plugin.rate_records import RateRecords

    if not config.pluginmanager.has_plugin("ddenv-rate-records"):
        config.pluginmanager.register(RateRecords(config), "ddenv-rate-records")


def pytest_unconfigure(config: pytest.Config) -> None:
    from pytest_ddenv.pytest_plugin.pools import close_cluster

    close_log(config)
    close_cluster(config)


@pytest.fixture
def robot_world(request: pytest.FixtureRequest) -> RobotWorld:
    """The test's world, ready to run: `robot_world.run()` simulates its scenario and returns a `Run`.

    The world comes from `--ddenv-world`, else an indirect parameter (a path or a `World`), else
    `@pytest.mark.ddenv(world=...)`. In a reduction's probe worker it is the candidate world.
    """
    from pytest_ddenv.pytest_plugin.worker import PROBE_BINDING
    from pytest_ddenv.scenario.robot_world import DEFAULT_MAX_WALL_TIME, RobotWorld

    item = request.node
    spec, predicates = marks.spec_of(item)
    options = options_of(request.config)
    seed = spec.seed if options.seed is None else options.seed
    timeout = options.run_timeout or DEFAULT_MAX_WALL_TIME
    engine = options.engine or spec.engine  # also for the worlds a @given test draws (robot_world.rebound)
    binding = request.config.stash.get(PROBE_BINDING, None)
    if binding is not None:
        binding.robot_world = RobotWorld(binding.world, predicates=predicates, seed=seed, attempt=binding.attempt,
                                         max_wall_time=timeout, engine=binding.world.physics.engine)  # the probe's
        return binding.robot_world
    problem: str | None = None
    try:
        world = load_test_world(request, spec, predicates)
    except DdenvError as error:  # a broken world file or marker: one clear line at setup, no plugin traceback
        problem = error.shown_from(Path(request.config.invocation_params.dir))
    if problem is not None:
        from pytest_ddenv.driver.report_text import clip_lines

        pytest.fail(clip_lines(f"{item.nodeid}: {problem}"), pytrace=False)
    return RobotWorld(world, predicates=predicates, seed=seed, max_wall_time=timeout, engine=engine)


def header_line(config: pytest.Config) -> str | None:
    """"ddenv: reduction on, seed ..., workers ..., ..." (None: the plugin does nothing here and not -v; an
    xdist worker, whose controller prints the header)."""
    options = options_of(config)
    if hasattr(config, "workerinput") or not (options.reduce or options.world or config.get_verbosity() > 0):
        return None
    seed_text = "per marker (default 0)" if options.seed is None else str(options.seed)
    engine = f", engine {options.engine}" if options.engine else ""
    if not options.reduce:
        world = f", world {options.world}" if options.world else ""
        return f"ddenv: reduction off (--ddenv-reduce to reduce failing robot tests), seed {seed_text}{world}{engine}"
    workers = options.workers or "auto"
    if workers == "auto":
        workers = f"auto (the idle cores of {os.cpu_count() or 1})"
    return (f"ddenv: reduction on, seed {seed_text}, workers {workers}, executor {options.executor or 'local'}, "
            f"media {options.media}, artifacts {options.artifacts}{engine}")
