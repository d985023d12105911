"""`ddenv reduce`'s command line as the driver's `ReductionPlan`: the artifacts folder, the reduction's settings,
the command that replays it, the `ddenv run` of a kept other failure, and the code under test."""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pytest_ddenv import defaults
from pytest_ddenv.cli.output import world_stem
from pytest_ddenv.oracle.predicates import PredicateSpec

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.driver.run import ReductionPlan
    from pytest_ddenv.world.model import World


def artifacts_folder(arguments: argparse.Namespace) -> Path:
    """--out, else ddenv-artifacts/ named by the world (the command's "test id") and the seed."""
    from pytest_ddenv.driver.artifacts import artifact_dir_name

    if arguments.out:
        return Path(arguments.out)
    return Path("ddenv-artifacts") / artifact_dir_name(world_stem(arguments.world), arguments.seed)


def reduction_plan(arguments: argparse.Namespace, world: World, original: Any, predicates: Sequence[PredicateSpec],
                   keep: tuple[str, ...], priority: str) -> ReductionPlan:
    """What `ddenv reduce` hands to the driver: the world, its failure on the pool (`original`), the settings, the
    folder, the replay commands and what identifies the problem (the settings, predicates and code under test)."""
    import dataclasses

    from pytest_ddenv.cli.replay import predicates_to_json
    from pytest_ddenv.driver.confirm import ConfirmationRun
    from pytest_ddenv.driver.markers import ReductionSpec
    from pytest_ddenv.driver.run import ReductionPlan
    from pytest_ddenv.oracle.verdict import FailureReference, classify_result

    spec = dataclasses.replace(
        ReductionSpec(), partition=arguments.partition, priority=priority, n_partitions=arguments.n_partitions,
        granularity=arguments.granularity, deflake=arguments.deflake, tolerance=arguments.tolerance,
        same_failure=arguments.same_failure_match, keep=keep,
        seed=arguments.seed, max_probes=arguments.max_probes, max_seconds=arguments.max_seconds,
        stages=arguments.stages, stage_probes=arguments.stage_probes, confirm_engines=arguments.confirm_engines,
    )
    folder = artifacts_folder(arguments)
    command = "ddenv " + " ".join(shlex.quote(a) for a in _command_line(arguments))
    settings = {key: value for key, value in spec.__dict__.items() if key != "world"}
    plan = ReductionPlan(
        world=world, test_id=f"ddenv reduce {arguments.world}", reference=FailureReference.of(original.error),
        reference_run=original.run, spec=spec, artifacts=folder,
        replay_command=f"ddenv replay {shlex.quote(str(folder))}" + "".join(
            f" --import {shlex.quote(spec_)}" for spec_ in arguments.imports) + (
            f" --controller {shlex.quote(arguments.controller)}" if arguments.controller else ""),
        fingerprint={**settings, "predicates": predicates_to_json(predicates), "timeout": arguments.timeout,
                     "controller": arguments.controller, "imports": list(arguments.imports)},
        code=_code_under_test(arguments), confirmed=True, media=arguments.media, keep_other=arguments.keep_other,
        other_replay=lambda world_file, seed: _other_replay(arguments, world_file, seed),
        model_paths=tuple(folder for value in arguments.model_paths for folder in value.split(os.pathsep) if folder),
        run_settings={"predicates": predicates_to_json(predicates), "timeout": arguments.timeout,
                       "scenario_seed": arguments.seed, "command": command, "controller": arguments.controller,
                       "imports": list(arguments.imports)},
    )
    verdict = classify_result(original.error, plan.reference, plan.rule).value  # the run the failure came from
    return dataclasses.replace(plan, confirmations=(ConfirmationRun(0, original, verdict),))


TEST_FILES = ("test_*.py", "*_test.py")
"""pytest's default `python_files`: test files beside a controller are not scripts it runs."""


def _code_under_test(arguments: argparse.Namespace) -> Any:
    """The code under test of `ddenv reduce`: the modules loaded from the current folder and from the folders of
    the --import and --controller files (all imported by now), with those files themselves and the Python
    scripts beside them, which they may run as programs (`code_identity.scripts_beside`; pytest's test files
    there, `TEST_FILES`, are not code `ddenv reduce` runs)."""
    from pytest_ddenv.driver.code_identity import identify, scripts_beside

    specs = [*arguments.imports, *([arguments.controller.rpartition(":")[0]] if arguments.controller else [])]
    files = [Path(spec).expanduser() if spec.endswith(".py") or os.sep in spec
             else Path(getattr(sys.modules.get(spec), "__file__", None) or "") for spec in specs]
    files = [path for path in files if path.suffix == ".py"]
    beside = [script for path in files for script in scripts_beside(path, TEST_FILES)]
    return identify([Path.cwd(), *(path.parent for path in files)], data_files=list(dict.fromkeys([*files, *beside])))


def _other_replay(arguments: argparse.Namespace, world_file: Path, seed: int | None) -> str:
    """`ddenv run` of a kept other failure's world with the reduction's predicates, time limit and code, and
    the run seed it failed with."""
    words = ["ddenv", "run", str(world_file)]
    for text in arguments.predicates:
        words += ["--predicate", text]
    words += ["--seed", str(arguments.seed if seed is None else seed)]
    if arguments.timeout is not None:
        words.append(f"--timeout={arguments.timeout}")
    for spec in arguments.imports:
        words += ["--import", spec]
    if arguments.controller:
        words += ["--controller", arguments.controller]
    return " ".join(shlex.quote(word) for word in words)


def _command_line(arguments: argparse.Namespace) -> list[str]:
    """The `ddenv` arguments that run this reduction again (the command in `summary.json`)."""
    words = ["reduce", arguments.world]
    for text in arguments.predicates:
        words += ["--predicate", text]
    for spec in arguments.imports:
        words += ["--import", spec]
    if arguments.controller:
        words += ["--controller", arguments.controller]
    for option in ("scenario", "robot", "start", "goal", "timeout"):
        if getattr(arguments, option, None) is not None:  # --start=-4,5: a value may start with a minus
            words.append(f"--{option}={getattr(arguments, option)}")
    for folders in arguments.model_paths:
        words += ["--model-path", folders]
    if arguments.skip_unsupported:
        words.append("--skip-unsupported")
    words += ["--partition", arguments.partition, "--priority", arguments.priority, "--deflake", str(arguments.deflake),
              "--seed", str(arguments.seed)]
    if arguments.keep_other:
        words += ["--keep-other", str(arguments.keep_other)]
    if arguments.same_failure != defaults.SAME_FAILURE:
        words += ["--same-failure", arguments.same_failure]
    return words
