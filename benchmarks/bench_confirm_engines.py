"""Cross-engine confirmation on the paper scenarios: how often the minimal and the original world fail in the
reduction's engine and in the other one, and what the confirmation costs beside the reduction.

    python benchmarks/bench_confirm_engines.py --quick                 # ditch, seed 0
    python benchmarks/bench_confirm_engines.py [--seeds 0 1 2]         # 3 scenarios x 3 seeds

For each paper scenario (the predicates and schema pairing of examples/test_paper_scenarios.py) and seed it
runs `ddenv reduce WORLD ... --seed S --engine ENGINE --confirm-engines OTHER --workers 2 --media none` as a
user would (a fresh process, the default budget and stages), and reads `summary.json`: the minimal and the
original world's rates in both engines with their 95 % Wilson intervals (`cross_engine`), the flag, and the
cost of the confirmation (its simulations, worker CPU seconds and wall seconds, `cross_engine`) next to the
reduction's (every other simulation, CPU second and the wall time of the whole command less the
confirmation's). `--out` writes every row as JSON.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
STUCK = "stuck:window=5,min_progress=0.2"
SCENARIOS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # predicates, schema pairing: as examples/test_paper_scenarios.py
    "ditch": ((STUCK,), ("--partition", "model2model", "--priority", "avg-trajectory")),
    "rubble": (("high_centered", STUCK), ("--partition", "timeseg", "--priority", "avg-trajectory")),
    "friction": ((STUCK,), ("--partition", "model2model", "--priority", "avg-trajectory")),
}
OTHER = {"pybullet": "mujoco", "mujoco": "pybullet"}


def command(scenario: str, seed: int, engine: str, out: Path) -> list[str]:
    predicates, pairing = SCENARIOS[scenario]
    return [sys.executable, "-m", "pytest_ddenv", "reduce", str(ROOT / "worlds" / f"{scenario}.yaml"),
            *(word for predicate in predicates for word in ("-p", predicate)), *pairing, "--seed", str(seed),
            "--engine", engine, "--confirm-engines", OTHER[engine], "--workers", "2", "--media", "none",
            "--out", str(out), "--quiet"]


def measure(scenario: str, seed: int, engine: str) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="ddenv-bench-confirm-") as folder:
        out = Path(folder) / "artifacts"
        started = time.monotonic()
        done = subprocess.run(command(scenario, seed, engine, out), cwd=folder, capture_output=True, text=True,
                              check=False)
        wall = time.monotonic() - started
        summary_path = out / "summary.json"
        if not summary_path.exists():
            return {"scenario": scenario, "seed": seed, "engine": engine, "error": (done.stderr or done.stdout)[-400:]}
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
    crossed = summary.get("cross_engine")
    row: dict[str, Any] = {"scenario": scenario, "seed": seed, "engine": engine,
                           "status": summary.get("status", "reduced"),
                           "size": f"{summary.get('original_size')} -> {summary.get('minimal_size', '-')}"}
    if crossed is None:
        return {**row, "error": summary.get("message", "no cross_engine in summary.json")}
    row.update({
        "minimal": crossed["minimal"]["rates"], "original": crossed["original"]["rates"], "flag": crossed["flag"],
        "confirm_simulations": crossed["simulations"], "confirm_cpu": crossed["cpu_seconds"],
        "confirm_wall": crossed["wall_seconds"],
        "reduction_simulations": summary["simulations"] - crossed["simulations"],
        "reduction_cpu": round(summary["cpu_seconds"] - crossed["cpu_seconds"], 3),
        "reduction_wall": round(wall - crossed["wall_seconds"], 3),
    })
    return row


def rate_text(rate: dict[str, Any]) -> str:
    low, high = rate["interval"]
    errors = f" +{rate['errors']}err" if rate["errors"] else ""
    return f"{rate['fails']}/{rate['runs']} [{low:.2f}, {high:.2f}]{errors}"


def rates_table(rows: list[dict[str, Any]]) -> str:
    header = ("| scenario | seed | models | minimal: reduction's engine | minimal: other engine | original: "
              "reduction's engine | original: other engine | flag |")
    lines = [header, "|---|---|---|---|---|---|---|---|"]
    for row in rows:
        if "error" in row:
            lines.append(f"| {row['scenario']} | {row['seed']} | {row.get('size', '')} | error: "
                         f"{row['error'].splitlines()[-1] if row['error'] else '?'} | | | | |")
            continue
        cells = [f"{rate['engine']} {rate_text(rate)}" for world in ("minimal", "original") for rate in row[world]]
        lines.append(f"| {row['scenario']} | {row['seed']} | {row['size']} | {' | '.join(cells)} | "
                     f"{row['flag'] or '-'} |")
    return "\n".join(lines)


def cost_table(rows: list[dict[str, Any]]) -> str:
    lines = ["| scenario | seed | reduction: simulations, CPU s, wall s | confirmation: simulations, CPU s, wall s |",
             "|---|---|---|---|"]
    for row in rows:
        if "error" in row:
            continue
        lines.append(f"| {row['scenario']} | {row['seed']} | {row['reduction_simulations']}, "
                     f"{row['reduction_cpu']:.1f}, {row['reduction_wall']:.1f} | {row['confirm_simulations']}, "
                     f"{row['confirm_cpu']:.1f}, {row['confirm_wall']:.1f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="ditch, seed 0 only")
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--engine", default="pybullet", choices=list(OTHER),
                        help="the reduction's engine (the other one confirms)")
    parser.add_argument("--out", type=Path, help="write the rows as JSON here")
    arguments = parser.parse_args(argv)
    scenarios, seeds = (["ditch"], [0]) if arguments.quick else (arguments.scenarios, arguments.seeds)
    started = time.monotonic()
    rows = []
    for scenario in scenarios:
        for seed in seeds:
            rows.append(measure(scenario, seed, arguments.engine))
            print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    print(rates_table(rows))
    print()
    print(cost_table(rows))
    print(f"\n{len(rows)} reductions in {(time.monotonic() - started) / 60:.1f} min")
    if arguments.out is not None:
        arguments.out.write_text(json.dumps(rows, indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
