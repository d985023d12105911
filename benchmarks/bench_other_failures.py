"""The other failures a reduction meets on the paper scenarios, grouped as the report shows them.

    python benchmarks/bench_other_failures.py --quick          # ditch, seed 0 (about 0.3 min)
    python benchmarks/bench_other_failures.py [--seeds 0 1 2]  # 3 scenarios x 3 seeds (about 4 min on 2 cores)

For each paper scenario (the predicates of examples/test_paper_scenarios.py, the plugin's default schema
pairing as bench_stages.py, or `--pairing examples`) and seed, it runs `ddenv reduce WORLD ... --seed S
--keep-other 1 --media none --workers 2` as a user would (a fresh process, the default budget and stages) and
reads `summary.json`: the model-level probes (decided candidates), every simulation, the other-failure groups
(`other_failures`) with their probe counts and smallest worlds. Then it runs the replay command of the first
group (`ddenv run other-1.yaml` with the predicates and the run seed it failed with) and says whether it fails
the same way as the group (`same_failure` against the group's first signature, the reduction's tolerance).
`--out` writes every row as JSON.
"""

from __future__ import annotations

import argparse
import itertools
import json
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from bench_stages import DEFAULT_PAIRING, ROOT, SCENARIOS

from pytest_ddenv.oracle import FailureSignature, same_failure

LARGEST = 3
"""Groups described per row in the table (the JSON has all of them)."""


def reduce_command(scenario: str, seed: int, workers: int, folder: Path, pairing: tuple[str, ...]) -> list[str]:
    """`ddenv reduce` of a paper scenario with the examples' predicates, keeping the largest other failure."""
    predicates = SCENARIOS[scenario][0]
    return ["ddenv", "reduce", str(ROOT / "worlds" / f"{scenario}.yaml"), *[a for p in predicates for a in ("-p", p)],
            *pairing, "--seed", str(seed), "--workers", str(workers), "--keep-other", "1", "--media", "none",
            "--out", str(folder), "-q"]


def one(scenario: str, seed: int, workers: int, folder: Path, examples_pairing: bool = False) -> dict[str, Any]:
    pairing = SCENARIOS[scenario][1] if examples_pairing else DEFAULT_PAIRING
    command = reduce_command(scenario, seed, workers, folder, pairing)
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"{shlex.join(command)} exited {done.returncode}:\n{done.stderr[-2000:]}")
    summary = json.loads((folder / "summary.json").read_text())
    groups = summary["other_failures"]
    return {
        "scenario": scenario, "seed": seed, "pairing": " ".join(pairing[1::2]),
        "wall_seconds": round(time.perf_counter() - started, 1),
        "model_probes": summary["probes"], "simulations": summary["simulations"],
        "minimal_size": summary["minimal_size"], "groups": len(groups),
        "other_probes": sum(group["probes"] for group in groups),
        "stage_only_groups": sum(group["smallest_world"] is None for group in groups),
        "largest": [{"description": group["description"], "probes": group["probes"],
                     "smallest_world": None if group["smallest_world"] is None else group["smallest_world"]["size"],
                     "seen_in": group["seen_in"]} for group in groups],
        "other_1_replay": replay_first(groups, summary["tolerance"]),
        "report_lines": [line for line in done.stdout.splitlines() if line.startswith(("other failure: ", "and "))],
    }


def replay_first(groups: list[dict[str, Any]], tolerance: float) -> str | None:
    """Run the first kept group's replay command: "same" (fails as the group), "other: ..." or "passes"."""
    kept = next((group for group in groups if group["replay"]), None)
    if kept is None:
        return None
    words = shlex.split(kept["replay"])
    done = subprocess.run([*words, "--json", "--no-picture"], capture_output=True, text=True, check=False,
                          cwd=tempfile.gettempdir())
    failure = json.loads(done.stdout)["failure"]
    if failure is None:
        return "passes"
    if "predicate" not in kept["signature"]:
        return f"other: {failure['predicate']}"
    same = same_failure(FailureSignature.from_dict(failure), FailureSignature.from_dict(kept["signature"]), tolerance)
    return "same" if same else f"other: {failure['predicate']}"


def table(rows: list[dict[str, Any]]) -> list[str]:
    lines = [("| scenario | seed | model probes | simulations | other-failure groups (probes) | largest groups: "
              "probes, smallest world | other-1.yaml replays |"),
             "|---|---:|---:|---:|---:|---|---|"]
    for row in rows:
        largest = "; ".join(
            f"{group['description']}: {group['probes']}, "
            + ("stages only" if group["smallest_world"] is None
               else f"{group['smallest_world']} model{'s' if group['smallest_world'] != 1 else ''}")
            for group in row["largest"][:LARGEST])
        more = len(row["largest"]) - LARGEST
        largest += f"; +{more} more" if more > 0 else ""
        lines.append(f"| {row['scenario']} | {row['seed']} | {row['model_probes']} | {row['simulations']} | "
                     f"{row['groups']} ({row['other_probes']}) | {largest or '(none)'} | "
                     f"{row['other_1_replay'] or ''} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="ditch, seed 0")
    parser.add_argument("--out", type=Path, help="every row as JSON, written after each reduction")
    parser.add_argument("--scenarios", nargs="+", choices=list(SCENARIOS), default=list(SCENARIOS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--pairing", choices=["default", "examples"], default="default",
                        help="the plugin's default schema pairing, or the examples' (timeseg on rubble)")
    options = parser.parse_args()
    runs = [("ditch", 0)] if options.quick else list(itertools.product(options.scenarios, options.seeds))
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as scratch:
        for scenario, seed in runs:
            row = one(scenario, seed, options.workers, Path(scratch) / f"{scenario}-{seed}",
                      examples_pairing=options.pairing == "examples")
            rows.append(row)
            print(f"{scenario} seed {seed}: {row['groups']} groups, {row['wall_seconds']} s", file=sys.stderr)
            if options.out is not None:
                options.out.write_text(json.dumps(rows, indent=2) + "\n")
    print("\n".join(table(rows)))
    print("\ngroups (probes): the other-failure groups and the probes in them; largest groups: the "
          f"{LARGEST} largest, as the report describes them")


if __name__ == "__main__":
    main()
