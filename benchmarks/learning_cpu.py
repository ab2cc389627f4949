"""Does PPO learn on this machine? The longest flat-ground training a 2-core CPU affords.

Ball feet, flat task, the paper's networks and PPO settings, with a command range a few million
steps can reach (forward -1..1 m/s, lateral -0.5..0.5 m/s, heading-driven yaw rate; the task's
default is -2..2 m/s forward, which takes the GPU budget). Prints one line per evaluation
(deterministic policy, --eval-envs robots, whole 20 s episodes): env steps, wall time, mean
episode length, forward tracking error, return, mean base height; then one JSON line with the
whole curve. The observation holds the PD targets, as the flat task's default
(ObservationConfig.pd_targets); --no-pd-targets leaves them out, as before 2026-11-25.

    python benchmarks/learning_cpu.py --out /tmp/learning --timesteps 5000000 --max-minutes 90
    python benchmarks/learning_cpu.py --out /tmp/learning --timesteps 5000000 --resume   # goes on
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True, help="run folder (a new one, or the run to --resume)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its newest checkpoint "
                   "(parameters only: Brax restarts Adam and the adaptive learning rate)")
    p.add_argument("--feet", default="ball", choices=("ball", "aff", "aof"))
    p.add_argument("--timesteps", type=int, default=5_000_000)
    p.add_argument("--num-envs", type=int, default=128)
    p.add_argument("--eval-every", type=int, default=500_000, help="env steps between evaluations")
    p.add_argument("--eval-envs", type=int, default=64)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-minutes", type=float,
                   help="stop at the checkpoint before this wall time (train's max_wall_s)")
    p.add_argument("--no-pd-targets", action="store_true",
                   help="leave the PD targets out of the observation (ObservationConfig.pd_targets), as before "
                        "2026-11-25's fifth session")
    p.add_argument("--build-dir", type=Path, help="footforge build of the feet (default build/<feet>)")
    args = p.parse_args(argv)
    if args.out.exists() and not args.resume:
        p.error(f"--out {args.out} exists; give a new folder, or --resume")
    if args.resume and not args.out.is_dir():
        p.error(f"--resume: --out {args.out} holds no run to continue")
    if args.max_minutes is not None and args.max_minutes <= 0:
        p.error(f"--max-minutes must be positive, got {args.max_minutes:g}")

    import jax

    from footforge import envs
    from footforge.rl import train

    cfg = envs.default_config("flat", args.feet, "B")
    cfg = replace(cfg, build_dir=str(args.build_dir) if args.build_dir else None,
                  commands=replace(cfg.commands, lin_vel_x_range=(-1.0, 1.0), lin_vel_y_range=(-0.5, 0.5)),
                  observations=replace(cfg.observations, pd_targets=not args.no_pd_targets))
    ppo = train.default_ppo("flat", num_envs=args.num_envs, num_timesteps=args.timesteps, unroll_length=24,
                            batch_size=args.num_envs // 2, num_minibatches=4, checkpoint_every_steps=args.eval_every,
                            num_eval_envs=args.eval_envs, seed=args.seed)
    t0 = time.time()
    print("env steps | wall s | episode length (policy steps) | forward error m/s | return | base height m", flush=True)

    def progress(step, total, metrics, evaluation):
        if not evaluation or "eval/episode_reward" not in metrics:
            return
        print(f"{step:>9,} | {time.time() - t0:6.0f} | {metrics['eval/avg_episode_length']:6.1f} | "
              f"{metrics['eval/episode_error/lin_vel_x_per_step']:.3f} | {metrics['eval/episode_reward']:.3f} | "
              f"{metrics.get('eval/episode_base_height_m_per_step', float('nan')):.3f}",
              flush=True)

    train.train(cfg, ppo, args.out, progress=progress, resume=args.resume,
                max_wall_s=args.max_minutes * 60 if args.max_minutes else None)
    curve = [{"env_steps": e["global_step"], "wall_s": round(e["wall_s"], 1),
              "episode_length": e["eval/avg_episode_length"],
              "forward_error_mps": e["eval/episode_error/lin_vel_x_per_step"], "return": e["eval/episode_reward"],
              "base_height_m": e.get("eval/episode_base_height_m_per_step")}
             for e in map(json.loads, (args.out / "metrics.jsonl").read_text().splitlines())
             if "eval/episode_reward" in e]
    print(json.dumps({"benchmark": "learning_cpu", "machine": platform.platform(), "cpu_cores": os.cpu_count(), "jax_devices": jax.device_count(),
                      "feet": args.feet, "pd_targets": cfg.observations.pd_targets, "timesteps": args.timesteps,
                      "num_envs": args.num_envs,
                      "wall_s": round(time.time() - t0, 1), "curve": curve}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
