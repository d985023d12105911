"""The `Run` record: everything one simulation produced, as numpy arrays and plain values."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pytest_ddenv.oracle.predicates import FailureSignature
from pytest_ddenv.sim.settings import RunSettings

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RunDetail:
    """What a run records beyond the robot's pose when asked (`pytest_ddenv.detail.recording_detail`), for
    the animations and the 3D recording. Sampled at the run's `times`.

    `bodies`: moving model name -> (T, 7) x y z qx qy qz qw (static models stay where the world puts them).
    `joints`: (T, J) the robot's joint positions in joint index order (wheels turning). `scan_angles` (R,)
    and `scan_ranges` (T, R): the latest laser scan at each time (robot frame, `inf` = no hit; None without a
    laser), from `scan_height` above the robot's base at `scan_origin` (x forward, y left, m). `contacts`: per
    time, (model, x, y, z, normal force) of each point where the robot touches a model, or the ground with a
    part that is not a wheel.
    """

    bodies: Mapping[str, FloatArray]
    joints: FloatArray
    scan_angles: FloatArray | None
    scan_ranges: FloatArray | None
    scan_height: float
    contacts: tuple[tuple[tuple[str, float, float, float, float], ...], ...]
    scan_origin: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True, eq=False)
class Run:
    """One simulated run of a world with a seed.

    Arrays are sampled at `settings.record_rate` (and always at the final tick):
    `times` (T,), `poses` (T, 6) x y z roll pitch yaw of the robot base in the world frame,
    `velocities` (T, 6) linear xyz + angular xyz (world frame), `wheel_contacts` (T, W) normal force on
    each of the robot's W wheels, in the robot's wheel order (the Husky's: front left, front right, rear
    left, rear right; > 0 = touching something).

    `robot` is the robot's name and `footprint` its (length, width) in metres, as drawn in pictures.

    `first_touch` / `last_touch`: model name -> first / last simulated time the robot touched it (checked
    every control tick). `first_sensed`: model name -> first time a laser ray hit it.

    An arm's run (`robot_kind` "arm", docs/writing-tests.md "Arms") records its end effector in the place of
    the base: `poses` and `velocities` are the end effector's, `wheel_contacts` (T, 2) the normal forces on
    the two fingers, `first_touch`/`last_touch` the models any arm link touched, `target_path` (T, 3) the
    target's position (None: a mobile robot, or no target), and `reached_goal` means the target was placed.
    """

    seed: int
    settings: RunSettings
    world_name: str
    model_names: tuple[str, ...]
    times: FloatArray
    poses: FloatArray
    velocities: FloatArray
    wheel_contacts: FloatArray
    first_touch: Mapping[str, float]
    last_touch: Mapping[str, float]
    first_sensed: Mapping[str, float]
    reached_goal: bool
    goal_time: float | None
    failure: FailureSignature | None
    sim_time: float
    wall_time: float
    steps: int
    pybullet_version: str
    robot: str = "husky"
    footprint: tuple[float, float] = (0.99, 0.67)
    detail: RunDetail | None = None
    engine: str = "pybullet"
    """The physics engine that ran it; `engine_version` its version (`pybullet_version` is empty for others)."""
    engine_version: str = ""
    robot_kind: str = "mobile"
    """"mobile" (a wheeled base) or "arm"."""
    target_path: FloatArray | None = None
    """An arm's run: (T, 3) x y z of the target at `times` (None: no target, or a mobile robot)."""

    @property
    def positions(self) -> FloatArray:
        """(T, 3) x y z of the robot base."""
        return self.poses[:, :3]

    @property
    def yaw_rates(self) -> FloatArray:
        """(T,) angular velocity about the world z axis."""
        return self.velocities[:, 5]

    @property
    def touched(self) -> frozenset[str]:
        """Every model the robot touched during the run."""
        return frozenset(self.first_touch)

    @property
    def failed(self) -> bool:
        return self.failure is not None

    def same_trajectory(self, other: Run) -> bool:
        """Bit-identical recorded trajectory (times, poses and velocities)."""
        return (
            np.array_equal(self.times, other.times)
            and np.array_equal(self.poses, other.poses)
            and np.array_equal(self.velocities, other.velocities)
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able data (arrays become nested lists of floats; a mobile robot's as it always was)."""
        data: dict[str, Any] = {
            "seed": self.seed,
            "settings": self.settings.to_dict(),
            "world_name": self.world_name,
            "model_names": list(self.model_names),
            "robot": self.robot,
            "footprint": list(self.footprint),
            "times": self.times.tolist(),
            "poses": self.poses.tolist(),
            "velocities": self.velocities.tolist(),
            "wheel_contacts": self.wheel_contacts.tolist(),
            "first_touch": dict(self.first_touch),
            "last_touch": dict(self.last_touch),
            "first_sensed": dict(self.first_sensed),
            "reached_goal": self.reached_goal,
            "goal_time": self.goal_time,
            "failure": None if self.failure is None else self.failure.to_dict(),
            "sim_time": self.sim_time,
            "wall_time": self.wall_time,
            "steps": self.steps,
            "pybullet_version": self.pybullet_version,
            "engine": self.engine,
            "engine_version": self.engine_version,
        }
        if self.robot_kind != "mobile":
            data["robot_kind"] = self.robot_kind
        if self.target_path is not None:
            data["target_path"] = self.target_path.tolist()
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Run:
        def array(key: str, width: int) -> FloatArray:
            return np.asarray(data[key], dtype=np.float64).reshape(-1, width)

        return cls(
            seed=int(data["seed"]),
            settings=RunSettings.from_dict(data["settings"]),
            world_name=str(data["world_name"]),
            model_names=tuple(data["model_names"]),
            robot=str(data.get("robot", "husky")),
            footprint=_footprint(data.get("footprint", (0.99, 0.67))),
            times=np.asarray(data["times"], dtype=np.float64).reshape(-1),
            poses=array("poses", 6),
            velocities=array("velocities", 6),
            wheel_contacts=_wheel_contacts(data["wheel_contacts"]),
            first_touch={str(k): float(v) for k, v in data["first_touch"].items()},
            last_touch={str(k): float(v) for k, v in data["last_touch"].items()},
            first_sensed={str(k): float(v) for k, v in data["first_sensed"].items()},
            reached_goal=bool(data["reached_goal"]),
            goal_time=None if data["goal_time"] is None else float(data["goal_time"]),
            failure=None if data["failure"] is None else FailureSignature.from_dict(data["failure"]),
            sim_time=float(data["sim_time"]),
            wall_time=float(data["wall_time"]),
            steps=int(data["steps"]),
            pybullet_version=str(data["pybullet_version"]),
            engine=str(data.get("engine", "pybullet")),
            engine_version=str(data.get("engine_version", data["pybullet_version"])),
            robot_kind=str(data.get("robot_kind", "mobile")),
            target_path=None if data.get("target_path") is None else array("target_path", 3),
        )


def _footprint(value: Any) -> tuple[float, float]:
    length, width = (float(v) for v in value)
    return length, width


def _wheel_contacts(value: Any) -> FloatArray:
    loads = np.asarray(value, dtype=np.float64)
    return loads.reshape(len(loads), -1) if loads.size else np.zeros((len(loads), 0))
