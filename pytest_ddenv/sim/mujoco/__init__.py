"""The MuJoCo engine (`physics: {engine: mujoco}` in a world file; `pip install "pytest-ddenv[mujoco]"`).

`physics.py` (`MujocoPhysics`, the seam's MuJoCo side), `world_spec.py` (a `World` and its robot as one
`MjSpec`), `pieces.py` (convex pieces of meshes and polylines), `contacts.py` (friction and restitution as
MuJoCo contact parameters), `robot_spec.py` (a URDF wheeled robot: free joint, ellipsoid wheels, velocity
actuators, the servos' armature), `driven_robot.py` (`MujocoRobot`: its motors, encoders and base state),
`near.py` (near contacts: what pybullet lists within 2 cm, with force 0). See docs/simulation.md.
"""
