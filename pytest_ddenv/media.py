"""What a reduction shows besides its files: which media to make, and the animations and 3D recording.

`--ddenv-media` (ini `ddenv_media`, `$DDENV_MEDIA`, `ddenv reduce --media`) chooses: `all` (the default:
pictures, `original.gif`/`minimal.gif`, and `recording.rrd` when rerun-sdk is installed), `pictures` (the
PNG pictures only) or `none`. Animations and the recording are drawn from runs that recorded their full
detail (`Run.detail`): the run that confirmed the failure, and one run of the minimal world.
"""

from __future__ import annotations

import hashlib
import os
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pytest_ddenv.sim.run import Run
from pytest_ddenv.world import Model, World

PALETTE = ((0.55, 0.42, 0.30), (0.36, 0.50, 0.63), (0.52, 0.60, 0.36), (0.66, 0.46, 0.52), (0.45, 0.45, 0.58),
            (0.70, 0.58, 0.34), (0.40, 0.58, 0.55))
"""Colours of the models left at the default grey, in the animations and the recording."""
DEFAULT_COLOR = (0.6, 0.6, 0.6, 1.0)

GROUND_RGBA = (0.78, 0.78, 0.74, 1.0)
ROBOT_RGBA = (0.95, 0.75, 0.1, 1.0)
"""The ground, and a robot drawn as its footprint box, in the animations and the recording."""
MEDIA_CHOICES = ("all", "pictures", "none")
MEDIA_ENV = "DDENV_MEDIA"
DEFAULT_MEDIA = "all"


class MediaChoiceError(ValueError):
    """A media setting that is not one of `MEDIA_CHOICES`; the message says where it was given."""


def media_choice(value: str | None, where: str) -> str:
    """`value` checked (None or empty: `$DDENV_MEDIA`, else `all`); `where` names the option in the error."""
    if value in (None, ""):
        value, where = os.environ.get(MEDIA_ENV, "").strip(), f"${MEDIA_ENV}"
        if not value:
            return DEFAULT_MEDIA
    text = str(value).strip().lower()
    if text not in MEDIA_CHOICES:
        raise MediaChoiceError(f"{where}: expected one of {', '.join(MEDIA_CHOICES)}, got {value!r}")
    return text


@dataclass(frozen=True)
class Shown:
    """A run to animate and record: its label (the file name), its world, the run (None: none could be
    had) and whether it failed the same way as the reduced failure."""

    label: str
    world: World
    run: Run | None
    failed: bool


@dataclass
class MediaWritten:
    """The files `write_media` made and what each took (`info`: file name -> frames, bytes, seconds ...)."""

    paths: list[Path] = field(default_factory=list)
    info: dict[str, dict[str, Any]] = field(default_factory=dict)
    seconds: float = 0.0


def write_media(directory: Path, shown: Sequence[Shown], *, failure_text: str = "") -> MediaWritten:
    """`<label>.gif` for each run shown, and one `recording.rrd` of them all (when rerun-sdk is installed).
    `failure_text` describes the reduced failure; the last frame of a run that failed the same way without
    a predicate firing (a plain `assert` after the run) says it. Never raises: a medium that cannot be made
    is a warning (the reduction's files are what matter)."""
    from pytest_ddenv.animate import write_animation

    started = time.perf_counter()
    written = MediaWritten()
    runs = [(item.label, item.world, item.run) for item in shown if item.run is not None]
    for item in shown:
        if item.run is None:
            continue
        label, world, run = item.label, item.world, item.run
        try:
            info = write_animation(directory / f"{label}.gif", world, run, title=f"{label} ({_models(world)})",
                                   failure_text=failure_text if item.failed else "")
        except Exception as error:  # noqa: BLE001 - a convenience; never lose the reduction over one
            warnings.warn(f"ddenv: {label}.gif not written: {type(error).__name__}: {error}", stacklevel=1)
            continue
        written.paths.append(info.path)
        written.info[info.path.name] = info.to_dict()
    if runs:
        _write_recording(directory / "recording.rrd", runs, written)
    written.seconds = time.perf_counter() - started
    return written


def _write_recording(path: Path, runs: Sequence[tuple[str, World, Run]], written: MediaWritten) -> None:
    from pytest_ddenv.recording import recording_available, write_recording

    if not recording_available():  # the optional `viewer` extra is not installed
        return
    try:
        info = write_recording(path, runs)
    except Exception as error:  # noqa: BLE001 - as above
        warnings.warn(f"ddenv: {path.name} not written: {type(error).__name__}: {error}", stacklevel=1)
        return
    written.paths.append(info.path)
    written.info[info.path.name] = info.to_dict()


def model_rgba(model: Model) -> tuple[float, float, float, float]:
    """The model's colour in the animations and the recording: its own, or when it is left at the default
    grey one of `PALETTE` by its name (the same model has the same colour in every world)."""
    if tuple(model.color) != DEFAULT_COLOR:
        red, green, blue, alpha = (float(v) for v in model.color)
        return red, green, blue, alpha
    index = int(hashlib.sha1(model.name.encode()).hexdigest(), 16) % len(PALETTE)
    return (*PALETTE[index], 1.0)


def _models(world: World) -> str:
    return f"{len(world)} model{'' if len(world) == 1 else 's'}"
