"""Rubble, before and after (issue 33, point 3): prints Markdown tables. Not a timed test.

    python benchmarks/bench_rubble.py                    # this checkout
    python benchmarks/bench_rubble.py --compare main     # and the code and worlds of a git ref, same machine
    python benchmarks/bench_rubble.py --no-reduce        # the real-time factors only (seconds, not minutes)

Per noise seed (0 1 2 by default): one probe of worlds/rubble.yaml as `ddenv run/reduce` runs it (a
`ScenarioJob` with the examples' predicates, high_centered and stuck, handled in this process: world
build, run, result), timed `--repeats` times after one untimed warm-up; the real-time factor is the
simulated seconds over the probe's CPU seconds (median), and over its wall seconds. Then `ddenv reduce
worlds/rubble.yaml --seed S` with the examples' schemas (timeseg + avg-trajectory, deflake auto, the
failure-rate check, stages `models` only, `--workers 2`, no media): the minimal world and the simulations
it took (`summary.json`).

With `--compare REF` the ref's files (`git archive REF`) go to a temporary folder and every measurement runs
there as well (`PYTHONPATH` first on the path): the probes of one checkout and then the other's, the
reductions in turn for each seed; the "largest
deviation" column is the largest distance between the robot's recorded positions (x, y, z) of the two runs
of a seed over their common samples, to read against the oracle's 0.5 m tolerance.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import platform
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
PREDICATES = ("high_centered", "stuck:window=5,min_progress=0.2")


def probe_rows(seeds: list[int], repeats: int) -> list[dict[str, Any]]:
    """Run in the checkout under test (the `--probe` child): one row per seed."""
    import pytest_ddenv
    from pytest_ddenv.driver.scenario_job import ScenarioJob
    from pytest_ddenv.oracle import PredicateSpec
    from pytest_ddenv.world import World

    world = World.load(Path(pytest_ddenv.__file__).resolve().parent.parent / "worlds" / "rubble.yaml")
    specs = (PredicateSpec("high_centered", {}), PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}))
    ScenarioJob(specs, seed=0).handler()(world, 0)  # warm-up: not timed
    rows = []
    for seed in seeds:
        cpus, walls, run = [], [], None
        for _ in range(repeats):
            handler = ScenarioJob(specs, seed=seed).handler()
            cpu, wall = time.process_time(), time.perf_counter()
            result = handler(world, 0)
            cpus.append(time.process_time() - cpu)
            walls.append(time.perf_counter() - wall)
            run = result.run
            if run is None:
                raise SystemExit(f"rubble seed {seed}: the scenario could not be run: {result.error}")
        assert run is not None
        failure = run.failure
        rows.append({
            "seed": seed, "sim_time": run.sim_time, "cpu": statistics.median(cpus), "wall": statistics.median(walls),
            "failure": "pass" if failure is None else
            f"{failure.predicate} at t = {failure.time:.2f} s, ({failure.position[0]:.2f}, {failure.position[1]:.2f})",
            "positions": run.poses[:, :3].tolist(),
        })
    return rows


def measure(root: Path, seeds: list[int], repeats: int) -> list[dict[str, Any]]:
    """The probe rows of the checkout at `root`, measured in a fresh process that imports it."""
    done = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--probe", "--seeds", *map(str, seeds),
         "--repeats", str(repeats)],
        env=_env(root), cwd=root, capture_output=True, text=True, check=False,
    )
    if done.returncode != 0:
        raise SystemExit(f"the probes in {root} exited with {done.returncode}:\n{done.stderr[-2000:]}")
    rows: list[dict[str, Any]] = json.loads(done.stdout.strip().splitlines()[-1])
    return rows


def reduce(root: Path, seed: int, out: Path) -> dict[str, Any]:
    """`ddenv reduce` of the checkout at `root`'s rubble world: minimal world, simulations, wall seconds."""
    command = [sys.executable, "-m", "pytest_ddenv.cli", "reduce", "worlds/rubble.yaml",
               *[arg for p in PREDICATES for arg in ("--predicate", p)], "--partition", "timeseg",
               "--priority", "avg-trajectory", "--seed", str(seed), "--workers", "2", "--media", "none",
               "--stages", "models", "-q", "--out", str(out)]
    started = time.perf_counter()
    done = subprocess.run(command, env=_env(root), cwd=root, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command[1:])} in {root} exited with {done.returncode}:\n{done.stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text())
    rate = summary.get("rate_check") or {}
    return {"minimal": summary["minimal_models"], "simulations": summary["simulations"],
            "wall": time.perf_counter() - started, "rate": rate.get("decision", "")}


