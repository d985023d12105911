"""The order the suite runs in: the modules with `slow` tests first, the rest after them; under xdist, the
modules whose module-scoped fixtures are expensive on one worker each.

Under pytest-xdist (`pytest -n auto`, CI's command) the tests are handed to the workers in collection order, so
a long test collected last (the examples, the paper's scenarios, the shipped worlds' reductions: `tests/test_*.py`
sorts after the folders) starts when the other worker has nothing left to do and the run waits for it alone.
Started first, the long tests run side by side and the many short ones fill the end on both workers.

Whole modules move, each in its own order: a module's tests stay together, so a module-scoped fixture is still
made once per worker (a test that moved alone would make it a second time). Nothing else changes: the same
tests are collected, `-m` selects from them as before, and without xdist the order only shifts which module
runs first.

xdist's default distribution (`--dist load`) deals the tests out one by one, so both workers run a part of
every module and each makes the module's fixtures: two Ray heads, two dask clusters, the same reductions twice.
When `-n` is given without `--dist`, tests/conftest.py gives xdist a scheduler (`make_scheduler`) that sends
all the tests of a module in GROUPED to one worker, which makes their fixtures once. A `--dist` given on the
command line is left as it is.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

FIRST = (
    "test_paper_regression.py", "test_paper_regression_mujoco.py", "test_friction_drift.py", "test_examples.py",
    "test_tabletop_reduction.py", "test_reduce_scenarios.py", "test_controller_matters.py", "test_cli_edit_rerun.py",
)
"""Modules (relative to tests/) that start before the other slow ones: their single tests are the longest
(whole reductions of the shipped scenarios and examples, and edits re-reduced: 30 s to 2 min each in
`--durations` on a busy machine)."""

GROUPED = (
    "execution/test_ray_pool.py",  # a Ray head (`ray start --head`) and the pools on it
    "execution/test_pool_dask.py",  # a local dask cluster of 2 workers
    "execution/test_pool_local.py",  # a pool of worker processes
    "stages/test_stages_keep_the_cause.py",  # the two-post gap reduced with every stage
    "test_replay.py",  # the wall world reduced in each engine
    "test_cli.py",  # one `ddenv reduce --json` of the wall world
    "test_reach.py",  # a yard of 300 models and its failing run
    "test_bisect.py",  # a git repository of several commits
    "test_benchmarks_smoke.py",  # the benchmarks' yard problem and its pool
    "test_arm_pictures.py",  # the arm's runs with their full detail
)
"""Modules (relative to tests/) whose tests run on one xdist worker (`make_scheduler`): their module-scoped
fixtures cost seconds to minutes, and the module's tests mostly read them."""

TESTS = Path(__file__).resolve().parent


def module_of(path: Path) -> str | None:
    try:
        return path.relative_to(TESTS).as_posix()
    except ValueError:  # a test outside tests/ (a pytester run's own files are in their own session)
        return None


def make_scheduler(config: pytest.Config, log: Any) -> Any:
    """xdist's `pytest_xdist_make_scheduler` when `-n` came without `--dist`: xdist's scope scheduler with
    one scope per GROUPED module and one per test elsewhere (None: xdist's own choice). xdist runs the
    groups first, then hands the other tests out one at a time, each worker keeping two or three queued.

    (Not `--dist loadgroup` with `xdist_group` marks: pytest-xdist 3.8 names a group by rewriting
    `item._nodeid`, which pytest 9 no longer reads, so the groups fall apart silently.)"""
    if getattr(config.option, "dist", "no") != "load" or any(
            arg.startswith("--dist") for arg in config.invocation_params.args):
        return None
    from xdist.scheduler import LoadScopeScheduling

    grouped = {f"{prefix}{module}" for module in GROUPED for prefix in scope_prefixes(config)}

    class ModuleGroups(LoadScopeScheduling):  # type: ignore[misc]
        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split("::", 1)[0]
            return module if module in grouped else nodeid

    return ModuleGroups(config, log)


def scope_prefixes(config: pytest.Config) -> tuple[str, ...]:
    """How a node id names a module of tests/: relative to the rootdir."""
    try:
        return (TESTS.relative_to(config.rootpath).as_posix() + "/",)
    except ValueError:
        return ()


def rank(path: Path, slow_modules: set[Path]) -> int:
    """0: a module of FIRST, 1: another module with a slow test, 2: the rest."""
    relative = module_of(path)
    if relative is None:
        return 2
    if relative in FIRST:
        return 0
    return 1 if path in slow_modules else 2


def long_tests_first(items: list[pytest.Item]) -> list[pytest.Item]:
    """`items` with the modules that hold slow tests first (FIRST's before the others), each module's tests
    together and in their own order; a stable sort, so the order is the same in every xdist worker."""
    slow_modules = {item.path for item in items if item.get_closest_marker("slow") is not None}
    first_seen: dict[Path, int] = {}
    for index, item in enumerate(items):
        first_seen.setdefault(item.path, index)
    return sorted(items, key=lambda item: (rank(item.path, slow_modules), first_seen[item.path]))
