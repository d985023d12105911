"""The `--ddenv-*` options (and their ini twins): declared, read and checked once, in `pytest_configure`.

`read_options(config)` turns every setting into one frozen `DdenvOptions` (the command line over the ini
file; a bad value is one `pytest.UsageError` that names the option and where it came from, before any test
runs); the plugin keeps it in the config's stash and reads it from there, as pytest's stepwise plugin does.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from pytest_ddenv.driver.artifacts import folder_problem
from pytest_ddenv.driver.markers import MarkerError, parse_deflake
from pytest_ddenv.errors import DdenvError, shown, shown_path
from pytest_ddenv.execution.factory import executor_problem
from pytest_ddenv.validation import expected

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

    def stages_for(self, marker: tuple[str, ...] | None) -> tuple[str, ...] | None:
        """--ddenv-stages, else the marker's stages=, else the ini value (None: the default stages)."""
        if self.stages_command_line is not None:
            return self.stages_command_line
        return marker if marker is not None else self.stages_ini


def add_options(parser: pytest.Parser) -> None:
    """The `--ddenv-*` options and their ini twins (`ddenv_*`)."""
    group = parser.getgroup("ddenv", "robot world reduction (pytest-ddenv)")
    options: list[tuple[str, str, dict[str, Any]]] = [
        ("reduce", "when a robot scenario test fails, reduce its world to the models the failure needs",
         {"action": "store_true", "ini_type": "bool"}),
        ("artifacts", ("folder for minimal worlds, run logs and summaries (default: ddenv-artifacts); a relative "
                      "path is relative to the folder pytest runs in (in an ini file: to that file's folder)"),
         {"metavar": "DIR"}),
        ("deflake", ("re-runs of a candidate that did not reproduce the failure: an integer, 'adaptive', or "
                    "'auto' (calibrated on the original world's failure rate)"),
         {"metavar": "N"}),
        ("max-probes", "stop a reduction after this many simulations (best world so far is kept)", {"metavar": "N"}),
        ("max-time", "stop a reduction after this many wall-clock seconds", {"metavar": "SECONDS"}),
        ("seed", "base seed of every robot run (default: the marker's seed, else 0)", {"metavar": "N"}),
        ("workers", ("simulation worker processes: a number, 'auto' for one per core (the default), or 1 to "
         "simulate in the pytest process"), {"metavar": "N"}),
        ("executor", ("where probes simulate: 'local' worker processes (default), 'dask' (a local dask cluster) "
         "or tcp://HOST:PORT of a dask scheduler"), {"metavar": "ADDRESS"}),
        ("world", "run every robot test against this world file instead of its own (e.g. a minimal.yaml)",
         {"metavar": "PATH"}),
        ("model-path", "extra folders (separated by ':') searched for SDF <include>s of model://NAME",
         {"metavar": "DIRS"}),
        ("probe-timeout", ("wall-clock limit of one probe of a reduction: SECONDS, 'auto' (the default: max(60 s, "
                          "10 x the longest of the original run and the slowest probe)) or 'none'; a probe past "
                          "it is an error, not a verdict (default: $DDENV_PROBE_TIMEOUT, else auto)"),
         {"metavar": "SECONDS"}),
        ("stages", ("what to do after the model-level reduction, comma-separated: models (always), shapes, "
                   "attributes, time, explain, passing, or 'all' (default: models,explain,passing; the marker's "
                   "stages= when this is not given on the command line)"), {"metavar": "LIST"}),
        ("media", ("what a reduction shows besides its files: 'all' (pictures, original.gif/minimal.gif "
                  "animations, recording.rrd when rerun-sdk is installed), 'pictures' or 'none' (default: "
                  "$DDENV_MEDIA, else all)"), {"metavar": "WHAT"}),
        ("stage-probes", ("simulations each stage after the models may start (default: all of them together at "
                         "most twice the model-level simulations)"), {"metavar": "N"}),
        ("keep-other", ("write the smallest worlds of the N most frequent other failures a reduction's probes "
                       "met as other-1.yaml ... other-N.yaml in its artifacts folder (default 0: listed in the "
                       "report and summary.json only)"), {"metavar": "N"}),
        ("run-timeout", ("wall-clock seconds one robot_world.run() may take before it fails with ControllerTimeout "
                        "(default 300): bounds a controller that is too slow"), {"metavar": "SECONDS"}),
    ]
    for name, help_text, extra in options:
        ini_name = f"ddenv_{name.replace('-', '_')}"
        ini_type = extra.pop("ini_type", "string")
        group.addoption(f"--ddenv-{name}", dest=ini_name, default=None, help=help_text, **extra)
        parser.addini(ini_name, help_text, type=ini_type, default=False if ini_type == "bool" else "")



def _setting(config: pytest.Config, name: str) -> Any:
    """The command-line value of a setting, else its ini value (validated by `_validate_options`)."""
    value = config.getoption(name)
    return config.getini(name) if value in (None, False) else value


def _where(config: pytest.Config, name: str) -> str:
    """How the user gave a setting: `--ddenv-max-probes` on the command line, else `ddenv_max_probes in
    pytest.ini` (or wherever the ini value came from)."""
    if config.getoption(name) not in (None, False):
        return "--" + name.replace("_", "-")
    return f"{name} in {config.inipath.name}" if config.inipath is not None else f"ini option {name}"


