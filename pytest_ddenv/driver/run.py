"""The one reduction driver: confirm a failure on a probe pool, reduce its world, write the artifacts.

The pytest plugin, the `ddenv reduce` command and the benchmarks all call `run_reduction` with a `Pool`
serving their job (the user's test, or a world's scenario); they differ only in how they build the job
and word the result. No pytest import.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import functools
import os
import signal
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.driver import artifacts
from pytest_ddenv.driver.calls import Calls
from pytest_ddenv.driver.code_identity import CodeIdentity
from pytest_ddenv.driver.confirm import Confirmation, ConfirmationRun, confirm
from pytest_ddenv.driver.cross_engine import CrossEngine, confirm_in_engines
from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.driver.other_failures import original_reproduction, other_failures
from pytest_ddenv.driver.problem import ENGINE_PART, Problem, problem_of
from pytest_ddenv.driver.reach import reach_cut
from pytest_ddenv.driver.report import (
    Cost,
    ReductionReport,
    ReportFiles,
    provisional_summary,
    world_independent_summary,
)
from pytest_ddenv.execution import Pool
from pytest_ddenv.execution.base import world_size
from pytest_ddenv.media.writer import DEFAULT_MEDIA, BackgroundMedia, PendingMedia, Shown, records_runs
from pytest_ddenv.oracle.predicates import FailureSignature
from pytest_ddenv.oracle.verdict import ErrorInfo, FailureReference, SameFailureRule, classify_result
from pytest_ddenv.reduce import (
    Outcome,
    ProbeLog,
    ProgressEvent,
    Reduction,
    ReductionInterrupted,
    ReductionSettings,
    events,
    reduce,
)
from pytest_ddenv.reduce.deflake import make_policy
from pytest_ddenv.reduce.independence import INDEPENDENCE
from pytest_ddenv.scenario.probe import (
    ProbeResult,
    check_rule,
    keeps_start_support,
    make_probe,
    signature_record,
    trace_of,
)
from pytest_ddenv.stages import (
    DEFAULT_STAGES,
    StageBudget,
    StageContext,
    StagesOutcome,
    run_stages,
    scenario_models,
    stage_budget,
    stage_policy,
)

if TYPE_CHECKING:
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World

TRAJECTORY_PARTITIONS = ("timeseg", "trajectoryseg")
TRAJECTORY_PRIORITIES = ("failure-proximal", "avg-trajectory-proximal", "min-trajectory-proximal", "timestep")
BUDGETS = ("max_probes", "max_seconds", "stages", "stage_probes", "confirm_engines")
"""Settings that do not change the problem: a run with another budget (or other stages after the models, or
other engines to confirm in) resumes the same log."""


@dataclass(frozen=True)
class ReductionPlan:
    """What to reduce and how.

    `reference` is the failure to reproduce and `reference_run` the run it happened in (None: the test
    made no run and reported none, so trajectory-guided schemas fall back). `confirmed`: the failure was
    already seen on the pool (skip the confirmation runs). `fingerprint` (the settings), `test_source`, `code`
    and the world identify the problem for resume (`problem.problem_of`).
    """

    world: World
    test_id: str
    reference: FailureReference
    reference_run: Run | None
    spec: ReductionSpec
    artifacts: Path
    replay_command: str
    fingerprint: Mapping[str, Any]
    test_source: str = ""
    code: CodeIdentity = field(default_factory=CodeIdentity)
    """The code under test (`code_identity.identify`): part of the problem, so an edit starts a fresh log."""
    confirmed: bool = False
    run_settings: Mapping[str, Any] = field(default_factory=dict)
    """The caller's own entries of `summary.json` (predicates, noise seed, command line ...)."""
    model_paths: tuple[str, ...] = ()
    """The folders the world's SDF `model://` includes were found in (to cut `minimal.sdf` from the file)."""
    media: str = DEFAULT_MEDIA
    """What to show besides the files: "all" (pictures, animations, 3D recording), "pictures" or "none"
    (`pytest_ddenv.media`)."""
    keep_other: int = 0
    """Write the smallest worlds of this many other failures the probes met as `other-<k>.yaml`
    (`--ddenv-keep-other`, `ddenv reduce --keep-other`; `artifacts.write_other_worlds`)."""
    other_replay: Callable[[Path, int | None], str] | None = None
    """The command that replays a kept other failure: (its `other-<k>.yaml`, the run seed it failed with, None
    when unknown) -> command line; None: no command."""
    no_run_reason: str = ""
    """Why there is no `reference_run` when the caller knows better than "no run was made" (the run raised)."""
    same_failure: SameFailureRule | None = None
    """Which failures are the reference failure (None: `spec`'s match and tolerance, `spec.same_failure_rule()`)."""
    media_later: bool = False
    """Render the animations and recordings in a background process once the summary is written, the pictures
    first in that process (the outcome's `media`, which the caller finishes), instead of before `run_reduction`
    returns. Without animations or recordings to make, the pictures are drawn before it returns."""

    @property
    def rule(self) -> SameFailureRule:
        return self.same_failure if self.same_failure is not None else self.spec.same_failure_rule()


