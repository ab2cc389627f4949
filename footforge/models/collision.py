"""Convex decomposition of collision meshes with CoACD, in a subprocess, cached on disk.

A mesh whose volume is within `convex_tolerance` of its convex hull's is convex: it becomes one
hull. Any other mesh is decomposed by CoACD into convex hulls of at most `max_hull_vertices`
vertices each (PhysX's default cap is 64; MJX is fastest with small hulls). CoACD can crash on
some inputs, so it runs in a child process with a timeout. Results are cached under
`cache_dir`, keyed by the SHA-256 of the mesh file's bytes and of the parameters, so a rebuild
with the same inputs does not decompose again. A mesh of more than `face_budget` faces is
simplified first (footforge.models.mesh_simplify): CoACD's time grows with the input's size, and a CAD
export of 40-50 thousand faces took minutes per part.
"""

from __future__ import annotations

import hashlib
import io
import json
import multiprocessing as mp
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
import trimesh

from footforge.errors import InputError
from footforge.inputs.meshes import flat_mesh_problem
from footforge.models.mesh_simplify import DEFAULT_FACE_BUDGET, simplify_to_budget
from footforge.processes import die_with_parent

CACHE_VERSION = 1


@dataclass(frozen=True)
class DecompositionConfig:
    threshold: float = 0.05
    """CoACD concavity threshold (smaller: more, tighter hulls)."""
    max_convex_hulls: int = 8
    """Upper bound on hulls per mesh (CoACD merges down to it)."""
    max_hull_vertices: int = 64
    """Vertex cap per hull (CoACD decimation), PhysX's default limit."""
    preprocess_resolution: int = 50
    """CoACD manifold preprocessing resolution."""
    seed: int = 0
    """CoACD's random seed: the same seed gives the same hulls."""
    convex_tolerance: float = 0.02
    """A mesh whose hull volume exceeds its volume by less than this fraction counts as convex."""
    timeout_s: float = 900.0
    """Kill CoACD after this long and report the mesh (the user's --coacd-timeout): a guard against a
    decomposition that never ends, not a budget. Generous, since the time depends on the machine's
    load: the public SoftFoot-Q's ankle.stl (13,896 faces, simplified to 1,000) finished in time
    on quiet cores and passed 120 s (the default until 2026-11-28) with other work sharing them;
    the whole cold build took 298 s quiet and 738 s shared."""
    face_budget: int = DEFAULT_FACE_BUDGET
    """A mesh with more faces is simplified to this many before CoACD (footforge.models.mesh_simplify;
    the user's --face-budget; 0 keeps every face)."""


@dataclass(frozen=True)
class Hulls:
    """Convex pieces of one mesh, in the mesh's own frame."""

    vertices: tuple[np.ndarray, ...]
    faces: tuple[np.ndarray, ...]
    decomposed: bool
    """False when the mesh was already convex (one hull, no CoACD)."""
    cached: bool

    def stl_bytes(self, i: int) -> bytes:
        mesh = trimesh.Trimesh(self.vertices[i], self.faces[i], process=False)
        return cast(bytes, mesh.export(file_type="stl"))  # STL: bytes


def _coacd_worker(vertices, faces, config: dict, queue, parent_pid: int) -> None:
    die_with_parent(parent_pid)  # a killed build must not leave CoACD running for minutes
    try:
        import coacd

        coacd.set_log_level("error")
        parts = coacd.run_coacd(
            coacd.Mesh(vertices, faces),
            threshold=config["threshold"],
            max_convex_hull=config["max_convex_hulls"],
            preprocess_resolution=config["preprocess_resolution"],
            merge=True,
            decimate=True,
            max_ch_vertex=config["max_hull_vertices"],
            seed=config["seed"],
        )
        queue.put([(np.asarray(v, dtype=float), np.asarray(f, dtype=np.int64)) for v, f in parts])
    except Exception as e:  # reported to the parent, which names the mesh
        queue.put(e)


def cache_key(mesh_bytes: bytes, config: DecompositionConfig) -> str:
    h = hashlib.sha256(mesh_bytes)
    params = {k: v for k, v in asdict(config).items() if k != "timeout_s"}
    h.update(json.dumps({"params": params, "version": CACHE_VERSION}, sort_keys=True).encode())
    return h.hexdigest()


def default_cache_dir() -> Path:
    base = os.environ.get("FOOTFORGE_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "footforge"
    )
    return Path(base) / "coacd"


