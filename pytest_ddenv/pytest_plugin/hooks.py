"""pytest glue: options, markers, the `robot_world` fixture and reduction of failing scenario tests.

Hooks stay thin; the work is done in plain modules (markers, robot_world, probe, reduce, artifacts).
A probe runs the whole test again on a candidate world, in a worker process that is a pytest session of its
own (see worker.py), or, with one worker, by calling the test function again in this process.
"""

from __future__ import annotations

import base64
import contextlib
import dataclasses
import inspect
import os
import shlex
import traceback
import warnings
from collections.abc import Callable, Generator
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.errors import DdenvError, raised_by_ddenv, shown
from pytest_ddenv.pytest_plugin.options import DdenvOptions, add_options, read_options
from pytest_ddenv.pytest_plugin.progress import PytestProgress, close_log, open_log
from pytest_ddenv.scenario.robot_world import FIXTURE
from pytest_ddenv.validation import expected
from pytest_ddenv.world.files import is_file, regular_file_problem

if TYPE_CHECKING:
    from pytest_ddenv.oracle.predicates import PredicateSpec
    from pytest_ddenv.pytest_plugin.given_example import GivenExample
    from pytest_ddenv.scenario.robot_world import RobotWorld
    from pytest_ddenv.world.model import World

REPORT_KEY = "ddenv"
SECTION = "ddenv reduction"
_spec_key = pytest.StashKey[tuple[ReductionSpec, "tuple[PredicateSpec, ...]"]]()
_result_key = pytest.StashKey[dict[str, Any]]()
_cluster_key = pytest.StashKey[Any]()
_options_key = pytest.StashKey[DdenvOptions]()
_misplaced_key = pytest.StashKey[dict[tuple[str, str], str]]()
"""Usage errors for predicates given alone to robot_failure(...), by (module node id, predicate name)."""
_STATELESS_FIXTURES = {"request", "pytestconfig", "record_property", "record_xml_attribute", "tmp_path_factory"}


# -- options and markers ---------------------------------------------------------------------------------


def pytest_addoption(parser: pytest.Parser) -> None:
    add_options(parser)


def _options(config: pytest.Config) -> DdenvOptions:
    """The session's checked settings (read once, in `pytest_configure`)."""
    options = config.stash.get(_options_key, None)
    if options is None:  # a config that did not go through pytest_configure (unusual): read them now
        options = config.stash[_options_key] = read_options(config)
    return options


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "ddenv(world=PATH, partition=..., priority=..., n_partitions=2, granularity='ddmin', deflake='auto', "
        "tolerance=0.5, same_failure='all'|'place'|'touched'|function, keep=(...), seed=0, budget=N, "
        "skip_unsupported=False, stages='models,explain,passing'): "
        "the world of a robot scenario test and how to reduce it when the test fails under --ddenv-reduce.",
    )
    config.addinivalue_line(
        "markers",
        "robot_failure(NAME, **params, same_failure=...): a failure predicate checked while the robot runs "
        "(stuck, flipped, high_centered, fell, collided, timeout); stackable.",
    )
    options = config.stash[_options_key] = read_options(config)
    if options.reduce:
        open_log(config)
    from pytest_ddenv.pytest_plugin.worker import WORKER

    if options.world and not config.stash.get(WORKER, False):  # a @given test runs once on that world (replay)
        from pytest_ddenv.pytest_plugin.given_example import GivenReplay

        config.pluginmanager.register(GivenReplay(options.world), "ddenv-given-replay")


def pytest_report_header(config: pytest.Config) -> str | None:
    """One line to reproduce a session's reductions (as pytest-randomly prints its seed): whether reduction
    is on, the seed, the workers, the executor, the media and the artifacts folder."""
    if hasattr(config, "workerinput"):  # an xdist worker: the controller prints the header
        return None
    options = _options(config)
    seed_text = "per marker (default 0)" if options.seed is None else str(options.seed)
    if not options.reduce:
        return f"ddenv: reduction off (--ddenv-reduce to reduce failing robot tests), seed {seed_text}"
    workers = options.workers or "auto"
    if workers == "auto":
        workers = f"auto ({os.cpu_count() or 1} cores)"
    return (f"ddenv: reduction on, seed {seed_text}, workers {workers}, executor {options.executor or 'local'}, "
            f"media {options.media}, artifacts {options.artifacts}")


