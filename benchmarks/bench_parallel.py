"""Parallel probes: the ditch reduction with 1 and 2 workers, and the pool's overhead per probe.

    python benchmarks/bench_parallel.py [--world worlds/ditch.yaml] [--workers 1 2] [--overhead-runs 100]

Prints a markdown table (the one in docs/performance.md, "Parallel probes"). The reduction is the one the
examples run on the ditch (stuck(window=5.0, min_progress=0.2), model2model + avg-trajectory-proximal,
deflake 2, seed 0), run exactly as `ddenv reduce` runs it: the world's scenario is a `ScenarioJob` served by
a pool from `make_pool` (1 worker: the job's handler in this process; N: N local worker processes), the
original failing run is one `pool.call`, then `pytest_ddenv.driver.run_reduction` (the plugin's and the
CLI's driver) reduces with `pool.size` probes in flight and writes the artifacts (minimal world, log,
summary, pictures) to a temporary folder.

Pools are started and warmed (every worker has run the world once) before the clock starts: worker start-up
is not timed here. "wall time" is the original run plus the engine's
reduction (its 5 failure-rate runs of the minimal world included), as in earlier versions of this table; the
speed-up is computed on it. "with artifacts" adds what the driver does after the engine (summary, the
minimal world's run for the pictures, the pictures).

`--pytest N` adds the plugin's whole path, end to end: `pytest examples/test_paper_scenarios.py::
test_husky_crosses_the_ditch --ddenv-reduce --ddenv-workers W` in a fresh process, N times per worker count
(the whole command's wall time: pytest start-up, the failing test, probe workers that are pytest sessions
collecting the test, confirmation, reduction, artifacts and pictures; and the engine's own time from
summary.json). `--cli N` does the same for the command: `ddenv reduce worlds/ditch.yaml -p stuck:... --workers W`
(its pool is a `ScenarioJob`; media included, as a user gets it by default).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import open_pool, warm

from pytest_ddenv.driver import ReductionOutcome, ReductionPlan, run_reduction
from pytest_ddenv.execution import LocalPool, Pool, PoolStats, cpu_count
from pytest_ddenv.driver.markers import ReductionSpec
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.scenario.probe import FailureReference, ProbeResult
from pytest_ddenv.reduce import Reduction
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.world import World

ROOT = Path(__file__).resolve().parent.parent
PREDICATES = (PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}),)
SPEC = ReductionSpec(partition="model2model", priority="avg-trajectory-proximal", deflake=2, tolerance=0.5, seed=0)
TRIVIAL = """
format: 1
name: trivial
scenario: {start: {x: 0, y: 0, yaw: 0}, goal: {x: 4, y: 0}, timeout: 0.05}
models:
  - {name: box, pose: [-4, 4, 0.25], box: [0.5, 0.5, 0.5]}
"""


def yard(count: int = 40) -> World:
    """A synthetic yard: a wall across the robot's path and `count - 1` boxes and posts off the path."""
    import random

    rng = random.Random(7)
    lines = ["format: 1", "name: yard", "scenario: {start: {x: 0, y: 0, yaw: 0}, goal: {x: 4, y: 0}, timeout: 20}",
             "models:", "  - {name: wall, pose: [2.0, 0, 0.5], box: [0.3, 4.0, 1.0]}"]
    for index in range(count - 1):
        x, y = rng.uniform(-8, 10), rng.choice([-1, 1]) * rng.uniform(3.5, 9)
        if index % 2:
            lines.append(f"  - {{name: box_{index:02d}, pose: [{x:.2f}, {y:.2f}, 0.25], box: [0.5, 0.5, 0.5]}}")
        else:
            lines.append(f"  - {{name: post_{index:02d}, pose: [{x:.2f}, {y:.2f}, 0.5], "
                         "cylinder: {radius: 0.2, length: 1.0}}")
    return World.from_yaml("\n".join(lines) + "\n", source="yard.yaml")


def warm_pool(workers: int, world: World, predicates: tuple[PredicateSpec, ...] = PREDICATES) -> Pool:
    """A pool serving the scenario test (`predicates`, seed 0) whose workers are all up and have built
    `world` once (created once per pytest session in real use: not timed)."""
    pool = open_pool(ScenarioJob(predicates, seed=0), workers)
    try:
        warm(pool, world)
    except BaseException:
        pool.close()
        raise
    return pool


def reduce_on(world: World, pool: Pool, artifacts: Path | None = None) -> tuple[ReductionOutcome, float, float]:
    """The example's reduction of `world` on `pool`, as `ddenv reduce` runs it: the original run, then the
    driver. Returns (outcome, original run + engine seconds, end-to-end seconds incl. the artifacts)."""
    with tempfile.TemporaryDirectory(prefix="ddenv-bench-") as scratch:
        started = time.perf_counter()
        original = pool.call(world, 0)
        assert isinstance(original, ProbeResult)
        original_seconds = time.perf_counter() - started
        if original.error is None or original.error.ddenv_error or original.run is None \
                or original.run.failure is None:
            raise SystemExit(f"{world.source}: the original world does not fail; nothing to reduce")
        plan = ReductionPlan(
            world=world, test_id=f"bench_parallel {world.source}", reference=FailureReference.of(original.error),
            reference_run=original.run, spec=SPEC, artifacts=artifacts or Path(scratch) / "artifacts",
            replay_command="", fingerprint={"benchmark": "bench_parallel"}, confirmed=True,
        )
        outcome = run_reduction(plan, pool)
        total = time.perf_counter() - started
    if outcome.reduction is None:
        raise SystemExit(f"{world.source}: the reduction did not run: {outcome.status} {outcome.message}")
    return outcome, original_seconds + outcome.reduction.wall_time, total


