"""A shipped policy's walking verdict under both physics engines (footforge.envs.engine): the same
evaluation (footforge evaluate's: robots, seconds, seed, commands, pushes) stepped by MJX and by
MuJoCo's C engine, one JSON line with each policy's verdict, falls, uptime, forward error and base
height per engine, and each evaluation's wall time (compilation included).

Usage: python benchmarks/engine_verdicts.py [--policy policies/flat_aof_B ...] [--num-envs 32]
           [--seconds 20] [--seed 0] [--engines mjx mujoco]

The engines step the same model in different precision (MJX in the policy's float32, C in float64),
so single robots part after a few seconds of walking (chaos): the indices agree in distribution,
not robot by robot. What must agree is the verdict.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument(
        "--policy", type=Path, nargs="+", default=[Path("policies/flat_aof_B"), Path("policies/flat_ball_B_cpu")]
    )
    p.add_argument("--num-envs", type=int, default=32)
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--engines", nargs="+", default=["mjx", "mujoco"], choices=["mjx", "mujoco"])
    args = p.parse_args()

    import jax

    from footforge.cli.builds import build_defaults_if_missing
    from footforge.rl.evaluate import evaluate
    from footforge.rl.policy_files import load_policy_config, policy_folder

    rows = {}
    for path in args.policy:
        folder = policy_folder(path)
        build_defaults_if_missing([load_policy_config(folder).feet], None)
        for physics in args.engines:
            start = time.perf_counter()
            r = evaluate(folder, num_envs=args.num_envs, seconds=args.seconds, seed=args.seed, physics=physics)
            w = r["walking"]
            rows.setdefault(str(path), {})[physics] = {
                "verdict": w["verdict"],
                "line": w["line"],
                "falls": r["falls"],
                "diverged": r["diverged"],
                "uptime": w["uptime"],
                "forward_error_mps": w["forward_error_mps"],
                "base_height_m": w["base_height_m"],
                "gait": w["gait"],
                "wall_s": round(time.perf_counter() - start, 1),
            }
            print(
                f"{path} [{physics}]: {w['line']}, {r['falls']} of {args.num_envs} fell "
                f"({time.perf_counter() - start:.0f} s)",
                file=sys.stderr,
                flush=True,
            )
    same = all(len({e["verdict"] for e in engines.values()}) == 1 for engines in rows.values())
    print(
        json.dumps(
            {
                "benchmark": "engine_verdicts",
                "machine": platform.platform(),
                "backend": jax.default_backend(),
                "num_envs": args.num_envs,
                "seconds": args.seconds,
                "seed": args.seed,
                "same_verdict": same,
                "policies": rows,
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
