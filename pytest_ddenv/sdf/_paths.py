"""Where Gazebo models live: `model://` and file URIs resolved through the user's model paths."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from urllib.parse import unquote, urlparse

from pytest_ddenv.errors import PATH_CHARACTERS, shown, shown_path
from pytest_ddenv.sdf._fuel import FuelModelMissing, FuelUri, parse_fuel_uri, resolve_fuel
from pytest_ddenv.world.files import exists

MODEL_PATH_VARIABLES = ("GAZEBO_MODEL_PATH", "GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "SDF_PATH")
"""Environment variables searched for `model://` URIs, in this order, after the explicit paths."""
RESOURCE_PATH_VARIABLE = "GAZEBO_RESOURCE_PATH"
"""Gazebo-classic's resource folders (`/usr/share/gazebo-11` holds `media/`), searched for relative `file://` URIs
(`file://media/materials/textures/grass.png`) after the world file's folder and before the model path."""


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

    def __init__(self, uri: str, searched: Sequence[Path], reason: str = "not found", *, hint: bool = True,
                 fuel: FuelUri | None = None, remote: bool = False) -> None:
        self.uri = uri
        self.searched = tuple(searched)
        self.reason = reason
        self.hint = hint  # whether adding a folder to the model path may help
        self.fuel = fuel  # a Fuel model that is not here
        self.remote = remote or fuel is not None  # a remote URI: what it names is not here (never fetched)
        super().__init__(uri)

    def describe(self) -> str:
        uri = shown(self.uri, PATH_CHARACTERS)
        if not self.hint:
            return f"{uri}: {self.reason}"
        places = ", ".join(str(p) for p in self.searched) if self.searched else "(no folders: no model path is set)"
        return f"{uri}: {self.reason}; searched, in order: {places}. {MODEL_PATH_HINT}"


MODEL_PATH_HINT = (
    "Add the folder that holds the model to the model path: `ddenv ... --model-path DIRS` or pytest's "
    f"`--ddenv-model-path DIRS` (folders separated by '{os.pathsep}'), or the environment variable "
    f"{' / '.join(MODEL_PATH_VARIABLES)}"
)


def is_remote(uri: str) -> bool:
    return urlparse(uri).scheme.lower() in ("http", "https", "ftp")


def resolve_uri(uri: str, base_dir: Path | None, search_paths: Sequence[Path]) -> Path:
    """The local path a URI names: `model://NAME/rest` through `search_paths`, a Gazebo Fuel URL through the
    local Fuel cache (then `search_paths` by the model's name), `file://` and plain paths (relative ones against
    `base_dir`, then through `search_paths`, as Gazebo finds `<uri>x500</uri>` on its resource path). Remote
    files are never fetched. Raises UnresolvedURI."""
    uri = uri.strip()
    if is_remote(uri):
        fuel = parse_fuel_uri(uri)
        if fuel is None:
            raise UnresolvedURI(uri, (), f"{shown(uri, PATH_CHARACTERS)} is not a Gazebo Fuel model URL; remote "
                                "files are never downloaded: download it and name it by its local path", hint=False,
                                remote=True)
        try:
            return resolve_fuel(fuel, search_paths)
        except FuelModelMissing as missing:
            raise UnresolvedURI(uri, (), missing.describe(), hint=False, fuel=fuel) from None
    if uri.startswith("model://"):
        return _model_file(uri, search_paths)
    if uri.startswith("file://"):
        rest = unquote(uri[len("file://"):])
        rest = rest[len("localhost"):] if rest.startswith("localhost/") else rest
        if not rest.startswith("/"):  # file://media/...: Gazebo-classic's form, relative to its resource folders
            return _relative_file(uri, Path(rest), base_dir, search_paths)
        path = Path(rest)
    else:
        path = Path(uri).expanduser()
        if not path.is_absolute():
            return _relative_path(uri, path, base_dir, search_paths)
    if not exists(path):
        raise UnresolvedURI(uri, (), f"file not found: {shown_path(path)}", hint=False)
    return path


def _relative_path(uri: str, relative: Path, base_dir: Path | None, search_paths: Sequence[Path]) -> Path:
    """A plain relative path: in the including file's folder, then in each folder of the model path."""
    folders = tuple(dict.fromkeys([base_dir if base_dir is not None else Path.cwd(), *search_paths]))
    for folder in folders:
        if exists(folder / relative):
            return folder / relative
    raise UnresolvedURI(uri, folders, "not found")


def _model_file(uri: str, search_paths: Sequence[Path]) -> Path:
    """`model://NAME/rest` through `search_paths`; when NAME is found but not `rest`, says where NAME is."""
    rest = uri[len("model://"):].strip("/")
    if not rest:
        raise UnresolvedURI(uri, (), "a model:// URI needs a model name", hint=False)
    for directory in search_paths:
        if exists(directory / rest):
            return directory / rest
    name, _, inside = rest.partition("/")
    for directory in search_paths:
        if inside and exists(directory / name):
            raise UnresolvedURI(uri, tuple(search_paths), f"model '{name}' was found at {shown_path(directory / name)}"
                                f", but it has no file {shown(inside, PATH_CHARACTERS)}", hint=False)
    raise UnresolvedURI(uri, tuple(search_paths), "model not found")


def resource_search_paths(environ: Mapping[str, str] | None = None) -> tuple[Path, ...]:
    """The folders of GAZEBO_RESOURCE_PATH (`os.pathsep`-separated; empty entries skipped)."""
    environ = os.environ if environ is None else environ
    entries = environ.get(RESOURCE_PATH_VARIABLE, "").split(os.pathsep)
    return tuple(Path(entry).expanduser() for entry in entries if entry)


def _relative_file(uri: str, relative: Path, base_dir: Path | None, search_paths: Sequence[Path]) -> Path:
    """A relative `file://` URI: in the world file's folder, then GAZEBO_RESOURCE_PATH, then the model path."""
    folders = tuple(dict.fromkeys([*([base_dir] if base_dir is not None else []), *resource_search_paths(),
                                   *search_paths]))
    for folder in folders:
        if exists(folder / relative):
            return folder / relative
    places = ", ".join(str(folder) for folder in folders) or "(no folders)"
    holder = shown(f"{relative.parts[0] if relative.parts else relative}/", PATH_CHARACTERS)
    raise UnresolvedURI(uri, folders, f"file not found; searched, in order: {places}. Add the folder that holds "
                        f"{holder} to {RESOURCE_PATH_VARIABLE} or to the model path (--model-path, --ddenv-model-path)",
                        hint=False)
