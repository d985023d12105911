"""Pictures of worlds, runs and reductions (matplotlib, headless).

Three pictures, all top-down and to scale in metres (see docs/pictures.md):

- `plot_world`: every model's footprint (the real outline of each shape projected on the ground), static,
  dynamic and unusual-friction models shown apart, the start and the goal, and one or more trajectories
  with the failure pose marked.
- `plot_reduction`: the original world with the removed models ghosted and the kept models highlighted and
  labelled, the original failing trajectory and the minimal world's failing trajectory.
- `plot_progress`: world size against the number of probes, accepted steps marked (the paper's Fig. 2).

`pytest_ddenv.driver.pictures.write_reduction_pictures` writes the last two into an artifacts folder.
matplotlib is imported lazily with the Agg backend, so importing this package is cheap and no display is ever
needed.

The modules, one job each: `canvas` (sizes, colours, figures saved as PNG), `footprints` (what each model
looks like from above), `drawing` (the parts of a top-down picture), `tabletop` (the parts that differ for an
arm on a table: the view zoomed to the table, the arm's base, the place region, the target's path), `labels`
(model names placed without overlap), `world_picture` (`plot_world`, `plot_reduction`), `progress_chart`
(`plot_progress`).
"""

from __future__ import annotations

from pytest_ddenv.render.canvas import DPI, PROGRESS_SIZE, WORLD_SIZE
from pytest_ddenv.render.drawing import ROBOT_FOOTPRINT, robot_outline
from pytest_ddenv.render.footprints import (
    HIGH_FRICTION,
    LOW_FRICTION,
    TERRAIN_EXTENT,
    Category,
    Footprint,
    Friction,
    Shading,
    category,
    footprints,
    friction,
    frictions_shown,
)
from pytest_ddenv.render.labels import MAX_LABELS
from pytest_ddenv.render.progress_chart import draw_progress, plot_progress
from pytest_ddenv.render.world_picture import draw_reduction, draw_world, plot_reduction, plot_world

__all__ = [
    "DPI",
    "HIGH_FRICTION",
    "LOW_FRICTION",
    "MAX_LABELS",
    "PROGRESS_SIZE",
    "ROBOT_FOOTPRINT",
    "TERRAIN_EXTENT",
    "WORLD_SIZE",
    "Category",
    "Footprint",
    "Friction",
    "Shading",
    "category",
    "draw_progress",
    "draw_reduction",
    "draw_world",
    "footprints",
    "friction",
    "frictions_shown",
    "plot_progress",
    "plot_reduction",
    "plot_world",
    "robot_outline",
]
