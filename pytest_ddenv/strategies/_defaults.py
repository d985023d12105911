"""The units, defaults and type aliases that the strategy modules share."""

from __future__ import annotations

from typing import Literal, TypeAlias

from pytest_ddenv.world.model import Pose, Scenario

Point: TypeAlias = tuple[float, float]
Region: TypeAlias = tuple[Point, Point]
"""((xmin, ymin), (xmax, ymax)) in metres, world frame."""
Range: TypeAlias = tuple[float, float]
"""(lowest, highest), both included."""
PrimitiveKind: TypeAlias = Literal["box", "cylinder", "sphere"]

PRIMITIVE_KINDS: tuple[PrimitiveKind, ...] = ("box", "cylinder", "sphere")
HUSKY_FOOTPRINT: tuple[float, float] = (0.99, 0.67)
"""The built-in Husky's (length, width) in metres: `pytest_ddenv.sim.Husky().footprint`, which this layer
cannot import (tests/test_strategies.py checks that they agree)."""
DEFAULT_REGION: Region = ((0.0, -5.0), (10.0, 5.0))
DEFAULT_SCENARIO = Scenario(start=Pose(0.0, 0.0, 0.0), goal=(10.0, 0.0, None))
"""The robot starts at the origin heading +x; the goal is 10 m ahead (the far edge of DEFAULT_REGION)."""
DEFAULT_SIZE: Range = (0.2, 0.8)
DEFAULT_MASS: Range = (0.5, 10.0)
DEFAULT_FRICTION: Range = (0.5, 1.0)
MILLI = 1000
"""Lengths, masses and friction coefficients are drawn in steps of 1 / MILLI (millimetres, grams)."""
STACK_STEPS = 100
"""`stacked` is honoured to 1 / STACK_STEPS."""
