"""`python -m footforge.cli`: the `footforge` command."""

import sys

from footforge.cli.main import main

sys.exit(main())
