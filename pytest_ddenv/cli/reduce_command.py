"""`ddenv reduce`: a world whose scenario fails reduced to the models the failure needs, on a pool of workers
running a `ScenarioJob`, with the progress on stderr and the result as text or JSON (`reduce_plan` makes the
driver's plan of the command line)."""

from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from pytest_ddenv.cli.console import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, emit, print_json
from pytest_ddenv.cli.output import check_matplotlib_backend
from pytest_ddenv.cli.predicates import check_named_models, reduce_predicates
from pytest_ddenv.cli.reduce_plan import artifacts_folder, reduction_plan
from pytest_ddenv.cli.run_command import RUN_TIMEOUT_HINT, run_outcome
from pytest_ddenv.cli.user_code import load_user_code, same_failure_rule
from pytest_ddenv.cli.world_options import UsageError, dropped_models, load_world, with_scenario
from pytest_ddenv.driver.progress import ProgressLine
from pytest_ddenv.driver.settings import SETTING, SettingError, watchdog
from pytest_ddenv.driver.user_code import UserCodeExit, is_exit
from pytest_ddenv.oracle.predicates import PredicateSpec
from pytest_ddenv.oracle.verdict import hit_wall_clock_cap, is_run_error, wall_clock_cap_message

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.driver.report import ReductionReport
    from pytest_ddenv.execution import Pool
    from pytest_ddenv.world.model import World


def _resolved_media(given: str | None) -> str:
    """--media, else $DDENV_MEDIA, else all."""
    try:
        return str(SETTING["media"].check(given, "--media"))
    except SettingError as error:
        raise UsageError(str(error)) from None


def cmd_reduce(arguments: argparse.Namespace) -> int:
    from pytest_ddenv.driver.scenario_job import ScenarioJob
    from pytest_ddenv.execution import check_executor, make_pool
    from pytest_ddenv.media.writer import records_runs
    from pytest_ddenv.reduce import PRIORITY_ALIASES

    arguments.media = _resolved_media(arguments.media)
    if arguments.media != "none":
        check_matplotlib_backend()
    load_user_code(arguments)
    world = with_scenario(arguments, load_world(arguments, arguments.world), arguments.world)
    predicates = reduce_predicates(arguments.predicates, world)
    check_named_models(predicates, world)
    arguments.same_failure_match = same_failure_rule(arguments.same_failure)
    keep = _keep(world, arguments.keep)
    priority = PRIORITY_ALIASES.get(arguments.priority, arguments.priority)
    executor = check_executor(arguments.executor)
    from pytest_ddenv.driver.artifacts import folder_problem
    from pytest_ddenv.driver.run import IMPORT_AHEAD_WAIT, import_ahead

    problem = folder_problem(artifacts_folder(arguments))
    if problem is not None:
        raise UsageError(f"{'--out' if arguments.out else 'the artifacts folder'}: {problem}")
    # --timeout is in the world's scenario (with_scenario), not a per-run override: the time stage's shorter
    # limit must apply to its candidates
    job = ScenarioJob(tuple(predicates), seed=arguments.seed, controller=arguments.controller,
                      imports=tuple(arguments.imports), max_wall_time=arguments.run_timeout)
    progress = ProgressLine(sys.stderr, quiet=arguments.quiet)
    in_process = job.handler() if executor is None and arguments.workers == 1 else None
    ahead: threading.Thread | None = None
    try:
        with make_pool(job, arguments.workers, executor, in_process=in_process,
                       watchdog=watchdog(arguments.probe_timeout)) as pool:
            if in_process is None:  # the workers run the original: the engine's imports meanwhile
                ahead = import_ahead()
            progress.note(f"simulating the original world ({len(world)} models, seed {arguments.seed}; "
                          f"{_where(pool)})")
            original = pool.call(world, 0, record=records_runs(arguments.media))
            if original.error is None or is_run_error(original.error):
                return _does_not_fail(arguments, original)
            progress.note(f"it fails: {_failure_text(original)}; reducing")
            outcome, interrupted = _reduce(arguments, world, original, predicates, keep, priority, pool,
                                           progress)
    finally:
        progress.close()
        if ahead is not None:  # never exit while it imports (see driver.IMPORT_AHEAD_WAIT)
            ahead.join(IMPORT_AHEAD_WAIT)
    if outcome.report is None:  # nothing reduced: the failure does not depend on the world
        print(f"ddenv: {arguments.world}: {outcome.message}", file=sys.stderr)
        if arguments.json:
            print_json({"ok": False, "status": outcome.status, "error": outcome.message,
                        "exit_code": EXIT_FAILED})
        return EXIT_FAILED
    pictures = [str(p) for p in outcome.attachments if p.suffix == ".png"]
    media = [str(p) for p in outcome.attachments if p.suffix in (".gif", ".rrd")]
    emit(arguments, _reduction_text(arguments.world, outcome.report, pictures, media),
         {"ok": True, **outcome.report.to_json(), "pictures": pictures, "media": media,
          "dropped": dropped_models(world)})
    return EXIT_INTERRUPTED if interrupted else EXIT_OK


