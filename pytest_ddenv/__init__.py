"""pytest-ddenv: reduce the simulated world of a failing robot scenario test to the objects that matter.

The names a scenario test needs are exported here: the world model, the controller interface
(`Observation` in, `Command`/`WheelCommand` out), `RobotWorld` and `RobotFailure`, robot and predicate
registration. Simulation names are imported on first use, so that loading the pytest plugin stays cheap.
"""

from importlib import import_module
from typing import TYPE_CHECKING, Any

from pytest_ddenv._version import __version__
from pytest_ddenv.errors import DdenvError, ReductionError, ScenarioError, WorldError
from pytest_ddenv.world.model import (
    ArmDescription,
    Ground,
    LaserMount,
    Model,
    Physics,
    Pose,
    RobotDescription,
    Scenario,
    Shape,
    World,
)

if TYPE_CHECKING:
    from pytest_ddenv.oracle.arm_state import ArmState
    from pytest_ddenv.oracle.predicates import FailureSignature, Predicate, RobotState, predicate, register_predicate
    from pytest_ddenv.scenario.robot_world import RobotFailure, RobotWorld
    from pytest_ddenv.sim import (
        Command,
        ControllerError,
        ControllerTimeout,
        LaserScan,
        Observation,
        Robot,
        Run,
        RunSettings,
        WheelCommand,
        WheeledRobot,
        register_robot,
    )
    from pytest_ddenv.sim.arm.control import ArmObservation, EndEffectorTarget, GripperCommand, JointTargets
    from pytest_ddenv.sim.arm.pick_place import PickAndPlace

_LAZY = {
    "ArmObservation": "pytest_ddenv.sim.arm.control",
    "EndEffectorTarget": "pytest_ddenv.sim.arm.control",
    "GripperCommand": "pytest_ddenv.sim.arm.control",
    "JointTargets": "pytest_ddenv.sim.arm.control",
    "PickAndPlace": "pytest_ddenv.sim.arm.pick_place",
    "ArmState": "pytest_ddenv.oracle.arm_state",
    "Command": "pytest_ddenv.sim",
    "ControllerError": "pytest_ddenv.sim",
    "ControllerTimeout": "pytest_ddenv.sim",
    "LaserScan": "pytest_ddenv.sim",
    "Observation": "pytest_ddenv.sim",
    "Robot": "pytest_ddenv.sim",
    "Run": "pytest_ddenv.sim",
    "RunSettings": "pytest_ddenv.sim",
    "WheelCommand": "pytest_ddenv.sim",
    "WheeledRobot": "pytest_ddenv.sim",
    "register_robot": "pytest_ddenv.sim",
    "FailureSignature": "pytest_ddenv.oracle.predicates",
    "Predicate": "pytest_ddenv.oracle.predicates",
    "RobotState": "pytest_ddenv.oracle.predicates",
    "register_predicate": "pytest_ddenv.oracle.predicates",
    "predicate": "pytest_ddenv.oracle.predicates",
    "RobotFailure": "pytest_ddenv.scenario.robot_world",
    "RobotWorld": "pytest_ddenv.scenario.robot_world",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'pytest_ddenv' has no attribute {name!r}")


__all__ = [
    "ArmDescription",
    "ArmObservation",
    "ArmState",
    "Command",
    "ControllerError",
    "ControllerTimeout",
    "DdenvError",
    "EndEffectorTarget",
    "FailureSignature",
    "GripperCommand",
    "Ground",
    "JointTargets",
    "LaserMount",
    "LaserScan",
    "Model",
    "Observation",
    "Physics",
    "PickAndPlace",
    "Pose",
    "Predicate",
    "ReductionError",
    "Robot",
    "RobotDescription",
    "RobotFailure",
    "RobotState",
    "RobotWorld",
    "Run",
    "RunSettings",
    "Scenario",
    "ScenarioError",
    "Shape",
    "WheelCommand",
    "WheeledRobot",
    "World",
    "WorldError",
    "__version__",
    "predicate",
    "register_predicate",
    "register_robot",
]
