"""The installed distribution's version: `pytest_ddenv.__version__` and `ddenv --version`."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("pytest-ddenv")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0"
