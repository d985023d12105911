"""The cost of honesty (issue 33): our reductions with the rate comparison on, against picire, same probe.

    python benchmarks/bench_honesty.py --quick [--out honesty.json]    # ditch, seed 0: 2.6 min at load 6-10
    python benchmarks/bench_honesty.py [--out honesty.json]            # 3 scenarios x 3 rules x 3 seeds: hours
    python benchmarks/bench_honesty.py --scenarios friction --seeds 0  # 16.9 min at load 6-12
    python benchmarks/bench_honesty.py --picire-from honesty.json      # ours again, picire's rows reused

Per row (scenario x deflake rule: any-of-1 is `deflake=0`, any-of-4 `deflake=3`, and `auto`): our mean
simulations with the end-of-run rate comparison on (`failure_rate_runs=20`, the plugin's default; every
simulation started is counted: calibration, reduction, speculative, rate comparison, drift watch and
back-offs), picire's best settings' mean simulations (the configuration of `common.PICIRE_CONFIGS` with the
fewest simulations on the first seed, then run on every seed; same probe, same rule; with `auto` picire gets
the rule our calibration chose and is charged its runs), and both minimal worlds' failure rates on the same
10 fresh seeds (attempts 100-109 of the reduction seed, never used by a reduction). The verdict compares the
means on the seeds where picire returned a minimal world: where its original run did not fail under the rule
it aborts, reducing nothing (the table says so and which seeds).

The failure is the scenario test's own failing run (noise seed 0); each seed is a reduction seed, as in
paper_tables.py's default protocol. `--picire-from FILE` takes picire's rows (its best settings, chosen on the
first seed as above, and their fresh runs) from an earlier `--out` FILE instead of running picire again: they
do not depend on our engine (with `auto`, picire's rule is our calibration's, which only depends on the
original world's runs; a different one is refused), and a row the file lacks is refused before anything
runs. Our engine runs with `--workers` probe processes (default 1: serial
like picire, so no speculative run is started; 2 counts the speculative ones too).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import (
    PICIRE_CONFIGS,
    SCENARIOS,
    NotFailing,
    Row,
    calibrated_rule,
    ddenv_reduce,
    load,
    machine,
    make_problem,
    picire_reduce,
    pool_of,
    table,
    write_json,
)

from pytest_ddenv import defaults
from pytest_ddenv.reduce.deflake import DeflakePolicy
from pytest_ddenv.world import World

RULES: dict[str, int | str] = {"any-of-1": 0, "any-of-4": 3, "auto": "auto"}
RATE_CHECK_RUNS = 20
FRESH_RUNS = 10


def ours(row: Row) -> int:
    """Every simulation our reduction started (the pool's count)."""
    return int(row.extra["simulations_started"])


def split(rows: list[Row]) -> str:
    """Mean simulations by purpose: decided probes (calibration included), the rest (fresh runs of the rate
    comparison, the drift watch and the back-offs, speculative runs)."""
    probes = statistics.mean(int(r.extra["probes"]) for r in rows)
    return f"{probes:.1f} + {statistics.mean(map(ours, rows)) - probes:.1f}"


def fails(rows: list[Row]) -> str:
    return f"{sum(r.failure_rate[0] for r in rows)}/{sum(r.failure_rate[1] for r in rows)}"


def aborted(row: Row) -> bool:
    """picire stopped without a minimal world (its original run did not fail under the rule)."""
    return row.note.startswith("picire aborted")


def verdict(our_rows: list[Row], their_rows: list[Row]) -> str:
    """Fewer simulations than picire's best on the seeds where picire returned a minimal world (a run that
    aborted reduced nothing: its simulations are no reduction's cost), and the fresh failure rates."""
    if not their_rows:
        return "-"
    seeds = {row.seed for row in their_rows if not aborted(row)}
    if not seeds:
        return "picire reduced nothing"
    mine = statistics.mean(ours(r) for r in our_rows if r.seed in seeds)
    theirs = statistics.mean(r.simulations for r in their_rows if r.seed in seeds)
    fewer = "yes" if mine <= theirs else f"NO (+{mine - theirs:.1f})"
    if len(seeds) < len(their_rows):
        fewer += f" on seeds {sorted(seeds)} ({mine:.1f} vs {theirs:.1f})"
    rate_mine = sum(r.failure_rate[0] for r in our_rows) / max(1, sum(r.failure_rate[1] for r in our_rows))
    rate_theirs = sum(r.failure_rate[0] for r in their_rows) / max(1, sum(r.failure_rate[1] for r in their_rows))
    return f"{fewer}; fresh rate {'>=' if rate_mine >= rate_theirs else '<'} picire's"


Key = tuple[str, str]
"""(scenario, rule name)."""


def picire_rows(path: str, scenarios: list[str], rules: list[str], seeds: list[int]
                ) -> tuple[dict[Key, str], dict[tuple[str, str, int], Row]]:
    """picire's best settings and their rows by (scenario, rule, seed) from an earlier `--out` file; SystemExit
    naming the file and the first row it lacks."""
    try:
        data = json.loads(Path(path).read_text())
        rows = [Row(**{f.name: item[f.name] for f in dataclasses.fields(Row) if f.name in item})
                for item in data["rows"] if str(item["tool"]).startswith("picire")]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise SystemExit(f"--picire-from {path}: not an --out file of bench_honesty.py ({error})") from error
    config = {row.tool: row.priority for row in rows}  # "picire 21.8 default" -> "default"
    by_key: dict[tuple[str, str, int, str], Row] = {
        (row.world, str(row.extra.get("rule")), row.seed, config[row.tool]): row for row in rows}
    best: dict[Key, str] = {}
    for name in scenarios:
        for rule in rules:
            named = data.get("picire_best", {}).get(f"{name} {rule}")
            tried = sorted({(seed, c) for (w, r, seed, c) in by_key if (w, r) == (name, rule)})
            first = [c for seed, c in tried if seed == tried[0][0]] if tried else []
            if named is None and set(first) >= set(PICIRE_CONFIGS):
                named = min(PICIRE_CONFIGS, key=lambda c: (by_key[(name, rule, tried[0][0], c)].simulations,
                                                           list(PICIRE_CONFIGS).index(c)))
            if named is None:
                raise SystemExit(f"--picire-from {path}: no best picire settings for {name} {rule} (its rows: "
                                 f"{sorted(set(first)) or 'none'}, the first seed's must cover {list(PICIRE_CONFIGS)})")
            best[(name, rule)] = named
            for seed in seeds:
                if (name, rule, seed, named) not in by_key:
                    raise SystemExit(f"--picire-from {path}: no picire row for {name} {rule} seed {seed} "
                                     f"(settings {named}); run without --picire-from for it")
    chosen = {(name, rule, seed): by_key[(name, rule, seed, best[(name, rule)])]
              for (name, rule) in best for seed in seeds}
    return best, chosen


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="ditch only, seed 0 (picire's sweep still runs)")
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    parser.add_argument("--rules", nargs="+", default=list(RULES), choices=list(RULES))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--workers", type=int, default=1, help="our engine's probe processes (1: serial)")
    parser.add_argument("--out", help="write every measurement to this JSON file")
    parser.add_argument("--picire-from", metavar="FILE",
                        help="reuse picire's rows from an earlier --out FILE (refused when it lacks one)")
    args = parser.parse_args(argv)
    scenarios = ["ditch"] if args.quick else args.scenarios
    seeds = args.seeds[:1] if args.quick else args.seeds
    reused = picire_rows(args.picire_from, scenarios, args.rules, seeds) if args.picire_from else None

    info = machine()
    info["command"] = " ".join(["python", "benchmarks/bench_honesty.py", *(argv if argv is not None else sys.argv[1:])])
    print(f"{info['date']}  {info['cores']} cores, {info['cpu']}, load average {info['load_average']}")
    print(f"scenarios {scenarios}, rules {args.rules}, seeds {seeds}, our engine with {args.workers} worker(s), "
          f"rate comparison up to {RATE_CHECK_RUNS} runs; picire sequential\n", flush=True)
    results: dict[str, Any] = {"machine": info, "settings": vars(args), "rows": []}
    mine: dict[tuple[str, str], list[Row]] = {}
    theirs: dict[tuple[str, str], list[Row]] = {}
    best: dict[tuple[str, str], str] = {}
    started = time.perf_counter()
    with pool_of(args.workers) as pools:
        for name in scenarios:
            scenario = SCENARIOS[name]
            try:
                problem = make_problem(World.load(scenario.world), scenario.predicates, 0, pools)
            except NotFailing as error:
                print(f"skipped: {error}", flush=True)
                continue
            for rule_name in args.rules:
                deflake = RULES[rule_name]
                for seed in seeds:
                    problem.attempt_offset = 1000 * seed
                    row = ddenv_reduce(problem, partition=defaults.PARTITION, priority=defaults.PRIORITY,
                                       deflake=deflake, workers=args.workers, failure_rate_runs=FRESH_RUNS,
                                       world_label=name, seed=seed, rate_check_runs=RATE_CHECK_RUNS)
                    row.extra["rule"] = rule_name
                    mine.setdefault((name, rule_name), []).append(row)
                    results["rows"].append(row.to_dict())
                    print(f"{name} {rule_name} seed {seed}: ours {ours(row)} sims ({row.extra['deflake_used']}, "
                          f"calibration {row.extra['calibration']}, back-offs {row.extra['rate_backoffs']}), "
                          f"{row.original_size} -> {row.final_size}, fresh {row.failure_rate[0]}/"
                          f"{row.failure_rate[1]}; {row.extra['rate_check']}; {row.wall_time:.1f} s, "
                          f"load {load()}", flush=True)
                    rule: int | DeflakePolicy = deflake if isinstance(deflake, int) else 3
                    calibration = row.extra["calibration"]
                    if (calibrated := calibrated_rule(row)) is not None:
                        rule = calibrated
                    configs = list(PICIRE_CONFIGS) if (name, rule_name) not in best else [best[(name, rule_name)]]
                    tried: dict[str, Row] = {}
                    if reused is not None:
                        best[(name, rule_name)] = config = reused[0][(name, rule_name)]
                        earlier = tried[config] = reused[1][(name, rule_name, seed)]
                        label = rule.label if not isinstance(rule, int) else rule
                        if earlier.deflake != str(label):
                            raise SystemExit(f"--picire-from {args.picire_from}: picire's {name} {rule_name} seed "
                                             f"{seed} ran with rule {earlier.deflake}, ours calibrated {label}")
                        earlier.extra["reused_from"] = args.picire_from
                        results["rows"].append(earlier.to_dict())
                        print(f"  picire {config} (from {args.picire_from}): {earlier.simulations} sims, "
                              f"fresh {earlier.failure_rate[0]}/{earlier.failure_rate[1]}", flush=True)
                        configs = []
                    for config in configs:
                        theirs_row = picire_reduce(problem, config_name=config, deflake=rule,
                                                   failure_rate_runs=FRESH_RUNS, world_label=name,
                                                   calibration_runs=calibration[1] if calibration else 0)
                        theirs_row.seed = seed
                        theirs_row.extra["rule"] = rule_name
                        tried[config] = theirs_row
                        results["rows"].append(theirs_row.to_dict())
                        print(f"  picire {config}: {theirs_row.simulations} sims, {theirs_row.original_size} -> "
                              f"{theirs_row.final_size}, fresh {theirs_row.failure_rate[0]}/"
                              f"{theirs_row.failure_rate[1]} {theirs_row.note}", flush=True)
                    if (name, rule_name) not in best:
                        best[(name, rule_name)] = min(tried, key=lambda c: (tried[c].simulations, configs.index(c)))
                    theirs.setdefault((name, rule_name), []).append(tried[best[(name, rule_name)]])
                    write_json(args.out, results)
    results["picire_best"] = {f"{k[0]} {k[1]}": v for k, v in best.items()}
    results["total_seconds"] = total = time.perf_counter() - started
    lines = []
    for (name, rule_name), rows in mine.items():
        other = theirs.get((name, rule_name), [])
        lines.append([name, rule_name, len(rows), f"{statistics.mean(map(ours, rows)):.1f}", split(rows),
                      f"{statistics.mean(r.simulations for r in other):.1f}" if other else "-",
                      best.get((name, rule_name), "-"), fails(rows), fails(other) if other else "-",
                      verdict(rows, other)])
    print(f"\nWith the rate comparison on: mean simulations (every one started) and fresh failures of the minimal "
          f"worlds ({FRESH_RUNS} fresh seeds each)\n")
    print(table(["scenario", "rule", "seeds", "ours", "ours: probes + rate runs",
                 "picire best", "picire settings", "our minimal fails",
                 "picire's minimal fails", "ours <= picire"], lines))
    for name, rule_name in mine:  # picire's aborted runs reduced nothing: say which
        other = theirs.get((name, rule_name), [])
        if any(map(aborted, other)):
            print(f"{name} {rule_name}: picire aborted on seed(s) {sorted(r.seed for r in other if aborted(r))} (no "
                  f"minimal world; its simulations are in 'picire best', the verdict compares the other seeds)")
    print(f"\ntotal {total / 60:.1f} min; load average at the end {load()}")
    write_json(args.out, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
