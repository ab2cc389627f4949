"""The rough-terrain generator: layout, difficulty formulas, determinism, MuJoCo's surface."""

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from footforge.envs.terrain import KINDS, TerrainConfig, add_to_spec, column_kinds, generate, preview, surface_height
from footforge.errors import InputError

# Small tiles keep the tests fast; every kind gets a column.
SMALL = TerrainConfig(num_levels=5, num_columns=6, tile_size_m=4.0, border_m=1.0, platform_m=1.0, seed=3)


def tile(terrain, level, column):
    n = terrain.config.samples_per_tile
    i0, j0 = terrain.border_samples + column * n, terrain.border_samples + level * n
    return terrain.heights_m[i0 : i0 + n, j0 : j0 + n]


def test_every_kind_has_a_column_in_the_configured_proportions():
    assert sorted(set(column_kinds(SMALL))) == sorted(KINDS)
    kinds = column_kinds(TerrainConfig())  # the default: 20 columns
    assert len(kinds) == 20 and {k: kinds.count(k) for k in KINDS} == {
        "smooth_slope": 2,
        "rough_slope": 2,
        "stairs_up": 5,
        "stairs_down": 5,
        "discrete": 4,
        "stepping_stones": 2,
    }
    only_stairs = column_kinds(replace(SMALL, proportions=(0, 0, 1, 1, 0, 0)))
    assert set(only_stairs) == {"stairs_up", "stairs_down"}


