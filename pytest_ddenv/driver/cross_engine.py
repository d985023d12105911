"""After a reduction, its minimal and original worlds in other physics engines (`--ddenv-confirm-engines`).

Each world is run on fresh attempts in each named engine, as many as the reduction's own fresh runs of it
(the minimal world's failure-rate runs, the original's runs of the rate comparison; `DEFAULT_RUNS` when the
reduction measured none), with the same attempts (seeds) where the run log has them, on the reduction's pool
and budget (`Calls`), each classified by the reduction's same-failure rule. Both engines' rates are reported
with their Wilson intervals (`CONFIDENCE`); when another engine's rate is clearly below the reduction's engine's
(`rates.clearly_below`: the one-sided Fisher exact test of the end-of-run comparison, at 5 %), the failure is
flagged as possibly an artefact of the reduction's engine: never a pass, the test still fails.

Every run is in the reduction's simulations and CPU time (the pool's counters) and in the run log as an
`events.EngineRun` keyed by the engine and its version: a resumed reduction reuses a completed run only for
the same world, attempt, engine and version (the log itself is resumed only for the same world and code).
"""

from __future__ import annotations

import concurrent.futures
import functools
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from pytest_ddenv.driver.calls import Calls
from pytest_ddenv.oracle.verdict import classify_result
from pytest_ddenv.reduce import Outcome, ProbeLog, Reduction, events
from pytest_ddenv.reduce.rates import Rate, clearly_below, wilson_interval
from pytest_ddenv.scenario.probe import signature_record
from pytest_ddenv.world.limits import engine_version

if TYPE_CHECKING:
    from pytest_ddenv.execution import Pool
    from pytest_ddenv.scenario.probe import ProbeResult
    from pytest_ddenv.world.model import World

CONFIDENCE = 0.95
"""The confidence of the Wilson intervals reported."""
DEFAULT_RUNS = 10
"""Runs of a world in each engine when the reduction made no fresh runs of it (its budget ran out first)."""


@dataclass(frozen=True)
class EngineRate:
    """How often one world failed the same way in one engine: `fails` of `runs` (ERROR runs apart, in `errors`;
    `reused`: runs taken from the run log of an earlier, interrupted run of this reduction)."""

    engine: str
    version: str
    fails: int
    runs: int
    errors: int = 0
    reused: int = 0

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(Rate(self.fails, self.runs), CONFIDENCE)

    def describe(self) -> str:
        """"in mujoco 9/10 [0.60, 0.98]"."""
        low, high = self.interval
        errors = f" ({self.errors} more errored)" if self.errors else ""
        return f"in {self.engine} {self.fails}/{self.runs} [{low:.2f}, {high:.2f}]{errors}"

    def to_json(self) -> dict[str, Any]:
        low, high = self.interval
        return {"engine": self.engine, "version": self.version, "fails": self.fails, "runs": self.runs,
                "errors": self.errors, "interval": [round(low, 4), round(high, 4)], "reused": self.reused}


@dataclass(frozen=True)
class WorldRates:
    """One world ("minimal" or "original") in the reduction's engine (`main`) and in the others."""

    world: str
    main: EngineRate
    others: tuple[EngineRate, ...]

    @property
    def not_reproduced_in(self) -> tuple[str, ...]:
        """The engines whose rate is clearly below the reduction's engine's (`rates.clearly_below`)."""
        reference = Rate(self.main.fails, self.main.runs)
        return tuple(other.engine for other in self.others if clearly_below(Rate(other.fails, other.runs), reference))

    @property
    def flag(self) -> str | None:
        """"possibly an artefact of the pybullet physics" when another engine does not reproduce the failure."""
        return f"possibly an artefact of the {self.main.engine} physics" if self.not_reproduced_in else None

    def describe(self) -> str:
        rates = ", ".join(rate.describe() for rate in (self.main, *self.others))
        flag = self.flag
        if flag is None:
            return f"fails {rates}"
        return f"fails {rates}: {flag} ({', '.join(self.not_reproduced_in)} does not reproduce it)"

    def to_json(self) -> dict[str, Any]:
        return {"rates": [rate.to_json() for rate in (self.main, *self.others)],
                "not_reproduced_in": list(self.not_reproduced_in), "flag": self.flag}


