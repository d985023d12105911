"""Loading the user's code outside pytest: `ddenv --import MODULE_OR_FILE` and `--controller module:attribute`.

The same functions run in the `ddenv` process (to fail early with a clear error) and in every probe worker
(so that robots, predicates and controllers registered by that code exist there too).
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import inspect
import os
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, NoReturn

from pytest_ddenv.errors import DdenvError, shown, shown_path
from pytest_ddenv.validation import expected

if TYPE_CHECKING:
    from pytest_ddenv.oracle.verdict import ErrorInfo


class UserCodeError(DdenvError):
    """The user's code could not be loaded: a missing module or file, an import that raised, a missing
    attribute, a controller that cannot be called. The message names the module (or file) and the option."""


class UserCodeExit(DdenvError):
    """The user's code exited (`sys.exit`, `raise SystemExit`, `os._exit`) while pytest-ddenv ran it: an error
    of the run, never its success (`ddenv` exits with status 3). The message says which code and how."""


def exit_text(error: SystemExit) -> str:
    """How an exit reads in a message: `os._exit(0)`, `SystemExit(0)`, `SystemExit('why')`."""
    if isinstance(error, ProcessExit):
        return f"os._exit({shown(error.code)})"
    return f"SystemExit({shown(error.code)})" if error.code is not None else "SystemExit()"


def import_user_code(spec: str, *, option: str = "--import") -> ModuleType:
    """Import `spec`: a module name (found from the current folder too) or a path to a .py file."""
    if spec.endswith(".py") or os.sep in spec:
        return _import_file(Path(spec), option)
    if str(Path.cwd()) not in sys.path and "" not in sys.path:
        sys.path.insert(0, str(Path.cwd()))
    shown_spec = shown_path(spec)
    try:
        with exits_raised():
            return importlib.import_module(spec)
    except ModuleNotFoundError as error:
        if error.name and spec.startswith(error.name):
            raise UserCodeError(f"{option} {shown_spec}: no module named {shown(error.name)} (looked in the "
                                "current folder and the Python path)") from None
        raise UserCodeError(f"{option} {shown_spec}: importing it failed: {_raised(error)}") from error
    except SystemExit as error:
        raise UserCodeExit(f"{option} {shown_spec}: importing it exited ({exit_text(error)}); a module given to "
                           "ddenv must not exit when it is imported") from None
    except Exception as error:
        raise UserCodeError(f"{option} {shown_spec}: importing it failed: {_raised(error)}") from error


def _raised(error: BaseException) -> str:
    """An exception in a one-line message: its type and its message, clipped."""
    return f"{type(error).__name__}: {shown(str(error), 200)[1:-1]}"


class ProcessExit(SystemExit):
    """`os._exit(code)` called by the user's code while `exits_raised` is active, raised instead of ending the
    process at once."""


@contextlib.contextmanager
def exits_raised() -> Iterator[None]:
    """While the user's code runs: `os._exit(code)` raises `SystemExit(code)` instead of ending this process
    without a word, so that the caller can report it (`sys.exit` raises SystemExit anyway). Only in the main
    thread of this process: other threads, and the children the user's code forks, exit as before."""
    original = os._exit
    main, pid = threading.main_thread(), os.getpid()

    def raising(status: int) -> NoReturn:
        if os.getpid() != pid or threading.current_thread() is not main:
            original(status)
        raise ProcessExit(status)

    os._exit = raising
    try:
        yield
    finally:
        os._exit = original


def _import_file(path: Path, option: str) -> ModuleType:
    try:
        path = path.expanduser().resolve()
    except (RuntimeError, OSError) as error:  # ~nosuchuser/x.py, a loop of symbolic links
        raise UserCodeError(f"{option} {shown_path(path)}: {error}") from None
    if not path.is_file():
        raise UserCodeError(f"{option} {shown_path(path)}: no such file")
    name = path.stem if path.stem.isidentifier() else "ddenv_user_module"
    if name in sys.modules and getattr(sys.modules[name], "__file__", None) == str(path):
        return sys.modules[name]
    if str(path.parent) not in sys.path:
        sys.path.insert(0, str(path.parent))  # its sibling modules import as they would with `python file.py`
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:  # pragma: no cover - a .py file always has a loader
        raise UserCodeError(f"{option} {path}: not an importable Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        with exits_raised():
            spec.loader.exec_module(module)
    except SystemExit as error:
        del sys.modules[name]
        raise UserCodeExit(f"{option} {shown_path(path)}: importing it exited ({exit_text(error)}); a module given "
                           "to ddenv must not exit when it is imported") from None
    except Exception as error:
        del sys.modules[name]
        raise UserCodeError(f"{option} {shown_path(path)}: importing it failed: {_raised(error)}") from error
    return module


def load_attribute(reference: str, *, option: str = "--controller") -> Any:
    """`module:attribute` (or `path/file.py:attribute`; dotted attributes allowed). A class is instantiated
    without arguments, so `module:MyController` works like `module:MyController()`."""
    module_name, colon, attribute = reference.rpartition(":")
    shown_reference = shown_path(reference)
    if not colon or not module_name or not attribute:
        raise UserCodeError(f"{option} {shown(reference)}: expected MODULE:ATTRIBUTE, e.g. my_robot.control:avoid")
    value: Any = import_user_code(module_name, option=option)
    for part in attribute.split("."):
        try:
            value = getattr(value, part)
        except AttributeError:
            raise UserCodeError(f"{option} {shown_reference}: {shown_path(module_name)} has no attribute "
                                f"{shown(attribute)}") from None
    if inspect.isclass(value):
        try:
            with exits_raised():
                value = value()
        except SystemExit as error:
            raise UserCodeExit(f"{option} {shown_reference}: {shown(attribute)[1:-1]}() exited "
                               f"({exit_text(error)})") from None
        except Exception as error:
            raise UserCodeError(f"{option} {shown_reference}: {shown(attribute)[1:-1]}() raised "
                                f"{_raised(error)}") from error
    if not callable(value):
        raise UserCodeError(expected("a function, or an object that can be called (a class is made an instance "
                                     "first)", value, f"{option} {shown_reference}"))
    return value


def exit_location(error: SystemExit) -> str:
    """file:line where the user's code exited: the deepest frame of `error`'s traceback outside this module."""
    import traceback

    frames = [frame for frame in traceback.extract_tb(error.__traceback__) if frame.filename != __file__]
    return f"{Path(frames[-1].filename).name}:{frames[-1].lineno}" if frames else "?"


def exit_error(error: SystemExit, what: str) -> ErrorInfo:
    """What a probe whose code under test exited reports: an error (never a verdict), saying how and where."""
    from pytest_ddenv.oracle.verdict import ErrorInfo

    return ErrorInfo(type(error).__qualname__, exit_message(error, what), exit_location(error), ddenv_error=True)


def is_exit(error: ErrorInfo) -> bool:
    """Whether a probe's error is the code under test exiting (`exit_error`)."""
    return error.ddenv_error and error.type_name in (SystemExit.__qualname__, ProcessExit.__qualname__)


def exit_message(error: SystemExit, what: str) -> str:
    """The message for the user's code that exited during `what` (e.g. "the run"): an error, never a pass."""
    return (f"the code under test exited during {what} ({exit_text(error)} at {exit_location(error)}); an exit is an "
            "error of the run, never its success: return or raise instead")

