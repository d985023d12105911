"""The `ddenv` command line."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from pytest_ddenv import __version__
from pytest_ddenv.errors import DdenvError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ddenv",
        description="Reduce the simulated world of a failing robot scenario to the objects that cause the failure.",
        epilog="Inside pytest, use `pytest --ddenv-reduce`. Documentation: docs/index.md",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks for errors")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    check = commands.add_parser("check", help="load a world file and report its models, or the first error")
    check.add_argument("world", help="world file (.yaml)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    arguments = parser.parse_args(argv)
    if arguments.command is None:
        parser.print_help()
        return 0
    try:
        if arguments.command == "check":
            from pytest_ddenv.world import World

            world = World.load(arguments.world)
            print(f"{arguments.world}: {len(world)} models ({len(world.reducible_names)} reducible)")
        return 0
    except DdenvError as error:
        if arguments.debug:
            raise
        print(f"ddenv: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
