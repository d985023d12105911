"""What the stages after the models (`--stages all`) find and cost on the paper scenarios.

    python benchmarks/bench_stages.py --quick            # ditch, seed 0 (about 0.5 min)
    python benchmarks/bench_stages.py [--seeds 0 1 2]    # 3 scenarios x 3 seeds (about 6 min on 2 cores)

For each paper scenario (the predicates of examples/test_paper_scenarios.py; the default schema pairing,
model2model + avg-trajectory-proximal, or with `--pairing examples` the examples' own: timeseg on rubble)
and seed, it runs `ddenv reduce WORLD ... --seed S --stages all --workers 2` as a user would (a fresh process, the
default budget), reads `summary.json`, and then runs the model-level `minimal.yaml` and the stages'
`simplified.yaml` on the same 10 fresh noise seeds (attempts 1_000_000 .., used by no reduction), counting
the runs that fail the same way as the reduction's reference failure (`classify_result`, tolerance 0.5 m).

Per row: the model-level probes (decided candidates) and simulations; per stage the decisions, the
simulations and what it found; the stages' total decisions against twice the model-level probes; the
minimal and the simplified world's fails on the fresh seeds. `--out` writes every row as JSON.
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
sys.path.insert(0, str(ROOT))

from pytest_ddenv.oracle import FailureSignature, PredicateSpec
from pytest_ddenv.scenario.probe import FailureReference, classify_result
from pytest_ddenv.reduce import Outcome
from pytest_ddenv.driver.scenario_job import ScenarioJob
from pytest_ddenv.world import World

STUCK = "stuck:window=5,min_progress=0.2"
SCENARIOS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # predicates, schema pairing: as examples/test_paper_scenarios.py
    "ditch": ((STUCK,), ("--partition", "model2model", "--priority", "avg-trajectory")),
    "rubble": (("high_centered", STUCK), ("--partition", "timeseg", "--priority", "avg-trajectory")),
    "friction": ((STUCK,), ("--partition", "model2model", "--priority", "avg-trajectory")),
}
FRESH_RUNS = 10
FRESH_FIRST_ATTEMPT = 1_000_000


def predicate_specs(texts: tuple[str, ...]) -> tuple[PredicateSpec, ...]:
    specs = []
    for text in texts:
        name, _, params = text.partition(":")
        values = {key: float(value) for key, value in (item.split("=") for item in params.split(",") if item)}
        specs.append(PredicateSpec(name, values))
    return tuple(specs)


def fresh_fails(world: World, predicates: tuple[PredicateSpec, ...], seed: int, reference: FailureReference) -> int:
    handle = ScenarioJob(predicates, seed=seed).handler()
    return sum(classify_result(handle(world, attempt).error, reference, 0.5) is Outcome.FAIL
               for attempt in range(FRESH_FIRST_ATTEMPT, FRESH_FIRST_ATTEMPT + FRESH_RUNS))


def reference_of(summary: dict[str, Any]) -> FailureReference:
    data = summary["reference_failure"]
    signature = data.get("signature")
    return FailureReference(data["exception_type"], data["location"],
                            None if signature is None else FailureSignature.from_dict(signature))


DEFAULT_PAIRING = ("--partition", "model2model", "--priority", "avg-trajectory-proximal")


def one(scenario: str, seed: int, workers: int, folder: Path, examples_pairing: bool = False) -> dict[str, Any]:
    predicates, pairing = SCENARIOS[scenario]
    pairing = pairing if examples_pairing else DEFAULT_PAIRING
    command = ["ddenv", "reduce", str(ROOT / "worlds" / f"{scenario}.yaml"), *[a for p in predicates for a in ("-p", p)],
               *pairing, "--seed", str(seed), "--stages", "all", "--workers", str(workers), "--out", str(folder), "-q"]
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} exited {done.returncode}:\n{done.stderr[-2000:]}")
    summary = json.loads((folder / "summary.json").read_text())
    staged = summary["stages"]
    specs = predicate_specs(predicates)
    reference = reference_of(summary)
    minimal = World.load(folder / "minimal.yaml")
    simplified_path = folder / "simplified.yaml"
    simplified = World.load(simplified_path) if simplified_path.exists() else minimal
    stages = {result["stage"]: result for result in staged["results"]}
    return {
        "scenario": scenario, "seed": seed, "pairing": " ".join(pairing[1::2]), "wall_seconds": round(wall, 1),
        "model_probes": summary["probes"], "model_simulations": summary["simulations"] - staged["simulations"],
        "minimal_size": summary["minimal_size"],
        "stage_probes": staged["probes"], "stage_simulations": staged["simulations"], "budget": staged["budget"],
        "stages": {name: {"probes": result["probes"], "simulations": result["simulations"],
                          "findings": result["findings"], "incomplete": result["incomplete"],
                          "reverted": bool(result.get("reverted"))} for name, result in stages.items()},
        "minimal_fresh_fails": fresh_fails(minimal, specs, seed, reference),
        "simplified_fresh_fails": fresh_fails(simplified, specs, seed, reference) if simplified is not minimal else None,
        "fresh_runs": FRESH_RUNS, "changed": staged["changed"],
        "passing_found": bool(stages.get("passing", {}).get("found")),
    }


def short(result: dict[str, Any]) -> str:
    """One stage's finding in a few words for the table."""
    if result.get("reverted"):
        return "reverted (rate)"
    findings = [f for f in result["findings"] if "(the failure holds)" not in f]
    held = sum("(the failure holds)" in f for f in result["findings"])
    text = f"{held} held; " if held else ""
    return (text + (findings[0] if findings else "")).replace("|", "/")[:70]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--quick", action="store_true", help="ditch, seed 0")
    parser.add_argument("--pairing", choices=["default", "examples"], default="default",
                        help="the plugin's default schema pairing, or the examples' (timeseg on rubble)")
    parser.add_argument("--out", type=Path)
    arguments = parser.parse_args()
    if arguments.quick:
        arguments.scenarios, arguments.seeds = ["ditch"], [0]
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for scenario in arguments.scenarios:
            for seed in arguments.seeds:
                rows.append(one(scenario, seed, arguments.workers, Path(scratch) / f"{scenario}-{seed}",
                                examples_pairing=arguments.pairing == "examples"))
                if arguments.out:
                    arguments.out.write_text(json.dumps(rows, indent=2) + "\n")
    print("| scenario | seed | model probes / sims | stage probes / sims (budget) | <= 2x | shapes | attributes | time "
          "| passing | minimal fresh fails | simplified fresh fails | wall s |")
    print("|---|---:|---:|---:|:-:|---|---|---|:-:|---:|---:|---:|")
    for row in rows:
        stages = row["stages"]
        cells = [short(stages[name]) if name in stages else "" for name in ("shapes", "attributes", "time")]
        simplified = "unchanged" if row["simplified_fresh_fails"] is None else f"{row['simplified_fresh_fails']}/{row['fresh_runs']}"
        print(f"| {row['scenario']} | {row['seed']} | {row['model_probes']} / {row['model_simulations']} | "
              f"{row['stage_probes']} / {row['stage_simulations']} ({row['budget']}) | "
              f"{'yes' if row['stage_simulations'] <= 2 * row['model_simulations'] else 'NO'} | "
              + " | ".join(cells)
              + f" | {'yes' if row['passing_found'] else 'no'} | {row['minimal_fresh_fails']}/{row['fresh_runs']} | "
              f"{simplified} | {row['wall_seconds']} |")
    print("\n<= 2x: the stages' simulations are at most twice the model-level reduction's")


if __name__ == "__main__":
    main()
