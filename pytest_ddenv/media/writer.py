"""What a reduction shows besides its files: which media to make, and the animations and 3D recordings.

`--ddenv-media` (ini `ddenv_media`, `$DDENV_MEDIA`, `ddenv reduce --media`) chooses: `all` (the default:
pictures, `original.gif`/`minimal.gif`, `recording.rrd` when rerun-sdk is installed and `recording.mcap` when
foxglove-sdk is), `pictures` (the PNG pictures only), `none`, or a list of `pictures`, `animations`, `rrd` and
`mcap` (`pictures,mcap`); the pictures come with every choice but `none`, and a recording named in a list
whose package is not installed is an error (`all` leaves it out). Animations and recordings are drawn from
runs that recorded their full detail (`Run.detail`): the run that confirmed the failure, and one run of the
minimal world.
"""

from __future__ import annotations

import concurrent.futures
import concurrent.futures.process
import os
import time
import warnings
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.errors import DdenvError
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.urdf_geometry import pybullet_installed
from pytest_ddenv.world.model import World

if TYPE_CHECKING:
    from pytest_ddenv.media.animate import AnimationInfo

MEDIA_CHOICES = ("all", "pictures", "none")
"""The words of `--ddenv-media` besides a list of `MEDIA_PARTS`."""
MEDIA_PARTS = ("pictures", "animations", "rrd", "mcap")
"""What a list may name: the PNG pictures, `original.gif`/`minimal.gif`, `recording.rrd`, `recording.mcap`."""
RECORDED_PARTS = frozenset({"animations", "rrd", "mcap"})
"""The media drawn from runs with their full detail (`Run.detail`)."""
MEDIA_ENV = "DDENV_MEDIA"
DEFAULT_MEDIA = "all"


class MediaChoiceError(DdenvError, ValueError):
    """A media setting that is not one of `MEDIA_CHOICES` or a list of `MEDIA_PARTS`, or names a recording
    whose package is not installed; the message says where it was given."""


def media_choice(value: str | None, where: str) -> str:
    """`value` checked (None or empty: `$DDENV_MEDIA`, else `all`); `where` names the option in the error. A
    list comes back in the order of `MEDIA_PARTS`, with `pictures` first (`mcap` -> `pictures,mcap`)."""
    if value in (None, ""):
        value, where = os.environ.get(MEDIA_ENV, "").strip(), f"${MEDIA_ENV}"
        if not value:
            return DEFAULT_MEDIA
    text = str(value).strip().lower()
    if text in MEDIA_CHOICES:
        return text
    named = [part.strip() for part in text.split(",")]
    unknown = [part for part in named if part not in MEDIA_PARTS]
    if unknown:
        raise MediaChoiceError(f"{where}: expected one of {', '.join(MEDIA_CHOICES)}, got {value!r} (or a "
                               f"comma-separated list of {', '.join(MEDIA_PARTS)})")
    missing = _missing_package(set(named))
    if missing:
        raise MediaChoiceError(f"{where}: {missing}")
    return ",".join(part for part in MEDIA_PARTS if part in named or part == "pictures")


def media_parts(choice: str) -> frozenset[str]:
    """The `MEDIA_PARTS` a checked choice makes (`all`: every one, the recordings when their package is
    installed; `none`: none)."""
    if choice == "all":
        return frozenset(MEDIA_PARTS)
    if choice == "none":
        return frozenset()
    return frozenset(choice.split(","))


def records_runs(choice: str) -> bool:
    """Whether a checked choice draws media from runs with their full detail (animations or recordings)."""
    return bool(media_parts(choice) & RECORDED_PARTS)


def _missing_package(named: set[str]) -> str | None:
    """What a recording named explicitly needs and is not installed, in words, or None."""
    if "rrd" in named:
        from pytest_ddenv.media.recording import INSTALL_HINT, recording_available

        if not recording_available():
            return f"'rrd' was asked for, but {INSTALL_HINT}"
    if "mcap" in named:
        from pytest_ddenv.media.mcap import INSTALL_HINT as MCAP_HINT
        from pytest_ddenv.media.mcap import mcap_available

        if not mcap_available():
            return f"'mcap' was asked for, but {MCAP_HINT}"
    return None


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
    pictures: list[Path] = field(default_factory=list)
    """The pictures drawn before the media (`BackgroundMedia(pictures=...)`), and the seconds they took."""
    picture_seconds: float = 0.0


Pictures = Callable[[], list[Path]]
"""Draws a reduction's PNG pictures and returns the paths written (warns, never raises); picklable, to run in
`BackgroundMedia`'s process."""


