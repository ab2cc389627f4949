"""Which geoms touch the ground, from MJX's (or CPU MuJoCo's) fixed-size contact arrays, and
where the base and thighs are probed for ground contact geometrically.

Every function takes the robot's geom categories (footforge.envs.anymal: GEOM_BASE, GEOM_THIGH +
leg, GEOM_FOOT + leg, in the order LF, RF, LH, RH), the floor geom's id, the contact slots' geom
pairs (ncon, 2) and signed distances (ncon,), m; a slot touches when its distance is negative.
The MJX environments (footforge.envs.locomotion) read their contact slots through these; the CPU
runner (footforge.envs.engine_mujoco.CpuRobots) reads MJCF contact sensors instead, which the
tests check against these functions applied to MuJoCo's own contact list.
"""

from __future__ import annotations

import jax.numpy as jp
import mujoco
import numpy as np

from footforge.envs.anymal import GEOM_BASE, GEOM_FOOT, GEOM_THIGH
from footforge.geometry import box_corners


def floor_hits(geom_category, floor_geom, geoms, dist):
    """Which contacts touch the floor, and the category of the geom touching it."""
    floor = geoms == floor_geom
    other = jp.where(floor[:, 0], geom_category[geoms[:, 1]], geom_category[geoms[:, 0]])
    return (dist < 0) & (floor[:, 0] | floor[:, 1]), other


def foot_contacts(geom_category, floor_geom, geoms, dist):
    """Per leg (LF, RF, LH, RH): does any of its foot geoms touch the floor."""
    hit, other = floor_hits(geom_category, floor_geom, geoms, dist)
    return jp.stack([jp.any(hit & (other == GEOM_FOOT + i)) for i in range(4)])


def foot_normal_forces(geom_category, floor_geom, geoms, dist, normal):
    """Per leg (LF, RF, LH, RH): the summed normal force `normal` (per contact slot, N) of its
    foot's slots that touch the floor, N."""
    hit, other = floor_hits(geom_category, floor_geom, geoms, dist)
    return jp.stack([jp.sum(jp.where(hit & (other == GEOM_FOOT + i), normal, 0.0)) for i in range(4)])


def ground_contacts(geom_category, floor_geom, geoms, dist):
    """(any base geom touches the floor, number of legs with a thigh geom touching it), from
    fixed-size contact arrays (geom pairs (ncon, 2), signed distances (ncon,)): for CPU MuJoCo's
    models, where the base and thighs collide (the reference the CPU runner's ground-contact
    sensors are tested against)."""
    hit, other = floor_hits(geom_category, floor_geom, geoms, dist)
    base = jp.any(hit & (other == GEOM_BASE))
    knees = sum(jp.any(hit & (other == GEOM_THIGH + i)).astype(jp.int32) for i in range(4))
    return base, knees


def foot_points(model: mujoco.MjModel, geom_category: np.ndarray):
    """Points whose lowest reach bounds each foot collider from below, for any pose: (geom ids,
    points in the geom frame, radius). A collider's lowest point is the lowest of its points' z
    minus their radius: a box's 8 corners (radius 0), a sphere's centre (its radius)."""
    geoms, points, radius = [], [], []
    for g in np.flatnonzero((geom_category >= GEOM_FOOT) & (geom_category < GEOM_FOOT + 4)):
        size, kind = model.geom_size[g], model.geom_type[g]
        if kind == mujoco.mjtGeom.mjGEOM_BOX:
            local, r = box_corners(size), 0.0
        elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            local, r = np.zeros((1, 3)), size[0]
        else:
            raise ValueError(f"foot geom {model.geom(g).name}: no lowest points for geom type {kind}")
        geoms += [g] * len(local)
        points.append(local)
        radius += [r] * len(local)
    return np.array(geoms), np.concatenate(points), np.array(radius)


def surface_points(model: mujoco.MjModel, geom_category: np.ndarray):
    """Sample points on the base and thigh geoms: (geom ids, points in the geom frame, category)."""
    geoms, points, category = [], [], []
    for g in np.flatnonzero(
        (geom_category == GEOM_BASE) | ((geom_category >= GEOM_THIGH) & (geom_category < GEOM_THIGH + 4))
    ):
        size = model.geom_size[g]
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            local = box_corners(size)
        elif model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CYLINDER:
            angles = np.arange(8) * np.pi / 4
            rim = np.stack([size[0] * np.cos(angles), size[0] * np.sin(angles)], axis=1)
            local = np.concatenate([np.hstack([rim, np.full((8, 1), z)]) for z in (-size[1], size[1])])
        else:  # the corners of its bounding box in the geom frame
            centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
            local = box_corners(half, centre)
        geoms += [g] * len(local)
        points.append(local)
        category += [geom_category[g]] * len(local)
    return np.array(geoms), np.concatenate(points), np.array(category)
