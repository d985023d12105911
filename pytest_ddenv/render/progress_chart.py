"""The progress chart of a reduction: world size against the number of probes, accepted steps and every probe
marked (the paper's Fig. 2)."""

from __future__ import annotations

from collections.abc import Collection, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.render.canvas import DPI, OUTCOME_COLORS, PROGRESS_SIZE, models_text, pyplot, save

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


def plot_progress(steps: Sequence[tuple[int, int]], *, path: str | Path, probes: int | None = None,
                  probe_sizes: Sequence[tuple[int, int, str]] = (), title: str | None = None,
                  note: str | None = None, accepted: Collection[int] | None = None) -> Path:
    """Write world size against the number of probes (the paper's Fig. 2) to `path`.

    `steps`: (probes so far, size) at the start and after each accepted step (`Reduction.steps`);
    `probes`: total probes (extends the last step and the axis); `probe_sizes`: (probe number, candidate
    size, outcome) of every simulation, drawn as small dots coloured by outcome; `accepted`: the numbers of
    the same-failure probes on an adopted world (None: all of them); the others are drawn as hollow red
    dots, "same failure, not accepted"; `note`: text under the legend.
    """
    return save(draw_progress(steps, probes=probes, probe_sizes=probe_sizes, title=title, note=note,
                              accepted=accepted), path)


def draw_progress(steps: Sequence[tuple[int, int]], *, probes: int | None = None,
                  probe_sizes: Sequence[tuple[int, int, str]] = (), title: str | None = None,
                  note: str | None = None, accepted: Collection[int] | None = None) -> Figure:
    """The figure of `plot_progress` (close it with `matplotlib.pyplot.close` when done)."""
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator

    plt = pyplot()
    figure: Figure = plt.figure(figsize=(PROGRESS_SIZE[0] / DPI, PROGRESS_SIZE[1] / DPI), dpi=DPI)
    axes = figure.add_axes((0.08, 0.12, 0.62, 0.78))
    steps = [(int(p), int(s)) for p, s in steps] or [(0, 0)]
    total = max(probes if probes is not None else 0, steps[-1][0], max((p for p, _, _ in probe_sizes), default=0))
    xs = [p for p, _ in steps] + [total]
    ys = [s for _, s in steps] + [steps[-1][1]]
    axes.step(xs, ys, where="post", color="#1f77b4", linewidth=2.2, zorder=3)
    handles: list[Any] = [Line2D([], [], color="#1f77b4", linewidth=2.2, label="current world size")]
    if len(steps) > 1:
        axes.plot([p for p, _ in steps[1:]], [s for _, s in steps[1:]], "o", color="#1f77b4",
                  markeredgecolor="black", markersize=7, zorder=4)
        handles.append(Line2D([], [], marker="o", color="#1f77b4", markeredgecolor="black", linestyle="none",
                              label="accepted step\n(a smaller world fails)"))
    handles += _probe_dots(axes, probe_sizes, accepted)
    axes.set_xlim(0, max(total, 1) * 1.03)
    axes.set_ylim(-0.5, max(ys + [s for _, s, _ in probe_sizes]) * 1.08 + 0.5)
    axes.xaxis.set_major_locator(MaxNLocator(integer=True))
    axes.yaxis.set_major_locator(MaxNLocator(integer=True))
    axes.set_xlabel("probes (the runs whose results the reduction used)")
    axes.set_ylabel("world size (models)")
    axes.grid(True, color="#dddddd", linewidth=0.6)
    axes.set_axisbelow(True)
    axes.set_title(title or f"{steps[0][1]} → {models_text(steps[-1][1])} in {total} probes", fontsize=12)
    axes.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=9,
                frameon=False)
    if note:
        axes.text(1.02, 0.0, note, transform=axes.transAxes, ha="left", va="bottom", fontsize=9)
    return figure


NOT_ACCEPTED = "probe: same failure,\nits world not accepted"


def _probe_dots(axes: Axes, probe_sizes: Sequence[tuple[int, int, str]], accepted: Collection[int] | None) -> list[Any]:
    """One scatter per outcome (gid "probes:OUTCOME"), and its legend handles."""
    from matplotlib.lines import Line2D

    handles: list[Any] = []
    labels = {"fail": "probe: same failure", "other": "probe: other failure", "pass": "probe: passed",
              "error": "probe: error"}
    for outcome, color in OUTCOME_COLORS.items():
        chosen = [(p, s) for p, s, o in probe_sizes if o == outcome and (
            outcome != "fail" or accepted is None or p in accepted)]
        if not chosen:
            continue
        dots = axes.scatter([p for p, _ in chosen], [s for _, s in chosen], s=18, color=color, alpha=0.8, zorder=5,
                            linewidths=0)
        dots.set_gid(f"probes:{outcome}")
        handles.append(Line2D([], [], marker="o", color=color, alpha=0.7, linestyle="none", markersize=5,
                              label=labels[outcome]))
    rejected = [(p, s) for p, s, o in probe_sizes if o == "fail" and accepted is not None and p not in accepted]
    if rejected:
        color = OUTCOME_COLORS["fail"]
        dots = axes.scatter([p for p, _ in rejected], [s for _, s in rejected], s=22, facecolors="none",
                            edgecolors=color, linewidths=1.2, zorder=5)
        dots.set_gid("probes:fail-not-accepted")
        handles.append(Line2D([], [], marker="o", markerfacecolor="none", markeredgecolor=color, linestyle="none",
                              markersize=5, label=NOT_ACCEPTED))
    return handles