def _int_setting(config: pytest.Config, name: str, minimum: int) -> int | None:
    value = _setting(config, name)
    if value in (None, ""):
        return None
    try:
        number = int(value)
    except (TypeError, ValueError):
        number = minimum - 1
    if number < minimum:
        raise pytest.UsageError(expected(f"an integer >= {minimum}", value, _where(config, name)))
    return number


def _media_setting(config: pytest.Config) -> str:
    """--ddenv-media, else the ini value, else $DDENV_MEDIA, else all."""
    from pytest_ddenv.media.writer import MediaChoiceError, media_choice

    value = _setting(config, "ddenv_media")
    try:
        return media_choice(value, _where(config, "ddenv_media"))
    except MediaChoiceError as error:
        raise pytest.UsageError(str(error)) from None


def _positive_seconds(value: Any) -> float | None:
    """`value` (a number or its text) as a positive, finite number of seconds; None if it is not one (nan, inf,
    0, a negative number, a word)."""
    try:
        seconds = float(value)
    except (TypeError, ValueError):
        return None
    return seconds if math.isfinite(seconds) and seconds > 0 else None


def _seconds_setting(config: pytest.Config, name: str) -> float | None:
    value = _setting(config, name)
    if value in (None, ""):
        return None
    seconds = _positive_seconds(value)
    if seconds is None:
        raise pytest.UsageError(expected("a positive, finite number of seconds", value, _where(config, name)))
    return seconds


def _stage_list(config: pytest.Config, value: Any) -> tuple[str, ...] | None:
    from pytest_ddenv.driver.markers import parse_stage_list

    if value in (None, ""):
        return None
    try:
        return parse_stage_list(value, _where(config, "ddenv_stages"))
    except MarkerError as error:
        raise pytest.UsageError(str(error)) from None


def _watchdog_setting(config: pytest.Config) -> Any:
    """`--ddenv-probe-timeout` as the pools' `watchdog` argument: seconds, 'auto', None, or DEFAULT (unset:
    $DDENV_PROBE_TIMEOUT, else auto)."""
    from pytest_ddenv.execution.base import DEFAULT

    value = _setting(config, "ddenv_probe_timeout")
    if value in (None, ""):
        from pytest_ddenv.execution import PoolConfigError
        from pytest_ddenv.execution.base import check_watchdog

        try:  # $DDENV_PROBE_TIMEOUT is read by the pools: checked now, not when a test fails
            check_watchdog(DEFAULT)
        except PoolConfigError as error:
            raise pytest.UsageError(str(error)) from None
        return DEFAULT
    text = str(value).strip().lower()
    if text in ("auto", "none"):
        return None if text == "none" else "auto"
    seconds = _positive_seconds(text)
    if seconds is None:
        raise pytest.UsageError(expected("a positive, finite number of seconds, 'auto' or 'none'", value,
                                         _where(config, "ddenv_probe_timeout")))
    return seconds


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
    deflake = _setting(config, "ddenv_deflake")
    if deflake not in (None, ""):
        try:
            deflake = parse_deflake(deflake, _where(config, "ddenv_deflake"))
        except MarkerError as error:
            raise pytest.UsageError(str(error)) from None
    workers = _setting(config, "ddenv_workers")
    if workers not in (None, "", "auto"):
        workers = _int_setting(config, "ddenv_workers", 1)
    executor = _setting(config, "ddenv_executor")
    problem = executor_problem(str(executor)) if executor not in (None, "") else None
    if problem is not None:
        raise pytest.UsageError(f"{_where(config, 'ddenv_executor')}: {problem}")
    world = _setting(config, "ddenv_world")
    if world not in (None, "") and not _kind_is(Path(world), "file", config, "ddenv_world"):
        raise pytest.UsageError(f"{_where(config, 'ddenv_world')}: no such file: {shown_path(world)}")
    model_paths = tuple(p for p in str(_setting(config, "ddenv_model_path") or "").split(os.pathsep) if p)
    for folder in model_paths:
        if not _kind_is(_expanded_setting(folder, config, "ddenv_model_path"), "folder", config, "ddenv_model_path"):
            raise pytest.UsageError(f"{_where(config, 'ddenv_model_path')}: no such folder: {shown_path(folder)}")
    root, given = _artifacts_root(config)
    problem = folder_problem(root) if given or reduce else None
    if problem is not None:
        raise pytest.UsageError(f"{_where(config, 'ddenv_artifacts')}: {problem}")
    return DdenvOptions(
        reduce=reduce, artifacts=root, artifacts_given=given, deflake=None if deflake in (None, "") else deflake,
        max_probes=_int_setting(config, "ddenv_max_probes", 1),
        max_seconds=_seconds_setting(config, "ddenv_max_time"), seed=_int_setting(config, "ddenv_seed", 0),
        workers=workers or None, executor=executor or None, world=world or None, model_paths=model_paths,
        watchdog=_watchdog_setting(config),
        stages_command_line=_stage_list(config, config.getoption("ddenv_stages")),
        stages_ini=_stage_list(config, config.getini("ddenv_stages")),
        stage_probes=_int_setting(config, "ddenv_stage_probes", 1),
        run_timeout=_seconds_setting(config, "ddenv_run_timeout"), media=_media_setting(config),
        keep_other=_int_setting(config, "ddenv_keep_other", 0) or 0,
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
