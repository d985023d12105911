"""What a stage found: the world it leaves, what it cost, and its findings in words and as JSON."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pytest_ddenv.reduce import Reduction
    from pytest_ddenv.sim import Run
    from pytest_ddenv.world.model import World


@dataclass
class StageResult:
    """`world`: the world after the stage (the one it started from if it changed nothing). `probes`: the
    candidates the engine decided; `simulations`: every simulation the stage started. `incomplete`: why
    the stage stopped early (a budget), None when it finished."""

    stage: str
    world: World
    probes: int = 0
    simulations: int = 0
    findings: list[str] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
    incomplete: str | None = None
    reduction: Reduction | None = None
    differences: dict[str, Callable[[World], World]] = field(default_factory=dict)
    """Changes of the final world that each broke the failure here (what the nearest passing world may
    apply), by their description."""
    run: Run | None = None
    """A run of `world` that shows what the stage says of it (the nearest passing world: a passing run), when
    one was simulated now (None: decided from the log, or nothing to show)."""

    def to_dict(self) -> dict[str, Any]:
        return {"stage": self.stage, "probes": self.probes, "simulations": self.simulations,
                "findings": list(self.findings), "incomplete": self.incomplete, **self.details}
