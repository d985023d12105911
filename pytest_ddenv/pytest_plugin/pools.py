"""The pool of probe workers a test's extra runs go to: a reduction's probes and a failure rate's runs.

Worker processes that collect the test and run it (or this process, with one worker), or the session's
distributed cluster (`--ddenv-executor`), opened once per session through `execution.make_cluster` and closed
when the session ends.
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import pytest

from pytest_ddenv.pytest_plugin.options import options_of
from pytest_ddenv.scenario.robot_world import FIXTURE

if TYPE_CHECKING:
    from pytest_ddenv.execution import Pool
    from pytest_ddenv.pytest_plugin.given_example import GivenExample
    from pytest_ddenv.scenario.probe import ProbeResult

_CLUSTER = pytest.StashKey[Any]()
"""The session's cluster of `--ddenv-executor` (dask, a scheduler's address, ...), opened on first use."""
_STATELESS_FIXTURES = {"request", "pytestconfig", "record_property", "record_xml_attribute", "tmp_path_factory"}


def probe_pool(item: pytest.Function, example: GivenExample | None = None,
               warn: Callable[[str], None] | None = None, *, seed: int | None = None) -> Pool[ProbeResult]:
    """A pool serving this test's probes: worker processes that run the test (or this process, with one
    worker), or the session's cluster. `seed`: the probes' base seed (None: the test's own)."""
    from pytest_ddenv.execution import check_executor, make_cluster, make_pool
    from pytest_ddenv.execution.factory import idle_cores
    from pytest_ddenv.media.writer import background_pids
    from pytest_ddenv.pytest_plugin.worker import ItemHandler, PytestJob

    config = item.config
    options = options_of(config)
    workers = default_workers(config)
    count = int(workers) if str(workers).isdigit() else workers
    executor = check_executor(options.executor)
    watchdog = options.watchdog
    if executor is None:
        # Probes run in this process when one worker is asked for, or when 'auto' finds one idle core and the
        # test has no function-scoped fixture a probe would share (else one worker process, where each probe
        # runs the whole test as with more workers). 'auto' counts the earlier reductions' media, made in the
        # background, as idle: they end within seconds, the reduction lasts longer.
        in_process = ItemHandler(item, example, seed) if count == 1 else None
        if count == "auto":
            count = idle_cores(ours=background_pids())
            if count == 1:
                in_process = None if shared_fixtures(item) else ItemHandler(item, example, seed)
        return make_pool(PytestJob.of(item, example=example, seed=seed), count, in_process=in_process,
                         watchdog=watchdog, warn=warn)
    cluster = config.stash.get(_CLUSTER, None)
    if cluster is None:
        cluster = config.stash[_CLUSTER] = make_cluster(executor, count)
    return make_pool(PytestJob.of(item, capture="sys", example=example, seed=seed), count, executor,
                     cluster=cluster, watchdog=watchdog)


def default_workers(config: pytest.Config) -> str:
    """`--ddenv-workers` as given, else "auto" (the idle cores: `execution.idle_cores`), in a pytest-xdist
    worker too: while the other xdist workers run tests that is one core (the probes in this process), and the
    idle cores when the last long reductions run alone at the session's end."""
    given = options_of(config).workers
    return str(given) if given else "auto"


def close_cluster(config: pytest.Config) -> None:
    """Close the session's cluster, if one was opened (`pytest_unconfigure`)."""
    cluster = config.stash.get(_CLUSTER, None)
    if cluster is not None:
        del config.stash[_CLUSTER]
        cluster.close()


def shared_fixtures(item: pytest.Function) -> list[str]:
    """The test's function-scoped fixtures that probes run in this process would share (not made again for
    each run), `robot_world` and stateless ones left out."""
    parameters = set(inspect.signature(item.obj).parameters)
    fixture_info = getattr(item, "_fixtureinfo", None)
    definitions = getattr(fixture_info, "name2fixturedefs", {}) or {}
    return sorted(
        name
        for name in parameters & set(item.funcargs)
        if name != FIXTURE and name not in _STATELESS_FIXTURES
        and all(getattr(d, "scope", "function") == "function" for d in definitions.get(name, ()))
    )


def warn_about_shared_fixtures(item: pytest.Function) -> None:
    """With one worker (this process), the test's function-scoped fixtures are not made again for each run."""
    shared = shared_fixtures(item)
    if shared:
        warnings.warn(
            pytest.PytestWarning(
                f"{item.nodeid}: function-scoped fixture(s) {', '.join(shared)} are not re-created for each "
                "reduction probe with one worker (in this process); every probe reuses their values from the "
                "failing run. With --ddenv-workers 2 or more each probe runs the whole test in a worker."
            ),
            stacklevel=1,
        )
