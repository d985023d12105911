"""Loading the user's code outside pytest: `ddenv --import MODULE_OR_FILE` and `--controller module:attribute`.

The same functions run in the `ddenv` process (to fail early with a clear error) and in every probe worker
(so that robots, predicates and controllers registered by that code exist there too).
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import os
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

from pytest_ddenv.errors import DdenvError


class UserCodeError(DdenvError):
    """The user's code could not be loaded: a missing module or file, an import that raised, a missing
    attribute. The message names the module (or file) and the option."""


def import_user_code(spec: str, *, option: str = "--import") -> ModuleType:
    """Import `spec`: a module name (found from the current folder too) or a path to a .py file."""
    if spec.endswith(".py") or os.sep in spec:
        return _import_file(Path(spec), option)
    if str(Path.cwd()) not in sys.path and "" not in sys.path:
        sys.path.insert(0, str(Path.cwd()))
    try:
        return importlib.import_module(spec)
    except ModuleNotFoundError as error:
        if error.name and spec.startswith(error.name):
            raise UserCodeError(f"{option} {spec}: no module named {error.name!r} (looked in the current folder "
                                "and the Python path)") from None
        raise UserCodeError(f"{option} {spec}: importing it failed: {type(error).__name__}: {error}") from error
    except Exception as error:
        raise UserCodeError(f"{option} {spec}: importing it failed: {type(error).__name__}: {error}") from error


def _import_file(path: Path, option: str) -> ModuleType:
    path = path.expanduser().resolve()
    if not path.is_file():
        raise UserCodeError(f"{option} {path}: no such file")
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
        spec.loader.exec_module(module)
    except Exception as error:
        del sys.modules[name]
        raise UserCodeError(f"{option} {path}: importing it failed: {type(error).__name__}: {error}") from error
    return module


def load_attribute(reference: str, *, option: str = "--controller") -> Any:
    """`module:attribute` (or `path/file.py:attribute`; dotted attributes allowed). A class is instantiated
    without arguments, so `module:MyController` works like `module:MyController()`."""
    module_name, colon, attribute = reference.rpartition(":")
    if not colon or not module_name or not attribute:
        raise UserCodeError(f"{option} {reference!r}: expected MODULE:ATTRIBUTE, e.g. my_robot.control:avoid")
    value: Any = import_user_code(module_name, option=option)
    for part in attribute.split("."):
        try:
            value = getattr(value, part)
        except AttributeError:
            raise UserCodeError(f"{option} {reference}: {module_name} has no attribute {attribute!r}") from None
    if inspect.isclass(value):
        try:
            value = value()
        except Exception as error:
            raise UserCodeError(f"{option} {reference}: {attribute}() raised "
                                f"{type(error).__name__}: {error}") from error
    return value