def decompose(
    mesh_path: Path, config: DecompositionConfig = DecompositionConfig(), *, cache_dir: Path | None = None
) -> Hulls:
    """Convex hulls of the mesh at `mesh_path` (see the module docstring).

    Raises:
      InputError: the mesh cannot be read, CoACD fails, or it runs past the timeout.
    """
    mesh_path = Path(mesh_path)
    data = mesh_path.read_bytes()
    cache_dir = cache_dir or default_cache_dir()
    entry = cache_dir / f"{cache_key(data, config)}.npz"
    if entry.is_file():
        with np.load(entry) as z:
            n = int(z["count"])
            return Hulls(
                tuple(z[f"v{i}"] for i in range(n)),
                tuple(z[f"f{i}"] for i in range(n)),
                decomposed=bool(z["decomposed"]),
                cached=True,
            )
    try:
        mesh = cast(
            trimesh.Trimesh,  # force="mesh": one Trimesh
            trimesh.load(io.BytesIO(data), file_type=mesh_path.suffix.lstrip(".").lower(), force="mesh"),
        )
    except Exception as e:
        raise InputError(f"cannot read mesh: {e}", file=str(mesh_path), fix="export it as STL or OBJ") from None
    problem = flat_mesh_problem(mesh)
    if problem:
        raise InputError(
            f"collision mesh unusable: {problem}",
            file=str(mesh_path),
            fix="export a closed solid mesh, or remove the <collision> element that uses it",
        )
    hull = mesh.convex_hull
    convex = mesh.is_volume and hull.volume <= mesh.volume * (1.0 + config.convex_tolerance)
    if convex and len(hull.vertices) <= config.max_hull_vertices:
        parts = [(np.asarray(mesh.vertices), np.asarray(mesh.faces))]
        decomposed = False
    else:
        if config.face_budget and len(mesh.faces) > config.face_budget:
            v, f = simplify_to_budget(mesh.vertices, mesh.faces, config.face_budget)
            mesh = trimesh.Trimesh(v, f, process=False)
        parts = _run_coacd(mesh_path, mesh, config)
        decomposed = True
    cache_dir.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, Any] = {"count": len(parts), "decomposed": decomposed}
    for i, (v, f) in enumerate(parts):
        arrays[f"v{i}"], arrays[f"f{i}"] = v, f
    tmp = entry.with_suffix(f".tmp{os.getpid()}.npz")
    np.savez(tmp, **arrays)
    os.replace(tmp, entry)
    return Hulls(tuple(v for v, _ in parts), tuple(f for _, f in parts), decomposed=decomposed, cached=False)


def _run_coacd(mesh_path: Path, mesh: trimesh.Trimesh, config: DecompositionConfig):
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(
        target=_coacd_worker,
        daemon=True,
        args=(np.asarray(mesh.vertices), np.asarray(mesh.faces), asdict(config), queue, os.getpid()),
    )
    proc.start()
    try:
        result = queue.get(timeout=config.timeout_s)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: stop CoACD now, not when this process exits
        proc.kill()
        raise
    except Exception:
        proc.kill()
        raise InputError(
            f"CoACD did not finish within {config.timeout_s:.0f} s ({len(mesh.faces)} faces)",
            file=str(mesh_path),
            fix=f"raise --coacd-timeout (now {config.timeout_s:.0f} s), lower --face-budget "
            f"(now {config.face_budget}), or replace the mesh by primitives in the description",
        ) from None
    finally:
        proc.join(timeout=5)
    if isinstance(result, Exception):
        raise InputError(
            f"CoACD failed: {result}",
            file=str(mesh_path),
            fix="repair the mesh (closed, manifold) or replace it by primitives",
        )
    parts = []
    for v, f in result:
        # The vertex cap is CoACD's decimation target; enforce it exactly on the convex hull.
        h = trimesh.Trimesh(v, f).convex_hull
        if len(h.vertices) > config.max_hull_vertices:
            h = _cap_vertices(h, config.max_hull_vertices)
        parts.append((np.asarray(h.vertices), np.asarray(h.faces)))
    return parts


def _cap_vertices(hull: trimesh.Trimesh, max_vertices: int) -> trimesh.Trimesh:
    # Farthest-point subsample of the hull's vertices, then their hull: stays inside the original.
    v = np.asarray(hull.vertices)
    chosen = [int(np.argmax(np.linalg.norm(v - v.mean(0), axis=1)))]
    dist = np.linalg.norm(v - v[chosen[0]], axis=1)
    while len(chosen) < max_vertices:
        k = int(np.argmax(dist))
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(v - v[k], axis=1))
    return trimesh.Trimesh(v[chosen]).convex_hull
