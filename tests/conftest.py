# pytester's in-process runs (pytester.runpytest) take modules imported during the run out of sys.modules
# afterwards, and a C extension cannot be loaded twice in one process ("cannot load module more than once per
# process"). pytest-ddenv imports scipy.stats (the failure-rate test; numpy.fft under it) lazily, so it is
# imported here, once, before any such run.
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import joblib
import pytest
import scipy.stats  # noqa: F401
import yaml  # noqa: F401  # likewise: its C parser (yaml._yaml) outlives a re-import of the yaml package
from engines import ENGINE_PARAMS, PYBULLET_MODULES, installed, known_gap, skip_reason
from sdformat_build import build_sdformat_tool
from suite_order import long_tests_first, make_scheduler
from unit_tier import in_unit_tier, no_process_started

# For the same reason a test must not import a heavy package (dask.distributed, ...) only to check that it is
# installed while a pytester snapshot is active: use importlib.util.find_spec.

pytest_plugins = ["pytester"]

# The suite runs about a hundred reductions: each makes the PNG pictures only, not the animations and the 3D
# recording of the default `--ddenv-media all` (seconds each). tests/test_media.py asks for them explicitly.
# Set here, before any test starts, so that pytester subprocesses and `ddenv` subprocesses inherit it.
os.environ.setdefault("DDENV_MEDIA", "pictures")

# `import mujoco` loads its GLFW bindings, which start a Python process to check the GLFW library's version the
# first time in a process; and mujoco is a C extension too. Imported here once, before any test (no unit-tier test
# starts that process, and no pytester run imports it a second time).
if installed("mujoco"):
    import mujoco  # noqa: F401

# scikit-learn's k-means asks joblib for the number of physical cores, which runs `lscpu` the first time in a
# process. Asked here once, before any test: no unit-tier test starts that process (tests/unit_tier.py).
joblib.cpu_count(only_physical_cores=True)

SDF_DATA = Path(__file__).resolve().parent / "data" / "sdf"


# -- the tiers: `-m unit` (tests/unit_tier.py), `-m "not slow"` (the fast tier), all; the order (suite_order.py) --
@pytest.hookimpl(tryfirst=True)  # before `-m` selects by marker
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if in_unit_tier(item):
            item.add_marker(pytest.mark.unit)
        if item.path.name in PYBULLET_MODULES:
            item.add_marker(pytest.mark.pybullet)
        reason = skip_reason(item)  # tests/engines.py: the `pybullet` and `mujoco` markers
        if reason is not None:
            item.add_marker(pytest.mark.skip(reason=reason))
        gap = known_gap(item)
        if gap is not None:
            item.add_marker(gap)
    items[:] = long_tests_first(items)  # tests/suite_order.py: the modules with slow tests start first


@pytest.hookimpl(optionalhook=True)  # pytest-xdist's hook, in its controller process
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    return make_scheduler(config, log)  # tests/suite_order.py: an expensive module's tests on one worker


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item) -> Iterator[None]:
    if item.get_closest_marker("unit") is None:
        yield
        return
    with no_process_started(item.nodeid):
        yield


# -- the physics engines (tests/engines.py) ----------------------------------------------------------------------
@pytest.fixture(params=ENGINE_PARAMS)
def physics_engine(request: pytest.FixtureRequest) -> str:
    """Each physics engine in turn ("pybullet", "mujoco"); the one not installed is skipped with a reason."""
    return str(request.param)


# -- the libsdformat programs, built once and kept by content (tests/sdformat_build.py) ----------------------
@pytest.fixture(scope="session")
def sdformat_cache(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The pytest cache's folder for the builds (kept from run to run), or this run's temporary folder under
    `-p no:cacheprovider`."""
    cache = getattr(request.config, "cache", None)
    return cache.mkdir("ddenv-sdformat") if cache is not None else tmp_path_factory.mktemp("sdformat")


@pytest.fixture(scope="session")
def sdformat_check(sdformat_cache: Path) -> Path:
    """tests/data/sdf/sdformat_check.cc built: loads SDF files with libsdformat, says `ok, N models` or errors."""
    return build_sdformat_tool(SDF_DATA / "sdformat_check.cc", sdformat_cache)


@pytest.fixture(scope="session")
def sdformat_dump(sdformat_cache: Path) -> Path:
    """tests/data/sdf/sdformat_dump.cc built: what libsdformat reads of an SDF file, one fact a line."""
    return build_sdformat_tool(SDF_DATA / "sdformat_dump.cc", sdformat_cache)
