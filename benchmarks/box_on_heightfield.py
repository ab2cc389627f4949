"""One adaptive sole on a slope: a heightfield against a tilted plane of the same slope, in MuJoCo's
C engine and in MJX (float64), for the sole as a box (footforge's collider) and as two capsules on its long
bottom edges (an alternative, boxes_as_edge_capsules).

A heightfield whose samples lie on one plane is that plane, so a sole resting on it should do what
it does on the plane geom (whose box and capsule contacts are exact in both engines): the same
contact force, the same settling. Each case places a 6 kg sole (AOF's front sole box,
62 x 55 x 36 mm; the contact settings of the `stance` contact in float64) 2 mm into the surface,
aligned with it, at one of three spots of the 0.1 m grid (a grid vertex, a cell's centre, a
yawed off-centre spot), and steps it 1 s (400 steps of 2.5 ms). Reported per case: the largest
normal force (N) and how far the sole moved (mm), on the plane and on the heightfield, and the
contacts the heightfield gave. Slopes 0, 10 and 20 deg; the heightfield exact or quantised to 5 mm
as footforge's terrain (then it is a staircase of the plane, no longer equal to it).

Prints one JSON line: per engine and shape, the worst ratio of peak force heightfield / plane and
the worst extra motion (mm) over the exact heightfields, and every case under "cases".

    python benchmarks/box_on_heightfield.py [--engines c mjx] \
        [--shapes box "edge capsules" "corner spheres"] [--out FILE.jsonl]
    python benchmarks/box_on_heightfield.py --summarise FILE.jsonl   # the summary of a written run again
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

os.environ.setdefault("JAX_ENABLE_X64", "1")  # before JAX is imported: MJX in float64

import mujoco
import numpy as np

SOLE_HALF_M = (0.031194947123107143, 0.027649726678878793, 0.018039302680202221)
"""AOF's front sole box (half sizes), as footforge builds it."""
MASS_KG = 6.0
GRID_M, SAMPLES = 0.1, 41  # a 4 m x 4 m heightfield at the terrain's 0.1 m
SPOTS = ((0.0, 0.0, 0.0), (0.05, 0.05, 0.0), (0.03, 0.07, 30.0))
"""(x, y, yaw deg): on a grid vertex, at a cell's centre, off-centre and yawed."""
SLOPES_DEG = (0, 10, 20)
STEPS = 400
START_DEPTHS_M = (0.002, 0.006, 0.010)
"""How deep the sole starts in the surface: a resting depth, and three and five times it (impacts;
random PD targets on rough tiles put a foot deeper than 6 mm in about 1 % of physics steps)."""


EDGE_RADIUS_M = 0.010
"""The edge capsules' radius (--edge-radius-m)."""


def boxes_as_edge_capsules(body, radius_m: float) -> None:
    """Each colliding box of `body` (an MjsBody) replaced by two capsules of radius_m whose lowest
    lines are the box's two long bottom edges: on a plane the same four support points (its bottom
    corners) and four contacts; the box's height above them does not collide. The alternative
    collider measured here (RESULTS.md, "Physics engines"): it follows a planar heightfield in both
    engines, but on flat heightfield ground at rest MuJoCo's C engine makes its contacts flicker
    (26 to 2 from one step to the next) and robots standing on it fell; footforge keeps the boxes."""
    for geom in list(body.geoms):
        if geom.type != mujoco.mjtGeom.mjGEOM_BOX:
            continue
        hx, hy, hz = geom.size
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, np.asarray(geom.quat, float))
        rot = rot.reshape(3, 3)
        for side in (-1.0, 1.0):
            ends = [np.asarray(geom.pos) + rot @ np.array([x, side * hy, -(hz - radius_m)]) for x in (-hx, hx)]
            body.add_geom(
                type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                fromto=np.concatenate(ends),
                size=[radius_m, 0.0, 0.0],
                condim=geom.condim,
                friction=geom.friction,
                solref=geom.solref,
                solimp=geom.solimp,
                mass=0.0,
            )


CORNER_SPHERE_RADIUS_M = 0.008
"""The corner spheres' radius: the build's `collision` option `sole: spheres, grid [2, 2], radius_m`."""
SHAPES = ("box", "edge capsules", "corner spheres")