@pytest.hookimpl(tryfirst=True)
def pytest_pycollect_makeitem(collector: pytest.Module | pytest.Class, name: str, obj: object) -> list[Any] | None:
    """A predicate class or function given alone to `robot_failure(...)` was marked instead of the test (and
    the test lost): remember the usage error, raised once collection is over."""
    from pytest_ddenv.driver.markers import marked_predicate

    holder = marked_predicate(obj)
    if holder is None or (inspect.isfunction(obj) and collector.funcnamefilter(name) and obj.__name__ == name):
        return None  # nothing marked by mistake, or a test marked with a bare robot_failure (checked later)
    test = name if collector.funcnamefilter(name) and name != getattr(holder, "__name__", name) else None
    _record_misplaced(collector, holder, test)
    return []


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> Generator[None, pytest.CollectReport,
                                                                          pytest.CollectReport]:
    """A test module that failed to import because a predicate given alone to `robot_failure(...)` was called
    with the test as its state: the usage error instead of the predicate's traceback."""
    report = yield
    excinfo = getattr(getattr(report, "call", None), "excinfo", None)
    if report.failed and isinstance(collector, pytest.Module) and excinfo is not None:
        found = _predicate_called_as_decorator(excinfo.value.__traceback__)
        if found is not None:
            holder, line = found
            report.longrepr = _record_misplaced(collector, holder, None, line)
    return report


def _predicate_called_as_decorator(trace: TracebackType | None) -> tuple[object, int] | None:
    """The predicate marked by mistake that the failed import of a test module ran into, and the module's line."""
    from pytest_ddenv.driver.markers import marked_predicate

    while trace is not None:
        frame = trace.tb_frame
        if frame.f_code.co_name == "<module>":
            called = trace.tb_next.tb_frame if trace.tb_next is not None else None
            places = [frame.f_globals] + ([called.f_globals] if called is not None else [])
            for holder in (value for place in places for value in list(place.values())):
                if holder is not None and marked_predicate(holder) is holder:
                    return holder, trace.tb_lineno
        trace = trace.tb_next
    return None


def _record_misplaced(collector: pytest.Collector, holder: object, test: str | None, line: int | None = None) -> str:
    """The usage error for `holder` given alone to robot_failure(...) in `collector`'s module, naming the test
    (`test`, else the function defined after `line`, else the one the module's source marks with it)."""
    from pytest_ddenv.driver.markers import defined_after, find_marked_test, misplaced_predicate_message

    name = str(getattr(holder, "__name__", holder))
    lines = _source_lines(collector.path)
    if test is None and line is not None:
        test = defined_after(lines, line)
    if test is None:
        found = find_marked_test(lines, name)
        test = found[0] if found else None
    module = collector.nodeid.split("::")[0]
    text = f"{module}::{test if test else '(a test)'}: {misplaced_predicate_message(holder)}"
    known = collector.config.stash.setdefault(_misplaced_key, {})
    if (module, name) not in known or test:
        known[(module, name)] = text
    return known[(module, name)]