def test_heights_stay_within_each_kinds_bounds_and_platforms_are_flat():
    c = SMALL
    terrain = generate(c)
    rows, cols = terrain.heights_m.shape
    assert (rows, cols) == (2 * 10 + 6 * 40 + 1, 2 * 10 + 5 * 40 + 1)
    half_run = c.tile_size_m / 2 - c.platform_m / 2
    for level in range(c.num_levels):
        d = c.difficulty(level)
        step = c.stair_height_m[0] + c.stair_height_m[1] * d
        bound = {
            "smooth_slope": c.max_slope * d * half_run,
            "rough_slope": c.max_slope * d * half_run + c.rough_noise_m,
            "stairs_up": np.floor(half_run / c.stair_width_m) * step,
            "stairs_down": np.floor(half_run / c.stair_width_m) * step,
            "discrete": c.obstacle_height_m[0] + c.obstacle_height_m[1] * d,
            "stepping_stones": c.pit_depth_m,
        }
        for column, kind in enumerate(terrain.column_kinds):
            h = tile(terrain, level, column)
            assert np.abs(h).max() <= bound[kind] + c.vertical_resolution_m, (level, kind)
            n = c.samples_per_tile
            centre = h[n // 2 - 4 : n // 2 + 4, n // 2 - 4 : n // 2 + 4]  # within the 1 m platform
            assert np.ptp(centre) == 0.0, (level, kind)
    # Quantised to the vertical resolution; the border is flat at 0.
    assert np.allclose(
        terrain.heights_m / c.vertical_resolution_m, np.round(terrain.heights_m / c.vertical_resolution_m)
    )
    assert not terrain.heights_m[: terrain.border_samples].any()


def test_stair_heights_follow_the_difficulty_formula():
    c = SMALL
    terrain = generate(c)
    for level in range(c.num_levels):
        expected = c.stair_height_m[0] + c.stair_height_m[1] * c.difficulty(level)  # 0.05 + 0.175 d
        for kind, sign in (("stairs_up", -1), ("stairs_down", 1)):
            h = tile(terrain, level, terrain.column_kinds.index(kind))
            line = h[c.samples_per_tile // 2, c.samples_per_tile // 2 :]  # centre to the +x edge
            risers = np.diff(line)[np.diff(line) != 0]
            assert np.allclose(-sign * risers, expected, atol=c.vertical_resolution_m / 2 + 1e-9), (level, kind, risers)
            # Treads are the configured width (the outermost one meets the tile's edge).
            widths = np.diff(np.flatnonzero(np.diff(line))) * c.horizontal_resolution_m
            assert np.allclose(widths, c.stair_width_m), widths


def test_same_seed_same_terrain_other_seed_other_terrain():
    a, b, other = generate(SMALL), generate(SMALL), generate(replace(SMALL, seed=4))
    assert np.array_equal(a.heights_m, b.heights_m)
    assert not np.array_equal(a.heights_m, other.heights_m)


def test_surface_height_matches_mujoco_ray_casts(tmp_path):
    terrain = generate(SMALL)
    spec = mujoco.MjSpec()
    add_to_spec(spec, terrain)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(0)
    lo, hi = terrain.origin_xy, terrain.origin_xy + (np.array(terrain.heights_m.shape[::-1]) - 1) * terrain.resolution_m
    points = rng.uniform(lo, hi, size=(300, 2))
    geom_id = np.zeros(1, np.int32)
    for x, y in points:
        distance = mujoco.mj_ray(model, data, np.array([x, y, 10.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geom_id)
        expected = terrain.height_at(x, y)
        # Within float32 (MuJoCo stores the heightfield normalised in float32) of the exact surface.
        assert abs((10.0 - distance) - expected) < 1e-4, (x, y)
    # The same function in JAX (the environments' height scan) agrees with numpy to float32's
    # precision on grid coordinates of a few hundred samples (~1e-5 of a cell, times the slope).
    import jax.numpy as jp

    np.testing.assert_allclose(
        np.asarray(
            surface_height(
                jp.asarray(terrain.heights_m), terrain.origin_xy, terrain.resolution_m, jp.asarray(points), jp
            )
        ),
        [terrain.height_at(x, y) for x, y in points],
        atol=1e-4,
    )
    preview(terrain, tmp_path / "terrain.png")
    assert (tmp_path / "terrain.png").stat().st_size > 10_000


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("num_levels", 0, "num_levels must be at least 1"),
        ("tile_size_m", -1.0, "tile_size_m must be positive"),
        ("proportions", (1, 1), "proportions must be 6"),
        ("platform_m", 9.0, "platform must be smaller"),
        ("num_columns", 2, r"num_columns \(2\) is fewer than the 6 terrain kinds"),  # crashed in generate before
    ],
)
def test_bad_terrain_configs_are_input_errors(field, value, message):
    with pytest.raises(InputError, match=message):
        generate(replace(TerrainConfig(), **{field: value}))


def test_as_many_columns_as_kinds_in_use_make_a_terrain():
    """The smallest terrains the tests use: two columns for two kinds with a share."""
    terrain = generate(replace(TerrainConfig(), num_levels=1, num_columns=2, proportions=(1, 1, 0, 0, 0, 0)))
    assert column_kinds(terrain.config) == (KINDS[0], KINDS[1])


def test_evaluation_robots_cover_every_terrain_kind_first():
    """A rough evaluation with few robots measures every kind of terrain before a second level of
    any (robot i used to go to level i mod 10 of column i // 10: 8 robots, smooth slopes only)."""
    from footforge.envs.terrain import TerrainConfig, column_kinds
    from footforge.rl.evaluate import spawn_tiles

    kinds = column_kinds(TerrainConfig())
    levels, columns = spawn_tiles(8, kinds, 10)
    covered = [kinds[c] for c in columns]
    assert set(covered[:6]) == set(kinds) and len(set(kinds)) == 6
    assert list(levels[:6]) == [0] * 6 and list(levels[6:]) == [1, 1]
    levels, columns = spawn_tiles(1200, kinds, 10)
    tiles = set(zip(levels, columns))
    assert len(tiles) == 10 * len(kinds)  # every tile (10 levels x 20 columns, one kind each) gets robots
    assert {kinds[c] for c in columns} == set(kinds) and levels.max() == 9
    few = spawn_tiles(4, kinds, 10)[1]
    assert len({kinds[c] for c in few}) == 4
