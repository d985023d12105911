"""pytest glue: options, markers, the `robot_world` fixture and reduction of failing scenario tests.

Hooks stay thin; the work is done in plain modules (markers, robot_world, probe, reduce, artifacts).
A probe runs the whole test again on a candidate world, in a worker process that is a pytest session of its
own (see pytest_worker.py), or, with one worker, by calling the test function again in this process.
"""

from __future__ import annotations

import base64
import dataclasses
import inspect
import os
import shlex
import time
import traceback
import warnings
from collections.abc import Generator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.robot_world import FIXTURE
from pytest_ddenv.markers import (
    MarkerError,
    ReductionSpec,
    parse_deflake,
)

if TYPE_CHECKING:
    from pytest_ddenv.oracle import PredicateSpec
    from pytest_ddenv.robot_world import RobotWorld

REPORT_KEY = "ddenv"
SECTION = "ddenv reduction"
_spec_key = pytest.StashKey[tuple[ReductionSpec, "tuple[PredicateSpec, ...]"]]()
_result_key = pytest.StashKey[dict[str, Any]]()
_cluster_key = pytest.StashKey[Any]()
_STATELESS_FIXTURES = {"request", "pytestconfig", "record_property", "record_xml_attribute", "tmp_path_factory"}


# -- options and markers ---------------------------------------------------------------------------------


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("ddenv", "robot world reduction (pytest-ddenv)")
    options: list[tuple[str, str, dict[str, Any]]] = [
        ("reduce", "when a robot scenario test fails, reduce its world to the models the failure needs",
         {"action": "store_true", "ini_type": "bool"}),
        ("artifacts", "folder for minimal worlds, run logs and summaries (default: ddenv-artifacts)",
         {"metavar": "DIR", "ini_default": "ddenv-artifacts"}),
        ("deflake", "re-runs of a candidate that did not reproduce the failure: an integer, 'adaptive', or "
                    "'auto' (calibrated on the original world's failure rate)",
         {"metavar": "N"}),
        ("max-probes", "stop a reduction after this many simulations (best world so far is kept)", {"metavar": "N"}),
        ("max-time", "stop a reduction after this many wall-clock seconds", {"metavar": "SECONDS"}),
        ("seed", "base seed of every robot run (default: the marker's seed, else 0)", {"metavar": "N"}),
        ("workers", "simulation worker processes: a number, 'auto' for one per core (the default), or 1 to "
         "simulate in the pytest process", {"metavar": "N"}),
        ("executor", "where probes simulate: 'local' worker processes (default), 'dask' (a local dask cluster) "
         "or tcp://HOST:PORT of a dask scheduler", {"metavar": "ADDRESS"}),
        ("world", "run every robot test against this world file instead of its own (e.g. a minimal.yaml)",
         {"metavar": "PATH"}),
        ("model-path", "extra folders (separated by ':') searched for SDF <include>s of model://NAME",
         {"metavar": "DIRS"}),
        ("run-timeout", "wall-clock seconds one robot_world.run() may take before it fails with ControllerTimeout "
                        "(default 300): bounds a controller that is too slow", {"metavar": "SECONDS"}),
    ]
    for name, help_text, extra in options:
        ini_name = f"ddenv_{name.replace('-', '_')}"
        ini_type = extra.pop("ini_type", "string")
        ini_default = extra.pop("ini_default", None)
        group.addoption(f"--ddenv-{name}", dest=ini_name, default=None, help=help_text, **extra)
        parser.addini(ini_name, help_text, type=ini_type, default=ini_default if ini_type != "bool" else False)


def _setting(config: pytest.Config, name: str) -> Any:
    value = config.getoption(name)
    return config.getini(name) if value in (None, False) else value


def _int_setting(config: pytest.Config, name: str, minimum: int) -> int | None:
    value = _setting(config, name)
    if value in (None, ""):
        return None
    try:
        number = int(value)
    except (TypeError, ValueError):
        number = minimum - 1
    if number < minimum:
        flag = "--" + name.replace("_", "-")
        raise pytest.UsageError(f"{flag}: expected an integer >= {minimum}, got {value!r}")
    return number


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "ddenv(world=PATH, partition=..., priority=..., n_partitions=2, granularity='ddmin', deflake='auto', "
        "tolerance=0.5, keep=(...), seed=0, budget=N, skip_unsupported=False): the world of a robot scenario test "
        "and how to reduce it when the test fails under --ddenv-reduce.",
    )
    config.addinivalue_line(
        "markers",
        "robot_failure(NAME, **params): a failure predicate checked while the robot runs "
        "(stuck, flipped, high_centered, fell, collided, timeout); stackable.",
    )
    _validate_options(config)


def _seconds_setting(config: pytest.Config, name: str) -> float | None:
    value = _setting(config, name)
    if value in (None, ""):
        return None
    try:
        seconds = float(value)
    except ValueError:
        seconds = -1.0
    if not (seconds > 0 and seconds != float("inf")):
        flag = "--" + name.replace("_", "-")
        raise pytest.UsageError(f"{flag}: expected a positive number of seconds, got {value!r}")
    return seconds


