"""Reducing what Hypothesis finds: Hypothesis's shrinking, ddenv's reduction, or both?

    python benchmarks/bench_generated.py [--seeds 0 1 2] [--out results.json]

For each Hypothesis seed it runs the test of examples/test_generated_worlds.py (cluttered worlds drawn by
`pytest_ddenv.strategies.worlds`, the `collided` predicate) under `pytest --ddenv-reduce` twice, in a fresh
pytest process each (media off, models stage only, 2 workers):

- `ddenv`: Hypothesis generates but does not shrink; ddenv reduces the first falsifying world;
- `shrink+ddenv`: Hypothesis shrinks the falsifying world first, then ddenv reduces what it left.

Per row: the test calls Hypothesis made (generation and shrinking: each one a simulation), the failure
Hypothesis reported (predicate, model touched, x), ddenv's simulations, the world sizes (drawn, after
shrinking, minimal), the minimal world's failure rate on fresh runs, and the wall time of the pytest run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path
from typing import Any

TEST = textwrap.dedent(
    """\
    import os
    import pytest
    from hypothesis import HealthCheck, Phase, given, seed, settings

    from pytest_ddenv.strategies import worlds

    PHASES = [Phase.explicit, Phase.generate] + ([Phase.shrink] if os.environ["SHRINK"] == "1" else [])


    @pytest.mark.ddenv(partition="model2model", priority="avg-trajectory")
    @pytest.mark.robot_failure("collided")
    @seed(int(os.environ["SEED"]))
    @settings(max_examples=30, deadline=None, database=None, report_multiple_bugs=False, phases=PHASES,
              suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(world=worlds(count=(6, 16), size=(0.4, 1.0), static=True))
    def test_yard(robot_world, world):
        with open(os.environ["CALLS"], "a") as calls:
            calls.write(f"{len(world)}\\n")
        robot_world.rebound(world).run()
    """
)


def measure(seed: int, shrink: bool, folder: Path) -> dict[str, Any]:
    """One pytest run of the test with this Hypothesis seed, shrinking on or off."""
    run_folder = folder / f"seed{seed}-{'shrink' if shrink else 'plain'}"
    run_folder.mkdir(parents=True)
    (run_folder / "test_yard.py").write_text(TEST)
    calls = run_folder / "calls.txt"
    environment = {**os.environ, "SEED": str(seed), "SHRINK": "1" if shrink else "0", "CALLS": str(calls)}
    begin = time.monotonic()
    subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--ddenv-reduce",
                    "--ddenv-media", "none", "--ddenv-stages", "models", "--ddenv-workers", "2"],
                   cwd=run_folder, env=environment, capture_output=True, text=True, check=False)
    wall = time.monotonic() - begin
    sizes = [int(line) for line in calls.read_text().split()] if calls.exists() else []
    summaries = list(run_folder.glob("ddenv-artifacts/*/summary.json"))
    row: dict[str, Any] = {"seed": seed, "mode": "shrink+ddenv" if shrink else "ddenv", "hypothesis_calls": len(sizes),
                           "wall_seconds": round(wall, 1)}
    if not summaries:
        return {**row, "found": False}
    summary = json.loads(summaries[0].read_text())
    signature = summary["reference_failure"].get("signature") or {}
    fails, runs = summary["failure_rate"]["fails"], summary["failure_rate"]["runs"]
    return {**row, "found": True, "drawn_size": max(sizes) if sizes else None,
            "first_failing_size": next((size for size in sizes[::-1]), None),
            "reduced_from": summary["original_size"], "minimal_size": summary["minimal_size"],
            "failure": f"{signature.get('predicate')} {','.join(signature.get('touched', []))} "
                       f"x={signature.get('pose', [0])[0]:.1f}",
            "ddenv_simulations": summary["simulations"], "minimal_fails": f"{fails}/{runs}"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as temporary:
        for seed in args.seeds:
            for shrink in (False, True):
                rows.append(measure(seed, shrink, Path(temporary)))
                if args.out:
                    args.out.write_text(json.dumps(rows, indent=2) + "\n")
    print("| seed | mode | Hypothesis calls | reported failure | ddenv reduced | ddenv simulations | "
          "minimal fails | total simulations | wall s |")
    print("|---:|---|---:|---|---|---:|---:|---:|---:|")
    for row in rows:
        if not row["found"]:
            print(f"| {row['seed']} | {row['mode']} | {row['hypothesis_calls']} | no failure | | | | | "
                  f"{row['wall_seconds']} |")
            continue
        total = row["hypothesis_calls"] + row["ddenv_simulations"]
        print(f"| {row['seed']} | {row['mode']} | {row['hypothesis_calls']} | {row['failure']} | "
              f"{row['reduced_from']} -> {row['minimal_size']} | {row['ddenv_simulations']} | {row['minimal_fails']} | "
              f"{total} | {row['wall_seconds']} |")


if __name__ == "__main__":
    main()
