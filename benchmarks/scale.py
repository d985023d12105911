"""Reduction cost against world size: seeded synthetic yards of 100 to 3000 static objects with one trap.

    python benchmarks/scale.py --quick [--workers 2] [--out scale.json]     # one seed, learner: < 10 min
    python benchmarks/scale.py [--sizes 100 300 1000 3000] [--seeds 0 1 2] [--workers 2] [--out scale.json]

Each yard (benchmarks/make_yard.py, generated with the yard seed = the run's seed) holds a wall pocket across
the robot's path whose back wall is the only culprit, and N - 3 clutter objects off the path. Per size it
reduces the yard to a 1-minimal world with our engine (the plugin's probe, `stuck(window=5.0,
min_progress=0.2)`, deflake auto by default) and prints simulations, wall time, whether the result is exactly the culprit,
and simulations / (log2 N x culprits). `--plot PNG` (default docs/images/scale_simulations.png) draws
simulations against world size.

Probes run the scenario test as a `ScenarioJob` on a `pytest_ddenv.execution` pool (`--workers 1`: in this
process; N: N local worker processes), one pool per yard seed, started and warmed on each yard before any
timing: worker start-up is not part of the wall times.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import (
    ROOT,
    Row,
    ddenv_reduce,
    load,
    machine,
    make_problem,
    pool_of,
    table,
    write_json,
)
from make_yard import CULPRITS, PREDICATES, make_yard

PAIRINGS = {
    "learner": ("learner", "avg-trajectory-proximal"),
    "model2model": ("model2model", "avg-trajectory-proximal"),
    "ddmin": ("even", "sequential"),
}


def fit_log(sizes: list[int], sims: list[float]) -> tuple[float, float]:
    """Least squares sims = a + b * log2(N)."""
    xs = [math.log2(n) for n in sizes]
    mx, my = statistics.mean(xs), statistics.mean(sims)
    sxx = sum((x - mx) ** 2 for x in xs)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, sims)) / sxx if sxx else 0.0
    return my - b * mx, b


def plot(path: Path, by_pairing: dict[str, dict[int, list[Row]]], title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    all_sizes: set[int] = set()
    for label, per_size in by_pairing.items():
        sizes = sorted(per_size)
        all_sizes.update(sizes)
        means = [statistics.mean(r.simulations for r in per_size[n]) for n in sizes]
        lows = [min(r.simulations for r in per_size[n]) for n in sizes]
        highs = [max(r.simulations for r in per_size[n]) for n in sizes]
        ax.plot(sizes, means, marker="o", label=f"{label} (mean)")
        ax.fill_between(sizes, lows, highs, alpha=0.2)
    if all_sizes:
        xs = sorted(all_sizes)
        ax.plot(xs, [math.log2(n) * len(CULPRITS) for n in xs], "k--", label="log2 N x culprits")
    ax.set_xscale("log")
    ax.set_xlabel("objects in the world (N)")
    ax.set_ylabel("simulations to a 1-minimal world")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one seed, one pairing (learner)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 1000, 3000])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--pairings", nargs="+", default=list(PAIRINGS), choices=list(PAIRINGS))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--deflake", default="auto", type=lambda v: int(v) if v.isdigit() else v,
                        help="re-runs of a candidate that did not fail, or 'auto' (the plugin's default)")
    parser.add_argument("--failure-rate-runs", type=int, default=4)
    parser.add_argument("--max-seconds", type=float, default=1800.0, help="budget per reduction")
    parser.add_argument("--out", help="write every measurement to this JSON file")
    parser.add_argument("--plot", default=str(ROOT / "docs" / "images" / "scale_simulations.png"),
                        help="PNG of simulations against world size ('' for none)")
    args = parser.parse_args(argv)
    seeds = args.seeds[:1] if args.quick else args.seeds
    pairings = ["learner"] if args.quick else args.pairings

    info = machine()
    info["command"] = " ".join(["python", "benchmarks/scale.py", *(argv if argv is not None else sys.argv[1:])])
    print(f"{info['date']}  {info['cores']} cores, {info['cpu']}, load average {info['load_average']}")
    print(f"sizes {args.sizes}, seeds {seeds}, pairings {pairings}, deflake={args.deflake}, "
          f"{args.workers} worker(s); culprits: {list(CULPRITS)}\n", flush=True)
    results: dict[str, Any] = {"machine": info, "settings": vars(args), "rows": []}
    by_pairing: dict[str, dict[int, list[Row]]] = {}
    started = time.perf_counter()
    with pool_of(args.workers) as pools:
        for size in args.sizes:
            for seed in seeds:
                world = make_yard(size, seed)
                pools.get(PREDICATES, seed, world)  # started and warmed on this yard: not timed
                built = time.perf_counter()
                problem = make_problem(world, PREDICATES, seed, pools)
                one_run = time.perf_counter() - built
                for label in pairings:
                    partition, priority = PAIRINGS[label]
                    row = ddenv_reduce(problem, partition=partition, priority=priority, deflake=args.deflake,
                                       workers=args.workers, failure_rate_runs=args.failure_rate_runs,
                                       max_seconds=args.max_seconds, world_label=world.name)
                    row.extra.update(pairing=label, size=size, original_run_seconds=one_run,
                                     exact=tuple(row.minimal) == CULPRITS)
                    by_pairing.setdefault(label, {}).setdefault(size, []).append(row)
                    results["rows"].append(row.to_dict())
                    print(f"N={size} seed {seed} {label}: {row.simulations} sims, {row.cache_hits} cache hits, "
                          f"-> {row.minimal}, 1-minimal {row.one_minimal}, fails {row.failure_rate[0]}/"
                          f"{row.failure_rate[1]}, {row.wall_time:.1f} s (one run of the original "
                          f"{one_run:.1f} s), load {load()} {row.note}", flush=True)
                    write_json(args.out, results)
    total = time.perf_counter() - started
    results["total_seconds"] = total

    print(f"\nSimulations and wall time to a 1-minimal world (deflake={args.deflake}, {args.workers} workers); "
          "mean (min-max) over seeds\n")
    lines = []
    fits = {}
    for label, per_size in by_pairing.items():
        sizes = sorted(per_size)
        for n in sizes:
            rows = per_size[n]
            sims = [r.simulations for r in rows]
            walls = [r.wall_time for r in rows]
            mean_sims = statistics.mean(sims)
            lines.append([
                label, n, len(rows), f"{mean_sims:.1f} ({min(sims)}-{max(sims)})",
                f"{statistics.mean(r.cache_hits for r in rows):.1f}",
                f"{sum(r.extra['exact'] for r in rows)}/{len(rows)}", f"{sum(r.one_minimal for r in rows)}/{len(rows)}",
                f"{statistics.mean(walls):.0f} ({min(walls):.0f}-{max(walls):.0f})",
                f"{statistics.mean(r.extra['original_run_seconds'] for r in rows):.2f}",
                f"{mean_sims / (math.log2(n) * len(CULPRITS)):.2f}",
            ])
        if len(sizes) >= 2:
            a, b = fit_log(sizes, [statistics.mean(r.simulations for r in per_size[n]) for n in sizes])
            fits[label] = {"intercept": a, "per_doubling": b}
    print(table(["pairing", "N", "seeds", "simulations", "cache hits", "exactly the culprit", "1-minimal",
                 "wall s", "one run s", "sims / (log2 N x culprits)"], lines))
    for label, fit in fits.items():
        print(f"\n{label}: simulations ~ {fit['intercept']:.1f} + {fit['per_doubling']:.2f} x log2 N "
              f"(least squares over the sizes); growth is O(log N x culprits) when the last column stays flat")
    results["fits"] = fits
    if args.plot:
        plot(Path(args.plot), by_pairing, f"{info['date'][:10]}, {info['cores']} cores, deflake={args.deflake}, "
             f"{args.workers} workers, seeds {seeds}")
        print(f"\nplot: {args.plot}")
    print(f"\ntotal {total / 60:.1f} min; load average at the end {load()}")
    write_json(args.out, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
