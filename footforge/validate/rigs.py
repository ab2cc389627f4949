"""The rig of every (scenario, variant), as MJCF text and assets for worker processes."""

from __future__ import annotations

import numpy as np

from footforge import constants as C
from footforge.inputs.params import VariantParams
from footforge.mjcf import foot as foot_lib
from footforge.mjcf.rig import build_rig
from footforge.models.foot_source import FootSource
from footforge.validate.scenarios import Scenario, SoleExtent, add_obstacle, mount_quat
from footforge.validate.simulate import RigCase
from footforge.variants import foot_variant


def build_feet(source: FootSource, variants) -> dict[str, foot_lib.FootModel | None]:
    """The closed chain and each requested variant (None for the ball), from one source."""
    full = foot_lib.build_full(source)
    feet: dict[str, foot_lib.FootModel | None] = {"full": full}
    for v in variants:
        if foot_variant(v).derived:
            feet[v] = foot_lib.build_derived(source, v, full=full)
        elif not foot_variant(v).adaptive:
            feet[v] = None
    return feet


def sole_extent(full: foot_lib.FootModel) -> SoleExtent:
    """Half-length and half-width of the closed chain's sole collision geometry (reference pose)."""
    model, data = foot_lib.posed_at_reference(full)
    sole = foot_lib.sole_bodies(full)
    pts = foot_lib.collision_points(model, data, sole)
    centre = data.xpos[model.body(full.root_body).id]
    return SoleExtent(
        half_length_m=float(np.abs(pts[:, 0] - centre[0]).max()),
        half_width_m=float(np.abs(pts[:, 1] - centre[1]).max()),
    )


def rig_case(
    foot: foot_lib.FootModel | None,
    variant: str,
    scenario: Scenario,
    sole: SoleExtent,
    params: VariantParams,
    friction: float,
) -> RigCase:
    rig = build_rig(
        foot, C.BALL_FOOT_RADIUS_M, variant=variant, params=params, friction=friction, mount_quat=mount_quat(scenario)
    )
    add_obstacle(rig.mjcf, scenario, sole)
    return RigCase(
        scenario,
        variant,
        rig.mjcf.to_xml_string(),
        rig.mjcf.get_assets(),
        sole_bodies=tuple(foot_lib.sole_bodies(foot)) if foot is not None else (),
    )
