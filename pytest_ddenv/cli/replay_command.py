"""`ddenv replay` on the command line: the user's code the reduction recorded loaded, the minimal world of an
artifacts folder re-run (`cli/replay.py`), each run reported, and optionally an animation of one."""

from __future__ import annotations

import argparse
from pathlib import Path

from pytest_ddenv.cli.console import EXIT_FAILED, EXIT_OK, emit
from pytest_ddenv.cli.output import check_output, write_gif
from pytest_ddenv.cli.predicates import parsed_predicates
from pytest_ddenv.cli.user_code import load_user_code, same_failure_rule


def cmd_replay(arguments: argparse.Namespace) -> int:
    from pytest_ddenv.cli.replay import read_artifacts, replay, summary_field
    from pytest_ddenv.outcome import Outcome

    if not arguments.imports and not arguments.controller:  # what the reduction itself used, if recorded
        folder = Path(arguments.artifacts)
        summary, _ = read_artifacts(folder)
        where = folder / "summary.json"
        arguments.imports = summary_field(summary, "imports", where, "a list of module names or files",
                                          lambda value: isinstance(value, list)
                                          and all(isinstance(item, str) for item in value), [])
        arguments.controller = summary_field(summary, "controller", where, "MODULE:ATTRIBUTE or null",
                                             lambda value: value is None or isinstance(value, str), None)
    if arguments.animate:
        check_output("--animate", arguments.animate, ".gif")
    controller = load_user_code(arguments)
    predicates = parsed_predicates(arguments.predicates) or None
    from pytest_ddenv.detail import recording_detail

    with recording_detail(arguments.animate is not None):
        rule = None if arguments.same_failure is None else same_failure_rule(arguments.same_failure)
        result = replay(arguments.artifacts, predicates=predicates, max_runs=arguments.runs,
                        tolerance=arguments.tolerance, controller=controller, recorded=arguments.recorded,
                        engine=arguments.engine, run_timeout=arguments.run_timeout, same_failure=rule)
    reference = result.reference
    lines = [(f"{arguments.artifacts}: minimal world of {len(result.world)} models in "
              f"{result.world.physics.engine}; reference failure: "
             f"{reference.predicate} at t = {reference.time:.2f} s at ({reference.position[0]:.2f}, "
             f"{reference.position[1]:.2f}, {reference.position[2]:.2f}) m")]
    for run in result.runs:
        what = "no failure" if run.failure is None else f"{run.failure.predicate} at t = {run.failure.time:.2f} s"
        what = f"raised {run.raised}" if run.raised else what
        lines.append(f"  seed {run.seed}: {run.outcome.value} ({what})" + (f": {run.why}" if run.why else ""))
    lines.append(result.describe())
    data = result.to_dict()
    shown = [run for run in result.runs if run.run is not None]
    if arguments.animate is not None and shown:
        chosen = next((run for run in shown if run.outcome is Outcome.FAIL), shown[0])
        assert chosen.run is not None
        animation = write_gif(arguments.animate or str(Path(arguments.artifacts) / "replay.gif"), result.world,
                              chosen.run, f"replay seed {chosen.seed}")
        lines.append(f"wrote {animation.path} (seed {chosen.seed}, {animation.frames} frames)")
        data["animation"] = animation.to_dict()
    emit(arguments, "\n".join(lines), data)
    return EXIT_OK if result.ok else EXIT_FAILED
