"""The region cut into a grid of cells, one model on the ground to a cell, and the cells the robot keeps free."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeAlias

from pytest_ddenv.strategies._defaults import MILLI, Region
from pytest_ddenv.world.model import Scenario

Rectangle: TypeAlias = tuple[float, float, float, float]
"""(xmin, ymin, xmax, ymax) in metres."""


@dataclass(frozen=True)
class _Grid:
    """The region cut into square cells of `pitch` m (a whole, even number of millimetres, so that cell
    centres are whole millimetres): each model resting on the ground gets a cell of its own and stays
    `clearance` / 2 inside it, so that models in two cells are at least `clearance` apart."""

    centres: tuple[tuple[int, int], ...]
    """Cell centres in millimetres, row by row from (xmin, ymin)."""
    columns: int
    rows: int
    pitch: float
    clearance: float

    @classmethod
    def of(cls, region: Region, widest: float, clearance: float) -> _Grid:
        pitch_mm = 2 * math.ceil(round((widest + clearance) * MILLI, 6) / 2)
        (xmin, ymin), (xmax, ymax) = region
        x0, y0 = math.ceil(round(xmin * MILLI, 6)), math.ceil(round(ymin * MILLI, 6))
        width, depth = math.floor(round(xmax * MILLI, 6)) - x0, math.floor(round(ymax * MILLI, 6)) - y0
        columns, rows = max(width, 0) // pitch_mm, max(depth, 0) // pitch_mm
        x0 += (width - columns * pitch_mm) // 2  # the cells centred in the region
        y0 += (depth - rows * pitch_mm) // 2
        centres = tuple((x0 + i * pitch_mm + pitch_mm // 2, y0 + j * pitch_mm + pitch_mm // 2)
                        for j in range(rows) for i in range(columns))
        return cls(centres, columns, rows, pitch_mm / MILLI, clearance)

    @property
    def inner(self) -> float:
        """Half the side of the part of a cell a model may cover."""
        return (self.pitch - self.clearance) / 2.0

    def free(self, keep_out: Sequence[Rectangle]) -> tuple[tuple[int, int], ...]:
        """The cells whose inner part does not reach into any of the `keep_out` rectangles."""
        inner = self.inner

        def clear(centre: tuple[int, int]) -> bool:
            x, y = centre[0] / MILLI, centre[1] / MILLI
            return not any(x - inner < xmax and x + inner > xmin and y - inner < ymax and y + inner > ymin
                           for xmin, ymin, xmax, ymax in keep_out)

        return tuple(centre for centre in self.centres if clear(centre))

    def most_blocked(self, side: float) -> int:
        """The most cells a keep-out square of `side` m (clearance included) can block, wherever it is: the
        inner parts of the cells it reaches along an axis lie in an open interval of `side - clearance +
        pitch` m."""
        per_axis = math.ceil((side - self.clearance) / self.pitch) + 1
        return min(per_axis, self.columns) * min(per_axis, self.rows)


def _keep_out(scenario: Scenario, footprint: tuple[float, float], clearance: float) -> tuple[Rectangle, Rectangle]:
    """Where no model may be: the bounds of the robot's footprint at its start (at the start heading) and
    standing on the goal (at any heading), each grown by `clearance`."""
    length, width = footprint
    c, s = abs(math.cos(scenario.start.yaw)), abs(math.sin(scenario.start.yaw))
    hx = length / 2.0 * c + width / 2.0 * s + clearance
    hy = length / 2.0 * s + width / 2.0 * c + clearance
    x, y = scenario.start.x, scenario.start.y
    reach = math.hypot(length, width) / 2.0 + clearance
    gx, gy = scenario.goal[0], scenario.goal[1]
    return (x - hx, y - hy, x + hx, y + hy), (gx - reach, gy - reach, gx + reach, gy + reach)


def _too_many(count: int, needed: int, region: Region, grid: _Grid, widest: float, blocked: int, why: str) -> str:
    (xmin, ymin), (xmax, ymax) = region
    side = math.ceil(math.ceil(math.sqrt(needed + blocked)) * grid.pitch * 10.0) / 10.0  # k x k cells, to 0.1 m
    kept = f"; {why} {blocked} of them free" if blocked else ""
    return (
        f"worlds(count={count}): {needed} model(s) need {needed} cell(s) of {grid.pitch:g} x {grid.pitch:g} m "
        f"(the widest footprint, {widest:.3g} m, plus the clearance, {grid.clearance:g} m), but the region, "
        f"{xmax - xmin:g} x {ymax - ymin:g} m, holds {grid.columns} x {grid.rows} cells{kept}: room for "
        f"{len(grid.centres) - blocked}. Use a larger region (about {side:g} x {side:g} m), fewer models, "
        "smaller models (size=(lo, hi)) or a smaller clearance."
    )
