"""The last phase's pictures and media: the pictures drawn (never failing the reduction over one), or the
pictures, animations and recordings made later in a background process (`LaterMedia`)."""

from __future__ import annotations

import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from pytest_ddenv.driver import artifacts
from pytest_ddenv.driver.report import ReductionReport
from pytest_ddenv.media.writer import BackgroundMedia
from pytest_ddenv.reduce import Reduction
from pytest_ddenv.stages import StagesOutcome

if TYPE_CHECKING:
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World


class LaterMedia:
    """A reduction's pictures, animations and recordings made in a background process (`plan.media_later`)
    after its summary was written: `finish()` waits for them, says what could not be made (warnings, as when
    they are made before `run_reduction` returns) and adds them to `summary.json` (`media`,
    `timings.pictures_background` and `timings.media` the seconds they took, `timings.media_wait` the seconds
    `finish()` waited)."""

    def __init__(self, media: BackgroundMedia, report: ReductionReport, summary: Path) -> None:
        self.media, self.report, self.summary = media, report, summary
        self.done: list[Path] | None = None

    def finish(self) -> list[Path]:
        """The files made (waits for the background process once; later calls return the same list)."""
        if self.done is not None:
            return self.done
        started = time.perf_counter()
        written = self.media.finish()
        drawn = {} if self.media.pictures is None else {"pictures_background": round(written.picture_seconds, 3)}
        timings = {**self.report.run_settings.get("timings", {}), **drawn, "media": round(written.seconds, 3),
                   "media_wait": round(time.perf_counter() - started, 3)}
        report = replace(self.report.with_media(written.info, written.seconds) if written.info else self.report,
                         run_settings={**self.report.run_settings, "timings": timings})
        artifacts.write_json(self.summary, report.to_json())
        self.done = [*written.pictures, *written.paths]
        return self.done


def picture_paths(paths: artifacts.ArtifactPaths, staged: StagesOutcome | None) -> list[Path]:
    """The pictures `write_pictures` writes when nothing goes wrong."""
    written = [paths.reduction_png, paths.progress_png]
    if staged is not None and staged.changed and staged.final is not None:
        written.append(paths.directory / "simplified.png")
    if staged is not None and staged.passing is not None:
        written.append(paths.directory / "passing.png")
    return written


def write_pictures(world: World, reduction: Reduction, paths: artifacts.ArtifactPaths, original_run: Run | None,
                   minimal_run: Run | None, staged: StagesOutcome | None = None) -> list[Path]:
    """reduction.png and progress.png (the original and the minimal world's failing trajectories), and the
    stages' simplified.png and passing.png."""
    try:
        from pytest_ddenv.driver import pictures

        written = list(pictures.write_reduction_pictures(world, reduction, paths, original_run=original_run,
                                                         minimal_run=minimal_run))
        if staged is not None:
            written += pictures.write_stage_pictures(staged, paths)
        return written
    except Exception as error:  # noqa: BLE001 - pictures are a convenience; never lose the reduction over one
        warnings.warn(f"ddenv: pictures not written: {type(error).__name__}: {error}", stacklevel=1)
        return []
