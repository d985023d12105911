"""Runs the stages keep besides their verdicts: a failing run of a world they measured (the path the time
stage searches along, the run `simplified.png` draws), taken from runs they make anyway."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from pytest_ddenv.outcome import Outcome
from pytest_ddenv.scenario.probe import ProbeResult
from pytest_ddenv.stages.context import FRESH_ATTEMPTS, StageContext

if TYPE_CHECKING:
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World


class _Recording:
    """A stage's call that keeps the run of each attempt it makes."""

    def __init__(self, context: StageContext) -> None:
        self.call = context.call
        self.runs: dict[int, Run] = {}

    def __call__(self, world: World, attempt: int) -> ProbeResult:
        result = self.call(world, attempt)
        if result.run is not None:
            self.runs[attempt] = result.run
        return result


def measure(context: StageContext, stage: str, label: str, world: World, runs: int, *,
            first_attempt: int = FRESH_ATTEMPTS, stage_begin: int | None = None
            ) -> tuple[int, int, int, Run | None]:
    """`context.measure(...)` and the first of its runs simulated now that failed the same way (None: none,
    or every outcome came from the log)."""
    recording = _Recording(context)
    fails, counted, errors = dataclasses.replace(context, call=recording).measure(
        stage, label, world, runs, first_attempt=first_attempt, stage_begin=stage_begin)
    outcomes = context.log.view(stage).measured("failure-rate", [label])
    failing = next((recording.runs[attempt] for attempt in sorted(recording.runs)
                    if outcomes.get(attempt) is Outcome.FAIL), None)
    return fails, counted, errors, failing
