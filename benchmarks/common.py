"""Shared building blocks of the reduction benchmarks (paper_tables.py, scale.py).

Everything here drives the reduction through the same execution layer and probe as the plugin and `ddenv
reduce` (pytest_ddenv/driver/run.py): the test is a `ScenarioJob` (the world's scenario with the test's
predicates and noise seed: `RobotWorld(candidate, predicates, seed, attempt).run()`), served by a
`pytest_ddenv.execution` pool (`make_pool(job, workers, in_process=job.handler())`: 1 worker = the job's
handler in this process, as `ddenv reduce --workers 1`; N > 1 = N persistent local worker processes); the
probe is `pytest_ddenv.scenario.probe.make_probe(world, pool.call, ...)` (same failure = same predicate, failure
position within `tolerance` of the reference `FailureSignature`); the reference trace is the original
failing run's; the only precondition is `keeps_start_support(world)`, and `keep: true` models are kept.
With more than one worker the engine gets a ThreadPoolExecutor of as many threads, as the driver does.
The engine is called directly (`reduce`, not `driver.run_reduction`) because the benchmarks need finer
control than a whole reduction with artifacts: their own reduction seed and re-run noise seeds, no
failure-rate runs inside the timed reduction, and the very same probe for picire.

A pool serves one job, and a job has one predicate set and one noise seed: `Pools` (from `pool_of`) keeps
one pool per (predicates, seed), started and warmed (every worker has run the world once) before any
timing: worker start-up is never part of a measured wall time.

The picire adapter (`picire_reduce`) hands picire the *same* probe function: picire's config is a list of
indices into the world's reducible models; a config is FAIL iff our deflake rule (`deflake=N`: the first run,
then up to N re-runs, each with a fresh noise seed, FAIL as soon as one run gives our Outcome.FAIL) says
the candidate reproduces f; a candidate the precondition refuses is PASS without a simulation, as in our
engine. Attempt k of a candidate uses the noise seed `seed + (k + attempt_offset) * 1_000_003`, in both
tools: `seed` is the noise seed of the original failing run, `attempt_offset` (1000 x the reduction seed)
gives each reduction seed its own re-run seeds while the failure being reduced stays the same.
With `deflake="auto"` picire gets the rule our engine calibrated (e.g. 2-of-3: FAIL iff 2 of at most 3
runs fail), and the calibration runs are added to its simulations too (the rule includes them).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import dataclasses
import json
import os
import platform
import subprocess
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.execution import Pool, check_executor, make_pool, resolve_workers
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.reduce import Outcome, ProbeObservation, Reduction, reduce
from pytest_ddenv.reduce.deflake import CalibratedReruns, DeflakePolicy, FixedReruns
from pytest_ddenv.scenario.probe import FailureReference, ProbeResult, keeps_start_support, make_probe, trace_of
from pytest_ddenv.stages import scenario_models
from pytest_ddenv.world import World

ROOT = Path(__file__).resolve().parent.parent
TOLERANCE = 0.5
"""The plugin's default `tolerance` (ReductionSpec): same failure = failure position within 0.5 m."""
WARM_TIMEOUT = 0.1
"""Simulated seconds of the warm-up runs (the world is built, the robot spawned, a few ticks run)."""

STUCK = PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2})
HIGH_CENTERED = PredicateSpec("high_centered", {})


@dataclass(frozen=True)
class Scenario:
    name: str
    world: Path
    predicates: tuple[PredicateSpec, ...]


SCENARIOS: dict[str, Scenario] = {
    # the predicates of examples/test_paper_scenarios.py
    "ditch": Scenario("ditch", ROOT / "worlds" / "ditch.yaml", (STUCK,)),
    "rubble": Scenario("rubble", ROOT / "worlds" / "rubble.yaml", (HIGH_CENTERED, STUCK)),
    "friction": Scenario("friction", ROOT / "worlds" / "friction.yaml", (STUCK,)),
}


# -- pools: the execution layer ------------------------------------------------------------------------


def open_pool(job: ScenarioJob, workers: int | str = 1, executor: str | None = None) -> Pool:
    """The pool `ddenv reduce --workers N [--executor E]` would make for `job` (1 local worker: in process)."""
    local_one = check_executor(executor) is None and resolve_workers(workers) == 1
    return make_pool(job, workers, executor, in_process=job.handler() if local_one else None)


