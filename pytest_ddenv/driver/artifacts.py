"""Files a reduction leaves behind: minimal world (YAML, SDF), run log, summary, pictures; and the lock that
keeps two reductions out of one folder. What the files say is decided before they are written (the summary by
`report.py`, a world by its format's writer, `world/formats.py`): this module only writes.

Every file is written atomically and durably (write a temporary file, fsync it, rename it over the old one,
fsync the folder), so a crash at any moment leaves either the old or the new file, never half of one. The
run log `runs.jsonl` is appended and fsynced line by line by the engine and is never deleted: its first
record names the problem it belongs to (`problem.Problem.header`), and a log of another problem is moved aside
(`runs.previous-N.jsonl`), not removed. While a reduction runs, `minimal.yaml` and a provisional
`summary.json` (``"complete": false``) hold the best world so far, rewritten at every accepted step.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import re
import stat
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

from pytest_ddenv.driver.problem import Problem
from pytest_ddenv.errors import DdenvError, ReductionError, WorldError
from pytest_ddenv.reduce import events
from pytest_ddenv.reduce.log import sync_directory, write_failure
from pytest_ddenv.reduce.records import json_value, read_regular
from pytest_ddenv.world.formats import FORMATS, format_of
from pytest_ddenv.world.model import World

if TYPE_CHECKING:
    from pytest_ddenv.driver.other_failures import OtherFailure
    from pytest_ddenv.stages import StagesOutcome

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: no folder lock
    fcntl = None  # type: ignore[assignment]

LOCK_NAME = ".ddenv.lock"
"""The lock file of an artifacts folder (holds the pid of the reduction that has it)."""
STALE_OUTPUTS = ("minimal.sdf", "minimal.xml", "reduction.png", "progress.png")
"""Outputs of an earlier problem that a new log makes stale (rewritten at the end of the reduction)."""
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


class ArtifactsError(ReductionError):
    """The artifacts folder cannot be used: another reduction holds it, it cannot be written (a full disk, no
    permission), or (`ddenv replay`) it is missing a file or holds something that cannot be replayed. The
    message says which folder or file, why, and what to do."""


def artifact_dir_name(test_id: str, seed: int) -> str:
    """A folder name for a test id and the seed of the run reduced ("test_x.py__test_y-seed7-1a2b3c4d"): safe on
    every file system, no traversal, and unique per (id, seed), so that CI pages group a test's folders and a
    rerun of the same test and seed resumes in the same one."""
    digest = hashlib.sha1(f"{test_id}\0{seed}".encode()).hexdigest()[:8]
    return f"{readable_test_id(test_id)}-seed{seed}-{digest}"


def readable_test_id(test_id: str) -> str:
    """The readable start of `artifact_dir_name`: the test id with "::" as "__" and every other character that
    is not a letter, a digit, ".", "_" or "-" as "_", at most 80 characters."""
    return (_UNSAFE.sub("_", test_id.replace("::", "__")).strip("._") or "test")[:80]


def write_text_atomic(path: Path, text: str) -> None:
    """Replace `path` with `text` all at once and durably; ArtifactsError (the file untouched) if it cannot."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_bytes_atomic(path: Path, data: bytes) -> None:
    """`write_text_atomic` for bytes (a cut SDF file keeps its original encoding)."""
    temporary = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        handle = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o644)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(handle, view):]
            os.fsync(handle)
        finally:
            os.close(handle)
        os.replace(temporary, path)
    except OSError as error:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise ArtifactsError(write_failure(path, error)) from error
    sync_directory(path.parent)


