"""The files `ddenv` writes where the user says (`-o` pictures, `--animate` GIFs, `--record` runs), checked before
any simulation: the right kind of file in a place that takes one, and one clear error naming the option and the
path when writing fails; their default names (`world_stem`) and the animations written."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from pytest_ddenv.cli.world_options import UsageError
from pytest_ddenv.errors import shown_path

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.media.animate import AnimationInfo
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World

KINDS = {".png": "a PNG picture", ".gif": "a GIF animation"}


def check_output(option: str, path: str | None, suffix: str) -> None:
    """`path` (None: the default name) is a file name ending in `suffix` (".png", ".gif") whose folder exists or
    can be made; UsageError naming `option` otherwise."""
    if path is None:
        return
    target = Path(path)
    if target.is_dir() or path.endswith(("/", os.sep)) or target.name in ("", ".", ".."):
        raise UsageError(f"{option}: {shown_path(path)} is a folder; give a file name ending in {suffix}")
    if target.suffix.lower() != suffix:
        raise UsageError(f"{option}: {shown_path(path)}: ddenv writes {KINDS[suffix]} here, so the name must end in "
                         f"{suffix}")
    folder = target.parent
    while not folder.exists() and folder.parent != folder:
        folder = folder.parent
    if not folder.is_dir():
        raise UsageError(f"{option}: {shown_path(path)}: {shown_path(folder)} is a file, not a folder")


def check_record(path: str | None) -> None:
    """`--record PATH` may be appended to: not a folder (checked before the run)."""
    if path is not None and Path(path).is_dir():
        raise UsageError(f"--record: {shown_path(path)} is a folder; give a file to append the run to")


@contextlib.contextmanager
def appended(option: str, path: str) -> Iterator[TextIO]:
    """`path` opened for appending text (made if missing); never blocking on a FIFO without a reader, and any
    failure (a full disk, a device, no permission) one UsageError naming `option` and `path`."""
    try:
        handle = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK, 0o644)
    except OSError as error:
        raise UsageError(_cannot_write(option, path, error)) from None
    fcntl.fcntl(handle, fcntl.F_SETFL, fcntl.fcntl(handle, fcntl.F_GETFL) & ~os.O_NONBLOCK)
    stream = os.fdopen(handle, "a", encoding="utf-8")
    try:
        yield stream
        stream.flush()
    except OSError as error:
        raise UsageError(_cannot_write(option, path, error)) from None
    finally:
        with contextlib.suppress(OSError):
            stream.close()


def _cannot_write(option: str, path: str, error: OSError) -> str:
    code = errno.errorcode.get(error.errno or 0, "")
    why = "no process reads this pipe" if error.errno == errno.ENXIO else (error.strerror or str(error))
    return f"{option} {shown_path(path)}: cannot write: {why}" + (f" ({code})" if code else "")


def check_matplotlib_backend() -> None:
    """matplotlib can be imported to draw: it refuses to when $MPLBACKEND names no backend it knows (even though
    ddenv draws with its own 'agg')."""
    try:
        import matplotlib  # noqa: F401 - imported to see that it can be
    except ValueError:  # "Key backend: 'x' is not a valid value for backend; ..."
        value = os.environ.get("MPLBACKEND", "")
        raise UsageError(f"$MPLBACKEND: {shown_path(value)} is not a matplotlib backend, so no picture can be drawn; "
                         "unset it or set MPLBACKEND=agg") from None


def world_stem(path: str) -> str:
    """The world file's name without its suffix: the default names of what a command writes about it."""
    return Path(path).stem or "world"


def write_gif(target: str, world: World, run: Run, title: str) -> AnimationInfo:
    """The animation of `run` in `world` written to `target` (`--animate`)."""
    from pytest_ddenv.media.animate import write_animation

    return write_animation(Path(target), world, run, title=title)
