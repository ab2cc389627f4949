"""Rough terrain: one MuJoCo heightfield of tiles, levels of difficulty by columns of kinds.

Layout (the public baseline's): `num_levels` rows of tiles along x, difficulty d = level /
num_levels rising with x, and `num_columns` columns along y, each column one kind of terrain
(chosen by `proportions`). Every tile has a flat square at its centre where robots spawn.
Heights are in metres, quantised to the vertical resolution; the grid is stored row-major with
rows along y and columns along x, MuJoCo's heightfield order.

Resolution: 0.1 m between samples by default (the baseline's). MJX collides a geom with a
heightfield by testing the prisms of a fixed sub-grid around it: (2 r / res + 1)^2 prisms for a
geom of bounding radius r, so the AFF/AOF sole boxes (r <= 0.071 m) test at most 3 x 3 prisms
at 0.1 m and 4 x 4 at 0.05 m. Edges are linear between samples (a stair riser is a 0.1 m ramp).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from footforge.errors import InputError

KINDS = ("smooth_slope", "rough_slope", "stairs_up", "stairs_down", "discrete", "stepping_stones")
KIND_LEVEL_STEPS = "terrain/{}/steps_at_level_{}"
"""The rough environment's metric of the steps an episode spent on one of KINDS and one level (format with the
kind and the level): without the _per_step suffix Brax's logger averages each episode's sum, so that its values
over the kinds and levels are proportional to the time robots spend on each (a share of episodes would count a
fall of a few steps as much as a whole episode). A resume restores the curriculum from them
(footforge.rl.train.checkpoint_level_shares_by_kind)."""


@dataclass(frozen=True)
class TerrainConfig:
    num_levels: int = 10
    """Rows of tiles along x; level l has difficulty d = l / num_levels."""
    num_columns: int = 20
    """Columns of tiles along y, each of one kind."""
    tile_size_m: float = 8.0
    """Side of a square tile, m."""
    horizontal_resolution_m: float = 0.1
    """Distance between heightfield samples, m (see the module docstring for its MJX cost)."""
    vertical_resolution_m: float = 0.005
    """Heights are multiples of this, m."""
    proportions: tuple[float, ...] = (0.1, 0.1, 0.25, 0.25, 0.2, 0.1)
    """Share of the columns of each kind, in KINDS order (normalised; every kind with a positive
    share gets at least one column)."""
    border_m: float = 8.0
    """Flat ground around the tiles, m."""
    platform_m: float = 2.0
    """Side of the flat spawn square at each tile's centre, m."""
    max_slope: float = 0.4
    """Slope (rise over run) of the slope tiles is max_slope * d."""
    rough_noise_m: float = 0.1
    """Rough slopes add uniform noise in [-rough_noise_m, rough_noise_m], m."""
    rough_noise_spacing_m: float = 0.2
    """The noise is drawn on a grid this coarse and interpolated, m."""
    stair_width_m: float = 0.30
    stair_height_m: tuple[float, float] = (0.05, 0.175)
    """Step height = a + b * d, m."""
    obstacle_height_m: tuple[float, float] = (0.025, 0.15)
    """Discrete obstacle height = a + b * d, m (each obstacle raised or sunk at random)."""
    obstacle_size_m: tuple[float, float] = (1.0, 2.0)
    """Side range of the rectangular obstacles, m."""
    obstacles_per_tile: int = 20
    stone_size_m: tuple[float, float] = (2.0, -1.8)
    """Stepping-stone side = a + b * d, m."""
    stone_gap_m: float = 0.1
    pit_depth_m: float = 1.0
    """Depth of the gaps between stepping stones, m."""
    seed: int = 0

    def check(self) -> None:
        """Raises InputError on values that cannot make a terrain."""
        for name in ("num_levels", "num_columns"):
            if getattr(self, name) < 1:
                raise InputError(
                    f"terrain {name} must be at least 1, got {getattr(self, name)}", fix=f"give a positive {name}"
                )
        for name in ("tile_size_m", "horizontal_resolution_m", "vertical_resolution_m", "stair_width_m"):
            if not getattr(self, name) > 0:
                raise InputError(
                    f"terrain {name} must be positive, got {getattr(self, name)}", fix=f"give a positive {name}"
                )
        if len(self.proportions) != len(KINDS) or min(self.proportions) < 0 or sum(self.proportions) <= 0:
            raise InputError(
                f"terrain proportions must be {len(KINDS)} non-negative shares ({', '.join(KINDS)}), "
                f"got {self.proportions}",
                fix="e.g. (0.1, 0.1, 0.25, 0.25, 0.2, 0.1)",
            )
        used = sum(1 for share in self.proportions if share > 0)
        if self.num_columns < used:  # column_kinds gives every kind in use a column of its own
            raise InputError(
                f"terrain num_columns ({self.num_columns}) is fewer than the {used} terrain kinds with a share "
                f"in proportions {self.proportions} ({', '.join(KINDS)}): each kind needs a column",
                fix=f"give num_columns >= {used}, or zero shares for the kinds to leave out",
            )
        if self.platform_m >= self.tile_size_m:
            raise InputError(
                "the spawn platform must be smaller than a tile", fix=f"platform_m < tile_size_m ({self.tile_size_m})"
            )

    @property
    def samples_per_tile(self) -> int:
        return int(round(self.tile_size_m / self.horizontal_resolution_m))

    def difficulty(self, level: int) -> float:
        return level / self.num_levels