@dataclass
class ReductionOutcome:
    """What `run_reduction` did. `status`: "reduced" (maybe incomplete: see the reduction), "not-reproducible"
    (the confirmation runs never failed the same way), "world-independent" (the world without its removable
    models fails the same way: nothing to reduce) or "error" (the test could not be run: `message`)."""

    status: str
    message: str = ""
    report: ReductionReport | None = None
    """The result of a reduction (status "reduced"), also written as `summary.json`."""
    attachments: list[Path] = field(default_factory=list)
    interrupted: ReductionInterrupted | None = None
    minimal_run: Run | None = None
    media: LaterMedia | None = None
    """The pictures, animations and recordings still being made (`plan.media_later`): `media.finish()` waits for
    them and adds them to `summary.json`; their files are among the `attachments` already."""

    @property
    def reduction(self) -> Reduction | None:
        return None if self.report is None else self.report.reduction


def interrupted_outcome(stop: ReductionInterrupted) -> ReductionOutcome | None:
    """The outcome `run_reduction` wrote before Ctrl-C or SIGTERM stopped it (None: `reduce` itself was
    interrupted, or a caller of its own)."""
    return stop.outcome if isinstance(stop.outcome, ReductionOutcome) else None


Note = Callable[[str], None]


def run_reduction(plan: ReductionPlan, pool: Pool[ProbeResult], *, note: Note = lambda text: None,
                  on_progress: Callable[[ProgressEvent], None] | None = None) -> ReductionOutcome:
    """Confirm `plan.reference` on `pool`, reduce `plan.world`, write the artifacts; see `ReductionOutcome`.

    Durable at every step: the artifacts folder is locked (`artifacts.FolderLock`: a second reduction into it
    fails with `ArtifactsError` naming the holder's pid), the log is resumed whatever else is missing, and
    `minimal.yaml` with a provisional `summary.json` is rewritten at every accepted step. The budgets
    (`spec.max_probes`, `spec.max_seconds`) cover every simulation of the reduction, the confirmation and
    picture runs included; running probes are stopped at the time budget's deadline. Raises
    `ReductionInterrupted` on Ctrl-C or SIGTERM, after writing the best world so far (its outcome:
    `interrupted_outcome`), and `ArtifactsError` / `ReductionError` when the folder or the log cannot be
    written (the log keeps every complete record: run again to resume).

    The phases, each a call that returns what the next needs: `confirm` (is the failure there?), the
    folder (`artifacts.prepare`, the log), `_Locked.reduce_models`, `_Locked.runs_to_show`, `_run_stages`,
    `_Locked.write` (the files, the report, the pictures and the media)."""
    if plan.spec.engine is not None and plan.world.physics.engine != plan.spec.engine:
        plan = replace(plan, world=plan.world.with_engine(plan.spec.engine))  # every probe's world carries it
    spec, world = plan.spec, plan.world
    make_policy(spec.deflake, 0.95)  # an invalid deflake fails now, before any simulation
    deadline = None if spec.max_seconds is None else time.monotonic() + spec.max_seconds
    if plan.reference_run is not None:  # the watchdog scales with the original run
        pool.expect(plan.reference_run.wall_time, world_size(world))
    # This process waits for the workers: import meanwhile (a caller may have started it earlier).
    ahead = None if pool.in_process else import_ahead()
    timings: dict[str, float] = {}
    try:
        check_rule(plan.reference, plan.rule)  # a user's rule that cannot match the failure itself fails now
        calls = Calls(pool, plan.reference, plan.rule, deadline)
        with _sigterm_as_interrupt():
            with timed(timings, "confirmation"):
                confirmation = Confirmation() if plan.confirmed else confirm(
                    world, plan.reference, plan.rule, calls, deflake=spec.deflake, max_probes=spec.max_probes,
                    record=records_runs(plan.media), note=note)
            if confirmation.status != "confirmed":
                return ReductionOutcome(confirmation.status, message=confirmation.message)
            partition, priority, notes = _schemas(spec, plan.reference_run, plan.no_run_reason)
            for text in notes:
                note(text)
            settings = {key: value for key, value in plan.fingerprint.items()
                        if key not in BUDGETS and key != "engine"}  # the engine is a part of its own (problem.py)
            problem = problem_of(world, {**settings, "partition": partition, "priority": priority},
                                 plan.test_source, plan.code, test_id=plan.test_id,
                                 reference=plan.reference.to_dict())
            with artifacts.FolderLock(plan.artifacts):
                paths, prepared = artifacts.prepare(
                    plan.artifacts, problem,
                    same_reference=lambda logged: same_reference(logged, plan.reference, plan.rule))
                log = ProbeLog(paths.log)
                for text in prepared + log.notes:
                    note(text)
                try:
                    return _reduce_locked(plan, pool, calls, paths, log, problem, partition, priority,
                                          notes + prepared + log.notes, confirmation.runs, on_progress, timings)
                finally:
                    log.close()
    finally:
        if ahead is not None:  # never leave it importing while the caller goes on (see IMPORT_AHEAD_WAIT)
            ahead.join(IMPORT_AHEAD_WAIT)


