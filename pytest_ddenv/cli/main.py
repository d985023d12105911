"""The `ddenv` command line: run, show, reduce, replay and convert worlds without pytest.

Exit codes: 0 success, 1 the scenario failed (or the original world does not fail, or a replay did not
reproduce), 2 usage or input error, 3 internal error (a bug: please report it), 130 interrupted.
Errors are one line on stderr, `ddenv: error: ...`; `--debug` shows the traceback. `--json` prints one
JSON object on stdout instead of text. See docs/cli.md.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from pytest_ddenv import defaults
from pytest_ddenv._version import __version__
from pytest_ddenv.cli.bisect import add_bisect, cmd_bisect
from pytest_ddenv.cli.output import appended, check_matplotlib_backend, check_output, check_record
from pytest_ddenv.cli.world_options import (
    WORLD_SETTINGS,
    UsageError,
    add_scenario_options,
    add_world_options,
    check_robot,
    dropped_models,
    load_world,
    same_file,
    with_scenario,
)
from pytest_ddenv.driver.progress import ProgressLine
from pytest_ddenv.driver.settings import (
    SETTING,
    Check,
    Setting,
    SettingError,
    flag,
    flag_settings,
    integer,
    names,
    positive,
    same_failure,
    watchdog,
)
from pytest_ddenv.driver.user_code import UserCodeExit, is_exit
from pytest_ddenv.errors import DdenvError, raised_by_ddenv, shown
from pytest_ddenv.oracle.predicates import PredicateSpec, check_predicate_models
from pytest_ddenv.oracle.verdict import hit_wall_clock_cap, is_run_error, wall_clock_cap_message

if TYPE_CHECKING:  # pragma: no cover
    from pytest_ddenv.driver.report import ReductionReport
    from pytest_ddenv.execution import Pool
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERNAL = 3
EXIT_USER_EXIT = 3
"""The user's code (a controller, an --import) exited during the run: as an internal error, never a success."""
EXIT_INTERRUPTED = 130

YAML_SUFFIXES = (".yaml", ".yml")
SDF_SUFFIXES = (".sdf", ".world")
MJCF_SUFFIXES = (".xml", ".mjcf")
"""Read only: a world is not written as MJCF (a reduction cuts `minimal.xml` from the scene)."""


class _ArgumentError(Exception):
    """argparse found a usage error (raised instead of printing usage and exiting)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise _ArgumentError(f"{message} (see '{self.prog} --help')")


# -- argument types -------------------------------------------------------------------------------------
def _type(kind: Check, where: str) -> Callable[[str], Any]:
    """An argparse `type` that checks a flag's text as `kind` (argparse names the flag in its message)."""

    def check(text: str) -> Any:
        try:
            return kind(text, where, True)
        except SettingError as error:
            raise argparse.ArgumentTypeError(str(error).removeprefix(f"{where}: ")) from None

    return check


def _resolved_media(given: str | None) -> str:
    """--media, else $DDENV_MEDIA, else all."""
    try:
        return str(SETTING["media"].check(given, "--media"))
    except SettingError as error:
        raise UsageError(str(error)) from None


def add_setting_flags(parser: argparse.ArgumentParser, settings: Sequence[Setting]) -> None:
    """The flags of `settings` (`driver/settings.py`), each with its declared help, default and check."""
    for setting in settings:
        options: dict[str, Any] = {"dest": setting.name, "default": setting.default, "help": setting.help}
        if setting.kind is flag:
            options["action"] = "store_true"
        elif setting.kind is names:
            options.update(action="append", default=[], metavar=setting.metavar)
        elif setting.choices is not None:
            options["choices"] = setting.choices()
        elif setting.kind is same_failure:  # MODULE:FUNCTION is loaded once the --import modules are
            options["metavar"] = setting.metavar
        else:
            options.update(type=_type(setting.kind, setting.flag_name), metavar=setting.metavar)
        parser.add_argument(setting.flag_name, **options)


