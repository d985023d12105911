"""How the world's friction and restitution become MuJoCo contact parameters (docs/simulation.md, "MuJoCo").

MuJoCo has no friction combination rule of the product or min kind: a contact takes the friction of the geom
with the higher `priority`, and the element-wise max at equal priority. Every geom's priority here falls
as its mu grows (`friction_priority`), so the smaller mu of any pair decides. Under the run's "min" friction
a model's mu is first clamped at the wheels' 1, as in the pybullet engine; under "product" it is left as it
is and a model's geoms rank above the robot's (against a wheel of mu 1 the product is the model's mu).

MuJoCo has no restitution either: a contact is a damped spring, `solref = (timeconst, dampratio)`.
`restitution_solref` maps a coefficient e > 0 to the damping ratio of a mass-spring-damper that bounces
with e, with a time constant the time step resolves.
"""

from __future__ import annotations

import math

import mujoco

from pytest_ddenv.sim.builder import WHEEL_MU

ROBOT_GROUP = 3
"""Geom group of every robot geom: rays leave it out."""
WORLD_GROUP = 0
RAY_GROUPS = (1, 1, 1, 0, 1, 1)
"""The geom groups a ray sees: all but the robot's."""
SOLREF = (0.02, 1.0)
"""MuJoCo's default contact stiffness and damping (time constant s, damping ratio)."""
SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)
TORSION = 0.005
ROLLING = 0.0001
ABOVE_ROBOT = 20_000
"""Added to a world geom's priority under "product" friction: above any robot geom's."""
RESTITUTION_TIMECONST = 0.05
"""A bouncing contact's time constant (s): at MuJoCo's 0.02 and a 1/240 s step a light damping gains energy
(measured: e = 2.0 for a target of 0.7)."""


def friction_priority(mu: float) -> int:
    """A geom priority that makes the smaller mu of a contact pair win: 0 for mu 1, 301 for 0.5, -3000 for
    1000 (MuJoCo uses the higher priority geom's friction)."""
    return round(-1000.0 * math.log10(max(mu, 1e-9)))


def effective_mu(mu: float, friction: str) -> float:
    """The geom's mu for the run's friction rule: min(mu, wheel mu) under "min", mu under "product"."""
    return min(mu, WHEEL_MU) if friction == "min" else mu


def restitution_solref(restitution: float) -> tuple[float, float]:
    """`solref` for a coefficient of restitution: e = exp(-zeta pi / sqrt(1 - zeta^2)), so zeta = -ln e /
    sqrt(pi^2 + ln^2 e); e = 0 keeps MuJoCo's default."""
    if restitution <= 0:
        return SOLREF
    e = min(restitution, 0.999)
    zeta = -math.log(e) / math.sqrt(math.pi**2 + math.log(e) ** 2)
    return max(SOLREF[0], RESTITUTION_TIMECONST), max(zeta, 1e-3)


def set_contact(geom: mujoco.MjsGeom, mu: float, restitution: float, friction: str) -> None:
    """A world geom's contact parameters."""
    mu = effective_mu(mu, friction)
    geom.friction = [mu, TORSION, ROLLING]
    geom.priority = friction_priority(mu) + (ABOVE_ROBOT if friction == "product" else 0)
    geom.condim = 3
    geom.solref = list(restitution_solref(restitution))
    geom.solimp = list(SOLIMP)
    geom.group = WORLD_GROUP
