"""The paper's Tables II-IV re-measured, next to picire, on the three shipped scenarios.

    python benchmarks/paper_tables.py --quick [--workers 2] [--out results.json]    # < 10 min
    python benchmarks/paper_tables.py [--seeds 0 1 2] [--workers 2] [--out results.json]   # < 60 min

For each scenario (ditch, rubble, friction, with the predicates of examples/test_paper_scenarios.py) and each
seed, it reduces the world. `--protocol reduction` (the default): the failure is the scenario test's own
failing run (noise seed `--failure-seed`, 0 as in the examples) and each seed is a reduction seed (the
engine's seed and its own re-run noise seeds). `--protocol failure`: seed s is also the noise seed of the
original failing run, so each seed reduces a possibly different failure. It reduces
with the paper's three schema pairings, the project's `learner` and the plain ddmin baseline
(`even` + `sequential`), through the same probe the plugin builds (benchmarks/common.py), with
`--deflake` (default auto: the plugin's default, re-runs calibrated on the original world; an integer N
is the paper's rule with N re-runs). Then it drives picire's DD with the same
probe and the same deflake rule: its default settings, and its best settings for the problem (full mode:
the configuration of `common.PICIRE_CONFIGS` with the fewest simulations on the first seed, chosen per
scenario, then run on every seed).

Both tools' probes run the scenario test as a `ScenarioJob` on a `pytest_ddenv.execution` pool (`--workers
1`: in this process; N: N local worker processes), one pool per predicate set and failing run, started and
warmed before any timing: worker start-up is not part of any wall time below.

`--quick`: one seed (the first), one pairing (`learner`), picire default only.
Per row: simulations (first runs and deflake re-runs), cache hits, % reduction, final size, 1-minimal proven,
the minimal world's failure rate over 10 fresh seeds, wall time; and the paper's figures. The original
world's failure rate over the same 10 fresh seeds is printed first (how reproducible f itself is).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import (
    PICIRE_CONFIGS,
    SCENARIOS,
    TOLERANCE,
    NotFailing,
    Problem,
    Row,
    calibrated_rule,
    ddenv_reduce,
    failure_rate,
    load,
    machine,
    make_problem,
    picire_reduce,
    pool_of,
    table,
    write_json,
)

from pytest_ddenv.reduce.deflake import DeflakePolicy
from pytest_ddenv.world import World

PAIRINGS: list[tuple[str, str, str]] = [
    # (label, partition, priority)
    ("model2model + failure-proximal", "model2model", "failure-proximal"),
    ("model2model + avg-trajectory", "model2model", "avg-trajectory-proximal"),
    ("timeseg + avg-trajectory", "timeseg", "avg-trajectory-proximal"),
    ("learner + avg-trajectory", "learner", "avg-trajectory-proximal"),
    ("even + sequential (ddmin)", "even", "sequential"),
]
QUICK_PAIRING = "learner + avg-trajectory"

# The paper's best result per scenario (the figures from Tables II-IV: tests, % reduction, minutes)
# and, per pairing, what the paper's public artifact logged for it (shared/reference/paper-artifact.md §6).
# The other cells of Tables II-IV are not in the reference material: printed as "n/a".
PAPER_BEST = {"ditch": (82, 95, 108), "rubble": (162, 89, 231), "friction": (116, 76, 183)}
PAPER_FINAL_SIZE = {"ditch": 2, "rubble": 4, "friction": 6}
"""The paper's best final sizes (43 -> 2, 36 -> 4, 25 -> 6): its percentages are these, rounded."""
PAPER_BEST_PAIRING = {
    # the pairing examples/test_paper_scenarios.py names as the paper's best per scenario
    "ditch": "model2model + avg-trajectory",
    "rubble": "timeseg + avg-trajectory",
    "friction": "model2model + avg-trajectory",
}
ARTIFACT_LOGS = {
    ("ditch", "timeseg + avg-trajectory"): (35, 97.7, 42, "artifact log (trajectoryseg = equal-time split)"),
    ("rubble", "model2model + avg-trajectory"): (178, 77.8, 277, "artifact log"),
    ("friction", "model2model + failure-proximal"): (116, 76, 183, "artifact log (ran crash_proximal)"),
}