def throughput(world: World, pool: Pool, runs: int) -> float:
    """Seconds for `runs` independent runs of the scenario test on `world` (attempts 0..runs-1: each its own
    noise seed), pool.size at a time."""
    started = time.perf_counter()
    with concurrent.futures.ThreadPoolExecutor(pool.size) as threads:
        list(threads.map(lambda attempt: pool.call(world, attempt), range(runs)))
    return time.perf_counter() - started


def overhead(runs: int) -> tuple[float, float, float]:
    """(direct ms, via a 1-process pool ms, transport ms) per probe of a trivial world, medians. Direct: the
    job's handler in this process (what a 1-worker in-process pool runs); via: a `LocalPool` of 1 worker
    process serving the same job."""
    world = World.from_yaml(TRIVIAL)
    job = ScenarioJob((), seed=0)
    handler = job.handler()
    for _ in range(3):
        handler(world, 0)
    direct = []
    for attempt in range(runs):
        started = time.perf_counter()
        handler(world, attempt)
        direct.append(time.perf_counter() - started)
    with LocalPool(job, 1) as pool:
        for _ in range(3):
            pool.call(world, 0)
        through = []
        for attempt in range(runs):
            started = time.perf_counter()
            pool.call(world, attempt)
            through.append(time.perf_counter() - started)
        transport = pool.stats.mean_overhead
    return statistics.median(direct) * 1e3, statistics.median(through) * 1e3, transport * 1e3


DITCH_TEST = "examples/test_paper_scenarios.py::test_husky_crosses_the_ditch"


CLI_REDUCE = ("reduce", "worlds/ditch.yaml", "-p", "stuck:window=5,min_progress=0.2", "--partition", "model2model",
              "--priority", "avg-trajectory", "--quiet")


def end_to_end(command: list[str], folder: str) -> tuple[float, float, int, tuple[str, ...]]:
    """(whole command s, the engine's reduction s, probes, minimal world) of one reduction in a fresh process,
    with the defaults a user gets (media included)."""
    started = time.perf_counter()
    subprocess.run(command, cwd=ROOT, capture_output=True, check=False)
    seconds = time.perf_counter() - started
    (summary_file,) = Path(folder).glob("**/summary.json")
    summary = json.loads(summary_file.read_text())
    return seconds, float(summary["wall_time"]), int(summary["probes"]), tuple(summary["minimal_models"])


def through_pytest(workers: int) -> tuple[float, float, int, tuple[str, ...]]:
    """The ditch example under pytest: `pytest TEST --ddenv-reduce --ddenv-workers W`."""
    with tempfile.TemporaryDirectory() as folder:
        return end_to_end([sys.executable, "-m", "pytest", DITCH_TEST, "--ddenv-reduce", "--ddenv-workers",
                           str(workers), "-q", "-p", "no:cacheprovider", "--ddenv-artifacts", folder], folder)


def through_cli(workers: int) -> tuple[float, float, int, tuple[str, ...]]:
    """The ditch world through the command: `ddenv reduce worlds/ditch.yaml ... --workers W`."""
    with tempfile.TemporaryDirectory() as folder:
        return end_to_end([sys.executable, "-m", "pytest_ddenv.cli", *CLI_REDUCE, "--workers", str(workers),
                           "--out", folder], folder)


