"""Run settings: control and sensor rates, controller gains, noise levels (all part of a run's key)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from pytest_ddenv.errors import ScenarioError
from pytest_ddenv.validation import expected, is_finite_number, is_integer


@dataclass(frozen=True)
class NoiseSettings:
    """Standard deviations of the seeded noise sources. All zeros = a noise-free run.

    - `start_xy` (m) and `start_yaw` (rad): jitter of the spawn pose, drawn once per run.
    - `actuation`: multiplicative noise on each commanded wheel speed (0.05 = 5 %), per control tick.
    - `odometry`: multiplicative noise on each measured wheel speed used by dead reckoning, per tick.
    - `imu_yaw` (rad): additive noise on the yaw the robot's IMU/compass reports, per tick.
    - `laser` (m): additive noise on each laser range, per ray and scan.
    """

    start_xy: float = 0.05
    start_yaw: float = 0.03
    actuation: float = 0.05
    odometry: float = 0.02
    imu_yaw: float = 0.01
    laser: float = 0.01

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if not is_finite_number(value) or value < 0:
                raise ScenarioError(expected("a finite standard deviation >= 0", value),
                                    field=f"noise.{item.name}")

    @classmethod
    def none(cls) -> NoiseSettings:
        """No noise at all (every run of a world is the same, whatever the seed)."""
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class RunSettings:
    """How a run is simulated besides the world's physics settings.

    Control: the controller runs at `control_rate` Hz and drives to the goal at up to `max_speed` m/s,
    turning at `turn_gain` x heading error (at most `max_turn_rate` rad/s); it slows down for large
    heading errors. Laser: `laser_rays` rays over `laser_fov` rad at `laser_rate` Hz, up to `laser_range` m
    (0 rays = no laser). `avoid_obstacles` turns away from close laser hits (off: the paper's robot was
    blind). Recording: poses are recorded at `record_rate` Hz (at most the control rate). `stop_early`
    ends the run once a predicate fires or the goal is reached.

    `friction` is how a model's `mu` meets the robot's wheels (mu 1): "min" (default) gives pybullet
    `lateralFriction = min(mu, 1)`, so every robot contact gets min(mu, wheel mu) as in Gazebo/ODE, whose
    worlds these are; "product" passes `mu` unchanged and Bullet multiplies the two coefficients (clamped
    at 10), so a mu-1000 patch becomes a surface the skid-steered Husky cannot turn on. See
    docs/simulation.md.
    """

    control_rate: float = 20.0
    laser_rays: int = 90
    laser_rate: float = 5.0
    laser_range: float = 10.0
    laser_fov: float = 2 * math.pi
    avoid_obstacles: bool = False
    noise: NoiseSettings = field(default_factory=NoiseSettings)
    record_rate: float = 20.0
    stop_early: bool = True
    max_speed: float = 1.0
    turn_gain: float = 2.0
    max_turn_rate: float = 0.8
    friction: str = "min"

    def __post_init__(self) -> None:
        for name in ("control_rate", "laser_rate", "laser_range", "laser_fov", "record_rate", "max_speed",
                     "turn_gain", "max_turn_rate"):
            value = getattr(self, name)
            if not is_finite_number(value) or value <= 0:
                raise ScenarioError(expected("a finite number > 0", value), field=f"settings.{name}")
        if not is_integer(self.laser_rays) or self.laser_rays < 0:
            raise ScenarioError(expected("an integer >= 0", self.laser_rays), field="settings.laser_rays")
        if self.friction not in ("min", "product"):
            raise ScenarioError(expected("'min' or 'product'", self.friction), field="settings.friction")
        if not isinstance(self.noise, NoiseSettings):
            raise ScenarioError(expected("a NoiseSettings", self.noise), field="settings.noise")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RunSettings:
        values = dict(data)
        values["noise"] = NoiseSettings(**values.get("noise", {}))
        return cls(**values)
