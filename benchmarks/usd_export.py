"""USD export cost per variant: export, validation and comparison with the MJCF (seconds, best of
3), and the written file sizes; prints one JSON line.

Usage: python benchmarks/usd_export.py
"""

import json
import platform
import tempfile
import time
from importlib.metadata import version
from pathlib import Path

import mujoco

from footforge import usd
from footforge.build import VARIANTS, BuildOptions, build


def best_of(n, fn):
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return min(times), result


def main() -> None:
    figures = {"machine": platform.platform(), "usd-core": version("usd-core")}
    with tempfile.TemporaryDirectory() as tmp:
        for variant in VARIANTS:
            out = Path(tmp) / variant
            build(BuildOptions(variant=variant, out_dir=out, formats=("mjcf",)))
            model = mujoco.MjModel.from_xml_path(str(out / "robot.xml"))
            t_export, exported = best_of(3, lambda: usd.export_model(model, name="robot", keyframe="home"))  # noqa: B023
            t_validate, _ = best_of(3, lambda: usd.validate_stage(exported.stage))  # noqa: B023
            t_compare, _ = best_of(3, lambda: usd.compare_with_model(exported.stage, model, keyframe="home"))  # noqa: B023
            usd.write_stage(exported.stage, out, "robot")
            figures[variant] = {
                "export_s": round(t_export, 4),
                "validate_s": round(t_validate, 4),
                "compare_s": round(t_compare, 4),
                "usda_kb": round((out / "robot.usda").stat().st_size / 1024, 1),
                "usd_kb": round((out / "robot.usd").stat().st_size / 1024, 1),
                "prims": sum(1 for _ in exported.stage.Traverse()),
                "unsupported_items": len(exported.unsupported),
            }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
