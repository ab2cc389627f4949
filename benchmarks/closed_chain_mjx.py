"""The closed chain (`footforge build --variant full`) on MJX: does the 34-joint foot, with its
`connect` loop closures, joint coupling and arch-band tendon, step stably when batched, how far do
its loops open, and at what speed. One JSON line.

    python benchmarks/closed_chain_mjx.py --model rig --batch 4 --seconds 1.0
    python benchmarks/closed_chain_mjx.py --model robot --batch 2 --seconds 0.25

--model rig: one foot under its 13 kg slider (foot_rig.xml), released 2 cm above the floor;
robot: ANYmal C on four closed-chain feet (scene.xml) from its `stand` keyframe, actuators
holding it. The build's own settings (0.25 ms step, Newton, 100 iterations, elliptic cone for the
robot) unless --iterations is given. Reported: compile time, physics steps per second over the
batch, the largest closure opening over the run (distance between each `connect` equality's two
sites, mm) and whether every state stayed finite. Needs `footforge build --variant full` first.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", choices=["rig", "robot"], default="rig")
    p.add_argument("--build", default="build/full", help="the full variant's build folder")
    p.add_argument("--batch", type=int, default=4)
    p.add_argument("--seconds", type=float, default=1.0)
    p.add_argument("--iterations", type=int, help="Newton iterations (default: the build's)")
    args = p.parse_args(argv)
    path = Path(args.build) / ("foot_rig.xml" if args.model == "rig" else "scene.xml")
    if not path.exists():
        p.error(f"{path} not found: run footforge build --variant full --out {args.build}")
    if args.batch < 1 or args.seconds <= 0:
        p.error("--batch must be >= 1 and --seconds > 0")

    import jax
    import jax.numpy as jp
    import mujoco
    import numpy as np
    from mujoco import mjx

    model = mujoco.MjModel.from_xml_path(str(path))
    if args.iterations:
        model.opt.iterations = args.iterations
    data = mujoco.MjData(model)
    key = "reference" if args.model == "rig" else "stand"
    mujoco.mj_resetDataKeyframe(model, data, model.key(key).id)
    if args.model == "rig":
        data.qpos[model.jnt_qposadr[model.joint("slider").id]] += 0.02
    mujoco.mj_forward(model, data)
    connects = [e for e in range(model.neq) if model.eq_type[e] == mujoco.mjtEq.mjEQ_CONNECT]
    sites = np.array([[model.eq_obj1id[e], model.eq_obj2id[e]] for e in connects])
    if not len(sites) or model.eq_objtype[connects[0]] != mujoco.mjtObj.mjOBJ_SITE:
        p.error(f"{path} has no site-to-site connect closures: is it the full variant?")

    mx = mjx.put_model(model)
    d0 = mjx.put_data(model, data)
    batch = jax.tree_util.tree_map(lambda x: jp.broadcast_to(x, (args.batch,) + x.shape), d0)
    steps = int(round(args.seconds / model.opt.timestep))
    chunk = 100  # physics steps per compiled call

    def gap(d):
        return jp.linalg.norm(d.site_xpos[sites[:, 0]] - d.site_xpos[sites[:, 1]], axis=-1).max()

    @jax.jit
    def run(d):
        def body(carry, _):
            d, worst = carry
            d = jax.vmap(mjx.step, in_axes=(None, 0))(mx, d)
            return (d, jp.maximum(worst, jax.vmap(gap)(d).max())), None

        (d, worst), _ = jax.lax.scan(body, (d, jp.zeros(())), None, length=chunk)
        return d, worst

    t0 = time.perf_counter()
    state, worst = run(batch)
    jax.block_until_ready(state.qpos)
    compile_s = time.perf_counter() - t0
    worst_gap = float(worst)
    t0 = time.perf_counter()
    for _ in range(max(0, steps // chunk - 1)):
        state, w = run(state)
        worst_gap = max(worst_gap, float(w))
    jax.block_until_ready(state.qpos)
    elapsed = time.perf_counter() - t0
    finite = bool(np.isfinite(np.asarray(state.qpos)).all() and np.isfinite(np.asarray(state.qvel)).all())
    timed = max(0, steps // chunk - 1) * chunk
    print(
        json.dumps(
            {
                "benchmark": "closed_chain_mjx",
                "machine": platform.platform(),
                "device": str(jax.devices()[0]),
                "model": args.model,
                "batch": args.batch,
                "seconds": round(steps // chunk * chunk * model.opt.timestep, 4),
                "timestep": model.opt.timestep,
                "iterations": int(model.opt.iterations),
                "nv": model.nv,
                "connect_closures": len(connects),
                "compile_s": round(compile_s, 1),
                "physics_steps_per_s": round(args.batch * timed / elapsed, 1) if timed else None,
                "max_closure_gap_mm": round(1e3 * worst_gap, 3),
                "finite": finite,
                "slider_height_m": (
                    round(float(np.asarray(state.qpos)[:, model.jnt_qposadr[model.joint("slider").id]].mean()), 4)
                    if args.model == "rig"
                    else None
                ),
                "base_height_m": (
                    round(float(np.asarray(state.qpos)[:, 2].mean()), 4) if args.model == "robot" else None
                ),
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
