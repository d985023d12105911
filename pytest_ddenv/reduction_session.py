"""Reduce the world of one failed scenario test: confirm, reduce, write artifacts, describe the result.

Called by the plugin from inside the test's call phase, after the test raised. Each probe calls the test
function again with `robot_world` rebound to the candidate world; everything else the test received is
passed unchanged.
"""

from __future__ import annotations

import contextlib
import inspect
import signal
import threading
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv import artifacts
from pytest_ddenv.markers import ReductionSpec, parse_deflake
from pytest_ddenv.plugin import FIXTURE, replay_command
from pytest_ddenv.probe import (
    FailureReference,
    keeps_start_support,
    make_probe,
    reference_from,
    trace_of,
)
from pytest_ddenv.reduce import Outcome, Reduction, reduce
from pytest_ddenv.reduce.types import ProgressEvent, ReductionInterrupted
from pytest_ddenv.robot_world import RobotWorld

if TYPE_CHECKING:
    from pytest_ddenv.execution import Pool
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world import World

Progress = Callable[..., None]


@dataclass
class ReductionSession:
    item: pytest.Function
    error: BaseException
    spec: ReductionSpec
    artifacts_root: Path
    deflake: str | int | None
    max_probes: int | None
    max_seconds: float | None
    progress: Progress
    pool: Pool | None = None

    def run(self) -> dict[str, Any]:
        robot_world: RobotWorld = self.item.funcargs[FIXTURE]  # type: ignore[assignment]
        world = robot_world.world
        reference = reference_from(self.error, self.item.path)
        deflake = self.spec.deflake if self.deflake in (None, "") else parse_deflake(self.deflake, "--ddenv-deflake")
        run_test = self._runner(robot_world)
        probe = make_probe(world, run_test, reference, tolerance=self.spec.tolerance, test_file=self.item.path)
        confirmations = 1 + (deflake if isinstance(deflake, int) else 3)
        confirmed = 0
        for attempt in range(confirmations):
            self.progress(f"confirming the failure ({attempt + 1}/{confirmations})")
            if probe(world.names, attempt).outcome is Outcome.FAIL:
                confirmed = attempt + 1
                break
        if not confirmed:
            return self._not_reproducible(world, reference, confirmations)

        settings = {**self.spec.__dict__, "deflake": deflake, "test": self.item.nodeid}
        try:
            test_source = inspect.getsource(self.item.obj)
        except (OSError, TypeError):
            test_source = ""
        problem = artifacts.fingerprint(world, settings, test_source)
        paths = artifacts.prepare(self.artifacts_root / artifacts.artifact_dir_name(self.item.nodeid), problem)
        keep = (set(self.spec.keep) & set(world.names)) | {m.name for m in world.models if m.keep}
        last_run: Run | None = robot_world.runs[-1] if robot_world.runs else None
        interrupted: ReductionInterrupted | None = None
        threads = _probe_threads(self.pool)
        try:
            with _sigterm_as_interrupt():
                reduction = reduce(
                    world.names,
                    probe,
                    geometry=world,
                    reference=trace_of(last_run) if last_run is not None else None,
                    partition=self.spec.partition,
                    priority=self.spec.priority,
                    n_partitions=self.spec.n_partitions,
                    granularity=self.spec.granularity,
                    deflake=deflake,
                    keep=tuple(sorted(keep)),
                    preconditions=(keeps_start_support(world),),
                    max_probes=self.max_probes or self.spec.max_probes,
                    max_seconds=self.max_seconds or self.spec.max_seconds,
                    seed=self.spec.seed,
                    log=paths.log,
                    on_progress=self._on_progress,
                    executor=threads,
                )
        except ReductionInterrupted as stop:
            interrupted, reduction = stop, stop.reduction
            if self.pool is not None:
                self.pool.close()  # first: probe threads blocked on simulations return at once
        finally:
            if threads is not None:
                threads.shutdown(wait=interrupted is None, cancel_futures=True)
        summary = artifacts.write_reduction(
            paths, world, reduction,
            test_id=self.item.nodeid,
            replay_command=replay_command(self.item, paths.minimal_yaml),
            problem_fingerprint=problem,
            reference=reference.to_dict(),
            extra={
                "confirmed_on_attempt": confirmed,
                "predicates": [{"name": p.name, "params": dict(p.params)} for p in robot_world.predicates],
                "tolerance": self.spec.tolerance,
                "scenario_seed": robot_world.seed,
                "workers": None if self.pool is None else self.pool.stats.to_dict(),
            },
        )
        attachments = [paths.minimal_yaml, paths.log, paths.summary]
        if interrupted is None:
            minimal_run = run_test(world.select(reduction.minimal), 0)[1]
            attachments += _pictures(world, reduction, paths, last_run, minimal_run)
        result = self._describe(world, reduction, summary, [str(p) for p in attachments if p.exists()])
        self.progress(result["line"], final=True)
        if interrupted is not None:
            raise interrupted
        return result

    def _runner(self, robot_world: RobotWorld) -> Callable[[World, int], tuple[BaseException | None, Run | None]]:
        arguments = {name: self.item.funcargs[name] for name in inspect.signature(self.item.obj).parameters
                     if name in self.item.funcargs}

        def run_test(candidate: World, attempt: int) -> tuple[BaseException | None, Run | None]:
            rebound = robot_world.rebound(
                candidate, attempt=attempt, simulate=None if self.pool is None else self.pool.simulate
            )
            try:
                self.item.obj(**{**arguments, FIXTURE: rebound})
            except Exception as error:  # noqa: BLE001 - every exception is an outcome to classify
                return error, rebound.runs[-1] if rebound.runs else None
            return None, rebound.runs[-1] if rebound.runs else None

        return run_test

    def _on_progress(self, event: ProgressEvent) -> None:
        probe_line = None
        if event.kind == "probe" and event.candidate is not None and event.outcome is not None:
            probe_line = f"probe {event.probes}: {len(event.candidate)} models -> {event.outcome.value}"
        self.progress(f"reducing {self.item.name}: {event.size} models, {event.probes} probes", probe_line=probe_line)

    def _not_reproducible(self, world: World, reference: FailureReference, runs: int) -> dict[str, Any]:
        text = (
            f"not reproducible: 0 of {runs} re-runs failed the same way ({reference.describe()}); "
            "no reduction was run. The failure may depend on state outside the world (other fixtures, "
            "globals) or on the seed; try a larger --ddenv-deflake."
        )
        line = f"{self.item.nodeid}: {text}"
        return {"text": text + "\n", "line": line, "attachments": [], "reproducible": False}

    def _describe(self, world: World, reduction: Reduction, summary: dict[str, Any],
                  attachments: list[str]) -> dict[str, Any]:
        fails, runs = reduction.failure_rate
        status = "1-minimal" if reduction.one_minimal else f"incomplete ({reduction.incomplete_reason})"
        removed = summary["removed_models"]
        folder = _shown_path(Path(summary["files"]["summary"]).parent)
        text = "\n".join([
            f"world: {summary['world']}",
            f"reduced {reduction.original_size} -> {reduction.minimal_size} models "
            f"({summary['reduction_percent']}%), {status}",
            f"minimal world: {', '.join(reduction.minimal) or '(no models)'}",
            f"removed ({len(removed)}): {_listing(removed)}",
            f"probes: {reduction.probes} simulated, {reduction.cache_hits} from cache, "
            f"{reduction.skipped} skipped, {reduction.errors} errors; {reduction.wall_time:.1f} s",
            f"schemas: {reduction.partition} + {reduction.priority}, deflake={reduction.deflake}",
            artifacts.failure_rate_line(reduction),
            f"artifacts: {folder}",
            f"replay: {summary['replay']}",
        ]) + "\n"
        line = (
            f"{self.item.nodeid}: {reduction.original_size} -> {reduction.minimal_size} models "
            f"({summary['reduction_percent']:.0f}%), {reduction.probes} probes, {reduction.wall_time:.0f} s, "
            f"fails {fails}/{runs}{'' if reduction.one_minimal else ', ' + status} -> {folder}"
        )
        return {"text": text, "line": line, "attachments": attachments, "summary": summary, "reproducible": True}


