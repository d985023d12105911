"""Controller cost: simulation speed with a Python controller called every control tick vs the built-in law.

    python benchmarks/bench_controller.py --quick                       # 1 seed, 3 repeats, 5 s simulated
    python benchmarks/bench_controller.py [--worlds worlds/ditch.yaml worlds/rubble.yaml] [--seeds 0 1 2]
                                          [--repeat 5] [--timeout 10] [--out controller.json]

Variants, on each world and noise seed:

- builtin: the default run (`controller=None`: the built-in `GoToGoal` law, `default_controller(settings)`);
- function: `controller=` a plain Python function that computes the same go-to-goal command (the arithmetic of
  `GoToGoal`, copied): the same commands, so the same trajectory, bit for bit (checked);
- scan: the same function, but it also reads the laser scan every tick (numpy: the clearance in a corridor
  ahead and the nearest hit) before returning the same command: the same trajectory again;
- avoid: `AvoidObstacles(GoToGoal())` from pytest_ddenv.sim.controllers (reads the scan every tick and turns away
  from what lies ahead: the robot drives differently, so its physics cost differs too).

Every run goes through the probe path of `ddenv run/reduce`: a `ScenarioJob` (no predicates, `timeout=`
the same simulated duration for every variant, `RunSettings(stop_early=False)`) whose handler runs in this
process (one core, no worker processes: nothing to start, nothing to warm but the first run of each world
and variant, which is not timed). The measure is the run's own wall time (`Run.wall_time`: the control
loop, physics and sensors; the world build is the same for every variant and excluded) per simulated
second: the median over `--repeat` runs per seed (variants interleaved, order rotated per repeat), then the
mean over seeds. The CPU time of the whole handler call (world build included) per simulated second is
printed beside it: on a machine other jobs load it moves much less than wall time. The controller is
called on every control tick (20 Hz) unless the robot has reached its goal (then it is told to stand
still): the "goal reached" column says whether that happened.

Target: the function variant at most 10 % slower than the built-in law.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import load, machine, table, write_json

from pytest_ddenv.sim.controllers import AvoidObstacles, GoToGoal
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.sim import Command, ControllerLike, Observation, RunSettings
from pytest_ddenv.world import World

ROOT = Path(__file__).resolve().parent.parent
WORLDS = (ROOT / "worlds" / "ditch.yaml", ROOT / "worlds" / "rubble.yaml")
TARGET_PERCENT = 10.0
SETTINGS = RunSettings(stop_early=False)

# GoToGoal's default gains (RunSettings' max_speed, turn_gain, max_turn_rate), as a user would write them
MAX_SPEED = 1.0
TURN_GAIN = 2.0
MAX_TURN_RATE = 0.8
STOP_DISTANCE = 0.05
CORRIDOR_HALF_WIDTH = 0.4
CORRIDOR_DEPTH = 1.4


def go_to_goal(observation: Observation) -> Command:
    """A user's go-to-goal controller: the arithmetic of `GoToGoal()`, as a plain function."""
    x, y, yaw = observation.pose
    goal = observation.goal
    dx, dy = goal[0] - x, goal[1] - y
    distance = math.hypot(dx, dy)
    if distance < STOP_DISTANCE:
        return Command(0.0, 0.0)
    error = (math.atan2(dy, dx) - yaw + math.pi) % (2.0 * math.pi) - math.pi
    angular = max(-MAX_TURN_RATE, min(MAX_TURN_RATE, TURN_GAIN * error))
    linear = min(MAX_SPEED, 0.8 * distance) * max(0.0, math.cos(error)) ** 2
    return Command(linear, angular)


class ScanReader:
    """`go_to_goal` after reading the laser scan (numpy on `scan.ranges` every tick); `clearance` and
    `nearest` keep what it computed, so the work is really done."""

    def __init__(self) -> None:
        self.clearance = math.inf
        self.nearest = math.inf

    def __call__(self, observation: Observation) -> Command:
        scan = observation.scan
        if scan is not None:
            finite = np.isfinite(scan.ranges)
            ranges = np.where(finite, scan.ranges, scan.max_range)
            ahead = ranges * np.cos(scan.angles)
            side = ranges * np.sin(scan.angles)
            blocking = finite & (ahead > 0.0) & (ahead < CORRIDOR_DEPTH) & (np.abs(side) < CORRIDOR_HALF_WIDTH)
            self.clearance = float(ahead[blocking].min()) if blocking.any() else math.inf
            self.nearest = float(ranges.min())
        return go_to_goal(observation)


