"""The committed SoftFoot-Q meshes: closed, correctly sized, reproducible."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh  # noqa: E402  (a hard dependency: its absence is a failure, not a skip)

MESH_DIR = Path(__file__).parents[1] / "descriptions/softfoot_q/meshes"
GENERATOR = MESH_DIR / "generate_meshes.py"

# target bounding boxes (m): (min xyz, max xyz); see generate_meshes.py
TARGET_BOUNDS = {
    "ankle": ((-0.020, -0.020, 0.0), (0.020, 0.020, 0.0307)),
    "arch": ((-0.007, -0.01445, -0.034), (0.0659, 0.01445, 0.0047)),
    "roll_link": ((-0.0067, -0.0255, -0.0230), (0.0086, 0.0255, 0.0023)),
    "inner_link": ((-0.00565, -0.0059, -0.0059), (0.00565, 0.0059, 0.0186)),
    "outer_link": ((-0.0085, -0.0059, -0.0059), (0.0085, 0.0151, 0.0186)),
}
# published bounding-box sizes of the real parts (mm)
PUBLISHED_SIZE_MM = {
    "ankle": (40.0, 40.0, 30.7),
    "arch": (72.9, 28.9, 38.7),
    "roll_link": (15.3, 51.0, 25.3),
    "inner_link": (11.3, 11.8, 24.5),
    "outer_link": (17.0, 21.0, 24.5),
}
NONCONVEX = ("arch", "outer_link")
TOL = 0.5e-3  # m


def _load(name: str):
    path = MESH_DIR / f"{name}.stl"
    assert path.is_file(), f"{path} missing: run {GENERATOR}"
    return trimesh.load(path, force="mesh")


@pytest.mark.parametrize("name", sorted(TARGET_BOUNDS))
def test_mesh_closed_and_sized(name):
    m = _load(name)
    assert m.is_watertight
    assert m.is_winding_consistent
    assert m.volume > 0
    assert 8 <= len(m.vertices) <= 2000
    lo, hi = (np.asarray(b) for b in TARGET_BOUNDS[name])
    np.testing.assert_allclose(m.bounds[0], lo, atol=TOL)
    np.testing.assert_allclose(m.bounds[1], hi, atol=TOL)
    np.testing.assert_allclose(m.extents * 1e3, PUBLISHED_SIZE_MM[name], atol=0.5)


@pytest.mark.parametrize("name", NONCONVEX)
def test_nonconvex_parts_are_nonconvex(name):
    m = _load(name)
    assert m.volume / m.convex_hull.volume < 0.9


def test_chain_link_geometry():
    # the inner link fits between the outer link's side plates
    inner, outer = _load("inner_link"), _load("outer_link")
    # (every outer-link vertex lies on a plate face, |x| = 5.7 or 8.5 mm)
    assert inner.bounds[1, 0] < np.min(np.abs(outer.vertices[:, 0]))
    # the pad is the lowest part (largest +y) and spans the full width
    pad = outer.vertices[np.isclose(outer.vertices[:, 1], outer.bounds[1, 1])]
    assert np.ptp(pad[:, 0]) == pytest.approx(0.017, abs=1e-6)


def test_generator_reproduces_committed_files(tmp_path):
    subprocess.run(
        [sys.executable, str(GENERATOR), str(tmp_path)],
        check=True,
        capture_output=True,
        text=True,
        timeout=300,
    )
    for name in TARGET_BOUNDS:
        committed = (MESH_DIR / f"{name}.stl").read_bytes()
        regenerated = (tmp_path / f"{name}.stl").read_bytes()
        assert regenerated == committed, f"{name}.stl differs from the generator output"


def test_coacd_splits_outer_link():
    import coacd

    coacd.set_log_level("error")
    m = _load("outer_link")
    parts = coacd.run_coacd(
        coacd.Mesh(np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int32)),
        threshold=0.05,
        max_convex_hull=8,
        merge=True,
        decimate=True,
        max_ch_vertex=64,
        seed=0,
    )
    assert len(parts) >= 2
