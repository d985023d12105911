"""`python -m pytest_ddenv`: the `ddenv` command."""

import sys

from pytest_ddenv.cli.main import main

sys.exit(main())
