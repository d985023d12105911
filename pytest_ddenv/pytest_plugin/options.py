"""The `--ddenv-*` options (and their ini twins): declared, read and checked once, in `pytest_configure`.

`read_options(config)` turns every setting into one frozen `DdenvOptions` (the command line over the ini
file; a bad value is one `pytest.UsageError` that names the option and where it came from, before any test
runs); the plugin keeps it in the config's stash and reads it from there, as pytest's stepwise plugin does.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.driver.artifacts import folder_problem
from pytest_ddenv.driver.settings import SETTING, SettingError, option_settings, watchdog
from pytest_ddenv.errors import DdenvError, shown, shown_path

DEFAULT_ARTIFACTS = "ddenv-artifacts"


@dataclass(frozen=True)
class DdenvOptions:
    """Every `--ddenv-*` setting of a session, checked (None: not given, the marker's or the default)."""

    reduce: bool
    artifacts: Path
    artifacts_given: bool
    deflake: int | str | None
    max_probes: int | None
    max_seconds: float | None
    seed: int | None
    workers: int | str | None
    executor: str | None
    world: str | None
    engine: str | None
    """--ddenv-engine (None: the marker's engine=, else the world's)."""
    model_paths: tuple[str, ...]
    watchdog: Any
    """The pools' `watchdog` argument: seconds, "auto", None (off), or DEFAULT ($DDENV_PROBE_TIMEOUT)."""
    stages_command_line: tuple[str, ...] | None
    stages_ini: tuple[str, ...] | None
    stage_probes: int | None
    run_timeout: float | None
    media: str
    keep_other: int = 0
    """Write the smallest worlds of this many other failures a reduction met (`other-<k>.yaml`)."""
    confirm_engines: tuple[str, ...] | None = None
    """--ddenv-confirm-engines (None: the marker's confirm_engines=, else none)."""
    rate: int | None = None
    """--ddenv-rate (None: the marker's rate=, else 1)."""
    max_failure_rate: float | None = None
    """--ddenv-max-failure-rate (None: the marker's max_failure_rate=, else 0)."""

    def stages_for(self, marker: tuple[str, ...] | None) -> tuple[str, ...] | None:
        """--ddenv-stages, else the marker's stages=, else the ini value (None: the default stages)."""
        if self.stages_command_line is not None:
            return self.stages_command_line
        return marker if marker is not None else self.stages_ini


_options_key = pytest.StashKey[DdenvOptions]()


def stash_options(config: pytest.Config, options: DdenvOptions) -> DdenvOptions:
    """Keep the session's checked settings in its config's stash (`pytest_configure`)."""
    config.stash[_options_key] = options
    return options


def options_of(config: pytest.Config) -> DdenvOptions:
    """The session's checked settings (read once, in `pytest_configure`)."""
    options = config.stash.get(_options_key, None)
    if options is None:  # a config that did not go through pytest_configure (unusual): read them now
        options = stash_options(config, read_options(config))
    return options


def add_options(parser: pytest.Parser) -> None:
    """The `--ddenv-*` options and their ini twins (`ddenv_*`), as `driver/settings.py` declares them."""
    group = parser.getgroup("ddenv", "robot world reduction (pytest-ddenv)")
    for setting in option_settings():
        extra: dict[str, Any] = {"action": "store_true"} if setting.ini_type == "bool" else {"metavar": setting.metavar}
        group.addoption(setting.option_name, dest=setting.ini_name, default=None, help=setting.help, **extra)
        parser.addini(setting.ini_name, setting.help, type=setting.ini_type,
                      default=False if setting.ini_type == "bool" else "")


def _setting(config: pytest.Config, name: str) -> Any:
    """The command-line value of a setting, else its ini value (validated by `_checked`)."""
    value = config.getoption(name)
    return config.getini(name) if value in (None, False) else value


def _where(config: pytest.Config, name: str) -> str:
    """How the user gave a setting: `--ddenv-max-probes` on the command line, else `ddenv_max_probes in
    pytest.ini` (or wherever the ini value came from)."""
    if config.getoption(name) not in (None, False):
        return "--" + name.replace("_", "-")
    return f"{name} in {config.inipath.name}" if config.inipath is not None else f"ini option {name}"


def _checked(config: pytest.Config, name: str, value: Any = None) -> Any:
    """A setting (its command-line value, else its ini value; or `value`) checked as declared; None when not
    given. A usage error naming the option or ini key otherwise."""
    setting = SETTING[name]
    if value is None:
        value = _setting(config, setting.ini_name)
    if value in (None, "") and name != "media":  # media: unset is $DDENV_MEDIA, else all
        return None
    try:
        return setting.check_text(value, _where(config, setting.ini_name))
    except SettingError as error:
        raise pytest.UsageError(str(error)) from None


def _watchdog_setting(config: pytest.Config) -> Any:
    """`--ddenv-probe-timeout` as the pools' `watchdog` argument (`driver.settings.watchdog`); unset, the
    $DDENV_PROBE_TIMEOUT the pools will read is checked now, not when a test fails."""
    timeout = _checked(config, "probe_timeout")
    if timeout is None:
        from pytest_ddenv.execution import PoolConfigError
        from pytest_ddenv.execution.base import DEFAULT, check_watchdog

        try:
            check_watchdog(DEFAULT)
        except PoolConfigError as error:
            raise pytest.UsageError(str(error)) from None
    return watchdog(timeout)


def read_options(config: pytest.Config) -> DdenvOptions:
    """Every ddenv setting, checked now: a bad value is a usage error before any test runs, never an error
    in place of a test's own failure at the end (its lines clipped: a value may be a whole file)."""
    from pytest_ddenv.driver.report_text import clip_lines

    try:
        return _read_options(config)
    except pytest.UsageError as error:
        raise pytest.UsageError(clip_lines(str(error))) from None


def _read_options(config: pytest.Config) -> DdenvOptions:
    try:
        reduce = bool(_setting(config, "ddenv_reduce"))
    except (pytest.UsageError, ValueError) as error:  # pytest before 9.2 raises ValueError for a bad ini bool
        raise pytest.UsageError(f"{_where(config, 'ddenv_reduce')}: expected true or false (or 1/0, yes/no, "
                                f"on/off): {error}") from None
    world = _setting(config, "ddenv_world")
    if world not in (None, "") and not _kind_is(Path(world), "file", config, "ddenv_world"):
        raise pytest.UsageError(f"{_where(config, 'ddenv_world')}: no such file: {shown_path(world)}")
    model_paths = _checked(config, "model_paths") or ()
    for folder in model_paths:
        if not _kind_is(_expanded_setting(folder, config, "ddenv_model_path"), "folder", config, "ddenv_model_path"):
            raise pytest.UsageError(f"{_where(config, 'ddenv_model_path')}: no such folder: {shown_path(folder)}")
    root, given = _artifacts_root(config)
    problem = folder_problem(root) if given or reduce else None
    if problem is not None:
        raise pytest.UsageError(f"{_where(config, 'ddenv_artifacts')}: {problem}")
    return DdenvOptions(
        reduce=reduce, artifacts=root, artifacts_given=given, deflake=_checked(config, "deflake"),
        max_probes=_checked(config, "max_probes"), max_seconds=_checked(config, "max_seconds"),
        seed=_checked(config, "seed"), workers=_checked(config, "workers"), executor=_checked(config, "executor"),
        world=world or None, engine=_checked(config, "engine"), model_paths=model_paths,
        watchdog=_watchdog_setting(config),
        stages_command_line=_checked(config, "stages", config.getoption("ddenv_stages")),
        stages_ini=_checked(config, "stages", config.getini("ddenv_stages") or None),
        stage_probes=_checked(config, "stage_probes"), run_timeout=_checked(config, "run_timeout"),
        media=_checked(config, "media"), keep_other=_checked(config, "keep_other") or 0,
        confirm_engines=_checked(config, "confirm_engines"), rate=_checked(config, "rate"),
        max_failure_rate=_checked(config, "max_failure_rate"),
    )


def _artifacts_root(config: pytest.Config) -> tuple[Path, bool]:
    """Where reductions write (and whether the user chose it): a relative --ddenv-artifacts is relative to
    the folder pytest was started in, a relative ini value to the ini file's folder."""
    option = config.getoption("ddenv_artifacts")
    invocation = Path(config.invocation_params.dir)
    if option not in (None, ""):
        return invocation / _expanded_setting(str(option), config, "ddenv_artifacts"), True
    ini = str(config.getini("ddenv_artifacts") or "")
    if ini:
        base = config.inipath.parent if config.inipath is not None else invocation
        return base / _expanded_setting(ini, config, "ddenv_artifacts"), True
    return invocation / DEFAULT_ARTIFACTS, False


def expand_home(text: str, where: str) -> Path:
    """`text` as a path with a leading `~` or `~NAME` made the home folder (`Path.expanduser`); DdenvError
    naming `where` when there is no such user (or no home folder)."""
    try:
        return Path(text).expanduser()
    except RuntimeError:  # pathlib: "Could not determine home directory."
        user = text[1:].split("/", 1)[0]
        who = f"no user named {shown(user)}" if user else "no home folder is known"
        raise DdenvError(f"{where}: {shown(text)}: {who} (a path starting with ~ or ~NAME is in that user's home "
                         "folder)") from None


def _kind_is(path: Path, kind: str, config: pytest.Config, name: str) -> bool:
    """Whether `path` is a "file" or a "folder"; a usage error naming the setting when the system cannot tell
    (a name too long, a loop of symbolic links)."""
    try:
        return path.is_file() if kind == "file" else path.is_dir()
    except OSError as error:
        raise pytest.UsageError(f"{_where(config, name)}: {shown_path(path)}: {error.strerror or error}") from None


def _expanded_setting(text: str, config: pytest.Config, name: str) -> Path:
    """`expand_home` for a setting: a usage error naming the option or ini key."""
    try:
        return expand_home(text, _where(config, name))
    except DdenvError as error:
        raise pytest.UsageError(str(error)) from None
