"""Tabletop reductions: our engine against picire on the three shipped arm scenarios, each with and without
20 distractors far from the arm.

    python benchmarks/bench_tabletop.py [--seeds 0] [--workers 1] [--worlds tall_box tight_grasp carry]
                                        [--out results.json]

For each scenario of examples/test_tabletop.py (its world and predicate), each noise seed and each variant
(the shipped world, and the same world with `with_distractors`: 20 small objects on the floor 1.5-2.5 m
behind the arm's base), both tools reduce the same failure with the same probe and the same deflake rule
(benchmarks/common.py): our engine (model2model partition, avg-trajectory-proximal priority, deflake
`auto`, calibrated on the original world) and picire's default DD under the rule our engine calibrated, its
calibration runs counted. Per row: the minimal world, the simulations started, the minimal world's failure
rate on 10 fresh noise seeds, the wall time (pools warm before the clock starts), and for the distractor
variant the extra simulations against the plain world, in per cent.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from common import ROOT, Row, calibrated_rule, ddenv_reduce, make_problem, picire_reduce, pool_of

from pytest_ddenv.oracle import PredicateSpec
from pytest_ddenv.world import Model, Pose, Shape, World

WORLDS = ROOT / "worlds"
TABLETOP: dict[str, tuple[Path, tuple[PredicateSpec, ...], tuple[str, ...]]] = {
    # name: (world, the predicates of examples/test_tabletop.py, the cause known by construction)
    "tall_box": (WORLDS / "tabletop_tall_box.yaml", (PredicateSpec("arm_collision", {}),), ("cereal_box",)),
    "tight_grasp": (WORLDS / "tabletop_tight_grasp.yaml", (PredicateSpec("grasp_failed", {}),), ("juice_box",)),
    "carry": (WORLDS / "tabletop_carry.yaml", (PredicateSpec("object_dropped", {}),), ("divider",)),
}
DISTRACTORS = 20
PARTITION, PRIORITY = "model2model", "avg-trajectory-proximal"


def with_distractors(world: World, count: int = DISTRACTORS) -> World:
    """`world` with `count` small dynamic objects (boxes, cylinders and spheres, 6-10 cm) on the floor in a
    grid 1.5-2.5 m behind the arm's base (x < 0, the arm faces +x): out of its reach, never touched."""
    assert world.scenario is not None
    base = world.scenario.start
    columns = 5
    models = []
    for index in range(count):
        row, column = divmod(index, columns)
        x = base.x - 1.5 - 0.25 * row
        y = base.y + 0.3 * (column - (columns - 1) / 2)
        size = 0.06 + 0.01 * (index % 5)
        kind = ("box", "cylinder", "sphere")[index % 3]
        shape = (Shape("box", size=(size, size, size)) if kind == "box"
                 else Shape("cylinder", radius=size / 2, length=size) if kind == "cylinder"
                 else Shape("sphere", radius=size / 2))
        models.append(Model(f"distractor_{index:02d}", (shape,), Pose(x, y, size / 2), mass=0.1, static=False,
                            color=(0.5, 0.5, 0.8, 1.0)))
    return dataclasses.replace(world, name=f"{world.name}+{count}", models=(*world.models, *models))


def measure(name: str, seeds: list[int], workers: int) -> list[Row]:
    """Both tools on scenario `name`, plain and with distractors, each noise seed."""
    path, predicates, _ = TABLETOP[name]
    plain = World.load(path)
    rows: list[Row] = []
    with pool_of(workers) as pools:
        for seed in seeds:
            for label, world in ((name, plain), (f"{name}+{DISTRACTORS}", with_distractors(plain))):
                problem = make_problem(world, predicates, seed, pools)
                ours = ddenv_reduce(problem, partition=PARTITION, priority=PRIORITY, deflake="auto",
                                    world_label=label)
                rule = calibrated_rule(ours)
                calibration = ours.extra["calibration"]
                theirs = picire_reduce(problem, config_name="default", deflake=rule if rule is not None else 1,
                                       world_label=label, calibration_runs=calibration[1] if calibration else 0)
                rows += [ours, theirs]
    return rows


def kept(row: Row, world: World) -> str:
    """The minimal world's models other than the scenario's table and target."""
    assert world.scenario is not None
    fixed = {world.scenario.table, world.scenario.target}
    return ", ".join(n for n in row.minimal if n not in fixed) or "(none)"


def table(rows: list[Row]) -> str:
    """The Markdown table of docs/benchmarks.md ("Tabletop")."""
    lines = [("| world | tool | models | minimal (besides table, target) | simulations | vs plain | "
              "minimal fails | wall s |"), "|---|---|---:|---|---:|---:|---:|---:|"]
    plain: dict[tuple[str, str, int], int] = {}
    for row in rows:
        base = row.world.split("+")[0]
        world = World.load(TABLETOP[base][0])
        tool = "ddenv" if row.tool == "ddenv" else "picire"
        key = (base, tool, row.seed)
        extra = ""
        if "+" in row.world:
            extra = f"{100.0 * (row.simulations - plain[key]) / max(1, plain[key]):+.0f} %" if key in plain else ""
        else:
            plain[key] = row.simulations
        rate = f"{row.failure_rate[0]}/{row.failure_rate[1]}"
        lines.append(f"| {row.world} | {tool} | {row.original_size} -> {row.final_size} | {kept(row, world)} | "
                     f"{row.simulations} | {extra} | {rate} | {row.wall_time:.1f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--worlds", nargs="+", choices=sorted(TABLETOP), default=list(TABLETOP))
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    rows: list[Row] = []
    for name in args.worlds:
        rows += measure(name, args.seeds, args.workers)
        if args.out:
            args.out.write_text(json.dumps([row.to_dict() for row in rows], indent=2) + "\n")
    print(table(rows))


if __name__ == "__main__":
    main()