def parse_predicate(text: str) -> PredicateSpec:
    """`NAME[:key=value,...]`, e.g. `stuck:window=5,min_progress=0.2` or `collided:models=[wall,barrel]`.

    Values are numbers, true/false, none, or [a,b,...] lists of names; validated by `oracle.make_predicate`.
    """
    from pytest_ddenv.oracle.predicates import make_predicate

    name, _, rest = text.partition(":")
    if not name.strip():
        raise UsageError(f"--predicate {shown(text)}: expected NAME[:key=value,...]")
    params: dict[str, Any] = {}
    for item in _split_top_level(rest):
        key, equals, value = item.partition("=")
        if not equals or not key.strip():
            raise UsageError(f"--predicate {shown(text)}: expected key=value, got {shown(item)} "
                             "(form: NAME[:key=value,...], e.g. stuck:window=5,min_progress=0.2)")
        if key.strip() in params:
            raise UsageError(f"--predicate {shown(text)}: {shown(key.strip())} is given twice; give each "
                             "parameter once")
        params[key.strip()] = _predicate_value(value.strip())
    try:
        make_predicate(name.strip(), **params)
    except DdenvError as error:
        raise UsageError(f"--predicate {shown(text)}: {error}") from None
    return PredicateSpec(name.strip(), params)


def _split_top_level(text: str) -> list[str]:
    """Split at commas that are not inside [...]."""
    items, depth, current = [], 0, ""
    for char in text:
        depth += char == "["
        depth -= char == "]"
        if char == "," and depth == 0:
            items.append(current)
            current = ""
        else:
            current += char
    if current.strip():
        items.append(current)
    return [item for item in items if item.strip()]


def _predicate_value(text: str) -> Any:
    lowered = text.lower()
    if lowered in ("none", "null"):
        return None
    if lowered in ("true", "false"):
        return lowered == "true"
    if text.startswith("[") and text.endswith("]"):
        return [item.strip() for item in text[1:-1].split(",") if item.strip()]
    for convert in (int, float):
        try:
            return convert(text)
        except ValueError:
            pass
    return text


