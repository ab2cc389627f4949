"""Standing still in the built scenes: sink and slip of each variant over 10 s (footforge.validate.stance).

For each variant: from `stand` (the rest pose the build computes) and from `home` (the default
angles, unloaded), the base height drop after the first 0.5 s and the largest foot slip, at the
scene's own timestep and solver; `--pyramidal` also runs MuJoCo's default contact model on the
same scene (pyramidal cone, impratio 1, solimp 0.9/0.95) for comparison; `--loads` also the
stance's ground forces (each foot's horizontal over vertical force at `stand`) and where the robot
comes to rest without friction (footforge.validate.stance.foot_loads, frictionless_rest). One JSON line.

    python benchmarks/stance.py --build-root build --pyramidal [--loads]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

import mujoco

from footforge.variants import FEET


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--build-root", type=Path, default=Path("build"), help="holds <variant>/scene.xml")
    p.add_argument("--variants", nargs="+", default=list(FEET))
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--pyramidal", action="store_true", help="also MuJoCo's default contact model")
    p.add_argument("--loads", action="store_true", help="also the stance's sideways loads and frictionless rest")
    args = p.parse_args(argv)

    from footforge.validate.stance import foot_loads, frictionless_rest, stand

    out = {"benchmark": "stance", "machine": platform.platform(), "mujoco": mujoco.__version__, "seconds": args.seconds}
    for variant in args.variants:
        scene = args.build_root / variant / "scene.xml"
        if not scene.is_file():
            p.error(f"{scene} does not exist: run footforge build --variant {variant} --out {scene.parent}")
        models = {"build": mujoco.MjModel.from_xml_path(str(scene))}
        if args.pyramidal:
            m = mujoco.MjModel.from_xml_path(str(scene))
            m.opt.cone, m.opt.impratio = mujoco.mjtCone.mjCONE_PYRAMIDAL, 1.0
            m.geom_solimp[:, :3] = (0.9, 0.95, 0.001)
            models["pyramidal"] = m
        if args.loads:
            height, splay = frictionless_rest(models["build"], seconds=args.seconds)
            out[f"{variant}/loads"] = {
                "sideways_ratio": [round(float(r), 3) for r in foot_loads(models["build"]).sideways_ratio],
                "frictionless_base_height_m": round(height, 4),
                "frictionless_splay_mm": round(1e3 * splay, 1),
            }
        for name, model in models.items():
            for key in ("stand", "home"):
                s = stand(model, keyframe=key, seconds=args.seconds)
                out[f"{variant}/{name}/{key}"] = {
                    "drop_mm": round(1e3 * s.drop_after_settle_m, 2),
                    "slip_mm": round(1e3 * s.slip_after_settle_m, 2),
                    "base_height_m": round(s.base_height_start_m, 4),
                    "finite": s.finite,
                }
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
