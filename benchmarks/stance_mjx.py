"""Contact settings in MJX itself: does a robot stand still at zero action, and does it survive
random actions? One JSON line.

Each setting is (integrator, cone, Newton iterations, line-search iterations) plus, per grid point,
(physics step s, impratio, solimp dmin, solimp dmax, solref time constant s). The robot is the
training environment's (`load_robot`: flat ground, its colliders), `--robots` of them vmapped in
MJX on whatever JAX device is present, starting at the build's `stand` keyframe with joint
velocities U(-0.1, 0.1) rad/s and base velocities U(-0.05, 0.05) m/s (as a reset leaves them), PD
targets at the defaults, for `--seconds`:

- rest: zero actions. `ok` robots stayed finite and within 0.3 m of their start height; for them
  the base's largest drop after 0.5 s and the largest foot slip after 0.5 s (mm).
- act: an untrained policy's actions (N(0, 1) clipped to +-1 every 20 ms, the flat task's velocity
  model: target += 13.5 a 0.02 within the joint ranges). `div`: robots whose velocities turned
  non-finite or passed 1000 (EnvConfig.diverged_speed).
- us_robot_policystep: wall time of the act rollout per robot and 20 ms policy step (compiled).

    python benchmarks/stance_mjx.py --feet ball --integrator euler --cone pyramidal --iterations 8 16 \\
        --grid 0.0025,10,0.99,0.999,0.005 [--friction 0.5] [--build-dir DIR]

With JAX_ENABLE_X64=1 in the environment MJX runs in float64 (MJX's own default is float32), to
tell precision from the solver and the collision code when MJX and CPU MuJoCo disagree.
"""

from __future__ import annotations

import argparse
import copy
import json
import platform
import time

import jax
import jax.numpy as jp
import mujoco
import numpy as np
from mujoco import mjx

from footforge.envs.anymal import load_robot
from footforge.envs.config import EnvConfig
from footforge.envs.stability import VELOCITY_ACTION_SCALE
from footforge.variants import FEET

FLAT = EnvConfig(action="velocity", action_scale=VELOCITY_ACTION_SCALE)
"""The flat baseline's velocity action model: target += action_scale x a x policy_dt (a clipped)."""
POLICY_DT = FLAT.policy_dt


