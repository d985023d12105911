"""The README's main job end to end, and where its time goes.

    python benchmarks/bench_job.py [--workers auto|1|2 ...] [--burners 0 1 2 ...] [--repeat 1]
                                   [--checkout PATH] [--out results.json] [-- extra pytest arguments]

Runs `pytest examples --ddenv-reduce` exactly as the README's user does (a fresh process in the checkout, the
artifacts in a temporary folder, `--ddenv-workers W` unless W is `default`), once per workers x burners x
repetition, with `--burners N` real CPU-bound processes (`yes > /dev/null` each) running beside it the whole time.
Then prints, from what the plugin records in each reduction's `summary.json` (`timings`, seconds):

- per test: the failing test's own run (`test_run`), starting the probe pool (`pool_start`), `confirmation`
  (the failure on the pool: worker start-up is paid here), `reduction` (the models), `recording_runs` (the
  runs the pictures and media are drawn from), `stages`, `files` (minimal worlds, summary), `pictures`
  (`pictures_background` since issue 33's second session: drawn in the media's background process),
  `media` (animations and recordings: in a background process since issue 33, beside the next test) and
  `media_wait` (how long the session waited for them at its end);
- in total: the command's wall time, pytest's start-up and collection (`pytest examples --collect-only -q`
  timed on its own before), the sums of the columns above, and the rest (passing tests, the doorway's rate,
  the session's end).

A checkout without the `timings` (before issue 33) shows the wall time, simulations and media seconds only.
The load average (1 min) before and after each run is printed beside it, and the CPU seconds of the job's
whole process tree (pytest, the forkserver, the probe workers, the media processes; sampled every 0.1 s with
psutil, which `.[dev]` installs through dask: a process's last 0.1 s may be missed): figures from a shared
machine are only comparable to figures taken at the same load, the CPU seconds less so.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_loaded import start_burners, stop_burners

ROOT = Path(__file__).resolve().parent.parent
PHASES = ("test_run", "pool_start", "confirmation", "reduction", "recording_runs", "stages", "files", "pictures",
          "pictures_background", "media", "media_wait")
BACKGROUND = ("pictures_background", "media")
"""The phases made in a background process beside the rest (not on the job's critical path)."""


@contextlib.contextmanager
def burners(count: int) -> Iterator[None]:
    """`count` CPU-bound processes running for the block's duration (bench_loaded's)."""
    processes = start_burners(count)
    try:
        yield
    finally:
        stop_burners(processes)


def load() -> float:
    return round(os.getloadavg()[0], 2)


def collection_seconds(checkout: Path, extra: Sequence[str]) -> float:
    """pytest's start-up and collection of the examples (with the plugin loaded), on their own."""
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "pytest", "examples", "--collect-only", "-q", "-p", "no:cacheprovider",
                    *extra], cwd=checkout, capture_output=True, check=False)
    return time.perf_counter() - started


class TreeCpu:
    """The CPU seconds (user + system) of a process and all its descendants, sampled in a thread while it runs:
    each process's largest reading, summed (a process's children's times are not added: they are sampled
    themselves)."""

    def __init__(self, pid: int, interval: float = 0.1) -> None:
        self.pid, self.interval = pid, interval
        self.seen: dict[tuple[int, float], float] = {}
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._sample, daemon=True)
        self.thread.start()

    def _sample(self) -> None:
        try:
            import psutil
        except ImportError:  # no psutil: no CPU figure
            return
        while not self.stop.is_set():
            try:
                root = psutil.Process(self.pid)
                processes = [root, *root.children(recursive=True)]
            except psutil.Error:
                processes = []
            for process in processes:
                try:
                    times = process.cpu_times()
                    key = (process.pid, process.create_time())
                except psutil.Error:
                    continue
                self.seen[key] = max(self.seen.get(key, 0.0), times.user + times.system)
            self.stop.wait(self.interval)

    def seconds(self) -> float | None:
        self.stop.set()
        self.thread.join()
        return round(sum(self.seen.values()), 1) if self.seen else None