@dataclass(frozen=True)
class CrossEngine:
    """The cross-engine confirmation of a reduction: both worlds' rates and what the runs cost."""

    engine: str
    """The reduction's engine."""
    minimal: WorldRates
    original: WorldRates
    simulations: int
    """Runs started in this run of the driver (the reused ones not included)."""
    cpu_seconds: float
    wall_seconds: float
    notes: tuple[str, ...] = ()

    @property
    def flag(self) -> str | None:
        """The minimal world's flag, else the original's."""
        return self.minimal.flag or self.original.flag

    def lines(self) -> list[str]:
        """The report section's lines."""
        reused = sum(rate.reused for world in (self.minimal, self.original) for rate in world.others)
        reused_text = f", {reused} more from the run log" if reused else ""
        return [f"cross-engine: minimal world {self.minimal.describe()}",
                f"cross-engine: original world {self.original.describe()}",
                (f"cross-engine cost: {self.simulations} simulations{reused_text}, {self.cpu_seconds:.1f} s of worker "
                 f"CPU, {self.wall_seconds:.1f} s wall (Wilson {CONFIDENCE:.0%} intervals)"),
                *(f"note: {note}" for note in self.notes)]

    def terminal(self) -> str:
        """The terminal line's words: the minimal world's rates, and the flag."""
        rates = ", ".join(rate.describe() for rate in (self.minimal.main, *self.minimal.others))
        flag = self.flag
        return f"fails {rates}" + ("" if flag is None else f", {flag}")

    def to_json(self) -> dict[str, Any]:
        return {"engine": self.engine, "confidence": CONFIDENCE, "minimal": self.minimal.to_json(),
                "original": self.original.to_json(), "flag": self.flag, "simulations": self.simulations,
                "cpu_seconds": round(self.cpu_seconds, 3), "wall_seconds": round(self.wall_seconds, 3),
                "notes": list(self.notes)}


@dataclass(frozen=True)
class _Run:
    """One run to make: in `engine`, of the world `kind` ("minimal"/"original", `world` in that engine), on
    `attempt`."""

    engine: str
    kind: str
    world: World = field(compare=False, hash=False)
    attempt: int = 0


def confirm_in_engines(engines: tuple[str, ...], original: World, reduction: Reduction, calls: Calls,
                       log: ProbeLog, pool: Pool[ProbeResult], *, max_probes: int | None) -> CrossEngine:
    """Run `reduction`'s minimal world and the `original` world in each of `engines` (the reduction's own
    engine, `original.physics.engine`, is skipped with a note) and measure how often each fails the same way."""
    main = original.physics.engine
    notes = [f"confirm_engines names {main}, the engine the reduction ran in: its rates are the reduction's own"
             ] if main in engines else []
    others = tuple(engine for engine in engines if engine != main)
    worlds = {"minimal": original.select(reduction.minimal), "original": original}
    own = _own_rates(reduction, original)
    plan: list[_Run] = []
    for kind, world in worlds.items():
        # an original whose runs the rate comparison did not need (rates.settled): as many as the minimal world's
        attempts = _attempts(log, kind, world, own[kind] or own["minimal"])
        for engine in ((main,) if own[kind] is None else ()) + others:
            plan += [_Run(engine, kind, world.with_engine(engine), attempt) for attempt in attempts]
    reused = _reused(log, plan)
    to_run = [run for run in plan if run not in reused]
    left = None if max_probes is None else max(0, max_probes - calls.started)
    if left is not None and left < len(to_run):
        notes.append(f"the budget ran out: {len(to_run) - left} of the cross-engine runs were not made")
        to_run = to_run[:left]
    before, started = pool.stats, time.monotonic()
    outcomes = {**reused, **_run_all(to_run, calls, log, pool.size)}
    after = pool.stats
    rates = {(engine, kind): _rate(engine, kind, plan, outcomes, reused)
             for engine in (main, *others) for kind in worlds}

    def world_rates(kind: str) -> WorldRates:
        known = own[kind]
        main_rate = rates[(main, kind)] if known is None else EngineRate(main, engine_version(main), *known)
        return WorldRates(kind, main_rate, tuple(rates[(engine, kind)] for engine in others))

    return CrossEngine(main, world_rates("minimal"), world_rates("original"),
                       simulations=after.simulations - before.simulations,
                       cpu_seconds=max(0.0, after.cpu_seconds - before.cpu_seconds),
                       wall_seconds=time.monotonic() - started, notes=tuple(notes))


