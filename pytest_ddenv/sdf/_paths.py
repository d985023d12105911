"""Where Gazebo models live: `model://` and file URIs resolved through the user's model paths."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from urllib.parse import unquote, urlparse

from pytest_ddenv.errors import PATH_CHARACTERS, shown, shown_path
from pytest_ddenv.world import exists

MODEL_PATH_VARIABLES = ("GAZEBO_MODEL_PATH", "GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "SDF_PATH")
"""Environment variables searched for `model://` URIs, in this order, after the explicit paths."""


def model_search_paths(
    extra: Iterable[str | os.PathLike[str]] = (), environ: Mapping[str, str] | None = None
) -> tuple[Path, ...]:
    """The directories searched for `model://NAME`: `extra` first, then the environment variables.

    Each variable holds a `os.pathsep`-separated list; empty entries are skipped, duplicates kept once.
    """
    environ = os.environ if environ is None else environ
    paths: list[Path] = [Path(p).expanduser() for p in extra]
    for variable in MODEL_PATH_VARIABLES:
        paths.extend(Path(entry).expanduser() for entry in environ.get(variable, "").split(os.pathsep) if entry)
    unique: dict[Path, None] = dict.fromkeys(paths)
    return tuple(unique)


class UnresolvedURI(Exception):
    """A URI that names no existing file; `searched` lists the places that were tried."""

    def __init__(self, uri: str, searched: Sequence[Path], reason: str = "not found") -> None:
        self.uri = uri
        self.searched = tuple(searched)
        self.reason = reason
        super().__init__(uri)

    def describe(self) -> str:
        if not self.uri.startswith("model://"):
            return f"{shown(self.uri, PATH_CHARACTERS)}: {self.reason}"
        places = ", ".join(str(p) for p in self.searched) if self.searched else "(no folders: no model path is set)"
        return f"{shown(self.uri, PATH_CHARACTERS)}: {self.reason}; searched, in order: {places}. {MODEL_PATH_HINT}"


MODEL_PATH_HINT = (
    "Add the folder that holds the model to the model path: `ddenv ... --model-path DIRS` or pytest's "
    f"`--ddenv-model-path DIRS` (folders separated by '{os.pathsep}'), or the environment variable "
    f"{' / '.join(MODEL_PATH_VARIABLES)}"
)


def is_remote(uri: str) -> bool:
    return urlparse(uri).scheme.lower() in ("http", "https", "ftp")


def resolve_uri(uri: str, base_dir: Path | None, search_paths: Sequence[Path]) -> Path:
    """The local path a URI names: `model://NAME/rest` through `search_paths`, `file://` and plain paths
    (relative ones against `base_dir`). Remote URIs are never fetched. Raises UnresolvedURI."""
    uri = uri.strip()
    if is_remote(uri):
        raise UnresolvedURI(uri, (), "remote URIs are not fetched (no network access); download the model and "
                                     "add its folder to the model path (--model-path, --ddenv-model-path or "
                                     "GAZEBO_MODEL_PATH)")
    if uri.startswith("model://"):
        rest = uri[len("model://"):].strip("/")
        if not rest:
            raise UnresolvedURI(uri, (), "a model:// URI needs a model name")
        candidates = [directory / rest for directory in search_paths]
        for candidate in candidates:
            if exists(candidate):
                return candidate
        raise UnresolvedURI(uri, tuple(search_paths), "model not found")
    if uri.startswith("file://"):
        path = Path(unquote(urlparse(uri).path))
    else:
        path = Path(uri).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    if not exists(path):
        raise UnresolvedURI(uri, (), f"file not found: {shown_path(path)}")
    return path
