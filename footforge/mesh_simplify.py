"""Simplifying a large collision mesh before CoACD, to a face budget.

CAD exports carry far more triangles than a convex decomposition needs: the public SoftFoot-Q's
collision meshes have 43-51 thousand faces each, and CoACD spent about 200 s on its ankle alone
(10 minutes for the foot on 2 cores). Hulls capped at 64 vertices cannot show detail below a
millimetre anyway, so a mesh above `face_budget` faces is simplified first.

The method is vertex clustering on a uniform grid: every vertex moves to the mean of the vertices
in its grid cell, faces that collapse are dropped, duplicates are removed. The cell size is the
smallest (found by bisection) that brings the face count within the budget. It needs nothing but
numpy, and it is deterministic: the same mesh and budget always give the same triangles, so the
CoACD cache key (mesh bytes + parameters) stays meaningful. Clustering may leave the surface
non-manifold; CoACD's manifold preprocessing (run when its input is not manifold) rebuilds a
watertight surface from it, which is what it does for any imperfect CAD export.
"""

from __future__ import annotations

import numpy as np

DEFAULT_FACE_BUDGET = 1000
"""Faces a collision mesh keeps before CoACD (0: no simplification). At this budget the grid cell
for the public SoftFoot-Q's 30-75 mm parts is about 2 mm, and CoACD's time on its ankle fell from
about 200 s to about 70 s on 2 shared cores (4000 faces: about 100 s). The project's own meshes
have fewer faces and are left as they are."""

_BISECTION_STEPS = 30


def _cluster(vertices: np.ndarray, faces: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices merged per grid cell of size `cell` (mesh units) and the faces that survive."""
    origin = vertices.min(axis=0)
    keys = np.floor((vertices - origin) / cell).astype(np.int64)
    _, cluster_of, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    cluster_of = cluster_of.reshape(-1)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, cluster_of, vertices)
    new_vertices = sums / counts[:, None]
    f = cluster_of[faces]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f = f[keep]
    # The same triangle twice (either winding) after merging: keep its first occurrence.
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    f = f[np.sort(first)]
    used, new_faces = np.unique(f, return_inverse=True)
    return new_vertices[used], new_faces.reshape(-1, 3).astype(np.int64)


def simplify_to_budget(vertices: np.ndarray, faces: np.ndarray,
                       face_budget: int = DEFAULT_FACE_BUDGET) -> tuple[np.ndarray, np.ndarray]:
    """The mesh with at most `face_budget` faces (unchanged if it already has no more, or if the
    budget is 0), by vertex clustering on the finest grid that meets the budget."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    if face_budget <= 0 or len(faces) <= face_budget:
        return vertices, faces
    extent = float(np.max(vertices.max(axis=0) - vertices.min(axis=0)))
    if extent <= 0.0:
        return vertices, faces
    fine, coarse = 0.0, extent  # a cell as large as the mesh collapses it: 0 faces
    best = _cluster(vertices, faces, coarse)
    for _ in range(_BISECTION_STEPS):
        cell = 0.5 * (fine + coarse)
        v, f = _cluster(vertices, faces, cell)
        if len(f) <= face_budget:
            coarse, best = cell, (v, f)
        else:
            fine = cell
        if coarse - fine < 1e-4 * extent:
            break
    return best
