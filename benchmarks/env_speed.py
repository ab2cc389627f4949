"""Environment throughput per task, foot variant, policy type, contact model, physics engine and batch size:
compile time and policy steps per second (and physics steps per second: a policy step is 4 physics
steps of 5 ms under contact_model 'fast', 8 of 2.5 ms under 'stance'), on whatever JAX
device is present; one JSON line. Rough terrain uses the default 10 x 20 tile heightfield; the
figures of one run are comparable with each other (ratios), not with another machine's.

Usage: python benchmarks/env_speed.py [--batches 16 64 256] [--steps 20] [--feet ball aff aof]
           [--tasks flat rough] [--policies B P BH PH] [--contact-models fast stance]
           [--float64-physics] [--shank-collisions on off] [--heightfield-soles spheres box] [--playground]
           [--mjx-impl jax|warp]
           [--build-roots [LABEL=]DIR ...] [--physics mjx mujoco] [--raw-c]

Keys: <task>_<feet>_<policy>_b<batch> for 'fast' (the key of the measurements before the
environments' default became 'stance'), with _stance before _b<batch> for 'stance'; each model at
its own step and iterations (envs.default_config). --physics (default mjx) measures each environment
under each engine (EnvConfig.physics; footforge.envs.engine): the C engine's keys end in _mujoco
before _b<batch>. --raw-c also times MuJoCo's C engine alone on each C environment's own model
(mujoco.rollout, `decimation` physics steps per policy step from the reset states, the policy step's
PD targets held, no task code): keys <name>_raw_c<threads>_b<batch> for one thread and for all
(the limit this machine sets). --float64-physics runs every environment of
the run in float64 (EnvConfig.float64_physics; JAX's x64 is process-wide).

--playground (off by default) also measures MuJoCo Playground's Go1 joystick environment
(Go1JoystickFlatTerrain / Go1JoystickRoughTerrain, MJX "jax" implementation, zero actions) for each
of the run's tasks at the same batch sizes and steps, in the same process: keys
playground_go1_<task>_b<batch>, each with compile_s, policy_steps_per_s and physics_steps_per_s as
above (a Go1 policy step is 5 physics steps of 4 ms) plus its ctrl_dt, sim_dt, solver iterations,
cone and contacts per foot; and playground (the package's version). --feet, --policies,
--contact-models and --shank-collisions do not apply to it; under --float64-physics it runs in
float64 too (x64 is process-wide). It needs the optional bench extra
(pip install -c constraints.txt -e ".[bench]"; without it the run exits with code 2); see
benchmarks/playground_go1.py (stand-in visual meshes for Menagerie's Go1, physics checked).
"""

import argparse
import json
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path

import jax
import jax.numpy as jp