def _validate_options(config: pytest.Config) -> None:
    _int_setting(config, "ddenv_max_probes", 1)
    _int_setting(config, "ddenv_seed", 0)
    _seconds_setting(config, "ddenv_max_time")
    _seconds_setting(config, "ddenv_run_timeout")
    deflake = _setting(config, "ddenv_deflake")
    if deflake not in (None, ""):
        try:
            parse_deflake(deflake, "--ddenv-deflake")
        except MarkerError as error:
            raise pytest.UsageError(str(error)) from None
    workers = _setting(config, "ddenv_workers")
    if workers not in (None, "", "auto"):
        _int_setting(config, "ddenv_workers", 1)
    executor = _setting(config, "ddenv_executor")
    if executor not in (None, "", "local", "dask") and not str(executor).startswith(("tcp://", "tls://")):
        raise pytest.UsageError(
            f"--ddenv-executor: expected 'local', 'dask' or a dask scheduler address such as "
            f"tcp://scheduler:8786, got {executor!r}"
        )
    world = _setting(config, "ddenv_world")
    if world not in (None, "") and not Path(world).is_file():
        raise pytest.UsageError(f"--ddenv-world: no such file: {world}")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Validate the markers of every collected robot test now, not in the middle of a run."""
    from pytest_ddenv.markers import parse_ddenv_marker, parse_failure_markers

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


def _world_path(item: pytest.Item, raw: str | Path) -> Path:
    """A world path as given: absolute, else relative to the test file, else to the rootdir."""
    path = Path(raw).expanduser()
    if path.is_absolute():
        return path
    candidates = [Path(str(item.path)).parent / path, Path(str(item.config.rootpath)) / path]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise DdenvError(f"world file not found: {raw} (looked in {', '.join(str(c.parent) for c in candidates)})")


@pytest.fixture
def robot_world(request: pytest.FixtureRequest) -> RobotWorld:
    """The test's world, ready to run: `robot_world.run()` simulates its scenario and returns a `Run`.

    The world comes from `--ddenv-world`, else an indirect parameter (a path or a `World`), else
    `@pytest.mark.ddenv(world=...)`. In a reduction's probe worker it is the candidate world.
    """
    from pytest_ddenv.pytest_worker import PROBE_BINDING
    from pytest_ddenv.robot_world import DEFAULT_MAX_WALL_TIME, RobotWorld
    from pytest_ddenv.world import World

    item = request.node
    spec, predicates = item.stash.get(_spec_key, (ReductionSpec(), ()))
    seed = _int_setting(request.config, "ddenv_seed", 0)
    timeout = _seconds_setting(request.config, "ddenv_run_timeout") or DEFAULT_MAX_WALL_TIME
    binding = request.config.stash.get(PROBE_BINDING, None)
    if binding is not None:
        binding.robot_world = RobotWorld(binding.world, predicates=predicates, seed=spec.seed if seed is None else seed,
                                         attempt=binding.attempt, max_wall_time=timeout)
        return binding.robot_world
    model_paths = [p for p in str(_setting(request.config, "ddenv_model_path") or "").split(os.pathsep) if p]
    options = {"model_paths": model_paths, "skip_unsupported": spec.skip_unsupported}
    override = _setting(request.config, "ddenv_world")
    param = getattr(request, "param", None)
    if override:
        world = World.load(override, **options)
    elif isinstance(param, World):
        world = param
    elif param is not None:
        world = World.load(_world_path(item, param), **options)
    elif spec.world is not None:
        world = World.load(_world_path(item, spec.world), **options)
    else:
        raise DdenvError(
            f"{item.nodeid}: robot_world needs a world: @pytest.mark.ddenv(world='worlds/x.yaml'), "
            "an indirect parameter, or --ddenv-world PATH"
        )
    unknown = sorted(set(spec.keep) - set(world.names))
    if unknown:
        raise DdenvError(
            f"{item.nodeid}: ddenv(keep=...) names model(s) not in {world.source or world.name}: "
            f"{', '.join(unknown)}"
        )
    return RobotWorld(world, predicates=predicates, seed=spec.seed if seed is None else seed, max_wall_time=timeout)


# -- reduction on failure ----------------------------------------------------------------------------------


@pytest.hookimpl(wrapper=True)
def pytest_pyfunc_call(pyfuncitem: pytest.Function) -> Generator[None, object, object]:
    from pytest_ddenv.pytest_worker import WORKER

    if pyfuncitem.config.stash.get(WORKER, False):
        _bind_probe(pyfuncitem)
        return (yield)
    try:
        return (yield)
    except Exception as error:
        if _should_reduce(pyfuncitem, error):
            _reduce_failed_test(pyfuncitem, error)
        raise


def _bind_probe(item: pytest.Function) -> None:
    """In a probe worker: make sure the test gets the candidate world, even from an overridden fixture."""
    from pytest_ddenv.pytest_worker import PROBE_BINDING
    from pytest_ddenv.robot_world import RobotWorld

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
    if not _setting(config, "ddenv_reduce") or config.getoption("usepdb", False):
        return False
    if FIXTURE not in item.fixturenames or item.get_closest_marker("xfail") is not None:
        return False
    if isinstance(error, pytest.skip.Exception) or isinstance(error, DdenvError):
        return False  # a broken setup (bad world file, bad scenario) is not a failure to reduce
    from pytest_ddenv.robot_world import RobotWorld

    return isinstance(item.funcargs.get(FIXTURE), RobotWorld)


def _probe_pool(item: pytest.Function) -> Any:
    """A pool serving this test's probes: worker processes that run the test (or this process, with one
    worker), or the session's dask cluster."""
    from pytest_ddenv.execution import DaskCluster, check_executor, make_pool
    from pytest_ddenv.pytest_worker import ItemHandler, PytestJob

    config = item.config
    default = "1" if hasattr(config, "workerinput") else "auto"  # xdist already uses every core
    workers = _setting(config, "ddenv_workers") or default
    count = int(workers) if str(workers).isdigit() else workers
    executor = check_executor(_setting(config, "ddenv_executor") or None)
    if executor is None:
        return make_pool(PytestJob.of(item), count, in_process=ItemHandler(item))
    cluster = config.stash.get(_cluster_key, None)
    if cluster is None:
        cluster = DaskCluster(None if executor == "dask" else executor,
                              n_workers=None if count == "auto" else int(count))
        config.stash[_cluster_key] = cluster
    return make_pool(PytestJob.of(item, capture="sys"), count, executor, cluster=cluster)