@dataclass(frozen=True)
class ArtifactPaths:
    directory: Path

    @property
    def minimal_yaml(self) -> Path:
        return self.directory / "minimal.yaml"

    @property
    def minimal_sdf(self) -> Path:
        return self.directory / "minimal.sdf"

    @property
    def minimal_xml(self) -> Path:
        return self.directory / "minimal.xml"

    @property
    def log(self) -> Path:
        return self.directory / "runs.jsonl"

    @property
    def summary(self) -> Path:
        return self.directory / "summary.json"

    @property
    def simplified_yaml(self) -> Path:
        return self.directory / "simplified.yaml"

    @property
    def passing_yaml(self) -> Path:
        return self.directory / "passing.yaml"

    @property
    def reduction_png(self) -> Path:
        return self.directory / "reduction.png"

    @property
    def progress_png(self) -> Path:
        return self.directory / "progress.png"


class FolderLock:
    """An exclusive lock on an artifacts folder (`fcntl.flock` on its `.ddenv.lock`, which holds the owner's
    pid). The kernel releases it when its process ends, however it ends (kill -9 included)."""

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self._fd: int | None = None

    def __enter__(self) -> Self:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def acquire(self) -> None:
        path = self.directory / LOCK_NAME
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            # never through a symbolic link (its target would get our pid), never blocking on a FIFO
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o644)
        except OSError as error:
            if error.errno == errno.ELOOP:
                raise ArtifactsError(f"cannot use the artifacts folder {self.directory}: its lock file {path} is a "
                                     "symbolic link, which a reduction never follows (it would overwrite the link's "
                                     "target); remove the link") from None
            if error.errno == errno.EISDIR:
                raise ArtifactsError(f"cannot use the artifacts folder {self.directory}: its lock file {path} is a "
                                     "folder; remove it") from None
            raise ArtifactsError(f"cannot use the artifacts folder {self.directory}: "
                                 f"{error.strerror or error}; pass a writable folder") from error
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise ArtifactsError(f"cannot use the artifacts folder {self.directory}: its lock file {path} is not a "
                                 "regular file; remove it")
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                holder = _read_holder(fd)
                os.close(fd)
                raise ArtifactsError(
                    f"the artifacts folder {self.directory} is in use by another reduction ({holder}); two "
                    "reductions cannot share one folder: wait for it to end, or pass another artifacts folder"
                ) from None
        with contextlib.suppress(OSError):  # the pid is only for the message above
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()} {time.strftime('%Y-%m-%dT%H:%M:%S')}\n".encode(), 0)
        self._fd = fd

    def release(self) -> None:
        if self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)  # closing the last descriptor releases the flock
            self._fd = None


def _read_holder(fd: int) -> str:
    try:
        words = os.pread(fd, 200, 0).decode("utf-8", errors="replace").split()
    except OSError:
        words = []
    if words and words[0].isdigit():
        return f"pid {words[0]}" + (f", since {words[1]}" if len(words) > 1 else "")
    return "pid unknown"


def prepare(directory: Path, problem: Problem, *,
            same_reference: Callable[[Mapping[str, Any]], bool] = lambda reference: True
            ) -> tuple[ArtifactPaths, list[str]]:
    """Create the folder and make `runs.jsonl` the log of `problem`; returns the paths and notes.

    An existing log is resumed when its first record (`Problem.header`) names this problem and
    `same_reference(the failure it reduced)` holds: the same world, settings, test and code under test, and
    the same failure (whatever the fingerprint says, a log that reduced another failure is never reused). A
    log of another problem is moved aside to ``runs.previous-N.jsonl`` (never deleted), and the notes say so
    and what changed. Call it while holding the folder's `FolderLock`."""
    paths = ArtifactPaths(Path(directory))
    notes: list[str] = []
    try:
        paths.directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ArtifactsError(f"cannot create the artifacts folder {paths.directory}: "
                             f"{error.strerror or error}") from error
    if paths.log.exists() and not paths.log.is_file():
        raise ArtifactsError(f"cannot use the artifacts folder {paths.directory}: its run log {paths.log} is "
                             f"{'a folder' if paths.log.is_dir() else 'not a regular file'}; move it away")
    if paths.log.exists():
        first, size = _first_record(paths.log)
        why = "its test, world, code or reduction settings differ"
        if isinstance(first, events.Problem):
            if first.fingerprint == problem.fingerprint:
                reference = first.reference
                if reference is not None and same_reference(reference):
                    return paths, notes
                why = "it reduced another failure"
            else:
                why = "; ".join(problem.differences(first)) or why
        elif size == 0:
            paths.log.unlink()  # an empty file holds nothing to keep
        if paths.log.exists():
            kept = _free_name(paths.directory, "runs.previous-{}.jsonl")
            try:
                os.replace(paths.log, kept)
            except OSError as error:
                raise ArtifactsError(f"cannot move the run log of another problem {paths.log} aside to {kept.name}: "
                                     f"{error.strerror or error}; move or delete it yourself") from error
            notes.append(f"the run log of another problem ({why}) was kept as {kept.name}; this reduction starts "
                         f"a new {paths.log.name}")
    for name in STALE_OUTPUTS:
        with contextlib.suppress(OSError):
            (paths.directory / name).unlink()
    write_text_atomic(paths.log, events.encode(problem.header()) + "\n")
    return paths, notes


