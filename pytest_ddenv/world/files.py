"""The files a world names (the world file itself, its meshes, heightmap images and URDFs), read only when
they are regular files.

A FIFO blocks `open()` until a writer comes, a device such as /dev/zero never ends, a folder cannot be read
and a loop of symbolic links resolves to nothing: `file_kind` says which of these a path is, so that a reader
can refuse it by what it is, and `read_regular` opens without blocking and checks what it opened before it
reads (no race between the check and the read). A file a world names is found relative to the world file
(`resolve_relative`).
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from pytest_ddenv.errors import WorldError, shown_path

MISSING = "missing"
"""`file_kind` of a path that names nothing (or a name the system refuses: too long, a NUL in it)."""
_NOT_FOUND = (errno.ENOENT, errno.ENOTDIR, errno.ENAMETOOLONG)


def file_kind(path: str | os.PathLike[str]) -> str | None:
    """What `path` is when it is not a regular file (symbolic links followed): MISSING, "a folder", "a FIFO
    (named pipe)", "a device", "a socket", "a loop of symbolic links"; None for a regular file."""
    try:
        mode = os.stat(path).st_mode
    except OSError as error:
        if error.errno == errno.ELOOP:
            return "a loop of symbolic links"
        return MISSING if error.errno in _NOT_FOUND else f"unreadable ({error.strerror or error})"
    except ValueError:  # a NUL character in the name
        return MISSING
    return _mode_kind(mode)


def _mode_kind(mode: int) -> str | None:
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def regular_file_problem(path: Path, what: str) -> str | None:
    """Why the file named `path` cannot be read as a `what` ("mesh file", "URDF file", ...), or None when it is a
    regular file: "{what} not found: PATH" (saying where a dangling symbolic link points), or "not a {what}:
    PATH is a folder" (a FIFO, a device, ...)."""
    kind = file_kind(path)
    if kind is None:
        return None
    if kind == MISSING:
        return f"{what} not found: {shown_path(path)}{dangling_link(path)}"
    return f"not a {what}: {shown_path(path)} is {kind}"


def dangling_link(path: Path) -> str:
    """" (a symbolic link to TARGET, which does not exist)" when `path` is such a link, else ""."""
    try:
        target = os.readlink(path)
    except (OSError, ValueError):
        return ""
    return f" (a symbolic link to {shown_path(target)}, which does not exist)"


def read_regular(path: Path, limit: int, what: str = "world file") -> bytes:
    """The bytes of the regular file `path`, refusing more than `limit` bytes (read in chunks: memory stays near
    the file's size) and anything that is not a regular file: a folder, a FIFO (opened without blocking, so
    that no writer is waited for), a device such as /dev/zero, a socket (WorldError naming the file)."""
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        descriptor = os.open(path, flags)
    except OSError as error:
        kind = file_kind(path)
        if kind is not None and kind != MISSING and not kind.startswith("unreadable"):
            raise WorldError(f"not a {what}: {kind}, not a file", source=path) from None
        raise WorldError(f"cannot read {what}: {error.strerror or error}", source=path) from error
    try:
        with os.fdopen(descriptor, "rb") as handle:
            kind = _mode_kind(os.fstat(descriptor).st_mode)
            if kind is not None:
                raise WorldError(f"not a {what}: {kind}, not a file", source=path)
            os.set_blocking(descriptor, True)
            chunks: list[bytes] = []
            total = 0
            while total <= limit:
                chunk = handle.read(min(1 << 20, limit + 1 - total))
                if not chunk:
                    break
                chunks.append(chunk)
                total += len(chunk)
    except OSError as error:
        raise WorldError(f"cannot read {what}: {error.strerror or error}", source=path) from error
    if total > limit:
        raise WorldError(f"{what} is larger than the {limit} byte limit; refusing to read it", source=path)
    return b"".join(chunks)


def resolve_mesh_path(mesh: str | None, source: str | None) -> Path:
    """A mesh path as given, or relative to the directory of the world file that names it."""
    if mesh is None:
        raise WorldError("a mesh shape needs a 'mesh' file", source=source)
    return resolve_relative(mesh, source)


def is_file(path: Path) -> bool:
    """Whether `path` is a file; False, not OSError, for names the system refuses (too long, ...)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


def exists(path: Path) -> bool:
    """Whether `path` exists; False, not OSError, for names the system refuses (too long, ...)."""
    try:
        return path.exists()
    except (OSError, ValueError):
        return False


def resolve_relative(file: str, source: str | None) -> Path:
    """A file named in a world file: as given if absolute, else relative to the world file's folder."""
    path = Path(file).expanduser()
    if not path.is_absolute() and source is not None:
        path = Path(source).parent / path
    return path