@dataclass(frozen=True)
class Terrain:
    """A generated terrain; heights_m[i, j] is at x = origin_xy[0] + j * res, y = origin_xy[1] + i * res."""

    config: TerrainConfig
    heights_m: np.ndarray
    origin_xy: np.ndarray
    """World position of sample (0, 0), m."""
    column_kinds: tuple[str, ...]
    """Kind of each column of tiles."""

    @property
    def resolution_m(self) -> float:
        return self.config.horizontal_resolution_m

    def tile_center(self, level, column):
        """World xy of the centre of tile (level, column) (numpy or JAX arrays)."""
        c = self.config
        border = self.border_samples * c.horizontal_resolution_m
        return (
            self.origin_xy[0] + border + (level + 0.5) * c.tile_size_m,
            self.origin_xy[1] + border + (column + 0.5) * c.tile_size_m,
        )

    @property
    def border_samples(self) -> int:
        return int(round(self.config.border_m / self.config.horizontal_resolution_m))

    def height_at(self, x: float, y: float) -> float:
        """Terrain height at world (x, y) on MuJoCo's triangulated surface (numpy)."""
        return float(surface_height(self.heights_m, self.origin_xy, self.resolution_m, np.array([x, y]), np))


def column_kinds(config: TerrainConfig) -> tuple[str, ...]:
    """The kind of each column: shares rounded by largest remainder, every used kind at least once."""
    shares = np.asarray(config.proportions, float) / sum(config.proportions)
    counts = np.floor(shares * config.num_columns).astype(int)
    used = shares > 0
    counts[used & (counts == 0)] = 1
    while counts.sum() > config.num_columns:
        counts[np.argmax(np.where(counts > 1, counts - shares * config.num_columns, -np.inf))] -= 1
    while counts.sum() < config.num_columns:
        counts[np.argmax(shares * config.num_columns - counts)] += 1
    return tuple(k for k, n in zip(KINDS, counts) for _ in range(n))


def generate(config: TerrainConfig) -> Terrain:
    """The terrain of `config`; the same config (seed included) gives the same heights."""
    config.check()
    rng = np.random.default_rng(config.seed)
    n, border = config.samples_per_tile, int(round(config.border_m / config.horizontal_resolution_m))
    kinds = column_kinds(config)
    heights = np.zeros((2 * border + config.num_columns * n + 1, 2 * border + config.num_levels * n + 1))
    for level in range(config.num_levels):
        for column, kind in enumerate(kinds):
            tile = _TILES[kind](config, config.difficulty(level), rng)
            i0, j0 = border + column * n, border + level * n
            heights[i0 : i0 + n, j0 : j0 + n] = tile
    heights = np.round(heights / config.vertical_resolution_m) * config.vertical_resolution_m
    half = (
        (heights.shape[1] - 1) * config.horizontal_resolution_m / 2,
        (heights.shape[0] - 1) * config.horizontal_resolution_m / 2,
    )
    # The terrain is centred on the world origin.
    return Terrain(config, heights, np.array([-half[0], -half[1]]), kinds)