from footforge import envs
from footforge.variants import FEET


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--batches", type=int, nargs="+", default=[16, 64, 256])
    p.add_argument("--steps", type=int, default=20, help="policy steps timed per batch size")
    p.add_argument("--feet", nargs="+", default=list(FEET))
    p.add_argument("--tasks", nargs="+", default=["flat", "rough"], choices=list(envs.TASKS))
    p.add_argument(
        "--policies",
        nargs="+",
        default=["B", "PH"],
        help="policy types where the task has them (PH on ball feet falls back to P)",
    )
    p.add_argument(
        "--contact-models",
        nargs="+",
        default=["stance", "fast"],
        choices=["stance", "fast"],
        help="EnvConfig.contact_model values to measure (default both: stance, the environments' default, and fast)",
    )
    p.add_argument("--float64-physics", action="store_true", help="MJX in float64 (EnvConfig.float64_physics)")
    p.add_argument(
        "--shank-collisions",
        nargs="+",
        default=["on"],
        choices=["on", "off"],
        help="rough task: shank tubes colliding with the terrain (EnvConfig.shank_collisions); "
        "'on off' measures both (keys of 'off' end in _noshank before _b<batch>)",
    )
    p.add_argument(
        "--heightfield-soles",
        nargs="+",
        default=["spheres"],
        choices=["spheres", "box"],
        help="rough AFF/AOF: the sole colliders on the heightfield (EnvConfig.heightfield_soles); "
        "'spheres box' measures both (keys of 'box' end in _soleboxes before _b<batch>)",
    )
    p.add_argument(
        "--no-compile-cache",
        action="store_true",
        help="measure cold compilation: without JAX's persistent cache (footforge/rl/compile_cache.py)",
    )
    p.add_argument(
        "--playground",
        action="store_true",
        help="also MuJoCo Playground's Go1 joystick for each task and batch size (keys "
        "playground_go1_<task>_b<batch>; needs the bench extra)",
    )
    p.add_argument(
        "--mjx-impl",
        choices=["jax", "warp"],
        default="jax",
        help="MJX's backend (EnvConfig.mjx_impl): warp needs MuJoCo Warp and an NVIDIA GPU",
    )
    p.add_argument(
        "--build-roots",
        nargs="+",
        default=[""],
        metavar="[LABEL=]DIR",
        help="builds to measure, each holding <DIR>/<feet>/ (default: the environments' own, build/); "
        "a LABEL is added to the keys (<task>_<feet>_<policy>_<LABEL>..._b<batch>), so that "
        "builds from different parameter files are measured in one run",
    )
    p.add_argument(
        "--physics",
        nargs="+",
        default=["mjx"],
        choices=["mjx", "mujoco"],
        help="engines to measure (EnvConfig.physics): keys of mujoco end in _mujoco before _b<batch>",
    )
    p.add_argument(
        "--raw-c",
        action="store_true",
        help="with --physics mujoco: also MuJoCo's C engine alone (mujoco.rollout) on the same model, "
        "1 thread and all (keys <name>_raw_c<threads>_b<batch>)",
    )
    args = p.parse_args()
    if args.mjx_impl != "jax":  # refused before any compiling, as a usage error (exit 2)
        from footforge.envs.anymal import check_mjx_impl
        from footforge.envs.config import EnvConfig
        from footforge.errors import InputError

        try:
            check_mjx_impl(EnvConfig(mjx_impl=args.mjx_impl))
        except InputError as e:
            p.error(f"--mjx-impl {args.mjx_impl}: {e}")
    roots = [tuple(r.split("=", 1)) if "=" in r else ("", r) for r in args.build_roots]
    if len(roots) > 1:  # every build its own keys: an unlabelled one is named after its folder
        roots = [(label or Path(root).name, root) for label, root in roots]
        if len({label for label, _ in roots}) < len(roots):
            p.error("--build-roots: two builds with one label; name them LABEL=DIR")
    go1 = None
    if args.playground:
        sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/playground_go1.py
        import playground_go1 as go1

        if not go1.available():
            p.error(f"--playground: {go1.MISSING_MESSAGE}")  # exit code 2
    if args.float64_physics:  # before any JAX array
        jax.config.update("jax_enable_x64", True)
    from footforge.rl import compile_cache

    cache = compile_cache.enable(not args.no_compile_cache)
    figures = {
        "machine": platform.platform(),
        "device": str(jax.devices()[0]),
        "jax": jax.__version__,
        "mjx_impl": args.mjx_impl,
        "compile_cache": str(cache) if cache else None,
        "float64_physics": args.float64_physics,
    }
    if go1:
        figures["playground"] = go1.version()
    for task in args.tasks:
        for feet in args.feet:
            policies = envs.policy_types(task, feet, args.policies)
            shanks = args.shank_collisions if task == "rough" else ["on"]
            soles = args.heightfield_soles if task == "rough" and feet != "ball" else ["spheres"]
            for policy, contact, shank, sole, (label, root), engine in (
                (kind, model, on, so, r, e)
                for kind in policies
                for model in args.contact_models
                for on in shanks
                for so in soles
                for r in roots
                for e in args.physics
            ):
                config = envs.default_config(task, feet, policy, contact)
                env = envs.from_config(
                    replace(
                        envs.with_float64_physics(config, args.float64_physics),
                        shank_collisions=shank == "on",
                        mjx_impl=args.mjx_impl,
                        build_dir=f"{root}/{feet}" if root else config.build_dir,
                        physics=engine,
                        heightfield_soles=sole,
                    )
                )
                name = (
                    f"{task}_{feet}_{policy}"
                    + (f"_{label}" if label else "")
                    + ("" if contact == "fast" else f"_{contact}")
                    + ("" if shank == "on" else "_noshank")
                    + ("" if sole == "spheres" else "_soleboxes")
                )
                for batch in args.batches:
                    suffix = "_mujoco" if engine == "mujoco" else ""
                    figures[f"{name}{suffix}_b{batch}"] = _measure(env, batch, args.steps)
                    if args.raw_c and engine == "mujoco":
                        for threads in sorted({1, env.physics._rollouts.threads}):
                            figures[f"{name}_raw_c{threads}_b{batch}"] = _measure_raw_c(env, batch, args.steps, threads)
        if go1 and task in go1.ENV_NAMES:
            env, meshes = go1.make_env(task)
            for batch in args.batches:
                figures[f"playground_go1_{task}_b{batch}"] = go1.measure(task, batch, args.steps, env=env) | {
                    "meshes": meshes
                }
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
    return {
        "compile_s": round(compile_s, 1),
        "policy_steps_per_s": round(rate, 1),
        "physics_steps_per_s": round(rate * env.config.decimation, 1),
    }


def _measure_raw_c(env, batch: int, steps: int, threads: int) -> dict:
    """MuJoCo's C engine alone on the C environment's model: `steps` policy steps of `decimation`
    physics steps for `batch` robots from their reset states (PD targets held), by mujoco.rollout."""
    import mujoco
    import numpy as np
    from mujoco import rollout

    engine = env.physics
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), batch)).pipeline_state
    start = engine._initial_state(
        np.asarray(state.qpos), np.asarray(state.qpos_rest), np.asarray(state.qvel), np.asarray(state.qvel_rest)
    )
    control = np.repeat(np.asarray(state.ctrl, np.float64)[:, None, :], env.config.decimation, axis=1)
    warm = np.zeros((batch, engine.model.nv))
    with rollout.Rollout(nthread=threads if threads > 1 else 0) as pool:
        datas = [mujoco.MjData(engine.model) for _ in range(threads)]
        t0 = time.perf_counter()
        for _ in range(steps):
            states, _ = pool.rollout(
                engine.model, datas, start, control, nstep=env.config.decimation, initial_warmstart=warm
            )
            start = states[:, -1]
        rate = batch * steps / (time.perf_counter() - t0)
    return {
        "threads": threads,
        "policy_steps_per_s": round(rate, 1),
        "physics_steps_per_s": round(rate * env.config.decimation, 1),
    }


if __name__ == "__main__":
    main()