def box_as_corner_spheres(body, geom, radius_m: float) -> None:
    """Four spheres of radius_m inset by it from the box's bottom corners, their lowest points on its
    bottom face (the sole the build makes with `collision: sole: spheres, grid [2, 2]`)."""
    hx, hy, hz = geom.size
    for x in (-1, 1):
        for y in (-1, 1):
            body.add_geom(
                type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=[radius_m, 0, 0],
                mass=0.0,
                pos=np.asarray(geom.pos) + [x * (hx - radius_m), y * (hy - radius_m), -(hz - radius_m)],
                condim=geom.condim,
                friction=geom.friction,
                solref=geom.solref,
                solimp=geom.solimp,
            )


def scene(surface: str, slope_deg: float, quantum_m: float, shape: str) -> mujoco.MjModel:
    t = math.radians(slope_deg)
    spec = mujoco.MjSpec()
    spec.option.timestep = 0.0025
    spec.option.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
    spec.option.impratio = 10.0  # contact_model "stance"'s (envs.contact_physics)
    spec.option.iterations = spec.option.ls_iterations = 50
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    if surface == "plane":
        quat = np.zeros(4)
        mujoco.mju_axisAngle2Quat(quat, [0, 1, 0], -t)
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5, 5, 0.1], quat=quat)
    else:
        x = np.linspace(-2, 2, SAMPLES)
        heights = np.tile(x * math.tan(t), (SAMPLES, 1))  # rows along y, columns along x
        if quantum_m:
            heights = np.round(heights / quantum_m) * quantum_m
        lo, span = heights.min(), max(heights.max() - heights.min(), 1e-3)
        spec.add_hfield(
            name="ramp",
            nrow=SAMPLES,
            ncol=SAMPLES,
            size=[2, 2, span, 0.5],
            userdata=((heights - lo) / span).ravel().tolist(),
        )
        spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname="ramp", pos=[0, 0, lo])
    body = spec.worldbody.add_body(name="probe_foot/sole")
    body.add_freejoint()
    # The solid box's mass and inertia whatever collides, as footforge's feet (explicit inertials).
    body.explicitinertial = True
    body.mass = MASS_KG
    body.inertia = [MASS_KG / 3 * (SOLE_HALF_M[(i + 1) % 3] ** 2 + SOLE_HALF_M[(i + 2) % 3] ** 2) for i in range(3)]
    body.add_geom(
        name="sole",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=SOLE_HALF_M,
        friction=[0.8, 0.005, 0.0001],
        solref=[0.004, 1],
        solimp=[0.99, 0.999, 0.001, 0.5, 2],
    )
    if shape == "corner spheres":
        box_as_corner_spheres(body, spec.geom("sole"), CORNER_SPHERE_RADIUS_M)
        spec.delete(spec.geom("sole"))
    if shape == "edge capsules":
        boxes_as_edge_capsules(body, EDGE_RADIUS_M)
        spec.delete(spec.geom("sole"))
    return spec.compile()


def start(slope_deg, x, y, yaw_deg, depth_m):
    t = math.radians(slope_deg)
    normal = np.array([-math.sin(t), 0.0, math.cos(t)])
    pos = np.array([x, y, x * math.tan(t)]) + normal * (SOLE_HALF_M[2] - depth_m)
    tilt, turn, quat = np.zeros(4), np.zeros(4), np.zeros(4)
    mujoco.mju_axisAngle2Quat(tilt, [0, 1, 0], -t)
    mujoco.mju_axisAngle2Quat(turn, [0, 0, 1], math.radians(yaw_deg))
    mujoco.mju_mulQuat(quat, tilt, turn)
    return np.concatenate([pos, quat]), normal


