# pytester's in-process runs (pytester.runpytest) take modules imported during the run out of sys.modules
# afterwards, and a C extension cannot be loaded twice in one process ("cannot load module more than once per
# process"). pytest-ddenv imports scipy.stats (the failure-rate test; numpy.fft under it) lazily, so it is
# imported here, once, before any such run.
import scipy.stats  # noqa: F401

pytest_plugins = ["pytester"]