def end_to_end_table(title: str, run: Callable[[int], tuple[float, float, int, tuple[str, ...]]],
                     workers_list: list[int], repeat: int) -> None:
    print(f"\n{title}, in a fresh process, median of {repeat}\n")
    print("| workers | whole command (s) | speed-up | reduction in the engine (s) | speed-up | probes | minimal world |")
    print("|---:|---:|---:|---:|---:|---:|---|")
    rows: dict[int, list[tuple[float, float, int, tuple[str, ...]]]] = {w: [] for w in workers_list}
    for index in range(repeat):
        for workers in workers_list if index % 2 == 0 else list(reversed(workers_list)):
            rows[workers].append(run(workers))
    base_total = statistics.median(r[0] for r in rows[workers_list[0]])
    base_engine = statistics.median(r[1] for r in rows[workers_list[0]])
    for workers in workers_list:
        total = statistics.median(r[0] for r in rows[workers])
        engine = statistics.median(r[1] for r in rows[workers])
        probes = sorted({r[2] for r in rows[workers]})
        minimal = {r[3] for r in rows[workers]}
        print(f"| {workers} | {total:.1f} | {base_total / total:.2f}x | {engine:.1f} | {base_engine / engine:.2f}x | "
              f"{'-'.join(map(str, probes))} | {' / '.join(', '.join(m) for m in minimal)} |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default=str(ROOT / "worlds" / "ditch.yaml"))
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--throughput-runs", type=int, default=12)
    parser.add_argument("--overhead-runs", type=int, default=100)
    parser.add_argument("--no-yard", action="store_true", help="skip the synthetic 40-object yard")
    parser.add_argument("--repeat", type=int, default=3, help="reductions per worker count (median reported)")
    parser.add_argument("--pytest", type=int, default=0, metavar="N",
                        help="also time the plugin end to end, N pytest runs per worker count")
    parser.add_argument("--cli", type=int, default=0, metavar="N",
                        help="also time `ddenv reduce` end to end, N runs per worker count")
    args = parser.parse_args(argv)
    cases = [(World.load(args.world), PREDICATES, "stuck(window=5.0, min_progress=0.2)")]
    if not args.no_yard:
        cases.append((yard(), (PredicateSpec("stuck", {"window": 2.0, "min_progress": 0.2}),),
                      "stuck(window=2.0, min_progress=0.2)"))
    try:
        load = " ".join(f"{v:.1f}" for v in os.getloadavg())
    except OSError:  # pragma: no cover
        load = "?"
    print(f"cores: {cpu_count()}, load average before: {load}; pools are started and warmed before timing "
          "(worker start-up not timed); 1 worker = the job's handler in this process\n")
    print("| world | predicate | workers | wall time (s), median | speed-up | with artifacts (s), median | probes | "
          "pool errors | minimal world |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---|")
    # imports (scikit-learn, matplotlib, ...) and caches must not be charged to one row
    small = yard(8)
    with warm_pool(1, small, cases[-1][1]) as pool:
        reduce_on(small, pool)
    same = True
    speedups: list[str] = []
    for world, predicates, shown in cases:
        timings: dict[int, list[float]] = {workers: [] for workers in args.workers}
        totals: dict[int, list[float]] = {workers: [] for workers in args.workers}
        results: dict[int, tuple[Reduction, PoolStats]] = {}
        minimals: set[tuple[str, ...]] = set()
        for repeat in range(args.repeat):  # alternate the order: a loaded machine drifts
            for workers in args.workers if repeat % 2 == 0 else list(reversed(args.workers)):
                with warm_pool(workers, world, predicates) as pool:
                    outcome, seconds, total = reduce_on(world, pool)
                    assert outcome.reduction is not None
                    timings[workers].append(seconds)
                    totals[workers].append(total)
                    results.setdefault(workers, (outcome.reduction, pool.stats))
                    minimals.add(outcome.reduction.minimal)
        base = statistics.median(timings[args.workers[0]])
        name = Path(world.source or world.name).name
        for workers in args.workers:
            reduction, stats = results[workers]
            seconds = statistics.median(timings[workers])
            print(f"| {name} ({len(world)}) | {shown} | {workers} | {seconds:.1f} | {base / seconds:.2f}x | "
                  f"{statistics.median(totals[workers]):.1f} | {reduction.probes} | {stats.errors} | "
                  f"{reduction.minimal_size}: {', '.join(reduction.minimal)} |")
        if len(args.workers) > 1:
            last = args.workers[-1]
            speedups.append(f"{name}: {last} workers vs {args.workers[0]}: "
                            f"{base / statistics.median(timings[last]):.2f}x")
        same = same and len(minimals) == 1
    print(f"\nidentical minimal worlds across worker counts and repeats: {'yes' if same else 'NO'}")
    for line in speedups:
        print(f"parallel speed-up (medians of {args.repeat}), {line}")

    world = cases[0][0]
    print(f"\nThroughput: {args.throughput_runs} independent runs of the scenario test on {Path(args.world).name}\n")
    print("| workers | wall time (s) | speed-up |")
    print("|---:|---:|---:|")
    times = []
    for workers in args.workers:
        with warm_pool(workers, world) as pool:
            throughput(world, pool, workers)  # every worker has run this world to the end once
            times.append(throughput(world, pool, args.throughput_runs))
        print(f"| {workers} | {times[-1]:.1f} | {times[0] / times[-1]:.2f}x |")

    direct, through, transport = overhead(args.overhead_runs)
    print(f"\nPool overhead per probe (trivial world, 0.05 s simulated, {args.overhead_runs} runs, medians)\n")
    print("| direct: the job's handler in this process (ms) | through a 1-worker pool (ms) | difference (ms) | "
          "transport only (ms) |")
    print("|---:|---:|---:|---:|")
    print(f"| {direct:.2f} | {through:.2f} | {through - direct:+.2f} | {transport:.2f} |")
    if args.pytest:
        end_to_end_table(f"The plugin end to end: `pytest {DITCH_TEST} --ddenv-reduce --ddenv-workers W`",
                         through_pytest, args.workers, args.pytest)
    if args.cli:
        end_to_end_table(f"The command end to end: `ddenv {' '.join(CLI_REDUCE)} --workers W`", through_cli,
                         args.workers, args.cli)
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
