"""Each reduction setting is declared once (`pytest_ddenv.driver.settings.SETTINGS`): the pytest options, the
ini keys, the `ddenv(...)` marker's arguments and the `ddenv reduce` flags are the declared ones, no more and
no fewer, and each front end checks a value as the declaration says (its own error, naming the place)."""

from __future__ import annotations

import argparse
import re

import pytest

from pytest_ddenv.cli import main as cli
from pytest_ddenv.driver.markers import MarkerError, parse_ddenv_marker
from pytest_ddenv.driver.settings import (
    SETTINGS,
    flag_settings,
    marker_settings,
    option_settings,
)

REDUCE_COMMAND_FLAGS = {
    "-h", "--help", "--json", "--debug", "--predicate", "-p", "--import", "--controller", "--timeout",
    "--scenario", "--robot", "--start", "--goal",
}
"""`ddenv reduce`'s flags that are not reduction settings: what to simulate (world, scenario, predicates, user
code) and the command's output (cli.REDUCE_FLAGS)."""


def _reduce_parser() -> argparse.ArgumentParser:
    commands = next(action for action in cli.build_parser()._actions
                    if isinstance(action, argparse._SubParsersAction))
    parser: argparse.ArgumentParser = commands.choices["reduce"]
    return parser


def test_the_names_of_a_setting_are_unique() -> None:
    for interface in ("name", "option", "marker", "flag"):
        given = [getattr(setting, interface) for setting in SETTINGS if getattr(setting, interface) is not None]
        assert len(given) == len(set(given)), interface


def test_the_pytest_options_and_ini_keys_are_the_declared_ones(pytestconfig: pytest.Config) -> None:
    parser = pytestconfig._parser
    options = {name for option in parser.getgroup("ddenv").options for name in option.names()}
    assert options == {setting.option_name for setting in option_settings()}
    ini_keys = {name for name in parser._inidict if name.startswith("ddenv_")}
    assert ini_keys == {setting.ini_name for setting in option_settings()}


def test_the_markers_line_names_every_marker_argument(pytestconfig: pytest.Config) -> None:
    line = next(line for line in pytestconfig.getini("markers") if line.startswith("ddenv("))
    assert re.findall(r"(\w+)=", line.partition(":")[0]) == [setting.marker for setting in marker_settings()]


@pytest.mark.parametrize("setting", marker_settings(), ids=lambda setting: setting.marker)
def test_each_marker_argument_is_taken_and_checked(setting: object) -> None:
    keyword = getattr(setting, "marker")
    with pytest.raises(MarkerError, match=re.escape(f"ddenv({keyword}=...): ")) as raised:
        parse_ddenv_marker((), {keyword: object()})
    assert "unknown argument" not in str(raised.value)


def test_ddenv_reduce_takes_the_declared_flags() -> None:
    flags = {name for action in _reduce_parser()._actions for name in action.option_strings}
    own = REDUCE_COMMAND_FLAGS | {name for names in cli.REDUCE_FLAGS for name in names}
    assert flags - own == {setting.flag_name for setting in flag_settings()}
    assert own <= flags


@pytest.mark.parametrize("setting", [setting for setting in flag_settings()
                                     if setting.name not in ("keep", "same_failure", "skip_unsupported",
                                                             "model_paths")],
                         ids=lambda setting: setting.flag)
def test_each_flag_is_checked_as_declared(setting: object) -> None:
    flag = getattr(setting, "flag_name")
    with pytest.raises(cli._ArgumentError, match=re.escape(f"argument {flag}: ")):
        cli.build_parser().parse_args(["reduce", "w.yaml", "-p", "stuck", flag, "-1.5?"])


@pytest.mark.parametrize(("keyword", "value", "message"), [
    ("rate", 0, "ddenv(rate=...): expected an integer >= 1 and <= 10000, got 0"),
    ("rate", 10_001, "ddenv(rate=...): expected an integer >= 1 and <= 10000, got 10001"),
    ("rate", "20", "ddenv(rate=...): expected an integer >= 1 and <= 10000, got '20'"),
    ("rate", True, "ddenv(rate=...): expected an integer >= 1 and <= 10000, got True"),
    ("max_failure_rate", 1.0, "ddenv(max_failure_rate=...): expected a number >= 0 and < 1"),
    ("max_failure_rate", -0.1, "ddenv(max_failure_rate=...): expected a number >= 0 and < 1"),
    ("max_failure_rate", float("nan"), "ddenv(max_failure_rate=...): expected a number >= 0 and < 1"),
    ("max_failure_rate", "0.1", "ddenv(max_failure_rate=...): expected a number >= 0 and < 1"),
])
def test_a_bad_rate_marker_argument_is_one_clear_error(keyword: str, value: object, message: str) -> None:
    with pytest.raises(MarkerError, match=re.escape(message)):
        parse_ddenv_marker((), {keyword: value})


def test_the_rate_marker_arguments_are_taken() -> None:
    spec = parse_ddenv_marker((), {"rate": 20, "max_failure_rate": 0.1})
    assert (spec.rate, spec.max_failure_rate) == (20, 0.1)
    assert (parse_ddenv_marker((), {}).rate, parse_ddenv_marker((), {}).max_failure_rate) == (1, 0.0)
