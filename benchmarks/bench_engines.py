"""The two physics engines side by side (not a timed test): prints a Markdown table.
Run: python benchmarks/bench_engines.py   (about 8 minutes on 2 cores; docs/performance.md, "Two engines")

For each paper scenario (ditch, rubble, friction; the predicates of examples/test_paper_scenarios.py) and each
installed engine (pybullet, mujoco):

- per probe: the scenario test as a `ScenarioJob` probe in this process (world build, run, result) on the
  noise seeds 0..N-1 (`--seeds`), after one untimed warm-up probe; its wall time (median, max) and the
  real-time factor (simulated seconds / wall seconds, median);
- a reduction: our engine on a warm pool of `--workers` worker processes (benchmarks/common.py, the pairing
  of the examples: model2model, timeseg for rubble, avg-trajectory priority, deflake auto) from the failing run
  of seed 0: the minimal world, the simulations it started, its wall time, and the minimal world's failure
  rate on 10 fresh seeds (10 more simulations, not in the reduction's count).
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import time

from common import SCENARIOS, NotFailing, ddenv_reduce, make_problem, pool_of, table

from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.scenario.probe import ProbeResult
from pytest_ddenv.world import World

ENGINES = ("pybullet", "mujoco")
PAIRINGS = {"ditch": "model2model", "rubble": "timeseg", "friction": "model2model"}


def installed(engine: str) -> bool:
    return importlib.util.find_spec(engine) is not None


def probe_times(world: World, name: str, seeds: int) -> tuple[list[float], list[float], list[str]]:
    """Wall time and simulated time of one probe per seed, and what each run ended with."""
    walls, simulated, outcomes = [], [], []
    job = ScenarioJob(SCENARIOS[name].predicates, seed=0)
    handler = job.handler()
    handler(world, 0)  # warm-up: imports, the engine's first world
    for seed in range(seeds):
        seeded = ScenarioJob(SCENARIOS[name].predicates, seed=seed).handler()
        started = time.perf_counter()
        result = seeded(world, 0)
        walls.append(time.perf_counter() - started)
        assert isinstance(result, ProbeResult) and result.run is not None
        simulated.append(result.run.sim_time)
        failure = result.run.failure
        outcomes.append("pass" if failure is None else failure.predicate)
    return walls, simulated, outcomes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=3, help="noise seeds per probe measurement (default 3)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes of a reduction (default 2)")
    parser.add_argument("--worlds", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    parser.add_argument("--engines", nargs="+", default=[e for e in ENGINES if installed(e)], choices=ENGINES)
    parser.add_argument("--no-reduction", action="store_true", help="per-probe measurements only")
    arguments = parser.parse_args()
    probe_rows, reduction_rows = [], []
    for name in arguments.worlds:
        for engine in arguments.engines:
            world = World.load(SCENARIOS[name].world).with_engine(engine)
            walls, simulated, outcomes = probe_times(world, name, arguments.seeds)
            rtf = statistics.median(s / w for s, w in zip(simulated, walls, strict=True))
            probe_rows.append([name, engine, f"{statistics.median(walls):.2f} / {max(walls):.2f} s",
                               f"{statistics.median(simulated):.1f} s", f"{rtf:.0f}x", ", ".join(outcomes)])
            print(" | ".join(probe_rows[-1]), flush=True)
            if arguments.no_reduction:
                continue
            with pool_of(arguments.workers) as pools:
                try:
                    problem = make_problem(world, SCENARIOS[name].predicates, 0, pools)
                except NotFailing as error:
                    reduction_rows.append([name, engine, str(error), "", "", "", "", ""])
                    continue
                row = ddenv_reduce(problem, partition=PAIRINGS[name], priority="avg-trajectory", deflake="auto")
            fails, runs = row.failure_rate
            reduction_rows.append([name, engine, row.failure, f"{row.original_size} -> {row.final_size}",
                                   ", ".join(row.minimal), str(row.extra["simulations_started"]),
                                   f"{row.wall_time:.1f} s", f"{fails}/{runs}"])
            print(" | ".join(reduction_rows[-1]), flush=True)
    print()
    print(table(["world", "engine", "probe wall (median / max)", "simulated (median)", "real-time factor",
                 f"seeds 0-{arguments.seeds - 1}"], probe_rows))
    if reduction_rows:
        print()
        print(table(["world", "engine", "failure (seed 0)", "models", "minimal world", "simulations", "wall time",
                     "minimal fails (fresh)"], reduction_rows))


if __name__ == "__main__":
    main()
