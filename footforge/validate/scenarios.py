"""Drop-test scenarios: what the foot lands on, from how high, with the leg at which angle.

Every scenario is a frozen, named set of numbers, run identically for every variant. Obstacle
positions are fractions of the sole's half-length (x) and half-width (y), measured on the closed
chain's sole at its reference pose, so the same scenarios fit another foot description.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from footforge.errors import InputError

if TYPE_CHECKING:  # the names alone: footforge --help lists the scenarios without dm_control (footforge[build])
    from dm_control import mjcf

ObstacleKind = Literal["flat", "slope", "step", "cylinder", "rock", "rough"]


@dataclass(frozen=True)
class SoleExtent:
    """The closed chain's sole at its reference pose, in the foot mount frame."""

    half_length_m: float
    half_width_m: float


@dataclass(frozen=True)
class Scenario:
    name: str
    obstacle: ObstacleKind
    """flat floor, tilted plane, box step, cylinder lying on the floor, half-buried sphere, or a
    random heightfield patch."""
    drop_height_m: float = 0.02
    """Gap between the foot's lowest point and the obstacle when released, m."""
    leg_pitch_deg: float = 0.0
    """Tilt of the foot mount about y (positive: toe down), deg."""
    leg_roll_deg: float = 0.0
    """Tilt of the foot mount about x (positive: left side up), deg."""
    slope_deg: float = 0.0
    """slope: plane inclination, deg (toe or left side uphill)."""
    slope_axis: Literal["pitch", "roll"] = "pitch"
    """slope: `pitch` rises along x (toe uphill), `roll` along y (left side uphill)."""
    x_frac: float = 0.0
    """step/cylinder/rock: obstacle position along the sole, -1 heel end .. 1 toe end."""
    y_frac: float = 0.0
    """step/rock: obstacle position across the sole, -1 right edge .. 1 left edge."""
    step_side: Literal["toe", "heel", "left", "right"] = "toe"
    """step: which part of the sole is over the raised side."""
    step_height_m: float = 0.02
    cylinder_radius_m: float = 0.025
    cylinder_axis: Literal["across", "along"] = "across"
    """cylinder: `across` the sole (axis y) or `along` it (axis x)."""
    rock_radius_m: float = 0.02
    rough_amplitude_m: float = 0.012
    """rough: peak-to-peak height of the random patch, m."""
    rough_cell_m: float = 0.005
    """rough: heightfield grid spacing, m (the chain links are about 14 mm long)."""
    seed: int = 0
    """rough: the patch's random seed."""
    duration_s: float = 1.0
    """Simulated time from release, s."""

    def describe(self) -> dict:
        """The parameters that matter for this obstacle kind (for reports)."""
        keep = {"name", "obstacle", "drop_height_m", "leg_pitch_deg", "leg_roll_deg", "duration_s"}
        keep |= {
            "slope": {"slope_deg", "slope_axis"},
            "step": {"step_side", "step_height_m"},
            "cylinder": {"cylinder_radius_m", "cylinder_axis", "x_frac"},
            "rock": {"rock_radius_m", "x_frac", "y_frac"},
            "rough": {"rough_amplitude_m", "rough_cell_m", "seed"},
        }.get(self.obstacle, set())
        return {k: v for k, v in asdict(self).items() if k in keep}


def _scenarios() -> tuple[Scenario, ...]:
    s = [
        Scenario("flat_2cm", "flat"),
        Scenario("flat_5cm", "flat", drop_height_m=0.05),
        Scenario("flat_10cm", "flat", drop_height_m=0.10),
    ]
    for axis in ("pitch", "roll"):
        for deg in (10, 20):
            s.append(Scenario(f"slope_{axis}_{deg}deg", "slope", slope_deg=deg, slope_axis=axis))
    s += [Scenario(f"step_{side}", "step", step_side=side) for side in ("toe", "heel", "left")]
    s += [
        Scenario("cylinder_across", "cylinder", cylinder_axis="across"),
        Scenario("cylinder_along", "cylinder", cylinder_axis="along"),
        Scenario("cylinder_across_10cm", "cylinder", cylinder_axis="across", drop_height_m=0.10),
    ]
    s += [Scenario(f"rock_{where}", "rock", x_frac=x) for where, x in (("front", 0.6), ("middle", 0.0), ("back", -0.6))]
    s += [Scenario("rock_middle_10cm", "rock", drop_height_m=0.10), Scenario("rock_side", "rock", y_frac=0.6)]
    s += [Scenario(f"rough_seed{k}", "rough", seed=k) for k in range(3)]
    for axis in ("pitch", "roll"):
        for deg in (10, -10):
            s.append(Scenario(f"leg_{axis}_{deg:+d}deg", "flat", **{f"leg_{axis}_deg": float(deg)}))  # type: ignore[arg-type]
    s.append(Scenario("slope_pitch_20deg_5cm", "slope", slope_deg=20, slope_axis="pitch", drop_height_m=0.05))
    return tuple(s)