def pytest_unconfigure(config: pytest.Config) -> None:
    cluster = config.stash.get(_cluster_key, None)
    if cluster is not None:
        cluster.close()
        del config.stash[_cluster_key]


def _reduce_failed_test(item: pytest.Function, error: BaseException) -> None:
    from pytest_ddenv.reduction_session import ReductionSession

    spec, _ = item.stash.get(_spec_key, (ReductionSpec(), ()))
    deflake = _setting(item.config, "ddenv_deflake")
    spec = dataclasses.replace(
        spec,
        deflake=spec.deflake if deflake in (None, "") else parse_deflake(deflake, "--ddenv-deflake"),
        max_probes=_int_setting(item.config, "ddenv_max_probes", 1) or spec.max_probes,
        max_seconds=_seconds_setting(item.config, "ddenv_max_time") or spec.max_seconds,
    )
    session = ReductionSession(
        item=item,
        error=error,
        spec=spec,
        artifacts_root=Path(str(item.config.rootpath)) / str(_setting(item.config, "ddenv_artifacts")),
        progress=_ProgressLine(item.config),
        replay=replay_command,
        model_paths=tuple(p for p in str(_setting(item.config, "ddenv_model_path") or "").split(os.pathsep) if p),
    )
    try:
        with _probe_pool(item) as pool:
            if getattr(pool, "in_process", False):
                _warn_about_shared_fixtures(item)
            result = session.run(pool)
    except KeyboardInterrupt:
        raise
    except Exception as crash:  # noqa: BLE001 - the test's own failure must stay what the user sees
        detail = "".join(traceback.format_exception(crash))
        result = {
            "text": f"the reduction itself crashed; the test's failure above is unchanged.\n{detail}",
            "line": f"{item.nodeid}: reduction crashed: {type(crash).__name__}: {crash}",
            "attachments": [],
        }
    item.stash[_result_key] = result
    attachments = "".join(f"[[ATTACHMENT|{path}]]\n" for path in result.get("attachments", []))
    if attachments:  # a stdout section reaches JUnit's <system-out> (with junit_logging = system-out)
        item.add_report_section("call", "stdout", attachments)


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


class _ProgressLine:
    """One updating terminal line while reducing (a line per probe with -v); silent when not a terminal."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.reporter = config.pluginmanager.getplugin("terminalreporter")
        self.capture = config.pluginmanager.getplugin("capturemanager")
        self.verbose = config.get_verbosity() > 0
        self.started = time.monotonic()

    def __call__(self, text: str, *, final: bool = False, probe_line: str | None = None) -> None:
        if self.reporter is None or hasattr(self.config, "workerinput"):
            return
        elapsed = time.monotonic() - self.started
        line = f"ddenv: {text}" if final else f"ddenv: {text}, {elapsed:.0f} s"
        suspend = self.capture.global_and_fixture_disabled() if self.capture is not None else _nullcontext()
        with suspend:
            if self.verbose and probe_line:
                self.reporter.write_line(f"    {probe_line}")
            elif final or self.reporter.isatty:
                self.reporter.rewrite(line, erase=True) if not final else self.reporter.write_line(line)


class _nullcontext:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None


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
        for path in attachments:
            if path.endswith(".png"):  # embedded, so the picture survives --self-contained-html and moves
                content = base64.b64encode(Path(path).read_bytes()).decode("ascii")
                extras.append(html.extras.png(content, name=Path(path).name))
            else:
                extras.append(html.extras.url(path, name=Path(path).name))
        report.extras = extras
    return report


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
