"""The test's view of a world (layer 7): what a scenario test holds and what one call of it gives.

`robot_world` (`RobotWorld`, the fixture's value, and `RobotFailure`), `gym_env` (the scenario as a
gymnasium environment: `robot_world.make_env()`), `reported` (the runs of a simulator of the user's own),
`probe` (one call of the test as the reduction sees it: `ProbeResult`, `ErrorInfo`, `FailureReference`, the
verdict on it, `make_probe`).
"""
