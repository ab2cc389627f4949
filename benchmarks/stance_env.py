"""Issue 12's stance target in the training environments themselves: zero actions for --seconds
from the task's start, per feet, at the environment's default physics (or --contact-model).

The starts are footforge.validate.stance.env_stance_start's (flat: the task's reset; rough: level 0 from
the `stand` keyframe; the randomised rough start is tests/test_rough.py's survival test). Figures
after the first 0.5 s: the base's sinking and the largest foot slip; target < 10 mm and < 5 mm.
One JSON line per (task, feet, seed); the seed moves the rough task's spawn on tile (0, 0) and
its heading, and draws the flat reset's joint velocities.

    python benchmarks/stance_env.py --tasks flat rough --feet ball aff aof
    python benchmarks/stance_env.py --tasks rough --feet aff aof --seed 0 1 2     # three spawns
    python benchmarks/stance_env.py --feet aff aof --float64-physics     # JAX's x64 mode, set first
    python benchmarks/stance_env.py --tasks rough --feet aof --physics mujoco --heightfield-soles box
The seeds of one (task, feet) share one compiled step.
"""

from __future__ import annotations

import argparse
import itertools
import json
import platform
import sys
import time

from footforge.variants import FEET


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tasks", nargs="+", default=["flat", "rough"], choices=["flat", "rough"])
    p.add_argument("--feet", nargs="+", default=list(FEET), choices=FEET)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--contact-model", choices=["stance", "fast", "build"], help="default: the environments' own")
    p.add_argument("--float64-physics", action="store_true")
    p.add_argument("--build-root", default="build", help="builds of each feet: <root>/<feet>/")
    p.add_argument("--seed", type=int, nargs="+", default=[0], help="one run per seed")
    p.add_argument(
        "--physics", choices=["mjx", "mujoco"], help="the engine (EnvConfig.physics); default: the configuration's own"
    )
    p.add_argument(
        "--heightfield-soles",
        choices=["spheres", "box"],
        help="rough AFF/AOF: the sole colliders on the heightfield (EnvConfig.heightfield_soles); default: "
        "the configuration's own",
    )
    args = p.parse_args(argv)
    if args.seconds <= 0.5:
        p.error("--seconds must exceed the 0.5 s the robot is given to settle")

    import jax

    from footforge.validate.stance import env_stance, env_stance_start

    overrides = {"heightfield_soles": args.heightfield_soles} if args.heightfield_soles else {}
    steps = {}
    for task, feet, seed in itertools.product(args.tasks, args.feet, args.seed):
        env, state = env_stance_start(
            task,
            feet,
            f"{args.build_root}/{feet}",
            contact_model=args.contact_model,
            float64_physics=args.float64_physics,
            seed=seed,
            physics=args.physics,
            **overrides,
        )
        config = env.config
        t0 = time.time()
        step = steps.setdefault((task, feet), jax.jit(env.step))  # the seeds differ in the start only
        result = env_stance(env, state, seconds=args.seconds, step=step)
        print(
            json.dumps(
                {
                    "benchmark": "stance_env",
                    "machine": platform.platform(),
                    "task": task,
                    "feet": feet,
                    "seed": seed,
                    "contact_model": config.contact_model,
                    "physics": config.physics,
                    "heightfield_soles": config.heightfield_soles if task == "rough" and feet != "ball" else None,
                    "precision": str(state.pipeline_state.qpos.dtype),
                    "sim_dt": config.sim_dt,
                    "iterations": [config.solver_iterations, config.solver_ls_iterations],
                    "seconds": args.seconds,
                    "drop_mm": round(1e3 * result.drop_after_settle_m, 2),
                    "slip_mm": round(1e3 * result.slip_after_settle_m, 2),
                    "base_height_min_m": round(result.base_height_min_m, 4),
                    "fell": result.fell,
                    "wall_s": round(time.time() - t0, 1),
                }
            ),
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
