"""Simulation benchmark (not a timed test): prints a Markdown table. Run: python benchmarks/bench_sim.py

Measures, on one core: real-time factor of the Husky on flat ground, with 40 static boxes, with 33
dynamic 2x4 boards; rebuild time of a world in a live Simulator; RSS over 200 runs; what early stopping
saves on a failing run; and one failing and one passing run of each shipped scenario.

The engine rows (real-time factor, rebuild, memory, early stop) drive a `Simulator` directly, with its
default controller (the built-in `GoToGoal`). The scenario rows go through the probe path of `ddenv
run/reduce`: a `ScenarioJob` (the predicates flipped, high_centered, stuck, timeout; noise seed s) whose
handler runs in this process; the time is the whole probe (world build, run, result), after one untimed
warm-up probe per world. No worker processes: nothing to start or warm besides that.
"""

from __future__ import annotations

import argparse
import platform
import resource
import statistics
import time
from pathlib import Path

import numpy as np

from pytest_ddenv.oracle import PredicateSpec, make_predicate
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.sim import RunSettings, Simulator
from pytest_ddenv.world import Model, Pose, Scenario, Shape, World

ROOT = Path(__file__).resolve().parent.parent


def _world(models: tuple[Model, ...] = (), timeout: float = 20.0, goal=(10.0, 0.0)) -> World:
    return World(models=models, scenario=Scenario(start=Pose(), goal=(goal[0], goal[1], None), timeout=timeout))


def static_boxes(n: int = 40) -> tuple[Model, ...]:
    rng = np.random.default_rng(0)
    return tuple(
        Model(f"box{i}", (Shape("box", size=(0.5, 0.5, 0.5)),),
              pose=Pose(float(rng.uniform(-10, 20)), float(rng.choice([-1, 1]) * rng.uniform(2, 10)), 0.25))
        for i in range(n)
    )


def boards(n: int = 33) -> tuple[Model, ...]:
    rng = np.random.default_rng(1)
    return tuple(
        Model(f"board{i}", (Shape("box", size=(1.2192, 0.038, 0.0888)),),
              pose=Pose(float(rng.uniform(1, 9)), float(rng.uniform(-1.5, 1.5)), 0.0444, 0, 0,
                        float(rng.uniform(-3.14, 3.14))),
              static=False, mass=1.411, mu=5.0)
        for i in range(n)
    )


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def rtf(sim: Simulator, world: World, repeats: int) -> tuple[float, float]:
    values = []
    for seed in range(repeats):
        run = sim.run(world, seed=seed, settings=RunSettings(stop_early=False))
        values.append(run.sim_time / run.wall_time)
    return statistics.median(values), min(values)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-scenarios", action="store_true")
    args = parser.parse_args()
    rows: list[tuple[str, str]] = []
    with Simulator() as sim:
        for label, world in (
            ("RTF, flat ground, 240 Hz, 20 s", _world()),
            ("RTF, + 40 static boxes", _world(static_boxes())),
            ("RTF, + 33 dynamic 2x4 boards in the path", _world(boards())),
        ):
            median, low = rtf(sim, world, args.repeats)
            rows.append((label, f"{median:.1f}x (min {low:.1f}x)"))
        # rebuild cost: a 0-step run is resetSimulation + world + robot + first state (timed from outside:
        # `Run.wall_time` starts once the world is built)
        for label, world in (("rebuild, 40 static boxes", _world(static_boxes(), timeout=1e-6)),
                             ("rebuild, 33 boards", _world(boards(), timeout=1e-6))):
            times = []
            for seed in range(20):
                started = time.perf_counter()
                sim.run(world, seed=seed)
                times.append((time.perf_counter() - started) * 1000)
            rows.append((label, f"{statistics.median(times):.1f} ms (max {max(times):.1f})"))
        short = _world(static_boxes(), timeout=0.5)
        before = rss_mb()
        for seed in range(200):
            sim.run(short, seed=seed)
            if seed == 19:
                after20 = rss_mb()
        rows.append(("max RSS before / after 20 / after 200 runs", f"{before:.0f} / {after20:.0f} / {rss_mb():.0f} MB"))
        wall = Model("wall", (Shape("box", size=(0.3, 6.0, 1.0)),), pose=Pose(4.0, 0.0, 0.5))
        failing = _world((wall,), timeout=60.0)
        stuck = [make_predicate("stuck")]
        early = sim.run(failing, seed=0, predicates=stuck)
        full = sim.run(failing, seed=0, predicates=stuck, settings=RunSettings(stop_early=False))
        rows.append(("early stop on a failing run (blocked by a wall, 60 s limit)",
                     f"{early.wall_time:.2f} s ({early.sim_time:.1f} sim s) vs {full.wall_time:.2f} s "
                     f"({full.sim_time:.0f} sim s): {full.wall_time / early.wall_time:.1f}x"))
    if not args.no_scenarios:
        specs = tuple(PredicateSpec(n, {}) for n in ("flipped", "high_centered", "stuck", "timeout"))
        for failing_name, passing_name in (("ditch", "ditch_ground_only"), ("rubble", "rubble_no_blocks"),
                                           ("friction", "friction_no_barrels")):
            for name in (failing_name, passing_name):
                path = ROOT / "worlds" / f"{name}.yaml"
                if not path.exists():
                    continue
                world = World.load(path)
                ScenarioJob(specs, seed=0).handler()(world, 0)  # warm-up: not timed
                runs, walls = [], []
                for seed in range(args.repeats):
                    handler = ScenarioJob(specs, seed=seed).handler()
                    started = time.perf_counter()
                    result = handler(world, 0)
                    walls.append(time.perf_counter() - started)
                    if result.run is None:
                        raise SystemExit(f"{name}: the scenario could not be run: {result.error}")
                    runs.append(result.run)
                outcome = "pass" if runs[0].reached_goal else runs[0].failure.predicate  # type: ignore[union-attr]
                rows.append((f"scenario {name} (seed 0: {outcome}, {runs[0].sim_time:.1f} sim s)",
                             f"{statistics.median(walls):.2f} s wall per probe (max {max(walls):.2f})"))
    print(f"# bench_sim on {platform.node()} ({platform.processor() or platform.machine()}), "
          f"{time.strftime('%Y-%m-%d %H:%M')}, pybullet {sim.pybullet_version}\n")
    print("| measurement | result |\n|---|---|")
    for label, value in rows:
        print(f"| {label} | {value} |")


if __name__ == "__main__":
    main()
