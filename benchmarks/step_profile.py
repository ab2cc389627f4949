"""Where an MJX physics step's time goes, per task, feet and contact model: each stage of
mjx.step (the smooth position stage, collision, constraint rows, velocity and actuation, the
constraint solve, the integrator) compiled on its own, vmapped over a batch of robots that have
stood for a while (so that the feet's contacts are active and the solve is warm-started as in
training), and timed alone; one JSON line.

Usage: python benchmarks/step_profile.py [--tasks flat rough] [--feet ball aff aof]
           [--contact-models stance fast] [--batch 128] [--repeats 20] [--settle-steps 10]
           [--variant KEY=VALUE ...]

Per configuration: nv, the contact slots (ncon) and constraint rows (nefc) MJX allocates, and
ms per physics step of the whole batch for each stage and for mjx.step itself (the stages'
sum is close to it; XLA fuses across stage boundaries in the whole step). --variant changes
the MJX model's options for an experiment without touching the environment (each value
measured as an extra configuration, keys ending in _<key><value>): `solver=cg`,
`iterations=N`, `ls_iterations=N`, `cone=elliptic`. The figures of one run are comparable with
each other; the machine's load moves them between runs.
"""

import argparse
import copy
import json
import platform
import time

import jax
import jax.numpy as jp
import mujoco
from mujoco import mjx
from mujoco.mjx._src import collision_driver, constraint, forward, sensor, smooth, solver

from footforge import envs

VARIANTS = {
    "solver": {"cg": mujoco.mjtSolver.mjSOL_CG, "newton": mujoco.mjtSolver.mjSOL_NEWTON},
    "cone": {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL},
}


def _stages():
    """mjx.forward and the Euler step, cut at the boundaries the profile reports."""
    def position(m, d):
        for f in (smooth.kinematics, smooth.com_pos, smooth.camlight, smooth.tendon, smooth.crb,
                  smooth.tendon_armature, smooth.factor_m):
            d = f(m, d)
        return d

    def velocity(m, d):
        d = smooth.transmission(m, d)
        d = sensor.sensor_pos(m, d)
        d = forward.fwd_velocity(m, d)
        d = sensor.sensor_vel(m, d)
        d = forward.fwd_actuation(m, d)
        return forward.fwd_acceleration(m, d)

    return {"position": position, "collision": collision_driver.collision,
            "constraint": constraint.make_constraint, "velocity": velocity,
            "solve": solver.solve, "integrate": forward.euler}


def _time(fn, m, data, repeats: int) -> tuple[float, float]:
    f = jax.jit(jax.vmap(fn, in_axes=(None, 0)))
    t0 = time.perf_counter()
    jax.block_until_ready(f(m, data))
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    for _ in range(repeats):
        out = f(m, data)
    jax.block_until_ready(out)
    return compile_s, (time.perf_counter() - t0) / repeats * 1e3


def profile(env, batch: int, repeats: int, settle_steps: int, options: dict) -> dict:
    reset = jax.jit(jax.vmap(env.reset))
    step = jax.jit(jax.vmap(env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(0), batch))
    actions = jp.zeros((batch, env.action_size))
    for _ in range(settle_steps):
        state = step(state, actions)
    data = state.pipeline_state
    mj = copy.deepcopy(env.robot.model)
    for key, value in options.items():
        if key in VARIANTS:
            setattr(mj.opt, key, VARIANTS[key][value])
        else:
            setattr(mj.opt, key, int(value))
    m = mjx.put_model(mj, impl=env.config.mjx_impl)
    if "cone" in options:  # the constraint rows change size with the cone: rebuild them
        data = jax.vmap(mjx.forward, in_axes=(None, 0))(m, data)
    jax.block_until_ready(data)
    sample = jax.tree.map(lambda x: x[0], data)
    ms, compile_s = {}, {}
    staged = data
    for name, fn in _stages().items():
        compile_s[name], ms[name] = _time(fn, m, staged, repeats)
        staged = jax.vmap(fn, in_axes=(None, 0))(m, staged)
    compile_s["step"], ms["step"] = _time(mjx.step, m, data, repeats)
    active = int((data._impl.contact.dist[0] < 0).sum())
    return {"nv": mj.nv, "ncon": int(sample._impl.contact.dist.shape[0]), "ncon_active_robot0": active,
            "nefc": int(sample._impl.efc_J.shape[0]), "iterations": mj.opt.iterations,
            "ls_iterations": mj.opt.ls_iterations, "solver": int(mj.opt.solver), "cone": int(mj.opt.cone),
            "ms_per_physics_step": {k: round(v, 2) for k, v in ms.items()},
            "stages_sum_ms": round(sum(v for k, v in ms.items() if k != "step"), 2),
            "compile_s": {k: round(v, 1) for k, v in compile_s.items()}}


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--tasks", nargs="+", default=["flat", "rough"], choices=list(envs.TASKS))
    p.add_argument("--feet", nargs="+", default=["ball", "aff", "aof"], choices=list(envs.FEET))
    p.add_argument("--contact-models", nargs="+", default=["stance"], choices=["stance", "fast"])
    p.add_argument("--batch", type=int, default=128)
    p.add_argument("--repeats", type=int, default=20)
    p.add_argument("--settle-steps", type=int, default=10, help="zero-action policy steps before timing")
    p.add_argument("--variant", nargs="*", default=[], metavar="KEY=VALUE",
                   help="extra configurations with one MJX option changed: solver=cg|newton, "
                        "cone=elliptic|pyramidal, iterations=N, ls_iterations=N")
    args = p.parse_args()
    variants = [{}]
    for v in args.variant:
        key, _, value = v.partition("=")
        if key in VARIANTS and value in VARIANTS[key]:
            variants.append({key: value})
        elif key in ("iterations", "ls_iterations") and value.isdigit() and int(value) > 0:
            variants.append({key: value})
        else:
            p.error(f"--variant {v}: use solver=cg|newton, cone=elliptic|pyramidal, iterations=N or ls_iterations=N")
    if args.batch < 1 or args.repeats < 1 or args.settle_steps < 0:
        p.error("--batch and --repeats must be at least 1, --settle-steps at least 0")
    from footforge.rl import compile_cache

    compile_cache.enable(True)
    figures = {"benchmark": "step_profile", "machine": platform.platform(), "device": str(jax.devices()[0]),
               "jax": jax.__version__, "mujoco": mujoco.__version__, "batch": args.batch}
    for task in args.tasks:
        for feet in args.feet:
            for contact in args.contact_models:
                env = envs.from_config(envs.default_config(task, feet, "B", contact))
                for options in variants:
                    name = f"{task}_{feet}_{contact}" + "".join(f"_{k}{v}" for k, v in options.items())
                    figures[name] = profile(env, args.batch, args.repeats, args.settle_steps, options)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
