"""Which physics engine runs a world: its `physics.engine`, made on first use (sim/physics.py is the seam)."""

from __future__ import annotations

from pytest_ddenv.errors import WorldError
from pytest_ddenv.sim.physics import PhysicsEngine
from pytest_ddenv.world.limits import engine_problem


def make_physics(engine: str, source: str | None = None) -> PhysicsEngine:
    """A new physics engine by name (a world's `physics.engine`); WorldError naming `source` and the field when
    the name is unknown or the engine is not installed."""
    problem = engine_problem(engine)
    if problem is not None:
        raise WorldError(problem, source=source, field="physics.engine")
    if engine == "mujoco":
        from pytest_ddenv.sim.mujoco.physics import MujocoPhysics

        return MujocoPhysics()
    from pytest_ddenv.sim.pybullet_physics import PybulletPhysics

    return PybulletPhysics()

