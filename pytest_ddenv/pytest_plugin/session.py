"""Reduce the world of one failed scenario test (pytest glue over `driver.run_reduction`) and word the result
for the report: the "ddenv reduction" section, the terminal line, the attachments.

Called by the plugin from inside the test's call phase, after the test raised, with a pool that runs the
test's probes (worker processes that collected the test, or this process).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.driver import artifacts
from pytest_ddenv.driver.code_identity import CodeIdentity, collected_elsewhere, identify, scripts_beside
from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.driver.report_text import result_lines, status_of
from pytest_ddenv.driver.run import LaterMedia, ReductionOutcome, ReductionPlan, interrupted_outcome, run_reduction
from pytest_ddenv.errors import DdenvError
from pytest_ddenv.media.writer import DEFAULT_MEDIA
from pytest_ddenv.oracle.verdict import FailureReference
from pytest_ddenv.pytest_plugin.given_example import GivenExample, reproduction
from pytest_ddenv.reduce.types import ProgressEvent, Reduction, ReductionInterrupted
from pytest_ddenv.scenario.probe import describe_error
from pytest_ddenv.scenario.robot_world import FIXTURE, RobotWorld

if TYPE_CHECKING:
    from pytest_ddenv.driver.report import ReductionReport
    from pytest_ddenv.execution import Pool
    from pytest_ddenv.pytest_plugin.rate_runs import RateRun
    from pytest_ddenv.scenario.probe import ProbeResult

Progress = Callable[..., None]


@dataclass
class ReductionSession:
    item: pytest.Function
    error: BaseException
    spec: ReductionSpec
    artifacts_root: Path
    progress: Progress
    replay: Callable[[pytest.Item, Path], str]
    model_paths: tuple[str, ...] = ()
    media: str = DEFAULT_MEDIA
    example: GivenExample | None = None
    """The falsifying example of a `@given` test (its world is the one reduced)."""
    keep_other: int = 0
    """`--ddenv-keep-other`: write the smallest worlds of this many other failures (`other-<k>.yaml`)."""
    seconds: Callable[[], float] | None = None
    """Seconds since the reduction started, on the progress lines' clock (the result line's time); None: the
    engine's own time."""
    verbose: bool = False
    """-v: the report section also gives the statistics of the failure-rate comparison."""
    failing: RateRun | None = None
    """The failing run of a failure-rate verdict that is reduced (`--ddenv-rate`): its failure is the reference,
    its last run the reference run, its seed the reduction's (`spec.seed`); None: the test's own failure."""
    timings: dict[str, float] | None = None
    """Seconds of what happened before the reduction (the test's own run, starting the pool), for
    `summary.json`'s `timings` beside the driver's phases."""
    later_media: LaterMedia | None = None
    """After `run`: the animations and recordings still rendering in the background (`finish()` waits)."""

    def run(self, pool: Pool[ProbeResult]) -> dict[str, Any]:
        fixture: RobotWorld = self.item.funcargs[FIXTURE]  # type: ignore[assignment]
        robot_world = fixture.latest  # the world the test ran last (a @given test rebinds each example's)
        world = robot_world.world
        failing = self.failing
        error = describe_error(self.error, self.item.path) if failing is None else failing.error
        assert error is not None
        reference = FailureReference.of(error)
        reference_run = robot_world.runs[-1] if robot_world.runs else None
        if failing is not None and failing.index > 0:
            reference_run = failing.run
        folder = self.artifacts_root / artifacts.artifact_dir_name(self.item.nodeid, self.spec.seed)
        try:
            test_source = inspect.getsource(self.item.obj)
        except (OSError, TypeError):
            test_source = ""
        plan = ReductionPlan(
            world=world, test_id=self.item.nodeid, reference=reference,
            reference_run=reference_run, spec=self.spec, artifacts=folder,
            replay_command=self.replay(self.item, folder / "minimal.yaml"),
            fingerprint={**self.spec.__dict__, "test": self.item.nodeid}, test_source=test_source,
            code=self._code(),
            run_settings={
                "predicates": [spec.to_json() for spec in robot_world.predicates],
                "scenario_seed": robot_world.seed if failing is None else failing.seed,
                **({} if self.example is None else
                   {"hypothesis": reproduction(self.item, self.error, self.example)}),
            },
            model_paths=self.model_paths, media=self.media, keep_other=self.keep_other,
            other_replay=self._other_replay, no_run_reason=no_run_reason(robot_world),
            same_failure=self.spec.same_failure_rule(robot_world.predicates), media_later=True,
        )
        if self.timings:
            plan = replace(plan, run_settings={**plan.run_settings, "timings": {
                phase: round(seconds, 3) for phase, seconds in self.timings.items()}})
        try:
            outcome = run_reduction(plan, pool, note=self.progress, on_progress=self._on_progress)
        except ReductionInterrupted as stop:
            interrupted = interrupted_outcome(stop)
            if interrupted is not None:
                self.progress(self._describe(interrupted)["line"], final=True)
            raise
        except DdenvError as error:  # the folder is locked or cannot be written: say so, keep the test's failure
            outcome = ReductionOutcome("error", message=f"the reduction stopped: {error}")
        self.later_media = outcome.media
        result = self._describe(outcome)
        if failing is not None:  # which of the failure rate's runs was reduced
            which = f"reduced run {failing.index} of the failure-rate runs (seed {failing.seed})"
            result["text"] = f"{which}\n{result['text']}"
            result["line"] = f"{result['line']} [run {failing.index}, seed {failing.seed}]"
        self.progress(result["line"], final=True)
        return result

    def _code(self) -> CodeIdentity:
        """The code under test: the project's modules this session loaded, but other test files and the
        conftests of other folders (unless the test's own files import them), and the Python scripts beside
        the test file that it may run as programs (`scripts_beside`)."""
        collected = {item.path for item in self.item.session.items}
        config = self.item.config
        return identify([config.rootpath], exclude=collected_elsewhere(self.item.path, collected),
                        data_files=scripts_beside(self.item.path, config.getini("python_files")))

    def _other_replay(self, world_file: Path, seed: int | None) -> str:
        """The command that re-runs the test on a kept other failure's world, with the run seed it failed with
        (`--ddenv-seed`, when not the test's own)."""
        command = self.replay(self.item, world_file)
        return command if seed is None or seed == self.spec.seed else f"{command} --ddenv-seed {seed}"

    def _on_progress(self, event: ProgressEvent) -> None:
        probe_line = None
        if event.kind == "probe" and event.candidate is not None and event.outcome is not None:
            probe_line = f"probe {event.probes}: {_models(len(event.candidate))} -> {event.outcome.value}"
        self.progress(f"reducing {self.item.name}: {_models(event.size)}, {event.probes} probe"
                      f"{'s' if event.probes != 1 else ''}", probe_line=probe_line, event=event)

    def _describe(self, outcome: ReductionOutcome) -> dict[str, Any]:
        if outcome.status != "reduced":
            line = f"{self.item.nodeid}: {outcome.message.splitlines()[0]}"
            return {"text": outcome.message + "\n", "line": line, "attachments": [],
                    "reproducible": outcome.status != "not-reproducible", "status": outcome.status}
        assert outcome.report is not None
        return describe_reduction(self.item.nodeid, outcome.report, outcome.attachments,
                                  seconds=None if self.seconds is None else self.seconds(), verbose=self.verbose)


