"""The stages after the models (`stages/`) as a phase of the reduction: from the minimal world, within their
budget, on the reduction's pool, and the passing run for `passing.png`."""

from __future__ import annotations

import concurrent.futures
from typing import TYPE_CHECKING

from pytest_ddenv.driver import artifacts
from pytest_ddenv.driver.calls import Calls
from pytest_ddenv.driver.logged_runs import logged_run
from pytest_ddenv.execution import Pool
from pytest_ddenv.reduce import Outcome, ProbeLog, Reduction, events
from pytest_ddenv.reduce.deflake import make_policy
from pytest_ddenv.scenario.probe import ProbeResult
from pytest_ddenv.stages import (
    DEFAULT_STAGES,
    StageBudget,
    StageContext,
    StagesOutcome,
    run_stages,
    stage_budget,
    stage_policy,
)

if TYPE_CHECKING:
    from pytest_ddenv.driver.plan import ReductionPlan
    from pytest_ddenv.sim import Run


def run_stages_after_models(plan: ReductionPlan, pool: Pool[ProbeResult], reduction: Reduction, calls: Calls,
                            log: ProbeLog, paths: artifacts.ArtifactPaths, minimal_run: Run | None) -> StagesOutcome:
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
    run, _ = logged_run(calls, log, world, 0, "picture", False)
    last = log.events[-1]
    if run is not None and isinstance(last, events.Probe) and last.result is Outcome.PASS:  # as it was classified
        staged.passing_run = run
