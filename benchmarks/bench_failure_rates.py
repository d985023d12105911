"""Is the reported minimal world still the failure? Its failure rate on fresh seeds, next to the original's.

    python benchmarks/bench_failure_rates.py --quick [--workers 2] [--out results.json]   # ditch, seed 0 (about 0.2 min)
    python benchmarks/bench_failure_rates.py [--rules 3 auto] [--seeds 0 1 2] [--out results.json]   # about 5 min

For each paper scenario (ditch, rubble, friction: the predicates and schema pairing of
examples/test_paper_scenarios.py, priority avg-trajectory-proximal), each reduction seed and each deflake
rule (`--rules`: `3` = the paper's rule, `reduce()`'s default before issue 16; `auto` = the default everywhere; any
value `reduce(deflake=...)` accepts), it reduces the scenario test's own failing run (noise seed
`--failure-seed`, 0 as in the examples) through the same probe path as the plugin and `ddenv reduce`: a
`ScenarioJob` on a `pytest_ddenv.execution` pool, `make_probe(world, pool.call, reference)`, `reduce(...)` with
the driver's arguments (its failure-rate runs included, `keeps_start_support` as precondition, `--workers`
probe threads). See benchmarks/common.py.

Then it runs the minimal world and the original world on the same `--fresh-runs` FRESH noise seeds
(attempts `--fresh-first-attempt` .., noise seed `failure_seed + attempt * 1_000_003`), which no reduction
ever uses: a reduction with seed s runs attempts 1000 s + k (k < 1000: first runs, deflake re-runs,
calibration, its failure-rate runs), so attempts 1000..1009 would be reduction seed 1's own runs of the
original world; the default 1_000_000 is far from every reduction seed below 999. A run counts as a failure
when the oracle classifies it as the same failure f as the original reference run (same predicate, failure
position within 0.5 m): `Outcome.FAIL` of the very probe the reduction used.

Per row: minimal size (reducible models, `keep: true` excluded), simulations the reduction started (every
simulation: first runs, deflake re-runs, calibration, the engine's failure-rate runs, speculative runs
started on idle workers; not the fresh-seed runs of this benchmark), the minimal world's and the original's
fails on the fresh seeds, and a flag when the minimal world fails less than half as often as the original.
The original's rate is measured once per scenario (same world, same failing run, same fresh seeds for
every row). `--out` writes every field (breakdown of the simulations included) after every row.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import (
    SCENARIOS,
    TOLERANCE,
    NotFailing,
    Problem,
    load,
    machine,
    make_problem,
    pool_of,
    table,
    write_json,
)

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce import Outcome, Reduction, reduce
from pytest_ddenv.reduce.deflake import make_policy
from pytest_ddenv.world import World

PRIORITY = "avg-trajectory-proximal"
PARTITIONS = {
    # the schema pairing of examples/test_paper_scenarios.py (the paper's best per scenario)
    "ditch": "model2model",
    "rubble": "timeseg",
    "friction": "model2model",
}
DEFAULT_RULES = ("3", "auto")
"""`3`: the paper's rule (reduce()'s default before issue 16); `auto`: the default of every entry point."""
ATTEMPTS_PER_SEED = 1000
"""A reduction with seed s runs attempts ATTEMPTS_PER_SEED * s + k (common.Problem.attempt_offset)."""
FRESH_FIRST_ATTEMPT = 1_000_000
FRESH_RUNS = 10


def parse_rule(text: str) -> int | str:
    """A deflake rule as `reduce(deflake=...)` takes it: a number of re-runs, or a named policy ('auto')."""
    value: int | str = int(text) if text.strip().isdigit() else text.strip()
    try:
        make_policy(value, 0.95)
    except ReductionError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return value


def check_fresh(seeds: Sequence[int], first_attempt: int) -> None:
    """Refuse fresh attempts that a reduction with one of `seeds` may use itself (attempts 1000 s .. 1000 s + 999;
    the original failing run is attempt 0)."""
    for seed in seeds:
        if seed < 0 or ATTEMPTS_PER_SEED * (seed + 1) > first_attempt:
            raise ValueError(f"fresh attempts from {first_attempt} are not above the attempts of reduction seed "
                             f"{seed} ({ATTEMPTS_PER_SEED * seed}..{ATTEMPTS_PER_SEED * (seed + 1) - 1}); pass a "
                             "larger --fresh-first-attempt")


def fresh_rate(problem: Problem, candidate: Sequence[str], runs: int, first_attempt: int,
               workers: int) -> dict[str, Any]:
    """Outcomes of `candidate` on attempts first_attempt .. first_attempt + runs - 1 (no reduction offset),
    classified by the reduction's own probe: {"fails", "runs", "outcomes"}."""
    probe = problem.probe()
    candidate = tuple(candidate)
    saved, problem.attempt_offset = problem.attempt_offset, 0
    try:
        with concurrent.futures.ThreadPoolExecutor(max(1, workers)) as threads:
            outcomes = list(threads.map(lambda k: probe(candidate, first_attempt + k).outcome, range(runs)))
    finally:
        problem.attempt_offset = saved
        problem.counter.reset()
    return {"fails": sum(o is Outcome.FAIL for o in outcomes), "runs": runs,
            "outcomes": [o.value for o in outcomes]}