def paper_cell(scenario: str, pairing: str) -> str:
    if PAPER_BEST_PAIRING.get(scenario) == pairing:
        tests, percent, minutes = PAPER_BEST[scenario]
        return f"{tests} tests, {percent}%, {minutes} min (paper best)"
    if (scenario, pairing) in ARTIFACT_LOGS:
        logged = ARTIFACT_LOGS[(scenario, pairing)]
        return f"{logged[0]} tests, {logged[1]}%, {logged[2]} min (log)"
    return "n/a"


def spread(values: Sequence[float], fmt: str = "{:.0f}") -> str:
    if len(values) == 1:
        return fmt.format(values[0])
    return f"{fmt.format(statistics.mean(values))} ({fmt.format(min(values))}-{fmt.format(max(values))})"


def summary_rows(rows: list[Row], scenario: str, label: str) -> list[Any]:
    sims = [r.simulations for r in rows]
    fails = sum(r.failure_rate[0] for r in rows)
    runs = sum(r.failure_rate[1] for r in rows)
    return [
        scenario, label, len(rows), spread(sims), spread([r.cache_hits for r in rows]),
        spread([r.reduction_percent for r in rows], "{:.1f}"), spread([r.final_size for r in rows], "{:.1f}"),
        f"{sum(r.one_minimal for r in rows)}/{len(rows)}", f"{fails}/{runs}",
        spread([r.wall_time for r in rows], "{:.1f}"),
    ]


def results_rows(ours: dict[tuple[str, str], list[Row]], theirs: dict[tuple[str, str], list[Row]]) -> list[Row]:
    """Every row, by scenario (in SCENARIOS order), seed, then ours before picire's."""
    rows = [row for group in (*ours.values(), *theirs.values()) for row in group]
    order = {name: index for index, name in enumerate(SCENARIOS)}
    return sorted(rows, key=lambda r: (order.get(r.world, 99), r.seed, r.tool != "ddenv"))