def _reduce_locked(plan: ReductionPlan, pool: Pool[ProbeResult], calls: Calls, paths: artifacts.ArtifactPaths,
                   log: ProbeLog, problem: Problem, partition: str, priority: str, notes: list[str],
                   confirmations: tuple[ConfirmationRun, ...],
                   on_progress: Callable[[ProgressEvent], None] | None,
                   timings: dict[str, float]) -> ReductionOutcome:
    """The reduction once its folder is locked and its log open, in its phases: the model-level reduction,
    the runs to show, the stages, the other engines (`cross_engine.py`), the files (`_Locked`). Ctrl-C in a
    phase skips the phases after it but the files."""
    locked = _Locked(plan, pool, calls, paths, log, problem, notes, on_progress)
    locked.timings = timings
    for attempt, result, verdict in confirmations:
        _log_run(log, "confirmation", plan.world.names, attempt, result, verdict)
    with timed(timings, "reduction"):
        reduction, interrupted = locked.reduce_models(partition, priority)
    if reduction.independent:
        return locked.world_independent(reduction)
    locked.notes = list(dict.fromkeys([*locked.notes, *reduction.notes]))
    minimal_run: Run | None = None
    shown: list[Shown] = []
    staged: StagesOutcome | None = None
    crossed: CrossEngine | None = None
    try:
        if interrupted is None:
            with timed(timings, "recording_runs"):
                minimal_run, shown = locked.runs_to_show(reduction, confirmations)
        if interrupted is None and len(plan.spec.stages or DEFAULT_STAGES) > 1 and reduction.minimal:
            with timed(timings, "stages"):
                staged = _run_stages(plan, pool, reduction, calls, log, paths, minimal_run)
        if interrupted is None and plan.spec.confirm_engines:
            with timed(timings, "other_engines"):
                crossed = confirm_in_engines(plan.spec.confirm_engines, plan.world, reduction, calls, log, pool,
                                             max_probes=plan.spec.max_probes)
    except KeyboardInterrupt as stop:  # the models are reduced: the summary says so, no pictures
        pool.close()
        interrupted = ReductionInterrupted(reduction)
        interrupted.__cause__ = stop
    outcome = locked.write(reduction, staged, interrupted, minimal_run, shown, crossed)
    if outcome.interrupted is not None:
        outcome.interrupted.outcome = outcome
        raise outcome.interrupted
    return outcome