def write_media(directory: Path, shown: Sequence[Shown], *, failure_text: str = "",
                media: str = DEFAULT_MEDIA) -> MediaWritten:
    """`<label>.gif` for each run shown, one `recording.rrd` and one `recording.mcap` of them all (each when
    its package is installed), as far as `media` (a checked `--ddenv-media`) asks for them.
    `failure_text` describes the reduced failure; the last frame of a run that failed the same way without
    a predicate firing (a plain `assert` after the run) says it. Never raises: a medium that cannot be made
    is a warning (the reduction's files are what matter)."""
    return PendingMedia(directory, shown, failure_text=failure_text, media=media).finish()


class PendingMedia:
    """`write_media` started now and finished by `finish()`. With `helper=True` (a reduction that ran its
    probes in worker processes: more than one core is the user's) the first animation renders in a helper
    process, started like the probe workers, while this process makes the pictures, the other animations
    and the recordings; without, everything is made in this process by `finish()`. Without pybullet,
    MuJoCo's renderer draws every animation in one helper process (media/gl_helper.py), started now with
    `helper=True`, else by `finish()`."""

    def __init__(self, directory: Path, shown: Sequence[Shown], *, failure_text: str = "",
                 helper: bool = False, media: str = DEFAULT_MEDIA) -> None:
        self.started = time.perf_counter()
        self.directory, self.failure_text = directory, failure_text
        self.parts = media_parts(media)
        self.recorded = [item for item in shown if item.run is not None]
        self.items = self.recorded if "animations" in self.parts else []
        self.elsewhere: tuple[Shown, concurrent.futures.ProcessPoolExecutor, concurrent.futures.Future[Any]] | None
        self.elsewhere = None
        self.in_mujoco: MujocoAnimations | None = None
        if self.items and not pybullet_installed():  # MuJoCo's renderer draws them, in a helper process
            self.in_mujoco = MujocoAnimations(directory, self.items, failure_text, start_now=helper)
        elif helper and len(self.items) >= 2:  # pybullet's TinyRenderer draws them
            self.elsewhere = _render_elsewhere(directory, self.items[0], failure_text)

    def finish(self) -> MediaWritten:
        written = MediaWritten()
        made: dict[str, AnimationInfo | None] = {}
        animated = self.items[1:] if self.elsewhere is not None else self.items
        if self.in_mujoco is not None:
            made.update(self.in_mujoco.result())
            animated = []
        for item in animated:
            made[item.label] = _animation(self.directory, item, self.failure_text)
        if self.elsewhere is not None:
            item, executor, future = self.elsewhere
            try:
                made[item.label] = future.result()
            except concurrent.futures.process.BrokenProcessPool:  # the helper died: draw it here
                made[item.label] = _animation(self.directory, item, self.failure_text)
            except Exception as error:  # noqa: BLE001 - as in _animation
                warnings.warn(f"ddenv: {item.label}.gif not written: {type(error).__name__}: {error}", stacklevel=1)
                made[item.label] = None
            finally:
                executor.shutdown(wait=True)
        for item in self.items:  # in the order shown
            info = made.get(item.label)
            if info is not None:
                written.paths.append(info.path)
                written.info[info.path.name] = info.to_dict()
        runs = [(item.label, item.world, item.run) for item in self.recorded if item.run is not None]
        if runs and "rrd" in self.parts:
            _write_recording(self.directory / "recording.rrd", runs, written)
        if runs and "mcap" in self.parts:
            _write_mcap(self.directory / "recording.mcap", runs, written)
        written.seconds = time.perf_counter() - self.started
        return written


def background_pids() -> list[int]:
    """The process ids of this process's `BackgroundMedia` still running (`execution.idle_cores(ours=...)`)."""
    return [media.process.pid for media in list(_RUNNING) if media.process.pid is not None
            and media.process.is_alive()]


