"""The test tiers and the suite's own machinery: the unit tier starts no process (tests/unit_tier.py), and the
libsdformat programs are built once and kept by content (tests/sdformat_build.py)."""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from sdformat_build import build_key, build_sdformat_tool
from suite_order import FIRST, GROUPED
from unit_tier import PROCESS_FIXTURES, ProcessStarted, in_unit_tier

SOURCE = Path(__file__).resolve().parent / "data" / "sdf" / "sdformat_check.cc"


def _nothing() -> None:
    pass


def _process_pool() -> None:
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        pool.submit(_nothing).result()


@pytest.mark.parametrize("start", [
    lambda: subprocess.run([sys.executable, "-c", "pass"], check=False),
    lambda: subprocess.check_output(["true"]),
    lambda: os.system("true"),
    lambda: multiprocessing.get_context("fork").Process(target=_nothing).start(),
    lambda: multiprocessing.get_context("forkserver").Process(target=_nothing).start(),
    lambda: multiprocessing.get_context("spawn").Process(target=_nothing).start(),
    _process_pool,
], ids=["subprocess.run", "check_output", "os.system", "fork", "forkserver", "spawn", "process-pool"])
def test_a_unit_test_that_starts_a_process_fails_naming_it(request: pytest.FixtureRequest,
                                                            start: Callable[[], object]) -> None:
    assert request.node.get_closest_marker("unit") is not None  # this module is in the unit tier
    with pytest.raises(ProcessStarted, match=r"test_tiers\.py::.* is in the unit tier, which starts no process"):
        start()


def test_the_unit_marker_follows_the_folders_modules_and_process_fixtures(request: pytest.FixtureRequest) -> None:
    """Of the tests collected in this session: a slow test or one that requests a process fixture is never
    in the unit tier; the engine's folder is in it; each marked test is one `in_unit_tier` takes."""
    items = request.session.items
    for item in items:
        unit = item.get_closest_marker("unit") is not None
        assert unit == in_unit_tier(item), item.nodeid
        if unit:
            assert item.get_closest_marker("slow") is None, item.nodeid
            assert not PROCESS_FIXTURES.intersection(getattr(item, "fixturenames", ())), item.nodeid
    engine = [item for item in items if "/tests/reduce/" in item.path.as_posix()]
    assert all(item.get_closest_marker("unit") for item in engine)


def test_a_build_is_named_by_its_source_compiler_and_library(tmp_path: Path) -> None:
    changed = tmp_path / "sdformat_check.cc"
    changed.write_bytes(SOURCE.read_bytes() + b"\n")
    key = build_key(SOURCE, "g++ 12.2.0", "-lsdformat12", "12.3.0")
    assert key == build_key(SOURCE, "g++ 12.2.0", "-lsdformat12", "12.3.0")
    assert len({key, build_key(changed, "g++ 12.2.0", "-lsdformat12", "12.3.0"),
                build_key(SOURCE, "g++ 13.1.0", "-lsdformat12", "12.3.0"),
                build_key(SOURCE, "g++ 12.2.0", "-lsdformat12 -lextra", "12.3.0"),
                build_key(SOURCE, "g++ 12.2.0", "-lsdformat12", "12.4.0")}) == 5


def test_the_checker_is_built_once_and_reused(sdformat_check: Path, sdformat_cache: Path) -> None:
    """The session's build sits in the cache under its key; asked again, it is reused, not compiled again."""
    assert sdformat_check.parent == sdformat_cache and sdformat_check.name.startswith("sdformat_check-")
    built = sdformat_check.stat().st_mtime_ns
    assert build_sdformat_tool(SOURCE, sdformat_cache) == sdformat_check
    assert sdformat_check.stat().st_mtime_ns == built
    assert not list(sdformat_cache.glob("*.partial"))


def test_the_modules_with_slow_tests_run_first_each_module_together(request: pytest.FixtureRequest) -> None:
    """tests/suite_order.py: under xdist the long tests start first, not last; a module's tests stay together
    (its module-scoped fixtures are made once per worker)."""
    modules = [item.path for item in request.session.items]
    in_order = list(dict.fromkeys(modules))
    assert [path for index, path in enumerate(modules) if index == 0 or modules[index - 1] != path] == in_order
    slow = {item.path for item in request.session.items if item.get_closest_marker("slow") is not None}
    has_slow = [path in slow for path in in_order]
    assert has_slow == sorted(has_slow, reverse=True), "a module with slow tests after one without"


def test_the_modules_the_order_names_exist() -> None:
    for module in (*FIRST, *GROUPED):
        assert (Path(__file__).resolve().parent / module).is_file(), module