def _env(root: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(root), "DDENV_MEDIA": "none"}


def extract(ref: str, into: Path) -> Path:
    """The files of git ref `ref` of this repository, in `into`."""
    data = subprocess.run(["git", "archive", ref], cwd=ROOT, capture_output=True, check=True).stdout
    with tarfile.open(fileobj=io.BytesIO(data)) as archive:
        archive.extractall(into, filter="data")
    return into


def deviation(a: list[list[float]], b: list[list[float]]) -> float:
    """The largest distance between the positions of `a` and `b` over their common samples."""
    common = zip(a, b, strict=False)  # a run that ends earlier has fewer samples
    return max((sum((x - y) ** 2 for x, y in zip(p, q, strict=True)) ** 0.5 for p, q in common), default=0.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--compare", metavar="REF", help="also measure this git ref (e.g. main)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-reduce", action="store_true", help="real-time factors only")
    parser.add_argument("--probe", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.probe:  # `measure` runs this child in the checkout it means to measure, with PYTHONPATH first
        import pytest_ddenv

        imported = Path(pytest_ddenv.__file__).resolve().parent.parent
        if imported != Path.cwd().resolve():
            raise SystemExit(f"bench_rubble: imported pytest_ddenv from {imported}, not from {Path.cwd()}")
        print(json.dumps(probe_rows(args.seeds, args.repeats)))
        return
    with tempfile.TemporaryDirectory(prefix="bench-rubble-") as tmp:
        checkouts = {"this checkout": ROOT}
        if args.compare:
            checkouts = {args.compare: extract(args.compare, Path(tmp) / "ref"), **checkouts}
        load = os.getloadavg()[0]
        probes = {label: measure(root, args.seeds, args.repeats) for label, root in checkouts.items()}
        reductions: dict[str, list[dict[str, Any]]] = {label: [] for label in checkouts}
        if not args.no_reduce:
            for seed in args.seeds:
                for label, root in checkouts.items():
                    reductions[label].append(reduce(root, seed, Path(tmp) / f"{len(reductions[label])}-{label}"))
        print(f"# bench_rubble on {platform.node()} ({platform.machine()}), {time.strftime('%Y-%m-%d %H:%M')}, "
              f"load average {load:.1f} before, {os.getloadavg()[0]:.1f} after\n")
        reference = probes[args.compare] if args.compare else None
        print("| code | seed | failure | simulated | probe CPU | RTF (CPU) | probe wall | RTF (wall) | "
              "largest deviation from " + (args.compare or "-") + " |")
        print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
        for label, rows in probes.items():
            for i, row in enumerate(rows):
                moved = "-" if reference is None else f"{deviation(reference[i]['positions'], row['positions']):.3f} m"
                print(f"| {label} | {row['seed']} | {row['failure']} | {row['sim_time']:.2f} s | {row['cpu']:.2f} s | "
                      f"{row['sim_time'] / row['cpu']:.1f}x | {row['wall']:.2f} s | "
                      f"{row['sim_time'] / row['wall']:.1f}x | {moved} |")
        for label, rows in probes.items():
            simulated, cpu = sum(r["sim_time"] for r in rows), sum(r["cpu"] for r in rows)
            print(f"\n{label}: {simulated:.2f} simulated s in {cpu:.2f} CPU s, real-time factor (CPU) "
                  f"{simulated / cpu:.1f}x")
        if not args.no_reduce:
            print("\n| code | seed | minimal world | simulations | rate check | wall |\n|---|---:|---|---:|---|---:|")
            for label, done in reductions.items():
                for seed, row in zip(args.seeds, done, strict=True):
                    print(f"| {label} | {seed} | {len(row['minimal'])}: {', '.join(row['minimal'])} | "
                          f"{row['simulations']} | {row['rate']} | {row['wall']:.0f} s |")


if __name__ == "__main__":
    main()