def _where(pool: Pool[Any]) -> str:
    if pool.in_process:
        return "in this process"
    return f"{pool.size} workers"


def _failure_text(result: Any) -> str:
    error = result.error
    if error.signature is not None:
        return f"{error.signature.predicate} at t = {error.signature.time:.2f} s"
    return f"{error.type_name} at {error.location}"


def _keep(world: World, names: Sequence[str]) -> tuple[str, ...]:
    unknown = sorted(set(names) - set(world.names))
    if unknown:
        raise UsageError(f"--keep: no model named {', '.join(map(repr, unknown))} in the world")
    return tuple(sorted(set(names) | {m.name for m in world.models if m.keep}))


def _does_not_fail(arguments: argparse.Namespace, result: Any) -> int:
    if result.error is not None and is_exit(result.error):  # the code under test exited: an error, never a pass
        raise UserCodeExit(f"{arguments.world}: {result.error.message}")
    if result.error is not None and hit_wall_clock_cap(result.error):  # an error of the run, nothing to reduce
        message = (f"{arguments.world}: {wall_clock_cap_message(result.error.location)} "
                   f"({result.error.message.replace(RUN_TIMEOUT_HINT, 'ddenv reduce --run-timeout SECONDS')})")
        print(f"ddenv: {message}", file=sys.stderr)
        if arguments.json:
            print_json({"ok": False, "error": message, "exit_code": EXIT_FAILED, "outcome": "error"})
        return EXIT_FAILED
    if result.error is not None:  # the scenario cannot be run at all: an input error
        raise UsageError(f"{arguments.world}: the scenario could not be run: {result.error.describe()}")
    run = result.run
    outcome = "reached the goal" if run is not None and run.reached_goal else "no failure predicate fired"
    simulated = "" if run is None else f" after {run.sim_time:.1f} s simulated"
    message = (f"{arguments.world}: the original world does not fail with seed {arguments.seed} ({outcome}"
               f"{simulated}); nothing to reduce. Check the --predicate options with `ddenv run`.")
    print(f"ddenv: {message}", file=sys.stderr)
    if arguments.json:
        print_json({"ok": False, "error": message, "exit_code": EXIT_FAILED,
                    "outcome": "no_run" if run is None else run_outcome(run)})
    return EXIT_FAILED


def _reduce(arguments: argparse.Namespace, world: World, original: Any, predicates: Sequence[PredicateSpec],
            keep: tuple[str, ...], priority: str, pool: Any,
            progress: ProgressLine) -> tuple[Any, bool]:
    from pytest_ddenv.driver.run import interrupted_outcome, run_reduction
    from pytest_ddenv.reduce import ReductionInterrupted

    try:
        plan = reduction_plan(arguments, world, original, predicates, keep, priority)
        return run_reduction(plan, pool, note=progress.note, on_progress=progress.update), False
    except ReductionInterrupted as stop:
        progress.note("interrupted: the best world found so far is written")
        outcome = interrupted_outcome(stop)
        if outcome is None:  # pragma: no cover - run_reduction always writes its outcome before it re-raises
            raise
        return outcome, True
    finally:
        progress.close()


def _reduction_text(path: str, report: ReductionReport, pictures: Sequence[str], media: Sequence[str]) -> str:
    from pytest_ddenv.driver.report_text import result_lines, status_of

    reduction = report.reduction
    return "\n".join([
        (f"{path}: {reduction.original_size} -> {reduction.minimal_size} models "
         f"({report.reduction_percent}% removed), {status_of(reduction)}"),
        *result_lines(report),
        f"artifacts: {report.files.folder}",
        f"pictures: {', '.join(pictures) or '(none)'}",
        *([f"animations and recording: {', '.join(media)}"] if media else []),
        f"replay: {report.replay}",
    ])
