"""The reduction's defaults, in one place: the marker, the pytest options, `ddenv reduce` and `reduce()`
all start from these values (and accept the same spellings: the aliases live with the schemas,
`reduce.partition.PARTITION_ALIASES` and `reduce.priority.PRIORITY_ALIASES`)."""

from __future__ import annotations

PARTITION = "model2model"
"""How a world is cut into parts to try removing (docs/algorithm.md)."""
PRIORITY = "avg-trajectory-proximal"
"""Which parts are tried first."""
N_PARTITIONS = 2
"""Parts of the first split (at least 2)."""
GRANULARITY = "ddmin"
"""How the split refines: ddmin's doubling, or the paper's."""
DEFLAKE = "auto"
"""Re-runs of a candidate that did not reproduce the failure: calibrated on the original world's rate."""
TOLERANCE = 0.5
"""Metres between two failure positions of the same predicate that still count as the same failure."""
SEED = 0
"""Base seed of the robot's noise and of the schemas' random choices."""
SAME_FAILURE = "all"
"""How a failure is matched with the reference (`oracle.SameFailureRule`): same predicate, within `TOLERANCE`,
touching one of the models the reference touched."""
