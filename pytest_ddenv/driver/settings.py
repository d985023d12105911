"""The reduction's settings, each declared once: its name, help, default, accepted values and the names each
front end gives it.

A `Setting` is taken as the pytest option `--ddenv-{option}` with its ini key `ddenv_{option}`
(`pytest_plugin/options.py`), as the `ddenv(...)` marker argument `marker` (`driver/markers.py`) and as the
`ddenv reduce` flag `--{flag}` (`cli/parser.py`); each front end builds its options, keys, arguments and flags
from `SETTINGS`, so that a new setting is one more entry here (and its use where the reduction reads it).
`Setting.check(value, where)` checks a value given in Python (a marker argument), `Setting.check_text(text,
where)` one given as text (an option, an ini key, a flag); both raise `SettingError` worded "{where}: expected
..., got ...", which each front end raises as its own error (`pytest.UsageError`, `MarkerError`, the `ddenv`
command's usage error, exit 2). The engine's own settings, for `reduce()` in Python, are
`reduce.ReductionSettings`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from pytest_ddenv import defaults
from pytest_ddenv.errors import DdenvError, shown
from pytest_ddenv.validation import at_least, expected, is_finite_number, positive_finite

RUN_TIMEOUT = 300.0
"""The default of `run_timeout`: `robot_world.DEFAULT_MAX_WALL_TIME`."""

MAX_RATE_RUNS = 10_000
"""The most runs `--ddenv-rate` takes (each run is a whole simulation)."""

MAX_STAGE_ITEMS = 20
MAX_STAGE_NAME = 40
"""Bounds of a list of stages as given (the names are short words): what is beyond is refused unread."""


class SettingError(DdenvError, ValueError):
    """A setting's value is not one it accepts; the message names where it was given."""


Check = Callable[[Any, str, bool], Any]
"""(value, where, given as text) -> the value checked; SettingError otherwise."""


@dataclass(frozen=True)
class Setting:
    """One setting of a reduction and the names it has in each front end (None: not taken there)."""

    name: str
    """Its field in `ReductionSpec` and `DdenvOptions`."""
    help: str
    kind: Check
    metavar: str = "VALUE"
    default: Any = None
    """The value when it is given nowhere (the `ddenv reduce` flag's default; the pytest option's is None: the
    marker's value, else this)."""
    option: str | None = None
    marker: str | None = None
    flag: str | None = None
    ini_type: Literal["string", "bool"] = "string"
    choices: Callable[[], Sequence[str]] | None = None
    """The accepted words, aliases included, for a setting that is a choice (the flag's `choices`)."""

    @property
    def option_name(self) -> str:
        return f"--ddenv-{self.option}"

    @property
    def ini_name(self) -> str:
        return f"ddenv_{str(self.option).replace('-', '_')}"

    @property
    def flag_name(self) -> str:
        return f"--{self.flag}"

    def check(self, value: Any, where: str) -> Any:
        return self.kind(value, where, False)

    def check_text(self, text: Any, where: str) -> Any:
        return self.kind(text, where, True)


# -- kinds of values ---------------------------------------------------------------------------------------


def integer(minimum: int) -> Check:
    """An integer >= `minimum` (as text: its digits)."""

    def check(value: Any, where: str, text: bool) -> int:
        number = at_least(value, minimum, text=text)
        if number is None:
            raise SettingError(expected(f"an integer >= {minimum}", value, where))
        return number

    return check


def positive(unit: str = "") -> Check:
    """A positive, finite number (of `unit`)."""

    def check(value: Any, where: str, text: bool) -> float:
        number = positive_finite(value, text=text)
        if number is None:
            raise SettingError(expected(f"a positive, finite number{unit}", value, where))
        return number

    return check


def run_count(value: Any, where: str, text: bool) -> int:
    """The runs of a failure-rate verdict: an integer from 1 to `MAX_RATE_RUNS`."""
    number = at_least(value, 1, text=text)
    if number is None or number > MAX_RATE_RUNS:
        raise SettingError(expected(f"an integer >= 1 and <= {MAX_RATE_RUNS}", value, where))
    return number