def _source_lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return []


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Validate the markers of every collected robot test now, not in the middle of a run."""
    from pytest_ddenv.driver.markers import parse_ddenv_marker, parse_failure_markers

    misplaced = config.stash.get(_misplaced_key, {})
    if misplaced:
        raise pytest.UsageError(*misplaced.values())
    for item in items:
        ddenv_marker = item.get_closest_marker("ddenv")
        failure_markers = list(item.iter_markers("robot_failure"))
        if ddenv_marker is None and not failure_markers:
            continue
        try:
            spec = parse_ddenv_marker(ddenv_marker.args, ddenv_marker.kwargs) if ddenv_marker else ReductionSpec()
            predicates = parse_failure_markers([(m.args, m.kwargs) for m in reversed(failure_markers)])
        except DdenvError as error:
            raise pytest.UsageError(f"{item.nodeid}: {error}") from None
        item.stash[_spec_key] = (spec, predicates)


# -- the fixture -------------------------------------------------------------------------------------------


def _world_path(item: pytest.Item, raw: str | os.PathLike[str]) -> Path:
    """A world path as given: absolute, else relative to the test file, else to the rootdir."""
    from pytest_ddenv.pytest_plugin.options import expand_home

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


@pytest.fixture
def robot_world(request: pytest.FixtureRequest) -> RobotWorld:
    """The test's world, ready to run: `robot_world.run()` simulates its scenario and returns a `Run`.

    The world comes from `--ddenv-world`, else an indirect parameter (a path or a `World`), else
    `@pytest.mark.ddenv(world=...)`. In a reduction's probe worker it is the candidate world.
    """
    from pytest_ddenv.pytest_plugin.worker import PROBE_BINDING
    from pytest_ddenv.scenario.robot_world import DEFAULT_MAX_WALL_TIME, RobotWorld

    item = request.node
    spec, predicates = item.stash.get(_spec_key, (ReductionSpec(), ()))
    options = _options(request.config)
    seed = options.seed
    timeout = options.run_timeout or DEFAULT_MAX_WALL_TIME
    binding = request.config.stash.get(PROBE_BINDING, None)
    if binding is not None:
        binding.robot_world = RobotWorld(binding.world, predicates=predicates, seed=spec.seed if seed is None else seed,
                                         attempt=binding.attempt, max_wall_time=timeout)
        return binding.robot_world
    problem: str | None = None
    try:
        world = _test_world(request, spec, predicates)
    except DdenvError as error:  # a broken world file or marker: one clear line at setup, no plugin traceback
        problem = error.shown_from(Path(request.config.invocation_params.dir))
    if problem is not None:
        from pytest_ddenv.driver.report_text import clip_lines

        pytest.fail(clip_lines(f"{item.nodeid}: {problem}"), pytrace=False)
    return RobotWorld(world, predicates=predicates, seed=spec.seed if seed is None else seed, max_wall_time=timeout)


def _test_world(request: pytest.FixtureRequest, spec: ReductionSpec, predicates: tuple[PredicateSpec, ...]) -> World:
    """The world a test runs in, checked against its markers (DdenvError naming the file and field)."""
    from pytest_ddenv.oracle.predicates import check_predicate_models
    from pytest_ddenv.pytest_plugin.given_example import inner_test
    from pytest_ddenv.scenario.robot_world import NO_WORLD_YET
    from pytest_ddenv.world.model import World

    item = request.node
    options: dict[str, Any] = {"model_paths": list(_options(request.config).model_paths),
                               "skip_unsupported": spec.skip_unsupported}
    override = _options(request.config).world
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
        from pytest_ddenv.sim.robot import check_robot

        check_robot(world.scenario.robot, world.source)
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


# -- reduction on failure ----------------------------------------------------------------------------------


@pytest.hookimpl(wrapper=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> Generator[None, object, object]:
    from pytest_ddenv.pytest_plugin.worker import WORKER

    if pyfuncitem.config.stash.get(WORKER, False):
        _bind_probe(pyfuncitem)
        return (yield)
    calls: list[dict[str, Any]] = []
    try:
        with _recording_given_calls(pyfuncitem) as calls:
            return (yield)
    except Exception as error:
        if _should_reduce(pyfuncitem, error):
            _reduce_failed_test(pyfuncitem, error, calls[-1] if calls else None)
        raise


def _recording_given_calls(item: pytest.Function) -> contextlib.AbstractContextManager[list[dict[str, Any]]]:
    """For a `@given` test that may be reduced: record its calls, to find the falsifying example."""
    from pytest_ddenv.pytest_plugin.given_example import inner_test, recording_calls

    if not _options(item.config).reduce or FIXTURE not in item.fixturenames or inner_test(item) is None:
        return contextlib.nullcontext([])
    return recording_calls(item)


def _bind_probe(item: pytest.Function) -> None:
    """In a probe worker: make sure the test gets the candidate world, even from an overridden fixture."""
    from pytest_ddenv.pytest_plugin.worker import PROBE_BINDING
    from pytest_ddenv.scenario.robot_world import RobotWorld

    binding = item.config.stash.get(PROBE_BINDING, None)
    given = item.funcargs.get(FIXTURE)
    if binding is None or not isinstance(given, RobotWorld):
        return
    if given.world is not binding.world or given.attempt != binding.attempt:
        given = given.rebound(binding.world, attempt=binding.attempt)
        item.funcargs[FIXTURE] = given
    binding.robot_world = given


def _should_reduce(item: pytest.Function, error: BaseException) -> bool:
    config = item.config
    if not _options(config).reduce or config.getoption("usepdb", False):
        return False
    if FIXTURE not in item.fixturenames or item.get_closest_marker("xfail") is not None:
        return False
    if isinstance(error, pytest.skip.Exception) or raised_by_ddenv(error):
        return False  # a broken setup (bad world file, bad scenario) is not a failure to reduce
    from pytest_ddenv.scenario.robot_world import RobotWorld

    return isinstance(item.funcargs.get(FIXTURE), RobotWorld)


def _given_example(item: pytest.Function, call: dict[str, Any] | None) -> GivenExample | None:
    """The falsifying example of a `@given` test (None for a plain test); DdenvError if it cannot be
    re-run in a probe."""
    from pytest_ddenv.pytest_plugin.given_example import GivenExample

    if call is None:
        return None
    robot_world = item.funcargs[FIXTURE]
    fixtures = {name: value for name, value in item.funcargs.items() if name in call and call[name] is value}
    return GivenExample.of(call, robot_world.latest.world, fixtures)  # type: ignore[attr-defined]


def _probe_pool(item: pytest.Function, example: GivenExample | None = None,
                warn: Callable[[str], None] | None = None) -> Any:
    """A pool serving this test's probes: worker processes that run the test (or this process, with one
    worker), or the session's dask cluster."""
    from pytest_ddenv.execution import DaskCluster, check_executor, make_pool
    from pytest_ddenv.pytest_plugin.worker import ItemHandler, PytestJob

    config = item.config
    default = "1" if hasattr(config, "workerinput") else "auto"  # xdist already uses every core
    options = _options(config)
    workers = options.workers or default
    count = int(workers) if str(workers).isdigit() else workers
    executor = check_executor(options.executor)
    watchdog = options.watchdog
    if executor is None:
        return make_pool(PytestJob.of(item, example=example), count, in_process=ItemHandler(item, example),
                         watchdog=watchdog, warn=warn)
    cluster = config.stash.get(_cluster_key, None)
    if cluster is None:
        cluster = DaskCluster(None if executor == "dask" else executor,
                              n_workers=None if count == "auto" else int(count))
        config.stash[_cluster_key] = cluster
    return make_pool(PytestJob.of(item, capture="sys", example=example), count, executor, cluster=cluster,
                     watchdog=watchdog)


