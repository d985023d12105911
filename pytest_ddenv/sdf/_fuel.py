"""Gazebo Fuel URIs read from this machine: the Fuel cache that `gz fuel download` (and Gazebo itself) fills,
or the model path by the model's name. Nothing is downloaded.

The cache is laid out as Gazebo's fuel tools write it: `<cache>/<server>/<owner>/models/<name>/<version>/`,
owner and name lowercased (older fuel tools kept their case; both are found), one folder per version number.
The cache is `$GZ_FUEL_CACHE_PATH` (or `$IGN_FUEL_CACHE_PATH`) when set, else `~/.gz/fuel` and the older
`~/.ignition/fuel`. A URI without a version (or with `tip`) takes the highest version there.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlparse

from pytest_ddenv.errors import PATH_CHARACTERS, shown
from pytest_ddenv.world.files import exists

FUEL_CACHE_VARIABLES = ("GZ_FUEL_CACHE_PATH", "IGN_FUEL_CACHE_PATH")
"""Environment variables that name the Fuel cache folder (instead of the default ones)."""
DEFAULT_CACHES = ("~/.gz/fuel", "~/.ignition/fuel")
SAME_SERVERS = ("fuel.gazebosim.org", "fuel.ignitionrobotics.org")
"""Fuel's two names: a model cached under one is the model of a URI naming the other."""
_API_VERSION = re.compile(r"\d+(\.\d+)*")


@dataclass(frozen=True)
class FuelUri:
    """A Fuel model URL (`https://SERVER/1.0/OWNER/models/NAME[/VERSION][/files/PATH]`), decoded."""

    uri: str
    scheme: str
    server: str
    owner: str
    name: str
    version: str  # "" or "tip": the highest one cached
    file: str  # a file inside the model ("" for the model itself)

    @property
    def model_url(self) -> str:
        """The model's URL as `gz fuel download -u` takes it (without version and file)."""
        return f"{self.scheme}://{self.server}/1.0/{self.owner}/models/{self.name}"

    @property
    def folder_names(self) -> tuple[str, ...]:
        """The names a folder of this model may have on the model path: as on Fuel, lowercased, snake_case."""
        snake = re.sub(r"\s+", "_", self.name.strip()).lower()
        return tuple(dict.fromkeys((self.name, self.name.lower(), snake)))


def parse_fuel_uri(uri: str) -> FuelUri | None:
    """The parts of a Fuel model URL, or None when `uri` is not one."""
    parsed = urlparse(uri.strip())
    if parsed.scheme.lower() not in ("http", "https") or not parsed.hostname:
        return None
    parts = [unquote(part) for part in parsed.path.split("/") if part]
    if parts and _API_VERSION.fullmatch(parts[0]):
        parts = parts[1:]
    if len(parts) < 3 or parts[1].lower() != "models" or not parts[0] or not parts[2]:
        return None
    owner, name, rest = parts[0], parts[2], parts[3:]
    version = ""
    if rest and (rest[0].isdigit() or rest[0].lower() == "tip"):
        version, rest = rest[0].lower(), rest[1:]
    if rest and rest[0] == "files":
        rest = rest[1:]
    return FuelUri(uri.strip(), parsed.scheme.lower(), parsed.hostname.lower(), owner, name, version, "/".join(rest))


def fuel_caches(environ: Mapping[str, str] | None = None) -> tuple[Path, ...]:
    """The Fuel cache folders searched, in order."""
    environ = os.environ if environ is None else environ
    given = [Path(environ[variable]) for variable in FUEL_CACHE_VARIABLES if environ.get(variable)]
    folders: list[Path] = []
    for folder in given or [Path(folder) for folder in DEFAULT_CACHES]:
        try:
            folders.append(folder.expanduser())
        except RuntimeError:  # no home folder to expand "~" to: no such cache
            continue
    return tuple(dict.fromkeys(folders))


class FuelModelMissing(Exception):
    """A Fuel model that is neither in the Fuel cache nor on the model path."""

    def __init__(self, fuel: FuelUri, caches: Sequence[Path], search_paths: Sequence[Path]) -> None:
        self.fuel = fuel
        self.caches = tuple(caches)
        self.search_paths = tuple(search_paths)
        super().__init__(fuel.uri)

    def describe(self) -> str:
        fuel = self.fuel
        version = fuel.version if fuel.version.isdigit() else "VERSION"
        layout = f"{fuel.server}/{fuel.owner.lower()}/models/{fuel.name.lower()}/{version}"
        cache = f"{', '.join(str(path) for path in self.caches)}: {shown(layout, PATH_CHARACTERS)[1:-1]}"
        names = " or ".join(shown(name, PATH_CHARACTERS) for name in dict.fromkeys(fuel.folder_names[::2]))
        paths = ", ".join(str(path) for path in self.search_paths) or "none set"
        pinned = f" version {fuel.version}" if fuel.version.isdigit() else ""
        return (f"Gazebo Fuel model {fuel.owner}/{fuel.name}{pinned} is not here: not in the Fuel cache "
                f"({cache}) nor on the model path ({paths}) as a folder {names}; get it with: gz fuel download -u "
                f"{shown(fuel.model_url, PATH_CHARACTERS)}")


def resolve_fuel(fuel: FuelUri, search_paths: Sequence[Path], environ: Mapping[str, str] | None = None) -> Path:
    """The local folder (or file) of a Fuel URI: the cache's version folder, else a model path folder named after
    the model. Raises FuelModelMissing."""
    caches = fuel_caches(environ)
    servers = SAME_SERVERS if fuel.server in SAME_SERVERS else (fuel.server,)
    for cache in caches:
        for server in servers:
            models = cache / server / fuel.owner.lower() / "models"
            folder = _version_folder(_entry(models, fuel.name), fuel.version)
            if folder is not None:
                return folder / fuel.file if fuel.file else folder
    for directory in search_paths:
        for name in fuel.folder_names:
            if exists(directory / name):
                return directory / name / fuel.file if fuel.file else directory / name
    raise FuelModelMissing(fuel, caches, search_paths)


def _entry(folder: Path, name: str) -> Path | None:
    """The entry of `folder` named `name`, its case and URL-encoding aside (fuel tools lowercase names)."""
    wanted = name.casefold()
    try:
        entries = sorted(folder.iterdir()) if folder.is_dir() else []
    except OSError:
        return None
    return next((entry for entry in entries if unquote(entry.name).casefold() == wanted), None)


def _version_folder(model: Path | None, version: str) -> Path | None:
    """The folder of `version` (a number), or of the highest version ("" or "tip")."""
    if model is None:
        return None
    try:
        numbered = {int(entry.name): entry for entry in model.iterdir() if entry.name.isdigit() and entry.is_dir()}
    except OSError:
        return None
    if version.isdigit():
        return numbered.get(int(version))
    return numbered[max(numbered)] if numbered else None
