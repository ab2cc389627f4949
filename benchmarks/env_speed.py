"""MJX environment throughput per task, foot variant, policy type and batch size: compile time and
policy steps per second (each policy step is 4 physics steps), on whatever JAX device is present;
one JSON line. Rough terrain uses the default 10 x 20 tile heightfield; the figures of one run are
comparable with each other (ratios), not with another machine's.

Usage: python benchmarks/env_speed.py [--batches 16 64 256] [--steps 20] [--feet ball aff aof]
           [--tasks flat rough] [--policies B P BH PH]
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
    p.add_argument("--tasks", nargs="+", default=["flat", "rough"], choices=list(envs.TASKS))
    p.add_argument("--policies", nargs="+", default=["B", "PH"],
                   help="policy types where the task has them (PH on ball feet falls back to P)")
    p.add_argument("--no-compile-cache", action="store_true",
                   help="measure cold compilation: without JAX's persistent cache (footforge/compile_cache.py)")
    args = p.parse_args()
    from footforge import compile_cache

    cache = compile_cache.enable(not args.no_compile_cache)
    figures = {"machine": platform.platform(), "device": str(jax.devices()[0]), "jax": jax.__version__,
               "compile_cache": str(cache) if cache else None}
    for task in args.tasks:
        for feet in args.feet:
            policies = []
            for policy in args.policies:
                if feet == "ball":  # no passive joints to read: the blind or perceptive type
                    policy = policy.replace("H", "")
                if policy in envs.TASKS[task] and policy not in policies:
                    policies.append(policy)
            for policy in policies:
                env = envs.make(task, feet, policy)
                for batch in args.batches:
                    figures[f"{task}_{feet}_{policy}_b{batch}"] = _measure(env, batch, args.steps)
    print(json.dumps(figures))


def _measure(env, batch: int, steps: int) -> dict:
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
    for _ in range(steps):
        state = step(state, actions)
    jax.block_until_ready(state.obs)
    rate = batch * steps / (time.perf_counter() - t0)
    return {"compile_s": round(compile_s, 1), "policy_steps_per_s": round(rate, 1),
            "physics_steps_per_s": round(rate * env.config.decimation, 1)}


if __name__ == "__main__":
    main()