class _Locked:
    """One reduction in its locked folder: its log, its usage and the files it writes."""

    def __init__(self, plan: ReductionPlan, pool: Pool[ProbeResult], calls: Calls, paths: artifacts.ArtifactPaths,
                 log: ProbeLog, problem: Problem, notes: list[str],
                 on_progress: Callable[[ProgressEvent], None] | None) -> None:
        self.plan, self.pool, self.calls, self.paths, self.log = plan, pool, calls, paths, log
        self.problem = problem
        self.notes = notes
        self.on_progress = on_progress
        self.history = artifacts.usage_of(log.events)  # the earlier runs of this reduction, if resumed
        log.write(events.Session(pid=os.getpid(), time=time.strftime("%Y-%m-%dT%H:%M:%S")))
        self.best = _last_step(log.own_events()) or plan.world.names
        self.fresh = log.started_with() is None
        self.timings: dict[str, float] = {}
        """Seconds of each phase so far (`timed`), for `summary.json`'s `timings` (with the caller's own)."""

    def run_settings(self) -> dict[str, Any]:
        """The caller's entries of `summary.json` with the phases' `timings` added to the caller's own."""
        earlier = self.plan.run_settings.get("timings", {})
        return {**self.plan.run_settings, "timings": {**earlier, **rounded(self.timings)}}

    def cost(self, probes: int) -> Cost:
        stats = self.pool.stats
        return Cost(probes, self.history.simulations + stats.simulations, self.history.cpu_seconds + stats.cpu_seconds,
                    stats.simulations, stats.cpu_seconds, stats.to_dict(), resumed_runs=self.history.runs,
                    cpu_seconds_complete=self.history.complete)

    def record_usage(self, final: bool = False) -> None:
        stats = self.pool.stats
        self.log.write(events.Usage(simulations=stats.simulations, cpu_seconds=round(stats.cpu_seconds, 6),
                                    final=final))

    def progress(self, event: ProgressEvent) -> None:
        """At the start and at every accepted step: the best world so far and a provisional summary."""
        if (event.kind == "start" and self.fresh) or (event.kind == "step" and event.candidate is not None):
            if event.kind == "step":
                assert event.candidate is not None
                self.best = event.candidate
                self.calls.pin(self.best)
            plan, paths = self.plan, self.paths
            best = plan.world.select(self.best)
            artifacts.write_world(paths.minimal_yaml, best, paths.directory)
            artifacts.write_json(paths.summary, provisional_summary(
                test_id=plan.test_id, world=plan.world.source or plan.world.name, original=plan.world.names,
                best=best.names, problem_fingerprint=self.problem.fingerprint, replay_command=plan.replay_command,
                reference=plan.reference.to_dict(), counts=self.cost(event.probes).to_json(),
                files=ReportFiles(paths.minimal_yaml, paths.log, paths.summary),
                extra={**plan.run_settings, "tolerance": plan.spec.tolerance,
                       "same_failure": plan.rule.to_json(), "notes": self.notes,
                       "world_notes": list(plan.world.notes)}))
            self.record_usage()
        if self.on_progress is not None:
            self.on_progress(event)

    def world_independent(self, reduction: Reduction) -> ReductionOutcome:
        """The outcome of a failure that the world without its removable models reproduced (the engine's
        `check_independence`): nothing reduced, a summary that says so, no minimal world."""
        plan = self.plan
        empty = next((probe.candidate for probe in reversed(self.log.probes(INDEPENDENCE))), ())
        simulations = self.cost(reduction.probes).simulations
        only = f" (only {', '.join(empty)} kept)" if empty else ""
        message = (f"the failure does not depend on the world: it also happens with no models{only}, the same "
                   f"way ({plan.reference.describe()}); no reduction was run ({_count(simulations, 'simulation')}). "
                   "Look at the code under test rather than the world.")
        self.record_usage(final=True)
        artifacts.remove_outputs(self.paths)
        artifacts.write_json(self.paths.summary, world_independent_summary(
            test_id=plan.test_id, world=plan.world.source or plan.world.name, original_size=len(plan.world),
            kept=empty, message=message, reference=plan.reference.to_dict(),
            counts=self.cost(reduction.probes).to_json(), log=self.paths.log, summary=self.paths.summary))
        return ReductionOutcome("world-independent", message=message)

    def reduce_models(self, partition: str, priority: str) -> tuple[Reduction, ReductionInterrupted | None]:
        """The engine's reduction of the models (the best so far when interrupted)."""
        plan, calls, pool = self.plan, self.calls, self.pool
        spec, world = plan.spec, plan.world
        keep = (set(spec.keep) & set(world.names)) | {m.name for m in world.models if m.keep} | set(
            scenario_models(world))  # an arm's table and target: not candidates, the scenario needs them
        probe = calls.cancellable(make_probe(world, calls, plan.reference, rule=plan.rule))
        left = spec.max_probes if spec.max_probes is None else max(0, spec.max_probes - calls.started)
        seconds = None if calls.deadline is None else max(0.0, calls.deadline - time.monotonic())
        threads = (concurrent.futures.ThreadPoolExecutor(pool.size, thread_name_prefix="ddenv-probe")
                   if pool.size > 1 else None)
        clean = False
        try:
            settings = ReductionSettings(
                partition=partition, priority=priority, n_partitions=spec.n_partitions,
                granularity=spec.granularity, deflake=spec.deflake, keep=tuple(sorted(keep)),
                preconditions=(keeps_start_support(world),), max_probes=left, max_seconds=seconds, seed=spec.seed,
                workers=pool.size, check_independence=True, first_cut=self.first_cut(),
            )
            reduction = reduce(
                world.names, probe, settings, geometry=world,
                reference=trace_of(plan.reference_run) if plan.reference_run is not None else None,
                log=self.log, on_progress=self.progress, executor=threads,
            )
            clean = True
            return reduction, None
        except ReductionInterrupted as stop:
            pool.close()  # first: probe threads blocked on workers return at once
            return stop.reduction, stop
        except BaseException:
            pool.close()  # a crash (a full disk, a bug): free the probe threads, then let it through
            raise
        finally:
            if threads is not None:
                threads.shutdown(wait=clean, cancel_futures=True)

    def first_cut(self) -> tuple[str, ...] | None:
        """The models within reach of the original run (`reach.py`) for the engine to try first; None (logged
        as a "first-cut" event "skipped", with the reason) when there is nothing to cut or the reach is not
        bounded."""
        cut = reach_cut(self.plan.world, self.plan.reference_run)
        if cut.made:
            return cut.kept
        self.log.write(events.FirstCut(original=len(self.plan.world), kept=len(cut.kept), decision="skipped",
                                       reason=cut.reason or "every model is within reach of the original run"))
        return None

    def runs_to_show(self, reduction: Reduction, confirmations: tuple[ConfirmationRun, ...]
                     ) -> tuple[Run | None, list[Shown]]:
        """The minimal world's failing run for the pictures, and the runs to animate and record (run now,
        before the summary, so that its counts include every simulation)."""
        plan, calls = self.plan, self.calls
        if plan.media == "none":
            return None, []
        record = records_runs(plan.media)
        minimal_world = plan.world.select(reduction.minimal)
        minimal_run = calls.run_of(reduction.minimal, plan.world, plan.reference_run)
        shown: list[Shown] = []
        if (minimal_run is None or record) and calls.may_start(plan.spec.max_probes):
            purpose = "recording" if record else "picture"
            recorded, failed = _logged_run(calls, self.log, minimal_world, 0, purpose, record)
            minimal_run = minimal_run or recorded
            shown = [Shown("minimal", minimal_world, recorded, failed)] if record else []
        if record:
            shown.insert(0, Shown("original", plan.world, *_recorded_original(plan, calls, self.log, confirmations)))
        return minimal_run, shown

    def write(self, reduction: Reduction, staged: StagesOutcome | None, interrupted: ReductionInterrupted | None,
              minimal_run: Run | None, shown: list[Shown], crossed: CrossEngine | None = None) -> ReductionOutcome:
        """The minimal world, the summary, the stage worlds, the pictures and the media. Ctrl-C (or SIGTERM)
        while the files are written waits until the summary is (the reduction's result is never left "in
        progress"), and stops the pictures and media; the outcome's `interrupted` is then set."""
        plan, paths = self.plan, self.paths
        started = time.perf_counter()
        with interrupts_deferred() as deferred:
            self.record_usage(final=True)
            how = artifacts.write_minimal_world(paths, plan.world, plan.world.select(reduction.minimal),
                                                reduction.removed, model_paths=plan.model_paths)
            how_xml = artifacts.write_minimal_xml(paths.minimal_xml, plan.world, plan.world.select(reduction.minimal),
                                                  reduction.removed)
            others, other_worlds = artifacts.write_other_worlds(
                paths, plan.world, other_failures(self.log.events, rule=plan.rule, reference=plan.reference),
                plan.keep_other, plan.other_replay)
            files = ReportFiles(paths.minimal_yaml, paths.log, paths.summary,
                                minimal_sdf=paths.minimal_sdf if how is not None else None, other_worlds=other_worlds,
                                minimal_xml=paths.minimal_xml if paths.minimal_xml.is_file() and how_xml else None)
            report = ReductionReport(
                test=plan.test_id, world=plan.world.source or plan.world.name, reduction=reduction,
                reference_failure=plan.reference.to_dict(), replay=plan.replay_command,
                fingerprint=self.problem.fingerprint,
                files=files, cost=self.cost(reduction.probes), tolerance=plan.spec.tolerance, minimal_sdf=how,
                minimal_xml=how_xml,
                same_failure=plan.rule, engine=self.problem.parts.get(ENGINE_PART, ""),
                reproduction=original_reproduction(self.log.events, plan.world.names, plan.reference, plan.rule),
                notes=tuple(dict.fromkeys([*self.notes, *self.pool.notes])),
                world_notes=tuple(plan.world.notes), stages=staged,
                stage_files=artifacts.write_stage_worlds(paths, staged) if staged is not None else {},
                run_settings=plan.run_settings, other_failures=others, cross_engine=crossed)
            self.timings["files"] = time.perf_counter() - started
            report = replace(report, run_settings=self.run_settings())
            artifacts.write_json(paths.summary, report.to_json())
        if deferred and interrupted is None:
            interrupted = ReductionInterrupted(reduction)
        attachments = [paths.minimal_yaml, paths.log, paths.summary, *map(Path, report.stage_files.values()),
                       *other_worlds]
        pending: PendingMedia | None = None
        later: LaterMedia | None = None
        try:
            if interrupted is None and shown and not plan.media_later:
                # with worker processes, an animation renders beside the pictures
                pending = PendingMedia(paths.directory, shown, failure_text=plan.reference.describe(),
                                       helper=self.pool.size > 1 and not self.pool.in_process, media=plan.media)
            # with animations or recordings to make in a background process, the pictures are drawn there first
            drawn_later = interrupted is None and plan.media != "none" and plan.media_later and bool(shown)
            if interrupted is None and plan.media != "none" and not drawn_later:
                with timed(self.timings, "pictures"):
                    attachments += _pictures(plan.world, reduction, paths, plan.reference_run, minimal_run, staged)
                report = replace(report, run_settings=self.run_settings())
                artifacts.write_json(paths.summary, report.to_json())
            if drawn_later:  # beside the next test
                pictures = functools.partial(_pictures, plan.world, reduction, paths, plan.reference_run,
                                             minimal_run, staged)
                later = LaterMedia(BackgroundMedia(paths.directory, shown, failure_text=plan.reference.describe(),
                                                   media=plan.media, pictures=pictures,
                                                   picture_paths=_picture_paths(paths, staged)),
                                   report, paths.summary)
            if pending is not None:
                media = pending.finish()
                attachments += media.paths
                if media.info:  # what was made and what it took, in the summary
                    self.timings["media"] = media.seconds
                    report = replace(report.with_media(media.info, media.seconds), run_settings=self.run_settings())
                    artifacts.write_json(paths.summary, report.to_json())
        except KeyboardInterrupt as stop:  # the summary is written: only pictures and media are missing
            interrupted = interrupted or ReductionInterrupted(reduction)
            interrupted.__cause__ = interrupted.__cause__ or stop
            if pending is not None and pending.elsewhere is not None:  # its helper finishes on its own
                pending.elsewhere[1].shutdown(wait=False, cancel_futures=True)
        existing = [path for path in attachments if path.exists()]
        return ReductionOutcome("reduced", report=report,
                                attachments=existing + ([] if later is None else later.media.expected_paths()),
                                interrupted=interrupted, minimal_run=minimal_run, media=later)


