"""Contact settings for the training environments, tried on perturbed stances: stable or not, sink
and slip. One JSON line.

Each trial loads the training environment's robot (`load_robot`, at its 5 ms physics step), sets
one contact model (cone, impratio, solimp, solref time constant) and solver (Newton iterations,
line-search iterations), starts `--robots` robots at the `stand` keyframe with the actuators at
its targets and small random velocities (joints U(-amp, amp) rad/s, base U(-amp/2, amp/2) m/s,
as a reset or a policy would leave them), and simulates `--seconds`. A robot is stable if it stays
finite, MuJoCo never flags a bad acceleration and its base stays within 0.3 m of its start; for
the stable ones: the base's drop after 0.5 s and the largest foot slip after 0.5 s (mm).

`--sim cpu` steps MuJoCo; `--sim mjx` steps the same model in MJX (vmapped over the robots, on
whatever JAX device is present) and also reports microseconds per robot step. `--amp 0` is the
issue's stance measurement (at rest).

    python benchmarks/contact_sweep.py --feet ball aff aof --sim cpu
    python benchmarks/contact_sweep.py --feet ball --sim mjx --settings fast elliptic-converged
"""

from __future__ import annotations

import argparse
import copy
import json
import platform
import sys
import time

import mujoco
import numpy as np

from footforge.variants import FEET

SETTINGS = {
    # name: (cone, impratio, solimp[:2], solref time constant s, iterations, ls_iterations[, step s])
    "fast": ("pyramidal", 1.0, (0.9, 0.95), 0.02, 4, 8),
    "pyramidal-impratio10": ("pyramidal", 10.0, (0.99, 0.999), 0.02, 4, 8),
    "elliptic-impratio10": ("elliptic", 10.0, (0.99, 0.999), 0.004, 4, 8),
    "elliptic-impratio10-16it": ("elliptic", 10.0, (0.99, 0.999), 0.004, 16, 8),
    "elliptic-firm-8it": ("elliptic", 1.0, (0.99, 0.999), 0.02, 8, 8),
    "elliptic-converged": ("elliptic", 10.0, (0.99, 0.999), 0.004, 16, 50),
    # friction stiffened alone (impratio) on MuJoCo's default, soft normal impedance
    "elliptic-soft-impratio10": ("elliptic", 10.0, (0.9, 0.95), 0.02, 4, 8),
    "elliptic-soft-impratio100": ("elliptic", 100.0, (0.9, 0.95), 0.02, 4, 8),
    "elliptic-soft-impratio100-8it": ("elliptic", 100.0, (0.9, 0.95), 0.02, 8, 8),
    "elliptic-soft-impratio1000": ("elliptic", 1000.0, (0.9, 0.95), 0.02, 4, 8),
    # the same kinds at a 2 ms physics step (MuJoCo's refsafe floor is then 4 ms)
    "fast-2ms": ("pyramidal", 1.0, (0.9, 0.95), 0.004, 4, 8, 0.002),
    "pyramidal-firm-2ms": ("pyramidal", 1.0, (0.99, 0.999), 0.004, 4, 8, 0.002),
    "pyramidal-mid-2ms": ("pyramidal", 1.0, (0.95, 0.99), 0.004, 4, 8, 0.002),
    "elliptic-firm-2ms": ("elliptic", 1.0, (0.99, 0.999), 0.004, 4, 8, 0.002),
    "pyramidal-firm-1ms": ("pyramidal", 1.0, (0.99, 0.999), 0.002, 4, 8, 0.001),
}
"""solref time constants below 2 steps (10 ms) are raised to 10 ms by MuJoCo (refsafe)."""


def configure(
    model: mujoco.MjModel,
    setting: str,
    leg_armature: float | None = None,
    foot_armature: float | None = None,
    integrator: str | None = None,
) -> mujoco.MjModel:
    cone, impratio, solimp, timeconst, iterations, ls_iterations, *step = SETTINGS[setting]
    m = copy.copy(model)
    if step:
        m.opt.timestep = step[0]
    m.opt.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL if cone == "pyramidal" else mujoco.mjtCone.mjCONE_ELLIPTIC
    m.opt.impratio = impratio
    m.opt.iterations, m.opt.ls_iterations = iterations, ls_iterations
    m.geom_solimp[:, :2] = solimp
    m.geom_solimp[:, 2] = 0.001
    m.geom_solref[:, 0] = timeconst
    if integrator is not None:
        m.opt.integrator = {
            "euler": mujoco.mjtIntegrator.mjINT_EULER,
            "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
        }[integrator]
    # armature (reflected rotor inertia, kg m^2) of the actuated leg joints and of the passive foot joints
    legs = m.jnt_dofadr[m.actuator_trnid[:, 0]]
    if leg_armature is not None:
        m.dof_armature[legs] = leg_armature
    if foot_armature is not None:
        passive = np.setdiff1d(np.arange(6, m.nv), legs)
        m.dof_armature[passive] = foot_armature
    return m


