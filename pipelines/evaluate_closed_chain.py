"""footforge evaluate-closed-chain, by the name the pipelines have always had:
`python pipelines/evaluate_closed_chain.py --help`."""

from __future__ import annotations

import sys

from footforge.cli.evaluate_closed_chain import main

if __name__ == "__main__":
    sys.exit(main(prog="python pipelines/evaluate_closed_chain.py"))
