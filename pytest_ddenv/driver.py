"""The one reduction driver: confirm a failure on a probe pool, reduce its world, write the artifacts.

The pytest plugin, the `ddenv reduce` command and the benchmarks all call `run_reduction` with a `Pool`
serving their job (the user's test, or a world's scenario); they differ only in how they build the job
and word the result. No pytest import.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import signal
import threading
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv import artifacts
from pytest_ddenv.execution import Pool, WorkerError, WorkerStartError
from pytest_ddenv.markers import ReductionSpec
from pytest_ddenv.probe import (
    FailureReference,
    ProbeResult,
    classify_result,
    keeps_start_support,
    make_probe,
    trace_of,
)
from pytest_ddenv.reduce import Outcome, ProgressEvent, Reduction, ReductionInterrupted, reduce

if TYPE_CHECKING:
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world import World

TRAJECTORY_PARTITIONS = ("timeseg", "trajectoryseg")
TRAJECTORY_PRIORITIES = ("failure-proximal", "avg-trajectory-proximal", "min-trajectory-proximal", "timestep")
BUDGETS = ("max_probes", "max_seconds")
"""Settings that do not change the problem: a run with another budget resumes the same log."""
AUTO_CONFIRMATIONS = 4
"""Runs that may confirm the failure with deflake="auto"/"adaptive" (1 + the paper's default 3 re-runs)."""


@dataclass(frozen=True)
class ReductionPlan:
    """What to reduce and how.

    `reference` is the failure to reproduce and `reference_run` the run it happened in (None: the test
    made no run and reported none, so trajectory-guided schemas fall back). `confirmed`: the failure was
    already seen on the pool (skip the confirmation runs). `fingerprint` identifies the problem for resume.
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
    confirmed: bool = False
    summary_extra: Mapping[str, Any] = field(default_factory=dict)
    model_paths: tuple[str, ...] = ()
    """The folders the world's SDF `model://` includes were found in (to cut `minimal.sdf` from the file)."""


@dataclass
class ReductionOutcome:
    """What `run_reduction` did. `status`: "reduced" (maybe incomplete: see the reduction), "not-reproducible"
    (the confirmation runs never failed the same way) or "error" (the test could not be run: `message`)."""

    status: str
    message: str = ""
    reduction: Reduction | None = None
    summary: dict[str, Any] | None = None
    attachments: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    interrupted: ReductionInterrupted | None = None
    minimal_run: Run | None = None


Note = Callable[[str], None]


def run_reduction(plan: ReductionPlan, pool: Pool, *, note: Note = lambda text: None,
                  on_progress: Callable[[ProgressEvent], None] | None = None) -> ReductionOutcome:
    """Confirm `plan.reference` on `pool`, reduce `plan.world`, write the artifacts; see `ReductionOutcome`.

    Raises `ReductionInterrupted` on Ctrl-C or SIGTERM, after writing the best world so far (the
    outcome is attached as `.outcome`)."""
    spec, world = plan.spec, plan.world
    if not getattr(pool, "in_process", False):  # this process waits for the workers: import meanwhile
        threading.Thread(target=_import_ahead, name="ddenv-import-ahead", daemon=True).start()
    call = _checked_call(pool)
    if not plan.confirmed:
        failed = _confirm(plan, call, note)
        if failed is not None:
            return failed
    partition, priority, notes = _schemas(spec, plan.reference_run)
    for text in notes:
        note(text)
    settings = {key: value for key, value in plan.fingerprint.items() if key not in BUDGETS}
    problem = artifacts.fingerprint(world, {**settings, "partition": partition, "priority": priority},
                                    plan.test_source)
    paths = artifacts.prepare(plan.artifacts, problem)
    keep = (set(spec.keep) & set(world.names)) | {m.name for m in world.models if m.keep}
    probe = make_probe(world, call, plan.reference, tolerance=spec.tolerance)
    threads = concurrent.futures.ThreadPoolExecutor(pool.size, thread_name_prefix="ddenv-probe") if pool.size > 1 else None
    interrupted: ReductionInterrupted | None = None
    try:
        with _sigterm_as_interrupt():
            reduction = reduce(
                world.names, probe, geometry=world,
                reference=trace_of(plan.reference_run) if plan.reference_run is not None else None,
                partition=partition, priority=priority, n_partitions=spec.n_partitions,
                granularity=spec.granularity, deflake=spec.deflake, keep=tuple(sorted(keep)),
                preconditions=(keeps_start_support(world),), max_probes=spec.max_probes,
                max_seconds=spec.max_seconds, seed=spec.seed, log=paths.log, on_progress=on_progress,
                executor=threads,
            )
    except ReductionInterrupted as stop:
        interrupted, reduction = stop, stop.reduction
        pool.close()  # first: probe threads blocked on workers return at once
    finally:
        if threads is not None:
            threads.shutdown(wait=interrupted is None, cancel_futures=True)
    summary = artifacts.write_reduction(
        paths, world, reduction, test_id=plan.test_id, replay_command=plan.replay_command,
        problem_fingerprint=problem, reference=plan.reference.to_dict(), model_paths=plan.model_paths,
        extra={**plan.summary_extra, "tolerance": spec.tolerance, "workers": pool.stats.to_dict(),
               "notes": notes, "world_notes": list(world.notes)},
    )
    outcome = ReductionOutcome("reduced", reduction=reduction, summary=summary, notes=notes,
                               attachments=[paths.minimal_yaml, paths.log, paths.summary], interrupted=interrupted)
    if interrupted is None:
        outcome.minimal_run = _minimal_run(call, world.select(reduction.minimal))
        outcome.attachments += _pictures(world, reduction, paths, plan.reference_run, outcome.minimal_run)
    outcome.attachments = [path for path in outcome.attachments if path.exists()]
    if interrupted is not None:
        interrupted.outcome = outcome  # type: ignore[attr-defined]
        raise interrupted
    return outcome


HEAVY_IMPORTS = ("sklearn.cluster", "sklearn.linear_model", "matplotlib.pyplot", "matplotlib.collections")
"""What the schemas and the pictures import on first use (about 1.5 s together): imported while the first
probes run in the workers, so that the engine's first round does not wait for scikit-learn."""


def _import_ahead() -> None:
    import importlib

    for module in HEAVY_IMPORTS:
        if module.startswith("matplotlib"):
            import matplotlib

            matplotlib.use("Agg")  # as render.py does: no display
        try:
            importlib.import_module(module)
        except ImportError:  # pragma: no cover - the dependencies are installed with the package
            return


def _checked_call(pool: Pool) -> Callable[[World, int], ProbeResult]:
    def call(world: World, attempt: int) -> ProbeResult:
        result = pool.call(world, attempt)
        if not isinstance(result, ProbeResult):
            raise TypeError(f"the pool's job returned {type(result).__name__}, not a ProbeResult")
        return result

    return call


def _confirm(plan: ReductionPlan, call: Callable[[World, int], ProbeResult], note: Note) -> ReductionOutcome | None:
    """None when the failure reproduces on the pool; else the outcome that says why it does not."""
    deflake = plan.spec.deflake
    runs = 1 + deflake if isinstance(deflake, int) else AUTO_CONFIRMATIONS
    seen: list[str] = []
    errors: list[str] = []
    for attempt in range(runs):
        note(f"confirming the failure ({attempt + 1}/{runs})")
        try:
            result = call(plan.world, attempt)
        except WorkerStartError as error:
            return ReductionOutcome("error", message=f"the test could not be run in a probe worker: {error}")
        except WorkerError as error:
            errors.append(str(error))
            seen.append("error")
            continue
        outcome = classify_result(result.error, plan.reference, plan.spec.tolerance)
        if outcome is Outcome.FAIL:
            return None
        if outcome is Outcome.ERROR and result.error is not None:
            errors.append(result.error.describe() + ("\n" + result.error.traceback if result.error.traceback else ""))
        seen.append(outcome.value if result.error is None or outcome is Outcome.ERROR
                    else f"{outcome.value} ({result.error.type_name} at {result.error.location})")
    if errors and len(errors) == runs:
        return ReductionOutcome("error", message=f"every confirmation run of the test raised an error instead of "
                                f"running; the first one:\n{errors[0]}")
    return ReductionOutcome(
        "not-reproducible",
        message=(f"not reproducible: 0 of {runs} re-runs failed the same way ({plan.reference.describe()}); they "
                 f"gave: {', '.join(seen)}. No reduction was run. The failure may depend on state outside the "
                 "world (other fixtures, globals) or on the seed; try a larger --ddenv-deflake."),
    )


def _schemas(spec: ReductionSpec, reference_run: Run | None) -> tuple[str, str, list[str]]:
    """The partition and priority to use, and notes on any fallback (no trajectory to guide them)."""
    partition, priority, notes = spec.partition, spec.priority, []
    if reference_run is None:
        why = "the test made no robot_world.run() and no robot_world.report(), so there is no trajectory"
        if partition in TRAJECTORY_PARTITIONS:
            notes.append(f"{why}: partition {partition} -> model2model")
            partition = "model2model"
        if priority in TRAJECTORY_PRIORITIES:
            notes.append(f"{why}: priority {priority} -> sequential")
            priority = "sequential"
    return partition, priority, notes


def _minimal_run(call: Callable[[World, int], ProbeResult], minimal: World) -> Run | None:
    """The minimal world's attempt-0 run, for the pictures (None if it cannot be had)."""
    try:
        return call(minimal, 0).run
    except Exception:  # noqa: BLE001 - pictures are a convenience
        return None


def _pictures(world: World, reduction: Reduction, paths: artifacts.ArtifactPaths, original_run: Run | None,
              minimal_run: Run | None) -> list[Path]:
    """reduction.png and progress.png (the original and the minimal world's failing trajectories)."""
    try:
        from pytest_ddenv import render

        return list(render.write_reduction_pictures(world, reduction, paths, original_run=original_run,
                                                    minimal_run=minimal_run))
    except Exception as error:  # noqa: BLE001 - pictures are a convenience; never lose the reduction over one
        warnings.warn(f"ddenv: pictures not written: {type(error).__name__}: {error}", stacklevel=1)
        return []


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
