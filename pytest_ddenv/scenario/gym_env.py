"""`RobotEnv`: a scenario test's world as a `gymnasium.Env`, for policies (learned or not) stepped by hand.

Get one from the fixture: `env = robot_world.make_env()` (needs the `gym` extra:
`pip install 'pytest-ddenv[gym]'`). It is the same simulation as `robot_world.run()`: `reset()` starts an
`Episode` on this process's shared simulator with the test's world, failure predicates and seed, and each
`step(action)` is one control tick. A policy whose actions equal what a controller returns gives the very
run `robot_world.run(controller=...)` gives.

Observation space (a `gymnasium.spaces.Dict` of float32 `Box`es; what the robot's own sensors say, with the
seeded noise, never the true pose):

- `"pose"` (3,): x, y by dead reckoning and the IMU yaw in [-pi, pi]; `"goal"` (2,): the goal's x, y.
- `"velocity"` (2,): linear (m/s) and angular (rad/s) as the wheel encoders imply.
- `"wheel_speeds"` (W,): each wheel's measured speed (rad/s) in the robot's wheel order (the Husky: 4).
  Left out for a robot whose encoders report no wheel speeds.
- `"scan"` (R,): the latest laser ranges in [0, max_range] m, robot frame, counterclockwise from behind
  (see `LaserScan`); a ray that hit nothing reads max_range. Left out when the robot has no laser (or
  `settings.laser_rays == 0`).
- `"time"` (1,): simulated seconds since the start, in [0, time limit + one tick].

W and R are fixed when the environment is built: `__init__` starts (and drops) one episode of the world to
read them, so the spaces never change between episodes. `env.last_observation` is the full `Observation`
of the last reset/step (contacts, IMU roll and pitch, scan angles), for policies that want more.

Action space: `Box([-max_speed, -max_turn_rate], [max_speed, max_turn_rate])` from the `RunSettings`, a
`Command(linear, angular)`. With `wheel_actions=True`: `Box([-b, -b], [b, b])`, a `WheelCommand(left,
right)` in rad/s, where `b = (max_speed + max_turn_rate * track * track_factor / 2) / wheel_radius` is the
fastest wheel speed a `Command` inside the body-velocity box asks for (the Husky: about 7.55 rad/s; a robot
without `wheel_radius`/`track` attributes gets `max_speed / 0.1`). Actions are used as given (float64, not
clipped to the box); a NaN or infinite action raises `ControllerError`, a wrong shape `ValueError`. Once
the goal is reached without `stop_early`, the robot is told to stand still, as `robot_world.run()` does.

Reward: the decrease of the true planar distance to the goal since the previous step (m), minus 10 on the
step a failure predicate fires, plus 10 on the step the goal is reached.

Termination: an episode ends when the underlying run ends. `terminated` is True when a failure predicate
fired or the goal was reached (with the default `stop_early`, on that very step); `truncated` when the
time limit ended it without either. `info` holds `"failure"` (the `FailureSignature` as a dict, or None),
`"reached_goal"`, `"time"` and `"goal_distance"` (true, m); `reset()`'s info also the episode's `"seed"`.

Runs: when an episode ends, its `Run` is appended to `robot_world.runs` (once) and returned in
`info["run"]`; an episode left unfinished after at least one step is appended when the next `reset()` or
`close()` drops it. So `robot_world.check()` after stepping raises `RobotFailure` exactly as after
`robot_world.run()`, and a failing policy test is reduced like any other scenario test. `reset()` without
a seed uses `robot_world.run_seed`; `reset(seed=s)` uses `s` shifted like `robot_world.run(seed=s)`, so
that the reduction's re-runs of a probe get distinct seeds either way.

One process runs one episode at a time (the shared simulator holds one world): interleaving two
environments' episodes, or calling `robot_world.run()` mid-episode, breaks the live episode (stepping it
afterwards raises a RuntimeError when another `RobotEnv` took over). Use one process per environment for
vectorised training (`gymnasium.vector.AsyncVectorEnv`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any, Protocol, SupportsFloat

import numpy as np
from numpy.typing import ArrayLike, NDArray

try:
    import gymnasium
    from gymnasium import spaces
except ImportError as _missing:  # pragma: no cover - exercised without the extra installed
    raise ImportError("robot_world.make_env() needs gymnasium: pip install 'pytest-ddenv[gym]'") from _missing

from pytest_ddenv.errors import ControllerError, ControllerTimeout, ScenarioError
from pytest_ddenv.oracle.predicates import Predicate
from pytest_ddenv.sim import shared_simulator
from pytest_ddenv.sim.control import AnyCommand, Command, Observation, WheelCommand
from pytest_ddenv.sim.engine import wall_limit
from pytest_ddenv.sim.episode import Episode
from pytest_ddenv.sim.robot import Robot
from pytest_ddenv.sim.run import Run
from pytest_ddenv.sim.settings import RunSettings
from pytest_ddenv.validation import expected
from pytest_ddenv.world.model import World

__all__ = ["FAILURE_PENALTY", "GOAL_BONUS", "RobotEnv"]

ObsDict = dict[str, NDArray[np.float32]]
GOAL_BONUS = 10.0
"""Reward added on the step the goal is reached."""
FAILURE_PENALTY = 10.0
"""Reward subtracted on the step a failure predicate fires."""
FALLBACK_WHEEL_RADIUS = 0.1
"""Wheel radius (m) assumed for the wheel-speed bound of a robot that does not say its own."""

_holder = 0
"""Which `RobotEnv` start last used this process's shared simulator (see `_claim_simulator`)."""
_starts = 0