def short_world(world: World, timeout: float = WARM_TIMEOUT) -> World:
    """`world` with a scenario time limit of `timeout` simulated seconds (for warm-up runs)."""
    if world.scenario is None:
        return world
    return dataclasses.replace(world, scenario=dataclasses.replace(world.scenario, timeout=timeout))


def warm(pool: Pool, world: World) -> None:
    """Make every worker start its job (imports, pybullet connect) and build `world` once, `pool.size`
    short probes at a time, so that no measurement pays for it."""
    short = short_world(world)
    with concurrent.futures.ThreadPoolExecutor(pool.size) as threads:
        list(threads.map(lambda attempt: pool.call(short, attempt), range(pool.size)))


class Pools:
    """Pools of `workers` workers serving `ScenarioJob`s, one per (predicates, noise seed), opened on first
    use and warmed on the world they are asked for. At most `max_open` stay open (the least recently used
    one is closed first; asking for it again reopens and re-warms it)."""

    def __init__(self, workers: int, *, max_open: int = 2) -> None:
        self.workers = resolve_workers(workers)
        self.max_open = max(1, max_open)
        self._open: OrderedDict[str, Pool] = OrderedDict()
        self._warmed: dict[tuple[str, int], World] = {}  # the world is kept so that its id stays unique
        self._lock = threading.Lock()  # probe threads ask for their pool concurrently

    @property
    def size(self) -> int:
        return self.workers

    @staticmethod
    def key(predicates: Sequence[PredicateSpec], seed: int) -> str:
        return f"{tuple(predicates)!r} seed={seed}"

    def get(self, predicates: Sequence[PredicateSpec], seed: int, world: World | None = None) -> Pool:
        """The pool whose job is the scenario test with `predicates` and noise seed `seed`, warmed on `world`."""
        key = self.key(predicates, seed)
        with self._lock:
            pool = self._open.get(key)
            if pool is None:
                pool = open_pool(ScenarioJob(tuple(predicates), seed=seed), self.workers)
                self._open[key] = pool
                self._forget(key)
                while len(self._open) > self.max_open:
                    old_key, old = self._open.popitem(last=False)
                    old.close()
                    self._forget(old_key)
            self._open.move_to_end(key)
            if world is not None and (key, id(world)) not in self._warmed:
                warm(pool, world)
                self._warmed[(key, id(world))] = world
            return pool

    def _forget(self, key: str) -> None:
        for item in [item for item in self._warmed if item[0] == key]:
            del self._warmed[item]

    def close(self) -> None:
        with self._lock:
            while self._open:
                self._open.popitem()[1].close()
            self._warmed.clear()

    def __enter__(self) -> Pools:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@contextlib.contextmanager
def pool_of(workers: int) -> Iterator[Pools]:
    """`Pools` of `workers` workers each (1: the job's handler in this process), closed at the end."""
    pools = Pools(workers)
    try:
        yield pools
    finally:
        pools.close()


# -- the problem: a world, its test, its original failure ------------------------------------------------


@dataclass
class Problem:
    """A failing world and everything a reduction of it needs (built once per world and seed)."""

    world: World
    predicates: tuple[PredicateSpec, ...]
    seed: int
    pools: Pools
    reference: FailureReference
    reference_trace: Any
    failure: str
    """The original failure, e.g. 'stuck at t=9.5 s'."""
    keep: tuple[str, ...]
    reducible: tuple[str, ...]
    counter: SimCounter = field(default_factory=lambda: SimCounter())
    attempt_offset: int = 0
    """Added to every probe's attempt number: the reduction seed's own re-run noise (0 for the original run)."""

    @property
    def pool(self) -> Pool:
        """The warm pool serving this problem's test (a `ScenarioJob` with its predicates and seed)."""
        return self.pools.get(self.predicates, self.seed, self.world)

    @property
    def workers(self) -> int:
        return self.pools.size

    def call(self, candidate: World, attempt: int) -> ProbeResult:
        """One run of the scenario test on `candidate`, on the pool (what `make_probe` calls)."""
        self.counter.add()
        result = self.pool.call(candidate, attempt + self.attempt_offset)
        if not isinstance(result, ProbeResult):
            raise TypeError(f"the pool's job returned {type(result).__name__}, not a ProbeResult")
        return result

    def probe(self) -> Callable[[tuple[str, ...], int], ProbeObservation]:
        return make_probe(self.world, self.call, self.reference, tolerance=TOLERANCE)

    def preconditions(self) -> tuple[Callable[[tuple[str, ...]], str | None], ...]:
        return (keeps_start_support(self.world),)


