"""Keeps a training run in the repository: what git holds of it, copied into a policy folder.

    python scripts/keep_run.py runs/rough_aof_P policies/rough_aof_P

config.json, progress.json, the learning curve gzipped (metrics.jsonl.gz; `footforge train --resume`
unpacks it) and the weights once: the newest intact checkpoint while the run is still in training
(the one kept before goes), or policy/ once it reached its total steps (checkpoints/ goes). The
folder's evaluation/ and closed_chain/ stay. policies/README.md says what a policy folder keeps;
footforge.rl.kept_run.keep_run does the work. Exit 0, or 2 naming the folder and what to change.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from footforge.errors import InputError
from footforge.rl.kept_run import keep_run


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="the run's folder (footforge train's --out)")
    parser.add_argument("dest", type=Path, help="the policy folder to keep it in, e.g. policies/rough_aof_P")
    args = parser.parse_args(argv)
    try:
        written = keep_run(args.run, args.dest)
    except InputError as e:
        print(f"keep_run: {e}", file=sys.stderr)
        return e.exit_code
    print(f"keep_run: {args.dest}: {', '.join(written)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