def reduce_as_the_driver(problem: Problem, *, partition: str, priority: str, deflake: int | str, seed: int,
                         workers: int) -> tuple[Reduction, int, float]:
    """`reduce` called as pytest_ddenv/driver/run.py calls it (same probe, keep, precondition, reference trace,
    failure-rate runs, `workers` probe threads), with reduction seed `seed` (engine seed and re-run noise).
    Returns the reduction, the simulations it started and its wall time."""
    saved, problem.attempt_offset = problem.attempt_offset, ATTEMPTS_PER_SEED * seed
    probe = problem.probe()
    executor = (concurrent.futures.ThreadPoolExecutor(workers, thread_name_prefix="ddenv-probe")
                if workers > 1 else None)
    problem.counter.reset()
    started = time.perf_counter()
    try:
        reduction = reduce(
            problem.world.names, probe, geometry=problem.world, reference=problem.reference_trace,
            partition=partition, priority=priority, deflake=deflake, keep=problem.keep,
            preconditions=problem.preconditions(), seed=seed, executor=executor, workers=workers,
        )
    finally:
        if executor is not None:
            executor.shutdown(wait=True, cancel_futures=True)
        problem.attempt_offset = saved
    wall = time.perf_counter() - started
    return reduction, problem.counter.reset(), wall


def measure(problem: Problem, *, scenario: str, partition: str, priority: str, rule: int | str, seed: int,
            workers: int, original: dict[str, Any], fresh_runs: int = FRESH_RUNS,
            fresh_first_attempt: int = FRESH_FIRST_ATTEMPT) -> dict[str, Any]:
    """Reduce `problem` with deflake `rule` and reduction seed `seed`, then measure the minimal world on the
    fresh seeds; `original` is the original world's `fresh_rate` on the same seeds. One result row."""
    check_fresh([seed], fresh_first_attempt)
    reduction, simulations, wall = reduce_as_the_driver(problem, partition=partition, priority=priority,
                                                        deflake=rule, seed=seed, workers=workers)
    minimal = fresh_rate(problem, reduction.minimal, fresh_runs, fresh_first_attempt, workers)
    calibration_runs = reduction.calibration[1] if reduction.calibration else 0
    below_half = 2 * minimal["fails"] * original["runs"] < original["fails"] * minimal["runs"]
    return {
        "scenario": scenario,
        "reduction_seed": seed,
        "failure_seed": problem.seed,
        "failure": problem.failure,
        "partition": partition,
        "priority": priority,
        "rule": str(rule),
        "rule_used": str(reduction.deflake),
        "original_size": len(problem.reducible),
        "minimal_size": len([n for n in reduction.minimal if n not in problem.keep]),
        "minimal": list(reduction.minimal),
        "one_minimal": reduction.one_minimal,
        "incomplete_reason": reduction.incomplete_reason,
        "simulations": simulations,
        "probes": reduction.probes,
        "calibration_runs": calibration_runs,
        "engine_failure_rate": list(reduction.failure_rate),
        "not_decided_simulations": simulations - reduction.probes,
        "rate_check": None if reduction.rate_check is None else reduction.rate_check.decision,
        "rate_backoffs": reduction.rate_backoffs,
        "cache_hits": reduction.cache_hits,
        "errors": reduction.errors,
        "minimal_fresh": minimal,
        "original_fresh": {k: original[k] for k in ("fails", "runs")},
        "below_half": below_half,
        "fresh_attempts": [fresh_first_attempt, fresh_first_attempt + fresh_runs - 1],
        "wall_time": round(wall, 2),
        "workers": workers,
        "load_average": load(),
    }


def table_row(row: dict[str, Any]) -> list[Any]:
    rule = row["rule"] if row["rule_used"] in (row["rule"], f"auto:{row['rule']}") else (
        f"{row['rule']} ({row['rule_used'].removeprefix('auto:')})")
    minimal, original = row["minimal_fresh"], row["original_fresh"]
    size = f"{row['original_size']} → {row['minimal_size']}" + ("" if row["one_minimal"] else " (not 1-minimal)")
    check = row.get("rate_check") or "-"
    if row.get("rate_backoffs"):
        check += f" ({row['rate_backoffs']} back-off{'s' if row['rate_backoffs'] > 1 else ''})"
    return [row["scenario"], row["reduction_seed"], rule, size, row["simulations"], check,
            f"{minimal['fails']}/{minimal['runs']}", f"{original['fails']}/{original['runs']}",
            "**BELOW HALF**" if row["below_half"] else ""]


HEADERS = ["scenario", "reduction seed", "rule", "minimal size", "simulations", "rate check", "minimal fails (fresh)",
           "original fails (fresh)", "< half the original's"]


