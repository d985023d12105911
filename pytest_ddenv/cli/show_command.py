"""`ddenv show`: a world drawn, with the runs of a `ddenv run --record` file or the failure poses of a run log,
and optionally an animation of one run."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv.cli.console import EXIT_OK, emit
from pytest_ddenv.cli.output import check_matplotlib_backend, check_output, world_stem, write_gif
from pytest_ddenv.cli.world_options import UsageError, dropped_models, load_world
from pytest_ddenv.errors import DdenvError

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World


def cmd_show(arguments: argparse.Namespace) -> int:
    from pytest_ddenv import render

    check_output("--output", arguments.output, ".png")
    if arguments.animate:
        check_output("--animate", arguments.animate, ".gif")
    check_matplotlib_backend()
    world = load_world(arguments, arguments.world)
    runs, poses, outcomes = _read_runs(Path(arguments.runs)) if arguments.runs else ([], [], [])
    target = arguments.output or f"{world_stem(arguments.world)}.png"
    picture = render.plot_world(world, runs, path=target, failure_poses=poses, failure_outcomes=outcomes,
                                robot_footprint=_robot_footprint(world) if poses and not runs else None)
    text = f"wrote {picture} ({len(world)} models, {len(runs)} runs, {len(poses)} failure poses)"
    data: dict[str, Any] = {"ok": True, "picture": str(picture), "models": len(world), "runs": len(runs),
                            "failure_poses": len(poses), "dropped": dropped_models(world)}
    if arguments.animate is not None:
        if world.scenario is None:
            raise UsageError(f"{arguments.world}: --animate needs a scenario (a robot to follow); add one with "
                             "--robot/--start/--goal")
        run = runs[0] if runs else _simulated_run(world)
        animation = write_gif(arguments.animate or f"{world_stem(arguments.world)}.gif", world, run,
                              "recorded run" if runs else "seed 0")
        text += f"\nwrote {animation.path} ({animation.frames} frames, {animation.size_bytes // 1024} KB)"
        data["animation"] = animation.to_dict()
    emit(arguments, text, data)
    return EXIT_OK


def _simulated_run(world: World) -> Run:
    from pytest_ddenv.detail import recording_detail
    from pytest_ddenv.driver.scenario_job import run_scenario

    with recording_detail():
        return run_scenario(world, (), seed=0)


def _robot_footprint(world: World) -> tuple[float, float] | None:
    """The (length, width) of the world's own robot, for failure poses drawn without a run (None: unknown)."""
    if world.scenario is None:
        return None
    from pytest_ddenv.sim.quiet import silenced
    from pytest_ddenv.sim.robot import make_robot

    try:
        with silenced():  # a URDF robot imports pybullet, which prints its build time on the C-level stdout
            return tuple(make_robot(world.scenario.robot, world.source).footprint)  # type: ignore[return-value]
    except DdenvError:  # a robot this process does not know (registered by the user's code)
        return None


def _read_runs(path: Path) -> tuple[list[Run], list[list[float]], list[str]]:
    """Runs (`ddenv run --record` lines), failure poses (probe-log lines) and each pose's outcome ("fail":
    the same failure as the reduced one, "other": another failure) of a JSON-lines file."""
    from pytest_ddenv.reduce import events
    from pytest_ddenv.reduce.log import numbered_records
    from pytest_ddenv.reduce.records import MAX_JSON_NESTING
    from pytest_ddenv.sim import Run

    if path.exists() and not path.is_file():
        raise UsageError(f"{path}: not a runs file: {'a folder' if path.is_dir() else 'a pipe or a device'}")
    if not path.is_file():
        raise UsageError(f"{path}: no such runs file")
    runs: list[Run] = []
    poses: list[list[float]] = []
    outcomes: list[str] = []
    for number, record in numbered_records(path):
        if record is None:
            raise UsageError(f"{path}:{number}: not a JSON line (damaged, or nested more than {MAX_JSON_NESTING} "
                             "deep)")
        if "poses" in record:
            try:
                runs.append(Run.from_dict(record))
            except (KeyError, TypeError, ValueError) as error:
                raise UsageError(f"{path}:{number}: not a recorded run ({error})") from None
        elif isinstance(probe := events.from_json(record), events.Probe):
            pose = (probe.signature or {}).get("pose")
            if isinstance(pose, list) and len(pose) >= 3:
                poses.append([float(v) for v in pose])
                outcomes.append("other" if probe.outcome == "other" else "fail")
    if not runs and not poses:
        raise UsageError(f"{path}: no runs and no failure poses in this file")
    return runs, poses, outcomes