def failure_rate(value: Any, where: str, text: bool) -> float:
    """A failure rate a test may have: a number >= 0 and < 1 (0.1: one run in ten)."""
    number: Any = value
    if text and isinstance(value, str):
        try:
            number = float(value)
        except ValueError:
            number = None
    if not is_finite_number(number) or not 0 <= float(number) < 1:
        raise SettingError(expected("a number >= 0 and < 1 (a failure rate, 0.1 for 10 %)", value, where))
    return float(number)


def workers(value: Any, where: str, text: bool) -> int | str:
    """'auto' (the idle cores) or a number of worker processes >= 1."""
    if value == "auto":
        return "auto"
    number = at_least(value, 1, text=text)
    if number is None:
        raise SettingError(expected("an integer >= 1 or 'auto'", value, where))
    return number


def probe_timeout(value: Any, where: str, text: bool) -> float | str:
    """Seconds, 'auto' or 'none' (see `watchdog`)."""
    word = str(value).strip().lower()
    if word in ("auto", "none"):
        return word
    number = positive_finite(word, text=True) if isinstance(value, str) else positive_finite(value)
    if number is None:
        raise SettingError(expected("a positive, finite number of seconds, 'auto' or 'none'", value, where))
    return number


def watchdog(timeout: float | str | None) -> Any:
    """A probe timeout as the pools' `watchdog` argument: None (not given) is DEFAULT ($DDENV_PROBE_TIMEOUT, else
    auto), 'none' is None (no limit)."""
    from pytest_ddenv.execution.base import DEFAULT

    return DEFAULT if timeout is None else None if timeout == "none" else timeout


def choice(title: str, choices: Callable[[], Sequence[str]], aliases: Callable[[], Mapping[str, str]]) -> Check:
    """One of `choices()`, or an alias of one (the name it stands for is returned)."""

    def check(value: Any, where: str, text: bool) -> str:
        known = choices()
        named = aliases().get(value, value) if isinstance(value, str) else value
        if not isinstance(named, str) or named not in known:
            raise SettingError(f"{where}: unknown {title} {shown(value)}; valid choices: {', '.join(known)}")
        return named

    return check


def deflake(value: Any, where: str, text: bool) -> int | str:
    """An integer >= 0 (re-runs of a non-reproducing candidate) or a named policy ('adaptive', 'auto')."""
    from pytest_ddenv.reduce.deflake import DEFLAKE_POLICIES, MAX_DEFLAKE

    if isinstance(value, str) and value in DEFLAKE_POLICIES:
        return value
    number = at_least(value, 0, text=isinstance(value, str))
    if number is None or number > MAX_DEFLAKE:
        raise SettingError(expected(f"an integer >= 0 and <= {MAX_DEFLAKE} or one of {', '.join(DEFLAKE_POLICIES)}",
                                    value, where))
    return number


def stages(value: Any, where: str, text: bool) -> tuple[str, ...]:
    """The stages after the model-level reduction: 'models,shapes,...', a list of names, or 'all'."""
    from pytest_ddenv.stages import StagesError, parse_stages

    if not isinstance(value, (str, list, tuple)):
        raise SettingError(expected("a comma-separated string or a list of stage names", value, where))
    items = value.split(",") if isinstance(value, str) else list(value)
    if len(items) > MAX_STAGE_ITEMS or any(not isinstance(item, str) or len(item) > MAX_STAGE_NAME
                                           for item in items):  # no stage name is long: keep the message short
        raise SettingError(expected(f"at most {MAX_STAGE_ITEMS} stage names of at most {MAX_STAGE_NAME} characters "
                                    "each, comma-separated or in a list", value, where))
    try:
        return parse_stages(value)
    except StagesError as error:
        raise SettingError(f"{where}: {error}") from None


def media(value: Any, where: str, text: bool) -> str:
    """'all', 'pictures', 'none' or a list of pictures, animations, rrd, mcap (None or empty: $DDENV_MEDIA,
    else all)."""
    from pytest_ddenv.media.writer import MediaChoiceError, media_choice

    try:
        return media_choice(value, where)
    except MediaChoiceError as error:
        raise SettingError(str(error)) from None