class RobotWorldLike(Protocol):
    """What a `RobotEnv` uses of the `RobotWorld` it is made from (`robot_world.make_env()`)."""

    world: World
    seed: int
    max_wall_time: float | None
    runs: list[Run]
    """Each finished episode is appended."""

    @property
    def run_seed(self) -> int:
        """The seed of an episode reset without one: the test's, shifted per reduction re-run."""

    def build_predicates(self) -> list[Predicate]: ...


def _claim_simulator() -> int:
    """A new token for an episode about to be started on the shared simulator; it invalidates the others."""
    global _holder, _starts
    _starts += 1
    _holder = _starts
    return _holder


class RobotEnv(gymnasium.Env[dict[str, Any], NDArray[Any]]):
    """A `RobotWorld`'s scenario as a gymnasium environment (see the module docstring for the spaces,
    the reward, termination and how episodes land in `robot_world.runs`).

    `settings` (default `RunSettings()`) and `timeout` (simulated seconds, default the world file's) are
    what `robot_world.run()` takes; `wheel_actions` switches the action to wheel speeds; `max_wall_time`
    (wall-clock seconds per episode, default the fixture's) raises `ControllerTimeout` when exceeded.
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 - as gymnasium.Env declares it (ClassVar conflicts)

    def __init__(
        self,
        robot_world: RobotWorldLike,
        *,
        settings: RunSettings | None = None,
        timeout: float | None = None,
        wheel_actions: bool = False,
        max_wall_time: float | None = None,
        render_mode: str | None = None,
    ) -> None:
        if render_mode is not None:
            raise ValueError(f"{expected('None', render_mode, 'render_mode')}; RobotEnv renders nothing "
                             "(pictures of a run: pytest_ddenv.render)")
        if settings is not None and not isinstance(settings, RunSettings):
            raise TypeError(expected("a RunSettings", settings, "settings"))
        self.robot_world = robot_world
        self.settings = settings if settings is not None else RunSettings()
        self.timeout = timeout
        self.wheel_actions = bool(wheel_actions)
        self.max_wall_time = wall_limit(robot_world.max_wall_time if max_wall_time is None else max_wall_time)
        self.render_mode = None
        self.last_observation: Observation | None = None
        self._episode: Episode | None = None
        self._token = 0
        self._run: Run | None = None
        self._distance = 0.0
        self._layout(self._start(robot_world.run_seed, ()))

    # -- spaces --------------------------------------------------------------------------------------
    def _layout(self, probe: Episode) -> None:
        """Build both spaces from a throwaway episode (wheel and ray counts, time limit, wheel geometry)."""
        first = probe.observe()
        wheels = len(first.wheel_speeds)
        rays = None if first.scan is None else len(first.scan.ranges)
        self._max_range = float(self.settings.laser_range)
        self._has_wheels, self._has_scan = wheels > 0, rays is not None
        self.observation_space = _observation_space(wheels, rays, self._max_range, probe.limit + probe.tick_dt)
        if self.wheel_actions:
            high = np.full(2, _wheel_bound(probe.robot, self.settings))
        else:
            high = np.array([self.settings.max_speed, self.settings.max_turn_rate])
        self.action_space = _box(-high, high)

    def _encode(self, observation: Observation) -> ObsDict:
        """The observation dict of an `Observation` (new arrays every call)."""
        f32 = np.float32
        encoded: ObsDict = {
            "pose": np.array(observation.pose, dtype=f32),
            "goal": np.array(observation.goal[:2], dtype=f32),
            "velocity": np.array(observation.velocity, dtype=f32),
            "time": np.array([observation.time], dtype=f32),
        }
        if self._has_wheels:
            encoded["wheel_speeds"] = np.array(observation.wheel_speeds, dtype=f32)
        if observation.scan is not None and self._has_scan:
            ranges = np.where(np.isfinite(observation.scan.ranges), observation.scan.ranges, self._max_range)
            encoded["scan"] = np.clip(ranges, 0.0, self._max_range).astype(f32)
        return encoded

    # -- gymnasium API -------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[ObsDict, dict[str, Any]]:
        """Start a new episode (recording the previous one if it was stepped and not yet recorded)."""
        if options:
            raise ValueError(f"RobotEnv.reset() takes no options, got {sorted(options)}; pass settings and "
                             "timeout to robot_world.make_env()")
        super().reset(seed=seed)
        self._drop_episode()
        episode = self._start(self._episode_seed(seed), self.robot_world.build_predicates())
        self._episode, self._run = episode, None
        observation = self._observe(episode)
        self._distance = _goal_distance(episode)
        info = self._info(episode)
        info["seed"] = episode.seed
        if episode.finished:  # decided at the start (e.g. spawned on the goal)
            info["run"] = self._record(episode)
        return observation, info

    def step(self, action: ArrayLike) -> tuple[ObsDict, SupportsFloat, bool, bool, dict[str, Any]]:
        """Apply `action` for one control tick; see the module docstring for reward and termination."""
        episode = self._live_episode()
        command = self._command(action, episode)
        failed_before, reached_before = episode.failure is not None, episode.reached
        episode.act(command)
        self._check_wall_time(episode)
        observation = self._observe(episode)
        reward = self._reward(episode, failed_before, reached_before)
        decided = episode.failure is not None or episode.reached
        terminated = episode.finished and decided
        truncated = episode.finished and not decided
        info = self._info(episode)
        if episode.finished:
            info["run"] = self._record(episode)
        return observation, reward, terminated, truncated, info

    def render(self) -> None:
        """Nothing to render (`render_mode` is always None)."""
        return None

    def close(self) -> None:
        """Record an unfinished episode that was stepped, and drop it."""
        self._drop_episode()
        super().close()

    # -- helpers -------------------------------------------------------------------------------------
    @property
    def episode(self) -> Episode | None:
        """The current episode (None before the first reset and after close)."""
        return self._episode

    def _start(self, seed: int, predicates: Sequence[Predicate]) -> Episode:
        """Start an episode on the shared simulator (which ends any other environment's episode)."""
        self._token = _claim_simulator()
        episode = shared_simulator().start(self.robot_world.world, seed=seed, predicates=predicates,
                                           settings=self.settings, timeout=self.timeout)
        if not isinstance(episode, Episode):
            raise ScenarioError("make_env() drives wheeled robots; this world's robot is an arm")
        return episode

    def _episode_seed(self, seed: int | None) -> int:
        world = self.robot_world
        if seed is None:
            return world.run_seed
        return int(seed) + world.run_seed - world.seed  # shifted per re-run as `run_seed` is

    def _observe(self, episode: Episode) -> ObsDict:
        """Observe the tick (draws its noise unless the episode is finished) and encode it."""
        self.last_observation = episode.observe()
        return self._encode(self.last_observation)

    def _live_episode(self) -> Episode:
        episode = self._episode
        if episode is None:
            raise RuntimeError("call reset() before step()")
        if episode.finished:
            raise RuntimeError("the episode is over (terminated or truncated); call reset() to start another")
        if self._token != _holder:
            raise RuntimeError("another RobotEnv started an episode on this process's shared simulator since this "
                               "environment's reset(), so this episode is gone: a process runs one episode at a "
                               "time (step environments one after another, or one process per environment)")
        return episode

    def _command(self, action: ArrayLike, episode: Episode) -> AnyCommand:
        """The command for `action` (a standstill once the goal is reached, as in `robot_world.run()`)."""
        values = _action_values(action, "wheel speeds (left, right)" if self.wheel_actions else "(linear, angular)")
        if not all(math.isfinite(v) for v in values):
            raise ControllerError(expected("finite numbers", list(values),
                                           f"the policy's action at t = {episode.time:.2f} s"))
        if episode.reached:
            return Command(0.0, 0.0)
        if self.wheel_actions:
            return WheelCommand(values[0], values[1])
        return Command(values[0], values[1])

    def _check_wall_time(self, episode: Episode) -> None:
        limit = self.max_wall_time
        if limit is None or time.perf_counter() - episode.started <= limit:
            return
        self._episode = None  # like robot_world.run(), a run that timed out is not recorded
        raise ControllerTimeout(
            f"the episode took more than its wall-clock limit of {limit:g} s (at t = {episode.time:.2f} s "
            f"simulated of {episode.limit:g} s): the policy or the world is too slow; raise the limit "
            "(robot_world.make_env(max_wall_time=...), --ddenv-run-timeout)"
        )

    def _reward(self, episode: Episode, failed_before: bool, reached_before: bool) -> float:
        distance = _goal_distance(episode)
        reward = self._distance - distance
        self._distance = distance
        if episode.failure is not None and not failed_before:
            reward -= FAILURE_PENALTY
        if episode.reached and not reached_before:
            reward += GOAL_BONUS
        return float(reward)

    @staticmethod
    def _info(episode: Episode) -> dict[str, Any]:
        return {
            "failure": None if episode.failure is None else episode.failure.to_dict(),
            "reached_goal": bool(episode.reached),
            "time": float(episode.time),
            "goal_distance": _goal_distance(episode),
        }

    def _record(self, episode: Episode) -> Run:
        """Append the episode's run to `robot_world.runs`, once; return it."""
        if self._run is None:
            self._run = episode.result()
            self.robot_world.runs.append(self._run)
        return self._run

    def _drop_episode(self) -> None:
        episode = self._episode
        if episode is not None and episode.tick > 0:
            self._record(episode)
        self._episode, self._run = None, None


# -- module helpers ------------------------------------------------------------------------------------
def _observation_space(wheels: int, rays: int | None, max_range: float, time_high: float) -> spaces.Dict:
    inf = np.float32(np.inf)
    boxes: dict[str, spaces.Space[Any]] = {
        "pose": _box(np.array([-inf, -inf, -np.pi], dtype=np.float32), np.array([inf, inf, np.pi], dtype=np.float32)),
        "goal": _box(np.full(2, -inf), np.full(2, inf)),
        "velocity": _box(np.full(2, -inf), np.full(2, inf)),
        "time": _box(np.zeros(1), np.full(1, time_high)),
    }
    if wheels:
        boxes["wheel_speeds"] = _box(np.full(wheels, -inf), np.full(wheels, inf))
    if rays is not None:
        boxes["scan"] = _box(np.zeros(rays), np.full(rays, max_range))
    return spaces.Dict(boxes)


def _box(low: NDArray[Any], high: NDArray[Any]) -> spaces.Box:
    """A float32 Box; the bounds are rounded to float32 first, as the observations are."""
    return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)


