"""`python -m tax3d.cli <command> [options]`: the `tax3d` command."""

import sys

from tax3d.cli import main

sys.exit(main())