class LaterMedia:
    """A reduction's pictures, animations and recordings made in a background process (`plan.media_later`)
    after its summary was written: `finish()` waits for them, says what could not be made (warnings, as when
    they are made before `run_reduction` returns) and adds them to `summary.json` (`media`,
    `timings.pictures_background` and `timings.media` the seconds they took, `timings.media_wait` the seconds
    `finish()` waited)."""

    def __init__(self, media: BackgroundMedia, report: ReductionReport, summary: Path) -> None:
        self.media, self.report, self.summary = media, report, summary
        self.done: list[Path] | None = None

    def finish(self) -> list[Path]:
        """The files made (waits for the background process once; later calls return the same list)."""
        if self.done is not None:
            return self.done
        started = time.perf_counter()
        written = self.media.finish()
        drawn = {} if self.media.pictures is None else {"pictures_background": round(written.picture_seconds, 3)}
        timings = {**self.report.run_settings.get("timings", {}), **drawn, "media": round(written.seconds, 3),
                   "media_wait": round(time.perf_counter() - started, 3)}
        report = replace(self.report.with_media(written.info, written.seconds) if written.info else self.report,
                         run_settings={**self.report.run_settings, "timings": timings})
        artifacts.write_json(self.summary, report.to_json())
        self.done = [*written.pictures, *written.paths]
        return self.done


