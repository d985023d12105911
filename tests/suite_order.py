"""The order the suite runs in: the modules with `slow` tests first, the rest after them.

Under pytest-xdist (`pytest -n auto`, CI's command) the tests are handed to the workers in collection order, so
a long test collected last (the examples, the paper's scenarios, the shipped worlds' reductions: `tests/test_*.py`
sorts after the folders) starts when the other worker has nothing left to do and the run waits for it alone.
Started first, the long tests run side by side and the many short ones fill the end on both workers.

Whole modules move, each in its own order: a module's tests stay together, so a module-scoped fixture is still
made once per worker (a test that moved alone would make it a second time). Nothing else changes: the same
tests are collected, `-m` selects from them as before, and without xdist the order only shifts which module
runs first.
"""

from __future__ import annotations

from pathlib import Path

import pytest

FIRST = (
    "test_paper_regression.py", "test_paper_regression_mujoco.py", "test_friction_drift.py", "test_examples.py",
    "test_tabletop_reduction.py", "test_reduce_scenarios.py", "test_controller_matters.py",
)
"""Modules (relative to tests/) that start before the other slow ones: their single tests are the longest
(whole reductions of the shipped scenarios and examples, a minute or more each on a quiet machine)."""

TESTS = Path(__file__).resolve().parent


def rank(path: Path, slow_modules: set[Path]) -> int:
    """0: a module of FIRST, 1: another module with a slow test, 2: the rest."""
    try:
        relative = path.relative_to(TESTS).as_posix()
    except ValueError:  # a test outside tests/ (a pytester run's own files are in their own session)
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
