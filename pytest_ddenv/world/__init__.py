"""The world model (layer 2): a world as an immutable value, and its files.

`model` (`World`, `Model`, `Shape`, `Pose`, `Scenario`, `RobotDescription`, `LaserMount`, `Physics`, `Ground`;
sub-worlds, bounds and distances), `files` (the files a world names: regular files only, read without
blocking), `values` (the numbers the simulator takes, checked for every world however made), `geometry` (the
shapes' bounds and distances, in numpy), `yaml_format` (the ddenv YAML format, with `_robot_yaml` and
`_bounded_yaml`). Gazebo SDF is `pytest_ddenv.sdf`, in the same layer.
"""

from pytest_ddenv.world.model import (
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

__all__ = ["Ground", "LaserMount", "Model", "Physics", "Pose", "RobotDescription", "Scenario", "Shape", "World"]
