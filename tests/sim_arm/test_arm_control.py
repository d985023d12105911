"""An arm's controller contract, its joints' limits, inverse kinematics, and seeded, reproducible runs."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pytest_ddenv import World
from pytest_ddenv.errors import ControllerError
from pytest_ddenv.sim import RunSettings, Simulator
from pytest_ddenv.sim.arm.control import ArmObservation, EndEffectorTarget, GripperCommand, JointTargets
from pytest_ddenv.sim.settings import NoiseSettings

SMOKE = Path(__file__).resolve().parents[1] / "data" / "arm_smoke.yaml"

pytestmark = pytest.mark.pybullet


@pytest.mark.parametrize(("command", "message"), [
    (None, "returned NoneType None; an arm's controller returns JointTargets"),
    (GripperCommand("grab"), "a gripper action 'open' or 'close'"),
    (EndEffectorTarget((0.5, 0.0, math.nan)), "finite numbers"),
    (EndEffectorTarget((0.5, 0.0)), "an end-effector position"),  # type: ignore[arg-type]
    (JointTargets((0.0,) * 6), "JointTargets with 7 positions"),
    (JointTargets((0.0,) * 7, gripper="shut"), "a gripper action"),
])
def test_a_bad_command_names_the_controller_and_the_time(sim: Simulator, smoke: World, command: object,
                                                         message: str) -> None:
    def clumsy(observation: ArmObservation) -> object:
        return command if observation.time > 0.2 else GripperCommand("open")

    with pytest.raises(ControllerError, match=message) as caught:
        sim.run(smoke, controller=clumsy, timeout=1.0)  # type: ignore[arg-type]
    assert "controller test_a_bad_command_names_the_controller_and_the_time.<locals>.clumsy at t = 0.25 s" in str(
        caught.value)


def test_a_mobile_robots_command_is_refused(sim: Simulator, smoke: World) -> None:
    from pytest_ddenv.sim import Command

    with pytest.raises(ControllerError, match="returned Command"):
        sim.run(smoke, controller=lambda o: Command(1.0, 0.0), timeout=1.0)  # type: ignore[arg-type,return-value]


def test_joint_targets_beyond_the_limits_are_held_at_the_limits(sim: Simulator, smoke: World) -> None:
    seen: list[ArmObservation] = []

    def stretch(observation: ArmObservation) -> JointTargets:
        seen.append(observation)
        return JointTargets((5.0, -0.785, 0.0, -2.356, 0.0, 1.571, -5.0))  # turned past joints 1 and 7's limits

    sim.run(smoke, controller=stretch, timeout=3.0, settings=RunSettings(noise=NoiseSettings.none()))
    positions = np.array([o.joint_positions for o in seen])
    lower = np.array([-2.9671, -1.8326, -2.9671, -3.1416, -2.9671, -0.0873, -2.9671])
    upper = -lower
    upper[3], upper[5] = 0.0, 3.8223
    assert (positions >= lower - 0.01).all() and (positions <= upper + 0.01).all()
    assert positions[-1, 0] == pytest.approx(2.9671, abs=0.01)  # driven to the limits, not past them
    assert positions[-1, 6] == pytest.approx(-2.9671, abs=0.01)
    velocities = np.abs(np.array([o.joint_velocities for o in seen]))
    assert velocities[:, 0].max() <= 2.175 * 1.05 and velocities[:, 6].max() <= 2.61 * 1.05  # the URDF's limits


@pytest.mark.parametrize("point", [(0.45, 0.2, 0.6), (0.3, -0.3, 0.5), (0.55, 0.0, 0.45)])
def test_an_end_effector_target_is_reached(sim: Simulator, smoke: World, point: tuple[float, float, float]) -> None:
    run = sim.run(smoke, controller=lambda o: EndEffectorTarget(point, yaw=0.3), timeout=3.0,
                  settings=RunSettings(noise=NoiseSettings.none()))
    assert math.dist(run.poses[-1, :3], point) < 0.005
    assert abs(abs(run.poses[-1, 3]) - math.pi) < 0.02 and abs(run.poses[-1, 4]) < 0.02  # pointing down
    assert run.poses[-1, 5] == pytest.approx(0.3, abs=0.02)


def test_the_observation_holds_the_named_objects_and_the_place(sim: Simulator, smoke: World) -> None:
    seen: list[ArmObservation] = []

    def look(observation: ArmObservation) -> GripperCommand:
        seen.append(observation)
        return GripperCommand("open")

    sim.run(smoke, controller=look, timeout=0.2)
    first = seen[0]
    assert set(first.objects) == {"cube", "table", "mug"} and first.target == "cube"
    assert first.place == (0.45, 0.3, None) and first.place_tolerance == 0.08
    assert first.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert first.gripper_opening == pytest.approx(0.08, abs=1e-3)
    assert math.dist(first.target_pose[:2], (0.5, 0.0)) < 0.05  # type: ignore[index]


def test_the_noise_is_seeded(sim: Simulator, smoke: World) -> None:
    one, again, other = (sim.run(smoke, seed=seed) for seed in (4, 4, 5))
    assert one.same_trajectory(again) and one.reached_goal
    assert not one.same_trajectory(other)


def test_removing_an_untouched_model_changes_nothing_else(sim: Simulator, smoke: World) -> None:
    full = sim.run(smoke, seed=2)
    assert "post" not in full.touched
    assert full.same_trajectory(sim.run(smoke.without(["post"]), seed=2))


RUN_IN_A_PROCESS = textwrap.dedent(f"""\
    import json
    from pytest_ddenv import World
    from pytest_ddenv.sim import simulate
    run = simulate(World.load({str(SMOKE)!r}), seed=7)
    print(json.dumps({{"poses": run.poses.tolist(), "target": run.target_path.tolist(), "goal": run.goal_time}}))
    """)


def test_two_processes_make_the_same_run() -> None:
    outputs = [subprocess.run([sys.executable, "-c", RUN_IN_A_PROCESS], capture_output=True, text=True, check=True,
                              timeout=300).stdout for _ in range(2)]
    first, second = (json.loads(output.strip().splitlines()[-1]) for output in outputs)
    assert first == second and first["goal"] is not None