@contextlib.contextmanager
def timed(timings: dict[str, float], phase: str) -> Iterator[None]:
    """Add the block's wall-clock seconds to `timings[phase]` (even when it raises)."""
    started = time.perf_counter()
    try:
        yield
    finally:
        timings[phase] = timings.get(phase, 0.0) + time.perf_counter() - started


def rounded(timings: Mapping[str, float]) -> dict[str, float]:
    return {phase: round(seconds, 3) for phase, seconds in timings.items()}


def _run_stages(plan: ReductionPlan, pool: Pool[ProbeResult], reduction: Reduction, calls: Calls, log: ProbeLog,
                paths: artifacts.ArtifactPaths, minimal_run: Run | None) -> StagesOutcome:
    """The stages after the models (`spec.stages`), from the minimal world, within their budget."""
    spec = plan.spec
    left = None if spec.max_probes is None else max(0, spec.max_probes - calls.started)
    logged = len(log.probes())  # resumed runs too
    model_cost = max(logged, pool.stats.simulations)  # speculative runs cancelled unlogged count too
    limit, per_stage = stage_budget(model_cost, spec.stage_probes, left)
    started = calls.started
    policy = stage_policy(make_policy(spec.deflake, 0.95), reduction)
    threads = (concurrent.futures.ThreadPoolExecutor(pool.size, thread_name_prefix="ddenv-stage")
               if pool.size > 1 else None)

    context = StageContext(
        base=plan.world.select(reduction.minimal), call=calls, reference=plan.reference, rule=plan.rule,
        log=log, policy=policy, seed=spec.seed, budget=StageBudget(limit, lambda: calls.started, started, per_stage),
        executor=threads, workers=pool.size, wrap=calls.cancellable,
    )
    try:
        staged = run_stages(spec.stages or DEFAULT_STAGES, context, reduction, minimal_run=minimal_run,
                            folder=paths.directory, log_only=spec.stages is None)
    finally:
        if threads is not None:
            threads.shutdown(wait=False, cancel_futures=True)
    if plan.media != "none":
        _stage_runs_to_show(staged, calls, log, spec.max_probes)
    return staged


