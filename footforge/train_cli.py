"""The command line of the training pipelines (pipelines/train_flat.py, pipelines/train_rough.py)."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path


def main(task: str, description: str, argv: list[str] | None = None) -> int:
    from footforge.envs import FEET, TASKS

    p = argparse.ArgumentParser(description=description)
    p.add_argument("--feet", choices=FEET, default="aof")
    p.add_argument("--policy", choices=TASKS[task], default="B")
    p.add_argument("--num-envs", type=int, help="parallel robots (default 2048)")
    p.add_argument("--timesteps", type=int, help="environment steps in total (default 1e8)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, required=True, help="run folder")
    p.add_argument("--resume", action="store_true", help="continue from the run folder's last checkpoint")
    p.add_argument("--max-minutes", type=float,
                   help="wall-clock budget: stop at the last checkpoint that leaves no time for another epoch "
                        "(for time-limited jobs; --resume continues)")
    p.add_argument("--unroll-length", type=int, help="policy steps per robot per iteration (default 48)")
    p.add_argument("--batch-size", type=int, help="trajectories per minibatch (default 512)")
    p.add_argument("--minibatches", type=int, help="minibatches per iteration (default 4)")
    p.add_argument("--checkpoint-every", type=int, help="environment steps between checkpoints (default 5e6)")
    p.add_argument("--eval-envs", type=int, help="robots per evaluation (default 128)")
    p.add_argument("--build-dir", type=Path, help="footforge build output for the feet (default build/<feet>)")
    p.add_argument("--coordinator", metavar="HOST:PORT",
                   help="several machines: the address of process 0 (with --num-processes and --process-id; "
                        "under SLURM or Open MPI jax finds all three itself, pass --coordinator auto)")
    p.add_argument("--num-processes", type=int)
    p.add_argument("--process-id", type=int)
    if task == "rough":
        p.add_argument("--terrain", action="append", default=[], metavar="FIELD=VALUE",
                       help="override a TerrainConfig field, e.g. --terrain seed=3 --terrain num_levels=5 "
                            "(repeatable; footforge/envs/terrain.py lists the fields)")
    args = p.parse_args(argv)

    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from footforge import envs, train
    from footforge.errors import FootforgeError

    console = Console()
    if args.coordinator:  # before any other use of jax: Brax's PPO then trains over every device of every process
        import jax

        jax.distributed.initialize(**({} if args.coordinator == "auto" else {
            "coordinator_address": args.coordinator, "num_processes": args.num_processes,
            "process_id": args.process_id}))
    try:
        env_config = envs.default_config(task, args.feet, args.policy)
        if args.build_dir:
            env_config = replace(env_config, build_dir=str(args.build_dir))
        if task == "rough":
            env_config = replace(env_config, terrain=_override(env_config.terrain, args.terrain))
        overrides = {k: v for k, v in {
            "num_envs": args.num_envs, "num_timesteps": args.timesteps, "unroll_length": args.unroll_length,
            "batch_size": args.batch_size, "num_minibatches": args.minibatches,
            "checkpoint_every_steps": args.checkpoint_every, "num_eval_envs": args.eval_envs}.items() if v is not None}
        ppo = train.default_ppo(task, seed=args.seed, **overrides)
        with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed:,.0f}/{task.total:,.0f} steps"),
                      TimeElapsedColumn(), TimeRemainingColumn(), console=console) as progress:
            bar = progress.add_task("compiling and training", total=ppo.num_timesteps)

            def report(step, total, metrics):
                reward = metrics.get("eval/episode_reward", float("nan"))
                err = metrics.get("eval/episode_error/lin_vel_x_per_step", float("nan"))
                text = f"return {reward:7.2f}  vx error {err:5.3f} m/s"
                if task == "rough":
                    text += f"  terrain level {metrics.get('episode/terrain/level_per_step', float('nan')):4.2f}"
                progress.update(bar, completed=min(step, total), description=text)
            metrics = train.train(env_config, ppo, args.out, resume=args.resume, progress=report,
                                  max_wall_s=args.max_minutes * 60 if args.max_minutes is not None else None)
    except FootforgeError as e:
        console.print(f"train_{task}: error: {e}", markup=False, soft_wrap=True)
        return e.exit_code
    if metrics.get("stopped_for_time"):
        console.print(f"stopped at the wall-time budget ({args.max_minutes:g} min) after a checkpoint; "
                      f"--resume continues")
    console.print(f"policy written to {args.out / 'policy'}; final evaluation return "
                  f"{metrics.get('eval/episode_reward', float('nan')):.2f}")
    return 0


def _override(config, assignments: list[str]):
    """`config` with FIELD=VALUE assignments applied, each value read as its field's type."""
    from dataclasses import fields

    from footforge.errors import InputError

    known = {f.name: getattr(config, f.name) for f in fields(config)}
    changes = {}
    for text in assignments:
        name, sep, value = text.partition("=")
        if not sep or name not in known:
            raise InputError(f"--terrain {text}: expected FIELD=VALUE with FIELD one of {', '.join(known)}",
                             fix="e.g. --terrain num_levels=5")
        default = known[name]
        try:
            if isinstance(default, tuple):
                changes[name] = tuple(float(v) for v in value.split(","))
            else:
                changes[name] = type(default)(value)
        except ValueError:
            expected = "comma-separated list of numbers" if isinstance(default, tuple) else type(default).__name__
            raise InputError(f"--terrain {text}: '{value}' is not a {expected}",
                             fix=f"e.g. --terrain {name}={','.join(map(str, default)) if isinstance(default, tuple) else default}") from None
    config = replace(config, **changes)
    config.check()
    return config
