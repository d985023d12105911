"""Parallel probes: the ditch reduction with 1 and 2 workers, and the pool's overhead per probe.

    python benchmarks/bench_parallel.py [--world worlds/ditch.yaml] [--workers 1 2] [--overhead-runs 100]

Prints a markdown table (the one in docs/performance.md, "Parallel probes"). The reduction is the one the
examples run on the ditch (stuck(window=5.0, min_progress=0.2), model2model + avg-trajectory-proximal,
deflake 2, seed 0), driven through the same probe the plugin uses (RobotWorld -> pool.simulate). With N
workers, N probes of a round are in flight at once (a ThreadPoolExecutor of N threads, as the plugin does).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import os
import statistics
import time
from pathlib import Path

from pytest_ddenv.execution import PoolStats, SimulationPool, cpu_count
from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.probe import keeps_start_support, make_probe, reference_from, trace_of
from pytest_ddenv.reduce import Reduction, reduce
from pytest_ddenv.robot_world import RobotWorld
from pytest_ddenv.sim import Run, Simulator
from pytest_ddenv.world import World

ROOT = Path(__file__).resolve().parent.parent
PREDICATES = (PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}),)
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


def warm_pool(workers: int, world: World) -> SimulationPool:
    """A pool whose workers are all up (created once per pytest session in real use: not timed)."""
    pool = SimulationPool(workers)
    with concurrent.futures.ThreadPoolExecutor(workers) as threads:
        list(threads.map(lambda seed: pool.simulate(world, seed=seed, timeout=0.1), range(workers)))
    return pool


def reduce_on(world: World, pool: SimulationPool, predicates: tuple[PredicateSpec, ...]) -> tuple[Reduction, float]:
    """The example's reduction of `world` with pool.size probes in flight (1 = the serial engine)."""
    workers = pool.size

    def run_test(candidate: World, attempt: int) -> tuple[BaseException | None, Run | None]:
        robot_world = RobotWorld(candidate, predicates=predicates, seed=0, attempt=attempt, simulate=pool.simulate)
        try:
            robot_world.run()
        except Exception as error:  # noqa: BLE001 - the outcome to classify
            return error, robot_world.runs[-1] if robot_world.runs else None
        return None, robot_world.runs[-1]

    started = time.perf_counter()
    error, first = run_test(world, 0)
    if error is None or first is None or first.failure is None:
        raise SystemExit(f"{world.source}: the original world does not fail with {predicates}; nothing to reduce")
    reference = reference_from(error, None)
    probe = make_probe(world, run_test, reference, tolerance=0.5)
    executor = concurrent.futures.ThreadPoolExecutor(workers) if workers > 1 else None
    try:
        reduction = reduce(
            world.names, probe, geometry=world, reference=trace_of(first), partition="model2model",
            priority="avg-trajectory-proximal", deflake=2, seed=0, preconditions=(keeps_start_support(world),),
            keep=tuple(m.name for m in world.models if m.keep), executor=executor,
        )
    finally:
        if executor is not None:
            executor.shutdown(wait=True)
    return reduction, time.perf_counter() - started


def throughput(world: World, pool: SimulationPool, runs: int) -> float:
    """Seconds for `runs` independent simulations of `world` (seeds 0..runs-1), pool.size at a time."""
    started = time.perf_counter()
    with concurrent.futures.ThreadPoolExecutor(pool.size) as threads:
        list(threads.map(lambda seed: pool.simulate(world, seed=seed, predicates=PREDICATES), range(runs)))
    return time.perf_counter() - started


