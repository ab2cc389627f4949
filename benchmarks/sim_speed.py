"""Simulated seconds per wall-clock second of the whole robot standing under its PD controller,
for each variant at its own timestep, measured in one run; prints one JSON line.

The figure is the ratio full : aof : aff : ball (the premise of the simplified feet is that they
are far cheaper than the closed chain). Single-threaded MuJoCo (C), the home keyframe, 2 s of
simulation per variant after a 0.2 s warm-up.

Usage: python benchmarks/sim_speed.py [--seconds S]
"""

import argparse
import json
import platform
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

from footforge.build import VARIANTS, BuildOptions, build


def realtime_factor(model: mujoco.MjModel, seconds: float) -> tuple[float, float]:
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    for _ in range(int(0.2 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    steps = int(round(seconds / model.opt.timestep))
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data)
    wall = time.perf_counter() - t0
    assert np.all(np.isfinite(data.qpos))
    return steps * model.opt.timestep / wall, steps / wall


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    figures = {"machine": platform.platform(), "mujoco": mujoco.__version__, "simulated_s": args.seconds}
    with tempfile.TemporaryDirectory() as tmp:
        for variant in VARIANTS:
            out = Path(tmp) / variant
            build(BuildOptions(variant=variant, out_dir=out))
            model = mujoco.MjModel.from_xml_path(str(out / "scene.xml"))
            rtf, sps = realtime_factor(model, args.seconds)
            figures[f"{variant}_timestep_s"] = model.opt.timestep
            figures[f"{variant}_realtime_factor"] = round(rtf, 3)
            figures[f"{variant}_steps_per_s"] = round(sps, 1)
    for variant in VARIANTS:
        figures[f"{variant}_speedup_vs_full"] = round(
            figures[f"{variant}_realtime_factor"] / figures["full_realtime_factor"], 2
        )
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
