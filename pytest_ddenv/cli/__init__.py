"""The `ddenv` command (layer 11, a front end beside the pytest plugin).

`main` (the sub-commands `check`, `run`, `show`, `reduce`, `replay`, `convert`; the console
script `ddenv` and `python -m pytest_ddenv`), `world_options` (the options that say how to read a world and
give it a scenario; the pytest plugin's `--ddenv-world` shares them), `replay` (`ddenv replay`: a minimal
world's failure re-run with fresh seeds).
"""
