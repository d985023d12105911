"""Which of pytest-ddenv's frames pytest leaves out of a failing test's traceback.

The modules between a test's `robot_world.run()` and the user's own code (the simulator, the episode, the
robot, the controller checks) set `__tracebackhide__ = hidden_in_tracebacks`; pytest asks it for each of
their frames. A `RobotFailure`, a controller's broken contract, an error of the world or the scenario, or an
exception of the user's controller or predicate is shown at the user's lines only: the test's call, then the
user's function that raised. An exception pytest-ddenv did not mean to raise (a bug) keeps its frames, so
that it can be reported; `pytest --fulltrace` shows every frame.
"""

from __future__ import annotations

import os
import sysconfig
from pathlib import Path
from types import TracebackType
from typing import Any

from pytest_ddenv.errors import DdenvError

PACKAGE = str(Path(__file__).resolve().parents[1]) + os.sep
"""The folder of pytest_ddenv."""
_LIBRARIES = tuple(dict.fromkeys(
    str(Path(folder).resolve()) for key in ("stdlib", "platstdlib", "purelib", "platlib")
    if (folder := sysconfig.get_paths().get(key))
))


def hidden_in_tracebacks(excinfo: Any) -> bool:
    """For pytest's `__tracebackhide__`: True (hide the frame) unless `excinfo`'s exception is one that
    pytest-ddenv raised without meaning to."""
    error = getattr(excinfo, "value", None)
    if not isinstance(error, BaseException):
        return False
    if isinstance(error, DdenvError):  # on purpose: the world, the scenario, the controller (`ControllerError`)
        return True
    if isinstance(error, AssertionError) and type(error) is not AssertionError:  # a test failure: RobotFailure
        return True  # (a plain AssertionError inside the package is one of its own asserts that failed)
    return not _raised_in_the_package(error.__traceback__)


def _raised_in_the_package(trace: TracebackType | None) -> bool:
    """Whether the innermost frame that is not the standard library's or an installed library's is one of
    pytest_ddenv's (else it is the user's code: a controller, a predicate)."""
    files = []
    while trace is not None:
        files.append(trace.tb_frame.f_code.co_filename)
        trace = trace.tb_next
    for file in reversed(files):
        if file.startswith(PACKAGE):
            return True
        if not file.startswith(_LIBRARIES) and not file.startswith("<"):
            return False
    return False
