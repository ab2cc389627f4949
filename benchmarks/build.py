"""Cold (empty CoACD cache) and cached `footforge build` time per variant; prints one JSON line.

Usage: python benchmarks/build.py
"""

import json
import platform
import tempfile
import time
from pathlib import Path

from footforge.build import VARIANTS, BuildOptions, build


def main() -> None:
    figures = {"machine": platform.platform(), "processor": platform.processor() or platform.machine()}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for variant in VARIANTS:
            cache = tmp / f"cache_{variant}"
            times = []
            for run in ("cold", "cached"):
                t0 = time.perf_counter()
                build(BuildOptions(variant=variant, out_dir=tmp / f"{variant}_{run}", cache_dir=cache))
                times.append(time.perf_counter() - t0)
            figures[f"{variant}_cold_s"] = round(times[0], 3)
            figures[f"{variant}_cached_s"] = round(times[1], 3)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
