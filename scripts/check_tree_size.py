"""CI's size check of the tracked tree: no tracked file over 2 MiB and at most 15 MB in all, outside
descriptions/ (the robot descriptions and their meshes, which footforge ships as inputs). Run
outputs, caches and raw records stay out of git (policies/README.md says what a policy folder keeps).

    python scripts/check_tree_size.py          # exit 0, or 1 naming what is over

Reads `git ls-files` (the index: what a commit would hold) from the repository this script is in.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MAX_FILE_BYTES = 2 * 1024 * 1024
MAX_TREE_BYTES = 15_000_000
EXEMPT = "descriptions/"


def tracked_sizes(repo: Path = REPO) -> dict[str, int]:
    """Size in bytes of every tracked file that exists in the work tree, outside EXEMPT."""
    names = (
        subprocess.run(["git", "ls-files", "-z"], cwd=repo, capture_output=True, check=True, timeout=60)
        .stdout.decode()
        .split("\0")
    )
    return {n: (repo / n).stat().st_size for n in names if n and not n.startswith(EXEMPT) and (repo / n).is_file()}


def problems(sizes: dict[str, int]) -> list[str]:
    found = [
        f"{name}: {size / 2**20:.2f} MiB, over the {MAX_FILE_BYTES / 2**20:.0f} MiB a tracked file may have"
        for name, size in sorted(sizes.items())
        if size > MAX_FILE_BYTES
    ]
    total = sum(sizes.values())
    if total > MAX_TREE_BYTES:
        largest = ", ".join(f"{n} ({s / 1e6:.1f} MB)" for n, s in sorted(sizes.items(), key=lambda x: -x[1])[:5])
        found.append(
            f"the tracked tree outside {EXEMPT} is {total / 1e6:.1f} MB, over {MAX_TREE_BYTES / 1e6:.0f} MB "
            f"(largest: {largest})"
        )
    return found


def main() -> int:
    sizes = tracked_sizes()
    found = problems(sizes)
    for line in found:
        print(f"check_tree_size: {line}", file=sys.stderr)
    if not found:
        print(f"check_tree_size: {len(sizes)} tracked files outside {EXEMPT}, {sum(sizes.values()) / 1e6:.1f} MB")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
