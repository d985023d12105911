"""The `ddenv` options that say how to read a world: where `model://` includes are found (`--model-path`),
what to do with models that cannot be simulated (`--skip-unsupported`), and a scenario given on the command
line (`--robot`, `--start`, `--goal`, `--timeout`, `--scenario FILE.yaml`) for worlds without one, such as
Gazebo worlds."""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
from pathlib import Path

from pytest_ddenv.driver.settings import SETTING
from pytest_ddenv.errors import DdenvError, shown, shown_path
from pytest_ddenv.world.files import MISSING, dangling_link, file_kind, resolve_relative
from pytest_ddenv.world.model import Pose, RobotDescription, Scenario, World

NO_SCENARIO_HELP = (
    "give one with --start X,Y[,YAW] --goal X,Y [--robot NAME] [--timeout S], or --scenario FILE.yaml (a "
    "'scenario:' block as in a world file), or add it to the world file (a <ddenv:scenario> element in SDF: "
    "see docs/sdf.md)"
)


class UsageError(DdenvError):
    """The command line is wrong: a bad option value, an unknown model, a missing file."""


WORLD_SETTINGS = ("model_paths", "skip_unsupported")
"""The settings (`driver/settings.py`) every command that reads a world takes: --model-path, --skip-unsupported."""


def add_world_options(parser: argparse.ArgumentParser) -> None:
    """--model-path (repeatable, before GAZEBO_MODEL_PATH and the other environment variables) and
    --skip-unsupported (every command that reads a world)."""
    model_paths, skip = (SETTING[name] for name in WORLD_SETTINGS)
    parser.add_argument(model_paths.flag_name, dest=model_paths.name, action="append", default=[],
                        metavar=model_paths.metavar, help=f"{model_paths.help}; repeatable")
    parser.add_argument(skip.flag_name, dest=skip.name, action="store_true", help=skip.help)


def add_scenario_options(parser: argparse.ArgumentParser) -> None:
    """--robot, --start, --goal, --scenario (commands that simulate; --timeout is theirs already)."""
    parser.add_argument("--scenario", metavar="FILE.yaml",
                        help="take the scenario from this YAML file's 'scenario:' block (overrides the world's)")
    parser.add_argument("--robot", metavar="NAME", help="the scenario's robot (a registered name, default husky)")
    parser.add_argument("--start", metavar="X,Y[,YAW]", help="the robot's start (m, m, rad)")
    parser.add_argument("--goal", metavar="X,Y[,Z]", help="the goal (m)")


def dropped_models(world: World) -> list[str]:
    """What `skip_unsupported` dropped from `world`: one line per model (its name, the element and why)."""
    return [note.removeprefix("dropped ") for note in world.notes if note.startswith("dropped ")]


def dropped_warning(world: World, where: str) -> str | None:
    """One line naming each model that `skip_unsupported` dropped from `world` (read from `where`); None when
    nothing was dropped."""
    dropped = dropped_models(world)
    if not dropped:
        return None
    count = f"{len(dropped)} model{'s' if len(dropped) != 1 else ''}"
    return f"{where}: skip_unsupported dropped {count} that cannot be simulated: {'; '.join(dropped)}"


def load_world(arguments: argparse.Namespace, path: str, *, warn: bool = True) -> World:
    """The world file at `path`, read with the command's --model-path and --skip-unsupported, in its --engine
    (run, reduce); with `warn`, one warning line on stderr naming the models --skip-unsupported dropped."""
    file = Path(path)
    kind = file_kind(file)
    if kind == MISSING:
        raise UsageError(f"{shown_path(path)}: no such world file{dangling_link(file)}")
    if kind == "a folder":
        raise UsageError(f"{shown_path(path)}: is a folder, not a world file")
    folders = [os.path.expanduser(folder) for value in getattr(arguments, "model_paths", [])
               for folder in value.split(os.pathsep) if folder]
    for folder in folders:
        if not Path(folder).is_dir():
            raise UsageError(f"--model-path: no such folder: {folder}")
    world = World.load(file, model_paths=folders, skip_unsupported=getattr(arguments, "skip_unsupported", False))
    engine = getattr(arguments, "engine", None)  # --engine of run and reduce (checked by argparse)
    if engine is not None:
        world = world.with_engine(engine)
    warning = dropped_warning(world, path) if warn else None
    if warning is not None:
        print(f"ddenv: warning: {warning}", file=sys.stderr)
    return world


