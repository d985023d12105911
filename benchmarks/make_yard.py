"""Seeded synthetic yards for the scale benchmark: N static models (boxes, barrels, a 3-wall trap).

    python benchmarks/make_yard.py 1000 [--seed 0] [--out yard_1000.yaml]

The Husky starts at (0, 0) heading +x and drives straight to a goal 7 m ahead. Across its path stands the
trap, a wall pocket: a back wall across the path ("pocket_back", 1.8 m wide, at x = 3.6) and two side walls
along it ("pocket_left", "pocket_right", 1.6 m apart, so the 0.67 m wide robot never touches them). The robot
drives into the pocket, hits the back wall and the `stuck` predicate fires at x = 3.0. Without the back wall
it drives through and reaches the goal; the side walls alone change nothing. So the unique 1-minimal
failing world is {pocket_back}: the culprit count is 1, with two decoys right next to the failure (which
the proximity priorities rank first). Checked on 6 seeds while tuning; tests/test_benchmarks_smoke.py
checks the yard's verdicts.

Other traps were tried and rejected because their verdicts depend on the noise seed: a gap narrower than
the robot between two walls (either wall alone also stops the robot once it overlaps the path by more than
about 5 cm, and below that the verdict flips with the seed), and a funnel of two angled walls (with one
wall the robot slides along it, its odometry drifts, and it gets "stuck" 0.3-2.5 m further on, sometimes
within the 0.5 m failure tolerance of the original).

The other N - 3 models are clutter: static boxes (0.3-1.0 m) and barrels (radius 0.2-0.35 m, 0.9 m tall)
scattered uniformly over a square yard (about 4 m^2 per object, so density does not change with N), never
inside a 5 m wide corridor around the robot's path, so none of them can touch the robot. Positions come from
`random.Random(seed)`, and so does the trap's place in the file order (the order matters to ddmin's even
split): the same N and seed always give the same file.
"""

from __future__ import annotations

import argparse
import math
import random
from pathlib import Path

from pytest_ddenv.oracle import PredicateSpec

START = (0.0, 0.0)
GOAL = (7.0, 0.0)
TRAP = (
    ("pocket_back", (3.6, 0.0, 0.4), (0.2, 1.8, 0.8)),
    ("pocket_left", (2.9, 0.8, 0.4), (1.2, 0.2, 0.8)),
    ("pocket_right", (2.9, -0.8, 0.4), (1.2, 0.2, 0.8)),
)
"""(name, centre, size) of the trap's static walls, m."""
CORRIDOR = 2.5
"""No clutter within this distance of the line from start to goal (extended 3 m at both ends)."""
AREA_PER_OBJECT = 4.0
CULPRITS = ("pocket_back",)
PREDICATES = (PredicateSpec("stuck", {"window": 5.0, "min_progress": 0.2}),)


def yard_yaml(count: int, seed: int = 0) -> str:
    """The world file of a yard of `count` reducible models (3 trap walls + `count - 3` clutter)."""
    if count < len(TRAP):
        raise ValueError(f"a yard has at least the {len(TRAP)} trap walls")
    rng = random.Random(seed)
    half = max(12.0, math.sqrt(count * AREA_PER_OBJECT) / 2)
    cx = (START[0] + GOAL[0]) / 2
    lines = [
        "format: 1",
        f"name: yard_{count}",
        "scenario:",
        f"  start: {{x: {START[0]}, y: {START[1]}, yaw: 0.0}}",
        f"  goal: {{x: {GOAL[0]}, y: {GOAL[1]}}}",
        "  goal_tolerance: 0.5",
        "  timeout: 30.0",
        "models:",
    ]
    trap = [f"  - {{name: {name}, pose: [{x}, {y}, {z}], box: [{sx}, {sy}, {sz}], "
            "color: [0.9, 0.2, 0.1, 1.0], tags: {role: trap}}" for name, (x, y, z), (sx, sy, sz) in TRAP]
    clutter: list[str] = []
    while len(clutter) < count - len(TRAP):
        x = rng.uniform(cx - half, cx + half)
        y = rng.uniform(-half, half)
        if START[0] - 3 <= x <= GOAL[0] + 3 and abs(y) < CORRIDOR:
            continue
        index = len(clutter)
        if rng.random() < 0.5:
            sx, sy, sz = (round(rng.uniform(0.3, 1.0), 2) for _ in range(3))
            yaw = round(rng.uniform(-math.pi, math.pi), 3)
            clutter.append(f"  - {{name: box_{index:04d}, pose: [{x:.2f}, {y:.2f}, {sz / 2:.3f}, 0, 0, {yaw}], "
                           f"box: [{sx}, {sy}, {sz}]}}")
        else:
            radius = round(rng.uniform(0.2, 0.35), 2)
            clutter.append(f"  - {{name: barrel_{index:04d}, pose: [{x:.2f}, {y:.2f}, 0.45], "
                           f"cylinder: {{radius: {radius}, length: 0.9}}, color: [1.0, 0.5, 0.0, 1.0]}}")
    # the trap sits at a seeded random place in the file order (ddmin's even split depends on it)
    at = rng.randint(0, len(clutter))
    lines += clutter[:at] + trap + clutter[at:]
    return "\n".join(lines) + "\n"


def make_yard(count: int, seed: int = 0):  # -> World
    from pytest_ddenv.world import World

    return World.from_yaml(yard_yaml(count, seed), source=f"yard_{count}_seed{seed}.yaml")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("count", type=int, help="number of reducible models (>= 3)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", help="file to write (default: stdout)")
    args = parser.parse_args(argv)
    text = yard_yaml(args.count, args.seed)
    if args.out:
        Path(args.out).write_text(text)
    else:
        print(text, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
