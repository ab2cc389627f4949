"""CoACD decomposition: vertex cap, convex pass-through, deterministic, cached by content+params."""

import numpy as np
import pytest
import trimesh

from footforge.errors import InputError
from footforge.models.collision import DecompositionConfig, decompose

from conftest import REPO

OUTER_LINK = REPO / "descriptions/softfoot_q/meshes/outer_link.stl"


def test_nonconvex_mesh_is_split_into_capped_hulls_and_cached(tmp_path):
    config = DecompositionConfig(max_hull_vertices=32)
    first = decompose(OUTER_LINK, config, cache_dir=tmp_path)
    assert first.decomposed and not first.cached and len(first.vertices) >= 2
    assert max(len(v) for v in first.vertices) <= 32
    for v, f in zip(first.vertices, first.faces):
        assert trimesh.Trimesh(v, f).is_convex
    again = decompose(OUTER_LINK, config, cache_dir=tmp_path)
    assert again.cached
    for a, b in zip(first.vertices, again.vertices):
        np.testing.assert_array_equal(a, b)
    # Same seed, fresh cache: the same hulls (CoACD is deterministic for a seed).
    fresh = decompose(OUTER_LINK, config, cache_dir=tmp_path / "other")
    assert not fresh.cached
    for a, b in zip(first.vertices, fresh.vertices):
        np.testing.assert_allclose(a, b)
    # Other parameters are another cache entry.
    assert not decompose(OUTER_LINK, DecompositionConfig(max_hull_vertices=16), cache_dir=tmp_path).cached
    # The hulls cover the part: their bounding box is the mesh's within 1 mm.
    mesh = trimesh.load(OUTER_LINK)
    pts = np.concatenate(first.vertices)
    np.testing.assert_allclose(pts.min(0), mesh.bounds[0], atol=1e-3)
    np.testing.assert_allclose(pts.max(0), mesh.bounds[1], atol=1e-3)


def test_convex_mesh_stays_one_hull(tmp_path):
    path = tmp_path / "box.stl"
    trimesh.creation.box([0.01, 0.02, 0.03]).export(path)
    hulls = decompose(path, cache_dir=tmp_path / "cache")
    assert not hulls.decomposed and len(hulls.vertices) == 1


def test_timeout_is_reported(tmp_path):
    with pytest.raises(InputError, match="did not finish"):
        decompose(OUTER_LINK, DecompositionConfig(timeout_s=0.01), cache_dir=tmp_path)


def test_unreadable_mesh(tmp_path):
    path = tmp_path / "bad.stl"
    path.write_bytes(b"not a mesh")
    with pytest.raises(InputError):
        decompose(path, cache_dir=tmp_path / "cache")


def test_mesh_thickness_is_the_thinnest_extent_whatever_the_orientation():
    """Computed two ways: a 30 x 20 x 4 mm box turned by a random rotation is 4 mm thick; squashed
    flat it is 0, and decompose refuses it with the file named."""
    from footforge.inputs.meshes import mesh_thickness_m

    box = trimesh.creation.box(extents=(0.03, 0.02, 0.004))
    rotation = trimesh.transformations.random_rotation_matrix(np.random.default_rng(3).random(3))
    box.apply_transform(rotation)
    assert mesh_thickness_m(box.vertices) == pytest.approx(0.004, rel=1e-9)
    flat = box.vertices @ rotation[:3, :3]  # back to the box frame
    flat[:, 2] = 0.0
    assert mesh_thickness_m(flat @ rotation[:3, :3].T) < 1e-12


def test_a_flat_mesh_is_refused_before_any_hull(tmp_path):
    path = tmp_path / "flat.stl"
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float) * 0.05
    trimesh.Trimesh(square, [[0, 1, 2], [0, 2, 3]], process=False).export(path)
    with pytest.raises(InputError, match="flat") as e:
        decompose(path, cache_dir=tmp_path / "cache")
    assert e.value.file == str(path)
