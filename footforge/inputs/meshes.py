"""Whether a collision mesh can be used at all: a mesh that encloses no volume has no convex hull."""

from __future__ import annotations

import numpy as np
import trimesh

FLAT_MESH_THICKNESS_M = 1e-6
"""A collision mesh thinner than this across its thinnest direction encloses no volume: it has
no convex hull (qhull fails on coplanar points) and no mass properties."""


def mesh_thickness_m(vertices: np.ndarray) -> float:
    """The mesh's extent along its thinnest principal direction (0 for a flat mesh, in the
    vertices' unit): the spread of the vertices projected on the last right-singular vector of
    the centred vertex cloud."""
    v = np.asarray(vertices, float)
    if len(v) < 4:
        return 0.0
    centred = v - v.mean(axis=0)
    thinnest = np.linalg.svd(centred, full_matrices=False)[2][-1]
    projection = centred @ thinnest
    return float(projection.max() - projection.min())


def flat_mesh_problem(mesh: trimesh.Trimesh, scale: float = 1.0) -> str | None:
    """Why a collision mesh cannot be used (empty or flat), or None; `scale` converts its unit to
    metres (the URDF <mesh scale>)."""
    if len(mesh.faces) == 0:
        return "it has no faces"
    thickness = mesh_thickness_m(mesh.vertices) * scale
    if thickness < FLAT_MESH_THICKNESS_M:
        return (
            f"it is flat ({thickness:.2g} m thick across its thinnest direction): it encloses no volume, "
            "so it has no convex hull and cannot collide as a solid"
        )
    return None
