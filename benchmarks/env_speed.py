"""MJX environment throughput per task, foot variant, policy type, contact model and batch size:
compile time and policy steps per second (and physics steps per second: a policy step is 4 physics
steps for ball feet under contact_model 'fast', 8 otherwise), on whatever JAX
device is present; one JSON line. Rough terrain uses the default 10 x 20 tile heightfield; the
figures of one run are comparable with each other (ratios), not with another machine's.

Usage: python benchmarks/env_speed.py [--batches 16 64 256] [--steps 20] [--feet ball aff aof]
           [--tasks flat rough] [--policies B P BH PH] [--contact-models fast stance]
           [--float64-physics] [--shank-collisions on off]

Keys: <task>_<feet>_<policy>_b<batch> for 'fast' (the key of the measurements before the
environments' default became 'stance'), with _stance before _b<batch> for 'stance'; each model at
its own step and iterations (envs.default_config). --float64-physics runs every environment of
the run in float64 (EnvConfig.float64_physics; JAX's x64 is process-wide).
"""

import argparse
import json
import platform
import time
from dataclasses import replace

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
    p.add_argument("--contact-models", nargs="+", default=["stance", "fast"], choices=["stance", "fast"],
                   help="EnvConfig.contact_model values to measure (default both: stance, the environments' "
                        "default, and fast)")
    p.add_argument("--float64-physics", action="store_true", help="MJX in float64 (EnvConfig.float64_physics)")
    p.add_argument("--shank-collisions", nargs="+", default=["on"], choices=["on", "off"],
                   help="rough task: shank tubes colliding with the terrain (EnvConfig.shank_collisions); "
                        "'on off' measures both (keys of 'off' end in _noshank before _b<batch>)")
    p.add_argument("--no-compile-cache", action="store_true",
                   help="measure cold compilation: without JAX's persistent cache (footforge/compile_cache.py)")
    args = p.parse_args()
    if args.float64_physics:  # before any JAX array
        jax.config.update("jax_enable_x64", True)
    from footforge import compile_cache

    cache = compile_cache.enable(not args.no_compile_cache)
    figures = {"machine": platform.platform(), "device": str(jax.devices()[0]), "jax": jax.__version__,
               "compile_cache": str(cache) if cache else None, "float64_physics": args.float64_physics}
    for task in args.tasks:
        for feet in args.feet:
            policies = []
            for policy in args.policies:
                if feet == "ball":  # no passive joints to read: the blind or perceptive type
                    policy = policy.replace("H", "")
                if policy in envs.TASKS[task] and policy not in policies:
                    policies.append(policy)
            shanks = args.shank_collisions if task == "rough" else ["on"]
            for policy, contact, shank in ((kind, model, on) for kind in policies for model in args.contact_models
                                           for on in shanks):
                config = envs.default_config(task, feet, policy, contact)
                env = envs.from_config(replace(config, float64_physics=args.float64_physics,
                                               shank_collisions=shank == "on"))
                name = (f"{task}_{feet}_{policy}" + ("" if contact == "fast" else f"_{contact}")
                        + ("" if shank == "on" else "_noshank"))
                for batch in args.batches:
                    figures[f"{name}_b{batch}"] = _measure(env, batch, args.steps)
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