def executor(value: Any, where: str, text: bool) -> str:
    """'local', 'dask', a dask scheduler's address, 'ray' or a Ray cluster's ray:// address."""
    from pytest_ddenv.execution.factory import executor_problem

    problem = executor_problem(value) if isinstance(value, str) else expected("a string", value)
    if problem is not None:
        raise SettingError(f"{where}: {problem}")
    return str(value)


def same_failure(value: Any, where: str, text: bool) -> str:
    """'all', 'place', 'touched', or a function same_failure(reference, signature) -> bool ("module:qualname")."""
    from pytest_ddenv.oracle.verdict import same_failure_match

    try:
        return same_failure_match(value, where)
    except DdenvError as error:
        raise SettingError(str(error)) from None


def engine(value: Any, where: str, text: bool) -> str:
    """A physics engine that is installed here: 'pybullet' or 'mujoco'."""
    from pytest_ddenv.world.limits import engine_problem

    problem = engine_problem(value)
    if problem is not None:
        raise SettingError(f"{where}: {problem}")
    return str(value)


MAX_CONFIRM_ENGINES = 8
"""Names a list of engines to confirm in may hold as given (there are two engines): what is beyond is refused
unread."""


def engines(value: Any, where: str, text: bool) -> tuple[str, ...]:
    """Physics engines installed here, comma-separated ('mujoco', 'pybullet,mujoco') or a list; each once."""
    if not isinstance(value, (str, list, tuple)):
        raise SettingError(expected("a comma-separated string or a list of engine names", value, where))
    items = [item.strip() for item in value.split(",")] if isinstance(value, str) else list(value)
    if not items or len(items) > MAX_CONFIRM_ENGINES:
        raise SettingError(expected(f"1 to {MAX_CONFIRM_ENGINES} engine names", value, where))
    return tuple(dict.fromkeys(engine(item, where, text) for item in items))


def names(value: Any, where: str, text: bool) -> tuple[str, ...]:
    """Model names: one, or a list of them."""
    given = (value,) if isinstance(value, str) else value
    if not isinstance(given, (list, tuple, set, frozenset)) or not all(isinstance(name, str) for name in given):
        raise SettingError(expected("a list of model names", value, where))
    return tuple(given)


def non_empty(value: Any, where: str, text: bool) -> str:
    if not isinstance(value, str) or not value:
        raise SettingError(expected("a non-empty string", value, where))
    return value


def folders(value: Any, where: str, text: bool) -> tuple[str, ...]:
    """Folders separated by the system's path separator (':')."""
    return tuple(folder for folder in str(value or "").split(os.pathsep) if folder)


def flag(value: Any, where: str, text: bool) -> bool:
    if not isinstance(value, bool):
        raise SettingError(expected("True or False", value, where))
    return value


def budget(value: Any, where: str, text: bool) -> dict[str, Any]:
    """A probe count or {'probes': N, 'seconds': S}: the `max_probes` and `max_seconds` it sets."""
    if not isinstance(value, bool) and isinstance(value, int):
        return {"max_probes": integer(1)(value, where, False)}
    if isinstance(value, Mapping) and value and set(value) <= {"probes", "seconds"}:
        given: dict[str, Any] = {}
        if "probes" in value:
            given["max_probes"] = integer(1)(value["probes"], where, False)
        if "seconds" in value:
            given["max_seconds"] = positive()(value["seconds"], where, False)
        return given
    raise SettingError(expected("a probe count or {'probes': N, 'seconds': S}", value, where))


def _partitions() -> Sequence[str]:
    from pytest_ddenv.reduce.partition import PARTITIONS

    return PARTITIONS


def _partition_aliases() -> Mapping[str, str]:
    from pytest_ddenv.reduce.partition import PARTITION_ALIASES

    return PARTITION_ALIASES


def _priorities() -> Sequence[str]:
    from pytest_ddenv.reduce.priority import PRIORITIES

    return PRIORITIES


def _priority_aliases() -> Mapping[str, str]:
    from pytest_ddenv.reduce.priority import PRIORITY_ALIASES

    return PRIORITY_ALIASES