def run_job(checkout: Path, workers: str, extra: Sequence[str]) -> dict[str, Any]:
    """One run of the README job in a fresh artifacts folder: wall time, exit status, the summaries."""
    with tempfile.TemporaryDirectory(prefix="ddenv-bench-job-") as folder:
        command = [sys.executable, "-m", "pytest", "examples", "--ddenv-reduce", "--ddenv-artifacts", folder, "-q",
                   "-p", "no:cacheprovider", *([] if workers == "default" else ["--ddenv-workers", workers]), *extra]
        before = load()
        started = time.perf_counter()
        with subprocess.Popen(command, cwd=checkout, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) as job:
            cpu = TreeCpu(job.pid)
            stdout, _ = job.communicate()
        wall = time.perf_counter() - started
        cpu_seconds = cpu.seconds()
        summaries = [json.loads(path.read_text()) for path in sorted(Path(folder).glob("*/summary.json"))]
    lines = stdout.strip().splitlines()
    tail = lines[-1:] or [""]
    warned = [line.strip() for line in lines if "Warning" in line]  # pytest's warnings summary, one line each
    return {"command": " ".join(command), "exit": job.returncode, "wall": round(wall, 2), "cpu": cpu_seconds,
            "load_before": before, "load_after": load(), "warnings": warned, "last_line": tail[0],
            "tests": [test_row(summary) for summary in summaries]}


def test_row(summary: dict[str, Any]) -> dict[str, Any]:
    timings = summary.get("timings", {})
    media = summary.get("media") or {}
    pool = summary.get("workers") or {}
    return {"test": str(summary.get("test", "?")).split("::")[-1], "simulations": summary.get("simulations"),
            "workers": pool.get("workers"),
            "timings": {phase: timings.get(phase) for phase in PHASES},
            "media_seconds": media.get("seconds")}


def show(result: dict[str, Any]) -> None:
    print(f"\n## workers {result['workers']}, burners {result['burners']}: {result['wall']:.1f} s wall, "
          f"{result['cpu']} CPU-s (exit {result['exit']}, load {result['load_before']} -> {result['load_after']}), "
          f"start-up and collection {result['collection']:.1f} s; {result['last_line']}")
    headers = ["test", "sims", "workers", *PHASES]
    print("| " + " | ".join(headers) + " |")
    print("|" + "---|" * len(headers))
    totals = dict.fromkeys(PHASES, 0.0)
    for row in result["tests"]:
        cells = []
        for phase in PHASES:
            value = row["timings"][phase]
            if phase == "media" and value is None:
                value = row["media_seconds"]
            totals[phase] += value or 0.0
            cells.append("" if value is None else f"{value:.1f}")
        print(f"| {row['test']} | {row['simulations']} | {row.get('workers')} | " + " | ".join(cells) + " |")
    print(f"| total ({len(result['tests'])} reductions) | {sum(r['simulations'] or 0 for r in result['tests'])} | | "
          + " | ".join(f"{totals[phase]:.1f}" for phase in PHASES) + " |")
    critical = sum(totals[phase] for phase in PHASES if phase not in BACKGROUND)
    print(f"rest (start-up, collection, passing tests, the doorway's rate, session end): "
          f"{result['wall'] - critical:.1f} s of which start-up and collection {result['collection']:.1f} s")
    for line in result["warnings"]:
        print(f"warning: {line}")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--workers", nargs="+", default=["default"],
                        help="--ddenv-workers values; 'default' passes none (the plugin's default)")
    parser.add_argument("--burners", nargs="+", type=int, default=[0], help="CPU-bound processes beside the job")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--checkout", type=Path, default=ROOT, help="the repository to run the examples of")
    parser.add_argument("--out", type=Path, default=None, help="every run as JSON, written as it happens")
    parser.add_argument("extra", nargs="*", help="more pytest arguments (after --)")
    args = parser.parse_args(argv)
    results = []
    for count in args.burners:
        with burners(count):
            collection = collection_seconds(args.checkout, args.extra)
            for _ in range(args.repeat):
                for workers in args.workers:
                    result = {"workers": workers, "burners": count, "collection": round(collection, 2),
                              **run_job(args.checkout, workers, args.extra)}
                    show(result)
                    results.append(result)
                    if args.out is not None:
                        args.out.write_text(json.dumps(results, indent=1) + "\n")
    print("\n| burners | workers | wall s | CPU-s | load before | simulations |")
    print("|---|---|---|---|---|---|")
    for result in results:
        print(f"| {result['burners']} | {result['workers']} | {result['wall']:.1f} | {result['cpu']} | "
              f"{result['load_before']} | "
              f"{sum(row['simulations'] or 0 for row in result['tests'])} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
