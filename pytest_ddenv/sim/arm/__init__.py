"""Arms: a fixed-base arm with a parallel gripper on a table (docs/writing-tests.md, "Arms").

`control.py` (`ArmObservation` and the commands: `JointTargets`, `EndEffectorTarget`, `GripperCommand`),
`driven.py` (`DrivenArm`: an arm as one physics engine drives it), `panda/` (the Franka Panda, from
pybullet_data: its URDF and collision meshes, Apache 2.0).
"""
