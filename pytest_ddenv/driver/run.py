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
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.driver import artifacts
from pytest_ddenv.driver.calls import Calls
from pytest_ddenv.driver.confirm import Confirmation, ConfirmationRun, confirm
from pytest_ddenv.driver.cross_engine import CrossEngine, confirm_in_engines
from pytest_ddenv.driver.import_ahead import IMPORT_AHEAD_WAIT, import_ahead
from pytest_ddenv.driver.interrupts import interrupts_deferred, sigterm_as_interrupt
from pytest_ddenv.driver.logged_runs import log_run, logged_run, recorded_original
from pytest_ddenv.driver.media_phase import LaterMedia, picture_paths, write_pictures
from pytest_ddenv.driver.other_failures import original_reproduction, other_failures
from pytest_ddenv.driver.plan import ReductionOutcome, ReductionPlan, interrupted_outcome, schemas
from pytest_ddenv.driver.problem import ENGINE_PART, Problem, problem_of
from pytest_ddenv.driver.reach import reach_cut
from pytest_ddenv.driver.report import (
    Cost,
    ReductionReport,
    ReportFiles,
    provisional_summary,
    world_independent_summary,
)
from pytest_ddenv.driver.stages_phase import run_stages_after_models
from pytest_ddenv.execution import Pool
from pytest_ddenv.execution.base import world_size
from pytest_ddenv.media.writer import BackgroundMedia, PendingMedia, Shown, records_runs
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
from pytest_ddenv.scenario.probe import ProbeResult, check_rule, keeps_start_support, make_probe, trace_of
from pytest_ddenv.stages import DEFAULT_STAGES, StagesOutcome, scenario_models

if TYPE_CHECKING:
    from pytest_ddenv.sim import Run

__all__ = ["BUDGETS", "IMPORT_AHEAD_WAIT", "LaterMedia", "Note", "ReductionOutcome", "ReductionPlan", "import_ahead",
           "interrupted_outcome", "interrupts_deferred", "rounded", "run_reduction", "same_reference", "timed"]
"""This module's own names, and those of the driver's other modules that callers import from here (the plan and
the outcome, the media made later, the import-ahead thread, the deferred interrupts)."""

BUDGETS = ("max_probes", "max_seconds", "stages", "stage_probes", "confirm_engines")
"""Settings that do not change the problem: a run with another budget (or other stages after the models, or
other engines to confirm in) resumes the same log."""


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
    folder (`artifacts.prepare`, the log), `_Locked.reduce_models`, `_Locked.runs_to_show`, `run_stages_after_models`,
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
        with sigterm_as_interrupt():
            with timed(timings, "confirmation"):
                confirmation = Confirmation(plan.confirmations) if plan.confirmed else confirm(
                    world, plan.reference, plan.rule, calls, deflake=spec.deflake, max_probes=spec.max_probes,
                    record=records_runs(plan.media), note=note)
            if confirmation.status != "confirmed":
                return ReductionOutcome(confirmation.status, message=confirmation.message)
            partition, priority, notes = schemas(spec, plan.reference_run, plan.no_run_reason)
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
        log_run(log, "confirmation", plan.world.names, attempt, result, verdict)
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
                staged = run_stages_after_models(plan, pool, reduction, calls, log, paths, minimal_run)
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
            recorded, failed = logged_run(calls, self.log, minimal_world, 0, purpose, record)
            minimal_run = minimal_run or recorded
            shown = [Shown("minimal", minimal_world, recorded, failed)] if record else []
        if record:
            shown.insert(0, Shown("original", plan.world, *recorded_original(plan, calls, self.log, confirmations)))
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
                    attachments += write_pictures(plan.world, reduction, paths, plan.reference_run, minimal_run, staged)
                report = replace(report, run_settings=self.run_settings())
                artifacts.write_json(paths.summary, report.to_json())
            if drawn_later:  # beside the next test
                pictures = functools.partial(write_pictures, plan.world, reduction, paths, plan.reference_run,
                                             minimal_run, staged)
                later = LaterMedia(BackgroundMedia(paths.directory, shown, failure_text=plan.reference.describe(),
                                                   media=plan.media, pictures=pictures,
                                                   picture_paths=picture_paths(paths, staged)),
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