def _granularities() -> Sequence[str]:
    from pytest_ddenv.reduce.settings import GRANULARITIES

    return GRANULARITIES


def _no_aliases() -> Mapping[str, str]:
    return {}


# -- the settings ------------------------------------------------------------------------------------------

SETTINGS: tuple[Setting, ...] = (
    Setting("reduce", "when a robot scenario test fails, reduce its world to the models the failure needs",
            flag, option="reduce", ini_type="bool", default=False),
    Setting("artifacts", "folder for minimal worlds, run logs and summaries (default: ddenv-artifacts); a relative "
            "path is relative to the folder pytest runs in (in an ini file: to that file's folder)",
            non_empty, "DIR", option="artifacts"),
    Setting("world", "run every robot test against this world file instead of its own (e.g. a minimal.yaml)",
            non_empty, "PATH", option="world", marker="world"),
    Setting("engine", "the physics engine that simulates the world: pybullet or mujoco (default: the world file's "
            "physics.engine, else pybullet where it is installed, otherwise mujoco)", engine, "ENGINE",
            option="engine", marker="engine", flag="engine"),
    Setting("model_paths", "extra folders (separated by ':') searched for SDF <include>s of model://NAME",
            folders, "DIRS", option="model-path", flag="model-path"),
    Setting("partition", "partition schema (default model2model)", choice("partition", _partitions,
            _partition_aliases), "SCHEMA", defaults.PARTITION, marker="partition", flag="partition",
            choices=lambda: [*_partitions(), *_partition_aliases()]),
    Setting("priority", "priority schema (default avg-trajectory-proximal)", choice("priority", _priorities,
            _priority_aliases), "SCHEMA", defaults.PRIORITY, marker="priority", flag="priority",
            choices=lambda: [*_priorities(), *_priority_aliases()]),
    Setting("n_partitions", "parts of the first split (default 2)", integer(2), "N", defaults.N_PARTITIONS,
            marker="n_partitions", flag="n-partitions"),
    Setting("granularity", "how the split refines: ddmin (the default) or paper", choice("granularity",
            _granularities, _no_aliases), "RULE", defaults.GRANULARITY, marker="granularity", flag="granularity",
            choices=_granularities),
    Setting("deflake", "re-runs of a candidate that did not reproduce the failure: an integer, 'adaptive', or "
            "'auto' (the default: calibrated on the original world's failure rate)", deflake, "N|adaptive|auto",
            defaults.DEFLAKE, option="deflake", marker="deflake", flag="deflake"),
    Setting("tolerance", "same failure: failure position within this many metres (default 0.5)", positive(),
            "M", defaults.TOLERANCE, marker="tolerance", flag="tolerance"),
    Setting("same_failure", "which failures are the one reduced: 'all' (the default: same predicate, within the "
            "tolerance, touching one of the models it touched), 'place' (touched models ignored), 'touched' "
            "(place ignored) or MODULE:FUNCTION, a function same_failure(reference, signature) -> bool",
            same_failure, "RULE", defaults.SAME_FAILURE, marker="same_failure", flag="same-failure"),
    Setting("keep", "never remove this model", names, "MODEL", (), marker="keep", flag="keep"),
    Setting("seed", "base seed of every robot run and of the schemas (default: the marker's seed, else 0)",
            integer(0), "N", defaults.SEED, option="seed", marker="seed", flag="seed"),
    Setting("rate", "run each robot_world test N times (run i with seed + i * 1000003; runs 1..N-1 on the "
            "reduction's worker pool) and judge it by its failure rate and its Wilson interval at 95 percent "
            f"(default 1: run once); at most {MAX_RATE_RUNS}", run_count, "N", 1, option="rate", marker="rate"),
    Setting("max_failure_rate", "with --ddenv-rate: the failure rate a test may have; it fails when the lower end "
            "of its Wilson interval (95 percent) is above this (default 0: any failing run fails it)", failure_rate,
            "RATE", 0.0, option="max-failure-rate", marker="max_failure_rate"),
    Setting("budget", "a probe count or {'probes': N, 'seconds': S}", budget, marker="budget"),
    Setting("max_probes", "stop a reduction after this many simulations (best world so far is kept)", integer(1),
            "N", option="max-probes", flag="max-probes"),
    Setting("max_seconds", "stop a reduction after this many wall-clock seconds", positive(" of seconds"),
            "SECONDS", option="max-time", flag="max-time"),
    Setting("skip_unsupported", "drop the models that cannot be simulated (a warning names each) instead of "
            "refusing the world", flag, marker="skip_unsupported", flag="skip-unsupported", default=False),
    Setting("stages", "what to do after the model-level reduction, comma-separated: models (always), shapes, "
            "attributes, time, explain, passing, or 'all' (default: models,explain,passing; under pytest the "
            "marker's stages= when not given on the command line)", stages, "LIST",
            option="stages", marker="stages", flag="stages"),
    Setting("confirm_engines", "after the reduction, run the minimal and the original world in these physics "
            "engines too, comma-separated (pybullet, mujoco), as often as the reduction's own fresh runs of each, "
            "and report both failure rates; a failure another engine does not reproduce is flagged as possibly an "
            "artefact of the reduction's engine (the reduction's own engine named here adds nothing: a note says "
            "so)", engines, "ENGINES", (), option="confirm-engines", marker="confirm_engines", flag="confirm-engines"),
    Setting("stage_probes", "simulations each stage after the models may start (default: all of them together "
            "at most twice the model-level simulations)", integer(1), "N", option="stage-probes",
            flag="stage-probes"),
    Setting("media", "what a reduction shows besides its files: 'all' (pictures, original.gif/minimal.gif "
            "animations, recording.rrd when rerun-sdk is installed, recording.mcap when foxglove-sdk is), "
            "'pictures', 'none', or a comma-separated list of pictures, animations, rrd, mcap (the pictures come "
            "with every choice but none) (default: $DDENV_MEDIA, else all)", media, "WHAT", option="media",
            flag="media"),
    Setting("probe_timeout", "wall-clock limit of one probe of a reduction: SECONDS, 'auto' (the default: "
            "max(60 s, 10 x the longest of the original run and the slowest probe)) or 'none'; a probe past it "
            "is an error, not a verdict (default: $DDENV_PROBE_TIMEOUT, else auto)", probe_timeout, "SECONDS",
            option="probe-timeout", flag="probe-timeout"),
    Setting("workers", "simulation worker processes: a number, 'auto' for the cores other processes leave idle "
            "(the default; at least 1), or 1 to simulate in the main process", workers, "N", "auto",
            option="workers", flag="workers"),
    Setting("executor", "where probes simulate: 'local' worker processes (default), 'dask' (a local dask "
            "cluster), tcp://HOST:PORT of a dask scheduler, 'ray' (a local Ray cluster started for the session) "
            "or ray://HOST:PORT of a running Ray cluster (through the Ray client)", executor, "ADDRESS",
            option="executor", flag="executor"),
    Setting("keep_other", "write the smallest worlds of the N most frequent other failures a reduction's probes "
            "met as other-1.yaml ... other-N.yaml in its artifacts folder (default 0: listed in the report and "
            "summary.json only)", integer(0), "N", 0, option="keep-other", flag="keep-other"),
    Setting("run_timeout", "wall-clock seconds one run of the scenario may take (robot_world.run(), every probe "
            "of a reduction, every replayed run) before it ends with ControllerTimeout, an error of the run, never "
            "a verdict (default 300): bounds a controller that is too slow, or a big world on a busy machine",
            positive(" of seconds"), "SECONDS", RUN_TIMEOUT, option="run-timeout", flag="run-timeout"),
)
SETTING: dict[str, Setting] = {setting.name: setting for setting in SETTINGS}


def option_settings() -> tuple[Setting, ...]:
    """The pytest options (and ini keys), in `--help`'s order."""
    return tuple(setting for setting in SETTINGS if setting.option is not None)


def marker_settings() -> tuple[Setting, ...]:
    """The `ddenv(...)` marker's arguments."""
    return tuple(setting for setting in SETTINGS if setting.marker is not None)


def flag_settings() -> tuple[Setting, ...]:
    """The `ddenv reduce` flags."""
    return tuple(setting for setting in SETTINGS if setting.flag is not None)
