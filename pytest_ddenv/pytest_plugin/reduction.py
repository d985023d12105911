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
import functools
import shlex
import time
import traceback
from collections.abc import Generator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.errors import DdenvError, raised_by_ddenv
from pytest_ddenv.pytest_plugin.marks import spec_of
from pytest_ddenv.pytest_plugin.options import options_of
from pytest_ddenv.pytest_plugin.progress import PytestProgress, open_log
from pytest_ddenv.scenario.robot_world import FIXTURE

if TYPE_CHECKING:
    from pytest_ddenv.driver.run import LaterMedia
    from pytest_ddenv.pytest_plugin.given_example import GivenExample

REPORT_KEY = "ddenv"
SECTION = "ddenv reduction"
_result_key = pytest.StashKey[dict[str, Any]]()
_media_key = pytest.StashKey["LaterMedia"]()
"""A reduced test's animations and recordings, rendering in the background (`LaterMedia`)."""


class ReductionPlugin:
    """`--ddenv-reduce`: reduce each failing robot test, and report it."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.media: list[LaterMedia] = []
        """The reductions' animations and recordings rendering in the background: the session waits for them."""
        self.warmed = False
        open_log(config)

    @pytest.hookimpl(wrapper=True)
    def pytest_pyfunc_call(self, pyfuncitem: pytest.Function) -> Generator[None, object, object]:
        __tracebackhide__ = True  # the failure's traceback is the test's, not this wrapper's
        calls: list[dict[str, Any]] = []
        if not self.warmed and FIXTURE in pyfuncitem.fixturenames:
            self.warmed = True
            _warm_up(pyfuncitem.config)
        started = time.perf_counter()
        try:
            with _recording_given_calls(pyfuncitem) as calls:
                outcome = yield
        except Exception as error:
            if _should_reduce(pyfuncitem, error):
                test_run = time.perf_counter() - started
                media = _reduce_failed_test(pyfuncitem, error, calls[-1] if calls else None, test_run)
                if media is not None:
                    self.media.append(media)
            raise
        if FIXTURE in pyfuncitem.fixturenames:
            _note_earlier_reductions(pyfuncitem)
        return outcome

    def pytest_sessionfinish(self, session: pytest.Session, exitstatus: int) -> None:
        """Wait for the animations and recordings still rendering (Ctrl-C: stop them)."""
        interrupted = exitstatus == pytest.ExitCode.INTERRUPTED
        while self.media:
            media = self.media.pop(0)
            if interrupted:
                media.media.cancel()
            else:
                media.finish()

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_makereport(self, item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, Any, Any]:
        return _with_result(item, call, (yield))

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> Generator[None, None, None]:
        yield
        _drop_attachment_lines(report)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        _terminal_summary(terminalreporter)



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


def _warm_up(config: pytest.Config) -> None:
    """At the session's first robot test: start the probe workers' forkserver (it imports the simulation, pytest
    and its plugins once, in its own process) while the test runs, so that a failing test's reduction finds it
    warm. Nothing when the probes would not run in local worker processes (one worker, a cluster, an xdist
    worker's default of one), nor on a machine without a core to spare beside this process (1-minute load
    average above the cores minus one): a session whose tests pass must not pay for it there."""
    import os

    from pytest_ddenv.execution import cpu_count
    from pytest_ddenv.pytest_plugin.pools import default_workers

    options = options_of(config)
    if options.executor in (None, "", "local") and default_workers(config) != "1" and \
            os.getloadavg()[0] <= cpu_count() - 1:
        from pytest_ddenv.execution.factory import start_forkserver

        start_forkserver()


def _reduce_failed_test(item: pytest.Function, error: BaseException, given_call: dict[str, Any] | None,
                        test_run: float = 0.0) -> LaterMedia | None:
    """Reduce the failed test's world; the animations and recordings still rendering, if any."""
    from pytest_ddenv.pytest_plugin.pools import probe_pool, warn_about_shared_fixtures
    from pytest_ddenv.pytest_plugin.rate_runs import FailureRateExceeded
    from pytest_ddenv.pytest_plugin.session import ReductionSession

    spec, _ = spec_of(item)
    options = options_of(item.config)
    failing = error.verdict.reduced_run() if isinstance(error, FailureRateExceeded) else None
    test_seed = spec.seed if options.seed is None else options.seed
    spec = dataclasses.replace(
        spec,
        seed=test_seed if failing is None else failing.seed,
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
        replay=functools.partial(replay_command, seed=None if failing is None or failing.seed == test_seed
                                 else failing.seed),
        failing=failing,
        model_paths=options.model_paths,
        media=options.media,
        keep_other=options.keep_other,
        seconds=progress.seconds,
        verbose=item.config.get_verbosity() > 0,
        timings={"test_run": test_run},
    )
    try:
        session.example = _given_example(item, given_call)
        started = time.perf_counter()
        with probe_pool(item, session.example, lambda text: progress(text, final=True),
                        seed=None if failing is None else failing.seed) as pool:
            assert session.timings is not None
            session.timings["pool_start"] = time.perf_counter() - started
            if pool.in_process:
                warn_about_shared_fixtures(item)
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
    if session.later_media is not None:
        item.stash[_media_key] = session.later_media
    return session.later_media


def _note_earlier_reductions(item: pytest.Function) -> None:
    """A robot test that passes: the folders of its earlier reductions are stale (`driver.superseded`); each
    gets the mark in its `summary.json`, and the test's report a line in the "ddenv reductions" summary."""
    from pytest_ddenv.driver.superseded import earlier_reductions, mark_superseded

    folders = [folder for folder in earlier_reductions(options_of(item.config).artifacts, item.nodeid)
               if mark_superseded(folder)]
    if folders:
        shown = ", ".join(str(folder) for folder in folders)
        line = (f"{item.nodeid}: passes now; the earlier reduction{'s' if len(folders) > 1 else ''} in {shown} "
                "(of earlier code or an earlier world) marked superseded in summary.json")
        item.stash[_result_key] = {"text": line + "\n", "line": line, "attachments": [],
                                   "attachments_shown": True}


def _attachment_lines(result: dict[str, Any]) -> str:
    """The JUnit attachments of a reduction's files, one `[[ATTACHMENT|path]]` line each (GitLab, Jenkins)."""
    return "".join(f"[[ATTACHMENT|{path}]]\n" for path in result.get("attachments", []))


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
        media = item.stash.get(_media_key, None)
        if media is not None and getattr(item.config.option, "htmlpath", None):  # an HTML report is written:
            media.finish()  # it embeds the animations, which must be there
        extras = list(getattr(report, "extras", []))
        for path in sorted(attachments, key=_html_order):  # the report shows the first image: the animation
            if not Path(path).exists():  # a medium that could not be made (a warning says why)
                continue
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


def replay_command(item: pytest.Item, minimal_yaml: Path, seed: int | None = None) -> str:
    """The command that re-runs the test on its minimal world (run from the rootdir), in the engine
    `--ddenv-engine` chose (over the marker's, as in the reduction), with `seed` (a failure-rate run's) when
    given."""
    try:
        shown = minimal_yaml.relative_to(item.config.rootpath)
    except ValueError:
        shown = minimal_yaml
    engine = options_of(item.config).engine
    return (f"pytest {shlex.quote(item.nodeid)} --ddenv-world {shlex.quote(str(shown))}"
            + (f" --ddenv-engine {engine}" if engine else "") + (f" --ddenv-seed {seed}" if seed is not None else ""))