def pytest_unconfigure(config: pytest.Config) -> None:
    close_log(config)
    cluster = config.stash.get(_cluster_key, None)
    if cluster is not None:
        cluster.close()
        del config.stash[_cluster_key]


def _reduce_failed_test(item: pytest.Function, error: BaseException, given_call: dict[str, Any] | None) -> None:
    from pytest_ddenv.pytest_plugin.session import ReductionSession

    spec, _ = item.stash.get(_spec_key, (ReductionSpec(), ()))
    options = _options(item.config)
    spec = dataclasses.replace(
        spec,
        deflake=spec.deflake if options.deflake is None else options.deflake,
        max_probes=options.max_probes or spec.max_probes,
        max_seconds=options.max_seconds or spec.max_seconds,
        stages=options.stages_for(spec.stages),
        stage_probes=options.stage_probes,
    )
    progress = PytestProgress(item.config, item.nodeid)
    session = ReductionSession(
        item=item,
        error=error,
        spec=spec,
        artifacts_root=options.artifacts,
        progress=progress,
        replay=replay_command,
        model_paths=options.model_paths,
        media=options.media,
        keep_other=options.keep_other,
        seconds=progress.seconds,
        verbose=item.config.get_verbosity() > 0,
    )
    try:
        session.example = _given_example(item, given_call)
        with _probe_pool(item, session.example, lambda text: progress(text, final=True)) as pool:
            if pool.in_process:
                _warn_about_shared_fixtures(item)
            result = session.run(pool)
    except KeyboardInterrupt:
        raise
    except DdenvError as error:  # the pool could not start (a dask scheduler that does not answer, ...)
        from pytest_ddenv.driver.report_text import clip_lines

        problem = clip_lines(str(error))
        result = {
            "text": f"no reduction: {problem}\nThe test's failure above is unchanged.\n",
            "line": f"{item.nodeid}: no reduction: {problem}",
            "attachments": [],
        }
        progress(result["line"], final=True)
    except Exception as crash:  # noqa: BLE001 - the test's own failure must stay what the user sees
        detail = "".join(traceback.format_exception(crash))
        result = {
            "text": f"the reduction itself crashed; the test's failure above is unchanged.\n{detail}",
            "line": f"{item.nodeid}: reduction crashed: {type(crash).__name__}: {crash}",
            "attachments": [],
        }
        progress(result["line"], final=True)
    finally:
        progress.close()
    result["attachments_shown"] = item.config.get_verbosity() > 0
    item.stash[_result_key] = result
    attachments = _attachment_lines(result)
    if attachments:  # a stdout section: JUnit's <system-out> (junit_logging = system-out); not the terminal's
        item.add_report_section("call", "stdout", attachments)