SCENARIOS: tuple[Scenario, ...] = _scenarios()
QUICK = ("flat_2cm", "slope_pitch_10deg", "step_toe", "cylinder_across", "rock_front", "leg_roll_+10deg")
"""About six scenarios covering each obstacle family, for CI and quick checks."""
BY_NAME = {s.name: s for s in SCENARIOS}


def select(spec: list[str] | tuple[str, ...] | str) -> list[Scenario]:
    """'quick', 'all', or scenario names (a list, or one comma-separated string).

    Raises:
      InputError: an unknown name (the known ones are listed).
    """
    names = [spec] if isinstance(spec, str) else list(spec)
    names = [n.strip() for item in names for n in item.split(",") if n.strip()]
    if not names or names == ["quick"]:
        return [BY_NAME[n] for n in QUICK]
    if names == ["all"]:
        return list(SCENARIOS)
    unknown = [n for n in names if n not in BY_NAME]
    if unknown:
        raise InputError(
            f"unknown scenario(s): {', '.join(unknown)}", fix="use quick, all, or names from: " + ", ".join(BY_NAME)
        )
    return [BY_NAME[n] for n in dict.fromkeys(names)]


def mount_quat(scenario: Scenario) -> np.ndarray:
    """The foot mount's tilt (wxyz): roll about x, then pitch about y."""
    import mujoco

    quat = np.zeros(4)
    mujoco.mju_euler2Quat(quat, np.radians([scenario.leg_roll_deg, scenario.leg_pitch_deg, 0.0]), "XYZ")
    return quat


def add_obstacle(root: mjcf.RootElement, scenario: Scenario, sole: SoleExtent) -> None:
    """Adds the scenario's ground to a rig's worldbody; the flat floor stays where the obstacle
    stands on it and is replaced by the plane for slopes."""
    world = root.worldbody
    floor = root.find("geom", "floor")
    kw = {"contype": 1, "conaffinity": 1, "rgba": [0.55, 0.45, 0.35, 1]}  # friction as the floor's
    L, W = sole.half_length_m, sole.half_width_m
    o = scenario.obstacle
    if o == "flat":
        return
    if o == "slope":
        floor.remove()
        angle = math.radians(scenario.slope_deg)
        # Rising toward +x (toe) is a rotation about -y; toward +y (left) about +x.
        axis = [0, -1, 0] if scenario.slope_axis == "pitch" else [1, 0, 0]
        world.add("geom", name="obstacle", type="plane", size=[0, 0, 0.05], axisangle=axis + [angle], **kw)
    elif o == "step":
        h = scenario.step_height_m
        half = 0.5
        # A box whose top is at z = h and whose edge passes under the middle of the named part.
        edge, direction = {
            "toe": (0.5 * L, [1, 0]),
            "heel": (-0.5 * L, [-1, 0]),
            "left": (0.5 * W, [0, 1]),
            "right": (-0.5 * W, [0, -1]),
        }[scenario.step_side]
        centre = np.array(direction, float) * half + (np.array([edge, 0]) if direction[0] else np.array([0, edge]))
        world.add("geom", name="obstacle", type="box", size=[half, half, h / 2], pos=[*centre, h / 2], **kw)
    elif o == "cylinder":
        r = scenario.cylinder_radius_m
        quat = (
            [0.7071067811865476, 0.7071067811865476, 0, 0]
            if scenario.cylinder_axis == "across"
            else [0.7071067811865476, 0, 0.7071067811865476, 0]
        )
        world.add(
            "geom", name="obstacle", type="cylinder", size=[r, 0.15], pos=[scenario.x_frac * L, 0, r], quat=quat, **kw
        )
    elif o == "rock":
        world.add(
            "geom",
            name="obstacle",
            type="sphere",
            size=[scenario.rock_radius_m],
            pos=[scenario.x_frac * L, scenario.y_frac * W, 0],
            **kw,
        )
    elif o == "rough":
        n, cell = 41, scenario.rough_cell_m
        rng = np.random.default_rng(scenario.seed)
        heights = rng.uniform(0.0, 1.0, size=(n, n))
        # Smooth with a 3x3 mean so bumps are a couple of cells wide, then span [0, 1].
        padded = np.pad(heights, 1, mode="edge")
        heights = sum(padded[i : i + n, j : j + n] for i in range(3) for j in range(3)) / 9.0  # type: ignore[assignment]
        heights = (heights - heights.min()) / (heights.max() - heights.min())
        half = cell * (n - 1) / 2
        root.asset.add(
            "hfield",
            name="rough",
            nrow=n,
            ncol=n,
            size=[half, half, scenario.rough_amplitude_m, 0.005],
            elevation=heights.ravel().tolist(),
        )
        world.add("geom", name="obstacle", type="hfield", hfield="rough", **kw)
    else:
        raise InputError(
            f"unknown obstacle kind '{o}' in scenario '{scenario.name}'",
            fix="use flat, slope, step, cylinder, rock or rough",
        )