def _probe_threads(pool: Pool | None) -> ThreadPoolExecutor | None:
    """Threads that run probes (the test function) while their simulations run in the pool's workers."""
    if pool is None or pool.size < 2:
        return None
    return ThreadPoolExecutor(pool.size, thread_name_prefix="ddenv-probe")


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


def _listing(names: list[str], limit: int = 12) -> str:
    if not names:
        return "(none)"
    shown = ", ".join(names[:limit])
    return shown if len(names) <= limit else f"{shown}, ... and {len(names) - limit} more (see summary.json)"


def _shown_path(path: Path) -> Path:
    """A path relative to the working directory when it is inside it (shorter terminal lines)."""
    try:
        return path.relative_to(Path.cwd())
    except ValueError:
        return path


def _pictures(
    world: World, reduction: Reduction, paths: artifacts.ArtifactPaths, original_run: Run | None,
    minimal_run: Run | None,
) -> list[Path]:
    """reduction.png and progress.png (the original and the minimal world's failing trajectories)."""
    try:
        from pytest_ddenv import render

        return list(render.write_reduction_pictures(
            world, reduction, paths, original_run=original_run, minimal_run=minimal_run
        ))
    except Exception as error:  # noqa: BLE001 - pictures are a convenience; never lose the reduction over one
        warnings.warn(f"ddenv: pictures not written: {type(error).__name__}: {error}", stacklevel=1)
        return []