class SimCounter:
    """Thread-safe count of simulations started (independent of the engine's own counters)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.count = 0

    def add(self) -> None:
        with self._lock:
            self.count += 1

    def reset(self) -> int:
        with self._lock:
            value, self.count = self.count, 0
        return value


class NotFailing(RuntimeError):
    pass


def make_problem(world: World, predicates: Sequence[PredicateSpec], seed: int, pools: Pools) -> Problem:
    """Run the original world once with noise seed `seed` (the failing run a user would have seen), on the
    pool of `pools` for (predicates, seed), which is warmed on `world` first."""
    named = scenario_models(world)  # an arm's table and target: kept, as the driver keeps them
    keep = tuple(m.name for m in world.models if m.keep or m.name in named)
    problem = Problem(world=world, predicates=tuple(predicates), seed=seed, pools=pools,
                      reference=FailureReference("", ""), reference_trace=None, failure="", keep=keep,
                      reducible=tuple(n for n in world.names if n not in keep))
    result = problem.call(world, 0)
    problem.counter.reset()
    error, run = result.error, result.run
    if error is None or error.ddenv_error or run is None or run.failure is None:
        what = "passed" if error is None else error.describe()
        raise NotFailing(f"{world.name}: seed {seed}: the original world does not fail ({what})")
    problem.reference = FailureReference.of(error)
    problem.reference_trace = trace_of(run)
    problem.failure = problem.reference.describe()
    return problem


# -- our engine -----------------------------------------------------------------------------------------


@dataclass
class Row:
    """One reduction's measurements (one JSON object in --out)."""

    tool: str
    world: str
    seed: int
    partition: str
    priority: str
    deflake: str
    original_size: int
    final_size: int
    minimal: list[str]
    simulations: int
    cache_hits: int
    one_minimal: bool
    failure_rate: tuple[int, int]
    wall_time: float
    workers: int
    failure: str
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def reduction_percent(self) -> float:
        return 100.0 * (self.original_size - self.final_size) / max(1, self.original_size)

    def to_dict(self) -> dict[str, Any]:
        data = asdict(self)
        data["reduction_percent"] = round(self.reduction_percent, 1)
        return data


def ddenv_reduce(problem: Problem, *, partition: str, priority: str, deflake: int | str,
                 workers: int | None = None, max_seconds: float | None = None, failure_rate_runs: int = 10,
                 world_label: str | None = None, seed: int | None = None, rate_check_runs: int = 0) -> Row:
    """Reduce with our engine (the driver's call of `reduce`: `workers` probe threads, default the pool's
    size), then measure the minimal world's failure rate. The pool is warm before the clock starts.
    `rate_check_runs`: the engine's own rate comparison (`failure_rate_runs` of `reduce`; 0: off, the
    paper tables' setting; 20: the plugin's default); `simulations_started` in `extra` counts every
    simulation started, that comparison's and the speculative ones included."""
    workers = problem.pool.size if workers is None else workers
    probe = problem.probe()
    executor = (concurrent.futures.ThreadPoolExecutor(workers, thread_name_prefix="ddenv-probe")
                if workers > 1 else None)
    problem.counter.reset()
    started = time.perf_counter()
    try:
        reduction: Reduction = reduce(
            problem.world.names, probe, geometry=problem.world, reference=problem.reference_trace,
            partition=partition, priority=priority, deflake=deflake, keep=problem.keep,
            preconditions=problem.preconditions(), seed=problem.seed if seed is None else seed, executor=executor,
            workers=workers, max_seconds=max_seconds, failure_rate_runs=rate_check_runs,
        )
    finally:
        if executor is not None:
            executor.shutdown(wait=True, cancel_futures=True)
    wall = time.perf_counter() - started
    started_sims = problem.counter.reset()
    rate = failure_rate(problem, reduction.minimal, failure_rate_runs, workers)
    return Row(
        tool="ddenv", world=world_label or problem.world.name, seed=problem.seed if seed is None else seed,
        partition=partition,
        priority=priority, deflake=str(deflake), original_size=len(problem.reducible),
        final_size=len([n for n in reduction.minimal if n not in problem.keep]), minimal=list(reduction.minimal),
        simulations=reduction.probes, cache_hits=reduction.cache_hits, one_minimal=reduction.one_minimal,
        failure_rate=rate, wall_time=wall, workers=workers, failure=problem.failure,
        note=reduction.incomplete_reason or "",
        extra={"simulations_started": started_sims, "skipped": reduction.skipped, "errors": reduction.errors,
               "steps": [list(s) for s in reduction.steps], "deflake_used": reduction.deflake,
               "calibration": reduction.calibration, "engine_simulations": reduction.simulations,
               "rate_check": None if reduction.rate_check is None else reduction.rate_check.describe(),
               "rate_backoffs": reduction.rate_backoffs, "probes": reduction.probes,
               "precondition_check": reduction.without_precondition_kept},
    )


