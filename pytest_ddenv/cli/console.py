"""What `ddenv` prints and returns: its exit codes, an error as one line on stderr (and one JSON object on
stdout under `--json`), a command's result as text or as JSON, and the traceback under `--debug`."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERNAL = 3
EXIT_USER_EXIT = 3
"""The user's code (a controller, an --import) exited during the run: as an internal error, never a success."""
EXIT_INTERRUPTED = 130


def traceback_if(debug: bool) -> None:
    """--debug: the traceback of the error being handled, on stderr (the exit code stays the same)."""
    if debug:
        import traceback

        traceback.print_exc(file=sys.stderr)


def describe_error(error: BaseException) -> str:
    if isinstance(error, OSError) and error.filename is not None:
        return f"{error.filename}: {error.strerror or error}"
    return str(error)


def fail(message: str, *, as_json: bool, code: int = EXIT_USAGE) -> int:
    from pytest_ddenv.driver.report_text import clip_lines

    message = clip_lines(message)
    print(f"ddenv: error: {message}", file=sys.stderr)
    if as_json:
        print_json({"ok": False, "error": message, "exit_code": code})
    return code


def print_json(data: Any) -> None:
    print(json.dumps(data, indent=2, default=str))


def emit(arguments: argparse.Namespace, text: str, data: dict[str, Any]) -> None:
    if arguments.json:
        print_json(data)
    else:
        print(text)