class BackgroundMedia:
    """`write_media` in a background process (started like the probe workers, not a daemon: MuJoCo's renderer
    starts its own helper from it), started now, after `pictures` (the PNG pictures, drawn first when given,
    expected at `picture_paths`); `finish()` waits for it. What could not be made is a warning here, as with
    `write_media`; a background process that dies makes them in this process instead."""

    def __init__(self, directory: Path, shown: Sequence[Shown], *, failure_text: str = "",
                 media: str = DEFAULT_MEDIA, pictures: Pictures | None = None,
                 picture_paths: Sequence[Path] = ()) -> None:
        from pytest_ddenv.execution.local import main_module_hidden, probe_context

        self.directory, self.shown, self.failure_text, self.media = directory, list(shown), failure_text, media
        self.pictures, self.picture_paths = pictures, list(picture_paths)
        context = probe_context()
        self.receive, send = context.Pipe(duplex=False)
        self.process = context.Process(target=_media_process, name="ddenv-media", daemon=False,
                                       args=(send, directory, self.shown, failure_text, media, pictures))
        with main_module_hidden():  # the process starts here: it must not re-import a user's script
            self.process.start()
        send.close()
        self.written: MediaWritten | None = None
        _RUNNING.add(self)

    def expected_paths(self) -> list[Path]:
        """The files `finish()` makes when nothing goes wrong (the pictures, `<label>.gif`, `recording.rrd`,
        `recording.mcap`)."""
        parts = media_parts(self.media)
        recorded = [item for item in self.shown if item.run is not None]
        paths = [*self.picture_paths]
        paths += [self.directory / f"{item.label}.gif" for item in recorded] if "animations" in parts else []
        if recorded and "rrd" in parts:
            from pytest_ddenv.media.recording import recording_available

            paths += [self.directory / "recording.rrd"] if recording_available() else []
        if recorded and "mcap" in parts:
            from pytest_ddenv.media.mcap import mcap_available

            paths += [self.directory / "recording.mcap"] if mcap_available() else []
        return paths

    def finish(self) -> MediaWritten:
        """The media made (waits for the background process, once)."""
        if self.written is not None:
            return self.written
        written: MediaWritten
        messages: list[str]
        try:
            written, messages = self.receive.recv()
        except (EOFError, OSError):  # the process died: make them here
            self.process.join()
            warnings.warn(f"ddenv: the media process {self.process.pid} ended with status {self.process.exitcode}; "
                          "making the media in this process", stacklevel=1)
            written, messages = _pictures_and_media(self.directory, self.shown, self.failure_text, self.media,
                                                    self.pictures), []
        finally:
            self.receive.close()
        self.process.join()
        for message in messages:  # the warnings of the background process, here, where pytest shows them
            warnings.warn(message, stacklevel=1)
        self.written = written
        return written

    def cancel(self) -> None:
        """Stop the background process (Ctrl-C): the media it had not finished are not made."""
        if self.written is None and self.process.is_alive():
            self.process.terminate()
        self.process.join()
        self.receive.close()


_RUNNING: weakref.WeakSet[BackgroundMedia] = weakref.WeakSet()
"""The background media started by this process (`background_pids`)."""


