"""Naming the models of a picture: labels with leader lines, placed so none overlaps another label, leaves the
axes or hides a marker."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from pytest_ddenv.render.canvas import EDGE
from pytest_ddenv.render.footprints import TERRAIN_EXTENT, Footprint

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

MAX_LABELS = 14
"""Models labelled in one picture at most; the others are counted in a corner."""


def label_models(axes: Axes, figure: Figure, prints: Sequence[Footprint], names: Sequence[str]) -> None:
    """Name each model with a leader line, placing labels so none overlaps another, leaves the axes, or
    covers a small labelled model or a marker (start, goal, failure) when a free place exists."""
    by_name = {fp.name: fp for fp in prints}
    chosen = [name for name in names if name in by_name]
    shown, hidden = chosen[:MAX_LABELS], chosen[MAX_LABELS:]
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
    frame = axes.get_window_extent(renderer)
    obstacles = _marker_boxes(axes) + [_display_box(axes, by_name[name]) for name in shown
                                       if by_name[name].extent <= TERRAIN_EXTENT / 4]
    placed: list[Any] = []
    for name in shown:
        anchor = _anchor(by_name[name], axes)
        text = f"{_short(name)}\ntop {by_name[name].top:.2f} m"
        placed.append(_place_label(axes, renderer, frame, placed, obstacles, text, anchor))
    if hidden:
        axes.text(0.99, 0.01, f"+{len(hidden)} more kept models (see summary.json)", transform=axes.transAxes,
                  ha="right", va="bottom", fontsize=8, color="#333333")


def _short(name: str, limit: int = 30) -> str:
    """A long model name with its middle elided (the full names are in summary.json)."""
    if len(name) <= limit:
        return name
    keep = (limit - 1) // 2
    return f"{name[:keep]}…{name[-keep:]}"


def _marker_boxes(axes: Axes) -> list[Any]:
    """Display boxes around the start, goal and failure markers, the goal's tolerance circle and the robot
    outlines at failure poses: what a label must not hide."""
    from matplotlib.patches import Circle, Polygon
    from matplotlib.transforms import Bbox

    boxes = []
    for line in axes.get_lines():
        if line.get_linestyle() not in ("None", "none", ""):
            continue
        for x, y in axes.transData.transform(np.column_stack(line.get_data()).astype(float)):
            boxes.append(Bbox.from_extents(x - 10, y - 10, x + 10, y + 10))
    for patch in axes.patches:
        if isinstance(patch, Circle) or (isinstance(patch, Polygon) and not patch.get_fill()):
            boxes.append(patch.get_window_extent())
    return boxes


def _display_box(axes: Axes, footprint: Footprint) -> Any:
    from matplotlib.transforms import Bbox

    corners = axes.transData.transform(np.stack([footprint.low, footprint.high]))
    return Bbox.from_extents(*corners.min(axis=0), *corners.max(axis=0))


def _anchor(footprint: Footprint, axes: Axes) -> tuple[float, float]:
    """A point of the model inside the view: its centre, or the centre of its visible part."""
    x0, x1 = axes.get_xlim()
    y0, y1 = axes.get_ylim()
    low = np.maximum(footprint.low, [x0, y0])
    high = np.minimum(footprint.high, [x1, y1])
    point = (low + high) / 2.0 if np.all(high > low) else (footprint.low + footprint.high) / 2.0
    return float(point[0]), float(point[1])


_DIRECTIONS = [(math.cos(a), math.sin(a)) for a in np.radians([45, 135, -45, -135, 90, -90, 0, 180,
                                                                      20, 160, -20, -160, 70, 110, -70, -110])]
_OFFSETS = [(round(dx * r, 1), round(dy * r, 1)) for r in (30, 50, 75, 105, 140, 180) for dx, dy in _DIRECTIONS]
_LABEL_PAD = 4.0
"""Pixels around a label's text taken by its rounded box."""


def _place_label(axes: Axes, renderer: Any, frame: Any, placed: list[Any], obstacles: Sequence[Any], text: str,
                 anchor: tuple[float, float]) -> Any:
    """Try offsets around the anchor, nearest first; take the first free one, else the least crowded.

    Returns the display box the label's text occupies.
    """
    from matplotlib.text import Text

    best: tuple[float, tuple[float, float], Any] | None = None
    for dx, dy in _OFFSETS:
        trial = axes.annotate(text, xy=anchor, xytext=(dx, dy), textcoords="offset points",
                              **_label_style(dx, dy))
        box = trial.get_window_extent(renderer).padded(_LABEL_PAD)  # no arrow yet: the text box only
        trial.remove()
        if not (frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1):
            continue
        cost = 100.0 * sum(box.overlaps(other) for other in placed) + sum(box.overlaps(o) for o in obstacles)
        if best is None or cost < best[0]:
            best = (cost, (dx, dy), box)
        if cost == 0:
            break
    offset = best[1] if best is not None else _OFFSETS[0]
    label = axes.annotate(text, xy=anchor, xytext=offset, textcoords="offset points", **_label_style(*offset),
                          arrowprops={"arrowstyle": "-", "color": EDGE, "linewidth": 0.8, "shrinkA": 0,
                                      "shrinkB": 0})
    return best[2] if best is not None else Text.get_window_extent(label, renderer).padded(_LABEL_PAD)


def _label_style(dx: float, dy: float) -> dict[str, Any]:
    return {
        "fontsize": 8.5,
        "zorder": 11,
        "ha": "left" if dx > 1e-6 else "right" if dx < -1e-6 else "center",
        "va": "bottom" if dy > 1e-6 else "top" if dy < -1e-6 else "center",
        "multialignment": "left",
        "bbox": {"boxstyle": "round,pad=0.2", "facecolor": "white", "edgecolor": EDGE, "alpha": 0.9},
    }