def simulate(engine, model, qpos0, normal):
    """Per step: (position, normal force on the sole N, active contacts)."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos0
    rows = []
    if engine == "c":
        mujoco.mj_forward(model, data)
        for i in range(STEPS + 1):
            if i:
                mujoco.mj_step(model, data)
            rows.append(
                (
                    data.qpos[:3].copy(),
                    float(data.qfrc_constraint[:3] @ normal),
                    int(np.sum(data.contact.dist[: data.ncon] < 0)),
                )
            )
        return rows
    import jax
    from mujoco import mjx

    mx, dx = mjx.put_model(model), mjx.put_data(model, data)
    step = jax.jit(mjx.step)
    dx = jax.jit(mjx.forward)(mx, dx)
    for i in range(STEPS + 1):
        if i:
            dx = step(mx, dx)
        dist = np.asarray(dx._impl.contact.dist)
        rows.append(
            (np.asarray(dx.qpos[:3]).copy(), float(np.asarray(dx.qfrc_constraint[:3]) @ normal), int(np.sum(dist < 0)))
        )
    return rows


def measure(engine, surface, slope, quantum, shape, spot, depth):
    qpos0, normal = start(slope, *spot, depth)
    rows = simulate(engine, scene(surface, slope, quantum, shape), qpos0, normal)
    return {
        "peak_force_N": round(max(r[1] for r in rows), 2),
        "rest_force_N": round(float(np.mean([r[1] for r in rows[-40:]])), 3),
        "moved_mm": round(float(np.linalg.norm(rows[-1][0] - qpos0[:3])) * 1e3, 3),
        "contacts_end": rows[-1][2],
    }


def summarise(cases, engines):
    """Per engine, shape and start depth: the worst peak-force ratio heightfield / plane and the worst
    extra motion (mm) over the exact heightfields, and the worst extra motion over the quantised ones."""
    summary = {}
    for engine in engines:
        for shape in sorted({c["shape"] for c in cases}, key=SHAPES.index):
            for depth in START_DEPTHS_M:
                mine = [
                    c for c in cases if c["engine"] == engine and c["shape"] == shape and c["start_depth_m"] == depth
                ]
                exact, quantised = [c for c in mine if not c["quantum_m"]], [c for c in mine if c["quantum_m"]]
                summary[f"{engine}, {shape}, {depth * 1e3:.0f} mm deep"] = {
                    "worst_peak_ratio": round(
                        max(c["heightfield"]["peak_force_N"] / c["plane"]["peak_force_N"] for c in exact), 3
                    ),
                    "worst_extra_motion_mm": round(
                        max(c["heightfield"]["moved_mm"] - c["plane"]["moved_mm"] for c in exact), 3
                    ),
                    "worst_extra_motion_mm_quantised": round(
                        max(c["heightfield"]["moved_mm"] - c["plane"]["moved_mm"] for c in quantised), 3
                    ),
                }
    return summary


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--engines", nargs="+", choices=("c", "mjx"), default=["c", "mjx"])
    parser.add_argument("--shapes", nargs="+", choices=SHAPES, default=list(SHAPES[:2]))
    parser.add_argument("--out", help="also write every case as JSON lines here")
    parser.add_argument("--edge-radius-m", type=float, help="the edge capsules' radius, m", default=None)
    parser.add_argument(
        "--summarise",
        metavar="CASES_JSONL",
        help="no simulation: print the summary of the cases a run wrote with --out",
    )
    args = parser.parse_args(argv)
    import platform

    if args.summarise:
        with open(args.summarise) as f:
            cases = [json.loads(line) for line in f if line.strip()]
        engines = sorted({c["engine"] for c in cases})
        print(
            json.dumps(
                {
                    "benchmark": "box_on_heightfield",
                    "summarised_from": args.summarise,
                    "summary": summarise(cases, engines),
                    "cases": len(cases),
                }
            )
        )
        return
    global EDGE_RADIUS_M
    if args.edge_radius_m is not None:
        EDGE_RADIUS_M = args.edge_radius_m
    radius = EDGE_RADIUS_M
    began = time.time()
    cases = []
    for shape in args.shapes:
        for slope in SLOPES_DEG:
            for spot in SPOTS:
                for depth in START_DEPTHS_M:
                    plane = measure("c", "plane", slope, 0.0, shape, spot, depth)
                    for quantum in (0.0, 0.005):
                        for engine in args.engines:
                            field = measure(engine, "heightfield", slope, quantum, shape, spot, depth)
                            case = {
                                "shape": shape,
                                "engine": engine,
                                "slope_deg": slope,
                                "spot": spot,
                                "start_depth_m": depth,
                                "quantum_m": quantum,
                                "plane": plane,
                                "heightfield": field,
                            }
                            cases.append(case)
                            print(json.dumps(case), file=sys.stderr, flush=True)
    summary = summarise(cases, args.engines)
    if args.out:
        with open(args.out, "w") as f:
            f.writelines(json.dumps(c) + "\n" for c in cases)
    print(
        json.dumps(
            {
                "benchmark": "box_on_heightfield",
                "machine": platform.platform(),
                "mujoco": mujoco.__version__,
                "wall_s": round(time.time() - began, 1),
                "edge_radius_m": radius,
                "summary": summary,
                "cases": len(cases),
            }
        )
    )


if __name__ == "__main__":
    main()
