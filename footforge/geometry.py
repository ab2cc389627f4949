"""Geometry shared by several packages."""

from __future__ import annotations

import numpy as np

BOX_CORNER_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
"""The eight corners of the unit box [-1, 1]^3."""


def box_corners(half_sizes, centre=0.0) -> np.ndarray:
    """(8, 3) corners of the box with these half sizes about `centre`, in the box's frame."""
    return np.asarray(centre, dtype=float) + BOX_CORNER_SIGNS * np.asarray(half_sizes, dtype=float)


def sole_primitives(center, half, kind: str, grid: tuple[int, int], radius_m: float) -> list[dict]:
    """Geom attributes of the spheres or capsules (`kind`) standing in for a sole box (`center`,
    `half` sizes, in the sole body's frame): `grid` along the box's x and y (for capsules, segments
    along x and rows along y), of `radius_m`. Their lowest points lie on the box's bottom face, the
    outer ones reaching its edges, so they touch flat ground where the box would."""
    r, (nx, ny) = radius_m, grid
    z = center[2] - half[2] + r
    ys = np.linspace(center[1] - half[1] + r, center[1] + half[1] - r, ny) if ny > 1 else [center[1]]
    if kind == "spheres":
        xs = np.linspace(center[0] - half[0] + r, center[0] + half[0] - r, nx) if nx > 1 else [center[0]]
        return [dict(type="sphere", size=[r], pos=[x, y, z]) for x in xs for y in ys]
    edges = np.linspace(center[0] - half[0] + r, center[0] + half[0] - r, nx + 1)  # capsule segments
    return [
        dict(type="capsule", size=[r], fromto=[x0, y, z, x1, y, z]) for x0, x1 in zip(edges[:-1], edges[1:]) for y in ys
    ]