VARIANTS: dict[str, tuple[str, Callable[[], ControllerLike | None]]] = {
    # name: (label in the table, a fresh controller for one run; None = the default, built-in law)
    "builtin": ("(a) built-in GoToGoal (default run)", lambda: None),
    "function": ("(b) Python function, same go-to-goal arithmetic", lambda: go_to_goal),
    "scan": ("(c) Python function + laser scan (numpy)", ScanReader),
    "avoid": ("(c') AvoidObstacles(GoToGoal()) (drives differently)", lambda: AvoidObstacles(GoToGoal())),
}


@dataclass(frozen=True)
class Sample:
    """One timed run."""

    world: str
    variant: str
    seed: int
    repeat: int
    sim_time: float
    wall_time: float
    """`Run.wall_time`: the control loop (controller, physics, sensors), world build excluded."""
    probe_time: float
    """The whole handler call (world build and result included)."""
    cpu_time: float
    """CPU seconds of this process during the whole handler call (steadier than wall time under load)."""
    reached_goal: bool
    final_pose: tuple[float, ...]

    @property
    def wall_per_sim_second(self) -> float:
        return self.wall_time / self.sim_time

    @property
    def cpu_per_sim_second(self) -> float:
        return self.cpu_time / self.sim_time


def run_once(world: World, variant: str, seed: int, timeout: float) -> tuple[Any, float, float]:
    """One run of `world` with `variant`'s controller through a `ScenarioJob` handler in this process:
    (the `Run`, wall seconds and CPU seconds the handler took)."""
    job = ScenarioJob((), seed=seed, timeout=timeout, controller=VARIANTS[variant][1](), settings=SETTINGS,
                      max_wall_time=None)
    handler = job.handler()
    started, cpu = time.perf_counter(), time.process_time()
    result = handler(world, 0)
    seconds, cpu = time.perf_counter() - started, time.process_time() - cpu
    if result.error is not None or result.run is None:
        detail = result.error.describe() if result.error is not None else "no run"
        raise RuntimeError(f"{world.name or world.source}: {variant}: the run did not complete: {detail}")
    return result.run, seconds, cpu


def measure(world: World, *, seeds: Sequence[int], repeat: int, timeout: float,
            variants: Sequence[str] = tuple(VARIANTS), label: str | None = None,
            progress: Callable[[str], None] | None = None) -> list[Sample]:
    """Time every variant on `world` for each seed, `repeat` times, interleaved (untimed warm-up run first)."""
    name = label or world.name or str(world.source)
    for variant in variants:  # imports, caches, the simulator: not timed
        run_once(world, variant, seeds[0], min(timeout, 0.5))
    samples: list[Sample] = []
    for index in range(repeat):
        for seed in seeds:
            shift = (index + seed) % len(variants)  # rotate the order: a loaded machine drifts
            for variant in [*variants[shift:], *variants[:shift]]:
                run, seconds, cpu = run_once(world, variant, seed, timeout)
                samples.append(Sample(name, variant, seed, index, float(run.sim_time), float(run.wall_time),
                                      seconds, cpu, bool(run.reached_goal), tuple(float(v) for v in run.poses[-1])))
        if progress is not None:
            progress(f"{name}: repeat {index + 1}/{repeat} done, load {load()}")
    return sorted(samples, key=lambda s: (list(variants).index(s.variant), s.seed, s.repeat))


def summarize(samples: Sequence[Sample]) -> list[dict[str, Any]]:
    """Per world and variant: ms of wall time per simulated second (median over repeats per seed, mean over
    seeds), the real-time factor, and the slowdown relative to the built-in law on the same world (%)."""
    rows: list[dict[str, Any]] = []
    worlds = list(dict.fromkeys(s.world for s in samples))
    for world in worlds:
        mine = [s for s in samples if s.world == world]
        wall: dict[str, float] = {}
        cpu: dict[str, float] = {}
        for variant in dict.fromkeys(s.variant for s in mine):
            runs = [s for s in mine if s.variant == variant]
            seeds = sorted({s.seed for s in runs})
            wall[variant] = _seed_mean(runs, seeds, lambda s: s.wall_per_sim_second)
            cpu[variant] = _seed_mean(runs, seeds, lambda s: s.cpu_per_sim_second)
            rows.append({
                "world": world, "variant": variant, "label": VARIANTS[variant][0] if variant in VARIANTS else variant,
                "runs": len(runs), "seeds": seeds, "sim_time": statistics.mean(s.sim_time for s in runs),
                "ms_per_sim_second": 1000.0 * wall[variant], "real_time_factor": 1.0 / wall[variant],
                "cpu_ms_per_sim_second": 1000.0 * cpu[variant],
                "probe_seconds": statistics.median(s.probe_time for s in runs),
                "reached_goal": sum(s.reached_goal for s in runs),
            })
        for row in rows:
            if row["world"] == world:
                row["slowdown"] = _percent(wall, row["variant"])
                row["cpu_slowdown"] = _percent(cpu, row["variant"])
    return rows


