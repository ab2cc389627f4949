"""The learning anchor: MuJoCo Playground's Go1JoystickFlatTerrain trained with Playground's own
PPO settings on this machine, for as many steps as footforge's CPU learning benchmark
(benchmarks/learning_cpu.py), and judged the same way: the deterministic policy's forward-velocity
error over 32 robots x 20 s, beside the error a robot standing still would score.

Playground's settings (mujoco_playground.config.locomotion_params.brax_ppo_config, playground
0.2.0) as they ship, except the robot count, which a 2-core CPU cannot hold: 128 robots instead of
8,192, with Playground's minibatch share of them kept (32 minibatches of 4 trajectories, as its 32
of 256), and its evaluations replaced by the training episodes' logs (as learning_cpu.py
--no-evaluations) and one deterministic rollout at the end. Everything else is Playground's: its
Go1 environment and rewards, commands, domain randomisation, networks (512-256-128, privileged
critic), learning rate 3e-4, entropy 0.01, discount 0.97, unroll 20, 4 updates per batch. MJX's
"jax" implementation and stand-in visual meshes, as benchmarks/playground_go1.py (whose docstring
shows they change no physics).

Needs the bench extra: pip install -c constraints.txt -e ".[bench]".

Usage: python benchmarks/playground_go1_learning.py [--timesteps 3000000] [--num-envs 128] [--seed 0]
Prints one JSON line: steps, wall_s, forward_error (m/s), standing_error (m/s: |commanded vx|),
falls (of the rollout's robots), episode curve (training episodes: steps, wall s, the tracking
term, the summed reward), machine.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import playground_go1  # noqa: E402  (benchmarks/playground_go1.py: the environment, meshes checked)


def rollout_forward_error(env, make_policy, params, robots: int, steps: int, seed: int) -> dict:
    """The deterministic policy's mean |commanded vx - vx| (base frame) over `robots` x `steps`
    policy steps, counted while a robot is up, and what standing still would score."""
    import jax
    import jax.numpy as jp

    policy = make_policy(params, deterministic=True)
    reset = jax.jit(jax.vmap(env.reset))
    step = jax.jit(jax.vmap(env.step))
    act = jax.jit(jax.vmap(lambda obs, key: policy(obs, key)[0]))
    linvel = jax.jit(jax.vmap(env.get_local_linvel))
    state = reset(jax.random.split(jax.random.PRNGKey(seed), robots))
    error = standing = counted = 0.0
    fell = jp.zeros(robots, bool)
    keys = jax.random.split(jax.random.PRNGKey(seed + 1), steps)
    for k in keys:
        state = step(state, act(state.obs, jax.random.split(k, robots)))
        vx, cmd = linvel(state.data)[:, 0], state.info["command"][:, 0]
        fell = fell | (state.done > 0)
        up = ~fell
        error += float(jp.sum(jp.where(up, jp.abs(cmd - vx), 0.0)))
        standing += float(jp.sum(jp.where(up, jp.abs(cmd), 0.0)))
        counted += float(jp.sum(up))
    return {
        "forward_error": error / max(counted, 1.0),
        "standing_error": standing / max(counted, 1.0),
        "falls": int(jp.sum(fell)),
        "robots": robots,
        "seconds": steps * env.dt,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--timesteps", type=int, default=3_000_000)
    p.add_argument("--num-envs", type=int, default=128)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--eval-robots", type=int, default=32)
    p.add_argument("--eval-seconds", type=float, default=20.0)
    args = p.parse_args(argv)
    if not playground_go1.available():
        print('needs MuJoCo Playground: pip install -c constraints.txt -e ".[bench]"', file=sys.stderr)
        return 2

    import jax
    from brax.training.agents.ppo import networks as ppo_networks, train as ppo
    from mujoco_playground import registry, wrapper
    from mujoco_playground.config import locomotion_params

    from footforge.rl import jax_compat

    jax_compat.install()  # Brax 0.14.2's PPO on newer JAX, as footforge trains
    name = playground_go1.ENV_NAMES["flat"]
    env, meshes = playground_go1.make_env("flat")  # Brax wraps it for training and leaves it as it is
    params = locomotion_params.brax_ppo_config(name, impl="jax")
    share = params.num_envs // params.batch_size  # Playground's minibatches: 8192 robots / 256 = 32
    settings = params.to_dict()
    network = settings.pop("network_factory")
    settings.pop("num_eval_envs", None)
    settings.pop("num_resets_per_eval", None)
    settings.update(
        num_timesteps=args.timesteps,
        num_envs=args.num_envs,
        batch_size=max(1, args.num_envs // share),
        num_minibatches=share,
        num_evals=2,
        run_evals=False,
        log_training_metrics=True,
        training_metrics_steps=max(args.timesteps // 12, 1),
    )
    curve = []
    t0 = time.time()

    def progress(step, metrics):
        if "episode/sum_reward" in metrics:
            row = {
                "env_steps": int(step),
                "wall_s": round(time.time() - t0, 1),
                "sum_reward": float(metrics["episode/sum_reward"]),
                "tracking_lin_vel": float(metrics.get("episode/reward/tracking_lin_vel", float("nan"))),
            }
            curve.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)

    make_policy, trained, _ = ppo.train(
        environment=env,
        progress_fn=progress,
        seed=args.seed,
        network_factory=functools.partial(ppo_networks.make_ppo_networks, **network),
        wrap_env_fn=wrapper.wrap_for_brax_training,
        randomization_fn=registry.get_domain_randomizer(name),
        **settings,
    )
    wall_s = time.time() - t0
    verdict = rollout_forward_error(
        env, make_policy, trained, args.eval_robots, int(round(args.eval_seconds / env.dt)), args.seed + 7
    )
    print(
        json.dumps(
            {
                "benchmark": "playground_go1_learning",
                "env": name,
                "meshes": meshes,
                "steps": int(args.timesteps),
                "num_envs": args.num_envs,
                "batch_size": settings["batch_size"],
                "num_minibatches": share,
                "unroll_length": settings["unroll_length"],
                "learning_rate": settings["learning_rate"],
                "entropy_cost": settings["entropy_cost"],
                "discounting": settings["discounting"],
                "wall_s": round(wall_s, 1),
                **verdict,
                "curve": curve,
                "machine": platform.platform(),
                "cpu_cores": os.cpu_count(),
                "backend": jax.default_backend(),
                "jax": jax.__version__,
                "playground": playground_go1.version(),
            }
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