def _wheel_bound(robot: Robot, settings: RunSettings) -> float:
    """The largest wheel speed (rad/s) a Command inside the body-velocity action box asks for."""
    if type(robot).drive_wheels is Robot.drive_wheels:
        raise ScenarioError(f"wheel_actions=True, but the robot {robot.name!r} takes Command(linear, angular) only; "
                            "use make_env() without wheel_actions", field="wheel_actions")
    radius = getattr(robot, "wheel_radius", None)
    track = getattr(robot, "track", None)
    if not radius or track is None:
        return float(settings.max_speed / FALLBACK_WHEEL_RADIUS)
    half = settings.max_turn_rate * float(track) * float(getattr(robot, "track_factor", 1.0)) / 2.0
    return float((settings.max_speed + half) / float(radius))


def _action_values(action: ArrayLike, meaning: str) -> tuple[float, float]:
    try:
        array = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(expected(f"2 numbers {meaning}", action, "action")) from error
    if array.shape != (2,):
        raise ValueError(expected(f"2 numbers {meaning}", action, "action", got=f"an array of shape {array.shape}"))
    return float(array[0]), float(array[1])


def _goal_distance(episode: Episode) -> float:
    """True planar distance from the robot to the goal (m)."""
    goal = episode.scenario.goal
    pose = episode.pose
    return float(math.hypot(pose[0] - goal[0], pose[1] - goal[1]))
