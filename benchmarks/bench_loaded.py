"""A big reduction beside CPU-bound processes: does `ddenv reduce` of a 3 000-object yard complete?

    python benchmarks/bench_loaded.py [--count 3000] [--seed 0] [--burners 2] [--workers auto]
                                      [--run-timeout SECONDS] [--json results/loaded.json]

Starts `--burners` real CPU burners (`yes > /dev/null`, one process each), writes the seeded yard of
`benchmarks/make_yard.py` (`--count` models, `--seed`), runs `ddenv reduce` on it as a user does (`python -m
pytest_ddenv.cli reduce yard.yaml -p stuck:window=5.0,min_progress=0.2 --media none --json`, the automatic
watchdog, `--workers`, and `--run-timeout` when given) and prints: completed or not (exit code, the error when
it did not), the minimal world (and whether it is the yard's culprit, `pocket_back`), the simulations, the
errors, the watchdog kills, the wall time, and the load average before and after. The burners are stopped at
the end whatever happens (SIGTERM and Ctrl-C included). Issue 33: before, the original run of a 3 000-object
yard under load was killed by the 60 s watchdog floor (no run had been timed yet).
"""

from __future__ import annotations

import argparse
import json
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from common import load, machine, table, write_json
from make_yard import CULPRITS, PREDICATES, yard_yaml

STUCK = "stuck:" + ",".join(f"{key}={value}" for key, value in PREDICATES[0].params.items())


def start_burners(count: int) -> list[subprocess.Popen[bytes]]:
    """`count` CPU-bound processes: `yes` writing to /dev/null (a Python busy loop where there is no `yes`)."""
    command = [shutil.which("yes") or ""] if shutil.which("yes") else [sys.executable, "-c", "while True: pass"]
    return [subprocess.Popen(command, stdout=subprocess.DEVNULL) for _ in range(count)]


def stop_burners(burners: list[subprocess.Popen[bytes]]) -> None:
    for burner in burners:
        burner.kill()
    for burner in burners:
        burner.wait()


def reduce_command(world: Path, out: Path, workers: str, run_timeout: float | None) -> list[str]:
    command = [sys.executable, "-m", "pytest_ddenv.cli", "reduce", str(world), "-p", STUCK, "--media", "none",
               "--workers", workers, "--out", str(out), "--json", "--quiet"]
    return command + ([] if run_timeout is None else ["--run-timeout", f"{run_timeout:g}"])


def measure(count: int, seed: int, burners: int, workers: str, run_timeout: float | None,
            folder: Path) -> dict[str, Any]:
    """One reduction of the yard beside `burners` CPU burners: what `main` prints."""
    world = folder / f"yard_{count}_seed{seed}.yaml"
    world.write_text(yard_yaml(count, seed))
    before = load()
    running = start_burners(burners)
    try:
        started = time.perf_counter()
        done = subprocess.run(reduce_command(world, folder / "out", workers, run_timeout), capture_output=True,
                              text=True, check=False)
        wall = time.perf_counter() - started
    finally:
        stop_burners(running)
    try:
        summary = json.loads(done.stdout)
    except json.JSONDecodeError:
        summary = {}
    minimal = summary.get("minimal_models")
    pool = summary.get("workers") or {}
    return {
        "count": count, "seed": seed, "burners": burners, "workers": workers, "run_timeout": run_timeout,
        "completed": done.returncode == 0 and bool(summary.get("complete", minimal is not None)),
        "exit_code": done.returncode, "error": summary.get("error") or (done.stderr.strip()[-2000:]
                                                                         if done.returncode else None),
        "minimal_models": minimal, "culprit_found": minimal == list(CULPRITS),
        "simulations": summary.get("simulations"), "errors": summary.get("errors"),
        "watchdog_kills": pool.get("timeouts"), "wall_seconds": round(wall, 1),
        "load_before": before, "load_after": load(),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=3000, help="models in the yard (default 3000)")
    parser.add_argument("--seed", type=int, default=0, help="the yard's seed (default 0)")
    parser.add_argument("--burners", type=int, default=2, help="CPU-bound processes beside it (default 2)")
    parser.add_argument("--workers", default="auto", help="ddenv reduce --workers (default auto)")
    parser.add_argument("--run-timeout", type=float, help="ddenv reduce --run-timeout (default: ddenv's, 300 s)")
    parser.add_argument("--json", help="also write the result to this file")
    args = parser.parse_args(argv)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # stopped: the burners are stopped too
    info = machine()
    with tempfile.TemporaryDirectory(prefix="ddenv-loaded-") as folder:
        result = measure(args.count, args.seed, args.burners, args.workers, args.run_timeout, Path(folder))
    print(f"{info['date']}  {info['cores']} cores, {info['cpu']}")
    print(table(["models", "burners", "workers", "completed", "minimal world", "simulations", "errors",
                 "watchdog kills", "wall s", "load before", "load after"],
                [[result["count"], result["burners"], result["workers"], "yes" if result["completed"] else "NO",
                  ", ".join(result["minimal_models"] or ["-"]), result["simulations"], result["errors"],
                  result["watchdog_kills"], result["wall_seconds"], result["load_before"], result["load_after"]]]))
    if result["error"]:
        print(f"error: {result['error']}")
    write_json(args.json, {"machine": info, "result": result})
    return 0 if result["completed"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
