"""What the animations and the 3D recordings add to a reduction (`--media all` against `--media pictures`).

    python benchmarks/bench_media.py [--scenarios ditch rubble friction cul_de_sac] [--out FILE.json]

For each scenario it runs `ddenv reduce WORLD ... --workers 2` twice as a user would (a fresh process and a
fresh artifacts folder each): once with `--media pictures` (the PNG pictures only), once with `--media all`
(plus original.gif, minimal.gif, recording.rrd and recording.mcap, each recording when its package is
installed). Per row: both wall times and their difference, the simulations of each (the `all` run makes one
more: the minimal world's recorded run), and from the `all` run's summary.json the seconds spent writing the
media in the reducing process, each file's frames (a GIF's), size and seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
STUCK = "stuck:window=5,min_progress=0.2"
SCENARIOS: dict[str, tuple[str, ...]] = {  # the predicates and schemas of examples/test_paper_scenarios.py
    "ditch": ("-p", STUCK, "--partition", "model2model", "--priority", "avg-trajectory"),
    "rubble": ("-p", "high_centered", "-p", STUCK, "--partition", "timeseg", "--priority", "avg-trajectory"),
    "friction": ("-p", STUCK, "--partition", "model2model", "--priority", "avg-trajectory"),
    "cul_de_sac": ("-p", STUCK),
}


def reduce_once(name: str, media: str, folder: Path) -> tuple[float, dict[str, Any]]:
    command = ["ddenv", "reduce", str(ROOT / "worlds" / f"{name}.yaml"), *SCENARIOS[name], "--workers", "2",
               "--media", media, "--out", str(folder), "--quiet"]
    started = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, env={**os.environ, "DDENV_MEDIA": ""})
    seconds = time.perf_counter() - started
    return seconds, json.loads((folder / "summary.json").read_text())


def measure(name: str) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as scratch:
        plain_seconds, plain = reduce_once(name, "pictures", Path(scratch) / "pictures")
        all_seconds, full = reduce_once(name, "all", Path(scratch) / "all")
    media = full.get("media", {})
    files = media.get("files", {})
    return {
        "scenario": name, "models": f"{full['original_size']} -> {full['minimal_size']}",
        "pictures_s": round(plain_seconds, 1), "all_s": round(all_seconds, 1),
        "added_s": round(all_seconds - plain_seconds, 1), "media_s": media.get("seconds"),
        "simulations": f"{plain['simulations']} / {full['simulations']}",
        "files": {file: {"frames": info.get("frames"), "kb": round(info.get("bytes", 0) / 1024),
                         "seconds": info.get("seconds")} for file, info in files.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    parser.add_argument("--out", type=Path, help="write the rows as JSON")
    arguments = parser.parse_args()
    rows = [measure(name) for name in arguments.scenarios]
    print(f"{'scenario':<11} {'models':<8} {'pictures':>8} {'all':>6} {'added':>6} {'media':>6}  simulations  files")
    for row in rows:
        files = ", ".join(f"{file} {info['frames'] or ''}{' fr ' if info['frames'] else ''}{info['kb']} KB "
                          f"{info['seconds']} s" for file, info in row["files"].items())
        print(f"{row['scenario']:<11} {row['models']:<8} {row['pictures_s']:>7}s {row['all_s']:>5}s "
              f"{row['added_s']:>5}s {row['media_s']:>5}s  {row['simulations']:<11}  {files}")
    if arguments.out:
        arguments.out.write_text(json.dumps({"python": sys.version.split()[0], "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
