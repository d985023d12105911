"""The user's code a `ddenv` command names, loaded in this process: the `--import` modules, the `--controller`,
and a `--same-failure MODULE:FUNCTION` rule (`driver/user_code.py` does the importing)."""

from __future__ import annotations

import argparse
from typing import Any


def load_user_code(arguments: argparse.Namespace) -> Any:
    """Import the --import modules now (their registrations are needed to read the options) and load the
    --controller; returns the controller (None: the built-in law)."""
    from pytest_ddenv.driver.user_code import import_user_code, load_attribute

    for spec in arguments.imports:
        import_user_code(spec)
    reference = getattr(arguments, "controller", None)
    return None if reference is None else load_attribute(reference)


def same_failure_rule(text: str, option: str = "--same-failure") -> str:
    """A match as `oracle.SameFailureRule` holds it: all, place, touched, or MODULE:FUNCTION loaded now (a
    file path works as the module, as for --controller) and held as "module:qualname"."""
    from pytest_ddenv.driver.user_code import load_attribute
    from pytest_ddenv.oracle.verdict import MATCHES, same_failure_match

    given: Any = load_attribute(text, option=option) if text not in MATCHES and ":" in text else text
    return same_failure_match(given, option)