def same_file(first: Path, second: Path) -> bool:
    """Whether two paths name the same file (False when either cannot be resolved: a loop of symbolic links,
    whose reader or writer then says so)."""
    try:
        return first.resolve() == second.resolve()
    except (OSError, RuntimeError):
        return False


def check_robot(world: World) -> None:
    """The robot of `world`'s scenario built as a run builds it, when the world file describes it by its URDF
    (`sim.robot.check_robot`): a URDF pybullet cannot load or without a wheel joint raises `ScenarioError`
    naming the file and the field. A registered robot's name is not checked: its registration is the user's
    code (`ddenv run --import`)."""
    if world.scenario is not None:
        from pytest_ddenv.sim.robot import check_robot as check_scenario_robot

        check_scenario_robot(world.scenario.robot, world.source)


def with_scenario(arguments: argparse.Namespace, world: World, path: str) -> World:
    """`world` with the scenario the command line gives (a --scenario file, then --robot/--start/--goal/
    --timeout on top); UsageError when it still has none."""
    scenario = world.scenario
    if getattr(arguments, "scenario", None):
        scenario = _scenario_file(arguments.scenario)
    overrides = {name: getattr(arguments, name, None) for name in ("robot", "start", "goal")}
    if scenario is None:
        if overrides["start"] is None or overrides["goal"] is None:
            given = [f"--{name}" for name, value in overrides.items() if value is not None]
            missing = "" if not given else f" ({' and '.join(given)} alone is not enough: give --start and --goal)"
            raise UsageError(f"{path}: the world has no scenario (robot, start, goal, timeout){missing}; "
                                   f"{NO_SCENARIO_HELP}")
        scenario = Scenario(timeout=getattr(arguments, "timeout", None) or Scenario().timeout)
    if overrides["robot"] is not None:
        scenario = dataclasses.replace(scenario, robot=overrides["robot"])
    if overrides["start"] is not None:
        x, y, *yaw = _numbers(overrides["start"], "--start", (2, 3))
        scenario = dataclasses.replace(scenario, start=Pose(x=x, y=y, yaw=yaw[0] if yaw else 0.0), start_z_given=False)
    if overrides["goal"] is not None:
        x, y, *z = _numbers(overrides["goal"], "--goal", (2, 3))
        scenario = dataclasses.replace(scenario, goal=(x, y, z[0] if z else None))
    if getattr(arguments, "timeout", None) is not None:
        scenario = dataclasses.replace(scenario, timeout=arguments.timeout)
    return world if scenario is world.scenario else dataclasses.replace(world, scenario=scenario)


def _scenario_file(path: str) -> Scenario:
    file = Path(path)
    kind = file_kind(file)
    if kind == MISSING:
        raise UsageError(f"--scenario {shown_path(path)}: no such file{dangling_link(file)}")
    if kind is not None:
        raise UsageError(f"--scenario {shown_path(path)}: {kind}, not a file")
    holder = World.load(file)
    if holder.scenario is None:
        raise UsageError(f"--scenario {path}: the file has no 'scenario:' block")
    if len(holder):
        raise UsageError(f"--scenario {path}: the file has models; give only a 'scenario:' block")
    robot = holder.scenario.robot
    if isinstance(robot, RobotDescription):  # its URDF is relative to the scenario file, not to the world
        robot = dataclasses.replace(robot, urdf=str(resolve_relative(robot.urdf, str(file)).resolve()))
    return dataclasses.replace(holder.scenario, robot=robot)


def _numbers(text: str, option: str, counts: tuple[int, ...]) -> list[float]:
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in counts or not all(math.isfinite(v) for v in values):
        form = "X,Y[,YAW]" if option == "--start" else "X,Y[,Z]"
        raise UsageError(f"{option}: expected {form} (numbers separated by commas), got {shown(text)}")
    return values
