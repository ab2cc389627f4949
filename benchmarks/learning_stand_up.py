"""Does PPO learn anything in 98 k steps on the CPU? Brax PPO on the flat ball environment stepped by
MuJoCo's C engine, a task made learnable that fast: zero commands, no pushes, no observation noise,
no domain randomisation, 2 s episodes, 32-32 networks, and the untrained policy made to fall (the
flat baseline's velocity actions at 13.5 rad/s per unit, PPO's settings before 2026-11-26: a
full-size output layer, rate 1e-3, adaptive KL 0.008, entropy 0.001). The untrained robot falls
within ~0.35 s; PPO must learn to hold itself up, which lengthens the episodes and raises the return.

One JSON line: the deterministic evaluation's curve (step, return, mean episode length in policy
steps), and `learned`: the last episode longer than 1.5 times the first, which was under 25 steps,
and the last return above 1.5 times the first. Was tests/test_train.py's
test_tiny_ppo_run_increases_the_return (a learning run judged by a threshold is a benchmark; the
tests keep a tiny training run end to end). Deterministic for a seed on one machine.

Usage: python benchmarks/learning_stand_up.py [--timesteps 98304] [--seed 0]
"""

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from footforge import envs
from footforge.build import BuildOptions, build
from footforge.rl import train
from footforge.rl.config import PPOConfig


def run(timesteps: int, seed: int, tmp: Path) -> dict:
    build(BuildOptions(variant="ball", out_dir=tmp / "ball", formats=("mjcf",)))
    cfg = envs.default_config("flat", "ball", "B")
    cfg = replace(cfg, action="velocity", action_scale=13.5, observations=replace(cfg.observations, pd_targets=True))
    cfg = replace(
        cfg,
        build_dir=str(tmp / "ball"),
        episode_length_s=2.0,
        commands=replace(
            cfg.commands, lin_vel_x_range=(0.0, 0.0), lin_vel_y_range=(0.0, 0.0), heading_range=(0.0, 0.0)
        ),
        pushes=replace(cfg.pushes, enabled=False),
        observations=replace(cfg.observations, noise=False),
        randomization=replace(cfg.randomization, friction_range=None),
        physics="mujoco",
    )
    ppo = PPOConfig(
        num_envs=32,
        unroll_length=16,
        batch_size=32,
        num_minibatches=4,
        num_timesteps=timesteps,
        checkpoint_every_steps=32_768,
        num_eval_envs=32,
        policy_hidden_layers=(32, 32),
        value_hidden_layers=(32, 32),
        learning_rate=1e-3,
        adaptive_kl=0.008,
        entropy_cost=0.001,
        policy_output_init_scale=1.0,
        seed=seed,
    )
    t0 = time.perf_counter()
    train.train(cfg, ppo, tmp / "run", notice=lambda text: None)
    wall = time.perf_counter() - t0
    lines = map(json.loads, (tmp / "run" / "metrics.jsonl").read_text().splitlines())
    evaluations = [line for line in lines if "eval/episode_reward" in line]  # the others: training episodes
    curve = [
        [e["global_step"], round(e["eval/episode_reward"], 3), round(e["eval/avg_episode_length"], 1)]
        for e in evaluations
    ]
    (_, first_return, first_length), (_, last_return, last_length) = curve[0], curve[-1]
    learned = first_length < 25 and last_length > 1.5 * first_length and last_return > 1.5 * first_return
    return {"timesteps": timesteps, "seed": seed, "wall_s": round(wall, 1), "curve": curve, "learned": learned}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--timesteps", type=int, default=98_304)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        print(json.dumps(run(args.timesteps, args.seed, Path(tmp))))


if __name__ == "__main__":
    main()
