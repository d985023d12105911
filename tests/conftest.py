# pytester's in-process runs (pytester.runpytest) take modules imported during the run out of sys.modules
# afterwards, and a C extension cannot be loaded twice in one process ("cannot load module more than once per
# process"). pytest-ddenv imports scipy.stats (the failure-rate test; numpy.fft under it) lazily, so it is
# imported here, once, before any such run.
import scipy.stats  # noqa: F401
import yaml  # noqa: F401  # likewise: its C parser (yaml._yaml) outlives a re-import of the yaml package

# For the same reason a test must not import a heavy package (dask.distributed, ...) only to check that it is
# installed while a pytester snapshot is active: use importlib.util.find_spec.

pytest_plugins = ["pytester"]

# The suite runs about a hundred reductions: each makes the PNG pictures only, not the animations and the 3D
# recording of the default `--ddenv-media all` (seconds each). tests/test_media.py asks for them explicitly.
# Set here, before any test starts, so that pytester subprocesses and `ddenv` subprocesses inherit it.
import os  # noqa: E402

os.environ.setdefault("DDENV_MEDIA", "pictures")
