"""`python -m pytest_ddenv.cli`: the `ddenv` command (also `python -m pytest_ddenv`)."""

import sys

from pytest_ddenv.cli.main import main

sys.exit(main())
