"""pytest-ddenv: reduce the simulated world of a failing robot scenario test to the objects that matter."""

from importlib.metadata import PackageNotFoundError, version

from pytest_ddenv.errors import DdenvError, ReductionError, ScenarioError, WorldError
from pytest_ddenv.world import Ground, Model, Physics, Pose, Scenario, Shape, World

try:
    __version__ = version("pytest-ddenv")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0"

__all__ = [
    "DdenvError",
    "Ground",
    "Model",
    "Physics",
    "Pose",
    "ReductionError",
    "Scenario",
    "ScenarioError",
    "Shape",
    "World",
    "WorldError",
    "__version__",
]
