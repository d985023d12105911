"""`ddenv run`: a world's scenario simulated once, with the predicates and the controller given, reported (a
picture, a recorded run) and said to pass (the goal reached) or fail."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

from pytest_ddenv.cli.console import EXIT_FAILED, EXIT_OK, emit
from pytest_ddenv.cli.output import appended, check_matplotlib_backend, check_output, check_record, world_stem
from pytest_ddenv.cli.predicates import check_named_models, parsed_predicates
from pytest_ddenv.cli.user_code import load_user_code
from pytest_ddenv.cli.world_options import dropped_models, load_world, with_scenario
from pytest_ddenv.errors import raised_by_ddenv

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World


def cmd_run(arguments: argparse.Namespace) -> int:
    from pytest_ddenv.driver.scenario_job import run_scenario

    if not arguments.no_picture:
        check_output("--output", arguments.output, ".png")
        check_matplotlib_backend()
    check_record(arguments.record)
    controller = load_user_code(arguments)
    world = with_scenario(arguments, load_world(arguments, arguments.world), arguments.world)
    predicates = parsed_predicates(arguments.predicates)
    check_named_models(predicates, world)
    try:
        run = run_scenario(world, predicates, seed=arguments.seed, timeout=arguments.timeout, controller=controller,
                           max_wall_time=arguments.run_timeout)
    except Exception as error:
        if raised_by_ddenv(error):
            raise
        return _run_raised(arguments, world, error)
    picture = None
    if not arguments.no_picture:
        from pytest_ddenv import render

        target = arguments.output or f"{world_stem(arguments.world)}-run.png"
        picture = render.plot_world(world, [run], path=target, title=f"{world_stem(arguments.world)}: "
                                    f"{len(world)} models, seed {arguments.seed}")
    if arguments.record:
        with appended("--record", arguments.record) as record:
            record.write(json.dumps(run.to_dict()) + "\n")
    passed = run.failure is None and run.reached_goal
    emit(arguments, _run_text(arguments.world, world, run, picture), {
        "ok": passed,
        "world": arguments.world,
        "models": len(world),
        "seed": run.seed,
        "outcome": run_outcome(run),
        "reached_goal": run.reached_goal,
        "goal_time": run.goal_time,
        "failure": None if run.failure is None else run.failure.to_dict(),
        "explanation": None if run.failure is None else run.failure.explain(),
        "touched": sorted(run.touched),
        "sim_time": run.sim_time,
        "wall_time": run.wall_time,
        "picture": None if picture is None else str(picture),
        "dropped": dropped_models(world),
    })
    return EXIT_OK if passed else EXIT_FAILED


RUN_TIMEOUT_HINT = "robot_world.run(max_wall_time=...), --ddenv-run-timeout"
"""How `ControllerTimeout` says to raise the limit in a test; `ddenv run` says `--run-timeout` instead."""


def _run_raised(arguments: argparse.Namespace, world: World, error: Exception) -> int:
    from dataclasses import replace

    from pytest_ddenv.scenario.probe import describe_error
    from pytest_ddenv.sim import ControllerTimeout

    info = describe_error(error, None)
    capped = isinstance(error, ControllerTimeout)  # the wall-clock cap: an error of the run, not a failure
    if capped:  # its hint names the pytest options: say ddenv's own
        info = replace(info, message=info.message.replace(RUN_TIMEOUT_HINT, "ddenv run --run-timeout SECONDS"))
    notes = "".join(f" {note}" for note in getattr(error, "__notes__", ()))
    verdict = "ERROR (the run went past its wall-clock cap:" if capped else "FAILED (the run raised"
    text = (f"{arguments.world}: {len(world)} models, seed {arguments.seed}: {verdict} "
            f"{info.type_name} at {info.location}: {info.message}){notes}")
    emit(arguments, text, {"ok": False, "world": arguments.world, "models": len(world), "seed": arguments.seed,
                           "outcome": "error" if capped else "raised", "exception": info.type_name,
                           "message": info.message,
                           "location": info.location, "dropped": dropped_models(world)})
    return EXIT_FAILED


def run_outcome(run: Run) -> str:
    """A run's "outcome" in the JSON of `ddenv run` and `ddenv reduce`."""
    if run.failure is not None:
        return "failed"
    return "reached_goal" if run.reached_goal else "goal_not_reached"


def _run_text(path: str, world: World, run: Run, picture: Path | None) -> str:
    head = f"{path}: {len(world)} models, seed {run.seed}: "
    if run.failure is not None:
        lines = [head + f"FAILED ({run.failure.predicate} at t = {run.failure.time:.2f} s)", run.failure.explain()]
    elif run.reached_goal:
        lines = [head + f"reached the goal at t = {run.goal_time or run.sim_time:.2f} s"]
    else:
        lines = [head + f"FAILED (the goal was not reached within {run.sim_time:.1f} s; no predicate fired)"]
    lines.append(f"simulated {run.sim_time:.1f} s in {run.wall_time:.2f} s wall ({run.engine} {run.engine_version})")
    if picture is not None:
        lines.append(f"picture: {picture}")
    return "\n".join(lines)
