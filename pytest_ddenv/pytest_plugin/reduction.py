"""The hooks of a session that reduces its failing robot tests: a plugin object that `hooks.pytest_configure`
registers only under `--ddenv-reduce` (as pytest's stepwise and cacheprovider plugins are registered only when
their option is on), so that a project that does not reduce runs no wrapper of ours around its tests.

When a test that uses `robot_world` fails in its call phase, its world is reduced (`session.ReductionSession`
over a pool of probe workers, or this process with one worker) before the failure goes on; the reduction's
section, JUnit attachments, HTML extras and terminal line are added to the test's report.
"""

from __future__ import annotations

import base64
import contextlib
import dataclasses
import inspect
import shlex
import traceback
import warnings
from collections.abc import Callable, Generator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.errors import DdenvError, raised_by_ddenv
from pytest_ddenv.pytest_plugin.marks import spec_of
from pytest_ddenv.pytest_plugin.options import options_of
from pytest_ddenv.pytest_plugin.progress import PytestProgress, close_log, open_log
from pytest_ddenv.scenario.robot_world import FIXTURE

if TYPE_CHECKING:
    from pytest_ddenv.execution import Pool
    from pytest_ddenv.pytest_plugin.given_example import GivenExample
    from pytest_ddenv.scenario.probe import ProbeResult

REPORT_KEY = "ddenv"
SECTION = "ddenv reduction"
_result_key = pytest.StashKey[dict[str, Any]]()
_STATELESS_FIXTURES = {"request", "pytestconfig", "record_property", "record_xml_attribute", "tmp_path_factory"}


class ReductionPlugin:
    """`--ddenv-reduce`: reduce each failing robot test, and report it."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.cluster: Any = None
        """The cluster of `--ddenv-executor` (dask, a scheduler's address, ...), opened on the first failure."""
        open_log(config)

    @pytest.hookimpl(wrapper=True)
    def pytest_pyfunc_call(self, pyfuncitem: pytest.Function) -> Generator[None, object, object]:
        calls: list[dict[str, Any]] = []
        try:
            with _recording_given_calls(pyfuncitem) as calls:
                return (yield)
        except Exception as error:
            if _should_reduce(pyfuncitem, error):
                _reduce_failed_test(self, pyfuncitem, error, calls[-1] if calls else None)
            raise

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_makereport(self, item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, Any, Any]:
        return _with_result(item, call, (yield))

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> Generator[None, None, None]:
        yield
        _drop_attachment_lines(report)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        _terminal_summary(terminalreporter)

    def pytest_unconfigure(self, config: pytest.Config) -> None:
        close_log(config)
        if self.cluster is not None:
            self.cluster, cluster = None, self.cluster
            cluster.close()


def _recording_given_calls(item: pytest.Function) -> contextlib.AbstractContextManager[list[dict[str, Any]]]:
    """For a `@given` test that may be reduced: record its calls, to find the falsifying example."""
    from pytest_ddenv.pytest_plugin.given_example import inner_test, recording_calls

    if FIXTURE not in item.fixturenames or inner_test(item) is None:
        return contextlib.nullcontext([])
    return recording_calls(item)


def _should_reduce(item: pytest.Function, error: BaseException) -> bool:
    if item.config.getoption("usepdb", False):
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


def _probe_pool(plugin: ReductionPlugin, item: pytest.Function, example: GivenExample | None = None,
                warn: Callable[[str], None] | None = None) -> Pool[ProbeResult]:
    """A pool serving this test's probes: worker processes that run the test (or this process, with one
    worker), or the session's dask cluster."""
    from pytest_ddenv.execution import check_executor, make_cluster, make_pool
    from pytest_ddenv.pytest_plugin.worker import ItemHandler, PytestJob

    config = item.config
    default = "1" if hasattr(config, "workerinput") else "auto"  # xdist already uses every core
    options = options_of(config)
    workers = options.workers or default
    count = int(workers) if str(workers).isdigit() else workers
    executor = check_executor(options.executor)
    watchdog = options.watchdog
    if executor is None:
        return make_pool(PytestJob.of(item, example=example), count, in_process=ItemHandler(item, example),
                         watchdog=watchdog, warn=warn)
    if plugin.cluster is None:
        plugin.cluster = make_cluster(executor, count)
    return make_pool(PytestJob.of(item, capture="sys", example=example), count, executor, cluster=plugin.cluster,
                     watchdog=watchdog)


def _reduce_failed_test(plugin: ReductionPlugin, item: pytest.Function, error: BaseException,
                        given_call: dict[str, Any] | None) -> None:
    from pytest_ddenv.pytest_plugin.session import ReductionSession

    spec, _ = spec_of(item)
    options = options_of(item.config)
    spec = dataclasses.replace(
        spec,
        deflake=spec.deflake if options.deflake is None else options.deflake,
        max_probes=options.max_probes or spec.max_probes,
        max_seconds=options.max_seconds or spec.max_seconds,
        stages=options.stages_for(spec.stages),
        stage_probes=options.stage_probes,
        engine=options.engine or spec.engine,
        confirm_engines=spec.confirm_engines if options.confirm_engines is None else options.confirm_engines,
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
        with _probe_pool(plugin, item, session.example, lambda text: progress(text, final=True)) as pool:
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


def _with_result(item: pytest.Item, call: pytest.CallInfo[None], report: Any) -> Any:
    """The call's report with the reduction's result: its section, and its pictures as pytest-html extras."""
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


def _drop_attachment_lines(report: pytest.TestReport) -> None:
    """Once every plugin has had the call's report (JUnit XML writes its `[[ATTACHMENT|...]]` lines from it, or
    from the teardown's, which keeps them), the lines leave the sections pytest prints for a failed test,
    unless -v: a failing test shows the user's own output, and the reduction's section says where the files are."""
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


def _terminal_summary(terminalreporter: Any) -> None:
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
    """The command that re-runs the test on its minimal world (run from the rootdir), in the engine
    `--ddenv-engine` chose (over the marker's, as in the reduction)."""
    try:
        shown = minimal_yaml.relative_to(item.config.rootpath)
    except ValueError:
        shown = minimal_yaml
    engine = options_of(item.config).engine
    return (f"pytest {shlex.quote(item.nodeid)} --ddenv-world {shlex.quote(str(shown))}"
            + (f" --ddenv-engine {engine}" if engine else ""))
