"""The `ddenv` command line: run, show, reduce, replay and convert worlds without pytest.

Exit codes: 0 success, 1 the scenario failed (or the original world does not fail, or a replay did not
reproduce), 2 usage or input error, 3 internal error (a bug: please report it), 130 interrupted.
Errors are one line on stderr, `ddenv: error: ...`; `--debug` shows the traceback. `--json` prints one
JSON object on stdout instead of text. See docs/cli.md.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence

from pytest_ddenv.cli.bisect import cmd_bisect
from pytest_ddenv.cli.console import (
    EXIT_FAILED,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    EXIT_USER_EXIT,
    describe_error,
    fail,
    traceback_if,
)
from pytest_ddenv.cli.parser import REDUCE_FLAGS, _ArgumentError, build_parser, negative_values_joined
from pytest_ddenv.cli.predicates import parse_predicate
from pytest_ddenv.cli.reduce_command import cmd_reduce
from pytest_ddenv.cli.replay_command import cmd_replay
from pytest_ddenv.cli.run_command import cmd_run
from pytest_ddenv.cli.show_command import cmd_show
from pytest_ddenv.cli.world_commands import cmd_check, cmd_convert
from pytest_ddenv.driver.user_code import UserCodeExit
from pytest_ddenv.errors import DdenvError

__all__ = ["EXIT_FAILED", "EXIT_INTERNAL", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_USAGE", "EXIT_USER_EXIT",
           "REDUCE_FLAGS", "build_parser", "main", "parse_predicate"]
"""The console script's `main`, and the parser, the predicate reader and the exit codes where the tests and
earlier callers import them from."""


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    arguments_list = list(sys.argv[1:] if argv is None else argv)
    try:
        arguments = parser.parse_args(negative_values_joined(arguments_list))
    except _ArgumentError as error:
        return fail(str(error), as_json="--json" in arguments_list)
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
        traceback_if(arguments.debug)
        return fail(str(error), as_json=arguments.json, code=EXIT_USER_EXIT)
    except (DdenvError, OSError) as error:
        traceback_if(arguments.debug)
        return fail(describe_error(error), as_json=arguments.json)
    except KeyboardInterrupt:
        print("ddenv: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as error:  # noqa: BLE001 - the CLI's last resort: a bug is an internal-error exit, not a traceback
        traceback_if(arguments.debug)
        hint = "" if arguments.debug else " (run with --debug for the traceback)"
        message = f"internal error: {type(error).__name__}: {error}{hint}"
        return fail(message, as_json=arguments.json, code=EXIT_INTERNAL)


_HANDLERS: dict[str, Callable[[argparse.Namespace], int]] = {
    "check": cmd_check,
    "run": cmd_run,
    "show": cmd_show,
    "reduce": cmd_reduce,
    "replay": cmd_replay,
    "bisect": cmd_bisect,
    "convert": cmd_convert,
}


if __name__ == "__main__":
    sys.exit(main())
