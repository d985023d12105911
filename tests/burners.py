"""Real CPU-bound processes beside a test: a machine as busy as a loaded CI runner."""

from __future__ import annotations

import contextlib
import multiprocessing
import time
from collections.abc import Iterator

from pytest_ddenv.execution import cpu_count


def _burn() -> None:  # pragma: no cover - runs in a child process until terminated
    while True:
        sum(i * i for i in range(10_000))


@contextlib.contextmanager
def every_core_busy() -> Iterator[list[int]]:
    """One CPU-bound process per core (and one more), running for the block; their process ids."""
    processes = [multiprocessing.get_context("spawn").Process(target=_burn, daemon=True)
                 for _ in range(cpu_count() + 1)]
    for process in processes:
        process.start()
    try:
        time.sleep(1.0)  # they have started (spawn imports) and are burning
        yield [process.pid for process in processes if process.pid is not None]
    finally:
        for process in processes:
            process.terminate()
        for process in processes:
            process.join()