def _stage_runs_to_show(staged: StagesOutcome, calls: Calls, log: ProbeLog, max_probes: int | None) -> None:
    """A passing run of the nearest passing world for `passing.png` when the stages decided it from the log
    (by default, they simulate nothing): one run (attempt 0, logged as "picture", counted in the stages'
    simulations, within their budget and the reduction's), kept only if it passed: a picture never shows a
    failing run as the passing one."""
    world = staged.passing
    if world is None or staged.passing_run is not None or not calls.may_start(max_probes) or (
            staged.budget is not None and staged.simulations >= staged.budget):
        return
    staged.simulations += 1
    run, _ = _logged_run(calls, log, world, 0, "picture", False)
    last = log.events[-1]
    if run is not None and isinstance(last, events.Probe) and last.result is Outcome.PASS:  # as it was classified
        staged.passing_run = run


def _count(number: int, noun: str) -> str:
    return f"{number} {noun}{'' if number == 1 else 's'}"


def same_reference(logged: Mapping[str, Any], reference: FailureReference, rule: SameFailureRule | float) -> bool:
    """Whether a run log's reference failure (`FailureReference.to_dict()`) is the failure being reduced now,
    under the same-failure rule the probes are judged by: a resumed log's verdicts were taken against it."""
    try:
        signature = logged.get("signature")
        earlier = ErrorInfo(str(logged["exception_type"]), "", str(logged["location"]),
                            signature=None if signature is None else FailureSignature.from_dict(signature))
    except (KeyError, TypeError, ValueError, AttributeError):
        return False
    now = ErrorInfo(reference.exception_type, "", reference.location, signature=reference.signature)
    return (classify_result(earlier, reference, rule) is Outcome.FAIL
            and classify_result(now, FailureReference.of(earlier), rule) is Outcome.FAIL)


def _last_step(logged: list[events.Event]) -> tuple[str, ...] | None:
    """The world adopted last in a log (the best world so far), if any."""
    return next((event.candidate for event in reversed(logged) if isinstance(event, events.Step)), None)


def _log_run(log: ProbeLog, purpose: str, names: tuple[str, ...], attempt: int, result: ProbeResult | None,
             outcome: str) -> None:
    """A simulation of the driver's own (confirmation, picture) in the run log, as a probe record."""
    run = None if result is None else result.run
    log.write(events.Probe(purpose=purpose, kind=purpose, candidate=names, size=len(names), attempt=attempt,
                           seed=None if run is None else int(run.seed), outcome=outcome,
                           signature=None if result is None else signature_record(result.error),
                           sim_time=0.0 if run is None else float(run.sim_time),
                           wall_time=0.0 if run is None else float(run.wall_time), detail=""))


HEAVY_IMPORTS = ("sklearn.cluster", "sklearn.linear_model", "matplotlib.pyplot", "matplotlib.collections")
"""What the schemas and the pictures import on first use (about 1.5 s together): imported while the first
probes run in the workers, so that the engine's first round does not wait for scikit-learn."""


IMPORT_AHEAD_WAIT = 60.0
"""Seconds `run_reduction` waits at its end for the import-ahead thread. CPython 3.11 before 3.11.8 can fail
with "SystemError: AST constructor recursion depth mismatch" when two threads compile source at once (a
fresh install has no .pyc files yet): a reduction that ends early (a failure that does not reproduce) must
not leave the thread compiling while pytest goes on importing (and rewriting) its own plugins."""


_ahead: threading.Thread | None = None
_ahead_lock = threading.Lock()


