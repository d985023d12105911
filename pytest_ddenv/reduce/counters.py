"""Counters: what one reduction call spent and saw (decided probes, simulations, cache hits, skips, errors)."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field


@dataclass
class Counters:
    """The counts of one reduction call, shared by the parts that decide candidates (simulations are
    counted from the probes' threads, under a lock)."""

    probes: int = 0
    """Probes decided: results used for a verdict (reduction and calibration runs) in this call."""
    started: int = 0
    """Simulations submitted (every kind); the probe budget counts these."""
    cache_hits: int = 0
    errors: int = 0
    skipped: set[frozenset[str]] = field(default_factory=set)
    errored: set[frozenset[str]] = field(default_factory=set)
    """Candidates rejected on ERROR runs alone (see Decision.errored)."""
    _ran: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def ran(self) -> None:
        """Count a simulation as it starts (called from the probe's thread)."""
        with self._lock:
            self._ran += 1

    @property
    def simulations(self) -> int:
        """Simulations that actually started (cancelled-before-start submissions excluded)."""
        with self._lock:
            return self._ran
