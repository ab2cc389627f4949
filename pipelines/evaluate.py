"""footforge evaluate, by the name the pipelines have always had: `python pipelines/evaluate.py --help`."""

from __future__ import annotations

import sys

from footforge.cli.evaluate import main

if __name__ == "__main__":
    sys.exit(main(prog="python pipelines/evaluate.py"))
