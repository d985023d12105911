"""Huge worlds end to end: `ddenv reduce` of seeded yards of 100 to 100 000 objects, as a user runs it.

    python benchmarks/bench_huge.py --quick [--workers 2] [--out huge.json]   # 100, 1 000, 10 000 objects
    python benchmarks/bench_huge.py [--sizes 100 1000 3000 10000 100000] [--workers 2] [--out huge.json]

Each yard is `python benchmarks/make_yard.py N --seed 0` (a wall pocket whose back wall, "pocket_back", is
the unique 1-minimal world; N - 3 static clutter objects off the robot's path). Per size it measures, in
this process: loading the yard's YAML (`World.load`) and one run of the whole yard (its CPU seconds, the
`stuck` predicate, seed 0); then it runs `ddenv reduce yard.yaml -p stuck:window=5,min_progress=0.2 --media
none --workers W` in a fresh process and reads its `summary.json`: every simulation started (the
confirmation, calibration, first-cut, fresh-run and speculative ones), the wall time from the command's start
to its exit (worker start-up, YAML loading and the files included), the minimal world and the first cut by
reach (models before -> after, the simulations of its trial).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import load, machine, table, write_json
from make_yard import CULPRITS, yard_yaml

STUCK = "stuck:window=5,min_progress=0.2"
QUICK = (100, 1000, 10000)
SIZES = (100, 1000, 3000, 10000, 100000)


def one_run_cpu(path: Path) -> tuple[float, float]:
    """(seconds to load the yard's YAML, CPU seconds of one run of the whole yard in this process)."""
    from pytest_ddenv.oracle import make_predicate
    from pytest_ddenv.sim import simulate
    from pytest_ddenv.world import World

    started = time.perf_counter()
    world = World.load(path)
    loaded = time.perf_counter() - started
    cpu = time.process_time()
    simulate(world, seed=0, predicates=[make_predicate("stuck", window=5.0, min_progress=0.2)])
    return loaded, time.process_time() - cpu


def reduce_yard(path: Path, out: Path, workers: int, options: list[str]) -> tuple[float, dict[str, Any]]:
    """(wall seconds of `ddenv reduce` from start to exit, its summary.json)."""
    command = [sys.executable, "-m", "pytest_ddenv", "reduce", str(path), "-p", STUCK, "--media", "none",
               "--workers", str(workers), "--out", str(out), "--quiet", *options]
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} exited {done.returncode}:\n{done.stdout}\n{done.stderr}")
    summary: dict[str, Any] = json.loads((out / "summary.json").read_text())
    return wall, summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=f"only {', '.join(map(str, QUICK))} objects")
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", help="write every measurement to this JSON file")
    parser.add_argument("--probe-timeout", type=float,
                        help="`ddenv reduce --probe-timeout` (the watchdog; default: the command's own)")
    args = parser.parse_args(argv)
    sizes = list(QUICK) if args.quick else args.sizes
    info = machine()
    info["command"] = " ".join(["python", "benchmarks/bench_huge.py", *(argv if argv is not None else sys.argv[1:])])
    print(f"{info['date']}  {info['cores']} cores, {info['cpu']}, load average {info['load_average']}", flush=True)
    results: dict[str, Any] = {"machine": info, "settings": vars(args), "rows": []}
    rows = []
    with TemporaryDirectory(prefix="ddenv-huge-") as folder:
        for size in sizes:
            path = Path(folder) / f"yard_{size}.yaml"
            path.write_text(yard_yaml(size, 0))
            loaded, cpu = one_run_cpu(path)
            options = [] if args.probe_timeout is None else ["--probe-timeout", str(args.probe_timeout)]
            wall, summary = reduce_yard(path, Path(folder) / f"out_{size}", args.workers, options)
            cut = summary.get("first_cut") or {}
            minimal = summary["minimal_models"]
            row = {"objects": size, "load_s": loaded, "one_run_cpu_s": cpu, "simulations": summary["simulations"],
                   "worker_cpu_s": summary["cpu_seconds"], "wall_s": wall, "minimal": minimal,
                   "exact": tuple(minimal) == CULPRITS, "first_cut": cut, "load_average": load()}
            results["rows"].append(row)
            write_json(args.out, results)
            rows.append([size, f"{loaded:.1f}", f"{cpu:.1f}", summary["simulations"], f"{summary['cpu_seconds']:.0f}",
                         f"{wall:.0f}", ", ".join(minimal),
                         f"{cut['original']} -> {cut['kept']} ({cut['simulations']} sims)" if cut else "not made",
                         row["load_average"]])
            print(f"N={size}: {wall:.0f} s, {summary['simulations']} simulations -> {minimal}, load {load()}",
                  flush=True)
    print()
    print(table(["objects", "yard load s", "one run CPU s", "simulations", "worker CPU s", "wall s (end to end)",
                 "minimal world", "first cut (models)", "load average after"], rows))
    write_json(args.out, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
