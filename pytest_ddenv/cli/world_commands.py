"""`ddenv check` (a world file read and its models reported, or the first error) and `ddenv convert` (a world
file written in another format: ddenv YAML, Gazebo SDF; MuJoCo MJCF is read only)."""

from __future__ import annotations

import argparse
from pathlib import Path

from pytest_ddenv.cli.console import EXIT_OK, emit
from pytest_ddenv.cli.world_options import UsageError, check_robot, dropped_models, load_world, same_file
from pytest_ddenv.world.formats import MJCF_SUFFIXES, SDF_SUFFIXES, YAML_SUFFIXES  # MJCF: read only


def cmd_check(arguments: argparse.Namespace) -> int:
    world = load_world(arguments, arguments.world, warn=False)  # its notes say what was dropped
    check_robot(world)
    count = len(world)
    text = f"{arguments.world}: {count} model{'s' if count != 1 else ''} ({len(world.reducible_names)} reducible)"
    text += "".join(f"\nnot simulated: {note}" for note in world.notes)
    emit(arguments, text, {"ok": True, "world": arguments.world, "models": len(world),
                           "reducible": len(world.reducible_names), "names": list(world.names),
                           "notes": list(world.notes)})
    return EXIT_OK


def cmd_convert(arguments: argparse.Namespace) -> int:
    source, target = Path(arguments.input), Path(arguments.output)
    for path, role in ((source, "input"), (target, "output")):
        if path.suffix.lower() not in (*YAML_SUFFIXES, *SDF_SUFFIXES, *(MJCF_SUFFIXES if role == "input" else ())):
            mjcf = ", .xml/.mjcf (MuJoCo MJCF)" if role == "input" else ""
            raise UsageError(f"{path}: unknown {role} format {path.suffix or '(no extension)'!r}; "
                             f"use .yaml/.yml (ddenv YAML){mjcf} or .sdf/.world (Gazebo SDF)")
    if same_file(source, target):
        raise UsageError(f"{target}: the output would overwrite the input")
    world = load_world(arguments, arguments.input)
    try:
        world.save(target)
    except ImportError:
        raise UsageError("SDF export is not available in this version of pytest-ddenv") from None
    text = f"wrote {target} ({len(world)} models) from {source}"
    emit(arguments, text, {"ok": True, "input": str(source), "output": str(target), "models": len(world),
                           "dropped": dropped_models(world)})
    return EXIT_OK
