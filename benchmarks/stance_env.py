"""Issue 12's stance target in the training environments themselves: zero actions for --seconds
from the task's start, per feet, at the environment's default physics (or --contact-model).

Flat: the flat task's reset (the `stand` keyframe, joint velocities U(+-0.1) rad/s). Rough: level 0
(the spawn platform) from the `stand` keyframe (the rough task's randomised joint angles off, as
the issue measures "at the home keyframe with the actuators at its targets"; the randomised start
is tests/test_rough.py's survival test). Figures after the first 0.5 s: the base's sinking and the
largest foot slip; target < 10 mm and < 5 mm. One JSON line per (task, feet).

    python benchmarks/stance_env.py --tasks flat rough --feet ball aff aof
    python benchmarks/stance_env.py --feet aff aof --float64-physics     # JAX's x64 mode, set first
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from dataclasses import replace


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tasks", nargs="+", default=["flat", "rough"], choices=["flat", "rough"])
    p.add_argument("--feet", nargs="+", default=["ball", "aff", "aof"], choices=["ball", "aff", "aof"])
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--contact-model", choices=["stance", "fast", "build"], help="default: the environments' own")
    p.add_argument("--float64-physics", action="store_true")
    p.add_argument("--build-root", default="build", help="builds of each feet: <root>/<feet>/")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)

    import jax

    from footforge import envs
    from footforge.envs.config import ResetConfig
    from footforge.envs.terrain import TerrainConfig
    from footforge.stance import env_stance

    if args.float64_physics:
        jax.config.update("jax_enable_x64", True)
    for task in args.tasks:
        for feet in args.feet:
            config = envs.default_config(task, feet, "B", args.contact_model)
            config = replace(config, build_dir=f"{args.build_root}/{feet}", float64_physics=args.float64_physics,
                             pushes=replace(config.pushes, enabled=False),
                             reset=ResetConfig(joint_pos_factor_range=(1.0, 1.0)))
            if task == "rough":  # a small field: level 0 is the same platform, compiled faster
                config = replace(config, terrain=TerrainConfig(num_levels=3, num_columns=6, tile_size_m=4.0,
                                                               border_m=2.0, platform_m=1.5))
            env = envs.from_config(config)
            key = jax.random.PRNGKey(args.seed)
            state = env.reset(key) if task == "flat" else env.reset_on_tile(key, 0, 0)
            t0 = time.time()
            result = env_stance(env, state, seconds=args.seconds)
            print(json.dumps({"benchmark": "stance_env", "machine": platform.platform(), "task": task, "feet": feet,
                              "contact_model": config.contact_model, "precision": str(state.pipeline_state.qpos.dtype),
                              "sim_dt": config.sim_dt, "iterations": [config.solver_iterations,
                                                                      config.solver_ls_iterations],
                              "seconds": args.seconds, "drop_mm": round(1e3 * result.drop_after_settle_m, 2),
                              "slip_mm": round(1e3 * result.slip_after_settle_m, 2),
                              "base_height_min_m": round(result.base_height_min_m, 4), "fell": result.fell,
                              "wall_s": round(time.time() - t0, 1)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