def calibrated_rule(row: Row) -> DeflakePolicy | None:
    """The deflake rule our engine calibrated in this reduction (deflake="auto"), or None."""
    calibration = row.extra.get("calibration")
    return None if calibration is None else CalibratedReruns().rule_for(*calibration)


def failure_rate(problem: Problem, candidate: Sequence[str], runs: int, workers: int) -> tuple[int, int]:
    """(fails, runs) of `candidate` over fresh noise seeds (attempts 100.., never used by a reduction)."""
    if runs <= 0:
        return (0, 0)
    probe = problem.probe()
    candidate = tuple(candidate)
    with concurrent.futures.ThreadPoolExecutor(max(1, workers)) as threads:
        outcomes = list(threads.map(lambda k: probe(candidate, 100 + k).outcome, range(runs)))
    problem.counter.reset()
    return sum(o is Outcome.FAIL for o in outcomes), runs


# -- picire ---------------------------------------------------------------------------------------------


PICIRE_CONFIGS: dict[str, dict[str, Any]] = {
    # picire's DD() with no arguments: ZellerSplit(n=2), ConfigCache, subset-first, forward/forward
    "default": {},
    # picire README's recommended invocation: no subset tests, complements backward
    "skip-subsets+backward": {"subset_iterator": "skip", "complement_iterator": "backward"},
    "complement-first": {"subset_first": False},
    "balanced-split": {"split": "balanced"},
}


def picire_dd(test: Callable[[list[int], tuple[str, ...]], Any], config: dict[str, Any],
              hits: list[int] | None = None) -> Any:
    """picire's DD with `config`; its (default) ConfigCache counts hits into `hits[0]`."""
    import picire  # type: ignore[import-untyped]
    from picire import config_iterators, config_splitters  # type: ignore[import-untyped]
    from picire.outcome_cache import ConfigCache  # type: ignore[import-untyped]

    class CountingCache(ConfigCache):
        def lookup(self, config: Any) -> Any:
            outcome = super().lookup(config)
            if outcome is not None and hits is not None:
                hits[0] += 1
            return outcome

    kwargs: dict[str, Any] = {"cache": CountingCache()}
    for key, value in config.items():
        if key in ("subset_iterator", "complement_iterator"):
            kwargs[key] = getattr(config_iterators, value)
        elif key == "split":
            kwargs[key] = config_splitters.BalancedSplit() if value == "balanced" else config_splitters.ZellerSplit()
        else:
            kwargs[key] = value
    return picire.DD(test, **kwargs)


