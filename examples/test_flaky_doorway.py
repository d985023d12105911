"""A flaky scenario judged by its failure rate: the Husky drives through a doorway it fits with 6 cm to spare.

The start pose jitter and the wheels' actuation noise (the default `NoiseSettings`) move it sideways by a few
centimetres, so on about 28 % of the seeds a door jamb catches it and it gets stuck (worlds/doorway.yaml: 276
of seeds 0..999 fail in pybullet). One run is a coin flip; `rate=20` runs the test on 20 seeds (run i with seed
`seed + i * 1000003`, runs 1..19 on the probe workers) and `max_failure_rate=0.5` fails it only when its
failure rate is significantly above 50 % (the lower end of the Wilson 95 % interval). This one passes its
verdict with a few failed runs, which the JUnit XML records as flaky failures, and which
`pytest examples --ddenv-reduce` does not reduce (only a failing verdict is reduced).
See docs/ci.md and benchmarks/bench_rate.py.
"""

import pytest


@pytest.mark.ddenv(world="worlds/doorway.yaml", rate=20, max_failure_rate=0.5)
@pytest.mark.robot_failure("stuck", window=5.0, min_progress=0.2)
def test_husky_drives_through_the_doorway(robot_world):
    run = robot_world.run()
    assert run.reached_goal
