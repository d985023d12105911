"""The pytest plugin (layer 11, a front end beside the `ddenv` command).

`hooks` (the plugin pytest loads: the `pytest11` entry point), `options` (the `--ddenv-*` options and ini
keys, read and checked once), `session` (one failing test's reduction), `worker` (the test collected again in
each probe worker: `PytestJob`), `given_example` (a Hypothesis test's falsifying example, re-run per probe),
`progress` (a reduction's progress beside pytest's own output).
"""