def initial_velocities(model: mujoco.MjModel, robots: int, amp: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    qvel = np.zeros((robots, model.nv))
    qvel[:, 6:] = rng.uniform(-amp, amp, (robots, model.nv - 6))
    qvel[:, :3] = rng.uniform(-amp / 2, amp / 2, (robots, 3))
    return qvel


def summarise(z: np.ndarray, feet_xy: np.ndarray, finite: np.ndarray, settle: int) -> dict:
    """z: (T, robots) base heights; feet_xy: (T, robots, 4, 2); finite: (robots,)."""
    with np.errstate(invalid="ignore"):
        stable = finite & np.isfinite(z).all(0) & (np.abs(z - z[0]).max(0) < 0.3)
    out = {"stable": f"{int(stable.sum())}/{len(stable)}"}
    if stable.any():
        drop = (z[settle] - z[settle:].min(0))[stable]
        slip = np.linalg.norm(feet_xy[-1] - feet_xy[settle], axis=-1).max(-1)[stable]
        out |= {"drop_mm": round(1e3 * float(drop.max()), 1), "slip_mm": round(1e3 * float(slip.max()), 1)}
    return out


def run_cpu(m, robot, qvel, steps, settle):
    z, xy, finite = [], [], []
    for v in qvel:
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, m.key("stand").id)
        d.qvel[:] = v
        mujoco.mj_forward(m, d)
        zs, xys = [], []
        for _ in range(steps):
            mujoco.mj_step(m, d)
            zs.append(d.qpos[2])
            xys.append(d.site_xpos[robot.foot_sites, :2].copy())
        z.append(zs), xy.append(xys)
        finite.append(d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number == 0)
    return summarise(np.array(z).T, np.array(xy).transpose(1, 0, 2, 3), np.array(finite), settle)


def run_mjx(m, robot, qvel, steps, settle):
    import jax
    import jax.numpy as jp
    from mujoco import mjx

    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("stand").id)
    mujoco.mj_forward(m, d)
    mx, d0 = mjx.put_model(m), mjx.put_data(m, d)
    batch = jax.vmap(lambda v: d0.replace(qvel=v))(jp.asarray(qvel, d0.qvel.dtype))
    sites = jp.asarray(robot.foot_sites)

    def body(dx, _):
        dx = jax.vmap(mjx.step, in_axes=(None, 0))(mx, dx)
        return dx, (dx.qpos[:, 2], dx.site_xpos[:, sites, :2])

    run = jax.jit(lambda b: jax.lax.scan(body, b, None, length=steps))
    start = time.perf_counter()
    jax.block_until_ready(run(batch))
    compile_and_run = time.perf_counter() - start
    start = time.perf_counter()
    _, (z, xy) = jax.block_until_ready(run(batch))
    wall = time.perf_counter() - start
    out = summarise(np.asarray(z), np.asarray(xy), np.ones(len(qvel), bool), settle)
    return out | {
        "us_per_robot_step": round(1e6 * wall / steps / len(qvel), 1),
        "compile_s": round(compile_and_run - wall, 1),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--feet", nargs="+", default=list(FEET), choices=FEET)
    p.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    p.add_argument("--sim", choices=["cpu", "mjx"], default="cpu")
    p.add_argument("--robots", type=int, default=6)
    p.add_argument("--amp", type=float, default=0.1, help="initial velocity bound, rad/s (joints)")
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--integrator", choices=["euler", "implicitfast"], help="default: the model's")
    p.add_argument(
        "--leg-armature", type=float, help="armature of the 12 actuated joints, kg m^2 (default: the model's)"
    )
    p.add_argument(
        "--foot-armature", type=float, help="armature of the passive foot joints, kg m^2 (default: the model's)"
    )
    args = p.parse_args(argv)

    from footforge.envs.anymal import load_robot
    from footforge.envs.config import EnvConfig

    out = {
        "benchmark": "contact_sweep",
        "machine": platform.platform(),
        "mujoco": mujoco.__version__,
        "sim": args.sim,
        "robots": args.robots,
        "amp": args.amp,
        "seconds": args.seconds,
        "integrator": args.integrator,
        "leg_armature": args.leg_armature,
        "foot_armature": args.foot_armature,
    }
    for feet in args.feet:
        robot = load_robot(EnvConfig(feet=feet))
        qvel = initial_velocities(robot.model, args.robots, args.amp, args.seed)
        for setting in args.settings:
            m = configure(robot.model, setting, args.leg_armature, args.foot_armature, args.integrator)
            steps = int(round(args.seconds / m.opt.timestep))
            settle = int(round(0.5 / m.opt.timestep))
            run = run_cpu if args.sim == "cpu" else run_mjx
            out[f"{feet}/{setting}"] = run(m, robot, qvel, steps, settle)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