def per_seed_row(row: Row) -> list[Any]:
    label = row.extra.get("pairing") or row.tool
    return [row.world, row.seed, label, row.extra.get("deflake_used", row.deflake), row.simulations,
            row.cache_hits, f"{row.original_size} → {row.final_size}", "yes" if row.one_minimal else "NO",
            f"{row.failure_rate[0]}/{row.failure_rate[1]}", f"{row.wall_time:.1f}"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one seed, one pairing (learner), picire default")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    parser.add_argument("--workers", type=int, default=2, help="simulation processes for our engine (1: serial)")
    parser.add_argument("--deflake", default="auto", type=lambda v: int(v) if v.isdigit() else v,
                        help="re-runs of a candidate that did not fail, or 'auto' (both tools; default auto)")
    parser.add_argument("--protocol", choices=["reduction", "failure"], default="reduction",
                        help="reduction: one failing run (--failure-seed), seeds vary the reduction; "
                             "failure: seed s is also the failing run's noise seed")
    parser.add_argument("--failure-seed", type=int, default=0, help="noise seed of the failing run (protocol reduction)")
    parser.add_argument("--no-picire", action="store_true")
    parser.add_argument("--picire-configs", nargs="+", default=None, choices=list(PICIRE_CONFIGS),
                        help="picire configurations to try for 'best' (default: all; --quick: none)")
    parser.add_argument("--failure-rate-runs", type=int, default=10)
    parser.add_argument("--out", help="write every measurement to this JSON file")
    args = parser.parse_args(argv)

    seeds = args.seeds[:1] if args.quick else args.seeds
    pairings = [p for p in PAIRINGS if p[0] == QUICK_PAIRING] if args.quick else PAIRINGS
    alternatives = [] if args.quick else [c for c in (args.picire_configs or PICIRE_CONFIGS) if c != "default"]
    info = machine()
    info["command"] = " ".join(["python", "benchmarks/paper_tables.py", *(argv if argv is not None else sys.argv[1:])])
    print(f"{info['date']}  {info['cores']} cores, {info['cpu']}, load average {info['load_average']}")
    print(f"python {info['python']}, " + ", ".join(f"{k} {v}" for k, v in info["versions"].items()))
    print(f"protocol {args.protocol}" + (f" (failing run: noise seed {args.failure_seed})" if args.protocol ==
          "reduction" else "") + f", seeds {seeds}, deflake={args.deflake}, our engine with {args.workers} "
          "worker(s); picire sequential\n", flush=True)

    results: dict[str, Any] = {"machine": info, "settings": vars(args), "rows": [], "skipped": []}
    ours: dict[tuple[str, str], list[Row]] = {}
    theirs: dict[tuple[str, str], list[Row]] = {}
    started = time.perf_counter()
    with pool_of(args.workers) as pools:
        for name in args.scenarios:
            scenario = SCENARIOS[name]
            world = World.load(scenario.world)
            best_config: str | None = None
            problems: dict[int, Problem] = {}
            for seed in seeds:
                failure_seed = args.failure_seed if args.protocol == "reduction" else seed
                if failure_seed not in problems:
                    try:
                        problems[failure_seed] = make_problem(world, scenario.predicates, failure_seed, pools)
                    except NotFailing as error:
                        print(f"skipped: {error}", flush=True)
                        results["skipped"].append(str(error))
                        continue
                    original = failure_rate(problems[failure_seed], world.names, args.failure_rate_runs, args.workers)
                    results.setdefault("original_fails", {})[f"{name} failing run seed {failure_seed}"] = original
                    print(f"{name} failing run (noise seed {failure_seed}): {problems[failure_seed].failure}; the "
                          f"original world fails {original[0]}/{original[1]} fresh seeds the same way (within "
                          f"{TOLERANCE} m)", flush=True)
                problem = problems[failure_seed]
                problem.attempt_offset = 1000 * seed if args.protocol == "reduction" else 0
                calibration: tuple[int, int] | None = None
                rule: int | DeflakePolicy = args.deflake if isinstance(args.deflake, int) else 3
                for label, partition, priority in pairings:
                    row = ddenv_reduce(problem, partition=partition, priority=priority, deflake=args.deflake,
                                       workers=args.workers, failure_rate_runs=args.failure_rate_runs,
                                       world_label=name, seed=seed)
                    if (calibrated := calibrated_rule(row)) is not None:
                        calibration, rule = row.extra["calibration"], calibrated
                    row.extra["pairing"] = label
                    ours.setdefault((name, label), []).append(row)
                    results["rows"].append(row.to_dict())
                    print(f"{name} seed {seed} ({problem.failure}, deflake {row.extra['deflake_used']}) {label}: "
                          f"{row.simulations} sims, "
                          f"{row.original_size} -> {row.final_size}, 1-minimal {row.one_minimal}, "
                          f"fails {row.failure_rate[0]}/{row.failure_rate[1]}, {row.wall_time:.1f} s, "
                          f"load {load()}; minimal {row.minimal}", flush=True)
                    write_json(args.out, results)
                if args.no_picire:
                    continue
                configs = ["default"]
                if alternatives:
                    configs += alternatives if best_config is None else [best_config]
                picked: dict[str, Row] = {}
                for config in configs:
                    row = picire_reduce(problem, config_name=config, deflake=rule,
                                        failure_rate_runs=args.failure_rate_runs, world_label=name,
                                        calibration_runs=calibration[1] if calibration else 0)
                    row.seed = seed
                    picked[config] = row
                    theirs.setdefault((name, config), []).append(row)
                    results["rows"].append(row.to_dict())
                    print(f"{name} seed {seed} picire {config}: {row.simulations} sims ({row.extra['retests']} "
                          f"re-tests), {row.original_size} -> {row.final_size}, fails {row.failure_rate[0]}/"
                          f"{row.failure_rate[1]}, {row.wall_time:.1f} s {row.note}", flush=True)
                    write_json(args.out, results)
                if alternatives and best_config is None:
                    best_config = min(alternatives, key=lambda c: (picked[c].simulations, alternatives.index(c)))
                    results.setdefault("picire_best", {})[name] = best_config
                    print(f"{name}: picire best settings (fewest simulations on seed {seed}): {best_config}",
                          flush=True)
    total = time.perf_counter() - started
    results["total_seconds"] = total

    headers = ["scenario", "pairing", "seeds", "simulations", "cache hits", "% reduction", "final size",
               "1-minimal", "minimal fails", "wall s"]
    print(f"\nOur engine (deflake={args.deflake}, {args.workers} workers); mean (min-max) over seeds\n")
    lines = []
    for name in args.scenarios:
        for label, _, _ in pairings:
            if (name, label) in ours:
                lines.append(summary_rows(ours[(name, label)], name, label) + [paper_cell(name, label)])
    print(table(headers + ["paper (tests, reduction, time)"], lines))

    if theirs:
        print(f"\npicire {info['versions']['picire']} DD, sequential, same probe and deflake rule\n")
        lines = []
        for name in args.scenarios:
            for config in PICIRE_CONFIGS:
                if (name, config) in theirs:
                    label = config + (" (best)" if results.get("picire_best", {}).get(name) == config else "")
                    lines.append(summary_rows(theirs[(name, config)], name, label)[:-1] + [
                        spread([r.wall_time for r in theirs[(name, config)]], "{:.1f}"),
                        spread([r.extra["retests"] for r in theirs[(name, config)]])])
        print(table(["scenario", "picire settings", "seeds", "simulations", "cache hits", "% reduction",
                     "final size", "1-minimal", "minimal fails", "wall s", "re-tests"], lines))

    print("\nTargets\n")
    lines = []
    for name in args.scenarios:
        tests, percent, _minutes = PAPER_BEST[name]
        default = theirs.get((name, "default"), [])
        for label, _, _ in pairings:
            rows = ours.get((name, label), [])
            if not rows:
                continue
            sims = statistics.mean(r.simulations for r in rows)
            worst_reduction = min(r.reduction_percent for r in rows)
            largest = max(r.final_size for r in rows)
            ratio = f"{sims / statistics.mean(r.simulations for r in default):.2f}x" if default else "-"
            lines.append([
                name, label,
                (f"yes (worst {worst_reduction:.1f}%)" if largest <= PAPER_FINAL_SIZE[name]
                 else f"NO (worst {worst_reduction:.1f}% < {percent}%)"),
                "yes" if all(r.one_minimal for r in rows) else "NO",
                "yes" if max(r.simulations for r in rows) < tests else f"NO (max {max(r.simulations for r in rows)})",
                "yes" if max(r.wall_time for r in rows) < 300 else "NO",
                ratio + ("" if not default else (" yes" if sims <= 0.6 * statistics.mean(
                    r.simulations for r in default) else " NO")),
            ])
    print(table(["scenario", "pairing", ">= paper's reduction", "1-minimal", "sims < paper's best (every seed)",
                 "< 5 min (every seed)", "sims vs picire default (<= 0.6x)"], lines))
    print("\nPer-seed rows\n")
    print(table(["scenario", "seed", "tool / pairing", "deflake", "simulations", "cache hits", "size", "1-minimal",
                 "minimal fails", "wall s"], [per_seed_row(row) for row in results_rows(ours, theirs)]))
    print(f"\ntotal {total / 60:.1f} min; load average at the end {load()}")
    write_json(args.out, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
