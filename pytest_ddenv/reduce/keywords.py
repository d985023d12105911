"""The former spelling of `reduce()`: its settings as keywords (`reduce(elements, probe, max_probes=10,
deflake=0, ...)`) instead of one `ReductionSettings`."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from pytest_ddenv.errors import ReductionError
from pytest_ddenv.reduce.settings import SETTING_NAMES, ReductionSettings
from pytest_ddenv.reduce.types import Reduction

ARGUMENTS = ("elements", "probe", "settings", "geometry", "reference", "log", "executor", "on_progress")
"""The arguments of `reduce()` (beside the settings' names)."""


def keyword_settings(function: Callable[..., Reduction]) -> Callable[..., Reduction]:
    """The former spelling `reduce(elements, probe, max_probes=10, deflake=0, ...)` still works: each keyword
    that names a `ReductionSettings` field goes into the settings (not beside a `settings=` of its own)."""

    @functools.wraps(function)
    def reduce(*arguments: Any, **keywords: Any) -> Reduction:
        named = {name: keywords.pop(name) for name in SETTING_NAMES if name in keywords}
        unknown = sorted(set(keywords) - set(ARGUMENTS))
        if unknown:
            raise ReductionError(f"reduce() got an unknown argument {unknown[0]!r}; its arguments are "
                                 f"{', '.join(ARGUMENTS)}, and the settings are "
                                 f"ReductionSettings({', '.join(SETTING_NAMES)})")
        if named:
            given = keywords.pop("settings", None) if len(arguments) < 3 else arguments[2]
            if given is not None:
                raise ReductionError(f"reduce(): {', '.join(named)} given beside settings=; put them in the "
                                     "ReductionSettings")
            keywords["settings"] = ReductionSettings(**named)
            arguments = arguments[:2]
        return function(*arguments, **keywords)

    return reduce