def _first_record(path: Path) -> tuple[events.Event | events.Unreadable | None, int]:
    """The first line of a log read (an event, or why it is none) and the file's size."""
    try:
        with path.open("rb") as handle:  # a regular file (`prepare` checked)
            line = handle.readline(1 << 20)
        size = path.stat().st_size
    except OSError:
        return None, 0
    return events.decode(line.decode("utf-8", errors="replace")), size


def _free_name(directory: Path, pattern: str) -> Path:
    number = 1
    while (directory / pattern.format(number)).exists():
        number += 1
    return directory / pattern.format(number)


@dataclass(frozen=True)
class Usage:
    """Simulations and worker CPU seconds of the earlier runs recorded in a log."""

    runs: int = 0
    simulations: int = 0
    cpu_seconds: float = 0.0
    complete: bool = True
    """False when an earlier run was stopped before it could record its usage (kill -9): its simulations are
    those it logged, its CPU time is unknown."""


def usage_of(logged: Iterable[events.Event]) -> Usage:
    """What the earlier runs in a log cost. Each run starts with a ``session`` event and records its
    cumulative ``usage`` at every accepted step and at its end; a run stopped in between adds the probes (and
    cross-engine runs) it logged after its last ``usage`` event."""
    runs: list[tuple[events.Usage | None, int]] = []  # (its last usage, the probes it logged after it)
    for event in logged:
        if isinstance(event, events.Session) or (not runs and isinstance(event, (events.Start, events.Probe))):
            runs.append((None, 0))
            if not isinstance(event, events.Probe):
                continue
        if not runs:
            continue
        if isinstance(event, events.Usage):
            runs[-1] = (event, 0)
        elif isinstance(event, (events.Probe, events.EngineRun)):
            runs[-1] = (runs[-1][0], runs[-1][1] + 1)
    usages = [(usage or events.Usage(), after) for usage, after in runs]
    return Usage(len(runs), sum(usage.simulations + after for usage, after in usages),
                 round(sum(usage.cpu_seconds for usage, _ in usages), 6), all(usage.final for usage, _ in usages))