def _attachment_lines(result: dict[str, Any]) -> str:
    """The JUnit attachments of a reduction's files, one `[[ATTACHMENT|path]]` line each (GitLab, Jenkins)."""
    return "".join(f"[[ATTACHMENT|{path}]]\n" for path in result.get("attachments", []))


def _warn_about_shared_fixtures(item: pytest.Function) -> None:
    parameters = set(inspect.signature(item.obj).parameters)
    fixture_info = getattr(item, "_fixtureinfo", None)
    definitions = getattr(fixture_info, "name2fixturedefs", {}) or {}
    shared = sorted(
        name
        for name in parameters & set(item.funcargs)
        if name != FIXTURE and name not in _STATELESS_FIXTURES
        and all(getattr(d, "scope", "function") == "function" for d in definitions.get(name, ()))
    )
    if shared:
        warnings.warn(
            pytest.PytestWarning(
                f"{item.nodeid}: function-scoped fixture(s) {', '.join(shared)} are not re-created for each "
                "reduction probe with one worker (in this process); every probe reuses their values from the "
                "failing run. With --ddenv-workers 2 or more each probe runs the whole test in a worker."
            ),
            stacklevel=1,
        )


# -- reports -----------------------------------------------------------------------------------------------


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, Any, Any]:
    report = yield
    result = item.stash.get(_result_key, None)
    if call.when != "call" or result is None:
        return report
    setattr(report, REPORT_KEY, result)  # a plain dict: travels with xdist
    report.sections.append((SECTION, result["text"]))
    attachments = result.get("attachments", [])
    html = item.config.pluginmanager.getplugin("html")
    if html is not None and hasattr(html, "extras"):
        extras = list(getattr(report, "extras", []))
        for path in sorted(attachments, key=_html_order):  # the report shows the first image: the animation
            if path.endswith((".png", ".gif")):  # embedded: survives --self-contained-html and moves
                content = base64.b64encode(Path(path).read_bytes()).decode("ascii")
                kind = Path(path).suffix[1:]
                extras.append(html.extras.image(content, name=Path(path).name, mime_type=f"image/{kind}",
                                                extension=kind))
            else:
                extras.append(html.extras.url(path, name=Path(path).name))
        report.extras = extras
    return report


@pytest.hookimpl(wrapper=True)
def pytest_runtest_logreport(report: pytest.TestReport) -> Generator[None, None, None]:
    """Once every plugin has had the call's report (JUnit XML writes its `[[ATTACHMENT|...]]` lines from it, or
    from the teardown's, which keeps them), the lines leave the sections pytest prints for a failed test,
    unless -v: a failing test shows the user's own output, and the reduction's section says where the files are."""
    yield
    result = getattr(report, REPORT_KEY, None)
    if report.when != "call" or not isinstance(result, dict) or result.get("attachments_shown", True):
        return
    lines = ("Captured stdout call", _attachment_lines(result))
    report.sections = [section for section in report.sections if section != lines]


_HTML_FIRST = ("minimal.gif", "original.gif")


def _html_order(path: str) -> int:
    """Where a file goes among the HTML report's extras: the animations first (pytest-html shows images one
    at a time, the first one open), then the rest in their own order."""
    name = Path(path).name
    return _HTML_FIRST.index(name) if name in _HTML_FIRST else len(_HTML_FIRST)


def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    lines = []
    for reports in terminalreporter.stats.values():
        for report in reports:
            result = getattr(report, REPORT_KEY, None)
            if isinstance(result, dict) and getattr(report, "when", None) == "call":
                lines.append(result["line"])
    if lines:
        terminalreporter.section("ddenv reductions")
        for line in lines:
            terminalreporter.write_line(line)


def replay_command(item: pytest.Item, minimal_yaml: Path) -> str:
    """The command that re-runs the test on its minimal world (run from the rootdir)."""
    try:
        shown = minimal_yaml.relative_to(item.config.rootpath)
    except ValueError:
        shown = minimal_yaml
    return f"pytest {shlex.quote(item.nodeid)} --ddenv-world {shlex.quote(str(shown))}"
