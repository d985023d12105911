"""The world model (layer 2): a world as an immutable value, and its files.

`model` (`World`, `Model`, `Shape`, `Pose`, `Scenario`, `RobotDescription`, `LaserMount`, `Physics`, `Ground`;
sub-worlds, bounds and distances), `files` (the files a world names: regular files only, read without
blocking), `meshes` (mesh files, polylines and heightmaps as meshes), `geometry` (the shapes' bounds and
distances, in numpy), `limits` (what one value may be), `values` (a whole world checked however made),
`formats` (which format reads and writes a file: `World.load` and `World.save` dispatch to it), `yaml_format`
(the ddenv YAML format, with `_robot_yaml` and `_bounded_yaml`). Gazebo SDF is `pytest_ddenv.sdf`, in the same
layer.
"""

from pytest_ddenv.world import formats  # noqa: F401 - installs the file formats of every World
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

__all__ = [
    "ArmDescription", "Ground", "LaserMount", "Model", "Physics", "Pose", "RobotDescription", "Scenario", "Shape",
    "World",
]
