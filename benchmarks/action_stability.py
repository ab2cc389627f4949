"""Does the training physics survive a policy's actions? An untrained policy's random actions on
flat ground (footforge.envs.stability: CPU MuJoCo on the MJX environment's own model) for each
feet and physics step; one JSON line: per setting, the robots that diverged and when.

`--sim mjx` runs the MJX environment itself instead (jitted, vmapped over the robots; its own
divergence check and restarts): the `diverged` count is then the episodes that ended diverged.

Usage: python benchmarks/action_stability.py [--sim cpu|mjx] [--feet aof aff ball] [--robots 16]
           [--seconds 10] [--sim-dt 0.005] [--decimation 4] [--seed 0]
"""

import argparse
import json
from dataclasses import replace

import numpy as np

from footforge import envs
from footforge.envs.stability import divergence_times
from footforge.variants import VALIDATED


def run(feet: str, robots: int, seconds: float, sim_dt: float, decimation: int, seed: int, **physics) -> dict:
    config = replace(envs.default_config("flat", feet, "B"), sim_dt=sim_dt, decimation=decimation, **physics)
    hit = [t for t in divergence_times(config, robots, seconds, seed) if t is not None]
    return {"diverged": len(hit), "robots": robots, "times_s": hit}


def run_mjx(feet: str, robots: int, seconds: float, sim_dt: float, decimation: int, seed: int, **physics) -> dict:
    import time

    import jax
    import jax.numpy as jp

    env = envs.make("flat", feet, "B", sim_dt=sim_dt, decimation=decimation, **physics)
    steps = int(round(seconds / env.config.policy_dt))
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))

    def rollout(state, key):
        def body(carry, k):
            s = step(carry, jp.clip(jax.random.normal(k, (robots, 12)), -1.0, 1.0))
            return s, s.metrics["diverged"]

        return jax.lax.scan(body, state, jax.random.split(key, steps))

    key_reset, key_run = jax.random.split(jax.random.PRNGKey(seed))
    t0 = time.perf_counter()
    state = reset(jax.random.split(key_reset, robots))
    _, diverged = jax.jit(rollout)(state, key_run)
    diverged = np.asarray(diverged)
    return {
        "diverged": int(diverged.sum()),
        "robots": robots,
        "robots_diverged": int((diverged.sum(0) > 0).sum()),
        "wall_s": round(time.perf_counter() - t0, 1),
    }


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--sim", choices=("cpu", "mjx"), default="cpu")
    p.add_argument("--feet", nargs="+", default=list(VALIDATED))
    p.add_argument("--robots", type=int, default=16)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--sim-dt", type=float, nargs="+", default=[0.005])
    p.add_argument("--decimation", type=int, nargs="+", default=[4], help="one per --sim-dt")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--contact-model", choices=("fast", "build", "stance"), default="fast", help="EnvConfig.contact_model"
    )
    p.add_argument(
        "--iterations",
        type=int,
        nargs=2,
        metavar=("NEWTON", "LINESEARCH"),
        help="EnvConfig.solver_iterations and solver_ls_iterations (default: the config's)",
    )
    args = p.parse_args()
    physics = {"contact_model": args.contact_model}
    if args.iterations:
        physics |= {"solver_iterations": args.iterations[0], "solver_ls_iterations": args.iterations[1]}
    figures = {}
    for feet in args.feet:
        for dt, dec in zip(args.sim_dt, args.decimation):
            figures[f"{feet}_dt{dt * 1000:g}ms"] = (run_mjx if args.sim == "mjx" else run)(
                feet, args.robots, args.seconds, dt, dec, args.seed, **physics
            )
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
