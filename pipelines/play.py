"""footforge play, by the name the pipelines have always had: `python pipelines/play.py --help`."""

from __future__ import annotations

import sys

from footforge.cli.play import main

if __name__ == "__main__":
    sys.exit(main(prog="python pipelines/play.py"))
