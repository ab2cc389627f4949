"""Simplifying a large collision mesh before CoACD, to a face budget.

CAD exports carry far more triangles than a convex decomposition needs: the public SoftFoot-Q's
collision meshes have 43-51 thousand faces each, and CoACD spent about 200 s on its ankle alone
(10 minutes for the foot on 2 cores). Hulls capped at 64 vertices cannot show detail below a
millimetre anyway, so a mesh above `face_budget` faces is simplified first.

The method is quadric edge-collapse decimation (Garland and Heckbert), trimesh's
`simplify_quadric_decimation` over the `fast-simplification` package: it keeps the shape's
surface within the smallest quadric error for the budget, and it is deterministic (the same mesh
and budget give the same triangles), so the CoACD cache key (mesh bytes + parameters) stays
meaningful.
"""

from __future__ import annotations

import numpy as np

DEFAULT_FACE_BUDGET = 1000
"""Faces a collision mesh keeps before CoACD (0: no simplification). At this budget the public
SoftFoot-Q's 30-75 mm parts keep their shape to about a millimetre, and CoACD's time on its ankle
falls from about 200 s to about 70 s on 2 shared cores (benchmarks/log/2026-11-21_to_26.md). The project's own
meshes have fewer faces and are left as they are."""


def simplify_to_budget(
    vertices: np.ndarray, faces: np.ndarray, face_budget: int = DEFAULT_FACE_BUDGET
) -> tuple[np.ndarray, np.ndarray]:
    """The mesh with at most `face_budget` faces (unchanged if it already has no more, or if the
    budget is 0), by quadric decimation."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    if face_budget <= 0 or len(faces) <= face_budget:
        return vertices, faces
    import trimesh  # here: the command line reads DEFAULT_FACE_BUDGET for every command

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    simplified = mesh.simplify_quadric_decimation(face_count=face_budget)
    return np.asarray(simplified.vertices, dtype=float), np.asarray(simplified.faces, dtype=np.int64)
