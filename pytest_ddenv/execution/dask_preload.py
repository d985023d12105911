"""A dask WorkerPlugin that imports modules on every worker, current and future (needs distributed)."""

from __future__ import annotations

import importlib
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin


class PreloadModules(WorkerPlugin):
    """Import `modules` on each worker (e.g. the module that registers a custom robot)."""

    name = "pytest-ddenv-preload"

    def __init__(self, modules: tuple[str, ...]) -> None:
        self.modules = modules

    def setup(self, worker: Any) -> None:
        for module in self.modules:
            importlib.import_module(module)