def overhead(runs: int) -> tuple[float, float, float]:
    """(direct ms, via a 1-process pool ms, transport ms) per simulation of a trivial world, medians."""
    world = World.from_yaml(TRIVIAL)
    with Simulator() as simulator:
        for _ in range(3):
            simulator.run(world, seed=0)
        direct = []
        for seed in range(runs):
            started = time.perf_counter()
            simulator.run(world, seed=seed)
            direct.append(time.perf_counter() - started)
    with SimulationPool(1, in_process=False) as pool:
        for _ in range(3):
            pool.simulate(world, seed=0)
        through = []
        for seed in range(runs):
            started = time.perf_counter()
            pool.simulate(world, seed=seed)
            through.append(time.perf_counter() - started)
        transport = pool.stats.mean_overhead
    return statistics.median(direct) * 1e3, statistics.median(through) * 1e3, transport * 1e3


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default=str(ROOT / "worlds" / "ditch.yaml"))
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--throughput-runs", type=int, default=12)
    parser.add_argument("--overhead-runs", type=int, default=100)
    parser.add_argument("--no-yard", action="store_true", help="skip the synthetic 40-object yard")
    parser.add_argument("--repeat", type=int, default=3, help="reductions per worker count (median reported)")
    args = parser.parse_args(argv)
    cases = [(World.load(args.world), PREDICATES, "stuck(window=5.0, min_progress=0.2)")]
    if not args.no_yard:
        cases.append((yard(), (PredicateSpec("stuck", {"window": 2.0, "min_progress": 0.2}),),
                      "stuck(window=2.0, min_progress=0.2)"))
    try:
        load = " ".join(f"{v:.1f}" for v in os.getloadavg())
    except OSError:  # pragma: no cover
        load = "?"
    print(f"cores: {cpu_count()}, load average before: {load}; pools are started and warmed before timing\n")
    print("| world | predicate | workers | wall time (s), median | speed-up | probes | pool errors | minimal world |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    with SimulationPool(1) as warm:  # imports (scikit-learn, ...) and caches must not be charged to one row
        reduce_on(yard(8), warm, cases[-1][1])
    same = True
    for world, predicates, shown in cases:
        timings: dict[int, list[float]] = {workers: [] for workers in args.workers}
        results: dict[int, tuple[Reduction, PoolStats]] = {}
        minimals: set[tuple[str, ...]] = set()
        for repeat in range(args.repeat):  # alternate the order: a loaded machine drifts
            for workers in args.workers if repeat % 2 == 0 else list(reversed(args.workers)):
                with warm_pool(workers, world) as pool:
                    reduction, seconds = reduce_on(world, pool, predicates)
                    timings[workers].append(seconds)
                    results.setdefault(workers, (reduction, pool.stats))
                    minimals.add(reduction.minimal)
        base = statistics.median(timings[args.workers[0]])
        for workers in args.workers:
            reduction, stats = results[workers]
            seconds = statistics.median(timings[workers])
            print(f"| {Path(world.source or world.name).name} ({len(world)}) | {shown} | {workers} | {seconds:.1f} | "
                  f"{base / seconds:.2f}x | {reduction.probes} | {stats.errors} | "
                  f"{reduction.minimal_size}: {', '.join(reduction.minimal)} |")
        same = same and len(minimals) == 1
    print(f"\nidentical minimal worlds across worker counts and repeats: {'yes' if same else 'NO'}")

    world = cases[0][0]
    print(f"\nThroughput: {args.throughput_runs} independent simulations of {Path(args.world).name}\n")
    print("| workers | wall time (s) | speed-up |")
    print("|---:|---:|---:|")
    times = []
    for workers in args.workers:
        with warm_pool(workers, world) as pool:
            throughput(world, pool, workers)  # every worker has built this world once
            times.append(throughput(world, pool, args.throughput_runs))
        print(f"| {workers} | {times[-1]:.1f} | {times[0] / times[-1]:.2f}x |")

    direct, through, transport = overhead(args.overhead_runs)
    print(f"\nPool overhead per probe (trivial world, 0.05 s simulated, {args.overhead_runs} runs, medians)\n")
    print("| direct Simulator (ms) | through a 1-worker pool (ms) | difference (ms) | transport only (ms) |")
    print("|---:|---:|---:|---:|")
    print(f"| {direct:.2f} | {through:.2f} | {through - direct:+.2f} | {transport:.2f} |")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
