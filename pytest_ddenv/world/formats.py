"""World files by format: ddenv YAML (`yaml_format`), Gazebo SDF (`pytest_ddenv.sdf`) and MuJoCo MJCF
(`pytest_ddenv.mjcf`, read only: a reduction cuts `minimal.xml` from the scene), chosen by a file's
suffix. The only module that knows the formats: `World.load`, `World.save`, `World.from_*` and `World.to_*`
reach it through `model.use_world_files`, installed when `pytest_ddenv.world` is imported, and a format's
module is imported when a world is first read or written in it.

A new format: a module that reads a file into a `World` and writes one as text, and its `WorldFormat` in
`FORMATS`.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from pytest_ddenv.errors import WorldError, shown_path
from pytest_ddenv.world.files import MISSING, file_kind
from pytest_ddenv.world.model import World, use_world_files
from pytest_ddenv.world.values import check_world_values

YAML_SUFFIXES = (".yaml", ".yml")
SDF_SUFFIXES = (".sdf", ".world")
MJCF_SUFFIXES = (".xml", ".mjcf")
PathLike = str | os.PathLike[str]


@dataclass(frozen=True)
class WorldFormat:
    """A world file format: its suffixes, how it reads a file and how it writes a world as text."""

    title: str
    """As the errors name it."""
    suffixes: tuple[str, ...]
    load: Callable[[Path, Sequence[PathLike], bool], World]
    """The world in a file (the folders searched for `model://` includes; whether the models that cannot be
    simulated are dropped)."""
    dump: Callable[[World, Path | None], str]
    """A world as text, its relative file paths from the folder given."""
    parse: Callable[[str, PathLike | None], World] | None = None
    """The world in a text (what names it in errors); None: the format reads files only."""
    writes: bool = True
    """Whether `World.save` writes it (MJCF is read only: its `dump` says why)."""


def _load_yaml(path: Path, model_paths: Sequence[PathLike], skip_unsupported: bool) -> World:
    from pytest_ddenv.world.yaml_format import load_yaml

    return load_yaml(path)


def _parse_yaml(text: str, source: PathLike | None) -> World:
    from pytest_ddenv.world.yaml_format import parse_yaml

    return parse_yaml(text, source=source)


def _dump_yaml(world: World, relative_to: Path | None) -> str:
    from pytest_ddenv.world.yaml_format import dump_yaml

    return dump_yaml(world, relative_to)


def _load_sdf(path: Path, model_paths: Sequence[PathLike], skip_unsupported: bool) -> World:
    """As Gazebo simulates it (see docs/sdf.md); its values must be within what the simulator takes."""
    from pytest_ddenv.sdf import load_sdf

    world = load_sdf(path, model_paths=[Path(folder) for folder in model_paths], skip_unsupported=skip_unsupported)
    check_world_values(world)
    return world


def _dump_sdf(world: World, relative_to: Path | None) -> str:
    from pytest_ddenv.sdf import dump_sdf

    return dump_sdf(world)


def _load_mjcf(path: Path, model_paths: Sequence[PathLike], skip_unsupported: bool) -> World:
    """As MuJoCo reads it (see docs/mjcf.md); needs mujoco."""
    from pytest_ddenv.mjcf import load_mjcf

    world = load_mjcf(path, skip_unsupported=skip_unsupported)
    check_world_values(world)
    return world


def _dump_mjcf(world: World, relative_to: Path | None) -> str:
    raise WorldError("writing a world as MJCF is not supported (a reduction of an MJCF scene writes minimal.xml, "
                     "cut from the scene); save it as .yaml or .sdf")


FORMATS = {
    "yaml": WorldFormat("ddenv YAML", YAML_SUFFIXES, _load_yaml, _dump_yaml, _parse_yaml),
    "sdf": WorldFormat("Gazebo SDF", SDF_SUFFIXES, _load_sdf, _dump_sdf),
    "mjcf": WorldFormat("MuJoCo MJCF", MJCF_SUFFIXES, _load_mjcf, _dump_mjcf, writes=False),
}
READ_AS = "yaml"
"""How a file is read whose suffix is none of the formats'."""


def format_of(path: Path) -> str | None:
    """The name in `FORMATS` of the format whose suffix `path` has, or None."""
    suffix = path.suffix.lower()
    return next((name for name, known in FORMATS.items() if suffix in known.suffixes), None)


class WorldFiles:
    """`World`'s files in the `FORMATS` (`model.WorldFiles`)."""

    def load(self, path: Path, format_name: str | None, model_paths: Sequence[PathLike],
             skip_unsupported: bool) -> World:
        return FORMATS[format_name or format_of(path) or READ_AS].load(path, model_paths, skip_unsupported)

    def parse(self, text: str, format_name: str, source: PathLike | None) -> World:
        parse = FORMATS[format_name].parse
        assert parse is not None, f"{format_name} reads files only"
        return parse(text, source)

    def dump(self, world: World, format_name: str, relative_to: Path | None) -> str:
        return FORMATS[format_name].dump(world, relative_to)

    def save(self, world: World, path: Path) -> None:
        """Atomically (write then rename); nothing is left behind when it fails."""
        format_name = format_of(path)
        if format_name is None:
            named = ", or ".join(f"{' or '.join(known.suffixes)} ({known.title})" for known in FORMATS.values()
                                 if known.writes)
            raise WorldError(f"unknown world file extension {path.suffix.lower() or '(none)'!r}; name it {named}",
                             source=path)
        check_world_values(world)
        kind = file_kind(path)
        if kind is not None and kind != MISSING:  # a folder, a device, a FIFO: never replaced by the file
            raise WorldError(f"is {kind}, not a world file; give the world file's name", source=path)
        text = FORMATS[format_name].dump(world, path.parent)
        temporary = path.with_name(f".{path.name}.tmp{os.getpid()}")
        try:
            temporary.write_text(text, encoding="utf-8")
            os.replace(temporary, path)
        except OSError as error:
            with contextlib.suppress(OSError):
                temporary.unlink()
            problem = error.strerror or str(error)
            if isinstance(error, FileNotFoundError) and not path.parent.is_dir():
                problem = f"the folder {shown_path(path.parent)} does not exist"
            raise WorldError(f"cannot write the world file: {problem}", source=path) from None


use_world_files(WorldFiles())
