"""CI's size check of the tracked tree: no tracked file over 2 MiB and at most 15 MB in all, outside
descriptions/ (the robot descriptions and their meshes, which footforge ships as inputs) and the trained
weights; those, the policies' `policy/` and `checkpoints/` folders, have a budget of their own, 30 MB. Run
outputs, caches and raw records stay out of git (policies/README.md says what a policy folder keeps).

    python scripts/check_tree_size.py          # exit 0, or 1 naming what is over

Reads `git ls-files` (the index: what a commit would hold) from the repository this script is in.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MAX_FILE_BYTES = 2 * 1024 * 1024
MAX_TREE_BYTES = 15_000_000
EXEMPT = "descriptions/"
WEIGHTS = re.compile(r"^policies/[^/]+/(policy|checkpoints)/")
"""The trained weights, each policy's once (policies/README.md): counted apart from the tree."""
MAX_WEIGHTS_BYTES = 30_000_000
"""The weights' budget. A rough policy's weights (a 512-256-128 actor and critic over its height scan)
take about 2 MB, a flat one's 0.2-0.5 MB; the rough campaign's eleven policies (issue 45) and the five
flat ones fit with room, where inside the tree's 15 MB the second rough policy already did not."""


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
    weights = {n: s for n, s in sizes.items() if WEIGHTS.match(n)}
    rest = {n: s for n, s in sizes.items() if n not in weights}
    for part, limit, what in (
        (rest, MAX_TREE_BYTES, f"the tracked tree outside {EXEMPT} and the policies' weights"),
        (weights, MAX_WEIGHTS_BYTES, "the policies' weights (policy/, checkpoints/)"),
    ):
        total = sum(part.values())
        if total > limit:
            largest = ", ".join(f"{n} ({s / 1e6:.1f} MB)" for n, s in sorted(part.items(), key=lambda x: -x[1])[:5])
            found.append(f"{what} is {total / 1e6:.1f} MB, over {limit / 1e6:.0f} MB (largest: {largest})")
    return found


def main() -> int:
    sizes = tracked_sizes()
    found = problems(sizes)
    for line in found:
        print(f"check_tree_size: {line}", file=sys.stderr)
    if not found:
        weights = sum(s for n, s in sizes.items() if WEIGHTS.match(n))
        rest = sum(sizes.values()) - weights
        print(
            f"check_tree_size: {len(sizes)} tracked files outside {EXEMPT}: {rest / 1e6:.1f} MB of "
            f"{MAX_TREE_BYTES / 1e6:.0f}, and the policies' weights {weights / 1e6:.1f} MB of "
            f"{MAX_WEIGHTS_BYTES / 1e6:.0f}"
        )
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
