"""Train an ANYmal C flat-terrain policy with Brax PPO on MuJoCo MJX (the paper's flat task).

    python pipelines/train_flat.py --feet aof --policy B --out runs/flat_aof_B
    python pipelines/train_flat.py --feet aof --policy B --out runs/flat_aof_B --resume   # after a kill
    python pipelines/train_flat.py --feet ball --num-envs 64 --timesteps 200000 --unroll-length 16 \\
        --batch-size 16 --minibatches 4 --checkpoint-every 50000 --out runs/cpu_smoke     # a CPU run

Writes <out>/config.json, checkpoints/<step>/, progress.json, tensorboard/ (every reward term and
tracking error) and policy/ (the final policy, with the environment and PPO configs in
footforge.json; load it with footforge.train.load_policy).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    from footforge.envs import FEET, TASKS

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--feet", choices=FEET, default="aof")
    p.add_argument("--policy", choices=TASKS["flat"], default="B")
    p.add_argument("--num-envs", type=int, help="parallel robots (default 2048)")
    p.add_argument("--timesteps", type=int, help="environment steps in total (default 1e8)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, required=True, help="run folder")
    p.add_argument("--resume", action="store_true", help="continue from the run folder's last checkpoint")
    p.add_argument("--unroll-length", type=int, help="policy steps per robot per iteration (default 48)")
    p.add_argument("--batch-size", type=int, help="trajectories per minibatch (default 512)")
    p.add_argument("--minibatches", type=int, help="minibatches per iteration (default 4)")
    p.add_argument("--checkpoint-every", type=int, help="environment steps between checkpoints (default 5e6)")
    p.add_argument("--eval-envs", type=int, help="robots per evaluation (default 128)")
    p.add_argument("--build-dir", type=Path, help="footforge build output for the feet (default build/<feet>)")
    args = p.parse_args(argv)

    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from footforge import envs, train
    from footforge.errors import FootforgeError

    console = Console()
    try:
        env_config = envs.default_config("flat", args.feet, args.policy)
        if args.build_dir:
            env_config = replace(env_config, build_dir=str(args.build_dir))
        overrides = {k: v for k, v in {
            "num_envs": args.num_envs, "num_timesteps": args.timesteps, "unroll_length": args.unroll_length,
            "batch_size": args.batch_size, "num_minibatches": args.minibatches,
            "checkpoint_every_steps": args.checkpoint_every, "num_eval_envs": args.eval_envs}.items() if v is not None}
        ppo = replace(train.PPOConfig(seed=args.seed), **overrides)
        with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed:,.0f}/{task.total:,.0f} steps"),
                      TimeElapsedColumn(), TimeRemainingColumn(), console=console) as progress:
            task = progress.add_task("compiling and training", total=ppo.num_timesteps)

            def report(step, total, metrics):
                reward = metrics.get("eval/episode_reward", float("nan"))
                err = metrics.get("eval/episode_error/lin_vel_x_per_step", float("nan"))
                progress.update(task, completed=min(step, total),
                                description=f"return {reward:7.2f}  vx error {err:5.3f} m/s")
            metrics = train.train(env_config, ppo, args.out, resume=args.resume, progress=report)
    except FootforgeError as e:
        console.print(f"train_flat: error: {e}", markup=False)
        return e.exit_code
    console.print(f"policy written to {args.out / 'policy'}; final evaluation return "
                  f"{metrics.get('eval/episode_reward', float('nan')):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
