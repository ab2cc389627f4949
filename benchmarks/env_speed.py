"""MJX environment throughput per foot variant and batch size: compile time and policy steps per
second (each policy step is 4 physics steps), on whatever JAX device is present; one JSON line.

Usage: python benchmarks/env_speed.py [--batches 16 64 256] [--steps 20] [--feet ball aff aof]
"""

import argparse
import json
import platform
import time

import jax
import jax.numpy as jp

from footforge import envs


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--batches", type=int, nargs="+", default=[16, 64, 256])
    p.add_argument("--steps", type=int, default=20, help="policy steps timed per batch size")
    p.add_argument("--feet", nargs="+", default=["ball", "aff", "aof"])
    args = p.parse_args()
    figures = {"machine": platform.platform(), "device": str(jax.devices()[0]), "jax": jax.__version__}
    for feet in args.feet:
        env = envs.make("flat", feet, "B")
        for batch in args.batches:
            reset = jax.jit(jax.vmap(env.reset))
            step = jax.jit(jax.vmap(env.step))
            keys = jax.random.split(jax.random.PRNGKey(0), batch)
            actions = jp.zeros((batch, env.action_size))
            t0 = time.perf_counter()
            state = reset(keys)
            state = step(state, actions)
            jax.block_until_ready(state.obs)
            compile_s = time.perf_counter() - t0
            t0 = time.perf_counter()
            for _ in range(args.steps):
                state = step(state, actions)
            jax.block_until_ready(state.obs)
            rate = batch * args.steps / (time.perf_counter() - t0)
            figures[f"{feet}_b{batch}"] = {"compile_s": round(compile_s, 1), "policy_steps_per_s": round(rate, 1),
                                           "physics_steps_per_s": round(rate * env.config.decimation, 1)}
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