def _own_rates(reduction: Reduction, original: World) -> dict[str, tuple[int, int] | None]:
    """(fails, runs) of each world's fresh runs in the reduction's engine, from the reduction (None: none made)."""
    minimal = reduction.failure_rate if reduction.failure_rate[1] else None
    whole = reduction.original_failure_rate
    if whole is None and frozenset(reduction.minimal) == frozenset(original.names):
        whole = minimal  # nothing was removed: one world
    return {"minimal": minimal, "original": whole if whole is not None and whole[1] else None}


def _attempts(log: ProbeLog, kind: str, world: World, own: tuple[int, int] | None) -> list[int]:
    """The attempts to run `world` on: those of the reduction's own fresh runs of it (the same seeds), as many
    as it counted; attempts 1.. (after the reference run's 0) when the log holds none."""
    wanted = DEFAULT_RUNS if own is None else own[1]
    logged = log.measured("failure-rate", world.names)
    if kind == "original":
        logged = {**log.measured("calibration", world.names), **logged}
    attempts = sorted(attempt for attempt in logged if attempt > 0 or kind == "minimal")[:wanted]
    following = max(attempts, default=0) + 1
    return attempts + list(range(following, following + wanted - len(attempts)))


def _engine_text(engine: str) -> str:
    return f"{engine} {engine_version(engine)}"


def _reused(log: ProbeLog, plan: list[_Run]) -> dict[_Run, Outcome]:
    """The runs of `plan` that an earlier run of this reduction completed (same world, attempt, engine and
    version; ERROR runs are made again)."""
    wanted = {(_engine_text(run.engine), frozenset(run.world.names), run.attempt): run for run in plan}
    found: dict[_Run, Outcome] = {}
    for event in log.events:
        if isinstance(event, events.EngineRun) and event.result is not Outcome.ERROR:
            run = wanted.get((event.engine, frozenset(event.candidate), event.attempt))
            if run is not None:
                found[run] = event.result
    return found


def _run_all(runs: list[_Run], calls: Calls, log: ProbeLog, workers: int) -> dict[_Run, Outcome]:
    """Make `runs` on the pool, `workers` at a time (one: in this thread, as the engine's probes of an
    in-process pool, whose wall-clock alarm needs the main thread); each logged in this thread as it completes."""
    outcomes: dict[_Run, Outcome] = {}

    def finished(run: _Run, result: ProbeResult | None) -> None:
        outcome = Outcome.ERROR if result is None else classify_result(result.error, calls.reference, calls.rule)
        outcomes[run] = outcome
        _log(log, run, result, outcome)

    if workers <= 1:
        for run in runs:
            finished(run, _made(functools.partial(calls, run.world, run.attempt)))
        return outcomes
    threads = concurrent.futures.ThreadPoolExecutor(workers, thread_name_prefix="ddenv-cross-engine")
    try:
        futures = {threads.submit(calls, run.world, run.attempt): run for run in runs}
        for future in concurrent.futures.as_completed(futures):
            finished(futures[future], _made(future.result))
    finally:
        threads.shutdown(wait=False, cancel_futures=True)
    return outcomes


def _made(call: Callable[[], ProbeResult]) -> ProbeResult | None:
    """What `call` returned; None when it raised (a worker that died, the time budget): an error, never a
    verdict."""
    try:
        return call()
    except Exception:  # noqa: BLE001
        return None


def _log(log: ProbeLog, run: _Run, result: ProbeResult | None, outcome: Outcome) -> None:
    ran = None if result is None else result.run
    log.write(events.EngineRun(
        engine=_engine_text(run.engine), world=run.kind, candidate=run.world.names, attempt=run.attempt,
        seed=None if ran is None else int(ran.seed), outcome=outcome.value,
        signature=None if result is None else signature_record(result.error),
        sim_time=None if ran is None else float(ran.sim_time), wall_time=None if ran is None else float(ran.wall_time)))


def _rate(engine: str, kind: str, plan: list[_Run], outcomes: Mapping[_Run, Outcome],
          reused: Mapping[_Run, Outcome]) -> EngineRate:
    made = [run for run in plan if run.engine == engine and run.kind == kind and run in outcomes]
    counted = [outcomes[run] for run in made if outcomes[run] is not Outcome.ERROR]
    return EngineRate(engine, engine_version(engine), sum(outcome is Outcome.FAIL for outcome in counted),
                      len(counted), errors=len(made) - len(counted), reused=sum(run in reused for run in made))
