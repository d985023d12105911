"""The `ddenv` command (layer 11, a front end beside the pytest plugin).

`main` (the console script `ddenv` and `python -m pytest_ddenv`: the dispatch to each sub-command and its error
handling), `parser` (the sub-commands and their options), `console` (exit codes; an error line, text or JSON on
stdout), `predicates` (`--predicate` read and checked), `user_code` (the `--import`, `--controller` and
`--same-failure` code loaded), `output` (the files written where the user says), the commands: `world_commands`
(`check`, `convert`), `run_command`, `show_command`, `reduce_command` + `reduce_plan` (its `ReductionPlan`),
`replay_command` + `replay` (`ddenv replay`: a minimal world's failure re-run with fresh seeds), `bisect`;
`world_options` (the options that say how to read a world and give it a scenario; the pytest plugin's
`--ddenv-world` shares them).
"""
