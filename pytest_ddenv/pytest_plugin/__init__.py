"""The pytest plugin (layer 11, a front end beside the `ddenv` command).

`hooks` (the plugin pytest loads: the `pytest11` entry point; thin hooks over the modules below), `options`
(the `--ddenv-*` options and ini keys, built from `driver/settings.py` and checked once), `marks` (the markers
of collected tests, and a predicate given alone to `robot_failure`), `fixture` (the world `robot_world` runs
in), `reduction` (`ReductionPlugin`: the hooks registered only under `--ddenv-reduce`), `session` (one failing
test's reduction), `worker` (the test collected again in each probe worker: `PytestJob`), `given_example` (a
Hypothesis test's falsifying example, re-run per probe), `progress` (a reduction's progress beside pytest's
own output).
"""
