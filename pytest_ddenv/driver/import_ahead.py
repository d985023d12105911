"""The heavy modules the engine's schemas and the pictures import on first use (scikit-learn, matplotlib),
imported in a thread while this process waits for its probe workers."""

from __future__ import annotations

import threading

HEAVY_IMPORTS = ("sklearn.cluster", "sklearn.linear_model", "matplotlib.pyplot", "matplotlib.collections")
"""What the schemas and the pictures import on first use (about 1.5 s together): imported while the first
probes run in the workers, so that the engine's first round does not wait for scikit-learn."""


IMPORT_AHEAD_WAIT = 60.0
"""Seconds `run_reduction` waits at its end for the import-ahead thread. CPython 3.11 before 3.11.8 can fail
with "SystemError: AST constructor recursion depth mismatch" when two threads compile source at once (a
fresh install has no .pyc files yet): a reduction that ends early (a failure that does not reproduce) must
not leave the thread compiling while pytest goes on importing (and rewriting) its own plugins."""


_ahead: threading.Thread | None = None
_ahead_lock = threading.Lock()


def import_ahead() -> threading.Thread:
    """Start importing the modules the engine and the pictures need (scikit-learn, matplotlib) in a thread,
    once per process, so that they are loaded by the time they are needed while this process waits for
    its probe workers; the thread (started now or earlier)."""
    global _ahead
    with _ahead_lock:
        if _ahead is None:
            _ahead = threading.Thread(target=_import_heavy_modules, name="ddenv-import-ahead", daemon=True)
            _ahead.start()
        return _ahead


def _import_heavy_modules() -> None:
    import importlib

    for module in HEAVY_IMPORTS:
        if module.startswith("matplotlib"):
            import matplotlib

            matplotlib.use("Agg")  # as render/canvas.py does: no display
        try:
            importlib.import_module(module)
        except ImportError:  # pragma: no cover - the dependencies are installed with the package
            return
