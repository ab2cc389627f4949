"""Where an MJX physics step's time goes, per task, feet and contact model: each stage of
mjx.step (the smooth position stage, collision, constraint rows, velocity and actuation, the
constraint solve, the integrator) compiled on its own, vmapped over a batch of robots that have
stood for a while (so that the feet's contacts are active and the solve is warm-started as in
training), and timed alone; one JSON line.

Usage: python benchmarks/step_profile.py [--tasks flat rough] [--feet ball aff aof]
           [--contact-models stance fast] [--batch 128] [--repeats 20] [--settle-steps 10]

Per configuration: nv, the contact slots (ncon) and constraint rows (nefc) MJX allocates, and
ms per physics step of the whole batch for each stage, for mjx.step itself and for the environment's own
policy step divided by its physics steps (`env_step`: what benchmarks/env_speed.py times, with
the observation, rewards and resets; one call per policy step). Each is timed on its own,
compiled with the model as a constant, as the environment's step is. The stages rank the costs
rather than add up: a call costs some dispatch, so the smallest read high, and XLA schedules a
stage differently inside the whole step (AOF's heightfield collision alone has timed longer than
the whole step, 170 against 147 ms). env_step is the figure to compare feet by. The figures of
one run are comparable with each other; the machine's load moves them between runs.
"""

import argparse
import json
import platform
import time

import jax
import jax.numpy as jp
import mujoco
from mujoco import mjx
from mujoco.mjx._src import collision_driver, constraint, forward, sensor, smooth, solver

from footforge import envs


def _stages():
    """mjx.forward and the Euler step, cut at the boundaries the profile reports."""

    def position(m, d):
        for f in (
            smooth.kinematics,
            smooth.com_pos,
            smooth.camlight,
            smooth.tendon,
            smooth.crb,
            smooth.tendon_armature,
            smooth.factor_m,
        ):
            d = f(m, d)
        return d

    def velocity(m, d):
        d = smooth.transmission(m, d)
        d = sensor.sensor_pos(m, d)
        d = forward.fwd_velocity(m, d)
        d = sensor.sensor_vel(m, d)
        d = forward.fwd_actuation(m, d)
        return forward.fwd_acceleration(m, d)

    return {
        "position": position,
        "collision": collision_driver.collision,
        "constraint": constraint.make_constraint,
        "velocity": velocity,
        "solve": solver.solve,
        "integrate": forward.euler,
    }


def _time(f, data, repeats: int) -> tuple[float, float]:
    """(compile s, ms per call) of the jitted f(data)."""
    t0 = time.perf_counter()
    jax.block_until_ready(f(data))
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(repeats):
        out = f(data)
    jax.block_until_ready(out)
    return compile_s, (time.perf_counter() - t0) / repeats * 1e3


def _batched(fn, m):
    """fn(m, d) jitted over a batch of d, the model a constant as in the environment's step."""
    return jax.jit(jax.vmap(lambda d: fn(m, d)))


def profile(env, batch: int, repeats: int, settle_steps: int) -> dict:
    reset = jax.jit(jax.vmap(env.reset))
    step = jax.jit(jax.vmap(env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(0), batch))
    actions = jp.zeros((batch, env.action_size))
    for _ in range(settle_steps):
        state = step(state, actions)
    data = state.pipeline_state
    mj = env.robot.model
    m = env.sys  # the environment's own MJX model
    jax.block_until_ready(data)
    ms, compile_s = {}, {}
    staged = data
    for name, fn in _stages().items():
        staged_fn = _batched(fn, m)
        compile_s[name], ms[name] = _time(staged_fn, staged, repeats)
        staged = staged_fn(staged)
    compile_s["step"], ms["step"] = _time(_batched(mjx.step, m), data, repeats)
    # The environment's own policy step: physics, observation, rewards, resets.
    t, per_policy_step = _time(lambda s: step(s, actions), state, repeats)
    compile_s["env_step"], ms["env_step"] = t, per_policy_step / env.config.decimation
    active = int((data._impl.contact.dist[0] < 0).sum())
    return {
        "nv": mj.nv,
        "ncon": int(data._impl.contact.dist.shape[1]),
        "ncon_active_robot0": active,
        "nefc": int(data._impl.efc_J.shape[1]),
        "iterations": mj.opt.iterations,
        "ls_iterations": mj.opt.ls_iterations,
        "solver": int(mj.opt.solver),
        "cone": int(mj.opt.cone),
        "ms_per_physics_step": {k: round(v, 2) for k, v in ms.items()},
        "stages_sum_ms": round(sum(v for k, v in ms.items() if k not in ("step", "env_step")), 2),
        "compile_s": {k: round(v, 1) for k, v in compile_s.items()},
    }


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--tasks", nargs="+", default=["flat", "rough"], choices=list(envs.TASKS))
    p.add_argument("--feet", nargs="+", default=list(envs.FEET), choices=list(envs.FEET))
    p.add_argument("--contact-models", nargs="+", default=["stance"], choices=["stance", "fast"])
    p.add_argument("--batch", type=int, default=128)
    p.add_argument("--repeats", type=int, default=20)
    p.add_argument("--settle-steps", type=int, default=10, help="zero-action policy steps before timing")
    args = p.parse_args()
    if args.batch < 1 or args.repeats < 1 or args.settle_steps < 0:
        p.error("--batch and --repeats must be at least 1, --settle-steps at least 0")
    from footforge.rl import compile_cache

    compile_cache.enable(True)
    figures = {
        "benchmark": "step_profile",
        "machine": platform.platform(),
        "device": str(jax.devices()[0]),
        "jax": jax.__version__,
        "mujoco": mujoco.__version__,
        "batch": args.batch,
    }
    for task in args.tasks:
        for feet in args.feet:
            for contact in args.contact_models:
                env = envs.from_config(envs.default_config(task, feet, "B", contact))
                figures[f"{task}_{feet}_{contact}"] = profile(env, args.batch, args.repeats, args.settle_steps)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