def _media_process(send: Any, directory: Path, shown: Sequence[Shown], failure_text: str, media: str,
                   pictures: Pictures | None = None) -> None:
    """The background process of `BackgroundMedia`: the pictures and media, and the warnings said while making
    them."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        written = _pictures_and_media(directory, shown, failure_text, media, pictures)
    said = [str(warning.message) for warning in caught]
    send.send((written, [message for message in said if message.startswith("ddenv:")]))
    send.close()


def _pictures_and_media(directory: Path, shown: Sequence[Shown], failure_text: str, media: str,
                        pictures: Pictures | None) -> MediaWritten:
    """`pictures()` (when given), then `write_media`."""
    started = time.perf_counter()
    drawn = [] if pictures is None else pictures()
    drawn_in = time.perf_counter() - started
    written = write_media(directory, shown, failure_text=failure_text, media=media)
    written.pictures, written.picture_seconds = drawn, drawn_in
    return written


def _render_elsewhere(directory: Path, item: Shown, failure_text: str
                      ) -> tuple[Shown, concurrent.futures.ProcessPoolExecutor, concurrent.futures.Future[Any]]:
    """`item`'s animation started in a helper process (forkserver with the workers' preloads)."""
    from pytest_ddenv.execution.local import main_module_hidden, probe_context

    executor = concurrent.futures.ProcessPoolExecutor(1, mp_context=probe_context())
    with main_module_hidden():  # the process starts here: it must not re-import a user's script
        future = executor.submit(render_animation, directory, item, failure_text)
    return item, executor, future


def render_animation(directory: Path, item: Shown, failure_text: str) -> AnimationInfo:
    """`<label>.gif` of `item` (raises what the renderer raises). Runs in a helper process too."""
    from pytest_ddenv.media.animate import write_animation

    assert item.run is not None
    return write_animation(directory / f"{item.label}.gif", item.world, item.run,
                           title=_title(item),
                           failure_text=failure_text if item.failed else "")


class MujocoAnimations:
    """The animations drawn by MuJoCo's renderer, all in one helper process (`in_gl_helper`), started in a
    thread now (`start_now`) or by `result()`."""

    def __init__(self, directory: Path, items: Sequence[Shown], failure_text: str, *, start_now: bool) -> None:
        self.directory, self.items, self.failure_text = directory, list(items), failure_text
        self.thread = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="ddenv-media")
        self.future = self.thread.submit(self._draw) if start_now else None

    def _draw(self) -> list[AnimationInfo | str]:
        from pytest_ddenv.media.gl_helper import in_gl_helper

        return in_gl_helper(draw_in_mujoco, self.directory, self.items, self.failure_text)

    def result(self) -> dict[str, AnimationInfo | None]:
        """Label -> the animation made, or None (with a warning: one for all when no renderer starts)."""
        from pytest_ddenv.media.gl_helper import AnimationUnavailable

        names = ", ".join(f"{item.label}.gif" for item in self.items)
        try:
            drawn = self.future.result() if self.future is not None else self._draw()
        except AnimationUnavailable as error:  # one warning, not one per animation
            warnings.warn(f"ddenv: {names} not written: {error}", stacklevel=1)
            return {}
        except Exception as error:  # noqa: BLE001 - as in _animation
            warnings.warn(f"ddenv: {names} not written: {type(error).__name__}: {error}", stacklevel=1)
            return {}
        finally:
            self.thread.shutdown(wait=True)
        made: dict[str, AnimationInfo | None] = {}
        for item, outcome in zip(self.items, drawn, strict=True):
            if isinstance(outcome, str):
                warnings.warn(f"ddenv: {item.label}.gif not written: {outcome}", stacklevel=1)
            made[item.label] = None if isinstance(outcome, str) else outcome
        return made


def draw_in_mujoco(directory: Path, items: Sequence[Shown], failure_text: str) -> list[AnimationInfo | str]:
    """Each item's animation drawn by MuJoCo's renderer in this (helper) process, or why it was not; raises
    `GLUnavailable` when the renderer cannot start (the next OpenGL backend is tried)."""
    from pytest_ddenv.media.animate import FPS, MAX_FRAMES, draw_animation
    from pytest_ddenv.media.mujoco_scene import GLUnavailable

    drawn: list[AnimationInfo | str] = []
    for item in items:
        assert item.run is not None
        try:
            drawn.append(draw_animation(directory / f"{item.label}.gif", item.world, item.run, _title(item), FPS,
                                        MAX_FRAMES, failure_text if item.failed else "", "mujoco"))
        except GLUnavailable:
            raise
        except Exception as error:  # noqa: BLE001 - as in _animation
            drawn.append(f"{type(error).__name__}: {error}")
    return drawn


def _title(item: Shown) -> str:
    return f"{item.label} ({_models(item.world)})"


def _animation(directory: Path, item: Shown, failure_text: str) -> AnimationInfo | None:
    try:
        return render_animation(directory, item, failure_text)
    except Exception as error:  # noqa: BLE001 - a convenience; never lose the reduction over one
        warnings.warn(f"ddenv: {item.label}.gif not written: {type(error).__name__}: {error}", stacklevel=1)
        return None


def _write_recording(path: Path, runs: Sequence[tuple[str, World, Run]], written: MediaWritten) -> None:
    from pytest_ddenv.media.recording import recording_available, write_recording

    if not recording_available():  # the optional `viewer` extra is not installed
        return
    try:
        info = write_recording(path, runs)
    except Exception as error:  # noqa: BLE001 - as above
        warnings.warn(f"ddenv: {path.name} not written: {type(error).__name__}: {error}", stacklevel=1)
        return
    written.paths.append(info.path)
    written.info[info.path.name] = info.to_dict()


def _write_mcap(path: Path, runs: Sequence[tuple[str, World, Run]], written: MediaWritten) -> None:
    from pytest_ddenv.media.mcap import mcap_available, write_mcap

    if not mcap_available():  # the optional `mcap` extra is not installed
        return
    try:
        info = write_mcap(path, runs)
    except Exception as error:  # noqa: BLE001 - as above
        warnings.warn(f"ddenv: {path.name} not written: {type(error).__name__}: {error}", stacklevel=1)
        return
    written.paths.append(info.path)
    written.info[info.path.name] = info.to_dict()


def _models(world: World) -> str:
    return f"{len(world)} model{'' if len(world) == 1 else 's'}"