def read_summary(path: Path) -> dict[str, Any] | None:
    """The summary at `path`, None when it is missing, not a regular file, not JSON or nested too deep."""
    try:
        data = json_value(read_regular(path).decode("utf-8", errors="replace"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def write_minimal_world(paths: ArtifactPaths, world: World, minimal: World, removed: Sequence[str], *,
                        model_paths: Sequence[str | Path] = ()) -> str | None:
    """Write the minimal world `minimal` of `world` (`minimal.yaml`, and `minimal.sdf` for a world read from
    SDF); returns how `minimal.sdf` was made (None: not written).

    `minimal.sdf` of a world read from an SDF file is that file with the `removed` models cut out (see
    `write_minimal_sdf`); `model_paths` are those the world was read with (to name its includes again).
    """
    write_world(paths.minimal_yaml, minimal, paths.directory)
    return write_minimal_sdf(paths.minimal_sdf, world, minimal, removed, model_paths)


def write_world(path: Path, world: World, folder: Path) -> None:
    """`world` as a YAML file at `path` in `folder` (its relative paths rebased onto the folder)."""
    write_text_atomic(path, FORMATS["yaml"].dump(world, folder))


def write_json(path: Path, data: Mapping[str, Any]) -> None:
    """Write a JSON file (`summary.json`) atomically."""
    write_text_atomic(path, json.dumps(data, indent=2) + "\n")


def write_stage_worlds(paths: ArtifactPaths, staged: StagesOutcome) -> dict[str, str]:
    """`simplified.yaml` (the world after the stages that change it, when they did) and `passing.yaml` (the
    nearest passing world, when found), each with an `.sdf` beside it when the world can be written as SDF;
    returns {file key: path}. Files of an earlier run that this one did not find are removed."""
    files: dict[str, str] = {}
    for key, path, world in (("simplified", paths.simplified_yaml, staged.final if staged.changed else None),
                             ("passing", paths.passing_yaml, staged.passing)):
        sdf = path.with_suffix(".sdf")
        if world is None:
            for stale in (path, sdf):
                stale.unlink(missing_ok=True)
            continue
        write_world(path, world, paths.directory)
        files[f"{key}_yaml"] = str(path)
        try:
            text = FORMATS["sdf"].dump(world, None)
        except DdenvError:  # a world SDF cannot say (a robot given as a URDF description): YAML only
            sdf.unlink(missing_ok=True)
            continue
        write_text_atomic(sdf, text)
        files[f"{key}_sdf"] = str(sdf)
    return files


OTHER_WORLD = re.compile(r"other-(\d+)\.yaml")
"""The file name of a kept other failure's smallest world (`write_other_worlds`)."""


def write_other_worlds(paths: ArtifactPaths, world: World, failures: Sequence[OtherFailure], keep: int,
                       replay: Callable[[Path, int | None], str] | None = None
                       ) -> tuple[tuple[OtherFailure, ...], tuple[Path, ...]]:
    """Write the smallest worlds of the first `keep` other failures that have one (`failures` come largest
    first) as `other-1.yaml`, `other-2.yaml` ...; returns the failures, those written with their `world_file`
    and `replay` (`replay(path, run seed)`) set, and the files. An `other-<k>.yaml` of an earlier run that
    this one did not write is removed."""
    written: list[Path] = []
    result: list[OtherFailure] = []
    known = set(world.names)
    for failure in failures:
        models = failure.smallest_world
        if len(written) < keep and models is not None and set(models) <= known:
            path = paths.directory / f"other-{len(written) + 1}.yaml"
            write_world(path, world.select(models), paths.directory)
            written.append(path)
            failure = replace(failure, world_file=str(path), replay=None if replay is None
                                          else replay(path, failure.smallest_seed))
        result.append(failure)
    for stale in paths.directory.glob("other-*.yaml"):
        if OTHER_WORLD.fullmatch(stale.name) and stale not in written:
            stale.unlink(missing_ok=True)
    return tuple(result), tuple(written)


def remove_outputs(paths: ArtifactPaths) -> None:
    """Remove the worlds and pictures of an earlier reduction (a failure that turned out not to depend on the
    world has none)."""
    for name in ("minimal.yaml", "simplified.yaml", "simplified.sdf", "passing.yaml", "passing.sdf",
                 *STALE_OUTPUTS):
        with contextlib.suppress(OSError):
            (paths.directory / name).unlink()


def write_minimal_sdf(target: Path, world: World, minimal: World, removed: Sequence[str],
                      model_paths: Sequence[str | Path]) -> str | None:
    """Write `minimal.sdf` and say how: "cut from <file>[; ...]" (the original SDF file with the removed models
    and their `<state>` entries deleted, its `ddenv:scenario` the reduction's, nothing else changed; the rest says
    where its relative paths resolve), or "regenerated[: why not cut]" (from the world model), or None when no
    SDF could be written."""
    from pytest_ddenv.sdf import SurgeryError
    from pytest_ddenv.sdf._surgical_check import minimal_cut

    source = Path(world.source) if world.source else None
    reason = ""
    if source is not None and source.suffix.lower() in (".sdf", ".world") and source.is_file():
        try:
            data, how = minimal_cut(source, minimal, removed, model_paths)
        except SurgeryError as error:
            reason = f": {error.reason}"
        else:
            write_bytes_atomic(target, data)
            return how
    try:
        minimal.save(target)
    except Exception:  # noqa: BLE001 - SDF export is optional; the YAML is the reference artifact
        return None
    return "regenerated" + reason


def write_minimal_xml(target: Path, world: World, minimal: World, removed: Sequence[str]) -> str | None:
    """For a world read from an MJCF scene: write `minimal.xml` and say how ("cut from <file>[; ...]", or
    "regenerated: why not cut", `mjcf.minimal_xml`); "not written: why" when neither gives the minimal world;
    None (nothing written) for a world from another format."""
    source = Path(world.source) if world.source else None
    if source is None or format_of(source) != "mjcf" or not source.is_file():
        return None
    from pytest_ddenv.mjcf import minimal_xml

    try:
        data, how = minimal_xml(source, minimal, removed)
    except DdenvError as error:
        target.unlink(missing_ok=True)
        return f"not written: {error.reason if isinstance(error, WorldError) else error}"
    write_bytes_atomic(target, data)
    return how


def folder_problem(folder: Path) -> str | None:
    """Why reductions cannot write into `folder` (made when missing), or None: a file in its place, a symbolic
    link to nothing, the folder (or its nearest existing parent) not writable, or a place where no folder can be
    made (`/proc`, a read-only file system). Checked before any probe runs, by trying: a file is made and
    removed in an existing folder, a folder of a name of its own is made and removed in the nearest existing parent
of a missing one (never the missing folder itself: processes that check at once must not see each other's)."""
    try:
        if folder.is_symlink() and not folder.exists():
            return f"{folder} is a symbolic link to {os.readlink(folder)}, which does not exist"
        if folder.exists() and not folder.is_dir():
            return f"{folder} is a file, not a folder"
        existing = folder
        while not existing.exists() and existing.parent != existing:
            if existing.is_symlink():
                return f"{existing} is a symbolic link to {os.readlink(existing)}, which does not exist"
            existing = existing.parent
        if not existing.is_dir():
            return f"{existing} is a file, so the folder {folder} cannot be made"
        if not os.access(existing, os.W_OK | os.X_OK):
            made = "" if existing == folder else f" (to make {folder} in it)"
            return f"the folder {existing} is not writable{made}"
        if existing == folder:
            lock, log = folder / LOCK_NAME, ArtifactPaths(folder).log
            if lock.is_symlink():
                return f"its lock file {lock} is a symbolic link, which a reduction never follows; remove the link"
            if log.exists() and not log.is_file():
                return f"its run log {log} is {'a folder' if log.is_dir() else 'not a regular file'}; move it away"
            try:
                handle, name = tempfile.mkstemp(prefix=".ddenv-check-", dir=folder)
            except OSError as error:
                return f"no file can be written in the folder {folder}: {error.strerror or error}"
            os.close(handle)
            os.unlink(name)
        else:  # a folder of a name of its own: processes checking at once (probe workers) never collide
            try:
                made = tempfile.mkdtemp(prefix=".ddenv-check-", dir=existing)
            except OSError as error:
                return f"no folder can be made in {existing} (to make {folder}): {error.strerror or error}"
            os.rmdir(made)
    except OSError as error:  # a loop of symbolic links, a name too long, a place that takes no folder ...
        return f"{folder} cannot be used: {error.strerror or error}"
    return None
