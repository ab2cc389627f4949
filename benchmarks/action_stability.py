"""Does the training physics survive a policy's actions? CPU MuJoCo on the MJX environment's own
model (footforge.envs.anymal.load_robot: its timestep, contact and solver settings), robots driven
by an untrained policy's actions: each policy step a ~ N(0, 1) clipped to +-1 (PPO's initial
Gaussian, EnvConfig.init_noise_std 1), turned into PD targets by the flat task's velocity model
(target += 13.5 a dt, within the joint ranges). A robot diverges when a generalised velocity passes
EnvConfig.diverged_speed or turns non-finite (the environment's own test). One JSON line: per
setting, the robots that diverged and when.

`--sim mjx` runs the MJX environment itself instead (jitted, vmapped over the robots; its own
divergence check and restarts): the `diverged` count is then the episodes that ended diverged.

Usage: python benchmarks/action_stability.py [--sim cpu|mjx] [--feet aof aff ball] [--robots 16]
           [--seconds 10] [--sim-dt 0.005] [--decimation 4] [--seed 0]
"""

import argparse
import json
from dataclasses import replace

import mujoco
import numpy as np

from footforge import envs
from footforge.envs.anymal import load_robot


def run(feet: str, robots: int, seconds: float, sim_dt: float, decimation: int, seed: int) -> dict:
    config = replace(envs.default_config("flat", feet, "B"), sim_dt=sim_dt, decimation=decimation)
    robot = load_robot(config)
    model = robot.model
    model.opt.timestep = sim_dt
    policy_dt = sim_dt * decimation
    rng = np.random.default_rng(seed)
    steps = int(round(seconds / policy_dt))
    diverged_at = []
    for _ in range(robots):
        data = mujoco.MjData(model)
        data.qpos[:] = robot.stand_qpos
        target = robot.default_q.copy()
        data.ctrl[robot.actuator_ids] = target
        mujoco.mj_forward(model, data)
        when = None
        for k in range(steps):
            a = np.clip(rng.normal(size=12), -config.action_clip, config.action_clip)
            target = np.clip(target + config.action_scale * a * policy_dt, robot.q_limits[:, 0], robot.q_limits[:, 1])
            data.ctrl[robot.actuator_ids] = target
            mujoco.mj_step(model, data, nstep=decimation)
            if not np.all(np.abs(data.qvel) < config.diverged_speed):
                when = round((k + 1) * policy_dt, 3)
                break
        diverged_at.append(when)
    hit = [t for t in diverged_at if t is not None]
    return {"diverged": len(hit), "robots": robots, "times_s": hit}


def run_mjx(feet: str, robots: int, seconds: float, sim_dt: float, decimation: int, seed: int) -> dict:
    import time

    import jax
    import jax.numpy as jp

    env = envs.make("flat", feet, "B", sim_dt=sim_dt, decimation=decimation)
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
    return {"diverged": int(diverged.sum()), "robots": robots, "robots_diverged": int((diverged.sum(0) > 0).sum()),
            "wall_s": round(time.perf_counter() - t0, 1)}


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--sim", choices=("cpu", "mjx"), default="cpu")
    p.add_argument("--feet", nargs="+", default=["aof", "aff", "ball"])
    p.add_argument("--robots", type=int, default=16)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--sim-dt", type=float, nargs="+", default=[0.005])
    p.add_argument("--decimation", type=int, nargs="+", default=[4], help="one per --sim-dt")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    figures = {}
    for feet in args.feet:
        for dt, dec in zip(args.sim_dt, args.decimation):
            figures[f"{feet}_dt{dt * 1000:g}ms"] = (run_mjx if args.sim == "mjx" else run)(
                feet, args.robots, args.seconds, dt, dec, args.seed)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
