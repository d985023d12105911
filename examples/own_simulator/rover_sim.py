"""A tiny 2D rover simulator of "your own", standing in for Gazebo or a company simulator.

It knows nothing of pytest-ddenv or PyBullet: it reads an SDF world (the models' poses and their box,
cylinder and sphere collisions, seen from above), drives a disc-shaped rover from the start to the goal,
and prints what happened as JSON on stdout. When something blocks its way it sidesteps to the left, up
to 1.5 m, then heads for the goal again; if it cannot, it stops there, blocked.

    python rover_sim.py WORLD.sdf --start X Y --goal X Y
"""

from __future__ import annotations

import argparse
import json
import math
import xml.etree.ElementTree as ET

RADIUS = 0.3  # m, the rover's footprint
SPEED = 0.5  # m/s
STEP = 0.1  # s
SIDESTEP = 1.5  # m at most per obstacle
TIME_LIMIT = 60.0  # s


def numbers(text: str | None, count: int) -> list[float]:
    values = [float(v) for v in (text or "").split()]
    return (values + [0.0] * count)[:count]


def obstacles(path: str) -> list[dict]:
    """Each model's collision shapes as 2D footprints: boxes (centre, half sizes, yaw) and discs."""
    found = []
    for model in ET.parse(path).getroot().iter("model"):
        name = model.get("name", "")
        if name == "ground_plane":
            continue
        x, y, _, _, _, yaw = numbers(model.findtext("pose"), 6)
        for collision in model.iter("collision"):
            dx, dy, _, _, _, dyaw = numbers(collision.findtext("pose"), 6)
            cx = x + dx * math.cos(yaw) - dy * math.sin(yaw)
            cy = y + dx * math.sin(yaw) + dy * math.cos(yaw)
            geometry = collision.find("geometry")
            if geometry is None:
                continue
            if geometry.find("box") is not None:
                sx, sy, _ = numbers(geometry.findtext("box/size"), 3)
                found.append({"name": name, "kind": "box", "x": cx, "y": cy, "hx": sx / 2, "hy": sy / 2,
                              "yaw": yaw + dyaw})
            for kind in ("cylinder", "sphere"):
                if geometry.find(kind) is not None:
                    found.append({"name": name, "kind": "disc", "x": cx, "y": cy,
                                  "r": float(geometry.findtext(f"{kind}/radius") or 0.0)})
    return found


def hits(x: float, y: float, shape: dict) -> bool:
    """Does the rover at (x, y) overlap `shape`?"""
    if shape["kind"] == "disc":
        return math.hypot(x - shape["x"], y - shape["y"]) < RADIUS + shape["r"] - 1e-6
    c, s = math.cos(-shape["yaw"]), math.sin(-shape["yaw"])
    lx = (x - shape["x"]) * c - (y - shape["y"]) * s
    ly = (x - shape["x"]) * s + (y - shape["y"]) * c
    nx = max(-shape["hx"], min(shape["hx"], lx))
    ny = max(-shape["hy"], min(shape["hy"], ly))
    return math.hypot(lx - nx, ly - ny) < RADIUS - 1e-6


def simulate(shapes: list[dict], start: tuple[float, float], goal: tuple[float, float]) -> dict:
    x, y = start
    t, sidestepped = 0.0, 0.0
    times, poses, touched = [0.0], [[x, y, 0.0]], []
    blocked_at = None
    while t < TIME_LIMIT and math.hypot(goal[0] - x, goal[1] - y) > 0.2:
        heading = math.atan2(goal[1] - y, goal[0] - x)
        nx, ny = x + SPEED * STEP * math.cos(heading), y + SPEED * STEP * math.sin(heading)
        in_the_way = [shape["name"] for shape in shapes if hits(nx, ny, shape)]
        if in_the_way:
            touched += [name for name in in_the_way if name not in touched]
            heading += math.radians(100)  # sidestep to the left, backing off a little
            nx, ny = x + SPEED * STEP * math.cos(heading), y + SPEED * STEP * math.sin(heading)
            sidestepped += SPEED * STEP
            blocked_by = [shape["name"] for shape in shapes if hits(nx, ny, shape)]
            if blocked_by or sidestepped > SIDESTEP:
                touched += [name for name in blocked_by if name not in touched]
                blocked_at = [x, y]
                break
        else:
            sidestepped = 0.0
        x, y, t = nx, ny, t + STEP
        times.append(round(t, 6))
        poses.append([x, y, heading])
    reached = math.hypot(goal[0] - x, goal[1] - y) <= 0.2
    return {"times": times, "poses": poses, "reached": reached, "blocked_at": blocked_at, "touched": touched}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("world")
    parser.add_argument("--start", type=float, nargs=2, required=True)
    parser.add_argument("--goal", type=float, nargs=2, required=True)
    arguments = parser.parse_args()
    print(json.dumps(simulate(obstacles(arguments.world), tuple(arguments.start), tuple(arguments.goal))))


if __name__ == "__main__":
    main()