# Tiles: (n, n) heights, rows along y, centred platform at height 0 -------------------------------


def _tile_coords(config: TerrainConfig):
    n, res = config.samples_per_tile, config.horizontal_resolution_m
    u = (np.arange(n) + 0.5) * res - config.tile_size_m / 2  # sample centres relative to the tile centre
    x, y = np.meshgrid(u, u)
    return x, y, np.maximum(np.abs(x), np.abs(y))


def _pyramid_slope(config, d, rng):
    """A pyramid (or pit) rising from 0 at the tile's edges to the platform, up or down at random."""
    _, _, r = _tile_coords(config)
    rise = config.max_slope * d * (config.tile_size_m / 2 - np.maximum(r, config.platform_m / 2))
    return rise if rng.random() < 0.5 else -rise


def _rough_slope(config, d, rng):
    slope = _pyramid_slope(config, d, rng)
    n, res = config.samples_per_tile, config.horizontal_resolution_m
    step = max(1, int(round(config.rough_noise_spacing_m / res)))
    coarse = rng.uniform(-config.rough_noise_m, config.rough_noise_m, (n // step + 2, n // step + 2))
    idx = np.arange(n) / step
    i0, f = np.floor(idx).astype(int), idx - np.floor(idx)
    rows = coarse[i0] * (1 - f)[:, None] + coarse[i0 + 1] * f[:, None]
    noise = rows[:, i0] * (1 - f)[None, :] + rows[:, i0 + 1] * f[None, :]
    _, _, r = _tile_coords(config)
    noise[r <= config.platform_m / 2] = 0.0
    return slope + noise


def _steps_from_edge(config, d):
    """(number of whole steps between the tile's edge and each sample, step height)."""
    _, _, r = _tile_coords(config)
    steps = np.floor((config.tile_size_m / 2 - np.maximum(r, config.platform_m / 2)) / config.stair_width_m)
    return steps, config.stair_height_m[0] + config.stair_height_m[1] * d


def _stairs_up(config, d, rng):
    """A pit of stairs: the platform at the bottom, so a robot leaving it climbs."""
    steps, height = _steps_from_edge(config, d)
    return -steps * height


def _stairs_down(config, d, rng):
    """A pyramid of stairs: the platform on top, so a robot leaving it descends."""
    steps, height = _steps_from_edge(config, d)
    return steps * height


def _discrete(config, d, rng):
    n = config.samples_per_tile
    x, y, r = _tile_coords(config)
    tile = np.zeros((n, n))
    height = config.obstacle_height_m[0] + config.obstacle_height_m[1] * d
    half = config.tile_size_m / 2
    for _ in range(config.obstacles_per_tile):
        w, h = rng.uniform(*config.obstacle_size_m, size=2)
        cx, cy = rng.uniform(-half, half, size=2)
        inside = (np.abs(x - cx) <= w / 2) & (np.abs(y - cy) <= h / 2)
        tile[inside] = height * rng.choice([-1.0, 1.0])
    tile[r <= config.platform_m / 2] = 0.0
    return tile


def _stepping_stones(config, d, rng):
    x, y, r = _tile_coords(config)
    size = max(config.stone_size_m[0] + config.stone_size_m[1] * d, 2 * config.horizontal_resolution_m)
    period = size + config.stone_gap_m
    offset = rng.uniform(0, period, size=2)
    on_stone = (np.mod(x + offset[0], period) < size) & (np.mod(y + offset[1], period) < size)
    tile = np.where(on_stone, 0.0, -config.pit_depth_m)
    tile[r <= config.platform_m / 2] = 0.0
    return tile


_TILES = {
    "smooth_slope": _pyramid_slope,
    "rough_slope": _rough_slope,
    "stairs_up": _stairs_up,
    "stairs_down": _stairs_down,
    "discrete": _discrete,
    "stepping_stones": _stepping_stones,
}


def surface_height(heights, origin_xy, resolution, xy, xp):
    """Height of MuJoCo's heightfield surface at points xy (..., 2), with numpy or jax.numpy as xp.

    MuJoCo splits each grid cell into two triangles along the diagonal from sample (i, j) to
    (i + 1, j + 1); within a triangle the surface is planar. Points outside the grid take the
    nearest edge cell's extension.
    """
    rows, cols = heights.shape
    g = (xy - xp.asarray(origin_xy)) / resolution
    gx = xp.clip(g[..., 0], 0.0, cols - 1.000001)
    gy = xp.clip(g[..., 1], 0.0, rows - 1.000001)
    j, i = xp.floor(gx).astype(int), xp.floor(gy).astype(int)
    fx, fy = gx - j, gy - i
    h00, h01 = heights[i, j], heights[i, j + 1]
    h10, h11 = heights[i + 1, j], heights[i + 1, j + 1]
    lower = fx >= fy  # the triangle (i, j), (i, j + 1), (i + 1, j + 1)
    return xp.where(lower, h00 + fx * (h01 - h00) + fy * (h11 - h01), h00 + fy * (h10 - h00) + fx * (h11 - h10))


def add_to_spec(spec, terrain: Terrain, name: str = "floor", base_thickness_m: float = 1.0):
    """Adds the terrain to a mujoco.MjSpec as a heightfield geom named `name`."""
    import mujoco

    h = terrain.heights_m
    lo, hi = float(h.min()), float(h.max())
    span = max(hi - lo, 1e-3)
    rows, cols = h.shape
    res = terrain.resolution_m
    field = spec.add_hfield(
        name=f"{name}_hfield",
        nrow=rows,
        ncol=cols,
        size=[(cols - 1) * res / 2, (rows - 1) * res / 2, span, base_thickness_m],
        userdata=((h - lo) / span).astype(np.float32).ravel().tolist(),
    )
    centre = terrain.origin_xy + np.array([(cols - 1) * res / 2, (rows - 1) * res / 2])
    return spec.worldbody.add_geom(
        name=name, type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=field.name, pos=[centre[0], centre[1], lo]
    )


def preview(terrain: Terrain, path) -> None:
    """A PNG of the heights with the tile grid, each column's kind and each level's difficulty."""
    from matplotlib.figure import Figure  # no pyplot: a library leaves the backend to its user

    c, h = terrain.config, terrain.heights_m
    res = terrain.resolution_m
    extent = (
        terrain.origin_xy[0],
        terrain.origin_xy[0] + (h.shape[1] - 1) * res,
        terrain.origin_xy[1],
        terrain.origin_xy[1] + (h.shape[0] - 1) * res,
    )
    fig = Figure(figsize=(6, 10))
    ax = fig.subplots()
    image = ax.imshow(np.clip(h, -0.5, None), origin="lower", extent=extent, cmap="terrain")
    fig.colorbar(image, ax=ax, label="height (m), pits clipped at -0.5", shrink=0.6)
    for column, kind in enumerate(terrain.column_kinds):
        _, y = terrain.tile_center(0, column)
        ax.text(extent[0] + 0.5, y, kind.replace("_", " "), fontsize=5, va="center")
    for level in range(c.num_levels):
        x, _ = terrain.tile_center(level, 0)
        ax.text(x, extent[2] + 1, f"d={c.difficulty(level):.1f}", fontsize=5, ha="center")
    ax.set(
        xlabel="x (m): difficulty rises",
        ylabel="y (m): columns of kinds",
        title=f"terrain, seed {c.seed}, {res} m samples",
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