def import_ahead() -> threading.Thread:
    """Start importing the modules the engine and the pictures need (scikit-learn, matplotlib) in a thread,
    once per process, so that they are loaded by the time they are needed while this process waits for
    its probe workers; the thread (started now or earlier)."""
    global _ahead
    with _ahead_lock:
        if _ahead is None:
            _ahead = threading.Thread(target=_import_heavy_modules, name="ddenv-import-ahead", daemon=True)
            _ahead.start()
        return _ahead


def _import_heavy_modules() -> None:
    import importlib

    for module in HEAVY_IMPORTS:
        if module.startswith("matplotlib"):
            import matplotlib

            matplotlib.use("Agg")  # as render/canvas.py does: no display
        try:
            importlib.import_module(module)
        except ImportError:  # pragma: no cover - the dependencies are installed with the package
            return


NO_RUN = "the test made no robot_world.run() and no robot_world.report(), so there is no trajectory"


def _schemas(spec: ReductionSpec, reference_run: Run | None, no_run_reason: str = "") -> tuple[str, str, list[str]]:
    """The partition and priority to use, and notes on any fallback (no trajectory to guide them)."""
    partition, priority, notes = spec.partition, spec.priority, []
    if reference_run is None:
        why = no_run_reason or NO_RUN
        if partition in TRAJECTORY_PARTITIONS:
            notes.append(f"{why}: partition {partition} -> model2model")
            partition = "model2model"
        if priority in TRAJECTORY_PRIORITIES:
            notes.append(f"{why}: priority {priority} -> sequential")
            priority = "sequential"
    return partition, priority, notes


def _logged_run(call: Calls, log: ProbeLog, world: World, attempt: int, purpose: str,
                record: bool) -> tuple[Run | None, bool]:
    """A run of `world` for the pictures (`record`: and the animations, with its full detail), logged: the
    run (None if it cannot be had) and whether it failed the same way."""
    try:
        result = call(world, attempt, record=record)
    except Exception:  # noqa: BLE001 - pictures are a convenience
        _log_run(log, purpose, world.names, attempt, None, "error")
        return None, False
    outcome = classify_result(result.error, call.reference, call.rule)
    _log_run(log, purpose, world.names, attempt, result, outcome.value)
    return result.run, outcome is Outcome.FAIL


def _recorded_original(plan: ReductionPlan, call: Calls, log: ProbeLog,
                       confirmations: tuple[ConfirmationRun, ...]) -> tuple[Run | None, bool]:
    """The original world's failing run with its full detail: the run that confirmed the failure, else one
    more run (attempt 0, logged) when the budget allows; and whether it failed the same way."""
    for _, result, verdict in confirmations:
        if verdict == Outcome.FAIL.value and result is not None and result.run is not None \
                and result.run.detail is not None:
            return result.run, True
    if not call.may_start(plan.spec.max_probes):
        return None, False
    return _logged_run(call, log, plan.world, 0, "recording", True)


def _picture_paths(paths: artifacts.ArtifactPaths, staged: StagesOutcome | None) -> list[Path]:
    """The pictures `_pictures` writes when nothing goes wrong."""
    written = [paths.reduction_png, paths.progress_png]
    if staged is not None and staged.changed and staged.final is not None:
        written.append(paths.directory / "simplified.png")
    if staged is not None and staged.passing is not None:
        written.append(paths.directory / "passing.png")
    return written


def _pictures(world: World, reduction: Reduction, paths: artifacts.ArtifactPaths, original_run: Run | None,
              minimal_run: Run | None, staged: StagesOutcome | None = None) -> list[Path]:
    """reduction.png and progress.png (the original and the minimal world's failing trajectories), and the
    stages' simplified.png and passing.png."""
    try:
        from pytest_ddenv.driver import pictures

        written = list(pictures.write_reduction_pictures(world, reduction, paths, original_run=original_run,
                                                         minimal_run=minimal_run))
        if staged is not None:
            written += pictures.write_stage_pictures(staged, paths)
        return written
    except Exception as error:  # noqa: BLE001 - pictures are a convenience; never lose the reduction over one
        warnings.warn(f"ddenv: pictures not written: {type(error).__name__}: {error}", stacklevel=1)
        return []


@contextlib.contextmanager
def interrupts_deferred() -> Iterator[list[int]]:
    """Ctrl-C and SIGTERM wait until the block is over (in the main thread): the list it yields holds the
    signals that came meanwhile (empty: none), for the caller to act on afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield []
        return
    came: list[int] = []
    previous = {number: signal.signal(number, lambda signum, frame: came.append(signum))
                for number in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield came
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM (a CI job being cancelled) ends the reduction like Ctrl-C: best world kept, log complete."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