def grid_point(text: str) -> tuple[float, ...]:
    """argparse type of --grid: five comma-separated numbers."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 5:
        raise argparse.ArgumentTypeError(f"'{text}' is not dt,impratio,dmin,dmax,timeconst (five numbers)")
    return values


def rollout(mx, d0, qvel, key, decimation, policy_steps, acting, robot):
    act, lo, hi = jp.asarray(robot.actuator_ids), jp.asarray(robot.q_limits[:, 0]), jp.asarray(robot.q_limits[:, 1])
    sites = jp.asarray(robot.foot_sites)

    def policy_step(carry, k):
        d, target, bad = carry
        a = jp.clip(jax.random.normal(k, (12,)), -FLAT.action_clip, FLAT.action_clip) * acting
        target = jp.clip(target + FLAT.action_scale * a * POLICY_DT, lo, hi)
        d = d.replace(ctrl=d.ctrl.at[act].set(target))
        # Under JAX_ENABLE_X64 mjx.step returns some integer fields wider than put_data made
        # them; the loop carry keeps the input's dtypes (a no-op in float32).
        d = jax.lax.fori_loop(
            0, decimation, lambda _, x: jax.tree.map(lambda new, old: new.astype(old.dtype), mjx.step(mx, x), x), d
        )
        bad = bad | ~jp.all(jp.isfinite(d.qvel)) | jp.any(jp.abs(d.qvel) > 1000.0)
        return (d, target, bad), (d.qpos[2], d.site_xpos[sites, :2])

    start = (d0.replace(qvel=qvel.astype(d0.qvel.dtype)), jp.asarray(robot.default_q, d0.ctrl.dtype), jp.array(False))
    (_, _, bad), (z, xy) = jax.lax.scan(policy_step, start, jax.random.split(key, policy_steps))
    return bad, z, xy


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--feet", choices=FEET, default="ball")
    p.add_argument("--integrator", choices=["euler", "implicitfast"], default="euler")
    p.add_argument("--cone", choices=["pyramidal", "elliptic"], default="pyramidal")
    p.add_argument("--iterations", type=int, nargs=2, default=[8, 16], metavar=("NEWTON", "LINESEARCH"))
    p.add_argument(
        "--grid",
        nargs="+",
        type=grid_point,
        default=[grid_point("0.0025,10,0.99,0.999,0.005")],
        help="dt,impratio,dmin,dmax,timeconst per point",
    )
    p.add_argument("--friction", type=float, help="sliding friction of every geom (default: the model's 0.8)")
    p.add_argument(
        "--foot-armature", type=float, help="armature of the passive foot joints, kg m^2 (default: the model's)"
    )
    p.add_argument("--robots", type=int, default=8)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--build-dir", help="a build folder of --feet (default build/<feet>)")
    args = p.parse_args(argv)

    robot = load_robot(EnvConfig(feet=args.feet, build_dir=args.build_dir))
    m0 = robot.model
    m0.opt.integrator = {
        "euler": mujoco.mjtIntegrator.mjINT_EULER,
        "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    }[args.integrator]
    m0.opt.cone = {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC}[args.cone]
    m0.opt.iterations, m0.opt.ls_iterations = args.iterations
    if args.friction is not None:
        m0.geom_friction[:, 0] = args.friction
    if args.foot_armature is not None:
        m0.dof_armature[robot.passive_dof] = args.foot_armature
    rng = np.random.default_rng(args.seed)
    qvel = np.zeros((args.robots, m0.nv), np.float32)
    qvel[:, 6:] = rng.uniform(-0.1, 0.1, (args.robots, m0.nv - 6))
    qvel[:, :3] = rng.uniform(-0.05, 0.05, (args.robots, 3))
    keys = jax.random.split(jax.random.PRNGKey(args.seed + 1), args.robots)
    policy_steps = int(round(args.seconds / POLICY_DT))
    settle = int(round(0.5 / POLICY_DT))
    out = {
        "benchmark": "stance_mjx",
        "machine": platform.platform(),
        "jax_device": str(jax.devices()[0]),
        "feet": args.feet,
        "integrator": args.integrator,
        "cone": args.cone,
        "iterations": args.iterations,
        "friction": args.friction,
        "foot_armature": args.foot_armature,
        "robots": args.robots,
        "seconds": args.seconds,
    }
    compiled = {}
    for point in args.grid:
        dt, impratio, dmin, dmax, timeconst = point
        m = copy.copy(m0)
        m.opt.timestep, m.opt.impratio = dt, impratio
        m.geom_solimp[:, :3] = (dmin, dmax, 0.001)
        m.geom_solref[:, 0] = timeconst
        d = mujoco.MjData(m)
        d.qpos[:] = robot.stand_qpos
        d.ctrl[robot.actuator_ids] = robot.default_q
        mujoco.mj_forward(m, d)
        mx, d0 = mjx.put_model(m), mjx.put_data(m, d)
        decimation = int(round(POLICY_DT / dt))
        if decimation not in compiled:
            compiled[decimation] = jax.jit(
                jax.vmap(
                    lambda mx, d0, v, k, acting, n=decimation: rollout(mx, d0, v, k, n, policy_steps, acting, robot),
                    in_axes=(None, None, 0, 0, None),
                )
            )
        run = compiled[decimation]
        figures = {}
        for name, acting in (("rest", 0.0), ("act", 1.0)):
            bad, z, xy = (np.asarray(x) for x in jax.block_until_ready(run(mx, d0, jp.asarray(qvel), keys, acting)))
            if name == "rest":
                z, xy = z.T, xy.transpose(1, 0, 2, 3)  # (time, robot), (time, robot, foot, 2)
                ok = ~bad & (np.abs(z - z[0]).max(0) < 0.3)
                figures["rest"] = {"ok": int(ok.sum())}
                if ok.any():
                    figures["rest"] |= {
                        "drop_mm": round(1e3 * float((z[settle] - z[settle:].min(0))[ok].max()), 1),
                        "slip_mm": round(
                            1e3 * float(np.linalg.norm(xy[-1] - xy[settle], axis=-1).max(-1)[ok].max()), 1
                        ),
                    }
            else:
                figures["act"] = {"div": int(bad.sum())}
        start = time.perf_counter()
        jax.block_until_ready(run(mx, d0, jp.asarray(qvel), keys, 1.0))
        figures["us_robot_policystep"] = round(1e6 * (time.perf_counter() - start) / args.robots / policy_steps)
        out[",".join(f"{v:g}" for v in point)] = figures
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
