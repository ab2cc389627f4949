"""Runs a script (argv[1:]) and, when it ends, prints which build-time-only packages it imported
(`footforge-kit: imported NAME...`): the kit's training path must not need them (the GPU machine
has none of dm_control, pinocchio, coacd, pxr (usd-core), xacro)."""

import atexit
import runpy
import sys

FORBIDDEN = ("dm_control", "pinocchio", "coacd", "pxr", "xacro")


def _report() -> None:
    found = sorted(m for m in FORBIDDEN if m in sys.modules)
    print(
        f"footforge-kit: imported {' '.join(found)}" if found else "footforge-kit: no build-time package imported",
        flush=True,
    )


atexit.register(_report)
sys.argv = sys.argv[1:]
runpy.run_path(sys.argv[0], run_name="__main__")