def _seed_mean(runs: Sequence[Sample], seeds: Sequence[int], value: Callable[[Sample], float]) -> float:
    return statistics.mean(statistics.median(value(s) for s in runs if s.seed == seed) for seed in seeds)


def _percent(values: dict[str, float], variant: str) -> float | None:
    base = values.get("builtin")
    return None if base is None else round(100.0 * (values[variant] / base - 1.0), 1)


def same_trajectory(samples: Sequence[Sample], variant: str) -> bool:
    """Whether `variant` ended every run where the built-in law did (same commands, same physics)."""
    base = {(s.world, s.seed, s.repeat): s.final_pose for s in samples if s.variant == "builtin"}
    return all(base.get((s.world, s.seed, s.repeat)) == s.final_pose for s in samples if s.variant == variant)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="first seed only, 3 repeats, 5 s simulated")
    parser.add_argument("--worlds", nargs="+", default=[str(w) for w in WORLDS])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--repeat", type=int, default=5, help="runs per world, variant and seed (median used)")
    parser.add_argument("--timeout", type=float, default=10.0,
                        help="simulated seconds of every run (the same for every variant)")
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--out", help="write every sample and the summary to this JSON file")
    args = parser.parse_args(argv)
    seeds = args.seeds[:1] if args.quick else args.seeds
    repeat = min(args.repeat, 3) if args.quick else args.repeat
    timeout = min(args.timeout, 5.0) if args.quick else args.timeout
    variants = ["builtin", *[v for v in args.variants if v != "builtin"]]

    info = machine()
    given = argv if argv is not None else sys.argv[1:]
    info["command"] = " ".join(["python", "benchmarks/bench_controller.py", *given])
    print(f"{info['date']}  {info['cores']} cores, {info['cpu']}, load average {info['load_average']}")
    print(f"seeds {seeds}, {repeat} repeat(s), {timeout:g} s simulated per run, control at {SETTINGS.control_rate:g} "
          f"Hz, laser {SETTINGS.laser_rays} rays at {SETTINGS.laser_rate:g} Hz; one process, no workers\n",
          flush=True)
    samples: list[Sample] = []
    for path in args.worlds:
        world = World.load(path)
        samples += measure(world, seeds=seeds, repeat=repeat, timeout=timeout, variants=variants,
                           label=Path(path).name, progress=lambda text: print(text, file=sys.stderr, flush=True))
    rows = summarize(samples)
    print(table(
        ["world", "controller", "runs", "simulated s per run", "wall ms per simulated s", "real-time factor",
         "slowdown vs (a)", "CPU ms per simulated s (whole run)", "CPU slowdown vs (a)", "goal reached"],
        [[r["world"], r["label"], r["runs"], f"{r['sim_time']:.2f}", f"{r['ms_per_sim_second']:.1f}",
          f"{r['real_time_factor']:.1f}x", "-" if r["variant"] == "builtin" else f"{r['slowdown']:+.1f} %",
          f"{r['cpu_ms_per_sim_second']:.1f}", "-" if r["variant"] == "builtin" else f"{r['cpu_slowdown']:+.1f} %",
          f"{r['reached_goal']}/{r['runs']}"] for r in rows],
    ))
    print()
    for variant in ("function", "scan"):
        if variant in variants:
            print(f"{VARIANTS[variant][0]}: same trajectory as (a) in every run: "
                  f"{'yes' if same_trajectory(samples, variant) else 'NO'}")
    for row in rows:
        if row["variant"] == "function":
            ok = row["slowdown"] <= TARGET_PERCENT
            print(f"target {row['world']}: (b) at most {TARGET_PERCENT:g} % slower than (a): "
                  f"{row['slowdown']:+.1f} % wall ({row['cpu_slowdown']:+.1f} % CPU): {'met' if ok else 'NOT met'}")
    print(f"\nload average at the end {load()}")
    write_json(args.out, {"machine": info, "settings": {**vars(args), "seeds": seeds, "repeat": repeat,
                                                         "timeout": timeout},
                          "samples": [asdict(s) for s in samples], "summary": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
