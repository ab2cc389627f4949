"""Where a training environment's compile time goes: for each task, feet, policy type and contact
model, the batched reset and step that PPO runs (footforge's training wrapping, domain
randomisation included) are traced and lowered to StableHLO, then compiled by XLA on whatever
device is present. One JSON line: per environment and per function (reset, step) the seconds to
trace and lower, the seconds XLA took to compile, and the size of the lowered program (operations
in its StableHLO text; the compile time of a backend grows with it), plus the model's sizes
(bodies, DOFs, geoms, collision pairs, and those pairs by geom types), so that what makes a program
large can be told from one run.

Usage: python benchmarks/compile_profile.py [--tasks flat rough] [--feet ball aff aof]
           [--policies B PH] [--contact-models stance fast] [--batch 128]
           [--shank-collisions on off] [--repeat-step]

Tracing and lowering run on the host's Python on every machine; the XLA compile is the device's
(the GPU machine compiles on its CPU cores for its GPU). The figures of one run compare with each
other (ratios); on a shared machine the seconds are upper bounds. JAX's persistent compilation
cache is switched off (a cold compile is what a new machine pays). --repeat-step also times a
second lowering of the step (the cost of tracing again, as each new process pays).
"""

import argparse
import json
import platform
import re
import time
from dataclasses import replace

import jax
import jax.numpy as jp
import mujoco

from footforge import envs
from footforge.envs.randomization import randomizer
from footforge.envs.wrappers import wrap_for_training
from footforge.variants import FEET


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tasks", nargs="+", default=["flat", "rough"], choices=list(envs.TASKS))
    p.add_argument("--feet", nargs="+", default=list(FEET), choices=list(FEET))
    p.add_argument(
        "--policies",
        nargs="+",
        default=["B"],
        help="policy types where the task has them (PH on ball feet falls back to P)",
    )
    p.add_argument("--contact-models", nargs="+", default=["stance"], choices=["stance", "fast"])
    p.add_argument("--batch", type=int, default=128, help="robots in the batched reset and step")
    p.add_argument(
        "--shank-collisions",
        nargs="+",
        default=["on"],
        choices=["on", "off"],
        help="rough task: the shank tubes colliding with the terrain (EnvConfig.shank_collisions)",
    )
    p.add_argument("--repeat-step", action="store_true", help="also time a second trace and lowering of the step")
    args = p.parse_args()
    if args.batch < 1:
        p.error(f"--batch must be at least 1 (got {args.batch})")
    # Cold compilation, whatever the environment sets (the GPU kit's run.sh sets JAX_COMPILATION_CACHE_DIR).
    jax.config.update("jax_enable_compilation_cache", False)
    figures = {
        "machine": platform.platform(),
        "device": str(jax.devices()[0]),
        "jax": jax.__version__,
        "mujoco": mujoco.__version__,
        "batch": args.batch,
    }
    for task in args.tasks:
        for feet in args.feet:
            policies = envs.policy_types(task, feet, args.policies)
            shanks = args.shank_collisions if task == "rough" else ["on"]
            for policy in policies:
                for contact in args.contact_models:
                    for shank in shanks:
                        config = replace(
                            envs.default_config(task, feet, policy, contact), shank_collisions=shank == "on"
                        )
                        name = f"{task}_{feet}_{policy}_{contact}" + ("" if shank == "on" else "_noshank")
                        figures[name] = profile(envs.from_config(config), args.batch, args.repeat_step)
                        print(f"{name}: {figures[name]}", flush=True)
    print(json.dumps(figures))


def model_sizes(env) -> dict:
    """The model's sizes that the compiled program's size follows."""
    m = env.robot.model
    groups = _collision_groups(m)
    return {
        "nbody": m.nbody,
        "nv": m.nv,
        "ngeom": m.ngeom,
        "nhfield": m.nhfield,
        "collision_pairs": sum(groups.values()),
        "collision_groups": groups,
    }


def _collision_groups(m: mujoco.MjModel) -> dict[str, int]:
    """The geom pairs that may collide (on different bodies, contype/conaffinity bits matching) by
    their (type, type): MJX compiles a collision function per distinct pair of types."""
    groups: dict[str, int] = {}
    for i in range(m.ngeom):
        for j in range(i + 1, m.ngeom):
            if m.geom_bodyid[i] == m.geom_bodyid[j]:
                continue
            if not ((m.geom_contype[i] & m.geom_conaffinity[j]) or (m.geom_contype[j] & m.geom_conaffinity[i])):
                continue
            key = "-".join(
                sorted(mujoco.mjtGeom(int(m.geom_type[g])).name.removeprefix("mjGEOM_").lower() for g in (i, j))
            )
            groups[key] = groups.get(key, 0) + 1
    return groups


def _operations(text: str) -> int:
    """Operations in a StableHLO module's text: lines that assign a result (%x = ...)."""
    return sum(1 for line in text.splitlines() if re.match(r"\s*%[\w#:]+(, %[\w#:]+)* = ", line))


def _time_lowering(fn, *example):
    t0 = time.perf_counter()
    lowered = jax.jit(fn).lower(*example)
    trace_lower_s = time.perf_counter() - t0
    return lowered, trace_lower_s


def profile(env, batch: int, repeat_step: bool) -> dict:
    """Trace/lower and compile seconds and program sizes of the training stack's reset and step."""
    # The wrapping and randomisation PPO trains with (footforge.rl.train passes the same).
    randomization = randomizer(env)
    keys = jax.random.split(jax.random.PRNGKey(0), batch)
    rand_fn = None if randomization is None else (lambda sys: randomization(sys, keys))
    wrapped = wrap_for_training(env, env.config.episode_steps, randomization_fn=rand_fn)
    figures = {"decimation": env.config.decimation} | model_sizes(env)
    lowered, figures["reset_trace_lower_s"] = _time_lowering(wrapped.reset, keys)
    figures["reset_ops"] = _operations(lowered.as_text())
    t0 = time.perf_counter()
    reset = lowered.compile()
    figures["reset_compile_s"] = time.perf_counter() - t0
    state = reset(keys)
    actions = jp.zeros((batch, env.action_size))
    lowered, figures["step_trace_lower_s"] = _time_lowering(wrapped.step, state, actions)
    figures["step_ops"] = _operations(lowered.as_text())
    t0 = time.perf_counter()
    step = lowered.compile()
    figures["step_compile_s"] = time.perf_counter() - t0
    jax.block_until_ready(step(state, actions).obs)
    if repeat_step:
        _, figures["step_trace_lower_again_s"] = _time_lowering(wrapped.step, state, actions)
    return {k: round(v, 2) if isinstance(v, float) else v for k, v in figures.items()}


if __name__ == "__main__":
    main()
