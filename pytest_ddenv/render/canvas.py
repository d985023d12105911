"""The canvas every picture shares: pixel sizes, colours, headless matplotlib figures saved atomically as PNG.

matplotlib is imported lazily with the Agg backend (`pyplot`), so importing this module is cheap and no display
is ever needed.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

DPI = 100
WORLD_SIZE = (1000, 800)
"""Pixel size (width, height) of world and reduction pictures."""
PROGRESS_SIZE = (900, 500)
"""Pixel size (width, height) of progress pictures."""

FILL = {"static": "#b0b0b0", "dynamic": "#5b9bd5", "high": "#eb9486", "low": "#8fd3e8"}
"""Face colour of a model by its friction class, else by its category."""
EDGE = "#404040"
DYNAMIC_EDGE = "#1f4e96"
HIGHLIGHT = "#ff8c00"
PRECONDITION = "#c51b7d"
"""The halo of a model kept by a precondition (not shown needed for the failure), dashed magenta."""
RUN_COLORS = ("#d62728", "#7b2cbf", "#ff7f0e", "#2ca02c", "#8c564b", "#e377c2")
OUTCOME_COLORS = {"fail": "#d62728", "other": "#ff7f0e", "pass": "#2ca02c", "error": "#000000"}
"""Colour of a probe's outcome (failure poses, progress dots)."""


def pyplot() -> Any:
    """matplotlib.pyplot, on the Agg backend."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def new_figure(size: tuple[int, int]) -> tuple[Figure, Axes]:
    """A figure of `size` pixels with one axes on its left, the right side left for the legend."""
    plt = pyplot()
    figure = plt.figure(figsize=(size[0] / DPI, size[1] / DPI), dpi=DPI)
    axes = figure.add_axes((0.07, 0.08, 0.62, 0.84))
    return figure, axes


def save(figure: Figure, path: str | Path) -> Path:
    """Write `figure` to `path` as PNG (through a temporary file, so a reader never sees half a picture) and
    close it."""
    plt = pyplot()
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    temporary = target.with_name(f".{target.name}.tmp.png")
    try:
        figure.savefig(temporary, dpi=DPI, format="png", metadata={"Software": "pytest-ddenv"})
        temporary.replace(target)
    finally:
        plt.close(figure)
        temporary.unlink(missing_ok=True)
    return target


def wrap(text: str, width: int = 36) -> str:
    """`text` on lines of at most `width` characters, the later ones indented (legend entries, titles)."""
    return "\n".join(textwrap.wrap(text, width=width, subsequent_indent="  "))


def models_text(count: int) -> str:
    """A count of models in words: "1 model", "3 models"."""
    return f"{count} model" if count == 1 else f"{count} models"
