"""The `ddenv` command line's parser: the sub-commands and their options (the reduction's settings built from
`driver/settings.py`), each value checked as argparse reads it, and argparse's usage errors raised as
`_ArgumentError` instead of printed with an exit."""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from pytest_ddenv._version import __version__
from pytest_ddenv.cli.bisect import add_bisect
from pytest_ddenv.cli.world_options import WORLD_SETTINGS, add_scenario_options, add_world_options
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
)


class _ArgumentError(Exception):
    """argparse found a usage error (raised instead of printing usage and exiting)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise _ArgumentError(f"{message} (see '{self.prog} --help')")


def _type(kind: Check, where: str) -> Callable[[str], Any]:
    """An argparse `type` that checks a flag's text as `kind` (argparse names the flag in its message)."""

    def check(text: str) -> Any:
        try:
            return kind(text, where, True)
        except SettingError as error:
            raise argparse.ArgumentTypeError(str(error).removeprefix(f"{where}: ")) from None

    return check


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
    _add_predicate_option(reduce, required=False)  # required for a mobile robot: reduce_predicates
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