def _models(count: int) -> str:
    """"1 model", "2 models"."""
    return f"{count} model{'s' if count != 1 else ''}"


def describe_reduction(test_id: str, report: ReductionReport, attachments: Sequence[Path], *,
                       seconds: float | None = None, verbose: bool = False) -> dict[str, Any]:
    """The report section, the terminal line and the attachments of a reduction. `seconds`: how long it took
    (default: the engine's time); `verbose`: the statistics of the failure-rate comparison too."""
    reduction = report.reduction
    fails, runs = reduction.failure_rate
    status = status_of(reduction)
    folder = _shown_path(report.files.folder)
    lines = [
        f"world: {report.world}",
        (f"reduced {reduction.original_size} -> {reduction.minimal_size} models "
         f"({report.reduction_percent}%), {status}"),
        *result_lines(report),
        *(rate_statistics(reduction) if verbose else []),
        f"artifacts: {folder}",
        f"replay: {report.replay}",
    ]
    rates = f"fails {fails}/{runs}" if report.cross_engine is None else report.cross_engine.terminal()
    cost = report.cost  # a resumed log's earlier runs are counted: say this run's share (its time is this run's)
    this_run = f" ({cost.this_run_simulations} in this run)" if cost.resumed_runs else ""
    line = (
        f"{test_id}: {reduction.original_size} -> {reduction.minimal_size} models "
        f"({report.reduction_percent:.0f}%), {reduction.probes} probes, {cost.simulations} simulations{this_run}, "
        f"{reduction.wall_time if seconds is None else seconds:.0f} s, "
        f"{rates}{'' if reduction.one_minimal else ', ' + status} -> {folder}"
    )
    return {"text": "\n".join(lines) + "\n", "line": line, "attachments": [str(p) for p in attachments],
            "summary": report.to_json(), "reproducible": True, "status": "reduced"}


def rate_statistics(reduction: Reduction) -> list[str]:
    """The test behind the failure-rate line (docs/algorithm.md section 2), as summary.json's `rate_check` has it."""
    check = reduction.rate_check
    if check is None:
        return []
    return [(f"rate check (one-sided Fisher exact test): p = {check.p_value:.3g}, level {check.level:.3g} per look, "
             f"decision {check.decision!r} on {check.reduced} vs {check.original} fresh runs")]


def _shown_path(path: Path) -> Path:
    """A path relative to the working directory when it is inside it (shorter terminal lines)."""
    try:
        return path.relative_to(Path.cwd())
    except ValueError:
        return path


def no_run_reason(robot_world: RobotWorld) -> str:
    """Why the failing test left no run behind, when its `robot_world.run()` raised ("" otherwise)."""
    error = robot_world.run_error
    if error is None or robot_world.runs:
        return ""
    return f"robot_world.run() raised {type(error).__name__}, so there is no trajectory"