# -- the parser -----------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    common = _Parser(add_help=False)
    common.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                        help="print one JSON object on stdout instead of text")
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show tracebacks for errors")
    parser = _Parser(
        prog="ddenv",
        description="Reduce the simulated world of a failing robot scenario to the objects that cause the failure.",
        epilog="Exit codes: 0 success, 1 the scenario failed or a replay did not reproduce, 2 usage or input "
               "error, 3 internal error. Inside pytest, use `pytest --ddenv-reduce`. Documentation: docs/cli.md",
        parents=[common],
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    _add_check(commands, common)
    _add_run(commands, common)
    _add_show(commands, common)
    _add_reduce(commands, common)
    _add_replay(commands, common)
    add_bisect(commands, common)
    _add_convert(commands, common)
    return parser


def _add_check(commands: Any, common: argparse.ArgumentParser) -> None:
    check = commands.add_parser("check", parents=[common],
                                help="load a world file and report its models, or the first error")
    check.add_argument("world", help="world file (.yaml, .sdf, .xml)")
    add_world_options(check)


def _add_predicate_option(parser: argparse.ArgumentParser, *, required: bool) -> None:
    parser.add_argument("--predicate", "-p", dest="predicates", action="append", type=str, default=[],
                        required=required, metavar="NAME[:k=v,...]",
                        help="failure predicate, repeatable, e.g. stuck:window=5,min_progress=0.2 "
                             "(stuck, flipped, high_centered, fell, collided, timeout; for an arm arm_collision, "
                             "grasp_failed, object_dropped, not_placed, knocked_over, joint_limit, self_collision; "
                             "or one registered by an --import)")


def _add_user_code_options(parser: argparse.ArgumentParser, *, controller: bool = True) -> None:
    parser.add_argument("--import", dest="imports", action="append", default=[], metavar="MODULE_OR_FILE",
                        help="import this module (or .py file) first, repeatable: the code that registers your "
                             "robots (register_robot), predicates (register_predicate) or controllers")
    if controller:
        parser.add_argument("--controller", metavar="MODULE:ATTRIBUTE",
                            help="the controller that drives the robot, e.g. my_robot.control:avoid (a function "
                                 "or object called with an Observation, or a class instantiated without "
                                 "arguments); default: the built-in go-to-goal law")


def _add_run(commands: Any, common: argparse.ArgumentParser) -> None:
    run = commands.add_parser("run", parents=[common], help="simulate a world's scenario once and picture it")
    run.add_argument("world", help="world file (.yaml, .sdf, .xml)")
    run.add_argument("--seed", type=_type(integer(0), "--seed"), default=0, help="seed of the run's noise (default 0)")
    _add_predicate_option(run, required=False)
    _add_user_code_options(run)
    run.add_argument("--timeout", type=_type(positive(), "--timeout"),
                     help="simulated seconds (default: the world's scenario)")
    add_scenario_options(run)
    add_world_options(run)
    add_setting_flags(run, [SETTING["engine"], SETTING["run_timeout"]])
    run.add_argument("-o", "--output", help="picture to write (default: WORLD-run.png in the current folder)")
    run.add_argument("--no-picture", action="store_true", help="do not write a picture")
    run.add_argument("--record", metavar="RUNS.jsonl", help="append the run (trajectory included) to this file")


def _add_show(commands: Any, common: argparse.ArgumentParser) -> None:
    show = commands.add_parser("show", parents=[common], help="draw a world, optionally with recorded runs")
    show.add_argument("world", help="world file (.yaml, .sdf, .xml)")
    show.add_argument("--runs", metavar="FILE", help="runs to draw: a `ddenv run --record` file, or a "
                                                      "reduction's runs.jsonl (failure poses)")
    show.add_argument("-o", "--output", help="picture to write (default: WORLD.png in the current folder)")
    show.add_argument("--animate", nargs="?", const="", default=None, metavar="GIF",
                      help="also write an animation (default: WORLD.gif) of the first run of --runs, or of one "
                           "simulated run of the world's scenario (seed 0, built-in controller) without --runs")
    add_world_options(show)


def _add_reduce(commands: Any, common: argparse.ArgumentParser) -> None:
    reduce = commands.add_parser("reduce", parents=[common],
                                 help="reduce a failing world to the models the failure needs")
    reduce.add_argument("world", help="world file (.yaml, .sdf, .xml)")
    _add_predicate_option(reduce, required=False)  # required for a mobile robot: _reduce_predicates
    _add_user_code_options(reduce)
    reduce.add_argument("--timeout", type=_type(positive(), "--timeout"),
                        help="simulated seconds per run (default: the world's)")
    add_scenario_options(reduce)
    add_world_options(reduce)
    add_setting_flags(reduce, [setting for setting in flag_settings() if setting.name not in WORLD_SETTINGS])
    for flags, options in REDUCE_FLAGS.items():
        reduce.add_argument(*flags, **options)


REDUCE_FLAGS: dict[tuple[str, ...], dict[str, Any]] = {
    ("--out",): {"metavar": "DIR", "help": "artifacts folder (default ddenv-artifacts/WORLD-seedN-HASH: the world "
                 "file's name and the seed)"},
    ("--quiet", "-q"): {"action": "store_true", "help": "no progress on stderr"},
}
"""The `ddenv reduce` flags of this command alone (besides the world, predicate, user code and scenario ones);
the reduction's settings are `driver/settings.py`'s."""


def _add_replay(commands: Any, common: argparse.ArgumentParser) -> None:
    replay = commands.add_parser("replay", parents=[common],
                                 help="re-run a reduction's minimal world and check it still fails the same way")
    replay.add_argument("artifacts", metavar="ARTIFACT_DIR",
                        help="a folder written by ddenv reduce or pytest --ddenv-reduce")
    _add_predicate_option(replay, required=False)
    _add_user_code_options(replay)
    add_setting_flags(replay, [SETTING["engine"], SETTING["run_timeout"]])
    replay.add_argument("--runs", type=_type(integer(1), "--runs"), default=10, metavar="N",
                        help="run N fresh seeds, none a reduction probe used (default 10); with --recorded, at "
                             "most N of the seeds the reduction saw fail")
    replay.add_argument("--recorded", action="store_true",
                        help="re-run the seeds on which the reduction saw the minimal world fail (each should "
                             "fail again) instead of fresh ones")
    replay.add_argument("--tolerance", type=_type(positive(), "--tolerance"), metavar="M",
                        help="default: the recorded one")
    replay.add_argument("--same-failure", metavar="RULE",
                        help="all, place, touched or MODULE:FUNCTION (default: the recorded rule)")
    replay.add_argument("--animate", nargs="?", const="", default=None, metavar="GIF",
                        help="also write an animation of the first run that failed the same way (else the first "
                             "run): default ARTIFACT_DIR/replay.gif")


def _add_convert(commands: Any, common: argparse.ArgumentParser) -> None:
    convert = commands.add_parser("convert", parents=[common], help="convert a world between YAML and SDF")
    convert.add_argument("input", help="world file to read (.yaml, .yml, .sdf, .world, .xml, .mjcf)")
    convert.add_argument("output", help="world file to write; the format follows the extension")
    add_world_options(convert)


# -- main -----------------------------------------------------------------------------------------------
def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    arguments_list = list(sys.argv[1:] if argv is None else argv)
    try:
        arguments = parser.parse_args(negative_values_joined(arguments_list))
    except _ArgumentError as error:
        return _fail(str(error), as_json="--json" in arguments_list)
    except SystemExit as exit_:  # --help, --version
        return int(exit_.code or 0)
    arguments.json = getattr(arguments, "json", False)  # the options are shared with every subcommand, so
    arguments.debug = getattr(arguments, "debug", False)  # they have no default (argparse.SUPPRESS)
    if arguments.command is None:
        parser.print_help()
        return EXIT_OK
    handler = _HANDLERS[arguments.command]
    try:
        return handler(arguments)
    except BrokenPipeError:  # the reader went away (`ddenv ... | head`): stop quietly, as a Unix tool does
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_FAILED
    except UserCodeExit as error:  # the user's code exited while ddenv ran it: an error, never a success
        _traceback_if(arguments.debug)
        return _fail(str(error), as_json=arguments.json, code=EXIT_USER_EXIT)
    except (DdenvError, OSError) as error:
        _traceback_if(arguments.debug)
        return _fail(_describe_error(error), as_json=arguments.json)
    except KeyboardInterrupt:
        print("ddenv: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as error:  # noqa: BLE001 - the CLI's last resort: a bug is an internal-error exit, not a traceback
        _traceback_if(arguments.debug)
        hint = "" if arguments.debug else " (run with --debug for the traceback)"
        message = f"internal error: {type(error).__name__}: {error}{hint}"
        return _fail(message, as_json=arguments.json, code=EXIT_INTERNAL)


def negative_values_joined(words: Sequence[str]) -> list[str]:
    """`--start -5,-1` as `--start=-5,-1`: argparse takes a value that starts with '-' for an option (unless it
    is one plain number), so coordinates that start with a minus are joined to their option first."""
    joined: list[str] = []
    for word in words:
        if joined and joined[-1] in ("--start", "--goal") and re.match(r"-\.?\d", word):
            joined[-1] = f"{joined[-1]}={word}"
        else:
            joined.append(word)
    return joined


def _traceback_if(debug: bool) -> None:
    """--debug: the traceback of the error being handled, on stderr (the exit code stays the same)."""
    if debug:
        import traceback

        traceback.print_exc(file=sys.stderr)


def _describe_error(error: BaseException) -> str:
    if isinstance(error, OSError) and error.filename is not None:
        return f"{error.filename}: {error.strerror or error}"
    return str(error)


def _fail(message: str, *, as_json: bool, code: int = EXIT_USAGE) -> int:
    from pytest_ddenv.driver.report_text import clip_lines

    message = clip_lines(message)
    print(f"ddenv: error: {message}", file=sys.stderr)
    if as_json:
        _print_json({"ok": False, "error": message, "exit_code": code})
    return code


def _print_json(data: Any) -> None:
    print(json.dumps(data, indent=2, default=str))


def _emit(arguments: argparse.Namespace, text: str, data: dict[str, Any]) -> None:
    if arguments.json:
        _print_json(data)
    else:
        print(text)


# -- check, convert ---------------------------------------------------------------------------------------
def _cmd_check(arguments: argparse.Namespace) -> int:
    world = load_world(arguments, arguments.world, warn=False)  # its notes say what was dropped
    check_robot(world)
    count = len(world)
    text = f"{arguments.world}: {count} model{'s' if count != 1 else ''} ({len(world.reducible_names)} reducible)"
    text += "".join(f"\nnot simulated: {note}" for note in world.notes)
    _emit(arguments, text, {"ok": True, "world": arguments.world, "models": len(world),
                            "reducible": len(world.reducible_names), "names": list(world.names),
                            "notes": list(world.notes)})
    return EXIT_OK


def _cmd_convert(arguments: argparse.Namespace) -> int:
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
    _emit(arguments, text, {"ok": True, "input": str(source), "output": str(target), "models": len(world),
                            "dropped": dropped_models(world)})
    return EXIT_OK


# -- run, show --------------------------------------------------------------------------------------------
def _predicates(texts: Sequence[str]) -> tuple[PredicateSpec, ...]:
    return tuple(parse_predicate(text) for text in texts)


def _reduce_predicates(texts: Sequence[str], world: World) -> tuple[PredicateSpec, ...]:
    """`ddenv reduce`'s predicates: those given, or for an arm's world the arm's defaults (`ARM_DEFAULTS`); a
    mobile robot's world needs at least one (its run fails no other way)."""
    predicates = _predicates(texts)
    if predicates or world.scenario is None:
        return predicates
    from pytest_ddenv.oracle.arm_predicates import default_predicates
    from pytest_ddenv.sim.arm.robot import robot_kind

    if robot_kind(world.scenario.robot, world.source) == "arm":
        return default_predicates("arm")
    raise UsageError("the following arguments are required for a mobile robot's world: --predicate/-p "
                     "(e.g. -p stuck); an arm's world checks the arm's default predicates when none is given")


def _check_predicate_models(predicates: Sequence[PredicateSpec], world: World) -> None:
    try:
        check_predicate_models(predicates, world.names, world.source or world.name)
    except DdenvError as error:
        raise UsageError(f"--predicate: {error}") from None


def _world_stem(path: str) -> str:
    return Path(path).stem or "world"


def _user_code(arguments: argparse.Namespace) -> Any:
    """Import the --import modules now (their registrations are needed to read the options) and load the
    --controller; returns the controller (None: the built-in law)."""
    from pytest_ddenv.driver.user_code import import_user_code, load_attribute

    for spec in arguments.imports:
        import_user_code(spec)
    reference = getattr(arguments, "controller", None)
    return None if reference is None else load_attribute(reference)


def _cmd_run(arguments: argparse.Namespace) -> int:
    from pytest_ddenv.driver.scenario_job import run_scenario

    if not arguments.no_picture:
        check_output("--output", arguments.output, ".png")
        check_matplotlib_backend()
    check_record(arguments.record)
    controller = _user_code(arguments)
    world = with_scenario(arguments, load_world(arguments, arguments.world), arguments.world)
    predicates = _predicates(arguments.predicates)
    _check_predicate_models(predicates, world)
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

        target = arguments.output or f"{_world_stem(arguments.world)}-run.png"
        picture = render.plot_world(world, [run], path=target, title=f"{_world_stem(arguments.world)}: "
                                    f"{len(world)} models, seed {arguments.seed}")
    if arguments.record:
        with appended("--record", arguments.record) as record:
            record.write(json.dumps(run.to_dict()) + "\n")
    passed = run.failure is None and run.reached_goal
    _emit(arguments, _run_text(arguments.world, world, run, picture), {
        "ok": passed,
        "world": arguments.world,
        "models": len(world),
        "seed": run.seed,
        "outcome": _run_outcome(run),
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
    _emit(arguments, text, {"ok": False, "world": arguments.world, "models": len(world), "seed": arguments.seed,
                            "outcome": "error" if capped else "raised", "exception": info.type_name,
                            "message": info.message,
                            "location": info.location, "dropped": dropped_models(world)})
    return EXIT_FAILED


def _run_outcome(run: Run) -> str:
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


def _cmd_show(arguments: argparse.Namespace) -> int:
    from pytest_ddenv import render

    check_output("--output", arguments.output, ".png")
    if arguments.animate:
        check_output("--animate", arguments.animate, ".gif")
    check_matplotlib_backend()
    world = load_world(arguments, arguments.world)
    runs, poses, outcomes = _read_runs(Path(arguments.runs)) if arguments.runs else ([], [], [])
    target = arguments.output or f"{_world_stem(arguments.world)}.png"
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
        animation = _animate(arguments.animate or f"{_world_stem(arguments.world)}.gif", world, run,
                             "recorded run" if runs else "seed 0")
        text += f"\nwrote {animation.path} ({animation.frames} frames, {animation.size_bytes // 1024} KB)"
        data["animation"] = animation.to_dict()
    _emit(arguments, text, data)
    return EXIT_OK


def _simulated_run(world: World) -> Run:
    from pytest_ddenv.detail import recording_detail
    from pytest_ddenv.driver.scenario_job import run_scenario

    with recording_detail():
        return run_scenario(world, (), seed=0)


def _animate(target: str, world: World, run: Run, title: str) -> Any:
    from pytest_ddenv.media.animate import write_animation

    return write_animation(Path(target), world, run, title=title)


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


# -- reduce ------------------------------------------------------------------------------------------------
def _cmd_reduce(arguments: argparse.Namespace) -> int:
    from pytest_ddenv.driver.scenario_job import ScenarioJob
    from pytest_ddenv.execution import check_executor, make_pool
    from pytest_ddenv.media.writer import records_runs
    from pytest_ddenv.reduce import PRIORITY_ALIASES

    arguments.media = _resolved_media(arguments.media)
    if arguments.media != "none":
        check_matplotlib_backend()
    _user_code(arguments)
    world = with_scenario(arguments, load_world(arguments, arguments.world), arguments.world)
    predicates = _reduce_predicates(arguments.predicates, world)
    _check_predicate_models(predicates, world)
    arguments.same_failure_match = _same_failure(arguments.same_failure)
    keep = _keep(world, arguments.keep)
    priority = PRIORITY_ALIASES.get(arguments.priority, arguments.priority)
    executor = check_executor(arguments.executor)
    from pytest_ddenv.driver.artifacts import folder_problem
    from pytest_ddenv.driver.run import IMPORT_AHEAD_WAIT, import_ahead

    problem = folder_problem(_artifacts_folder(arguments))
    if problem is not None:
        raise UsageError(f"{'--out' if arguments.out else 'the artifacts folder'}: {problem}")
    # --timeout is in the world's scenario (with_scenario), not a per-run override: the time stage's shorter
    # limit must apply to its candidates
    job = ScenarioJob(tuple(predicates), seed=arguments.seed, controller=arguments.controller,
                      imports=tuple(arguments.imports), max_wall_time=arguments.run_timeout)
    progress = ProgressLine(sys.stderr, quiet=arguments.quiet)
    in_process = job.handler() if executor is None and arguments.workers == 1 else None
    ahead: threading.Thread | None = None
    try:
        with make_pool(job, arguments.workers, executor, in_process=in_process,
                       watchdog=watchdog(arguments.probe_timeout)) as pool:
            if in_process is None:  # the workers run the original: the engine's imports meanwhile
                ahead = import_ahead()
            progress.note(f"simulating the original world ({len(world)} models, seed {arguments.seed}; "
                          f"{_where(pool)})")
            original = pool.call(world, 0, record=records_runs(arguments.media))
            if original.error is None or is_run_error(original.error):
                return _does_not_fail(arguments, original)
            progress.note(f"it fails: {_failure_text(original)}; reducing")
            outcome, interrupted = _reduce(arguments, world, original, predicates, keep, priority, pool,
                                           progress)
    finally:
        progress.close()
        if ahead is not None:  # never exit while it imports (see driver.IMPORT_AHEAD_WAIT)
            ahead.join(IMPORT_AHEAD_WAIT)
    if outcome.report is None:  # nothing reduced: the failure does not depend on the world
        print(f"ddenv: {arguments.world}: {outcome.message}", file=sys.stderr)
        if arguments.json:
            _print_json({"ok": False, "status": outcome.status, "error": outcome.message,
                         "exit_code": EXIT_FAILED})
        return EXIT_FAILED
    pictures = [str(p) for p in outcome.attachments if p.suffix == ".png"]
    media = [str(p) for p in outcome.attachments if p.suffix in (".gif", ".rrd")]
    _emit(arguments, _reduction_text(arguments.world, outcome.report, pictures, media),
          {"ok": True, **outcome.report.to_json(), "pictures": pictures, "media": media,
           "dropped": dropped_models(world)})
    return EXIT_INTERRUPTED if interrupted else EXIT_OK


def _where(pool: Pool[Any]) -> str:
    if pool.in_process:
        return "in this process"
    return f"{pool.size} workers"


def _failure_text(result: Any) -> str:
    error = result.error
    if error.signature is not None:
        return f"{error.signature.predicate} at t = {error.signature.time:.2f} s"
    return f"{error.type_name} at {error.location}"


def _keep(world: World, names: Sequence[str]) -> tuple[str, ...]:
    unknown = sorted(set(names) - set(world.names))
    if unknown:
        raise UsageError(f"--keep: no model named {', '.join(map(repr, unknown))} in the world")
    return tuple(sorted(set(names) | {m.name for m in world.models if m.keep}))


def _does_not_fail(arguments: argparse.Namespace, result: Any) -> int:
    if result.error is not None and is_exit(result.error):  # the code under test exited: an error, never a pass
        raise UserCodeExit(f"{arguments.world}: {result.error.message}")
    if result.error is not None and hit_wall_clock_cap(result.error):  # an error of the run, nothing to reduce
        message = (f"{arguments.world}: {wall_clock_cap_message(result.error.location)} "
                   f"({result.error.message.replace(RUN_TIMEOUT_HINT, 'ddenv reduce --run-timeout SECONDS')})")
        print(f"ddenv: {message}", file=sys.stderr)
        if arguments.json:
            _print_json({"ok": False, "error": message, "exit_code": EXIT_FAILED, "outcome": "error"})
        return EXIT_FAILED
    if result.error is not None:  # the scenario cannot be run at all: an input error
        raise UsageError(f"{arguments.world}: the scenario could not be run: {result.error.describe()}")
    run = result.run
    outcome = "reached the goal" if run is not None and run.reached_goal else "no failure predicate fired"
    simulated = "" if run is None else f" after {run.sim_time:.1f} s simulated"
    message = (f"{arguments.world}: the original world does not fail with seed {arguments.seed} ({outcome}"
               f"{simulated}); nothing to reduce. Check the --predicate options with `ddenv run`.")
    print(f"ddenv: {message}", file=sys.stderr)
    if arguments.json:
        _print_json({"ok": False, "error": message, "exit_code": EXIT_FAILED,
                     "outcome": "no_run" if run is None else _run_outcome(run)})
    return EXIT_FAILED


def _artifacts_folder(arguments: argparse.Namespace) -> Path:
    """--out, else ddenv-artifacts/ named by the world (the command's "test id") and the seed."""
    from pytest_ddenv.driver.artifacts import artifact_dir_name

    if arguments.out:
        return Path(arguments.out)
    return Path("ddenv-artifacts") / artifact_dir_name(_world_stem(arguments.world), arguments.seed)


def _reduce(arguments: argparse.Namespace, world: World, original: Any, predicates: Sequence[PredicateSpec],
            keep: tuple[str, ...], priority: str, pool: Any,
            progress: ProgressLine) -> tuple[Any, bool]:
    import dataclasses

    from pytest_ddenv.cli.replay import predicates_to_json
    from pytest_ddenv.driver.markers import ReductionSpec
    from pytest_ddenv.driver.run import ReductionPlan, interrupted_outcome, run_reduction
    from pytest_ddenv.oracle.verdict import FailureReference
    from pytest_ddenv.reduce import ReductionInterrupted

    spec = dataclasses.replace(
        ReductionSpec(), partition=arguments.partition, priority=priority, n_partitions=arguments.n_partitions,
        granularity=arguments.granularity, deflake=arguments.deflake, tolerance=arguments.tolerance,
        same_failure=arguments.same_failure_match, keep=keep,
        seed=arguments.seed, max_probes=arguments.max_probes, max_seconds=arguments.max_seconds,
        stages=arguments.stages, stage_probes=arguments.stage_probes, confirm_engines=arguments.confirm_engines,
    )
    folder = _artifacts_folder(arguments)
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
    try:
        return run_reduction(plan, pool, note=progress.note, on_progress=progress.update), False
    except ReductionInterrupted as stop:
        progress.note("interrupted: the best world found so far is written")
        outcome = interrupted_outcome(stop)
        if outcome is None:  # pragma: no cover - run_reduction always writes its outcome before it re-raises
            raise
        return outcome, True
    finally:
        progress.close()


def _code_under_test(arguments: argparse.Namespace) -> Any:
    """The code under test of `ddenv reduce`: the modules loaded from the current folder and from the folders of
    the --import and --controller files (all imported by now), with those files themselves."""
    from pytest_ddenv.driver.code_identity import identify

    specs = [*arguments.imports, *([arguments.controller.rpartition(":")[0]] if arguments.controller else [])]
    files = [Path(spec).expanduser() if spec.endswith(".py") or os.sep in spec
             else Path(getattr(sys.modules.get(spec), "__file__", None) or "") for spec in specs]
    files = [path for path in files if path.suffix == ".py"]
    return identify([Path.cwd(), *(path.parent for path in files)], data_files=files)


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


def _same_failure(text: str, option: str = "--same-failure") -> str:
    """A match as `oracle.SameFailureRule` holds it: all, place, touched, or MODULE:FUNCTION loaded now (a
    file path works as the module, as for --controller) and held as "module:qualname"."""
    from pytest_ddenv.driver.user_code import load_attribute
    from pytest_ddenv.oracle.verdict import MATCHES, same_failure_match

    given: Any = load_attribute(text, option=option) if text not in MATCHES and ":" in text else text
    return same_failure_match(given, option)


def _reduction_text(path: str, report: ReductionReport, pictures: Sequence[str], media: Sequence[str]) -> str:
    from pytest_ddenv.driver.report_text import result_lines, status_of

    reduction = report.reduction
    return "\n".join([
        (f"{path}: {reduction.original_size} -> {reduction.minimal_size} models "
         f"({report.reduction_percent}% removed), {status_of(reduction)}"),
        *result_lines(report),
        f"artifacts: {report.files.folder}",
        f"pictures: {', '.join(pictures) or '(none)'}",
        *([f"animations and recording: {', '.join(media)}"] if media else []),
        f"replay: {report.replay}",
    ])


# -- replay ------------------------------------------------------------------------------------------------
def _cmd_replay(arguments: argparse.Namespace) -> int:
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
    controller = _user_code(arguments)
    predicates = _predicates(arguments.predicates) or None
    from pytest_ddenv.detail import recording_detail

    with recording_detail(arguments.animate is not None):
        result = replay(arguments.artifacts, predicates=predicates, max_runs=arguments.runs,
                        tolerance=arguments.tolerance, controller=controller, recorded=arguments.recorded,
                        engine=arguments.engine, run_timeout=arguments.run_timeout,
                        same_failure=None if arguments.same_failure is None else _same_failure(arguments.same_failure))
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
        animation = _animate(arguments.animate or str(Path(arguments.artifacts) / "replay.gif"), result.world,
                             chosen.run, f"replay seed {chosen.seed}")
        lines.append(f"wrote {animation.path} (seed {chosen.seed}, {animation.frames} frames)")
        data["animation"] = animation.to_dict()
    _emit(arguments, "\n".join(lines), data)
    return EXIT_OK if result.ok else EXIT_FAILED


_HANDLERS: dict[str, Callable[[argparse.Namespace], int]] = {
    "check": _cmd_check,
    "run": _cmd_run,
    "show": _cmd_show,
    "reduce": _cmd_reduce,
    "replay": _cmd_replay,
    "bisect": cmd_bisect,
    "convert": _cmd_convert,
}


if __name__ == "__main__":
    sys.exit(main())
