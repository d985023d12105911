"""The pictures of an artifacts folder: the reduction and its progress, and the worlds the stages found."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from pytest_ddenv.driver.picture_data import (
    accepted_probes_from_log,
    probe_sizes_from_log,
    reference_pose,
    reference_text,
    steps_from_log,
)
from pytest_ddenv.render.canvas import OUTCOME_COLORS, models_text, wrap
from pytest_ddenv.render.progress_chart import plot_progress
from pytest_ddenv.render.world_picture import plot_reduction, plot_world

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.driver.artifacts import ArtifactPaths
    from pytest_ddenv.reduce import Reduction
    from pytest_ddenv.sim import Run
    from pytest_ddenv.stages import StagesOutcome
    from pytest_ddenv.world.model import World


def write_reduction_pictures(world: World, reduction: Reduction, paths: ArtifactPaths, *,
                             original_run: Run | None = None, minimal_run: Run | None = None) -> list[Path]:
    """Write `paths.reduction_png` and `paths.progress_png`; return the paths written.

    Without `original_run`, the reference failure pose is read from `paths.summary` when it exists. The
    per-probe dots of the progress picture come from the run log `paths.log` when it exists.
    """
    failure_pose = None if original_run is not None else reference_pose(paths.summary)
    failure_text = reference_text(paths.summary)
    name = world.name or (Path(world.source).stem if world.source else "world")
    status = "1-minimal" if reduction.one_minimal else (reduction.incomplete_reason or "incomplete")
    reduction_title = (f"{name}: {reduction.original_size} → {models_text(reduction.minimal_size)} "
                       f"({reduction.probes} probes, {status})")
    probe_sizes = probe_sizes_from_log(paths.log)
    steps = steps_from_log(paths.log) if probe_sizes else None
    accepted = accepted_probes_from_log(paths.log) if steps else None
    written = [
        plot_reduction(world, reduction.minimal, path=paths.reduction_png, original_run=original_run,
                       minimal_run=minimal_run, failure_pose=failure_pose, title=reduction_title,
                       failure_text=failure_text,
                       precondition_kept=[name for name, _ in reduction.precondition_kept]),
        plot_progress(steps or reduction.steps, path=paths.progress_png,
                      probes=max(len(probe_sizes), reduction.probes) if steps else reduction.probes,
                      probe_sizes=probe_sizes, accepted=accepted,
                      title=f"{name}: world size during the reduction ({status})",
                      note=_progress_note(reduction)),
    ]
    return written


def write_stage_pictures(staged: StagesOutcome, paths: ArtifactPaths) -> list[Path]:
    """`simplified.png` (the world the stages left: the kept shapes, simplified models and the shortened
    start, with a run of that very world, from its start and with its time limit; the title names the stages
    it comes from) and `passing.png` (the nearest passing world with a passing run of it), when found. A world
    without such a run is drawn without one, and its title says so."""
    written: list[Path] = []
    if staged.changed and staged.final is not None:
        rate = "" if staged.final_rate is None else f", fails {staged.final_rate[0]}/{staged.final_rate[1]} fresh runs"
        runs = () if staged.final_run is None else (staged.final_run,)
        missing = "" if runs else " (no run of it recorded)"
        title = wrap(f"after the stages ({', '.join(staged.kept)}){rate}{missing}", 70)
        written.append(plot_world(staged.final, runs, path=paths.directory / "simplified.png", title=title))
    if staged.passing is not None:
        found = staged.result("passing")
        difference = "; ".join(found.details.get("difference", [])) if found is not None else ""
        runs = () if staged.passing_run is None else (staged.passing_run,)
        missing = "" if runs else " (no passing run of it recorded)"
        written.append(plot_world(staged.passing, runs, path=paths.directory / "passing.png",
                                  title=wrap(f"nearest passing world: {difference}{missing}", 60),
                                  run_colors=(OUTCOME_COLORS["pass"],)))
    return written


def _progress_note(reduction: Reduction) -> str:
    fails, runs = reduction.failure_rate
    # a resumed log's probes are the whole history's, the wall time this run's: say so (issue 33)
    earlier = f"{reduction.resumed_probes} in earlier runs, " if reduction.resumed_probes else ""
    lines = [f"{reduction.probes} probes ({earlier}{reduction.cache_hits} cached, {reduction.skipped} skipped)",
             f"{reduction.wall_time:.0f} s wall time{' in this run' if reduction.resumed_probes else ''}"]
    if runs:
        lines.append(f"minimal world fails {fails}/{runs} seeds")
    return "\n".join(lines)
