#!/usr/bin/env python3
"""Generate the paper's three scenario worlds (and their culprit-free variants) as YAML.

The numbers are transcribed from ``shared/reference/paper-artifact.md`` (sections 1a-1c and Appendices A-C),
which in turn reads the DDEnv artifact's Gazebo worlds ``rough_terrain_gap.world`` (ditch),
``rubble_loose11.world`` (rubble) and ``frictionpatch6.world`` (friction). Every pose is the **effective**
``<state>`` link pose that Gazebo simulates, never the stale model-level body pose.

Usage::

    python tools/make_scenario_worlds.py            # (re)write worlds/*.yaml
    python tools/make_scenario_worlds.py --check    # exit 1 if a committed file differs

The simulation engineer tunes the ``scenario:``/``physics:``/``ground:`` blocks of the three main files by
hand; this script keeps whatever those blocks say in the committed files (``--reset-settings`` restores the
defaults below) and regenerates only the models.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

from pytest_ddenv.world import Ground, Model, Physics, Pose, Scenario, Shape, World

ROOT = Path(__file__).resolve().parent.parent
WORLDS = ROOT / "worlds"

# -- materials ------------------------------------------------------------------------------------------
ASPHALT = (0.25, 0.25, 0.27, 1.0)
PAD_WOOD = (0.80, 0.70, 0.50, 1.0)
CINDER = (0.55, 0.55, 0.55, 1.0)
LUMBER = (0.76, 0.60, 0.42, 1.0)
RED = (1.0, 0.1, 0.1, 1.0)  # the tiles' Gazebo ambient colour
GREEN = (0.1, 1.0, 0.1, 1.0)
BARREL = (1.0, 0.45, 0.0, 1.0)

GAZEBO_GROUND = Ground(z=0.0, mu=100.0, mu2=50.0)  # ground_plane: plane 100x100, mu 100 / mu2 50
PAPER_PHYSICS = Physics(gravity=(0.0, 0.0, -9.8))  # the worlds use gravity -9.8 (ODE, 1 ms steps)
TIMEOUT = 60.0


def _r(value: float, digits: int = 6) -> float:
    """Round away binary noise from computed offsets so the YAML stays readable."""
    return float(round(value, digits)) + 0.0


# -- cinder block (inline model in the ditch and rubble worlds) -----------------------------------------
def cinder_block_shapes() -> tuple[Shape, ...]:
    """2 walls 0.43495 x 0.0339 x 0.2032 at y = +-0.08465, 3 webs 0.0339 x 0.1354 x 0.203 at x = 0, +-0.18625."""
    walls = tuple(Shape("box", size=(0.43495, 0.0339, 0.2032), pose=Pose(0.0, y, 0.1016)) for y in (0.08465, -0.08465))
    webs = tuple(Shape("box", size=(0.0339, 0.1354, 0.203), pose=Pose(x, 0.0, 0.1016)) for x in (-0.18625, 0.0, 0.18625))
    return walls + webs


def cinder_block(name: str, pose: Pose) -> Model:
    return Model(name, cinder_block_shapes(), pose=pose, mass=5.0, static=False, mu=1.0, mu2=1.0, color=CINDER)


# -- ditch: rough_terrain_gap.world -------------------------------------------------------------------------
# The FRC 2016 "rough terrain" defense: a 1.27 x 0.5969 x 0.003175 platform at z +0.08269 and 31 blocks of
# 0.0762 x 0.0762 in three rows (y = +0.1143, 0, -0.1143; 10 / 11 / 10 blocks, 0.1143 m apart). The
# reference gives the counts and sizes; the order of heights along each row is the one of
# osrf/gazebo_models frc2016_roughterrain/model.sdf, which the DDEnv world inlines (s = 0.0254 m high,
# m = 0.0508, l = 0.0762; blocks stand on the platform top at z +0.084278).
PAD_PLATFORM = (1.27, 0.5969, 0.003175)
PAD_PLATFORM_Z = 0.08269
PAD_BLOCK = 0.0762
PAD_ROWS: tuple[tuple[float, float, str], ...] = (
    (0.1143, 0.51435, "slmsmlssml"),  # row 1: first x, then -0.1143 per block
    (0.0, 0.5715, "mslmlsmlslm"),  # row 2
    (-0.1143, 0.51435, "lmlsmmlsms"),  # row 3
)
PAD_HEIGHTS = {"s": 0.0254, "m": 0.0508, "l": 0.0762}


def pad_shapes() -> tuple[Shape, ...]:
    top = PAD_PLATFORM_Z + PAD_PLATFORM[2] / 2.0
    shapes = [Shape("box", size=PAD_PLATFORM, pose=Pose(0.0, 0.0, PAD_PLATFORM_Z))]
    for y, first_x, heights in PAD_ROWS:
        for index, code in enumerate(heights):
            height = PAD_HEIGHTS[code]
            x = _r(first_x - 0.1143 * index, 5)
            shapes.append(Shape("box", size=(PAD_BLOCK, PAD_BLOCK, height), pose=Pose(x, y, _r(top + height / 2.0, 5))))
    return tuple(shapes)


# Appendix A, in file order: (name suffix after "frc2016_roughterrain", effective x, y, z); yaw 0.
DITCH_PADS_BEFORE = (
    ("", -0.461, -0.078, 0.769),
    ("_0", -0.343, -0.453, 0.769),
    ("_1", -0.346, 0.243, 0.777),
)
DITCH_PADS_AFTER_PLANES = (
    ("_2", 2.913, 0.026, 0.776),
    ("_1_clone", 0.746, 0.624, 0.776),
    ("_0_clone", 0.856, -0.735, 0.769),
    ("_0_clone_0", 0.865, -0.366, 0.769),
    ("_0_clone_1", 0.851, -0.040, 0.769),
    ("_0_clone_2", 0.857, 0.199, 0.769),
    ("_1_clone_0", -0.588, 0.591, 0.777),
    ("_1_clone_1", 0.012, 1.013, 0.777),
    ("_1_clone_2", 0.841, 0.951, 0.777),
    ("_1_clone_3", 0.854, 1.327, 0.777),
    ("_1_clone_4", 2.646, 0.752, 0.777),
    ("_1_clone_5", 2.636, 0.377, 0.777),
    ("_1_clone_6", 2.638, -0.072, 0.777),
    ("_1_clone_7", 3.578, 0.166, 0.777),
    ("_1_clone_8", 2.641, -0.424, 0.777),
    ("_1_clone_9", 2.643, -0.803, 0.777),
    ("_1_clone_10", 3.632, -0.301, 0.777),
    ("_1_clone_11", 3.606, -0.647, 0.777),
    ("_1_clone_12", 3.585, -1.054, 0.777),
    ("_1_clone_13", 3.594, 0.526, 0.777),
    ("_1_clone_14", 4.771, 0.363, 0.777),
    ("_1_clone_15", 4.866, 0.140, 0.777),
    ("_1_clone_16", 4.727, -0.053, 0.777),
)
DITCH_PADS_AFTER_BLOCK = (
    ("_1_clone_11_clone", -0.327, 1.360, 0.777),
    ("_1_clone_11_clone_0", -1.140, 0.946, 0.777),
    ("_1_clone_11_clone_1", 0.846, 1.666, 0.777),
    ("_1_clone_11_clone_2", 0.708, -1.091, 0.777),
    ("_1_clone_11_clone_3", 2.640, -1.167, 0.777),
    ("_1_clone_11_clone_4", 2.634, 1.713, 0.777),
    ("_1_clone_11_clone_5", 3.639, 1.646, 0.777),
    ("_1_clone_11_clone_6", 4.724, 0.707, 0.777),
    ("_1_clone_11_clone_7", 4.409, 1.298, 0.777),
    ("_1_clone_11_clone_8", 5.030, 1.029, 0.777),
    ("_1_clone_11_clone_9", 3.563, 0.843, 0.777),
    ("_1_clone_11_clone_10", 4.372, 0.766, 0.777),
    ("_1_clone_11_clone_11", 4.000, 1.000, 0.777),
    ("_1_clone_11_clone_12", 4.550, 1.596, 0.777),
)


def pads(rows: Iterable[tuple[str, float, float, float]]) -> list[Model]:
    shapes = pad_shapes()
    return [Model(f"frc2016_roughterrain{suffix}", shapes, pose=Pose(x, y, z), color=PAD_WOOD) for suffix, x, y, z in rows]


def plateau(name: str, pose: Pose, size: tuple[float, float, float]) -> Model:
    return Model(name, (Shape("box", size=size),), pose=pose, mu=100.0, mu2=50.0, color=ASPHALT)


# asphalt_plane: box 20 x 20 x 0.1 scaled (1, 1, 14.296) by <state>; asphalt_plane_clone: scaled 10.6472.
NEAR_PLATEAU_POSE = Pose(-8.53833, 2.29833, 0.165376)
NEAR_PLATEAU_SIZE = (20.0, 20.0, _r(0.1 * 14.296))
FAR_PLATEAU_POSE = Pose(11.9689, 2.28539, 0.340279)
FAR_PLATEAU_SIZE = (20.0, 20.0, _r(0.1 * 10.6472))


def ditch_models(*, bridged: bool = False) -> list[Model]:
    near_pose, near_size = NEAR_PLATEAU_POSE, NEAR_PLATEAU_SIZE
    if bridged:  # lengthen the near plateau in +x until it meets the far one: no gap
        far_edge = FAR_PLATEAU_POSE.x - FAR_PLATEAU_SIZE[0] / 2.0
        near_low = near_pose.x - near_size[0] / 2.0
        near_size = (_r(far_edge - near_low), near_size[1], near_size[2])
        near_pose = dataclasses.replace(near_pose, x=_r((near_low + far_edge) / 2.0))
    return [
        *pads(DITCH_PADS_BEFORE),
        plateau("asphalt_plane", near_pose, near_size),
        plateau("asphalt_plane_clone", FAR_PLATEAU_POSE, FAR_PLATEAU_SIZE),
        *pads(DITCH_PADS_AFTER_PLANES),
        cinder_block("cinder_block", Pose(4.448, -1.102, 0.872, 0.0, 0.0, -0.032)),
        *pads(DITCH_PADS_AFTER_BLOCK),
    ]


DITCH_SCENARIO = Scenario(start=Pose(-3.0, -0.5), goal=(3.75, -1.08, None), timeout=TIMEOUT)


# -- rubble: rubble_loose11.world ------------------------------------------------------------------------
LUMBER_SIZE = (1.2192, 0.038, 0.0888)  # a 48" 2x4
LUMBER_MASS = 1.4111
# Appendix B, in file order: (name suffix after "lumber_2x4x48", effective x y z roll pitch yaw).
RUBBLE_BOARDS: tuple[tuple[str, tuple[float, float, float, float, float, float]], ...] = (
    ("", (0.298, 0.248, 0.093, 0.000, 0.000, -0.026)),
    ("_clone", (-0.564, 0.385, 0.093, -0.004, 0.000, -0.014)),
    ("_clone_1", (0.260, 0.583, 0.091, -0.100, 0.001, -0.023)),
    ("_clone_3_clone", (-0.674, 0.753, 0.141, 1.593, -0.119, -0.740)),
    ("_clone_3_clone_0", (0.053, 0.777, 0.178, 1.481, -0.036, 0.721)),
    ("_clone_1_clone", (-0.550, -1.984, 0.099, -1.587, 0.050, -0.058)),
    ("_clone_3_clone_0_clone_0_clone", (-0.493, -1.881, 0.127, 1.587, 0.099, 0.593)),
    ("_clone_3_clone_0_clone_0_clone_0", (0.024, -1.834, 0.108, 1.577, -0.066, 2.414)),
    ("_clone_3_clone_0_clone_0_clone_0_clone", (-0.921, -2.084, 0.138, 1.491, -0.112, 2.814)),
    ("_clone_0_clone", (-0.711, -1.361, 0.130, -0.033, -0.060, 0.087)),
    ("_clone_0_clone_0", (0.225, -1.402, 0.093, -0.008, 0.000, -0.022)),
    ("_clone_3_clone_0_clone_1_clone", (-0.878, -1.945, 0.081, 1.603, 0.026, 1.313)),
    ("_clone_3_clone_0_clone_1_clone_clone", (0.013, -2.348, 0.134, 0.031, -0.066, 1.522)),
    ("_clone_3_clone_0_clone_1_clone_clone_2", (-1.687, -2.073, 0.113, -0.008, -0.033, 0.472)),
    ("_clone_3_clone_0_clone_clone", (-2.180, -1.452, 0.067, 1.579, 0.000, 0.618)),
    ("_clone_3_clone_0_clone_1_clone_clone_4", (-0.996, -0.582, 0.129, 1.582, -0.059, 0.668)),
    ("_clone_3_clone_0_clone_1_clone_0", (0.256, 0.753, 0.154, 1.336, 0.061, 1.785)),
    ("_clone_3_clone_0_clone_clone_0_clone_0", (-0.960, -1.754, 0.188, -1.526, -0.056, -1.148)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_2", (-1.163, -2.103, 0.067, -1.584, 0.001, -1.359)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_5", (2.072, -0.975, 0.068, -1.571, 0.000, -1.123)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_8", (0.824, -2.076, 0.068, 1.571, 0.000, -1.081)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_9", (-1.357, -0.559, 0.067, -1.573, 0.000, -1.286)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_10", (0.313, 0.823, 0.124, -1.576, -0.093, -1.223)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_11_clone", (-0.067, -1.927, 0.203, 1.748, 0.183, -2.153)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_11_clone_4", (-0.476, -2.088, 0.138, -1.695, 0.062, -2.068)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_11_clone_11", (0.871, 0.915, 0.117, 1.605, -0.080, -2.095)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_11_clone_13", (0.717, -0.749, 0.068, 1.574, 0.000, -2.567)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_11_clone_14_clone_clone_1", (0.949, 0.759, 0.151, 1.571, -0.136, -3.051)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_11_clone_14_clone_clone_5", (-1.143, -1.430, 0.202, 1.610, 0.071, -2.993)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_11_clone_clone_0", (-2.293, -1.597, 0.102, 1.487, 0.050, -1.989)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_0_clone_2", (0.713, -1.112, 0.134, -1.576, -0.071, -1.522)),
    ("_clone_3_clone_0_clone_clone_0_clone", (-1.258, -0.434, 0.098, 1.589, 0.049, 0.640)),
    ("_clone_3_clone_0_clone_clone_0_clone_0_clone_11_clone_13_clone", (-0.307, -0.588, 0.093, -0.004, 0.000, 2.453)),
)
RUBBLE_BLOCKS = (
    ("cinder_block", Pose(1.194, -0.908, 0.049, -0.001, 0.001, 0.001)),
    ("cinder_block_0", Pose(-0.563, -0.652, 0.050, 0.000, 0.000, -0.211)),
)


def lumber(suffix: str, pose: tuple[float, float, float, float, float, float]) -> Model:
    return Model(
        f"lumber_2x4x48{suffix}", (Shape("box", size=LUMBER_SIZE),), pose=Pose(*pose),
        mass=LUMBER_MASS, static=False, mu=5.0, mu2=5.0, color=LUMBER,
    )


def rubble_models(*, blocks: bool = True) -> list[Model]:
    asphalt = Model("asphalt_plane", (Shape("box", size=(20.0, 20.0, 0.1)),), pose=Pose(-0.112, 0.027, 0.0), color=ASPHALT)
    boards = [lumber(suffix, pose) for suffix, pose in RUBBLE_BOARDS]
    cinder = [cinder_block(name, pose) for name, pose in RUBBLE_BLOCKS] if blocks else []
    return [asphalt, *boards, *cinder]


# -- friction: frictionpatch6.world ----------------------------------------------------------------------
TILE_SIZE = (2.0, 0.2, 2.0)  # rolled by ~pi/2 about x: a flat 2 x 2 m slab, 0.2 m thick
# Appendix C, in file order: (name, effective x y z roll, high friction?) or a barrel / the slab.
FRICTION_ORDER: tuple[tuple[str, str, tuple[float, ...]], ...] = (
    ("tile_red", "grey_wall", (-1.014, 0.600, 0.141, 1.576)),
    ("tile_green", "grey_wall_0", (-1.015, -1.422, 0.150, 1.567)),
    ("slab", "asphalt_plane_0", (0.190, -0.007, 0.0)),
    ("tile_red", "grey_wall_clone", (-1.012, 4.671, 0.145, 1.576)),
    ("tile_green", "grey_wall_0_clone_clone", (1.037, 0.641, 0.150, 1.567)),
    ("tile_green", "grey_wall_0_clone_clone_0", (3.063, 2.689, 0.150, 1.567)),
    ("tile_red", "grey_wall_clone_clone_1", (3.082, 0.643, 0.145, 1.576)),
    ("tile_red", "grey_wall_clone_clone_2", (3.068, 4.721, 0.145, 1.576)),
    ("tile_red", "grey_wall_clone_clone_3", (5.084, 6.779, 0.145, 1.576)),
    ("tile_red", "grey_wall_clone_clone_4", (1.018, 2.676, 0.145, 1.576)),
    ("tile_red", "grey_wall_clone_clone_5", (1.033, -1.404, 0.145, 1.576)),
    ("tile_red", "grey_wall_clone_clone_6", (5.091, 2.697, 0.145, 1.576)),
    ("tile_green", "grey_wall_0_clone_clone_1", (1.033, 4.697, 0.150, 1.567)),
    ("tile_green", "grey_wall_0_clone_clone_2", (3.090, -1.425, 0.150, 1.567)),
    ("tile_green", "grey_wall_0_clone_clone_3", (5.108, 4.735, 0.150, 1.567)),
    ("tile_green", "grey_wall_0_clone_clone_4", (3.055, 6.764, 0.150, 1.567)),
    ("tile_green", "grey_wall_0_clone_clone_5", (-1.028, 2.641, 0.150, 1.567)),
    ("barrel", "Construction Barrel", (-1.572, 0.733, 0.0)),
    ("barrel", "Construction Barrel_0", (0.198, 4.485, 0.0)),
    ("barrel", "Construction Barrel_1", (1.255, 0.731, 0.0)),
    ("barrel", "Construction Barrel_2", (0.768, 2.093, 0.045)),
    ("barrel", "Construction Barrel_3", (1.224, -0.231, 0.0)),
    ("barrel", "Construction Barrel_4", (0.846, 3.299, 0.0)),
    ("barrel", "Construction Barrel_5", (-0.385, 4.788, 0.0)),
    ("barrel", "Construction Barrel_6", (1.331, 1.453, 0.0)),
)
SLAB_SIZE = (20.0, 20.0, 0.468848)
# construction_barrel.dae (osrf/gazebo_models, unit inch, origin at the bottom): base ring radius 20.1 in,
# body radius 11.7 in, top 47.4 in. The ring's height (3.875 in, where its taper meets the body) is read
# from the mesh's vertices; the handle (up to 51.8 in) is left out.
INCH = 0.0254
BARREL_RING_RADIUS = _r(20.1 * INCH)
BARREL_RING_HEIGHT = _r(3.875 * INCH)
BARREL_BODY_RADIUS = _r(11.7 * INCH)
BARREL_HEIGHT = _r(47.4 * INCH)
BARREL_MASS = 500.0


def barrel_shapes() -> tuple[Shape, ...]:
    return (
        Shape("cylinder", radius=BARREL_RING_RADIUS, length=BARREL_RING_HEIGHT, pose=Pose(z=_r(BARREL_RING_HEIGHT / 2))),
        Shape("cylinder", radius=BARREL_BODY_RADIUS, length=BARREL_HEIGHT, pose=Pose(z=_r(BARREL_HEIGHT / 2))),
    )


def friction_model(kind: str, name: str, values: tuple[float, ...]) -> Model:
    if kind == "slab":
        return Model(name, (Shape("box", size=SLAB_SIZE),), pose=Pose(*values), mu=1.0, mu2=1.0, color=ASPHALT)
    if kind == "barrel":
        return Model(name, barrel_shapes(), pose=Pose(*values), mass=BARREL_MASS, static=True, color=BARREL)
    x, y, z, roll = values
    high = kind == "tile_red"
    return Model(
        name, (Shape("box", size=TILE_SIZE),), pose=Pose(x, y, z, roll),
        mu=1000.0 if high else 1.0, mu2=500.0 if high else 5.0, color=RED if high else GREEN,
        tags={"friction": "high" if high else "low"},
    )


def friction_models(*, barrels: bool = True) -> list[Model]:
    return [friction_model(*row) for row in FRICTION_ORDER if barrels or row[0] != "barrel"]


FRICTION_SCENARIO = Scenario(start=Pose(-0.1, -0.3), goal=(0.9, 4.2, None), timeout=TIMEOUT)


# -- assembly ------------------------------------------------------------------------------------------------
def _world(name: str, models: list[Model], scenario: Scenario) -> World:
    return World(models=tuple(models), scenario=scenario, physics=PAPER_PHYSICS, ground=GAZEBO_GROUND, name=name)


# file stem -> (builder, the main world whose settings blocks it follows)
WORLD_BUILDERS: dict[str, tuple[Callable[[], World], str]] = {
    "ditch": (lambda: _world("ditch", ditch_models(), DITCH_SCENARIO), "ditch"),
    "ditch_bridged": (lambda: _world("ditch_bridged", ditch_models(bridged=True), DITCH_SCENARIO), "ditch"),
    "ditch_ground_only": (lambda: _world("ditch_ground_only", [], DITCH_SCENARIO), "ditch"),
    "rubble": (lambda: _world("rubble", rubble_models(), DITCH_SCENARIO), "rubble"),
    "rubble_no_blocks": (lambda: _world("rubble_no_blocks", rubble_models(blocks=False), DITCH_SCENARIO), "rubble"),
    "rubble_ground_only": (lambda: _world("rubble_ground_only", [], DITCH_SCENARIO), "rubble"),
    "friction": (lambda: _world("friction", friction_models(), FRICTION_SCENARIO), "friction"),
    "friction_no_barrels": (
        lambda: _world("friction_no_barrels", friction_models(barrels=False), FRICTION_SCENARIO), "friction",
    ),
    "friction_ground_only": (lambda: _world("friction_ground_only", [], FRICTION_SCENARIO), "friction"),
}

HEADERS = {
    "ditch": "The paper's ditch scenario (DDEnv rough_terrain_gap.world): 43 models at their effective <state> poses.",
    "ditch_bridged": "Culprit-free ditch: the near plateau lengthened by 0.507 m so that there is no gap.",
    "ditch_ground_only": "Culprit-free ditch: the ground plane alone (same scenario).",
    "rubble": "The paper's rubble scenario (DDEnv rubble_loose11.world): 36 models at their effective <state> poses.",
    "rubble_no_blocks": "Culprit-free rubble: the rubble world without its two cinder blocks.",
    "rubble_ground_only": "Culprit-free rubble: the ground plane alone (same scenario).",
    "friction": "The paper's friction scenario (DDEnv frictionpatch6.world): 25 models at their effective <state> poses.",
    "friction_no_barrels": "Culprit-free friction: the friction world without its eight construction barrels.",
    "friction_ground_only": "Culprit-free friction: the ground plane alone (same scenario).",
}


def _committed_settings(stem: str) -> World | None:
    path = WORLDS / f"{stem}.yaml"
    return World.load(path) if path.is_file() else None


def build(stem: str, *, keep_settings: bool = True) -> World:
    """The world `stem`; with `keep_settings`, scenario/physics/ground follow the committed main world."""
    builder, main = WORLD_BUILDERS[stem]
    world = builder()
    settings = _committed_settings(main) if keep_settings else None
    if settings is not None:
        world = dataclasses.replace(world, scenario=settings.scenario, physics=settings.physics, ground=settings.ground)
    return world


def render(stem: str, *, keep_settings: bool = True) -> str:
    header = (
        f"# {HEADERS[stem]}\n"
        "# Models generated by tools/make_scenario_worlds.py from shared/reference/paper-artifact.md;\n"
        "# see docs/scenarios.md. The scenario/physics/ground blocks may be tuned by hand.\n"
    )
    # the shipped worlds name no engine (pybullet where it is installed, otherwise mujoco): written as pybullet's,
    # whichever engines are installed where they are generated
    return header + build(stem, keep_settings=keep_settings).with_engine("pybullet").to_yaml()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with the committed files, write nothing")
    parser.add_argument("--reset-settings", action="store_true", help="write the default scenario/physics/ground")
    parser.add_argument("--sdf", action="store_true", help="also write worlds/{ditch,rubble,friction}.world")
    args = parser.parse_args(argv)
    texts = {stem: render(stem, keep_settings=not args.reset_settings) for stem in WORLD_BUILDERS}
    stale = []
    for stem, text in texts.items():
        path = WORLDS / f"{stem}.yaml"
        if args.check:
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                stale.append(path.name)
        else:
            path.write_text(text, encoding="utf-8")
    if args.sdf and not args.check:
        from pytest_ddenv.sdf import dump_sdf

        for stem in ("ditch", "rubble", "friction"):
            (WORLDS / f"{stem}.world").write_text(dump_sdf(World.load(WORLDS / f"{stem}.yaml")), encoding="utf-8")
    if stale:
        print(f"out of date: {', '.join(stale)}; run python tools/make_scenario_worlds.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
