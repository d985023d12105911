"""`RobotWorld`: what a scenario test gets from the `robot_world` fixture, and `RobotFailure`.

No pytest import: the same object serves the pytest fixture, the `ddenv` command and user scripts.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from pytest_ddenv.markers import PredicateSpec
from pytest_ddenv.world import World

if TYPE_CHECKING:
    from pytest_ddenv.oracle import FailureSignature
    from pytest_ddenv.sim import Run, RunSettings

SimulateFn = Callable[..., "Run"]
ATTEMPT_SEED_STRIDE = 1_000_003
"""Re-run k of a probe uses seed + k * stride, so deflaking re-runs never collide with a test's own seeds."""


class RobotFailure(AssertionError):
    """A failure predicate fired while the robot ran. Carries the failure signature and the run."""

    def __init__(self, signature: FailureSignature, run: Run) -> None:
        self.signature = signature
        self.run = run
        super().__init__(signature.explain())


class RobotWorld:
    """A world bound to a scenario test: run the robot in it, see the runs made so far.

    `run()` simulates the world's scenario with the test's failure predicates; when one fires it raises
    `RobotFailure` (an `AssertionError`), so the test fails with a one-paragraph explanation.
    """

    def __init__(
        self,
        world: World,
        *,
        predicates: Sequence[PredicateSpec] = (),
        seed: int = 0,
        attempt: int = 0,
        simulate: SimulateFn | None = None,
    ) -> None:
        self.world = world
        self.predicates = tuple(predicates)
        self.seed = seed
        self.attempt = attempt
        self.runs: list[Run] = []
        self._simulate = simulate

    def __repr__(self) -> str:
        return f"RobotWorld({self.world.name or self.world.source!r}, {len(self.world)} models, seed={self.seed})"

    def rebound(self, world: World, *, attempt: int, simulate: SimulateFn | None = None) -> RobotWorld:
        """The same test setup on another world and attempt (what a reduction probe runs).

        `simulate` replaces where the simulation runs (e.g. a worker pool's `simulate`).
        """
        return RobotWorld(
            world, predicates=self.predicates, seed=self.seed, attempt=attempt, simulate=simulate or self._simulate
        )

    def run(
        self,
        *,
        seed: int | None = None,
        timeout: float | None = None,
        settings: RunSettings | None = None,
        raise_on_failure: bool = True,
        **predicate_overrides: Any,
    ) -> Run:
        """Simulate the scenario once; raise `RobotFailure` if a failure predicate fires.

        `seed` defaults to the test's seed; `timeout` (simulated seconds) to the world file's.
        """
        from pytest_ddenv.oracle import make_predicate
        from pytest_ddenv.sim import RunSettings, simulate

        if predicate_overrides:
            raise TypeError(f"run() got unexpected keyword argument(s): {', '.join(sorted(predicate_overrides))}")
        predicates = [make_predicate(spec.name, **spec.params) for spec in self.predicates]
        effective_seed = (self.seed if seed is None else seed) + self.attempt * ATTEMPT_SEED_STRIDE
        simulate_fn = self._simulate or simulate
        result = simulate_fn(
            self.world, seed=effective_seed, predicates=predicates, settings=settings or RunSettings(), timeout=timeout
        )
        self.runs.append(result)
        if raise_on_failure and result.failure is not None:
            raise RobotFailure(result.failure, result)
        return result