def summary_lines(rows: Sequence[dict[str, Any]], rules: Sequence[int | str]) -> list[str]:
    lines = []
    for rule in rules:
        mine = [r for r in rows if r["rule"] == str(rule)]
        if not mine:
            continue
        below = sum(r["below_half"] for r in mine)
        reported = sum(r["one_minimal"] for r in mine)
        sims = [r["simulations"] for r in mine]
        fails = sum(r["minimal_fresh"]["fails"] for r in mine)
        runs = sum(r["minimal_fresh"]["runs"] for r in mine)
        original = sum(r["original_fresh"]["fails"] for r in mine)
        lines.append(
            f"rule {rule}: {below} of {len(mine)} minimal worlds ({reported} reported 1-minimal) fail less than half "
            f"as often as the original on fresh seeds; minimal worlds fail {fails}/{runs}, the originals "
            f"{original}/{runs}; simulations {sum(sims)} in all, {statistics.mean(sims):.0f} "
            f"({min(sims)}-{max(sims)}) per reduction")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one scenario (the first), one seed (the first)")
    parser.add_argument("--scenarios", nargs="+", default=list(PARTITIONS), choices=list(PARTITIONS))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="reduction seeds")
    parser.add_argument("--rules", type=parse_rule, nargs="+", default=[parse_rule(r) for r in DEFAULT_RULES],
                        help="deflake rules to compare: N re-runs, or a named rule such as 'auto' "
                             f"(default: {' '.join(DEFAULT_RULES)})")
    parser.add_argument("--workers", type=int, default=2, help="simulation processes (1: serial, in this process)")
    parser.add_argument("--failure-seed", type=int, default=0, help="noise seed of the failing run (the examples': 0)")
    parser.add_argument("--fresh-runs", type=int, default=FRESH_RUNS)
    parser.add_argument("--fresh-first-attempt", type=int, default=FRESH_FIRST_ATTEMPT)
    parser.add_argument("--out", help="write every measurement to this JSON file (after every row)")
    args = parser.parse_args(argv)

    scenarios = args.scenarios[:1] if args.quick else args.scenarios
    seeds = args.seeds[:1] if args.quick else args.seeds
    try:
        check_fresh(seeds, args.fresh_first_attempt)
    except ValueError as error:
        parser.error(str(error))
    info = machine()
    info["command"] = " ".join(["python", "benchmarks/bench_failure_rates.py",
                                *(argv if argv is not None else sys.argv[1:])])
    print(f"{info['date']}  {info['cores']} cores, {info['cpu']}, load average {info['load_average']}, git {info['git']}")
    print(f"scenarios {scenarios}, reduction seeds {seeds}, rules {[str(r) for r in args.rules]}, failing run: noise "
          f"seed {args.failure_seed}, {args.workers} worker(s); fresh attempts {args.fresh_first_attempt}.."
          f"{args.fresh_first_attempt + args.fresh_runs - 1}\n", flush=True)

    results: dict[str, Any] = {"machine": info, "settings": {**vars(args), "rules": [str(r) for r in args.rules]},
                               "originals": {}, "rows": [], "skipped": [], "load_samples": [load()]}
    started = time.perf_counter()
    with pool_of(args.workers) as pools:
        for name in scenarios:
            scenario = SCENARIOS[name]
            world = World.load(scenario.world)
            try:
                problem = make_problem(world, scenario.predicates, args.failure_seed, pools)
            except NotFailing as error:
                print(f"skipped: {error}", flush=True)
                results["skipped"].append(str(error))
                continue
            original = fresh_rate(problem, world.names, args.fresh_runs, args.fresh_first_attempt, args.workers)
            results["originals"][name] = {"failure": problem.failure, **original}
            print(f"{name}: failing run {problem.failure}; the original world fails {original['fails']}/"
                  f"{original['runs']} fresh seeds the same way (within {TOLERANCE} m)", flush=True)
            for seed in seeds:
                for rule in args.rules:
                    row = measure(problem, scenario=name, partition=PARTITIONS[name], priority=PRIORITY, rule=rule,
                                  seed=seed, workers=args.workers, original=original, fresh_runs=args.fresh_runs,
                                  fresh_first_attempt=args.fresh_first_attempt)
                    results["rows"].append(row)
                    results["load_samples"].append(row["load_average"])
                    print(f"{name} seed {seed} rule {row['rule_used']}: {row['original_size']} -> "
                          f"{row['minimal_size']}, {row['simulations']} simulations ({row['probes']} probes incl. "
                          f"{row['calibration_runs']} calibration; {row['not_decided_simulations']} fresh-run or speculative), "
                          f"rate check {row['rate_check']} ({row['rate_backoffs']} back-offs), minimal fails "
                          f"{row['minimal_fresh']['fails']}/{row['minimal_fresh']['runs']} fresh, original "
                          f"{original['fails']}/{original['runs']}, {row['wall_time']:.1f} s, load "
                          f"{row['load_average']}; minimal {row['minimal']}", flush=True)
                    write_json(args.out, results)
    results["total_seconds"] = round(time.perf_counter() - started, 1)
    results["load_samples"].append(load())
    results["summary"] = summary_lines(results["rows"], args.rules)
    print("\n" + table(HEADERS, [table_row(row) for row in results["rows"]]) + "\n")
    for line in results["summary"]:
        print(line)
    print(f"\ntotal {results['total_seconds'] / 60:.1f} min; load average at the end {load()}")
    write_json(args.out, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