def picire_reduce(problem: Problem, *, config_name: str, deflake: int | DeflakePolicy, failure_rate_runs: int = 10,
                  world_label: str | None = None, max_simulations: int | None = None,
                  calibration_runs: int = 0) -> Row:
    """picire's sequential DD driven by our probe (see the module docstring for the outcome mapping).

    `deflake`: re-runs (the paper's rule) or the rule our engine calibrated (deflake="auto");
    `calibration_runs`: simulations the calibration spent before the reduction, counted."""
    policy = FixedReruns(deflake) if isinstance(deflake, int) else deflake
    import picire  # type: ignore[import-untyped]

    probe = problem.probe()
    precondition = problem.preconditions()
    keep = set(problem.keep)
    names = problem.world.names
    reducible = problem.reducible
    counts = {"simulations": 0, "tests": 0, "retests": 0, "skipped": 0}

    def candidate_of(config: Sequence[int]) -> tuple[str, ...]:
        chosen = {reducible[i] for i in config} | keep
        return tuple(n for n in names if n in chosen)

    def test(config: list[int], config_id: tuple[str, ...]) -> Any:
        counts["tests"] += 1
        if "assert" in config_id:
            counts["retests"] += 1
        candidate = candidate_of(config)
        if any(check(candidate) for check in precondition):
            counts["skipped"] += 1
            return picire.Outcome.PASS
        outcomes: list[Outcome] = []
        while (verdict := policy.verdict(outcomes)) is None:
            if max_simulations is not None and counts["simulations"] >= max_simulations:
                raise _Budget()
            counts["simulations"] += 1
            outcomes.append(probe(candidate, len(outcomes)).outcome)
        return picire.Outcome.FAIL if verdict else picire.Outcome.PASS

    hits = [0]
    dd = picire_dd(test, PICIRE_CONFIGS[config_name], hits)
    problem.counter.reset()
    started = time.perf_counter()
    note = ""
    try:
        result = dd(list(range(len(reducible))))
    except _Budget:
        result, note = list(range(len(reducible))), f"stopped at {max_simulations} simulations"
    except AssertionError:
        # picire re-tests the current config at the start of every iteration (`assert ... is FAIL`);
        # with a flaky failure that re-test can pass and picire aborts
        result, note = None, "picire aborted: its per-iteration re-test of the current config passed"
    wall = time.perf_counter() - started
    problem.counter.reset()
    minimal = candidate_of(result) if result is not None else tuple(names)
    one_minimal = result is not None and not note
    rate = failure_rate(problem, minimal, failure_rate_runs, 1) if result is not None else (0, 0)
    return Row(
        tool=f"picire {picire_version()} {config_name}", world=world_label or problem.world.name, seed=problem.seed,
        partition="picire", priority=config_name, deflake=str(policy.label), original_size=len(reducible),
        final_size=len(result) if result is not None else len(reducible), minimal=list(minimal),
        simulations=counts["simulations"] + calibration_runs, cache_hits=hits[0], one_minimal=one_minimal,
        failure_rate=rate,
        wall_time=wall, workers=1, failure=problem.failure, note=note,
        extra={"tests": counts["tests"], "retests": counts["retests"], "skipped": counts["skipped"],
               "calibration_runs": calibration_runs},
    )


class _Budget(Exception):
    pass


def picire_version() -> str:
    try:
        from importlib.metadata import version

        return version("picire")
    except Exception:  # noqa: BLE001
        return "?"


# -- environment ----------------------------------------------------------------------------------------


def machine() -> dict[str, Any]:
    """Cores, CPU model, load and versions, for the record."""
    model = "?"
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    versions = {}
    for package in ("pytest-ddenv", "pybullet", "scikit-learn", "numpy", "picire"):
        try:
            from importlib.metadata import version

            versions[package] = version(package)
        except Exception:  # noqa: BLE001
            versions[package] = "not installed"
    commit = "?"
    with contextlib.suppress(Exception):
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, check=False).stdout.strip() or "?"
    return {
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "cores": os.cpu_count(),
        "cpu": model,
        "load_average": load(),
        "python": platform.python_version(),
        "versions": versions,
        "git": commit,
    }


def load() -> str:
    try:
        return " ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "?"


def write_json(path: str | os.PathLike[str] | None, payload: dict[str, Any]) -> None:
    if not path:
        return
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(payload, indent=1, default=str) + "\n")


def table(headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A plain-text (and markdown-compatible) table."""
    cells = [[str(h) for h in headers]] + [[str(c) for c in row] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = ["| " + " | ".join(c.ljust(w) for c, w in zip(cells[0], widths)) + " |",
             "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
    lines += ["| " + " | ".join(c.ljust(w) for c, w in zip(row, widths)) + " |" for row in cells[1:]]
    return "\n".join(lines)
